//! `/match`: a rectified pair (or a raw one with its calibration, rectified first) and points
//! (or boxes) in the left image in, each point's match in the right image with a status and a
//! confidence, and each box's robust distance, out. The
//! engine is [`stereo_core::vision::correspond`]; the distances are `/distance`'s own
//! ([`stereo_core::physics::measure`] through [`Measured`]), so the two never disagree.

pub mod types;

use std::time::Instant;

use axum::body::Bytes;
use axum::response::{IntoResponse, Response};
use serde::de::DeserializeOwned;
use serde_json::Value;
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{
    MatchDistance, MatchForm, MatchPoint, MatchQuery, MatchRegion, MatchResponse, MatchStatus,
    PointMatch, RegionMatch, RegionStatus,
};
use crate::api::wire::images::StageTimes;
use axum::extract::State;
use stereo_core::numbers::round_to;

use crate::api::HeavyState;
use crate::api::error::{ApiError, FieldErrors};
use crate::api::extract::{QueryParams, decode_object};
use crate::api::images::maps::MapCache;
use crate::api::images::output::{self, set_server_timing};
use crate::api::images::raw;
use crate::api::images::work;
use crate::api::images::{ImageForm, ImagePair, Job, Parts, limits, rig};
use crate::api::respond::Json;
use crate::api::wire::measured::Measured;
use crate::api::wire::openapi::ImageErrors;
use crate::api::wire::rig::CalibratedRig;
use stereo_core::calibration::files::Raw;
use stereo_core::physics::{self, Correspondence, Rig};
use stereo_core::pipeline::depth;
use stereo_core::vision::correspond::{self, Found, Rect};
use stereo_core::vision::{self, Cancelled, Params, Settings};

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
    let raw = raw::plan(&mut pair, query.rectify, query.alpha, &mut problems);
    let parts = &pair.parts;
    rig::require_rig(parts, "for the distances", &mut problems);
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
    let ndisp = pair.rig.as_ref().and_then(|g| g.max_disparity);
    let settings = Settings {
        min_disparity: query.min_disparity,
        max_disparity: query.max_disparity,
        ..Settings::default()
    };
    let params = limits::params(settings, ndisp, &mut problems);
    let (Some((width, height)), true, Some(params)) = (pair.size, pair.rig.is_some(), params)
    else {
        return Err(problems.into_error());
    };
    if !problems.is_empty() {
        return Err(problems.into_error());
    }
    let need = raw::match_need(
        raw.as_deref(),
        (width, height),
        params.count(),
        bytes_needed,
    );
    let points = points.unwrap_or_default();
    let regions = regions.unwrap_or_default();
    let cache = state.maps.clone();
    pair.run(need, move |job| {
        compute(
            job,
            &params,
            &points,
            &regions,
            raw.as_deref().map(|r| (r, &*cache)),
        )
    })
    .await?
}

/// Where a raw left pixel lands in the rectified left image (`None` where the lens model
/// cannot take it there).
fn to_rectified(raw: &Raw, (x, y): (f64, f64)) -> Option<(f64, f64)> {
    let r = &raw.rectification;
    let k = r.p1.fixed_view::<3, 3>(0, 0).into_owned();
    raw.pair
        .left
        .undistort_to([x, y], &r.r1, &k)
        .map(|[x, y]| (x, y))
}

/// Where a rectified right pixel was seen in the raw right frame.
fn to_raw_right(raw: &Raw, x: f64, y: f64) -> Option<[f64; 2]> {
    let r = &raw.rectification;
    let k = r.p2.fixed_view::<3, 3>(0, 0).into_owned().try_inverse()?;
    let ray = r.r2.transpose() * (k * nalgebra::Vector3::new(x, y, 1.0));
    raw.pair.right.project(&ray)
}

/// The bytes a request holds at its peak: the decoded pair, then the matcher's as for the
/// whole image, and the map.
fn bytes_needed(w: usize, h: usize, count: usize) -> usize {
    let after = w
        .saturating_mul(h)
        .saturating_mul(8)
        .saturating_add(vision::bytes_needed(w, h, count));
    limits::decode_then(w, h, after)
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

/// The pixels a box `[x, y, width, height]` covers on a `w × h` image (at least one pixel
/// across and down), or `None` when it is wholly off the image.
fn rect(b: [f64; 4], w: usize, h: usize) -> Option<Rect> {
    let span = |start: f64, size: f64, n: usize| {
        let a = start.round();
        let b = (start + size).round().max(a + 1.0);
        let (a, b) = (a.clamp(0.0, n as f64), b.clamp(0.0, n as f64));
        (a < b).then_some((a as usize, b as usize))
    };
    let (x0, x1) = span(b[0], b[2], w)?;
    let (y0, y1) = span(b[1], b[3], h)?;
    Some(Rect { x0, y0, x1, y1 })
}

/// Decodes, matches and answers, on a blocking thread.
fn compute(
    job: Job,
    params: &Params,
    points: &[(f64, f64)],
    regions: &[[f64; 4]],
    raw: Option<(&Raw, &MapCache)>,
) -> Result<Response, ApiError> {
    // The route runs the work only with a rig.
    let Some(given) = job.rig else {
        return Err(ApiError::Internal("matched without a rig".to_owned()));
    };
    let cancel = job.cancel;
    let started = Instant::now();
    let (mut left, mut right) = work::decode_pair(job.parts, job.limits, [false, false])?;
    let decode_time = started.elapsed();
    let rectify_time = raw.map(|raw| raw::rectify_raw_pair(&mut left, &mut right, raw, false));
    let (w, h) = (left.grey.width, left.grey.height);
    // Points and boxes are clicked on the raw frame: matched where they land once rectified
    // (a box as the rectangle around its corners' images).
    let rectified: Vec<(f64, f64)> = match raw {
        Some((raw, _)) => points
            .iter()
            .map(|&p| to_rectified(raw, p).unwrap_or((f64::NAN, f64::NAN)))
            .collect(),
        None => points.to_vec(),
    };
    let boxes_rectified: Vec<[f64; 4]> = match raw {
        Some((raw, _)) => regions
            .iter()
            .map(|b| {
                let corners = [
                    (b[0], b[1]),
                    (b[0] + b[2], b[1]),
                    (b[0], b[1] + b[3]),
                    (b[0] + b[2], b[1] + b[3]),
                ]
                .map(|c| to_rectified(raw, c).unwrap_or((f64::NAN, f64::NAN)));
                let (x0, x1) = corners
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, z), c| {
                        (a.min(c.0), z.max(c.0))
                    });
                let (y0, y1) = corners
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, z), c| {
                        (a.min(c.1), z.max(c.1))
                    });
                [x0, y0, x1 - x0, y1 - y0]
            })
            .collect(),
        None => regions.to_vec(),
    };
    let boxes: Vec<Option<Rect>> = boxes_rectified
        .iter()
        .map(|&b| {
            if b.iter().all(|v| v.is_finite()) {
                rect(b, w, h)
            } else {
                None
            }
        })
        .collect();
    let wanted: Vec<Rect> = boxes.iter().flatten().copied().collect();
    let found =
        correspond::correspond(&left.grey, &right.grey, params, &rectified, &wanted, cancel)
            .map_err(|Cancelled| ApiError::Internal("cancelled".to_owned()))?;
    let rig = &given.rig;
    let matches: Vec<PointMatch> = points
        .iter()
        .zip(&rectified)
        .zip(&found.found)
        .map(|((&(x, y), &(xr, yr)), f)| {
            let Some((raw, _)) = raw else {
                return point_match(rig, x, y, f);
            };
            let mut answer = point_match(rig, xr, yr, f);
            answer.x = x;
            answer.y = y;
            if xr.is_finite() {
                answer.x_rectified = Some(round_to(xr, 3));
                answer.y_rectified = Some(round_to(yr, 3));
            }
            if let Some(xm) = answer.x_right
                && let Some([u, v]) = to_raw_right(raw, xm, yr)
            {
                answer.x_right_raw = Some(round_to(u, 3));
                answer.y_right_raw = Some(round_to(v, 3));
            }
            answer
        })
        .collect();
    let regions: Vec<RegionMatch> = regions
        .iter()
        .zip(&boxes)
        .map(|(&b, r)| region_match(rig, &found.map, b, *r))
        .collect();
    // A pair sent as rectified: do its corners lie on their rows?
    let rows = raw
        .is_none()
        .then(|| depth::row_check(&left, &right, params));
    let mut warnings = given.warnings.clone();
    warnings.extend(depth::decode_notes(&left, &right));
    warnings.extend(rows.and_then(|r| depth::unrectified_warning(None, r)));
    let ms = |d: std::time::Duration| (d.as_secs_f64() * 1e4).round() / 10.0;
    let t = found.timings;
    let answer = MatchResponse {
        width: w,
        height: h,
        min_disparity: params.min_disparity(),
        max_disparity: params.max_disparity(),
        unit: CalibratedRig::from(&given.rig).unit,
        ok: matches
            .iter()
            .filter(|m| m.status == MatchStatus::Ok)
            .count(),
        matches,
        regions,
        rig: CalibratedRig::from(&given.rig),
        rows_matched: found.rows_matched,
        rectified: raw.is_some(),
        timings_ms: StageTimes {
            decode: ms(decode_time),
            cost: ms(t.cost),
            aggregate: ms(t.aggregate),
            refine: ms(t.refine),
            rectify: rectify_time.map(ms),
        },
        warnings,
    };
    let said = answer.warnings.clone();
    let mut response = Json(answer).into_response();
    output::set_warnings(&mut response, &said);
    let started = Instant::now();
    drop((left, right, found));
    let drop_time = started.elapsed();
    let [read, queue] = job.waited;
    let mut after = Vec::with_capacity(2);
    after.extend(rectify_time.map(|t| ("rectify", t)));
    after.push(("drop", drop_time));
    set_server_timing(
        &mut response,
        &work::matcher_stages([read, queue, decode_time], &t, &after),
    );
    Ok(response)
}

/// A point's answer: its status and confidence, and with a disparity (to 1/1000 px, the value
/// the distance is computed from) its match and its `/distance` answer.
fn point_match(rig: &Rig, x: f64, y: f64, found: &Found) -> PointMatch {
    let mut answer = PointMatch {
        x,
        y,
        status: found.status.into(),
        confidence: round_to(f64::from(found.confidence), 3),
        x_right: None,
        x_rectified: None,
        y_rectified: None,
        x_right_raw: None,
        y_right_raw: None,
        measured: MatchDistance::default(),
        relative_error: None,
        warnings: None,
        error: None,
    };
    if let Some(d) = found.disparity {
        let d = round_to(f64::from(d), 3);
        answer.x_right = Some(round_to(x - d, 3));
        answer.measured.disparity_px = Some(d);
        let c = Correspondence::at(x, y, d);
        let (rig, sigma) = with_sigma(rig, found.disparity_std);
        match physics::measure(&rig, c) {
            Ok(m) => {
                // Mapped as `/distance` maps it, its one error bar the point's σ.
                answer.measured = with_bar(&m, sigma);
                let m = Measured::from(&m);
                answer.relative_error = Some(m.relative_error);
                answer.warnings = Some(m.warnings);
            }
            Err(e) => answer.error = Some(e.to_string()),
        }
    }
    answer
}

/// The rig a match is measured with: its Δd the matcher's σ_d (to 1/1000 px, as answered in
/// `disparity_std_px`), so that `depth_error`, `relative_error` and their warning are the one
/// error bar σ_Z (with the rig's σ_f and σ_B), the same `/distance` answers for that
/// disparity with `disparity_error_px` = `disparity_std_px`. Without a σ_d, the rig as given.
fn with_sigma(rig: &Rig, sigma_d: Option<f32>) -> (Rig, Option<f64>) {
    let sigma = sigma_d.map(|s| round_to(f64::from(s), 3));
    match sigma.map(|s| rig.with_disparity_error(s)) {
        Some(Ok(measured)) => (measured, sigma),
        _ => (*rig, None),
    }
}

/// A measurement made with [`with_sigma`]'s rig, mapped as `/distance` maps it, with the σ_d
/// it stands on and its σ_Z as `distance_std` (its `depth_error`).
fn with_bar(m: &physics::Measurement, sigma: Option<f64>) -> MatchDistance {
    MatchDistance {
        disparity_std_px: sigma,
        distance_std: sigma.map(|_| m.depth_error),
        ..MatchDistance::from(m)
    }
}

/// A region's answer: the median, 10th and 90th percentile depths of its valid pixels, and the
/// `/distance` answer at its centre for the median.
fn region_match(rig: &Rig, map: &vision::Disparity, b: [f64; 4], r: Option<Rect>) -> RegionMatch {
    let mut answer = RegionMatch {
        x: b[0],
        y: b[1],
        width: b[2],
        height: b[3],
        status: RegionStatus::OutsideImage,
        valid_fraction: 0.0,
        measured: MatchDistance::default(),
        distance_p10: None,
        distance_p90: None,
    };
    let Some(r) = r else {
        return answer;
    };
    let (values, pixels) = correspond::in_box(map, r);
    // Only disparities in front of the cameras have a depth.
    let (mut values, mut stds): (Vec<f64>, Vec<f32>) = values
        .into_iter()
        .filter(|&(d, _)| f64::from(d) + rig.doffs() > 0.0)
        .map(|(d, s)| (f64::from(d), s))
        .unzip();
    values.sort_by(f64::total_cmp);
    answer.valid_fraction = round_to(values.len() as f64 / pixels.max(1) as f64, 4);
    answer.status = RegionStatus::NoValidPixels;
    if values.is_empty() {
        return answer;
    }
    // Nearest rank on the disparities, largest first: depth falls as disparity grows.
    let at = |q: f64| values[((1.0 - q) * (values.len() - 1) as f64).round() as usize];
    let median = round_to(at(0.5), 3);
    let centre = (
        (r.x0 + r.x1 - 1) as f64 / 2.0,
        (r.y0 + r.y1 - 1) as f64 / 2.0,
    );
    let c = Correspondence::at(centre.0, centre.1, median);
    let mid = stds.len() / 2;
    let (_, &mut typical, _) = stds.select_nth_unstable_by(mid, f32::total_cmp);
    let (sigma_rig, sigma) = with_sigma(rig, Some(correspond::median_std(typical, values.len())));
    let Ok(m) = physics::measure(&sigma_rig, c) else {
        return answer;
    };
    answer.status = RegionStatus::Ok;
    answer.measured = with_bar(&m, sigma);
    answer.distance_p10 = rig.distance_at(at(0.1)).ok();
    answer.distance_p90 = rig.distance_at(at(0.9)).ok();
    answer
}
