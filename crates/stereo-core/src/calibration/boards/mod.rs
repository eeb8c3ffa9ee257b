//! Calibration from checkerboard images: the board, the corner finder, Zhang's first guess,
//! the Levenberg–Marquardt refinements of each camera and of the pair, and each parameter's
//! standard deviation. Pure: no HTTP, no serde.
//!
//! - [`board`]: the printed target and its corners' positions on its plane.
//! - [`corners`]: finding the inner corners, to hundredths of a pixel.
//! - [`charuco`]: ChArUco boards, their markers read and their corners found by id.
//! - [`target`]: the target shot, a chessboard or a ChArUco board, and its corners in an
//!   image.
//! - [`zhang`]: homographies, Zhang's closed-form camera matrix and the views' poses.
//! - [`solve`]: Levenberg–Marquardt over lenses, extrinsics and poses, with the covariance.
//! - [`fit`]: one camera or a pair calibrated, outlier views left out, E, F, the epipolar
//!   check and the rectified rig's uncertainty.
//! - [`again`]: a pair calibrated again from an earlier calibration, its lenses held or not.
//! - [`report`]: the detections per view, coverage, tilt and the warnings a user checks a
//!   calibration by.
//! - [`uncertainty`]: the σ of a projection over each image, from the views' own scatter,
//!   told apart into the noise's part and the model's.
//! - [`cross_validation`]: two halves of the views calibrated apart and compared against what
//!   their σ predict.
//! - [`synthetic`]: boards rendered through the camera model with exact truth.

pub mod again;
pub mod board;
pub mod charuco;
pub mod corners;
pub mod cross_validation;
pub mod fit;
pub mod report;
pub mod solve;
pub mod synthetic;
pub mod target;
pub mod uncertainty;
pub mod zhang;

pub use again::{Start, board_pose, recalibrate};
pub use board::{Board, BoardFault, BoardMember};
pub use target::{Target, TargetMiss};
#[cfg(test)]
mod tests;

pub use fit::{
    CameraFit, Corners, Extrinsics, Fit, FitFault, Seen, ViewFit, ViewOutcome, calibrate, whole,
};

/// The most views (pairs, or one camera's images) one calibration takes: 60 holds every board
/// pose a careful calibration needs several times over, while bounding the solver's work (its
/// normal equations grow with six unknowns a view).
pub const MAX_VIEWS: usize = 60;
