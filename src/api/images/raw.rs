//! Raw pairs for the image routes: the engine's rectify plan ([`stereo_core::pipeline::plan`])
//! asked with what the form sent and its refusals named by part, and the memory rectifying
//! takes.

use super::form::{ImageForm, ImagePair};
use super::limits;
use super::parts::Parts;
use super::work::Need;
use crate::api::error::FieldErrors;
use crate::api::wire::images::RectifyMode;
use stereo_core::calibration::files::Raw;
use stereo_core::camera::Alpha;
use stereo_core::pipeline::{self, Calibrated, Maps, PlanFault, Sent};

impl From<RectifyMode> for pipeline::RectifyMode {
    fn from(mode: RectifyMode) -> Self {
        match mode {
            RectifyMode::Auto => pipeline::RectifyMode::Auto,
            RectifyMode::Yes => pipeline::RectifyMode::Yes,
            RectifyMode::No => pipeline::RectifyMode::No,
        }
    }
}

/// What the form sent to describe its rig: a `rig` part wins, as it describes rectified
/// images whatever came with it.
fn sent<F: ImageForm>(pair: &ImagePair<F>) -> Sent {
    sent_in(&pair.parts)
}

/// What `parts` sent to describe the rig ([`sent`]).
pub fn sent_in(parts: &Parts) -> Sent {
    if parts.get("rig").is_some() {
        Sent::Rig
    } else if parts.get("calibration").is_some() {
        Sent::Calibration
    } else {
        Sent::Nothing
    }
}

/// The part a plan's refusal is about.
fn field(fault: &PlanFault) -> &'static str {
    match fault {
        PlanFault::AlphaUnused => "alpha",
        PlanFault::RigIsRectified => "rig",
        PlanFault::WrongSize { .. } => "left",
        PlanFault::NoCalibration
        | PlanFault::NotRaw
        | PlanFault::CannotRectify(_)
        | PlanFault::Vertical => "calibration",
    }
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
    let sent = sent(pair);
    plan_rig(&mut pair.rig, sent, pair.size, (mode, alpha), problems)
}

/// [`plan`] for a rig and frames of `size` that did not come in a form (a stream's): `rig`
/// becomes the rectified rig when the frames are rectified.
pub fn plan_rig(
    rig: &mut Option<Calibrated>,
    sent: Sent,
    size: Option<(u32, u32)>,
    (mode, alpha): (Option<RectifyMode>, Option<f64>),
    problems: &mut FieldErrors,
) -> Option<Box<Raw>> {
    let alpha = problems.alpha(alpha);
    let mode = mode.unwrap_or_default().into();
    match pipeline::plan(rig.as_ref(), sent, size, mode, alpha) {
        Ok(Some(calibrated)) => {
            let raw = calibrated.raw.clone();
            *rig = Some(calibrated);
            raw
        }
        Ok(None) => None,
        Err(fault) => {
            problems.add(field(&fault), fault.to_string());
            None
        }
    }
}

/// The raw rig of the request, with `alpha` applied; `None` with the reasons in `problems`
/// when the form has no calibration of raw cameras for these images.
pub fn raw_rig(
    pair: &ImagePair<impl ImageForm>,
    alpha: Option<Alpha>,
    problems: &mut FieldErrors,
) -> Option<Calibrated> {
    match pipeline::raw_rig(pair.rig.as_ref(), sent(pair), pair.size, alpha) {
        Ok(calibrated) => calibrated,
        Err(fault) => {
            problems.add(field(&fault), fault.to_string());
            None
        }
    }
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
