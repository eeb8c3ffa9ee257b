//! The census transform: each pixel becomes a 62-bit signature of which of its 9 × 7
//! neighbours are darker than it, so that matching compares local structure (Hamming distance)
//! instead of brightness, and a gain or offset between the two cameras changes nothing.
//!
//! Every bit compares a neighbour with the same centre value, so noise on the centre pixel
//! flips many bits at once; where the texture is no stronger than the noise, the signature is
//! mostly noise. The centre is therefore the pixel through Lee's local-statistics filter (Lee,
//! "Digital image enhancement and noise filtering by use of local statistics", 1980): its
//! 3 × 3 mean plus `max(0, 1 − σ²/v)` of its difference from that mean, where `v` is the 3 × 3
//! variance and `σ` [`NOISE_SCALE`] times the image's noise, estimated after Immerkær's method
//! with a median ([`noise_sigma`]). Where the structure is well above the noise the
//! centre is the pixel itself; where it is not, the mean of nine. A gain scales `σ` and `v`
//! alike and an offset changes neither, so the signatures stay invariant to both.
//!
//! The window's samples are `stride` pixels apart ([`Texture::stride`]): 1 for an image sharp at its
//! pixels, more for one that is smooth over several (an upscale, a digital zoom, soft optics),
//! where neighbours one pixel apart all lie on the same smooth ramp and the signature says little.

use rayon::prelude::*;

use super::Gray;

/// Width of the census window (odd).
pub const WIDTH: usize = 9;
/// Height of the census window (odd).
pub const HEIGHT: usize = 7;
/// Bits in a signature: every pixel of the window but the centre.
pub const BITS: u32 = (WIDTH * HEIGHT - 1) as u32;

/// The local variance below which a centre counts as noise, in units of the estimated noise
/// variance, is `NOISE_SCALE²`: chosen on Motorcycle (clean, with a gain change, with σ = 4
/// noise), a rendered scene at a fifth and a tenth of its contrast under σ = 3 noise, and
/// Motorcycle made raw and rectified (`scripts/evaluate/rectification`). From 1.5 to 3.0 bad-1.0 moved by
/// at most 0.15 points on each but the fifth-contrast scene (1.5 to 1.85 %).
pub const NOISE_SCALE: f32 = 2.0;

/// The most pixels between the window's samples.
pub const MAX_STRIDE: usize = 4;

/// The census signature of every pixel, row-major, with the image's own noise estimate
/// ([`noise_sigma`]) and its samples one pixel apart. Pixels past the border repeat the border.
pub fn transform(image: &Gray) -> Vec<u64> {
    transform_with(image, noise_sigma(image), 1).0
}

/// [`transform`], given the standard deviation of the image's noise (16-bit levels) and the
/// pixels between the window's samples (`stride`, 1 to [`MAX_STRIDE`]), so that a crop of an
/// image is transformed as the whole image is; with the centres the signatures compared
/// against: the image through Lee's filter, its structure without its noise.
pub fn transform_with(image: &Gray, sigma: f32, stride: usize) -> (Vec<u64>, Gray) {
    let (signatures, centres) = transform_rows(image, sigma, stride, 0..image.height);
    (signatures, Gray::new(image.width, image.height, centres))
}

/// [`transform_with`] over the image's rows `rows` alone, exactly as the whole image's
/// transform gives them (the rows around them read from the image, its border repeated):
/// their signatures and their centres, row-major. The matcher transforms each stripe's rows
/// as it matches them, so that no image's signatures are held whole; on the calling thread
/// alone, since the stripes already run side by side (a thread waiting inside a stripe would
/// take up another stripe, and hold its memory too).
pub fn transform_rows(
    image: &Gray,
    sigma: f32,
    stride: usize,
    rows: std::ops::Range<usize>,
) -> (Vec<u64>, Vec<u16>) {
    let (w, h) = (image.width, image.height);
    let rows = rows.start.min(h)..rows.end.min(h);
    let n = rows.len();
    if w == 0 || n == 0 {
        return (Vec::new(), Vec::new());
    }
    let stride = stride.clamp(1, MAX_STRIDE);
    let (rx, ry) = (WIDTH / 2 * stride, HEIGHT / 2 * stride);
    // The rows' neighbourhood with the image's border repeated, so that the inner loop never
    // clamps.
    let pw = w + 2 * rx;
    let mut padded = vec![0u16; pw * (n + 2 * ry)];
    padded.chunks_mut(pw).enumerate().for_each(|(py, row)| {
        let y = (rows.start + py).saturating_sub(ry).min(h - 1);
        let src = &image.data[y * w..(y + 1) * w];
        for (px, out) in row.iter_mut().enumerate() {
            *out = src[px.saturating_sub(rx).min(w - 1)];
        }
    });
    let noise = NOISE_SCALE * sigma;
    let mut centres = vec![0u16; w * n];
    centres.chunks_mut(w).enumerate().for_each(|(y, row)| {
        let line = |dy: usize| {
            &padded[(y + ry + dy - 1) * pw + rx - 1..(y + ry + dy - 1) * pw + rx + w + 1]
        };
        lee_row([line(0), line(1), line(2)], noise * noise, row);
    });
    let mut out = vec![0u64; w * n];
    out.chunks_mut(w).enumerate().for_each(|(y, row)| {
        signatures(&padded, &centres[y * w..(y + 1) * w], (pw, stride), y, row);
    });
    (out, centres)
}

/// The standard deviation of an image's noise (16-bit levels), after Immerkær ("Fast noise
/// variance estimation", 1996): the response to the 3 × 3 difference of two Laplacians is blind
/// to planes and smooth shading, and on white noise of σ it is normal with a standard
/// deviation of 6σ. Immerkær averages its absolute value, which texture and edges inflate
/// (2.5 grey levels on Motorcycle); the median is taken here instead (`0.6745 · 6σ` on noise;
/// 1.2 on Motorcycle, 2.0 on a faint rendered texture whose grey levels carry σ ≈ 2 of added
/// noise), as Donoho's wavelet estimate takes the median of its finest detail.
/// 0 for an image smaller than 3 × 3.
pub fn noise_sigma(image: &Gray) -> f32 {
    // Bins 16 levels of response wide (a sixteenth of an 8-bit grey level), up to the
    // largest response (16 · 65535).
    const SHIFT: u32 = 4;
    const BINS: usize = ((16 * 65535) >> SHIFT) + 1;
    let (w, h) = (image.width, image.height);
    if w < 3 || h < 3 {
        return 0.0;
    }
    // One histogram a block of rows, a block a thread, added into one.
    let inner = 1..h - 1;
    let per = inner.len().div_ceil(rayon::current_num_threads().max(1));
    let histogram = inner
        .step_by(per)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|first| {
            let mut counts = vec![0u32; BINS];
            for y in first..(first + per).min(h - 1) {
                let row = |dy: usize| &image.data[(y + dy - 1) * w..(y + dy) * w];
                let (a, b, c) = (row(0), row(1), row(2));
                for x in 1..w - 1 {
                    let at = |r: &[u16], dx: usize| i32::from(r[x + dx - 1]);
                    let corners = at(a, 0) + at(a, 2) + at(c, 0) + at(c, 2);
                    let edges = at(a, 1) + at(b, 0) + at(b, 2) + at(c, 1);
                    let response = (corners - 2 * edges + 4 * at(b, 1)).unsigned_abs();
                    counts[(response >> SHIFT) as usize] += 1;
                }
            }
            counts
        })
        .reduce_with(|mut sum, counts| {
            sum.iter_mut().zip(&counts).for_each(|(s, c)| *s += c);
            sum
        })
        .unwrap_or_default();
    let half = ((w - 2) * (h - 2)) as f64 / 2.0;
    let mut below = 0f64;
    for (bin, &n) in histogram.iter().enumerate() {
        let n = f64::from(n);
        if n > 0.0 && below + n >= half {
            // Linear within the bin.
            let median = (bin as f64 + (half - below) / n) * f64::from(1u32 << SHIFT);
            return (median / (6.0 * 0.6745)) as f32;
        }
        below += n;
    }
    0.0
}

/// Lags (pixels) at which [`texture`] measures the images' second differences: every `s` and
/// `2s` for `s` up to [`MAX_STRIDE`].
const LAGS: [usize; 6] = [1, 2, 3, 4, 6, 8];

/// How many times the variance of an image's second differences must grow as their lag
/// doubles for the image to count as smooth at that lag. Where an image is smooth (twice
/// differentiable) the second difference `I(x − s) − 2 I(x) + I(x + s)` grows as `s²`, so its
/// variance grows 16 times; on rough texture, which natural images are at their own scale
/// (fractional Brownian, of Hurst exponent `H` below 1), it grows as `s^H`, less than 4 times.
/// 4 is the boundary between the two. Linear shading has no second difference, so it cannot
/// pass for smoothness. Measured on Motorcycle: 3.43 from lag 1 to 2 at its own size; upscaled
/// 4 ×, 10.41, 8.29, 5.77 and 4.14 from lags 1, 2, 3 and 4.
const SMOOTH_GROWTH: f64 = 4.0;

/// The share of the noise's variance below which a pair's texture is faint
/// ([`Texture::faint`]). The ratio is 0.04 on the tenth of the rendered unseen scene's
/// contrast under noise σ 3 and 0.03 on the tenth of the layered test scene's (where matching
/// coarse to fine takes bad-1.0 from 9.36 to 7.65 % and from 17.9 to 16.4 %), against 0.14 on
/// the unseen scene's fifth and 0.18 on the layered scene's fifth (1.51 → 1.67 % and no
/// change: not faint), 0.52 on the layered scene and 2.9 on the unseen one at full contrast
/// under the same noise, 5.2 on Motorcycle with noise σ 4 (13.33 → 13.80 % coarse to fine),
/// 15–62 on clean pairs.
pub const FAINT: f64 = 0.1;

/// What a pair's texture calls for: the census's [`Texture::stride`], and whether the pair is
/// [`Texture::faint`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Texture {
    /// The pixels between the census window's samples: the largest lag `s` (up to
    /// [`MAX_STRIDE`]) such that the pair is smooth at every lag up to `s`: the variance of its
    /// second differences that far apart (along rows and columns, less the `6σ²` that the noise
    /// `sigmas` adds at every lag) grows at least [`SMOOTH_GROWTH`] times from that lag to twice
    /// it. 1 when it is smooth at no lag, or too small to tell.
    ///
    /// Measured on Motorcycle (`examples/tune`, bad-1.0 %): at its own size the rule gives 1;
    /// upscaled 2 × it gives 2 (12.30 → 12.70 %, the one pair it did not help); 3 × gives 3
    /// (20.79 → 18.59 %); 4 × gives 4 (30.96 → 25.53 %), each the best stride there but the first.
    pub stride: usize,
    /// The texture is far weaker than the noise at one pixel's scale: the variance of the
    /// pair's second differences one pixel apart, less the noise's (`6σ²` an image and
    /// direction), is at most [`FAINT`] of the noise's.
    pub faint: bool,
    /// The variance of the pair's second differences one pixel apart less the noise's, over
    /// the noise's: how far its texture stands above its noise at one pixel's scale (infinite
    /// without noise, 0 when too small to tell). Faint is a clarity of at most [`FAINT`].
    pub clarity: f64,
}

/// The pair's [`Texture`], from the noise `sigmas` each image carries; a pair too small to
/// tell has stride 1 and is not faint, and so is a pair without noise.
pub fn texture(left: &Gray, right: &Gray, sigmas: (f32, f32)) -> Texture {
    let plain = Texture {
        stride: 1,
        faint: false,
        clarity: 0.0,
    };
    let reach = 2 * LAGS[LAGS.len() - 1];
    if [left, right]
        .iter()
        .any(|i| i.width <= reach || i.height <= reach || i.data.len() != i.width * i.height)
    {
        return plain;
    }
    let (l, r) = rayon::join(|| second_differences(left), || second_differences(right));
    let noise = 6.0 * (f64::from(sigmas.0).powi(2) + f64::from(sigmas.1).powi(2));
    let at = |lag: usize| {
        let i = LAGS.iter().position(|&l| l == lag).unwrap_or(0);
        l[i] + r[i] - noise
    };
    let mut stride = 1;
    for s in 1..=MAX_STRIDE {
        let (near, far) = (at(s), at(2 * s));
        if near <= 0.0 || far < SMOOTH_GROWTH * near {
            break;
        }
        stride = s;
    }
    let clarity = if noise > 0.0 {
        at(1).max(0.0) / noise
    } else {
        f64::INFINITY
    };
    Texture {
        stride,
        faint: noise > 0.0 && at(1) <= FAINT * noise,
        clarity,
    }
}

/// The mean square (16-bit levels) of an image's second differences `I(x − s) − 2 I(x) +
/// I(x + s)` for each `s` of [`LAGS`], along rows and along columns, over every fourth row;
/// computed on the levels' top 12 bits, so that each square fits a `u32` and the loop runs on
/// whole vectors of them.
fn second_differences(image: &Gray) -> [f64; LAGS.len()] {
    let (w, h) = (image.width, image.height);
    let reach = 2 * LAGS[LAGS.len() - 1];
    let rows: Vec<usize> = (0..h - reach).step_by(4).collect();
    let (sums, count) = rows
        .par_iter()
        .map(|&y| {
            let row = |dy: usize| &image.data[(y + dy) * w..(y + dy + 1) * w];
            let mut sums = [0f64; LAGS.len()];
            for (sum, &lag) in sums.iter_mut().zip(&LAGS) {
                let acc = lag_squares((row(0), row(lag), row(2 * lag)), lag, w - reach);
                *sum = acc as f64 * f64::from(1u32 << (2 * LAG_DROP));
            }
            (sums, 2 * (w - reach))
        })
        .reduce(
            || ([0f64; LAGS.len()], 0usize),
            |(mut a, n), (b, m)| {
                a.iter_mut().zip(&b).for_each(|(a, b)| *a += b);
                (a, n + m)
            },
        );
    let count = count.max(1) as f64;
    sums.map(|s| s / count)
}

/// The low bits of each level [`lag_squares`] drops.
const LAG_DROP: u32 = 4;

crate::dispatch! {
    /// The sum over `x < n` of the squared second differences at `lag` along the row `at`
    /// (around its pixel `x + lag`) and across the rows `above`, `at` and `below`, on the levels'
    /// top 12 bits ([`second_differences`]'s terms for one row and lag).
    fn lag_squares(rows: (&[u16], &[u16], &[u16]), lag: usize, n: usize) -> u64 {
        let (above, at, below) = rows;
        let (above, below) = (&above[lag..lag + n], &below[lag..lag + n]);
        let (before, here, after) = (&at[..n], &at[lag..lag + n], &at[2 * lag..2 * lag + n]);
        let level = |v: u16| i32::from(v >> LAG_DROP);
        let mut acc = 0u64;
        for x in 0..n {
            let centre = 2 * level(here[x]);
            let along = level(before[x]) + level(after[x]) - centre;
            let across = level(above[x]) + level(below[x]) - centre;
            // Each at most 2 · 8190², within a u32.
            acc += u64::from((along * along) as u32 + (across * across) as u32);
        }
        acc
    }
}

crate::dispatch! {
    /// One row of census centres by Lee's filter: `lines` are the rows above, at and below,
    /// each with one pixel more on either side than `out`; `noise_var` is the variance below
    /// which the local structure counts as noise.
    fn lee_row(lines: [&[u16]; 3], noise_var: f32, out: &mut [u16]) {
        let w = out.len();
        for (x, c) in out.iter_mut().enumerate() {
            // Sums of the differences from the pixel, which stay small (and exact in f32)
            // where the image is smooth.
            let raw = f32::from(lines[1][x + 1]);
            let (mut s1, mut s2) = (0f32, 0f32);
            for line in &lines {
                for &v in &line[x..x + 3] {
                    let d = f32::from(v) - raw;
                    s1 += d;
                    s2 += d * d;
                }
            }
            let offset = s1 * (1.0 / 9.0);
            let var = (s2 * (1.0 / 9.0) - offset * offset).max(0.0);
            let keep = if var > noise_var { 1.0 - noise_var / var } else { 0.0 };
            // The mean (raw + offset) plus `keep` of the pixel's difference from it (−offset).
            *c = level_of(raw + offset * (1.0 - keep));
        }
        debug_assert_eq!(lines[1].len(), w + 2);
    }
}

crate::dispatch! {
    /// The signatures of row `y` against its `centre` values, a block of [`BLOCK`] pixels at
    /// a time over every window offset, so that the comparisons run on whole vectors of pixels
    /// and the bits stay in registers; `padded` is the image with `stride` times the window's
    /// half-size repeated around it, `shape` its width and the stride.
    /// The bits are gathered 16 to a `u16` a pixel (four times the lanes of a `u64`), then
    /// joined.
    wide fn signatures(
        padded: &[u16],
        centre: &[u16],
        shape: (usize, usize),
        y: usize,
        row: &mut [u64],
    ) {
        let (pw, stride) = shape;
        let (rx, ry) = (WIDTH / 2, HEIGHT / 2);
        let w = row.len();
        // Where each window offset's line starts in `padded`, in the bits' order (the first
        // offset's bit is the highest).
        let starts: Vec<usize> = (0..HEIGHT)
            .flat_map(|wy| (0..WIDTH).map(move |wx| (wy, wx)))
            .filter(|&(wy, wx)| (wy, wx) != (ry, rx))
            .map(|(wy, wx)| (y + wy * stride) * pw + wx * stride)
            .collect();
        let groups: Vec<&[usize]> = starts.chunks(16).collect();
        // A block of pixels at a time, its bits gathered 16 offsets to a `u16` and held in
        // registers over the offsets (rather than each offset's bits stored across the row and
        // loaded again), then joined.
        let mut x0 = 0;
        while x0 + BLOCK <= w {
            let centre: &[u16; BLOCK] = centre[x0..x0 + BLOCK].try_into().expect("a block");
            let out = &mut row[x0..x0 + BLOCK];
            out.fill(0);
            let mut done = 0;
            for group in &groups {
                done += group.len();
                let bits = gather(padded, group, x0, centre);
                let shift = BITS as usize - done;
                for (sig, &b) in out.iter_mut().zip(&bits) {
                    *sig |= u64::from(b) << shift;
                }
            }
            x0 += BLOCK;
        }
        // The row's last pixels, one at a time.
        for (x, sig) in row.iter_mut().enumerate().skip(x0) {
            *sig = starts
                .iter()
                .fold(0u64, |b, &at| (b << 1) | u64::from(padded[at + x] < centre[x]));
        }
    }
}

/// `value` rounded (half away from zero) and clamped to a 16-bit grey level, as
/// `value.round().clamp(0.0, 65535.0) as u16` gives it: the whole number read from the mantissa
/// of itself plus 2^23 (exact there), so that [`lee_row`]'s builds convert on whole registers,
/// where a float's saturating cast goes one lane at a time. NaN gives 0, as the cast does.
#[inline(always)]
fn level_of(value: f32) -> u16 {
    let level = value.round().clamp(0.0, 65535.0);
    ((level + 8_388_608.0).to_bits() & 0xffff) as u16
}

/// The pixels [`signatures`] gathers at once: an AVX-512 register of `u16`.
const BLOCK: usize = 32;

/// The bits of the block of pixels from `x0` (their `centre` values) for at most 16 window
/// offsets whose lines start at `starts` in `padded`, the first offset's in the highest bit.
/// Inlined into [`signatures`]' builds, so that it runs on their vector widths (a closure
/// would not be).
#[inline(always)]
fn gather(padded: &[u16], starts: &[usize], x0: usize, centre: &[u16; BLOCK]) -> [u16; BLOCK] {
    debug_assert!(starts.len() <= 16);
    let mut bits = [0u16; BLOCK];
    for &at in starts {
        let line: &[u16; BLOCK] = padded[at + x0..at + x0 + BLOCK]
            .try_into()
            .expect("a block");
        for k in 0..BLOCK {
            bits[k] = (bits[k] << 1) | u16::from(line[k] < centre[k]);
        }
    }
    bits
}

/// The most a blank window's grey levels differ (16-bit levels): one level of 255.
pub const BLANK_LEVELS: u16 = 257;

/// The pixels whose census window tells them from nothing (their match would tie at every
/// disparity): a clipped sky, a board's square burnt out to white, the black beyond a fisheye's
/// image circle. A window is blank when every grey level in it (its [`WIDTH`] × [`HEIGHT`]
/// neighbourhood, the image's border repeated) is within [`BLANK_LEVELS`] of every other; its
/// signature is the same wherever the other image is as blank, so the costs tie and the
/// penalties carry a value in that looks sharp. So is a pixel at the floor of its window (none
/// of it darker, so its signature is zero) whose 3 × 3 and whose row's [`WIDTH`] are blank: the
/// dark rows beside a black region's edge, whose zero signature every blank pixel along the
/// other image's row shares. Answered row-major, one a pixel.
pub fn blank(image: &Gray) -> Vec<bool> {
    let (w, h) = (image.width, image.height);
    if w == 0 || h == 0 {
        return Vec::new();
    }
    let (rx, ry) = (WIDTH / 2, HEIGHT / 2);
    let span = |line: &[u16]| {
        let least = line.iter().copied().min().unwrap_or(0);
        (least, line.iter().copied().max().unwrap_or(least))
    };
    // Each row's least and greatest level over the window's width and over 3, then down the
    // window's height and down 3.
    let mut spans = vec![[(0u16, 0u16); 2]; w * h];
    spans
        .par_chunks_mut(w)
        .zip(image.data.par_chunks(w))
        .for_each(|(out, row)| {
            for (x, o) in out.iter_mut().enumerate() {
                let near = |r: usize| &row[x.saturating_sub(r)..(x + r + 1).min(w)];
                *o = [span(near(rx)), span(near(1))];
            }
        });
    let mut blank = vec![false; w * h];
    blank.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let down = |x: usize, r: usize, k: usize| {
            (y.saturating_sub(r)..(y + r + 1).min(h)).fold((u16::MAX, 0u16), |(l, g), v| {
                let (a, b) = spans[v * w + x][k];
                (l.min(a), g.max(b))
            })
        };
        for (x, b) in out.iter_mut().enumerate() {
            let (least, greatest) = down(x, ry, 0);
            let centre = image.data[y * w + x];
            let within = |(l, g): (u16, u16)| g - l <= BLANK_LEVELS;
            *b = within((least, greatest))
                || (least.saturating_add(BLANK_LEVELS) >= centre
                    && within(spans[y * w + x][0])
                    && within(down(x, 1, 1)));
        }
    });
    blank
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A band of rows is transformed exactly as the whole image transforms those rows, at the
    /// top, inside and at the bottom, at one pixel's stride and at three, so that a stripe
    /// making its own signatures matches as the whole image would.
    #[test]
    fn a_band_of_rows_is_the_whole_images_rows() {
        let (w, h) = (37, 29);
        let data = (0..w * h)
            .map(|i| ((i * 7919 + (i / w) * 104_729) % 60_000) as u16)
            .collect();
        let image = Gray::new(w, h, data);
        for stride in [1, 3] {
            let (whole, centres) = transform_with(&image, 300.0, stride);
            for rows in [0..5, 3..20, 11..29, 0..29, 28..29] {
                let (band, band_centres) = transform_rows(&image, 300.0, stride, rows.clone());
                let pixels = rows.start * w..rows.end * w;
                assert_eq!(band, whole[pixels.clone()], "{rows:?} at {stride}");
                assert_eq!(band_centres, centres.data[pixels], "{rows:?} at {stride}");
            }
        }
        assert_eq!(transform_rows(&image, 300.0, 1, 30..40), (vec![], vec![]));
    }

    /// The grey level read from the mantissa is the rounded, clamped cast's, at every level
    /// and half-way between, below zero, past 16 bits, at the infinities and for NaN.
    #[test]
    fn a_level_from_the_mantissa_is_the_casts() {
        let cast = |v: f32| v.round().clamp(0.0, 65535.0) as u16;
        let values = (0..=65_536u32)
            .flat_map(|l| [l as f32, l as f32 + 0.5, l as f32 - 0.5, l as f32 + 0.49])
            .chain([
                -1e9,
                -3.7,
                -0.5,
                -0.0,
                65_535.6,
                70_000.0,
                1e12,
                f32::INFINITY,
                f32::NEG_INFINITY,
                f32::NAN,
            ]);
        for v in values {
            assert_eq!(level_of(v), cast(v), "{v}");
        }
    }

    /// A window within one grey level is blank; one with a single pixel two levels off, or a
    /// faint noise over it, is not; the window reaches the border repeated, not past it.
    #[test]
    fn blank_windows_are_those_within_one_level() {
        let mut img = image(40, 30, 0.0, |_, _| 100.0);
        // Levels 100 and 101 (of 255) alike: still blank.
        img.data[5 * 40 + 5] = 101 * 257;
        // One pixel two levels down at (30, 15): every window holding it is not blank (their
        // centres have a darker neighbour).
        img.data[15 * 40 + 30] = 98 * 257;
        let b = blank(&img);
        assert!(b[5 * 40 + 5] && b[0]);
        assert!(!b[15 * 40 + 30] && !b[(15 + 3) * 40 + 30 + 4] && !b[(15 - 3) * 40 + 30 - 4]);
        assert!(b[(15 + 4) * 40 + 30] && b[15 * 40 + 30 - 5]);
        let noisy = image(40, 30, 2.0, |_, _| 100.0);
        assert!(blank(&noisy).iter().all(|&b| !b));
        // Texture above black: the black rows two or more below the edge are blank (nothing
        // darker, their 3 × 3 and row blank), the one beside it and the texture are not; a
        // dark spot narrower than the window on texture is not blank at its centre.
        let mut img = image(40, 30, 30.0, |_, _| 120.0);
        for (i, v) in img.data.iter_mut().enumerate() {
            let (x, y) = (i % 40, i / 40);
            if y >= 15 || ((5..10).contains(&x) && (5..10).contains(&y)) {
                *v = 0;
            }
        }
        let b = blank(&img);
        assert!(b[17 * 40 + 20] && b[16 * 40 + 20] && !b[15 * 40 + 20] && !b[14 * 40 + 20]);
        assert!(!b[7 * 40 + 7]);
    }

    /// A flat image has no structure: every signature is zero.
    #[test]
    fn flat_image_has_empty_signatures() {
        let image = Gray::new(12, 10, vec![500; 120]);
        assert!(transform(&image).iter().all(|&s| s == 0));
    }

    /// A pixel brighter than all its neighbours sets all 62 bits; its neighbours see it as
    /// not darker, so their bit for it stays clear.
    #[test]
    fn a_bright_peak_sets_every_bit() {
        let mut data = vec![100u16; 15 * 11];
        data[5 * 15 + 7] = 200;
        let sig = transform(&Gray::new(15, 11, data));
        assert_eq!(sig[5 * 15 + 7].count_ones(), BITS);
        assert_eq!(sig[5 * 15 + 6], 0);
    }

    /// The census as it was before Lee's filter: every neighbour against the raw centre.
    fn raw_centre_census(image: &Gray) -> Vec<u64> {
        raw_centre_census_every(image, 1)
    }

    /// [`raw_centre_census`] with the window's samples `stride` pixels apart.
    fn raw_centre_census_every(image: &Gray, stride: isize) -> Vec<u64> {
        let (w, h) = (image.width, image.height);
        let at = |x: isize, y: isize| {
            let x = x.clamp(0, w as isize - 1) as usize;
            let y = y.clamp(0, h as isize - 1) as usize;
            image.data[y * w + x]
        };
        let (rx, ry) = ((WIDTH / 2) as isize, (HEIGHT / 2) as isize);
        let mut out = Vec::with_capacity(w * h);
        for y in 0..h as isize {
            for x in 0..w as isize {
                let c = at(x, y);
                let mut sig = 0u64;
                for dy in -ry..=ry {
                    for dx in -rx..=rx {
                        if (dx, dy) != (0, 0) {
                            let (sx, sy) = (x + dx * stride, y + dy * stride);
                            sig = (sig << 1) | u64::from(at(sx, sy) < c);
                        }
                    }
                }
                out.push(sig);
            }
        }
        out
    }

    /// A `w × h` image of `f(x, y)` plus Gaussian noise of `sigma` grey levels (8-bit), in
    /// 16-bit levels.
    fn image(w: usize, h: usize, sigma: f32, f: impl Fn(usize, usize) -> f32) -> Gray {
        let mut rng = crate::vision::synthetic::Rng::new(41);
        let data = (0..w * h)
            .map(|i| {
                let v = f(i % w, i / w) + sigma * rng.normal();
                (v.clamp(0.0, 255.0) * 257.0).round() as u16
            })
            .collect();
        Gray::new(w, h, data)
    }

    /// The estimate finds the noise added to a shaded plane within 5 %, and next to no noise
    /// on the plane alone.
    #[test]
    fn noise_estimate_finds_the_noise_added() {
        let ramp = |x: usize, y: usize| 60.0 + 0.3 * x as f32 + 0.2 * y as f32;
        for sigma in [2.0f32, 4.0, 8.0] {
            let found = noise_sigma(&image(200, 150, sigma, ramp)) / 257.0;
            assert!(
                (found / sigma - 1.0).abs() < 0.05,
                "sigma {sigma}: found {found}"
            );
        }
        assert!(noise_sigma(&image(200, 150, 0.0, ramp)) / 257.0 < 0.1);
    }

    /// Without noise every centre is the pixel itself: the signatures are the plain census's.
    /// With noise the same texture's signatures change.
    #[test]
    fn without_noise_the_census_is_the_plain_one() {
        let texture = |x: usize, y: usize| {
            128.0 + 90.0 * ((x as f32 * 0.9).sin() * (y as f32 * 0.7 + 1.0).cos())
        };
        let clean = image(60, 40, 0.0, texture);
        let (signatures, centres) = transform_with(&clean, 0.0, 1);
        assert_eq!(signatures, raw_centre_census(&clean));
        assert_eq!(centres, clean, "no noise: every centre is its pixel");
        assert_ne!(
            transform_with(&clean, 20.0 * 257.0, 1).0,
            raw_centre_census(&clean)
        );
    }

    /// With the samples 2 and 4 pixels apart, each bit compares the neighbour that far away
    /// (the border repeated), as a direct census with that spacing does.
    #[test]
    fn a_stride_spaces_the_samples() {
        let texture = |x: usize, y: usize| {
            128.0 + 90.0 * ((x as f32 * 0.5).sin() * (y as f32 * 0.3 + 1.0).cos())
        };
        let clean = image(50, 37, 0.0, texture);
        for stride in [2, 4] {
            let (signatures, _) = transform_with(&clean, 0.0, stride);
            assert_eq!(signatures, raw_centre_census_every(&clean, stride as isize));
            assert_ne!(signatures, raw_centre_census(&clean));
        }
    }

    /// A `w × h` image of random grey levels on a grid `k` pixels apart, interpolated between
    /// them by Catmull-Rom's cubic: sharp at `k = 1`, smooth over about `k` pixels above.
    fn upscaled(w: usize, h: usize, k: usize, seed: u64) -> Gray {
        let mut rng = crate::vision::synthetic::Rng::new(seed);
        let (gw, gh) = (w / k + 4, h / k + 4);
        let grid: Vec<f32> = (0..gw * gh).map(|_| 40.0 + 170.0 * rng.unit()).collect();
        let weights = crate::vision::synthetic::catmull_rom;
        let data = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let (gx, gy) = (x / k, y / k);
                let wx = weights((x % k) as f32 / k as f32);
                let wy = weights((y % k) as f32 / k as f32);
                let mut v = 0.0;
                for (j, wy) in wy.iter().enumerate() {
                    for (i, wx) in wx.iter().enumerate() {
                        v += wx * wy * grid[(gy + j) * gw + gx + i];
                    }
                }
                (v.clamp(0.0, 255.0) * 257.0).round() as u16
            })
            .collect();
        Gray::new(w, h, data)
    }

    /// A pair sharp at its pixels keeps its samples one pixel apart, and so does the same kind
    /// of texture upscaled 2 × (its second differences grow 5.8 times from lag 1 to 2, then
    /// 1.3 times); upscaled 4 × it spreads them at least 2 apart; an image too small to
    /// measure keeps 1.
    #[test]
    fn the_stride_follows_the_images_smoothness() {
        let stride_of = |k: usize| {
            let (l, r) = (upscaled(240, 160, k, 3), upscaled(240, 160, k, 4));
            texture(&l, &r, (noise_sigma(&l), noise_sigma(&r))).stride
        };
        assert_eq!(stride_of(1), 1);
        assert_eq!(stride_of(2), 1);
        assert!(
            (2..=MAX_STRIDE).contains(&stride_of(4)),
            "4x: {}",
            stride_of(4)
        );
        let tiny = upscaled(8, 8, 4, 5);
        assert_eq!(texture(&tiny, &tiny, (0.0, 0.0)).stride, 1);
    }

    /// Noise on a flat field is faint (there is nothing but noise to match); a sharp texture
    /// under the same noise is not, nor is the field without noise (nothing to weigh the
    /// texture against).
    #[test]
    fn faint_is_texture_far_below_the_noise() {
        let flat = image(120, 90, 4.0, |_, _| 120.0);
        let sigma = noise_sigma(&flat);
        assert!(texture(&flat, &flat, (sigma, sigma)).faint);
        let sharp = image(120, 90, 4.0, |x, y| {
            if (x / 3 + y / 3) % 2 == 0 {
                90.0
            } else {
                150.0
            }
        });
        assert!(!texture(&sharp, &sharp, (sigma, sigma)).faint);
        let clean = image(120, 90, 0.0, |_, _| 120.0);
        assert!(!texture(&clean, &clean, (0.0, 0.0)).faint);
    }

    /// The noise's own share of the variogram is taken out: white noise on a flat field is
    /// sharp at every lag (stride 1), and so is a sharp texture under noise.
    #[test]
    fn noise_is_not_taken_for_smoothness() {
        let flat = image(120, 90, 4.0, |_, _| 120.0);
        let sigma = noise_sigma(&flat);
        assert_eq!(texture(&flat, &flat, (sigma, sigma)).stride, 1);
        let sharp = upscaled(120, 90, 1, 8);
        assert_eq!(texture(&sharp, &sharp, (sigma, sigma)).stride, 1);
    }

    /// On a flat field under noise, the plain census's bits all follow the centre's own noise
    /// (a bright centre sets nearly all 62, a dark one nearly none); with Lee's centre, the
    /// mean of nine there, the counts stay near half, their spread less than half as wide.
    #[test]
    fn noise_on_a_flat_field_does_not_swing_the_signatures() {
        let noisy = image(80, 60, 4.0, |_, _| 120.0);
        let spread = |sigs: &[u64]| {
            let counts: Vec<f32> = sigs.iter().map(|s| s.count_ones() as f32).collect();
            let mean = counts.iter().sum::<f32>() / counts.len() as f32;
            (counts.iter().map(|c| (c - mean).powi(2)).sum::<f32>() / counts.len() as f32).sqrt()
        };
        let (lee, plain) = (
            spread(&transform(&noisy)),
            spread(&raw_centre_census(&noisy)),
        );
        assert!(
            lee < 0.5 * plain,
            "Lee {lee:.1} bits against plain {plain:.1}"
        );
    }
}
