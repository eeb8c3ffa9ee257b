//! Holes in flat areas given the plane their textured surroundings imply (issue 68).
//!
//! Inside a flat area (a board's square, a wall) the census sees only noise, so the matcher
//! either refuses the pixels or carries a value in from the edges by its penalties, which
//! favour a constant disparity. The edges themselves are matched well. A surface's disparity is
//! affine in a rectified image wherever the surface is a plane (d = a·x + b·y + c), so a hole
//! whose neighbourhood's textured pixels fit one plane closely gets that plane's value there:
//!
//! - a pixel has texture where the horizontal central difference of the left image exceeds
//!   [`TEXTURE_LEVELS`] grey levels (of 255) at it or a neighbour (3 × 3);
//! - the support is the textured pixels with a disparity whose σ_d is at most [`SUPPORT_STD`];
//! - in the [`WINDOW`] × [`WINDOW`] window around each hole without texture, a plane is fitted
//!   to the support by least squares (running sums of the ten moments, so each pixel costs the
//!   same whatever the window);
//! - a hole takes the plane's value when at least [`MIN_SUPPORT`] pixels support it, with
//!   [`MIN_SIDE`] of them on each side of it, left, right, above and below (so that the plane
//!   is interpolated between edges, not carried past them), their RMS off the plane is within
//!   the scatter their own σ_d predict ([`SCATTER`] times their RMS σ_d) and at most
//!   [`MAX_RMS`] px (a window across a depth edge fits no plane), and the value lies in the
//!   range searched; its σ_d is √(rms² + [`FLOOR`]²).
//!
//! Measured on OpenCV's 13 real stereo photographs against each board's plane, and on
//! Middlebury (docs/matcher.md, "Real photographs: truth from the board's plane").

use std::ops::Range;

use rayon::prelude::*;

use super::Gray;

/// The window the plane is fitted over (pixels, odd): about a printed board's square at a
/// metre, and small enough that most windows hold one surface.
pub const WINDOW: usize = 41;
/// The least horizontal contrast (central difference, grey levels of 255) that counts as
/// texture: JPEG's blocks and a dark sensor's noise stay below it.
pub const TEXTURE_LEVELS: f32 = 4.0;
/// The largest σ_d (px) of a disparity that may support a plane.
pub const SUPPORT_STD: f32 = 1.0;
/// The fewest supporting pixels a plane is fitted to.
pub const MIN_SUPPORT: f64 = 30.0;
/// The fewest supporting pixels on each side of a hole (left, right, above and below it in its
/// window): a plane is only interpolated between its edges, never carried past the last one
/// (into an occluded strip beside a nearer surface, or past the image's border).
pub const MIN_SIDE: f64 = 10.0;
/// The largest RMS (px) of the support off its plane for the plane to be used, whatever the
/// support's σ_d: a window whose edges scatter more than a pixel off any plane holds more than
/// one surface.
pub const MAX_RMS: f64 = 1.0;
/// How far the support may scatter off its plane, in units of the scatter its own σ_d predict
/// (√(mean σ_d²)): a plane fits when the residuals are what the edges' noise makes them. On
/// clean pairs (σ_d ≈ 0.2–0.3 px at edges) that allows 0.4–0.6 px; on JPEG photographs
/// (σ_d ≈ 0.5 px) about a pixel, where a fixed 0.5 px refused 95 % of the boards' flat holes
/// whose support's RMS was 0.55–0.75 px (docs/matcher.md).
pub const SCATTER: f64 = 2.0;
/// The least σ_d (px) of a value the plane gave: how far a plane is from the surface between
/// its edges (fitted so that 68 % of those values on the boards lie within their σ_d).
pub const FLOOR: f32 = 0.5;

/// The rows that share one window's plane (its middle row's).
const BLOCK: usize = 8;

/// Fills the holes (NaN in `disparity`, a range index; `std` its σ_d) of `disparity` (`width`
/// a row) that lie in flat areas of `left` (the same size) with the plane their surroundings
/// imply, when they imply one ([the module's rules](self)), below `count` (the range's
/// size). Answers which pixels it gave a value.
pub fn fill(
    disparity: &mut [f32],
    std: &mut [f32],
    width: usize,
    left: &Gray,
    count: usize,
) -> Vec<bool> {
    let n = disparity.len();
    if width == 0 || n == 0 || left.data.len() != n {
        return vec![false; n];
    }
    let height = n / width;
    let flat = flat_pixels(left);
    let support: Vec<bool> = (flat.par_iter(), disparity.par_iter(), std.par_iter())
        .into_par_iter()
        .map(|(&f, d, &s)| !f && d.is_finite() && s <= SUPPORT_STD)
        .collect();
    let holes: Vec<bool> = (flat.par_iter(), disparity.par_iter())
        .into_par_iter()
        .map(|(&f, d)| f && d.is_nan())
        .collect();
    // Bands of whole blocks side by side on the cores; in each block of BLOCK rows the window
    // is its middle row's (a window 41 rows high moved by at most 4).
    let rows =
        (64.max(height.div_ceil(rayon::current_num_threads().max(1)))).next_multiple_of(BLOCK);
    let found: Vec<(usize, f32, f32)> = (0..height)
        .step_by(rows)
        .collect::<Vec<_>>()
        .into_par_iter()
        .flat_map_iter(|top| {
            let middle = |base: usize| (base + BLOCK / 2).min(height - 1);
            let mut window = Window::at((disparity, std), &support, width, middle(top));
            let mut out = Vec::new();
            for base in (top..(top + rows).min(height)).step_by(BLOCK) {
                let block = base..(base + BLOCK).min(height);
                if holes[block.start * width..block.end * width].contains(&true) {
                    window.move_to(middle(base));
                    window.planes(block, &holes, count, &mut out);
                }
            }
            out
        })
        .collect();
    let mut filled = vec![false; n];
    for (i, value, rms) in found {
        disparity[i] = value;
        std[i] = (rms * rms + FLOOR * FLOOR).sqrt();
        filled[i] = true;
    }
    filled
}

/// Which pixels of `image` are flat: no horizontal contrast above [`TEXTURE_LEVELS`] at them
/// or at any of their 8 neighbours.
fn flat_pixels(image: &Gray) -> Vec<bool> {
    let w = image.width.max(1);
    let threshold = (2.0 * TEXTURE_LEVELS * 257.0) as u32;
    // Contrast at each pixel, then the 3 × 3 neighbourhood: along the rows, then down the columns.
    let mut near = vec![false; image.data.len()];
    near.par_chunks_mut(w)
        .zip(image.data.par_chunks(w))
        .for_each(|(out, row)| {
            let mut textured = vec![false; w];
            for (x, pixels) in row.windows(3).enumerate() {
                textured[x + 1] = u32::from(pixels[2].abs_diff(pixels[0])) > threshold;
            }
            for (x, o) in out.iter_mut().enumerate() {
                *o = textured[x.saturating_sub(1)] || textured[x] || textured[(x + 1).min(w - 1)];
            }
        });
    let h = near.len() / w;
    let mut flat = vec![true; near.len()];
    flat.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let rows = [y.saturating_sub(1), y, (y + 1).min(h - 1)];
        for (x, f) in out.iter_mut().enumerate() {
            *f = !rows.iter().any(|&r| near[r * w + x]);
        }
    });
    flat
}

/// A column's sums over the window's rows: the support's ten moments, the sum of its σ_d²
/// ([`VARIANCE`]), then its count in the rows above the window's centre ([`ABOVE`]) and in those
/// below it ([`BELOW`]).
type Column = [f64; 13];
const VARIANCE: usize = 10;
const ABOVE: usize = 11;
const BELOW: usize = 12;

/// The [`WINDOW`]-row window around a centre row: each column's sums ([`Column`]), slid down
/// one row at a time.
struct Window<'a> {
    disparity: &'a [f32],
    std: &'a [f32],
    support: &'a [bool],
    width: usize,
    height: usize,
    centre: usize,
    columns: Vec<Column>,
}

impl<'a> Window<'a> {
    const HALF: usize = WINDOW / 2;

    /// The window around row `centre` (clipped to the image).
    fn at(
        (disparity, std): (&'a [f32], &'a [f32]),
        support: &'a [bool],
        width: usize,
        centre: usize,
    ) -> Self {
        let height = disparity.len() / width;
        let mut window = Window {
            disparity,
            std,
            support,
            width,
            height,
            centre,
            columns: vec![[0.0; 13]; width],
        };
        for row in centre.saturating_sub(Self::HALF)..(centre + Self::HALF + 1).min(height) {
            window.moments(row, 1.0);
            match row.cmp(&centre) {
                std::cmp::Ordering::Less => window.count(row, ABOVE, 1.0),
                std::cmp::Ordering::Greater => window.count(row, BELOW, 1.0),
                std::cmp::Ordering::Equal => {}
            }
        }
        window
    }

    /// Slides the window down to the row `centre` (at or below its own).
    fn move_to(&mut self, centre: usize) {
        while self.centre < centre {
            self.centre += 1;
            let c = self.centre;
            if c + Self::HALF < self.height {
                self.moments(c + Self::HALF, 1.0);
                self.count(c + Self::HALF, BELOW, 1.0);
            }
            if c > Self::HALF {
                self.moments(c - Self::HALF - 1, -1.0);
                self.count(c - Self::HALF - 1, ABOVE, -1.0);
            }
            self.count(c - 1, ABOVE, 1.0);
            self.count(c, BELOW, -1.0);
        }
    }

    /// Row `row`'s support added to (`sign` 1) or taken from (−1) the columns' moments.
    fn moments(&mut self, row: usize, sign: f64) {
        let start = row * self.width;
        for (x, column) in self.columns.iter_mut().enumerate() {
            if self.support[start + x] {
                let (px, py, d) = (x as f64, row as f64, f64::from(self.disparity[start + x]));
                let m = [px, py, d, px * px, px * py, py * py, px * d, py * d, d * d];
                column[0] += sign;
                for (s, v) in column[1..10].iter_mut().zip(m) {
                    *s += sign * v;
                }
                column[VARIANCE] += sign * f64::from(self.std[start + x]).powi(2);
            }
        }
    }

    /// Row `row`'s support added to or taken from the columns' count in `slot`.
    fn count(&mut self, row: usize, slot: usize, sign: f64) {
        let start = row * self.width;
        for (x, column) in self.columns.iter_mut().enumerate() {
            if self.support[start + x] {
                column[slot] += sign;
            }
        }
    }

    /// The planes of this window at the holes (`holes`, by pixel) of the rows `block`, each
    /// centred on its column, pushed to `out` as (pixel, value, rms) when the module's rules
    /// allow (the value below `count`).
    fn planes(
        &self,
        block: Range<usize>,
        holes: &[bool],
        count: usize,
        out: &mut Vec<(usize, f32, f32)>,
    ) {
        let (width, half, columns) = (self.width, Self::HALF, &self.columns);
        let mut sums: Column = [0.0; 13];
        // The support's count in the columns x − half .. x − 1 and x + 1 ..= x + half.
        let (mut before, mut after) = (0.0, 0.0);
        for column in &columns[..half.min(width)] {
            add(&mut sums, column, 1.0);
            after += column[0];
        }
        for x in 0..width {
            if x + half < width {
                add(&mut sums, &columns[x + half], 1.0);
                after += columns[x + half][0];
            }
            if x > half {
                add(&mut sums, &columns[x - half - 1], -1.0);
                before -= columns[x - half - 1][0];
            }
            if x > 0 {
                before += columns[x - 1][0];
            }
            after -= columns[x][0];
            if before.min(after).min(sums[ABOVE]).min(sums[BELOW]) < MIN_SIDE {
                continue;
            }
            for y in block.clone().filter(|y| holes[y * width + x]) {
                // The window's plane, at this pixel.
                if let Some((value, rms)) = plane_at(&sums, x as f64, y as f64)
                    && value >= 0.0
                    && value <= (count.max(1) - 1) as f64
                {
                    out.push((y * width + x, value as f32, rms as f32));
                }
            }
        }
    }
}

#[inline]
fn add(sums: &mut Column, moments: &Column, sign: f64) {
    for (s, m) in sums.iter_mut().zip(moments) {
        *s += sign * m;
    }
}

/// The least-squares plane through the support whose moments are `m` (count, Σx, Σy, Σd, Σx²,
/// Σxy, Σy², Σxd, Σyd, Σd², Σσ_d²), at `(x0, y0)`: its value there and the support's RMS off
/// it, when at least [`MIN_SUPPORT`] pixels fit it within [`SCATTER`] times their RMS σ_d and
/// within [`MAX_RMS`].
fn plane_at(m: &Column, x0: f64, y0: f64) -> Option<(f64, f64)> {
    let [n, sx, sy, sd, sxx, sxy, syy, sxd, syd, sdd, sss, ..] = *m;
    if n < MIN_SUPPORT {
        return None;
    }
    // In coordinates centred on the pixel (u = x − x0, v = y − y0), where the plane's constant
    // term is its value at the pixel.
    let su = sx - x0 * n;
    let sv = sy - y0 * n;
    let suu = sxx - 2.0 * x0 * sx + x0 * x0 * n;
    let svv = syy - 2.0 * y0 * sy + y0 * y0 * n;
    let suv = sxy - x0 * sy - y0 * sx + x0 * y0 * n;
    let sud = sxd - x0 * sd;
    let svd = syd - y0 * sd;
    let a = nalgebra::Matrix3::new(suu, suv, su, suv, svv, sv, su, sv, n);
    let b = nalgebra::Vector3::new(sud, svd, sd);
    let p = a.cholesky()?.solve(&b);
    let (pa, pb, pc) = (p[0], p[1], p[2]);
    let residual = sdd - 2.0 * (pa * sud + pb * svd + pc * sd)
        + pa * pa * suu
        + pb * pb * svv
        + pc * pc * n
        + 2.0 * (pa * pb * suv + pa * pc * su + pb * pc * sv);
    let rms = (residual.max(0.0) / n).sqrt();
    let scatter = SCATTER * (sss.max(0.0) / n).sqrt();
    (rms <= MAX_RMS.min(scatter) && pc.is_finite()).then_some((pc, rms))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A slanted plane seen as a board: vertical stripes of texture every 30 px with flat
    /// bands between, the stripes matched and the bands empty. The bands' pixels with edges on
    /// both sides within the window get the plane's value to within a hundredth of a pixel,
    /// with σ_d at the floor; textured holes stay empty.
    #[test]
    fn flat_holes_get_the_plane_their_edges_imply() {
        let (w, h) = (160, 80);
        let truth = |x: usize, y: usize| 20.0 + 0.05 * x as f32 - 0.03 * y as f32;
        let mut image = vec![128u16 * 257; w * h];
        let mut disparity = vec![f32::NAN; w * h];
        let mut std = vec![f32::NAN; w * h];
        for y in 0..h {
            for x in 0..w {
                if x % 30 < 4 {
                    image[y * w + x] = (40 + 60 * (x % 30) as u16) * 257;
                    disparity[y * w + x] = truth(x, y);
                    std[y * w + x] = 0.3;
                }
            }
        }
        // A hole inside the texture: not flat, so it stays a hole.
        disparity[40 * w + 31] = f32::NAN;
        let left = Gray::new(w, h, image);
        let filled = fill(&mut disparity, &mut std, w, &left, 64);
        assert!(!filled[40 * w + 31] && disparity[40 * w + 31].is_nan());
        let (x, y) = (45, 40);
        assert!(filled[y * w + x]);
        assert!(
            (disparity[y * w + x] - truth(x, y)).abs() < 0.01,
            "{}",
            disparity[y * w + x]
        );
        assert!((std[y * w + x] - FLOOR).abs() < 0.01, "{}", std[y * w + x]);
        let count = filled.iter().filter(|&&f| f).count();
        assert!(count > w * h / 4, "{count} filled");
        for (i, &f) in filled.iter().enumerate() {
            if f {
                let (x, y) = (i % w, i / w);
                assert!((disparity[i] - truth(x, y)).abs() < 0.05, "({x}, {y})");
            }
        }
    }

    /// The support may scatter off its plane as much as its own σ_d say, up to a pixel: edges
    /// off by ±0.8 px fit when their σ_d is 0.5 px (a noisy photograph's), not when it is
    /// 0.3 px (a clean pair's); edges off by ±1.2 px never do.
    #[test]
    fn the_support_scatters_as_its_sigma_says() {
        let (w, h) = (160, 80);
        let truth = |x: usize, y: usize| 20.0 + 0.05 * x as f32 - 0.03 * y as f32;
        let mut image = vec![128u16 * 257; w * h];
        for y in 0..h {
            for x in (0..w).filter(|x| x % 30 < 4) {
                image[y * w + x] = (40 + 60 * (x % 30) as u16) * 257;
            }
        }
        let left = Gray::new(w, h, image);
        let filled_with = |off: f32, sigma: f32| {
            let mut disparity = vec![f32::NAN; w * h];
            let mut std = vec![f32::NAN; w * h];
            for y in 0..h {
                for x in (0..w).filter(|x| x % 30 < 4) {
                    let sign = if (x + y) % 2 == 0 { 1.0 } else { -1.0 };
                    disparity[y * w + x] = truth(x, y) + sign * off;
                    std[y * w + x] = sigma;
                }
            }
            let filled = fill(&mut disparity, &mut std, w, &left, 64);
            let (x, y) = (45, 40);
            filled[y * w + x].then(|| (disparity[y * w + x], std[y * w + x]))
        };
        let (value, sigma) = filled_with(0.8, 0.5).expect("filled");
        assert!((value - truth(45, 40)).abs() < 0.1, "{value}");
        // σ_d = √(rms² + floor²) with rms 0.8.
        assert!(
            (sigma - (0.64f32 + FLOOR * FLOOR).sqrt()).abs() < 0.02,
            "{sigma}"
        );
        assert_eq!(filled_with(0.8, 0.3), None);
        assert_eq!(filled_with(1.2, 0.9), None);
    }

    /// Support on two surfaces at different depths fits no plane: the holes between them stay
    /// empty; and a plane whose value falls outside the range is not used.
    #[test]
    fn no_plane_across_a_depth_edge_or_outside_the_range() {
        let (w, h) = (120, 60);
        let mut image = vec![128u16 * 257; w * h];
        let mut disparity = vec![f32::NAN; w * h];
        let mut std = vec![f32::NAN; w * h];
        for y in 0..h {
            for x in [50usize, 51, 52, 68, 69, 70] {
                image[y * w + x] = (40 + 60 * (x % 3) as u16) * 257;
                disparity[y * w + x] = if x < 60 { 10.0 } else { 30.0 };
                std[y * w + x] = 0.3;
            }
        }
        let left = Gray::new(w, h, image.clone());
        let (mut d, mut s) = (disparity.clone(), std.clone());
        let filled = fill(&mut d, &mut s, w, &left, 64);
        assert!(!filled[30 * w + 60] && d[30 * w + 60].is_nan());
        // One surface at 30, searched over 0..20 only: nothing in range to give.
        for v in disparity.iter_mut().filter(|v| v.is_finite()) {
            *v = 30.0;
        }
        let filled = fill(&mut disparity, &mut std, w, &left, 20);
        assert!(filled.iter().all(|&f| !f));
    }
}
