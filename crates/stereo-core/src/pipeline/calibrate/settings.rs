//! How a calibration is made: the board, the lens model, `alpha`, the views' size and the
//! decoder's limits, and what its report holds.

use crate::calibration::boards::Target;
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
}
