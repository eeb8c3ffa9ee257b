//! `/depth-map`: a rectified pair (or a raw one with its calibration, rectified first) in
//! (multipart), a dense disparity and depth map out, as a
//! JSON summary or as the file a user's tool reads (PFM, KITTI PNG, NPY, depth PNG, preview,
//! PLY). The matcher is [`stereo_core::vision`]'s; this module reads the form, judges it against the
//! limits and the memory budget, runs the matcher off the async runtime and encodes the answer.

pub mod types;

use std::time::{Duration, Instant};

use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{
    DepthMapAnswers, DepthMapForm, DepthMapOutput, DepthMapQuery, DepthMapSummary,
    MatcherParameters, Spread, StageTimes,
};
use axum::extract::State;

use crate::api::HeavyState;
use crate::api::error::ApiError;
use crate::api::extract::QueryParams;
use crate::api::images::maps::MapCache;
use crate::api::images::output::{self, Disposition, set_server_timing};
use crate::api::images::raw;
use crate::api::images::work;
use crate::api::images::{GivenRig, ImageForm, ImagePair, Job, limits, rig};
use crate::api::respond::Json;
use stereo_core::calibration::files::Raw;
use stereo_core::physics::LengthUnit;
use stereo_core::vision::{self, Cancelled, Disparity, Params, encode};

/// `POST /depth-map`.
pub fn router() -> OpenApiRouter<HeavyState> {
    OpenApiRouter::new().routes(routes!(post_depth_map))
}

impl ImageForm for DepthMapForm {
    const PARTS: &'static [&'static str] = &[];
}

#[utoipa::path(
    post,
    path = "/depth-map",
    tag = "images",
    summary = "Dense disparity and depth maps from a stereo pair, rectified or raw with its calibration",
    description = "Matches a rectified stereo pair with semi-global matching on census costs \
                   (9 × 7 census, 8 paths, a P2 that shrinks across intensity edges, sub-pixel \
                   fit, left-right check, uniqueness, speckle and median filters) and answers \
                   the disparity map, the depth map Z = B·f / (d + doffs), or both in a summary.\n\n\
                   Raw frames: with a `calibration` that describes the raw cameras (a \
                   `stereoCalibrate` file, a ROS `CameraInfo` pair with D K R P, KITTI's raw \
                   `calib_cam_to_cam.txt`, `/calibrate`'s `opencv.yml`), `rectify=auto` (the \
                   default) rectifies the pair first as `/rectify` does; the outputs are then \
                   in the rectified left camera's frame and size (`rectified: true`). A pair \
                   sent as rectified that looks raw (under 20 % of the pixels matched, or \
                   matched corners a pixel or more off their rows) gets a warning in the \
                   summary saying how to rectify it. A file answer carries the warnings \
                   in its `Stereo-Warnings` header (a JSON array of strings, absent when there \
                   are none).\n\n\
                   A JPEG or PNG cut off before its image ends, or whose data is corrupt, is a \
                   422 naming the part; a JPEG whose scans are whole but whose end-of-image \
                   marker is missing is read, with a warning.\n\n\
                   Send `multipart/form-data` with parts `left` and `right` (PNG or JPEG, one \
                   size) and, for depths, `rig` (JSON with the members of `/distance`, e.g. \
                   what `/calibration` answers) or `calibration` (a calibration file, with \
                   `calibration_format`, `right_calibration`, `calibration_unit`, \
                   `calibration_cameras` parts as `/calibration` takes them). Options are \
                   query parameters.\n\n\
                   Outputs (`output`): `summary` (JSON), `disparity.pfm` (Middlebury PFM, \
                   invalid = +inf), `disparity.png` (KITTI 16-bit, round(d·256), 0 = \
                   invalid), `disparity.npy` and `depth.npy` (float32, invalid = NaN, depth in \
                   the rig's unit), each pixel's σ as `disparity_std.npy`, \
                   `disparity_std.pfm` (px) and `depth_std.npy` (the rig's unit), \
                   `arrays.npz` (NumPy's NPZ of `disparity`, `disparity_std` and, with a rig, \
                   `depth`, `depth_std` and `depth_error`; with `fill=true`, `filled`), \
                   `depth.png` (16-bit millimetres, 0 = invalid), `preview.png` (Turbo \
                   colours, near = warm) and `points.ply` (binary PLY, x y z in the rig's \
                   unit in the left camera's frame, coloured, each point's σ_Z as the float \
                   property `depth_std`). Every answer \
                   carries `Server-Timing` with the stages decode, cost, aggregate, refine, \
                   encode and, for raw pairs, rectify.\n\n\
                   Limits: images up to 8192 px a side and the server's `--max-image-pixels` (34 megapixels by default), at most 512 \
                   disparities, and the memory the request needs within the heavy group's \
                   budget (413 naming what to shrink when it can never fit, 503 with \
                   `Retry-After` while other image requests hold it).",
    params(DepthMapQuery),
    request_body(content = DepthMapForm, content_type = "multipart/form-data", description = "The pair (rectified, or raw with its calibration) and, for depths, the rig or a calibration file."),
    responses(DepthMapAnswers)
)]
pub async fn post_depth_map(
    State(state): State<HeavyState>,
    headers: HeaderMap,
    QueryParams(query, problems): QueryParams<DepthMapQuery>,
    mut pair: ImagePair<DepthMapForm>,
) -> Result<Response, ApiError> {
    let mut problems = pair.problems(problems);
    let raw = raw::plan(&mut pair, query.rectify, query.alpha, &mut problems);
    let output = query.output.unwrap_or_else(|| {
        headers
            .get(header::ACCEPT)
            .and_then(|a| a.to_str().ok())
            .and_then(DepthMapOutput::from_accept)
            .unwrap_or_default()
    });
    if output.needs_rig() {
        rig::require_rig(
            &pair.parts,
            &format!("for output={}", output.name()),
            &mut problems,
        );
    }
    let ndisp = pair.rig.as_ref().and_then(|g| g.max_disparity);
    let params = limits::params(query.settings(), ndisp, &mut problems);
    let (Some((raw_w, raw_h)), Some(params)) = (pair.size, params) else {
        return Err(problems.into_error());
    };
    if !problems.is_empty() {
        return Err(problems.into_error());
    }
    let need = raw::match_need(
        raw.as_deref(),
        (raw_w, raw_h),
        params.count(),
        move |w, h, n| bytes_needed(w, h, n, output),
    );
    let cache = state.maps.clone();
    pair.run(need, move |job| {
        compute(job, &params, output, raw.as_deref().map(|r| (r, &*cache)))
    })
    .await?
}

/// The bytes a request holds at its peak besides its body: the decoded pair, then the colours
/// for a point cloud, the matcher's, and the answer's per-pixel buffers. What a `w × h`
/// rectified pair searching `count` disparities reserves from the heavy budget.
pub fn bytes_needed(w: usize, h: usize, count: usize, output: DepthMapOutput) -> usize {
    // A point cloud's colours, σ_Z and the 4 more bytes of each point and vertex, or the
    // NPZ's four more arrays and the archive's copy of all five (and the fill's one-byte
    // mask, twice).
    let extra = match output {
        DepthMapOutput::PointsPly => 15,
        DepthMapOutput::ArraysNpz => 42,
        DepthMapOutput::DepthStdNpy => 4,
        _ => 0,
    };
    let after = w
        .saturating_mul(h)
        .saturating_mul(extra + 24)
        .saturating_add(vision::bytes_needed(w, h, count));
    limits::decode_then(w, h, after)
}

/// Decodes, matches and encodes, on a blocking thread. `waited` is how long the body took to
/// read and the work to get a thread, for `Server-Timing`.
fn compute(
    job: Job,
    params: &Params,
    output: DepthMapOutput,
    raw: Option<(&Raw, &MapCache)>,
) -> Result<Response, ApiError> {
    let Job {
        parts,
        limits: allowed,
        rig: given,
        cancel,
        waited: [read, queue],
    } = job;
    let started = Instant::now();
    let colour = output == DepthMapOutput::PointsPly;
    let (mut left, mut right) = work::decode_pair(parts, allowed, [colour, false])?;
    let decode_time = started.elapsed();
    let rectify_time = raw.map(|raw| raw::rectify_raw_pair(&mut left, &mut right, raw, colour));
    let (map, timings) = vision::disparity(&left.grey, &right.grey, params, cancel)
        .map_err(|Cancelled| ApiError::Internal("cancelled".to_owned()))?;
    // A pair sent as rectified: do its matched corners lie on their rows? (A file answer says
    // so in its `Stereo-Warnings` header.)
    let rows = raw
        .is_none()
        .then(|| raw::row_check(&left, &right, params))
        .flatten();
    let mut warnings = given.as_ref().map_or_else(Vec::new, |g| g.warnings.clone());
    warnings.extend(work::decode_notes(&left, &right));
    drop(right);
    let valid = map.data.iter().filter(|d| !d.is_nan()).count();
    let valid_fraction = valid as f64 / map.data.len().max(1) as f64;
    if rectify_time.is_none()
        && let Some(warning) = raw::unrectified_warning(Some(valid_fraction), rows)
    {
        warnings.push(warning);
    }
    // The summary also says what was done to a raw pair; the `Stereo-Warnings` header keeps to
    // what is wrong with what was sent (`rectified: true` says the rest).
    let mut said = warnings.clone();
    if rectify_time.is_some() {
        said.push(format!(
            "the raw pair was rectified first: the maps are the rectified left camera's, {} × \
             {} px, and the depths use the rectified rig",
            map.width, map.height
        ));
    }
    let started = Instant::now();
    let rig = given.as_ref().map(|g| g.rig);
    let depth = rig.map(|rig| depths(&map, rig.fb() as f32, rig.doffs() as f32));
    let depth_std = match (rig, &depth) {
        (Some(rig), Some(depth)) if output.wants_depth_std() => Some(depth_stds(&map, depth, rig)),
        _ => None,
    };
    let (w, h) = (map.width, map.height);
    let body: Result<Vec<u8>, DepthMapSummary> = match output {
        DepthMapOutput::Summary => Err(summary(
            &map,
            (depth.as_deref(), depth_std.as_deref()),
            params,
            (given, said),
            (rectify_time, valid_fraction),
            [decode_time, timings.cost, timings.aggregate, timings.refine],
            timings.paths,
        )),
        DepthMapOutput::DisparityPfm => Ok(encode::pfm(w, h, &map.data)),
        DepthMapOutput::DisparityPng => {
            Ok(encode::png16(w, h, &encode::kitti_disparity(&map.data)))
        }
        DepthMapOutput::DisparityNpy => Ok(encode::npy(w, h, &map.data)),
        DepthMapOutput::DepthNpy => Ok(encode::npy(w, h, depth.as_deref().unwrap_or_default())),
        DepthMapOutput::DisparityStdNpy => Ok(encode::npy(w, h, &map.std)),
        DepthMapOutput::DisparityStdPfm => Ok(encode::pfm(w, h, &map.std)),
        DepthMapOutput::DepthStdNpy => {
            Ok(encode::npy(w, h, depth_std.as_deref().unwrap_or_default()))
        }
        DepthMapOutput::ArraysNpz => Ok(arrays(&map, depth.as_deref(), depth_std.as_deref())?),
        DepthMapOutput::DepthPng => {
            let unit = rig.map_or(LengthUnit::Millimetre, |r| r.unit());
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
            (
                depth.as_deref().unwrap_or_default(),
                depth_std.as_deref().unwrap_or_default(),
            ),
            rig,
            left.rgb.as_deref().unwrap_or_default(),
        ))),
    };
    let encode_time = started.elapsed();
    let started = Instant::now();
    drop((left, map, depth, depth_std));
    let drop_time = started.elapsed();
    let mut after = Vec::with_capacity(3);
    after.extend(rectify_time.map(|t| ("rectify", t)));
    after.extend([("encode", encode_time), ("drop", drop_time)]);
    let mut response = match body {
        Ok(bytes) => {
            let how = if output == DepthMapOutput::PreviewPng {
                Disposition::Inline
            } else {
                Disposition::Attachment
            };
            output::file(bytes, output.media_type(), output.name(), how)
        }
        Err(summary) => Json(summary).into_response(),
    };
    output::set_warnings(&mut response, &warnings);
    set_server_timing(
        &mut response,
        &work::matcher_stages([read, queue, decode_time], &timings, &after),
    );
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

/// σ_Z of each depth: `√((Z²·σ_d / (f·B))² + (Z·σ_f / f)² + (Z·σ_B / B)²)` with the pixel's
/// σ_d and the rig's σ_f and σ_B; NaN where the depth is.
fn depth_stds(map: &Disparity, depth: &[f32], rig: stereo_core::physics::Rig) -> Vec<f32> {
    depth
        .iter()
        .zip(&map.std)
        .map(|(&z, &s)| {
            if z.is_nan() || s.is_nan() {
                f32::NAN
            } else {
                rig.depth_error_terms_with(f64::from(z), f64::from(s))
                    .total() as f32
            }
        })
        .collect()
}

/// The NPZ: the disparity and its σ_d and, with a rig, the depth, its σ_Z, and σ_Z again as
/// `depth_error` (its earlier name); with `fill`, which pixels the fill gave (`filled`).
fn arrays(
    map: &Disparity,
    depth: Option<&[f32]>,
    depth_std: Option<&[f32]>,
) -> Result<Vec<u8>, ApiError> {
    let (w, h) = (map.width, map.height);
    let mut entries = vec![
        ("disparity", encode::npy(w, h, &map.data)),
        ("disparity_std", encode::npy(w, h, &map.std)),
    ];
    if let (Some(depth), Some(depth_std)) = (depth, depth_std) {
        let std = encode::npy(w, h, depth_std);
        entries.push(("depth", encode::npy(w, h, depth)));
        entries.push(("depth_std", std.clone()));
        entries.push(("depth_error", std));
    }
    if !map.filled.is_empty() {
        entries.push(("filled", encode::npy_bool(w, h, &map.filled)));
    }
    encode::npz(&entries).map_err(|e| ApiError::Internal(format!("the NPZ was not written: {e}")))
}

/// The valid values' min, median and max.
fn spread(values: &[f32]) -> Option<Spread> {
    let mut valid: Vec<f32> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if valid.is_empty() {
        return None;
    }
    // NumPy's median (`numpy.nanmedian` of the NPY and NPZ outputs): the middle value, or the
    // mean of the two middle values of an even count.
    let (count, mid) = (valid.len(), valid.len() / 2);
    let (below, &mut upper, _) = valid.select_nth_unstable_by(mid, f32::total_cmp);
    let median = if count.is_multiple_of(2) {
        let lower = below.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        (f64::from(lower) + f64::from(upper)) / 2.0
    } else {
        f64::from(upper)
    };
    let (min, max) = valid
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    let round = |v: f64| (v * 1e4).round() / 1e4;
    Some(Spread {
        min: round(min.into()),
        median: round(median),
        max: round(max.into()),
    })
}

/// The summary of `map` with its depths and their σ (`(depth, depth_std)`, with a rig) and
/// the answer's warnings.
fn summary(
    map: &Disparity,
    (depth, depth_std): (Option<&[f32]>, Option<&[f32]>),
    params: &Params,
    (given, warnings): (Option<GivenRig>, Vec<String>),
    (rectified, valid_fraction): (Option<Duration>, f64),
    [decode, cost, aggregate, refine]: [Duration; 4],
    paths: Option<vision::sgm::Paths>,
) -> DepthMapSummary {
    let ms = |d: Duration| (d.as_secs_f64() * 1e4).round() / 10.0;
    let rig = given.map(|g| g.echo());
    DepthMapSummary {
        width: map.width,
        height: map.height,
        min_disparity: params.min_disparity(),
        max_disparity: params.max_disparity(),
        valid_fraction: (valid_fraction * 1e4).round() / 1e4,
        disparity_px: spread(&map.data),
        distance: depth.and_then(spread),
        disparity_std_px: spread(&map.std),
        distance_std: depth_std.and_then(spread),
        rig,
        parameters: MatcherParameters {
            preset: params.preset().into(),
            paths: match paths {
                Some(vision::sgm::Paths::Five) => 5,
                _ => 8,
            },
            p1: params.penalties().p1.into(),
            p2: params.penalties().p2.into(),
            p2_edge: params.penalties().edge.into(),
            uniqueness: params.uniqueness(),
            lr_tolerance: params.lr_tolerance().map(f64::from),
            subpixel: params.subpixel().into(),
            speckle_size: params.speckle_size() as u32,
            speckle_range: f64::from(params.speckle_range()),
            max_disparity_std: params.max_disparity_std(),
            median: params.median(),
            fill: params.fill(),
        },
        timings_ms: StageTimes {
            decode: ms(decode),
            cost: ms(cost),
            aggregate: ms(aggregate),
            refine: ms(refine),
            rectify: rectified.map(ms),
        },
        rectified: rectified.is_some(),
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
/// `point`), coloured from the left image, each with its σ_Z (`(depth, depth_std)`).
fn points(
    map: &Disparity,
    (depth, depth_std): (&[f32], &[f32]),
    rig: Option<stereo_core::physics::Rig>,
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
        let Some(Ok(p)) = rig.point_at(x, y, f64::from(z)) else {
            continue;
        };
        let colour = rgb
            .get(i * 3..i * 3 + 3)
            .map_or([200; 3], |c| [c[0], c[1], c[2]]);
        out.push(encode::ColouredPoint {
            xyz: [p.x as f32, p.y as f32, p.z as f32],
            rgb: colour,
            depth_std: depth_std.get(i).copied().unwrap_or(f32::NAN),
        });
    }
    out
}
