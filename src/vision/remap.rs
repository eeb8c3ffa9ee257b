//! Remapping an image through a rectification map, as OpenCV's `remap` does with float maps
//! and a constant black border: nearest, bilinear (coordinates rounded to 1/32 px, as OpenCV's
//! `INTER_BITS`) or bicubic (OpenCV's A = −0.75). Any number of interleaved channels, 8 or 16
//! bits; rows in parallel.

use rayon::prelude::*;

use crate::camera::Map;

/// How a pixel between the raw image's pixels is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Interpolation {
    Nearest,
    #[default]
    Linear,
    Cubic,
}

impl Interpolation {
    pub const ALL: [Interpolation; 3] = [
        Interpolation::Nearest,
        Interpolation::Linear,
        Interpolation::Cubic,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Interpolation::Nearest => "nearest",
            Interpolation::Linear => "linear",
            Interpolation::Cubic => "cubic",
        }
    }
}

/// A sample type remapped: its value as `f32` and back, rounded and clamped.
pub trait Sample: Copy + Default + Send + Sync {
    fn to_f32(self) -> f32;
    fn from_f32(v: f32) -> Self;
}

impl Sample for u8 {
    #[inline]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
    #[inline]
    fn from_f32(v: f32) -> Self {
        (v + 0.5).clamp(0.0, 255.0) as u8
    }
}

impl Sample for u16 {
    #[inline]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
    #[inline]
    fn from_f32(v: f32) -> Self {
        (v + 0.5).clamp(0.0, 65535.0) as u16
    }
}

/// A raw image: `width × height` pixels of `channels` interleaved samples.
#[derive(Debug, Clone, Copy)]
pub struct Source<'a, T> {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub data: &'a [T],
}

/// The subpixel steps a coordinate is rounded to (OpenCV's `INTER_TAB_SIZE`).
const STEPS: f32 = 32.0;

/// OpenCV's bicubic weights for a fraction `x` in 0..1.
#[inline]
fn cubic_weights(x: f32) -> [f32; 4] {
    const A: f32 = -0.75;
    let w0 = ((A * (x + 1.0) - 5.0 * A) * (x + 1.0) + 8.0 * A) * (x + 1.0) - 4.0 * A;
    let w1 = ((A + 2.0) * x - (A + 3.0)) * x * x + 1.0;
    let w2 = ((A + 2.0) * (1.0 - x) - (A + 3.0)) * (1.0 - x) * (1.0 - x) + 1.0;
    [w0, w1, w2, 1.0 - w0 - w1 - w2]
}

/// `source` read through `map` into an image of the map's size, with the same channels;
/// pixels read from outside the raw image are black.
pub fn remap<T: Sample>(source: Source<'_, T>, map: &Map, how: Interpolation) -> Vec<T> {
    let (w, h) = (map.size.width as usize, map.size.height as usize);
    let c = source.channels;
    let mut out = vec![T::default(); w * h * c];
    if w == 0 || c == 0 {
        return out;
    }
    let (sw, sh) = (source.width as i64, source.height as i64);
    let data = source.data;
    let at = |x: i64, y: i64, ch: usize| -> f32 {
        if x < 0 || y < 0 || x >= sw || y >= sh {
            0.0
        } else {
            data[(y as usize * source.width + x as usize) * c + ch].to_f32()
        }
    };
    out.par_chunks_mut(w * c)
        .enumerate()
        .for_each(|(row, line)| {
            let xs = &map.x[row * w..(row + 1) * w];
            let ys = &map.y[row * w..(row + 1) * w];
            for (i, (&mx, &my)) in xs.iter().zip(ys).enumerate() {
                let px = &mut line[i * c..(i + 1) * c];
                if !(mx.is_finite() && my.is_finite()) {
                    continue;
                }
                match how {
                    Interpolation::Nearest => {
                        let (x, y) = (mx.round() as i64, my.round() as i64);
                        if x >= 0 && y >= 0 && x < sw && y < sh {
                            let k = (y as usize * source.width + x as usize) * c;
                            px.copy_from_slice(&data[k..k + c]);
                        }
                    }
                    Interpolation::Linear => {
                        let (xi, yi) = ((mx * STEPS).round() as i64, (my * STEPS).round() as i64);
                        let (x0, y0) = (xi.div_euclid(32), yi.div_euclid(32));
                        if x0 < -1 || y0 < -1 || x0 >= sw || y0 >= sh {
                            continue;
                        }
                        let fx = xi.rem_euclid(32) as f32 / STEPS;
                        let fy = yi.rem_euclid(32) as f32 / STEPS;
                        let weights = [
                            (1.0 - fx) * (1.0 - fy),
                            fx * (1.0 - fy),
                            (1.0 - fx) * fy,
                            fx * fy,
                        ];
                        if x0 >= 0 && y0 >= 0 && x0 + 1 < sw && y0 + 1 < sh {
                            let k = (y0 as usize * source.width + x0 as usize) * c;
                            let down = k + source.width * c;
                            for (ch, v) in px.iter_mut().enumerate() {
                                *v = T::from_f32(
                                    data[k + ch].to_f32() * weights[0]
                                        + data[k + c + ch].to_f32() * weights[1]
                                        + data[down + ch].to_f32() * weights[2]
                                        + data[down + c + ch].to_f32() * weights[3],
                                );
                            }
                        } else {
                            for (ch, v) in px.iter_mut().enumerate() {
                                *v = T::from_f32(
                                    at(x0, y0, ch) * weights[0]
                                        + at(x0 + 1, y0, ch) * weights[1]
                                        + at(x0, y0 + 1, ch) * weights[2]
                                        + at(x0 + 1, y0 + 1, ch) * weights[3],
                                );
                            }
                        }
                    }
                    Interpolation::Cubic => {
                        let (xi, yi) = ((mx * STEPS).round() as i64, (my * STEPS).round() as i64);
                        let (x0, y0) = (xi.div_euclid(32) - 1, yi.div_euclid(32) - 1);
                        if x0 < -3 || y0 < -3 || x0 >= sw || y0 >= sh {
                            continue;
                        }
                        let wx = cubic_weights(xi.rem_euclid(32) as f32 / STEPS);
                        let wy = cubic_weights(yi.rem_euclid(32) as f32 / STEPS);
                        for (ch, v) in px.iter_mut().enumerate() {
                            let mut sum = 0.0;
                            for (dy, wyk) in wy.iter().enumerate() {
                                let mut row_sum = 0.0;
                                for (dx, wxk) in wx.iter().enumerate() {
                                    row_sum += at(x0 + dx as i64, y0 + dy as i64, ch) * wxk;
                                }
                                sum += row_sum * wyk;
                            }
                            *v = T::from_f32(sum);
                        }
                    }
                }
            }
        });
    out
}

/// The share of a map's pixels that read from inside the raw image (the rest are black).
pub fn valid_share(map: &Map, width: usize, height: usize) -> f64 {
    let (w, h) = (width as f32, height as f32);
    let inside = map
        .x
        .iter()
        .zip(&map.y)
        .filter(|(x, y)| **x >= 0.0 && **y >= 0.0 && **x <= w - 1.0 && **y <= h - 1.0)
        .count();
    inside as f64 / map.x.len().max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Size;

    fn shift_map(width: u32, height: u32, dx: f32, dy: f32) -> Map {
        let n = (width * height) as usize;
        let mut map = Map {
            size: Size { width, height },
            x: vec![0.0; n],
            y: vec![0.0; n],
        };
        for y in 0..height {
            for x in 0..width {
                let i = (y * width + x) as usize;
                map.x[i] = x as f32 + dx;
                map.y[i] = y as f32 + dy;
            }
        }
        map
    }

    /// A whole-pixel shift moves the image exactly in every interpolation, black where it
    /// reads outside; a half-pixel shift of a ramp gives the mean of neighbours.
    #[test]
    fn shifts_and_ramps() {
        let (w, h) = (8usize, 5usize);
        let data: Vec<u8> = (0..w * h)
            .map(|i| (i % w) as u8 * 10 + (i / w) as u8)
            .collect();
        let src = Source {
            width: w,
            height: h,
            channels: 1,
            data: &data,
        };
        for how in Interpolation::ALL {
            let out = remap(src, &shift_map(8, 5, 2.0, 1.0), how);
            for y in 0..h {
                for x in 0..w {
                    let expected = if x + 2 < w && y + 1 < h {
                        data[(y + 1) * w + x + 2]
                    } else {
                        0
                    };
                    assert_eq!(out[y * w + x], expected, "{how:?} at ({x}, {y})");
                }
            }
        }
        let out = remap(src, &shift_map(8, 5, 0.5, 0.0), Interpolation::Linear);
        assert_eq!(out[w + 3], 36, "(30 + 40) / 2 + 1");
    }

    /// Colour channels stay apart, and 16-bit samples keep their range.
    #[test]
    fn channels_and_depths() {
        let rgb: Vec<u8> = vec![10, 200, 30, 20, 100, 60];
        let out = remap(
            Source {
                width: 2,
                height: 1,
                channels: 3,
                data: &rgb,
            },
            &shift_map(1, 1, 0.5, 0.0),
            Interpolation::Linear,
        );
        assert_eq!(out, vec![15, 150, 45]);
        // A 16-bit ramp of 1000 a pixel, read a quarter pixel on by the cubic: 61297, as
        // `cv2.remap(..., INTER_CUBIC)` gives (A = −0.75 overshoots a ramp by 47).
        let grey: Vec<u16> = (0..6 * 4).map(|i| 59000 + 1000 * (i % 6) as u16).collect();
        let out = remap(
            Source {
                width: 6,
                height: 4,
                channels: 1,
                data: &grey,
            },
            &shift_map(6, 4, 0.25, 0.0),
            Interpolation::Cubic,
        );
        assert_eq!(out[6 + 2], 61297);
    }
}
