//! The disparity map's filters after the winners are chosen: speckle removal (OpenCV's
//! `filterSpeckles`, by union-find over runs in bands), the 3 × 3 median that ignores invalid pixels,
//! and hole filling for the pyramid's coarse levels; and [`finish`], the order they run in
//! with the blank windows' refusal, σ_d, the planes in flat holes and the keep rule.
//!
//! Invalid pixels are `f32::NAN` throughout.

use rayon::prelude::*;

use super::simd::{greatest as max, least as min};
use super::{Gray, Params, census, plane, sigma};

/// The map's finishing after the winners (`data`, range indices, `width` a row; `variance`,
/// their winners' variances): speckles, the median, the pixels of `left` whose census window is
/// blank refused ([`census::blank`]), σ_d ([`sigma::map`]), the planes in flat holes of `left`
/// ([`plane`]), the keep rule ([`sigma::keep`]) and the fill, as `params` ask.
/// Answers the map, its σ_d, the fill's mask (empty without `fill`; it also names the
/// values the planes gave that the keep rule kept) and the blank pixels.
pub(super) fn finish(
    mut data: Vec<f32>,
    variance: Vec<f32>,
    width: usize,
    left: &Gray,
    params: &Params,
) -> (Vec<f32>, Vec<f32>, Vec<bool>, Vec<bool>) {
    speckles(&mut data, width, params.speckle_size, params.speckle_range);
    if params.median {
        data = median(&data, width);
    }
    // A blank window matched nothing: its value was carried in. The planes may give it one.
    let blank = census::blank(left);
    for (d, &blank) in data.iter_mut().zip(&blank) {
        if blank {
            *d = f32::NAN;
        }
    }
    let mut std = sigma::map(&data, &variance, width);
    drop(variance);
    let planes = match params.plane {
        true => plane::fill(&mut data, &mut std, width, left, params.count),
        false => Vec::new(),
    };
    sigma::keep(&mut data, &mut std, params.max_std as f32);
    let mut filled = match params.fill {
        true => fill_with_std(&mut data, &mut std, width),
        false => Vec::new(),
    };
    for (f, (&p, d)) in filled.iter_mut().zip(planes.iter().zip(&data)) {
        *f |= p && !d.is_nan();
    }
    (data, std, filled, blank)
}

/// Invalidates the connected regions of fewer than `max_size` pixels whose neighbours differ by
/// at most `range` (OpenCV's `filterSpeckles`): small islands are usually mismatches.
///
/// The regions are found by union-find over runs, not pixels: a run is a row's stretch of valid
/// pixels each joined to the one before it, so a smooth map has few. In horizontal bands side
/// by side (one a core), each row is cut into runs, and each run is joined to every run of the
/// row above that it overlaps where a pixel is joined to the one above it (a walk over the two
/// rows' runs in order, each pair's columns read only while their regions differ). Then the
/// bands' regions that touch across a seam are joined the same way; then every run whose
/// region is small is invalidated, band by band again. Which pixels go depends neither on the
/// bands nor on the runs: the regions are those of the pixels' joins.
///
/// Memory: a run takes 12 bytes (its columns, and its parent or, at a root, its region's size),
/// each band's runs in buffers with room for one run a pixel, of which only what the runs use
/// is written: 12 bytes a pixel where every pixel is a run of its own, far less on a map of
/// surfaces. Nothing is copied between the bands: run `g` is band `g / band`'s run `g % band`.
pub fn speckles(disparity: &mut [f32], width: usize, max_size: usize, range: f32) {
    let n = disparity.len();
    // (A map of 2^31 pixels or more, which the decoder's limits never admit, is left as it is:
    // runs are numbered in `i32`.)
    if max_size == 0 || n == 0 || width == 0 || i32::try_from(n).is_err() {
        return;
    }
    let height = n / width;
    let per = height.div_ceil(rayon::current_num_threads().max(1)).max(1);
    let band = per * width;
    let joined = |a: f32, b: f32| (a - b).abs() <= range;
    let mut bands: Vec<Band> = disparity
        .par_chunks(band)
        .enumerate()
        .map(|(b, d)| Band::label(d, width, (b, band), &joined))
        .collect();
    // The seams: the last row of each band against the first row of the next.
    // One forest over every band's parents, their runs read beside it.
    let mut runs = Vec::with_capacity(bands.len());
    let mut parents = Vec::with_capacity(bands.len());
    for b in &mut bands {
        runs.push((&b.spans[..], &b.row_first[..]));
        parents.push(&mut b.parent[..]);
    }
    let mut forest = Forest {
        parents: &mut parents,
        first: 0,
        band,
    };
    for b in 1..runs.len() {
        let seam = b * band;
        let ((up, above), (down, below)) = (runs[b - 1], runs[b]);
        let upper = above[per - 1] as usize..above[per] as usize;
        let lower = below[0] as usize..below[1] as usize;
        let lines = [
            &disparity[seam - width..seam],
            &disparity[seam..seam + width],
        ];
        let firsts = [(b - 1) * band + upper.start, seam + lower.start];
        forest.join_rows(lines, [&up[upper], &down[lower]], firsts, &joined);
    }
    let parents: Vec<&[i32]> = bands.iter().map(|b| &b.parent[..]).collect();
    disparity
        .par_chunks_mut(band)
        .zip(&bands)
        .enumerate()
        .for_each(|(b, (d, runs))| {
            for (y, line) in d.chunks_mut(width).enumerate() {
                for i in runs.row_runs(y) {
                    if -root_size(&parents, band, b * band + i) as usize >= max_size {
                        continue;
                    }
                    let (start, end) = columns(runs.spans[i]);
                    line[start..end].fill(f32::NAN);
                }
            }
        });
}

/// One band's runs: their first and end columns (`spans`, the end in the high half), the
/// index of each row's first run (one past the last run at the end), and each run's parent (a
/// run number, `band · b + i` for band b's run i) or at a root its region's size, negated.
struct Band {
    spans: Vec<u64>,
    row_first: Vec<u32>,
    parent: Vec<i32>,
}

impl Band {
    /// Cuts band `b`'s rows (`d`, `width` pixels a row; its runs numbered from `b · band`)
    /// into runs and joins each row's runs to those of the row above, then points every run
    /// straight at its root.
    fn label(
        d: &[f32],
        width: usize,
        (b, band): (usize, usize),
        joined: &impl Fn(f32, f32) -> bool,
    ) -> Band {
        // Room for one run a pixel, written only as far as the runs go.
        let mut spans = Vec::with_capacity(d.len());
        let mut parent = Vec::with_capacity(d.len());
        let mut row_first = Vec::with_capacity(d.len() / width + 1);
        for (y, row) in d.chunks(width).enumerate() {
            let first = spans.len();
            row_first.push(first as u32);
            let mut x = 0;
            while x < width {
                if row[x].is_nan() {
                    x += 1;
                    continue;
                }
                let start = x;
                x += 1;
                // NaN is joined to nothing, so a run ends at the first invalid pixel too.
                while x < width && joined(row[x - 1], row[x]) {
                    x += 1;
                }
                // At most `width` pixels, far below 2^31 (the pixel limits).
                parent.push(-((x - start) as i32));
                spans.push((start as u64) | ((x as u64) << 32));
            }
            if y > 0 {
                let above = row_first[y - 1] as usize..first;
                let lines = [&d[(y - 1) * width..y * width], row];
                let both = [&spans[above.clone()], &spans[first..]];
                let firsts = [b * band + above.start, b * band + first];
                let mut forest = Forest {
                    parents: &mut [&mut parent[..]],
                    first: b,
                    band,
                };
                forest.join_rows(lines, both, firsts, joined);
            }
        }
        row_first.push(spans.len() as u32);
        let mut forest = Forest {
            parents: &mut [&mut parent[..]],
            first: b,
            band,
        };
        for i in 0..spans.len() {
            let g = b * band + i;
            let r = forest.find(g);
            if r != g {
                *forest.at(g) = r as i32;
            }
        }
        Band {
            spans,
            row_first,
            parent,
        }
    }

    /// The indices of row `y`'s runs.
    fn row_runs(&self, y: usize) -> std::ops::Range<usize> {
        self.row_first[y] as usize..self.row_first[y + 1] as usize
    }
}

/// A run's first and end columns, from its span.
#[inline(always)]
fn columns(span: u64) -> (usize, usize) {
    ((span as u32) as usize, (span >> 32) as usize)
}

/// A union-find over runs numbered `band · b + i` (band b's run i), over the parents of bands
/// `first ..` (`parents`, band by band).
struct Forest<'a, 'b> {
    parents: &'a mut [&'b mut [i32]],
    first: usize,
    band: usize,
}

impl Forest<'_, '_> {
    /// Run `g`'s parent, or at a root its region's size negated (one band's without a
    /// division).
    #[inline(always)]
    fn at(&mut self, g: usize) -> &mut i32 {
        if self.parents.len() == 1 {
            return &mut self.parents[0][g - self.first * self.band];
        }
        &mut self.parents[g / self.band - self.first][g % self.band]
    }

    /// The root of run `g`, halving its path.
    fn find(&mut self, mut g: usize) -> usize {
        loop {
            let up = *self.at(g);
            if up < 0 {
                return g;
            }
            let above = *self.at(up as usize);
            if above < 0 {
                return up as usize;
            }
            *self.at(g) = above;
            g = above as usize;
        }
    }

    /// Joins the regions of two consecutive rows' runs (`spans`, the upper row's and the
    /// lower's, numbered from `firsts`) wherever they overlap on a column whose two pixels
    /// (`lines`) are joined: the runs in column order, each overlapping pair's columns read
    /// only while the pair's regions differ. The smaller-numbered root keeps both sizes.
    fn join_rows(
        &mut self,
        lines: [&[f32]; 2],
        spans: [&[u64]; 2],
        firsts: [usize; 2],
        joined: &impl Fn(f32, f32) -> bool,
    ) {
        let [up, down] = spans;
        let (mut i, mut j) = (0, 0);
        while i < up.len() && j < down.len() {
            let (a0, a1) = columns(up[i]);
            let (b0, b1) = columns(down[j]);
            let (lo, hi) = (a0.max(b0), a1.min(b1));
            if lo < hi {
                let ra = self.find(firsts[0] + i);
                let rb = self.find(firsts[1] + j);
                if ra != rb && (lo..hi).any(|x| joined(lines[0][x], lines[1][x])) {
                    let (keep, gone) = (ra.min(rb), ra.max(rb));
                    let size = *self.at(gone);
                    *self.at(keep) += size;
                    *self.at(gone) = keep as i32;
                }
            }
            if a1 <= b1 {
                i += 1;
            } else {
                j += 1;
            }
        }
    }
}

/// The size, negated, of the region of run `g` (numbered as [`Forest`] numbers them, over
/// every band's `parents`), found without path compression: bands read it side by side, every
/// run points at its band's root, and the seams add at most one step per band.
fn root_size(parents: &[&[i32]], band: usize, mut g: usize) -> i32 {
    loop {
        let up = parents[g / band][g % band];
        if up < 0 {
            return up;
        }
        g = up as usize;
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
    fill_noting(disparity, width, |_, _, _| {});
}

/// [`fill`], also setting each filled pixel's σ_d in `std` (the same layout) from the values
/// it chose between ([`super::sigma::filled`]); answers which pixels it filled.
pub fn fill_with_std(disparity: &mut [f32], std: &mut [f32], width: usize) -> Vec<bool> {
    let mut filled = vec![false; disparity.len()];
    fill_noting(disparity, width, |i, left, right| {
        std[i] = super::sigma::filled(left, right);
        filled[i] = true;
    });
    filled
}

/// [`fill`], telling `filled` each filled pixel's index with the nearest valid values to its
/// left and right on the row (NaN where there is none).
fn fill_noting(disparity: &mut [f32], width: usize, mut filled: impl FnMut(usize, f32, f32)) {
    for (y, row) in disparity.chunks_exact_mut(width).enumerate() {
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
            if !row[x].is_nan() {
                filled(y * width + x, left_valid[x], next);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    /// too small, with one band and with many: on maps of many small regions of equal values
    /// and holes, and on maps whose rows drift (long runs, each joined to the row above at a
    /// few scattered columns only, so two runs' overlap must be read past its first column).
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
        let sizes = [(37, 23), (64, 64), (5, 101)];
        let maps = sizes
            .into_iter()
            .flat_map(|size| [(size, false), (size, true)]);
        for ((w, h), drifting) in maps {
            let d: Vec<f32> = if drifting {
                // Each row a walk of steps below the range from its own start, 5 % holes.
                let mut d = Vec::with_capacity(w * h);
                for _ in 0..h {
                    let mut v = rng.unit() * 40.0;
                    for _ in 0..w {
                        v += (rng.unit() - 0.5) * 1.8;
                        d.push(if rng.unit() < 0.05 { f32::NAN } else { v });
                    }
                }
                d
            } else {
                // Levels 0..6 a step apart (joined at range 1) with 20 % holes: regions of
                // every size, snaking across any band's seams.
                (0..w * h)
                    .map(|_| {
                        let u = rng.unit();
                        if u < 0.2 {
                            f32::NAN
                        } else {
                            (rng.unit() * 6.0).floor() * 1.5
                        }
                    })
                    .collect()
            };
            for max_size in [2, 5, 30, 200] {
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
}
