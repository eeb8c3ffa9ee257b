//! The measured values every distance answer carries (`/distance`, each point of a batch), mapped
//! from the physics in one place so that no two answers can disagree.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use stereo_core::physics;

/// A point in the left camera's frame: x right, y down, z forward, in `unit`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Point {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

impl From<physics::Point3> for Point {
    fn from(p: physics::Point3) -> Self {
        Self {
            x: p.x,
            y: p.y,
            z: p.z,
        }
    }
}

/// Something worth knowing about a result that was still computed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Warning {
    /// Stable code: `negative_disparity`, `large_relative_error`, `no_principal_point` or
    /// `implausible_baseline` (a baseline under 1 mm or over 10 m: its unit typed wrong).
    pub code: String,
    /// What it means and what to check.
    pub message: String,
}

impl From<&physics::Warning> for Warning {
    fn from(warning: &physics::Warning) -> Self {
        Self {
            code: warning.code().to_owned(),
            message: warning.to_string(),
        }
    }
}

/// The depth error's terms, each a standard deviation in `unit`; `depth_error` is their
/// quadrature sum √(disparity² + focal_length² + baseline²).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct DepthErrorTerms {
    /// From the disparity's uncertainty Δd: Z²·Δd/(f·B).
    pub disparity: f64,
    /// From the focal length's σ (`focal_length_std_px`): Z·σ_f/f; 0 without it.
    pub focal_length: f64,
    /// From the baseline's σ (`baseline_std`): Z·σ_B/B; 0 without it.
    pub baseline: f64,
}

impl From<physics::DepthErrorTerms> for DepthErrorTerms {
    fn from(t: physics::DepthErrorTerms) -> Self {
        Self {
            disparity: t.disparity,
            focal_length: t.focal_length,
            baseline: t.baseline,
        }
    }
}

/// What one triangulated correspondence gives: the part of every distance answer that comes
/// straight from the triangulation, the same in a single answer and in a batch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Measured {
    /// Depth: the distance Z along the optical axis, from the plane of the cameras to the
    /// point, in `unit`. This is what Z = B·f / |d + doffs| gives.
    pub distance: f64,
    /// Range: the straight-line distance √(X² + Y² + Z²) from the left camera's optical
    /// centre to the point, in `unit`. Equal to `distance` on the optical axis, longer off it.
    /// Absent when the rig has no principal point (no `cx`, `cy` or image size; a
    /// `no_principal_point` warning says so).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub range: Option<f64>,
    /// Expected depth error (one standard deviation), in `unit`: ΔZ = Z²·Δd/(f·B), and with
    /// a calibration's `focal_length_std_px` and `baseline_std`,
    /// √((Z²·Δd/(f·B))² + (Z·σ_f/f)² + (Z·σ_B/B)²).
    pub depth_error: f64,
    /// `depth_error`'s terms: what the disparity, the focal length and the baseline each add.
    pub depth_error_terms: DepthErrorTerms,
    /// depth_error / distance.
    pub relative_error: f64,
    /// Disparity d = x_left − x_right, in pixels (signed).
    pub disparity_px: f64,
    /// The feature's 3D position in the left camera's frame; absent, as `range`, without a
    /// principal point.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub point: Option<Point>,
    /// Caveats about this result; empty when there are none.
    pub warnings: Vec<Warning>,
}

impl From<&physics::Measurement> for Measured {
    fn from(m: &physics::Measurement) -> Self {
        Self {
            distance: m.distance,
            range: m.range,
            depth_error: m.depth_error,
            depth_error_terms: m.depth_error_terms.into(),
            relative_error: m.relative_error,
            disparity_px: m.disparity_px,
            point: m.point.map(Point::from),
            warnings: m.warnings.iter().map(Warning::from).collect(),
        }
    }
}
