//! A pair calibrated again from an earlier calibration and new views of the board: each
//! view's board placed by the earlier lenses, R and T found again with the lenses held (as
//! OpenCV's `stereoCalibrate` with `CALIB_FIX_INTRINSIC`) or every parameter refined from the
//! earlier ones.

use nalgebra::Vector3;

use super::fit::{
    Corners, Fit, FitFault, MIN_VIEWS, Seen, average, finish, right_from_left, together,
};
use super::solve::{Lens, Pose, State, ViewCorners, refine};
use super::zhang;
use crate::camera::{Camera, Size, StereoPair};

/// The fewest views that refit a pair's R and T with its lenses held ([`Start::hold`]): one
/// board seen by both cameras places each camera, and so the one against the other.
pub const MIN_VIEWS_HELD: usize = 1;

/// An earlier calibration a new one starts from.
#[derive(Debug, Clone, PartialEq)]
pub struct Start {
    /// The earlier pair. Its T's unit does not matter: R and T are found again from the
    /// views, the board's unit theirs.
    pub pair: StereoPair,
    /// Hold both lenses at the earlier pair's (OpenCV's `CALIB_FIX_INTRINSIC`): only R, T and
    /// the boards' poses move, from [`MIN_VIEWS_HELD`] view. Otherwise every parameter is
    /// refined from the earlier ones, over [`MIN_VIEWS`] views.
    pub hold: bool,
}

impl Start {
    /// The fewest views this start takes.
    pub fn fewest_views(&self) -> usize {
        if self.hold { MIN_VIEWS_HELD } else { MIN_VIEWS }
    }
}

/// A pair calibrated again from an earlier one (`start`) and new views of the board: each
/// camera's board pose in every view both cameras saw, placed by the earlier lens; R and T
/// started from the poses' mean relative motion; then refined together, the lenses held or
/// not as `start` says. The lens model is the earlier pair's.
pub fn recalibrate(
    object: &[Vector3<f64>],
    size: Size,
    start: &Start,
    views: &[Corners],
) -> Result<Fit, FitFault> {
    let found: Vec<bool> = views
        .iter()
        .map(|v| v.left.is_some() && v.right.is_some())
        .collect();
    let fewest = start.fewest_views();
    let (mut kept, mut poses, mut relative) = (Vec::new(), Vec::new(), Vec::new());
    for v in (0..views.len()).filter(|&v| found[v]) {
        let (Some(left), Some(right)) = (&views[v].left, &views[v].right) else {
            continue;
        };
        let (Some(l), Some(r)) = (
            board_pose(&start.pair.left, object, left),
            board_pose(&start.pair.right, object, right),
        ) else {
            continue;
        };
        relative.push(right_from_left(&l, &r));
        poses.push(l);
        kept.push(v);
    }
    if kept.len() < fewest {
        return Err(FitFault::TooFewViews {
            usable: kept.len(),
            needed: fewest,
        });
    }
    let extrinsics = average(&relative).ok_or(FitFault::Degenerate)?;
    let state = State {
        lenses: vec![Lens::of(&start.pair.left), Lens::of(&start.pair.right)],
        extrinsics: Some(extrinsics),
        poses,
        held: start.hold,
    };
    let joint = together(state, object, views, kept, fewest)?;
    let model = start.pair.left.distortion().model();
    let mut fit = finish(size, model, views, &found, joint, true)?;
    fit.held = start.hold;
    Ok(fit)
}

/// The board's pose in a calibrated camera from the corners it saw (`seen`, in the order of
/// `object`): the homography of the undistorted corners gives it, then the reprojection is
/// refined with the lens held. `None` with fewer than six corners or a degenerate view.
pub fn board_pose(camera: &Camera, object: &[Vector3<f64>], seen: &Seen) -> Option<Pose> {
    let (plane, rays): (Vec<[f64; 2]>, Vec<[f64; 2]>) = object
        .iter()
        .zip(seen)
        .filter_map(|(p, c)| Some(([p.x, p.y], camera.normalize((*c)?)?)))
        .unzip();
    if plane.len() < 6 {
        return None;
    }
    let unit = crate::camera::Intrinsics {
        fx: 1.0,
        fy: 1.0,
        cx: 0.0,
        cy: 0.0,
    };
    let (rotation, translation) = zhang::pose(&zhang::homography(&plane, &rays)?, &unit)?;
    let state = State {
        lenses: vec![Lens::of(camera)],
        extrinsics: None,
        poses: vec![Pose {
            rotation,
            translation,
        }],
        held: true,
    };
    let view = ViewCorners {
        left: Some(seen),
        right: None,
    };
    let solution = refine(state, object, &[view]).ok()?;
    Some(solution.state.poses[0])
}
