//! `/rectify`: a raw pair and the calibration of its cameras in (multipart), the rectified pair
//! out, as PNGs, a side-by-side picture with epipolar lines, the maps for OpenCV's `remap`, or
//! a JSON summary. The maps come from the heavy group's cache
//! ([`crate::api::images::maps`]); the remapping is [`stereo_core::vision::remap`]'s.

pub use crate::api::wire::rectify as types;

use std::time::Instant;

use axum::response::{IntoResponse, Response};
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{
    LatlonSystem, ProjectionChoice, RectifyAnswers, RectifyForm, RectifyOutput, RectifyQuery,
    RectifySummary, RectifyTimes, ValidShare,
};
use crate::api::error::ApiError;
use crate::api::extract::QueryParams;
use crate::api::images::HeavyState;
use crate::api::images::job;
use crate::api::images::maps::MapCache;
use crate::api::images::output::{self, Disposition, set_server_timing};
use crate::api::images::work::{self, Need};
use crate::api::images::{ImageForm, ImagePair, Job};
use crate::api::respond::Json;
use crate::api::wire::calibration::RawCameras;
use crate::api::wire::rig::CalibratedRig;
use stereo_core::calibration::files::Raw;
use stereo_core::pipeline::rectify::{self, Interpolation};
use stereo_core::pipeline::{Calibrated, Maps, depth};

/// `POST /rectify`.
pub fn router() -> OpenApiRouter<HeavyState> {
    OpenApiRouter::new().routes(routes!(post_rectify))
}

impl ImageForm for RectifyForm {
    const PARTS: &'static [&'static str] = &[];
    const TAKES_RIG: bool = false;
}

#[utoipa::path(
    post,
    path = "/rectify",
    tag = "images",
    summary = "Rectify a raw stereo pair (undistort and align its rows)",
    description = "Undistorts and rectifies the frames a stereo camera delivers, as OpenCV's \
                   `initUndistortRectifyMap` + `remap` do, with the camera model of the \
                   `calibration` part: a `stereoCalibrate` FileStorage (M1/K1 D1 M2/K2 D2 R T, \
                   with or without R1 R2 P1 P2 Q; `intrinsics.yml` in `calibration` and \
                   `extrinsics.yml` in `right_calibration`), a ROS `CameraInfo` pair with D K R \
                   P, KITTI's raw `calib_cam_to_cam.txt`, or `/calibrate`'s `opencv.yml` and \
                   ROS YAMLs. Models: `plumb_bob`, `rational_polynomial`, `equidistant` \
                   (fisheye).\n\n\
                   Send `multipart/form-data` with parts `left` and `right` (the raw frames, \
                   the calibration's size) and `calibration` (with `calibration_format`, \
                   `right_calibration`, `calibration_unit`, `calibration_cameras` as \
                   `/calibration` takes them).\n\n\
                   Outputs (`output`): `summary` (JSON: sizes, R1 R2 P1 P2 Q, ROIs, the \
                   rectified rig), `left.png`, `right.png`, `pair.png` (side by side with a \
                   line every 32 rows) and `maps.npz` (`left_map_x`, `left_map_y`, \
                   `right_map_x`, `right_map_y`, float32, for `cv2.remap`). The maps of the \
                   last rigs seen are cached, so a stream of frames pays for them once.",
    params(RectifyQuery),
    request_body(content = RectifyForm, content_type = "multipart/form-data", description = "The raw pair and the calibration of its cameras."),
    responses(RectifyAnswers)
)]
pub async fn post_rectify(
    axum::extract::State(state): axum::extract::State<HeavyState>,
    QueryParams(query, problems): QueryParams<RectifyQuery>,
    mut pair: ImagePair<RectifyForm>,
) -> Result<Response, ApiError> {
    let mut problems = pair.problems(problems);
    let output = query.output.unwrap_or_default();
    let how: Interpolation = query.interpolation.unwrap_or_default().into();
    let alpha = problems.alpha(query.alpha);
    let given = job::raw_rig(&pair, alpha, &mut problems);
    let (Some(_), Some(given)) = (pair.size, given) else {
        return Err(problems.into_error());
    };
    let raw = given.raw.clone().expect("checked by raw_rig");
    let latlon = query.latlon();
    let latlon = job::latlon_options(query.projection, latlon, &mut problems);
    let raw = job::projected(*raw, latlon, query.alpha, &mut problems);
    let Some(raw) = raw.filter(|_| problems.is_empty()) else {
        return Err(problems.into_error());
    };
    let rect = raw.rectified_size();
    let (rw, rh) = (rect.width as usize, rect.height as usize);
    // The decoded pair, the maps while they are built, both remapped images in colour and
    // grey, and the PNG being written.
    let bytes = stereo_core::pipeline::job::rectifying_bytes(&raw)
        .saturating_add(rw.saturating_mul(rh).saturating_mul(24));
    let need = Need {
        size: (rw, rh),
        count: 1,
        need: move |_| bytes,
    };
    let cache = state.maps.clone();
    pair.run(need, move |job| {
        compute(job, &cache, &given, &raw, output, how)
    })
    .await?
}

fn compute(
    job: Job,
    cache: &MapCache,
    given: &Calibrated,
    raw: &Raw,
    output: RectifyOutput,
    how: Interpolation,
) -> Result<Response, ApiError> {
    let [read, queue] = job.waited;
    let started = Instant::now();
    if output == RectifyOutput::MapsNpz {
        // The float maps themselves, as OpenCV makes them (the cache holds them in fixed
        // point).
        let bytes = rectify::maps_npz(raw).map_err(ApiError::Internal)?;
        let mut response = file(bytes, output);
        let timing = [
            ("read", read),
            ("queue", queue),
            ("maps", started.elapsed()),
        ];
        set_server_timing(&mut response, &timing);
        return Ok(response);
    }
    let (maps, cached) = cache.get(raw);
    let maps_time = if cached {
        std::time::Duration::ZERO
    } else {
        started.elapsed()
    };
    let mut timing = vec![("read", read), ("queue", queue), ("maps", maps_time)];
    let t = Instant::now();
    let (left, right) = work::decode_pair(job.parts, job.limits, [true, true])?;
    let decode_time = t.elapsed();
    let mut warnings = given.warnings.clone();
    warnings.extend(depth::decode_notes(&left, &right));
    let mut response = if output == RectifyOutput::Summary {
        let times = [decode_time, maps_time];
        let summary = summary(given, raw, &maps, how, cached, times, warnings.clone());
        Json(summary).into_response()
    } else {
        timing.push(("decode", decode_time));
        let t = Instant::now();
        let bytes = match output {
            RectifyOutput::LeftPng => maps.png(&left, false, how),
            RectifyOutput::RightPng => maps.png(&right, true, how),
            _ => maps.side_by_side_png(&left, &right, how),
        };
        timing.push(("remap", t.elapsed()));
        file(bytes, output)
    };
    set_server_timing(&mut response, &timing);
    output::set_warnings(&mut response, &warnings);
    Ok(response)
}

/// The summary of a rectification: the rectified size, the raw cameras and the rectified rig,
/// the share of each rectified image the raw one covers, and the stages' times (decode,
/// maps): nothing is remapped only to be timed.
fn summary(
    given: &Calibrated,
    raw: &Raw,
    maps: &Maps,
    how: Interpolation,
    cached: bool,
    [decode, built]: [std::time::Duration; 2],
    warnings: Vec<String>,
) -> RectifySummary {
    let ms = |d: std::time::Duration| (d.as_secs_f64() * 1e4).round() / 10.0;
    let [share_left, share_right] =
        maps.valid_shares((raw.size.width as usize, raw.size.height as usize));
    RectifySummary {
        width: maps.left.width as u32,
        height: maps.left.height as u32,
        interpolation: match how {
            Interpolation::Linear => types::InterpolationChoice::Linear,
            Interpolation::Nearest => types::InterpolationChoice::Nearest,
            Interpolation::Cubic => types::InterpolationChoice::Cubic,
        },
        raw: RawCameras::new(raw, given.file_unit),
        rig: CalibratedRig::from(&given.rig),
        valid_fraction: ValidShare {
            left: share_left,
            right: share_right,
        },
        projection: match raw.latlon {
            Some(_) => ProjectionChoice::Latlon,
            None => ProjectionChoice::Pinhole,
        },
        latlon: raw
            .latlon
            .as_ref()
            .map(|l| LatlonSystem::of(l, given.file_unit)),
        maps_cached: cached,
        timings_ms: RectifyTimes {
            decode: ms(decode),
            maps: ms(built),
        },
        warnings,
    }
}

/// `output`'s file: the maps to save, the pictures to show.
fn file(bytes: Vec<u8>, output: RectifyOutput) -> Response {
    let how = if output == RectifyOutput::MapsNpz {
        Disposition::Attachment
    } else {
        Disposition::Inline
    };
    output::file(bytes, output.media_type(), output.name(), how)
}
