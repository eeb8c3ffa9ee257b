//! The spread a depth map's summary states (min, median, max of the finite values), found
//! in a few linear passes: a histogram of the values' leading bits locates the median, and
//! only the values in its bucket are sorted out. Exact: the same numbers as sorting them all.
//! A map's four spreads are found side by side ([`Spreads::of`]).

use rayon::prelude::*;

use super::depth::DepthMap;

/// The valid values' min, median and max, each to 4 decimals.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spread {
    pub min: f64,
    pub median: f64,
    pub max: f64,
}

/// The spreads a depth map's summary states: the disparities, the depths, and their σ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spreads {
    pub disparity: Option<Spread>,
    pub depth: Option<Spread>,
    pub disparity_std: Option<Spread>,
    pub depth_std: Option<Spread>,
}

impl Spreads {
    /// The map's spreads, each found on its own rayon task (a 720p map's four take a few ms
    /// one after another, which a stream's every frame would wait for).
    pub fn of(map: &DepthMap) -> Spreads {
        let arrays = [
            Some(&map.disparity.data[..]),
            map.depth.as_deref(),
            Some(&map.disparity.std[..]),
            map.depth_std.as_deref(),
        ];
        let mut found = [None; 4];
        found
            .par_iter_mut()
            .zip(arrays)
            .for_each(|(spread_of, values)| *spread_of = values.and_then(spread));
        let [disparity, depth, disparity_std, depth_std] = found;
        Spreads {
            disparity,
            depth,
            disparity_std,
            depth_std,
        }
    }
}

/// Buckets of the histogram: the leading 16 bits of a value's order key (its sign, exponent
/// and 7 bits of mantissa, so one bucket spans under 1 % of its values' size).
const BUCKETS: usize = 1 << 16;

/// The buckets of the finite values: below them lie −∞ and the NaNs with the sign bit set,
/// above them +∞ and the other NaNs.
const FINITE: std::ops::RangeInclusive<usize> = 0x0080..=0xFF7F;

/// A key whose unsigned order is `f32::total_cmp`'s order of the values.
fn key(v: f32) -> u32 {
    let bits = v.to_bits();
    if bits >> 31 == 1 {
        !bits
    } else {
        bits | 0x8000_0000
    }
}

/// The value of a key.
fn value(key: u32) -> f32 {
    f32::from_bits(if key >> 31 == 1 {
        key & 0x7FFF_FFFF
    } else {
        !key
    })
}

fn bucket(key: u32) -> usize {
    (key >> 16) as usize
}

/// The spread of the finite values; `None` when there are none. The median is NumPy's
/// (`numpy.nanmedian` of the NPY and NPZ outputs): the middle value, or the mean of the two
/// middle values of an even count.
pub fn spread(values: &[f32]) -> Option<Spread> {
    // One pass: each value counted in its bucket, and the finite ones' least and greatest
    // key. Four lanes, each with its own counts, so that neighbouring pixels (mostly in one
    // bucket) do not wait on each other's increments.
    let mut counts = vec![[0u32; 4]; BUCKETS];
    let (mut least, mut greatest) = ([u32::MAX; 4], [0u32; 4]);
    let mut tally = |lane: usize, v: f32| {
        let k = key(v);
        counts[bucket(k)][lane] += 1;
        let finite = FINITE.contains(&bucket(k));
        least[lane] = least[lane].min(if finite { k } else { u32::MAX });
        greatest[lane] = greatest[lane].max(if finite { k } else { 0 });
    };
    let mut quads = values.chunks_exact(4);
    for quad in &mut quads {
        for (lane, &v) in quad.iter().enumerate() {
            tally(lane, v);
        }
    }
    for &v in quads.remainder() {
        tally(0, v);
    }
    let counts: Vec<usize> = counts[FINITE]
        .iter()
        .map(|lanes| lanes.iter().map(|&n| n as usize).sum())
        .collect();
    let count: usize = counts.iter().sum();
    if count == 0 {
        return None;
    }
    let min = value(least.into_iter().min().unwrap_or(u32::MAX));
    let max = value(greatest.into_iter().max().unwrap_or(0));
    // The ranks of the middle value(s), and the buckets that hold them.
    let mid = count / 2;
    let even = count.is_multiple_of(2);
    let (first, below) = locate(&counts, if even { mid - 1 } else { mid });
    let (last, _) = locate(&counts, mid);
    let (first, last) = (first + FINITE.start(), last + FINITE.start());
    // Only the values in those buckets (all finite), sorted out: the middle rank counted
    // from the values below them.
    let mut middle: Vec<f32> = Vec::new();
    for &v in values {
        if bucket(key(v)).wrapping_sub(first) <= last - first {
            middle.push(v);
        }
    }
    let (lower, &mut upper, _) = middle.select_nth_unstable_by(mid - below, f32::total_cmp);
    let median = if even {
        let lower = lower.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        (f64::from(lower) + f64::from(upper)) / 2.0
    } else {
        f64::from(upper)
    };
    let round = |v: f64| (v * 1e4).round() / 1e4;
    Some(Spread {
        min: round(min.into()),
        median: round(median),
        max: round(max.into()),
    })
}

/// The bucket holding the value of `rank` (counted from 0 in the values' order), and how
/// many values lie in the buckets below it. `rank` is below the counts' sum.
fn locate(counts: &[usize], rank: usize) -> (usize, usize) {
    let mut below = 0;
    for (b, &n) in counts.iter().enumerate() {
        if below + n > rank {
            return (b, below);
        }
        below += n;
    }
    (counts.len().saturating_sub(1), below)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::Rng;

    /// The spread by sorting every finite value, as the summary once found it.
    fn sorted_spread(values: &[f32]) -> Option<Spread> {
        let mut valid: Vec<f32> = values.iter().copied().filter(|v| v.is_finite()).collect();
        if valid.is_empty() {
            return None;
        }
        valid.sort_by(f32::total_cmp);
        let n = valid.len();
        let median = if n.is_multiple_of(2) {
            (f64::from(valid[n / 2 - 1]) + f64::from(valid[n / 2])) / 2.0
        } else {
            f64::from(valid[n / 2])
        };
        let round = |v: f64| (v * 1e4).round() / 1e4;
        Some(Spread {
            min: round(valid[0].into()),
            median: round(median),
            max: round(valid[n - 1].into()),
        })
    }

    /// `n` uniform draws in [0, 1), the project's seeded generator's.
    fn draws(seed: u64, n: usize) -> impl Iterator<Item = f32> {
        let mut rng = Rng::new(seed);
        (0..n).map(move |_| rng.unit())
    }

    /// The histogram's median is the sorted median to the digit: odd and even counts, ties,
    /// negative values and zeros of both signs, NaN and infinities left out, values whose
    /// middle pair straddles two buckets, one value, none.
    #[test]
    fn the_median_found_from_a_histogram_is_the_sorted_median() {
        let mut cases: Vec<Vec<f32>> = vec![
            vec![],
            vec![f32::NAN, f32::INFINITY],
            vec![3.5],
            vec![1.0, 2.0],
            vec![-0.0, 0.0, -0.0, 0.0],
            vec![-3.0, f32::NAN, 7.25, f32::NEG_INFINITY, -1.5, 2.0],
            // The two middle values in neighbouring buckets, and far apart.
            vec![1.0, 1.0f32.next_up(), 1.0 + 1.0 / 64.0, 2.0],
            vec![-100.0, 1e-30, 1e30, 0.5],
        ];
        for seed in 1..=6u64 {
            let n = 1000 + seed as usize * 337;
            // Disparities to 1/16 px (ties by the hundred), holes as NaN, some negative.
            cases.push(
                draws(seed, n)
                    .map(|u| match (u * 100.0) as u32 % 11 {
                        0 => f32::NAN,
                        1 => -(u * 7.0),
                        _ => (u * 128.0 * 16.0).round() / 16.0,
                    })
                    .collect(),
            );
            // Depths over four decades.
            cases.push(
                draws(seed + 99, n)
                    .map(|u| 10f32.powf(2.0 + 4.0 * u))
                    .collect(),
            );
        }
        for values in &cases {
            assert_eq!(spread(values), sorted_spread(values), "{values:?}");
        }
        let s = spread(&[4.0, f32::NAN, 1.0, 2.0, 3.0]).expect("four finite values");
        assert_eq!((s.min, s.median, s.max), (1.0, 2.5, 4.0));
    }
}
