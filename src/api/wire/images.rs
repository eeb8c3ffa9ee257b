//! The wire types the image routes share: their multipart form's documentation
//! ([`image_form!`]), whether a pair is rectified before matching ([`RectifyMode`]) and how
//! long a match's stages took ([`StageTimes`]).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::wire::de::choice_members;

/// The parts (or, in a stream's settings, the members) that carry a rig.
pub const RIG_PARTS: [&str; 6] = [
    "rig",
    "calibration",
    "calibration_format",
    "right_calibration",
    "calibration_unit",
    "calibration_cameras",
];

/// Whether an image route rectifies the pair before matching.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum RectifyMode {
    /// Rectify when the calibration describes raw cameras and the frames are their raw size
    /// (the default).
    #[default]
    Auto,
    /// Rectify; a calibration without the raw cameras is refused, saying what is missing.
    Yes,
    /// Take the pair as rectified.
    No,
}

choice_members!(RectifyMode);

/// How long each stage took, in milliseconds (also in the `Server-Timing` header).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct StageTimes {
    /// Decoding both images.
    pub decode: f64,
    /// Census transform and cost volume.
    pub cost: f64,
    /// Semi-global aggregation.
    pub aggregate: f64,
    /// Winner-takes-all, sub-pixel, left-right check, speckle and median filters.
    pub refine: f64,
    /// Rectifying a raw pair (after decoding, before matching); absent for a pair sent as
    /// rectified.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub rectify: Option<f64>,
}

/// Declares an image route's multipart form, for the documentation (the handler reads the
/// parts itself, to name each one in its errors): `left` and `right`, the route's own parts,
/// then the rig's parts, documented once here for every image route.
macro_rules! image_form {
    (
        $(#[$meta:meta])*
        pub struct $name:ident { $($(#[$attr:meta])* $field:ident: $ty:ty),* $(,)? }
    ) => {
        $(#[$meta])*
        #[derive(::utoipa::ToSchema)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        pub struct $name {
            /// The left image of the pair: PNG or JPEG, 8 or 16 bits, grey, RGB or RGBA.
            #[schema(value_type = String, format = Binary)]
            left: Vec<u8>,
            /// The right image, the same size as the left.
            #[schema(value_type = String, format = Binary)]
            right: Vec<u8>,
            $($(#[$attr])* $field: $ty,)*
            /// The rig, with the members of `/distance` (what `/calibration` answers as
            /// `rig`). The image size defaults to the images'.
            #[schema(nullable = false)]
            rig: Option<$crate::api::wire::rig::StereoRig>,
            /// A calibration file as `/calibration` reads it (Middlebury, KITTI, ROS, OpenCV).
            #[schema(value_type = Option<String>, format = Binary, nullable = false)]
            calibration: Option<Vec<u8>>,
            /// The calibration's format, or `auto` (the default).
            #[schema(nullable = false)]
            calibration_format: Option<String>,
            /// The right camera's ROS `CameraInfo`, for ROS calibrations.
            #[schema(value_type = Option<String>, format = Binary, nullable = false)]
            right_calibration: Option<Vec<u8>>,
            /// The unit of the calibration's lengths (required for OpenCV files).
            #[schema(nullable = false)]
            calibration_unit: Option<String>,
            /// KITTI only: the camera pair, `2-3` (the default) or `0-1`.
            #[schema(nullable = false)]
            calibration_cameras: Option<String>,
        }
    };
}
pub(crate) use image_form;

/// A file answer's bytes, documented as binary.
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct FileBody(pub Vec<u8>);
