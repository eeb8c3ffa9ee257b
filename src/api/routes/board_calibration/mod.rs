//! `/calibrate`: checkerboard views in (multipart, repeated `left` and `right` parts and a
//! `board`), a calibrated camera or stereo rig out, as a JSON summary with each parameter's
//! standard deviation or as OpenCV's and ROS's files. The engine is [`stereo_core::calibration::boards`]; this
//! module reads the form, judges it against the limits, finds the boards over the cores off the
//! async runtime and writes the answer.

mod board;
mod checks;
mod summary;
pub mod types;

use std::time::Instant;

use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::response::{IntoResponse, Response};
use rayon::prelude::*;
use utoipa_axum::{router::OpenApiRouter, routes};

use self::board::{charuco_mistake, read_board, size_mistake};
use self::checks::Checks;
use self::types::{CalibrateAnswers, CalibrateForm, CalibrateOutput, CalibrateQuery};
use crate::api::HeavyState;
use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::extract::QueryParams;
use crate::api::images::form::{Form, FormSpec};
use crate::api::images::limits;
use crate::api::images::output::{self, Disposition, set_server_timing};
use crate::api::images::work;
use crate::api::respond::Json;
use stereo_core::calibration::boards::TargetMiss;
use stereo_core::calibration::boards::corners::{Luma, Miss};
use stereo_core::calibration::boards::report::{
    Detections, Determination, agreed_charuco_mistake, agreed_other_size,
};
use stereo_core::calibration::boards::{self, FitFault, MAX_VIEWS, Target};
use stereo_core::calibration::files::{RigStd, opencv, ros};
use stereo_core::camera::{Alpha, Model, RectifyOptions, Size};
use stereo_core::vision::decode::{self, DecodeLimits};

/// `POST /calibrate`.
pub fn router() -> OpenApiRouter<HeavyState> {
    OpenApiRouter::new().routes(routes!(post_calibrate))
}

/// The form's parts: the views' images in order, the board, and what was wrong.
pub struct Upload {
    left: Vec<Bytes>,
    right: Vec<Bytes>,
    board: Option<Bytes>,
    problems: FieldErrors,
    admitted: work::Admitted,
    /// What the decoder takes (`--max-image-pixels`).
    limits: DecodeLimits,
}

impl FromRequest<HeavyState> for Upload {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &HeavyState) -> Result<Self, ApiError> {
        let spec = FormSpec {
            known: &["left", "right", "board"],
            repeatable: &["left", "right"],
            example: "multipart/form-data: the views as repeated file parts (curl -F \
                      left=@l0.png -F right=@r0.png -F left=@l1.png … -F \
                      board='{\"columns\":9,…}')",
        };
        let form = Form::read(req, state, spec).await?;
        let mut upload = Upload {
            left: Vec::new(),
            right: Vec::new(),
            board: None,
            problems: form.problems,
            admitted: form.admitted,
            limits: state.image_limits,
        };
        for (name, bytes) in form.parts {
            match name.as_str() {
                "left" => upload.left.push(bytes),
                "right" => upload.right.push(bytes),
                _ => upload.board = Some(bytes),
            }
        }
        Ok(upload)
    }
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
                   Outputs (`output`): `summary` (JSON), `opencv.yml` (FileStorage with M1 D1 \
                   M2 D2 R T E F R1 R2 P1 P2 Q), `ros-left.yaml` and `ros-right.yaml` (ROS \
                   `camera_calibration`). `/calibration` reads all three.\n\n\
                   Limits: at most 60 views; images up to 8192 px a side and the server's `--max-image-pixels` (34 megapixels by default), \
                   one size; fewer than 3 usable views is a 422 naming each view and why.",
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
        problems: form_problems,
        admitted,
        limits: allowed,
    } = upload;
    let mut problems = query_problems;
    problems.extend(form_problems);
    let alpha = problems.alpha(query.alpha).unwrap_or(Alpha::ZERO);
    if let Some(d) = query.uncertainty_distance
        && !(d.is_finite() && d > 0.0)
    {
        problems.add(
            "uncertainty_distance",
            format!("must be a distance greater than 0, in the board's unit, not {d}"),
        );
    }
    let output = query.output.unwrap_or_default();
    let model: Model = query.model.unwrap_or_default().into();
    let stereo = !right.is_empty();
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
    let board = read_board(board.as_ref(), &mut problems);
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
    if left.len().max(right.len()) > MAX_VIEWS {
        return Err(ApiError::Oversized(vec![FieldError::new(
            "left",
            format!(
                "has {} views; this server calibrates at most {MAX_VIEWS} in one request",
                left.len().max(right.len())
            ),
        )]));
    }
    let size = image_sizes(&left, &right, allowed, &mut problems)?;
    let (Some(board), Some((width, height))) = (board, size) else {
        return Err(problems.into_error());
    };
    if !problems.is_empty() {
        return Err(problems.into_error());
    }
    let images = left.len() + right.len();
    let threads = rayon::current_num_threads().clamp(1, images);
    // Per image being worked on: its decoded buffer, the grey levels as f32 and u8, and the
    // corner detector's response maps; for ChArUco markers, the sums of the grey levels, the
    // dark mask, the blobs' labels and the flood's stack instead of the response maps.
    let finding = match board {
        Target::Chessboard(_) => 16,
        Target::Charuco(_) => 8 + 1 + 4 + 8,
    };
    let per_image = (width as usize * height as usize).saturating_mul(10 + 4 + 1 + finding);
    let bytes = threads.saturating_mul(per_image);
    let too_large = |total: usize| {
        vec![FieldError::new(
            "left",
            format!(
                "{width} × {height} views need {} MiB to calibrate, more than the {} MiB this \
                 server has for image requests: send smaller images",
                bytes / (1024 * 1024),
                total / (1024 * 1024)
            ),
        )]
    };
    let settings = Settings {
        object: board.object_points(),
        board,
        model,
        alpha,
        output,
        corners: query.corners.unwrap_or(false),
        cross_validate: query.cross_validate.unwrap_or(false),
        uncertainty_distance: query.uncertainty_distance,
        size: Size { width, height },
        allowed,
    };
    work::run_reserved(admitted, bytes, too_large, move |cancel, _| {
        compute(&left, &right, &settings, cancel)
    })
    .await?
}

/// What the work needs to know besides the images.
struct Settings {
    board: Target,
    /// The board's corners on its plane, in the order the views give them.
    object: Vec<nalgebra::Vector3<f64>>,
    model: Model,
    alpha: Alpha,
    output: CalibrateOutput,
    corners: bool,
    cross_validate: bool,
    uncertainty_distance: Option<f64>,
    size: Size,
    allowed: DecodeLimits,
}

/// Every image's size from its header: past the limits is a 413 naming the part, a size other
/// than the first view's is named in `problems`. Returns the first image's size.
fn image_sizes(
    left: &[Bytes],
    right: &[Bytes],
    allowed: DecodeLimits,
    problems: &mut FieldErrors,
) -> Result<Option<(u32, u32)>, ApiError> {
    let mut first: Option<(u32, u32)> = None;
    let mut oversized = Vec::new();
    for (side, images) in [("left", left), ("right", right)] {
        for (i, bytes) in images.iter().enumerate() {
            let name = format!("{side}[{i}]");
            match decode::dimensions(bytes) {
                Ok((w, h)) => {
                    if let Some(message) = limits::over_the_limits((w, h), allowed) {
                        oversized.push(FieldError::new(name, message));
                        continue;
                    }
                    match first {
                        None => first = Some((w, h)),
                        Some((fw, fh)) if (fw, fh) != (w, h) => problems.add_new(
                            name,
                            format!(
                                "is {w} × {h} pixels but left[0] is {fw} × {fh}: every view \
                                 of a calibration has one size"
                            ),
                        ),
                        Some(_) => {}
                    }
                }
                Err(e) => problems.add_new(name, limits::describe(&e, allowed)),
            }
        }
    }
    if !oversized.is_empty() {
        return Err(ApiError::Oversized(oversized));
    }
    Ok(first)
}

/// One image's board: decoded, found and refined, with what the decoder forgave (named by
/// the part); the outer error is the image's decoding.
type Found = Result<(Result<boards::Seen, TargetMiss>, Option<String>), FieldError>;

fn find(name: String, bytes: &Bytes, board: &Target, allowed: DecodeLimits) -> Found {
    let decoded = match decode::decode(bytes, allowed, false) {
        Ok(decoded) => decoded,
        Err(e) => return Err(FieldError::new(name, limits::describe(&e, allowed))),
    };
    let note = decoded.note.map(|note| format!("{name} {note}"));
    let grey = decoded.grey;
    let luma = Luma::from_u16(grey.width, grey.height, &grey.data);
    Ok((board.find(&luma), note))
}

/// Finds the boards, calibrates and writes the answer, on a blocking thread.
fn compute(
    left: &[Bytes],
    right: &[Bytes],
    settings: &Settings,
    cancel: &std::sync::atomic::AtomicBool,
) -> Result<Response, ApiError> {
    let started = Instant::now();
    let jobs: Vec<(&str, usize, &Bytes)> = left
        .iter()
        .enumerate()
        .map(|(i, b)| ("left", i, b))
        .chain(right.iter().enumerate().map(|(i, b)| ("right", i, b)))
        .collect();
    let found: Vec<Option<Found>> = jobs
        .par_iter()
        .map(|&(side, i, bytes)| {
            (!cancel.load(std::sync::atomic::Ordering::Relaxed)).then(|| {
                find(
                    format!("{side}[{i}]"),
                    bytes,
                    &settings.board,
                    settings.allowed,
                )
            })
        })
        .collect();
    if found.iter().any(Option::is_none) {
        return Err(ApiError::Internal(
            "the calibration was abandoned".to_owned(),
        ));
    }
    let mut undecodable = Vec::new();
    let mut notes = Vec::new();
    let mut misses: Vec<Result<boards::Seen, TargetMiss>> = Vec::with_capacity(found.len());
    for f in found.into_iter().flatten() {
        match f {
            Ok((r, note)) => {
                misses.push(r);
                notes.extend(note);
            }
            Err(e) => {
                undecodable.push(e);
                misses.push(Err(TargetMiss::Chessboard(Miss::NoGrid)));
            }
        }
    }
    if !undecodable.is_empty() {
        return Err(ApiError::Invalid(undecodable));
    }
    let missed: Vec<Option<&TargetMiss>> = misses.iter().map(|r| r.as_ref().err()).collect();
    match &settings.board {
        Target::Chessboard(board) => {
            if let Some((size, showing)) = agreed_other_size(&missed, board) {
                return Err(size_mistake(board, size, showing, missed.len()));
            }
        }
        Target::Charuco(board) => {
            if let Some(mistake) = agreed_charuco_mistake(&missed) {
                return Err(charuco_mistake(board, &mistake, missed.len()));
            }
        }
    }
    let results: Vec<Result<boards::Seen, String>> = misses
        .into_iter()
        .map(|r| r.map_err(|m| m.to_string()))
        .collect();
    let stereo = !right.is_empty();
    let n = left.len();
    let Detections { views, reasons } = Detections::assemble(&results, stereo);
    let detect = started.elapsed();
    let solving = Instant::now();
    let fit = boards::calibrate(
        &settings.object,
        settings.size,
        settings.model,
        &views,
        stereo,
    )
    .map_err(|fault| fit_error(&fault, &reasons, n))?;
    let determination = Determination::of(&fit);
    if determination.refused() {
        let cause = determination.cause().unwrap_or_default();
        return Err(ApiError::Invalid(vec![FieldError::new(
            "left",
            format!("refused, {cause} (of {n} views sent)"),
        )]));
    }
    let solve = solving.elapsed();
    let rectifying = Instant::now();
    let options = RectifyOptions {
        alpha: settings.alpha,
        ..RectifyOptions::default()
    };
    let rectification = fit.rectify(options);
    let rig_std = fit.rig_std(options);
    let rectify = rectifying.elapsed();
    let unit = settings.board.unit();
    let mut response = match settings.output {
        CalibrateOutput::Summary => {
            let checks = Checks::of(&fit, &views, settings, stereo, determination);
            let mut summary = summary::summarize(
                &fit,
                &views,
                &reasons,
                settings,
                rectification.as_ref(),
                rig_std,
                &checks,
                [detect, solve, rectify],
            );
            summary.warnings.splice(0..0, notes.drain(..));
            notes.clone_from(&summary.warnings);
            Json(summary).into_response()
        }
        CalibrateOutput::OpencvYml => {
            let rect = rectification.as_ref().ok_or_else(not_rectifiable)?;
            let (Some(pair), Some(essential), Some(fundamental)) =
                (fit.pair(), fit.essential(), fit.fundamental())
            else {
                return Err(not_rectifiable());
            };
            let text = opencv::write(&opencv::StereoFile {
                size: fit.size,
                pair: &pair,
                essential,
                fundamental,
                rectification: rect,
                target: settings.board.recorded(),
                rig_std: rig_std.map(|[focal_px, baseline]| RigStd { focal_px, baseline }),
            });
            yaml(text, "opencv.yml")
        }
        CalibrateOutput::RosLeftYaml | CalibrateOutput::RosRightYaml => {
            let right_side = settings.output == CalibrateOutput::RosRightYaml;
            let text = match (&rectification, fit.pair()) {
                (Some(r), Some(pair)) => {
                    let (camera, name, rotation, projection) = if right_side {
                        (pair.right, "right", r.r2, r.p2)
                    } else {
                        (pair.left, "left", r.r1, r.p1)
                    };
                    ros::write(&ros::CameraInfo {
                        name,
                        size: fit.size,
                        camera: &camera,
                        rotation,
                        projection,
                        unit,
                        rig_std: rig_std.map(|[focal_px, baseline]| RigStd { focal_px, baseline }),
                    })
                }
                _ => ros::write(&ros::CameraInfo::alone(
                    "left",
                    fit.size,
                    &fit.left.camera,
                    unit,
                )),
            };
            yaml(text, settings.output.name())
        }
    };
    set_server_timing(
        &mut response,
        &[("detect", detect), ("solve", solve), ("rectify", rectify)],
    );
    output::set_warnings(&mut response, &notes);
    Ok(response)
}

fn not_rectifiable() -> ApiError {
    ApiError::Invalid(vec![FieldError::new(
        "right",
        "the calibrated pair cannot be rectified (the cameras do not overlap)",
    )])
}

fn yaml(text: String, name: &str) -> Response {
    output::file(
        text.into_bytes(),
        "application/x-yaml",
        name,
        Disposition::Attachment,
    )
}

/// A calibration that could not be made: a 422 naming each view that failed and why.
fn fit_error(fault: &FitFault, reasons: &[[Option<String>; 2]], n: usize) -> ApiError {
    let mut errors = Vec::new();
    for (i, [l, r]) in reasons.iter().enumerate() {
        for (side, reason) in [("left", l), ("right", r)] {
            if let Some(reason) = reason {
                errors.push(FieldError::new(
                    format!("{side}[{i}]"),
                    format!("board not found: {reason}"),
                ));
            }
        }
    }
    errors.push(FieldError::new(
        "left",
        format!("{fault} (of {n} views sent)"),
    ));
    ApiError::Invalid(errors)
}
