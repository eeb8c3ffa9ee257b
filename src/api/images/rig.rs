//! The rig of an image request, from a `rig` part (the members of `/distance`) or from a
//! `calibration` part with its options (read as `/calibration` reads a file), parsed once at
//! the request's edge into the engine's [`RigInput`] and made the rig of each frame size
//! there: a rig `/distance` refuses is refused here with the same message, its members named
//! `rig.cx`, `rig.baseline`…

use axum::body::Bytes;
use serde_json::{Map, Value};

use crate::api::error::FieldErrors;
use crate::api::extract::decode_object;
use crate::api::validate;
use crate::api::wire::calibration::{Cameras, FormatChoice, add_read_faults};
use crate::api::wire::de::request;
use crate::api::wire::params::Unit;
use crate::api::wire::rig::StereoRig;
use stereo_core::calibration::files::ReadOptions;
use stereo_core::physics::LengthUnit;
use stereo_core::pipeline::{
    self, AtFault, Calibrated, CalibrationFile, RigInput, Sent, SizeFault,
};

pub use crate::api::wire::images::{RIG_PARTS, RigParts};

/// The prefix of a rig member's name in the image routes' answers.
const RIG: &str = "rig.";

/// What a request sent to describe its rig (`parts`: a form's parts, a stream's settings, the
/// command's flags), parsed once: the `rig` member or the `calibration` members (not both),
/// a file read for images of `size` when the request has one size. `None` when either is at
/// fault (then `problems` says why); [`RigInput::Nothing`] when neither is given.
fn input(
    parts: &RigParts,
    size: Option<(u32, u32)>,
    takes_rig: bool,
    problems: &mut FieldErrors,
) -> Option<RigInput> {
    let has_calibration = parts.get("calibration").is_some();
    match (parts.get("rig"), has_calibration) {
        (Some(json), true) => {
            // Beside a calibration, a rig part may carry only the calibration's σ.
            let std = std_beside(json, problems);
            let input = calibration_parts(parts, std.flatten(), size, takes_rig, problems);
            input.filter(|_| std.is_some())
        }
        (Some(json), false) => rig_part(json, problems),
        (None, true) => calibration_parts(parts, None, size, takes_rig, problems),
        (None, false) => {
            let mut ok = true;
            for option in &RIG_PARTS[2..] {
                if parts.get(option).is_some() {
                    problems.add(option, "applies only with a calibration part");
                    ok = false;
                }
            }
            ok.then_some(RigInput::Nothing)
        }
    }
}

/// The rig `input` describes for images of `size` (unknown: `None`); `None` when nothing was
/// sent, or when it is not the rig of these images (then `problems` says why, naming the
/// calibration's parts and the rig's members `rig.…`).
pub fn at(
    input: &RigInput,
    size: Option<(u32, u32)>,
    takes_rig: bool,
    problems: &mut FieldErrors,
) -> Option<Calibrated> {
    input
        .at(size)
        .map_err(|fault| at_fault(fault, takes_rig, problems))
        .ok()
        .flatten()
}

/// What a request sent, parsed ([`input`], to make the rig of other sizes) and made the rig
/// of its images of `size` ([`at`]).
pub fn parsed(
    parts: &RigParts,
    size: Option<(u32, u32)>,
    takes_rig: bool,
    problems: &mut FieldErrors,
) -> (Option<RigInput>, Option<Calibrated>) {
    let input = input(parts, size, takes_rig, problems);
    let rig = input
        .as_ref()
        .and_then(|i| at(i, size, takes_rig, problems));
    (input, rig)
}

/// Names the parts or members an [`AtFault`] is about.
fn at_fault(fault: AtFault, takes_rig: bool, problems: &mut FieldErrors) {
    match fault {
        AtFault::Read(faults) => {
            add_read_faults(faults, ["calibration", "right_calibration"], problems);
        }
        AtFault::Size(SizeFault::Mismatch { calibrated, images }) => {
            problems.add("calibration", size_mismatch(calibrated, images, takes_rig));
        }
        AtFault::Size(SizeFault::Rig(faults)) | AtFault::Rig(faults) => {
            validate::faults(faults, RIG, problems);
        }
        AtFault::Declared(declared) => {
            for (member, declared, actual) in declared {
                problems.add(
                    &format!("{RIG}{}", member.name()),
                    format!(
                        "is {declared}, but the images are {actual} px: give the rig of these \
                         images (scale focal_length_px, cx, cy and doffs with them)"
                    ),
                );
            }
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
/// `None` when at fault.
fn std_beside(json: &Bytes, problems: &mut FieldErrors) -> Option<Option<pipeline::StdBeside>> {
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
    ok.then_some(Some(pipeline::StdBeside {
        focal_px: given.focal_length_std_px.unwrap_or(0.0),
        baseline: given.baseline_std.unwrap_or(0.0),
        unit: given.unit.map(LengthUnit::from),
    }))
}

/// Names `rig` as required, saying `why`, when the form has neither a `rig` nor a
/// `calibration` part (a part that is there but at fault is named by [`rig`] itself).
pub fn require_rig(sent: Sent, why: &str, problems: &mut FieldErrors) {
    if sent == Sent::Nothing {
        problems.add(
            "rig",
            format!(
                "is required {why}: give a rig part (the members of /distance) or a \
                 calibration part"
            ),
        );
    }
}

/// The `rig` part: a JSON object with the members of `/distance`, checked at the size it
/// declares (the images' is checked by [`at`]).
fn rig_part(json: &Bytes, problems: &mut FieldErrors) -> Option<RigInput> {
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
    let (given, refused) = decode_object::<StereoRig>(map);
    let mut local = FieldErrors::from(refused.prefixed(""));
    let spec = validate::marked_rig(given.rig_spec(), &local);
    let input = RigInput::members(spec)
        .map_err(|faults| validate::faults(faults, "", &mut local))
        .ok();
    let ok = local.is_empty();
    for error in local.prefixed(RIG) {
        problems.add_new(error.field, error.message);
    }
    input.filter(|_| ok)
}

request! {
    /// The options of a `calibration` part, each its own part.
    pub struct CalibrationOptions {
        calibration_format: FormatChoice,
        calibration_unit: Unit,
        calibration_cameras: Cameras,
    }
}

/// The calibration parts, read as `/calibration` reads a file (for images of `size`, when
/// known), with the σ sent beside them; their errors name the parts, and the rig's members
/// `rig.…`.
fn calibration_parts(
    parts: &RigParts,
    std: Option<pipeline::StdBeside>,
    size: Option<(u32, u32)>,
    takes_rig: bool,
    problems: &mut FieldErrors,
) -> Option<RigInput> {
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
    let (options, refused) = decode_object::<CalibrationOptions>(map);
    local.extend(refused);
    let text = parts.text("calibration", &mut local);
    let right_text = parts.text("right_calibration", &mut local);
    if !local.is_empty() {
        problems.extend(local);
        return None;
    }
    let file = CalibrationFile {
        text: text.unwrap_or_default(),
        right_text,
        format: options.calibration_format.unwrap_or_default().format(),
        kitti_pair: options.calibration_cameras.map(Into::into),
        options: ReadOptions {
            calibration_unit: options.calibration_unit.map(LengthUnit::from),
            unit: None,
        },
        std,
    };
    RigInput::file(file, size)
        .map_err(|fault| at_fault(fault, takes_rig, problems))
        .ok()
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
