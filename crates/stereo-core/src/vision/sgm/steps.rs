//! One step of the aggregation's paths at one pixel, over the pixel's window of disparities:
//! the recurrence of semi-global matching on whole registers, for path costs of 8 bits
//! (libSGM's: twice the lanes a register, exact while a cost plus `P2` fits a byte) or 16.

/// A path cost far above any real one (real ones stay below `2 · PAD + P2`), used for the
/// disparities just outside the padded range so the inner loop needs no bounds.
pub(crate) const FAR: u16 = 8192;

/// The narrowest chunk of a window the steps take, in lanes: the cost volume's windows are
/// multiples of it.
pub(super) const LANES: usize = super::super::cost::LANES;

/// A path cost as a pass stores it. `L(p, d) − min L(p−r)` of a path never exceeds
/// `C + P2`, so 8 bits hold it exactly while the largest cost ([`super::super::cost::PAD`])
/// plus the largest `P2` is at most [`u8::MAX`]; the sums over the paths are 16 bits either
/// way. The sentinel [`PathCost::FAR`] stands above every real path cost, and adding `P1` to
/// it saturates, so it is never the cheaper way in.
pub(super) trait PathCost: Copy + Ord + Default + 'static {
    /// Above every real path cost.
    const FAR: Self;
    /// Whether the steps take chunks of 64 lanes where a window allows (twice a register of
    /// 8-bit lanes with AVX2, one with AVX-512), or of [`LANES`] only.
    const WIDE: bool;
    /// A cost, as a path cost.
    fn of(cost: u8) -> Self;
    /// `v`, or [`PathCost::FAR`] when it is past what the type holds.
    fn capped(v: u16) -> Self;
    /// As a term of a sum over paths.
    fn widen(self) -> u16;
    fn saturating_add(self, other: Self) -> Self;
    fn wrapping_add(self, other: Self) -> Self;
    fn wrapping_sub(self, other: Self) -> Self;
}

impl PathCost for u8 {
    const FAR: Self = u8::MAX;
    const WIDE: bool = true;
    #[inline(always)]
    fn of(cost: u8) -> Self {
        cost
    }
    #[inline(always)]
    fn capped(v: u16) -> Self {
        v.min(u16::from(u8::MAX)) as u8
    }
    #[inline(always)]
    fn widen(self) -> u16 {
        u16::from(self)
    }
    #[inline(always)]
    fn saturating_add(self, other: Self) -> Self {
        u8::saturating_add(self, other)
    }
    #[inline(always)]
    fn wrapping_add(self, other: Self) -> Self {
        u8::wrapping_add(self, other)
    }
    #[inline(always)]
    fn wrapping_sub(self, other: Self) -> Self {
        u8::wrapping_sub(self, other)
    }
}

impl PathCost for u16 {
    const FAR: Self = FAR;
    const WIDE: bool = false;
    #[inline(always)]
    fn of(cost: u8) -> Self {
        u16::from(cost)
    }
    #[inline(always)]
    fn capped(v: u16) -> Self {
        v
    }
    #[inline(always)]
    fn widen(self) -> u16 {
        self
    }
    #[inline(always)]
    fn saturating_add(self, other: Self) -> Self {
        u16::saturating_add(self, other)
    }
    #[inline(always)]
    fn wrapping_add(self, other: Self) -> Self {
        u16::wrapping_add(self, other)
    }
    #[inline(always)]
    fn wrapping_sub(self, other: Self) -> Self {
        u16::wrapping_sub(self, other)
    }
}

/// The lanes of the next chunk of a window with `left` cells still to step (a multiple of
/// [`LANES`]): 64 where `wide` and the window allow, then 32, then [`LANES`]. (A loop rather
/// than a closure over the chunks: a closure would not be compiled with the features of the
/// build that calls it.)
#[inline(always)]
fn lanes(left: usize, wide: bool) -> usize {
    if wide && left >= 64 {
        64
    } else if wide && left >= 32 {
        32
    } else {
        LANES
    }
}

/// One step of the 4 paths of a pass at one pixel: for each path,
/// `L(p, d) = C(p, d) + min(L(p−r, d), L(p−r, d±1) + P1, min L(p−r) + P2) − min L(p−r)`,
/// written between the sentinels of its `out` slot; the 4 paths' total is written to `sum` in
/// the first pass, and added to it (the first pass's sums) in the second (`add`). Returns each
/// path's `min L(p)`.
#[inline(always)]
pub(super) fn step4<T: PathCost>(
    cost: &[u8],
    srcs: [&[T]; 4],
    mins: [T; 4],
    (p1, p2): (u16, [u16; 4]),
    outs: [&mut [T]; 4],
    sum: &mut [u16],
    add: bool,
) -> [T; 4] {
    let n = cost.len();
    let [o0, o1, o2, o3] = outs;
    let mut outs = [
        &mut o0[1..n + 1],
        &mut o1[1..n + 1],
        &mut o2[1..n + 1],
        &mut o3[1..n + 1],
    ];
    let sum = &mut sum[..n];
    let p1 = T::capped(p1);
    let mut jumps = [T::FAR; 4];
    for k in 0..4 {
        jumps[k] = T::capped(mins[k].widen() + p2[k]);
    }
    let mut least = [T::FAR; 4];
    let mut base = 0;
    while base < n {
        let step = lanes(n - base, T::WIDE);
        let c = &cost[base..base + step];
        let total = &mut sum[base..base + step];
        let costs = (mins, p1, jumps);
        least = match step {
            64 => four::<T, 64>(c, srcs, base, costs, &mut outs, total, add, least),
            32 => four::<T, 32>(c, srcs, base, costs, &mut outs, total, add, least),
            _ => four::<T, LANES>(c, srcs, base, costs, &mut outs, total, add, least),
        };
        base += step;
    }
    least
}

/// [`step4`] over one chunk of `L` lanes from `base`, its paths' least costs folded into
/// `least`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn four<T: PathCost, const L: usize>(
    cost: &[u8],
    srcs: [&[T]; 4],
    base: usize,
    (mins, p1, jumps): ([T; 4], T, [T; 4]),
    outs: &mut [&mut [T]; 4],
    total: &mut [u16],
    add: bool,
    mut least: [T; 4],
) -> [T; 4] {
    let mut c = [T::default(); L];
    for (c, &v) in c.iter_mut().zip(&cost[..L]) {
        *c = T::of(v);
    }
    let mut v = [[T::default(); L]; 4];
    for k in 0..4 {
        v[k] = path(&c, &srcs[k][base..base + L + 2], mins[k], p1, jumps[k]);
    }
    for (k, out) in outs.iter_mut().enumerate() {
        out[base..base + L].copy_from_slice(&v[k]);
    }
    // What is kept of `total`: all of it when adding, nothing when writing.
    let keep = if add { u16::MAX } else { 0 };
    let total = &mut total[..L];
    for i in 0..L {
        let here = v[0][i].widen() + v[1][i].widen() + v[2][i].widen() + v[3][i].widen();
        total[i] = (total[i] & keep).saturating_add(here);
    }
    for k in 0..4 {
        for &x in &v[k] {
            least[k] = least[k].min(x);
        }
    }
    least
}

/// One step of a single path at one pixel, as [`step4`]'s: written between the sentinels of
/// `out`, and added to `sum`. `(min, p1, jump)` are the previous pixel's least path cost, `P1`,
/// and that least plus `P2` (16 bits, capped to the type here). Returns the path's `min L(p)`.
#[inline(always)]
pub(super) fn step1<T: PathCost>(
    cost: &[u8],
    src: &[T],
    (min, p1, jump): (T, u16, u16),
    out: &mut [T],
    sum: &mut [u16],
) -> T {
    let n = cost.len();
    let src = &src[..n + 2];
    let out = &mut out[1..n + 1];
    let sum = &mut sum[..n];
    let (p1, jump) = (T::capped(p1), T::capped(jump));
    let mut least = T::FAR;
    let mut base = 0;
    while base < n {
        let step = lanes(n - base, T::WIDE);
        let (c, s) = (&cost[base..], &src[base..]);
        let here = match step {
            64 => one::<T, 64>(c, s, (min, p1, jump), out, sum, base),
            32 => one::<T, 32>(c, s, (min, p1, jump), out, sum, base),
            _ => one::<T, LANES>(c, s, (min, p1, jump), out, sum, base),
        };
        least = least.min(here);
        base += step;
    }
    least
}

/// [`step1`] over one chunk of `L` lanes from `base`: its least path cost.
#[inline(always)]
fn one<T: PathCost, const L: usize>(
    cost: &[u8],
    src: &[T],
    (min, p1, jump): (T, T, T),
    out: &mut [T],
    sum: &mut [u16],
    base: usize,
) -> T {
    let mut c = [T::default(); L];
    for (c, &v) in c.iter_mut().zip(&cost[..L]) {
        *c = T::of(v);
    }
    let v = path(&c, &src[..L + 2], min, p1, jump);
    out[base..base + L].copy_from_slice(&v);
    let total = &mut sum[base..base + L];
    for i in 0..L {
        total[i] = total[i].saturating_add(v[i].widen());
    }
    let mut least = T::FAR;
    for &x in &v {
        least = least.min(x);
    }
    least
}

/// One register of one path's step: `C + min(L(d), L(d ± 1) + P1, jump) − min`, where `prev`
/// holds the previous costs from d − 1 to d + L. Every candidate is at least `min` (the least
/// of `prev`; the sentinels and `jump` above it), so the difference never wraps, and the sum
/// is at most `C + P2`.
#[inline(always)]
pub(super) fn path<T: PathCost, const L: usize>(
    c: &[T; L],
    prev: &[T],
    prev_min: T,
    p1: T,
    jump: T,
) -> [T; L] {
    let prev = &prev[..L + 2];
    let mut out = [T::default(); L];
    for i in 0..L {
        let best = prev[i + 1]
            .min(prev[i].saturating_add(p1))
            .min(prev[i + 2].saturating_add(p1))
            .min(jump);
        out[i] = c[i].wrapping_add(best.wrapping_sub(prev_min));
    }
    out
}
