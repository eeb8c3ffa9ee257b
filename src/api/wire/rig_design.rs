//! The wire types of `/rig` and `/baseline`: what a rig and its disparity search see, and the
//! baseline a depth-error budget needs.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::extract::QueryForm;
use crate::api::wire::de::{camera_request, rig_request};
use crate::api::wire::params::Unit;
use stereo_core::physics::design::ErrorAt;

rig_request! {
    /// A rig and its disparity search: the depth range it sees and the error it makes there.
    #[schema(example = json!({
        "focal_length_px": 424, "baseline": 50, "unit": "mm",
        "image_width": 848, "image_height": 480, "disparity_error_px": 0.08,
        "max_disparity_px": 126, "at_distances": [500, 1000, 2000, 4000],
        "max_relative_error": 0.02
    }))]
    pub struct RigRequest {
        /// Largest disparity the matcher searches, in pixels (64, 95, 126, 256…): it sets
        /// the nearest distance the rig can see, `min_distance = f·B / (max + doffs)`.
        #[schema(required = true, exclusive_minimum = 0.0, example = 126.0)]
        max_disparity_px: f64,
        /// Smallest disparity told apart from infinity, in pixels: it sets the farthest
        /// distance, `max_distance = f·B / (min + doffs)`. Default: `disparity_error_px`, one
        /// subpixel step.
        #[schema(exclusive_minimum = 0.0, example = 0.5)]
        min_disparity_px: f64,
        /// Distances, in `unit`, at which to report the depth error (at most 1 000). In a
        /// query string: comma-separated, `at_distances=500,1000,2000`.
        #[schema(schema_with = at_distances_schema)]
        at_distances: Vec<f64>,
        /// A relative-error budget as a fraction (0.02 is 2 %): the answer says up to which
        /// distance the depth error stays within it.
        #[schema(exclusive_minimum = 0.0, maximum = 1.0, example = 0.02)]
        max_relative_error: f64,
    }
}

/// Most entries in `at_distances`.
pub const MAX_AT_DISTANCES: usize = 1_000;

fn at_distances_schema() -> utoipa::openapi::schema::Array {
    use utoipa::openapi::schema::{ArrayBuilder, ObjectBuilder, Type};
    ArrayBuilder::new()
        .items(
            ObjectBuilder::new()
                .schema_type(Type::Number)
                .format(Some(utoipa::openapi::SchemaFormat::KnownFormat(
                    utoipa::openapi::KnownFormat::Double,
                )))
                .exclusive_minimum(Some(0.0)),
        )
        .max_items(Some(MAX_AT_DISTANCES))
        .description(Some(
            "Distances, in `unit`, at which to report the depth error (at most 1 000). In a \
             query string: comma-separated, `at_distances=500,1000,2000`.",
        ))
        .examples([serde_json::json!([500, 1000, 2000])])
        .build()
}

camera_request! {
    /// The inverse problem: the shortest baseline that keeps the depth error within a budget
    /// at a target distance. Give `max_depth_error` or `max_relative_error`.
    #[schema(example = json!({
        "focal_length_px": 1000, "image_width": 1280, "image_height": 720, "unit": "mm",
        "disparity_error_px": 0.25, "target_distance": 5000, "max_relative_error": 0.005,
        "max_disparity_px": 128
    }))]
    pub struct BaselineRequest {
        /// Distance at which the error budget must hold, in `unit`.
        #[schema(required = true, exclusive_minimum = 0.0, example = 5000.0)]
        target_distance: f64,
    } then {
        /// Largest acceptable depth error at `target_distance`, in `unit`. Give this or
        /// `max_relative_error`.
        #[schema(exclusive_minimum = 0.0, example = 25.0)]
        max_depth_error: f64,
        /// Largest acceptable depth error at `target_distance` as a fraction of it (0.005 is
        /// 0.5 %). Give this or `max_depth_error`.
        #[schema(exclusive_minimum = 0.0, maximum = 1.0)]
        max_relative_error: f64,
        /// Largest disparity the matcher searches, in pixels: with it the answer also gives
        /// the nearest distance the baseline lets the rig see.
        #[schema(exclusive_minimum = 0.0, example = 128.0)]
        max_disparity_px: f64,
    }
}

impl QueryForm for BaselineRequest {}
impl QueryForm for RigRequest {
    const LISTS: &'static [&'static str] = &["at_distances"];
}

/// The depth error at one of the requested distances.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct DepthErrorAt {
    /// The distance, in `unit`.
    pub distance: f64,
    /// The disparity a point at this distance has, in pixels (raw, before `doffs`).
    pub disparity_px: f64,
    /// Expected (RMS) depth error ΔZ = Z²·Δd/(f·B), in `unit`.
    pub depth_error: f64,
    /// depth_error / distance.
    pub relative_error: f64,
    /// The relative error in percent.
    pub relative_error_pct: f64,
    /// Whether the distance lies within [min_distance, max_distance], the range the
    /// disparity search can see.
    pub in_range: bool,
}

impl From<ErrorAt> for DepthErrorAt {
    fn from(at: ErrorAt) -> Self {
        DepthErrorAt {
            distance: at.distance,
            disparity_px: at.disparity_px,
            depth_error: at.depth_error,
            relative_error: at.relative_error,
            relative_error_pct: at.relative_error * 100.0,
            in_range: at.in_range,
        }
    }
}

/// Where the relative depth error passes the caller's budget.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ErrorBudget {
    /// The budget, as a fraction.
    pub max_relative_error: f64,
    /// The distance at which the relative error reaches the budget, Z = r·f·B/Δd, in `unit`;
    /// nearer points do better.
    pub distance: f64,
    /// The answer in words, taking the disparity search's range into account.
    pub summary: String,
}

/// What a rig and its disparity search can see, and how well.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({
    "unit": "mm", "focal_length_px": 424.0, "horizontal_fov_deg": 90.0,
    "vertical_fov_deg": 59.02299711418064, "baseline": 50.0, "fb": 21200.0, "doffs": 0.0,
    "disparity_error_px": 0.08, "min_disparity_px": 0.08, "max_disparity_px": 126.0,
    "min_distance": 168.25396825396825, "max_distance": 265000.0,
    "at_distances": [{"distance": 2000.0, "disparity_px": 10.6, "depth_error": 15.09433962264151,
                      "relative_error": 0.007547169811320755,
                      "relative_error_pct": 0.7547169811320755, "in_range": true}],
    "error_budget": {"max_relative_error": 0.02, "distance": 5300.0,
                     "summary": "the relative depth error is below 2 % from 168.254 mm up to 5300 mm"}
}))]
pub struct RigResponse {
    /// Unit of every length in this response.
    pub unit: Unit,
    /// Focal length in pixels, after any conversion.
    pub focal_length_px: f64,
    /// Horizontal field of view in degrees (principal point at the image centre); absent
    /// without `image_width`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub horizontal_fov_deg: Option<f64>,
    /// Vertical field of view in degrees, from `focal_length_y_px` (principal point at the
    /// centre); absent without `image_height`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub vertical_fov_deg: Option<f64>,
    /// The baseline, in `unit`.
    pub baseline: f64,
    /// f_px·B in px·`unit`: the constant that turns a disparity into a depth, Z = fb / (d + doffs).
    pub fb: f64,
    /// The doffs added to every disparity, in pixels.
    pub doffs: f64,
    /// The Δd used for every depth error, in pixels.
    pub disparity_error_px: f64,
    /// The smallest disparity searched, in pixels.
    pub min_disparity_px: f64,
    /// The largest disparity searched, in pixels.
    pub max_disparity_px: f64,
    /// The nearest distance the search can see, f·B / (max_disparity_px + doffs), in `unit`.
    pub min_distance: f64,
    /// The farthest distance told apart from infinity, f·B / (min_disparity_px + doffs), in
    /// `unit`.
    pub max_distance: f64,
    /// The depth error at each requested distance, in request order.
    pub at_distances: Vec<DepthErrorAt>,
    /// Where the relative error passes `max_relative_error`, when the request gave one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub error_budget: Option<ErrorBudget>,
}

/// The shortest baseline that meets a depth-error budget at a distance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct BaselineResponse {
    /// Unit of every length in this response.
    pub unit: Unit,
    /// Focal length in pixels, after any conversion.
    pub focal_length_px: f64,
    /// Horizontal field of view in degrees; absent without `image_width`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub horizontal_fov_deg: Option<f64>,
    /// The Δd assumed, in pixels.
    pub disparity_error_px: f64,
    /// Where the budget must hold, in `unit`.
    pub target_distance: f64,
    /// The depth-error budget at `target_distance`, in `unit`.
    pub max_depth_error: f64,
    /// The same budget as a fraction of `target_distance`.
    pub max_relative_error: f64,
    /// The shortest baseline meeting the budget, B = Z²·Δd / (f·ΔZ), in `unit`.
    pub baseline: f64,
    /// The disparity of a point at `target_distance` with this baseline, in pixels.
    pub disparity_at_target_px: f64,
    /// The formula with this request's numbers in it.
    pub formula: String,
    /// The largest disparity searched, when the request gave one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub max_disparity_px: Option<f64>,
    /// The nearest distance this baseline lets the search see, f·B / max_disparity_px, in
    /// `unit`; given with `max_disparity_px`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub min_distance: Option<f64>,
}
