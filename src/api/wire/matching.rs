//! The wire types of `/match`: the multipart form (documentation), the points and regions it
//! carries, the query's range, and the answer per point and per region.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::extract::QueryForm;
use crate::api::wire::de::{latlon_request, request};
use crate::api::wire::images::{LatlonSystem, ProjectionChoice, image_form};
pub use crate::api::wire::images::{RectifyMode, StageTimes};
use crate::api::wire::measured::Measured;
use crate::api::wire::measured::{Point, Warning};
use crate::api::wire::params::Unit;
use crate::api::wire::rig::CalibratedRig;
use stereo_core::pipeline::matches::{self, MatchOutcome};

latlon_request! {
    /// The disparity range of `/match`, in the query string.
    pub struct MatchQuery {
        /// The smallest disparity searched ([`super::depth_map::RANGE_START`]).
        #[schema(schema_with = super::depth_map::range_start)]
        min_disparity: stereo_core::vision::RangeEnd,
        /// The search stops before this disparity ([`super::depth_map::RANGE_END`]).
        #[schema(schema_with = super::depth_map::range_end)]
        max_disparity: stereo_core::vision::RangeEnd,
        /// Rectify the pair first: `auto` (the default) when the calibration describes raw
        /// cameras and the frames are their raw size; `yes`, or `no`. Points and boxes are
        /// then given in the raw left image, as a person clicks them.
        rectify: RectifyMode,
        /// With rectification: recompute it as `cv2.stereoRectify` does with this `alpha`.
        #[schema(minimum = 0.0, maximum = 1.0)]
        alpha: f64,
        /// With rectification: the rectified projection, `pinhole` (default), `latlon` or
        /// `auto`, as `/depth-map`'s.
        #[schema(inline, default = "pinhole")]
        projection: crate::api::wire::images::ProjectionAsked,
    }
}

impl QueryForm for MatchQuery {}

request! {
    /// A point in the left image, in pixels (pixel centres at whole numbers, y down). A point
    /// off the image is answered with `status: outside_image`.
    #[schema(example = json!({"x": 412, "y": 230}))]
    pub struct MatchPoint {
        /// Column in the left image, in pixels. Required.
        x: f64,
        /// Row in the left image, in pixels. Required.
        y: f64,
    }
}

request! {
    /// A box in the left image, in pixels: from (`x`, `y`), its top-left corner, `width`
    /// across and `height` down. The part on the image is used; a box wholly off the image is
    /// answered with `status: outside_image`.
    #[schema(example = json!({"x": 380, "y": 200, "width": 60, "height": 60}))]
    pub struct MatchRegion {
        /// Left edge, in pixels. Required.
        x: f64,
        /// Top edge, in pixels. Required.
        y: f64,
        /// Width, in pixels, greater than 0. Required.
        #[schema(exclusive_minimum = 0.0)]
        width: f64,
        /// Height, in pixels, greater than 0. Required.
        #[schema(exclusive_minimum = 0.0)]
        height: f64,
    }
}

image_form! {
    /// The `multipart/form-data` parts of `/match` (for the documentation: the handler reads
    /// the parts itself, to name each one in its errors). Give `rig` or `calibration`.
    pub struct MatchForm {
        /// The points to match, a JSON array of `{"x", "y"}` in the left image: at most
        /// 10 000. Give `points`, `regions` or both. Repeated `points` parts (one point or
        /// array each, as generated clients send an array) are joined in order.
        #[schema(nullable = false, max_items = 10000)]
        points: Option<Vec<MatchPoint>>,
        /// The boxes to measure, a JSON array of `{"x", "y", "width", "height"}`: at most
        /// 1 000. Repeated `regions` parts are joined in order, as `points` are.
        #[schema(nullable = false, max_items = 1000)]
        regions: Option<Vec<MatchRegion>>,
    }
}

/// Whether to trust a point's match, or why not.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum MatchStatus {
    /// The match passed every check.
    Ok,
    /// It fails the left-right check: the right image's best match for its partner points
    /// elsewhere, as where the point is hidden from the right camera.
    Occluded,
    /// Another disparity more than a pixel away matches nearly as well (repeated texture).
    Ambiguous,
    /// The point's neighbourhood has no texture of its own (its grey levels vary by less than
    /// one level of 255): its disparity was carried in from around it.
    Textureless,
    /// No right pixel lies in the disparity range, or the best match is at the end of what
    /// the range and the right image allow: the true one may lie beyond. Every point of a
    /// pair that looks swapped (its scene at negative disparities, below any range; the
    /// warnings say so) is out of range too, but one already `ambiguous`.
    OutOfRange,
    /// Its neighbourhood disagrees: a depth edge, the border of an occlusion, or an isolated
    /// patch the speckle filter removed.
    Inconsistent,
    /// The point is not on the left image.
    OutsideImage,
}

impl From<MatchOutcome> for MatchStatus {
    fn from(s: MatchOutcome) -> Self {
        match s {
            MatchOutcome::Ok => MatchStatus::Ok,
            MatchOutcome::Occluded => MatchStatus::Occluded,
            MatchOutcome::Ambiguous => MatchStatus::Ambiguous,
            MatchOutcome::Textureless => MatchStatus::Textureless,
            MatchOutcome::OutOfRange => MatchStatus::OutOfRange,
            MatchOutcome::Inconsistent => MatchStatus::Inconsistent,
            MatchOutcome::OutsideImage => MatchStatus::OutsideImage,
        }
    }
}

/// The distance members a point's match and a region share, as `/distance` answers them:
/// each absent without a distance, but for a point's disparity and its σ_d (a point
/// `out_of_range` or `occluded` keeps both and gets no distance).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct MatchDistance {
    /// The disparity the distance is computed from, in pixels (to 1/1000 px): the point's
    /// `x − x_right`, or the median of the region's valid pixels.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub disparity_px: Option<f64>,
    /// Depth Z along the optical axis, in `unit`: the point's, or the median of the region's
    /// valid pixels.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub distance: Option<f64>,
    /// The straight-line distance √(X² + Y² + Z²) to `point`, in `unit`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub range: Option<f64>,
    /// The distance's one error bar, in `unit`: the same σ_Z as `distance_std` (this name is
    /// `/distance`'s, whose Δd is here the match's own `disparity_std_px`, not the rig's fixed
    /// `disparity_error_px`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub depth_error: Option<f64>,
    /// The standard deviation σ_d of `disparity_px`, in pixels, from what the matcher saw
    /// there (its cost curve, the left-right check, the neighbourhood; docs/matcher.md): a
    /// point's own, or a region's median's (its pixels' median σ_d · 1.2533 / √k, for k
    /// census windows' worth of valid pixels).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub disparity_std_px: Option<f64>,
    /// The standard deviation σ_Z of `distance`, in `unit`: √((Z²·σ_d/(f·B))² + (Z·σ_f/f)² +
    /// (Z·σ_B/B)²) with σ_d = `disparity_std_px` and the rig's σ_f and σ_B. `/distance` answers
    /// the same as `depth_error` for this disparity with `disparity_error_px` = σ_d.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub distance_std: Option<f64>,
    /// The point in the left camera's frame (a region's: its centre on the image at the
    /// median depth).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub point: Option<Point>,
}

impl From<&stereo_core::physics::Measurement> for MatchDistance {
    fn from(m: &stereo_core::physics::Measurement) -> Self {
        Self {
            disparity_px: Some(m.disparity_px),
            distance: Some(m.distance),
            range: m.range,
            depth_error: Some(m.depth_error),
            disparity_std_px: None,
            distance_std: None,
            point: m.point.map(Point::from),
        }
    }
}

/// One point's match, in the order of `points`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PointMatch {
    /// The point, as given.
    pub x: f64,
    pub y: f64,
    pub status: MatchStatus,
    /// A score in [0, 1], without units, for sorting and thresholds: the margin of the best
    /// match over the next one more than a pixel away, times the share of the 5 × 5
    /// neighbourhood within a pixel of it, times the texture; halved when `status` is not
    /// `ok`, 0 without a disparity. How far to trust the disparity in pixels is
    /// `disparity_std_px`.
    pub confidence: f64,
    /// x of the match in the right image, `x − disparity_px`, in pixels (in the rectified
    /// right image when the pair was rectified); absent without a disparity.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub x_right: Option<f64>,
    /// A rectified raw pair only: the point in the rectified left image, where it was
    /// matched and measured.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub x_rectified: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub y_rectified: Option<f64>,
    /// A rectified raw pair only: the match in the raw right image, to draw a marker on the
    /// frame the user sees.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub x_right_raw: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub y_right_raw: Option<f64>,
    /// The disparity `x − x_right` at the point's pixel (to 1/1000 px) and the `/distance`
    /// answer for `x`, that disparity and `y` with the request's rig, computed by the same
    /// code, present whenever the point has a disparity (whatever its status).
    #[serde(flatten)]
    pub measured: MatchDistance,
    /// σ_Z / distance (`distance_std` / `distance`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub relative_error: Option<f64>,
    /// Caveats about the distance, as `/distance` gives them.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub warnings: Option<Vec<Warning>>,
    /// Why a point with a disparity has no distance: it triangulates at infinity, or its
    /// status (`out_of_range`, `occluded`) says the disparity is not the point's match.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub error: Option<String>,
}

/// Whether a region has a distance, or why not.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum RegionStatus {
    /// At least one pixel in the box has a depth.
    Ok,
    /// No pixel in the box has a depth.
    NoValidPixels,
    /// The box is wholly off the left image.
    OutsideImage,
}

/// One region's distance, in the order of `regions`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RegionMatch {
    /// The box, as given.
    pub x: f64,
    pub y: f64,
    pub width: f64,
    pub height: f64,
    pub status: RegionStatus,
    /// The share of the box's pixels (on the image) with a depth, in [0, 1].
    pub valid_fraction: f64,
    /// The median disparity and depth of those pixels, and the `/distance` answer for the
    /// box's centre at that depth.
    #[serde(flatten)]
    pub measured: MatchDistance,
    /// The 10th percentile of their depths (the near side), in `unit`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub distance_p10: Option<f64>,
    /// The 90th percentile of their depths (the far side), in `unit`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub distance_p90: Option<f64>,
}

/// The answer of `/match`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({
    "width": 741, "height": 500, "min_disparity": 0, "max_disparity": 64, "disparity_range": {"chosen": "given", "why": "given: max_disparity (or the calibration file's ndisp)"}, "unit": "mm", "rectified": false, "projection": "pinhole",
    "ok": 1,
    "matches": [{"x": 420, "y": 260, "status": "ok", "confidence": 0.81, "x_right": 391.642,
                 "disparity_px": 28.358, "distance": 3221.3, "range": 3282.9,
                 "depth_error": 27.5, "disparity_std_px": 0.241, "distance_std": 27.5,
                 "relative_error": 0.00854,
                 "point": {"x": 352.5, "y": 16.8, "z": 3221.3}, "warnings": []}],
    "regions": [],
    "rig": {"focal_length_px": 994.978, "baseline": 193.001, "unit": "mm", "cx": 311.193,
            "cy": 254.877, "doffs": 31.086, "image_width": 741, "image_height": 500},
    "rows_matched": 69,
    "timings_ms": {"decode": 4.6, "cost": 2.1, "aggregate": 3.9, "refine": 1.2},
    "warnings": []
}))]
pub struct MatchResponse {
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// The smallest disparity searched.
    pub min_disparity: i32,
    /// The search stopped before this disparity.
    pub max_disparity: i32,
    /// How the disparity range was chosen: given, found from the pair, or the default.
    pub disparity_range: super::depth_map::RangeAnswer,
    /// The unit of every length in the answer: the rig's.
    pub unit: Unit,
    /// How many points are `ok`.
    pub ok: usize,
    /// One per point, in order.
    pub matches: Vec<PointMatch>,
    /// One per region, in order.
    pub regions: Vec<RegionMatch>,
    /// The rig used.
    pub rig: CalibratedRig,
    /// How many image rows were matched: only those the points and regions need, with context,
    /// unless they cover most of the image.
    pub rows_matched: usize,
    pub timings_ms: StageTimes,
    /// Whether the raw pair was rectified here first (`width` and `height` are then the
    /// rectified size, and `x_rectified`, `x_right_raw`… are given).
    pub rectified: bool,
    /// The rectified projection the pair was matched in; for `latlon`, its system (points'
    /// `x_rectified` is then azimuth and `y_rectified` elevation; `distance` is the depth
    /// along the rectified axis and `range` along the point's ray, mrcal's `stereo_range`).
    pub projection: ProjectionChoice,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub latlon: Option<LatlonSystem>,
    /// Things to know about the answer (such as a calibration option that did not apply).
    pub warnings: Vec<String>,
}

impl MatchDistance {
    /// A measurement made with the σ_d it stands on, mapped as `/distance` maps it, with its
    /// σ_Z as `distance_std` (its `depth_error`).
    fn with_bar(m: &stereo_core::physics::Measurement, sigma: Option<f64>) -> MatchDistance {
        MatchDistance {
            disparity_std_px: sigma,
            distance_std: sigma.map(|_| m.depth_error),
            ..MatchDistance::from(m)
        }
    }
}

impl PointMatch {
    /// The engine's match of a point, in the members `/distance` answers.
    fn of(p: &matches::PointMatch) -> PointMatch {
        let round = |v: f64| stereo_core::numbers::round_to(v, 3);
        let mut answer = PointMatch {
            x: p.x,
            y: p.y,
            status: p.found.status.into(),
            confidence: stereo_core::numbers::round_to(f64::from(p.found.confidence), 3),
            x_right: p.x_right,
            x_rectified: p.rectified.map(|(x, _)| round(x)),
            y_rectified: p.rectified.map(|(_, y)| round(y)),
            x_right_raw: p.right_raw.map(|[u, _]| round(u)),
            y_right_raw: p.right_raw.map(|[_, v]| round(v)),
            measured: MatchDistance {
                disparity_px: p.disparity,
                ..MatchDistance::default()
            },
            relative_error: None,
            warnings: None,
            error: None,
        };
        match &p.measured {
            Some(Ok(m)) => {
                answer.measured = MatchDistance::with_bar(m, p.disparity_std);
                let m = Measured::from(m);
                answer.relative_error = Some(m.relative_error);
                answer.warnings = Some(m.warnings);
            }
            Some(Err(e)) => answer.error = Some(e.to_string()),
            None if p.disparity.is_some() => {
                answer.measured.disparity_std_px = p.disparity_std;
                answer.error = p.found.status.withheld().map(str::to_owned);
            }
            None => {}
        }
        answer
    }
}

impl RegionMatch {
    /// The engine's answer for a region.
    fn of(r: &matches::RegionMatch) -> RegionMatch {
        let [x, y, width, height] = r.region;
        RegionMatch {
            x,
            y,
            width,
            height,
            status: match (&r.pixels, &r.measured) {
                (None, _) => RegionStatus::OutsideImage,
                (Some(_), None) => RegionStatus::NoValidPixels,
                (Some(_), Some(_)) => RegionStatus::Ok,
            },
            valid_fraction: r.valid_fraction,
            measured: r
                .measured
                .as_ref()
                .map(|m| MatchDistance::with_bar(m, r.disparity_std))
                .unwrap_or_default(),
            distance_p10: r.distance_p10,
            distance_p90: r.distance_p90,
        }
    }
}

impl MatchResponse {
    /// The answer of the engine's matches, made with `rig`, from a pair that took
    /// `decode` to read.
    pub fn of(
        found: &matches::Matches,
        rig: &stereo_core::physics::Rig,
        decode: std::time::Duration,
    ) -> MatchResponse {
        let ms = |d: std::time::Duration| (d.as_secs_f64() * 1e4).round() / 10.0;
        let t = &found.timings;
        let points: Vec<PointMatch> = found.points.iter().map(PointMatch::of).collect();
        let unit = rig.unit();
        let rig = CalibratedRig::from(rig);
        MatchResponse {
            width: found.width,
            height: found.height,
            min_disparity: found.range.min,
            max_disparity: found.range.max,
            disparity_range: super::depth_map::RangeAnswer::from(&found.range),
            unit: rig.unit,
            ok: points
                .iter()
                .filter(|m| m.status == MatchStatus::Ok)
                .count(),
            matches: points,
            regions: found.regions.iter().map(RegionMatch::of).collect(),
            rig,
            rows_matched: found.rows_matched,
            timings_ms: StageTimes {
                decode: ms(decode),
                cost: ms(t.cost),
                aggregate: ms(t.aggregate),
                refine: ms(t.refine),
                rectify: found.rectify.map(ms),
            },
            rectified: found.rectify.is_some(),
            projection: match found.latlon {
                Some(_) => ProjectionChoice::Latlon,
                None => ProjectionChoice::Pinhole,
            },
            latlon: found.latlon.map(|l| LatlonSystem::of(&l, unit)),
            warnings: found.warnings.clone(),
        }
    }
}
