//! Matches of points and regions: the pair rectified when it is raw (points and boxes given
//! in the raw left frame, matched where they land once rectified), only the rows they need
//! matched, each point's disparity with its σ_d measured as `/distance` measures it, and each
//! region's median depth with its 10th and 90th percentiles and the median's σ.

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use super::calibrated::Calibrated;
use super::depth::{decode_notes, row_check, unrectified_warning};
use super::latlon::{latlon_depth, latlon_measure};
use super::range::{self, RangeUsed, Stopped};
use super::rectify::Maps;
use crate::calibration::files::Raw;
use crate::camera::Latlon;
use crate::numbers::round_to;
use crate::physics::{self, Correspondence, Measurement, PhysicsError, Rig};
use crate::vision::correspond::{self, Correspondences};
pub use crate::vision::correspond::{Found, MatchOutcome, Rect};
use crate::vision::decode::Decoded;
use crate::vision::{Disparity, Params, Timings};

/// How points and regions are matched: the matcher's settings, the rig, and for a raw pair
/// its raw cameras and their maps.
#[derive(Debug, Clone, Copy)]
pub struct Request<'a> {
    pub params: &'a Params,
    pub calibrated: &'a Calibrated,
    /// The raw rig's maps: the pair is rectified through them first (with `calibrated.raw`).
    pub maps: Option<&'a Maps>,
}

/// A point's match.
#[derive(Debug, Clone)]
pub struct PointMatch {
    /// The point, as given.
    pub x: f64,
    pub y: f64,
    /// What the matcher found at it (where it landed once rectified, for a raw pair).
    pub found: Found,
    /// Where it landed in the rectified left image, for a raw pair (when the lens model takes
    /// it there).
    pub rectified: Option<(f64, f64)>,
    /// The disparity, to 1/1000 px: the value the distance is computed from.
    pub disparity: Option<f64>,
    /// The match's x in the (rectified) right image.
    pub x_right: Option<f64>,
    /// The match on the raw right frame, for a raw pair.
    pub right_raw: Option<[f64; 2]>,
    /// The disparity's σ, to 1/1000 px, when it was measured with it.
    pub disparity_std: Option<f64>,
    /// `/distance`'s measurement of the disparity, its Δd the σ_d.
    pub measured: Option<Result<Measurement, PhysicsError>>,
}

/// A region's answer.
#[derive(Debug, Clone)]
pub struct RegionMatch {
    /// The box `[x, y, width, height]`, as given.
    pub region: [f64; 4],
    /// `None` when the box is wholly off the image.
    pub pixels: Option<Rect>,
    /// The share of its pixels with a disparity in front of the cameras.
    pub valid_fraction: f64,
    /// The median disparity's measurement at the box's centre, its Δd the median's σ.
    pub measured: Option<Measurement>,
    /// The median's σ_d, to 1/1000 px.
    pub disparity_std: Option<f64>,
    /// The 10th and 90th percentile depths.
    pub distance_p10: Option<f64>,
    pub distance_p90: Option<f64>,
}

/// The matches of a pair.
#[derive(Debug, Clone)]
pub struct Matches {
    /// The (rectified) images' size.
    pub width: usize,
    pub height: usize,
    pub points: Vec<PointMatch>,
    pub regions: Vec<RegionMatch>,
    /// How many rows were matched (with their context).
    pub rows_matched: usize,
    pub timings: Timings,
    /// How long rectifying took, for a raw pair.
    pub rectify: Option<Duration>,
    /// What is wrong or was forgiven, in sentences.
    pub warnings: Vec<String>,
    /// The range matched over, and why.
    pub range: RangeUsed,
    /// The latitude-longitude system the pair was rectified to and matched in, if it was.
    pub latlon: Option<Latlon>,
}

/// The matches of `points` and `regions` (`[x, y, width, height]`) in the decoded pair.
pub fn matches(
    mut left: Decoded,
    mut right: Decoded,
    points: &[(f64, f64)],
    regions: &[[f64; 4]],
    request: Request<'_>,
    cancel: &AtomicBool,
) -> Result<Matches, Stopped> {
    let raw = request.maps.and(request.calibrated.raw.as_deref());
    let (rectify, ranged, surveyed) = range::rectify_and_choose(
        request.maps,
        (&mut left, &mut right),
        false,
        request.params,
        cancel,
    )?;
    let (w, h) = (left.grey.width, left.grey.height);
    // Points and boxes are clicked on the raw frame: matched where they land once rectified
    // (a box as the rectangle around its corners' images).
    let nowhere = (f64::NAN, f64::NAN);
    let rectified: Vec<(f64, f64)> = match raw {
        Some(raw) => points
            .iter()
            .map(|&p| to_rectified(raw, p).unwrap_or(nowhere))
            .collect(),
        None => points.to_vec(),
    };
    let boxes: Vec<Option<Rect>> = regions
        .iter()
        .map(|&b| {
            let b = match raw {
                Some(raw) => rectified_box(raw, b),
                None => b,
            };
            b.iter()
                .all(|v| v.is_finite())
                .then(|| rect(b, w, h))
                .flatten()
        })
        .collect();
    let wanted: Vec<Rect> = boxes.iter().flatten().copied().collect();
    let params = &ranged.params;
    let Correspondences {
        mut map,
        mut found,
        mut timings,
        rows_matched,
    } = correspond::correspond(&left.grey, &right.grey, params, &rectified, &wanted, cancel)?;
    timings.cost += surveyed;
    // A point the coarse view puts past the range's end is out of range, whatever its best
    // cost inside it; so is one whose pixel the range's judgement refuses (a given range
    // that stops short refuses the coarse view's holes among what runs past it too).
    let pixels: Vec<Option<(usize, usize)>> = rectified
        .iter()
        .map(|&(x, y)| correspond::pixel(x, y, w, h))
        .collect();
    let valid = |map: &Disparity, (x, y): (usize, usize)| !map.data[y * w + x].is_nan();
    let before: Vec<bool> = pixels
        .iter()
        .map(|p| p.is_some_and(|p| valid(&map, p)))
        .collect();
    let judged = ranged.judge(&mut map, Some(request.calibrated.rig));
    // A pair that looks swapped has its scene at negative disparities, outside any range
    // searched: what was matched inside it is not the scene, so no point or box is measured
    // on it (the warning says why), rather than answered with a confident wrong distance. A
    // point already `ambiguous` keeps that word (a repeating texture can look swapped too).
    let swapped = ranged.swapped();
    for ((f, pixel), before) in found.iter_mut().zip(pixels).zip(before) {
        if let Some(pixel) = pixel
            && f.disparity.is_some()
            && ((swapped && f.status != MatchOutcome::Ambiguous)
                || ranged.past(pixel)
                || (before && !valid(&map, pixel)))
        {
            f.status = MatchOutcome::OutOfRange;
        }
    }
    if swapped {
        map.data.fill(f32::NAN);
    }
    let at = Measuring {
        rig: &request.calibrated.rig,
        latlon: raw.and_then(|r| r.latlon.as_ref()),
    };
    let points = points
        .iter()
        .zip(&rectified)
        .zip(found)
        .map(|((&(x, y), &(xr, yr)), found)| {
            let mut answer = point_match(at, (xr, yr), found);
            if let Some(raw) = raw {
                answer.rectified = xr.is_finite().then_some((xr, yr));
                answer.right_raw = answer.x_right.and_then(|xm| to_raw_right(raw, xm, yr));
            }
            (answer.x, answer.y) = (x, y);
            answer
        })
        .collect();
    let regions = regions
        .iter()
        .zip(boxes)
        .map(|(&b, r)| region_match(at, &map, b, r))
        .collect();
    // A pair sent as rectified: do its corners lie on their rows?
    let rows = raw.is_none().then(|| row_check(&left, &right, &ranged));
    let mut warnings = request.calibrated.warnings.clone();
    warnings.extend(decode_notes(&left, &right));
    warnings.extend(judged);
    if !swapped {
        warnings.extend(rows.and_then(|r| unrectified_warning(None, r)));
    }
    Ok(Matches {
        width: w,
        height: h,
        points,
        regions,
        rows_matched,
        timings,
        rectify,
        warnings,
        range: ranged.used,
        latlon: at.latlon.copied(),
    })
}

/// Where a raw left pixel lands in the rectified left image (`None` where the lens model
/// cannot take it there).
pub fn to_rectified(raw: &Raw, (x, y): (f64, f64)) -> Option<(f64, f64)> {
    if let Some(l) = &raw.latlon {
        let ray = raw.pair.left.ray_of_pixel([x, y])?;
        let [u, v] = l.pixel(&(l.r1 * ray));
        return Some((u, v));
    }
    let r = &raw.rectification;
    let k = r.p1.fixed_view::<3, 3>(0, 0).into_owned();
    raw.pair
        .left
        .undistort_to([x, y], &r.r1, &k)
        .map(|[x, y]| (x, y))
}

/// Where a rectified right pixel was seen in the raw right frame.
pub fn to_raw_right(raw: &Raw, x: f64, y: f64) -> Option<[f64; 2]> {
    if let Some(l) = &raw.latlon {
        return raw.pair.right.project(&(l.r2.transpose() * l.ray([x, y])));
    }
    let r = &raw.rectification;
    let k = r.p2.fixed_view::<3, 3>(0, 0).into_owned().try_inverse()?;
    let ray = r.r2.transpose() * (k * nalgebra::Vector3::new(x, y, 1.0));
    raw.pair.right.project(&ray)
}

/// A raw box's rectified image: the rectangle around its corners' images (NaN where one
/// cannot be taken there).
fn rectified_box(raw: &Raw, b: [f64; 4]) -> [f64; 4] {
    let corners = [
        (b[0], b[1]),
        (b[0] + b[2], b[1]),
        (b[0], b[1] + b[3]),
        (b[0] + b[2], b[1] + b[3]),
    ]
    .map(|c| to_rectified(raw, c).unwrap_or((f64::NAN, f64::NAN)));
    let (x0, x1) = corners
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, z), c| {
            (a.min(c.0), z.max(c.0))
        });
    let (y0, y1) = corners
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, z), c| {
            (a.min(c.1), z.max(c.1))
        });
    [x0, y0, x1 - x0, y1 - y0]
}

/// The pixels a box `[x, y, width, height]` covers on a `w × h` image (at least one pixel
/// across and down), or `None` when it is wholly off the image.
pub fn rect(b: [f64; 4], w: usize, h: usize) -> Option<Rect> {
    let span = |start: f64, size: f64, n: usize| {
        let a = start.round();
        let b = (start + size).round().max(a + 1.0);
        let (a, b) = (a.clamp(0.0, n as f64), b.clamp(0.0, n as f64));
        (a < b).then_some((a as usize, b as usize))
    };
    let (x0, x1) = span(b[0], b[2], w)?;
    let (y0, y1) = span(b[1], b[3], h)?;
    Some(Rect { x0, y0, x1, y1 })
}

/// How a match's distance is measured: as `/distance` does with the rig, or in the latlon
/// system the pair was rectified to ([`latlon_measure`]).
#[derive(Clone, Copy)]
struct Measuring<'a> {
    rig: &'a Rig,
    latlon: Option<&'a Latlon>,
}

impl Measuring<'_> {
    /// The measurement of disparity `d` at `(x, y)` with `rig` (its Δd the σ_d).
    fn measure(&self, rig: &Rig, (x, y): (f64, f64), d: f64) -> Result<Measurement, PhysicsError> {
        match self.latlon {
            Some(l) => latlon_measure(l, rig, (x, y), d),
            None => physics::measure(rig, Correspondence::at(x, y, d)),
        }
    }

    /// The distance of disparity `d` at `(x, y)`, without its σ.
    fn distance(&self, (x, y): (f64, f64), d: f64) -> Option<f64> {
        match self.latlon {
            Some(l) => latlon_depth(l, (x, y), d),
            None => self.rig.distance_at(d).ok(),
        }
    }
}

/// A point's match at `(x, y)` (where it was matched): with a disparity (to 1/1000 px, the
/// value the distance is computed from), its match and its `/distance` measurement, which a
/// status that says the disparity is not the point's match withholds
/// ([`MatchOutcome::withheld`]).
fn point_match(at: Measuring, (x, y): (f64, f64), found: Found) -> PointMatch {
    let mut answer = PointMatch {
        x,
        y,
        found,
        rectified: None,
        disparity: None,
        x_right: None,
        right_raw: None,
        disparity_std: None,
        measured: None,
    };
    if let Some(d) = found.disparity {
        let d = round_to(f64::from(d), 3);
        answer.disparity = Some(d);
        answer.x_right = Some(round_to(x - d, 3));
        let (rig, sigma) = with_sigma(at.rig, found.disparity_std);
        answer.disparity_std = sigma;
        if found.status.withheld().is_none() {
            answer.measured = Some(at.measure(&rig, (x, y), d));
        }
    }
    answer
}

/// The rig a match is measured with: its Δd the matcher's σ_d (to 1/1000 px, as answered),
/// so that the depth error is the one error bar σ_Z (with the rig's σ_f and σ_B), the same
/// `/distance` answers for that disparity with that Δd. Without a σ_d, the rig as given.
fn with_sigma(rig: &Rig, sigma_d: Option<f32>) -> (Rig, Option<f64>) {
    let sigma = sigma_d.map(|s| round_to(f64::from(s), 3));
    match sigma.map(|s| rig.with_disparity_error(s)) {
        Some(Ok(measured)) => (measured, sigma),
        _ => (*rig, None),
    }
}

/// A region's answer: the median, 10th and 90th percentile depths of its valid pixels, and the
/// measurement at its centre for the median (in latlon, each percentile's depth at the centre
/// too: a depth there changes with the column as well as the disparity).
fn region_match(at: Measuring, map: &Disparity, b: [f64; 4], r: Option<Rect>) -> RegionMatch {
    let rig = at.rig;
    let mut answer = RegionMatch {
        region: b,
        pixels: r,
        valid_fraction: 0.0,
        measured: None,
        disparity_std: None,
        distance_p10: None,
        distance_p90: None,
    };
    let Some(r) = r else {
        return answer;
    };
    let (values, pixels) = correspond::in_box(map, r);
    // Only disparities in front of the cameras have a depth.
    let (mut values, mut stds): (Vec<f64>, Vec<f32>) = values
        .into_iter()
        .filter(|&(d, _)| f64::from(d) + rig.doffs() > 0.0)
        .map(|(d, s)| (f64::from(d), s))
        .unzip();
    values.sort_by(f64::total_cmp);
    answer.valid_fraction = round_to(values.len() as f64 / pixels.max(1) as f64, 4);
    if values.is_empty() {
        return answer;
    }
    // Nearest rank on the disparities, largest first: depth falls as disparity grows.
    let nearest = |q: f64| values[((1.0 - q) * (values.len() - 1) as f64).round() as usize];
    let median = round_to(nearest(0.5), 3);
    let centre = (
        (r.x0 + r.x1 - 1) as f64 / 2.0,
        (r.y0 + r.y1 - 1) as f64 / 2.0,
    );
    let mid = stds.len() / 2;
    let (_, &mut typical, _) = stds.select_nth_unstable_by(mid, f32::total_cmp);
    let (sigma_rig, sigma) = with_sigma(rig, Some(correspond::median_std(typical, values.len())));
    let Ok(m) = at.measure(&sigma_rig, centre, median) else {
        return answer;
    };
    answer.measured = Some(m);
    answer.disparity_std = sigma;
    answer.distance_p10 = at.distance(centre, nearest(0.1));
    answer.distance_p90 = at.distance(centre, nearest(0.9));
    answer
}
