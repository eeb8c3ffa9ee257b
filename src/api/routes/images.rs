//! What the image routes (`/depth-map`, and `/match` after it) share: the multipart form read
//! into named parts, the rig from a `rig` part or a `calibration` file, the pair's sizes judged
//! against the limits and the memory budget before anything is decoded, and the work run on a
//! blocking thread that stops when its request is abandoned.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use axum::body::Bytes;
use axum::extract::Multipart;
use axum::extract::multipart::MultipartRejection;
use serde_json::{Map, Value};

use super::calibration::types::{CalibratedRig, CalibrationRequest};
use super::distance::types::StereoRig;
use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::extract::decode_object;
use crate::api::validate::{self, Use};
use crate::api::wire::params::Unit;
use crate::budget::{Refusal, Reservation};
use crate::physics::{DEFAULT_DISPARITY_ERROR_PX, LengthUnit, Rig};
use crate::vision::decode::{self, DecodeError, Decoded, Limits};

/// The widest or tallest image accepted, in pixels.
pub const MAX_SIDE: u32 = 8192;
/// The most pixels an image may have: 12 megapixels (4000 × 3000).
pub const MAX_PIXELS: u64 = 12_000_000;
/// The most disparities one search covers.
pub const MAX_DISPARITIES: usize = 512;
/// The disparity search's end when neither the request nor a calibration file gives one.
pub const DEFAULT_MAX_DISPARITY: i32 = 128;

/// The decoder's limits for every image route.
pub const LIMITS: Limits = Limits {
    max_side: MAX_SIDE,
    max_pixels: MAX_PIXELS,
};

/// The media type the image routes read.
pub const MULTIPART: &str = "multipart/form-data";

/// The parts of a multipart form, by name.
#[derive(Debug, Default)]
pub struct Parts(BTreeMap<String, Bytes>);

impl Parts {
    pub fn get(&self, name: &str) -> Option<&Bytes> {
        self.0.get(name)
    }

    /// The part as UTF-8 text, or an error naming it.
    pub fn text(&self, name: &str, problems: &mut FieldErrors) -> Option<String> {
        let bytes = self.get(name)?;
        match std::str::from_utf8(bytes) {
            Ok(text) => Some(text.to_owned()),
            Err(e) => {
                problems.add(
                    name,
                    format!("must be UTF-8 text; byte {} is not", e.valid_up_to()),
                );
                None
            }
        }
    }
}

/// Reads every part of the form. A part this route does not read, a part given twice or one
/// without a name is recorded in `problems`, naming it; the form itself failing is an error.
pub async fn read_parts(
    form: Result<Multipart, MultipartRejection>,
    known: &[&str],
    limit: usize,
    problems: &mut FieldErrors,
) -> Result<Parts, ApiError> {
    let mut form = form.map_err(|rejection| ApiError::UnsupportedMediaType {
        got: rejection.body_text(),
        accepted: MULTIPART,
    })?;
    let mut parts = Parts::default();
    loop {
        let field = match form.next_field().await {
            Ok(Some(field)) => field,
            Ok(None) => break,
            Err(e) => return Err(multipart_error(&e, limit)),
        };
        let name = field.name().unwrap_or_default().to_owned();
        let bytes = field
            .bytes()
            .await
            .map_err(|e| multipart_error(&e, limit))?;
        if name.is_empty() {
            problems.add("body", "has a part without a name; name each part");
        } else if !known.contains(&name.as_str()) {
            problems.add_new(
                clip_name(&name),
                format!(
                    "is not a part of this request; the parts are {}",
                    known.join(", ")
                ),
            );
        } else if parts.0.insert(name.clone(), bytes).is_some() {
            problems.add(&name, "is given more than once; give it once");
        }
    }
    Ok(parts)
}

fn clip_name(name: &str) -> String {
    crate::numbers::clip(name, crate::api::wording::ECHO)
}

/// A multipart body that cannot be read: too large (413) or broken (400).
fn multipart_error(e: &axum::extract::multipart::MultipartError, limit: usize) -> ApiError {
    if e.status() == axum::http::StatusCode::PAYLOAD_TOO_LARGE {
        ApiError::PayloadTooLarge(limit)
    } else {
        ApiError::Malformed(FieldError::new(
            "body",
            format!(
                "is not a readable multipart/form-data body: {}",
                e.body_text()
            ),
        ))
    }
}

/// The size of one image of the pair, from its header, or why it cannot be read.
pub fn image_size(parts: &Parts, name: &str, problems: &mut FieldErrors) -> Option<(u32, u32)> {
    let Some(bytes) = parts.get(name) else {
        problems.add(
            name,
            format!("is required: the {name} image of the rectified pair (PNG or JPEG)"),
        );
        return None;
    };
    match decode::dimensions(bytes) {
        Ok(size) => Some(size),
        Err(e) => {
            problems.add(name, describe(&e));
            None
        }
    }
}

/// What a decode error says about a part.
pub fn describe(e: &DecodeError) -> String {
    match e {
        DecodeError::NotAnImage => "is not an image: send a PNG or JPEG file".to_owned(),
        DecodeError::Unsupported(format) => {
            format!("is a {format} file; send the image as PNG or JPEG")
        }
        DecodeError::TooLarge { width, height, .. } => too_many_pixels(*width, *height),
        DecodeError::Corrupt(what) => {
            format!("could not be decoded: {}", crate::numbers::clip(what, 120))
        }
    }
}

fn too_many_pixels(width: u32, height: u32) -> String {
    format!(
        "is {width} × {height} pixels; this server takes at most {MAX_SIDE} pixels a side and \
         {} megapixels: send smaller images (scale the rig with them)",
        MAX_PIXELS / 1_000_000
    )
}

/// Checks the pair's sizes: each within the limits (413 otherwise), and the right the same
/// size as the left (naming `right`).
pub fn check_pair(
    left: (u32, u32),
    right: (u32, u32),
    problems: &mut FieldErrors,
) -> Result<(), ApiError> {
    let over = |(w, h): (u32, u32)| {
        w > MAX_SIDE || h > MAX_SIDE || u64::from(w) * u64::from(h) > MAX_PIXELS
    };
    let mut oversized = Vec::new();
    for (name, size) in [("left", left), ("right", right)] {
        if over(size) {
            oversized.push(FieldError::new(name, too_many_pixels(size.0, size.1)));
        }
    }
    if !oversized.is_empty() {
        return Err(ApiError::Oversized(oversized));
    }
    if left != right {
        problems.add(
            "right",
            format!(
                "is {} × {} pixels but the left image is {} × {}: a rectified pair has one size",
                right.0, right.1, left.0, left.1
            ),
        );
    }
    Ok(())
}

/// The disparity search range from the query's `min_disparity` and `max_disparity`, with the
/// calibration's `ndisp` as the default end: `(min, count)`, or `None` with the fault named.
pub fn disparity_range(
    min: Option<i32>,
    max: Option<i32>,
    ndisp: Option<u32>,
    problems: &mut FieldErrors,
) -> Option<(i32, usize)> {
    let min = min.unwrap_or(0);
    let mut ok = true;
    if !(-4096..=4096).contains(&min) {
        problems.add(
            "min_disparity",
            format!("must lie in [-4096, 4096], got {min}"),
        );
        ok = false;
    }
    let max = max.unwrap_or_else(|| {
        ndisp.map_or(DEFAULT_MAX_DISPARITY, |n| {
            i32::try_from(n.min(MAX_DISPARITIES as u32)).unwrap_or(DEFAULT_MAX_DISPARITY)
        })
    });
    let count = i64::from(max) - i64::from(min);
    if count < 1 {
        problems.add(
            "max_disparity",
            format!("must be greater than min_disparity ({min}), got {max}"),
        );
    } else if count > MAX_DISPARITIES as i64 {
        problems.add(
            "max_disparity",
            format!(
                "searches {count} disparities from min_disparity {min}; at most \
                 {MAX_DISPARITIES} fit: narrow the range"
            ),
        );
    }
    let count = usize::try_from(count)
        .ok()
        .filter(|c| (1..=MAX_DISPARITIES).contains(c))?;
    ok.then_some((min, count))
}

/// The rig of a request, and what its calibration file adds.
#[derive(Debug, Clone, PartialEq)]
pub struct GivenRig {
    pub rig: Rig,
    /// The rig in the members `/calibration` answers, to echo.
    pub echo: CalibratedRig,
    /// The calibration file's disparity range (Middlebury `ndisp`).
    pub max_disparity: Option<u32>,
    pub warnings: Vec<String>,
}

/// The parts that carry a rig.
pub const RIG_PARTS: [&str; 6] = [
    "rig",
    "calibration",
    "calibration_format",
    "right_calibration",
    "calibration_unit",
    "calibration_cameras",
];

/// The rig from the `rig` part or the `calibration` parts (not both), for images of `size`;
/// `None` when neither is given or either is at fault (then `problems` says why).
pub fn rig(
    parts: &Parts,
    size: Option<(u32, u32)>,
    problems: &mut FieldErrors,
) -> Option<GivenRig> {
    let has_calibration = parts.get("calibration").is_some();
    match (parts.get("rig"), has_calibration) {
        (Some(_), true) => {
            problems.add("rig", "give rig or calibration, not both");
            problems.add("calibration", "give rig or calibration, not both");
            None
        }
        (Some(json), false) => rig_part(json, size, problems),
        (None, true) => calibration_parts(parts, size, problems),
        (None, false) => {
            for option in &RIG_PARTS[2..] {
                if parts.get(option).is_some() {
                    problems.add(option, "applies only with a calibration part");
                }
            }
            None
        }
    }
}

/// Names `rig` as required, saying `why`, when the form has neither a `rig` nor a
/// `calibration` part (a part that is there but at fault is named by [`rig`] itself).
pub fn require_rig(parts: &Parts, why: &str, problems: &mut FieldErrors) {
    if parts.get("rig").is_none() && parts.get("calibration").is_none() {
        problems.add(
            "rig",
            format!(
                "is required {why}: give a rig part (the members of /distance) or a \
                 calibration part"
            ),
        );
    }
}

/// The `rig` part: a JSON object with the members of `/distance`.
fn rig_part(
    json: &Bytes,
    size: Option<(u32, u32)>,
    problems: &mut FieldErrors,
) -> Option<GivenRig> {
    let map = match serde_json::from_slice::<Value>(json) {
        Ok(Value::Object(map)) => map,
        Ok(other) => {
            problems.add(
                "rig",
                format!(
                    "must be a JSON object of rig members, got {}",
                    crate::api::wording::describe(&other)
                ),
            );
            return None;
        }
        Err(e) => {
            problems.add("rig", format!("must be a JSON object of rig members: {e}"));
            return None;
        }
    };
    let (mut given, refused) = decode_object::<StereoRig>(map);
    let mut local = FieldErrors::from(refused.prefixed(""));
    if let Some((w, h)) = size {
        for (field, declared, actual) in [
            ("image_width", &mut given.image_width, w),
            ("image_height", &mut given.image_height, h),
        ] {
            match *declared {
                None => *declared = Some(actual),
                Some(d) if d != actual => local.add(
                    field,
                    format!(
                        "is {d}, but the images are {actual} px: give the rig of these images \
                         (scale focal_length_px, cx, cy and doffs with them)"
                    ),
                ),
                Some(_) => {}
            }
        }
    }
    let rig = validate::rig(&given.rig_params(), Use::Points, &mut local);
    let ok = local.is_empty();
    for error in local.prefixed("rig.") {
        problems.add_new(error.field, error.message);
    }
    let rig = rig.filter(|_| ok)?;
    Some(GivenRig {
        echo: echo(&rig),
        rig,
        max_disparity: None,
        warnings: Vec::new(),
    })
}

/// The rig's members as `/calibration` answers them.
fn echo(rig: &Rig) -> CalibratedRig {
    CalibratedRig {
        focal_length_px: rig.focal_px,
        focal_length_y_px: (rig.focal_y_px != rig.focal_px).then_some(rig.focal_y_px),
        baseline: rig.baseline,
        unit: Unit::from(rig.unit),
        cx: rig.cx,
        cy: rig.cy,
        doffs: rig.doffs,
        image_width: rig.image_width.map(|w| w as u32),
        image_height: rig.image_height.map(|h| h as u32),
    }
}

/// The calibration parts, read as `/calibration` reads them; their errors name the parts.
fn calibration_parts(
    parts: &Parts,
    size: Option<(u32, u32)>,
    problems: &mut FieldErrors,
) -> Option<GivenRig> {
    // The part names, and the member each is in a calibration request.
    const MEMBERS: [(&str, &str); 5] = [
        ("calibration", "text"),
        ("right_calibration", "right_text"),
        ("calibration_format", "format"),
        ("calibration_unit", "calibration_unit"),
        ("calibration_cameras", "cameras"),
    ];
    let mut map = Map::new();
    let mut local = FieldErrors::default();
    for (part, member) in MEMBERS {
        if let Some(text) = parts.text(part, &mut local) {
            map.insert(member.to_owned(), Value::String(text.trim().to_owned()));
        }
    }
    if let Some(Value::String(text)) = map.get_mut("text") {
        // The file's own text, untrimmed.
        if let Some(raw) = parts.text("calibration", &mut FieldErrors::default()) {
            *text = raw;
        }
    }
    let rename = |field: &str| {
        MEMBERS
            .iter()
            .find(|(_, member)| *member == field)
            .map_or(field, |(part, _)| part)
            .to_owned()
    };
    let (request, refused) = decode_object::<CalibrationRequest>(map);
    for e in refused.iter() {
        local.add(&rename(&e.field), e.message.clone());
    }
    if !local.is_empty() {
        problems.extend(local);
        return None;
    }
    let read = match super::calibration::read(&request, FieldErrors::default()) {
        Ok(read) => read,
        Err(ApiError::Invalid(errors)) => {
            for e in errors {
                problems.add(&rename(&e.field), e.message);
            }
            return None;
        }
        Err(other) => {
            for e in other.problem().errors {
                problems.add(&rename(&e.field), e.message);
            }
            return None;
        }
    };
    let r = read.rig;
    if let (Some((w, h)), Some(cw), Some(ch)) = (size, r.image_width, r.image_height)
        && (cw, ch) != (w, h)
    {
        problems.add(
            "calibration",
            format!(
                "is for {cw} × {ch} images, but these are {w} × {h}: give the calibration of \
                 these images, or a rig part with f, cx, cy and doffs scaled by {}",
                crate::numbers::Num(f64::from(w) / f64::from(cw))
            ),
        );
        return None;
    }
    let rig = Rig {
        focal_px: r.focal_length_px,
        focal_y_px: r.focal_length_y_px.unwrap_or(r.focal_length_px),
        baseline: r.baseline,
        unit: LengthUnit::from(r.unit),
        image_width: size.map(|s| f64::from(s.0)),
        image_height: size.map(|s| f64::from(s.1)),
        cx: r.cx,
        cy: r.cy,
        doffs: r.doffs,
        disparity_error_px: DEFAULT_DISPARITY_ERROR_PX,
    };
    Some(GivenRig {
        echo: echo(&rig),
        rig,
        max_disparity: read.max_disparity_px,
        warnings: read.warnings,
    })
}

/// Holds the memory the request will use, or says why not: 503 while other requests hold the
/// budget, 413 naming what to shrink when it would never fit.
pub fn reserve(
    reservation: &Reservation,
    bytes: usize,
    shrink: impl FnOnce(usize) -> Vec<FieldError>,
) -> Result<(), ApiError> {
    match reservation.grow(bytes) {
        Ok(()) => Ok(()),
        Err(Refusal::TooLarge { total, .. }) => Err(ApiError::Oversized(shrink(total))),
        Err(busy) => Err(ApiError::Memory(busy)),
    }
}

/// Sets its flag when dropped: the request's future was dropped (timed out, or its client
/// went away), so the blocking work should stop at its next check.
struct CancelOnDrop(Arc<AtomicBool>);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

/// Runs `work` on a blocking thread, off the async runtime, holding `reservation` until the
/// work ends. The flag `work` gets is set when this future is dropped.
pub async fn blocking<T: Send + 'static>(
    reservation: Reservation,
    work: impl FnOnce(&AtomicBool) -> T + Send + 'static,
) -> Result<T, ApiError> {
    let flag = Arc::new(AtomicBool::new(false));
    let _cancel = CancelOnDrop(Arc::clone(&flag));
    tokio::task::spawn_blocking(move || {
        let _held = reservation;
        work(&flag)
    })
    .await
    .map_err(|e| {
        if e.is_panic() {
            std::panic::resume_unwind(e.into_panic())
        } else {
            ApiError::Internal("the image work was stopped".to_owned())
        }
    })
}

/// Both images of the pair decoded at once (on the matcher's pool), the left in colour too
/// when `colour`; a 422 naming each image that cannot be decoded.
pub fn decode_pair(parts: &Parts, colour: bool) -> Result<(Decoded, Decoded), ApiError> {
    let read = |name: &str| {
        let bytes = parts.get(name).map_or(&[][..], Bytes::as_ref);
        decode::decode(bytes, LIMITS, colour && name == "left")
            .map_err(|e| FieldError::new(name, describe(&e)))
    };
    match rayon::join(|| read("left"), || read("right")) {
        (Ok(l), Ok(r)) => Ok((l, r)),
        (l, r) => Err(ApiError::Invalid(
            [l.err(), r.err()].into_iter().flatten().collect(),
        )),
    }
}

/// The bytes the decoded pair holds: for each image, the decoder's buffer at up to 8 bytes a
/// pixel and the grey levels at 2.
pub fn decoded_bytes(width: usize, height: usize) -> usize {
    width.saturating_mul(height).saturating_mul(2 * (8 + 2))
}

/// `Server-Timing: decode;dur=12.3, cost;dur=…`, in milliseconds.
pub fn server_timing(stages: &[(&str, std::time::Duration)]) -> String {
    stages
        .iter()
        .map(|(name, d)| format!("{name};dur={:.1}", d.as_secs_f64() * 1e3))
        .collect::<Vec<_>>()
        .join(", ")
}
