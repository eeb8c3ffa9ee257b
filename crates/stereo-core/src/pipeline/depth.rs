//! A depth map from a pair: the pair rectified when it is raw, matched, then each pixel's
//! depth, σ_Z and 3D point from the rig; the warnings a user needs (a pair sent as rectified
//! that looks raw, what the decoder forgave). The files are [`super::files`]'.

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use super::calibrated::Calibrated;
pub use super::latlon::{latlon_depth_stds, latlon_depths};
use super::range::{self, RangeUsed, Ranged, Stopped};
use super::rectify::Maps;
use crate::calibration::files::Raw;
use crate::camera::Latlon;
use crate::physics::Rig;
use crate::vision::decode::Decoded;
use crate::vision::rows::{self, RowOffsets};
use crate::vision::sparse::{SparseMatch, full_range, sparse_matches};
use crate::vision::temporal::{Counts, Temporal};
use crate::vision::{self, Disparity, Params, Timings};

/// Below this share of matched pixels, a pair sent as rectified may well be raw.
pub const UNRECTIFIED_SHARE: f64 = 0.2;
/// Matched corners this many rows apart (the median) mean the rows do not line up: a
/// rectified pair's are a few tenths of a pixel.
pub const UNRECTIFIED_ROWS: f64 = 1.0;
/// The corners the row check needs before it speaks.
pub const ROW_FEATURES: usize = 8;

/// How a depth map is made: the matcher's settings, the rig (none for disparities alone), the
/// maps of a raw pair (none for a pair sent as rectified), and what the caller will want.
#[derive(Debug, Clone, Copy)]
pub struct Request<'a> {
    pub params: &'a Params,
    pub calibrated: Option<&'a Calibrated>,
    /// The raw rig's maps: the pair is rectified through them first.
    pub maps: Option<&'a Maps>,
    /// Keep the left image's colours (a point cloud's).
    pub colour: bool,
    /// Compute each depth's σ_Z.
    pub depth_std: bool,
    /// Match sparse corners of the rectified pair too ([`Matched::take_sparse`]), for a
    /// stream that checks its calibration ([`super::check::Watch`]).
    pub sparse: bool,
}

/// A depth map and what it was made from.
#[derive(Debug)]
pub struct DepthMap {
    /// The disparities, with each one's σ_d.
    pub disparity: Disparity,
    /// The rig the depths use (the rectified rig, for a raw pair).
    pub rig: Option<Rig>,
    /// The latitude-longitude system the pair was rectified to, when it was: then the map's
    /// pixels are azimuth and elevation, and the depths and points are its ([`super::latlon`]).
    pub latlon: Option<Latlon>,
    /// The raw rig the pair was rectified with here, when it was (its left camera's own
    /// pixels are [`super::left_frame`]'s).
    pub raw: Option<Raw>,
    /// Z = f·B / (d + doffs) in the rig's unit (for latlon, the range's component along the
    /// rectified axis), NaN where the disparity is invalid.
    pub depth: Option<Vec<f32>>,
    /// σ_Z of each depth, when asked for.
    pub depth_std: Option<Vec<f32>>,
    /// The left image's colours (rectified with it), when asked for.
    pub rgb: Option<Vec<u8>>,
    /// The share of pixels with a disparity.
    pub valid_fraction: f64,
    /// What is wrong or was forgiven, in sentences.
    pub warnings: Vec<String>,
    /// The matcher's stages.
    pub timings: Timings,
    /// How long rectifying took, for a raw pair.
    pub rectify: Option<Duration>,
    /// How long the depths and their σ took.
    pub depths: Duration,
    /// What a stream's temporal filter did to the disparities, and how long it took.
    pub temporal: Option<(Counts, Duration)>,
    /// The range matched over, and why.
    pub range: RangeUsed,
}

impl DepthMap {
    /// The projection the map's pixels are in: `latlon` (azimuth and elevation) or `pinhole`.
    pub fn projection(&self) -> &'static str {
        match self.latlon {
            Some(_) => "latlon",
            None => "pinhole",
        }
    }

    /// One line naming the projection for a file's header, for latlon with its system.
    pub fn projection_note(&self) -> String {
        match &self.latlon {
            Some(l) => format!(
                "projection latlon: pixel (x, y) is azimuth (x - {:.6}) / {:.6} and elevation \
                 (y - {:.6}) / {:.6} radians about the rectified baseline",
                l.cx, l.fx, l.cy, l.fy
            ),
            None => "projection pinhole".to_owned(),
        }
    }

    /// The warnings and, for a raw pair, the note that it was rectified first (what was done,
    /// not a fault: a summary says it, a file answer's warnings do not).
    pub fn said(&self) -> Vec<String> {
        let mut said = self.warnings.clone();
        if self.rectify.is_some() {
            said.push(format!(
                "the raw pair was rectified first: the maps are the rectified left camera's, {} \
                 × {} px, and the depths use the rectified rig",
                self.disparity.width, self.disparity.height
            ));
        }
        said
    }
}

/// A depth map of the decoded pair: rectified first through `request.maps`, matched with
/// `request.params` over the range they give or the one found from the pair
/// ([`range::choose`]), and given depths with the rig. `Err` when `cancel` was set, or no
/// range was given and the scene needs more than one search covers.
pub fn depth_map(
    left: Decoded,
    right: Decoded,
    request: Request<'_>,
    cancel: &AtomicBool,
) -> Result<DepthMap, Stopped> {
    matched(left, right, request, cancel).map(|m| m.depth_map(request))
}

/// A pair matched, before its depths: the first half of [`depth_map`], for a stream that
/// steadies the disparities ([`Matched::steady`]) between the halves, in its frames' order,
/// while other frames are matched or given depths at once.
#[derive(Debug)]
pub struct Matched {
    /// The disparities, with each one's σ_d.
    pub disparity: Disparity,
    rgb: Option<Vec<u8>>,
    warnings: Vec<String>,
    timings: Timings,
    rectify: Option<Duration>,
    temporal: Option<(Counts, Duration)>,
    range: RangeUsed,
    sparse: Vec<SparseMatch>,
}

/// The first half of [`depth_map`]: the pair rectified through `request.maps` when there are
/// some, matched, and what a user should hear about it (a pair sent as rectified that looks
/// raw, what the decoder forgave, a range that stops short, cameras that look swapped). `Err`
/// as [`depth_map`]'s.
pub fn matched(
    mut left: Decoded,
    mut right: Decoded,
    request: Request<'_>,
    cancel: &AtomicBool,
) -> Result<Matched, Stopped> {
    let (rectify, ranged, surveyed) = range::rectify_and_choose(
        request.maps,
        (&mut left, &mut right),
        request.colour,
        request.params,
        cancel,
    )?;
    let params = &ranged.params;
    let (mut map, mut timings) = vision::disparity(&left.grey, &right.grey, params, cancel)?;
    // A raw pair, rectified: its corners' rows, for a calibration's check.
    let sparse = if request.sparse && rectify.is_some() {
        sparse_matches(&left.grey, &right.grey, full_range(left.grey.width))
    } else {
        Vec::new()
    };
    timings.cost += surveyed;
    // What the matcher answered, before a range that stops short refuses what lies past it,
    // over the pixels its coarse view puts inside the range (a low share then is the range's,
    // not a raw pair's).
    let matched_share = matched_share(&map, ranged.past_share());
    let started = Instant::now();
    let judged = ranged.judge(&mut map, request.calibrated.map(|c| c.rig));
    timings.refine += started.elapsed();
    // A pair sent as rectified: do its matched corners lie on their rows?
    let rows = rectify
        .is_none()
        .then(|| row_check(&left, &right, &ranged))
        .flatten();
    let mut warnings = request
        .calibrated
        .map_or_else(Vec::new, |c| c.warnings.clone());
    warnings.extend(decode_notes(&left, &right));
    let swapped = ranged.swapped();
    warnings.extend(judged);
    drop(right);
    if rectify.is_none()
        && !swapped
        && let Some(warning) = unrectified_warning(Some(matched_share), rows)
    {
        warnings.push(warning);
    }
    Ok(Matched {
        disparity: map,
        rgb: left.rgb.take().filter(|_| request.colour),
        warnings,
        timings,
        rectify,
        temporal: None,
        range: ranged.used,
        sparse,
    })
}

/// The share of a map's pixels with a disparity.
fn valid_share(map: &Disparity) -> f64 {
    let valid = map.data.iter().filter(|d| !d.is_nan()).count();
    valid as f64 / map.data.len().max(1) as f64
}

/// [`valid_share`], under [`UNRECTIFIED_SHARE`] of the pixels neither blank
/// ([`Disparity::blank`]) nor past the range's end (`past`, the share of the image the pair's
/// coarse view puts there, [`Ranged::past_share`]): a range that stops short leaves those
/// unmatched, which says nothing of the pair's rectification.
fn matched_share(map: &Disparity, past: f64) -> f64 {
    let share = valid_share(map);
    if share >= UNRECTIFIED_SHARE {
        return share;
    }
    let n = map.data.len() as f64;
    let blank = map.blank.iter().filter(|&&b| b).count() as f64;
    let judged = (n - blank - past.clamp(0.0, 1.0) * n).max(1.0);
    (share * n / judged).min(1.0)
}

impl Matched {
    /// The range the pair was matched over, and why.
    pub fn range(&self) -> RangeUsed {
        self.range
    }

    /// The rectified pair's sparse matches, when the request asked for them and the pair was
    /// rectified here (empty otherwise), taken out.
    pub fn take_sparse(&mut self) -> Vec<SparseMatch> {
        std::mem::take(&mut self.sparse)
    }

    /// Steadies the disparities with a stream's temporal filter (this frame being the
    /// filter's next), recording what it did and how long it took.
    pub fn steady(&mut self, filter: &mut Temporal) {
        let started = Instant::now();
        let counts = filter.apply(&mut self.disparity);
        self.temporal = Some((counts, started.elapsed()));
    }

    /// The second half of [`depth_map`]: each pixel's depth and, when `request` asks, its
    /// σ_Z, with the rig.
    pub fn depth_map(self, request: Request<'_>) -> DepthMap {
        let started = Instant::now();
        let map = self.disparity;
        let rig = request.calibrated.map(|c| c.rig);
        // Latitude-longitude only where the pair was rectified to it here.
        let raw = request
            .maps
            .and(request.calibrated)
            .and_then(|c| c.raw.as_deref().cloned());
        let latlon = raw.as_ref().and_then(|r| r.latlon);
        let depth = rig.map(|rig| match &latlon {
            Some(l) => latlon_depths(&map, l),
            None => depths(&map, rig),
        });
        let depth_std = match (rig, &depth) {
            (Some(rig), Some(depth)) if request.depth_std => Some(match &latlon {
                Some(l) => latlon_depth_stds(&map, depth, l, rig),
                None => depth_stds(&map, depth, rig),
            }),
            _ => None,
        };
        DepthMap {
            valid_fraction: valid_share(&map),
            disparity: map,
            rig,
            latlon,
            raw,
            depth,
            depth_std,
            rgb: self.rgb,
            warnings: self.warnings,
            timings: self.timings,
            rectify: self.rectify,
            depths: started.elapsed(),
            temporal: self.temporal,
            range: self.range,
        }
    }
}

/// What the decoder forgave in the pair's images (a JPEG read without its end-of-image
/// marker), each sentence naming its image: `left has no end-of-image marker …`.
pub fn decode_notes(left: &Decoded, right: &Decoded) -> Vec<String> {
    [("left", left), ("right", right)]
        .into_iter()
        .filter_map(|(name, d)| d.note.as_ref().map(|note| format!("{name} {note}")))
        .collect()
}

/// The row check of a pair sent as rectified ([`vision::rows`]), over the range the scene
/// needs ([`Ranged::rows_range`]).
pub fn row_check(left: &Decoded, right: &Decoded, ranged: &Ranged) -> Option<RowOffsets> {
    rows::row_offsets(&left.grey, &right.grey, ranged.rows_range())
}

/// The warning for a pair sent as rectified that looks raw: too few pixels matched
/// (`valid_fraction`, when the whole map was matched), or its matched corners off their rows.
/// `None` when neither shows.
pub fn unrectified_warning(
    valid_fraction: Option<f64>,
    rows: Option<RowOffsets>,
) -> Option<String> {
    let mut signs = Vec::new();
    if let Some(share) = valid_fraction.filter(|&v| v < UNRECTIFIED_SHARE) {
        signs.push(format!("only {:.1} % of the pixels matched", share * 100.0));
    }
    if let Some(rows) =
        rows.filter(|r| r.features >= ROW_FEATURES && r.median_offset >= UNRECTIFIED_ROWS)
    {
        signs.push(format!(
            "matched corners lie {:.1} px off their rows (the median of {}; a rectified pair's \
             are under {UNRECTIFIED_ROWS} px)",
            rows.median_offset, rows.features
        ));
    }
    if signs.is_empty() {
        return None;
    }
    Some(format!(
        "{}: if these are raw frames (lens distortion, rows that do not line up between the \
         cameras), they need rectifying: send the calibration of the raw cameras (a \
         stereoCalibrate file, a ROS CameraInfo pair with D K R P, KITTI's \
         calib_cam_to_cam.txt, /calibrate's opencv.yml) as the calibration part with \
         rectify=auto, or rectify them with /rectify",
        signs.join(", and ")
    ))
}

/// Depth Z = f·B / (d + doffs) of each pixel, NaN where the disparity is invalid or the point
/// would be at or beyond infinity (d + doffs ≤ 0).
pub fn depths(map: &Disparity, rig: Rig) -> Vec<f32> {
    let (fb, doffs) = (rig.fb() as f32, rig.doffs() as f32);
    map.data
        .iter()
        .map(|&d| {
            let effective = d + doffs;
            if effective > 0.0 {
                fb / effective
            } else {
                f32::NAN
            }
        })
        .collect()
}

/// σ_Z of each depth: `√((Z²·σ_d / (f·B))² + (Z·σ_f / f)² + (Z·σ_B / B)²)` with the pixel's
/// σ_d and the rig's σ_f and σ_B; NaN where the depth is.
pub fn depth_stds(map: &Disparity, depth: &[f32], rig: Rig) -> Vec<f32> {
    depth
        .iter()
        .zip(&map.std)
        .map(|(&z, &s)| {
            if z.is_nan() || s.is_nan() {
                f32::NAN
            } else {
                rig.depth_error_terms_with(f64::from(z), f64::from(s))
                    .total() as f32
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A map with `valid` of its 1000 pixels matched and `blank` of them blank.
    fn map(valid: usize, blank: usize) -> Disparity {
        Disparity {
            width: 100,
            height: 10,
            data: (0..1000)
                .map(|i| if i < valid { 5.0 } else { f32::NAN })
                .collect(),
            std: vec![0.2; 1000],
            filled: Vec::new(),
            blank: (0..1000).map(|i| i >= 1000 - blank).collect(),
        }
    }

    /// The share of a pair matched is judged over the pixels inside the range: 14.5 % matched
    /// with 35.6 % of the image past a range that stops short (OpenCV's photograph 05 at
    /// 96 disparities) is 22.5 % of the rest, no sign of a raw pair; with nothing past the
    /// range it is one, and blank pixels are left out as before.
    #[test]
    fn a_short_ranges_refusals_are_not_a_raw_sign() {
        let short = matched_share(&map(145, 0), 0.356);
        assert!((short - 0.145 / 0.644).abs() < 1e-9, "{short}");
        assert!(unrectified_warning(Some(short), None).is_none());
        let whole = matched_share(&map(145, 0), 0.0);
        assert!((whole - 0.145).abs() < 1e-12, "{whole}");
        assert!(
            unrectified_warning(Some(whole), None)
                .is_some_and(|w| w.starts_with("only 14.5 % of the pixels matched"))
        );
        assert!((matched_share(&map(145, 275), 0.0) - 0.2).abs() < 1e-9);
        // Above the threshold the share is the map's own; never above 1.
        assert_eq!(matched_share(&map(300, 0), 0.9), 0.3);
        assert_eq!(matched_share(&map(150, 500), 1.0), 1.0);
    }
}
