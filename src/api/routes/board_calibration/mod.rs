//! `/calibrate` (and `/board`, one image or pair's board, in [`sight`]): checkerboard views in (multipart, repeated `left` and `right` parts and a
//! `board`), a calibrated camera or stereo rig out, as a JSON summary with each parameter's
//! standard deviation or as OpenCV's and ROS's files. The engine is
//! [`stereo_core::pipeline::calibrate`]; this module reads the form, judges it against the
//! limits, runs the engine off the async runtime and writes its answer or names its faults.

mod board;
mod initial;
mod sight;
mod upload;
pub use crate::api::wire::board_calibration as types;

use axum::body::Bytes;
use axum::response::{IntoResponse, Response};
use utoipa_axum::{router::OpenApiRouter, routes};

use self::board::fault;
use self::types::{CalibrateAnswers, CalibrateForm, CalibrateOutput, CalibrateQuery};
use self::upload::{Upload, over_the_budget};
use crate::api::error::{ApiError, FieldErrors};
use crate::api::extract::QueryParams;
use crate::api::images::HeavyState;
use crate::api::images::board::read_board;
use crate::api::images::limits;
use crate::api::images::output::{self, Disposition, set_server_timing};
use crate::api::images::rig::RigParts;
use crate::api::images::work;
use crate::api::respond::Json;
use stereo_core::physics::LengthUnit;
use stereo_core::pipeline::calibrate as engine;

/// `POST /calibrate`, and `POST /board` (one image or pair's board, for a live view).
pub fn router() -> OpenApiRouter<HeavyState> {
    OpenApiRouter::new()
        .routes(routes!(post_calibrate))
        .routes(routes!(sight::post_board))
}

#[utoipa::path(
    post,
    path = "/calibrate",
    tag = "images",
    summary = "Calibrate a stereo rig (or one camera) from checkerboard views",
    description = "Finds a chessboard's inner corners in every view (ChESS corners labelled \
                   into a grid, ordered by the squares' colours, each refined by fitting a \
                   blurred corner model), calibrates each camera (Zhang's closed form, then \
                   Levenberg–Marquardt over intrinsics, distortion and poses), then both \
                   cameras and R, T together, leaving out views whose error is far above the \
                   others'. Answers each parameter's standard deviation, Bouguet's \
                   rectification and the rectified rig `/distance` takes, with its σ.\n\n\
                   Send `multipart/form-data`: `left` and `right` image parts, repeated, the \
                   i-th of each one view (only `left` parts calibrate one camera), and a \
                   `board` part, JSON `{\"columns\": 9, \"rows\": 6, \"square_size\": 25, \
                   \"unit\": \"mm\"}` (inner corners, as OpenCV's `patternSize`), or a \
                   ChArUco board in OpenCV's `CharucoBoard` terms, `{\"type\": \"charuco\", \
                   \"squares_x\": 8, \"squares_y\": 6, \"square_size\": 30, \"marker_size\": \
                   22, \"dictionary\": \"DICT_4X4_50\"}`, whose views count with the corners \
                   they show (6 or more, over two rows and two columns; OpenCV's ids).\n\n\
                   An `initial` part (an earlier calibration of the pair, as `/calibration` \
                   reads it, with `initial_right`, `initial_format`, `initial_unit` and \
                   `initial_rig` as the image routes' `calibration` parts) starts from it: \
                   with `refine=extrinsics` (the default) its lenses are held, as OpenCV's \
                   `CALIB_FIX_INTRINSIC` holds them, and R and T are found again from one \
                   view or more; with `refine=all` every parameter is refined from it. The \
                   summary's `since_initial` says how the pair turned since.\n\n\
                   Outputs (`output`): `summary` (JSON), `opencv.yml` (FileStorage with M1 D1 \
                   M2 D2 R T E F R1 R2 P1 P2 Q), `ros-left.yaml` and `ros-right.yaml` (ROS \
                   `camera_calibration`). `/calibration` reads all three.\n\n\
                   Limits: at most 60 views (a 422 past them); images up to 8192 px a side \
                   and the server's `--max-image-pixels` (34 megapixels by default), one \
                   size; fewer than 3 usable views (1 with `initial`) is a 422 naming each \
                   view and why.",
    params(CalibrateQuery),
    request_body(content = CalibrateForm, content_type = "multipart/form-data", description = "The views and the board."),
    responses(CalibrateAnswers)
)]
pub async fn post_calibrate(
    QueryParams(query, query_problems): QueryParams<CalibrateQuery>,
    upload: Upload,
) -> Result<Response, ApiError> {
    let Upload {
        left,
        right,
        board,
        initial,
        problems: form_problems,
        admitted,
        limits: allowed,
    } = upload;
    let mut problems = query_problems;
    problems.extend(form_problems);
    let output = query.output.unwrap_or_default();
    let settings = settings(
        &query,
        (board.as_ref(), &initial),
        [&left, &right],
        allowed,
        &mut problems,
    )?;
    let images = left.len() + right.len();
    let size = (settings.size.width, settings.size.height);
    let bytes = engine::bytes_needed(&settings.board, size, images);
    let too_large = |total| over_the_budget(size, "views need", "to calibrate", bytes, total);
    work::run_reserved(admitted, bytes, too_large, move |cancel, _| {
        let left: Vec<&[u8]> = left.iter().map(|b| b.as_ref()).collect();
        let right: Vec<&[u8]> = right.iter().map(|b| b.as_ref()).collect();
        let made =
            engine::calibrate(&left, &right, &settings, cancel).map_err(|f| fault(f, allowed))?;
        answer(&made, output)
    })
    .await?
}

/// The engine's settings from the query and the form, every fault named at once: the query's
/// members, the board's, the views' counts, sizes and limits (413 past the image limits),
/// and the earlier calibration's parts.
fn settings(
    query: &CalibrateQuery,
    (board, initial): (Option<&Bytes>, &RigParts),
    [left, right]: [&[Bytes]; 2],
    allowed: engine::DecodeLimits,
    problems: &mut FieldErrors,
) -> Result<engine::Settings, ApiError> {
    let alpha = problems.alpha(query.alpha).unwrap_or(engine::Alpha::ZERO);
    if let Some(d) = query.uncertainty_distance
        && !(d.is_finite() && d > 0.0)
    {
        problems.add(
            "uncertainty_distance",
            format!("must be a distance greater than 0, in the board's unit, not {d}"),
        );
    }
    let output = query.output.unwrap_or_default();
    let stereo = !right.is_empty();
    pair_output(output, stereo, problems);
    let board = read_board(board, problems);
    count_views([left, right], problems);
    let size = limits::view_sizes(left, right, allowed, problems)?;
    let unit = board
        .as_ref()
        .map_or(LengthUnit::Millimetre, engine::Target::unit);
    let asked = initial::Asked {
        refine: query.refine,
        model: query.model,
        stereo: stereo || left.is_empty(),
    };
    let initial = initial::read(initial, size, unit, &asked, problems);
    let (Some(board), Some((width, height))) = (board, size) else {
        return Err(std::mem::take(problems).into_error());
    };
    if !problems.is_empty() {
        return Err(std::mem::take(problems).into_error());
    }
    Ok(engine::Settings {
        board,
        model: query.model.unwrap_or_default().into(),
        alpha,
        size: engine::Size { width, height },
        limits: allowed,
        uncertainty: output == CalibrateOutput::Summary,
        corners: query.corners.unwrap_or(false),
        cross_validate: query.cross_validate.unwrap_or(false),
        uncertainty_distance: query.uncertainty_distance,
        initial,
    })
}

/// A file of the pair asked of one camera's views.
fn pair_output(output: CalibrateOutput, stereo: bool, problems: &mut FieldErrors) {
    if !stereo
        && matches!(
            output,
            CalibrateOutput::OpencvYml | CalibrateOutput::RosRightYaml
        )
    {
        problems.add(
            "output",
            format!(
                "{} needs a pair: send right images as well as left ones",
                output.name()
            ),
        );
    }
}

/// The views' counts: at least one left image, as many right images as left ones (or none),
/// at most [`engine::MAX_VIEWS`] (the form's `maxItems`).
fn count_views([left, right]: [&[Bytes]; 2], problems: &mut FieldErrors) {
    let stereo = !right.is_empty();
    if left.is_empty() {
        problems.add(
            "left",
            "is required: one image part per view (PNG or JPEG), repeated",
        );
    }
    if stereo && right.len() != left.len() {
        problems.add(
            "right",
            format!(
                "has {} images but left has {}: the i-th left and the i-th right are one view",
                right.len(),
                left.len()
            ),
        );
    }
    for (part, images) in [("left", left), ("right", right)] {
        if images.len() > engine::MAX_VIEWS {
            problems.add(
                part,
                format!(
                    "has {} views; this server calibrates at most {} in one request",
                    images.len(),
                    engine::MAX_VIEWS
                ),
            );
        }
    }
}

/// A calibration file answer.
fn yaml_file(text: String, output: CalibrateOutput) -> Response {
    let bytes = text.into_bytes();
    output::file(
        bytes,
        "application/x-yaml",
        output.name(),
        Disposition::Attachment,
    )
}

/// The calibration as the output asked for, with its stages in `Server-Timing` and the
/// decoder's notes (with a summary, all its warnings) in `Stereo-Warnings`.
fn answer(made: &engine::Calibration, output: CalibrateOutput) -> Result<Response, ApiError> {
    let yaml = |text: String| yaml_file(text, output);
    let (mut response, warnings) = match output {
        CalibrateOutput::Summary => {
            let summary = crate::api::wire::calibration_summary::summarize(made);
            let warnings = summary.warnings.clone();
            (Json(summary).into_response(), warnings)
        }
        CalibrateOutput::OpencvYml => {
            let allowed = made.settings().limits;
            let text = made.opencv_yml().map_err(|f| fault(f, allowed))?;
            (yaml(text), made.notes.clone())
        }
        CalibrateOutput::RosLeftYaml | CalibrateOutput::RosRightYaml => {
            let right = output == CalibrateOutput::RosRightYaml;
            (yaml(made.ros_yaml(right)), made.notes.clone())
        }
    };
    let [detect, solve, rectify] = made.times;
    set_server_timing(
        &mut response,
        &[("detect", detect), ("solve", solve), ("rectify", rectify)],
    );
    output::set_warnings(&mut response, &warnings);
    Ok(response)
}
