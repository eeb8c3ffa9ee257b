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

mod steps;

pub(crate) use steps::FAR;
use steps::{PathCost, step1, step4};

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
    /// [`Paths::Four`] on a pair [`Paths::Auto`] would give 5, [`Paths::Five`] otherwise: the
    /// fast preset's. On noise the path from the right is what keeps the fast preset within
    /// OpenCV's best mode (Motorcycle with noise σ 4: bad-1.0 16.11 % with 5 paths, 18.59 %
    /// with 4, OpenCV's best 17.13 %).
    Lean,
    /// All 8, in two passes (as OpenCV's `MODE_HH`): the most robust to noise.
    Eight,
    /// 5 in one pass, as OpenCV's `MODE_SGBM_3WAY` lays them out: the 4 from above and the
    /// left, and along each row from the right, run over the row once the row is done. No
    /// volume of sums is stored: each row's totals go to the winner-takes-all as they are made.
    Five,
    /// The 4 from above and the left in one pass, with no path from the right: the fast
    /// preset's. About a fifth less aggregation than [`Paths::Five`] (docs/matcher.md).
    Four,
}

/// The clarity (texture variance over noise variance at one pixel's scale) above which
/// [`Paths::Auto`] takes 5 paths: noise flips the census's comparisons of near-equal
/// neighbours, and the 3 paths from below are what outvotes those flips where it is strong.
/// Measured (docs/matcher.md): Motorcycle 61.6, with a gain change 58.0, with noise σ 4 5.2
/// (bad-1.0 13.33 % with 8 paths, 15.90 % with 5).
pub const CLEAR: f32 = 10.0;

impl Paths {
    /// How many paths are summed; undecided, the most the rule may take.
    pub fn count(self) -> u32 {
        match self {
            Paths::Four => 4,
            Paths::Five | Paths::Lean => 5,
            Paths::Auto | Paths::Eight => 8,
        }
    }

    /// The paths for a pair of this clarity whose census samples are `stride` pixels apart:
    /// `Auto` decided, the others as they are. A pair smooth at one pixel's scale (`stride`
    /// above 1, such as an upscaled one) gives each pixel's census little to go on, and takes
    /// 8 (Motorcycle upscaled 4 ×: bad-1.0 25.53 % with 8, 28.26 % with 5).
    pub fn for_pair(self, clarity: f32, stride: usize) -> Paths {
        match self {
            Paths::Auto if clarity > CLEAR && stride == 1 => Paths::Five,
            Paths::Auto => Paths::Eight,
            Paths::Lean if clarity > CLEAR && stride == 1 => Paths::Four,
            Paths::Lean => Paths::Five,
            chosen => chosen,
        }
    }
}

/// Aggregates `cost` along `paths`, guided by the grey levels of the volume's rows (`grey`,
/// `width × height` of them), and calls `on_row(y, totals)` for each row with the sum of the
/// paths' costs of its pixels (the row's cells, each pixel's window in turn): from the bottom
/// up with [`Paths::Eight`] (and `Auto`; the caller decides `Auto` and `Lean` first), from the
/// top down with [`Paths::Five`] and [`Paths::Four`].
pub fn aggregate(
    cost: &Volume<'_>,
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
    match paths {
        Paths::Five | Paths::Lean => {
            return pass(cost, grey, &table, Mode::Single, &mut row, on_row, cancel);
        }
        Paths::Four => return pass(cost, grey, &table, Mode::Forward, &mut row, on_row, cancel),
        Paths::Auto | Paths::Eight => {}
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
fn widest_row(cost: &Volume<'_>) -> usize {
    let o = &cost.windows.offsets;
    (0..cost.height)
        .map(|y| (o[(y + 1) * cost.width] - o[y * cost.width]) as usize)
        .max()
        .unwrap_or(0)
}

/// The widest window of the volume.
fn widest_window(cost: &Volume<'_>) -> usize {
    cost.windows
        .offsets
        .windows(2)
        .map(|p| (p[1] - p[0]) as usize)
        .max()
        .unwrap_or(0)
}

/// Whether a pass under `table` keeps its path costs in 8 bits exactly: a path cost is at
/// most the largest cost ([`super::cost::PAD`]) plus the largest `P2`, and the sentinel
/// above them is 255 (`P2` up to 131; the defaults' is 64).
fn bytes_hold(table: &Table) -> bool {
    let p2 = table.p2.iter().copied().max().unwrap_or(0);
    u16::from(super::cost::PAD) + p2.max(table.p1) < u16::from(u8::MAX)
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
fn seen_from<'a, T: PathCost>(
    src: &'a [T],
    from: usize,
    first: usize,
    n: usize,
    scratch: &'a mut [T],
) -> &'a [T] {
    if from == first && src.len() == n + 2 {
        return src;
    }
    let out = &mut scratch[..n + 2];
    out.fill(T::FAR);
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
    /// The only one, without the path from the right: rows and pixels in order, each row
    /// handed on.
    Forward,
}

/// What a pass reads: the cost volume, the grey levels that guide `P2`, the penalties, and
/// what it does with its sums.
#[derive(Clone, Copy)]
struct Pass<'a> {
    cost: &'a Volume<'a>,
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
    /// time in `sums` (one row), or a row at a time with or without the path from the right
    /// added. Compiled twice: for a volume whose pixels all search the same window, with no
    /// per-pixel lookups, and for per-pixel windows; and each with 8-bit path costs where the
    /// penalties let them be exact ([`bytes_hold`]), 16-bit otherwise. `wide`: AVX-512 takes a 64-disparity
    /// chunk of 8-bit path costs in one register.
    wide fn pass(
        cost: &Volume<'_>,
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
        match (uniform(&cost.windows), bytes_hold(table)) {
            (Some(window), true) => rows::<u8, true>(reads, sums, on_row, cancel, window),
            (None, true) => rows::<u8, false>(reads, sums, on_row, cancel, (0, 0)),
            (Some(window), false) => rows::<u16, true>(reads, sums, on_row, cancel, window),
            (None, false) => rows::<u16, false>(reads, sums, on_row, cancel, (0, 0)),
        }
    }
}

/// The body of [`pass`]; with `UNIFORM`, every pixel's window is `window` and the sentinels of
/// the row buffers are written once.
#[inline(always)]
fn rows<T: PathCost, const UNIFORM: bool>(
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
    // A row's cells, when they are made as the pass reaches the row.
    let mut made = vec![0u8; widest_row(cost)];
    let zero = T::default();
    let mut prev = [
        vec![zero; row_len],
        vec![zero; row_len],
        vec![zero; row_len],
    ];
    let mut cur = prev.clone();
    let mut prev_min = [vec![zero; w], vec![zero; w], vec![zero; w]];
    let mut cur_min = prev_min.clone();
    // Where a path starts, it starts from nothing: zero costs (the sentinels do not matter,
    // the zero between them always wins).
    let start = vec![zero; widest + 2];
    let mut along = vec![T::FAR; widest + 2];
    let mut along_next = along.clone();
    let (mut along_first, mut along_n) = (0usize, 0usize);
    let mut scratch = [
        vec![T::FAR; widest + 2],
        vec![T::FAR; widest + 2],
        vec![T::FAR; widest + 2],
        vec![T::FAR; widest + 2],
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
                buffer[x * (n + 2)] = T::FAR;
                buffer[x * (n + 2) + n + 1] = T::FAR;
            }
        }
        for buffer in [&mut along, &mut along_next] {
            buffer[0] = T::FAR;
            buffer[n + 1] = T::FAR;
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
        let row_costs = cost.row(y, &mut made);
        if let Mode::Add(stored) = mode {
            sums[..row_cells.len()].copy_from_slice(&stored[row_cells.clone()]);
        }
        let mut along_min = zero;
        let [cur0, cur1, cur2] = &mut cur;
        let [t0, t1, t2, t3] = &mut scratch;
        for j in 0..w {
            let x = if forward { j } else { w - 1 - j };
            let (first, at, n) = slot(y, x);
            let here = grey_row[x] >> 8;
            let jump = |other: u16| p2[usize::from(here.abs_diff(other >> 8))];
            let mut srcs: [&[T]; 4] = [&start, &start, &start, &start];
            let mut mins = [zero; 4];
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
                along_next[0] = T::FAR;
                along_next[n + 1] = T::FAR;
                for c in [&mut *cur0, &mut *cur1, &mut *cur2] {
                    c[at] = T::FAR;
                    c[at + n + 1] = T::FAR;
                }
            }
            let least = step4(
                &row_costs[cells.start - row_cells.start..cells.end - row_cells.start],
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
            let mut along_min = zero;
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
                    (src, along_min, along_min.widen() + jump)
                } else {
                    (&start[..n + 2], zero, 0)
                };
                if !UNIFORM {
                    along_next[0] = T::FAR;
                    along_next[n + 1] = T::FAR;
                }
                let r = at - 2 * x;
                along_min = step1(
                    &row_costs[r..r + n],
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

#[cfg(test)]
mod tests {
    use super::steps::LANES;
    use super::*;

    /// A stored volume's cells.
    fn stored<'a>(cost: &'a Volume<'_>) -> &'a [u8] {
        match &cost.cells {
            crate::vision::cost::Cells::Stored(data) => data,
            crate::vision::cost::Cells::Made(_) => unreachable!("the tests store their cells"),
        }
    }

    /// The pass by one of its four builds: 8-bit path costs with `bytes`, and one shared
    /// `window` or (with `None`) per-pixel windows. Gives the stored volume in [`Mode::Store`],
    /// otherwise the rows handed on, joined; and the rows' order.
    fn sums_by(
        reads: Pass<'_>,
        bytes: bool,
        window: Option<(usize, usize)>,
    ) -> (Vec<u16>, Vec<usize>) {
        let never = AtomicBool::new(false);
        let store = matches!(reads.mode, Mode::Store);
        let len = if store {
            reads.cost.windows.cells()
        } else {
            widest_row(reads.cost)
        };
        let mut sums = vec![0u16; len];
        let (mut out, mut order) = (Vec::new(), Vec::new());
        let mut on_row = |y, r: &[u16]| {
            out.extend_from_slice(r);
            order.push(y);
        };
        let (on_row, w) = (&mut on_row, window.unwrap_or((0, 0)));
        match (bytes, window.is_some()) {
            (true, true) => rows::<u8, true>(reads, &mut sums, on_row, &never, w),
            (true, false) => rows::<u8, false>(reads, &mut sums, on_row, &never, w),
            (false, true) => rows::<u16, true>(reads, &mut sums, on_row, &never, w),
            (false, false) => rows::<u16, false>(reads, &mut sums, on_row, &never, w),
        }
        .unwrap();
        (if store { sums } else { out }, order)
    }

    /// A `w × h` volume searching `count` disparities everywhere, of random costs below 60,
    /// random grey levels, and the penalties P1 10, P2 80, edge 16.
    fn random_case(
        (w, h, count): (usize, usize, usize),
        seed: u64,
    ) -> (Volume<'static>, Vec<u16>, Table) {
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
            cells: crate::vision::cost::Cells::Stored(data),
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
        let window = uniform(&cost.windows).expect("the whole range everywhere");
        let first = |mode| Pass {
            cost: &cost,
            grey: &grey,
            table: &table,
            mode,
        };
        let (one, _) = sums_by(first(Mode::Store), false, Some(window));
        let (each, _) = sums_by(first(Mode::Store), false, None);
        assert_eq!(one, each);
        let (a, _) = sums_by(first(Mode::Add(&one)), false, Some(window));
        let (b, _) = sums_by(first(Mode::Add(&one)), false, None);
        assert_eq!(a, b);
        assert!(a.iter().any(|&v| v > 0));
    }

    /// 8-bit path costs give the 16-bit pass's sums to the unit, in every mode and both
    /// builds, on costs up to the padding's and the largest `P2` a byte allows; one more and
    /// the pass keeps 16 bits.
    #[test]
    fn eight_bit_path_costs_are_exact() {
        let (mut cost, grey, _) = random_case((37, 11, 80), 3);
        let mut rng = crate::vision::synthetic::Rng::new(9);
        let crate::vision::cost::Cells::Stored(data) = &mut cost.cells else {
            unreachable!("random_case stores its cells")
        };
        for c in data {
            *c = (rng.unit() * f32::from(crate::vision::cost::PAD + 1)) as u8;
        }
        let table = |p2| Table {
            p1: 12,
            p2: p2_table(Penalties {
                p1: 12,
                p2,
                edge: 0,
            }),
        };
        assert!(!bytes_hold(&table(131)));
        let table = table(130);
        assert!(bytes_hold(&table));
        let window = uniform(&cost.windows).expect("the whole range everywhere");
        let reads = |mode| Pass {
            cost: &cost,
            grey: &grey,
            table: &table,
            mode,
        };
        let (stored8, _) = sums_by(reads(Mode::Store), true, Some(window));
        let (stored16, _) = sums_by(reads(Mode::Store), false, Some(window));
        assert_eq!(stored8, stored16);
        // Some path costs pass 128: a sum of 4 above 512.
        let most = stored16.iter().copied().max();
        assert!(most > Some(512), "{most:?}");
        for mode in [Mode::Add(&stored16), Mode::Single, Mode::Forward] {
            let (exact, _) = sums_by(reads(mode), false, Some(window));
            assert_eq!(sums_by(reads(mode), true, Some(window)).0, exact);
            assert_eq!(sums_by(reads(mode), true, None).0, exact);
        }
    }

    /// The single pass's totals are the first pass's 4 paths plus the path along each row from
    /// the right, computed here by its definition; the 4-path pass's are the first pass's
    /// alone. Both builds agree, and rows come in order.
    #[test]
    fn five_paths_add_the_row_from_the_right() {
        let (w, h) = (19, 7);
        let (cost, grey, table) = random_case((w, h, 20), 11);
        let n = cost.windows.offsets[1] as usize;
        let reads = |mode| Pass {
            cost: &cost,
            grey: &grey,
            table: &table,
            mode,
        };
        let window = uniform(&cost.windows).unwrap();
        let (four, _) = sums_by(reads(Mode::Store), false, Some(window));
        // The path from the right, by its definition, over each row's real cells.
        let mut expected = four.clone();
        for y in 0..h {
            let mut prev: Vec<u16> = Vec::new();
            for x in (0..w).rev() {
                let at = (y * w + x) * n;
                let c = &stored(&cost)[at..at + n];
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
        assert_ne!(four, expected);
        for shared in [Some(window), None] {
            let (got, order) = sums_by(reads(Mode::Single), false, shared);
            assert_eq!(got, expected, "one shared window: {}", shared.is_some());
            assert_eq!(order, (0..h).collect::<Vec<_>>());
            let (got, order) = sums_by(reads(Mode::Forward), false, shared);
            assert_eq!(
                got,
                four,
                "4 paths, one shared window: {}",
                shared.is_some()
            );
            assert_eq!(order, (0..h).collect::<Vec<_>>());
        }
    }

    /// With per-pixel windows (as below the pyramid's coarsest level), each path's cost is
    /// the recurrence's over the pixel's window, a neighbour's cost read at the same disparity
    /// and taken as FAR where the neighbour did not look: the first pass's sums against that
    /// definition, computed here over the whole range, on windows of 16 to 48 cells shifted
    /// anywhere; and 8-bit path costs give the same sums in every mode.
    #[test]
    fn per_pixel_windows_read_their_neighbours_at_the_same_disparity() {
        let (w, h, count) = (23, 9, 80);
        let (mut cost, grey, table) = random_case((w, h, count), 21);
        let mut rng = crate::vision::synthetic::Rng::new(4);
        let mut first = Vec::new();
        let mut lengths = Vec::new();
        for _ in 0..w * h {
            let len = LANES * (1 + (rng.unit() * 3.0) as usize).min(3);
            first.push((rng.unit() * (count - len + 1) as f32) as u16);
            lengths.push(len as u16);
        }
        let windows = crate::vision::cost::Windows::from_lengths(first, lengths.into_iter());
        let data: Vec<u8> = (0..windows.cells())
            .map(|_| (rng.unit() * 60.0) as u8)
            .collect();
        cost.windows = windows;
        cost.cells = crate::vision::cost::Cells::Stored(data.clone());
        assert!(uniform(&cost.windows).is_none());
        // The definition: path k's cost at every disparity of the range, FAR outside windows.
        let far = u32::from(FAR);
        let mut paths = vec![vec![vec![far; count]; w * h]; 4];
        let mut expected = vec![0u16; cost.windows.cells()];
        for y in 0..h {
            for x in 0..w {
                let (f, cells) = cost.windows.of(y * w + x);
                let neighbours = [(-1, 0), (-1, -1), (0, -1), (1, -1)];
                for (k, (dx, dy)) in neighbours.into_iter().enumerate() {
                    let (xs, ys) = (x as isize + dx, y as isize + dy);
                    let inside = xs >= 0 && ys >= 0 && xs < w as isize;
                    let prev = inside.then(|| paths[k][ys as usize * w + xs as usize].clone());
                    let p2 = inside.then(|| {
                        let other = grey[ys as usize * w + xs as usize] >> 8;
                        u32::from(table.p2[usize::from((grey[y * w + x] >> 8).abs_diff(other))])
                    });
                    for (j, cell) in cells.clone().enumerate() {
                        let d = f + j;
                        let c = u32::from(data[cell]);
                        let l = match (&prev, p2) {
                            (Some(prev), Some(p2)) => {
                                let m = *prev.iter().min().unwrap();
                                let at = |d: isize| {
                                    usize::try_from(d).ok().and_then(|d| prev.get(d)).copied()
                                };
                                let p1 = u32::from(table.p1);
                                let best = [
                                    at(d as isize),
                                    at(d as isize - 1).map(|v| v + p1),
                                    at(d as isize + 1).map(|v| v + p1),
                                    Some(m + p2),
                                ]
                                .into_iter()
                                .flatten()
                                .min()
                                .unwrap();
                                c + best - m
                            }
                            _ => c,
                        };
                        paths[k][y * w + x][d] = l;
                        expected[cell] += l as u16;
                    }
                }
            }
        }
        let reads = |mode| Pass {
            cost: &cost,
            grey: &grey,
            table: &table,
            mode,
        };
        assert_eq!(sums_by(reads(Mode::Store), false, None).0, expected);
        assert_eq!(sums_by(reads(Mode::Store), true, None).0, expected);
        assert_eq!(sums_by(reads(Mode::Forward), true, None).0, expected);
        for mode in [Mode::Add(&expected), Mode::Single, Mode::Forward] {
            let (wide, _) = sums_by(reads(mode), false, None);
            assert_eq!(sums_by(reads(mode), true, None).0, wide);
            assert!(wide.iter().any(|&v| v > 0));
        }
    }

    /// `Auto` takes 5 paths on a clear pair sharp at one pixel's scale, 8 on a noisy or a
    /// smooth one, and `Lean` 4 and 5; a choice made stays, and each counts its paths.
    #[test]
    fn auto_paths_follow_the_pair() {
        assert_eq!(Paths::Auto.for_pair(61.6, 1), Paths::Five);
        assert_eq!(Paths::Auto.for_pair(5.2, 1), Paths::Eight);
        assert_eq!(Paths::Auto.for_pair(61.6, 4), Paths::Eight);
        assert_eq!(Paths::Eight.for_pair(61.6, 1), Paths::Eight);
        assert_eq!(Paths::Five.for_pair(0.0, 4), Paths::Five);
        assert_eq!(Paths::Four.for_pair(0.0, 1), Paths::Four);
        assert_eq!(Paths::Lean.for_pair(61.6, 1), Paths::Four);
        assert_eq!(Paths::Lean.for_pair(5.2, 1), Paths::Five);
        assert_eq!(Paths::Lean.for_pair(61.6, 4), Paths::Five);
        let counts = [Paths::Four, Paths::Five, Paths::Eight].map(Paths::count);
        assert_eq!(counts, [4, 5, 8]);
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
