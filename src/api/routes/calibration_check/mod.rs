//! `/calibration/check`: a calibration and raw pairs of any scene in (multipart, repeated
//! `left` and `right` parts beside the calibration's parts), whether the calibration still
//! holds out, with the drift that explains the rows and the corrected calibration as OpenCV's
//! and ROS's files. The engine is [`stereo_core::pipeline::check`]; this module reads the
//! form, judges it against the limits, runs the engine off the async runtime and writes its
//! answer or names its faults.

pub use crate::api::wire::calibration_check as types;

use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::response::{IntoResponse, Response};
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{CheckAnswer, CheckAnswers, CheckForm, CheckQuery};
use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::extract::QueryParams;
use crate::api::images::form::{Form, FormSpec};
use crate::api::images::output::{self, Disposition};
use crate::api::images::rig::{self, RIG_PARTS, RigParts};
use crate::api::images::{HeavyState, limits, work};
use crate::api::respond::Json;
use crate::api::wire::board_calibration::CalibrateOutput;
use stereo_core::pipeline::check as engine;
use stereo_core::pipeline::{Calibrated, Sent};
use stereo_core::vision::decode::DecodeLimits;

/// `POST /calibration/check`.
pub fn router() -> OpenApiRouter<HeavyState> {
    OpenApiRouter::new().routes(routes!(post_check))
}

/// The form's parts: the pairs' frames in order, the calibration's parts, and what was wrong.
pub struct CheckUpload {
    left: Vec<Bytes>,
    right: Vec<Bytes>,
    rig: RigParts,
    problems: FieldErrors,
    admitted: work::Admitted,
    limits: DecodeLimits,
}

impl FromRequest<HeavyState> for CheckUpload {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &HeavyState) -> Result<Self, ApiError> {
        let known = [&["left", "right"][..], &RIG_PARTS[..]].concat();
        let spec = FormSpec {
            known: &known,
            repeatable: &["left", "right"],
            example: "multipart/form-data: the pairs as repeated file parts and the \
                      calibration (curl -F left=@l0.png -F right=@r0.png -F left=@l1.png … \
                      -F calibration=@opencv.yml)",
        };
        let form = Form::read(req, state, spec).await?;
        let mut upload = CheckUpload {
            left: Vec::new(),
            right: Vec::new(),
            rig: RigParts::default(),
            problems: form.problems,
            admitted: form.admitted,
            limits: state.image_limits,
        };
        for (name, bytes) in form.parts {
            match name.as_str() {
                "left" => upload.left.push(bytes),
                "right" => upload.right.push(bytes),
                other => {
                    upload.rig.set(other, bytes);
                }
            }
        }
        Ok(upload)
    }
}

#[utoipa::path(
    post,
    path = "/calibration/check",
    tag = "calibration",
    summary = "Check that a calibration still holds, from raw pairs of any scene",
    description = "Rectifies each raw pair as the calibration rectifies it, matches sparse \
                   corners of the scene's own texture between the rectified frames (one a \
                   cell of a 16 × 12 grid, refined to a few hundredths of a pixel), and \
                   reads their rows: a calibration that holds has every match on its row. \
                   What the rows say is fitted as the right camera's drift since it was \
                   calibrated: its turn about x and z, and its vertical focal ratio and \
                   principal-point row where the matches can tell them apart, each with its \
                   σ. A turn about y (yaw) or a change of baseline moves points along the rows \
                   only, and needs a known distance: the answer says so.\n\n\
                   Send `multipart/form-data`: `left` and `right` parts, repeated, the i-th of \
                   each one pair (PNG or JPEG at the calibration's raw size; no board needed: \
                   any textured scene, better several), and the calibration as the image \
                   routes take it (`calibration`, with `calibration_format`, \
                   `right_calibration`, `calibration_unit`, `calibration_cameras`; a `rig` \
                   part beside it may carry its σ). The calibration must describe the raw \
                   cameras (K, D, R, T).\n\n\
                   Outputs (`output`): `summary` (JSON: `holds`, `rows` before and after, \
                   over a 3 × 3 grid too, `correction`, `depth_effect` at 1 m and 5 m), or \
                   the corrected calibration as `opencv.yml`, `ros-left.yaml` or \
                   `ros-right.yaml`, the σ it came with carried.\n\n\
                   Limits: at most 30 pairs; images up to 8192 px a side and the server's \
                   `--max-image-pixels`; fewer than 30 matches in all is a 422 saying how \
                   many each pair gave.",
    params(CheckQuery),
    request_body(content = CheckForm, content_type = "multipart/form-data", description = "The pairs and the calibration."),
    responses(CheckAnswers)
)]
pub async fn post_check(
    QueryParams(query, query_problems): QueryParams<CheckQuery>,
    upload: CheckUpload,
) -> Result<Response, ApiError> {
    let CheckUpload {
        left,
        right,
        rig: parts,
        problems: form_problems,
        admitted,
        limits: allowed,
    } = upload;
    let mut problems = query_problems;
    problems.extend(form_problems);
    let (calibrated, (w, h), tolerance_px) =
        judged(&query, &parts, [&left, &right], allowed, problems)?;
    let output = query.output.unwrap_or_default();
    let warnings = calibrated.warnings.clone();
    let unit = calibrated.rig.unit().into();
    let encoded: usize = left.iter().chain(&right).map(Bytes::len).sum();
    // One pair at a time: its raw and rectified frames, their pyramids and smoothed copies,
    // and both cameras' float maps.
    let bytes = (w as usize) * (h as usize) * 64 + encoded;
    let too_large = |total: usize| {
        vec![FieldError::new(
            "left",
            format!(
                "{w} × {h} pairs need {} MiB to check, more than the {} MiB this server has \
                 for image requests: send smaller images",
                bytes / (1024 * 1024),
                total / (1024 * 1024)
            ),
        )]
    };
    let settings = engine::Settings { tolerance_px };
    work::run_reserved(admitted, bytes, too_large, move |cancel, _| {
        let left: Vec<&[u8]> = left.iter().map(|b| b.as_ref()).collect();
        let right: Vec<&[u8]> = right.iter().map(|b| b.as_ref()).collect();
        let frames = engine::Encoded {
            left: &left,
            right: &right,
            limits: allowed,
        };
        let check = engine::check_encoded(&calibrated, &frames, settings, cancel)
            .map_err(|f| fault(f, allowed))?;
        Ok(answer(&check, output, unit, warnings))
    })
    .await?
}

/// The form and the query judged, every fault named at once: the tolerance, the pairs'
/// counts and sizes, and the calibration, which must describe the raw cameras of frames of
/// that size. The calibration, the frames' size and the tolerance.
fn judged(
    query: &CheckQuery,
    parts: &RigParts,
    [left, right]: [&[Bytes]; 2],
    allowed: DecodeLimits,
    mut problems: FieldErrors,
) -> Result<(Calibrated, (u32, u32), f64), ApiError> {
    let tolerance_px = query.tolerance_px.unwrap_or(engine::DEFAULT_TOLERANCE_PX);
    if !(tolerance_px.is_finite() && tolerance_px > 0.0 && tolerance_px <= 10.0) {
        problems.add(
            "tolerance_px",
            format!("must be a number of pixels above 0 and at most 10, not {tolerance_px}"),
        );
    }
    count_pairs([left, right], &mut problems)?;
    let size = limits::view_sizes(left, right, allowed, &mut problems)?;
    if parts.sent() != Sent::Calibration {
        problems.add(
            "calibration",
            "is required: the calibration to check, of the raw cameras (K, D, R, T), as \
             /calibration reads it",
        );
    }
    let (_, calibrated) = rig::parsed(parts, size, false, &mut problems);
    if let Some(c) = &calibrated
        && c.raw.is_none()
    {
        problems.add(
            "calibration",
            "describes rectified images only (a rig's f, B, cx, cy): the check rectifies the \
             raw frames, so it needs the raw cameras (K, D, R, T), as /calibrate's opencv.yml \
             or a ROS CameraInfo pair gives them",
        );
    }
    match (calibrated, size, problems.is_empty()) {
        (Some(calibrated), Some(size), true) => Ok((calibrated, size, tolerance_px)),
        _ => Err(problems.into_error()),
    }
}

/// The pairs' counts: at least one, as many right frames as left ones, at most
/// [`engine::MAX_PAIRS`] (413 past it).
fn count_pairs([left, right]: [&[Bytes]; 2], problems: &mut FieldErrors) -> Result<(), ApiError> {
    if left.is_empty() {
        problems.add(
            "left",
            "is required: the left frame of each pair (PNG or JPEG), repeated",
        );
    }
    if right.len() != left.len() {
        problems.add(
            "right",
            format!(
                "has {} frames but left has {}: the i-th left and the i-th right are one pair",
                right.len(),
                left.len()
            ),
        );
    }
    let pairs = left.len().max(right.len());
    if pairs > engine::MAX_PAIRS {
        return Err(ApiError::Oversized(vec![FieldError::new(
            "left",
            format!(
                "has {pairs} pairs; this server checks at most {} in one request",
                engine::MAX_PAIRS
            ),
        )]));
    }
    Ok(())
}

/// The check as the output asked for, with the calibration file's notes in
/// `Stereo-Warnings`.
fn answer(
    check: &engine::Check,
    output: CalibrateOutput,
    unit: crate::api::wire::params::Unit,
    warnings: Vec<String>,
) -> Response {
    let yaml = |text: String| {
        output::file(
            text.into_bytes(),
            "application/x-yaml",
            output.name(),
            Disposition::Attachment,
        )
    };
    let mut response = match output {
        CalibrateOutput::Summary => {
            Json(CheckAnswer::of(check, unit, warnings.clone())).into_response()
        }
        CalibrateOutput::OpencvYml => yaml(check.opencv_yml()),
        CalibrateOutput::RosLeftYaml => yaml(check.ros_yaml(false)),
        CalibrateOutput::RosRightYaml => yaml(check.ros_yaml(true)),
    };
    output::set_warnings(&mut response, &warnings);
    response
}

/// The cameras' frames sent the wrong way round: both parts named.
fn swapped_cameras(found: usize, swapped: usize) -> ApiError {
    let message = format!(
        "looks swapped: the first pair gave {found} matches as sent and {swapped} with its \
         points at negative disparities, as the left camera's frames sent as the right's give \
         them; send the left camera's frames as left"
    );
    ApiError::Invalid(
        ["left", "right"]
            .map(|side| FieldError::new(side, message.clone()))
            .into(),
    )
}

/// Too few matches: how many each pair gave, and what to send.
fn too_few(per_pair: &[usize]) -> String {
    let found: usize = per_pair.iter().sum();
    let each: Vec<String> = per_pair.iter().map(ToString::to_string).collect();
    format!(
        "the pairs gave {found} matches in all ({} a pair); the check needs {}: send frames \
         of a textured scene, in focus, that both cameras see",
        each.join(", "),
        engine::MIN_MATCHES
    )
}

/// An engine's refusal, naming the parts at fault.
fn fault(fault: engine::Fault, allowed: DecodeLimits) -> ApiError {
    let one =
        |field: &str, message: String| ApiError::Invalid(vec![FieldError::new(field, message)]);
    match fault {
        engine::Fault::NotRaw => one(
            "calibration",
            "describes cameras whose raw frames are already rectified: there is no \
             rectification to check"
                .to_owned(),
        ),
        engine::Fault::Vertical => one(
            "calibration",
            "describes cameras one above the other: the check reads the rows of side-by-side \
             cameras"
                .to_owned(),
        ),
        engine::Fault::Size {
            pair,
            size,
            expected,
        } => one(
            &format!("left[{pair}]"),
            format!(
                "is {} × {} pixels, but the calibration's raw frames are {} × {}: send the \
                 frames the calibrated cameras take, at their size",
                size.0, size.1, expected.0, expected.1
            ),
        ),
        engine::Fault::Swapped { found, swapped } => swapped_cameras(found, swapped),
        engine::Fault::TooFewMatches { per_pair } => one("left", too_few(&per_pair)),
        engine::Fault::Undetermined => one(
            "left",
            "the matches do not determine the drift: send pairs whose texture spreads over \
             the whole image"
                .to_owned(),
        ),
        engine::Fault::CannotRectify(why) => one(
            "calibration",
            format!("corrected, cannot be rectified: {why}"),
        ),
        engine::Fault::Undecodable(frames) => ApiError::Invalid(
            frames
                .into_iter()
                .map(|(name, e)| FieldError::new(name, limits::describe(&e, allowed)))
                .collect(),
        ),
        engine::Fault::Cancelled => ApiError::Internal("the check was abandoned".to_owned()),
    }
}
