//! `/depth-map`: a rectified pair (or a raw one with its calibration, rectified first) in
//! (multipart), a dense disparity and depth map out, as a
//! JSON summary or as the file a user's tool reads (PFM, KITTI PNG, NPY, depth PNG, preview,
//! PLY). The matcher is [`stereo_core::vision`]'s; this module reads the form, judges it against the
//! limits and the memory budget, runs the matcher off the async runtime and encodes the answer.

pub use crate::api::wire::depth_map as types;

use std::time::Instant;

use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{DepthMapAnswers, DepthMapForm, DepthMapOutput, DepthMapQuery, DepthMapSummary};
use axum::extract::State;

use crate::api::error::ApiError;
use crate::api::extract::QueryParams;
use crate::api::images::HeavyState;
use crate::api::images::output::{self, Disposition, set_server_timing};
use crate::api::images::{ImageForm, ImagePair, Job, job, rig, ros, work};
use crate::api::respond::Json;
use crate::api::wire::rig::CalibratedRig;
use stereo_core::pipeline::{self, Answer, DepthJob, Product};

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
                   are none), and the projection its pixels are in (`pinhole` or `latlon`) in \
                   `Stereo-Projection`; `points.ply` says it in a comment, `arrays.npz` in \
                   `projection` (and, for latlon, `latlon`: f_az, f_el, cx, cy).\n\n\
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
                   property `depth_std`), and `left_depth.npy` (float32 depths at the raw left \
                   frame's own pixels, along the left camera's axis, whatever the projection). \
                   Every answer \
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
    let output = query.output.unwrap_or_else(|| {
        headers
            .get(header::ACCEPT)
            .and_then(|a| a.to_str().ok())
            .and_then(DepthMapOutput::from_accept)
            .unwrap_or_default()
    });
    let latlon = job::latlon_options(query.projection, query.latlon(), &mut problems)
        .and_then(|l| l.unless_pinhole(output.ros().is_some()));
    let asked = job::Asked {
        rectify: query.rectify,
        alpha: query.alpha,
        latlon,
        settings: query.settings(),
        prefix: "",
    };
    let planned = job::plan_pair(&mut pair, asked, &mut problems);
    if output.needs_rig() {
        let why = format!("for output={}", output.name());
        rig::require_rig(pair.sent, &why, &mut problems);
    }
    if latlon.is_some() && output.ros().is_some() {
        problems.add("output", job::ROS_NOT_LATLON);
    }
    let (Some(size), Some(planned)) = (pair.size, planned) else {
        return Err(problems.into_error());
    };
    if !problems.is_empty() {
        return Err(problems.into_error());
    }
    let products = output.needs().into_iter().collect();
    let need = job::need(planned.need(size, Answer::Files(products)));
    let cache = state.maps.clone();
    pair.run(need, move |work| {
        compute(work, planned.with_maps(|raw| cache.get(raw).0), output)
    })
    .await?
}

/// Decodes, runs the engine's depth map and writes the answer, on a blocking thread.
fn compute(work: Job, job: DepthJob, output: DepthMapOutput) -> Result<Response, ApiError> {
    let Job {
        parts,
        limits: allowed,
        cancel,
        waited: [read, queue],
    } = work;
    let started = Instant::now();
    let colour = output.needs().is_some_and(Product::wants_colour);
    let (left, right) = work::decode_pair(parts, allowed, [colour, false])?;
    let decode = started.elapsed();
    let request = job.request(colour, output.wants_depth_std());
    let map = pipeline::depth_map(left, right, request, cancel).map_err(ApiError::from)?;
    let started = Instant::now();
    let mut response = match output.is_file() {
        true => {
            let bytes = ros::file(output, &map).map_err(ApiError::Internal)?;
            let how = match output.product() {
                Some(Product::PreviewPng) => Disposition::Inline,
                _ => Disposition::Attachment,
            };
            output::file(bytes, output.media_type(), output.name(), how)
        }
        false => {
            let rig = job.calibrated().map(|c| CalibratedRig::from(&c.rig));
            Json(DepthMapSummary::of(&map, job.params(), rig, decode)).into_response()
        }
    };
    let encode = started.elapsed() + map.depths;
    let started = Instant::now();
    let (warnings, timings, rectify) = (map.warnings.clone(), map.timings, map.rectify);
    output::set_projection(&mut response, map.projection());
    drop(map);
    let mut after = Vec::with_capacity(3);
    after.extend(rectify.map(|t| ("rectify", t)));
    after.extend([("encode", encode), ("drop", started.elapsed())]);
    output::set_warnings(&mut response, &warnings);
    set_server_timing(
        &mut response,
        &work::matcher_stages([read, queue, decode], &timings, &after),
    );
    Ok(response)
}
