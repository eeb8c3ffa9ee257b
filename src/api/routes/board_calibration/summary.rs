//! `/calibrate`'s JSON summary: the fit, its report ([`stereo_core::calibration::boards::report`])
//! and the rectification mapped onto the wire types, and nothing computed here.

use std::time::Duration;

use super::Settings;
use super::checks::Checks;
use super::types::{
    self, BoardType, BoardUsed, CalibrateTimes, CalibrationSummary, CameraStd, CameraSummary,
    Coverage, CoverageSummary, CrossValidationSummary, ProjectionGrid,
    ProjectionUncertaintySummary, RectificationSummary, RigStd, ViewStatus, ViewSummary,
};
use crate::api::wire::params::Unit;
use crate::api::wire::rig::CalibratedRig;
use stereo_core::calibration::boards::charuco::CharucoBoard;
use stereo_core::calibration::boards::report::{self, Rectified};
use stereo_core::calibration::boards::{
    self, CameraFit, Corners, Fit, Target, ViewOutcome, cross_validation, uncertainty,
};
use stereo_core::camera::Model;
use stereo_core::numbers::round_to;

fn matrix3(m: &nalgebra::Matrix3<f64>) -> [[f64; 3]; 3] {
    std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]))
}

fn camera_summary(fit: &CameraFit) -> CameraSummary {
    CameraSummary {
        camera_matrix: matrix3(&fit.camera.matrix()),
        distortion: fit.camera.distortion().coefficients().to_vec(),
        rms: fit.rms,
        std: CameraStd {
            fx: fit.std[0],
            fy: fit.std[1],
            cx: fit.std[2],
            cy: fit.std[3],
            distortion: fit.std[4..].to_vec(),
        },
    }
}

/// How many corners a camera saw in a view.
fn count(corners: &Option<boards::Seen>) -> Option<usize> {
    corners.as_ref().map(|c| c.iter().flatten().count())
}

/// The corners a camera saw in a view, in the board's order.
fn seen(corners: &Option<boards::Seen>) -> Option<Vec<[f64; 2]>> {
    corners
        .as_ref()
        .map(|c| c.iter().flatten().copied().collect())
}

/// The ids of the corners a camera saw in a view (a ChArUco board's; a chessboard's are its
/// order, so they are left out).
fn ids(target: &Target, corners: &Option<boards::Seen>) -> Option<Vec<usize>> {
    let Target::Charuco(_) = target else {
        return None;
    };
    corners.as_ref().map(|c| {
        c.iter()
            .enumerate()
            .filter_map(|(id, p)| p.map(|_| id))
            .collect()
    })
}

/// The board as the summary gives it back.
fn board_used(target: &Target) -> BoardUsed {
    let (columns, rows) = target.inner_corners();
    let charuco = match target {
        Target::Charuco(b) => Some(b),
        Target::Chessboard(_) => None,
    };
    BoardUsed {
        board_type: if charuco.is_some() {
            BoardType::Charuco
        } else {
            BoardType::Chessboard
        },
        columns,
        rows,
        square_size: target.square_size(),
        unit: Unit::from(target.unit()),
        squares_x: charuco.map(|b| b.squares().0),
        squares_y: charuco.map(|b| b.squares().1),
        marker_size: charuco.map(CharucoBoard::marker_size),
        dictionary: charuco.map(|b| b.dictionary().into()),
        legacy: charuco.map(CharucoBoard::legacy),
    }
}

#[allow(clippy::too_many_arguments)]
pub fn summarize(
    fit: &Fit,
    views: &[Corners],
    reasons: &[[Option<String>; 2]],
    settings: &Settings,
    rectification: Option<&stereo_core::camera::Rectification>,
    rig_std: Option<[f64; 2]>,
    checks: &Checks,
    [detect, solve, rectify]: [Duration; 3],
) -> CalibrationSummary {
    let view_summaries: Vec<ViewSummary> = fit
        .views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let [l, r] = &reasons[i];
            let mut failed = Vec::new();
            let mut why = Vec::new();
            for (side, reason) in [("left", l), ("right", r)] {
                if let Some(reason) = reason {
                    failed.push(side.to_owned());
                    why.push(format!("{side}: {reason}"));
                }
            }
            let [residuals_left, residuals_right] = if settings.corners {
                fit.residuals(&settings.object, i, &views[i]).map(|r| {
                    r.map(|r| {
                        r.iter()
                            .map(|d| [round_to(d[0], 4), round_to(d[1], 4)])
                            .collect()
                    })
                })
            } else {
                [None, None]
            };
            ViewSummary {
                status: match v.status {
                    ViewOutcome::Used => ViewStatus::Used,
                    ViewOutcome::BoardNotFound => ViewStatus::BoardNotFound,
                    ViewOutcome::Outlier => ViewStatus::Outlier,
                },
                failed,
                reasons: why,
                rms_left: v.rms_left.map(|r| round_to(r, 4)),
                rms_right: v.rms_right.map(|r| round_to(r, 4)),
                tilt_deg: report::tilt_deg(v),
                corners_found_left: count(&views[i].left),
                corners_found_right: count(&views[i].right),
                corners_left: settings.corners.then(|| seen(&views[i].left)).flatten(),
                corners_right: settings.corners.then(|| seen(&views[i].right)).flatten(),
                ids_left: settings
                    .corners
                    .then(|| ids(&settings.board, &views[i].left))
                    .flatten(),
                ids_right: settings
                    .corners
                    .then(|| ids(&settings.board, &views[i].right))
                    .flatten(),
                residuals_left,
                residuals_right,
            }
        })
        .collect();
    let stereo = fit.right.is_some();
    let left = report::Coverage::of(views, fit, false, settings.size);
    let right = stereo.then(|| report::Coverage::of(views, fit, true, settings.size));
    let tilt_range = report::tilt_range(fit);
    let unit = settings.board.unit();
    // The rig carries its σ, so that it can be sent to `/distance` as it is.
    let rig = rectification.and_then(|r| r.rig(unit).ok()).map(|rig| {
        rig_std
            .and_then(|[f, b]| rig.with_calibration_std(f, b).ok())
            .unwrap_or(rig)
    });
    let rectified = match (stereo, rectification, &rig) {
        (false, _, _) => Rectified::Alone,
        (true, None, _) => Rectified::Failed,
        (true, Some(_), None) => Rectified::Vertical,
        (true, Some(_), Some(_)) => Rectified::Horizontal,
    };
    let mut warnings = report::warnings(
        fit,
        &checks.determination,
        [Some(&left), right.as_ref()],
        tilt_range,
        rectified,
    );
    warnings.extend(checks.cross_warning.clone());
    if let Some(u) = checks.uncertainty.as_ref() {
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
    }
    if let Some(c) = checks.cross.as_ref().filter(|c| !c.consistent()) {
        let (low, high) = cross_validation::CONSISTENT;
        warnings.push(if c.ratio > high {
            format!(
                "the two halves of the views project {:.2} px apart (median; {:.2} px at worst), \
                 {:.2} times what their uncertainties predict ({:.2} px), above {high}: the \
                 model does not fit these views alike. Take more views, try the \
                 rational_polynomial model for a wide lens, or check that the board is flat",
                c.median_px, c.worst_px, c.ratio, c.predicted_median_px
            )
        } else {
            format!(
                "the two halves of the views project {:.2} px apart (median), {:.2} times what \
                 their uncertainties predict ({:.2} px), below {low}: the uncertainty is \
                 cautious for these views (halves of few views scatter more than the whole)",
                c.median_px, c.ratio, c.predicted_median_px
            )
        });
    }
    let coverage = |c: report::Coverage| Coverage {
        x: c.x,
        y: c.y,
        cells: c.cells,
    };
    let cover = CoverageSummary {
        left: coverage(left),
        right: right.map(coverage),
        tilt_deg: tilt_range,
    };
    let e = fit.extrinsics;
    CalibrationSummary {
        image_width: settings.size.width,
        image_height: settings.size.height,
        model: match settings.model {
            Model::PlumbBob => types::ModelChoice::PlumbBob,
            Model::RationalPolynomial => types::ModelChoice::RationalPolynomial,
            Model::Equidistant => types::ModelChoice::Equidistant,
        },
        board: board_used(&settings.board),
        views: view_summaries,
        rms: fit.rms,
        determined: checks.determination.determined(),
        epipolar_error: fit.epipolar_error(views),
        left: camera_summary(&fit.left),
        right: fit.right.as_ref().map(camera_summary),
        rotation: e.map(|e| matrix3(e.rotation.matrix())),
        translation: e.map(|e| [e.translation.x, e.translation.y, e.translation.z]),
        rotation_std_deg: e.map(|e| e.rotation_std.map(f64::to_degrees)),
        translation_std: e.map(|e| e.translation_std),
        essential: fit.essential().map(|m| matrix3(&m)),
        fundamental: fit.fundamental().map(|m| matrix3(&m)),
        rectification: rectification.map(|r| RectificationSummary {
            R1: matrix3(&r.r1),
            R2: matrix3(&r.r2),
            P1: std::array::from_fn(|i| std::array::from_fn(|j| r.p1[(i, j)])),
            P2: std::array::from_fn(|i| std::array::from_fn(|j| r.p2[(i, j)])),
            Q: std::array::from_fn(|i| std::array::from_fn(|j| r.q[(i, j)])),
            alpha: r.alpha.unwrap_or_default(),
            roi_left: [
                r.roi_left.x,
                r.roi_left.y,
                r.roi_left.width,
                r.roi_left.height,
            ],
            roi_right: [
                r.roi_right.x,
                r.roi_right.y,
                r.roi_right.width,
                r.roi_right.height,
            ],
        }),
        rig: rig.as_ref().map(CalibratedRig::from),
        rig_std: rig.as_ref().and(rig_std).map(|[f, b]| RigStd {
            focal_length_px: f,
            baseline: b,
        }),
        coverage: cover,
        projection_uncertainty: checks
            .uncertainty
            .as_ref()
            .map(|u| ProjectionUncertaintySummary {
                distance: u.distance,
                left: projection_grid(&u.left),
                right: u.right.as_ref().map(projection_grid),
                model_error_dominates: u.left.model_error_dominates()
                    || u.right.as_ref().is_some_and(|g| g.model_error_dominates()),
            }),
        cross_validation: checks.cross.as_ref().map(|c| CrossValidationSummary {
            median_px: round_to(c.median_px, 4),
            worst_px: round_to(c.worst_px, 4),
            predicted_median_px: round_to(c.predicted_median_px, 4),
            predicted_worst_px: round_to(c.predicted_worst_px, 4),
            ratio: round_to(c.ratio, 3),
            ratio_centre: round_to(c.ratio_centre, 3),
            ratio_edge: round_to(c.ratio_edge, 3),
            consistent: c.consistent(),
        }),
        warnings,
        timings_ms: CalibrateTimes {
            detect: ms(detect),
            solve: ms(solve),
            rectify: ms(rectify),
        },
    }
}

fn projection_grid(g: &uncertainty::CameraGrid) -> ProjectionGrid {
    let rounded = |grid: &[Vec<Option<f64>>]| -> Vec<Vec<Option<f64>>> {
        grid.iter()
            .map(|row| row.iter().map(|v| v.map(|v| round_to(v, 4))).collect())
            .collect()
    };
    ProjectionGrid {
        grid: rounded(&g.grid),
        median_px: round_to(g.median_px, 4),
        worst_px: round_to(g.worst_px, 4),
        noise_median_px: round_to(g.noise_median_px, 4),
        model_median_px: round_to(g.model_median_px, 4),
        model_error_dominates: g.model_error_dominates(),
    }
}

pub fn ms(d: Duration) -> f64 {
    (d.as_secs_f64() * 1e4).round() / 10.0
}
