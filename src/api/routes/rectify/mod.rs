//! `/rectify`: a raw pair and the calibration of its cameras in (multipart), the rectified pair
//! out, as PNGs, a side-by-side picture with epipolar lines, the maps for OpenCV's `remap`, or
//! a JSON summary. The maps come from the heavy group's cache
//! ([`crate::api::images::maps`]); the remapping is [`crate::vision::remap`]'s.

pub mod types;

use std::time::Instant;

use axum::body::Bytes;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{
    RectifyForm, RectifyMode, RectifyOutput, RectifyQuery, RectifySummary, RectifyTimes, ValidShare,
};
use crate::api::HeavyState;
use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::extract::QueryParams;
use crate::api::images::maps::{MapCache, Maps, float_maps};
use crate::api::images::work::Need;
use crate::api::images::{GivenRig, ImageForm, ImagePair, limits};
use crate::api::respond::Json;
use crate::api::routes::calibration::alpha_message;
use crate::api::routes::calibration::types::{CalibratedRig, RawCameras};
use crate::api::routes::depth_map::FileBody;
use crate::api::wire::openapi::ImageErrors;
use crate::calibration::Raw;
use crate::camera::{Options, stereo_rectify};
use crate::vision::decode::{self, Decoded};
use crate::vision::encode;
use crate::vision::remap::{self, Fixed, Interpolation, Source};
use crate::vision::rows::RowOffsets;

/// `POST /rectify`.
pub fn router() -> OpenApiRouter<HeavyState> {
    OpenApiRouter::new().routes(routes!(post_rectify))
}

impl ImageForm for RectifyForm {
    const PARTS: &'static [&'static str] = &[];
}

/// What a calibration that cannot rectify lacks.
pub const NOT_RAW: &str = "describes only rectified images (a Middlebury or KITTI odometry \
     file, a Q matrix, projections without the cameras): rectifying raw frames needs each \
     camera's K and D and their pose or rectification: a stereoCalibrate file (M1 D1 M2 D2 R \
     T), a ROS CameraInfo pair with K D R P, KITTI's calib_cam_to_cam.txt with K_0i D_0i \
     R_rect_0i, or /calibrate's opencv.yml";

/// Below this share of matched pixels, a pair sent as rectified may well be raw.
pub const UNRECTIFIED_SHARE: f64 = 0.2;
/// Matched corners this many rows apart (the median) mean the rows do not line up: a
/// rectified pair's are a few tenths of a pixel.
pub const UNRECTIFIED_ROWS: f64 = 1.0;
/// The corners the row check needs before it speaks.
pub const ROW_FEATURES: usize = 8;

/// The summary's warning for a pair sent as rectified that looks raw: too few pixels matched
/// (`valid_fraction`, when the whole map was matched), or its matched corners off their rows
/// ([`crate::vision::rows`]). `None` when neither shows.
pub fn unrectified_warning(
    valid_fraction: Option<f64>,
    rows: Option<RowOffsets>,
) -> Option<String> {
    let mut signs = Vec::new();
    if let Some(share) = valid_fraction.filter(|&v| v < UNRECTIFIED_SHARE) {
        signs.push(format!("only {:.1} % of the pixels matched", share * 100.0));
    }
    if let Some(rows) =
        rows.filter(|r| r.features >= ROW_FEATURES && r.median_offset >= UNRECTIFIED_ROWS)
    {
        signs.push(format!(
            "matched corners lie {:.1} px off their rows (the median of {}; a rectified pair's \
             are under {UNRECTIFIED_ROWS} px)",
            rows.median_offset, rows.features
        ));
    }
    if signs.is_empty() {
        return None;
    }
    Some(format!(
        "{}: if these are raw frames (lens distortion, rows that do not line up between the \
         cameras), they need rectifying: send the calibration of the raw cameras (a \
         stereoCalibrate file, a ROS CameraInfo pair with D K R P, KITTI's \
         calib_cam_to_cam.txt, /calibrate's opencv.yml) as the calibration part with \
         rectify=auto, or rectify them with /rectify",
        signs.join(", and ")
    ))
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
    request_body(
        content = RectifyForm,
        content_type = "multipart/form-data",
        description = "The raw pair and the calibration of its cameras."
    ),
    responses(
        (status = 200, description = "The rectified pair in the `output` asked for.",
         headers(("Server-Timing" = String, description = "Stage times in milliseconds.")),
         content(
            (RectifySummary = "application/json"),
            (FileBody = "image/png"),
            (FileBody = "application/zip")
         )),
        ImageErrors
    )
)]
pub async fn post_rectify(
    axum::extract::State(state): axum::extract::State<HeavyState>,
    QueryParams(query, problems): QueryParams<RectifyQuery>,
    mut pair: ImagePair<RectifyForm>,
) -> Result<Response, ApiError> {
    let mut problems = pair.problems(problems);
    let output = query.output.unwrap_or_default();
    let how: Interpolation = query.interpolation.unwrap_or_default().into();
    let given = raw_rig(&pair, query.alpha, &mut problems);
    let (Some((width, height)), Some(given)) = (pair.size, given) else {
        return Err(problems.into_error());
    };
    if !problems.is_empty() {
        return Err(problems.into_error());
    }
    let raw = given.raw.clone().expect("checked by raw_rig");
    let rect = raw.rectification.size;
    let (rw, rh) = (rect.width as usize, rect.height as usize);
    // The decoded pair, the maps while they are built, both remapped images in colour and
    // grey, and the PNG being written.
    let bytes = limits::decoded_bytes(width as usize, height as usize)
        .saturating_add(Maps::bytes_for(&raw))
        .saturating_add(rw.saturating_mul(rh).saturating_mul(24));
    let need = Need {
        size: (rw, rh),
        count: 1,
        need: move |_| bytes,
    };
    let cache = state.maps.clone();
    pair.run(need, move |job| {
        compute(job.parts, &cache, &given, &raw, output, how, job.waited)
    })
    .await?
}

/// Whether an image route rectifies its pair (`mode`, with `alpha`): the raw rig to rectify
/// with, or `None` to match the pair as it is; each refusal in `problems`. The pair's rig
/// becomes the rectified rig (with `alpha` applied).
pub fn plan<F: ImageForm>(
    pair: &mut ImagePair<F>,
    mode: RectifyMode,
    alpha: Option<f64>,
    problems: &mut FieldErrors,
) -> Option<Box<Raw>> {
    let raw_frames = pair
        .rig
        .as_ref()
        .and_then(|g| g.raw.as_ref())
        .is_some_and(|raw| {
            !raw.is_identity() && Some((raw.size.width, raw.size.height)) == pair.size
        });
    let wanted = match mode {
        RectifyMode::No => false,
        RectifyMode::Yes => true,
        RectifyMode::Auto => raw_frames,
    };
    if !wanted {
        if let Some(alpha) = alpha {
            if !(0.0..=1.0).contains(&alpha) {
                problems.add("alpha", alpha_message(alpha));
            } else {
                problems.add(
                    "alpha",
                    "applies only when the pair is rectified here (rectify=yes, or auto with a \
                     calibration of raw cameras and frames of their size)",
                );
            }
        }
        return None;
    }
    let given = raw_rig(pair, alpha, problems)?;
    let raw = given.raw.clone();
    pair.rig = Some(given);
    raw
}

/// The raw rig of the request, with `alpha` applied; `None` with the reasons in `problems`
/// when the form has no calibration of raw cameras for these images.
pub fn raw_rig(
    pair: &ImagePair<impl ImageForm>,
    alpha: Option<f64>,
    problems: &mut FieldErrors,
) -> Option<GivenRig> {
    if let Some(alpha) = alpha
        && !(0.0..=1.0).contains(&alpha)
    {
        problems.add("alpha", alpha_message(alpha));
        return None;
    }
    if pair.parts.get("rig").is_some() {
        problems.add(
            "rig",
            "describes rectified images only: rectifying needs a calibration part with the \
             raw cameras",
        );
        return None;
    }
    if pair.parts.get("calibration").is_none() {
        problems.add(
            "calibration",
            "is required: the calibration of the raw cameras (a stereoCalibrate file, a ROS \
             CameraInfo pair, KITTI's calib_cam_to_cam.txt or /calibrate's opencv.yml)",
        );
        return None;
    }
    let given = pair.rig.clone()?;
    let Some(raw) = &given.raw else {
        problems.add("calibration", NOT_RAW);
        return None;
    };
    if let Some((w, h)) = pair.size
        && (raw.size.width, raw.size.height) != (w, h)
    {
        problems.add(
            "left",
            format!(
                "is {w} × {h}, but the calibration's raw frames are {} × {}: send the frames \
                 the cameras deliver, at the calibrated size",
                raw.size.width, raw.size.height
            ),
        );
        return None;
    }
    match alpha {
        Some(alpha) => with_alpha(given, alpha, problems),
        None => Some(given),
    }
}

/// The rig rectified again with `alpha`, as `cv2.stereoRectify` would.
fn with_alpha(mut given: GivenRig, alpha: f64, problems: &mut FieldErrors) -> Option<GivenRig> {
    let raw = given.raw.as_deref()?;
    let options = Options {
        alpha,
        new_size: Some(raw.rectification.size),
        ..Options::default()
    };
    let rectification = match stereo_rectify(&raw.pair, raw.size, options) {
        Ok(r) => r,
        Err(e) => {
            problems.add("calibration", format!("cannot be rectified: {e}"));
            return None;
        }
    };
    let rig = match rectification.rig(given.file_unit) {
        Ok(rig) => rig,
        Err(_) => {
            problems.add(
                "calibration",
                "the rectified cameras are one above the other (vertical stereo); this \
                 service measures horizontal disparities",
            );
            return None;
        }
    };
    given.raw = Some(Box::new(Raw {
        rectification,
        computed: true,
        ..raw.clone()
    }));
    given.rig = rig;
    Some(given)
}

/// Whether a decoded image has colour (any pixel whose channels differ).
fn has_colour(d: &Decoded) -> bool {
    d.rgb
        .as_deref()
        .is_some_and(|rgb| rgb.chunks_exact(3).any(|p| p[0] != p[1] || p[1] != p[2]))
}

/// A raw pair rectified in place for `/depth-map` and `/match`: the rig's maps from `cache`
/// (built on a miss), then [`rectify_pair`]. The time it took, for `Server-Timing`.
pub fn rectify_raw_pair(
    left: &mut Decoded,
    right: &mut Decoded,
    (raw, cache): (&Raw, &MapCache),
    colour: bool,
) -> std::time::Duration {
    let started = Instant::now();
    let (maps, _) = cache.get(raw);
    rectify_pair(left, right, &maps, colour);
    started.elapsed()
}

/// The row check of a pair sent as rectified ([`crate::vision::rows`]), over the matcher's
/// disparity range.
pub fn row_check(
    left: &Decoded,
    right: &Decoded,
    params: &crate::vision::Params,
) -> Option<RowOffsets> {
    let range = (params.min_disparity(), params.max_disparity());
    crate::vision::rows::row_offsets(&left.grey, &right.grey, range)
}

/// Both frames of a pair read through their maps: grey always, the left colours too when
/// `colour` (a point cloud's).
fn rectify_pair(left: &mut Decoded, right: &mut Decoded, maps: &Maps, colour: bool) {
    let grey = |d: &Decoded, map: &Fixed| {
        let g = &d.grey;
        crate::vision::Gray::new(
            map.width,
            map.height,
            remap::remap_fixed(
                Source {
                    width: g.width,
                    height: g.height,
                    channels: 1,
                    data: &g.data,
                },
                map,
                Interpolation::Linear,
            ),
        )
    };
    let (l, r) = rayon::join(|| grey(left, &maps.left), || grey(right, &maps.right));
    if colour && let Some(rgb) = left.rgb.as_deref() {
        let g = &left.grey;
        left.rgb = Some(remap::remap_fixed(
            Source {
                width: g.width,
                height: g.height,
                channels: 3,
                data: rgb,
            },
            &maps.left,
            Interpolation::Linear,
        ));
    }
    left.grey = l;
    right.grey = r;
}

/// A rectified image as PNG: RGB when the frame has colour, else grey, 8 bits when the frame
/// was (every level a multiple of 257), 16 otherwise.
fn png(image: &Decoded, map: &Fixed, how: Interpolation) -> Vec<u8> {
    let (w, h) = (map.width, map.height);
    let g = &image.grey;
    if has_colour(image) {
        let rgb = image.rgb.as_deref().unwrap_or_default();
        let out = remap::remap_fixed(
            Source {
                width: g.width,
                height: g.height,
                channels: 3,
                data: rgb,
            },
            map,
            how,
        );
        return encode::png_rgb(w, h, &out);
    }
    let out = remap::remap_fixed(
        Source {
            width: g.width,
            height: g.height,
            channels: 1,
            data: &g.data,
        },
        map,
        how,
    );
    if g.data.iter().all(|v| v % 257 == 0) {
        // Exact for 8-bit frames (v = 257·g); rounded for the in-between levels remapping made.
        let bytes: Vec<u8> = out
            .iter()
            .map(|&v| ((u32::from(v) + 128) / 257) as u8)
            .collect();
        encode::png_grey(w, h, &bytes)
    } else {
        encode::png16(w, h, &out)
    }
}

/// Both rectified images side by side in colour, with a green line every 32 rows.
fn side_by_side(
    left: &Decoded,
    right: &Decoded,
    maps: &Maps,
    how: Interpolation,
) -> (usize, usize, Vec<u8>) {
    let rgb = |d: &Decoded, map| {
        let g = &d.grey;
        remap::remap_fixed(
            Source {
                width: g.width,
                height: g.height,
                channels: 3,
                data: d.rgb.as_deref().unwrap_or_default(),
            },
            map,
            how,
        )
    };
    let (l, r) = rayon::join(|| rgb(left, &maps.left), || rgb(right, &maps.right));
    let (w, h) = (maps.left.width, maps.left.height);
    let mut out = vec![0u8; w * 2 * h * 3];
    for y in 0..h {
        let row = &mut out[y * w * 6..(y + 1) * w * 6];
        row[..w * 3].copy_from_slice(&l[y * w * 3..(y + 1) * w * 3]);
        row[w * 3..].copy_from_slice(&r[y * w * 3..(y + 1) * w * 3]);
        if y % 32 == 16 {
            for p in row.chunks_exact_mut(3) {
                p.copy_from_slice(&[0, 255, 0]);
            }
        }
    }
    (w * 2, h, out)
}

fn decode_both(parts: &crate::api::images::Parts) -> Result<(Decoded, Decoded), ApiError> {
    let read = |name: &str| {
        let bytes = parts.get(name).map_or(&[][..], Bytes::as_ref);
        decode::decode(bytes, limits::LIMITS, true)
            .map_err(|e| FieldError::new(name, limits::describe(&e)))
    };
    match rayon::join(|| read("left"), || read("right")) {
        (Ok(l), Ok(r)) => Ok((l, r)),
        (l, r) => Err(ApiError::Invalid(
            [l.err(), r.err()].into_iter().flatten().collect(),
        )),
    }
}

fn compute(
    parts: &crate::api::images::Parts,
    cache: &MapCache,
    given: &GivenRig,
    raw: &Raw,
    output: RectifyOutput,
    how: Interpolation,
    [read, queue]: [std::time::Duration; 2],
) -> Result<Response, ApiError> {
    let started = Instant::now();
    let ms = |d: std::time::Duration| (d.as_secs_f64() * 1e4).round() / 10.0;
    if output == RectifyOutput::MapsNpz {
        // The float maps themselves, as OpenCV makes them (the cache holds them in fixed
        // point).
        let (left, right) = float_maps(raw);
        let (w, h) = (left.size.width as usize, left.size.height as usize);
        let entries = [
            ("left_map_x", encode::npy(w, h, &left.x)),
            ("left_map_y", encode::npy(w, h, &left.y)),
            ("right_map_x", encode::npy(w, h, &right.x)),
            ("right_map_y", encode::npy(w, h, &right.y)),
        ];
        drop((left, right));
        let bytes = encode::npz(&entries)
            .map_err(|e| ApiError::Internal(format!("the NPZ was not written: {e}")))?;
        let mut response = file(bytes, output);
        set_timing(
            &mut response,
            &[
                ("read", read),
                ("queue", queue),
                ("maps", started.elapsed()),
            ],
        );
        return Ok(response);
    }
    let (maps, cached) = cache.get(raw);
    let maps_time = if cached {
        std::time::Duration::ZERO
    } else {
        started.elapsed()
    };
    let mut timing = vec![("read", read), ("queue", queue), ("maps", maps_time)];
    let body = match output {
        RectifyOutput::Summary => {
            let t = Instant::now();
            let (left, right) = decode_both(parts)?;
            let decode_time = t.elapsed();
            let t = Instant::now();
            let grey = |d: &Decoded, map| {
                remap::remap_fixed(
                    Source {
                        width: d.grey.width,
                        height: d.grey.height,
                        channels: 1,
                        data: &d.grey.data,
                    },
                    map,
                    how,
                )
            };
            let _ = rayon::join(|| grey(&left, &maps.left), || grey(&right, &maps.right));
            let remap_time = t.elapsed();
            let (w, h) = (raw.size.width as usize, raw.size.height as usize);
            let summary = RectifySummary {
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
                    left: (maps.left.valid_share(w, h) * 1e4).round() / 1e4,
                    right: (maps.right.valid_share(w, h) * 1e4).round() / 1e4,
                },
                maps_cached: cached,
                timings_ms: RectifyTimes {
                    decode: ms(decode_time),
                    maps: ms(maps_time),
                    remap: ms(remap_time),
                },
                warnings: given.warnings.clone(),
            };
            let mut response = Json(summary).into_response();
            set_timing(&mut response, &timing);
            return Ok(response);
        }
        _ => {
            let t = Instant::now();
            let (left, right) = decode_both(parts)?;
            timing.push(("decode", t.elapsed()));
            let t = Instant::now();
            let bytes = match output {
                RectifyOutput::LeftPng => png(&left, &maps.left, how),
                RectifyOutput::RightPng => png(&right, &maps.right, how),
                _ => {
                    let (w, h, rgb) = side_by_side(&left, &right, &maps, how);
                    encode::png_rgb(w, h, &rgb)
                }
            };
            timing.push(("remap", t.elapsed()));
            bytes
        }
    };
    let mut response = file(body, output);
    set_timing(&mut response, &timing);
    Ok(response)
}

/// A file answer with its media type and name.
fn file(bytes: Vec<u8>, output: RectifyOutput) -> Response {
    let mut response = bytes.into_response();
    let h = response.headers_mut();
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static(output.media_type()),
    );
    if let Ok(v) = HeaderValue::from_str(&format!(
        "{}; filename=\"{}\"",
        if output == RectifyOutput::MapsNpz {
            "attachment"
        } else {
            "inline"
        },
        output.name()
    )) {
        h.insert(header::CONTENT_DISPOSITION, v);
    }
    response
}

fn set_timing(response: &mut Response, stages: &[(&str, std::time::Duration)]) {
    let text = stages
        .iter()
        .map(|(name, d)| format!("{name};dur={:.1}", d.as_secs_f64() * 1e3))
        .collect::<Vec<_>>()
        .join(", ");
    if let Ok(v) = HeaderValue::from_str(&text) {
        response.headers_mut().insert("server-timing", v);
    }
}
