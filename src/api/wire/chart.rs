//! The wire types of `/chart-data` and `/chart.svg`: a rig and a range in, the distance and
//! depth-error series against disparity out.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::extract::QueryForm;
use crate::api::wire::de::{choice_members, range_request};
use crate::api::wire::params::Unit;

range_request! {
    /// A rig and a range: chart series of distance and depth error against disparity.
    #[schema(example = json!({
        "focal_length_px": 35, "baseline": 150, "unit": "mm",
        "image_width": 800, "image_height": 600,
        "x_left": 400, "x_right": 350, "points": 100
    }))]
    pub struct ChartRequest {
        /// Number of points per series, from 2 to the server's cap (10 000 by default).
        /// Default 100.
        #[schema(minimum = 2, example = 100)]
        points: u32,
        /// x of a measured feature in the left image, to mark on the chart (with `x_right`).
        #[schema(minimum = 0.0)]
        x_left: f64,
        /// x of the measured feature in the right image (with `x_left`).
        #[schema(minimum = 0.0)]
        x_right: f64,
        /// The measured feature's disparity in pixels, to mark on the chart instead of
        /// `x_left` and `x_right`.
        disparity_px: f64,
        /// The y axes: `linear` (the default) or `log`, in whole decades, which keeps the far
        /// end of a long range readable (a KITTI rig spans 4 m to 400 m). `/chart.svg` draws
        /// it; `/chart-data` reports it in `y_axis.scale` for the chart library.
        scale: AxisScale,
    }
}

impl QueryForm for ChartRequest {}

/// How an axis maps values to positions.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum AxisScale {
    /// Equal steps of value are equal distances.
    #[default]
    Linear,
    /// Equal ratios of value are equal distances (decades); only positive values are drawn.
    Log,
}

choice_members!(AxisScale);

/// A point of a chart series.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ChartPoint {
    pub x: f64,
    pub y: f64,
}

/// A chart axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Axis {
    /// Label with its unit, ready to print.
    pub label: String,
    /// The unit alone.
    pub unit: String,
    /// `linear` or `log`, as the request asked (the x axis is always linear).
    pub scale: AxisScale,
}

/// One named curve.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Series {
    /// `distance` or `depth_error`.
    pub name: String,
    /// Human-readable legend entry.
    pub label: String,
    /// Unit of the y values.
    pub unit: String,
    /// Points in ascending x (disparity in pixels).
    pub points: Vec<ChartPoint>,
}

/// Chart data: distance and depth error against disparity, ready for a chart library.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ChartResponse {
    /// Unit of every length in the chart.
    pub unit: Unit,
    /// The x axis: disparity in pixels.
    pub x_axis: Axis,
    /// The y axis: distance (and depth error) in `unit`.
    pub y_axis: Axis,
    /// `distance` then `depth_error`.
    pub series: Vec<Series>,
    /// The measured feature (x = its disparity, y = its distance), when the request gave
    /// `x_left` and `x_right`, or `disparity_px`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub marker: Option<ChartPoint>,
}
