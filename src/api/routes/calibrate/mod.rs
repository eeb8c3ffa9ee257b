//! `/calibrate`: checkerboard views in (multipart, repeated `left` and `right` parts and a
//! `board`), a calibrated camera or stereo rig out, as a JSON summary with each parameter's
//! standard deviation or as OpenCV's and ROS's files. The engine is [`crate::calibrate`]; this
//! module reads the form, judges it against the limits, finds the boards over the cores off the
//! async runtime and writes the answer.

pub mod files;
pub mod types;

use std::time::{Duration, Instant};

use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::response::{IntoResponse, Response};
use rayon::prelude::*;
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{
    BoardSpec, BoardUsed, CalibrateForm, CalibrateOutput, CalibrateQuery, CalibrateTimes,
    CalibrationSummary, CameraStd, CameraSummary, Coverage, CoverageSummary, RectificationSummary,
    RigStd, ViewStatus, ViewSummary,
};
use crate::api::HeavyState;
use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::extract::{self, QueryParams};
use crate::api::images::form::{Form, FormSpec};
use crate::api::images::limits::{self, LIMITS, MAX_PIXELS, MAX_SIDE};
use crate::api::images::output::{self, Disposition, set_server_timing};
use crate::api::images::work;
use crate::api::respond::Json;
use crate::api::wire::openapi::ImageErrors;
use crate::api::wire::params::Unit;
use crate::api::wire::rig::CalibratedRig;
use crate::calibrate::corners::{Luma, find_board};
use crate::calibrate::{self, Board, CameraFit, Corners, Fit, FitFault, Status};
use crate::camera::{Alpha, Model, Options, Size};
use crate::physics::LengthUnit;
use crate::vision::decode;

/// The most views one request may carry.
pub const MAX_VIEWS: usize = 60;

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
                   \"unit\": \"mm\"}` (inner corners, as OpenCV's `patternSize`).\n\n\
                   Outputs (`output`): `summary` (JSON), `opencv.yml` (FileStorage with M1 D1 \
                   M2 D2 R T E F R1 R2 P1 P2 Q), `ros-left.yaml` and `ros-right.yaml` (ROS \
                   `camera_calibration`). `/calibration` reads all three.\n\n\
                   Limits: at most 60 views; images up to 8192 px a side and 12 megapixels, \
                   one size; fewer than 3 usable views is a 422 naming each view and why.",
    params(CalibrateQuery),
    request_body(
        content = CalibrateForm,
        content_type = "multipart/form-data",
        description = "The views and the board."
    ),
    responses(
        (status = 200, description = "The calibration in the `output` asked for.",
         headers(("Server-Timing" = String, description = "Stage times in milliseconds.")),
         content(
            (CalibrationSummary = "application/json"),
            (String = "application/x-yaml")
         )),
        ImageErrors
    )
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
    } = upload;
    let mut problems = query_problems;
    problems.extend(form_problems);
    let alpha = problems.alpha(query.alpha).unwrap_or(Alpha::ZERO);
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
    let size = image_sizes(&left, &right, &mut problems)?;
    let (Some(board), Some((width, height))) = (board, size) else {
        return Err(problems.into_error());
    };
    if !problems.is_empty() {
        return Err(problems.into_error());
    }
    let images = left.len() + right.len();
    let threads = rayon::current_num_threads().clamp(1, images);
    // Per image being worked on: its decoded buffer, the grey levels as f32 and u8, and the
    // corner detector's response maps.
    let per_image = (width as usize * height as usize).saturating_mul(10 + 4 + 1 + 16);
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
        board,
        model,
        alpha,
        output,
        corners: query.corners.unwrap_or(false),
        size: Size { width, height },
    };
    work::run_reserved(admitted, bytes, too_large, move |cancel, _| {
        compute(&left, &right, &settings, cancel)
    })
    .await?
}

/// What the work needs to know besides the images.
struct Settings {
    board: Board,
    model: Model,
    alpha: Alpha,
    output: CalibrateOutput,
    corners: bool,
    size: Size,
}

/// The `board` part read into a board, each fault named `board.<member>`.
fn read_board(bytes: Option<&Bytes>, problems: &mut FieldErrors) -> Option<Board> {
    let Some(bytes) = bytes else {
        problems.add(
            "board",
            "is required: JSON {\"columns\": 9, \"rows\": 6, \"square_size\": 25, \"unit\": \"mm\"} \
             (inner corners)",
        );
        return None;
    };
    let (spec, refused) = match extract::decode_json::<BoardSpec>(bytes) {
        Ok(read) => read,
        Err(ApiError::Malformed(e)) => {
            problems.add("board", e.message);
            return None;
        }
        Err(_) => {
            problems.add("board", "must be a JSON object");
            return None;
        }
    };
    let refused_any = !refused.is_empty();
    problems.extend(FieldErrors::from(refused.prefixed("board.")));
    let mut missing = false;
    for (name, present) in [
        ("board.columns", spec.columns.is_some()),
        ("board.rows", spec.rows.is_some()),
        ("board.square_size", spec.square_size.is_some()),
    ] {
        if !present && !problems.has(name) {
            problems.add(name, "is required");
            missing = true;
        }
    }
    if missing || refused_any {
        return None;
    }
    let unit: LengthUnit = spec.unit.unwrap_or_default().into();
    match Board::new(spec.columns?, spec.rows?, spec.square_size?, unit) {
        Ok(board) => Some(board),
        Err(faults) => {
            for fault in faults {
                problems.add(&format!("board.{}", fault.member.name()), fault.message);
            }
            None
        }
    }
}

/// Every image's size from its header: past the limits is a 413 naming the part, a size other
/// than the first view's is named in `problems`. Returns the first image's size.
fn image_sizes(
    left: &[Bytes],
    right: &[Bytes],
    problems: &mut FieldErrors,
) -> Result<Option<(u32, u32)>, ApiError> {
    let mut first: Option<(u32, u32)> = None;
    let mut oversized = Vec::new();
    for (side, images) in [("left", left), ("right", right)] {
        for (i, bytes) in images.iter().enumerate() {
            let name = format!("{side}[{i}]");
            match decode::dimensions(bytes) {
                Ok((w, h)) => {
                    if w > MAX_SIDE || h > MAX_SIDE || u64::from(w) * u64::from(h) > MAX_PIXELS {
                        oversized.push(FieldError::new(
                            name,
                            format!(
                                "is {w} × {h} pixels; this server takes at most {MAX_SIDE} \
                                 pixels a side and {} megapixels",
                                MAX_PIXELS / 1_000_000
                            ),
                        ));
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
                Err(e) => problems.add_new(name, limits::describe(&e)),
            }
        }
    }
    if !oversized.is_empty() {
        return Err(ApiError::Oversized(oversized));
    }
    Ok(first)
}

/// One image's board: decoded, found and refined; the outer error is the image's decoding.
type Found = Result<Result<Vec<[f64; 2]>, String>, FieldError>;

fn find(name: String, bytes: &Bytes, board: &Board) -> Found {
    let decoded = decode::decode(bytes, LIMITS, false)
        .map_err(|e| FieldError::new(name, limits::describe(&e)))?;
    let grey = decoded.grey;
    let luma = Luma::from_u16(grey.width, grey.height, &grey.data);
    Ok(find_board(&luma, board).map_err(|m| m.to_string()))
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
            (!cancel.load(std::sync::atomic::Ordering::Relaxed))
                .then(|| find(format!("{side}[{i}]"), bytes, &settings.board))
        })
        .collect();
    if found.iter().any(Option::is_none) {
        return Err(ApiError::Internal(
            "the calibration was abandoned".to_owned(),
        ));
    }
    let mut undecodable = Vec::new();
    let mut results: Vec<Result<Vec<[f64; 2]>, String>> = Vec::with_capacity(found.len());
    for f in found.into_iter().flatten() {
        match f {
            Ok(r) => results.push(r),
            Err(e) => {
                undecodable.push(e);
                results.push(Err(String::new()));
            }
        }
    }
    if !undecodable.is_empty() {
        return Err(ApiError::Invalid(undecodable));
    }
    let stereo = !right.is_empty();
    let n = left.len();
    let reason = |r: &Result<Vec<[f64; 2]>, String>| r.as_ref().err().cloned();
    let views: Vec<Corners> = (0..n)
        .map(|i| Corners {
            left: results[i].as_ref().ok().cloned(),
            right: if stereo {
                results[n + i].as_ref().ok().cloned()
            } else {
                None
            },
        })
        .collect();
    let reasons: Vec<[Option<String>; 2]> = (0..n)
        .map(|i| {
            [
                reason(&results[i]),
                if stereo {
                    reason(&results[n + i])
                } else {
                    None
                },
            ]
        })
        .collect();
    let detect = started.elapsed();
    let solving = Instant::now();
    let fit = calibrate::calibrate(
        &settings.board,
        settings.size,
        settings.model,
        &views,
        stereo,
    )
    .map_err(|fault| fit_error(&fault, &reasons, n))?;
    let solve = solving.elapsed();
    let rectifying = Instant::now();
    let options = Options {
        alpha: settings.alpha,
        ..Options::default()
    };
    let rectification = fit.rectify(options);
    let rig_std = fit.rig_std(options);
    let rectify = rectifying.elapsed();
    let unit = settings.board.unit();
    let mut response = match settings.output {
        CalibrateOutput::Summary => {
            let summary = summarize(
                &fit,
                &views,
                &reasons,
                settings,
                rectification.as_ref(),
                rig_std,
                [detect, solve, rectify],
            );
            Json(summary).into_response()
        }
        CalibrateOutput::OpencvYml => {
            let rect = rectification.ok_or_else(not_rectifiable)?;
            let text =
                files::opencv_yml(&fit, &settings.board, &rect).ok_or_else(not_rectifiable)?;
            yaml(text, "opencv.yml")
        }
        CalibrateOutput::RosLeftYaml | CalibrateOutput::RosRightYaml => {
            let right_side = settings.output == CalibrateOutput::RosRightYaml;
            let text = match (&rectification, fit.pair()) {
                (Some(r), Some(pair)) => {
                    let (camera, name, rot, p) = if right_side {
                        (pair.right, "right", r.r2, r.p2)
                    } else {
                        (pair.left, "left", r.r1, r.p1)
                    };
                    files::ros_yaml(&camera, name, &fit, &rot, &p, unit)
                }
                _ => {
                    // One camera: no rectification; R = I and P = [K | 0].
                    let camera = fit.left.camera;
                    let p = nalgebra::Matrix3x4::from_columns(&[
                        camera.matrix().column(0).into_owned(),
                        camera.matrix().column(1).into_owned(),
                        camera.matrix().column(2).into_owned(),
                        nalgebra::Vector3::zeros(),
                    ]);
                    files::ros_yaml(
                        &camera,
                        "left",
                        &fit,
                        &nalgebra::Matrix3::identity(),
                        &p,
                        unit,
                    )
                }
            };
            yaml(text, settings.output.name())
        }
    };
    set_server_timing(
        &mut response,
        &[("detect", detect), ("solve", solve), ("rectify", rectify)],
    );
    Ok(response)
}

fn ms(d: Duration) -> f64 {
    (d.as_secs_f64() * 1e4).round() / 10.0
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

const MIN_GOOD_VIEWS: usize = 10;
const MIN_SPAN: f64 = 0.6;
const MIN_TILT_DEG: f64 = 15.0;
const HIGH_RMS_PX: f64 = 1.0;

fn round(v: f64, digits: i32) -> f64 {
    let s = 10f64.powi(digits);
    (v * s).round() / s
}

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

fn coverage(views: &[Corners], fit: &Fit, right: bool, size: Size) -> Coverage {
    let (w, h) = (f64::from(size.width), f64::from(size.height));
    let mut x = [f64::INFINITY, f64::NEG_INFINITY];
    let mut y = [f64::INFINITY, f64::NEG_INFINITY];
    let mut cells = [false; 16];
    for (view, v) in views.iter().zip(&fit.views) {
        if v.status != Status::Used {
            continue;
        }
        let corners = if right { &view.right } else { &view.left };
        for c in corners.iter().flatten() {
            let (fx, fy) = ((c[0] / w).clamp(0.0, 1.0), (c[1] / h).clamp(0.0, 1.0));
            x = [x[0].min(fx), x[1].max(fx)];
            y = [y[0].min(fy), y[1].max(fy)];
            let cell = ((fy * 4.0).min(3.0) as usize) * 4 + (fx * 4.0).min(3.0) as usize;
            cells[cell] = true;
        }
    }
    Coverage {
        x: [round(x[0], 3), round(x[1], 3)],
        y: [round(y[0], 3), round(y[1], 3)],
        cells: cells.iter().filter(|&&c| c).count() as f64 / 16.0,
    }
}

#[allow(clippy::too_many_arguments)]
fn summarize(
    fit: &Fit,
    views: &[Corners],
    reasons: &[[Option<String>; 2]],
    settings: &Settings,
    rectification: Option<&crate::camera::Rectification>,
    rig_std: Option<[f64; 2]>,
    [detect, solve, rectify]: [Duration; 3],
) -> CalibrationSummary {
    let tilt = |v: &calibrate::ViewFit| {
        v.pose.map(|p| {
            let z = p.rotation * nalgebra::Vector3::z();
            round(z.z.abs().clamp(0.0, 1.0).acos().to_degrees(), 2)
        })
    };
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
                fit.residuals(&settings.board, i, &views[i]).map(|r| {
                    r.map(|r| r.iter().map(|d| [round(d[0], 4), round(d[1], 4)]).collect())
                })
            } else {
                [None, None]
            };
            ViewSummary {
                status: match v.status {
                    Status::Used => ViewStatus::Used,
                    Status::BoardNotFound => ViewStatus::BoardNotFound,
                    Status::Outlier => ViewStatus::Outlier,
                },
                failed,
                reasons: why,
                rms_left: v.rms_left.map(|r| round(r, 4)),
                rms_right: v.rms_right.map(|r| round(r, 4)),
                tilt_deg: tilt(v),
                corners_left: settings.corners.then(|| views[i].left.clone()).flatten(),
                corners_right: settings.corners.then(|| views[i].right.clone()).flatten(),
                residuals_left,
                residuals_right,
            }
        })
        .collect();
    let tilts: Vec<f64> = fit.views.iter().filter_map(tilt).collect();
    let tilt_range = [
        tilts.iter().copied().fold(f64::INFINITY, f64::min),
        tilts.iter().copied().fold(0.0, f64::max),
    ];
    let stereo = fit.right.is_some();
    let cover = CoverageSummary {
        left: coverage(views, fit, false, settings.size),
        right: stereo.then(|| coverage(views, fit, true, settings.size)),
        tilt_deg: tilt_range,
    };
    let used = fit
        .views
        .iter()
        .filter(|v| v.status == Status::Used)
        .count();
    let mut warnings = Vec::new();
    if used < MIN_GOOD_VIEWS {
        warnings.push(format!(
            "only {used} views were used: 10 to 20 views at different places and tilts give a \
             trustworthy calibration"
        ));
    }
    for (name, c) in [("left", Some(&cover.left)), ("right", cover.right.as_ref())] {
        if let Some(c) = c
            && (c.x[1] - c.x[0] < MIN_SPAN || c.y[1] - c.y[0] < MIN_SPAN)
        {
            warnings.push(format!(
                "the corners covered only x {:.2}–{:.2} and y {:.2}–{:.2} of the {name} image: \
                 show the board near the edges and corners too, where the distortion is \
                 strongest",
                c.x[0], c.x[1], c.y[0], c.y[1]
            ));
        }
    }
    if tilt_range[1] < MIN_TILT_DEG {
        warnings.push(format!(
            "the board never tilted more than {:.0}°: tilt it 20–45° in some views, or the \
             focal length is poorly determined",
            tilt_range[1]
        ));
    }
    if fit.rms > HIGH_RMS_PX {
        warnings.push(format!(
            "the RMS error is {:.2} px (a good calibration is below 0.5): check that the board is \
             flat, the images sharp and the board's size right",
            fit.rms
        ));
    }
    let outliers: Vec<String> = fit
        .views
        .iter()
        .enumerate()
        .filter(|(_, v)| v.status == Status::Outlier)
        .map(|(i, _)| i.to_string())
        .collect();
    if !outliers.is_empty() {
        warnings.push(format!(
            "views {} were left out: their error was far above the others'",
            outliers.join(", ")
        ));
    }
    let unit = settings.board.unit();
    // The rig carries its σ, so that it can be sent to `/distance` as it is.
    let rig = rectification.and_then(|r| r.rig(unit).ok()).map(|rig| {
        rig_std
            .and_then(|[f, b]| rig.with_calibration_std(f, b).ok())
            .unwrap_or(rig)
    });
    if stereo && rectification.is_none() {
        warnings.push(
            "the pair could not be rectified: the fitted distortion cannot be inverted over the \
             image (show the board near the image's corners so that the distortion is measured \
             there); no rectification or rig"
                .to_owned(),
        );
    } else if stereo && rig.is_none() {
        warnings.push(
            "the cameras are one above the other: no horizontal rig for /distance".to_owned(),
        );
    }
    let e = fit.extrinsics;
    CalibrationSummary {
        image_width: settings.size.width,
        image_height: settings.size.height,
        model: match settings.model {
            Model::PlumbBob => types::ModelChoice::PlumbBob,
            Model::RationalPolynomial => types::ModelChoice::RationalPolynomial,
            Model::Equidistant => types::ModelChoice::Equidistant,
        },
        board: BoardUsed {
            columns: settings.board.columns(),
            rows: settings.board.rows(),
            square_size: settings.board.square_size(),
            unit: Unit::from(unit),
        },
        views: view_summaries,
        rms: fit.rms,
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
        warnings,
        timings_ms: CalibrateTimes {
            detect: ms(detect),
            solve: ms(solve),
            rectify: ms(rectify),
        },
    }
}
