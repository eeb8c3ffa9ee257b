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
        path::{Parameter, ParameterBuilder, ParameterIn, ParameterStyle},
        schema::Schema,
    },
};

use super::{error::FieldError, extract::QueryForm};
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

/// The representation of a `/table` answer.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum TableFormat {
    /// `application/json`: a [`TableResponse`].
    #[default]
    Json,
    /// `text/csv`: a header row, then one line per row, with the columns of [`TableRow`].
    Csv,
}

/// The URL query of `POST /table`, which may choose the format there instead of in the body.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct FormatQuery {
    /// `json` or `csv`; overrides the body's `format` and the `Accept` header.
    #[serde(default, deserialize_with = "present")]
    #[param(nullable = false)]
    pub format: Option<TableFormat>,
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

/// The camera as the caller stated it, before validation: focal length, image size, unit and
/// disparity error, the members every request shares.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CameraParams {
    pub focal_length_px: Option<f64>,
    pub focal_length_mm: Option<f64>,
    pub sensor_width_mm: Option<f64>,
    pub pixel_size_um: Option<f64>,
    pub horizontal_fov_deg: Option<f64>,
    pub unit: Option<Unit>,
    pub image_width: Option<u32>,
    pub image_height: Option<u32>,
    pub disparity_error_px: Option<f64>,
}

/// The rig as the caller stated it, before validation: the camera plus the baseline and the
/// principal points.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RigParams {
    pub camera: CameraParams,
    pub baseline: Option<f64>,
    pub doffs: Option<f64>,
    pub cx: Option<f64>,
    pub cy: Option<f64>,
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

/// The largest whole number a request member takes: the schema's `int32` format bounds it.
pub const MAX_WHOLE: u32 = i32::MAX as u32;

/// Deserializes a present whole number. JSON Schema's `integer` is a number with no fractional
/// part, so `800.0` is the integer 800 (as generators such as schemathesis send it); `800.5`,
/// a negative number, one beyond [`MAX_WHOLE`] and `null` are refused.
fn whole<'de, D>(deserializer: D) -> Result<Option<u32>, D::Error>
where
    D: serde::Deserializer<'de>,
{
    struct Whole;

    impl serde::de::Visitor<'_> for Whole {
        type Value = u32;

        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("a whole number")
        }

        fn visit_u64<E: serde::de::Error>(self, n: u64) -> Result<u32, E> {
            match u32::try_from(n) {
                Ok(n) if n <= MAX_WHOLE => Ok(n),
                _ => Err(E::custom(format!("must be at most {MAX_WHOLE}, got {n}"))),
            }
        }

        fn visit_i64<E: serde::de::Error>(self, n: i64) -> Result<u32, E> {
            match u64::try_from(n) {
                Ok(n) => self.visit_u64(n),
                Err(_) => Err(E::custom(format!("must not be negative, got {n}"))),
            }
        }

        fn visit_f64<E: serde::de::Error>(self, x: f64) -> Result<u32, E> {
            if !x.is_finite() || x.fract() != 0.0 {
                Err(E::invalid_type(serde::de::Unexpected::Float(x), &self))
            } else if x < 0.0 {
                Err(E::custom(format!("must not be negative, got {x}")))
            } else if x > f64::from(MAX_WHOLE) {
                Err(E::custom(format!("must be at most {MAX_WHOLE}, got {x}")))
            } else {
                // Exact: a whole number within range converts without loss.
                Ok(x as u32)
            }
        }

        fn visit_unit<E: serde::de::Error>(self) -> Result<u32, E> {
            Err(E::custom(
                "must not be null; leave the member out to use its default",
            ))
        }
    }

    deserializer.deserialize_any(Whole).map(Some)
}

/// Declares a flat request type holding the camera members, with `$early` after the focal
/// options and `$late` at the end, plus `camera_params()` and query-parameter docs. (Flat,
/// because `serde(flatten)` cannot be combined with `deny_unknown_fields`, and a misspelt field
/// must be an error.)
macro_rules! camera_request {
    (
        $(#[$meta:meta])*
        pub struct $name:ident { $($early:tt)* } then { $($late:tt)* }
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
            #[schema(nullable = false, exclusive_minimum = 0.0)]
            #[serde(default, deserialize_with = "present")]
            pub focal_length_mm: Option<f64>,
            /// Sensor width in millimetres, with `focal_length_mm`:
            /// f_px = f_mm · image_width / sensor_width_mm.
            #[schema(nullable = false, exclusive_minimum = 0.0)]
            #[serde(default, deserialize_with = "present")]
            pub sensor_width_mm: Option<f64>,
            /// Pixel pitch in micrometres, with `focal_length_mm`:
            /// f_px = f_mm · 1000 / pixel_size_um.
            #[schema(nullable = false, exclusive_minimum = 0.0)]
            #[serde(default, deserialize_with = "present")]
            pub pixel_size_um: Option<f64>,
            /// Horizontal field of view in degrees, over the full image width:
            /// f_px = (image_width / 2) / tan(hfov / 2).
            #[schema(nullable = false, exclusive_minimum = 0.0, exclusive_maximum = 180.0)]
            #[serde(default, deserialize_with = "present")]
            pub horizontal_fov_deg: Option<f64>,
            $($early)*
            /// Unit of every length in the request and the response (default `mm`).
            #[schema(nullable = false)]
            #[serde(default, deserialize_with = "present")]
            pub unit: Option<Unit>,
            /// Image width in pixels.
            #[schema(nullable = false, required = true, minimum = 1, example = 800)]
            #[serde(default, deserialize_with = "whole")]
            pub image_width: Option<u32>,
            /// Image height in pixels.
            #[schema(nullable = false, required = true, minimum = 1, example = 600)]
            #[serde(default, deserialize_with = "whole")]
            pub image_height: Option<u32>,
            /// Disparity uncertainty Δd in pixels (RMS) for the depth error
            /// ΔZ = Z²·Δd/(f·B). Default 0.5 (integer-pixel matching); subpixel matchers reach
            /// about 0.1.
            #[schema(nullable = false, minimum = 0.0, example = 0.5)]
            #[serde(default, deserialize_with = "present")]
            pub disparity_error_px: Option<f64>,
            $($late)*
        }

        impl $name {
            /// The camera members of this request.
            pub fn camera_params(&self) -> CameraParams {
                CameraParams {
                    focal_length_px: self.focal_length_px,
                    focal_length_mm: self.focal_length_mm,
                    sensor_width_mm: self.sensor_width_mm,
                    pixel_size_um: self.pixel_size_um,
                    horizontal_fov_deg: self.horizontal_fov_deg,
                    unit: self.unit,
                    image_width: self.image_width,
                    image_height: self.image_height,
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

/// Declares a flat request type holding the rig members (camera, baseline, principal points)
/// followed by its own, with `rig_params()`.
macro_rules! rig_request {
    (
        $(#[$meta:meta])*
        pub struct $name:ident { $($body:tt)* }
    ) => {
        camera_request! {
            $(#[$meta])*
            pub struct $name {
                /// Distance between the two optical centres, in `unit`.
                #[schema(nullable = false, required = true, exclusive_minimum = 0.0,
                         example = 150.0)]
                #[serde(default, deserialize_with = "present")]
                pub baseline: Option<f64>,
            } then {
                /// Principal-point offset between the cameras in pixels (Middlebury `doffs`),
                /// added to every disparity: Z = B·f / |d + doffs|. Default 0.
                #[schema(nullable = false, example = 0.0)]
                #[serde(default, deserialize_with = "present")]
                pub doffs: Option<f64>,
                /// Principal point x of the left camera in pixels, in [0, image_width].
                /// Default: the image centre.
                #[schema(nullable = false, minimum = 0.0)]
                #[serde(default, deserialize_with = "present")]
                pub cx: Option<f64>,
                /// Principal point y of the left camera in pixels, in [0, image_height].
                /// Default: the image centre.
                #[schema(nullable = false, minimum = 0.0)]
                #[serde(default, deserialize_with = "present")]
                pub cy: Option<f64>,
                $($body)*
            }
        }

        impl $name {
            /// The rig members of this request.
            pub fn rig_params(&self) -> RigParams {
                RigParams {
                    camera: self.camera_params(),
                    baseline: self.baseline,
                    doffs: self.doffs,
                    cx: self.cx,
                    cy: self.cy,
                }
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
        #[serde(default, deserialize_with = "whole")]
        pub steps: Option<u32>,
        /// Left-image x held fixed to compute each row's right-image `normalized_x`, in pixels.
        /// Default: the image centre.
        #[schema(nullable = false, minimum = 0.0)]
        #[serde(default, deserialize_with = "present")]
        pub x_left: Option<f64>,
        /// `json` (the default) or `csv`. Without it, an `Accept: text/csv` header asks for
        /// CSV. For POST it may also be given as `?format=csv` in the URL.
        #[schema(nullable = false)]
        #[serde(default, deserialize_with = "present")]
        pub format: Option<TableFormat>,
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
        #[serde(default, deserialize_with = "whole")]
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
        #[schema(nullable = false, required = true, exclusive_minimum = 0.0, example = 126.0)]
        #[serde(default, deserialize_with = "present")]
        pub max_disparity_px: Option<f64>,
        /// Smallest disparity told apart from infinity, in pixels: it sets the farthest
        /// distance, `max_distance = f·B / (min + doffs)`. Default: `disparity_error_px`, one
        /// subpixel step.
        #[schema(nullable = false, exclusive_minimum = 0.0, example = 0.5)]
        #[serde(default, deserialize_with = "present")]
        pub min_disparity_px: Option<f64>,
        /// Distances, in `unit`, at which to report the depth error (at most 1 000). In a
        /// query string: comma-separated, `at_distances=500,1000,2000`.
        #[schema(schema_with = at_distances_schema)]
        #[serde(default, deserialize_with = "present")]
        pub at_distances: Option<Vec<f64>>,
        /// A relative-error budget as a fraction (0.02 is 2 %): the answer says up to which
        /// distance the depth error stays within it.
        #[schema(nullable = false, exclusive_minimum = 0.0, maximum = 1.0, example = 0.02)]
        #[serde(default, deserialize_with = "present")]
        pub max_relative_error: Option<f64>,
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
        #[schema(nullable = false, required = true, exclusive_minimum = 0.0, example = 5000.0)]
        #[serde(default, deserialize_with = "present")]
        pub target_distance: Option<f64>,
    } then {
        /// Largest acceptable depth error at `target_distance`, in `unit`. Give this or
        /// `max_relative_error`.
        #[schema(nullable = false, exclusive_minimum = 0.0, example = 25.0)]
        #[serde(default, deserialize_with = "present")]
        pub max_depth_error: Option<f64>,
        /// Largest acceptable depth error at `target_distance` as a fraction of it (0.005 is
        /// 0.5 %). Give this or `max_depth_error`.
        #[schema(nullable = false, exclusive_minimum = 0.0, maximum = 1.0)]
        #[serde(default, deserialize_with = "present")]
        pub max_relative_error: Option<f64>,
        /// Largest disparity the matcher searches, in pixels: with it the answer also gives
        /// the nearest distance the baseline lets the rig see.
        #[schema(nullable = false, exclusive_minimum = 0.0, example = 128.0)]
        #[serde(default, deserialize_with = "present")]
        pub max_disparity_px: Option<f64>,
    }
}

rig_request! {
    /// The rig shared by every point of a batch.
    #[schema(example = json!({
        "focal_length_px": 35, "baseline": 150, "unit": "mm",
        "image_width": 800, "image_height": 600
    }))]
    pub struct StereoRig {}
}

/// One correspondence of a batch. Its shape is checked with the whole request (a wrong type,
/// an unknown or missing member is a 422 for the batch); its values against the rig, point by
/// point (a coordinate off the image or a point at infinity is that point's own `errors` in the
/// 200 answer), so the schema bounds no value.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct BatchPoint {
    /// x of the feature in the left image, in pixels; must lie in [0, image_width], or the
    /// point fails on its own.
    #[schema(nullable = false, required = true, example = 400.0)]
    #[serde(default, deserialize_with = "present")]
    pub x_left: Option<f64>,
    /// x of the same feature in the right image, in pixels; must lie in [0, image_width], or
    /// the point fails on its own.
    #[schema(nullable = false, required = true, example = 350.0)]
    #[serde(default, deserialize_with = "present")]
    pub x_right: Option<f64>,
    /// y (row) of the feature in the left image, in pixels; must lie in [0, image_height], or
    /// the point fails on its own. Default: the rig's `cy`.
    #[schema(nullable = false)]
    #[serde(default, deserialize_with = "present")]
    pub y: Option<f64>,
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
impl QueryForm for TableRequest {}
impl QueryForm for ChartRequest {}
impl QueryForm for BaselineRequest {}
impl QueryForm for FormatQuery {}
impl QueryForm for RigRequest {
    const LISTS: &'static [&'static str] = &["at_distances"];
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
            let (description, list) = match &property {
                RefOr::T(Schema::Object(o)) => (o.description.clone(), false),
                RefOr::T(Schema::Array(a)) => (a.description.clone(), true),
                _ => (None, false),
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
                // Lists are comma-separated in a query string: `at_distances=500,1000`.
                .style(list.then_some(ParameterStyle::Form))
                .explode(list.then_some(false))
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

impl From<physics::Point3> for Point {
    fn from(p: physics::Point3) -> Self {
        Self {
            x: p.x,
            y: p.y,
            z: p.z,
        }
    }
}

/// Something worth knowing about a result that was still computed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Warning {
    /// Stable code: `negative_disparity` or `large_relative_error`.
    pub code: String,
    /// What it means and what to check.
    pub message: String,
}

impl From<&physics::Warning> for Warning {
    fn from(warning: &physics::Warning) -> Self {
        Self {
            code: warning.code().to_owned(),
            message: warning.to_string(),
        }
    }
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
    /// Distance Z along the optical axis, in `unit`.
    pub distance: f64,
    /// Expected depth error ΔZ = Z²·Δd/(f·B), in `unit`.
    pub depth_error: f64,
    /// depth_error / distance.
    pub relative_error: f64,
    /// Disparity d = x_left − x_right, in pixels (signed).
    pub disparity_px: f64,
    /// The feature's 3D position in the left camera's frame.
    pub point: Point,
    /// Caveats about this result; empty when there are none.
    pub warnings: Vec<Warning>,
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
    /// Horizontal field of view in degrees (principal point at the image centre).
    pub horizontal_fov_deg: f64,
    /// Vertical field of view in degrees (square pixels, principal point at the centre).
    pub vertical_fov_deg: f64,
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
    /// Horizontal field of view in degrees.
    pub horizontal_fov_deg: f64,
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
