//! From aggregated costs to disparities: winner-takes-all with a uniqueness test and a sub-pixel
//! fit, the right image's disparities from the same volume for the left-right check, then
//! speckle removal, a median filter and, when asked, hole filling.
//!
//! Invalid pixels are `f32::NAN` throughout.

use rayon::prelude::*;

use super::Subpixel;

/// The winners of one row of the volume.
pub struct Winners {
    /// The left image's disparity of each pixel (index into the range, sub-pixel), or NaN when
    /// it is not unique enough.
    pub left: Vec<f32>,
    /// The right image's integer disparity of each pixel (index into the range), or `u16::MAX`.
    pub right: Vec<u16>,
}

/// The windows of one row of the volume: each pixel's first index into the range, and the
/// offsets of its cells (`width + 1` of them; the row's totals start at `offsets[0]`).
#[derive(Clone, Copy)]
pub struct RowWindows<'a> {
    pub first: &'a [u16],
    pub offsets: &'a [u32],
}

impl<'a> RowWindows<'a> {
    /// Row `y` of a `width`-pixel block's windows.
    pub fn of(windows: &'a super::cost::Windows, y: usize, width: usize) -> Self {
        RowWindows {
            first: &windows.first[y * width..(y + 1) * width],
            offsets: &windows.offsets[y * width..=(y + 1) * width],
        }
    }

    /// Pixel `x`'s first index and its totals in the row, cut to the range's `count`.
    #[inline(always)]
    fn totals<'t>(&self, totals: &'t [u16], x: usize, count: usize) -> (usize, &'t [u16]) {
        let base = self.offsets[0] as usize;
        let cells = &totals[self.offsets[x] as usize - base..self.offsets[x + 1] as usize - base];
        let first = usize::from(self.first[x]);
        (
            first,
            &cells[..cells.len().min(count.saturating_sub(first))],
        )
    }
}

crate::dispatch! {
    /// Winner-takes-all over one row of aggregated costs (each pixel's window, `windows`).
    /// `uniqueness` is in percent: the best cost must beat every disparity of the window more
    /// than one step away by that margin.
    pub fn winners(
        totals: &[u16],
        windows: RowWindows,
        count: usize,
        uniqueness: u32,
        subpixel: Subpixel,
    ) -> Winners {
        let width = windows.first.len();
        let mut left = vec![f32::NAN; width];
        // The right image's winners, kept in reverse order of x: the cells of left pixel x run
        // over right pixels x − first, x − first − 1, …, which is then one forward contiguous
        // run.
        let mut right_rev = vec![u16::MAX; width];
        let mut right_cost_rev = vec![u16::MAX; width];
        for (x, out) in left.iter_mut().enumerate() {
            let (first, total) = windows.totals(totals, x, count);
            if total.is_empty() {
                continue;
            }
            let (best, best_k) = argmin(total);
            let reach = (x + 1).saturating_sub(first).min(total.len());
            if reach > 0 {
                let start = width - 1 - x + first;
                keep_smaller(
                    &mut right_cost_rev[start..start + reach],
                    &mut right_rev[start..start + reach],
                    &total[..reach],
                    first as u16,
                );
            }
            let second = min_away_from(total, best_k);
            if !unique(best, second, uniqueness) {
                continue;
            }
            *out = first as f32 + fit(total, best_k, subpixel);
        }
        right_rev.reverse();
        Winners {
            left,
            right: right_rev,
        }
    }
}

/// The smallest value and its first index, in whole SIMD registers (`(u16::MAX, 0)` when
/// empty): the least of each lane over the registers, the least of those, then the first
/// register holding it and the first lane there, from a mask of the lanes equal to it.
#[inline(always)]
fn argmin(values: &[u16]) -> (u16, usize) {
    const L: usize = super::cost::LANES;
    let whole = values.len() / L * L;
    let mut least = [u16::MAX; L];
    for chunk in values[..whole].chunks_exact(L) {
        for i in 0..L {
            least[i] = least[i].min(chunk[i]);
        }
    }
    let mut value = least.iter().copied().fold(u16::MAX, u16::min);
    let mut k = usize::MAX;
    if whole > 0 {
        for (c, chunk) in values[..whole].chunks_exact(L).enumerate() {
            let mut equal = 0u32;
            for (i, &v) in chunk.iter().enumerate() {
                equal |= u32::from(v == value) << i;
            }
            if equal != 0 {
                k = c * L + equal.trailing_zeros() as usize;
                break;
            }
        }
    }
    for (i, &v) in values.iter().enumerate().skip(whole) {
        if v < value {
            (value, k) = (v, i);
        }
    }
    (value, if k == usize::MAX { 0 } else { k })
}

/// The smallest value more than one index away from `k`, in whole SIMD registers
/// (`u16::MAX` when there is none).
#[inline(always)]
fn min_away_from(values: &[u16], k: usize) -> u16 {
    const L: usize = super::cost::LANES;
    // `i` is within one of `k` when `i − (k − 1)` (wrapping) is at most 2.
    let near = (k as u16).wrapping_sub(1);
    let mut least = [u16::MAX; L];
    let mut index = [0u16; L];
    for (i, v) in index.iter_mut().enumerate() {
        *v = i as u16;
    }
    let whole = values.len() / L * L;
    for chunk in values[..whole].chunks_exact(L) {
        for i in 0..L {
            // All ones for the three cells around `k`, which then cannot be the least.
            let hide = 0u16.wrapping_sub(u16::from(index[i].wrapping_sub(near) <= 2));
            least[i] = least[i].min(chunk[i] | hide);
        }
        for v in &mut index {
            *v += L as u16;
        }
    }
    let mut second = least.iter().copied().fold(u16::MAX, u16::min);
    for (i, &v) in values.iter().enumerate().skip(whole) {
        if i.abs_diff(k) > 1 {
            second = second.min(v);
        }
    }
    second
}

/// `costs[k] = min(costs[k], totals[k])`, and `winners[k] = first + k` where the total won, in
/// whole SIMD registers.
#[inline(always)]
fn keep_smaller(costs: &mut [u16], winners: &mut [u16], totals: &[u16], first: u16) {
    const L: usize = super::cost::LANES;
    let mut index = [0u16; L];
    for (i, v) in index.iter_mut().enumerate() {
        *v = first + i as u16;
    }
    let whole = totals.len() / L * L;
    for ((c, w), t) in costs[..whole]
        .chunks_exact_mut(L)
        .zip(winners[..whole].chunks_exact_mut(L))
        .zip(totals[..whole].chunks_exact(L))
    {
        // Branch-free, on whole registers: a mask of the lanes where the total won.
        let mut kept = [0u16; L];
        let mut won = [0u16; L];
        for i in 0..L {
            let mask = 0u16.wrapping_sub(u16::from(t[i] < c[i]));
            kept[i] = c[i].min(t[i]);
            won[i] = (index[i] & mask) | (w[i] & !mask);
        }
        c.copy_from_slice(&kept);
        w.copy_from_slice(&won);
        for v in &mut index {
            *v += L as u16;
        }
    }
    for k in whole..totals.len() {
        if totals[k] < costs[k] {
            costs[k] = totals[k];
            winners[k] = first + k as u16;
        }
    }
}

/// The sub-pixel offset of the minimum of three costs at −1, 0, +1, in (−0.5, 0.5).
pub fn offset(before: f32, at: f32, after: f32, how: Subpixel) -> f32 {
    let o = match how {
        Subpixel::Off => 0.0,
        Subpixel::Parabola => {
            let denom = before - 2.0 * at + after;
            if denom <= 0.0 {
                0.0
            } else {
                0.5 * (before - after) / denom
            }
        }
        // The equiangular (V) fit: the lines through the minimum and its higher neighbour
        // mirrored, which does not lock to whole pixels the way a parabola does on
        // absolute-difference-like costs.
        Subpixel::Equiangular => {
            let rise = (before - at).max(after - at);
            if rise <= 0.0 {
                0.0
            } else {
                0.5 * (before - after) / rise
            }
        }
    };
    o.clamp(-0.5, 0.5)
}

/// What the winner-takes-all saw at pixel `x` of a row of aggregated costs (`totals` over
/// `windows`), judged by `params`' uniqueness and left-right tests against the row's
/// right-image winners `right`, as [`winners`] and [`left_right`] judge it; the raw costs around
/// it come from the census signatures of the block (`census`, `width` pixels a row).
pub fn probe(
    totals: &[u16],
    windows: RowWindows,
    census: (&[u64], &[u64]),
    (x, y): (usize, usize),
    params: &super::Params,
    right: &[u16],
) -> super::Probe {
    let count = params.count;
    let (first, total) = windows.totals(totals, x, count);
    let (best, k) = argmin(total);
    let second = min_away_from(total, k);
    let index = first + k;
    let subpixel = first as f32 + fit(total, k, params.subpixel);
    let consistent = params
        .lr_tolerance
        .is_none_or(|tolerance| agrees(right, x, subpixel, tolerance));
    // The raw costs summed over the 5 × 5 window around the pixel, for each disparity of the
    // whole range.
    let width = windows.first.len();
    let height = census.0.len() / width.max(1);
    let mut window = vec![0u32; count];
    let mut cells = 0u32;
    for yy in y.saturating_sub(2)..(y + 3).min(height) {
        for xx in x.saturating_sub(2)..(x + 3).min(width) {
            let sig = census.0[yy * width + xx];
            let row = &census.1[yy * width..(yy + 1) * width];
            for (j, sum) in window.iter_mut().enumerate() {
                let xr = xx as i64 - i64::from(params.min_disparity) - j as i64;
                *sum += if (0..width as i64).contains(&xr) {
                    (sig ^ row[xr as usize]).count_ones()
                } else {
                    u32::from(super::cost::OUTSIDE_CENSUS)
                };
            }
            cells += 1;
        }
    }
    let mean = |sum: u32| sum as f32 / cells.max(1) as f32;
    let (local, local_index) =
        window.iter().enumerate().fold(
            (u32::MAX, 0),
            |(b, k), (i, &v)| if v < b { (v, i) } else { (b, k) },
        );
    let local_second = window
        .iter()
        .enumerate()
        .filter(|(i, _)| i.abs_diff(local_index) > 1)
        .map(|(_, &v)| v)
        .min()
        .unwrap_or(u32::MAX);
    super::Probe {
        index,
        subpixel,
        best,
        second,
        unique: unique(best, second, params.uniqueness),
        consistent,
        window_cost: mean(window[index.min(count - 1)]),
        window_mean: mean(window.iter().sum::<u32>() / count.max(1) as u32),
        window_best: mean(local),
        window_second: mean(local_second),
    }
}

/// Invalidates the pixels whose disparity disagrees with the right image's by more than
/// `tolerance` pixels (occlusions, mismatches). Disparities are indices into the range.
pub fn left_right(left: &mut [f32], right: &[u16], tolerance: f32) {
    for (x, d) in left.iter_mut().enumerate() {
        if d.is_nan() {
            continue;
        }
        if !agrees(right, x, *d, tolerance) {
            *d = f32::NAN;
        }
    }
}

/// Whether the right image's winner at the match of left pixel `x` (disparity `d`) agrees
/// with `d` within `tolerance` (disparities as indices into the range).
#[inline(always)]
fn agrees(right: &[u16], x: usize, d: f32, tolerance: f32) -> bool {
    let xr = (x as f32 - d).round();
    xr >= 0.0
        && right
            .get(xr as usize)
            .is_some_and(|&r| r != u16::MAX && (f32::from(r) - d).abs() <= tolerance)
}

/// The uniqueness test: the best cost beats `second` (the least more than one index away) by
/// `uniqueness` percent.
#[inline(always)]
fn unique(best: u16, second: u16, uniqueness: u32) -> bool {
    u32::from(second) * 100 >= u32::from(best) * (100 + uniqueness)
}

/// The winner `k` of a pixel's costs `total` with its sub-pixel offset, as an index into the
/// range (no offset at the range's ends).
#[inline(always)]
fn fit(total: &[u16], k: usize, how: Subpixel) -> f32 {
    if how == Subpixel::Off || k == 0 || k + 1 >= total.len() {
        return k as f32;
    }
    k as f32
        + offset(
            f32::from(total[k - 1]),
            f32::from(total[k]),
            f32::from(total[k + 1]),
            how,
        )
}

/// Invalidates the connected regions of fewer than `max_size` pixels whose neighbours differ by
/// at most `range` (OpenCV's `filterSpeckles`): small islands are usually mismatches.
///
/// The regions are found by union-find in horizontal bands side by side (one a core), each
/// pixel joined to its left and upper neighbours, every tree's root holding its size; then the
/// bands' regions that touch across a seam are joined, their sizes added; then every pixel
/// whose region is small is invalidated, band by band again. Which pixels go does not depend
/// on the bands.
pub fn speckles(disparity: &mut [f32], width: usize, max_size: usize, range: f32) {
    if max_size == 0 || disparity.is_empty() || width == 0 {
        return;
    }
    let height = disparity.len() / width;
    let per = height.div_ceil(rayon::current_num_threads().max(1)).max(1);
    let band = per * width;
    let n = disparity.len();
    // `parent[p]` leads to the root of p's region (a pixel index); `size[r]` is root r's region
    // size. Both `u32`: the pixel limits keep an image far below 2^32 pixels.
    let mut parent = vec![0u32; n];
    let mut size = vec![0u32; n];
    let joined = |a: f32, b: f32| (a - b).abs() <= range;
    parent
        .par_chunks_mut(band)
        .zip(size.par_chunks_mut(band))
        .zip(disparity.par_chunks(band))
        .enumerate()
        .for_each(|(b, ((parent, size), d))| {
            let offset = (b * band) as u32;
            label_band(d, width, offset, parent, size, &joined);
        });
    // The seams: the last row of each band against the first row of the next.
    for seam in (band..n).step_by(band) {
        for p in seam - width..seam {
            let q = p + width;
            if joined(disparity[p], disparity[q]) {
                unite(&mut parent, &mut size, p, q);
            }
        }
    }
    let (parent, size) = (&parent, &size);
    disparity
        .par_chunks_mut(band)
        .enumerate()
        .for_each(|(b, d)| {
            for (i, v) in d.iter_mut().enumerate() {
                if !v.is_nan() && (size[root(parent, b * band + i)] as usize) < max_size {
                    *v = f32::NAN;
                }
            }
        });
}

/// Union-find over one band of a map (`d`, `width` pixels a row; its first pixel is pixel
/// `offset` of the map): each valid pixel joined to its left and upper neighbours when
/// `joined`, and then every pixel pointed straight at its root, each root's `size` its
/// region's pixel count in the band. `parent` and `size` are the band's slices (map indices).
fn label_band(
    d: &[f32],
    width: usize,
    offset: u32,
    parent: &mut [u32],
    size: &mut [u32],
    joined: &impl Fn(f32, f32) -> bool,
) {
    let find = |parent: &mut [u32], mut p: usize| {
        // Path halving, on band-local indices.
        while parent[p] as usize != p + offset as usize {
            let up = parent[p] as usize - offset as usize;
            parent[p] = parent[up];
            p = parent[p] as usize - offset as usize;
        }
        p
    };
    for (p, &v) in d.iter().enumerate() {
        parent[p] = p as u32 + offset;
        if v.is_nan() {
            continue;
        }
        let x = p % width;
        if x > 0 && joined(v, d[p - 1]) {
            parent[p] = parent[find(parent, p - 1)];
        }
        if p >= width && joined(v, d[p - width]) {
            let (a, b) = (find(parent, p), find(parent, p - width));
            if a != b {
                // The later root joins the earlier one.
                let (lo, hi) = (a.min(b), a.max(b));
                parent[hi] = lo as u32 + offset;
            }
        }
    }
    for p in 0..d.len() {
        if !d[p].is_nan() {
            let r = find(parent, p);
            parent[p] = r as u32 + offset;
            size[r] += 1;
        }
    }
}

/// The root of pixel `p`'s region (no path compression: bands read it side by side; after
/// [`label_band`] every pixel points at its band's root, and seams add at most one step per
/// band).
fn root(parent: &[u32], mut p: usize) -> usize {
    while parent[p] as usize != p {
        p = parent[p] as usize;
    }
    p
}

/// Joins the regions of `p` and `q` across a seam, the smaller-indexed root keeping both sizes.
fn unite(parent: &mut [u32], size: &mut [u32], p: usize, q: usize) {
    let (a, b) = (root(parent, p), root(parent, q));
    if a != b {
        let (lo, hi) = (a.min(b), a.max(b));
        parent[hi] = lo as u32;
        size[lo] += size[hi];
    }
}

/// A 3 × 3 median of the valid pixels around each valid pixel (invalid ones stay invalid and
/// are not counted), which removes single-pixel outliers and keeps edges.
pub fn median(disparity: &[f32], width: usize) -> Vec<f32> {
    let height = disparity.len() / width;
    let mut out = disparity.to_vec();
    out.par_chunks_mut(width).enumerate().for_each_init(
        || (vec![true; width], Columns::new(width)),
        |(slow, columns), (y, row)| {
            slow.fill(true);
            if y > 0 && y + 1 < height {
                let at = |yy: usize| &disparity[yy * width..(yy + 1) * width];
                median_interior([at(y - 1), at(y), at(y + 1)], columns, row, slow);
            }
            let mut window = [0f32; 9];
            for x in (0..width).filter(|&x| slow[x]) {
                if row[x].is_nan() {
                    continue;
                }
                let mut n = 0;
                for yy in y.saturating_sub(1)..(y + 2).min(height) {
                    for &v in &disparity
                        [yy * width + x.saturating_sub(1)..yy * width + (x + 2).min(width)]
                    {
                        if !v.is_nan() {
                            window[n] = v;
                            n += 1;
                        }
                    }
                }
                row[x] = if n == 9 {
                    median9(window)
                } else {
                    let w = &mut window[..n];
                    w.sort_unstable_by(f32::total_cmp);
                    if n % 2 == 1 {
                        w[n / 2]
                    } else {
                        0.5 * (w[n / 2 - 1] + w[n / 2])
                    }
                };
            }
        },
    );
    out
}

/// The 25 exchanges of a 9-input sorting network (checked on all 512 inputs of zeros and ones
/// in the tests, which by the 0-1 principle proves it sorts any input), each handed to
/// `$exchange!(a, b)`, which puts the smaller of elements `a` and `b` at `a`. A macro, so that
/// every index is a constant for the vectorised median as for the scalar one.
macro_rules! sorting_network {
    ($exchange:ident) => {
        $exchange!(0, 1);
        $exchange!(3, 4);
        $exchange!(6, 7);
        $exchange!(1, 2);
        $exchange!(4, 5);
        $exchange!(7, 8);
        $exchange!(0, 1);
        $exchange!(3, 4);
        $exchange!(6, 7);
        $exchange!(0, 3);
        $exchange!(3, 6);
        $exchange!(0, 3);
        $exchange!(1, 4);
        $exchange!(4, 7);
        $exchange!(1, 4);
        $exchange!(2, 5);
        $exchange!(5, 8);
        $exchange!(2, 5);
        $exchange!(1, 3);
        $exchange!(5, 7);
        $exchange!(2, 6);
        $exchange!(4, 6);
        $exchange!(2, 4);
        $exchange!(2, 3);
        $exchange!(5, 6);
    };
}

/// Lanes of the vectorised median.
const MEDIAN_LANES: usize = 16;

crate::dispatch! {
    /// The 3 × 3 median of the valid values around a row's inner valid pixels (`rows`: above,
    /// the row, below), [`MEDIAN_LANES`] pixels at a time, written to `out`: the nine values
    /// with the invalid ones made +∞ go through a sorting network ([`sorting_network`]), and
    /// with `n` of them valid the median is the mean of sorted elements `(n − 1) / 2` and
    /// `n / 2` (one element when `n` is odd), as [`median`] defines it. Clears `slow` for the
    /// pixels it did; the others (the row's ends, a last partial chunk) are left to the caller.
    fn median_interior(
        rows: [&[f32]; 3],
        columns: &mut Columns,
        out: &mut [f32],
        slow: &mut [bool],
    ) {
        const M: usize = MEDIAN_LANES;
        let inner = out.len().saturating_sub(2);
        columns.sort(rows);
        let Columns { low, mid, high, holes } = columns;
        for base in (0..inner / M * M).step_by(M) {
            // Every value of the chunk's nine neighbourhoods valid (most chunks): the median of
            // each is the median of its columns' greatest low, median middle and least high
            // (exact for 3 × 3, and the same element the network below picks).
            if holes[base..base + M + 2].iter().all(|&h| !h) {
                let out = &mut out[base + 1..base + 1 + M];
                for (i, out) in out.iter_mut().enumerate() {
                    let x = base + i;
                    let lo = max(max(low[x], low[x + 1]), low[x + 2]);
                    let hi = min(min(high[x], high[x + 1]), high[x + 2]);
                    let md = median3(mid[x], mid[x + 1], mid[x + 2]);
                    *out = median3(lo, md, hi);
                }
                slow[base + 1..base + 1 + M].fill(false);
                continue;
            }
            let mut p = [[0f32; M]; 9];
            for (k, row) in rows.iter().enumerate() {
                for dx in 0..3 {
                    p[k * 3 + dx].copy_from_slice(&row[base + dx..base + dx + M]);
                }
            }
            let centre = p[4];
            let mut valid = [0u32; M];
            for q in &mut p {
                for i in 0..M {
                    let ok = !q[i].is_nan();
                    valid[i] += u32::from(ok);
                    q[i] = if ok { q[i] } else { f32::INFINITY };
                }
            }
            macro_rules! exchange {
                ($a:literal, $b:literal) => {
                    let (x, y) = (p[$a], p[$b]);
                    p[$a] = std::array::from_fn(|i| if x[i] < y[i] { x[i] } else { y[i] });
                    p[$b] = std::array::from_fn(|i| if x[i] < y[i] { y[i] } else { x[i] });
                };
            }
            sorting_network!(exchange);
            let mut lo = [0f32; M];
            let mut hi = [0f32; M];
            for (k, sorted) in p.iter().enumerate() {
                for i in 0..M {
                    let n = valid[i] as usize;
                    lo[i] = if k + 1 == n.div_ceil(2) { sorted[i] } else { lo[i] };
                    hi[i] = if k == n / 2 { sorted[i] } else { hi[i] };
                }
            }
            let out = &mut out[base + 1..base + 1 + M];
            for i in 0..M {
                out[i] = if centre[i].is_nan() {
                    f32::NAN
                } else {
                    0.5 * (lo[i] + hi[i])
                };
            }
            slow[base + 1..base + 1 + M].fill(false);
        }
    }
}

/// A row's 3-pixel columns (the pixel above, itself, below) sorted: the least, middle and
/// greatest of each, and whether any of the three is invalid. Kept per thread across rows.
struct Columns {
    low: Vec<f32>,
    mid: Vec<f32>,
    high: Vec<f32>,
    holes: Vec<bool>,
}

impl Columns {
    fn new(width: usize) -> Columns {
        Columns {
            low: vec![0.0; width],
            mid: vec![0.0; width],
            high: vec![0.0; width],
            holes: vec![false; width],
        }
    }

    /// Sorts the columns of `rows` (above, the row, below). A column holding an invalid value
    /// is marked in `holes`, its sorted values meaningless.
    #[inline(always)]
    fn sort(&mut self, [above, row, below]: [&[f32]; 3]) {
        let n = row.len();
        let columns = self.low[..n]
            .iter_mut()
            .zip(&mut self.mid[..n])
            .zip(&mut self.high[..n])
            .zip(&mut self.holes[..n]);
        for ((((low, mid), high), hole), ((&a, &b), &c)) in
            columns.zip(above.iter().zip(row).zip(below))
        {
            *hole = a.is_nan() | b.is_nan() | c.is_nan();
            let (a, b) = (min(a, b), max(a, b));
            let (b, c) = (min(b, c), max(b, c));
            let (a, b) = (min(a, b), max(a, b));
            (*low, *mid, *high) = (a, b, c);
        }
    }
}

/// The smaller of two values none of which is NaN, as one instruction (`f32::min` also
/// checks for NaN).
#[inline(always)]
fn min(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// The greater of two values none of which is NaN, as one instruction.
#[inline(always)]
fn max(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// The median of three values (none NaN).
#[inline(always)]
fn median3(a: f32, b: f32, c: f32) -> f32 {
    max(min(a, b), min(max(a, b), c))
}

/// The median of 9 values (none NaN) by the sorting network ([`sorting_network`]).
fn median9(mut p: [f32; 9]) -> f32 {
    macro_rules! exchange {
        ($a:literal, $b:literal) => {
            (p[$a], p[$b]) = (p[$a].min(p[$b]), p[$a].max(p[$b]));
        };
    }
    sorting_network!(exchange);
    p[4]
}

/// Fills each invalid pixel with the smaller of the nearest valid disparities to its left and
/// right on its row (the background, in an occlusion), as Middlebury's evaluation does. A row
/// with no valid pixel stays invalid.
pub fn fill(disparity: &mut [f32], width: usize) {
    for row in disparity.chunks_exact_mut(width) {
        let mut left_valid = vec![f32::NAN; width];
        let mut last = f32::NAN;
        for (x, &d) in row.iter().enumerate() {
            if !d.is_nan() {
                last = d;
            }
            left_valid[x] = last;
        }
        let mut next = f32::NAN;
        for x in (0..width).rev() {
            if !row[x].is_nan() {
                next = row[x];
                continue;
            }
            row[x] = match (left_valid[x].is_nan(), next.is_nan()) {
                (false, false) => left_valid[x].min(next),
                (false, true) => left_valid[x],
                (true, false) => next,
                (true, true) => f32::NAN,
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both fits find the exact minimum of a symmetric curve and stay within half a pixel.
    #[test]
    fn subpixel_fits() {
        for how in [Subpixel::Parabola, Subpixel::Equiangular] {
            assert_eq!(offset(10.0, 2.0, 10.0, how), 0.0);
            assert!(offset(4.0, 2.0, 10.0, how) < 0.0);
            assert!(offset(0.0, 0.0, 100.0, how).abs() <= 0.5);
        }
        // A V of slope 4 with its minimum at +0.25 has costs 5, 1, 3: the V fit is exact.
        assert!((offset(5.0, 1.0, 3.0, Subpixel::Equiangular) - 0.25).abs() < 1e-6);
    }

    /// The filter, vectorised or not, gives each valid pixel the median of the valid values
    /// around it (the mean of the middle two for an even count) and leaves invalid ones
    /// invalid, on maps with many holes, few and none (where most or all chunks take the
    /// sorted columns), in the portable and the AVX2 build.
    #[test]
    fn median_filter_matches_its_definition() {
        let (w, h) = (53, 9);
        let mut rng = crate::vision::synthetic::Rng::new(12345);
        // Invalid often enough that windows with every count of valid values occur; rarely,
        // so that most chunks take the column path; and never.
        for share in [0.3, 0.01, 0.0] {
            let map: Vec<f32> = (0..w * h)
                .map(|_| {
                    let v = rng.unit();
                    if v < share { f32::NAN } else { v * 128.0 }
                })
                .collect();
            let expected: Vec<f32> = (0..w * h)
                .map(|i| {
                    let (x, y) = (i % w, i / w);
                    if map[i].is_nan() {
                        return f32::NAN;
                    }
                    let mut v: Vec<f32> = (y.saturating_sub(1)..(y + 2).min(h))
                        .flat_map(|yy| {
                            (x.saturating_sub(1)..(x + 2).min(w)).map(move |xx| (xx, yy))
                        })
                        .map(|(xx, yy)| map[yy * w + xx])
                        .filter(|v| !v.is_nan())
                        .collect();
                    v.sort_by(f32::total_cmp);
                    let n = v.len();
                    if n % 2 == 1 {
                        v[n / 2]
                    } else {
                        0.5 * (v[n / 2 - 1] + v[n / 2])
                    }
                })
                .collect();
            if share > 0.1 {
                assert!(map.iter().filter(|v| v.is_nan()).count() > 10);
            }
            for simd in [false, true] {
                crate::vision::simd::use_simd(simd);
                let got = median(&map, w);
                for (i, (g, e)) in got.iter().zip(&expected).enumerate() {
                    assert_eq!(g.to_bits(), e.to_bits(), "{share}, SIMD {simd}, pixel {i}");
                }
            }
        }
    }

    /// The uniqueness test's runner-up skips the winner and its two neighbours, whatever the
    /// length (whole registers and a tail) and wherever the winner is.
    #[test]
    fn runner_up_skips_the_winners_neighbours() {
        for len in [3usize, 16, 40, 64] {
            let values: Vec<u16> = (0..len).map(|i| (1000 - 7 * i) as u16).collect();
            for k in 0..len {
                let expected = (0..len)
                    .filter(|i| i.abs_diff(k) > 1)
                    .map(|i| values[i])
                    .min()
                    .unwrap_or(u16::MAX);
                assert_eq!(min_away_from(&values, k), expected, "len {len} k {k}");
            }
        }
    }

    /// The network sorts every input of zeros and ones, so (by the 0-1 principle) every input.
    #[test]
    fn sorting_network_sorts_every_input_of_zeros_and_ones() {
        for bits in 0u32..512 {
            let mut p: [u8; 9] = std::array::from_fn(|i| ((bits >> i) & 1) as u8);
            let mut expected = p;
            expected.sort_unstable();
            macro_rules! exchange {
                ($a:literal, $b:literal) => {
                    (p[$a], p[$b]) = (p[$a].min(p[$b]), p[$a].max(p[$b]));
                };
            }
            sorting_network!(exchange);
            assert_eq!(p, expected, "input {bits:09b}");
        }
    }

    /// The network finds the median of every arrangement of distinct values.
    #[test]
    fn median_of_nine() {
        let mut rng = crate::vision::synthetic::Rng::new(3);
        for _ in 0..2000 {
            let mut v = [0f32; 9];
            for x in &mut v {
                *x = rng.unit();
            }
            let mut sorted = v;
            sorted.sort_by(f32::total_cmp);
            assert_eq!(median9(v), sorted[4]);
        }
    }

    /// The vectorised argmin finds the first smallest value, past whole registers too.
    #[test]
    fn argmin_finds_the_first_minimum() {
        let mut v: Vec<u16> = (0..40).map(|i| 100 - i).collect();
        assert_eq!(argmin(&v), (61, 39));
        v[17] = 3;
        v[33] = 3;
        assert_eq!(argmin(&v), (3, 17));
        assert_eq!(argmin(&[]), (u16::MAX, 0));
    }

    /// An island smaller than the window is removed, a large region is kept.
    #[test]
    fn speckles_remove_small_islands() {
        let mut d = vec![10.0f32; 100];
        d[55] = 30.0;
        speckles(&mut d, 10, 5, 1.0);
        assert!(d[55].is_nan());
        assert_eq!(d.iter().filter(|v| v.is_nan()).count(), 1);
    }

    /// Islands on the image's edges are measured like any other: a 2-pixel one in a corner
    /// goes, a 6-pixel one along the right edge stays, and holes stay holes.
    #[test]
    fn speckles_at_the_edges() {
        let (w, h) = (12, 7);
        let mut d = vec![10.0f32; w * h];
        (d[6 * w], d[6 * w + 1]) = (40.0, 40.5);
        for y in 1..4 {
            (d[y * w + w - 2], d[y * w + w - 1]) = (25.0, 25.0);
        }
        d[3 * w + 4] = f32::NAN;
        speckles(&mut d, w, 5, 1.0);
        assert!(d[6 * w].is_nan() && d[6 * w + 1].is_nan());
        assert_eq!(d[2 * w + w - 1], 25.0);
        assert!(d[3 * w + 4].is_nan());
        assert_eq!(d.iter().filter(|v| v.is_nan()).count(), 3);
    }

    /// The filter by bands removes exactly the regions a flood fill over the whole map finds
    /// too small, on maps of many small regions and holes, with one band and with many.
    #[test]
    fn speckles_by_bands_match_a_flood_fill() {
        fn flood(d: &[f32], w: usize, max_size: usize, range: f32) -> Vec<f32> {
            let h = d.len() / w;
            let mut out = d.to_vec();
            let mut seen = vec![false; d.len()];
            for start in 0..d.len() {
                if seen[start] || d[start].is_nan() {
                    continue;
                }
                seen[start] = true;
                let (mut stack, mut members) = (vec![start], Vec::new());
                while let Some(p) = stack.pop() {
                    members.push(p);
                    let (x, y) = (p % w, p / w);
                    let mut near = Vec::new();
                    if x > 0 {
                        near.push(p - 1);
                    }
                    if x + 1 < w {
                        near.push(p + 1);
                    }
                    if y > 0 {
                        near.push(p - w);
                    }
                    if y + 1 < h {
                        near.push(p + w);
                    }
                    for q in near {
                        if !seen[q] && (d[q] - d[p]).abs() <= range {
                            seen[q] = true;
                            stack.push(q);
                        }
                    }
                }
                if members.len() < max_size {
                    for p in members {
                        out[p] = f32::NAN;
                    }
                }
            }
            out
        }
        let mut rng = crate::vision::synthetic::Rng::new(11);
        for (w, h) in [(37, 23), (64, 64), (5, 101)] {
            // Levels 0..6 a step apart (joined at range 1) with 20 % holes: regions of every
            // size, snaking across any band's seams.
            let d: Vec<f32> = (0..w * h)
                .map(|_| {
                    let u = rng.unit();
                    if u < 0.2 {
                        f32::NAN
                    } else {
                        (rng.unit() * 6.0).floor() * 1.5
                    }
                })
                .collect();
            for max_size in [2, 5, 30] {
                let expected = flood(&d, w, max_size, 1.0);
                for threads in [1, 3, 8] {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .unwrap();
                    let mut got = d.clone();
                    pool.install(|| speckles(&mut got, w, max_size, 1.0));
                    let same = got
                        .iter()
                        .zip(&expected)
                        .all(|(a, b)| a.to_bits() == b.to_bits());
                    assert!(same, "{w} x {h}, size {max_size}, {threads} bands");
                }
            }
        }
    }

    /// Holes take the smaller of their row neighbours, and row ends the only one they have.
    #[test]
    fn fill_takes_the_background() {
        let mut d = vec![f32::NAN, 5.0, f32::NAN, f32::NAN, 9.0, f32::NAN];
        fill(&mut d, 6);
        assert_eq!(d, vec![5.0, 5.0, 5.0, 5.0, 9.0, 9.0]);
    }

    /// The left-right check keeps agreeing pixels and drops the others.
    #[test]
    fn left_right_drops_disagreement() {
        // x = 1 (d 1.2) lands on right pixel 0, which says 1: kept. x = 2 (d 1) lands on
        // right pixel 1, which says 3: dropped. x = 3 (d 5) lands outside: dropped.
        let mut left = vec![0.0, 1.2, 1.0, 5.0];
        let right = vec![1, 3, 1, 0];
        left_right(&mut left, &right, 1.0);
        assert_eq!(&left[..2], &[0.0, 1.2]);
        assert!(left[2].is_nan() && left[3].is_nan());
    }
}
