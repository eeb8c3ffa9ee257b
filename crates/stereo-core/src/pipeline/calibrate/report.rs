//! What a user checks a calibration by besides its RMS: whether the views determine it, each
//! image's coverage and the boards' tilts, the projection uncertainty over each image, the
//! cross-validation of two halves of the views when asked, each view's corners and
//! residuals when asked, and the warnings saying what to shoot again or check.

use super::settings::Settings;
use crate::calibration::boards::Target;
use crate::calibration::boards::report::{self, Coverage, Determination, Rectified};
use crate::calibration::boards::{Corners, Fit, cross_validation, uncertainty};
use crate::camera::Rectification;
use crate::physics::{Implausible, Rig};

/// A view's residuals (px), left and right.
pub type Residuals = [Option<Vec<[f64; 2]>>; 2];

/// A calibration's report.
#[derive(Debug, Clone)]
pub struct Report {
    pub determination: Determination,
    /// The corners' coverage of the left image and, for a pair, the right.
    pub coverage: (Coverage, Option<Coverage>),
    /// The boards' smallest and largest tilt, in degrees.
    pub tilt_range: [f64; 2],
    /// The projection uncertainty, when asked for.
    pub uncertainty: Option<uncertainty::ProjectionUncertainty>,
    pub cross: Option<cross_validation::CrossValidation>,
    /// Each view's residuals (px) left and right, when the corners were asked for.
    pub residuals: Option<Vec<Residuals>>,
    /// What to shoot again or check, what the decoder forgave first.
    pub warnings: Vec<String>,
}

impl Report {
    /// The report of a fit of `views` made with `settings`, its rectification and rig σ, with
    /// the decoder's `notes` first among its warnings.
    pub fn of(
        (fit, views, settings): (&Fit, &[Corners], &Settings),
        (rectification, rig_std): (Option<&Rectification>, Option<[f64; 2]>),
        notes: &[String],
        determination: Determination,
    ) -> Report {
        let stereo = fit.right.is_some();
        let object = settings.board.object_points();
        let uncertainty = settings
            .uncertainty
            .then(|| uncertainty::projection_uncertainty(fit, settings.uncertainty_distance))
            .flatten();
        let (mut cross, mut cross_warning) = (None, None);
        if settings.cross_validate && settings.uncertainty {
            let distance = uncertainty.as_ref().map(|u| u.distance);
            let halves = distance.ok_or(0).and_then(|d| {
                cross_validation::cross_validation(&object, settings.model, fit, views, stereo, d)
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
        let left = Coverage::of(views, fit, false, settings.size);
        let right = stereo.then(|| Coverage::of(views, fit, true, settings.size));
        let tilt_range = report::tilt_range(fit);
        let rig = rectified_rig(rectification, rig_std, &settings.board);
        let rectified = match (stereo, rectification, rig) {
            (false, _, _) => Rectified::Alone,
            (true, None, _) => Rectified::Failed,
            (true, Some(_), None) => Rectified::Vertical,
            (true, Some(_), Some(_)) => Rectified::Horizontal,
        };
        let mut warnings = notes.to_vec();
        warnings.extend(report::warnings(
            fit,
            &determination,
            [Some(&left), right.as_ref()],
            tilt_range,
            rectified,
        ));
        warnings.extend(cross_warning);
        warnings.extend(lengths_warnings(fit, &settings.board, rig.as_ref()));
        if let Some(u) = uncertainty.as_ref() {
            warnings.extend(model_error_warnings(u));
        }
        if let Some(c) = cross.as_ref().filter(|c| !c.consistent()) {
            warnings.push(inconsistent_halves(c));
        }
        let residuals = settings.corners.then(|| {
            (0..views.len())
                .map(|i| fit.residuals(&object, i, &views[i]))
                .collect()
        });
        Report {
            determination,
            coverage: (left, right),
            tilt_range,
            uncertainty,
            cross,
            residuals,
            warnings,
        }
    }
}

/// What the lengths say of a user's slips: a board's square or a baseline no camera has (a
/// unit typed wrong), and a right camera that lies to the left of the left one (T_x > 0 in
/// OpenCV's X_right = R·X_left + T: the views' left and right swapped).
fn lengths_warnings(fit: &Fit, board: &Target, rig: Option<&Rig>) -> Vec<String> {
    let mut warnings = Vec::new();
    if let Some(i) = Implausible::square_size(board.square_size(), board.unit()) {
        warnings.push(format!("the board's {i}"));
    }
    if let Some(i) = rig.and_then(|r| Implausible::baseline(r.baseline(), r.unit())) {
        warnings.push(format!("the calibrated {i}"));
    }
    if let Some(t) = fit.extrinsics.as_ref().map(|e| e.translation)
        && t.x > 0.0
        && t.x.abs() >= t.y.abs()
    {
        warnings.push(format!(
            "the right camera lies to the left of the left one: T_x = +{} {} (OpenCV's \
             X_right = R·X_left + T, so a right camera on the right has T_x < 0). The views \
             look swapped: send each pair's left camera's image as `left` and the other as \
             `right`, or every disparity will come out negative",
            crate::numbers::short(t.x),
            board.unit().symbol()
        ));
    }
    warnings
}

/// A warning for each camera whose projection uncertainty the lens model's error dominates.
fn model_error_warnings(u: &uncertainty::ProjectionUncertainty) -> Vec<String> {
    let mut warnings = Vec::new();
    for (side, g) in [("left", Some(&u.left)), ("right", u.right.as_ref())] {
        let Some(g) = g.filter(|g| g.model_error_dominates()) else {
            continue;
        };
        warnings.push(format!(
            "model error dominates the {side} camera's projection uncertainty: {:.3} px \
             (median) of which the corners' noise explains {:.3} px and what the lens model \
             cannot fit {:.3} px. More views of the same kind will not lower it; try the \
             rational_polynomial model (a wide lens), add views with the board near the \
             image's edges and corners, and check that the board is flat",
            g.median_px, g.noise_median_px, g.model_median_px
        ));
    }
    warnings
}

/// The warning for two halves that disagree more, or less, than their uncertainties predict.
fn inconsistent_halves(c: &cross_validation::CrossValidation) -> String {
    let (low, high) = cross_validation::CONSISTENT;
    if c.ratio > high {
        format!(
            "the two halves of the views project {:.2} px apart (median; {:.2} px at worst), \
             {:.2} times what their uncertainties predict ({:.2} px), above {high}: the \
             model does not fit these views alike. Take more views, try the \
             rational_polynomial model for a wide lens, or check that the board is flat",
            c.observed.median, c.observed.worst, c.ratio, c.predicted.median
        )
    } else {
        format!(
            "the two halves of the views project {:.2} px apart (median), {:.2} times what \
             their uncertainties predict ({:.2} px), below {low}: the uncertainty is \
             cautious for these views (halves of few views scatter more than the whole)",
            c.observed.median, c.ratio, c.predicted.median
        )
    }
}

/// The rectified rig of a pair's rectification, with its σ.
pub fn rectified_rig(
    rectification: Option<&Rectification>,
    rig_std: Option<[f64; 2]>,
    board: &Target,
) -> Option<Rig> {
    let rig = rectification?.rig(board.unit()).ok()?;
    Some(
        rig_std
            .and_then(|[f, b]| rig.with_calibration_std(f, b).ok())
            .unwrap_or(rig),
    )
}
