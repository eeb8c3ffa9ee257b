//! From aggregated costs to disparities: winner-takes-all with a uniqueness test and a sub-pixel
//! fit, and the right image's disparities from the same volume for the left-right check. The
//! filters after it (speckles, median, filling) are [`super::filters`].
//!
//! Invalid pixels are `f32::NAN` throughout.

use super::Subpixel;
use super::cost::LANES;

/// The winners of one row of the volume.
pub struct Winners {
    /// The left image's disparity of each pixel (index into the range, sub-pixel), or NaN when
    /// it is not unique enough.
    pub left: Vec<f32>,
    /// The right image's integer disparity of each pixel (index into the range), or `u16::MAX`.
    pub right: Vec<u16>,
    /// What each pixel's cost curve says of its winner (unique or not), for its σ.
    pub cues: Vec<Cue>,
}

/// What a winner's aggregated cost curve says of it: the least cost, the least more than one
/// index away, and the curvature at the least (the neighbours' sum less twice the least; one
/// neighbour doubled at the range's ends).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Cue {
    pub best: u16,
    pub second: u16,
    pub curvature: u16,
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
        let mut cues = vec![Cue::default(); width];
        for ((x, out), cue) in left.iter_mut().enumerate().zip(cues.iter_mut()) {
            let (first, total) = windows.totals(totals, x, count);
            if total.is_empty() {
                continue;
            }
            let reach = (x + 1).saturating_sub(first).min(total.len());
            let start = width - 1 - x + first;
            let (best, best_k, second) = if reach == total.len() && reach.is_multiple_of(LANES) {
                // The common case, in one pass over the pixel's registers.
                scan(
                    total,
                    &mut right_cost_rev[start..start + reach],
                    &mut right_rev[start..start + reach],
                    first as u16,
                )
            } else {
                if reach > 0 {
                    keep_smaller(
                        &mut right_cost_rev[start..start + reach],
                        &mut right_rev[start..start + reach],
                        &total[..reach],
                        first as u16,
                    );
                }
                let (best, best_k) = argmin(total);
                (best, best_k, min_away_from(total, best_k))
            };
            *cue = Cue {
                best,
                second,
                curvature: curvature(total, best_k),
            };
            if !unique(best, second, uniqueness) {
                continue;
            }
            *out = first as f32 + fit(total, best_k, subpixel);
        }
        right_rev.reverse();
        Winners {
            left,
            right: right_rev,
            cues,
        }
    }
}

/// [`argmin`], [`min_away_from`] and [`keep_smaller`] in one pass over `values`, a whole
/// number of SIMD registers: `(least, its first index, the least more than one index away)`.
/// Each lane keeps its least value, that value's first index and its second least; the least
/// more than one index away is then, lane by lane, the lane's least unless that lies within
/// one index of the winner, and its second least if it does (a lane holds one index in
/// [`LANES`], so at most one of the winner's three).
#[inline(always)]
fn scan(values: &[u16], costs: &mut [u16], winners: &mut [u16], first: u16) -> (u16, usize, u16) {
    const L: usize = LANES;
    debug_assert!(values.len().is_multiple_of(L) && costs.len() == values.len());
    let mut least = [u16::MAX; L];
    let mut at = [0u16; L];
    let mut next = [u16::MAX; L];
    let mut index = [0u16; L];
    for (i, v) in index.iter_mut().enumerate() {
        *v = i as u16;
    }
    for ((t, c), w) in values
        .chunks_exact(L)
        .zip(costs.chunks_exact_mut(L))
        .zip(winners.chunks_exact_mut(L))
    {
        let mut kept = [0u16; L];
        let mut won = [0u16; L];
        for i in 0..L {
            let lower = 0u16.wrapping_sub(u16::from(t[i] < least[i]));
            next[i] = next[i].min(least[i].max(t[i]));
            least[i] = least[i].min(t[i]);
            at[i] = (index[i] & lower) | (at[i] & !lower);
            // The right image's winners: keep the smaller cost, and its disparity.
            let smaller = 0u16.wrapping_sub(u16::from(t[i] < c[i]));
            kept[i] = c[i].min(t[i]);
            won[i] = ((index[i] + first) & smaller) | (w[i] & !smaller);
        }
        c.copy_from_slice(&kept);
        w.copy_from_slice(&won);
        for v in &mut index {
            *v += L as u16;
        }
    }
    // The least and its first index in one least over the lanes, of (least, index) as one
    // `u32` key: a least of the indices where a lane holds the least (a select in a
    // reduction) was compiled lane by lane, 2 % of the matcher's CPU on its own.
    let mut keys = [0u32; L];
    for i in 0..L {
        keys[i] = (u32::from(least[i]) << 16) | u32::from(at[i]);
    }
    let key = keys.iter().copied().fold(u32::MAX, u32::min);
    let (best, k) = ((key >> 16) as u16, key as u16);
    let mut candidates = [0u16; L];
    let near = k.wrapping_sub(1);
    for i in 0..L {
        let by_winner = 0u16.wrapping_sub(u16::from(at[i].wrapping_sub(near) <= 2));
        candidates[i] = (next[i] & by_winner) | (least[i] & !by_winner);
    }
    let second = candidates.iter().copied().fold(u16::MAX, u16::min);
    (best, usize::from(k), second)
}

/// The smallest value and its first index, in whole SIMD registers (`(u16::MAX, 0)` when
/// empty): the least of each lane over the registers, the least of those, then the first
/// register holding it and the first lane there, from a mask of the lanes equal to it.
#[inline(always)]
fn argmin(values: &[u16]) -> (u16, usize) {
    const L: usize = LANES;
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
    const L: usize = LANES;
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
    const L: usize = LANES;
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
/// What one pixel's own aggregated curve `total` (its window starting at index `first`) says,
/// worked out alone: the winner's index in the window, its sub-pixel disparity as an index into
/// the range, its cue, and whether it passes the uniqueness test. [`winners`] gives the same
/// for a whole row at once.
fn winner_of(
    total: &[u16],
    first: usize,
    uniqueness: u32,
    how: Subpixel,
) -> (usize, f32, Cue, bool) {
    let (best, k) = argmin(total);
    let second = min_away_from(total, k);
    let cue = Cue {
        best,
        second,
        curvature: curvature(total, k),
    };
    (
        k,
        first as f32 + fit(total, k, how),
        cue,
        unique(best, second, uniqueness),
    )
}

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
    let (k, subpixel, cue, is_unique) = winner_of(total, first, params.uniqueness, params.subpixel);
    let index = first + k;
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
        cue,
        disagreement: disagreement(right, x, subpixel),
        unique: is_unique,
        consistent,
        window_cost: mean(window[index.min(count - 1)]),
        window_mean: mean(window.iter().sum::<u32>() / count.max(1) as u32),
        window_best: mean(local),
        window_second: mean(local_second),
    }
}

crate::dispatch! {
    /// [`disagreement`] of each pixel of a row of winners (`left`, NaN for none) with the right
    /// image's winners `right`: what the left-right check and the winners' variances both read.
    pub fn disagreements(left: &[f32], right: &[u16]) -> Vec<f32> {
        left.iter()
            .enumerate()
            .map(|(x, &d)| disagreement(right, x, d))
            .collect()
    }
}

crate::dispatch! {
    /// Invalidates the pixels whose disparity disagrees with the right image's by more than
    /// `tolerance` pixels (occlusions, mismatches): `disagreements` are the row's
    /// ([`disagreements`]). Disparities are indices into the range. Branch-free, on whole
    /// registers.
    pub fn left_right(left: &mut [f32], disagreements: &[f32], tolerance: f32) {
        for (d, &off) in left.iter_mut().zip(disagreements) {
            // An infinite or NaN disagreement never agrees.
            *d = if off <= tolerance { *d } else { f32::NAN };
        }
    }
}

/// How far the right image's winner at the match of left pixel `x` (disparity `d`) lies from
/// `d`, in pixels (infinite where the right image has no winner there).
#[inline(always)]
pub fn disagreement(right: &[u16], x: usize, d: f32) -> f32 {
    let xr = (x as f32 - d).round();
    if xr < 0.0 {
        return f32::INFINITY;
    }
    match right.get(xr as usize) {
        Some(&r) if r != u16::MAX => (f32::from(r) - d).abs(),
        _ => f32::INFINITY,
    }
}

/// Whether the right image's winner at the match of left pixel `x` (disparity `d`) agrees
/// with `d` within `tolerance` (disparities as indices into the range).
#[inline(always)]
fn agrees(right: &[u16], x: usize, d: f32, tolerance: f32) -> bool {
    disagreement(right, x, d) <= tolerance
}

/// The curvature of `total` at its least `k`: `total[k − 1] + total[k + 1] − 2 total[k]`, the
/// one neighbour there is doubled at an end, 0 for a single cell or none.
#[inline(always)]
fn curvature(total: &[u16], k: usize) -> u16 {
    let Some(&at) = total.get(k) else {
        return 0;
    };
    let at = u32::from(at);
    let before = k.checked_sub(1).map(|i| u32::from(total[i]));
    let after = total.get(k + 1).map(|&v| u32::from(v));
    let (b, a) = match (before, after) {
        (Some(b), Some(a)) => (b, a),
        (Some(b), None) => (b, b),
        (None, Some(a)) => (a, a),
        (None, None) => (at, at),
    };
    (b + a).saturating_sub(2 * at).min(u32::from(u16::MAX)) as u16
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

    /// The one-pass scan finds what argmin, the runner-up and the right image's update find
    /// apart, ties included.
    #[test]
    fn one_pass_equals_the_three() {
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as u16
        };
        for len in [16usize, 32, 64, 128] {
            for spread in [4u16, 50, 60000] {
                for _ in 0..200 {
                    let values: Vec<u16> = (0..len).map(|_| next() % spread).collect();
                    let costs: Vec<u16> = (0..len).map(|_| next() % spread).collect();
                    let winners: Vec<u16> = (0..len).map(|_| next()).collect();
                    let (mut c1, mut w1) = (costs.clone(), winners.clone());
                    let (mut c2, mut w2) = (costs.clone(), winners.clone());
                    let got = scan(&values, &mut c1, &mut w1, 9);
                    keep_smaller(&mut c2, &mut w2, &values, 9);
                    let (best, k) = argmin(&values);
                    assert_eq!(got, (best, k, min_away_from(&values, k)), "{values:?}");
                    assert_eq!((c1, w1), (c2, w2));
                }
            }
        }
    }

    /// A row's winners are each pixel's worked out alone (the least, the runner-up, the
    /// curvature, the uniqueness test and the sub-pixel fit of its own curve, bit for bit),
    /// and the right image's winners the first least along each diagonal: on random rows
    /// with ties, windows anywhere in the range, empty ones, ones cut at the range's end and
    /// ones reaching past the row's start, for each fit.
    #[test]
    fn a_rows_winners_are_each_pixels_own() {
        let mut rng = crate::vision::synthetic::Rng::new(31);
        for (count, spread) in [(64usize, 30.0f32), (50, 4.0), (128, 0.5)] {
            let width = 45;
            let mut first = Vec::new();
            let mut offsets = vec![0u32];
            for _ in 0..width {
                let len = LANES * (rng.unit() * 5.0) as usize;
                let len = len.min(crate::vision::cost::stride(count));
                let start = (rng.unit() * (count + LANES - len) as f32) as usize;
                first.push(start.min(count) as u16);
                offsets.push(offsets.last().unwrap() + len as u32);
            }
            // Each pixel's curve a V around a random least, with noise up to `spread`.
            let mut totals = Vec::new();
            for x in 0..width {
                let len = (offsets[x + 1] - offsets[x]) as usize;
                let least = rng.unit() * len as f32;
                totals.extend((0..len).map(|j| {
                    let v = 100.0 + 8.0 * (j as f32 - least).abs() + rng.unit() * spread;
                    v as u16
                }));
            }
            let windows = RowWindows {
                first: &first,
                offsets: &offsets,
            };
            for how in [Subpixel::Off, Subpixel::Parabola, Subpixel::Equiangular] {
                let got = winners(&totals, windows, count, 10, how);
                let mut right = vec![(u16::MAX, u16::MAX); width];
                for x in 0..width {
                    let (f, total) = windows.totals(&totals, x, count);
                    let (mut left, mut cue) = (f32::NAN, Cue::default());
                    if !total.is_empty() {
                        let (_, d, own, is_unique) = winner_of(total, f, 10, how);
                        cue = own;
                        if is_unique {
                            left = d;
                        }
                    }
                    assert_eq!(got.left[x].to_bits(), left.to_bits(), "{how:?} x {x}");
                    assert_eq!(got.cues[x], cue, "{how:?} x {x}");
                    for (j, &t) in total.iter().enumerate() {
                        if let Some(xr) = x.checked_sub(f + j)
                            && t < right[xr].0
                        {
                            right[xr] = (t, (f + j) as u16);
                        }
                    }
                }
                let right: Vec<u16> = right.iter().map(|r| r.1).collect();
                assert_eq!(got.right, right, "{how:?}");
                assert!(got.left.iter().any(|d| !d.is_nan()));
                assert!(got.left.iter().any(|d| d.fract() != 0.0) || how == Subpixel::Off);
            }
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

    /// The left-right check keeps agreeing pixels and drops the others.
    #[test]
    fn left_right_drops_disagreement() {
        // x = 1 (d 1.2) lands on right pixel 0, which says 1: kept. x = 2 (d 1) lands on
        // right pixel 1, which says 3: dropped. x = 3 (d 5) lands outside: dropped.
        let mut left = vec![0.0, 1.2, 1.0, 5.0];
        let right = vec![1, 3, 1, 0];
        let off = disagreements(&left, &right);
        left_right(&mut left, &off, 1.0);
        assert_eq!(&left[..2], &[0.0, 1.2]);
        assert!(left[2].is_nan() && left[3].is_nan());
    }
}
