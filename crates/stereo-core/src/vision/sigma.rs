//! The standard deviation σ_d of every disparity, in pixels: what the matcher knows of each
//! winner (its cost curve, the left-right agreement, the sub-pixel fit) and what the finished
//! map knows of its neighbourhood, turned into a σ by a model fitted on pairs with exact truth
//! (docs/matcher.md, "σ of every disparity").
//!
//! The model adds independent terms in quadrature:
//!
//! σ_d² = s₀² + (k·√(best + 1) / curvature)² + (q·best / (second − best))² + (u·|fraction|)²
//!        + (w·disagreement)² + (r·spread)² + (h·(9 − neighbours))²
//!
//! - `s₀`: the floor a correct match keeps on real images (the census, the resampling);
//! - `√(best + 1) / curvature`: the sub-pixel fit's error, a cost's noise (census costs count
//!   flipped bits, so their spread grows as the root of the least cost) over the curvature at
//!   the least;
//! - `best / (second − best)`: how near the runner-up comes, the chance of a wrong minimum;
//! - `|fraction|`: the fit's offset from the whole pixel, where its bias is largest;
//! - `disagreement`: how far the right image's winner lies from the left's;
//! - `spread`: the range of the valid disparities in the 3 × 3 neighbourhood after the
//!   filters (an edge or a slope the median straddles);
//! - `neighbours`: how many of those 9 are valid (a pixel at a hole's rim is less sure).
//!
//! The first five come from the winner ([`winner_variance`], summed as each row is chosen);
//! the last two from the finished map ([`map`], or [`at`] for a winner the map does not
//! hold). Then, in a depth map, [`super::plane`] adds one more term where its planes reach
//! ([`second_opinion`]): half the difference between the value and the plane its
//! neighbourhood's edges imply.
//! Filled pixels ([`filled`]) take half the spread of the values the fill chose
//! between. [`keep`] drops the disparities whose σ_d exceeds the caller's
//! `max_disparity_std`.

use rayon::prelude::*;

use super::refine::Cue;
use super::simd::{greatest, least};

/// The model's constants, fitted on Motorcycle and its gain-changed and noisy variants; the
/// floor refitted (0.179 → 0.155 px) when the map's planes began to widen σ_d where a value
/// disagrees with its neighbourhood's plane ([`super::plane`]), so that Motorcycle and its
/// variants stay at 68–73 % within 1 σ_d and each tenth's RMS within 1.4 × its σ
/// (docs/matcher.md gives the fit and its checks).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Model {
    pub floor: f32,
    pub fit: f32,
    pub ambiguity: f32,
    pub fraction: f32,
    pub disagreement: f32,
    pub spread: f32,
    pub neighbours: f32,
}

/// The fitted model.
pub const MODEL: Model = Model {
    floor: 0.155,
    fit: 0.094,
    ambiguity: 0.183,
    fraction: 0.413,
    disagreement: 0.296,
    spread: 0.222,
    neighbours: 0.139,
};

/// The left-right disagreement counted at most (pixels): beyond it a match is refuted
/// anyway, and a pixel with no right winner counts as this.
pub const MAX_DISAGREEMENT: f32 = 8.0;

/// The least σ_d of a filled pixel (pixels): a value taken from a neighbour, not matched
/// (fitted with [`filled`]'s half spread so that 66–71 % of the filled pixels of Motorcycle
/// and its variants lie within it).
pub const FILLED_FLOOR: f32 = 0.7;

/// The variance (px²) the winner itself contributes: its cost curve `cue`, its disparity `d`
/// (sub-pixel) and the left-right `disagreement` (pixels), on a pair whose census samples lie
/// `stride` pixels apart: a pair smooth over `stride` pixels knows each disparity √stride
/// times less well (the model was fitted at stride 1; measured on Motorcycle upscaled 2 × and
/// 4 ×, docs/matcher.md).
#[inline(always)]
pub fn winner_variance(cue: Cue, d: f32, disagreement: f32, stride: usize) -> f32 {
    let m = MODEL;
    let best = f32::from(cue.best);
    let fit = (best + 1.0).sqrt() / f32::from(cue.curvature.max(1));
    let margin = (f32::from(cue.second) - best).max(1.0);
    let ambiguity = best / margin;
    let fraction = (d - d.round()).abs();
    let disagreement = if disagreement.is_finite() {
        disagreement.min(MAX_DISAGREEMENT)
    } else {
        MAX_DISAGREEMENT
    };
    let scale = (stride.max(1) as f32).sqrt();
    (m.floor * m.floor
        + (m.fit * fit).powi(2)
        + (m.ambiguity * ambiguity).powi(2)
        + (m.fraction * fraction).powi(2)
        + (m.disagreement * disagreement).powi(2))
        * (scale * scale)
}

crate::dispatch! {
    /// [`winner_variance`] of each pixel of a row of winners with a disparity (`left`, its
    /// `cues`, and how far the right image's winners lie from it, `disagreements`,
    /// [`super::refine::disagreements`]), into `out`; the others are left as they are. Every
    /// pixel's is computed (NaN ones too, and discarded), so that the loop has no branch and
    /// its divisions and roots run on whole registers.
    pub fn winner_variances(
        left: &[f32],
        cues: &[Cue],
        disagreements: &[f32],
        stride: usize,
        out: &mut [f32],
    ) {
        for (((v, &d), &cue), &disagreement) in
            out.iter_mut().zip(left).zip(cues).zip(disagreements)
        {
            let variance = winner_variance(cue, d, disagreement, stride);
            *v = if d.is_nan() { *v } else { variance };
        }
    }
}

/// The map's σ_d (pixels): for each valid pixel of `disparity` (`width` a row), its winner's
/// variance (`variance`, the same layout) with its 3 × 3 neighbourhood's terms; NaN where the
/// disparity is. The value [`at`] gives pixel by pixel, made in bands of [`BAND`] rows side by
/// side: each row's least, greatest and count of the valid values of each pixel's three
/// columns once ([`Triples`]), then those of the three rows around each pixel, on whole
/// registers.
pub fn map(disparity: &[f32], variance: &[f32], width: usize) -> Vec<f32> {
    let width = width.max(1);
    let height = disparity.len() / width;
    let m = MODEL;
    let mut out = vec![f32::NAN; disparity.len()];
    out.par_chunks_mut(BAND * width)
        .enumerate()
        .for_each(|(band, rows)| {
            let top = band * BAND;
            let line = |y: usize| &disparity[y * width..(y + 1) * width];
            // Row y's triples in slot y % 3, for the rows above, at and below the one made.
            let mut triples: [Triples; 3] = std::array::from_fn(|_| Triples::new(width));
            if top > 0 {
                triples[(top - 1) % 3].of(line(top - 1));
            }
            triples[top % 3].of(line(top));
            let (mut lo, mut hi) = (vec![0f32; width], vec![0f32; width]);
            let mut count = vec![0u8; width];
            for (i, row) in rows.chunks_mut(width).enumerate() {
                let y = top + i;
                if y + 1 < height {
                    triples[(y + 1) % 3].of(line(y + 1));
                }
                let here = &triples[y % 3];
                lo.copy_from_slice(&here.lo);
                hi.copy_from_slice(&here.hi);
                count.copy_from_slice(&here.count);
                let around = [y.checked_sub(1), (y + 1 < height).then_some(y + 1)];
                for t in around.into_iter().flatten().map(|yy| &triples[yy % 3]) {
                    for (l, &v) in lo.iter_mut().zip(&t.lo) {
                        *l = least(*l, v);
                    }
                    for (h, &v) in hi.iter_mut().zip(&t.hi) {
                        *h = greatest(*h, v);
                    }
                    for (c, &v) in count.iter_mut().zip(&t.count) {
                        *c += v;
                    }
                }
                let (line, variance) = (line(y), &variance[y * width..(y + 1) * width]);
                for (x, sigma) in row.iter_mut().enumerate() {
                    let missing = 9u32.saturating_sub(u32::from(count[x])) as f32;
                    let spread = hi[x] - lo[x];
                    let s = (variance[x]
                        + (m.spread * spread).powi(2)
                        + (m.neighbours * missing).powi(2))
                    .sqrt();
                    *sigma = if line[x].is_nan() { f32::NAN } else { s };
                }
            }
        });
    out
}

/// The rows a band of [`map`] makes: each band makes the triples of its rows and of the two
/// around it, so taller bands make fewer twice.
const BAND: usize = 16;

/// One row's triples: for each pixel, the least and greatest valid value of it and its left and
/// right neighbours (+∞ and −∞ when none is valid) and how many are valid, the image's outside
/// counted as invalid.
struct Triples {
    lo: Vec<f32>,
    hi: Vec<f32>,
    count: Vec<u8>,
    /// The row with NaN as +∞, then as −∞, and its validity, each with one invalid pixel
    /// beyond either end.
    padded: (Vec<f32>, Vec<f32>, Vec<u8>),
}

impl Triples {
    fn new(width: usize) -> Self {
        Triples {
            lo: vec![f32::INFINITY; width],
            hi: vec![f32::NEG_INFINITY; width],
            count: vec![0; width],
            padded: (
                vec![f32::INFINITY; width + 2],
                vec![f32::NEG_INFINITY; width + 2],
                vec![0; width + 2],
            ),
        }
    }

    /// The triples of the row `line`.
    fn of(&mut self, line: &[f32]) {
        let width = line.len();
        let (low, high, valid) = &mut self.padded;
        for (((&v, l), h), c) in line
            .iter()
            .zip(&mut low[1..=width])
            .zip(&mut high[1..=width])
            .zip(&mut valid[1..=width])
        {
            let nan = v.is_nan();
            *l = if nan { f32::INFINITY } else { v };
            *h = if nan { f32::NEG_INFINITY } else { v };
            *c = u8::from(!nan);
        }
        // Each pixel's left neighbour, itself and its right neighbour as three slices side by
        // side, so that the loops run on whole registers without bounds checks.
        let (a, b, c) = (&low[..width], &low[1..=width], &low[2..width + 2]);
        for (((out, &a), &b), &c) in self.lo.iter_mut().zip(a).zip(b).zip(c) {
            *out = least(least(a, b), c);
        }
        let (a, b, c) = (&high[..width], &high[1..=width], &high[2..width + 2]);
        for (((out, &a), &b), &c) in self.hi.iter_mut().zip(a).zip(b).zip(c) {
            *out = greatest(greatest(a, b), c);
        }
        let (a, b, c) = (&valid[..width], &valid[1..=width], &valid[2..width + 2]);
        for (((out, &a), &b), &c) in self.count.iter_mut().zip(a).zip(b).zip(c) {
            *out = a + b + c;
        }
    }
}

/// σ_d (pixels) of the value `d` at `(x, y)` of a map (`width` a row; the map's own value
/// there, or one it does not hold, as a winner the filters removed), whose winner contributes
/// `variance`: that with the 3 × 3 neighbourhood's terms, `d` counted in it.
pub fn at(disparity: &[f32], width: usize, (x, y): (usize, usize), d: f32, variance: f32) -> f32 {
    let m = MODEL;
    let height = disparity.len() / width.max(1);
    let (mut lo, mut hi, mut valid) = (d, d, 1u32);
    for yy in y.saturating_sub(1)..(y + 2).min(height) {
        let line = &disparity[yy * width..(yy + 1) * width];
        for (xx, &v) in line
            .iter()
            .enumerate()
            .take((x + 2).min(width))
            .skip(x.saturating_sub(1))
        {
            if (xx, yy) != (x, y) && !v.is_nan() {
                lo = lo.min(v);
                hi = hi.max(v);
                valid += 1;
            }
        }
    }
    let missing = 9u32.saturating_sub(valid) as f32;
    (variance + (m.spread * (hi - lo)).powi(2) + (m.neighbours * missing).powi(2)).sqrt()
}

/// The keep rule: every disparity whose σ_d (`std`, the same layout) exceeds `max_std`
/// pixels is dropped (NaN in both). Runs once on the finished map, before any fill; the σ of
/// the pixels kept stays what the map gave them. Answers how many were dropped.
pub fn keep(disparity: &mut [f32], std: &mut [f32], max_std: f32) -> usize {
    let mut dropped = 0;
    for (d, s) in disparity.iter_mut().zip(std.iter_mut()) {
        if *s > max_std {
            *d = f32::NAN;
            *s = f32::NAN;
            dropped += 1;
        }
    }
    dropped
}

/// σ_d of a matched value `d` whose σ_d is `std` when a second estimate of it (its
/// neighbourhood's plane, [`super::plane`]) says `other`: of two estimates as likely, the
/// standard deviation is half their difference, added to what the match knew in quadrature.
#[inline]
pub fn second_opinion(std: f32, d: f32, other: f32) -> f32 {
    let half = 0.5 * (d - other);
    (std * std + half * half).sqrt()
}

/// σ_d of a pixel the fill gave a value (pixels): half the spread between the values it chose
/// from (`left` and `right`, either NaN when there was none), the standard deviation of a
/// value as likely at either; at least [`FILLED_FLOOR`].
#[inline]
pub fn filled(left: f32, right: f32) -> f32 {
    let half = 0.5 * (left - right).abs();
    if half.is_finite() {
        half.max(FILLED_FLOOR)
    } else {
        FILLED_FLOOR
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The map made in bands gives, to the bit, what [`at`] gives pixel by pixel, on maps with
    /// holes everywhere, the borders, the bands' seams and one-pixel-wide maps included.
    #[test]
    fn the_map_is_at_everywhere() {
        let mut rng = crate::vision::synthetic::Rng::new(21);
        // Maps of one band, of several (the last one short) and of a band and one row.
        for (w, h) in [(17, 9), (1, 5), (6, 1), (40, 23), (13, 70), (3, BAND + 1)] {
            let disparity: Vec<f32> = (0..w * h)
                .map(|_| match rng.unit() {
                    u if u < 0.3 => f32::NAN,
                    u => 10.0 + 20.0 * u,
                })
                .collect();
            let variance: Vec<f32> = (0..w * h).map(|_| 0.02 + rng.unit()).collect();
            let made = map(&disparity, &variance, w);
            for (i, (&m, &d)) in made.iter().zip(&disparity).enumerate() {
                if d.is_nan() {
                    assert!(m.is_nan());
                } else {
                    let one = at(&disparity, w, (i % w, i / w), d, variance[i]);
                    assert_eq!(m.to_bits(), one.to_bits(), "{w} × {h} at {i}");
                }
            }
        }
    }

    /// A row of winners' variances made by the dispatched build (AVX2 where the CPU has it)
    /// gives, to the bit, what [`winner_variance`] gives pixel by pixel, with the right image's
    /// winners missing, disagreeing and outside; pixels without a disparity keep their value.
    #[test]
    fn a_rows_variances_are_each_pixels() {
        let mut rng = crate::vision::synthetic::Rng::new(5);
        for stride in [1, 3] {
            let w = 97;
            let left: Vec<f32> = (0..w)
                .map(|_| match rng.unit() {
                    u if u < 0.2 => f32::NAN,
                    u => 40.0 * u,
                })
                .collect();
            let right: Vec<u16> = (0..w)
                .map(|_| match rng.unit() {
                    u if u < 0.2 => u16::MAX,
                    u => (40.0 * u) as u16,
                })
                .collect();
            let cues: Vec<Cue> = (0..w)
                .map(|_| Cue {
                    best: (900.0 * rng.unit()) as u16,
                    second: 900 + (900.0 * rng.unit()) as u16,
                    curvature: (300.0 * rng.unit()) as u16,
                })
                .collect();
            let mut out = vec![-1.0; w];
            let off = crate::vision::refine::disagreements(&left, &right);
            winner_variances(&left, &cues, &off, stride, &mut out);
            for x in 0..w {
                if left[x].is_nan() {
                    assert_eq!(out[x], -1.0);
                } else {
                    let disagreement = crate::vision::refine::disagreement(&right, x, left[x]);
                    let one = winner_variance(cues[x], left[x], disagreement, stride);
                    assert_eq!(out[x].to_bits(), one.to_bits(), "{x} at stride {stride}");
                }
            }
        }
    }

    /// A sharp, unambiguous, whole-pixel winner the right image agrees with keeps the floor;
    /// each cue that says less moves σ up.
    #[test]
    fn each_cue_moves_sigma_the_way_it_should() {
        let sure = Cue {
            best: 0,
            second: 1000,
            curvature: 1000,
        };
        let floor = winner_variance(sure, 12.0, 0.0, 1).sqrt();
        assert!((floor - MODEL.floor).abs() < 0.01, "{floor}");
        let worse = [
            winner_variance(Cue { best: 600, ..sure }, 12.0, 0.0, 1),
            winner_variance(
                Cue {
                    curvature: 2,
                    best: 50,
                    ..sure
                },
                12.0,
                0.0,
                1,
            ),
            winner_variance(sure, 12.4, 0.0, 1),
            winner_variance(sure, 12.0, 1.0, 1),
            winner_variance(sure, 12.0, f32::INFINITY, 1),
        ];
        for v in worse {
            assert!(v.sqrt() > floor + 0.05, "{} against {floor}", v.sqrt());
        }
        // A pair smooth over 4 pixels: twice the σ.
        let doubled = winner_variance(sure, 12.0, 0.0, 4).sqrt();
        assert!((doubled - 2.0 * floor).abs() < 1e-5);
    }

    /// The map adds the neighbourhood: a pixel inside a flat valid patch keeps its winner's σ,
    /// one at an edge or a hole's rim gets more, and invalid pixels stay NaN.
    #[test]
    fn the_map_adds_the_neighbourhood() {
        let width = 5;
        let mut d = vec![10.0f32; 25];
        d[4] = f32::NAN; // top-right corner: a hole
        d[20] = 14.0; // bottom-left: a step
        let variance = vec![0.04f32; 25];
        let s = map(&d, &variance, width);
        assert!((s[12] - 0.2).abs() < 1e-6, "{}", s[12]);
        assert!(s[4].is_nan());
        // (0, 3) sees the hole and the image's edge: 4 of its 9 missing.
        assert!(s[3] > s[12] + 0.3);
        // (1, 4) is beside the step of 4 px.
        assert!((s[16] - (0.04f32 + (MODEL.spread * 4.0).powi(2)).sqrt()).abs() < 1e-5);
    }

    /// The keep rule drops exactly the pixels whose σ_d is above the threshold, value and σ
    /// both, and leaves the rest (and the invalid ones) as they were.
    #[test]
    fn keep_drops_what_sigma_says_is_not_worth_keeping() {
        let mut d = vec![10.0, 11.0, f32::NAN, 12.0];
        let mut s = vec![0.3, 2.5, f32::NAN, 2.0];
        assert_eq!(keep(&mut d, &mut s, 2.0), 1);
        assert_eq!(d[0], 10.0);
        assert!(d[1].is_nan() && s[1].is_nan());
        assert!(d[2].is_nan());
        assert_eq!((d[3], s[3]), (12.0, 2.0));
    }

    /// A filled pixel is never surer than a pixel, and says how far apart its sources were.
    #[test]
    fn filled_pixels_say_how_little_is_known() {
        assert_eq!(filled(10.0, 10.2), FILLED_FLOOR);
        assert_eq!(filled(10.0, 30.0), 10.0);
        assert_eq!(filled(f32::NAN, 30.0), FILLED_FLOOR);
    }
}
