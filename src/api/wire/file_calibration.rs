//! The wire types of `/calibration`: a calibration file (or two, for ROS) in, the rig every
//! other endpoint takes out.

use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

use crate::api::extract::QueryForm;
pub use crate::api::wire::calibration::{CalibrationFormat, Cameras, FormatChoice, RawCameras};
use crate::api::wire::de::{member, plain_members, request};
use crate::api::wire::params::Unit;
pub use crate::api::wire::rig::CalibratedRig;

plain_members!(String);

request! {
    /// A calibration file to read, as text, with the options that some formats need.
    #[schema(example = json!({
        "text": "cam0=[1000 0 640; 0 1000 360; 0 0 1]\ncam1=[1000 0 652; 0 1000 360; 0 0 1]\n\
                 doffs=12\nbaseline=120\nwidth=1280\nheight=720\nndisp=192\n",
        "format": "auto"
    }))]
    pub struct CalibrationRequest {
        /// The calibration file's text (the left camera's `CameraInfo` for ROS). At most the
        /// server's body limit (64 KiB by default).
        #[schema(required = true)]
        text: String,
        /// The format, or `auto` (the default) to detect it.
        format: FormatChoice,
        /// ROS only: the right camera's `CameraInfo`, whose projection matrix holds the
        /// baseline (`P_r[3] = −f·B`).
        right_text: String,
        /// KITTI only: the camera pair, `2-3` (colour, the default) or `0-1` (grey).
        cameras: Cameras,
        /// The unit the file's lengths are in. Required for OpenCV files, whose lengths are in
        /// the unit the calibration target's squares were measured in, which the file does not
        /// record; other formats define theirs (Middlebury mm, KITTI and ROS m), and this
        /// overrides it.
        calibration_unit: Unit,
        /// The unit of the answer's lengths (default: the file's own).
        unit: Unit,
        /// For a file that describes the raw cameras (`stereoCalibrate`'s K D R T, ROS
        /// `CameraInfo`, KITTI's raw `calib_cam_to_cam.txt`): recompute the rectification as
        /// `cv2.stereoRectify` does with this `alpha`, from 0 (only valid pixels) to 1 (every
        /// raw pixel kept). Without it, the file's own R1 R2 P1 P2 are used, or `alpha` 0
        /// when the file has none.
        #[schema(minimum = 0.0, maximum = 1.0)]
        alpha: f64,
        /// The raw images' width in pixels, for a file of raw cameras that does not record
        /// it (OpenCV's `stereo_calib` sample writes `intrinsics.yml` and `extrinsics.yml`
        /// without `imageSize`); given with `image_height`. The file's own size wins.
        #[schema(minimum = 1, maximum = 8192)]
        image_width: u32,
        /// The raw images' height in pixels; given with `image_width`.
        #[schema(minimum = 1, maximum = 8192)]
        image_height: u32,
    }
}

/// The options of a calibration sent as a raw `text/plain` body, in the URL's query; each read
/// as [`member`] reads every request member (present, never `null`, a choice as a string).
#[derive(Debug, Clone, Default, PartialEq, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct CalibrationQuery {
    /// The format, or `auto` (the default) to detect it.
    #[serde(default, deserialize_with = "member")]
    #[param(nullable = false)]
    pub format: Option<FormatChoice>,
    /// KITTI only: the camera pair, `2-3` (the default) or `0-1`.
    #[serde(default, deserialize_with = "member")]
    #[param(nullable = false)]
    pub cameras: Option<Cameras>,
    /// The unit the file's lengths are in (required for OpenCV files).
    #[serde(default, deserialize_with = "member")]
    #[param(nullable = false)]
    pub calibration_unit: Option<Unit>,
    /// The unit of the answer's lengths (default: the file's own).
    #[serde(default, deserialize_with = "member")]
    #[param(nullable = false)]
    pub unit: Option<Unit>,
    /// Raw cameras only: recompute the rectification with this `alpha` (0 to 1).
    #[serde(default, deserialize_with = "member")]
    #[param(nullable = false, minimum = 0.0, maximum = 1.0)]
    pub alpha: Option<f64>,
    /// The raw images' width, for a file that does not record it (with `image_height`).
    #[serde(default, deserialize_with = "member")]
    #[param(nullable = false, minimum = 1, maximum = 8192)]
    pub image_width: Option<u32>,
    /// The raw images' height, for a file that does not record it (with `image_width`).
    #[serde(default, deserialize_with = "member")]
    #[param(nullable = false, minimum = 1, maximum = 8192)]
    pub image_height: Option<u32>,
}

impl QueryForm for CalibrationQuery {}

/// A calibration file read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({
    "format": "middlebury",
    "rig": {"focal_length_px": 1000.0, "baseline": 120.0, "unit": "mm", "cx": 640.0,
            "cy": 360.0, "doffs": 12.0, "image_width": 1280, "image_height": 720},
    "max_disparity_px": 192,
    "warnings": [],
    "raw_cameras": false
}))]
pub struct CalibrationResponse {
    /// The format the file was read as.
    pub format: CalibrationFormat,
    /// The rig, ready for `/distance`, `/rig`, `/table` and `/chart-data`.
    pub rig: CalibratedRig,
    /// The disparity search range the file recommends (Middlebury's `ndisp`), when it says.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub max_disparity_px: Option<u32>,
    /// Things worth checking that did not stop the reading; empty when there are none.
    pub warnings: Vec<String>,
    /// Whether the file describes the raw cameras (K, D and their pose or rectification),
    /// so that `/rectify`, `/depth-map` and `/match` can take the frames the cameras deliver.
    pub raw_cameras: bool,
    /// The raw cameras and the rectification of their frames, when `raw_cameras`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub raw: Option<RawCameras>,
}

/// The calibration file itself as the raw body (`Content-Type: text/plain`): its bytes, which
/// must be UTF-8 text. Documented as binary so that generated clients send a file's bytes.
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct CalibrationFile(pub Vec<u8>);
