//! How a calibration is made: the board, the lens model, `alpha`, the views' size, the
//! decoder's limits, what its report holds and the earlier calibration it may start from.

use crate::calibration::boards::{Start, Target};
use crate::camera::{Alpha, Model, Size};
use crate::vision::decode::DecodeLimits;

/// How a calibration is made.
#[derive(Debug, Clone)]
pub struct Settings {
    /// The board the views show.
    pub board: Target,
    /// The lens model fitted to each camera.
    pub model: Model,
    /// Bouguet's `alpha` for the rectification.
    pub alpha: Alpha,
    /// The views' size (every image's).
    pub size: Size,
    /// What the decoder takes.
    pub limits: DecodeLimits,
    /// Compute the projection uncertainty over each image (a summary's: the files do not
    /// carry it).
    pub uncertainty: bool,
    /// Each view's corners and residuals in the report.
    pub corners: bool,
    /// Cross-validate two halves of the views in the report (with the uncertainty only: the
    /// halves are judged against it).
    pub cross_validate: bool,
    /// The distance the projection uncertainty is stated at (default: the boards' median).
    pub uncertainty_distance: Option<f64>,
    /// An earlier calibration to start from (`/calibrate`'s `initial`): its lens model is
    /// the one fitted, and `model` is not used.
    pub initial: Option<Initial>,
}

/// An earlier calibration a pair's calibration starts from.
#[derive(Debug, Clone)]
pub struct Initial {
    /// The earlier pair (its T in the board's unit) and whether its lenses are held.
    pub start: Start,
    /// The earlier rectified rig's σ: the focal length's (px) and the baseline's as a
    /// fraction of the baseline; `None` when its file carried none.
    pub rig_std: Option<[f64; 2]>,
    /// What its file's reader noticed, in sentences (a unit overridden, a baseline no rig
    /// has).
    pub warnings: Vec<String>,
}
