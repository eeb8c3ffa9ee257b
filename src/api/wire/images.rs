//! The wire types the image routes share: their multipart form's documentation
//! ([`image_form!`]), what a request sent to describe its rig ([`RigParts`]), whether a pair is rectified before matching ([`RectifyMode`]) and how
//! long a match's stages took ([`StageTimes`]).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use axum::body::Bytes;

use crate::api::error::FieldErrors;
use crate::api::wire::de::choice_members;
use stereo_core::camera::Latlon;
use stereo_core::physics::LengthUnit;
use stereo_core::pipeline::Sent;

/// The parts (or, in a stream's settings, the members) that carry a rig.
pub const RIG_PARTS: [&str; 6] = [
    "rig",
    "calibration",
    "calibration_format",
    "right_calibration",
    "calibration_unit",
    "calibration_cameras",
];

/// What a request sent to describe its rig: each of [`RIG_PARTS`] as it came, taken once at
/// the request's edge (a form's parts, a stream's settings members, the command's flags) and
/// parsed once into the engine's `RigInput` (`api::images::rig::parsed`).
#[derive(Debug, Clone, Default)]
pub struct RigParts([Option<Bytes>; RIG_PARTS.len()]);

impl RigParts {
    /// A calibration file and its unit, as the `depth-map` command's flags give them.
    pub fn calibration(bytes: &[u8], unit: Option<&str>) -> RigParts {
        let mut input = RigParts::default();
        input.set("calibration", Bytes::copy_from_slice(bytes));
        if let Some(unit) = unit {
            input.set("calibration_unit", Bytes::from(unit.to_owned()));
        }
        input
    }

    /// Takes `bytes` as the member `name`; `false` (and nothing taken) when `name` is not one
    /// of [`RIG_PARTS`].
    pub fn set(&mut self, name: &str, bytes: Bytes) -> bool {
        match RIG_PARTS.iter().position(|p| *p == name) {
            Some(i) => {
                self.0[i] = Some(bytes);
                true
            }
            None => false,
        }
    }

    /// The member `name`, when it was sent.
    pub fn get(&self, name: &str) -> Option<&Bytes> {
        let i = RIG_PARTS.iter().position(|p| *p == name)?;
        self.0[i].as_ref()
    }

    /// The member as UTF-8 text, or an error naming it.
    pub fn text(&self, name: &str, problems: &mut FieldErrors) -> Option<String> {
        utf8(name, self.get(name)?, problems)
    }

    /// What was sent to describe the rig: a calibration file (a `rig` beside it carries
    /// only its σ), a rig's members, or nothing.
    pub fn sent(&self) -> Sent {
        if self.get("calibration").is_some() {
            Sent::Calibration
        } else if self.get("rig").is_some() {
            Sent::Rig
        } else {
            Sent::Nothing
        }
    }
}

/// A part's (or member's) bytes as UTF-8 text, or an error naming it.
pub fn utf8(name: &str, bytes: &Bytes, problems: &mut FieldErrors) -> Option<String> {
    match std::str::from_utf8(bytes) {
        Ok(text) => Some(text.to_owned()),
        Err(e) => {
            problems.add(
                name,
                format!("must be UTF-8 text; byte {} is not", e.valid_up_to()),
            );
            None
        }
    }
}

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

choice_members!(RectifyMode, ProjectionChoice, ProjectionAsked);

/// The rectified projection a request asks for: one of [`ProjectionChoice`]'s, or `auto`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum ProjectionAsked {
    /// The pinhole plane (the default).
    #[default]
    Pinhole,
    /// Latitude-longitude.
    Latlon,
    /// Latitude-longitude where the cameras together see wider than 100° (across the baseline
    /// or about it), where a pinhole plane stretches its edges 2.4 × and more; else the
    /// pinhole plane. With `alpha`, or an output only a pinhole rectification has (the ROS
    /// messages), the pinhole plane.
    Auto,
}

/// The rectified images' projection.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum ProjectionChoice {
    /// A pinhole plane, as `cv2.stereoRectify` (Bouguet) makes it (the default): straight
    /// lines stay straight; it holds well up to about 100° across and never 180°.
    #[default]
    Pinhole,
    /// Latitude-longitude, as mrcal's `rectified_system` makes it: columns are even steps of
    /// azimuth along the baseline, rows even steps of elevation about it, so epipolar lines
    /// are rows at every angle, up to 180° across: for wide and fisheye lenses.
    Latlon,
}

/// A latitude-longitude rectified pair, as mrcal's `rectified_system` gives it: column x
/// is azimuth (x − cx)/fx and row y elevation (y − cy)/fy, in radians; the ray of
/// (az, el) is (sin az, cos az·sin el, cos az·cos el) in the rectified frame, whose x runs
/// along the baseline. A disparity d (pixels) is the angle d/fx, and the range from the left
/// camera r = baseline·cos(az − d/fx)/sin(d/fx) (mrcal's `stereo_range`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct LatlonSystem {
    /// The centre of the field (mrcal's `az0_deg`, `el0_deg`) and its extent, in degrees.
    pub az0_deg: f64,
    pub el0_deg: f64,
    pub az_fov_deg: f64,
    pub el_fov_deg: f64,
    pub pixels_per_degree_az: f64,
    pub pixels_per_degree_el: f64,
    /// Pixels per radian, and the pixel of azimuth 0 and elevation 0.
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// The distance between the cameras, in `unit`.
    pub baseline: f64,
    pub unit: String,
    /// The rotations from each raw camera's frame to the rectified one (row-major 3 × 3,
    /// mrcal's `R_rect0_cam0` and `R_rect1_cam1`).
    pub r1: [f64; 9],
    pub r2: [f64; 9],
}

impl LatlonSystem {
    /// The system as the summary gives it, its baseline in `unit`.
    pub fn of(l: &Latlon, unit: LengthUnit) -> LatlonSystem {
        let rows = |m: &nalgebra::Matrix3<f64>| {
            let t = m.transpose();
            let s = t.as_slice();
            std::array::from_fn(|i| s[i])
        };
        LatlonSystem {
            az0_deg: l.az0_deg,
            el0_deg: l.el0_deg,
            az_fov_deg: l.az_fov_deg,
            el_fov_deg: l.el_fov_deg,
            pixels_per_degree_az: l.fx.to_radians(),
            pixels_per_degree_el: l.fy.to_radians(),
            fx: l.fx,
            fy: l.fy,
            cx: l.cx,
            cy: l.cy,
            baseline: l.baseline,
            unit: unit.symbol().to_owned(),
            r1: rows(&l.r1),
            r2: rows(&l.r2),
        }
    }
}

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

/// Declares a multipart form for the documentation with the calibration file's option parts
/// appended (`calibration_format`, `right_calibration`, `calibration_unit`,
/// `calibration_cameras`), documented once here for every form that takes a `calibration`.
macro_rules! with_calibration_options {
    (
        $(#[$meta:meta])*
        pub struct $name:ident { $($(#[$attr:meta])* $field:ident: $ty:ty),* $(,)? }
    ) => {
        $(#[$meta])*
        #[derive(::utoipa::ToSchema)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        pub struct $name {
            $($(#[$attr])* $field: $ty,)*
            /// The calibration's format, or `auto` (the default).
            #[schema(nullable = false)]
            calibration_format: Option<String>,
            /// The right camera's ROS `CameraInfo`, for ROS calibrations.
            #[schema(value_type = Option<String>, format = Binary, nullable = false)]
            right_calibration: Option<Vec<u8>>,
            /// The unit of the calibration's lengths (required for OpenCV files not written
            /// here).
            #[schema(nullable = false)]
            calibration_unit: Option<String>,
            /// KITTI only: the camera pair, `2-3` (the default) or `0-1`.
            #[schema(nullable = false)]
            calibration_cameras: Option<String>,
        }
    };
}
pub(crate) use with_calibration_options;

/// Declares an image route's multipart form, for the documentation (the handler reads the
/// parts itself, to name each one in its errors): `left` and `right`, the route's own parts,
/// then the rig's parts, documented once here for every image route.
macro_rules! image_form {
    (
        $(#[$meta:meta])*
        pub struct $name:ident { $($(#[$attr:meta])* $field:ident: $ty:ty),* $(,)? }
    ) => {
        $crate::api::wire::images::with_calibration_options! {
            $(#[$meta])*
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
            }
        }
    };
}
pub(crate) use image_form;

/// A file answer's bytes, documented as binary.
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct FileBody(pub Vec<u8>);
