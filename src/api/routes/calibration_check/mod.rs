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

use serde_json::Value;

use self::types::{CheckAnswer, CheckAnswers, CheckForm, CheckQuery, KnownDistance};
use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::extract::{QueryParams, decode_object};
use crate::api::images::board::read_board;
use crate::api::images::form::{Form, FormSpec};
use crate::api::images::output::{self, Disposition};
use crate::api::images::rig::{self, RIG_PARTS, RigParts};
use crate::api::images::{HeavyState, limits, work};
use crate::api::respond::Json;
use crate::api::wire::board_calibration::CalibrateOutput;
use stereo_core::physics::LengthUnit;
use stereo_core::pipeline::check as engine;
use stereo_core::pipeline::{Calibrated, Sent};
use stereo_core::vision::decode::DecodeLimits;

/// The most known points one check reads.
const MAX_KNOWN: usize = 10_000;

/// `POST /calibration/check`.
pub fn router() -> OpenApiRouter<HeavyState> {
    OpenApiRouter::new().routes(routes!(post_check))
}

/// The form's parts: the pairs' frames in order, the calibration's parts, and what was wrong.
pub struct CheckUpload {
    left: Vec<Bytes>,
    right: Vec<Bytes>,
    rig: RigParts,
    board: Option<Bytes>,
    known_distances: Option<Bytes>,
    problems: FieldErrors,
    admitted: work::Admitted,
    limits: DecodeLimits,
}

impl FromRequest<HeavyState> for CheckUpload {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &HeavyState) -> Result<Self, ApiError> {
        let known = [
            &["left", "right", "board", "known_distances"][..],
            &RIG_PARTS[..],
        ]
        .concat();
        let spec = FormSpec {
            known: &known,
            repeatable: &["left", "right"],
            example: "multipart/form-data: the pairs as repeated file parts and the \
                      calibration (curl -F left=@l0.png -F right=@r0.png -F left=@l1.png … \
                      -F calibration=@opencv.yml)",
        };
        let mut form = Form::read(req, state, spec).await?;
        let [left, right] = form.take_views();
        let mut upload = CheckUpload {
            left,
            right,
            rig: RigParts::default(),
            board: None,
            known_distances: None,
            problems: form.problems,
            admitted: form.admitted,
            limits: state.image_limits,
        };
        for (name, bytes) in form.parts {
            match name.as_str() {
                "board" => upload.board = Some(bytes),
                "known_distances" => upload.known_distances = Some(bytes),
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
    mut upload: CheckUpload,
) -> Result<Response, ApiError> {
    let mut problems = query_problems;
    problems.extend(std::mem::take(&mut upload.problems));
    let Judged {
        calibrated,
        size: (w, h),
        tolerance_px,
        known,
    } = judged(&query, &upload, problems)?;
    let CheckUpload {
        left,
        right,
        admitted,
        limits: allowed,
        ..
    } = upload;
    let output = query.output.unwrap_or_default();
    let warnings = calibrated.warnings.clone();
    let unit = calibrated.rig.unit().into();
    let encoded: usize = left.iter().chain(&right).map(Bytes::len).sum();
    // One pair at a time: its raw and rectified frames, their pyramids and smoothed copies,
    // and both cameras' float maps; with known points, their own smoothed copies and the
    // board's search too.
    let per_pixel = if known.is_empty() { 64 } else { 96 };
    let bytes = (w as usize) * (h as usize) * per_pixel + encoded;
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
        let check = engine::check_encoded(&calibrated, &frames, &known, settings, cancel)
            .map_err(|f| fault(f, allowed))?;
        Ok(answer(&check, output, unit, warnings))
    })
    .await?
}

/// What a request asks, judged.
struct Judged {
    calibrated: Calibrated,
    size: (u32, u32),
    tolerance_px: f64,
    known: engine::Known,
}

/// The form and the query judged, every fault named at once: the tolerance, the pairs'
/// counts and sizes, the calibration (which must describe the raw cameras of frames of that
/// size), the board and the known distances.
fn judged(
    query: &CheckQuery,
    upload: &CheckUpload,
    mut problems: FieldErrors,
) -> Result<Judged, ApiError> {
    let (left, right, parts) = (&upload.left, &upload.right, &upload.rig);
    let tolerance_px = query.tolerance_px.unwrap_or(engine::DEFAULT_TOLERANCE_PX);
    if !(tolerance_px.is_finite() && tolerance_px > 0.0 && tolerance_px <= 10.0) {
        problems.add(
            "tolerance_px",
            format!("must be a number of pixels above 0 and at most 10, not {tolerance_px}"),
        );
    }
    count_pairs([left, right], &mut problems)?;
    let size = limits::view_sizes(left, right, upload.limits, &mut problems)?;
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
    let board = upload
        .board
        .as_ref()
        .and_then(|b| read_board(Some(b), &mut problems));
    let unit = calibrated.as_ref().map(|c| c.file_unit);
    let points = upload
        .known_distances
        .as_ref()
        .map_or_else(Vec::new, |bytes| {
            known_distances(bytes, unit, left.len(), size, &mut problems)
        });
    match (calibrated, size, problems.is_empty()) {
        (Some(calibrated), Some(size), true) => Ok(Judged {
            calibrated,
            size,
            tolerance_px,
            known: engine::Known { board, points },
        }),
        _ => Err(problems.into_error()),
    }
}

/// The `known_distances` part: a JSON array of points, each named `known_distances[i].x`…
/// where at fault: a pair that was sent, a pixel inside its frames, a distance above 0; the
/// distances in the calibration's unit (`unit`).
fn known_distances(
    bytes: &Bytes,
    unit: Option<LengthUnit>,
    pairs: usize,
    size: Option<(u32, u32)>,
    problems: &mut FieldErrors,
) -> Vec<engine::KnownPoint> {
    const PART: &str = "known_distances";
    let Ok(Value::Array(items)) = serde_json::from_slice::<Value>(bytes) else {
        problems.add(
            PART,
            "must be a JSON array of points, such as [{\"pair\": 0, \"x\": 320, \"y\": 240, \
             \"distance\": 1500}]",
        );
        return Vec::new();
    };
    if items.len() > MAX_KNOWN {
        problems.add(
            PART,
            format!("has {} points; at most {MAX_KNOWN} are read", items.len()),
        );
        return Vec::new();
    }
    let sent = |n: usize, s: Option<(u32, u32)>| (n, s);
    items
        .into_iter()
        .enumerate()
        .filter_map(|(i, item)| known_point(i, item, unit, sent(pairs, size), problems))
        .collect()
}

/// One point of `known_distances` (the `i`-th), its faults named `known_distances[i].x`…;
/// `pairs` were sent, of frames of `size`.
fn known_point(
    i: usize,
    item: Value,
    unit: Option<LengthUnit>,
    (pairs, size): (usize, Option<(u32, u32)>),
    problems: &mut FieldErrors,
) -> Option<engine::KnownPoint> {
    let name = format!("known_distances[{i}]");
    let Value::Object(map) = item else {
        problems.add(&name, "must be an object {\"x\", \"y\", \"distance\"}");
        return None;
    };
    let (given, refused): (KnownDistance, _) = decode_object(map);
    let mut local = FieldErrors::from(refused.prefixed(&format!("{name}.")));
    let pair = given.pair.unwrap_or(0) as usize;
    if pair >= pairs {
        local.add(
            &format!("{name}.pair"),
            format!("is {pair}, but {pairs} pairs were sent"),
        );
    }
    let inside = |v: Option<f64>, side: Option<u32>| {
        v.is_some_and(|v| v.is_finite() && v >= 0.0 && side.is_none_or(|s| v <= f64::from(s) - 1.0))
    };
    for (member, v, side) in [
        ("x", given.x, size.map(|s| s.0)),
        ("y", given.y, size.map(|s| s.1)),
    ] {
        if !inside(v, side) && !local.has(&format!("{name}.{member}")) {
            local.add(
                &format!("{name}.{member}"),
                "is required: a pixel of the raw left frame",
            );
        }
    }
    let distance = given.distance.filter(|d| d.is_finite() && *d > 0.0);
    if distance.is_none() && !local.has(&format!("{name}.distance")) {
        local.add(
            &format!("{name}.distance"),
            "is required: the true distance, above 0",
        );
    }
    let ok = local.is_empty();
    problems.extend(local);
    let (x, y, d, to) = (given.x?, given.y?, distance?, unit?);
    let from = given.unit.map_or(to, LengthUnit::from);
    ok.then(|| engine::KnownPoint {
        pair,
        x,
        y,
        distance: from.convert(d, to),
    })
}

/// The pairs' counts: at least one, as many right frames as left ones, at most
/// [`engine::MAX_PAIRS`] (a 422 past it, as the schema's `maxItems` says).
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
        problems.add(
            "left",
            format!(
                "has {pairs} pairs; this server checks at most {} in one request",
                engine::MAX_PAIRS
            ),
        );
        return Err(std::mem::take(problems).into_error());
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
        engine::Fault::NothingKnown { board: true } => one(
            "board",
            "was found in both cameras of no pair: send pairs that show the whole board (a \
             ChArUco board: 6 corners or more) to both cameras"
                .to_owned(),
        ),
        engine::Fault::NothingKnown { board: false } => one(
            "known_distances",
            "matched in none of the pairs: give points on texture that both cameras see".to_owned(),
        ),
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
