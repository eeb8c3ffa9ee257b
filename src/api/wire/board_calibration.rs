//! The wire types of `/calibrate`: the query's options, the multipart form (documentation)
//! and the JSON summary; the `board` part's types are [`super::board`]'s.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::extract::QueryForm;
use crate::api::wire::de::{choice_members, request};
use crate::api::wire::openapi::{image_answers, named, text};
use crate::api::wire::rig::CalibratedRig;
use stereo_core::pipeline::calibrate as engine;

pub use crate::api::wire::board::{BoardSpec, BoardType, BoardUsed, DictionaryName};

/// The distortion model to fit, as ROS names them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum ModelChoice {
    /// OpenCV's default: k1 k2 p1 p2 k3.
    #[default]
    PlumbBob,
    /// OpenCV's `CALIB_RATIONAL_MODEL`: k1 k2 p1 p2 k3 k4 k5 k6.
    RationalPolynomial,
    /// Fisheye (OpenCV's `cv::fisheye`): k1 k2 k3 k4.
    Equidistant,
}

impl From<ModelChoice> for engine::Model {
    fn from(m: ModelChoice) -> Self {
        match m {
            ModelChoice::PlumbBob => engine::Model::PlumbBob,
            ModelChoice::RationalPolynomial => engine::Model::RationalPolynomial,
            ModelChoice::Equidistant => engine::Model::Equidistant,
        }
    }
}

/// What `/calibrate` answers.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
pub enum CalibrateOutput {
    /// JSON: the cameras, the pair, the rectification, the rig and how far to trust them.
    #[default]
    #[serde(rename = "summary")]
    Summary,
    /// OpenCV FileStorage YAML: M1 D1 M2 D2 R T E F R1 R2 P1 P2 Q, imageSize and the board.
    #[serde(rename = "opencv.yml")]
    OpencvYml,
    /// ROS `camera_calibration` YAML of the left camera.
    #[serde(rename = "ros-left.yaml")]
    RosLeftYaml,
    /// ROS `camera_calibration` YAML of the right camera.
    #[serde(rename = "ros-right.yaml")]
    RosRightYaml,
}

impl CalibrateOutput {
    pub fn name(self) -> &'static str {
        match self {
            CalibrateOutput::Summary => "summary",
            CalibrateOutput::OpencvYml => "opencv.yml",
            CalibrateOutput::RosLeftYaml => "ros-left.yaml",
            CalibrateOutput::RosRightYaml => "ros-right.yaml",
        }
    }
}

/// What moves when a calibration starts from an earlier one (`initial`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum RefineChoice {
    /// The lenses are held at the earlier calibration's (OpenCV's `CALIB_FIX_INTRINSIC`):
    /// only R and T are found again, from one view or more.
    #[default]
    Extrinsics,
    /// Every parameter is refined from the earlier ones, over 3 views or more.
    All,
}

choice_members!(ModelChoice, CalibrateOutput, RefineChoice);

request! {
    /// The options of `/calibrate`, in the query string.
    pub struct CalibrateQuery {
        /// The distortion model (default `plumb_bob`).
        model: ModelChoice,
        /// The rectification's free scaling, as `stereoRectify`'s: 0 keeps only valid pixels,
        /// 1 keeps every source pixel. Default 0.
        #[schema(minimum = 0.0, maximum = 1.0)]
        alpha: f64,
        /// What to answer (default `summary`).
        output: CalibrateOutput,
        /// Whether the summary lists each view's corners (for drawing). Default false.
        corners: bool,
        /// Whether to calibrate two disjoint halves of the views (split 8 ways) and report how
        /// far apart they project against their σ (`cross_validation`). Needs 6 views used.
        /// Default false.
        cross_validate: bool,
        /// The distance of the points `projection_uncertainty` is computed for, in the
        /// board's unit (default: the boards' median distance).
        #[schema(exclusive_minimum = 0.0)]
        uncertainty_distance: f64,
        /// With an `initial` part, what moves: `extrinsics` (the default: the lenses held,
        /// R and T found again from one view or more) or `all` (every parameter refined
        /// from the earlier ones, 3 views or more).
        refine: RefineChoice,
    }
}

impl QueryForm for CalibrateQuery {}

/// The `multipart/form-data` parts of `/calibrate` (for the documentation: the handler reads
/// the parts itself, to name each one in its errors).
#[derive(ToSchema)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
pub struct CalibrateForm {
    /// The left camera's images, one part per view, in order (PNG or JPEG, one size); at
    /// most 60.
    #[schema(value_type = Vec<String>, format = Binary, max_items = 60)]
    left: Vec<Vec<u8>>,
    /// The right camera's images, as many as `left`: the i-th left and the i-th right are one
    /// view. Without them, the left camera alone is calibrated.
    #[schema(value_type = Option<Vec<String>>, format = Binary, nullable = false, max_items = 60)]
    right: Option<Vec<Vec<u8>>>,
    /// The board, as JSON.
    board: BoardSpec,
    /// An earlier calibration of the pair to start from, as `/calibration` reads it (OpenCV,
    /// ROS, KITTI raw; the raw cameras, at the views' size). Its lenses are held (see
    /// `refine`), so that one view of the board finds R and T again.
    #[schema(value_type = Option<String>, format = Binary, nullable = false)]
    initial: Option<Vec<u8>>,
    /// The right camera's ROS `CameraInfo`, for a ROS `initial`.
    #[schema(value_type = Option<String>, format = Binary, nullable = false)]
    initial_right: Option<Vec<u8>>,
    /// The initial calibration's format, or `auto` (the default).
    #[schema(nullable = false)]
    initial_format: Option<String>,
    /// The unit of the initial calibration's lengths (for OpenCV files not written here).
    #[schema(nullable = false)]
    initial_unit: Option<String>,
    /// KITTI only: the camera pair, `2-3` (the default) or `0-1`.
    #[schema(nullable = false)]
    initial_cameras: Option<String>,
    /// The initial calibration's σ, when its file does not carry it:
    /// `{"focal_length_std_px": …, "baseline_std": …}`.
    #[schema(value_type = Option<Object>, nullable = false)]
    initial_rig: Option<String>,
}

/// How a pair calibrated again from `initial` moved since.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct SinceInitial {
    /// What moved: `extrinsics` (the lenses held at the initial's) or `all`.
    pub refined: RefineChoice,
    /// The right camera's turn relative to the left since then, degrees about x, y and z.
    pub rotation_deg: [f64; 3],
    /// The baseline then and now, in the board's unit.
    pub baseline_before: f64,
    pub baseline_after: f64,
}

/// What became of a view.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum ViewStatus {
    /// Its corners took part in the calibration.
    Used,
    /// The board was not found in one camera or both (`failed`).
    BoardNotFound,
    /// Its error was far above the other views' (more than 3 × their median and 0.5 px):
    /// left out.
    Outlier,
}

/// One view (pair) of the request, in order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ViewSummary {
    pub status: ViewStatus,
    /// Which cameras did not find the board: `left`, `right` or both.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub failed: Vec<String>,
    /// Why, for each camera that failed.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub reasons: Vec<String>,
    /// The view's RMS reprojection error in each camera, px (views used).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub rms_left: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub rms_right: Option<f64>,
    /// The board's tilt from facing the left camera, degrees (views used).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub tilt_deg: Option<f64>,
    /// How many of the board's corners each camera found in this view (a chessboard's all,
    /// a ChArUco board's those it shows; absent for a camera whose board was not found).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub corners_found_left: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub corners_found_right: Option<usize>,
    /// The corners found, in OpenCV's order, px (with `corners=true`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub corners_left: Option<Vec<[f64; 2]>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub corners_right: Option<Vec<[f64; 2]>>,
    /// A ChArUco board's corner ids (OpenCV's) of `corners_left` and `corners_right`, in
    /// their order (with `corners=true`).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub ids_left: Option<Vec<usize>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub ids_right: Option<Vec<usize>>,
    /// Each corner's residual in a view used, px (with `corners=true`): where the calibrated
    /// model projects the board's corner minus where it was found, `[dx, dy]` in the order
    /// of the corners.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub residuals_left: Option<Vec<[f64; 2]>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub residuals_right: Option<Vec<[f64; 2]>>,
}

/// The standard deviation of each of a camera's parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CameraStd {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// In the order of `distortion`.
    pub distortion: Vec<f64>,
}

/// One calibrated camera.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CameraSummary {
    /// K, row by row.
    pub camera_matrix: [[f64; 3]; 3],
    /// In OpenCV's order: k1 k2 p1 p2 k3 (plumb_bob), k1 k2 p1 p2 k3 k4 k5 k6
    /// (rational_polynomial), k1 k2 k3 k4 (equidistant).
    pub distortion: Vec<f64>,
    /// The RMS reprojection error of this camera over the views used, px.
    pub rms: f64,
    pub std: CameraStd,
}

/// Bouguet's rectification (OpenCV's `stereoRectify`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[allow(non_snake_case)]
pub struct RectificationSummary {
    pub R1: [[f64; 3]; 3],
    pub R2: [[f64; 3]; 3],
    pub P1: [[f64; 4]; 3],
    pub P2: [[f64; 4]; 3],
    pub Q: [[f64; 4]; 4],
    pub alpha: f64,
    /// The valid rectangle of each rectified image: x, y, width, height.
    pub roi_left: [i64; 4],
    pub roi_right: [i64; 4],
}

/// The rectified rig's standard deviations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RigStd {
    pub focal_length_px: f64,
    pub baseline: f64,
}

/// How much of one image the corners covered, as ROS `camera_calibration`'s bars: the range of
/// the corners' x and y as fractions of the image, and of the board's apparent size.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Coverage {
    /// [min, max] of the corners' x over the views used, as fractions of the width.
    pub x: [f64; 2],
    /// [min, max] of the corners' y, as fractions of the height.
    pub y: [f64; 2],
    /// The share of a 4 × 4 grid of cells over the image that hold a corner, 0–1.
    pub cells: f64,
}

/// One camera's projection σ over a 16 × 12 grid of cells across its image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ProjectionGrid {
    /// `grid[row][column]`: the σ (px, the worst direction's) of where a point at `distance`
    /// on the cell centre's ray projects; `null` where the lens cannot be inverted.
    pub grid: Vec<Vec<Option<f64>>>,
    pub median_px: f64,
    pub worst_px: f64,
    /// The median over the grid of the part the corners' noise explains (σ²·(JᵀJ)⁻¹), px.
    pub noise_median_px: f64,
    /// The median over the grid of the part the lens model cannot fit,
    /// √(max(0, σ² − σ_noise²)) cell by cell, px: a lean model on a real lens.
    pub model_median_px: f64,
    /// Whether the model's part dominates in this camera: `model_median_px` above 1.5 times
    /// `noise_median_px` (on an exact model the two come out about equal), from 6 views used
    /// or more (fewer scatter too little to tell the two parts apart).
    pub model_error_dominates: bool,
}

/// How precisely the calibration places a point at `distance` in each image (mrcal's
/// projection uncertainty): the point held fixed to the boards, a rigid move of the camera's
/// frame near the centre taken out (as mrcal's `projection_diff` compares calibrations), and
/// the σ from how the parameters scatter when the views change (over the views: the geometric
/// mean of the jackknife and the sandwich), so that what the lens model cannot fit counts
/// beside the corners' noise. On OpenCV's real photographs, calibrations from disjoint parts
/// of the views differ by 0.9–1.0 times what it predicts, where mrcal's own map predicts
/// 2.3–2.7 times too little (`scripts/evaluate/calibration`). High where no corners fell: take
/// views there.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ProjectionUncertaintySummary {
    /// The points' distance from the camera, in the board's unit (the boards' median
    /// distance unless `uncertainty_distance` is given).
    pub distance: f64,
    /// The left camera: its lens alone (it defines the rig's frame).
    pub left: ProjectionGrid,
    /// The right camera: its lens and the extrinsics, a point fixed in the left camera's frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub right: Option<ProjectionGrid>,
    /// Whether what the lens model cannot fit dominates in either camera (each camera's
    /// `model_error_dominates`). A warning then says what to do.
    pub model_error_dominates: bool,
}

/// Two calibrations from disjoint halves of the views, compared over both cameras' grids after
/// the rigid motion that best aligns them near the centre (as mrcal's `projection_diff`),
/// beside what their σ predict for the difference of two independent estimates,
/// √(σ_a² + σ_b²) (`cross_validate=true`). The views are split 8 ways (alternate views, the
/// first half against the second, then seeded shuffles) and each figure is the median over the
/// splits: one split is one draw of two calibrations' errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CrossValidationSummary {
    /// The median and largest distance between the halves' projections, px.
    pub median_px: f64,
    pub worst_px: f64,
    /// The median and largest √(σ_a² + σ_b²) of a cell, px.
    pub predicted_median_px: f64,
    pub predicted_worst_px: f64,
    /// Observed over predicted cell by cell, the median over the grid: 1 when the σ is true,
    /// below when cautious, above when optimistic.
    pub ratio: f64,
    /// The same over the grid's centre (within half the way to each edge) and over the rest.
    pub ratio_centre: f64,
    pub ratio_edge: f64,
    /// Whether `ratio` lies within 0.7–1.4. Above: the model does not fit the views alike
    /// (more views, a richer model such as `rational_polynomial`, a flatter board); below:
    /// the σ is cautious for these views.
    pub consistent: bool,
}

/// Where the corners fell, and how much the board tilted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CoverageSummary {
    pub left: Coverage,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub right: Option<Coverage>,
    /// [min, max] of the board's tilt from facing the left camera, degrees.
    pub tilt_deg: [f64; 2],
}

/// How long each stage took, in milliseconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CalibrateTimes {
    /// Decoding every image and finding its board (over the cores).
    pub detect: f64,
    /// The solves: first guesses, each camera's and the joint refinement.
    pub solve: f64,
    /// The rectification and the rig's uncertainty.
    pub rectify: f64,
}

/// A calibration, with how far to trust it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CalibrationSummary {
    pub image_width: u32,
    pub image_height: u32,
    pub model: ModelChoice,
    pub board: BoardUsed,
    pub views: Vec<ViewSummary>,
    /// The RMS reprojection error over every corner used, px.
    pub rms: f64,
    /// Whether the views determine the model: false when a focal length's σ is over 2 % of
    /// it, or the views repeat one pose (a warning then says which). A low RMS with
    /// `determined: false` fits these corners and says nothing about the lens. Over 20 % the
    /// calibration is refused (422).
    pub determined: bool,
    /// The mean distance of a corner from its partner's epipolar line, both ways, after
    /// undistortion, px (OpenCV's `stereo_calib.cpp` check). Pairs only.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub epipolar_error: Option<f64>,
    pub left: CameraSummary,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub right: Option<CameraSummary>,
    /// R of X_right = R·X_left + T, row by row.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub rotation: Option<[[f64; 3]; 3]>,
    /// T, in the board's unit.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub translation: Option<[f64; 3]>,
    /// σ of the rotation about x, y, z (degrees) and of T (board unit).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub rotation_std_deg: Option<[f64; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub translation_std: Option<[f64; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub essential: Option<[[f64; 3]; 3]>,
    /// F, scaled so that F[2][2] = 1.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub fundamental: Option<[[f64; 3]; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub rectification: Option<RectificationSummary>,
    /// The rectified rig in `/distance`'s members.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub rig: Option<CalibratedRig>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub rig_std: Option<RigStd>,
    pub coverage: CoverageSummary,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub projection_uncertainty: Option<ProjectionUncertaintySummary>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub cross_validation: Option<CrossValidationSummary>,
    /// How the pair moved since the `initial` calibration it started from.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub since_initial: Option<SinceInitial>,
    /// Things that make the calibration less trustworthy, and what to do.
    pub warnings: Vec<String>,
    pub timings_ms: CalibrateTimes,
}

image_answers! {
    /// `/calibrate`'s responses: the calibration in the `output` asked for, or the errors.
    pub struct CalibrateAnswers: "The calibration in the `output` asked for." {
        "application/json" => named::<CalibrationSummary>(),
        "application/x-yaml" => text(),
    }
}

/// The `multipart/form-data` parts of `/board` (for the documentation: the handler reads the
/// parts itself, to name each one in its errors).
#[derive(ToSchema)]
#[serde(deny_unknown_fields)]
#[allow(dead_code)]
pub struct BoardForm {
    /// The left camera's image (PNG or JPEG).
    #[schema(value_type = String, format = Binary)]
    left: Vec<u8>,
    /// The right camera's image of the same moment, of the same size; optional.
    #[schema(value_type = Option<String>, format = Binary, nullable = false)]
    right: Option<Vec<u8>>,
    /// The board, as JSON, as `/calibrate` takes it.
    board: BoardSpec,
}

/// One corner found: its id on the board and where it lies.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CornerSeen {
    /// The corner's id: OpenCV's order (row by row of inner corners, or the ChArUco id).
    pub id: usize,
    /// Its position in pixels (x right, y down; the centre of the top-left pixel is 0, 0).
    pub x: f64,
    pub y: f64,
}

/// What one image shows of the board.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct SightingSummary {
    /// Whether the board was found, as `/calibrate` would count the view.
    pub found: bool,
    /// Each corner found, refined as `/calibrate` refines them.
    pub corners: Vec<CornerSeen>,
    /// The convex hull of the corners found, `[x, y]` points in order around it: the part of
    /// the image the view covers.
    pub outline: Vec<[f64; 2]>,
    /// Why the board was not found.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub reason: Option<String>,
}

/// `/board`'s answer: the board in each image, and whether the pair would be a view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
#[schema(example = json!({
    "width": 640, "height": 480, "view": false,
    "left": {"found": true, "corners": [{"id": 0, "x": 212.4, "y": 160.9}],
             "outline": [[212.4, 160.9], [421.7, 158.2], [425.0, 301.5], [209.8, 304.1]]},
    "right": {"found": false, "corners": [], "outline": [],
              "reason": "no chessboard grid was found"},
    "warnings": []
}))]
pub struct BoardAnswer {
    /// The images' size, in pixels.
    pub width: u32,
    pub height: u32,
    /// Whether the pair (or the left image, sent alone) would count as a view of a
    /// calibration: the board found in each image.
    pub view: bool,
    pub left: SightingSummary,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub right: Option<SightingSummary>,
    /// What the decoder forgave.
    pub warnings: Vec<String>,
}

image_answers! {
    /// `/board`'s responses: the board in each image, or the errors.
    pub struct BoardAnswers: "The board in each image." {
        "application/json" => named::<BoardAnswer>(),
    }
}
