//! `/match`: a rectified pair (or a raw one with its calibration, rectified first) and points
//! (or boxes) in the left image in, each point's match in the right image with a status and a
//! confidence, and each box's robust distance, out. The
//! engine is [`stereo_core::vision::correspond`]; the distances are `/distance`'s own
//! ([`stereo_core::physics::measure`] through [`Measured`]), so the two never disagree.

pub use crate::api::wire::matching as types;

use std::time::Instant;

use axum::body::Bytes;
use axum::response::{IntoResponse, Response};
use serde::de::DeserializeOwned;
use serde_json::Value;
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{MatchForm, MatchPoint, MatchQuery, MatchRegion, MatchResponse};
use axum::extract::State;

use crate::api::error::{ApiError, FieldErrors};
use crate::api::extract::{QueryParams, decode_object};
use crate::api::images::HeavyState;
use crate::api::images::output::{self, set_server_timing};
use crate::api::images::{ImageForm, ImagePair, Job, Parts, job, rig, work};
use crate::api::respond::Json;
use crate::api::wire::openapi::ImageErrors;
use stereo_core::pipeline::{Answer, DepthJob, matches};
use stereo_core::vision::Settings;

/// `POST /match`.
pub fn router() -> OpenApiRouter<HeavyState> {
    OpenApiRouter::new().routes(routes!(post_match))
}

/// The most points one request may carry.
pub const MAX_POINTS: usize = 10_000;
/// The most regions one request may carry.
pub const MAX_REGIONS: usize = 1_000;

impl ImageForm for MatchForm {
    const PARTS: &'static [&'static str] = &["points", "regions"];
    const LISTS: &'static [&'static str] = &["points", "regions"];
}

#[utoipa::path(
    post,
    path = "/match",
    tag = "images",
    summary = "A point's match in the right image and its distance; a region's distance",
    description = "For each point of the left image, finds its match in the right image with \
                   the dense matcher of `/depth-map` (census costs, 8-path semi-global \
                   aggregation, sub-pixel fit, left-right check, uniqueness, speckle and median \
                   filters) and answers `x_right`, `disparity_px`, a `status` that says \
                   whether to trust it (`ok`, `occluded`, `ambiguous`, `textureless`, \
                   `out_of_range`, `inconsistent`, `outside_image`), a `confidence` in [0, 1], \
                   and, whenever it has a disparity, its σ `disparity_std_px` and the \
                   `/distance` answer for it (`distance`, `range`, `point`) with one error \
                   bar: σ_Z from that σ_d and the rig's σ_f and σ_B, as `distance_std` and as \
                   `depth_error` (with `relative_error`). For each box, answers the median \
                   depth of its valid pixels with the 10th and 90th percentiles and the \
                   median's σ.\n\n\
                   Raw frames: with a `calibration` of the raw cameras, `rectify=auto` (the \
                   default) rectifies the pair first; points and boxes are given in the raw \
                   left image, and each match also gives `x_rectified`, `y_rectified` (where \
                   it was matched) and `x_right_raw`, `y_right_raw` (the match on the raw \
                   right frame). A pair sent as rectified whose corners match a pixel or \
                   more off their rows gets a warning saying how to rectify it.\n\n\
                   Send `multipart/form-data` with parts `left` and `right` (PNG or JPEG, one \
                   size), `points` (a JSON array of `{\"x\", \"y\"}`, at most 10 000) and/or \
                   `regions` (a JSON array of `{\"x\", \"y\", \"width\", \"height\"}`, at most \
                   1 000), and `rig` (JSON with the members of `/distance`) or `calibration` \
                   (a calibration file, with the `calibration_*` parts of `/depth-map`). Only \
                   the image rows the points and boxes need are matched (with 32 rows of \
                   context each side) when they are a small part of the image.\n\n\
                   A point off the left image is that point's `status: outside_image`; a \
                   `points` or `regions` part that is not an array of such objects is a 422 \
                   naming the member, such as `points[3].x`. Limits as `/depth-map`.",
    params(MatchQuery),
    request_body(
        content = MatchForm,
        content_type = "multipart/form-data",
        description = "The rectified pair, the points and boxes, and the rig or a calibration \
                       file."
    ),
    responses(
        (status = 200, description = "Each point's match and each region's distance.",
         headers(("Server-Timing" = String, description = "Stage times in milliseconds.")),
         body = MatchResponse),
        ImageErrors
    )
)]
pub async fn post_match(
    State(state): State<HeavyState>,
    QueryParams(query, problems): QueryParams<MatchQuery>,
    mut pair: ImagePair<MatchForm>,
) -> Result<Response, ApiError> {
    let mut problems = pair.problems(problems);
    let settings = Settings {
        min_disparity: query.min_disparity,
        max_disparity: query.max_disparity,
        ..Settings::default()
    };
    let latlon = job::latlon_options(query.projection, query.latlon(), &mut problems);
    let asked = job::Asked {
        rectify: query.rectify,
        alpha: query.alpha,
        latlon,
        settings,
        prefix: "",
    };
    let planned = job::plan_pair(&mut pair, asked, &mut problems);
    let parts = &pair.parts;
    rig::require_rig(pair.sent, "for the distances", &mut problems);
    let points = list::<MatchPoint>(parts, "points", MAX_POINTS, &mut problems);
    let regions = list::<MatchRegion>(parts, "regions", MAX_REGIONS, &mut problems);
    let points = points.map(|ps| check_points(ps, &mut problems));
    let regions = regions.map(|rs| check_regions(rs, &mut problems));
    if parts.get("points").is_none() && parts.get("regions").is_none() {
        problems.add(
            "points",
            "is required unless regions are given: a JSON array of {\"x\", \"y\"} in the left \
             image",
        );
    }
    // Without a rig, `require_rig` (or the rig's own fault) has named it.
    let planned = planned.filter(|p| p.calibrated().is_some());
    let (Some(size), Some(planned)) = (pair.size, planned) else {
        return Err(problems.into_error());
    };
    if !problems.is_empty() {
        return Err(problems.into_error());
    }
    let need = job::need(planned.need(size, Answer::Matches));
    let points = points.unwrap_or_default();
    let regions = regions.unwrap_or_default();
    let cache = state.maps.clone();
    pair.run(need, move |work| {
        let planned = planned.with_maps(|raw| cache.get(raw).0);
        compute(work, &planned, &points, &regions)
    })
    .await?
}

/// A part holding a JSON array of objects `T` (or one object alone, as a generated client
/// sends a one-item array), each member's fault named `name[i].member`; `None` when the part
/// is absent or at fault.
fn list<T: DeserializeOwned + Default>(
    parts: &Parts,
    name: &str,
    cap: usize,
    problems: &mut FieldErrors,
) -> Option<Vec<(T, FieldErrors)>> {
    let items = items(parts, name, cap, problems)?;
    let mut decoded = Vec::with_capacity(items.len());
    for (index, item) in items.into_iter().enumerate() {
        let prefix = format!("{name}[{index}]");
        match item {
            Value::Object(map) => {
                let (value, refused) = decode_object::<T>(map);
                for e in refused.iter() {
                    problems.add_new(format!("{prefix}.{}", e.field), e.message.clone());
                }
                decoded.push((value, refused));
            }
            other => problems.add_new(
                prefix,
                format!(
                    "must be an object, got {}",
                    crate::api::member_messages::describe(&other)
                ),
            ),
        }
    }
    Some(decoded)
}

/// A part's JSON array (one object alone as a one-item array), within `cap` items and not
/// empty; `None` when the part is absent or at fault (named in `problems`).
fn items(parts: &Parts, name: &str, cap: usize, problems: &mut FieldErrors) -> Option<Vec<Value>> {
    let bytes: &Bytes = parts.get(name)?;
    let items = match serde_json::from_slice::<Value>(bytes) {
        Ok(Value::Array(items)) => items,
        Ok(Value::Object(one)) => vec![Value::Object(one)],
        Ok(other) => {
            problems.add(
                name,
                format!(
                    "must be a JSON array of objects, got {}",
                    crate::api::member_messages::describe(&other)
                ),
            );
            return None;
        }
        Err(e) => {
            problems.add(name, format!("must be a JSON array of objects: {e}"));
            return None;
        }
    };
    if items.is_empty() {
        problems.add(
            name,
            "must hold at least one item; leave the part out instead",
        );
        return None;
    }
    if items.len() > cap {
        problems.add(
            name,
            format!(
                "holds {} items; at most {cap} (the server's cap) are allowed in one request",
                items.len()
            ),
        );
        return None;
    }
    Some(items)
}

/// The points, each with both coordinates (a missing one is named).
fn check_points(
    points: Vec<(MatchPoint, FieldErrors)>,
    problems: &mut FieldErrors,
) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(points.len());
    for (index, (point, refused)) in points.into_iter().enumerate() {
        let mut need = |field: &str, value: Option<f64>| {
            if value.is_none() && !refused.has(field) {
                problems.add_new(
                    format!("points[{index}].{field}"),
                    "is required: a number of pixels",
                );
            }
            value
        };
        let x = need("x", point.x);
        let y = need("y", point.y);
        if let (Some(x), Some(y)) = (x, y) {
            out.push((x, y));
        }
    }
    out
}

/// The regions, each with its four members and a positive size (a fault is named).
fn check_regions(
    regions: Vec<(MatchRegion, FieldErrors)>,
    problems: &mut FieldErrors,
) -> Vec<[f64; 4]> {
    let mut out = Vec::with_capacity(regions.len());
    for (index, (region, refused)) in regions.into_iter().enumerate() {
        let mut need = |field: &str, value: Option<f64>, positive: bool| {
            let name = format!("regions[{index}].{field}");
            match value {
                None if !refused.has(field) => {
                    problems.add_new(name, "is required: a number of pixels");
                    None
                }
                Some(v) if positive && v <= 0.0 => {
                    problems.add_new(
                        name,
                        format!(
                            "must be greater than 0, got {}",
                            stereo_core::numbers::Num(v)
                        ),
                    );
                    None
                }
                other => other,
            }
        };
        let x = need("x", region.x, false);
        let y = need("y", region.y, false);
        let width = need("width", region.width, true);
        let height = need("height", region.height, true);
        if let (Some(x), Some(y), Some(width), Some(height)) = (x, y, width, height) {
            out.push([x, y, width, height]);
        }
    }
    out
}

/// Decodes, calls the engine's matches and answers, on a blocking thread.
fn compute(
    job: Job,
    planned: &DepthJob,
    points: &[(f64, f64)],
    regions: &[[f64; 4]],
) -> Result<Response, ApiError> {
    // The route runs the work only with a rig.
    let Some(request) = planned.matches_request() else {
        return Err(ApiError::Internal("matched without a rig".to_owned()));
    };
    let started = Instant::now();
    let (left, right) = work::decode_pair(job.parts, job.limits, [false, false])?;
    let decode = started.elapsed();
    let found = matches::matches(left, right, points, regions, request, job.cancel)
        .map_err(ApiError::from)?;
    let answer = MatchResponse::of(&found, &request.calibrated.rig, decode);
    let mut response = Json(&answer).into_response();
    output::set_warnings(&mut response, &answer.warnings);
    let (timings, rectify) = (found.timings, found.rectify);
    let started = Instant::now();
    drop(found);
    let mut after = Vec::with_capacity(2);
    after.extend(rectify.map(|t| ("rectify", t)));
    after.push(("drop", started.elapsed()));
    let [read, queue] = job.waited;
    set_server_timing(
        &mut response,
        &work::matcher_stages([read, queue, decode], &timings, &after),
    );
    Ok(response)
}
