//! Coarse to fine, after tSGM (Rothermel et al., 2012) and Hirschmüller's hierarchical
//! matching: the pair is halved until the range is narrow, matched over its whole range there,
//! and each finer level searches, at each pixel, only a window of a few SIMD registers around
//! what the level above found near it. The cells a pixel costs, and so the time and memory per
//! pixel, then stop growing with the disparity range.
//!
//! A pixel's window spans the least and greatest disparity found in the 5 × 5 coarse pixels
//! around it (holes filled from the row's background first, as occlusions are), doubled and
//! widened by [`MARGIN`], so that both sides of a depth edge are searched; it is at most
//! [`MAX_WINDOW`] cells, centred on the pixel's own coarse disparity when the edge is deeper.

use std::ops::Range;

use super::cost::{self, LANES, Windows};
use super::{Disparity, Gray, filters};

/// Coarser levels are added while the range holds more than this many disparities: the
/// coarsest level searches at most this many (narrowing the range below 64 cost accuracy:
/// Motorcycle's bad-1.0 7.94 → 8.6 at 64 disparities).
pub const NARROW: usize = 64;
/// Up to this many disparities a pair is searched whole at full size, with no coarser level,
/// while that search holds at most [`WHOLE_CELLS`] cells (else up to [`NARROW`]). A window costs more a cell
/// than the whole range does (each pixel reads its neighbours' path costs at its own
/// disparities, and steps in registers of [`LANES`] where the whole range takes 64 lanes at
/// once), and the coarse level's fixed costs weigh most on a small pair. Measured (`tune`,
/// defaults, 2 cores with AVX-512; docs/matcher.md), the whole range against coarse to fine:
/// Motorcycle at quarter size (0.37 MP) searching 80, 32 against 49 ms, bad-1.0 7.85 against
/// 8.34 %; at 1280 × 720 (0.92 MP), 96 in 95 against 104 ms, 128 in 108 against 104 ms
/// (bad-1.0 12.35 against 13.12 %); at 1920 × 1080 (2.07 MP), 96 in 343 against 299 ms, 128
/// in 424 against 296. Past it, the coarsest level stays at [`NARROW`]: coarsest levels of up
/// to 128 answered less of the photographed boards right (their median 68.8 → 66.2 %).
pub const WHOLE: usize = 128;
/// The most cells (pixels × disparities, the range in whole registers) a range up to
/// [`WHOLE`] may hold to be searched whole: where the two ways cost the same, between 1280 ×
/// 720 at 96 (88 M cells, whole 9 % faster) and at 128 (118 M, whole 4 % slower).
pub const WHOLE_CELLS: usize = 96 << 20;
/// How narrow the coarsest level's range is for a pair whose texture is faint (far weaker than
/// its noise at one pixel's scale, [`super::census::Texture::faint`]): each level averages four
/// pixels, halving the noise, while a texture of lower frequencies keeps most of its contrast.
/// The tenth of the rendered unseen scene's contrast under noise σ 3 (`tune`, bad-1.0 / bad-2.0
/// % at 64 disparities): 9.36 / 4.44 matched at its own size, 7.91 / 3.09 from a coarsest
/// level at 32, 7.65 / 2.81 at 16 (OpenCV's best 7.68 / 2.84), 7.65 / 2.81 at 8; the layered
/// test scene at a tenth: 17.9 → 16.4 % (`tests/vision_accuracy.rs`).
pub const FAINT_NARROW: usize = 16;
/// The most cells a pixel's window holds below the coarsest level.
pub const MAX_WINDOW: usize = 48;
/// Disparities searched beyond the coarse neighbourhood's least and greatest, on each side.
pub const MARGIN: f32 = 4.0;
/// Radius, in coarse pixels, of the neighbourhood a window spans.
const RADIUS: usize = 2;
/// The smallest coarse level: narrower or shorter images are not halved again.
const MIN_SIDE: (usize, usize) = (48, 24);

/// How the pyramid is shaped: the widest range searched whole, how narrow the coarsest
/// level's range is, and the windows below it. The tune build's grid tries others
/// ([`super::Params::with_shape`]); every request takes [`Shape::DEFAULT`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shape {
    /// Coarser levels are added while the range holds more than this many disparities.
    pub narrow: usize,
    /// Up to this many, a pair whose search holds at most [`WHOLE_CELLS`] is searched
    /// whole.
    pub whole: usize,
    /// The most cells a pixel's window holds below the coarsest level (a multiple of
    /// [`LANES`]).
    pub window: usize,
}

impl Shape {
    /// Every preset's: the whole range at full size up to [`WHOLE`] (or [`NARROW`]), windows
    /// of up to [`MAX_WINDOW`].
    pub const DEFAULT: Shape = Shape {
        narrow: NARROW,
        whole: WHOLE,
        window: MAX_WINDOW,
    };
}

impl super::Params {
    /// The pyramid matched through ([`Shape::DEFAULT`] unless [`super::Params::with_shape`]
    /// gave another).
    pub fn shape(&self) -> Shape {
        self.shape
    }

    /// These settings matched through another pyramid: the tune build's grid, which measured
    /// the shapes `docs/matcher.md` compares.
    pub fn with_shape(self, shape: Shape) -> super::Params {
        super::Params { shape, ..self }
    }
}

/// How many times to halve a `width × height` pair searching `count` disparities: none up to
/// [`WHOLE`] disparities while the search holds at most [`WHOLE_CELLS`]; else until the range
/// holds at most [`NARROW`] disparities, or [`FAINT_NARROW`] when the pair's texture is
/// `faint`.
pub fn levels(width: usize, height: usize, count: usize, faint: bool) -> usize {
    levels_shaped(width, height, count, faint, Shape::DEFAULT)
}

/// [`levels`] for a pyramid of `shape`: none up to `shape.whole` disparities while the search
/// holds at most [`WHOLE_CELLS`] (unless `faint`); else until the range holds at most `shape.narrow`
/// disparities (or [`FAINT_NARROW`], when that is narrower and the texture `faint`).
pub fn levels_shaped(
    width: usize,
    height: usize,
    count: usize,
    faint: bool,
    shape: Shape,
) -> usize {
    let cells = width
        .saturating_mul(height)
        .saturating_mul(cost::stride(count));
    if !faint && count <= shape.whole && cells <= WHOLE_CELLS {
        return 0;
    }
    let narrow = if faint {
        FAINT_NARROW.min(shape.narrow)
    } else {
        shape.narrow
    };
    let (mut w, mut h, mut c, mut n) = (width, height, count, 0);
    while c > narrow && w / 2 >= MIN_SIDE.0 && h / 2 >= MIN_SIDE.1 {
        (w, h, c, n) = (w.div_ceil(2), h.div_ceil(2), halve_range(0, c).1, n + 1);
    }
    n
}

/// The range `(min, count)` one level up covers: every disparity of `min .. min + count`
/// halved.
pub fn halve_range(min: i32, count: usize) -> (i32, usize) {
    let lo = min.div_euclid(2);
    let hi = (min + count as i32 - 1).div_euclid(2);
    (lo, (hi - lo + 1) as usize)
}

/// The image one level up: each 2 × 2 block averaged (the last row and column repeated when
/// the size is odd).
pub fn halve(image: &Gray) -> Gray {
    let (w, h) = (image.width, image.height);
    let (hw, hh) = (w.div_ceil(2), h.div_ceil(2));
    let mut data = Vec::with_capacity(hw * hh);
    for y in 0..hh {
        let r0 = &image.data[2 * y * w..(2 * y + 1) * w];
        let y1 = (2 * y + 1).min(h - 1);
        let r1 = &image.data[y1 * w..(y1 + 1) * w];
        for x in 0..hw {
            let (x0, x1) = (2 * x, (2 * x + 1).min(w - 1));
            let sum = u32::from(r0[x0]) + u32::from(r0[x1]) + u32::from(r1[x0]) + u32::from(r1[x1]);
            data.push(((sum + 2) / 4) as u16);
        }
    }
    Gray::new(hw, hh, data)
}

/// What a coarser level found, as each finer pixel's search needs it: the least and greatest
/// disparity (in coarse pixels) around each coarse pixel, and the pixel's own.
pub struct Prior {
    width: usize,
    height: usize,
    own: Vec<f32>,
    least: Vec<f32>,
    greatest: Vec<f32>,
    /// The most cells a window holds ([`Shape::window`]).
    cap: usize,
}

impl Prior {
    /// The prior of a coarse map: holes filled from the row's background (a row with no valid
    /// pixel takes the range's smallest disparity, `min`), then the least and greatest over
    /// the [`RADIUS`] neighbourhood; its windows hold at most [`MAX_WINDOW`] cells.
    pub fn new(map: &Disparity, min: i32) -> Prior {
        Prior::shaped(map, min, Shape::DEFAULT)
    }

    /// [`Prior::new`], its windows holding at most `shape.window` cells.
    pub fn shaped(map: &Disparity, min: i32, shape: Shape) -> Prior {
        let (w, h) = (map.width, map.height);
        let mut own = map.data.clone();
        filters::fill(&mut own, w);
        for d in &mut own {
            if d.is_nan() {
                *d = min as f32;
            }
        }
        let least = box_extreme(&own, w, h, f32::min);
        let greatest = box_extreme(&own, w, h, f32::max);
        Prior {
            width: w,
            height: h,
            own,
            least,
            greatest,
            cap: shape.window.max(LANES),
        }
    }

    /// The windows of the finer level's rows `rows` (`width` pixels a row), over its range
    /// `min .. min + count`. A fine pixel's window is its coarse pixel's, so each coarse row's
    /// windows are worked out once and repeated over the 2 × 2 fine pixels it covers.
    pub fn windows(&self, rows: Range<usize>, width: usize, (min, count): (i32, usize)) -> Windows {
        let pixels = rows.len() * width;
        let mut first = Vec::with_capacity(pixels);
        let mut lengths = Vec::with_capacity(pixels);
        let mut coarse = Vec::with_capacity(self.width);
        let mut coarse_y = usize::MAX;
        for y in rows {
            let cy = (y / 2).min(self.height - 1);
            if cy != coarse_y {
                coarse.clear();
                coarse.extend(
                    (cy * self.width..(cy + 1) * self.width).map(|c| self.window(c, (min, count))),
                );
                coarse_y = cy;
            }
            for x in 0..width {
                let (start, len) = coarse[(x / 2).min(self.width - 1)];
                first.push(start);
                lengths.push(len);
            }
        }
        Windows::from_lengths(first, lengths.into_iter())
    }

    /// Coarse pixel `c`'s window over the finer range `min .. min + count`: `(first index,
    /// cells)`.
    fn window(&self, c: usize, range: (i32, usize)) -> (u16, u16) {
        // Indices into the finer range, both at least 0: truncating is the floor, and the
        // ceiling is one more where the truncation lost a fraction.
        let floor = |v: f32| v as usize;
        let ceil = |v: f32| floor(v) + usize::from((floor(v) as f32) < v);
        self.window_rounding(c, range, floor, ceil)
    }

    /// [`Prior::window`] with its floor and ceiling given (the tests give `f32`'s own).
    fn window_rounding(
        &self,
        c: usize,
        (min, count): (i32, usize),
        floor: impl Fn(f32) -> usize,
        ceil: impl Fn(f32) -> usize,
    ) -> (u16, u16) {
        let full = cost::stride(count);
        let cap = self.cap.min(full);
        let last = count as f32 - 1.0;
        let lo = (2.0 * self.least[c] - MARGIN - min as f32).clamp(0.0, last);
        let hi = (2.0 * self.greatest[c] + MARGIN - min as f32).clamp(lo, last);
        let (lo, hi) = (floor(lo), ceil(hi));
        let mut len = (hi - lo + 1).div_ceil(LANES) * LANES;
        let mut start = lo;
        if len > cap {
            len = cap;
            let centre = (2.0 * self.own[c] - min as f32).clamp(0.0, last) as usize;
            start = centre.saturating_sub(cap / 2);
        }
        // Use the whole window inside the padded range.
        start = start.min(full - len);
        (start as u16, len as u16)
    }
}

/// The least (or greatest, by `pick`) value over the `(2·RADIUS + 1)²` box around each pixel,
/// clipped at the borders: one pass along rows, one along columns. `pick` is a function item,
/// compiled inline, where a function pointer was called for every value.
fn box_extreme(
    values: &[f32],
    w: usize,
    h: usize,
    pick: impl Fn(f32, f32) -> f32 + Copy,
) -> Vec<f32> {
    let mut rows = vec![0f32; w * h];
    for y in 0..h {
        let row = &values[y * w..(y + 1) * w];
        for x in 0..w {
            let span = &row[x.saturating_sub(RADIUS)..(x + RADIUS + 1).min(w)];
            rows[y * w + x] = span.iter().copied().reduce(pick).unwrap_or(f32::NAN);
        }
    }
    let mut out = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            out[y * w + x] = (y.saturating_sub(RADIUS)..(y + RADIUS + 1).min(h))
                .map(|yy| rows[yy * w + x])
                .reduce(pick)
                .unwrap_or(f32::NAN);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Up to WHOLE disparities a pair whose search holds at most WHOLE_CELLS is not halved;
    /// else the range is halved until it holds at most NARROW disparities, or the image gets
    /// small.
    #[test]
    fn levels_follow_the_range_and_the_size() {
        assert_eq!(levels(741, 500, 64, false), 0);
        // The whole range up to 128 while it holds at most 96 Mi cells; past it, down to 64
        // as before.
        assert_eq!(levels(741, 500, 128, false), 0);
        assert_eq!(levels(741, 500, 129, false), 2);
        assert_eq!(levels(640, 480, 192, false), 2);
        assert_eq!(levels(1280, 720, 96, false), 0);
        assert_eq!(levels(1280, 720, 128, false), 1);
        assert_eq!(levels(1092, 720, 128, false), 0);
        assert_eq!(levels(1920, 1080, 80, false), 1);
        assert_eq!(levels(1920, 1080, 256, false), 2);
        assert_eq!(levels(3000, 2000, 400, false), 3);
        assert_eq!(levels(90, 40, 400, false), 0);
        // A faint pair goes on to 16 disparities.
        assert_eq!(levels(741, 500, 64, true), 2);
        assert_eq!(levels(741, 500, 16, true), 0);
        assert_eq!(levels(3000, 2000, 400, true), 5);
        assert_eq!(levels(90, 40, 400, true), 0);
    }

    /// The halved range covers every halved disparity of the finer one, to the nearest
    /// whole coarse disparity.
    #[test]
    fn halved_ranges_cover() {
        assert_eq!(halve_range(0, 64), (0, 32));
        assert_eq!(halve_range(-5, 10), (-3, 6));
        for (min, count) in [(0, 64), (-5, 10), (7, 33), (-100, 400)] {
            let (lo, n) = halve_range(min, count);
            for d in min..min + count as i32 {
                let c = d as f32 / 2.0;
                assert!(
                    c >= lo as f32 && c <= (lo + n as i32 - 1) as f32 + 0.5,
                    "{d}"
                );
            }
        }
    }

    /// Halving averages 2 × 2 blocks and repeats the last row and column of odd sizes.
    #[test]
    fn halving_averages_blocks() {
        let g = Gray::new(3, 3, vec![0, 4, 8, 4, 8, 12, 100, 100, 100]);
        let h = halve(&g);
        assert_eq!((h.width, h.height), (2, 2));
        assert_eq!(h.data, vec![4, 10, 100, 100]);
    }

    /// A window spans the coarse neighbourhood's disparities, doubled, with the margin; at a
    /// deep edge it is capped and centred on the pixel's own.
    #[test]
    fn windows_span_the_neighbourhood() {
        // A coarse map: 10 on the left half, 40 on the right (a 60-disparity edge when doubled).
        let (cw, ch) = (20, 6);
        let data = (0..cw * ch)
            .map(|i| if i % cw < 10 { 10.0 } else { 40.0 })
            .collect();
        let prior = Prior::new(
            &Disparity {
                width: cw,
                height: ch,
                std: vec![0.2; cw * ch],
                filled: Vec::new(),
                blank: Vec::new(),
                data,
            },
            0,
        );
        let w = 2 * cw;
        let win = prior.windows(0..2, w, (0, 200));
        // Far from the edge: 20 ± 4 → 16 ..= 24, one register from 16.
        let (first, cells) = win.of(0);
        assert_eq!((first, cells.len()), (16, 16));
        // At the edge: 20 − 4 ..= 80 + 4 is 69 wide, more than the cap: centred on its own.
        let (first, cells) = win.of(19);
        assert_eq!(cells.len(), MAX_WINDOW);
        assert!(first <= 20 && first + MAX_WINDOW > 24, "first {first}");
        // A window never reaches past the padded range: 80 ± 4 in a range of 20 is its last
        // register.
        let win = prior.windows(0..1, w, (0, 20));
        assert_eq!((win.of(30).0, win.of(30).1.len()), (16, 16));
    }

    /// Each fine pixel's window, worked out once a coarse row, is what the window's rule gives
    /// pixel by pixel (floor and ceiling as `f32`'s), on a random coarse map with holes, at
    /// several ranges and offsets and over rows that start at an odd one.
    #[test]
    fn a_coarse_rows_windows_are_each_fine_pixels() {
        let (cw, ch) = (37, 9);
        let mut rng = crate::vision::synthetic::Rng::new(17);
        let data = (0..cw * ch)
            .map(|_| {
                let v = rng.unit();
                if v < 0.1 { f32::NAN } else { v * 60.0 - 5.0 }
            })
            .collect();
        let map = Disparity {
            width: cw,
            height: ch,
            std: vec![0.2; cw * ch],
            filled: Vec::new(),
            blank: Vec::new(),
            data,
        };
        for (min, count) in [(0, 128), (-7, 100), (3, 40), (0, 16)] {
            let prior = Prior::new(&map, min / 2);
            let (w, rows) = (2 * cw - 1, 3..2 * ch);
            let got = prior.windows(rows.clone(), w, (min, count));
            let mut i = 0;
            for y in rows {
                for x in 0..w {
                    let c = (y / 2).min(ch - 1) * cw + (x / 2).min(cw - 1);
                    let (start, len) = prior.window_rounding(
                        c,
                        (min, count),
                        |v| v.floor() as usize,
                        |v| v.ceil() as usize,
                    );
                    let (first, cells) = got.of(i);
                    assert_eq!(
                        (first, cells.len()),
                        (usize::from(start), usize::from(len)),
                        "{min} {count} ({x}, {y})"
                    );
                    i += 1;
                }
            }
        }
    }
}
