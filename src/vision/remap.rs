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
        // `as` saturates: no clamp needed.
        (v + 0.5) as u8
    }
}

impl Sample for u16 {
    #[inline]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
    #[inline]
    fn from_f32(v: f32) -> Self {
        (v + 0.5) as u16
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

/// A map coordinate in 1/32 px, rounded to the nearest, as an integer: without `round`, which
/// is a library call on x86-64's baseline and would cost more than the rest of the pixel. The
/// offset makes the truncation a floor for coordinates down to −32 768 px; farther ones (and
/// the saturated infinities) land outside any image, as they should.
#[inline]
fn steps(v: f32) -> i32 {
    const OFFSET: i32 = 1 << 20;
    (f64::from(v) * f64::from(STEPS) + (0.5 + f64::from(OFFSET))) as i32 - OFFSET
}

/// OpenCV's bicubic weights for a fraction `x` in 0..1.
#[inline]
fn cubic_weights(x: f32) -> [f32; 4] {
    const A: f32 = -0.75;
    let w0 = ((A * (x + 1.0) - 5.0 * A) * (x + 1.0) + 8.0 * A) * (x + 1.0) - 4.0 * A;
    let w1 = ((A + 2.0) * x - (A + 3.0)) * x * x + 1.0;
    let w2 = ((A + 2.0) * (1.0 - x) - (A + 3.0)) * (1.0 - x) * (1.0 - x) + 1.0;
    [w0, w1, w2, 1.0 - w0 - w1 - w2]
}

/// A map converted for reading, as OpenCV's `convertMaps` to `CV_16SC2` does: each rectified
/// pixel's raw top-left neighbour (x0, y0) and its position between the four neighbours in
/// 1/32 px. Half the bytes of the float map, and no float-to-integer work per frame, so a rig
/// whose maps are cached pays only for the reading.
#[derive(Debug, Clone, PartialEq)]
pub struct Fixed {
    pub width: usize,
    pub height: usize,
    /// (x0, y0), or (−2, −2) for a pixel read from wholly outside any image.
    xy: Vec<[i16; 2]>,
    /// `fy · 32 + fx`.
    frac: Vec<u16>,
}

impl Fixed {
    /// The map in fixed point.
    pub fn new(map: &Map) -> Fixed {
        let (width, height) = (map.size.width as usize, map.size.height as usize);
        let mut xy = vec![[-2i16; 2]; width * height];
        let mut frac = vec![0u16; width * height];
        xy.par_chunks_mut(width.max(1))
            .zip(frac.par_chunks_mut(width.max(1)))
            .enumerate()
            .for_each(|(row, (xy, frac))| {
                let xs = &map.x[row * width..(row + 1) * width];
                let ys = &map.y[row * width..(row + 1) * width];
                for i in 0..width {
                    let (mx, my) = (xs[i], ys[i]);
                    if !(mx.is_finite() && my.is_finite()) {
                        continue;
                    }
                    let (xi, yi) = (steps(mx), steps(my));
                    let (x0, y0) = (xi >> 5, yi >> 5);
                    if (-4..i32::from(i16::MAX)).contains(&x0)
                        && (-4..i32::from(i16::MAX)).contains(&y0)
                    {
                        xy[i] = [x0 as i16, y0 as i16];
                        frac[i] = (((yi & 31) << 5) | (xi & 31)) as u16;
                    }
                }
            });
        Fixed {
            width,
            height,
            xy,
            frac,
        }
    }

    /// The bytes it holds.
    pub fn bytes(&self) -> usize {
        self.xy.len() * 6
    }

    /// The share of pixels read from inside a raw image of `width × height`.
    pub fn valid_share(&self, width: usize, height: usize) -> f64 {
        let (w, h) = (width as i32, height as i32);
        let inside = self
            .xy
            .iter()
            .zip(&self.frac)
            .filter(|([x, y], f)| {
                let (x, y) = (i32::from(*x), i32::from(*y));
                let (fx, fy) = (i32::from(**f & 31), i32::from(**f >> 5));
                x >= 0
                    && y >= 0
                    && (x < w - 1 || (x == w - 1 && fx == 0))
                    && (y < h - 1 || (y == h - 1 && fy == 0))
            })
            .count();
        inside as f64 / self.xy.len().max(1) as f64
    }
}

/// The bilinear weights of each of the 32 × 32 positions between four pixels.
static LINEAR: std::sync::LazyLock<Vec<[f32; 4]>> = std::sync::LazyLock::new(|| {
    (0..1024)
        .map(|f| {
            let fx = (f & 31) as f32 / STEPS;
            let fy = (f >> 5) as f32 / STEPS;
            [
                (1.0 - fx) * (1.0 - fy),
                fx * (1.0 - fy),
                (1.0 - fx) * fy,
                fx * fy,
            ]
        })
        .collect()
});

/// The bicubic weights of each of the 32 positions between two pixels.
static CUBIC: std::sync::LazyLock<Vec<[f32; 4]>> =
    std::sync::LazyLock::new(|| (0..32).map(|f| cubic_weights(f as f32 / STEPS)).collect());

/// `source` read through `map` into an image of the map's size, with the same channels (1 to
/// 4); pixels read from outside the raw image are black.
pub fn remap<T: Sample>(source: Source<'_, T>, map: &Map, how: Interpolation) -> Vec<T> {
    remap_fixed(source, &Fixed::new(map), how)
}

/// [`remap`] through a map already in fixed point.
pub fn remap_fixed<T: Sample>(source: Source<'_, T>, map: &Fixed, how: Interpolation) -> Vec<T> {
    match source.channels {
        1 => remap_with::<T, 1>(source, map, how),
        2 => remap_with::<T, 2>(source, map, how),
        3 => remap_with::<T, 3>(source, map, how),
        4 => remap_with::<T, 4>(source, map, how),
        c => {
            debug_assert!(false, "{c} channels");
            vec![T::default(); map.width * map.height * c]
        }
    }
}

/// [`remap`] for `C` channels, known when compiled so that each pixel's loop unrolls.
fn remap_with<T: Sample, const C: usize>(
    source: Source<'_, T>,
    map: &Fixed,
    how: Interpolation,
) -> Vec<T> {
    let (w, h) = (map.width, map.height);
    let mut out = vec![T::default(); w * h * C];
    if w == 0 || source.data.len() < source.width * source.height * C {
        return out;
    }
    let (sw, sh) = (source.width as i32, source.height as i32);
    let stride = source.width * C;
    let data = source.data;
    let at = |x: i32, y: i32, ch: usize| -> f32 {
        if x < 0 || y < 0 || x >= sw || y >= sh {
            0.0
        } else {
            data[y as usize * stride + x as usize * C + ch].to_f32()
        }
    };
    let linear = &*LINEAR;
    let cubic = &*CUBIC;
    out.par_chunks_mut(w * C)
        .enumerate()
        .for_each(|(row, line)| {
            let xys = &map.xy[row * w..(row + 1) * w];
            let fracs = &map.frac[row * w..(row + 1) * w];
            let pixels = line.chunks_exact_mut(C).zip(xys).zip(fracs);
            match how {
                Interpolation::Nearest => {
                    for ((px, &[x0, y0]), &f) in pixels {
                        let x = i32::from(x0) + i32::from(f & 31 >= 16);
                        let y = i32::from(y0) + i32::from(f >> 5 >= 16);
                        if x >= 0 && y >= 0 && x < sw && y < sh {
                            let k = y as usize * stride + x as usize * C;
                            px.copy_from_slice(&data[k..k + C]);
                        }
                    }
                }
                Interpolation::Linear => {
                    for ((px, &[x0, y0]), &f) in pixels {
                        let (x0, y0) = (i32::from(x0), i32::from(y0));
                        let wt = linear[usize::from(f & 1023)];
                        if x0 >= 0 && y0 >= 0 && x0 + 1 < sw && y0 + 1 < sh {
                            let k = y0 as usize * stride + x0 as usize * C;
                            let top = &data[k..k + 2 * C];
                            let bottom = &data[k + stride..k + stride + 2 * C];
                            for ch in 0..C {
                                px[ch] = T::from_f32(
                                    top[ch].to_f32() * wt[0]
                                        + top[C + ch].to_f32() * wt[1]
                                        + bottom[ch].to_f32() * wt[2]
                                        + bottom[C + ch].to_f32() * wt[3],
                                );
                            }
                        } else if x0 >= -1 && y0 >= -1 && x0 < sw && y0 < sh {
                            for (ch, v) in px.iter_mut().enumerate() {
                                *v = T::from_f32(
                                    at(x0, y0, ch) * wt[0]
                                        + at(x0 + 1, y0, ch) * wt[1]
                                        + at(x0, y0 + 1, ch) * wt[2]
                                        + at(x0 + 1, y0 + 1, ch) * wt[3],
                                );
                            }
                        }
                    }
                }
                Interpolation::Cubic => {
                    for ((px, &[x0, y0]), &f) in pixels {
                        let (x0, y0) = (i32::from(x0) - 1, i32::from(y0) - 1);
                        if x0 < -3 || y0 < -3 || x0 >= sw || y0 >= sh {
                            continue;
                        }
                        let wx = cubic[usize::from(f & 31)];
                        let wy = cubic[usize::from((f >> 5) & 31)];
                        let interior = x0 >= 0 && y0 >= 0 && x0 + 3 < sw && y0 + 3 < sh;
                        for (ch, v) in px.iter_mut().enumerate() {
                            let mut sum = 0.0;
                            for (dy, wyk) in wy.iter().enumerate() {
                                let mut row_sum = 0.0;
                                if interior {
                                    let k = (y0 as usize + dy) * stride + x0 as usize * C + ch;
                                    for (dx, wxk) in wx.iter().enumerate() {
                                        row_sum += data[k + dx * C].to_f32() * wxk;
                                    }
                                } else {
                                    for (dx, wxk) in wx.iter().enumerate() {
                                        row_sum += at(x0 + dx as i32, y0 + dy as i32, ch) * wxk;
                                    }
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
