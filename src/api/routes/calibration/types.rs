//! The wire types of `/calibration`: a calibration file (or two, for ROS) in, the rig every
//! other endpoint takes out.

use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

use crate::api::extract::QueryForm;
use crate::api::wire::de::{choice_members, member, plain_members, request};
use crate::api::wire::params::Unit;
use crate::calibration::{Format, KittiPair};

/// The calibration formats, or `auto` to detect the format from the file.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum FormatChoice {
    /// Detect the format from the file's marks.
    #[default]
    Auto,
    /// Middlebury 2014 `calib.txt` (lengths in mm).
    Middlebury,
    /// KITTI `calib_cam_to_cam.txt` or odometry `calib.txt` (lengths in m).
    Kitti,
    /// A ROS `CameraInfo` per camera, `text` and `right_text` (lengths in m).
    Ros,
    /// OpenCV FileStorage YAML or XML after `stereoRectify` (lengths in `calibration_unit`).
    Opencv,
}

impl FormatChoice {
    /// The format asked for, `None` for `auto`.
    pub fn format(self) -> Option<Format> {
        match self {
            FormatChoice::Auto => None,
            FormatChoice::Middlebury => Some(Format::Middlebury),
            FormatChoice::Kitti => Some(Format::Kitti),
            FormatChoice::Ros => Some(Format::Ros),
            FormatChoice::Opencv => Some(Format::OpenCv),
        }
    }
}

/// The format a file was read as.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum CalibrationFormat {
    Middlebury,
    Kitti,
    Ros,
    Opencv,
}

impl From<Format> for CalibrationFormat {
    fn from(format: Format) -> Self {
        match format {
            Format::Middlebury => CalibrationFormat::Middlebury,
            Format::Kitti => CalibrationFormat::Kitti,
            Format::Ros => CalibrationFormat::Ros,
            Format::OpenCv => CalibrationFormat::Opencv,
        }
    }
}

/// A KITTI camera pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
pub enum Cameras {
    /// Cameras 2 and 3, the colour pair (the default).
    #[serde(rename = "2-3")]
    Colour,
    /// Cameras 0 and 1, the grey pair.
    #[serde(rename = "0-1")]
    Grey,
}

impl From<Cameras> for KittiPair {
    fn from(cameras: Cameras) -> Self {
        match cameras {
            Cameras::Colour => KittiPair::Colour,
            Cameras::Grey => KittiPair::Grey,
        }
    }
}

plain_members!(String);
choice_members!(FormatChoice, Cameras);

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
}

impl QueryForm for CalibrationQuery {}

/// The rig a calibration file describes, with the member names every other endpoint takes:
/// add a correspondence or a `disparity_px` and send it to `/distance`. Members the file does
/// not give are absent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CalibratedRig {
    /// Horizontal focal length fx, in pixels.
    pub focal_length_px: f64,
    /// Vertical focal length fy, in pixels; present only when it differs from fx.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub focal_length_y_px: Option<f64>,
    /// Distance between the optical centres, in `unit`.
    pub baseline: f64,
    /// Unit of `baseline`.
    pub unit: Unit,
    /// Left principal point x, in pixels.
    pub cx: f64,
    /// Left principal point y, in pixels.
    pub cy: f64,
    /// cx_right − cx_left in pixels, added to every disparity: Z = B·f / |d + doffs|.
    pub doffs: f64,
    /// Image width in pixels, when the file says.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub image_width: Option<u32>,
    /// Image height in pixels, when the file says.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub image_height: Option<u32>,
}

/// A calibration file read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({
    "format": "middlebury",
    "rig": {"focal_length_px": 1000.0, "baseline": 120.0, "unit": "mm", "cx": 640.0,
            "cy": 360.0, "doffs": 12.0, "image_width": 1280, "image_height": 720},
    "max_disparity_px": 192,
    "warnings": []
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
}

/// The calibration file itself as the raw body (`Content-Type: text/plain`): its bytes, which
/// must be UTF-8 text. Documented as binary so that generated clients send a file's bytes.
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct CalibrationFile(pub Vec<u8>);
