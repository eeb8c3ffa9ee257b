//! Raw pairs for the image routes: whether a request rectifies its pair (the raw rig with its
//! `alpha`, or why not), the memory rectifying takes, both frames read through the rig's
//! cached maps, and the row check (with its warning) of a pair sent as rectified.

use std::time::{Duration, Instant};

use super::form::{ImageForm, ImagePair};
use super::limits;
use super::maps::{MapCache, Maps};
use super::rig::GivenRig;
use super::work::Need;
use crate::api::error::FieldErrors;
use crate::api::wire::images::RectifyMode;
use stereo_core::calibration::files::Raw;
use stereo_core::camera::{Alpha, RectifyOptions, stereo_rectify};
use stereo_core::vision::decode::Decoded;
use stereo_core::vision::remap::{self, Fixed, Interpolation, RawImage};
use stereo_core::vision::rows::RowOffsets;

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
/// ([`stereo_core::vision::rows`]). `None` when neither shows.
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

/// Whether an image route rectifies its pair (`mode`, with `alpha`): the raw rig to rectify
/// with, or `None` to match the pair as it is; each refusal in `problems`. The pair's rig
/// becomes the rectified rig (with `alpha` applied).
pub fn plan<F: ImageForm>(
    pair: &mut ImagePair<F>,
    mode: Option<RectifyMode>,
    alpha: Option<f64>,
    problems: &mut FieldErrors,
) -> Option<Box<Raw>> {
    let alpha = problems.alpha(alpha);
    let raw_frames = pair
        .rig
        .as_ref()
        .and_then(|g| g.raw.as_ref())
        .is_some_and(|raw| {
            !raw.is_identity() && Some((raw.size.width, raw.size.height)) == pair.size
        });
    let wanted = match mode.unwrap_or_default() {
        RectifyMode::No => false,
        RectifyMode::Yes => true,
        RectifyMode::Auto => raw_frames,
    };
    if !wanted {
        if alpha.is_some() {
            problems.add(
                "alpha",
                "applies only when the pair is rectified here (rectify=yes, or auto with a \
                 calibration of raw cameras and frames of their size)",
            );
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
    alpha: Option<Alpha>,
    problems: &mut FieldErrors,
) -> Option<GivenRig> {
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
fn with_alpha(mut given: GivenRig, alpha: Alpha, problems: &mut FieldErrors) -> Option<GivenRig> {
    let raw = given.raw.as_deref()?;
    let options = RectifyOptions {
        alpha,
        new_size: Some(raw.rectification.size),
        ..RectifyOptions::default()
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

/// What matching a pair of `size` over `count` disparities needs: a raw pair is decoded at
/// its own size, its maps built (or found), and matched at the rectified size; a pair sent as
/// rectified is matched as it is. `bytes(w, h, count)` is the route's own need at the size
/// matched; the rectification's is added to it.
pub fn match_need<B: Fn(usize, usize, usize) -> usize>(
    raw: Option<&Raw>,
    (width, height): (u32, u32),
    count: usize,
    bytes: B,
) -> Need<impl Fn(usize) -> usize + use<B>> {
    let ((w, h), extra) = match raw {
        Some(raw) => {
            let s = raw.rectification.size;
            ((s.width as usize, s.height as usize), rectifying_bytes(raw))
        }
        None => ((width as usize, height as usize), 0),
    };
    Need {
        size: (w, h),
        count,
        need: move |count| bytes(w, h, count).saturating_add(extra),
    }
}

/// The bytes rectifying a raw pair holds: the decoded frames and the maps while they are built.
pub fn rectifying_bytes(raw: &Raw) -> usize {
    limits::decoded_bytes(raw.size.width as usize, raw.size.height as usize)
        .saturating_add(Maps::bytes_for(raw))
}

/// A raw pair rectified in place for `/depth-map` and `/match`: the rig's maps from `cache`
/// (built on a miss), then [`rectify_pair`]. The time it took, for `Server-Timing`.
pub fn rectify_raw_pair(
    left: &mut Decoded,
    right: &mut Decoded,
    (raw, cache): (&Raw, &MapCache),
    colour: bool,
) -> Duration {
    let started = Instant::now();
    let (maps, _) = cache.get(raw);
    rectify_pair(left, right, &maps, colour);
    started.elapsed()
}

/// The row check of a pair sent as rectified ([`stereo_core::vision::rows`]), over the matcher's
/// disparity range.
pub fn row_check(
    left: &Decoded,
    right: &Decoded,
    params: &stereo_core::vision::Params,
) -> Option<RowOffsets> {
    let range = (params.min_disparity(), params.max_disparity());
    stereo_core::vision::rows::row_offsets(&left.grey, &right.grey, range)
}

/// Both frames of a pair read through their maps: grey always, the left colours too when
/// `colour` (a point cloud's).
fn rectify_pair(left: &mut Decoded, right: &mut Decoded, maps: &Maps, colour: bool) {
    let grey = |d: &Decoded, map: &Fixed| {
        let g = &d.grey;
        stereo_core::vision::Gray::new(
            map.width,
            map.height,
            remap::remap_fixed(RawImage::grey(g), map, Interpolation::Linear),
        )
    };
    let (l, r) = rayon::join(|| grey(left, &maps.left), || grey(right, &maps.right));
    if colour && let Some(rgb) = left.rgb.as_deref() {
        let g = &left.grey;
        left.rgb = Some(remap::remap_fixed(
            RawImage {
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
