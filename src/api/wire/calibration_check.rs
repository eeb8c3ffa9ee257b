//! The wire types of `/calibration/check`: the query's options, the multipart form
//! (documentation) and the JSON answer, made from the engine's [`engine::Check`].

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::extract::QueryForm;
use crate::api::wire::board_calibration::CalibrateOutput;
use crate::api::wire::de::request;
use crate::api::wire::images::with_calibration_options;
use crate::api::wire::openapi::{image_answers, named, text};
use crate::api::wire::params::Unit;
use stereo_core::numbers::Num;
use stereo_core::pipeline::check as engine;

request! {
    /// The options of `/calibration/check`, in the query string.
    pub struct CheckQuery {
        /// What to answer (default `summary`): the check as JSON, or the corrected
        /// calibration as `opencv.yml`, `ros-left.yaml` or `ros-right.yaml`.
        output: CalibrateOutput,
        /// How far (px) the drift found may move a row anywhere in the image and the
        /// calibration still hold. Default 0.2.
        #[schema(exclusive_minimum = 0.0, maximum = 10.0)]
        tolerance_px: f64,
    }
}

impl QueryForm for CheckQuery {}

with_calibration_options! {
    /// The `multipart/form-data` parts of `/calibration/check` (for the documentation: the
    /// handler reads the parts itself, to name each one in its errors).
    pub struct CheckForm {
        /// The left camera's raw frames of any textured scene, one part a pair, in order (PNG
        /// or JPEG, the calibration's raw size); at most 30.
        #[schema(value_type = Vec<String>, format = Binary, max_items = 30)]
        left: Vec<Vec<u8>>,
        /// The right camera's frames, as many as `left`: the i-th of each is one pair.
        #[schema(value_type = Vec<String>, format = Binary, max_items = 30)]
        right: Vec<Vec<u8>>,
        /// The calibration to check, as `/calibration` reads it (OpenCV, ROS, KITTI raw): it
        /// must describe the raw cameras.
        #[schema(value_type = String, format = Binary)]
        calibration: Vec<u8>,
        /// A board the pairs show (as `/calibrate` takes it): its corners, their pose from the
        /// left camera, give known distances, which see a turn about y and a baseline's change.
        #[schema(nullable = false)]
        board: Option<crate::api::wire::board_calibration::BoardSpec>,
        /// Points with their true distance, a JSON array: `[{"pair": 0, "x": 320, "y": 240,
        /// "distance": 1500}]`.
        #[schema(nullable = false, max_items = 10000)]
        known_distances: Option<Vec<KnownDistance>>,
        /// The calibration's σ, when its file does not carry it:
        /// `{"focal_length_std_px": …, "baseline_std": …}`.
        #[schema(value_type = Option<Object>, nullable = false)]
        rig: Option<String>,
    }
}

request! {
    /// A point of a pair's raw left image whose true distance is known (measured by tape,
    /// a laser, a total station): depth along the left camera's optical axis.
    #[schema(example = json!({"pair": 0, "x": 320, "y": 240, "distance": 1500}))]
    pub struct KnownDistance {
        /// The pair it is in, from 0 (default 0).
        #[schema(minimum = 0)]
        pair: u32,
        /// Its pixel in the raw left image.
        #[schema(required = true)]
        x: f64,
        #[schema(required = true)]
        y: f64,
        /// Its true distance, in `unit`.
        #[schema(required = true, exclusive_minimum = 0.0)]
        distance: f64,
        /// The unit of `distance` (default the calibration's).
        unit: Unit,
    }
}

/// A value and its standard deviation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Estimate {
    pub value: f64,
    pub std: f64,
}

impl From<engine::Estimate> for Estimate {
    fn from(e: engine::Estimate) -> Self {
        Estimate {
            value: e.value,
            std: e.std,
        }
    }
}

/// The matches' row offsets (right − left, px) over a region.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RowStats {
    pub matches: usize,
    /// Absent where the region has no match.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub mean: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub rms: Option<f64>,
    /// The 95th percentile of the offsets' size.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub p95: Option<f64>,
}

impl From<engine::Rows> for RowStats {
    fn from(r: engine::Rows) -> Self {
        let finite = |v: f64| v.is_finite().then_some(v);
        RowStats {
            matches: r.matches,
            mean: finite(r.mean_px),
            rms: finite(r.rms_px),
            p95: finite(r.p95_px),
        }
    }
}

/// One cell of the 3 × 3 grid over the rectified image.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RowsCell {
    /// 0 (left) to 2 (right).
    pub column: usize,
    /// 0 (top) to 2 (bottom).
    pub row: usize,
    pub before_px: RowStats,
    pub after_px: RowStats,
}

/// The matches' vertical disparity: with the calibration as it was, after the correction
/// (the fit's residuals), and both over a 3 × 3 grid of the rectified image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Rows {
    pub before_px: RowStats,
    pub after_px: RowStats,
    pub over_image: Vec<RowsCell>,
}

/// The right camera's turn since it was calibrated, degrees about its own axes; absent
/// where the frames cannot see it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Rotation {
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub x: Option<Estimate>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub y: Option<Estimate>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub z: Option<Estimate>,
}

/// What explains the rows, each with its σ, and what the frames cannot see.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Correction {
    pub rotation_deg: Rotation,
    /// The right camera's fy over the calibrated fy.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub focal_ratio: Option<Estimate>,
    /// The right camera's principal point moved down by this many rows.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub cy_shift_px: Option<Estimate>,
    /// The baseline's length over the calibrated one (known distances at two depths or more
    /// tell it from a turn about y).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub baseline_ratio: Option<Estimate>,
    /// What the frames cannot see, in sentences.
    pub unseen: Vec<String>,
}

/// What the drift does to a distance measured with the calibration as it was.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct DepthEffect {
    /// The distance, in `unit`.
    pub distance: f64,
    pub unit: Unit,
    /// The distance read at the image's centre less the truth, in `unit`.
    pub error_centre: f64,
    /// The largest error over the image, signed.
    pub error_largest: f64,
    /// σ of a distance there from the calibration's own uncertainty (0 when unknown).
    pub calibration_std: f64,
}

/// Distance errors (measured less true) over the known points, in the rig's unit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Errors {
    pub mean: f64,
    pub rms: f64,
}

/// The known points' distances (a board's corners, `known_distances`) measured through the
/// calibration as it was and as corrected, against their truth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct DistanceCheck {
    pub points: usize,
    /// Their median true distance, in `unit`.
    pub median_distance: f64,
    pub unit: Unit,
    pub before: Errors,
    pub after: Errors,
    /// σ of a distance there from the calibration's own uncertainty (0 when unknown).
    pub calibration_std: f64,
}

/// `/calibration/check`'s answer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CheckAnswer {
    /// Whether the calibration still holds: the drift found moves no row by more than
    /// `tolerance_px` (or by no more than its own 3σ).
    pub holds: bool,
    /// The verdict in a sentence.
    pub verdict: String,
    /// The matches found in each pair, in order.
    pub matches: Vec<usize>,
    /// Matches left out of the fit, their rows far from every other's.
    pub outliers: usize,
    pub rows: Rows,
    /// The largest row the drift found moves over the image (px), with its σ.
    pub largest_row_shift_px: Estimate,
    /// The largest disparity it moves (px): a turn about y's, seen with known distances.
    pub largest_disparity_shift_px: Estimate,
    pub tolerance_px: f64,
    pub correction: Correction,
    /// What the drift does to a distance at 1 m and 5 m.
    pub depth_effect: Vec<DepthEffect>,
    /// With a board or known distances: their distances before and after the correction.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub distance: Option<DistanceCheck>,
    /// The calibration file's notes.
    pub warnings: Vec<String>,
}

impl CheckAnswer {
    /// The answer of a check, with the file's `warnings` and distances in `unit`.
    pub fn of(check: &engine::Check, unit: Unit, warnings: Vec<String>) -> CheckAnswer {
        let over_image = check
            .before
            .grid
            .iter()
            .zip(&check.after.grid)
            .enumerate()
            .map(|(k, (b, a))| RowsCell {
                column: k % engine::GRID,
                row: k / engine::GRID,
                before_px: (*b).into(),
                after_px: (*a).into(),
            })
            .collect();
        let c = &check.correction;
        let [x, y, z] = c.rotation_deg.map(|e| e.map(Estimate::from));
        CheckAnswer {
            holds: check.holds,
            verdict: verdict(check),
            matches: check.matches.clone(),
            outliers: check.outliers,
            rows: Rows {
                before_px: check.before.whole.into(),
                after_px: check.after.whole.into(),
                over_image,
            },
            largest_row_shift_px: check.largest_row_shift.into(),
            largest_disparity_shift_px: check.largest_disparity_shift.into(),
            tolerance_px: check.tolerance_px,
            correction: Correction {
                rotation_deg: Rotation { x, y, z },
                focal_ratio: c.focal_ratio.map(Into::into),
                cy_shift_px: c.cy_shift_px.map(Into::into),
                baseline_ratio: c.baseline_ratio.map(Into::into),
                unseen: c.unseen.clone(),
            },
            depth_effect: check
                .depth_effect
                .iter()
                .map(|e| DepthEffect {
                    distance: e.distance,
                    unit,
                    error_centre: e.error_centre,
                    error_largest: e.error_largest,
                    calibration_std: e.calibration_std,
                })
                .collect(),
            distance: check.distance.map(|d| DistanceCheck {
                points: d.points,
                median_distance: d.median_distance,
                unit,
                before: Errors {
                    mean: d.before.mean,
                    rms: d.before.rms,
                },
                after: Errors {
                    mean: d.after.mean,
                    rms: d.after.rms,
                },
                calibration_std: d.calibration_std,
            }),
            warnings,
        }
    }
}

/// `v` with `decimals` decimals.
fn fixed(v: f64, decimals: usize) -> String {
    format!("{v:.decimals$}")
}

/// The verdict in words: the rows before and after, and what explains them.
fn verdict(check: &engine::Check) -> String {
    let said = rows_verdict(check);
    match &check.baseline_doubt {
        Some(doubt) => format!(
            "{said}. But the calibration's {doubt}: no depth effect is told until its unit is \
             right (calibration_unit)"
        ),
        None => said,
    }
}

/// What the rows say, in words.
fn rows_verdict(check: &engine::Check) -> String {
    let rows = |r: &engine::Rows| fixed(r.rms_px, 2);
    let shift = check.largest_row_shift;
    let moved = check.largest_disparity_shift;
    let largest = if shift.value >= moved.value {
        shift
    } else {
        moved
    };
    if check.holds && largest.value <= check.tolerance_px {
        return format!(
            "holds: the matches' rows agree to {} px RMS, and the drift found moves no row \
             or disparity more than {} px (the tolerance is {} px)",
            rows(&check.before.whole),
            fixed(largest.value, 2),
            Num(check.tolerance_px)
        );
    }
    if check.holds {
        // Past the tolerance but within its own 3σ: not told from the matches' noise.
        return format!(
            "holds as far as these frames tell: the matches' rows agree to {} px RMS; the \
             drift found moves a row or disparity up to {} ± {} px, past the {} px tolerance \
             but within its own 3σ, so it is not told from noise. More pairs, textured over \
             the whole image, tell it better",
            rows(&check.before.whole),
            fixed(largest.value, 2),
            fixed(largest.std, 2),
            Num(check.tolerance_px)
        );
    }
    let turns: Vec<String> = check
        .correction
        .rotation_deg
        .iter()
        .zip(["x", "y", "z"])
        .filter_map(|(e, axis)| {
            let e = (*e)?;
            (e.value.abs() > 3.0 * e.std).then(|| {
                // Decimals down to the σ's first digit, three at least.
                let d = (1.0 - e.std.max(1e-9).log10().floor()).clamp(3.0, 9.0) as usize;
                format!("{}° ± {}° about {axis}", fixed(e.value, d), fixed(e.std, d))
            })
        })
        .collect();
    let explained = if turns.is_empty() {
        "the right camera's focal length or principal point moved".to_owned()
    } else {
        format!("the right camera turned {}", turns.join(" and "))
    };
    let how = match check.depth_effect.first() {
        Some(e) if moved.value > shift.value => format!(
            "disparities up to {} px off (a distance of {} reads up to {} % off)",
            fixed(moved.value, 2),
            Num(e.distance),
            fixed(100.0 * e.error_largest.abs() / e.distance, 2)
        ),
        _ => format!(
            "rows {} px RMS off (up to {} px over the image)",
            rows(&check.before.whole),
            fixed(shift.value, 2)
        ),
    };
    format!(
        "drifted: {how}, past the {} px tolerance; {explained}, which leaves rows {} px RMS. \
         Ask for output=opencv.yml (or ros-left.yaml and ros-right.yaml) for the corrected \
         calibration",
        Num(check.tolerance_px),
        rows(&check.after.whole)
    )
}

image_answers! {
    /// `/calibration/check`'s responses: the check, or the corrected calibration.
    pub struct CheckAnswers: "The check, or the corrected calibration in the `output` asked for." {
        "application/json" => named::<CheckAnswer>(),
        "application/x-yaml" => text(),
    }
}
