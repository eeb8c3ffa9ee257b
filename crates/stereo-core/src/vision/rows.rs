//! Do the rows line up? A check on a pair sent as rectified: strong corners of the left image
//! are looked for in the right image over the disparity range and rows up and down, and the
//! rows they are found on say whether the pair was rectified.
//!
//! A rectified pair has every match on its own row (to a few tenths of a pixel); a raw one has
//! its matches rows apart (a camera turned by 1° moves its image by f·π/180 ≈ 17 px at
//! f = 1000, and rolled by 1° moves the sides of a 1280-px frame 11 px up and down), while its
//! census matcher may still match a fair share of pixels on the wrong row. Only corners count,
//! where both the column and the row of a match are defined (the smaller eigenvalue of the
//! gradients' structure tensor, as Shi and Tomasi's), one per cell of a grid so that they spread
//! over the image; and only their unambiguous matches (a normalised cross-correlation of at
//! least [`MIN_SCORE`], clearly above any other peak).
//!
//! Raw frames can be tens of rows apart, so the search runs coarse to fine: both images are
//! halved until about [`COARSE_HEIGHT`] rows remain, the corners are found and matched there
//! over the whole (scaled) disparity range and [`SEARCH_ROWS`] rows either way (a twelfth of
//! the image's height or so), and each match is followed down the pyramid within 2 px at each
//! level, to a sub-pixel row at full size. A few milliseconds whatever the size and range, the corners
//! side by side on the cores.

use rayon::prelude::*;

use super::Gray;

/// The patch compared around each corner: `(2·RADIUS + 1)²` pixels.
const RADIUS: usize = 5;
/// How many rows up and down a match is looked for at the coarsest level.
pub const SEARCH_ROWS: i32 = 10;
/// The coarsest level has at least this many rows (when the image has).
pub const COARSE_HEIGHT: usize = 120;
/// The grid of cells that each give at most one corner.
const CELLS: (usize, usize) = (8, 6);
/// The normalised cross-correlation a match needs to count.
const MIN_SCORE: f32 = 0.85;
/// How far the best peak must stand above the best one elsewhere (more than a pixel away).
const MIN_MARGIN: f32 = 0.03;
/// How far (in pixels of a level) a match is looked for around the coarser level's.
const FOLLOW: i32 = 2;

/// What the corners found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowOffsets {
    /// The corners whose match counted.
    pub features: usize,
    /// The median of their matches' row offsets, in pixels (sub-pixel, unsigned).
    pub median_offset: f64,
    /// The farthest rows searched either way, in pixels.
    pub searched_rows: i32,
}

/// Finds the left image's corners in the right image over disparities `min_d..=max_d` and
/// rows up and down (about a twelfth of the height, at least [`SEARCH_ROWS`]). `None` when the
/// images differ in size, are too small for the search, or no corner matched unambiguously.
pub fn row_offsets(left: &Gray, right: &Gray, (min_d, max_d): (i32, i32)) -> Option<RowOffsets> {
    let (w, h) = (left.width, left.height);
    let side = 2 * RADIUS + 1;
    if right.width != w
        || right.height != h
        || h < side + 2
        || w < side + 2
        || left.data.len() != w * h
        || right.data.len() != w * h
        || min_d > max_d
    {
        return None;
    }
    let (lefts, rights) = pyramid(left, right);
    let searched_rows = SEARCH_ROWS * (1i32 << lefts.len());
    let mut offsets: Vec<f64> = trace(left, right, (&lefts, &rights), (min_d, max_d), CELLS)
        .into_iter()
        .map(|t| (t.row * f64::from(1i32 << t.level)).abs())
        .collect();
    if offsets.is_empty() {
        return None;
    }
    offsets.sort_by(f64::total_cmp);
    Some(RowOffsets {
        features: offsets.len(),
        median_offset: offsets[offsets.len() / 2],
        searched_rows,
    })
}

/// The halved levels of an image, down to about [`COARSE_HEIGHT`] rows (a third of its
/// pixels more, at most).
pub(super) fn pyramid(left: &Gray, right: &Gray) -> (Vec<Gray>, Vec<Gray>) {
    let side = 2 * RADIUS + 1;
    let (mut lefts, mut rights): (Vec<Gray>, Vec<Gray>) = (Vec::new(), Vec::new());
    loop {
        let (l, r) = (lefts.last().unwrap_or(left), rights.last().unwrap_or(right));
        if l.height / 2 < COARSE_HEIGHT || l.width / 2 < 4 * side {
            break;
        }
        let (l, r) = rayon::join(|| halve(l), || halve(r));
        lefts.push(l);
        rights.push(r);
    }
    (lefts, rights)
}

/// A corner of the coarsest level followed down the pyramid.
#[derive(Debug, Clone, Copy)]
pub(super) struct Traced {
    /// The corner at the finest level it was followed to (pixels of that level).
    pub x: usize,
    pub y: usize,
    /// The match there: its whole disparity and row offset, and the row to a fraction.
    pub d: i32,
    pub dy: i32,
    pub row: f64,
    /// That level (0: full size).
    pub level: usize,
}

/// The strongest corner of each of `cells` in the coarsest level, matched there over the
/// scaled range and [`SEARCH_ROWS`] rows either way, and each followed down the levels
/// (`lefts`, `rights`: [`pyramid`]'s) within [`FOLLOW`] px, as far as a clear peak holds.
pub(super) fn trace(
    left: &Gray,
    right: &Gray,
    (lefts, rights): (&[Gray], &[Gray]),
    (min_d, max_d): (i32, i32),
    cells: (usize, usize),
) -> Vec<Traced> {
    let level = |level: usize| match level {
        0 => (left, right),
        n => (&lefts[n - 1], &rights[n - 1]),
    };
    let levels = lefts.len();
    let scale = 1i32 << levels;
    let (coarse_l, coarse_r) = level(levels);
    // The disparities at the coarsest level: the scaled range, widened either way by as many
    // columns as rows are searched, since a raw pair is as far off in its columns (its
    // principal points and rotations move both).
    let range = (
        min_d.div_euclid(scale) - SEARCH_ROWS,
        max_d.div_euclid(scale) + i32::from(max_d.rem_euclid(scale) != 0) + SEARCH_ROWS,
    );
    // The corners side by side on the cores.
    corners(coarse_l, cells)
        .into_par_iter()
        .filter_map(|(x, y)| {
            let found = search(
                coarse_l,
                coarse_r,
                (x, y),
                range,
                (-SEARCH_ROWS, SEARCH_ROWS),
                true,
            )?;
            let mut traced = Traced {
                x,
                y,
                d: found.d,
                dy: found.dy,
                row: found.row,
                level: levels,
            };
            for finer in (0..levels).rev() {
                // The same place a level finer: the centre of the coarser pixel.
                let (x, y) = (2 * traced.x + 1, 2 * traced.y + 1);
                let (d, dy) = (2 * traced.d, 2 * traced.dy);
                let (l, r) = level(finer);
                match search(
                    l,
                    r,
                    (x, y),
                    (d - FOLLOW, d + FOLLOW),
                    (dy - FOLLOW, dy + FOLLOW),
                    false,
                ) {
                    Some(peak) => {
                        traced = Traced {
                            x,
                            y,
                            d: peak.d,
                            dy: peak.dy,
                            row: peak.row,
                            level: finer,
                        };
                    }
                    // No texture or no clear peak here: the coarser level's answer stands.
                    None => break,
                }
            }
            Some(traced)
        })
        .collect()
}

/// The image at half the size, each pixel the mean of a 2 × 2 block.
fn halve(img: &Gray) -> Gray {
    let (w, h) = (img.width / 2, img.height / 2);
    let mut data = Vec::with_capacity(w * h);
    for y in 0..h {
        let (top, bottom) = (
            &img.data[2 * y * img.width..][..2 * w],
            &img.data[(2 * y + 1) * img.width..][..2 * w],
        );
        data.extend(
            top.as_chunks::<2>()
                .0
                .iter()
                .zip(bottom.as_chunks::<2>().0)
                .map(|(t, b)| {
                    let sum = u32::from(t[0]) + u32::from(t[1]) + u32::from(b[0]) + u32::from(b[1]);
                    ((sum + 2) / 4) as u16
                }),
        );
    }
    Gray::new(w, h, data)
}

/// The strongest corner of each grid cell (a patch's width from the borders), by the smaller
/// eigenvalue of the structure tensor over a 7 × 7 window, sampled every few pixels; cells
/// without texture give none.
///
/// The tensor's three sums over each window come from running sums of the gradients'
/// products (whole numbers, so exact whatever the order): a column sum of 7 rows kept for
/// every column, then 7 columns of it a candidate, where each window summed its 49 products.
pub(super) fn corners(img: &Gray, cells: (usize, usize)) -> Vec<(usize, usize)> {
    const WINDOW: usize = 3;
    const SIDE: usize = 2 * WINDOW + 1;
    let (w, h) = (img.width, img.height);
    let (x0, x1, y0, y1) = (RADIUS + 1, w - RADIUS - 1, RADIUS + 1, h - RADIUS - 1);
    // About 12 000 candidates whatever the size (250 a cell).
    let step = (((x1 - x0) * (y1 - y0)) as f64 / 12_000.0).sqrt().max(1.0) as usize;
    let at = |x: usize, y: usize| i64::from(img.data[y * w + x]);
    // The gradients' products (central differences) at row `v`, columns `x0 − WINDOW ..
    // x1 + WINDOW`, added to (`sign` 1) or taken from (−1) the columns' sums.
    let (c0, c1) = (x0 - WINDOW, x1 + WINDOW);
    let mut columns = vec![[0i64; 3]; c1 - c0];
    let add_row = |columns: &mut [[i64; 3]], v: usize, sign: i64| {
        for (u, sums) in (c0..c1).zip(columns.iter_mut()) {
            let gx = at(u + 1, v) - at(u - 1, v);
            let gy = at(u, v + 1) - at(u, v - 1);
            sums[0] += sign * gx * gx;
            sums[1] += sign * gx * gy;
            sums[2] += sign * gy * gy;
        }
    };
    // Central differences in grey levels of 8 bits: the products scaled by 1 / 257².
    let scale = 1.0 / (257.0f64 * 257.0);
    let mut best = vec![(0.0f32, 0usize, 0usize); cells.0 * cells.1];
    // The rows the columns' sums hold: `top .. top + SIDE`.
    let mut top = y0 - WINDOW;
    for v in top..top + SIDE {
        add_row(&mut columns, v, 1);
    }
    for y in (y0..y1).step_by(step) {
        while top < y - WINDOW {
            add_row(&mut columns, top, -1);
            add_row(&mut columns, top + SIDE, 1);
            top += 1;
        }
        for x in (x0..x1).step_by(step) {
            let mut window = [0i64; 3];
            for sums in &columns[x - WINDOW - c0..][..SIDE] {
                window[0] += sums[0];
                window[1] += sums[1];
                window[2] += sums[2];
            }
            let [xx, xy, yy] = window.map(|s| (s as f64 * scale) as f32);
            let half_trace = 0.5 * (xx + yy);
            let min_eigen = half_trace - (0.25 * (xx - yy) * (xx - yy) + xy * xy).sqrt();
            let cell = (y - y0) * cells.1 / (y1 - y0) * cells.0 + (x - x0) * cells.0 / (x1 - x0);
            if min_eigen > best[cell].0 {
                best[cell] = (min_eigen, x, y);
            }
        }
    }
    // A gradient of a few grey levels a pixel over the window: texture, not noise.
    let floor = (SIDE * SIDE) as f32 * 4.0 * 4.0;
    best.into_iter()
        .filter(|&(s, _, _)| s > floor)
        .map(|(_, x, y)| (x, y))
        .collect()
}

/// The best match of one patch.
#[derive(Debug, Clone, Copy)]
pub(super) struct Peak {
    /// Its disparity and row offset, in whole pixels.
    pub d: i32,
    pub dy: i32,
    /// The row offset to a fraction of a pixel.
    pub row: f64,
}

/// The left patch at `(x, y)` looked for in the right image over disparities `d_lo..=d_hi`
/// and row offsets `dy_lo..=dy_hi` (both cut to where the patches fit). `None` when the patch
/// has no texture, the best score is under [`MIN_SCORE`], or (`unique`) another peak more
/// than a pixel away comes within [`MIN_MARGIN`] of it, or (not `unique`, following a coarser
/// level) the best lies on the edge of the window.
///
/// The score is the normalised cross-correlation. With the left patch made zero-mean, its
/// dot product with a right patch needs no right mean, and each right patch's norm comes from
/// running sums over the searched region: one multiply-add per pixel and candidate.
pub(super) fn search(
    left: &Gray,
    right: &Gray,
    (x, y): (usize, usize),
    (d_lo, d_hi): (i32, i32),
    (dy_lo, dy_hi): (i32, i32),
    unique: bool,
) -> Option<Peak> {
    let side = 2 * RADIUS + 1;
    let n = (side * side) as f64;
    let (w, h) = (left.width as i64, left.height as i64);
    let (x, y, r) = (x as i64, y as i64, RADIUS as i64);
    if x < r || y < r || x + r >= w || y + r >= h {
        return None;
    }
    // The candidates whose right patch lies inside the image: x − d ± r and y + dy ± r.
    let d_lo = i64::from(d_lo).max(x + r + 1 - w);
    let d_hi = i64::from(d_hi).min(x - r);
    let dy_lo = i64::from(dy_lo).max(r - y);
    let dy_hi = i64::from(dy_hi).min(h - 1 - r - y);
    if d_lo > d_hi || dy_lo > dy_hi {
        return None;
    }
    let (cols, rows) = ((d_hi - d_lo + 1) as usize, (dy_hi - dy_lo + 1) as usize);
    // The left patch, zero-mean and of unit norm.
    let wu = left.width;
    let mut reference = Vec::with_capacity(side * side);
    for v in (y - r) as usize..=(y + r) as usize {
        let row = &left.data[v * wu + (x - r) as usize..][..side];
        reference.extend(row.iter().map(|&p| f64::from(p) / 257.0));
    }
    let mean = reference.iter().sum::<f64>() / n;
    reference.iter_mut().for_each(|v| *v -= mean);
    let norm = reference.iter().map(|v| v * v).sum::<f64>().sqrt();
    if norm < 1e-3 {
        return None;
    }
    let reference: Vec<f32> = reference.iter().map(|v| (v / norm) as f32).collect();
    // The right region searched: columns x − d_hi − r ..= x − d_lo + r, rows
    // y + dy_lo − r ..= y + dy_hi + r.
    let (rx0, rw) = ((x - d_hi - r) as usize, cols + 2 * RADIUS);
    let (ry0, rh) = ((y + dy_lo - r) as usize, rows + 2 * RADIUS);
    let mut region = Vec::with_capacity(rw * rh);
    for v in ry0..ry0 + rh {
        region.extend(
            right.data[v * wu + rx0..][..rw]
                .iter()
                .map(|&p| f32::from(p) / 257.0),
        );
    }
    // Sums and sums of squares over every patch of the region: along the rows, then columns.
    let (mut row_sums, mut row_squares) = (vec![0.0f64; cols * rh], vec![0.0f64; cols * rh]);
    for v in 0..rh {
        let line = &region[v * rw..][..rw];
        let (mut s, mut q) = (0.0f64, 0.0f64);
        for &p in &line[..side] {
            s += f64::from(p);
            q += f64::from(p) * f64::from(p);
        }
        for u in 0..cols {
            row_sums[v * cols + u] = s;
            row_squares[v * cols + u] = q;
            if u + side < rw {
                let (add, drop) = (f64::from(line[u + side]), f64::from(line[u]));
                s += add - drop;
                q += add * add - drop * drop;
            }
        }
    }
    // scores[row · cols + i]: row 0 is dy_lo, i = 0 the largest disparity.
    // The dot products of a row of candidates at once, a line of the patch at a time: each
    // candidate's products summed in the same order as one at a time (a line's, then the
    // lines'), with the candidates in the vector lanes.
    let mut scores = vec![-1.0f32; cols * rows];
    let (mut dots, mut line_dots) = (vec![0.0f32; cols], vec![0.0f32; cols]);
    let (mut sums, mut squares) = (vec![0.0f64; cols], vec![0.0f64; cols]);
    for row in 0..rows {
        dots.fill(0.0);
        for (k, line) in reference.chunks_exact(side).enumerate() {
            let patches = &region[(row + k) * rw..][..rw];
            // −0.0: where a one-at-a-time `sum::<f32>()` starts, so that the sums agree bit for bit.
            line_dots.fill(-0.0);
            for (j, &a) in line.iter().enumerate() {
                for (dot, &b) in line_dots.iter_mut().zip(&patches[j..j + cols]) {
                    *dot += a * b;
                }
            }
            for (dot, &line_dot) in dots.iter_mut().zip(&line_dots) {
                *dot += line_dot;
            }
        }
        // The patches' sums and sums of squares, the candidates in the lanes again.
        sums.fill(0.0);
        squares.fill(0.0);
        for v in row..row + side {
            let line = v * cols..(v + 1) * cols;
            for (s, &a) in sums.iter_mut().zip(&row_sums[line.clone()]) {
                *s += a;
            }
            for (q, &b) in squares.iter_mut().zip(&row_squares[line]) {
                *q += b;
            }
        }
        for (u, (&s, &q)) in sums.iter().zip(&squares).enumerate() {
            let variance = q - s * s / n;
            if variance > 1e-6 {
                scores[row * cols + u] = (f64::from(dots[u]) / variance.sqrt()) as f32;
            }
        }
    }
    let (best, &top) = scores
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    let (row, col) = (best / cols, best % cols);
    if top < MIN_SCORE {
        return None;
    }
    if unique {
        let second = scores
            .iter()
            .enumerate()
            .filter(|&(i, _)| (i / cols).abs_diff(row) > 1 || (i % cols).abs_diff(col) > 1)
            .map(|(_, &s)| s)
            .fold(-1.0f32, f32::max);
        if top - second < MIN_MARGIN {
            return None;
        }
    } else if row == 0 || col == 0 || row + 1 == rows || col + 1 == cols {
        return None;
    }
    // A parabola through the row's neighbours for the sub-pixel offset.
    let dy = dy_lo + row as i64;
    let fraction = if row > 0 && row + 1 < rows {
        let (a, b, c) = (
            f64::from(scores[(row - 1) * cols + col]),
            f64::from(top),
            f64::from(scores[(row + 1) * cols + col]),
        );
        let curvature = a - 2.0 * b + c;
        if curvature < 0.0 {
            (0.5 * (a - c) / curvature).clamp(-0.5, 0.5)
        } else {
            0.0
        }
    } else {
        0.0
    };
    Some(Peak {
        d: (d_hi - col as i64) as i32,
        dy: dy as i32,
        row: dy as f64 + fraction,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A textured image (blurred random blocks) of `w × h`, and the same scene as a right
    /// camera sees it: moved by `dx` columns and down by `dy` rows, and turned by `roll`
    /// radians about the image's centre.
    fn pair(w: usize, h: usize, dx: f64, dy: f64, roll: f64) -> (Gray, Gray) {
        let (bw, bh) = (w / 4 + 40, h / 4 + 40);
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut blocks = vec![0u16; bw * bh];
        for b in &mut blocks {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            *b = (state % 256) as u16 * 257;
        }
        let scene = |x: f64, y: f64| -> f64 {
            // Bilinear between the 4-px blocks (offset so that x, y ≥ −80 stay inside):
            // smooth enough to correlate, sharp corners.
            let (fx, fy) = ((x + 80.0).max(0.0) / 4.0, (y + 80.0).max(0.0) / 4.0);
            let (ix, iy) = ((fx as usize).min(bw - 2), (fy as usize).min(bh - 2));
            let (tx, ty) = ((fx - ix as f64).min(1.0), (fy - iy as f64).min(1.0));
            let b = |i: usize, j: usize| f64::from(blocks[j * bw + i]);
            (1.0 - ty) * ((1.0 - tx) * b(ix, iy) + tx * b(ix + 1, iy))
                + ty * ((1.0 - tx) * b(ix, iy + 1) + tx * b(ix + 1, iy + 1))
        };
        let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
        let (sin, cos) = roll.sin_cos();
        let mut l = Vec::with_capacity(w * h);
        let mut r = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f64, y as f64);
                l.push(scene(xf, yf) as u16);
                // The right pixel (x, y) sees the scene point the left saw at
                // rot⁻¹((x, y) − c) + c + (dx, −dy).
                let (u, v) = (xf - cx, yf - cy);
                let (sx, sy) = (cos * u + sin * v + cx, -sin * u + cos * v + cy);
                r.push(scene(sx + dx, sy - dy) as u16);
            }
        }
        (Gray::new(w, h, l), Gray::new(w, h, r))
    }

    /// The corners taken from the running sums are each cell's strongest by the structure
    /// tensor summed pixel by pixel over its 7 × 7 window, on a pair sampled at every pixel
    /// and on one large enough to be sampled every few.
    #[test]
    fn corners_are_each_cells_strongest_by_the_windows_own_sums() {
        for (w, h) in [(320, 240), (900, 700)] {
            let (img, _) = pair(w, h, 0.0, 0.0, 0.0);
            let (x0, x1, y0, y1) = (RADIUS + 1, w - RADIUS - 1, RADIUS + 1, h - RADIUS - 1);
            let step = (((x1 - x0) * (y1 - y0)) as f64 / 12_000.0).sqrt().max(1.0) as usize;
            let at = |x: usize, y: usize| i64::from(img.data[y * w + x]);
            let mut best = vec![(0.0f32, 0usize, 0usize); CELLS.0 * CELLS.1];
            for y in (y0..y1).step_by(step) {
                for x in (x0..x1).step_by(step) {
                    let mut sums = [0i64; 3];
                    for v in y - 3..=y + 3 {
                        for u in x - 3..=x + 3 {
                            let gx = at(u + 1, v) - at(u - 1, v);
                            let gy = at(u, v + 1) - at(u, v - 1);
                            sums[0] += gx * gx;
                            sums[1] += gx * gy;
                            sums[2] += gy * gy;
                        }
                    }
                    let [xx, xy, yy] = sums.map(|s| (s as f64 / (257.0 * 257.0)) as f32);
                    let e = 0.5 * (xx + yy) - (0.25 * (xx - yy) * (xx - yy) + xy * xy).sqrt();
                    let cell =
                        (y - y0) * CELLS.1 / (y1 - y0) * CELLS.0 + (x - x0) * CELLS.0 / (x1 - x0);
                    if e > best[cell].0 {
                        best[cell] = (e, x, y);
                    }
                }
            }
            let expected: Vec<(usize, usize)> = best
                .into_iter()
                .filter(|&(e, _, _)| e > 49.0 * 16.0)
                .map(|(_, x, y)| (x, y))
                .collect();
            assert!(
                step > 1 || w < 400,
                "the large image is sampled every {step} px"
            );
            assert!(
                expected.len() >= 40,
                "{} corners at {w} × {h}",
                expected.len()
            );
            assert_eq!(corners(&img, CELLS), expected, "{w} × {h}");
        }
    }

    /// A pair whose rows line up gives offsets of zero.
    #[test]
    fn a_rectified_pair_has_its_matches_on_their_rows() {
        let (l, r) = pair(320, 240, 12.0, 0.0, 0.0);
        let found = row_offsets(&l, &r, (0, 24)).expect("corners found");
        assert!(found.features >= 20, "{found:?}");
        assert!(found.median_offset < 0.2, "{found:?}");
    }

    /// A right image three rows lower shows as three rows.
    #[test]
    fn rows_three_apart_are_measured() {
        let (l, r) = pair(320, 240, 12.0, 3.0, 0.0);
        let found = row_offsets(&l, &r, (0, 24)).expect("corners found");
        assert!(found.features >= 20, "{found:?}");
        assert!((found.median_offset - 3.0).abs() < 0.2, "{found:?}");
    }

    /// Raw frames tens of rows apart (a camera pitched by a degree or two) are found through
    /// the pyramid: 27.5 rows on a 640 × 480 pair at 50 disparities, and a frame also rolled
    /// by 1.5° (its sides 8 px up and down more) measures between the two.
    #[test]
    fn rows_tens_apart_are_found_coarse_to_fine() {
        let (l, r) = pair(640, 480, 31.0, 27.5, 0.0);
        let found = row_offsets(&l, &r, (0, 50)).expect("corners found");
        assert!(found.searched_rows >= 40, "{found:?}");
        assert!(found.features >= 20, "{found:?}");
        assert!((found.median_offset - 27.5).abs() < 0.3, "{found:?}");
        let (l, r) = pair(640, 480, 31.0, 20.0, 1.5f64.to_radians());
        let found = row_offsets(&l, &r, (0, 50)).expect("corners found");
        assert!(found.features >= 15, "{found:?}");
        assert!((16.0..=26.0).contains(&found.median_offset), "{found:?}");
    }

    /// Ranges reaching below zero and past the image's width are searched where the patches
    /// fit, never a panic.
    #[test]
    fn negative_and_wide_ranges_are_clipped() {
        let (l, r) = pair(320, 240, 12.0, 2.0, 0.0);
        let found = row_offsets(&l, &r, (-40, 400)).expect("corners found");
        assert!((found.median_offset - 2.0).abs() < 0.2, "{found:?}");
    }

    /// Flat images, images too small for the search and pairs of two sizes give no answer,
    /// never a panic.
    #[test]
    fn flat_tiny_or_mismatched_images_give_none() {
        let flat = Gray::new(100, 80, vec![1000; 8000]);
        assert_eq!(row_offsets(&flat, &flat, (0, 16)), None);
        let tiny = Gray::new(10, 10, vec![0; 100]);
        assert_eq!(row_offsets(&tiny, &tiny, (0, 4)), None);
        let (l, _) = pair(320, 240, 0.0, 0.0, 0.0);
        assert_eq!(row_offsets(&l, &flat, (0, 16)), None);
    }
}
