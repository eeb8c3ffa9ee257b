//! Semi-global aggregation (Hirschmüller 2008): the cost of each pixel and disparity, summed with
//! the smallest path cost that reaches it along 8 straight lines through the image, paying `P1`
//! for a one-pixel disparity step and `P2` for a larger jump. `P2` shrinks across an intensity
//! edge, where depth discontinuities are likely.
//!
//! Layout, as OpenCV's `MODE_HH`: the 8 paths run in two passes, the 4 that come from above and
//! the left (top to bottom, left to right) and the 4 that come from below and the right. Each
//! pass keeps line buffers only (the previous row's path costs for its three vertical and
//! diagonal paths, the previous pixel's for its horizontal one) and writes its sum over its 4
//! paths into a `u16` volume of its own, so the two passes run on two cores at once; the
//! winner-takes-all adds the two volumes.

use std::sync::atomic::{AtomicBool, Ordering};

use super::cost::Volume;
use super::{Cancelled, Gray};

/// The smoothness penalties.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Penalties {
    /// For a disparity step of one pixel between neighbours along a path.
    pub p1: u16,
    /// For a larger jump, where the intensity does not change.
    pub p2: u16,
    /// The intensity step (in 8-bit grey levels) across which `P2` is halved:
    /// `P2' = max(P1 + 1, P2 · T / (T + |ΔI|))`. 0 keeps `P2` constant.
    pub edge: u16,
}

/// A path cost far above any real one (real ones stay below `2 · PAD + P2`), used for the
/// disparities just outside the padded range so the inner loop needs no bounds.
const FAR: u16 = 8192;

/// The two passes' sums, each `width × height × stride` cells in the cost volume's layout.
pub struct Aggregated {
    pub forward: Vec<u16>,
    pub backward: Vec<u16>,
}

/// Aggregates `cost` along 8 paths, guided by the left image's intensities.
pub fn aggregate(
    cost: &Volume,
    left: &Gray,
    penalties: Penalties,
    cancel: &AtomicBool,
) -> Result<Aggregated, Cancelled> {
    let table = p2_table(penalties);
    let (forward, backward) = rayon::join(
        || pass(cost, left, penalties.p1, &table, true, cancel),
        || pass(cost, left, penalties.p1, &table, false, cancel),
    );
    Ok(Aggregated {
        forward: forward?,
        backward: backward?,
    })
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

crate::dispatch! {
    /// One pass: the 4 paths arriving from the previous row and the previous pixel, with rows
    /// and pixels visited in order (`forward`) or in reverse.
    fn pass(
        cost: &Volume,
        left: &Gray,
        p1: u16,
        p2: &[u16; 256],
        forward: bool,
        cancel: &AtomicBool,
    ) -> Result<Vec<u16>, Cancelled> {
        let (w, h, n) = (cost.width, cost.height, cost.stride);
        let slot = n + 2;
        let mut sum = vec![0u16; w * h * n];
        // Path costs of the previous and current rows, for the three paths that come from the
        // previous row: from the pixel before (diagonal), above, and after (other diagonal).
        // Each pixel's slot holds its n costs between two FAR sentinels.
        let mut row_buffer = vec![0u16; w * slot];
        for x in 0..w {
            row_buffer[x * slot] = FAR;
            row_buffer[x * slot + slot - 1] = FAR;
        }
        let mut prev = [row_buffer.clone(), row_buffer.clone(), row_buffer.clone()];
        let mut cur = [row_buffer.clone(), row_buffer.clone(), row_buffer];
        let mut prev_min = [vec![0u16; w], vec![0u16; w], vec![0u16; w]];
        let mut cur_min = prev_min.clone();
        // Where a path starts, it starts from nothing: zero costs, FAR outside the range.
        let mut start = vec![0u16; slot];
        start[0] = FAR;
        start[slot - 1] = FAR;
        let mut along = start.clone();
        let mut along_next = start.clone();

        let step: isize = if forward { 1 } else { -1 };
        for i in 0..h {
            if cancel.load(Ordering::Relaxed) {
                return Err(Cancelled);
            }
            let y = if forward { i } else { h - 1 - i };
            let first_row = i == 0;
            let grey = &left.data[y * w..(y + 1) * w];
            let grey_prev = if first_row {
                grey
            } else {
                let yp = if forward { y - 1 } else { y + 1 };
                &left.data[yp * w..(yp + 1) * w]
            };
            let mut along_min = 0u16;
            let [cur0, cur1, cur2] = &mut cur;
            for j in 0..w {
                let x = if forward { j } else { w - 1 - j };
                let here = grey[x] >> 8;
                let jump = |other: u16| p2[usize::from(here.abs_diff(other >> 8))];
                let mut srcs: [&[u16]; 4] = [&start; 4];
                let mut mins = [0u16; 4];
                let mut p2s = [0u16; 4];
                // Along the row, from the previous pixel.
                if j > 0 {
                    let xp = (x as isize - step) as usize;
                    srcs[0] = &along;
                    mins[0] = along_min;
                    p2s[0] = jump(grey[xp]);
                }
                // From the previous row: the pixel before, above, and after.
                if !first_row {
                    for (k, dx) in [-step, 0, step].into_iter().enumerate() {
                        let xs = x as isize + dx;
                        if xs >= 0 && xs < w as isize {
                            let xs = xs as usize;
                            srcs[k + 1] = &prev[k][xs * slot..(xs + 1) * slot];
                            mins[k + 1] = prev_min[k][xs];
                            p2s[k + 1] = jump(grey_prev[xs]);
                        }
                    }
                }
                let least = step4(
                    cost.at(x, y),
                    srcs,
                    mins,
                    p1,
                    p2s,
                    [
                        &mut along_next,
                        &mut cur0[x * slot..(x + 1) * slot],
                        &mut cur1[x * slot..(x + 1) * slot],
                        &mut cur2[x * slot..(x + 1) * slot],
                    ],
                    &mut sum[(y * w + x) * n..(y * w + x + 1) * n],
                );
                along_min = least[0];
                for k in 0..3 {
                    cur_min[k][x] = least[k + 1];
                }
                std::mem::swap(&mut along, &mut along_next);
            }
            std::mem::swap(&mut prev, &mut cur);
            std::mem::swap(&mut prev_min, &mut cur_min);
        }
        Ok(sum)
    }
}

/// SIMD width of the path loop, in `u16` lanes.
const LANES: usize = super::cost::LANES;

/// One step of the 4 paths of a pass at one pixel: for each path,
/// `L(p, d) = C(p, d) + min(L(p−r, d), L(p−r, d±1) + P1, min L(p−r) + P2) − min L(p−r)`,
/// written between the sentinels of its `out` slot; `sum` gets the 4 paths' total. Returns each
/// path's `min L(p)`.
#[inline(always)]
fn step4(
    cost: &[u8],
    srcs: [&[u16]; 4],
    mins: [u16; 4],
    p1: u16,
    p2: [u16; 4],
    outs: [&mut [u16]; 4],
    sum: &mut [u16],
) -> [u16; 4] {
    let n = cost.len();
    let mut least = [[u16::MAX; LANES]; 4];
    for base in (0..n).step_by(LANES) {
        let c = &cost[base..base + LANES];
        let mut total = [0u16; LANES];
        for dir in 0..4 {
            let prev = &srcs[dir][base..base + LANES + 2];
            let out = &mut outs[dir][base + 1..base + 1 + LANES];
            let jump = mins[dir] + p2[dir];
            for i in 0..LANES {
                let best = prev[i + 1]
                    .min(prev[i] + p1)
                    .min(prev[i + 2] + p1)
                    .min(jump);
                let v = u16::from(c[i]) + best - mins[dir];
                out[i] = v;
                total[i] += v;
                least[dir][i] = least[dir][i].min(v);
            }
        }
        sum[base..base + LANES].copy_from_slice(&total);
    }
    least.map(|l| l.into_iter().min().unwrap_or(0))
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let mut sum = [0u16; LANES];
        let [o0, o1, o2, o3] = &mut outs;
        let least = step4(
            &cost,
            [&prev, &start, &start, &start],
            [0; 4],
            2,
            [30; 4],
            [o0, o1, o2, o3],
            &mut sum,
        );
        // d0 stays at 0; d1 comes from d0 + P1; d2 and d4 from d3 + P1; d3 stays at 3; the
        // others jump from the minimum for P2 (30), cheaper than staying at 40.
        assert_eq!(&outs[0][1..7], &[5, 7, 10, 8, 65, 90]);
        // The three paths that start here cost just C.
        assert_eq!(&outs[1][1..6], &[5, 5, 5, 5, 60]);
        assert_eq!(&sum[..6], &[20, 22, 25, 23, 245, 270]);
        assert_eq!(least, [5, 5, 5, 5]);
    }
}
