//! The wire types of `/distance`: one correspondence or a batch in, a distance or one
//! outcome per point out.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::error::FieldError;
use crate::api::extract::QueryForm;
use crate::api::wire::de::{present, request, rig_request};
use crate::api::wire::measured::Measured;
use crate::api::wire::params::Unit;

rig_request! {
    /// A rig and one correspondence: where a feature appears in the left and right images.
    #[schema(example = json!({
        "focal_length_px": 35, "baseline": 150, "unit": "mm",
        "x_left": 400, "x_right": 350, "image_width": 800, "image_height": 600
    }))]
    pub struct DistanceRequest {
        /// x of the feature in the left image, in pixels, in [0, image_width]. Required with
        /// `x_right`; with `disparity_px` it only places the 3D point (default `cx`).
        #[schema(minimum = 0.0, example = 400.0)]
        x_left: f64,
        /// x of the same feature in the right image, in pixels, in [0, image_width]. Give
        /// `x_right` or `disparity_px`, not both.
        #[schema(minimum = 0.0, example = 350.0)]
        x_right: f64,
        /// The disparity d = x_left − x_right in pixels, as a matcher gives it, instead of
        /// `x_right`. Give `x_right` or `disparity_px`, not both.
        disparity_px: f64,
        /// y (row) of the feature in the left image, in pixels, in [0, image_height], for the
        /// 3D point. Default: `cy`.
        #[schema(minimum = 0.0)]
        y: f64,
    }
}

pub use crate::api::wire::rig::StereoRig;

request! {
    /// One correspondence of a batch. Its shape is checked with the whole request (a wrong
    /// type, an unknown or missing member is a 422 for the batch); its values against the rig,
    /// point by point (a coordinate off the image or a point at infinity is that point's own
    /// `errors` in the 200 answer), so the schema bounds no value.
    pub struct BatchPoint {
        /// x of the feature in the left image, in pixels; must lie in [0, image_width], or the
        /// point fails on its own. Required with `x_right`; default `cx` with `disparity_px`.
        #[schema(example = 400.0)]
        x_left: f64,
        /// x of the same feature in the right image, in pixels; must lie in [0, image_width],
        /// or the point fails on its own. Give `x_right` or `disparity_px`, not both (both
        /// is a 422 for the batch).
        #[schema(example = 350.0)]
        x_right: f64,
        /// The disparity d = x_left − x_right in pixels, instead of `x_right`.
        disparity_px: f64,
        /// y (row) of the feature in the left image, in pixels; must lie in [0, image_height],
        /// or the point fails on its own. Default: the rig's `cy`.
        y: f64,
    }
}

/// Many correspondences sharing one rig, answered in one response in the same order.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
#[schema(example = json!({
    "rig": {"focal_length_px": 35, "baseline": 150, "image_width": 800, "image_height": 600},
    "points": [{"x_left": 400, "x_right": 350}, {"x_left": 420, "x_right": 390, "y": 310}]
}))]
pub struct BatchDistanceRequest {
    /// The rig every point is seen by.
    #[schema(nullable = false, required = true)]
    #[serde(default, deserialize_with = "present")]
    pub rig: Option<StereoRig>,
    /// The correspondences: from 1 to the server's cap (10 000 by default).
    #[schema(nullable = false, required = true, min_items = 1)]
    #[serde(default, deserialize_with = "present")]
    pub points: Option<Vec<BatchPoint>>,
}

/// The body of `POST /distance`: one correspondence with its rig, or a batch.
#[derive(Debug, Clone, PartialEq, Deserialize, ToSchema)]
#[serde(untagged)]
pub enum DistanceInput {
    One(DistanceRequest),
    Batch(BatchDistanceRequest),
}

impl QueryForm for DistanceRequest {}

/// The distance to one feature, its expected error and the intermediate values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({
    "distance": 105.0, "range": 105.0, "unit": "mm", "distance_m": 0.105, "depth_error": 1.05,
    "depth_error_terms": {"disparity": 1.05, "focal_length": 0.0, "baseline": 0.0},
    "relative_error": 0.01, "disparity_error_px": 0.5, "disparity_px": 50.0,
    "effective_disparity_px": 50.0, "focal_length_px": 35.0, "baseline": 150.0,
    "normalized_x": 0.0, "projection_factor": 0.23333333333333334,
    "point": {"x": 0.0, "y": 0.0, "z": 105.0},
    "formula": "Z = B·f / |d + doffs| = 150 mm × 35 px / |50 px + 0 px| = 105 mm",
    "warnings": []
}))]
pub struct DistanceResponse {
    /// Distance, depth error, disparity, 3D point and warnings, as every distance answer has
    /// them.
    #[serde(flatten)]
    pub measured: Measured,
    /// Unit of every length in this response (that of the baseline).
    pub unit: Unit,
    /// The distance in metres.
    pub distance_m: f64,
    /// The Δd used for `depth_error`, in pixels.
    pub disparity_error_px: f64,
    /// d + doffs, in pixels.
    pub effective_disparity_px: f64,
    /// Focal length in pixels, after any conversion.
    pub focal_length_px: f64,
    /// The baseline, in `unit`.
    pub baseline: f64,
    /// (x_left − W/2) / (W/2): −1 at the left edge of the image, +1 at the right. Absent
    /// when the request gave no `image_width`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub normalized_x: Option<f64>,
    /// f_px / baseline, in pixels per `unit`.
    pub projection_factor: f64,
    /// The formula with this request's numbers in it.
    pub formula: String,
}

/// The answer to a batch `POST /distance`: one result per point, in order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct BatchDistanceResponse {
    /// Unit of every length in this response.
    pub unit: Unit,
    /// Focal length in pixels, after any conversion.
    pub focal_length_px: f64,
    /// The baseline, in `unit`.
    pub baseline: f64,
    /// The Δd used for every `depth_error`, in pixels.
    pub disparity_error_px: f64,
    /// How many points the request held.
    pub count: usize,
    /// How many got a distance.
    pub succeeded: usize,
    /// How many got errors instead; check this before using `results`.
    pub failed: usize,
    /// One entry per point, in request order: a distance, or the errors that prevented one.
    pub results: Vec<PointOutcome>,
}

/// The outcome for one point of a batch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(untagged)]
pub enum PointOutcome {
    Measured(PointDistance),
    Failed(PointFailure),
}

/// A point of a batch with its distance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PointDistance {
    /// The point's position in `points`.
    pub index: usize,
    /// Its distance, depth error, disparity, 3D point and warnings, as `/distance` answers
    /// them for the point alone.
    #[serde(flatten)]
    pub measured: Measured,
}

/// A point of a batch that has no distance, with every reason, named like
/// `points[17].x_left`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PointFailure {
    /// The point's position in `points`.
    pub index: usize,
    /// What is wrong with this point; never empty.
    pub errors: Vec<FieldError>,
}

/// The answer of `POST /distance`: a [`DistanceResponse`] for one correspondence, a
/// [`BatchDistanceResponse`] for a batch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(untagged)]
pub enum DistanceOutput {
    One(DistanceResponse),
    Batch(BatchDistanceResponse),
}
