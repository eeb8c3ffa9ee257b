//! What `/calibrate` checks a calibration by besides its RMS: the projection uncertainty over
//! each image and, when asked, the cross-validation of two halves of the views (the engine is
//! [`stereo_core::calibration::boards::uncertainty`], [`stereo_core::calibration::boards::cross_validation`]).

use super::Settings;
use stereo_core::calibration::boards::report::Determination;
use stereo_core::calibration::boards::{self, cross_validation, uncertainty};

/// What a user checks the calibration by besides its RMS: whether the views determine it,
/// the projection σ over each image, and (when asked) the cross-validation of two halves of
/// the views.
pub struct Checks {
    pub determination: Determination,
    pub uncertainty: Option<uncertainty::ProjectionUncertainty>,
    pub cross: Option<cross_validation::CrossValidation>,
    /// Why the cross-validation asked for was not made.
    pub cross_warning: Option<String>,
}

impl Checks {
    pub fn of(
        fit: &boards::Fit,
        views: &[boards::Corners],
        settings: &Settings,
        stereo: bool,
        determination: Determination,
    ) -> Checks {
        let uncertainty = uncertainty::projection_uncertainty(fit, settings.uncertainty_distance);
        let (mut cross, mut cross_warning) = (None, None);
        if settings.cross_validate {
            let distance = uncertainty.as_ref().map(|u| u.distance);
            let halves = distance.ok_or(0).and_then(|d| {
                cross_validation::cross_validation(
                    &settings.object,
                    settings.model,
                    fit,
                    views,
                    stereo,
                    d,
                )
            });
            match halves {
                Ok(c) => cross = Some(c),
                Err(used) => {
                    cross_warning = Some(format!(
                        "cross-validation needs two halves that each calibrate: at least 6 \
                         views used ({used} were)"
                    ));
                }
            }
        }
        Checks {
            determination,
            uncertainty,
            cross,
            cross_warning,
        }
    }
}
