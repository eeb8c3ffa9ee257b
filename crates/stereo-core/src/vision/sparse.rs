//! Sparse matches of a rectified pair to a few hundredths of a pixel in both directions: the
//! calibration check's evidence. The corners and their whole-pixel matches come from the row
//! check's search ([`super::rows`]: one strongest corner a cell of a finer grid, matched coarse
//! to fine over the whole disparity range and rows up and down); each one that reaches full
//! size is then refined by Lucas and Kanade's Gauss–Newton over a 15 × 15 window, with a gain
//! and an offset between the cameras, on both images smoothed (σ = 1 px) and the right read
//! by Catmull-Rom's cubic.
//!
//! A refined match counts only when its window is textured in both directions, it converged
//! within [`MAX_MOVE`] px of the whole-pixel match, and the windows then correlate to at least
//! [`MIN_NCC`].

use rayon::prelude::*;

use super::Gray;
use super::rows::{pyramid, trace};

/// The grid of cells that each give at most one corner: 192 a pair.
pub const CELLS: (usize, usize) = (16, 12);
/// Half the refined window's side: 15 × 15 pixels.
const RADIUS: i64 = 7;
/// How far (px) refinement may move a match from its whole-pixel start.
const MAX_MOVE: f64 = 1.5;
/// The normalised cross-correlation of the refined windows a match needs.
const MIN_NCC: f64 = 0.9;
/// The most Gauss–Newton steps, and the step (px) under which it has converged.
const STEPS: usize = 20;
const CONVERGED: f64 = 1e-3;

/// A left pixel and where it is in the right image, both in pixels of the (rectified)
/// images, the right to a fraction of a pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SparseMatch {
    pub left: [f64; 2],
    pub right: [f64; 2],
    /// The refined windows' normalised cross-correlation.
    pub score: f64,
}

/// The disparities a pair of `width` is searched over for its sparse matches: a little below
/// zero to a third of its width.
pub fn full_range(width: usize) -> (i32, i32) {
    (-8, (width / 3) as i32)
}

/// The pair's matches over disparities `range` (and [`super::rows::SEARCH_ROWS`] rows and more up
/// and down, as the row check searches), in no particular order. Empty when the images
/// differ in size or are too small.
pub fn sparse_matches(left: &Gray, right: &Gray, range: (i32, i32)) -> Vec<SparseMatch> {
    let (w, h) = (left.width, left.height);
    let side = (2 * RADIUS + 1) as usize;
    if right.width != w
        || right.height != h
        || h < 4 * side
        || w < 4 * side
        || left.data.len() != w * h
        || right.data.len() != w * h
        || range.0 > range.1
    {
        return Vec::new();
    }
    let (lefts, rights) = pyramid(left, right);
    let traced = trace(left, right, (&lefts, &rights), range, CELLS);
    let (smooth_left, smooth_right) = rayon::join(|| Smooth::new(left), || Smooth::new(right));
    traced
        .into_par_iter()
        .filter(|t| t.level == 0)
        .filter_map(|t| {
            let start = [-f64::from(t.d), t.row];
            let (offset, score) = refine(&smooth_left, &smooth_right, (t.x, t.y), start)?;
            let (x, y) = (t.x as f64, t.y as f64);
            Some(SparseMatch {
                left: [x, y],
                right: [x + offset[0], y + offset[1]],
                score,
            })
        })
        .collect()
}

/// The matches of chosen left pixels `points` over disparities `range` and two rows up and
/// down (a rectified pair), each refined as [`sparse_matches`] refines its corners; `None`
/// where a point has no clear match.
pub fn match_points(
    left: &Gray,
    right: &Gray,
    points: &[(usize, usize)],
    range: (i32, i32),
) -> Vec<Option<SparseMatch>> {
    let (w, h) = (left.width, left.height);
    if right.width != w
        || right.height != h
        || left.data.len() != w * h
        || right.data.len() != w * h
    {
        return vec![None; points.len()];
    }
    let (smooth_left, smooth_right) = rayon::join(|| Smooth::new(left), || Smooth::new(right));
    points
        .par_iter()
        .map(|&(x, y)| {
            let peak = super::rows::search(left, right, (x, y), range, (-2, 2), true)?;
            let start = [-f64::from(peak.d), peak.row];
            let (offset, score) = refine(&smooth_left, &smooth_right, (x, y), start)?;
            let (xf, yf) = (x as f64, y as f64);
            Some(SparseMatch {
                left: [xf, yf],
                right: [xf + offset[0], yf + offset[1]],
                score,
            })
        })
        .collect()
}

/// An image smoothed by a binomial kernel of σ = 1 px (1 4 6 4 1, each way), with its
/// gradients: what refinement reads, so that its cost is smooth between pixels and the
/// interpolation hardly blurs what it reads.
struct Smooth {
    width: usize,
    height: usize,
    value: Vec<f32>,
    gx: Vec<f32>,
    gy: Vec<f32>,
}

impl Smooth {
    fn new(img: &Gray) -> Smooth {
        let (w, h) = (img.width, img.height);
        const K: [f32; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];
        let clamp = |i: isize, n: usize| i.clamp(0, n as isize - 1) as usize;
        let mut across = vec![0.0f32; w * h];
        for y in 0..h {
            let row = &img.data[y * w..][..w];
            for x in 0..w {
                across[y * w + x] = K
                    .iter()
                    .enumerate()
                    .map(|(k, c)| c * f32::from(row[clamp(x as isize + k as isize - 2, w)]))
                    .sum::<f32>()
                    / 257.0;
            }
        }
        let mut value = vec![0.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                value[y * w + x] = K
                    .iter()
                    .enumerate()
                    .map(|(k, c)| c * across[clamp(y as isize + k as isize - 2, h) * w + x])
                    .sum();
            }
        }
        let mut gx = vec![0.0f32; w * h];
        let mut gy = vec![0.0f32; w * h];
        for y in 1..h.saturating_sub(1) {
            for x in 1..w.saturating_sub(1) {
                let i = y * w + x;
                gx[i] = 0.5 * (value[i + 1] - value[i - 1]);
                gy[i] = 0.5 * (value[i + w] - value[i - w]);
            }
        }
        Smooth {
            width: w,
            height: h,
            value,
            gx,
            gy,
        }
    }

    /// The value and both gradients at `(x, y)`, by Catmull-Rom's cubic over the 4 × 4
    /// pixels around it; `None` where those are not all inside the image (and a pixel in).
    fn at(&self, x: f64, y: f64) -> Option<[f64; 3]> {
        let (x0, y0) = (x.floor(), y.floor());
        if x0 < 2.0 || y0 < 2.0 || x0 + 3.0 >= self.width as f64 || y0 + 3.0 >= self.height as f64 {
            return None;
        }
        let (wx, wy) = (
            super::synthetic::catmull_rom((x - x0) as f32),
            super::synthetic::catmull_rom((y - y0) as f32),
        );
        let mut out = [0.0f64; 3];
        for (j, cy) in wy.iter().enumerate() {
            let row = (y0 as usize + j - 1) * self.width + x0 as usize - 1;
            for (i, cx) in wx.iter().enumerate() {
                let c = f64::from(cx * cy);
                out[0] += c * f64::from(self.value[row + i]);
                out[1] += c * f64::from(self.gx[row + i]);
                out[2] += c * f64::from(self.gy[row + i]);
            }
        }
        Some(out)
    }
}

/// The left window at `(x, y)` found in the right image at the offset that minimises
/// Σ (I_right(x + offset) − a·I_left(x) − b)² over the window, from `start`; the offset and
/// the windows' correlation there. `None` when it does not converge, leaves the image, moves
/// more than [`MAX_MOVE`] or correlates under [`MIN_NCC`].
fn refine(
    left: &Smooth,
    right: &Smooth,
    (x, y): (usize, usize),
    start: [f64; 2],
) -> Option<([f64; 2], f64)> {
    let (x, y) = (x as i64, y as i64);
    if x < RADIUS
        || y < RADIUS
        || x + RADIUS >= left.width as i64
        || y + RADIUS >= left.height as i64
    {
        return None;
    }
    let mut template = Vec::with_capacity(((2 * RADIUS + 1) * (2 * RADIUS + 1)) as usize);
    for v in y - RADIUS..=y + RADIUS {
        for u in x - RADIUS..=x + RADIUS {
            let t = f64::from(left.value[(v as usize) * left.width + u as usize]);
            template.push((u - x, v - y, t));
        }
    }
    let (mut p, mut a, mut b) = (start, 1.0f64, 0.0f64);
    let mut converged = false;
    for _ in 0..STEPS {
        // The normal equations of the step in (u, v, a, b).
        let mut normal = nalgebra::Matrix4::<f64>::zeros();
        let mut rhs = nalgebra::Vector4::<f64>::zeros();
        for &(du, dv, t) in &template {
            let [value, gx, gy] = right.at((x + du) as f64 + p[0], (y + dv) as f64 + p[1])?;
            // e = I(q) − a·t − b; its derivatives in (u, v, a, b).
            let e = value - a * t - b;
            let j = nalgebra::Vector4::new(gx, gy, -t, -1.0);
            normal += j * j.transpose();
            rhs -= j * e;
        }
        let step = normal.cholesky()?.solve(&rhs);
        p = [p[0] + step[0], p[1] + step[1]];
        a += step[2];
        b += step[3];
        if (p[0] - start[0]).hypot(p[1] - start[1]) > MAX_MOVE {
            return None;
        }
        if step[0].abs() < CONVERGED && step[1].abs() < CONVERGED {
            converged = true;
            break;
        }
    }
    if !converged || a <= 0.0 {
        return None;
    }
    // The windows' normalised cross-correlation at the offset found.
    let n = template.len() as f64;
    let samples: Vec<(f64, f64)> = template
        .iter()
        .map(|&(du, dv, t)| {
            right
                .at((x + du) as f64 + p[0], (y + dv) as f64 + p[1])
                .map(|r| (t, r[0]))
        })
        .collect::<Option<_>>()?;
    let (st, sr) = samples
        .iter()
        .fold((0.0, 0.0), |(st, sr), &(t, r)| (st + t, sr + r));
    let (mt, mr) = (st / n, sr / n);
    let (mut tt, mut rr, mut tr) = (0.0, 0.0, 0.0);
    for &(t, r) in &samples {
        tt += (t - mt) * (t - mt);
        rr += (r - mr) * (r - mr);
        tr += (t - mt) * (r - mr);
    }
    let ncc = tr / (tt * rr).sqrt().max(1e-12);
    (ncc >= MIN_NCC).then_some((p, ncc))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth random texture and the same scene moved by `(dx, dy)`: what the left camera
    /// saw at (x, y), the right one sees at (x − dx, y + dy).
    fn pair(w: usize, h: usize, dx: f64, dy: f64) -> (Gray, Gray) {
        let texture = crate::noise::Texture::new(7);
        let grey =
            |x: f64, y: f64| (30.0 + 200.0 * f64::from(texture.at(x as f32, y as f32))) * 257.0;
        let mut l = Vec::with_capacity(w * h);
        let mut r = Vec::with_capacity(w * h);
        for v in 0..h {
            for u in 0..w {
                let (x, y) = (u as f64, v as f64);
                l.push(grey(x, y).round() as u16);
                r.push(grey(x + dx, y - dy).round() as u16);
            }
        }
        (Gray::new(w, h, l), Gray::new(w, h, r))
    }

    /// A right image 0.37 rows lower and 20.6 columns to the left is measured as such, each
    /// match within 0.05 px, over the whole image.
    #[test]
    fn fractions_of_a_pixel_are_measured_in_both_directions() {
        let (l, r) = pair(480, 360, 20.6, 0.37);
        let found = sparse_matches(&l, &r, (0, 60));
        assert!(found.len() >= 100, "{} matches", found.len());
        for m in &found {
            let (d, row) = (m.left[0] - m.right[0], m.right[1] - m.left[1]);
            assert!((d - 20.6).abs() < 0.05, "{m:?}");
            assert!((row - 0.37).abs() < 0.05, "{m:?}");
        }
        let spread_x = found.iter().map(|m| m.left[0]).fold(0.0f64, f64::max)
            - found.iter().map(|m| m.left[0]).fold(f64::MAX, f64::min);
        assert!(spread_x > 300.0, "matches span {spread_x} px");
    }

    /// Flat or mismatched images give no matches, never a panic.
    #[test]
    fn flat_or_mismatched_images_give_none() {
        let flat = Gray::new(200, 150, vec![1000; 200 * 150]);
        assert!(sparse_matches(&flat, &flat, (0, 16)).is_empty());
        let (l, _) = pair(320, 240, 0.0, 0.0);
        assert!(sparse_matches(&l, &flat, (0, 16)).is_empty());
        assert!(sparse_matches(&l, &l, (5, 2)).is_empty());
    }
}
