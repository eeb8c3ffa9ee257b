//! Holes in flat areas given the plane their textured surroundings imply, and each matched
//! value's σ_d widened by how far it lies from that plane (issue 68).
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
//!   same whatever the window); where that window gives none to a block holding a flat pixel
//!   (a flat area wider than it: a board's square seen near, or in a large image), the window
//!   2 · [`WINDOW`] + 1 wide is tried (on OpenCV's 13 photographs enlarged 2 ×, their
//!   squares 60–90 px, it took the board's errors within 1 σ_d from 40 to 52 % and the board
//!   answered right from 17 to 33 %);
//! - a hole takes the plane's value when at least [`MIN_SUPPORT`] pixels support it, with
//!   [`MIN_SIDE`] of them on each side of it, left, right, above and below (so that the plane
//!   is interpolated between edges, not carried past them), their RMS off the plane is within
//!   the scatter their own σ_d predict ([`SCATTER`] times their RMS σ_d) and at most
//!   [`MAX_RMS`] px (a window across a depth edge fits no plane), and the value lies in the
//!   range searched; its σ_d is √(rms² + [`FLOOR`]²);
//! - a matched pixel where the same rules give a plane has two estimates of its disparity, its
//!   own match and the plane its neighbourhood's edges imply; when they differ by δ, its σ_d
//!   grows to √(σ_d² + (δ/2)²), half the difference being the standard deviation of a value
//!   as likely at either ([`super::sigma::second_opinion`]; a filled pixel's σ_d follows the
//!   same rule, [`super::sigma::filled`]).
//!   A value the penalties carried into a flat area, or a region matched one period of a
//!   pattern away, says so this way.
//!
//! Measured on OpenCV's 13 real stereo photographs against each board's plane, and on
//! Middlebury (docs/matcher.md, "Real photographs: truth from the board's plane").

use rayon::prelude::*;

use super::{Gray, sigma};

/// The window the plane is fitted over (pixels, odd): about a printed board's square at a
/// metre, and small enough that most windows hold one surface. Where it gives no plane, the
/// window `2 · WINDOW + 1` wide is tried.
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
/// The columns that share one window's plane (its middle column's).
const COLUMNS: usize = 4;

/// Fills the holes (NaN in `disparity`, a range index; `std` its σ_d) of `disparity` (`width`
/// a row) that lie in flat areas of `left` (the same size) with the plane their surroundings
/// imply, when they imply one ([the module's rules](self)), below `count` (the range's
/// size); and widens the σ_d of every matched pixel by its disagreement with the plane there.
/// Answers which pixels it gave a value.
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
    let flat = flat_pixels(left);
    let support: Vec<bool> = (flat.par_iter(), disparity.par_iter(), std.par_iter())
        .into_par_iter()
        .map(|(&f, d, &s)| !f && d.is_finite() && s <= SUPPORT_STD)
        .collect();
    let holes: Vec<bool> = (flat.par_iter(), disparity.par_iter())
        .into_par_iter()
        .map(|(&f, d)| f && d.is_nan())
        .collect();
    // The planes of the window, then, for the blocks it gives none that hold a flat pixel (a
    // flat area wider than it, such as a large square seen near), of the window twice as wide.
    let maps = (&*disparity, &*std);
    let groups = width.div_ceil(COLUMNS);
    let mut planes = planes_of(maps, &support, width, (WINDOW / 2, None));
    let mut wanted = vec![false; planes.len()];
    wanted
        .par_chunks_mut(groups)
        .zip(planes.par_chunks(groups))
        .zip(flat.par_chunks(width * BLOCK))
        .for_each(|((wanted, planes), flat)| {
            for row in flat.chunks(width) {
                for ((w, plane), flat) in wanted.iter_mut().zip(planes).zip(row.chunks(COLUMNS)) {
                    *w |= plane.is_none() && flat.contains(&true);
                }
            }
        });
    drop(flat);
    if wanted.contains(&true) {
        let wide = planes_of(maps, &support, width, (WINDOW, Some(&wanted)));
        for ((plane, wide), &wanted) in planes.iter_mut().zip(wide).zip(&wanted) {
            if wanted {
                *plane = wide;
            }
        }
    }
    drop(support);
    let last = (count.max(1) - 1) as f32;
    let mut filled = vec![false; n];
    (
        disparity.par_chunks_mut(width),
        std.par_chunks_mut(width),
        filled.par_chunks_mut(width),
    )
        .into_par_iter()
        .enumerate()
        .for_each(|(y, (d, s, f))| {
            let planes = &planes[y / BLOCK * groups..(y / BLOCK + 1) * groups];
            let holes = &holes[y * width..(y + 1) * width];
            for (x, ((d, s), (f, &hole))) in
                d.iter_mut().zip(s).zip(f.iter_mut().zip(holes)).enumerate()
            {
                let Some(plane) = &planes[x / COLUMNS] else {
                    continue;
                };
                if hole {
                    let value = plane.at(x, y);
                    if (0.0..=last).contains(&value) {
                        *d = value;
                        let rms = plane.rms as f32;
                        *s = (rms * rms + FLOOR * FLOOR).sqrt();
                        *f = true;
                    }
                } else if !d.is_nan() {
                    *s = sigma::second_opinion(*s, *d, plane.at(x, y));
                }
            }
        });
    filled
}

/// One plane for each block of [`BLOCK`] rows and [`COLUMNS`] columns of `disparity` (`width` a
/// row; `std` its σ_d; `support` the pixels that may support a plane), fitted around its
/// middle pixel over the window reaching `half` pixels each way, where the module's rules
/// allow: bands of whole blocks side by side on the cores, each writing its own blocks'
/// planes. With `wanted` (a flag a block), only the rows of blocks with a wanted one are
/// fitted (the others left `None`), the window moved down to them, or made again where that
/// would slide it further than making it costs.
fn planes_of(
    (disparity, std): (&[f32], &[f32]),
    support: &[bool],
    width: usize,
    (half, wanted): (usize, Option<&[bool]>),
) -> Vec<Option<Plane>> {
    let height = disparity.len() / width;
    let groups = width.div_ceil(COLUMNS);
    let rows =
        (64.max(height.div_ceil(rayon::current_num_threads().max(1)))).next_multiple_of(BLOCK);
    let mut planes: Vec<Option<Plane>> = Vec::new();
    planes.resize_with(height.div_ceil(BLOCK) * groups, || None);
    planes
        .par_chunks_mut(rows / BLOCK * groups)
        .enumerate()
        .for_each(|(band, out)| {
            let top = band * rows;
            let mut window: Option<Window> = None;
            for (base, out) in (top..(top + rows).min(height))
                .step_by(BLOCK)
                .zip(out.chunks_mut(groups))
            {
                let blocks = base / BLOCK * groups..(base / BLOCK + 1) * groups;
                if wanted.is_some_and(|w| !w[blocks].contains(&true)) {
                    continue;
                }
                let centre = middle(base, height);
                match window.as_mut() {
                    // Sliding moves two rows' sums a row; making it, a row's each of its own.
                    Some(w) if centre - w.centre <= half => w.move_to(centre),
                    _ => {
                        window = Some(Window::at((disparity, std), support, (width, half), centre))
                    }
                }
                if let Some(w) = &window {
                    w.planes(out);
                }
            }
        });
    planes
}

/// The centre row of the window for the block of rows from `base`: its middle row.
fn middle(base: usize, height: usize) -> usize {
    (base + BLOCK / 2).min(height - 1)
}

/// Which pixels of `image` are flat: no horizontal contrast above [`TEXTURE_LEVELS`] at them
/// or at any of their 8 neighbours.
fn flat_pixels(image: &Gray) -> Vec<bool> {
    let w = image.width.max(1);
    let n = image.data.len();
    let h = n / w;
    let threshold = (2.0 * TEXTURE_LEVELS * 257.0) as u32;
    // Contrast at each pixel (1 above the threshold), then the 3 × 3 neighbourhood: along the
    // rows (in place), then down the columns. Bytes, so that the loops run on whole vectors.
    let mut near = vec![0u8; n];
    near.par_chunks_mut(w)
        .zip(image.data.par_chunks(w))
        .for_each(|(out, row)| {
            if w < 3 {
                return;
            }
            for (o, pixels) in out[1..w - 1].iter_mut().zip(row.windows(3)) {
                *o = u8::from(u32::from(pixels[2].abs_diff(pixels[0])) > threshold);
            }
            let mut before = 0;
            for x in 0..w {
                let here = out[x];
                out[x] = before | here | out.get(x + 1).copied().unwrap_or(0);
                before = here;
            }
        });
    let mut flat = vec![false; n];
    flat.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let row = |r: usize| &near[r * w..(r + 1) * w];
        let (above, here, below) = (row(y.saturating_sub(1)), row(y), row((y + 1).min(h - 1)));
        for (f, ((&a, &b), &c)) in out.iter_mut().zip(above.iter().zip(here).zip(below)) {
            *f = a | b | c == 0;
        }
    });
    flat
}

/// A window's sums over its support, or a column's: the support's ten moments (count, Σx, Σy,
/// Σd, Σx², Σxy, Σy², Σxd, Σyd, Σd²), the sum of its σ_d² (the eleventh), then its count in the
/// rows above the window's centre ([`ABOVE`]); the count below it is the rest (the whole count
/// less those above and the centre row's).
type Column = [f64; SUMS];
const SUMS: usize = 12;
const ABOVE: usize = 11;

/// What a column keeps of its sums ([`Window`]'s rows of sums): the count, Σy, Σd, Σy², Σyd,
/// Σd², Σσ_d² and the count above the centre. The moments with an x are these times the
/// column's own x, which is the same for all its pixels ([`Window::column`]), so a row of the
/// image enters or leaves 7 sums a pixel, not 11.
const KEPT: usize = 8;
/// Where the count above the centre is among the kept sums.
const KEPT_ABOVE: usize = 7;

/// The window of `2 · half + 1` rows around a centre row: each column's sums, slid down one
/// row at a time. The sums are kept as [`KEPT`] rows of `width` (`sums[k][x]` is column `x`'s
/// kept sum `k`), so that a row of the image enters or leaves them on whole registers.
struct Window<'a> {
    disparity: &'a [f32],
    std: &'a [f32],
    support: &'a [bool],
    width: usize,
    height: usize,
    half: usize,
    centre: usize,
    sums: [Vec<f64>; KEPT],
}

impl<'a> Window<'a> {
    /// The window reaching `half` rows and columns each way around row `centre` (clipped to
    /// the image).
    fn at(
        (disparity, std): (&'a [f32], &'a [f32]),
        support: &'a [bool],
        (width, half): (usize, usize),
        centre: usize,
    ) -> Self {
        let height = disparity.len() / width;
        let mut window = Window {
            disparity,
            std,
            support,
            width,
            height,
            half,
            centre,
            sums: std::array::from_fn(|_| vec![0.0; width]),
        };
        for row in centre.saturating_sub(half)..(centre + half + 1).min(height) {
            window.moments(row, 1.0, row < centre);
        }
        window
    }

    /// Column `x`'s sums, those with an x made from its kept ones (all whole numbers or exact
    /// products while the kept sums are exact, so the same as summing each pixel's).
    fn column(&self, x: usize) -> Column {
        let [n, sy, sd, syy, syd, sdd, sss, above] = std::array::from_fn(|k| self.sums[k][x]);
        let px = x as f64;
        let sx = px * n;
        [
            n,
            sx,
            sy,
            sd,
            sx * px,
            px * sy,
            syy,
            px * sd,
            syd,
            sdd,
            sss,
            above,
        ]
    }

    /// Slides the window down to the row `centre` (at or below its own).
    fn move_to(&mut self, centre: usize) {
        while self.centre < centre {
            self.centre += 1;
            let c = self.centre;
            if c + self.half < self.height {
                self.moments(c + self.half, 1.0, false);
            }
            if c > self.half {
                self.moments(c - self.half - 1, -1.0, true);
            }
            self.count_above(c - 1);
        }
    }

    /// Row `row`'s support added to (`sign` 1) or taken from (−1) the columns' moments, and to
    /// or from their count above the centre when `above`. Without branches: a pixel that is no
    /// support adds zeros (the support is patchy, so a branch would be mispredicted often).
    fn moments(&mut self, row: usize, sign: f64, above: bool) {
        let start = row * self.width;
        let end = start + self.width;
        let pixels = (
            &self.support[start..end],
            &self.disparity[start..end],
            &self.std[start..end],
        );
        add_row(&mut self.sums, pixels, row as f64, sign, above);
    }

    /// Row `row`'s support added to the columns' count above the centre.
    fn count_above(&mut self, row: usize) {
        let start = row * self.width;
        let support = &self.support[start..start + self.width];
        add_count(&mut self.sums[KEPT_ABOVE], support, 1.0);
    }

    /// The planes of this window, one for each group of [`COLUMNS`] columns (`out`, from the
    /// first), fitted around its middle column (the last group's at the edge) when the
    /// module's rules allow.
    fn planes(&self, out: &mut [Option<Plane>]) {
        let (width, half) = (self.width, self.half);
        let count = &self.sums[0];
        let mut sums: Column = [0.0; SUMS];
        // The support's count in the columns x − half .. x − 1 and x + 1 ..= x + half, and on
        // the centre row within the window's columns.
        let (mut before, mut after, mut on_centre) = (0.0, 0.0, 0.0);
        let centre = &self.support[self.centre * width..(self.centre + 1) * width];
        let on = |x: usize| if centre[x] { 1.0 } else { 0.0 };
        for (x, &c) in count[..half.min(width)].iter().enumerate() {
            add(&mut sums, &self.column(x), 1.0);
            after += c;
            on_centre += on(x);
        }
        for x in 0..width {
            if x + half < width {
                add(&mut sums, &self.column(x + half), 1.0);
                after += count[x + half];
                on_centre += on(x + half);
            }
            if x > half {
                add(&mut sums, &self.column(x - half - 1), -1.0);
                before -= count[x - half - 1];
                on_centre -= on(x - half - 1);
            }
            if x > 0 {
                before += count[x - 1];
            }
            after -= count[x];
            let first = x / COLUMNS * COLUMNS;
            if x != (first + COLUMNS / 2).min(width - 1) {
                continue;
            }
            let below = sums[0] - sums[ABOVE] - on_centre;
            if before.min(after).min(sums[ABOVE]).min(below) >= MIN_SIDE {
                out[x / COLUMNS] = plane_at(&sums, x as f64, self.centre as f64);
            }
        }
    }
}

crate::dispatch! {
    /// One row's support (`support`, `disparity` and `std` of its pixels, row `py` of the image)
    /// added to (`sign` 1) or taken from (−1) the column sums `sums` ([`Window`]'s rows of
    /// kept sums, [`KEPT`]), and to or from their count above the centre when `above`.
    /// Branch-free, on whole registers: a pixel that is no support adds zeros, whatever its
    /// disparity holds.
    fn add_row(
        sums: &mut [Vec<f64>; KEPT],
        pixels: (&[bool], &[f32], &[f32]),
        py: f64,
        sign: f64,
        above: bool,
    ) {
        let (support, disparity, std) = pixels;
        let width = support.len().min(disparity.len()).min(std.len());
        let [n, sy, sd, syy, syd, sdd, sss, count_above] = sums;
        let (n, sy, sd) = (&mut n[..width], &mut sy[..width], &mut sd[..width]);
        let (syy, syd) = (&mut syy[..width], &mut syd[..width]);
        let (sdd, sss) = (&mut sdd[..width], &mut sss[..width]);
        for x in 0..width {
            let on = support[x];
            let w = if on { sign } else { 0.0 };
            let d = if on { f64::from(disparity[x]) } else { 0.0 };
            let s = if on { f64::from(std[x]) } else { 0.0 };
            let (wy, wd) = (w * py, w * d);
            n[x] += w;
            sy[x] += wy;
            sd[x] += wd;
            syy[x] += wy * py;
            syd[x] += wd * py;
            sdd[x] += wd * d;
            sss[x] += w * s * s;
        }
        if above {
            add_count(count_above, support, sign);
        }
    }
}

/// `sign` added to `counts` where there is `support`.
#[inline(always)]
fn add_count(counts: &mut [f64], support: &[bool], sign: f64) {
    for (count, &on) in counts.iter_mut().zip(support) {
        *count += if on { sign } else { 0.0 };
    }
}

#[inline]
fn add(sums: &mut Column, moments: &Column, sign: f64) {
    for (s, m) in sums.iter_mut().zip(moments) {
        *s += sign * m;
    }
}

/// A plane fitted around a pixel: the pixel, the plane's value there, its slopes along the row
/// and down the column (px a pixel) and the support's RMS off it (px).
struct Plane {
    centre: (f64, f64),
    value: f64,
    across: f64,
    down: f64,
    rms: f64,
}

impl Plane {
    /// The plane's disparity at pixel `(x, y)`.
    fn at(&self, x: usize, y: usize) -> f32 {
        let (x0, y0) = self.centre;
        (self.value + self.across * (x as f64 - x0) + self.down * (y as f64 - y0)) as f32
    }
}

/// The least-squares plane through the support whose moments are `m` (count, Σx, Σy, Σd, Σx²,
/// Σxy, Σy², Σxd, Σyd, Σd², Σσ_d²), around `(x0, y0)`, when at least [`MIN_SUPPORT`] pixels fit
/// it within [`SCATTER`] times their RMS σ_d and within [`MAX_RMS`].
fn plane_at(m: &Column, x0: f64, y0: f64) -> Option<Plane> {
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
    (rms <= MAX_RMS.min(scatter) && p.iter().all(|v| v.is_finite())).then_some(Plane {
        centre: (x0, y0),
        value: pc,
        across: pa,
        down: pb,
        rms,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The disparity of the tests' slanted plane at `(x, y)`.
    fn truth(x: usize, y: usize) -> f32 {
        20.0 + 0.05 * x as f32 - 0.03 * y as f32
    }

    /// A slanted plane seen as a board, 160 × 80: vertical stripes of texture every 30 px with
    /// flat bands between, the stripes matched (the plane's value, σ_d 0.3 px) and the bands
    /// empty.
    struct Striped {
        w: usize,
        h: usize,
        image: Vec<u16>,
        disparity: Vec<f32>,
        std: Vec<f32>,
    }

    fn striped() -> Striped {
        striped_every(30, (160, 80))
    }

    /// [`striped`] with a stripe every `period` px, `w × h`.
    fn striped_every(period: usize, (w, h): (usize, usize)) -> Striped {
        let mut image = vec![128u16 * 257; w * h];
        let mut disparity = vec![f32::NAN; w * h];
        let mut std = vec![f32::NAN; w * h];
        for y in 0..h {
            for x in (0..w).filter(|x| x % period < 4) {
                image[y * w + x] = (40 + 60 * (x % period) as u16) * 257;
                disparity[y * w + x] = truth(x, y);
                std[y * w + x] = 0.3;
            }
        }
        Striped {
            w,
            h,
            image,
            disparity,
            std,
        }
    }

    /// A slanted plane seen as a board: vertical stripes of texture every 30 px with flat
    /// bands between, the stripes matched and the bands empty. The bands' pixels with edges on
    /// both sides within the window get the plane's value to within a hundredth of a pixel,
    /// with σ_d at the floor; textured holes stay empty.
    #[test]
    fn flat_holes_get_the_plane_their_edges_imply() {
        let Striped {
            w,
            h,
            image,
            mut disparity,
            mut std,
        } = striped();
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

    /// A matched pixel that disagrees with the plane its edges imply (a value the penalties
    /// carried into a flat band, 3 px off) gets σ_d of at least half the disagreement; the
    /// edges that agree with their plane keep their σ_d, and so does a pixel with no plane.
    #[test]
    fn a_value_off_its_plane_is_as_unsure_as_the_disagreement() {
        let Striped {
            w,
            h,
            image,
            mut disparity,
            mut std,
        } = striped();
        // A carried value inside a flat band, and one where no plane reaches (no edge to its
        // right).
        let (x, y) = (45, 40);
        disparity[y * w + x] = truth(x, y) + 3.0;
        std[y * w + x] = 0.4;
        disparity[40 * w + 155] = truth(155, 40) + 3.0;
        std[40 * w + 155] = 0.4;
        let left = Gray::new(w, h, image);
        let filled = fill(&mut disparity, &mut std, w, &left, 64);
        assert!(!filled[y * w + x]);
        assert!((disparity[y * w + x] - truth(x, y) - 3.0).abs() < 1e-6);
        let expected = (0.4f32 * 0.4 + 1.5 * 1.5).sqrt();
        assert!(
            (std[y * w + x] - expected).abs() < 0.02,
            "{}",
            std[y * w + x]
        );
        assert!(
            (std[40 * w + 61] - 0.3).abs() < 0.01,
            "{}",
            std[40 * w + 61]
        );
        assert_eq!(std[40 * w + 155], 0.4);
    }

    /// Flat bands wider than the window (stripes every 70 px, 160 px tall): a carried value
    /// at a band's middle, 33 px from its edges, gets its plane from the window twice as wide,
    /// and σ_d of half its disagreement with it; a hole there is filled with the plane's
    /// value. Bands wider than both windows (every 200 px) get neither.
    #[test]
    fn a_flat_area_wider_than_the_window_gets_the_wide_windows_plane() {
        for (period, reached) in [(70, true), (200, false)] {
            let Striped {
                w,
                h,
                image,
                mut disparity,
                mut std,
            } = striped_every(period, (2 * period + 4, 160));
            let (x, y) = (period + 2 + period / 2, 80);
            disparity[y * w + x] = truth(x, y) + 3.0;
            std[y * w + x] = 0.4;
            let hole = (x - 1, y);
            let left = Gray::new(w, h, image);
            let filled = fill(&mut disparity, &mut std, w, &left, 64);
            let expected = (0.4f32 * 0.4 + 1.5 * 1.5).sqrt();
            let i = hole.1 * w + hole.0;
            if reached {
                assert!(
                    (std[y * w + x] - expected).abs() < 0.02,
                    "{}",
                    std[y * w + x]
                );
                assert!(filled[i] && (disparity[i] - truth(hole.0, hole.1)).abs() < 0.01);
            } else {
                assert_eq!(std[y * w + x], 0.4);
                assert!(!filled[i] && disparity[i].is_nan());
            }
        }
    }

    /// The support may scatter off its plane as much as its own σ_d say, up to a pixel: edges
    /// off by ±0.8 px fit when their σ_d is 0.5 px (a noisy photograph's), not when it is
    /// 0.3 px (a clean pair's); edges off by ±1.2 px never do.
    #[test]
    fn the_support_scatters_as_its_sigma_says() {
        let Striped { w, h, image, .. } = striped();
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
