//! The wire types of `/rectify`: the query's options, the multipart form (documentation) and
//! the JSON summary.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::extract::QueryForm;
use crate::api::wire::calibration::RawCameras;
use crate::api::wire::de::{choice_members, latlon_request};
use crate::api::wire::images::FileBody;
use crate::api::wire::images::image_form;
pub use crate::api::wire::images::{LatlonSystem, ProjectionAsked, ProjectionChoice, RectifyMode};
use crate::api::wire::openapi::{image_answers, named};
use crate::api::wire::rig::CalibratedRig;
use stereo_core::pipeline::rectify::Interpolation;

/// What `/rectify` answers.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
pub enum RectifyOutput {
    /// JSON: the raw and rectified sizes, the rectification (R1 R2 P1 P2 Q, ROIs), the
    /// rectified rig, the share of valid pixels and the stage times.
    #[default]
    #[serde(rename = "summary")]
    Summary,
    /// The rectified left image, PNG (RGB when the frame has colour, else grey of its depth).
    #[serde(rename = "left.png")]
    LeftPng,
    /// The rectified right image, PNG.
    #[serde(rename = "right.png")]
    RightPng,
    /// Both rectified images side by side (RGB PNG) with a line every 32 rows across both,
    /// to check by eye that features lie on the same row.
    #[serde(rename = "pair.png")]
    PairPng,
    /// NumPy's NPZ of the maps as `initUndistortRectifyMap(..., CV_32FC1)` makes them:
    /// `left_map_x`, `left_map_y`, `right_map_x`, `right_map_y` (float32, rectified height ×
    /// width; for `cv2.remap(raw, map_x, map_y, cv2.INTER_LINEAR)`).
    #[serde(rename = "maps.npz")]
    MapsNpz,
}

impl RectifyOutput {
    pub fn name(self) -> &'static str {
        match self {
            RectifyOutput::Summary => "summary",
            RectifyOutput::LeftPng => "left.png",
            RectifyOutput::RightPng => "right.png",
            RectifyOutput::PairPng => "pair.png",
            RectifyOutput::MapsNpz => "maps.npz",
        }
    }

    pub fn media_type(self) -> &'static str {
        match self {
            RectifyOutput::Summary => "application/json",
            RectifyOutput::MapsNpz => "application/zip",
            _ => "image/png",
        }
    }
}

/// How a rectified pixel is read between the raw image's pixels.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum InterpolationChoice {
    /// Bilinear, as `cv2.INTER_LINEAR` (the default).
    #[default]
    Linear,
    /// The nearest pixel, as `cv2.INTER_NEAREST`.
    Nearest,
    /// Bicubic, as `cv2.INTER_CUBIC`.
    Cubic,
}

impl From<InterpolationChoice> for Interpolation {
    fn from(c: InterpolationChoice) -> Self {
        match c {
            InterpolationChoice::Linear => Interpolation::Linear,
            InterpolationChoice::Nearest => Interpolation::Nearest,
            InterpolationChoice::Cubic => Interpolation::Cubic,
        }
    }
}

choice_members!(RectifyOutput, InterpolationChoice);

latlon_request! {
    /// The options of `/rectify`, in the query string.
    pub struct RectifyQuery {
        /// What to answer. Default `summary`.
        output: RectifyOutput,
        /// Recompute the rectification as `cv2.stereoRectify` does with this `alpha`: 0 keeps
        /// only valid pixels (no black borders, best for matching), 1 keeps every raw pixel.
        /// Default: the calibration file's own R1 R2 P1 P2, or 0 when it has none.
        #[schema(minimum = 0.0, maximum = 1.0, example = 0)]
        alpha: f64,
        /// How pixels between the raw pixels are read. Default `linear`.
        interpolation: InterpolationChoice,
        /// The rectified projection: `pinhole` (default), `latlon` (wide lenses) or `auto`
        /// (latlon where the cameras see wider than 100° and no `alpha` is given).
        projection: ProjectionAsked,
    }
}

impl QueryForm for RectifyQuery {}

image_form! {
    /// The `multipart/form-data` parts of `/rectify`: the raw pair and a `calibration` that
    /// describes the raw cameras (a `stereoCalibrate` file, a ROS `CameraInfo` pair, KITTI's
    /// raw `calib_cam_to_cam.txt`, or `/calibrate`'s outputs).
    pub struct RectifyForm {}
}

/// The share of each rectified image read from inside its raw frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ValidShare {
    pub left: f64,
    pub right: f64,
}

/// Stage times in milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RectifyTimes {
    pub decode: f64,
    /// Building the maps; 0 when they came from the cache. No frame is remapped for a
    /// summary: `/depth-map`'s `timings_ms.rectify` times the remapping its matching needs,
    /// and the image outputs' `Server-Timing` times theirs.
    pub maps: f64,
}

/// What `/rectify` answers as `summary`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RectifySummary {
    /// The rectified images' size.
    pub width: u32,
    pub height: u32,
    pub interpolation: InterpolationChoice,
    /// The raw cameras and the rectification used (R1 R2 P1 P2 Q, ROIs).
    pub raw: RawCameras,
    /// The rectified rig, for `/distance` and for `/depth-map` on the rectified images.
    pub rig: CalibratedRig,
    pub valid_fraction: ValidShare,
    /// The rectified projection; for `latlon`, its system (the `rig` is then the pinhole
    /// plane's, for comparison: a latlon disparity is an angle, see `latlon`).
    pub projection: ProjectionChoice,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub latlon: Option<LatlonSystem>,
    /// Whether the maps came from the cache (a rig seen lately).
    pub maps_cached: bool,
    pub timings_ms: RectifyTimes,
    pub warnings: Vec<String>,
}

image_answers! {
    /// `/rectify`'s responses: the rectified pair in the `output` asked for, or the errors.
    pub struct RectifyAnswers: "The rectified pair in the `output` asked for." {
        "application/json" => named::<RectifySummary>(),
        "image/png" => named::<FileBody>(),
        "application/zip" => named::<FileBody>(),
    }
}
