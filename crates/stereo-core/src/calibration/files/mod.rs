//! Calibration files in, a rectified rig out: Middlebury 2014 `calib.txt`, KITTI's calibration
//! files, a pair of ROS `CameraInfo`s and OpenCV's `stereoRectify` output (FileStorage YAML or
//! XML). Pure functions on text, with no HTTP or serde in any signature; each error names the
//! file (left or right) and the line. [`read`] turns a file into a checked
//! [`crate::physics::Rig`] with its unit resolved and its warnings.
//!
//! Every format is reduced to the same numbers, with the conventions of [`crate::physics`]:
//! `f` in pixels, the baseline `B` in the file's length unit, the left principal point and
//! `doffs = cx_right − cx_left`, so that `Z = B·f / |d + doffs|`.

mod kitti;
mod middlebury;
pub mod opencv;
mod parse;
mod raw;
mod read;
pub mod ros;
mod xml;
pub mod yaml;

pub use parse::{Rejected, parse};
pub use raw::Raw;
pub use read::{Input, Read, ReadFault, ReadOptions, UNIT_REQUIRED, read};

use crate::camera::Alpha;
use crate::numbers::{Num, clip};
use std::fmt;

use crate::physics::LengthUnit;

/// The largest image side a calibration file may state, in pixels.
const MAX_PIXELS: f64 = 1e6;

/// `value` as an image extent: a whole number of pixels from 1 to [`MAX_PIXELS`] (`2964.0` is
/// 2964); `None` when it is not one. Every reader states image sizes through this.
fn pixels(value: f64) -> Option<u32> {
    (value.fract() == 0.0 && (1.0..=MAX_PIXELS).contains(&value)).then_some(value as u32)
}

/// The calibration formats the service reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    Middlebury,
    Kitti,
    Ros,
    OpenCv,
}

impl Format {
    /// The name used on the wire.
    pub fn name(self) -> &'static str {
        match self {
            Format::Middlebury => "middlebury",
            Format::Kitti => "kitti",
            Format::Ros => "ros",
            Format::OpenCv => "opencv",
        }
    }

    /// The unit the format's lengths are in, when the format defines one (OpenCV's are in the
    /// unit of the calibration target's squares, which the file does not record).
    pub fn unit(self) -> Option<LengthUnit> {
        match self {
            Format::Middlebury => Some(LengthUnit::Millimetre),
            Format::Kitti | Format::Ros => Some(LengthUnit::Metre),
            Format::OpenCv => None,
        }
    }
}

/// Which KITTI camera pair to read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum KittiPair {
    /// Cameras 2 and 3, the colour pair (KITTI's default for stereo benchmarks).
    #[default]
    Colour,
    /// Cameras 0 and 1, the grey pair.
    Grey,
}

impl KittiPair {
    /// The (left, right) camera indices.
    pub fn cameras(self) -> (u8, u8) {
        match self {
            KittiPair::Colour => (2, 3),
            KittiPair::Grey => (0, 1),
        }
    }
}

/// What to read.
#[derive(Debug, Clone, Copy, Default)]
pub struct Source<'a> {
    /// The calibration file (the left camera's, for ROS).
    pub text: &'a str,
    /// The right camera's file, for ROS.
    pub right_text: Option<&'a str>,
    /// The format, or `None` to detect it.
    pub format: Option<Format>,
    /// The KITTI pair, or `None` for the default (colour, falling back to grey with a
    /// warning when the file has only the grey pair).
    pub kitti_pair: Option<KittiPair>,
    /// For a file that describes raw cameras: recompute the rectification with this `alpha`
    /// (0..=1) instead of using the file's own (`None`: the file's, or 0 when it has none).
    pub alpha: Option<Alpha>,
    /// The raw images' size, when the file may not say (the images of the request).
    pub image_size: Option<(u32, u32)>,
}

/// Which file an error is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    Text,
    RightText,
}

/// A problem with a file: where it is and what was expected there.
#[derive(Debug, Clone, PartialEq)]
pub struct ParseError {
    pub part: Part,
    /// The 1-based line, when the problem is on one.
    pub line: Option<usize>,
    pub message: String,
}

/// The longest message a [`ParseError`] carries, in characters.
pub const MAX_MESSAGE: usize = 200;

impl ParseError {
    /// A problem on `line` of the (left) file. Messages end with what the line held, which
    /// can be anything, so they are cut to [`MAX_MESSAGE`] characters.
    pub fn at(line: usize, message: impl Into<String>) -> Self {
        Self {
            part: Part::Text,
            line: Some(line),
            message: clip(&message.into(), MAX_MESSAGE),
        }
    }

    /// A problem with the (left) file as a whole.
    pub fn whole(message: impl Into<String>) -> Self {
        Self {
            part: Part::Text,
            line: None,
            message: message.into(),
        }
    }

    /// The same problem, in the right camera's file.
    pub fn in_right(self) -> Self {
        Self {
            part: Part::RightText,
            ..self
        }
    }
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "line {line}: {}", self.message),
            None => f.write_str(&self.message),
        }
    }
}

/// A rectified rig as a calibration file states it.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    pub format: Format,
    /// `fx` in pixels.
    pub focal_px: f64,
    /// `fy` in pixels (equal to `fx` when the file gives no other).
    pub focal_y_px: f64,
    /// The baseline, in the file's length unit.
    pub baseline: f64,
    /// The left camera's principal point, in pixels.
    pub cx: f64,
    pub cy: f64,
    /// `cx_right − cx_left`, in pixels.
    pub doffs: f64,
    /// `(width, height)` in pixels, when the file says.
    pub image_size: Option<(u32, u32)>,
    /// The disparity search range the file recommends (Middlebury's `ndisp`).
    pub max_disparity_px: Option<u32>,
    /// Things worth knowing that did not stop the reading.
    pub warnings: Vec<String>,
    /// The raw cameras and their rectification, when the file describes them.
    pub raw: Option<Box<Raw>>,
    /// The length unit the file records (our own `opencv.yml` writes `unit`).
    pub unit: Option<LengthUnit>,
    /// The rectified rig's standard deviations the file records (our own `opencv.yml` and
    /// ROS files write them): the focal length's in pixels and the baseline's in the file's
    /// unit.
    pub rig_std: Option<RigStd>,
}

/// The calibration's uncertainty of the rectified rig, as our files record it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigStd {
    /// σ of the focal length, in pixels.
    pub focal_px: f64,
    /// σ of the baseline, in the file's unit.
    pub baseline: f64,
}

impl Calibration {
    /// The rig a rectified pair's 3×4 projection matrices describe (row-major, as KITTI, ROS
    /// and OpenCV write them, the right one's `P[0,3] = −f·B`): `fy`, `cx` and `cy` from the
    /// left one, `B = (P_l[0,3] − P_r[0,3]) / f` and `doffs = cx_right − cx_left`. `f` is the
    /// focal length the format takes (a rectified pair shares one); both slices hold 12
    /// numbers.
    fn from_projections(
        format: Format,
        left: &[f64],
        right: &[f64],
        f: f64,
        image_size: Option<(u32, u32)>,
        warnings: Vec<String>,
    ) -> Self {
        Self {
            format,
            focal_px: f,
            focal_y_px: left[5],
            baseline: (left[3] - right[3]) / f,
            cx: left[2],
            cy: left[6],
            doffs: right[2] - left[2],
            image_size,
            max_disparity_px: None,
            warnings,
            raw: None,
            unit: None,
            rig_std: None,
        }
    }

    /// Checks what every format must give: a positive focal length and baseline, finite
    /// numbers. `line` places the error.
    fn checked(self, line: Option<usize>) -> Result<Self, Vec<ParseError>> {
        let error = |message: String| ParseError {
            part: Part::Text,
            line,
            message,
        };
        let mut errors = Vec::new();
        if !(self.focal_px.is_finite() && self.focal_px > 0.0) {
            errors.push(error(format!(
                "the focal length must be greater than 0, got {}",
                Num(self.focal_px)
            )));
        }
        if !(self.focal_y_px.is_finite() && self.focal_y_px > 0.0) {
            errors.push(error(format!(
                "the vertical focal length must be greater than 0, got {}",
                Num(self.focal_y_px)
            )));
        }
        if !(self.baseline.is_finite() && self.baseline > 0.0) {
            errors.push(error(format!(
                "the baseline must be greater than 0, got {}",
                Num(self.baseline)
            )));
        }
        for (name, value) in [("cx", self.cx), ("cy", self.cy), ("doffs", self.doffs)] {
            if !value.is_finite() {
                errors.push(error(format!("{name} is not a finite number")));
            }
        }
        if errors.is_empty() {
            Ok(self)
        } else {
            Err(errors)
        }
    }
}

/// The most problems reported for one file; a file in another format would otherwise get one
/// per line.
const MAX_ERRORS: usize = 10;

/// The format a file is in, from the marks each format leaves.
pub fn detect(text: &str, has_right: bool) -> Result<Format, Vec<ParseError>> {
    let lines = || text.lines().map(str::trim);
    let key = |k: &str| {
        lines().any(|l| {
            l.strip_prefix(k)
                .is_some_and(|rest| rest.trim_start().starts_with([':', '=']))
        })
    };
    if lines().any(|l| l.starts_with("cam0=") || l.starts_with("cam0 =")) {
        return Ok(Format::Middlebury);
    }
    let opencv_marks = text.contains("opencv-matrix")
        || text.contains("<opencv_storage>")
        || lines().next().is_some_and(|l| l.starts_with("%YAML:"));
    if opencv_marks {
        return Ok(Format::OpenCv);
    }
    if (0..4).any(|i| key(&format!("P_rect_0{i}")) || key(&format!("P{i}"))) {
        return Ok(Format::Kitti);
    }
    if ["Q", "P1", "P2"].iter().all(|k| key(k)) {
        return Ok(Format::OpenCv);
    }
    if key("projection_matrix") || key("camera_matrix") || key("p") || key("P") || has_right {
        return Ok(Format::Ros);
    }
    Err(vec![ParseError::whole(
        "not a calibration file this service reads; tried middlebury (a calib.txt with \
         cam0=[...] and cam1=[...]), kitti (P_rect_02/P_rect_03 or P0..P3 lines), opencv \
         (FileStorage YAML or XML with Q, or P1 and P2) and ros (a CameraInfo YAML with \
         projection_matrix, or k and p, with the right camera's beside it)",
    )])
}

/// The camera tests' pair (OpenCV's reference), its images' size and its rectification at the
/// default options: what the writers' round-trip tests write and read back.
#[cfg(test)]
fn sample_pair() -> (
    crate::camera::StereoPair,
    crate::camera::Size,
    crate::camera::Rectification,
) {
    let size = crate::camera::Size {
        width: 640,
        height: 480,
    };
    let pair = crate::camera::opencv_pair();
    let rect = crate::camera::stereo_rectify(&pair, size, Default::default()).expect("rectified");
    (pair, size, rect)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each format is recognised by its own marks; anything else says what was tried.
    #[test]
    fn detection() {
        assert_eq!(
            detect("cam0=[1 0 2; 0 1 3; 0 0 1]\n", false),
            Ok(Format::Middlebury)
        );
        assert_eq!(detect("P_rect_02: 1 2 3\n", false), Ok(Format::Kitti));
        assert_eq!(detect("P0: 1 2 3\nP1: 4\n", false), Ok(Format::Kitti));
        assert_eq!(detect("%YAML:1.0\n---\nQ: 1\n", false), Ok(Format::OpenCv));
        assert_eq!(
            detect("P1: !!opencv-matrix\n  rows: 3\n", false),
            Ok(Format::OpenCv)
        );
        assert_eq!(
            detect("<?xml version=\"1.0\"?>\n<opencv_storage>\n", false),
            Ok(Format::OpenCv)
        );
        assert_eq!(
            detect("projection_matrix:\n  rows: 3\n", false),
            Ok(Format::Ros)
        );
        assert_eq!(detect("k:\n- 1.0\np:\n- 1.0\n", false), Ok(Format::Ros));
        let kitti = "calib_time: 09-Jan-2012\n".repeat(30) + "P_rect_02: 1 0 2 0 0 1 3 0 0 0 1 0\n";
        let errors = parse(Source {
            text: &kitti,
            format: Some(Format::Middlebury),
            ..Source::default()
        })
        .unwrap_err()
        .errors;
        assert!(
            errors[0]
                .message
                .starts_with("this looks like a kitti file")
        );
        assert_eq!(errors.len(), MAX_ERRORS + 1);
        assert!(errors[MAX_ERRORS].message.contains("more problems"));
        let error = detect("hello world\n", false).unwrap_err();
        for tried in ["middlebury", "kitti", "opencv", "ros"] {
            assert!(error[0].message.contains(tried), "{tried}");
        }
    }
}
