//! The wire types of the API: requests, responses and their OpenAPI schemas, all derived from
//! these definitions so that the spec cannot drift from the code.
//!
//! Every request member is optional in Rust so that validation can report *all* missing fields
//! at once; the ones the API requires are marked `required` in the schema.

use serde::{Deserialize, Serialize};
use utoipa::{
    IntoParams, PartialSchema, ToSchema,
    openapi::{
        RefOr, Required,
        path::{Parameter, ParameterBuilder, ParameterIn},
        schema::Schema,
    },
};

use crate::physics::{self, LengthUnit};

/// Unit of the baseline and of every length in the response.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum Unit {
    #[default]
    Mm,
    Cm,
    M,
    In,
    Ft,
}

impl From<Unit> for LengthUnit {
    fn from(unit: Unit) -> Self {
        match unit {
            Unit::Mm => LengthUnit::Millimetre,
            Unit::Cm => LengthUnit::Centimetre,
            Unit::M => LengthUnit::Metre,
            Unit::In => LengthUnit::Inch,
            Unit::Ft => LengthUnit::Foot,
        }
    }
}

/// How table rows or chart points are spread across the range.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum Spacing {
    /// Equal steps.
    #[default]
    Linear,
    /// Equal ratios (geometric), denser where the curve bends.
    Log,
}

impl From<Spacing> for physics::Spacing {
    fn from(spacing: Spacing) -> Self {
        match spacing {
            Spacing::Linear => physics::Spacing::Linear,
            Spacing::Log => physics::Spacing::Log,
        }
    }
}

/// The rig as the caller stated it, before validation: the members every request shares.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RigParams {
    pub focal_length_px: Option<f64>,
    pub focal_length_mm: Option<f64>,
    pub sensor_width_mm: Option<f64>,
    pub pixel_size_um: Option<f64>,
    pub horizontal_fov_deg: Option<f64>,
    pub baseline: Option<f64>,
    pub unit: Option<Unit>,
    pub image_width: Option<u32>,
    pub image_height: Option<u32>,
    pub doffs: Option<f64>,
    pub cx: Option<f64>,
    pub cy: Option<f64>,
    pub disparity_error_px: Option<f64>,
}

/// The sample range as the caller stated it, before validation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RangeParams {
    pub distance_min: Option<f64>,
    pub distance_max: Option<f64>,
    pub disparity_min: Option<f64>,
    pub disparity_max: Option<f64>,
    pub spacing: Option<Spacing>,
}

/// Deserializes a member that is present: `null` is refused like any other wrong type, because
/// optional members are optional, not nullable (omit a member to take its default).
fn present<'de, D, T>(deserializer: D) -> Result<Option<T>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de>,
{
    match Option::<T>::deserialize(deserializer)? {
        Some(value) => Ok(Some(value)),
        None => Err(serde::de::Error::custom(
            "must not be null; leave the member out to use its default",
        )),
    }
}

/// Declares a flat request type holding the rig members followed by its own, with
/// `rig_params()` and query-parameter docs. (Flat, because `serde(flatten)` cannot be combined
/// with `deny_unknown_fields`, and a misspelt field must be an error.)
macro_rules! rig_request {
    (
        $(#[$meta:meta])*
        pub struct $name:ident { $($body:tt)* }
    ) => {
        #[derive(Debug, Clone, Default, PartialEq, Deserialize, ToSchema)]
        #[serde(deny_unknown_fields)]
        $(#[$meta])*
        pub struct $name {
            /// Focal length in pixels (`fx` from a calibration). Give exactly one of
            /// `focal_length_px`, `focal_length_mm` (with `sensor_width_mm` or `pixel_size_um`),
            /// or `horizontal_fov_deg`.
            #[schema(nullable = false, exclusive_minimum = 0.0, example = 700.0)]
            #[serde(default, deserialize_with = "present")]
            pub focal_length_px: Option<f64>,
            /// Focal length in millimetres. Needs `sensor_width_mm` or `pixel_size_um` to convert
            /// it to pixels: millimetres times a disparity in pixels is not a length.
            #[schema(nullable = false, exclusive_minimum = 0.0, example = 4.0)]
            #[serde(default, deserialize_with = "present")]
            pub focal_length_mm: Option<f64>,
            /// Sensor width in millimetres, with `focal_length_mm`:
            /// f_px = f_mm · image_width / sensor_width_mm.
            #[schema(nullable = false, exclusive_minimum = 0.0, example = 6.4)]
            #[serde(default, deserialize_with = "present")]
            pub sensor_width_mm: Option<f64>,
            /// Pixel pitch in micrometres, with `focal_length_mm`:
            /// f_px = f_mm · 1000 / pixel_size_um.
            #[schema(nullable = false, exclusive_minimum = 0.0, example = 3.0)]
            #[serde(default, deserialize_with = "present")]
            pub pixel_size_um: Option<f64>,
            /// Horizontal field of view in degrees, over the full image width:
            /// f_px = (image_width / 2) / tan(hfov / 2).
            #[schema(nullable = false, exclusive_minimum = 0.0, exclusive_maximum = 180.0,
                     example = 90.0)]
            #[serde(default, deserialize_with = "present")]
            pub horizontal_fov_deg: Option<f64>,
            /// Distance between the two optical centres, in `unit`.
            #[schema(nullable = false, required = true, exclusive_minimum = 0.0,
                     example = 150.0)]
            #[serde(default, deserialize_with = "present")]
            pub baseline: Option<f64>,
            /// Unit of `baseline` and of every length in the response (default `mm`).
            #[schema(nullable = false)]
            #[serde(default, deserialize_with = "present")]
            pub unit: Option<Unit>,
            /// Image width in pixels.
            #[schema(nullable = false, required = true, minimum = 1, example = 800)]
            #[serde(default, deserialize_with = "present")]
            pub image_width: Option<u32>,
            /// Image height in pixels.
            #[schema(nullable = false, required = true, minimum = 1, example = 600)]
            #[serde(default, deserialize_with = "present")]
            pub image_height: Option<u32>,
            /// Principal-point offset between the cameras in pixels (Middlebury `doffs`), added
            /// to every disparity: Z = B·f / |d + doffs|. Default 0.
            #[schema(nullable = false, example = 0.0)]
            #[serde(default, deserialize_with = "present")]
            pub doffs: Option<f64>,
            /// Principal point x of the left camera in pixels, in [0, image_width]. Default: the
            /// image centre.
            #[schema(nullable = false, minimum = 0.0)]
            #[serde(default, deserialize_with = "present")]
            pub cx: Option<f64>,
            /// Principal point y of the left camera in pixels, in [0, image_height]. Default: the
            /// image centre.
            #[schema(nullable = false, minimum = 0.0)]
            #[serde(default, deserialize_with = "present")]
            pub cy: Option<f64>,
            /// Disparity uncertainty Δd in pixels for the depth error ΔZ = Z²·Δd/(f·B).
            /// Default 0.5 (integer-pixel matching); subpixel matchers reach about 0.1.
            #[schema(nullable = false, minimum = 0.0, example = 0.5)]
            #[serde(default, deserialize_with = "present")]
            pub disparity_error_px: Option<f64>,
            $($body)*
        }

        impl $name {
            /// The rig members of this request.
            pub fn rig_params(&self) -> RigParams {
                RigParams {
                    focal_length_px: self.focal_length_px,
                    focal_length_mm: self.focal_length_mm,
                    sensor_width_mm: self.sensor_width_mm,
                    pixel_size_um: self.pixel_size_um,
                    horizontal_fov_deg: self.horizontal_fov_deg,
                    baseline: self.baseline,
                    unit: self.unit,
                    image_width: self.image_width,
                    image_height: self.image_height,
                    doffs: self.doffs,
                    cx: self.cx,
                    cy: self.cy,
                    disparity_error_px: self.disparity_error_px,
                }
            }
        }

        impl IntoParams for $name {
            fn into_params(_: impl Fn() -> Option<ParameterIn>) -> Vec<Parameter> {
                query_parameters(<$name as PartialSchema>::schema())
            }
        }
    };
}

/// Declares the range members shared by `/table` and `/chart-data`, with `range_params()`.
macro_rules! range_request {
    (
        $(#[$meta:meta])*
        pub struct $name:ident { $($body:tt)* }
    ) => {
        rig_request! {
            $(#[$meta])*
            pub struct $name {
                /// Nearest distance to sample, in `unit`. Give `distance_min` and
                /// `distance_max`, or `disparity_min` and `disparity_max`, or neither (then the
                /// disparities from 1 px across a quarter of the image width are used).
                #[schema(nullable = false, exclusive_minimum = 0.0)]
                #[serde(default, deserialize_with = "present")]
                pub distance_min: Option<f64>,
                /// Farthest distance to sample, in `unit`; greater than `distance_min`.
                #[schema(nullable = false, exclusive_minimum = 0.0)]
                #[serde(default, deserialize_with = "present")]
                pub distance_max: Option<f64>,
                /// Smallest disparity to sample, in pixels; `disparity_min + doffs` must be > 0.
                #[schema(nullable = false)]
                #[serde(default, deserialize_with = "present")]
                pub disparity_min: Option<f64>,
                /// Largest disparity to sample, in pixels; greater than `disparity_min`.
                #[schema(nullable = false)]
                #[serde(default, deserialize_with = "present")]
                pub disparity_max: Option<f64>,
                /// Spacing of the samples across the range (default `linear`).
                #[schema(nullable = false)]
                #[serde(default, deserialize_with = "present")]
                pub spacing: Option<Spacing>,
                $($body)*
            }
        }

        impl $name {
            /// The range members of this request.
            pub fn range_params(&self) -> RangeParams {
                RangeParams {
                    distance_min: self.distance_min,
                    distance_max: self.distance_max,
                    disparity_min: self.disparity_min,
                    disparity_max: self.disparity_max,
                    spacing: self.spacing,
                }
            }
        }
    };
}

rig_request! {
    /// A rig and one correspondence: where a feature appears in the left and right images.
    #[schema(example = json!({
        "focal_length_px": 35, "baseline": 150, "unit": "mm",
        "x_left": 400, "x_right": 350, "image_width": 800, "image_height": 600
    }))]
    pub struct DistanceRequest {
        /// x of the feature in the left image, in pixels, in [0, image_width].
        #[schema(nullable = false, required = true, minimum = 0.0, example = 400.0)]
        #[serde(default, deserialize_with = "present")]
        pub x_left: Option<f64>,
        /// x of the same feature in the right image, in pixels, in [0, image_width].
        #[schema(nullable = false, required = true, minimum = 0.0, example = 350.0)]
        #[serde(default, deserialize_with = "present")]
        pub x_right: Option<f64>,
        /// y (row) of the feature in the left image, in pixels, in [0, image_height], for the
        /// 3D point. Default: `cy`.
        #[schema(nullable = false, minimum = 0.0)]
        #[serde(default, deserialize_with = "present")]
        pub y: Option<f64>,
    }
}

range_request! {
    /// A rig and a range: the sample table of distance against disparity.
    #[schema(example = json!({
        "focal_length_px": 35, "baseline": 150, "unit": "mm",
        "image_width": 800, "image_height": 600,
        "disparity_min": 10, "disparity_max": 100, "steps": 10
    }))]
    pub struct TableRequest {
        /// Number of rows, from 1 to the server's cap (10 000 by default). Default 10.
        #[schema(nullable = false, minimum = 1, example = 10)]
        #[serde(default, deserialize_with = "present")]
        pub steps: Option<u32>,
        /// Left-image x held fixed to compute each row's right-image `normalized_x`, in pixels.
        /// Default: the image centre.
        #[schema(nullable = false, minimum = 0.0)]
        #[serde(default, deserialize_with = "present")]
        pub x_left: Option<f64>,
    }
}

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
        #[schema(nullable = false, minimum = 2, example = 100)]
        #[serde(default, deserialize_with = "present")]
        pub points: Option<u32>,
        /// x of a measured feature in the left image, to mark on the chart (with `x_right`).
        #[schema(nullable = false, minimum = 0.0)]
        #[serde(default, deserialize_with = "present")]
        pub x_left: Option<f64>,
        /// x of the measured feature in the right image (with `x_left`).
        #[schema(nullable = false, minimum = 0.0)]
        #[serde(default, deserialize_with = "present")]
        pub x_right: Option<f64>,
    }
}

/// Documents each member of a request body schema as a query parameter, so that the GET form of
/// an operation is described by the very type its POST form takes.
fn query_parameters(schema: RefOr<Schema>) -> Vec<Parameter> {
    let RefOr::T(Schema::Object(object)) = schema else {
        return Vec::new();
    };
    object
        .properties
        .into_iter()
        .map(|(name, property)| {
            let description = match &property {
                RefOr::T(Schema::Object(o)) => o.description.clone(),
                _ => None,
            };
            let required = if object.required.contains(&name) {
                Required::True
            } else {
                Required::False
            };
            ParameterBuilder::new()
                .name(name)
                .parameter_in(ParameterIn::Query)
                .required(required)
                .description(description)
                .schema(Some(property))
                .build()
        })
        .collect()
}

/// A point in the left camera's frame: x right, y down, z forward, in `unit`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Point {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// Something worth knowing about a result that was still computed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Warning {
    /// Stable code: `negative_disparity` or `large_relative_error`.
    pub code: String,
    /// What it means and what to check.
    pub message: String,
}

/// The distance to one feature, its expected error and the intermediate values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({
    "distance": 105.0, "unit": "mm", "distance_m": 0.105, "depth_error": 1.05,
    "relative_error": 0.01, "disparity_error_px": 0.5, "disparity_px": 50.0,
    "effective_disparity_px": 50.0, "focal_length_px": 35.0, "baseline": 150.0,
    "normalized_x": 0.0, "projection_factor": 0.23333333333333334,
    "point": {"x": 0.0, "y": 0.0, "z": 105.0},
    "formula": "Z = B·f / |d + doffs| = 150 mm × 35 px / |50 px + 0 px| = 105 mm",
    "warnings": []
}))]
pub struct DistanceResponse {
    /// Distance Z along the optical axis, in `unit`.
    pub distance: f64,
    /// Unit of every length in this response (that of the baseline).
    pub unit: Unit,
    /// The distance in metres.
    pub distance_m: f64,
    /// Expected depth error ΔZ = Z²·Δd/(f·B), in `unit`.
    pub depth_error: f64,
    /// depth_error / distance.
    pub relative_error: f64,
    /// The Δd used for `depth_error`, in pixels.
    pub disparity_error_px: f64,
    /// Disparity d = x_left − x_right, in pixels (signed).
    pub disparity_px: f64,
    /// d + doffs, in pixels.
    pub effective_disparity_px: f64,
    /// Focal length in pixels, after any conversion.
    pub focal_length_px: f64,
    /// The baseline, in `unit`.
    pub baseline: f64,
    /// (x_left − W/2) / (W/2): −1 at the left edge of the image, +1 at the right.
    pub normalized_x: f64,
    /// f_px / baseline, in pixels per `unit`.
    pub projection_factor: f64,
    /// The feature's 3D position in the left camera's frame.
    pub point: Point,
    /// The formula with this request's numbers in it.
    pub formula: String,
    /// Caveats about this result; empty when there are none.
    pub warnings: Vec<Warning>,
}

/// One row of the sample table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TableRow {
    /// Distance Z, in `unit`.
    pub distance: f64,
    /// Disparity d, in pixels.
    pub disparity_px: f64,
    /// Normalised x of the right-image feature (x_right = x_left − d).
    pub normalized_x: f64,
    /// f_px / baseline.
    pub projection_factor: f64,
    /// Depth error at this distance, in `unit`.
    pub depth_error: f64,
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
    /// `x_left` and `x_right`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub marker: Option<ChartPoint>,
}
