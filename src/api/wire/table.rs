//! The wire types of `/table`: a rig and a range in, rows of distance against disparity out,
//! as JSON or CSV (`/table.csv`).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::extract::QueryForm;
use crate::api::wire::de::range_request;
use crate::api::wire::params::Unit;

range_request! {
    /// A rig and a range: the sample table of distance against disparity.
    #[schema(example = json!({
        "focal_length_px": 700, "baseline": 120, "unit": "mm", "image_width": 1280,
        "image_height": 720, "disparity_min": 10, "disparity_max": 100, "steps": 10
    }))]
    pub struct TableRequest {
        /// Number of rows, from 1 to the server's cap (10 000 by default). Default 10.
        #[schema(minimum = 1, example = 10)]
        steps: u32,
        /// Left-image x held fixed to compute each row's right-image `normalized_x`, in pixels.
        /// Default: the image centre (`cx` when the image width is not given).
        #[schema(minimum = 0.0)]
        x_left: f64,
    }
}

impl QueryForm for TableRequest {}

/// One row of the sample table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TableRow {
    /// Distance Z, in `unit`.
    pub distance: f64,
    /// Disparity d, in pixels.
    pub disparity_px: f64,
    /// Normalised x of the right-image feature (x_right = x_left − d); absent without
    /// `image_width`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub normalized_x: Option<f64>,
    /// f_px / baseline.
    pub projection_factor: f64,
    /// Depth error at this distance, in `unit`.
    pub depth_error: f64,
    /// depth_error / distance.
    pub relative_error: f64,
}

/// The sample table of distance against disparity for a rig.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TableResponse {
    /// Unit of every length in the table.
    pub unit: Unit,
    /// Focal length in pixels, after any conversion.
    pub focal_length_px: f64,
    /// The baseline, in `unit`.
    pub baseline: f64,
    /// The Δd used for `depth_error`, in pixels.
    pub disparity_error_px: f64,
    /// The left-image x used for `normalized_x`, in pixels.
    pub x_left: f64,
    /// The rows, in ascending order of the ranged quantity.
    pub rows: Vec<TableRow>,
}
