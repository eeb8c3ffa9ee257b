//! The calibration options the image routes share with `/calibration`: the format to read
//! a file as, and KITTI's camera pair, each a closed choice read as a string; and the raw
//! cameras a file describes, as both answer them; and a file's faults named as each takes it.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use nalgebra::Matrix3;

use crate::api::error::FieldErrors;
use crate::api::wire::de::choice_members;
use crate::api::wire::params::Unit;
use stereo_core::calibration::files::{Format, Input, KittiPair, Raw, ReadFault};
use stereo_core::camera::{Camera, Roi};
use stereo_core::physics::LengthUnit;

/// Names each fault of reading a calibration in `problems`, by where the route takes what it
/// came from: the file as `text` and the right camera's file as `right_text` (a JSON member or a
/// form part, as the route names them), the unit as `calibration_unit`, a rig member as
/// `rig.<member>`.
pub fn add_read_faults(
    faults: Vec<ReadFault>,
    [text, right_text]: [&str; 2],
    problems: &mut FieldErrors,
) {
    for fault in faults {
        let field = match fault.input() {
            Input::Text => text.to_owned(),
            Input::RightText => right_text.to_owned(),
            Input::CalibrationUnit => "calibration_unit".to_owned(),
            Input::Rig(member) => format!("rig.{}", member.name()),
        };
        problems.add(&field, fault.message());
    }
}

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

choice_members!(FormatChoice, Cameras);

/// Where a raw calibration's rectification came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum RectificationSource {
    /// The file's own R1 R2 P1 P2 (ROS's R and P, KITTI's `R_rect` and `P_rect`).
    File,
    /// Computed here as `cv2.stereoRectify` (or `cv2.fisheye.stereoRectify`) computes it,
    /// with `alpha`.
    Computed,
}

/// One raw camera: its model, camera matrix and distortion coefficients in OpenCV's order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[allow(non_snake_case)]
pub struct RawCamera {
    /// `plumb_bob`, `rational_polynomial` or `equidistant`.
    pub model: String,
    pub K: [[f64; 3]; 3],
    pub D: Vec<f64>,
}

/// The raw cameras a calibration describes and the rectification that turns their frames
/// into the rectified pair of the rig (OpenCV's names and conventions).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[allow(non_snake_case)]
pub struct RawCameras {
    pub left: RawCamera,
    pub right: RawCamera,
    /// The right camera's pose: X_right = R·X_left + T.
    pub R: [[f64; 3]; 3],
    /// In `unit`.
    pub T: [f64; 3],
    /// The unit of T and of the rectified rig's baseline as the file states them.
    pub unit: Unit,
    /// The raw frames' size, in pixels.
    pub raw_width: u32,
    pub raw_height: u32,
    /// The rectified images' size, in pixels (the rig's `image_width` and `image_height`).
    pub rectified_width: u32,
    pub rectified_height: u32,
    pub rectification_source: RectificationSource,
    /// The `alpha` the rectification was computed with; absent for a file's own.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub alpha: Option<f64>,
    pub R1: [[f64; 3]; 3],
    pub R2: [[f64; 3]; 3],
    pub P1: [[f64; 4]; 3],
    pub P2: [[f64; 4]; 3],
    pub Q: [[f64; 4]; 4],
    /// The rectangle of valid pixels in each rectified image: x, y, width, height.
    pub roi_left: [i64; 4],
    pub roi_right: [i64; 4],
    /// True when rectifying changes nothing (no distortion, no rotation, the same camera
    /// matrices): the raw frames are already rectified.
    pub identity: bool,
}

impl RawCameras {
    /// The wire form of a raw calibration whose lengths are in `unit`.
    pub fn new(raw: &Raw, unit: LengthUnit) -> Self {
        let m3 = |m: &Matrix3<f64>| std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]));
        let camera = |c: &Camera| RawCamera {
            model: c.distortion().model().name().to_owned(),
            K: m3(&c.matrix()),
            D: c.distortion().coefficients().to_vec(),
        };
        let r = &raw.rectification;
        let roi = |r: Roi| [r.x, r.y, r.width, r.height];
        let t = raw.pair.translation;
        RawCameras {
            left: camera(&raw.pair.left),
            right: camera(&raw.pair.right),
            R: m3(raw.pair.rotation.matrix()),
            T: [t.x, t.y, t.z],
            unit: unit.into(),
            raw_width: raw.size.width,
            raw_height: raw.size.height,
            rectified_width: r.size.width,
            rectified_height: r.size.height,
            rectification_source: if raw.computed {
                RectificationSource::Computed
            } else {
                RectificationSource::File
            },
            alpha: r.alpha,
            R1: m3(&r.r1),
            R2: m3(&r.r2),
            P1: std::array::from_fn(|i| std::array::from_fn(|j| r.p1[(i, j)])),
            P2: std::array::from_fn(|i| std::array::from_fn(|j| r.p2[(i, j)])),
            Q: std::array::from_fn(|i| std::array::from_fn(|j| r.q[(i, j)])),
            roi_left: roi(r.roi_left),
            roi_right: roi(r.roi_right),
            identity: raw.is_identity(),
        }
    }
}

/// A 3 × 3 matrix as its rows, as the JSON answers write it.
pub fn matrix3(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]))
}
