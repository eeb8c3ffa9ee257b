//! What a check answers: the rows before and after over the image, the correction with its
//! σ and what the frames cannot see, what the drift does to a distance, the known points'
//! distances, and the corrected calibration as OpenCV's and ROS's files.

use super::known::{self, Located};
use super::model::{Fitted, Model, Param};
use crate::calibration::files::{Raw, RigStd, opencv, ros};
use crate::physics::{LengthUnit, Rig};
use crate::pipeline::Calibrated;

/// The distances (metres) at which a drift's effect is told.
pub const EFFECT_AT_M: [f64; 2] = [1.0, 5.0];

/// A value and its standard deviation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    pub value: f64,
    pub std: f64,
}

/// The rows' offsets (right − left, px) over a region.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rows {
    pub matches: usize,
    pub mean_px: f64,
    pub rms_px: f64,
    /// The 95th percentile of the offsets' size.
    pub p95_px: f64,
}

impl Rows {
    fn of(offsets: &[f64]) -> Rows {
        let n = offsets.len();
        if n == 0 {
            return Rows {
                matches: 0,
                mean_px: f64::NAN,
                rms_px: f64::NAN,
                p95_px: f64::NAN,
            };
        }
        let mut sizes: Vec<f64> = offsets.iter().map(|o| o.abs()).collect();
        sizes.sort_by(f64::total_cmp);
        Rows {
            matches: n,
            mean_px: offsets.iter().sum::<f64>() / n as f64,
            rms_px: (offsets.iter().map(|o| o * o).sum::<f64>() / n as f64).sqrt(),
            p95_px: sizes[((n as f64 * 0.95).ceil() as usize).clamp(1, n) - 1],
        }
    }
}

/// The rows over the whole image and over a 3 × 3 grid of it (row-major from the top left).
#[derive(Debug, Clone, PartialEq)]
pub struct RowSpread {
    pub whole: Rows,
    pub grid: Vec<Rows>,
}

/// The grid [`RowSpread`] is told over.
pub const GRID: usize = 3;

impl RowSpread {
    pub(super) fn of(points: &[([f64; 2], f64)], size: (u32, u32)) -> RowSpread {
        let cell = |[x, y]: [f64; 2]| {
            let c = ((x / f64::from(size.0)) * GRID as f64).clamp(0.0, GRID as f64 - 1.0) as usize;
            let r = ((y / f64::from(size.1)) * GRID as f64).clamp(0.0, GRID as f64 - 1.0) as usize;
            r * GRID + c
        };
        let grid = (0..GRID * GRID)
            .map(|k| {
                let offsets: Vec<f64> = points
                    .iter()
                    .filter(|(p, _)| cell(*p) == k)
                    .map(|(_, o)| *o)
                    .collect();
                Rows::of(&offsets)
            })
            .collect();
        let all: Vec<f64> = points.iter().map(|(_, o)| *o).collect();
        RowSpread {
            whole: Rows::of(&all),
            grid,
        }
    }
}

/// What the drift does to a distance: the error of a distance measured with the calibration
/// as it was, at the centre of the image and the largest over it, beside the calibration's
/// own σ there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthEffect {
    /// The distance, in the rig's unit.
    pub distance: f64,
    /// What a distance measured at the image's centre reads less the truth.
    pub error_centre: f64,
    /// The largest error over the image, signed.
    pub error_largest: f64,
    /// σ of a distance from the calibration's own uncertainty (0 when unknown).
    pub calibration_std: f64,
}

/// Distance errors (measured less true, in the rig's unit) over the known points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Errors {
    pub mean: f64,
    pub rms: f64,
}

impl Errors {
    fn of(errors: &[(f64, f64)]) -> Errors {
        let n = errors.len().max(1) as f64;
        Errors {
            mean: errors.iter().map(|e| e.0).sum::<f64>() / n,
            rms: (errors.iter().map(|e| e.0 * e.0).sum::<f64>() / n).sqrt(),
        }
    }
}

/// The known points' distances through the calibration as it was and as corrected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DistanceCheck {
    pub points: usize,
    /// Their median true distance, in the rig's unit.
    pub median_distance: f64,
    pub before: Errors,
    pub after: Errors,
    /// σ of a distance there from the calibration's own uncertainty (0 when unknown).
    pub calibration_std: f64,
}

/// What explains the rows.
#[derive(Debug, Clone, PartialEq)]
pub struct Correction {
    /// The right camera's turn since it was calibrated, about its x, y and z axes (degrees),
    /// where the matches see it.
    pub rotation_deg: [Option<Estimate>; 3],
    /// Its fy over the calibrated fy.
    pub focal_ratio: Option<Estimate>,
    /// Its cy's move (px).
    pub cy_shift_px: Option<Estimate>,
    /// The baseline's length over the calibrated one (known distances at two depths or
    /// more tell it from a yaw).
    pub baseline_ratio: Option<Estimate>,
    /// What the frames cannot see, in sentences.
    pub unseen: Vec<String>,
}

/// A check's answer.
#[derive(Debug, Clone, PartialEq)]
pub struct Check {
    /// Whether the calibration holds: the drift moves no row by more than the tolerance (or
    /// by no more than its own 3σ).
    pub holds: bool,
    /// The matches found in each pair.
    pub matches: Vec<usize>,
    /// Matches left out of the fit (their rows far from every other's).
    pub outliers: usize,
    /// The matches' rows with the calibration as it was, and after the correction.
    pub before: RowSpread,
    pub after: RowSpread,
    /// The largest row the drift moves over the image (px), with its σ.
    pub largest_row_shift: Estimate,
    /// The largest disparity it moves (px): a turn about y's, seen with known distances.
    pub largest_disparity_shift: Estimate,
    pub tolerance_px: f64,
    pub correction: Correction,
    /// The drift's effect on distances (none when the baseline is in doubt).
    pub depth_effect: Vec<DepthEffect>,
    /// Why the calibration's baseline is in doubt: no rig has it (a unit typed wrong).
    pub baseline_doubt: Option<String>,
    /// The known points' distances before and after the correction.
    pub distance: Option<DistanceCheck>,
    /// The calibration corrected, with the σ it came with.
    pub corrected: Raw,
    pub unit: LengthUnit,
    pub rig_std: Option<RigStd>,
}

impl Check {
    /// The corrected calibration as OpenCV's FileStorage YAML.
    pub fn opencv_yml(&self) -> String {
        let c = &self.corrected;
        opencv::write(&opencv::StereoFile {
            size: c.size,
            pair: &c.pair,
            essential: c.pair.essential(),
            fundamental: c.pair.fundamental(),
            rectification: &c.rectification,
            target: None,
            unit: self.unit,
            rig_std: self.rig_std,
        })
    }

    /// The corrected calibration's left or right camera as ROS's `CameraInfo` YAML.
    pub fn ros_yaml(&self, right: bool) -> String {
        let c = &self.corrected;
        let r = &c.rectification;
        let (camera, name, rotation, projection) = if right {
            (&c.pair.right, "right", r.r2, r.p2)
        } else {
            (&c.pair.left, "left", r.r1, r.p1)
        };
        ros::write(&ros::CameraInfo {
            name,
            size: c.size,
            camera,
            rotation,
            projection,
            unit: self.unit,
            rig_std: self.rig_std,
        })
    }
}

/// The σ of the calibration a check carries into its corrected file: the rig's, in the
/// file's unit, when it has one.
pub(super) fn rig_std(rig: &Rig, unit: LengthUnit) -> Option<RigStd> {
    (rig.focal_std_px() > 0.0 || rig.baseline_std() > 0.0).then(|| RigStd {
        focal_px: rig.focal_std_px(),
        baseline: rig.unit().convert(rig.baseline_std(), unit),
    })
}

/// The known points' distance errors through the calibration as it was and as corrected, in
/// the rig's unit; `None` without known points.
pub(super) fn distances(
    located: &[Located],
    raw: &Raw,
    corrected: &Raw,
    calibrated: &Calibrated,
) -> Option<DistanceCheck> {
    if located.is_empty() {
        return None;
    }
    let (file, unit) = (calibrated.file_unit, calibrated.rig.unit());
    let errors = |through: &Raw| -> Vec<(f64, f64)> {
        located
            .iter()
            .filter_map(|k| known::distance_error(through, file, k))
            .map(|(e, z)| (file.convert(e, unit), file.convert(z, unit)))
            .collect()
    };
    let (before, after) = (errors(raw), errors(corrected));
    let mut truths: Vec<f64> = before.iter().map(|&(_, z)| z).collect();
    truths.sort_by(f64::total_cmp);
    let median = *truths.get(truths.len() / 2)?;
    Some(DistanceCheck {
        points: located.len(),
        median_distance: median,
        before: Errors::of(&before),
        after: Errors::of(&after),
        calibration_std: median * calibrated.rig.calibration_relative_error(),
    })
}

/// What a drift moves: the largest row and disparity over the image, and the distances.
pub(super) struct Shifts {
    pub rows: Estimate,
    pub disparity: Estimate,
    pub depth: Vec<DepthEffect>,
}

/// The largest row and column shifts over a 9 × 7 grid of the rectified image (a column
/// shift is a disparity error), and the disparity shifts (and a baseline's scale) made
/// distance errors at [`EFFECT_AT_M`].
pub(super) fn effects(model: &Model, fitted: &Fitted, rig: &Rig, (w, h): (u32, u32)) -> Shifts {
    let zero = Estimate {
        value: 0.0,
        std: 0.0,
    };
    let (mut rows, mut disparity) = (zero, zero);
    let mut columns: Vec<f64> = Vec::new();
    let (cx, cy) = (
        rig.cx().unwrap_or(f64::from(w) / 2.0),
        rig.cy().unwrap_or(f64::from(h) / 2.0),
    );
    let shift = |x: f64, y: f64| fitted.shift_at(model, model.raw_of([x, y])?);
    for j in 0..7 {
        for i in 0..9 {
            let (x, y) = (
                f64::from(w - 1) * f64::from(i) / 8.0,
                f64::from(h - 1) * f64::from(j) / 6.0,
            );
            let Some(([dx, dy], [sx, sy])) = shift(x, y) else {
                continue;
            };
            if dy.abs() > rows.value {
                rows = Estimate {
                    value: dy.abs(),
                    std: sy,
                };
            }
            if dx.abs() > disparity.value {
                disparity = Estimate {
                    value: dx.abs(),
                    std: sx,
                };
            }
            columns.push(dx);
        }
    }
    let centre = shift(cx, cy).map_or(0.0, |([dx, _], _)| dx);
    let widest = columns
        .iter()
        .copied()
        .fold(centre, |a, b| if b.abs() > a.abs() { b } else { a });
    let (fb, scale) = (rig.fb(), fitted.drift.baseline_scale);
    let depth = EFFECT_AT_M
        .iter()
        .map(|&metres| {
            let z = LengthUnit::Metre.convert(metres, rig.unit());
            // Read with the old calibration, a disparity Δx too large: Z_read − Z ≈
            // −Z²·Δx/(f·B); a baseline k longer than calibrated reads Z/(1 + k).
            let error = |dx: f64| -z * z * dx / fb - z * scale;
            DepthEffect {
                distance: z,
                error_centre: error(centre),
                error_largest: error(widest),
                calibration_std: z * rig.calibration_relative_error(),
            }
        })
        .collect();
    Shifts {
        rows,
        disparity,
        depth,
    }
}

/// The fit told as a correction, in degrees, with what the frames could not see.
pub(super) fn correction(fitted: &Fitted, dropped: &[(Param, Param)], known: bool) -> Correction {
    let degrees = |p| {
        fitted.estimate(p).map(|(v, s)| Estimate {
            value: v.to_degrees(),
            std: s.to_degrees(),
        })
    };
    let plain = |p| {
        fitted
            .estimate(p)
            .map(|(value, std)| Estimate { value, std })
    };
    let mut unseen = Vec::new();
    if !known {
        unseen.push(
            "a turn about y (yaw) or a change of baseline moves points along the rows only: \
             it offsets or scales every disparity, and needs a known distance to be seen (send \
             a board or known_distances)"
                .to_owned(),
        );
    }
    for &(lost, with) in dropped {
        let name = |p| match p {
            Param::AboutX => "a turn about x",
            Param::AboutY => "a turn about y",
            Param::AboutZ => "a turn about z",
            Param::FocalRatio => "the vertical focal ratio",
            Param::CyShift => "a shift of the principal point's row",
            Param::BaselineScale => "a change of baseline",
        };
        let (why, remedy) = if lost == Param::BaselineScale {
            (
                "at the known distances given, it offsets the disparities as",
                " (points at two distances or more tell them apart)",
            )
        } else {
            ("it moves these points as", "")
        };
        unseen.push(format!(
            "{}: {why} {} does; the frames cannot tell them apart, so the correction gives \
             it to {}{remedy}",
            name(lost),
            name(with),
            name(with)
        ));
    }
    Correction {
        rotation_deg: [Param::AboutX, Param::AboutY, Param::AboutZ].map(degrees),
        focal_ratio: plain(Param::FocalRatio).map(|e| Estimate {
            value: 1.0 + e.value,
            std: e.std,
        }),
        cy_shift_px: plain(Param::CyShift),
        baseline_ratio: plain(Param::BaselineScale).map(|e| Estimate {
            value: 1.0 + e.value,
            std: e.std,
        }),
        unseen,
    }
}
