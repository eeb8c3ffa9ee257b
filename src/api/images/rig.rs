//! The rig of an image request, from a `rig` part (the members of `/distance`) or from a
//! `calibration` part with its options (read as `/calibration` reads a file), built through
//! [`Rig::new`] like every rig: a rig `/distance` refuses is refused here with the same
//! message, its members named `rig.cx`, `rig.baseline`…

use axum::body::Bytes;
use serde_json::{Map, Value};

use crate::api::error::FieldErrors;
use crate::api::extract::decode_object;
use crate::api::validate;
use crate::api::wire::calibration::{Cameras, FormatChoice, add_read_faults};
use crate::api::wire::de::request;
use crate::api::wire::params::Unit;
use crate::api::wire::rig::StereoRig;
use stereo_core::calibration::files::{self, ReadOptions, Source};
use stereo_core::physics::LengthUnit;
use stereo_core::pipeline::{Calibrated, SizeFault};

pub use crate::api::wire::images::{RIG_PARTS, RigInput};

/// The prefix of a rig member's name in the image routes' answers.
const RIG: &str = "rig.";

/// The rig from the `rig` member or the `calibration` members (not both) that a request sent
/// (`parts`: a form's parts, a stream's settings), for images of `size`;
/// `None` when neither is given or either is at fault (then `problems` says why).
pub fn rig(
    parts: &RigInput,
    size: Option<(u32, u32)>,
    takes_rig: bool,
    problems: &mut FieldErrors,
) -> Option<Calibrated> {
    let has_calibration = parts.get("calibration").is_some();
    match (parts.get("rig"), has_calibration) {
        (Some(json), true) => {
            // Beside a calibration, a rig part may carry only the calibration's σ.
            let std = std_beside(json, problems);
            let given = calibration_parts(parts, size, takes_rig, problems)?;
            let (focal, baseline, unit) = std?;
            let unit = unit.map_or(given.rig.unit(), LengthUnit::from);
            let baseline = unit.convert(baseline, given.rig.unit());
            match given.rig.with_calibration_std(focal, baseline) {
                Ok(rig) => Some(Calibrated { rig, ..given }),
                Err(faults) => {
                    validate::faults(faults, RIG, problems);
                    None
                }
            }
        }
        (Some(json), false) => rig_part(json, size, problems),
        (None, true) => calibration_parts(parts, size, takes_rig, problems),
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

request! {
    /// A `rig` part beside a `calibration` part: only the calibration's σ, which a file from
    /// elsewhere does not carry.
    pub struct StdBeside {
        focal_length_std_px: f64,
        baseline_std: f64,
        unit: Unit,
    }
}

/// A `rig` part beside a `calibration` part: `focal_length_std_px` and `baseline_std` (in
/// `unit`, default the calibration's), each 0 when absent; any other member is named.
fn std_beside(json: &Bytes, problems: &mut FieldErrors) -> Option<(f64, f64, Option<Unit>)> {
    let Ok(Value::Object(map)) = serde_json::from_slice::<Value>(json) else {
        problems.add(
            "rig",
            "beside a calibration part, must be a JSON object holding only the calibration's \
             σ: {\"focal_length_std_px\": …, \"baseline_std\": …}",
        );
        return None;
    };
    let foreign: Vec<String> = map
        .keys()
        .filter(|k| !["focal_length_std_px", "baseline_std", "unit"].contains(&k.as_str()))
        .cloned()
        .collect();
    let (given, mut refused) = decode_object::<StdBeside>(map);
    for key in &foreign {
        refused.reword(
            key,
            "is given by the calibration part: beside it, rig holds only \
             focal_length_std_px, baseline_std and their unit",
        );
    }
    let ok = refused.is_empty();
    for error in refused.prefixed(RIG) {
        problems.add_new(error.field, error.message);
    }
    ok.then(|| {
        (
            given.focal_length_std_px.unwrap_or(0.0),
            given.baseline_std.unwrap_or(0.0),
            given.unit,
        )
    })
}

/// Names `rig` as required, saying `why`, when the form has neither a `rig` nor a
/// `calibration` part (a part that is there but at fault is named by [`rig`] itself).
pub fn require_rig(parts: &RigInput, why: &str, problems: &mut FieldErrors) {
    if !parts.has_rig() {
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
) -> Option<Calibrated> {
    let map = match serde_json::from_slice::<Value>(json) {
        Ok(Value::Object(map)) => map,
        Ok(other) => {
            problems.add(
                "rig",
                format!(
                    "must be a JSON object of rig members, got {}",
                    crate::api::member_messages::describe(&other)
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
    let rig = validate::rig(given.rig_spec(), &mut local);
    let ok = local.is_empty();
    for error in local.prefixed(RIG) {
        problems.add_new(error.field, error.message);
    }
    rig.filter(|_| ok).map(Calibrated::of_rig)
}

request! {
    /// The options of a `calibration` part, each its own part.
    pub struct CalibrationParts {
        calibration_format: FormatChoice,
        calibration_unit: Unit,
        calibration_cameras: Cameras,
    }
}

/// The calibration parts, read as `/calibration` reads a file; their errors name the parts,
/// and the rig's members `rig.…`.
fn calibration_parts(
    parts: &RigInput,
    size: Option<(u32, u32)>,
    takes_rig: bool,
    problems: &mut FieldErrors,
) -> Option<Calibrated> {
    let mut local = FieldErrors::default();
    let mut map = Map::new();
    for part in [
        "calibration_format",
        "calibration_unit",
        "calibration_cameras",
    ] {
        if let Some(text) = parts.text(part, &mut local) {
            map.insert(part.to_owned(), Value::String(text.trim().to_owned()));
        }
    }
    let (options, refused) = decode_object::<CalibrationParts>(map);
    local.extend(refused);
    let text = parts.text("calibration", &mut local);
    let right_text = parts.text("right_calibration", &mut local);
    if !local.is_empty() {
        problems.extend(local);
        return None;
    }
    let source = Source {
        text: text.as_deref().unwrap_or_default(),
        right_text: right_text.as_deref(),
        format: options.calibration_format.unwrap_or_default().format(),
        kitti_pair: options.calibration_cameras.map(Into::into),
        alpha: None,
        image_size: size,
    };
    let read = files::read(
        source,
        ReadOptions {
            calibration_unit: options.calibration_unit.map(LengthUnit::from),
            unit: None,
        },
    );
    let read = match read {
        Ok(read) => read,
        Err(faults) => {
            add_read_faults(faults, ["calibration", "right_calibration"], problems);
            return None;
        }
    };
    match Calibrated::from_file(read, size) {
        Ok(calibrated) => Some(calibrated),
        Err(SizeFault::Mismatch { calibrated, images }) => {
            problems.add("calibration", size_mismatch(calibrated, images, takes_rig));
            None
        }
        Err(SizeFault::Rig(faults)) => {
            validate::faults(faults, RIG, problems);
            None
        }
    }
}

/// Why images of `(w, h)` do not fit a calibration of `(cw, ch)`, with the scale when it is a
/// whole ratio (half-size frames, or a calibration made at half size).
fn size_mismatch((cw, ch): (f64, f64), (w, h): (u32, u32), takes_rig: bool) -> String {
    let (w, h) = (f64::from(w), f64::from(h));
    let whole = |a: f64, b: f64| {
        let r = a / b;
        (r.fract() == 0.0 && r >= 2.0).then_some(r)
    };
    let scale = match (whole(cw, w), whole(ch, h), whole(w, cw), whole(h, ch)) {
        (Some(a), Some(b), _, _) if a == b => {
            format!(
                " (the images are 1/{} of the calibrated size: scale them up, or calibrate at this size)",
                stereo_core::numbers::Num(a)
            )
        }
        (_, _, Some(a), Some(b)) if a == b => {
            format!(
                " (the images are {}× the calibrated size: scale them down, or calibrate at this size)",
                stereo_core::numbers::Num(a)
            )
        }
        _ => String::new(),
    };
    let or_a_rig = if takes_rig {
        ", or a rig part with f, cx, cy and doffs scaled to them"
    } else {
        ""
    };
    format!(
        "is for {} × {} images, but these are {} × {}{scale}: give the calibration of these \
         images{or_a_rig}",
        stereo_core::numbers::Num(cw),
        stereo_core::numbers::Num(ch),
        stereo_core::numbers::Num(w),
        stereo_core::numbers::Num(h)
    )
}
