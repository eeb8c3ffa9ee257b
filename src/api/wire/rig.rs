//! The rig's two wire shapes, shared by every route that takes or gives one: [`StereoRig`],
//! the members of `/distance` as a request states them (a batch's `rig`, the image routes'
//! `rig` part), and [`CalibratedRig`], a checked rig as `/calibration` and the image routes
//! answer it.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::wire::de::rig_request;
use crate::api::wire::params::Unit;
use stereo_core::physics::Rig;

rig_request! {
    /// A rig as a request states it, with the members of `/distance`: a batch's `rig`, the
    /// image routes' `rig` part.
    #[schema(example = json!({
        "focal_length_px": 35, "baseline": 150, "unit": "mm",
        "image_width": 800, "image_height": 600
    }))]
    pub struct StereoRig {}
}

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
    /// σ of `focal_length_px` in pixels, when a calibration estimated it (`/calibrate`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub focal_length_std_px: Option<f64>,
    /// σ of `baseline` in `unit`, when a calibration estimated it (`/calibrate`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub baseline_std: Option<f64>,
}

impl From<&Rig> for CalibratedRig {
    /// The rig's members as `/calibration` answers them: fy only when it differs from fx, the
    /// image size only when known.
    fn from(rig: &Rig) -> Self {
        Self {
            focal_length_px: rig.focal_px(),
            focal_length_y_px: (rig.focal_y_px() != rig.focal_px()).then_some(rig.focal_y_px()),
            baseline: rig.baseline(),
            unit: Unit::from(rig.unit()),
            cx: rig.cx().unwrap_or_default(),
            cy: rig.cy().unwrap_or_default(),
            doffs: rig.doffs(),
            image_width: rig.image_width().map(|w| w as u32),
            image_height: rig.image_height().map(|h| h as u32),
            focal_length_std_px: (rig.focal_std_px() > 0.0).then_some(rig.focal_std_px()),
            baseline_std: (rig.baseline_std() > 0.0).then_some(rig.baseline_std()),
        }
    }
}
