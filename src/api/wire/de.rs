//! Deserialization rules every request shares, and the macros that declare request types
//! with the common members (camera, rig, range) so that each endpoint's type stays flat.
//!
//! Every request member is optional in Rust so that validation can report *all* missing fields
//! at once; the ones the API requires are marked `required` in the schema. Members are present
//! or absent, never `null`.

use serde::Deserialize;

use crate::api::member_messages;

/// The type of a request member: how it is read when present. Every member is read through
/// [`member`], which refuses `null`, so the rule is stated once for all of them.
pub trait Member: Sized {
    fn read<'de, D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error>;
}

/// Members read as serde reads their type.
macro_rules! plain_members {
    ($($ty:ty),*) => {
        $(impl $crate::api::wire::de::Member for $ty {
            fn read<'de, D: ::serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
                <$ty as ::serde::Deserialize>::deserialize(deserializer)
            }
        })*
    };
}

plain_members!(f64, Vec<f64>);

/// Enumerated members (`unit`, `spacing`, …): read through [`choice`], so that only a string
/// is taken and any refusal lists the allowed values.
macro_rules! choice_members {
    ($($ty:ty),*) => {
        $(impl $crate::api::wire::de::Member for $ty {
            fn read<'de, D: ::serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
                $crate::api::wire::de::choice(deserializer)
            }
        })*
    };
}

choice_members!(super::params::Unit, super::params::Spacing);

/// An enumerated member: one of its values, given as a string. serde's own enum reading also
/// takes `{"mm": null}` and says `expected string or map` for a number; this takes only the
/// string, and says `must be one of mm, cm, m, in, ft, got 5`.
pub fn choice<'de, D, T>(deserializer: D) -> Result<T, D::Error>
where
    D: serde::Deserializer<'de>,
    T: serde::de::DeserializeOwned,
{
    use serde::de::{Error, IntoDeserializer};

    let value = serde_json::Value::deserialize(deserializer)?;
    let read = |text: &str| {
        T::deserialize(IntoDeserializer::<serde::de::value::Error>::into_deserializer(text))
    };
    let refusal = match &value {
        serde_json::Value::String(text) => match read(text) {
            Ok(choice) => return Ok(choice),
            Err(error) => error,
        },
        // The empty string is no value's name: its refusal lists them all.
        _ => match read("") {
            Ok(choice) => return Ok(choice),
            Err(error) => error,
        },
    };
    Err(D::Error::custom(member_messages::message(
        &refusal.to_string(),
        Some(&value),
    )))
}

/// Deserializes a member that is present: `null` is refused like any other wrong type, because
/// optional members are optional, not nullable (omit a member to take its default). For the
/// members of hand-written types; [`request!`] types read every member through [`member`].
pub fn present<'de, D, T>(deserializer: D) -> Result<Option<T>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de>,
{
    match Option::<T>::deserialize(deserializer)? {
        Some(value) => Ok(Some(value)),
        None => Err(null_refused()),
    }
}

fn null_refused<E: serde::de::Error>() -> E {
    E::custom("must not be null; leave the member out to use its default")
}

/// [`present`] for a [`Member`] type (whole numbers read as [`Member for u32`] says).
pub fn member<'de, D, T>(deserializer: D) -> Result<Option<T>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Member,
{
    struct Present<T>(T);

    impl<'de, T: Member> Deserialize<'de> for Present<T> {
        fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
            T::read(deserializer).map(Present)
        }
    }

    match Option::<Present<T>>::deserialize(deserializer)? {
        Some(Present(value)) => Ok(Some(value)),
        None => Err(null_refused()),
    }
}

/// A value that must be a JSON object. serde's derived structs also read an array, by
/// position (`[620, 610]` as `x_left`, `x_right`); the schema says an object, so this refuses
/// anything else, in the same single pass.
#[derive(Debug)]
pub struct Object<T>(pub T);

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Object<T> {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Members<T>(std::marker::PhantomData<T>);

        impl<'de, T: Deserialize<'de>> serde::de::Visitor<'de> for Members<T> {
            type Value = T;

            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("an object")
            }

            fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> Result<T, A::Error> {
                T::deserialize(serde::de::value::MapAccessDeserializer::new(map))
            }
        }

        deserializer
            .deserialize_map(Members(std::marker::PhantomData))
            .map(Object)
    }
}

/// The largest whole number a request member takes: the schema's `int32` format bounds it.
pub const MAX_WHOLE: u32 = i32::MAX as u32;

/// A whole number. JSON Schema's `integer` is a number with no fractional part, so `800.0` is
/// the integer 800 (as generators such as schemathesis send it); `800.5`, a negative number and
/// one beyond [`MAX_WHOLE`] are refused.
impl Member for u32 {
    fn read<'de, D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
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
        }

        deserializer.deserialize_any(Whole)
    }
}

/// A whole number that may be negative (`min_disparity`): an integral JSON number within
/// ±[`MAX_WHOLE`], `−32.0` included.
impl Member for i32 {
    fn read<'de, D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        use serde::de::Error;

        let value = serde_json::Value::deserialize(deserializer)?;
        let refuse = || {
            D::Error::custom(format!(
                "must be a whole number, got {}",
                member_messages::describe(&value)
            ))
        };
        let x = value.as_f64().ok_or_else(refuse)?;
        if x.fract() != 0.0 {
            return Err(D::Error::custom(format!(
                "must be a whole number, got {}",
                stereo_core::numbers::Num(x)
            )));
        }
        if x.abs() > f64::from(MAX_WHOLE) {
            return Err(D::Error::custom(format!(
                "must lie in [-{MAX_WHOLE}, {MAX_WHOLE}], got {}",
                stereo_core::numbers::Num(x)
            )));
        }
        Ok(x as i32)
    }
}

/// The end of the search: the word `auto` (found from the pair) or a whole number of pixels,
/// read as [`Member for i32`] reads one.
impl Member for stereo_core::vision::RangeEnd {
    fn read<'de, D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        use stereo_core::vision::RangeEnd;

        match serde_json::Value::deserialize(deserializer)? {
            serde_json::Value::String(s) if s == "auto" => Ok(RangeEnd::Auto),
            value @ serde_json::Value::Number(_) => i32::read(value)
                .map(RangeEnd::Px)
                .map_err(|e| D::Error::custom(e.to_string())),
            other => Err(D::Error::custom(format!(
                "must be auto or a whole number of pixels, got {}",
                member_messages::describe(&other)
            ))),
        }
    }
}

/// The schema of `max_disparity` ([`stereo_core::vision::RangeEnd`]): `auto` or an integer
/// the engine's range bounds take, described by `description`.
pub fn max_disparity_schema(description: &str) -> utoipa::openapi::schema::Schema {
    range_end_schema(description, (-4095, 4608), 64)
}

/// The schema of `min_disparity`: `auto` or an integer within the engine's bounds.
pub fn min_disparity_schema(description: &str) -> utoipa::openapi::schema::Schema {
    range_end_schema(description, (-4096, 4096), 0)
}

/// `auto` or an integer in `low ..= high`, described by `description`, with an example.
fn range_end_schema(
    description: &str,
    (low, high): (i32, i32),
    example: i32,
) -> utoipa::openapi::schema::Schema {
    use utoipa::openapi::schema::{ObjectBuilder, OneOfBuilder, SchemaFormat, Type};
    OneOfBuilder::new()
        .item(
            ObjectBuilder::new()
                .schema_type(Type::Integer)
                .format(Some(SchemaFormat::KnownFormat(
                    utoipa::openapi::KnownFormat::Int32,
                )))
                .minimum(Some(low))
                .maximum(Some(high)),
        )
        .item(
            ObjectBuilder::new()
                .schema_type(Type::String)
                .enum_values(Some(["auto"])),
        )
        .description(Some(description))
        .examples([serde_json::json!(example)])
        .build()
        .into()
}

/// A switch: `true` or `false`, as JSON booleans or, in a query string, as those words.
impl Member for bool {
    fn read<'de, D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        use serde::de::Error;

        match serde_json::Value::deserialize(deserializer)? {
            serde_json::Value::Bool(b) => Ok(b),
            serde_json::Value::String(s) if s == "true" => Ok(true),
            serde_json::Value::String(s) if s == "false" => Ok(false),
            other => Err(D::Error::custom(format!(
                "must be true or false, got {}",
                member_messages::describe(&other)
            ))),
        }
    }
}

/// Declares a request type from its members, each written `name: Type` with its docs and
/// schema attributes: every member becomes `Option<Type>`, read through [`member`] (present,
/// never `null`; absent is `None`) and documented as not nullable. Unknown members are refused,
/// and the GET form's query parameters are documented from the same schema.
macro_rules! request {
    (
        $(#[$meta:meta])*
        pub struct $name:ident { $($(#[$attr:meta])* $field:ident: $ty:ty),* $(,)? }
    ) => {
        #[derive(Debug, Clone, Default, PartialEq, ::serde::Deserialize, ::utoipa::ToSchema)]
        #[serde(deny_unknown_fields)]
        $(#[$meta])*
        pub struct $name {
            $(
                $(#[$attr])*
                #[schema(nullable = false)]
                #[serde(default, deserialize_with = "crate::api::wire::de::member")]
                pub $field: Option<$ty>,
            )*
        }

        impl ::utoipa::IntoParams for $name {
            fn into_params(
                _: impl Fn() -> Option<::utoipa::openapi::path::ParameterIn>,
            ) -> Vec<::utoipa::openapi::path::Parameter> {
                crate::api::wire::openapi::query_parameters(
                    <$name as ::utoipa::PartialSchema>::schema(),
                )
            }
        }
    };
}

/// Declares a flat request type holding the camera members, with `$early` after the focal
/// options and `$late` at the end, plus `camera_spec()`. (Flat, because `serde(flatten)`
/// cannot be combined with `deny_unknown_fields`, and a misspelt field must be an error.)
macro_rules! camera_request {
    (
        $(#[$meta:meta])*
        pub struct $name:ident { $($early:tt)* } then { $($late:tt)* }
    ) => {
        $crate::api::wire::de::request! {
            $(#[$meta])*
            pub struct $name {
                /// Focal length in pixels (`fx` from a calibration). Give exactly one of
                /// `focal_length_px`, `focal_length_mm` (with `sensor_width_mm` or
                /// `pixel_size_um`), or `horizontal_fov_deg`.
                #[schema(exclusive_minimum = 0.0, example = 700.0)]
                focal_length_px: f64,
                /// Focal length in millimetres. Needs `sensor_width_mm` or `pixel_size_um` to
                /// convert it to pixels: millimetres times a disparity in pixels is not a length.
                #[schema(exclusive_minimum = 0.0)]
                focal_length_mm: f64,
                /// Sensor width in millimetres, with `focal_length_mm`:
                /// f_px = f_mm · image_width / sensor_width_mm.
                #[schema(exclusive_minimum = 0.0)]
                sensor_width_mm: f64,
                /// Pixel pitch in micrometres, with `focal_length_mm`:
                /// f_px = f_mm · 1000 / pixel_size_um.
                #[schema(exclusive_minimum = 0.0)]
                pixel_size_um: f64,
                /// Horizontal field of view in degrees, over the full image width:
                /// f_px = (image_width / 2) / tan(hfov / 2).
                #[schema(exclusive_minimum = 0.0, exclusive_maximum = 180.0)]
                horizontal_fov_deg: f64,
                /// Vertical focal length `fy` in pixels, for the point's Y
                /// (Y = (y − cy)·Z / fy). Default: the horizontal focal length, as for square
                /// pixels. Disparities and depth use only the horizontal one.
                #[schema(exclusive_minimum = 0.0)]
                focal_length_y_px: f64,
                $($early)*
                /// Unit of every length in the request and the response (default `mm`).
                unit: crate::api::wire::params::Unit,
                /// Image width in pixels. Needed only by what uses it: the default `cx`, a
                /// focal length from `sensor_width_mm` or `horizontal_fov_deg`, the
                /// horizontal field of view, `normalized_x` and a default sample range. A
                /// focal length in pixels with `cx` and `cy` needs no image size.
                #[schema(minimum = 1, example = 800)]
                image_width: u32,
                /// Image height in pixels. Needed only for the default `cy` and the vertical
                /// field of view.
                #[schema(minimum = 1, example = 600)]
                image_height: u32,
                /// Disparity uncertainty Δd in pixels (RMS) for the depth error
                /// ΔZ = Z²·Δd/(f·B). Default 0.5 (integer-pixel matching); subpixel matchers
                /// reach about 0.1.
                #[schema(minimum = 0.0, example = 0.5)]
                disparity_error_px: f64,
                $($late)*
            }
        }

        impl $name {
            /// The camera this request states, for [`stereo_core::physics::RectifiedCamera::new`].
            pub fn camera_spec(&self) -> stereo_core::physics::CameraSpec {
                stereo_core::physics::CameraSpec {
                    focal: stereo_core::physics::Focal {
                        px: self.focal_length_px,
                        mm: self.focal_length_mm,
                        sensor_width_mm: self.sensor_width_mm,
                        pixel_size_um: self.pixel_size_um,
                        horizontal_fov_deg: self.horizontal_fov_deg,
                    },
                    focal_y_px: self.focal_length_y_px,
                    unit: self.unit.unwrap_or_default().into(),
                    image_width: self.image_width,
                    image_height: self.image_height,
                    disparity_error_px: self.disparity_error_px,
                    unreadable: Vec::new(),
                }
            }
        }
    };
}

/// Declares a flat request type holding the rig members (camera, baseline, principal points)
/// followed by its own, with `rig_spec()`.
macro_rules! rig_request {
    (
        $(#[$meta:meta])*
        pub struct $name:ident { $($body:tt)* }
    ) => {
        $crate::api::wire::de::camera_request! {
            $(#[$meta])*
            pub struct $name {
                /// Distance between the two optical centres, in `unit`.
                #[schema(required = true, exclusive_minimum = 0.0, example = 150.0)]
                baseline: f64,
            } then {
                /// Principal-point offset between the cameras in pixels (Middlebury `doffs`),
                /// added to every disparity: Z = B·f / |d + doffs|. Default 0.
                #[schema(example = 0.0)]
                doffs: f64,
                /// Principal point x of the left camera in pixels, in [0, image_width] when
                /// the width is given. Default: the image centre (then `image_width` is
                /// required).
                #[schema(minimum = 0.0)]
                cx: f64,
                /// Principal point y of the left camera in pixels, in [0, image_height] when
                /// the height is given. Default: the image centre (then `image_height` is
                /// required).
                #[schema(minimum = 0.0)]
                cy: f64,
                /// Standard deviation of `focal_length_px` in pixels, from a calibration
                /// (`/calibrate` answers it as the rig's `focal_length_std_px`). With it,
                /// `depth_error` adds the term Z·σ_f/f. Default 0.
                #[schema(minimum = 0.0)]
                focal_length_std_px: f64,
                /// Standard deviation of `baseline` in `unit`, from a calibration. With it,
                /// `depth_error` adds the term Z·σ_B/B. Default 0.
                #[schema(minimum = 0.0)]
                baseline_std: f64,
                $($body)*
            }
        }

        impl $name {
            /// The rig this request states, for [`stereo_core::physics::Rig::new`].
            pub fn rig_spec(&self) -> stereo_core::physics::RigSpec {
                stereo_core::physics::RigSpec {
                    camera: self.camera_spec(),
                    baseline: self.baseline,
                    cx: self.cx,
                    cy: self.cy,
                    doffs: self.doffs,
                    focal_std_px: self.focal_length_std_px,
                    baseline_std: self.baseline_std,
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
        $crate::api::wire::de::rig_request! {
            $(#[$meta])*
            pub struct $name {
                /// Nearest distance to sample, in `unit`. Give `distance_min` and
                /// `distance_max`, or `disparity_min` and `disparity_max`, or neither (then the
                /// disparities from 1 px across a quarter of the image width are used).
                #[schema(exclusive_minimum = 0.0)]
                distance_min: f64,
                /// Farthest distance to sample, in `unit`; greater than `distance_min`.
                #[schema(exclusive_minimum = 0.0)]
                distance_max: f64,
                /// Smallest disparity to sample, in pixels; `disparity_min + doffs` must be > 0.
                disparity_min: f64,
                /// Largest disparity to sample, in pixels; greater than `disparity_min`.
                disparity_max: f64,
                /// Spacing of the samples across the range (default `linear`).
                spacing: crate::api::wire::params::Spacing,
                $($body)*
            }
        }

        impl $name {
            /// The range members of this request.
            pub fn range_params(&self) -> crate::api::wire::params::RangeParams {
                crate::api::wire::params::RangeParams {
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

/// Declares a request type whose own members (ending with its `projection`) are followed by
/// the latitude-longitude members `az_fov`, `el_fov` and `pixels_per_degree`, with `latlon()`.
macro_rules! latlon_request {
    (
        $(#[$meta:meta])*
        pub struct $name:ident { $($body:tt)* }
    ) => {
        $crate::api::wire::de::request! {
            $(#[$meta])*
            pub struct $name {
                $($body)*
                /// `latlon`: the azimuth field, across the baseline, in degrees (up to 180).
                /// Default: where both cameras see along the raw images' centre rows.
                #[schema(exclusive_minimum = 0.0, maximum = 180.0, example = 120)]
                az_fov: f64,
                /// `latlon`: the elevation field in degrees (up to 180). Default: where both
                /// cameras see along the raw images' centre columns.
                #[schema(exclusive_minimum = 0.0, maximum = 180.0, example = 90)]
                el_fov: f64,
                /// `latlon`: the resolution along both axes, in pixels per degree. Default:
                /// the left camera's at the centre of the field (mrcal's).
                #[schema(exclusive_minimum = 0.0, example = 8)]
                pixels_per_degree: f64,
            }
        }

        impl $name {
            /// The latitude-longitude options, as given: az_fov, el_fov, pixels_per_degree.
            pub fn latlon(&self) -> [Option<f64>; 3] {
                [self.az_fov, self.el_fov, self.pixels_per_degree]
            }
        }
    };
}

pub(crate) use {
    camera_request, choice_members, latlon_request, plain_members, range_request, request,
    rig_request,
};
