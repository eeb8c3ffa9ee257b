//! A rig's design figures, as `/rig` and `/baseline` answer them: the depth error at a
//! distance against the range a disparity search sees ([`Rig::error_at`]), where a
//! relative-error budget is passed ([`Rig::budget_reach`]), and the shortest baseline that
//! meets a depth-error budget ([`baseline_design`]).

use super::{Fault, PhysicsError, RectifiedCamera, Rig, baseline_for, finite};

/// The depth error a rig makes at one distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorAt {
    pub distance: f64,
    /// The disparity a point at `distance` has, in pixels (raw, before `doffs`).
    pub disparity_px: f64,
    /// `σ_Z`, in the rig's unit.
    pub depth_error: f64,
    /// `σ_Z / Z`.
    pub relative_error: f64,
    /// Whether `distance` lies in the range the search sees.
    pub in_range: bool,
}

/// Where a relative-error budget is passed, against the range `(near, far)` the search sees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reach {
    /// The error stays below the budget over the whole range.
    Whole,
    /// Below the budget from `near` up to the budget's distance.
    UpTo,
    /// Already past the budget at `near`, where the relative error is this.
    Nowhere { relative_error_at_near: f64 },
}

/// A depth-error budget: a length in the rig's unit, or a fraction of the target distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum DepthBudget {
    Error(f64),
    Relative(f64),
}

impl DepthBudget {
    /// The budget as a length at `target`: `r·Z` for a fraction.
    pub fn at(self, target: f64) -> f64 {
        match self {
            DepthBudget::Error(dz) => dz,
            DepthBudget::Relative(r) => r * target,
        }
    }
}

impl Rig {
    /// The depth error at `distance`, and whether the search's range `(near, far)` sees it;
    /// refused when a figure is not finite.
    pub fn error_at(
        &self,
        distance: f64,
        (near, far): (f64, f64),
    ) -> Result<ErrorAt, PhysicsError> {
        Ok(ErrorAt {
            distance,
            disparity_px: finite(self.disparity_at(distance))?,
            depth_error: finite(self.depth_error_at(distance))?,
            relative_error: finite(self.relative_error_at(distance))?,
            in_range: (near..=far).contains(&distance),
        })
    }

    /// The distance at which the relative error reaches `budget`, and how that sits in the
    /// search's range `(near, far)`; `None` when no distance reaches it.
    pub fn budget_reach(&self, budget: f64, (near, far): (f64, f64)) -> Option<(f64, Reach)> {
        let at = self.distance_at_relative_error(budget)?;
        let reach = if at >= far {
            Reach::Whole
        } else if at > near {
            Reach::UpTo
        } else {
            Reach::Nowhere {
                relative_error_at_near: self.relative_error_at(near),
            }
        };
        Some((at, reach))
    }
}

/// The shortest baseline that meets a depth-error budget at a target distance, and what the
/// rig built with it sees.
#[derive(Debug, Clone, PartialEq)]
pub struct BaselineDesign {
    /// The rig with the baseline found.
    pub rig: Rig,
    /// The budget as a length at the target.
    pub max_depth_error: f64,
    /// The budget as a fraction of the target.
    pub max_relative_error: f64,
    pub disparity_at_target_px: f64,
    /// The nearest distance a search up to the given disparity sees.
    pub min_distance: Option<f64>,
}

/// Why a baseline cannot be designed, by the figure that failed.
#[derive(Debug, Clone, PartialEq)]
pub enum DesignFault {
    /// `B = Z²·Δd / (f·ΔZ)` is not finite.
    Baseline(PhysicsError),
    /// The rig with that baseline is refused.
    Rig(Vec<Fault>),
    /// The nearest distance at the given disparity.
    MinDistance(PhysicsError),
    /// The disparity at the target.
    Target(PhysicsError),
}

/// The baseline `camera` needs to keep the depth error at `target` within `budget`, with the
/// nearest distance a search up to `max_disparity_px` would see.
pub fn baseline_design(
    camera: RectifiedCamera,
    target: f64,
    budget: DepthBudget,
    max_disparity_px: Option<f64>,
) -> Result<BaselineDesign, DesignFault> {
    let max_depth_error = budget.at(target);
    let baseline = baseline_for(
        camera.focal_px(),
        target,
        max_depth_error,
        camera.disparity_error_px(),
    )
    .map_err(DesignFault::Baseline)?;
    let rig = Rig::from_camera(camera, baseline).map_err(DesignFault::Rig)?;
    let min_distance = max_disparity_px
        .map(|d| rig.distance_at(d))
        .transpose()
        .map_err(DesignFault::MinDistance)?;
    let disparity_at_target_px = finite(rig.disparity_at(target)).map_err(DesignFault::Target)?;
    Ok(BaselineDesign {
        rig,
        max_depth_error,
        max_relative_error: max_depth_error / target,
        disparity_at_target_px,
        min_distance,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::{CameraSpec, RigSpec};

    fn camera() -> RectifiedCamera {
        let mut spec = CameraSpec {
            image_width: Some(848),
            image_height: Some(480),
            disparity_error_px: Some(0.1),
            ..CameraSpec::default()
        };
        spec.focal.px = Some(424.0);
        RectifiedCamera::new(&spec).unwrap()
    }

    /// A 2 % budget at 2 m is 40 mm, and the baseline meets it exactly: σ_Z at the target is
    /// the budget, and the disparity there is f·B/Z.
    #[test]
    fn the_baseline_meets_its_budget() {
        let design =
            baseline_design(camera(), 2000.0, DepthBudget::Relative(0.02), Some(64.0)).unwrap();
        assert_eq!(design.max_depth_error, 40.0);
        assert_eq!(design.max_relative_error, 0.02);
        let b = 2000.0 * 2000.0 * 0.1 / (424.0 * 40.0);
        assert!((design.rig.baseline() - b).abs() < 1e-9, "{:?}", design.rig);
        let err = design.rig.error_at(2000.0, (0.0, f64::INFINITY)).unwrap();
        assert!((err.depth_error - 40.0).abs() < 1e-9, "{err:?}");
        assert!((design.disparity_at_target_px - 424.0 * b / 2000.0).abs() < 1e-9);
        assert!((design.min_distance.unwrap() - 424.0 * b / 64.0).abs() < 1e-9);
    }

    /// The budget's distance sits where the relative error reaches it, and is placed against
    /// the range: beyond its far end, inside it, or short of its near end.
    #[test]
    fn the_budget_is_placed_in_the_range() {
        let spec = RigSpec {
            camera: CameraSpec {
                image_width: Some(848),
                image_height: Some(480),
                disparity_error_px: Some(0.1),
                focal: crate::physics::Focal {
                    px: Some(424.0),
                    ..Default::default()
                },
                ..CameraSpec::default()
            },
            baseline: Some(50.0),
            ..RigSpec::default()
        };
        let rig = Rig::new(&spec).unwrap();
        let (at, reach) = rig.budget_reach(0.02, (100.0, 1e9)).unwrap();
        assert!((rig.relative_error_at(at) - 0.02).abs() < 1e-9);
        assert_eq!(reach, Reach::UpTo);
        assert_eq!(rig.budget_reach(0.02, (100.0, at)).unwrap().1, Reach::Whole);
        let Reach::Nowhere {
            relative_error_at_near,
        } = rig.budget_reach(0.02, (2.0 * at, 1e9)).unwrap().1
        else {
            panic!("past the budget")
        };
        assert!(relative_error_at_near > 0.02);
    }
}
