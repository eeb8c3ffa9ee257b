//! `/calibrate`'s JSON summary made from the engine's (the route's `of`, as every answer's is
//! in `wire`): the engine's calibration, its report
//! ([`stereo_core::pipeline::calibrate::report`]) and the rectification mapped onto the wire
//! types, and nothing computed here.

use std::time::Duration;

use crate::api::wire::board_calibration::{
    self, BoardType, BoardUsed, CalibrateTimes, CalibrationSummary, CameraStd, CameraSummary,
    Coverage, CoverageSummary, CrossValidationSummary, ProjectionGrid,
    ProjectionUncertaintySummary, RectificationSummary, RefineChoice, RigStd, SinceInitial,
    ViewStatus, ViewSummary,
};
use crate::api::wire::calibration::matrix3;
use crate::api::wire::params::Unit;
use crate::api::wire::rig::CalibratedRig;
use stereo_core::numbers::round_to;
use stereo_core::pipeline::calibrate as engine;

fn camera_summary(fit: &engine::CameraFit) -> CameraSummary {
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
fn count(corners: &Option<engine::Seen>) -> Option<usize> {
    corners.as_ref().map(|c| c.iter().flatten().count())
}

/// The corners a camera saw in a view, in the board's order.
fn seen(corners: &Option<engine::Seen>) -> Option<Vec<[f64; 2]>> {
    corners
        .as_ref()
        .map(|c| c.iter().flatten().copied().collect())
}

/// The ids of the corners a camera saw in a view (a ChArUco board's; a chessboard's are its
/// order, so they are left out).
fn ids(target: &engine::Target, corners: &Option<engine::Seen>) -> Option<Vec<usize>> {
    let engine::Target::Charuco(_) = target else {
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
fn board_used(target: &engine::Target) -> BoardUsed {
    let (columns, rows) = target.inner_corners();
    let charuco = match target {
        engine::Target::Charuco(b) => Some(b),
        engine::Target::Chessboard(_) => None,
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
        marker_size: charuco.map(engine::CharucoBoard::marker_size),
        dictionary: charuco.map(|b| b.dictionary().into()),
        legacy: charuco.map(engine::CharucoBoard::legacy),
    }
}

/// The summary of `made`: each view's outcome, both cameras with their σ, the pair's
/// extrinsics and rectification, the rig with its σ, and the report.
pub fn summarize(made: &engine::Calibration) -> CalibrationSummary {
    let (fit, views, settings) = (&made.fit, &made.views, made.settings());
    let report = &made.report;
    let residuals = report.residuals.as_ref();
    let view_summaries: Vec<ViewSummary> = fit
        .views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let [l, r] = &made.reasons[i];
            let mut failed = Vec::new();
            let mut why = Vec::new();
            for (side, reason) in [("left", l), ("right", r)] {
                if let Some(reason) = reason {
                    failed.push(side.to_owned());
                    why.push(format!("{side}: {reason}"));
                }
            }
            let rounded = |r: &Option<Vec<[f64; 2]>>| {
                r.as_ref().map(|r| {
                    r.iter()
                        .map(|d| [round_to(d[0], 4), round_to(d[1], 4)])
                        .collect()
                })
            };
            let [residuals_left, residuals_right] =
                residuals.map_or([None, None], |r| [rounded(&r[i][0]), rounded(&r[i][1])]);
            let corners = settings.corners;
            ViewSummary {
                status: match v.status {
                    engine::ViewOutcome::Used => ViewStatus::Used,
                    engine::ViewOutcome::BoardNotFound => ViewStatus::BoardNotFound,
                    engine::ViewOutcome::Outlier => ViewStatus::Outlier,
                },
                failed,
                reasons: why,
                rms_left: v.rms_left.map(|r| round_to(r, 4)),
                rms_right: v.rms_right.map(|r| round_to(r, 4)),
                tilt_deg: engine::tilt_deg(v),
                corners_found_left: count(&views[i].left),
                corners_found_right: count(&views[i].right),
                corners_left: corners.then(|| seen(&views[i].left)).flatten(),
                corners_right: corners.then(|| seen(&views[i].right)).flatten(),
                ids_left: corners
                    .then(|| ids(&settings.board, &views[i].left))
                    .flatten(),
                ids_right: corners
                    .then(|| ids(&settings.board, &views[i].right))
                    .flatten(),
                residuals_left,
                residuals_right,
            }
        })
        .collect();
    let coverage = |c: &engine::Coverage| Coverage {
        x: c.x,
        y: c.y,
        cells: c.cells,
    };
    let (left, right) = &report.coverage;
    let cover = CoverageSummary {
        left: coverage(left),
        right: right.as_ref().map(coverage),
        tilt_deg: report.tilt_range,
    };
    let rig = made.rig();
    let e = fit.extrinsics;
    let [detect, solve, rectify] = made.times;
    CalibrationSummary {
        image_width: settings.size.width,
        image_height: settings.size.height,
        model: match settings.model {
            engine::Model::PlumbBob => board_calibration::ModelChoice::PlumbBob,
            engine::Model::RationalPolynomial => board_calibration::ModelChoice::RationalPolynomial,
            engine::Model::Equidistant => board_calibration::ModelChoice::Equidistant,
        },
        board: board_used(&settings.board),
        views: view_summaries,
        rms: fit.rms,
        determined: report.determination.determined(),
        epipolar_error: fit.epipolar_error(views),
        left: camera_summary(&fit.left),
        right: fit.right.as_ref().map(camera_summary),
        rotation: e.map(|e| matrix3(e.rotation.matrix())),
        translation: e.map(|e| [e.translation.x, e.translation.y, e.translation.z]),
        rotation_std_deg: e.map(|e| e.rotation_std.map(f64::to_degrees)),
        translation_std: e.map(|e| e.translation_std),
        essential: fit.essential().map(|m| matrix3(&m)),
        fundamental: fit.fundamental().map(|m| matrix3(&m)),
        rectification: made.rectification.as_ref().map(|r| RectificationSummary {
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
        rig_std: rig.as_ref().and(made.rig_std).map(|[f, b]| RigStd {
            focal_length_px: f,
            baseline: b,
        }),
        coverage: cover,
        projection_uncertainty: report
            .uncertainty
            .as_ref()
            .map(|u| ProjectionUncertaintySummary {
                distance: u.distance,
                left: projection_grid(&u.left),
                right: u.right.as_ref().map(projection_grid),
                model_error_dominates: u.left.model_error_dominates()
                    || u.right.as_ref().is_some_and(|g| g.model_error_dominates()),
            }),
        cross_validation: report.cross.as_ref().map(|c| CrossValidationSummary {
            median_px: round_to(c.observed.median, 4),
            worst_px: round_to(c.observed.worst, 4),
            predicted_median_px: round_to(c.predicted.median, 4),
            predicted_worst_px: round_to(c.predicted.worst, 4),
            ratio: round_to(c.ratio, 3),
            ratio_centre: round_to(c.ratio_centre, 3),
            ratio_edge: round_to(c.ratio_edge, 3),
            consistent: c.consistent(),
        }),
        since_initial: made.since.map(|since| SinceInitial {
            refined: if fit.held {
                RefineChoice::Extrinsics
            } else {
                RefineChoice::All
            },
            rotation_deg: since.rotation_deg.map(|a| round_to(a, 5)),
            baseline_before: since.baseline[0],
            baseline_after: since.baseline[1],
        }),
        warnings: report.warnings.clone(),
        timings_ms: CalibrateTimes {
            detect: ms(detect),
            solve: ms(solve),
            rectify: ms(rectify),
        },
    }
}

fn projection_grid(g: &engine::uncertainty::CameraGrid) -> ProjectionGrid {
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
