//! `/depth-map`: a rectified pair in (multipart), a dense disparity and depth map out, as a
//! JSON summary or as the file a user's tool reads (PFM, KITTI PNG, NPY, depth PNG, preview,
//! PLY). The matcher is [`crate::vision`]'s; this module reads the form, judges it against the
//! limits and the memory budget, runs the matcher off the async runtime and encodes the answer.

pub mod types;

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use axum::Extension;
use axum::extract::multipart::MultipartRejection;
use axum::extract::{Multipart, State};
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use utoipa::ToSchema;
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{
    DepthMapForm, DepthMapOutput, DepthMapQuery, DepthMapSummary, MatcherParameters, Spread,
    StageTimes,
};
use super::images::{self, GivenRig, Parts};
use crate::api::HeavyState;
use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::extract::{BodyLimit, QueryParams};
use crate::api::respond::Json;
use crate::api::wire::openapi::ImageErrors;
use crate::budget::Reservation;
use crate::physics::LengthUnit;
use crate::vision::{self, Cancelled, Disparity, Params, encode, sgm};

/// `POST /depth-map`.
pub fn router() -> OpenApiRouter<HeavyState> {
    OpenApiRouter::new().routes(routes!(post_depth_map))
}

/// A file answer's bytes, documented as binary.
#[derive(ToSchema)]
#[schema(value_type = String, format = Binary)]
pub struct FileBody(pub Vec<u8>);

#[utoipa::path(
    post,
    path = "/depth-map",
    tag = "images",
    summary = "Dense disparity and depth maps from a rectified pair",
    description = "Matches a rectified stereo pair with semi-global matching on census costs \
                   (9 × 7 census, 8 paths, a P2 that shrinks across intensity edges, sub-pixel \
                   fit, left-right check, uniqueness, speckle and median filters) and answers \
                   the disparity map, the depth map Z = B·f / (d + doffs), or both in a summary.\n\n\
                   Send `multipart/form-data` with parts `left` and `right` (PNG or JPEG, one \
                   size) and, for depths, `rig` (JSON with the members of `/distance`, e.g. \
                   what `/calibration` answers) or `calibration` (a calibration file, with \
                   `calibration_format`, `right_calibration`, `calibration_unit`, \
                   `calibration_cameras` parts as `/calibration` takes them). Options are \
                   query parameters.\n\n\
                   Outputs (`output`): `summary` (JSON), `disparity.pfm` (Middlebury PFM, \
                   invalid = +inf), `disparity.png` (KITTI 16-bit, round(d·256), 0 = \
                   invalid), `disparity.npy` and `depth.npy` (float32, invalid = NaN, depth in \
                   the rig's unit), `arrays.npz` (NumPy's NPZ of `disparity` and, with a rig, \
                   `depth` and `depth_error`), `depth.png` (16-bit millimetres, 0 = invalid), \
                   `preview.png` (Turbo colours, near = warm) and `points.ply` (binary PLY, \
                   x y z in the rig's unit in the left camera's frame, coloured). Every answer \
                   carries `Server-Timing` with the stages decode, cost, aggregate, refine and \
                   encode.\n\n\
                   Limits: images up to 8192 px a side and 12 megapixels, at most 512 \
                   disparities, and the memory the request needs within the heavy group's \
                   budget (413 naming what to shrink when it can never fit, 503 with \
                   `Retry-After` while other image requests hold it).",
    params(DepthMapQuery),
    request_body(
        content = DepthMapForm,
        content_type = "multipart/form-data",
        description = "The rectified pair and, for depths, the rig or a calibration file."
    ),
    responses(
        (status = 200, description = "The depth map in the `output` asked for.",
         headers(("Server-Timing" = String, description = "Stage times in milliseconds.")),
         content(
            (DepthMapSummary = "application/json"),
            (FileBody = "image/png"),
            (FileBody = "image/x-portable-floatmap"),
            (FileBody = "application/x-npy"),
            (FileBody = "application/x-ply"),
            (FileBody = "application/zip")
         )),
        ImageErrors
    )
)]
pub async fn post_depth_map(
    State(state): State<HeavyState>,
    Extension(reservation): Extension<Reservation>,
    headers: HeaderMap,
    QueryParams(query, mut problems): QueryParams<DepthMapQuery>,
    form: Result<Multipart, MultipartRejection>,
) -> Result<Response, ApiError> {
    let BodyLimit(limit) = state.body_limit;
    let known = [&["left", "right"][..], &images::RIG_PARTS[..]].concat();
    let parts = images::read_parts(form, &known, limit, &mut problems).await?;
    let output = query.output.unwrap_or_else(|| {
        headers
            .get(header::ACCEPT)
            .and_then(|a| a.to_str().ok())
            .and_then(DepthMapOutput::from_accept)
            .unwrap_or_default()
    });
    let left = images::image_size(&parts, "left", &mut problems);
    let right = images::image_size(&parts, "right", &mut problems);
    if let (Some(l), Some(r)) = (left, right) {
        images::check_pair(l, r, &mut problems)?;
    }
    let given = images::rig(&parts, left, &mut problems);
    if output.needs_rig() {
        images::require_rig(
            &parts,
            &format!("for output={}", output.name()),
            &mut problems,
        );
    }
    let ndisp = given.as_ref().and_then(|g| g.max_disparity);
    let params = settings(&query, ndisp, &mut problems);
    let (Some((width, height)), Some(params)) = (left, params) else {
        return Err(problems.into_error());
    };
    if !problems.is_empty() {
        return Err(problems.into_error());
    }
    let (w, h) = (width as usize, height as usize);
    images::reserve(
        &reservation,
        bytes_needed(w, h, params.count, output),
        |total| shrink(w, h, params.count, output, total),
    )?;
    images::blocking(reservation, move |cancel| {
        compute(&parts, &params, given, output, cancel)
    })
    .await?
}

/// The search range and the matcher's parameters from the query, with the calibration's
/// `ndisp` as the default end of the range.
fn settings(q: &DepthMapQuery, ndisp: Option<u32>, problems: &mut FieldErrors) -> Option<Params> {
    let defaults = Params::default();
    let range = images::disparity_range(q.min_disparity, q.max_disparity, ndisp, problems);
    let whole =
        |field: &str, value: Option<u32>, default: u32, lo: u32, hi: u32, p: &mut FieldErrors| {
            let v = value.unwrap_or(default);
            if (lo..=hi).contains(&v) {
                Some(v)
            } else {
                p.add(field, format!("must be from {lo} to {hi}, got {v}"));
                None
            }
        };
    let p1 = whole("p1", q.p1, defaults.penalties.p1.into(), 1, 255, problems);
    let p2 = whole("p2", q.p2, defaults.penalties.p2.into(), 2, 1024, problems);
    if let (Some(p1), Some(p2)) = (p1, p2)
        && p2 <= p1
    {
        problems.add("p2", format!("must be greater than p1 ({p1}), got {p2}"));
    }
    let edge = whole(
        "p2_edge",
        q.p2_edge,
        defaults.penalties.edge.into(),
        0,
        255,
        problems,
    );
    let uniqueness = whole(
        "uniqueness",
        q.uniqueness,
        defaults.uniqueness,
        0,
        100,
        problems,
    );
    let speckle_size = whole(
        "speckle_size",
        q.speckle_size,
        defaults.speckle_size as u32,
        0,
        1_000_000,
        problems,
    );
    let real = |field: &str,
                value: Option<f64>,
                default: f64,
                open_low: bool,
                hi: f64,
                p: &mut FieldErrors| {
        let v = value.unwrap_or(default);
        let low_ok = if open_low { v > 0.0 } else { v >= 0.0 };
        if v.is_finite() && low_ok && v <= hi {
            Some(v)
        } else {
            let bracket = if open_low { "(" } else { "[" };
            p.add(
                field,
                format!(
                    "must lie in {bracket}0, {hi}], got {}",
                    crate::numbers::Num(v)
                ),
            );
            None
        }
    };
    let tolerance = real("lr_tolerance", q.lr_tolerance, 1.0, false, 64.0, problems);
    let speckle_range = real("speckle_range", q.speckle_range, 2.0, true, 64.0, problems);
    if q.lr_check == Some(false) && q.lr_tolerance.is_some() {
        problems.add("lr_tolerance", "applies only when lr_check is true");
    }
    let (min_disparity, count) = range?;
    Some(Params {
        min_disparity,
        count,
        penalties: sgm::Penalties {
            p1: p1? as u16,
            p2: p2? as u16,
            edge: edge? as u16,
        },
        uniqueness: uniqueness?,
        lr_tolerance: if q.lr_check.unwrap_or(true) {
            Some(tolerance? as f32)
        } else {
            None
        },
        subpixel: q.subpixel.map_or(defaults.subpixel, Into::into),
        speckle_size: speckle_size? as usize,
        speckle_range: speckle_range? as f32,
        median: q.median.unwrap_or(defaults.median),
        fill: q.fill.unwrap_or(defaults.fill),
    })
}

/// The bytes a request holds at its peak: the decoded pair, the colours for a point cloud, the
/// matcher's, and the answer's per-pixel buffers.
fn bytes_needed(w: usize, h: usize, count: usize, output: DepthMapOutput) -> usize {
    // A point cloud's colours, or the NPZ's two more arrays and the archive's copy of all three.
    let extra = match output {
        DepthMapOutput::PointsPly => 3,
        DepthMapOutput::ArraysNpz => 20,
        _ => 0,
    };
    images::decoded_bytes(w, h)
        .saturating_add(w.saturating_mul(h).saturating_mul(extra + 24))
        .saturating_add(vision::bytes_needed(w, h, count))
}

/// What to shrink so that the request fits in a budget of `total` bytes.
fn shrink(
    w: usize,
    h: usize,
    count: usize,
    output: DepthMapOutput,
    total: usize,
) -> Vec<FieldError> {
    let need = bytes_needed(w, h, count, output);
    let per_pixel = need / (w * h).max(1);
    let max_pixels = total / per_pixel.max(1);
    let mut fits = count;
    while fits > 16 && bytes_needed(w, h, fits, output) > total {
        fits -= 16;
    }
    let mib = |b: usize| b / (1024 * 1024);
    let mut errors = vec![FieldError::new(
        "left",
        format!(
            "a {w} × {h} pair searching {count} disparities needs {} MiB, more than the {} MiB \
             this server has for image requests: send smaller images (at most {:.1} megapixels \
             at this range)",
            mib(need),
            mib(total),
            max_pixels as f64 / 1e6
        ),
    )];
    if bytes_needed(w, h, fits, output) <= total {
        errors.push(FieldError::new(
            "max_disparity",
            format!("or search fewer disparities: at most {fits} fit at this size"),
        ));
    }
    errors
}

/// Decodes, matches and encodes, on a blocking thread.
fn compute(
    parts: &Parts,
    params: &Params,
    given: Option<GivenRig>,
    output: DepthMapOutput,
    cancel: &AtomicBool,
) -> Result<Response, ApiError> {
    let started = Instant::now();
    let (left, right) = images::decode_pair(parts, output == DepthMapOutput::PointsPly)?;
    let decode_time = started.elapsed();
    let (map, timings) = vision::disparity(&left.grey, &right.grey, params, cancel)
        .map_err(|Cancelled| ApiError::Internal("cancelled".to_owned()))?;
    drop(right);
    let started = Instant::now();
    let rig = given.as_ref().map(|g| g.rig);
    let depth = rig.map(|rig| depths(&map, rig.fb() as f32, rig.doffs as f32));
    let (w, h) = (map.width, map.height);
    let body: Result<Vec<u8>, DepthMapSummary> = match output {
        DepthMapOutput::Summary => Err(summary(
            &map,
            depth.as_deref(),
            params,
            given,
            [decode_time, timings.cost, timings.aggregate, timings.refine],
        )),
        DepthMapOutput::DisparityPfm => Ok(encode::pfm(w, h, &map.data)),
        DepthMapOutput::DisparityPng => {
            Ok(encode::png16(w, h, &encode::kitti_disparity(&map.data)))
        }
        DepthMapOutput::DisparityNpy => Ok(encode::npy(w, h, &map.data)),
        DepthMapOutput::DepthNpy => Ok(encode::npy(w, h, depth.as_deref().unwrap_or_default())),
        DepthMapOutput::ArraysNpz => Ok(arrays(&map, depth.as_deref(), rig)),
        DepthMapOutput::DepthPng => {
            let unit = rig.map_or(LengthUnit::Millimetre, |r| r.unit);
            let mm: Vec<f32> = depth
                .as_deref()
                .unwrap_or_default()
                .iter()
                .map(|&z| unit.convert(f64::from(z), LengthUnit::Millimetre) as f32)
                .collect();
            Ok(encode::png16(w, h, &encode::millimetres(&mm)))
        }
        DepthMapOutput::PreviewPng => Ok(encode::png_rgb(w, h, &preview(&map))),
        DepthMapOutput::PointsPly => Ok(encode::ply(&points(
            &map,
            depth.as_deref().unwrap_or_default(),
            rig,
            left.rgb.as_deref().unwrap_or_default(),
        ))),
    };
    let encode_time = started.elapsed();
    let stages = [
        ("decode", decode_time),
        ("cost", timings.cost),
        ("aggregate", timings.aggregate),
        ("refine", timings.refine),
        ("encode", encode_time),
    ];
    let mut response = match body {
        Ok(bytes) => {
            let mut response = bytes.into_response();
            let h = response.headers_mut();
            h.insert(
                header::CONTENT_TYPE,
                HeaderValue::from_static(output.media_type()),
            );
            if let Ok(v) = HeaderValue::from_str(&format!(
                "{}; filename=\"{}\"",
                if output == DepthMapOutput::PreviewPng {
                    "inline"
                } else {
                    "attachment"
                },
                output.name()
            )) {
                h.insert(header::CONTENT_DISPOSITION, v);
            }
            response
        }
        Err(summary) => Json(summary).into_response(),
    };
    if let Ok(v) = HeaderValue::from_str(&images::server_timing(&stages)) {
        response.headers_mut().insert("server-timing", v);
    }
    Ok(response)
}

/// Depth Z = f·B / (d + doffs) of each pixel, NaN where the disparity is invalid or the point
/// would be at or beyond infinity (d + doffs ≤ 0).
fn depths(map: &Disparity, fb: f32, doffs: f32) -> Vec<f32> {
    map.data
        .iter()
        .map(|&d| {
            let effective = d + doffs;
            if effective > 0.0 {
                fb / effective
            } else {
                f32::NAN
            }
        })
        .collect()
}

/// The NPZ: the disparity and, with a rig, the depth and its error ΔZ = Z²·Δd / (f·B).
fn arrays(map: &Disparity, depth: Option<&[f32]>, rig: Option<crate::physics::Rig>) -> Vec<u8> {
    let (w, h) = (map.width, map.height);
    let mut entries = vec![("disparity", encode::npy(w, h, &map.data))];
    if let (Some(depth), Some(rig)) = (depth, rig) {
        let error: Vec<f32> = depth
            .iter()
            .map(|&z| rig.depth_error_at(f64::from(z)) as f32)
            .collect();
        entries.push(("depth", encode::npy(w, h, depth)));
        entries.push(("depth_error", encode::npy(w, h, &error)));
    }
    encode::npz(&entries)
}

/// The valid values' min, median and max.
fn spread(values: &[f32]) -> Option<Spread> {
    let mut valid: Vec<f32> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if valid.is_empty() {
        return None;
    }
    let mid = valid.len() / 2;
    let (_, &mut median, _) = valid.select_nth_unstable_by(mid, f32::total_cmp);
    let (min, max) = valid
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    let round = |v: f32| (f64::from(v) * 1e4).round() / 1e4;
    Some(Spread {
        min: round(min),
        median: round(median),
        max: round(max),
    })
}

fn summary(
    map: &Disparity,
    depth: Option<&[f32]>,
    params: &Params,
    given: Option<GivenRig>,
    [decode, cost, aggregate, refine]: [Duration; 4],
) -> DepthMapSummary {
    let valid = map.data.iter().filter(|d| !d.is_nan()).count();
    let ms = |d: Duration| (d.as_secs_f64() * 1e4).round() / 10.0;
    let (rig, warnings) = given.map_or((None, Vec::new()), |g| (Some(g.echo), g.warnings));
    DepthMapSummary {
        width: map.width,
        height: map.height,
        min_disparity: params.min_disparity,
        max_disparity: params.min_disparity + params.count as i32,
        valid_fraction: (valid as f64 / map.data.len().max(1) as f64 * 1e4).round() / 1e4,
        disparity_px: spread(&map.data),
        distance: depth.and_then(spread),
        rig,
        parameters: MatcherParameters {
            p1: params.penalties.p1.into(),
            p2: params.penalties.p2.into(),
            p2_edge: params.penalties.edge.into(),
            uniqueness: params.uniqueness,
            lr_tolerance: params.lr_tolerance.map(f64::from),
            subpixel: params.subpixel.into(),
            speckle_size: params.speckle_size as u32,
            speckle_range: f64::from(params.speckle_range),
            median: params.median,
            fill: params.fill,
        },
        timings_ms: StageTimes {
            decode: ms(decode),
            cost: ms(cost),
            aggregate: ms(aggregate),
            refine: ms(refine),
        },
        warnings,
    }
}

/// The disparity map coloured: Turbo from the smallest valid disparity (far, blue) to the
/// largest (near, red), invalid black.
fn preview(map: &Disparity) -> Vec<u8> {
    let (lo, hi) = map
        .data
        .iter()
        .filter(|d| !d.is_nan())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &d| {
            (lo.min(d), hi.max(d))
        });
    let span = (hi - lo).max(1e-3);
    map.data
        .iter()
        .flat_map(|&d| {
            if d.is_nan() {
                [0, 0, 0]
            } else {
                encode::turbo((d - lo) / span)
            }
        })
        .collect()
}

/// The valid pixels as points in the left camera's frame (the same formula as `/distance`'s
/// `point`), coloured from the left image.
fn points(
    map: &Disparity,
    depth: &[f32],
    rig: Option<crate::physics::Rig>,
    rgb: &[u8],
) -> Vec<encode::ColouredPoint> {
    let Some(rig) = rig else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (i, &z) in depth.iter().enumerate() {
        if z.is_nan() {
            continue;
        }
        let (x, y) = ((i % map.width) as f64, (i / map.width) as f64);
        let Ok(p) = rig.point_at(x, y, f64::from(z)) else {
            continue;
        };
        let colour = rgb
            .get(i * 3..i * 3 + 3)
            .map_or([200; 3], |c| [c[0], c[1], c[2]]);
        out.push(encode::ColouredPoint {
            xyz: [p.x as f32, p.y as f32, p.z as f32],
            rgb: colour,
        });
    }
    out
}
