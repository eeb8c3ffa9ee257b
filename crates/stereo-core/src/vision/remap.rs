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

/// A sample type remapped: its value as `f32` or `u32` and back, rounded and clamped.
pub trait Sample: Copy + Default + Send + Sync {
    fn to_f32(self) -> f32;
    fn from_f32(v: f32) -> Self;
    fn to_u32(self) -> u32;
    /// From a value that fits (a weighted mean of samples).
    fn from_u32(v: u32) -> Self;
    /// One row of a one-channel image remapped bilinearly by a vectorised routine, where
    /// this type and the CPU have one: `false` (nothing written) when not. The raw image is
    /// `width × height` samples, `stride` apart; `xy` and `frac` are the row's map (as in
    /// [`Fixed`]), `out` the row.
    #[doc(hidden)]
    fn linear_grey_row(
        _data: &[Self],
        _size: (usize, usize),
        _xy: &[[i16; 2]],
        _frac: &[u16],
        _out: &mut [Self],
    ) -> bool {
        false
    }
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
    #[inline]
    fn to_u32(self) -> u32 {
        u32::from(self)
    }
    #[inline]
    fn from_u32(v: u32) -> Self {
        v as u8
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
    #[inline]
    fn to_u32(self) -> u32 {
        u32::from(self)
    }
    #[inline]
    fn from_u32(v: u32) -> Self {
        v as u16
    }
    fn linear_grey_row(
        data: &[u16],
        (width, height): (usize, usize),
        xy: &[[i16; 2]],
        frac: &[u16],
        out: &mut [u16],
    ) -> bool {
        #[cfg(target_arch = "x86_64")]
        if crate::vision::simd::avx2()
            && width < 32_768
            && height < 32_768
            && data.len() >= width * height
        {
            let raw = Raw {
                data,
                stride: width,
                width: width as i32,
                height: height as i32,
            };
            // SAFETY: `avx2()` checked that this CPU has AVX2.
            unsafe { linear_grey_avx2(&raw, xy, frac, out) };
            return true;
        }
        let _ = (data, width, height, xy, frac, out);
        false
    }
}

/// A raw image: `width × height` pixels of `channels` interleaved samples.
#[derive(Debug, Clone, Copy)]
pub struct RawImage<'a, T> {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub data: &'a [T],
}

impl<'a> RawImage<'a, u16> {
    /// A grey image's levels, one channel.
    pub fn grey(image: &'a super::Gray) -> Self {
        RawImage {
            width: image.width,
            height: image.height,
            channels: 1,
            data: &image.data,
        }
    }
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

/// A raw image as the remapping reads it: `width × height` pixels of `C` samples, rows
/// `stride` samples apart.
struct Raw<'a, T> {
    data: &'a [T],
    stride: usize,
    width: i32,
    height: i32,
}

/// The bits of the bilinear weights: positions are 1/32 px on each axis, so the four weights
/// `(32 − fx)(32 − fy)`, `fx(32 − fy)`, `(32 − fx)fy` and `fx·fy` are whole numbers of 1/1024
/// and add up to exactly 1. OpenCV's 8-bit remap uses the same weights times 32
/// (`INTER_REMAP_COEF_BITS` = 15), so both round to the same values. A 16-bit sample times a
/// weight, summed, stays within `u32`.
const COEF_BITS: u32 = 10;

/// One pixel read bilinearly at `(x0, y0)` plus `f` (`fy · 32 + fx`, in 1/32 px) in fixed
/// point; neighbours outside the image count as black, and a pixel read from wholly outside
/// is left as it is (black).
#[inline(always)]
fn linear_pixel<T: Sample, const C: usize>(raw: &Raw<'_, T>, px: &mut [T], xy: [i16; 2], f: u16) {
    let (x0, y0) = (i32::from(xy[0]), i32::from(xy[1]));
    let (fx, fy) = (u32::from(f & 31), u32::from((f >> 5) & 31));
    let wt = [
        (32 - fx) * (32 - fy),
        fx * (32 - fy),
        (32 - fx) * fy,
        fx * fy,
    ];
    let round = |sum: u32| T::from_u32((sum + (1 << (COEF_BITS - 1))) >> COEF_BITS);
    let inner = (
        (raw.width - 1).max(0) as u32,
        (raw.height - 1).max(0) as u32,
    );
    if (x0 as u32) < inner.0 && (y0 as u32) < inner.1 {
        let k = y0 as usize * raw.stride + x0 as usize * C;
        let (Some(top), Some(bottom)) = (
            raw.data.get(k..k + 2 * C),
            raw.data.get(k + raw.stride..k + raw.stride + 2 * C),
        ) else {
            return;
        };
        for ch in 0..C {
            px[ch] = round(
                top[ch].to_u32() * wt[0]
                    + top[C + ch].to_u32() * wt[1]
                    + bottom[ch].to_u32() * wt[2]
                    + bottom[C + ch].to_u32() * wt[3],
            );
        }
    } else if x0 >= -1 && y0 >= -1 && x0 < raw.width && y0 < raw.height {
        let at = |x: i32, y: i32, ch: usize| -> u32 {
            if x < 0 || y < 0 || x >= raw.width || y >= raw.height {
                0
            } else {
                raw.data
                    .get(y as usize * raw.stride + x as usize * C + ch)
                    .map_or(0, |v| v.to_u32())
            }
        };
        for (ch, v) in px.iter_mut().enumerate() {
            *v = round(
                at(x0, y0, ch) * wt[0]
                    + at(x0 + 1, y0, ch) * wt[1]
                    + at(x0, y0 + 1, ch) * wt[2]
                    + at(x0 + 1, y0 + 1, ch) * wt[3],
            );
        }
    }
}

/// [`linear_pixel`] for a row of 16-bit grey, 8 pixels at a time with AVX2 where all 8 read
/// from inside the image: their neighbour pairs gathered as 32-bit words, the horizontal step
/// as one multiply-add of 16-bit pairs (the samples offset by 32 768 to be signed), the
/// vertical one in 32 bits. The same sums as [`linear_pixel`], so the same values.
///
/// # Safety
/// The CPU must have AVX2; `raw` is one channel with `stride` = `width` < 32 768 and at least
/// `width × height` samples.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn linear_grey_avx2(raw: &Raw<'_, u16>, xy: &[[i16; 2]], frac: &[u16], out: &mut [u16]) {
    use std::arch::x86_64::*;
    let n = out.len().min(xy.len()).min(frac.len());
    let (lim_x, lim_y) = (
        _mm256_set1_epi32(raw.width - 1),
        _mm256_set1_epi32(raw.height - 1),
    );
    let minus_one = _mm256_set1_epi32(-1);
    // (x, y) as a pair of i16 times (1, stride): the sample's index.
    let to_index = _mm256_set1_epi32(((raw.stride as i32) << 16) | 1);
    let next_row = _mm256_set1_epi32(raw.stride as i32);
    let flip = _mm256_set1_epi32(0x8000_8000_u32 as i32);
    let unflip = _mm256_set1_epi32(32_768 * 32);
    let (fx_mask, thirty_two, half) = (
        _mm256_set1_epi32(31),
        _mm256_set1_epi32(32),
        _mm256_set1_epi32(1 << (COEF_BITS - 1)),
    );
    let base = raw.data.as_ptr().cast::<i32>();
    let mut i = 0;
    while i + 8 <= n {
        // SAFETY: i + 8 ≤ n ≤ xy.len(), frac.len(), out.len().
        let v = unsafe { _mm256_loadu_si256(xy.as_ptr().add(i).cast()) };
        let x = _mm256_srai_epi32::<16>(_mm256_slli_epi32::<16>(v));
        let y = _mm256_srai_epi32::<16>(v);
        let inside = _mm256_and_si256(
            _mm256_and_si256(
                _mm256_cmpgt_epi32(lim_x, x),
                _mm256_cmpgt_epi32(x, minus_one),
            ),
            _mm256_and_si256(
                _mm256_cmpgt_epi32(lim_y, y),
                _mm256_cmpgt_epi32(y, minus_one),
            ),
        );
        if _mm256_movemask_epi8(inside) != -1 {
            for j in i..i + 8 {
                linear_pixel::<u16, 1>(raw, &mut out[j..j + 1], xy[j], frac[j]);
            }
            i += 8;
            continue;
        }
        let index = _mm256_madd_epi16(v, to_index);
        // SAFETY: every pixel is inside, 0 ≤ x < width − 1 and 0 ≤ y < height − 1, so the
        // words read (samples index, index + 1 and index + stride, index + stride + 1) lie
        // within the `width × height` samples; `gather` reads unaligned words.
        let (top, bottom) = unsafe {
            (
                _mm256_i32gather_epi32::<2>(base, index),
                _mm256_i32gather_epi32::<2>(base, _mm256_add_epi32(index, next_row)),
            )
        };
        let f = _mm256_cvtepu16_epi32(unsafe { _mm_loadu_si128(frac.as_ptr().add(i).cast()) });
        let fx = _mm256_and_si256(f, fx_mask);
        let fy = _mm256_and_si256(_mm256_srli_epi32::<5>(f), fx_mask);
        let wx = _mm256_or_si256(
            _mm256_sub_epi32(thirty_two, fx),
            _mm256_slli_epi32::<16>(fx),
        );
        let t = _mm256_add_epi32(_mm256_madd_epi16(_mm256_xor_si256(top, flip), wx), unflip);
        let b = _mm256_add_epi32(
            _mm256_madd_epi16(_mm256_xor_si256(bottom, flip), wx),
            unflip,
        );
        let sum = _mm256_add_epi32(
            _mm256_slli_epi32::<5>(t),
            _mm256_mullo_epi32(_mm256_sub_epi32(b, t), fy),
        );
        let r = _mm256_srli_epi32::<{ COEF_BITS as i32 }>(_mm256_add_epi32(sum, half));
        let packed = _mm256_permute4x64_epi64::<0b1000>(_mm256_packus_epi32(r, r));
        // SAFETY: i + 8 ≤ out.len().
        unsafe {
            _mm_storeu_si128(
                out.as_mut_ptr().add(i).cast(),
                _mm256_castsi256_si128(packed),
            )
        };
        i += 8;
    }
    for j in i..n {
        linear_pixel::<u16, 1>(raw, &mut out[j..j + 1], xy[j], frac[j]);
    }
}

/// The bicubic weights of each of the 32 positions between two pixels.
static CUBIC: std::sync::LazyLock<Vec<[f32; 4]>> =
    std::sync::LazyLock::new(|| (0..32).map(|f| cubic_weights(f as f32 / STEPS)).collect());

/// `source` read through `map` into an image of the map's size, with the same channels (1 to
/// 4); pixels read from outside the raw image are black.
pub fn remap<T: Sample>(source: RawImage<'_, T>, map: &Map, how: Interpolation) -> Vec<T> {
    remap_fixed(source, &Fixed::new(map), how)
}

/// [`remap`] through a map already in fixed point.
pub fn remap_fixed<T: Sample>(source: RawImage<'_, T>, map: &Fixed, how: Interpolation) -> Vec<T> {
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
    source: RawImage<'_, T>,
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
    let cubic = &*CUBIC;
    // Bands of rows, so that a thread's task is worth handing out.
    let band = (16_384 / w).clamp(1, 64);
    out.par_chunks_mut(w * C * band)
        .enumerate()
        .flat_map_iter(|(b, lines)| {
            lines
                .chunks_mut(w * C)
                .enumerate()
                .map(move |(i, line)| (b * band + i, line))
        })
        .for_each(|(row, line)| {
            let xys = &map.xy[row * w..(row + 1) * w];
            let fracs = &map.frac[row * w..(row + 1) * w];
            match how {
                Interpolation::Nearest => {
                    for ((px, &[x0, y0]), &f) in line.chunks_exact_mut(C).zip(xys).zip(fracs) {
                        let x = i32::from(x0) + i32::from(f & 31 >= 16);
                        let y = i32::from(y0) + i32::from(f >> 5 >= 16);
                        if x >= 0 && y >= 0 && x < sw && y < sh {
                            let k = y as usize * stride + x as usize * C;
                            px.copy_from_slice(&data[k..k + C]);
                        }
                    }
                }
                Interpolation::Linear => {
                    if C == 1
                        && T::linear_grey_row(data, (source.width, source.height), xys, fracs, line)
                    {
                        return;
                    }
                    let raw = Raw {
                        data,
                        stride,
                        width: sw,
                        height: sh,
                    };
                    for ((px, &xy), &f) in line.chunks_exact_mut(C).zip(xys).zip(fracs) {
                        linear_pixel::<T, C>(&raw, px, xy, f);
                    }
                }
                Interpolation::Cubic => {
                    for ((px, &[x0, y0]), &f) in line.chunks_exact_mut(C).zip(xys).zip(fracs) {
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
        let src = RawImage {
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
            RawImage {
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
            RawImage {
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

    /// Bilinear 16-bit grey, 8 pixels at a time with AVX2 or one at a time without, equals
    /// the bilinear mean worked out in `f64` (outside neighbours black, rounded to the nearest)
    /// at every pixel of a map that reads inside, across the borders and wholly outside, for
    /// rows whose length is not a multiple of 8.
    #[test]
    fn vectorised_linear_equals_the_definition() {
        let (sw, sh) = (37usize, 23usize);
        let data: Vec<u16> = (0..sw * sh)
            .map(|i| ((i as u64 * 2_654_435_761) % 65_536) as u16)
            .collect();
        let (w, h) = (45u32, 29u32);
        let mut map = shift_map(w, h, 0.0, 0.0);
        for (i, (x, y)) in map.x.iter_mut().zip(map.y.iter_mut()).enumerate() {
            let (col, row) = ((i % w as usize) as f32, (i / w as usize) as f32);
            let k = i as f32;
            if row < 15.0 {
                // Inside, as a rectification map reads most of a frame: whole runs of 8.
                *x = col * 0.75 + 0.4 + (i % 32) as f32 / 32.0;
                *y = row * 1.2 + 0.3 + (i % 7) as f32 / 32.0;
            } else {
                // From −2.5 to past the far side, at every 1/32 step.
                *x = (k * 0.871).rem_euclid(sw as f32 + 4.0) - 2.5 + (i % 32) as f32 / 32.0;
                *y = (k * 0.377).rem_euclid(sh as f32 + 4.0) - 2.5 + (i % 29) as f32 / 32.0;
            }
        }
        let at = |x: i64, y: i64| -> f64 {
            if x < 0 || y < 0 || x >= sw as i64 || y >= sh as i64 {
                0.0
            } else {
                f64::from(data[y as usize * sw + x as usize])
            }
        };
        let expected: Vec<u16> = map
            .x
            .iter()
            .zip(&map.y)
            .map(|(&x, &y)| {
                let (xs, ys) = (steps(x), steps(y));
                let (x0, y0) = (i64::from(xs >> 5), i64::from(ys >> 5));
                if x0 < -1 || y0 < -1 || x0 >= sw as i64 || y0 >= sh as i64 {
                    return 0;
                }
                let (fx, fy) = (f64::from(xs & 31) / 32.0, f64::from(ys & 31) / 32.0);
                let v = at(x0, y0) * (1.0 - fx) * (1.0 - fy)
                    + at(x0 + 1, y0) * fx * (1.0 - fy)
                    + at(x0, y0 + 1) * (1.0 - fx) * fy
                    + at(x0 + 1, y0 + 1) * fx * fy;
                (v + 0.5).floor() as u16
            })
            .collect();
        let source = RawImage {
            width: sw,
            height: sh,
            channels: 1,
            data: &data,
        };
        for simd in [false, true] {
            crate::vision::simd::use_simd(simd);
            let got = remap(source, &map, Interpolation::Linear);
            for (i, (g, e)) in got.iter().zip(&expected).enumerate() {
                assert_eq!(g, e, "SIMD {simd}, pixel {i}");
            }
        }
    }
}
