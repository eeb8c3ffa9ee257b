//! The calibration options the image routes share with `/calibration`: the format to read
//! a file as, and KITTI's camera pair, each a closed choice read as a string.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::wire::de::choice_members;
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

choice_members!(FormatChoice, Cameras);
