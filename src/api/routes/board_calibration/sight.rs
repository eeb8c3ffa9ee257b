//! `POST /board`: one left image (and its right partner) in, the board found in each out,
//! with its corners and outline, as a live camera's views are judged before one is kept for
//! `/calibrate`. The engine is [`stereo_core::pipeline::calibrate::sight`].

use axum::body::Bytes;
use axum::response::{IntoResponse, Response};

use super::upload::{Upload, over_the_budget};
use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::images::board::read_board;
use crate::api::images::limits;
use crate::api::images::output::set_server_timing;
use crate::api::images::work;
use crate::api::respond::Json;
use crate::api::wire::board_calibration::{
    BoardAnswer, BoardAnswers, BoardForm, CornerSeen, SightingSummary,
};
use stereo_core::pipeline::calibrate as engine;

#[utoipa::path(
    post,
    path = "/board",
    tag = "images",
    summary = "Find a calibration board in one image or one pair",
    description = "Finds the board in a left image and, when given, its right partner, as \
                   `/calibrate` finds each view's: every corner with its id and position, \
                   the outline the corners span (their convex hull), or why the board was \
                   not found. `view` says whether the pair would count as a view of a \
                   calibration. The page's Live mode calls it on camera frames to draw the \
                   board and to keep only views that show it.\n\n\
                   Send `multipart/form-data`: one `left` image part, an optional `right` \
                   part of the same size, and the `board` part as `/calibrate` takes it.\n\n\
                   Limits: images up to 8192 px a side and the server's `--max-image-pixels`.",
    request_body(content = BoardForm, content_type = "multipart/form-data", description = "The images and the board."),
    responses(BoardAnswers)
)]
pub async fn post_board(upload: Upload) -> Result<Response, ApiError> {
    let Upload {
        left,
        right,
        board,
        mut problems,
        admitted,
        limits: allowed,
        ..
    } = upload.without_initial();
    let board = read_board(board.as_ref(), &mut problems);
    let left = one(left, "left", true, &mut problems);
    let right = one(right, "right", false, &mut problems);
    let size = sizes(left.as_ref(), right.as_ref(), allowed, &mut problems)?;
    let (Some(board), Some(left), Some(size)) = (board, left, size) else {
        return Err(problems.into_error());
    };
    if !problems.is_empty() {
        return Err(problems.into_error());
    }
    let images = 1 + usize::from(right.is_some());
    let bytes = engine::bytes_needed(&board, size, images);
    let too_large = |total| over_the_budget(size, "images need", "to search", bytes, total);
    work::run_reserved(admitted, bytes, too_large, move |_, _| {
        let started = std::time::Instant::now();
        let find = |part: &str, bytes: &Bytes| {
            engine::sight(bytes, &board, allowed)
                .map_err(|e| FieldError::new(part, limits::describe(&e, allowed)))
        };
        let (l, r) = rayon::join(
            || find("left", &left),
            || right.as_ref().map(|b| find("right", b)),
        );
        let (l, r) = match (l, r.transpose()) {
            (Ok(l), Ok(r)) => (l, r),
            (l, r) => {
                let errors = l.err().into_iter().chain(r.err()).collect();
                return Err(ApiError::Invalid(errors));
            }
        };
        let warnings: Vec<String> = [&l.note, &r.as_ref().and_then(|r| r.note.clone())]
            .into_iter()
            .flatten()
            .cloned()
            .collect();
        let answer = BoardAnswer {
            width: l.size.0,
            height: l.size.1,
            view: l.found() && r.as_ref().is_none_or(engine::Sighting::found),
            left: summary(&l),
            right: r.as_ref().map(summary),
            warnings,
        };
        let mut response = Json(answer).into_response();
        set_server_timing(&mut response, &[("detect", started.elapsed())]);
        Ok(response)
    })
    .await?
}

/// The one image a part holds: a second is named, and a missing `left` when it is required.
fn one(
    images: Vec<Bytes>,
    part: &str,
    required: bool,
    problems: &mut FieldErrors,
) -> Option<Bytes> {
    if images.len() > 1 {
        problems.add(
            part,
            format!(
                "has {} images: /board takes one {part} image (send the views to /calibrate \
                 together)",
                images.len()
            ),
        );
    }
    if images.is_empty() && required {
        problems.add(part, "is required: the left camera's image (PNG or JPEG)");
    }
    images.into_iter().next()
}

/// The images' size from their headers: past the limits a 413 naming the part, a right image
/// of another size named in `problems`.
fn sizes(
    left: Option<&Bytes>,
    right: Option<&Bytes>,
    allowed: engine::DecodeLimits,
    problems: &mut FieldErrors,
) -> Result<Option<(u32, u32)>, ApiError> {
    let mut oversized = Vec::new();
    let mut size_of = |part: &str, bytes: &Bytes, problems: &mut FieldErrors| {
        match stereo_core::vision::decode::dimensions(bytes) {
            Ok(size) => match limits::over_the_limits(size, allowed) {
                Some(message) => {
                    oversized.push(FieldError::new(part, message));
                    None
                }
                None => Some(size),
            },
            Err(e) => {
                problems.add(part, limits::describe(&e, allowed));
                None
            }
        }
    };
    let l = left.and_then(|b| size_of("left", b, problems));
    let r = right.and_then(|b| size_of("right", b, problems));
    if !oversized.is_empty() {
        return Err(ApiError::Oversized(oversized));
    }
    if let (Some(l), Some(r)) = (l, r)
        && l != r
    {
        problems.add(
            "right",
            format!(
                "is {} × {} pixels but left is {} × {}: the two images of a pair have one size",
                r.0, r.1, l.0, l.1
            ),
        );
    }
    Ok(l)
}

/// One image's sighting as the wire has it.
fn summary(seen: &engine::Sighting) -> SightingSummary {
    SightingSummary {
        found: seen.found(),
        corners: seen
            .corners
            .iter()
            .map(|&(id, [x, y])| CornerSeen { id, x, y })
            .collect(),
        outline: seen.outline.clone(),
        reason: seen.miss.clone(),
    }
}
