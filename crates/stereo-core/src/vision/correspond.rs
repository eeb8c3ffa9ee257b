//! Correspondences for chosen points and regions (the `/match` engine): where a left pixel is
//! in the right image, with a status that says whether to trust it and a confidence.
//!
//! The disparity comes from the dense matcher ([`super::disparity_probed`]): its filtered map
//! where that holds a value, else the winner on the aggregated costs. Each point is then
//! judged on the evidence the matcher saw there:
//! - `OutsideImage`: the point is not on the left image;
//! - `OutOfRange`: no right pixel lies in the disparity range, or the best one is at the end of
//!   what the range and the right image allow, or hardly better than no match at all (the true
//!   match may lie beyond);
//! - `Textureless`: the census window around the point is flat (its grey levels vary by less
//!   than [`TEXTURE_MIN`]); its disparity was carried in from its surroundings;
//! - `Occluded`: the right image's own best match points elsewhere (the left-right check);
//!   checked before ambiguity, since a pixel the right camera cannot see has no true match and
//!   so often also fails the uniqueness test;
//! - `Ambiguous`: a disparity more than one pixel away costs nearly as little (the uniqueness
//!   test);
//! - `Inconsistent`: its neighbourhood disagrees: the speckle filter removed it, or more than
//!   [`INVALID_NEIGHBOURS_MAX`] of its 8 neighbours have no disparity (the border of an
//!   occlusion), or its 5 × 5 neighbourhood spans more than [`SPREAD_MAX`] pixels of
//!   disparity, or a disparity more than [`EDGE_STEP`] pixels from its own lies on its row
//!   within the census window (a depth edge, where the point may belong to either surface and
//!   the nearer one is fattened);
//! - `Ok` otherwise.
//!
//! Only the rows the points and regions need are matched when they are a small part of the
//! image ([`bands`]); each band carries the same context rows as the matcher's stripes.

use std::ops::Range;
use std::sync::atomic::AtomicBool;

use rayon::prelude::*;

use super::{Cancelled, Disparity, Gray, Params, Probe, STRIPE_MARGIN, Timings};

/// A matched band: its map, stage times and probes, as [`super::disparity_probed`] answers.
type Band = (Disparity, Timings, Vec<Vec<Probe>>);

/// The least standard deviation of grey levels (of 255) over the census window for a point to
/// have texture of its own.
pub const TEXTURE_MIN: f32 = 1.0;
/// The most of a point's 8 neighbours that may lack a disparity for it to be `Ok`.
pub const INVALID_NEIGHBOURS_MAX: usize = 2;
/// The widest span of disparities, in pixels, in a point's 5 × 5 neighbourhood for it to be
/// `Ok`.
pub const SPREAD_MAX: f32 = 3.0;
/// The most a point's match may cost, as a share of what its 5 × 5 window costs on average
/// over the whole range (what no match costs): a match that is hardly better than none means
/// the true one lies outside the range. A share, not a number of bits, so that noise, which
/// raises every cost, does not turn true matches into none.
pub const MATCH_COST_RATIO: f32 = 0.8;
/// The least margin, in average census bits, by which the best match of the point's own 5 × 5
/// window must beat any other more than a pixel away (repeated texture matches equally well
/// at several disparities, whatever the aggregation chose).
pub const WINDOW_MARGIN_MIN: f32 = 0.1;
/// The step in disparity, in pixels, that makes a depth edge for [`near_edge`].
pub const EDGE_STEP: f32 = 2.0;
/// The cost margin (second best over best, minus one) at which the uniqueness part of the
/// confidence is full.
pub const MARGIN_FULL: f32 = 0.5;

/// Whether to trust a correspondence, or why not.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MatchOutcome {
    Ok,
    OutsideImage,
    OutOfRange,
    Textureless,
    Ambiguous,
    Occluded,
    Inconsistent,
}

impl MatchOutcome {
    /// Why a point with this status and a disparity gets no distance, when it gets none: its
    /// disparity is the best cost in the range, not its match (beyond the range, or hidden from
    /// the right camera), and a distance from it would be confidently wrong.
    pub fn withheld(self) -> Option<&'static str> {
        match self {
            MatchOutcome::OutOfRange => Some(
                "no distance: the match lies outside the disparity search range, so this \
                 disparity is only the range's best cost, not the point's match; search a wider \
                 range (max_disparity, min_disparity)",
            ),
            MatchOutcome::Occluded => Some(
                "no distance: the right camera does not see this point (the left-right check \
                 failed), so this disparity is not its match",
            ),
            _ => None,
        }
    }
}

/// A point's correspondence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Found {
    pub status: MatchOutcome,
    /// The disparity `x_left − x_right` at the point's pixel, in pixels; `None` when the point
    /// is outside the left image or no right pixel lies in the range.
    pub disparity: Option<f32>,
    /// How sure the match is, in [0, 1]: the uniqueness margin times the share of the 5 × 5
    /// neighbourhood that agrees within a pixel, times the texture; halved when `status` is not
    /// `Ok`, 0 without a disparity.
    pub confidence: f32,
    /// The standard deviation of `disparity`, in pixels ([`super::sigma`]): the map's σ_d
    /// where the disparity is the map's, else the winner's with its neighbourhood.
    pub disparity_std: Option<f32>,
}

/// A box in the left image, in pixels: columns `x0..x1`, rows `y0..y1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
}

/// What [`correspond`] answers.
#[derive(Debug, Clone, PartialEq)]
pub struct Correspondences {
    /// The filtered disparity map, NaN where invalid and on rows nothing needed.
    pub map: Disparity,
    /// One per point, in order.
    pub found: Vec<Found>,
    /// Stage times: the bands' wall time shared in proportion to their summed stage times.
    pub timings: Timings,
    /// How many rows were matched (with their context).
    pub rows_matched: usize,
}

/// The pixel a point `(x, y)` falls in (pixel centres at whole numbers), if it is on a
/// `width × height` image.
pub fn pixel(x: f64, y: f64, width: usize, height: usize) -> Option<(usize, usize)> {
    let inside = |v: f64, n: usize| {
        let p = (v + 0.5).floor();
        (p >= 0.0 && p < n as f64).then_some(p as usize)
    };
    Some((inside(x, width)?, inside(y, height)?))
}

/// The correspondences of `points` (in the left image), matching the rows they and `boxes`
/// need; `cancel` as in [`super::disparity`].
pub fn correspond(
    left: &Gray,
    right: &Gray,
    params: &Params,
    points: &[(f64, f64)],
    boxes: &[Rect],
    cancel: &AtomicBool,
) -> Result<Correspondences, Cancelled> {
    let (w, h) = (left.width, left.height);
    let pixels: Vec<Option<(usize, usize)>> =
        points.iter().map(|&(x, y)| pixel(x, y, w, h)).collect();
    let mut needed: Vec<Range<usize>> = pixels
        .iter()
        .flatten()
        .map(|&(_, y)| y.saturating_sub(2)..(y + 3).min(h))
        .chain(boxes.iter().map(|b| b.y0.min(h)..b.y1.min(h)))
        .filter(|r| !r.is_empty())
        .collect();
    needed.sort_by_key(|r| r.start);
    let mut map = vec![f32::NAN; w * h];
    let mut std = vec![f32::NAN; w * h];
    let mut probes: Vec<Vec<Probe>> = vec![Vec::new(); h];
    let mut timings = Timings::default();
    let mut rows_matched = 0;
    let bands = bands(&needed, h);
    let started = std::time::Instant::now();
    // The whole pair's noise and stride, so that each band's census is the whole image's there.
    let seen = super::PairNoise::of(left, right);
    // The bands side by side on the cores (each band's stripes too).
    let matched: Vec<Result<Band, Cancelled>> = bands
        .par_iter()
        .map(|(keep, band)| {
            let mut wanted: Vec<Vec<usize>> = vec![Vec::new(); band.len()];
            for &(x, y) in pixels.iter().flatten() {
                if keep.contains(&y) {
                    wanted[y - band.start].push(x);
                }
            }
            let crop = |image: &Gray| {
                Gray::new(
                    w,
                    band.len(),
                    image.data[band.start * w..band.end * w].to_vec(),
                )
            };
            // No planes in flat holes here: a point's status says what its own match was.
            let params = &Params {
                plane: false,
                ..*params
            };
            super::disparity_probed_in(&crop(left), &crop(right), seen, params, cancel, &wanted)
        })
        .collect();
    for ((keep, band), result) in bands.iter().zip(matched) {
        let (part, t, found) = result?;
        let rows = keep.start - band.start..keep.end - band.start;
        map[keep.start * w..keep.end * w].copy_from_slice(&part.data[rows.start * w..rows.end * w]);
        std[keep.start * w..keep.end * w].copy_from_slice(&part.std[rows.start * w..rows.end * w]);
        for (y, row) in found
            .into_iter()
            .enumerate()
            .skip(rows.start)
            .take(rows.len())
        {
            probes[band.start + y] = row;
        }
        timings.cost += t.cost;
        timings.aggregate += t.aggregate;
        timings.refine += t.refine;
        rows_matched += band.len();
    }
    let timings = timings.sharing(started.elapsed());
    let map = Disparity {
        width: w,
        height: h,
        data: map,
        std,
        filled: Vec::new(),
        blank: Vec::new(),
    };
    // Each row's probes, taken in the order the points were pushed.
    let mut next = vec![0usize; h];
    let found = pixels
        .iter()
        .map(|&p| {
            let Some((x, y)) = p else {
                return Found {
                    status: MatchOutcome::OutsideImage,
                    disparity: None,
                    confidence: 0.0,
                    disparity_std: None,
                };
            };
            let probe = probes[y].get(next[y]).copied();
            next[y] += 1;
            judge(left, &map, (params, seen.stride), x, y, probe)
        })
        .collect();
    Ok(Correspondences {
        map,
        found,
        timings,
        rows_matched,
    })
}

/// The bands of rows to match for the `needed` rows (sorted by start): `(rows kept, rows
/// matched)`, each kept range within its matched one, with [`STRIPE_MARGIN`] rows and a few
/// more for the filters around it. Bands that would overlap are one; when they would cover
/// most of the image, the whole image is one band.
pub fn bands(needed: &[Range<usize>], height: usize) -> Vec<(Range<usize>, Range<usize>)> {
    const CONTEXT: usize = STRIPE_MARGIN + 8;
    let mut out: Vec<(Range<usize>, Range<usize>)> = Vec::new();
    for r in needed {
        let band = r.start.saturating_sub(CONTEXT)..(r.end + CONTEXT).min(height);
        match out.last_mut() {
            Some((keep, matched)) if band.start <= matched.end => {
                keep.end = keep.end.max(r.end);
                matched.end = matched.end.max(band.end);
            }
            _ => out.push((r.clone(), band)),
        }
    }
    let total: usize = out.iter().map(|(_, m)| m.len()).sum();
    if total * 4 >= height * 3 {
        return vec![(0..height, 0..height)];
    }
    out
}

/// A point's status, disparity and confidence from what the matcher saw there.
/// `stride` is the pair's census stride ([`super::PairNoise`]), which scales the winner's σ.
fn judge(
    left: &Gray,
    map: &Disparity,
    (params, stride): (&Params, usize),
    x: usize,
    y: usize,
    probe: Option<Probe>,
) -> Found {
    let none = |status| Found {
        status,
        disparity: None,
        confidence: 0.0,
        disparity_std: None,
    };
    let w = map.width as i64;
    let count = params.count as i64;
    let min = i64::from(params.min_disparity);
    // The indices into the range whose right pixel x − (min + k) is on the right image.
    let lo = (x as i64 - min - (w - 1)).max(0);
    let hi = (x as i64 - min).min(count - 1);
    let Some(probe) = probe.filter(|_| lo <= hi) else {
        return none(MatchOutcome::OutOfRange);
    };
    let raw = probe.subpixel + params.min_disparity as f32;
    let filtered = map.data[y * map.width + x];
    let index = probe.index as i64;
    let texture = texture(left, x, y);
    let (invalid, spread, agree) = neighbourhood(map, x, y, filtered);
    let edge = near_edge(map, x, y, filtered);
    let status = if index >= hi || index < lo || (index == lo && (lo > 0 || min > 0)) {
        MatchOutcome::OutOfRange
    } else if texture < TEXTURE_MIN {
        MatchOutcome::Textureless
    } else if !probe.consistent {
        MatchOutcome::Occluded
    } else if !probe.unique || probe.window_second < probe.window_best + WINDOW_MARGIN_MIN {
        MatchOutcome::Ambiguous
    } else if probe.window_cost > MATCH_COST_RATIO * probe.window_mean {
        MatchOutcome::OutOfRange
    } else if filtered.is_nan() || invalid > INVALID_NEIGHBOURS_MAX || spread > SPREAD_MAX || edge {
        MatchOutcome::Inconsistent
    } else {
        MatchOutcome::Ok
    };
    let (disparity, disparity_std) = match status {
        MatchOutcome::Ambiguous | MatchOutcome::Occluded | MatchOutcome::OutOfRange => (raw, None),
        _ if filtered.is_nan() => (raw, None),
        _ => (filtered, Some(map.std[y * map.width + x])),
    };
    // A winner the map does not hold: its own σ, with the neighbourhood it would have had.
    let disparity_std = disparity_std.unwrap_or_else(|| {
        let variance =
            super::sigma::winner_variance(probe.cue, probe.subpixel, probe.disagreement, stride);
        super::sigma::at(&map.data, map.width, (x, y), raw, variance)
    });
    let (best, second) = (probe.cue.best, probe.cue.second);
    let margin = f32::from(second.saturating_sub(best)) / f32::from(best.max(1));
    let mut confidence =
        (margin / MARGIN_FULL).min(1.0) * agree * (texture / (4.0 * TEXTURE_MIN)).min(1.0);
    if status != MatchOutcome::Ok {
        confidence *= 0.5;
    }
    Found {
        status,
        disparity: Some(disparity),
        confidence: confidence.clamp(0.0, 1.0),
        disparity_std: Some(disparity_std),
    }
}

/// The standard deviation of the left image's grey levels (of 255) over the census window
/// around `(x, y)`, clipped to the image.
fn texture(left: &Gray, x: usize, y: usize) -> f32 {
    let (rx, ry) = (super::census::WIDTH / 2, super::census::HEIGHT / 2);
    let (mut n, mut sum, mut sq) = (0.0f64, 0.0f64, 0.0f64);
    for yy in y.saturating_sub(ry)..(y + ry + 1).min(left.height) {
        for xx in x.saturating_sub(rx)..(x + rx + 1).min(left.width) {
            let v = f64::from(left.data[yy * left.width + xx]) / 257.0;
            n += 1.0;
            sum += v;
            sq += v * v;
        }
    }
    let mean = sum / n.max(1.0);
    ((sq / n.max(1.0) - mean * mean).max(0.0).sqrt()) as f32
}

/// Around `(x, y)` in the filtered map: how many of the 8 neighbours (on the image) lack a
/// disparity, the span of the 5 × 5 neighbourhood's disparities, and the share of the 5 × 5
/// neighbourhood (on the image) within a pixel of `d`.
fn neighbourhood(map: &Disparity, x: usize, y: usize, d: f32) -> (usize, f32, f32) {
    let (w, h) = (map.width, map.height);
    let at = |xx: usize, yy: usize| map.data[yy * w + xx];
    let mut invalid = 0;
    for yy in y.saturating_sub(1)..(y + 2).min(h) {
        for xx in x.saturating_sub(1)..(x + 2).min(w) {
            if (xx, yy) != (x, y) && at(xx, yy).is_nan() {
                invalid += 1;
            }
        }
    }
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    let (mut agree, mut seen) = (0usize, 0usize);
    for yy in y.saturating_sub(2)..(y + 3).min(h) {
        for xx in x.saturating_sub(2)..(x + 3).min(w) {
            let v = at(xx, yy);
            seen += 1;
            if v.is_nan() {
                continue;
            }
            lo = lo.min(v);
            hi = hi.max(v);
            if (v - d).abs() <= 1.0 {
                agree += 1;
            }
        }
    }
    let spread = if hi >= lo { hi - lo } else { 0.0 };
    (invalid, spread, agree as f32 / seen.max(1) as f32)
}

/// Whether a disparity more than [`EDGE_STEP`] pixels from `d` lies on the row within the
/// census window's half width of `(x, y)`: a depth edge that close puts both surfaces in the
/// point's window, where a matcher fattens the nearer one.
fn near_edge(map: &Disparity, x: usize, y: usize, d: f32) -> bool {
    let half = super::census::WIDTH / 2;
    let row = &map.data[y * map.width..(y + 1) * map.width];
    row[x.saturating_sub(half)..(x + half + 1).min(map.width)]
        .iter()
        .any(|v| (v - d).abs() > EDGE_STEP)
}

/// The valid disparities of the map inside `rect` (clipped to the map) with each one's σ_d,
/// and how many pixels of the map the clipped box covers.
pub fn in_box(map: &Disparity, rect: Rect) -> (Vec<(f32, f32)>, usize) {
    let (x1, y1) = (rect.x1.min(map.width), rect.y1.min(map.height));
    let mut values = Vec::new();
    let mut pixels = 0;
    for y in rect.y0.min(y1)..y1 {
        let cells = y * map.width + rect.x0.min(x1)..y * map.width + x1;
        pixels += cells.len();
        values.extend(
            map.data[cells.clone()]
                .iter()
                .zip(&map.std[cells])
                .filter(|(d, _)| !d.is_nan())
                .map(|(&d, &s)| (d, s)),
        );
    }
    (values, pixels)
}

/// The pixels over which a map's errors go together: a census window's (neighbours share most
/// of their windows, hence most of their errors).
pub const CORRELATED_PIXELS: usize = super::census::WIDTH * super::census::HEIGHT;

/// σ_d of the median of `n` disparities whose own σ_d have the median `median_std`: a median's
/// 1.2533 σ / √n for `n / CORRELATED_PIXELS` independent values (at least one).
pub fn median_std(median_std: f32, n: usize) -> f32 {
    let independent = (n as f32 / CORRELATED_PIXELS as f32).max(1.0);
    1.2533 * median_std / independent.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point's pixel is the one whose centre is nearest; off the image there is none.
    #[test]
    fn points_fall_in_pixels() {
        assert_eq!(pixel(0.0, 0.0, 10, 5), Some((0, 0)));
        assert_eq!(pixel(-0.5, 4.49, 10, 5), Some((0, 4)));
        assert_eq!(pixel(9.49, 2.0, 10, 5), Some((9, 2)));
        assert_eq!(pixel(9.5, 2.0, 10, 5), None);
        assert_eq!(pixel(-0.6, 2.0, 10, 5), None);
        assert_eq!(pixel(3.0, 5.0, 10, 5), None);
    }

    /// Nearby needs share a band with context around it; far ones get their own; needs over
    /// most of the image make one band of the whole.
    #[test]
    fn bands_cover_the_needed_rows_with_context() {
        let c = STRIPE_MARGIN + 8;
        let b = bands(&[10..15, 20..25, 300..305], 1000);
        assert_eq!(b, vec![(10..25, 0..25 + c), (300..305, 300 - c..305 + c)]);
        assert_eq!(bands(&[0..500, 600..900], 1000), vec![(0..1000, 0..1000)]);
    }

    /// Matching only the bands the points need answers as matching the whole image does: the
    /// same statuses and disparities within a hundredth of a pixel at almost every point.
    #[test]
    fn bands_answer_as_the_whole_image() {
        let (w, h) = (320, 480);
        let pair = super::super::synthetic::render(&super::super::synthetic::layered(w, h));
        let params = Params::range(0, 48).unwrap();
        let points: Vec<(f64, f64)> = (0..40)
            .map(|i| (f64::from(40 + i * 7), f64::from(30 + (i % 3) * 190)))
            .collect();
        let cancel = AtomicBool::new(false);
        let banded = correspond(&pair.left, &pair.right, &params, &points, &[], &cancel).unwrap();
        let whole = Rect {
            x0: 0,
            y0: 0,
            x1: w,
            y1: h,
        };
        let full =
            correspond(&pair.left, &pair.right, &params, &points, &[whole], &cancel).unwrap();
        assert!(banded.rows_matched < h / 2, "{}", banded.rows_matched);
        assert_eq!(full.rows_matched, h);
        let same = banded
            .found
            .iter()
            .zip(&full.found)
            .filter(|(a, b)| {
                a.status == b.status
                    && match (a.disparity, b.disparity) {
                        (Some(x), Some(y)) => (x - y).abs() < 0.01,
                        (x, y) => x == y,
                    }
            })
            .count();
        assert!(same * 20 >= points.len() * 19, "{same} of {}", points.len());
    }

    /// A box's valid values and its pixels on the map, clipped at the map's edge.
    #[test]
    fn boxes_are_clipped_to_the_map() {
        let map = Disparity {
            width: 4,
            height: 3,
            data: vec![
                1.0,
                2.0,
                f32::NAN,
                4.0,
                5.0,
                6.0,
                7.0,
                8.0,
                9.0,
                10.0,
                11.0,
                12.0,
            ],
            std: vec![0.2; 12],
            filled: Vec::new(),
            blank: Vec::new(),
        };
        let (values, pixels) = in_box(
            &map,
            Rect {
                x0: 1,
                y0: 0,
                x1: 9,
                y1: 2,
            },
        );
        assert_eq!(
            values.iter().map(|v| v.0).collect::<Vec<_>>(),
            vec![2.0, 4.0, 6.0, 7.0, 8.0]
        );
        assert!(values.iter().all(|v| v.1 == 0.2));
        assert_eq!(pixels, 6);
    }

    /// A median over one census window knows no more than a pixel does (times the median's
    /// 1.2533); over many windows, √ of their count less.
    #[test]
    fn a_median_knows_more_over_more_windows() {
        assert!((median_std(0.4, 10) - 1.2533 * 0.4).abs() < 1e-6);
        let windows = 16;
        let many = median_std(0.4, windows * CORRELATED_PIXELS);
        assert!((many - 1.2533 * 0.4 / 4.0).abs() < 1e-6);
    }
}
