//! What the caller stated, before validation: the unit and spacing enums, and the sample range
//! gathered from whichever request type carried it. (The camera and the rig a request states
//! are the physics' own specs, `CameraSpec` and `RigSpec`, made by the request macros.)

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use stereo_core::physics::{self, LengthUnit};

/// Unit of the baseline and of every length in the response.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum Unit {
    #[default]
    Mm,
    Cm,
    M,
    In,
    Ft,
}

impl From<Unit> for LengthUnit {
    fn from(unit: Unit) -> Self {
        match unit {
            Unit::Mm => LengthUnit::Millimetre,
            Unit::Cm => LengthUnit::Centimetre,
            Unit::M => LengthUnit::Metre,
            Unit::In => LengthUnit::Inch,
            Unit::Ft => LengthUnit::Foot,
        }
    }
}

impl From<LengthUnit> for Unit {
    fn from(unit: LengthUnit) -> Self {
        match unit {
            LengthUnit::Millimetre => Unit::Mm,
            LengthUnit::Centimetre => Unit::Cm,
            LengthUnit::Metre => Unit::M,
            LengthUnit::Inch => Unit::In,
            LengthUnit::Foot => Unit::Ft,
        }
    }
}

/// How table rows or chart points are spread across the range.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum Spacing {
    /// Equal steps.
    #[default]
    Linear,
    /// Equal ratios (geometric), denser where the curve bends.
    Log,
}

impl From<Spacing> for physics::Spacing {
    fn from(spacing: Spacing) -> Self {
        match spacing {
            Spacing::Linear => physics::Spacing::Linear,
            Spacing::Log => physics::Spacing::Log,
        }
    }
}

/// The sample range as the caller stated it, before validation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RangeParams {
    pub distance_min: Option<f64>,
    pub distance_max: Option<f64>,
    pub disparity_min: Option<f64>,
    pub disparity_max: Option<f64>,
    pub spacing: Option<Spacing>,
}
