//! Semi-global aggregation (Hirschmüller 2008): the cost of each pixel and disparity, summed with
//! the smallest path cost that reaches it along 8 straight lines through the image, paying `P1`
//! for a one-pixel disparity step and `P2` for a larger jump. `P2` shrinks across an intensity
//! edge, where depth discontinuities are likely.
//!
//! Layout, as OpenCV's `MODE_HH`: the 8 paths run in two passes, the 4 that come from above and
//! the left (top to bottom, left to right) and the 4 that come from below and the right. Each
//! pass keeps line buffers only (the previous row's path costs for its three vertical and
//! diagonal paths, the previous pixel's for its horizontal one). The first pass stores its sums
//! in a `u16` volume; the second adds its own to them one row at a time and hands each finished
//! row of totals to the winner-takes-all, so no second volume is written or read back. The
//! matcher runs this on horizontal stripes of the image, one per core (see [`super::disparity`]).
//!
//! Below the pyramid's coarsest level ([`super::pyramid`]) each pixel has its own window of the
//! range: a neighbour's path costs are read at this pixel's disparities, and as FAR where the
//! neighbour did not look, so a path can only continue through disparities both searched or
//! jump for `P2`.

use std::sync::atomic::{AtomicBool, Ordering};

use super::Cancelled;
use super::cost::Volume;

/// The smoothness penalties.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Penalties {
    /// For a disparity step of one pixel between neighbours along a path.
    pub p1: u16,
    /// For a larger jump, where the intensity does not change.
    pub p2: u16,
    /// The intensity step (in 8-bit grey levels of the guide the matcher passes: the left
    /// image's census centres, its structure without its noise) across which `P2` is halved:
    /// `P2' = max(P1 + 1, P2 · T / (T + |ΔI|))`. 0 keeps `P2` constant.
    pub edge: u16,
}

/// Which paths the aggregation sums.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Paths {
    /// [`Paths::Five`] on a pair whose texture stands well above its noise (its
    /// [`super::PairNoise::clarity`] above [`CLEAR`]) at one pixel's scale (its census
    /// samples one pixel apart), [`Paths::Eight`] otherwise.
    Auto,
    /// All 8, in two passes (as OpenCV's `MODE_HH`): the most robust to noise.
    Eight,
    /// 5 in one pass, as OpenCV's `MODE_SGBM_3WAY` lays them out: the 4 from above and the
    /// left, and along each row from the right, run over the row once the row is done. No
    /// volume of sums is stored: each row's totals go to the winner-takes-all as they are made.
    Five,
}

/// The clarity (texture variance over noise variance at one pixel's scale) above which
/// [`Paths::Auto`] takes 5 paths: noise flips the census's comparisons of near-equal
/// neighbours, and the 3 paths from below are what outvotes those flips where it is strong.
/// Measured (docs/matcher.md): Motorcycle 61.6, with a gain change 58.0, with noise σ 4 5.2
/// (bad-1.0 13.33 % with 8 paths, 15.90 % with 5).
pub const CLEAR: f32 = 10.0;

impl Paths {
    /// The paths for a pair of this clarity whose census samples are `stride` pixels apart:
    /// `Auto` decided, the others as they are. A pair smooth at one pixel's scale (`stride`
    /// above 1, such as an upscaled one) gives each pixel's census little to go on, and takes
    /// 8 (Motorcycle upscaled 4 ×: bad-1.0 25.53 % with 8, 28.26 % with 5).
    pub fn for_pair(self, clarity: f32, stride: usize) -> Paths {
        match self {
            Paths::Auto if clarity > CLEAR && stride == 1 => Paths::Five,
            Paths::Auto => Paths::Eight,
            chosen => chosen,
        }
    }
}

/// A path cost far above any real one (real ones stay below `2 · PAD + P2`), used for the
/// disparities just outside the padded range so the inner loop needs no bounds.
pub(crate) const FAR: u16 = 8192;

/// Aggregates `cost` along `paths`, guided by the grey levels of the volume's rows (`grey`,
/// `width × height` of them), and calls `on_row(y, totals)` for each row with the sum of the
/// paths' costs of its pixels (the row's cells, each pixel's window in turn): from the bottom
/// up with [`Paths::Eight`] (and `Auto`, which the caller decides first), from the top down
/// with [`Paths::Five`].
pub fn aggregate(
    cost: &Volume,
    grey: &[u16],
    penalties: Penalties,
    paths: Paths,
    cancel: &AtomicBool,
    on_row: &mut dyn FnMut(usize, &[u16]),
) -> Result<(), Cancelled> {
    let table = Table {
        p1: penalties.p1,
        p2: p2_table(penalties),
    };
    let mut row = vec![0u16; widest_row(cost)];
    if paths == Paths::Five {
        return pass(cost, grey, &table, Mode::Single, &mut row, on_row, cancel);
    }
    // Every cell is written by the first pass before the second reads it.
    let mut forward = super::huge_pages::WORDS.take(cost.windows.cells());
    pass(
        cost,
        grey,
        &table,
        Mode::Store,
        &mut forward,
        &mut |_, _| {},
        cancel,
    )?;
    let second = pass(
        cost,
        grey,
        &table,
        Mode::Add(&forward),
        &mut row,
        on_row,
        cancel,
    );
    super::huge_pages::WORDS.give(forward);
    second
}

/// The most cells a row of the volume holds.
fn widest_row(cost: &Volume) -> usize {
    let o = &cost.windows.offsets;
    (0..cost.height)
        .map(|y| (o[(y + 1) * cost.width] - o[y * cost.width]) as usize)
        .max()
        .unwrap_or(0)
}

/// The widest window of the volume.
fn widest_window(cost: &Volume) -> usize {
    cost.windows
        .offsets
        .windows(2)
        .map(|p| (p[1] - p[0]) as usize)
        .max()
        .unwrap_or(0)
}

/// The penalties as a pass uses them: `P1`, and `P2` for each intensity step 0..=255.
struct Table {
    p1: u16,
    p2: [u16; 256],
}

/// `P2` for each intensity step 0..=255.
fn p2_table(p: Penalties) -> [u16; 256] {
    let mut table = [p.p2; 256];
    if p.edge > 0 {
        for (diff, slot) in table.iter_mut().enumerate() {
            let scaled = u32::from(p.p2) * u32::from(p.edge) / (u32::from(p.edge) + diff as u32);
            *slot = (scaled as u16).max(p.p1 + 1);
        }
    }
    table
}

/// A neighbour's path costs as seen from a pixel whose window starts at index `first` and holds
/// `n` cells: `src` is the neighbour's slot (its window starting at `from`, between two FAR
/// sentinels). The slot itself when the windows are the same; otherwise `scratch`, filled with
/// the neighbour's costs at this window's disparities and FAR where the neighbour did not look.
#[inline(always)]
fn seen_from<'a>(
    src: &'a [u16],
    from: usize,
    first: usize,
    n: usize,
    scratch: &'a mut [u16],
) -> &'a [u16] {
    if from == first && src.len() == n + 2 {
        return src;
    }
    let out = &mut scratch[..n + 2];
    out.fill(FAR);
    // out[j] = src[first − from + j] where that is inside src.
    let shift = first as isize - from as isize;
    let j0 = (-shift).max(0) as usize;
    let j1 = ((src.len() as isize - shift).min((n + 2) as isize)).max(j0 as isize) as usize;
    if j0 < j1 {
        let s0 = (j0 as isize + shift) as usize;
        out[j0..j1].copy_from_slice(&src[s0..s0 + (j1 - j0)]);
    }
    out
}

/// What a pass does with its sums.
#[derive(Clone, Copy)]
enum Mode<'a> {
    /// The first of two: rows and pixels in order, its sums stored in the whole volume.
    Store,
    /// The second of two: rows and pixels in reverse, its sums added to the first's (these)
    /// one row at a time, each row handed on.
    Add(&'a [u16]),
    /// The only one: rows and pixels in order, then each row from the right, handed on.
    Single,
}

/// What a pass reads: the cost volume, the grey levels that guide `P2`, the penalties, and
/// what it does with its sums.
#[derive(Clone, Copy)]
struct Pass<'a> {
    cost: &'a Volume,
    grey: &'a [u16],
    table: &'a Table,
    mode: Mode<'a>,
}

/// The window every pixel searches, `(first, cells)`, when they all search the same one (the
/// whole range, below the pyramid).
fn uniform(windows: &super::cost::Windows) -> Option<(usize, usize)> {
    let first = *windows.first.first()?;
    let n = windows.offsets.get(1)? - windows.offsets[0];
    let same = windows.first.iter().all(|&f| f == first)
        && windows.offsets.windows(2).all(|p| p[1] - p[0] == n);
    same.then_some((usize::from(first), n as usize))
}

crate::dispatch! {
    /// One pass: the 4 paths arriving from the previous row and the previous pixel, as
    /// [`Mode`] says: stored in `sums` (the whole volume), or added to stored sums a row at a
    /// time in `sums` (one row), or a row at a time with the path from the right added. Compiled
    /// twice: for a volume whose pixels all search the same window, with no per-pixel lookups,
    /// and for per-pixel windows.
    fn pass(
        cost: &Volume,
        grey: &[u16],
        table: &Table,
        mode: Mode,
        sums: &mut [u16],
        on_row: &mut dyn FnMut(usize, &[u16]),
        cancel: &AtomicBool,
    ) -> Result<(), Cancelled> {
        let reads = Pass {
            cost,
            grey,
            table,
            mode,
        };
        match uniform(&cost.windows) {
            Some(window) => rows::<true>(reads, sums, on_row, cancel, window),
            None => rows::<false>(reads, sums, on_row, cancel, (0, 0)),
        }
    }
}

/// The body of [`pass`]; with `UNIFORM`, every pixel's window is `window` and the sentinels of
/// the row buffers are written once.
#[inline(always)]
fn rows<const UNIFORM: bool>(
    Pass {
        cost,
        grey,
        table,
        mode,
    }: Pass,
    sums: &mut [u16],
    on_row: &mut dyn FnMut(usize, &[u16]),
    cancel: &AtomicBool,
    window: (usize, usize),
) -> Result<(), Cancelled> {
    let (w, h) = (cost.width, cost.height);
    let windows = &cost.windows;
    let (p1, p2) = (table.p1, &table.p2);
    let forward = !matches!(mode, Mode::Add(_));
    let store = matches!(mode, Mode::Store);
    let widest = widest_window(cost);
    // Path costs of the previous and current rows, for the three paths that come from the
    // previous row: from the pixel before (diagonal), above, and after (other diagonal).
    // Pixel x of row y has its slot at (its cells' offset in the row) + 2x: its window's
    // costs between two FAR sentinels.
    let row_len = widest_row(cost) + 2 * w;
    let mut prev = [
        vec![0u16; row_len],
        vec![0u16; row_len],
        vec![0u16; row_len],
    ];
    let mut cur = prev.clone();
    let mut prev_min = [vec![0u16; w], vec![0u16; w], vec![0u16; w]];
    let mut cur_min = prev_min.clone();
    // Where a path starts, it starts from nothing: zero costs (the sentinels do not matter,
    // the zero between them always wins).
    let start = vec![0u16; widest + 2];
    let mut along = vec![FAR; widest + 2];
    let mut along_next = along.clone();
    let (mut along_first, mut along_n) = (0usize, 0usize);
    let mut scratch = [
        vec![FAR; widest + 2],
        vec![FAR; widest + 2],
        vec![FAR; widest + 2],
        vec![FAR; widest + 2],
    ];

    let step: isize = if forward { 1 } else { -1 };
    let slot = |y: usize, x: usize| {
        if UNIFORM {
            let (first, n) = window;
            (first, x * (n + 2), n)
        } else {
            let row = windows.offsets[y * w] as usize;
            let (first, cells) = windows.of(y * w + x);
            (first, cells.start - row + 2 * x, cells.len())
        }
    };
    if UNIFORM {
        // The slots never move: their sentinels are written once.
        let n = window.1;
        for buffer in cur.iter_mut().chain(prev.iter_mut()) {
            for x in 0..w {
                buffer[x * (n + 2)] = FAR;
                buffer[x * (n + 2) + n + 1] = FAR;
            }
        }
        for buffer in [&mut along, &mut along_next] {
            buffer[0] = FAR;
            buffer[n + 1] = FAR;
        }
    }
    for i in 0..h {
        if cancel.load(Ordering::Relaxed) {
            return Err(Cancelled);
        }
        let y = if forward { i } else { h - 1 - i };
        let first_row = i == 0;
        let yp = if forward { y.wrapping_sub(1) } else { y + 1 };
        let grey_row = &grey[y * w..(y + 1) * w];
        let grey_prev = if first_row {
            grey_row
        } else {
            &grey[yp * w..(yp + 1) * w]
        };
        let row_cells = windows.offsets[y * w] as usize..windows.offsets[(y + 1) * w] as usize;
        if let Mode::Add(stored) = mode {
            sums[..row_cells.len()].copy_from_slice(&stored[row_cells.clone()]);
        }
        let mut along_min = 0u16;
        let [cur0, cur1, cur2] = &mut cur;
        let [t0, t1, t2, t3] = &mut scratch;
        for j in 0..w {
            let x = if forward { j } else { w - 1 - j };
            let (first, at, n) = slot(y, x);
            let here = grey_row[x] >> 8;
            let jump = |other: u16| p2[usize::from(here.abs_diff(other >> 8))];
            let mut srcs: [&[u16]; 4] = [&start, &start, &start, &start];
            let mut mins = [0u16; 4];
            let mut p2s = [0u16; 4];
            // Along the row, from the previous pixel.
            if j > 0 {
                let xp = (x as isize - step) as usize;
                srcs[0] = if UNIFORM {
                    &along[..n + 2]
                } else {
                    seen_from(&along[..along_n + 2], along_first, first, n, t0)
                };
                mins[0] = along_min;
                p2s[0] = jump(grey_row[xp]);
            }
            // From the previous row: the pixel before, above, and after.
            if !first_row {
                for (k, (dx, t)) in [(-step, &mut *t1), (0, &mut *t2), (step, &mut *t3)]
                    .into_iter()
                    .enumerate()
                {
                    let xs = x as isize + dx;
                    if xs >= 0 && xs < w as isize {
                        let xs = xs as usize;
                        let (from, pos, m) = slot(yp, xs);
                        srcs[k + 1] = if UNIFORM {
                            &prev[k][pos..pos + n + 2]
                        } else {
                            seen_from(&prev[k][pos..pos + m + 2], from, first, n, t)
                        };
                        mins[k + 1] = prev_min[k][xs];
                        p2s[k + 1] = jump(grey_prev[xs]);
                    }
                }
            }
            // The pixel's cells: its slot, less the sentinels of the pixels before it.
            let start = row_cells.start + at - 2 * x;
            let cells = start..start + n;
            let sum = if store {
                &mut sums[cells.clone()]
            } else {
                let r = cells.start - row_cells.start;
                &mut sums[r..r + n]
            };
            if !UNIFORM {
                along_next[0] = FAR;
                along_next[n + 1] = FAR;
                for c in [&mut *cur0, &mut *cur1, &mut *cur2] {
                    c[at] = FAR;
                    c[at + n + 1] = FAR;
                }
            }
            let least = step4(
                &cost.data[cells],
                srcs,
                mins,
                (p1, p2s),
                [
                    &mut along_next[..n + 2],
                    &mut cur0[at..at + n + 2],
                    &mut cur1[at..at + n + 2],
                    &mut cur2[at..at + n + 2],
                ],
                sum,
                !forward,
            );
            along_min = least[0];
            for k in 0..3 {
                cur_min[k][x] = least[k + 1];
            }
            std::mem::swap(&mut along, &mut along_next);
            (along_first, along_n) = (first, n);
        }
        if matches!(mode, Mode::Single) {
            // Along the row from the right: the fifth path, added to the row's sums.
            let mut along_min = 0u16;
            for j in 0..w {
                let x = w - 1 - j;
                let (first, at, n) = slot(y, x);
                let (src, min, jump) = if j > 0 {
                    let src = if UNIFORM {
                        &along[..n + 2]
                    } else {
                        seen_from(&along[..along_n + 2], along_first, first, n, t0)
                    };
                    let jump = p2[usize::from((grey_row[x] >> 8).abs_diff(grey_row[x + 1] >> 8))];
                    (src, along_min, along_min + jump)
                } else {
                    (&start[..n + 2], 0, 0)
                };
                if !UNIFORM {
                    along_next[0] = FAR;
                    along_next[n + 1] = FAR;
                }
                let r = at - 2 * x;
                along_min = step1(
                    &cost.data[row_cells.start + r..row_cells.start + r + n],
                    src,
                    (min, p1, jump),
                    &mut along_next[..n + 2],
                    &mut sums[r..r + n],
                );
                std::mem::swap(&mut along, &mut along_next);
                (along_first, along_n) = (first, n);
            }
        }
        std::mem::swap(&mut prev, &mut cur);
        std::mem::swap(&mut prev_min, &mut cur_min);
        if !store {
            on_row(y, &sums[..row_cells.len()]);
        }
    }
    Ok(())
}

/// SIMD width of the path loop, in `u16` lanes.
const LANES: usize = super::cost::LANES;

/// One step of the 4 paths of a pass at one pixel: for each path,
/// `L(p, d) = C(p, d) + min(L(p−r, d), L(p−r, d±1) + P1, min L(p−r) + P2) − min L(p−r)`,
/// written between the sentinels of its `out` slot; the 4 paths' total is written to `sum` in
/// the first pass, and added to it (the first pass's sums) in the second (`add`). Returns each
/// path's `min L(p)`.
#[inline(always)]
fn step4(
    cost: &[u8],
    srcs: [&[u16]; 4],
    mins: [u16; 4],
    (p1, p2): (u16, [u16; 4]),
    outs: [&mut [u16]; 4],
    sum: &mut [u16],
    add: bool,
) -> [u16; 4] {
    let n = cost.len();
    let [s0, s1, s2, s3] = srcs;
    let [o0, o1, o2, o3] = outs;
    let (s0, s1, s2, s3) = (&s0[..n + 2], &s1[..n + 2], &s2[..n + 2], &s3[..n + 2]);
    let (o0, o1, o2, o3) = (
        &mut o0[1..n + 1],
        &mut o1[1..n + 1],
        &mut o2[1..n + 1],
        &mut o3[1..n + 1],
    );
    let sum = &mut sum[..n];
    // What is kept of `sum`: all of it when adding, nothing when writing.
    let keep = if add { u16::MAX } else { 0 };
    let jumps = [
        mins[0] + p2[0],
        mins[1] + p2[1],
        mins[2] + p2[2],
        mins[3] + p2[3],
    ];
    let mut l0 = [u16::MAX; LANES];
    let mut l1 = [u16::MAX; LANES];
    let mut l2 = [u16::MAX; LANES];
    let mut l3 = [u16::MAX; LANES];
    for base in (0..n).step_by(LANES) {
        let mut c = [0u16; LANES];
        for (c, &v) in c.iter_mut().zip(&cost[base..base + LANES]) {
            *c = u16::from(v);
        }
        let v0 = path(&c, &s0[base..base + LANES + 2], mins[0], p1, jumps[0]);
        let v1 = path(&c, &s1[base..base + LANES + 2], mins[1], p1, jumps[1]);
        let v2 = path(&c, &s2[base..base + LANES + 2], mins[2], p1, jumps[2]);
        let v3 = path(&c, &s3[base..base + LANES + 2], mins[3], p1, jumps[3]);
        o0[base..base + LANES].copy_from_slice(&v0);
        o1[base..base + LANES].copy_from_slice(&v1);
        o2[base..base + LANES].copy_from_slice(&v2);
        o3[base..base + LANES].copy_from_slice(&v3);
        let total = &mut sum[base..base + LANES];
        for i in 0..LANES {
            let here = v0[i] + v1[i] + v2[i] + v3[i];
            total[i] = (total[i] & keep).saturating_add(here);
            l0[i] = l0[i].min(v0[i]);
            l1[i] = l1[i].min(v1[i]);
            l2[i] = l2[i].min(v2[i]);
            l3[i] = l3[i].min(v3[i]);
        }
    }
    let least = |l: [u16; LANES]| l.into_iter().fold(u16::MAX, u16::min);
    [least(l0), least(l1), least(l2), least(l3)]
}

/// One step of a single path at one pixel, as [`step4`]'s: written between the sentinels of
/// `out`, and added to `sum`. `(min, p1, jump)` are the previous pixel's least path cost, `P1`,
/// and that least plus `P2`. Returns the path's `min L(p)`.
#[inline(always)]
fn step1(
    cost: &[u8],
    src: &[u16],
    (min, p1, jump): (u16, u16, u16),
    out: &mut [u16],
    sum: &mut [u16],
) -> u16 {
    let n = cost.len();
    let src = &src[..n + 2];
    let out = &mut out[1..n + 1];
    let sum = &mut sum[..n];
    let mut least = [u16::MAX; LANES];
    for base in (0..n).step_by(LANES) {
        let mut c = [0u16; LANES];
        for (c, &v) in c.iter_mut().zip(&cost[base..base + LANES]) {
            *c = u16::from(v);
        }
        let v = path(&c, &src[base..base + LANES + 2], min, p1, jump);
        out[base..base + LANES].copy_from_slice(&v);
        let total = &mut sum[base..base + LANES];
        for i in 0..LANES {
            total[i] = total[i].saturating_add(v[i]);
            least[i] = least[i].min(v[i]);
        }
    }
    least.into_iter().fold(u16::MAX, u16::min)
}

/// One register of one path's step: `C + min(L(d), L(d ± 1) + P1, jump) − min`, where `prev`
/// holds the previous costs from d − 1 to d + LANES.
#[inline(always)]
fn path(c: &[u16; LANES], prev: &[u16], prev_min: u16, p1: u16, jump: u16) -> [u16; LANES] {
    let prev = &prev[..LANES + 2];
    let mut out = [0u16; LANES];
    for i in 0..LANES {
        let best = prev[i + 1]
            .min(prev[i] + p1)
            .min(prev[i + 2] + p1)
            .min(jump);
        out[i] = c[i] + best - prev_min;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `w × h` volume searching `count` disparities everywhere, of random costs below 60,
    /// random grey levels, and the penalties P1 10, P2 80, edge 16.
    fn random_case((w, h, count): (usize, usize, usize), seed: u64) -> (Volume, Vec<u16>, Table) {
        let mut rng = crate::vision::synthetic::Rng::new(seed);
        let windows = crate::vision::cost::Windows::full(w * h, count);
        let data = (0..windows.cells())
            .map(|_| (rng.unit() * 60.0) as u8)
            .collect();
        let cost = Volume {
            width: w,
            height: h,
            min: 0,
            count,
            windows,
            data,
        };
        let grey = (0..w * h).map(|_| (rng.unit() * 65535.0) as u16).collect();
        let table = Table {
            p1: 10,
            p2: p2_table(Penalties {
                p1: 10,
                p2: 80,
                edge: 16,
            }),
        };
        (cost, grey, table)
    }

    /// The build for one shared window and the build for per-pixel windows give the same sums
    /// on a volume whose pixels all search the whole range, in both passes.
    #[test]
    fn both_builds_of_the_pass_agree() {
        let (cost, grey, table) = random_case((23, 9, 20), 5);
        let never = AtomicBool::new(false);
        let window = uniform(&cost.windows).expect("the whole range everywhere");
        let first = |mode| Pass {
            cost: &cost,
            grey: &grey,
            table: &table,
            mode,
        };
        let mut one = vec![0u16; cost.windows.cells()];
        let mut each = one.clone();
        rows::<true>(first(Mode::Store), &mut one, &mut |_, _| {}, &never, window).unwrap();
        rows::<false>(
            first(Mode::Store),
            &mut each,
            &mut |_, _| {},
            &never,
            (0, 0),
        )
        .unwrap();
        assert_eq!(one, each);
        let (mut a, mut b) = (Vec::new(), Vec::new());
        let mut row = vec![0u16; widest_row(&cost)];
        rows::<true>(
            first(Mode::Add(&one)),
            &mut row,
            &mut |_, r| a.extend_from_slice(r),
            &never,
            window,
        )
        .unwrap();
        rows::<false>(
            first(Mode::Add(&one)),
            &mut row,
            &mut |_, r| b.extend_from_slice(r),
            &never,
            (0, 0),
        )
        .unwrap();
        assert_eq!(a, b);
        assert!(a.iter().any(|&v| v > 0));
    }

    /// The single pass's totals are the first pass's 4 paths plus the path along each row from
    /// the right, computed here by its definition; both builds agree, and rows come in order.
    #[test]
    fn five_paths_add_the_row_from_the_right() {
        let (w, h) = (19, 7);
        let (cost, grey, table) = random_case((w, h, 20), 11);
        let n = cost.windows.offsets[1] as usize;
        let never = AtomicBool::new(false);
        let reads = |mode| Pass {
            cost: &cost,
            grey: &grey,
            table: &table,
            mode,
        };
        let mut four = vec![0u16; cost.windows.cells()];
        let window = uniform(&cost.windows).unwrap();
        rows::<true>(
            reads(Mode::Store),
            &mut four,
            &mut |_, _| {},
            &never,
            window,
        )
        .unwrap();
        // The path from the right, by its definition, over each row's real cells.
        let mut expected = four.clone();
        for y in 0..h {
            let mut prev: Vec<u16> = Vec::new();
            for x in (0..w).rev() {
                let at = (y * w + x) * n;
                let c = &cost.data[at..at + n];
                let l: Vec<u16> = if prev.is_empty() {
                    c.iter().map(|&v| u16::from(v)).collect()
                } else {
                    let m = *prev.iter().min().unwrap();
                    let step = (grey[y * w + x] >> 8).abs_diff(grey[y * w + x + 1] >> 8);
                    let jump = m + table.p2[usize::from(step)];
                    (0..n)
                        .map(|d| {
                            let mut best = prev[d].min(jump);
                            if d > 0 {
                                best = best.min(prev[d - 1] + 10);
                            }
                            if d + 1 < n {
                                best = best.min(prev[d + 1] + 10);
                            }
                            u16::from(c[d]) + best - m
                        })
                        .collect()
                };
                for d in 0..n {
                    expected[at + d] += l[d];
                }
                prev = l;
            }
        }
        for uniform_build in [true, false] {
            let mut got = vec![0u16; cost.windows.cells()];
            let mut order = Vec::new();
            let mut row = vec![0u16; widest_row(&cost)];
            let mut on_row = |y: usize, r: &[u16]| {
                got[y * w * n..(y + 1) * w * n].copy_from_slice(r);
                order.push(y);
            };
            if uniform_build {
                rows::<true>(reads(Mode::Single), &mut row, &mut on_row, &never, window)
            } else {
                rows::<false>(reads(Mode::Single), &mut row, &mut on_row, &never, (0, 0))
            }
            .unwrap();
            assert_eq!(got, expected, "uniform build: {uniform_build}");
            assert_eq!(order, (0..h).collect::<Vec<_>>());
        }
    }

    /// `Auto` takes 5 paths on a clear pair sharp at one pixel's scale, 8 on a noisy or a
    /// smooth one; a choice made stays.
    #[test]
    fn auto_paths_follow_the_pair() {
        assert_eq!(Paths::Auto.for_pair(61.6, 1), Paths::Five);
        assert_eq!(Paths::Auto.for_pair(5.2, 1), Paths::Eight);
        assert_eq!(Paths::Auto.for_pair(61.6, 4), Paths::Eight);
        assert_eq!(Paths::Eight.for_pair(61.6, 1), Paths::Eight);
        assert_eq!(Paths::Five.for_pair(0.0, 4), Paths::Five);
    }

    /// `P2` halves at an intensity step of `edge` grey levels and never falls to `P1`.
    #[test]
    fn p2_shrinks_across_edges() {
        let t = p2_table(Penalties {
            p1: 10,
            p2: 120,
            edge: 20,
        });
        assert_eq!((t[0], t[20], t[255]), (120, 60, 11));
        let flat = p2_table(Penalties {
            p1: 10,
            p2: 120,
            edge: 0,
        });
        assert!(flat.iter().all(|&v| v == 120));
    }

    /// A path step keeps the cheapest way in: the same disparity, one step for P1, or any
    /// jump for P2, less the previous minimum.
    #[test]
    fn a_step_takes_the_cheapest_transition() {
        let mut cost = [5u8; LANES];
        cost[4..].fill(60);
        let mut prev = [40u16; LANES + 2];
        (prev[0], prev[1], prev[4], prev[LANES + 1]) = (FAR, 0, 3, FAR);
        let start = [0u16; LANES + 2];
        let mut outs = [[0u16; LANES + 2]; 4];
        // The first pass writes its sums over whatever the buffer held.
        let mut sum = [999u16; LANES];
        let pass = |outs: &mut [[u16; LANES + 2]; 4], sum: &mut [u16; LANES], second| {
            let [o0, o1, o2, o3] = outs;
            step4(
                &cost,
                [&prev, &start, &start, &start],
                [0; 4],
                (2, [30; 4]),
                [o0, o1, o2, o3],
                sum,
                second,
            )
        };
        let least = pass(&mut outs, &mut sum, false);
        // d0 stays at 0; d1 comes from d0 + P1; d2 and d4 from d3 + P1; d3 stays at 3; the
        // others jump from the minimum for P2 (30), cheaper than staying at 40.
        assert_eq!(&outs[0][1..7], &[5, 7, 10, 8, 65, 90]);
        // The three paths that start here cost just C.
        assert_eq!(&outs[1][1..6], &[5, 5, 5, 5, 60]);
        assert_eq!(&sum[..6], &[20, 22, 25, 23, 245, 270]);
        // The second pass adds its sums to the first's.
        pass(&mut outs, &mut sum, true);
        assert_eq!(&sum[..6], &[40, 44, 50, 46, 490, 540]);
        assert_eq!(least, [5, 5, 5, 5]);
    }
}
