//! `/calibrate`'s `initial` parts: an earlier calibration of the pair, read as the image
//! routes read their `calibration` parts (each part renamed `initial…`, and so named in the
//! errors), made the engine's [`engine::Initial`] for the views' size.

use crate::api::error::FieldErrors;
use crate::api::images::rig::{self, RigParts};
use crate::api::wire::board_calibration::{ModelChoice, RefineChoice};
use stereo_core::physics::LengthUnit;
use stereo_core::pipeline::Calibrated;
use stereo_core::pipeline::calibrate as engine;

/// Each `initial` part and the image routes' part it is read as.
pub const INITIAL_PARTS: [(&str, &str); 6] = [
    ("initial", "calibration"),
    ("initial_right", "right_calibration"),
    ("initial_format", "calibration_format"),
    ("initial_unit", "calibration_unit"),
    ("initial_cameras", "calibration_cameras"),
    ("initial_rig", "rig"),
];

/// The image routes' part a form's part is read as, when it is one of [`INITIAL_PARTS`].
pub fn read_as(name: &str) -> Option<&'static str> {
    INITIAL_PARTS
        .iter()
        .find(|(ours, _)| *ours == name)
        .map(|(_, theirs)| *theirs)
}

/// A field the calibration reader named (`calibration`, `rig.baseline_std`…) as this form
/// calls it (`initial`, `initial_rig.baseline_std`…).
fn renamed(field: &str) -> String {
    for (ours, theirs) in INITIAL_PARTS {
        if field == theirs {
            return ours.to_owned();
        }
        if let Some(rest) = field.strip_prefix(theirs)
            && rest.starts_with('.')
        {
            return format!("{ours}{rest}");
        }
    }
    field.to_owned()
}

/// What the rest of the request says of the earlier calibration: what moves, the lens model
/// asked for, whether the views are pairs.
pub struct Asked {
    pub refine: Option<RefineChoice>,
    pub model: Option<ModelChoice>,
    pub stereo: bool,
}

/// The earlier calibration the form sent (`parts`, read as the image routes' parts), for
/// views of `size`, its T in the board's `unit`; `asked` says what moves. `None` when none
/// was sent or it is at fault (then `problems` names each part): one that describes
/// rectified images only, or cameras of another size; one camera's views; another lens model
/// asked for; a `refine` or an `initial_…` part without one.
pub fn read(
    parts: &RigParts,
    size: Option<(u32, u32)>,
    unit: LengthUnit,
    asked: &Asked,
    problems: &mut FieldErrors,
) -> Option<engine::Initial> {
    if parts.get("calibration").is_none() {
        strays(parts, "applies only with an initial part", problems);
        if asked.refine.is_some() {
            problems.add(
                "refine",
                "applies only with an initial part: the calibration to start from",
            );
        }
        return None;
    }
    let calibrated = raw_calibration(parts, size, problems)?;
    let raw = calibrated.raw.as_deref()?;
    let mut pair = raw.pair;
    pair.translation *= calibrated.file_unit.convert(1.0, unit);
    judge(pair.left.distortion().model(), asked, problems);
    let rig = &calibrated.rig;
    let rig_std = (rig.focal_std_px() > 0.0 || rig.baseline_std() > 0.0)
        .then(|| [rig.focal_std_px(), rig.baseline_std() / rig.baseline()]);
    Some(engine::Initial {
        start: engine::Start {
            pair,
            hold: asked.refine.unwrap_or_default() == RefineChoice::Extrinsics,
        },
        rig_std,
        // Its reader's sentences, its parts named as this form names them.
        warnings: calibrated
            .warnings
            .iter()
            .map(|w| w.replace("calibration_unit", "initial_unit"))
            .collect(),
    })
}

/// Names each `initial…` part sent, saying `why` it does not apply (no `initial`, or a
/// route that does not take one).
pub fn strays(parts: &RigParts, why: &str, problems: &mut FieldErrors) {
    for (ours, theirs) in INITIAL_PARTS {
        if parts.get(theirs).is_some() {
            problems.add(ours, why);
        }
    }
}

/// The earlier calibration read for views of `size`, its faults named as this form names
/// the parts; `None` unless it describes the raw cameras of views of that size.
fn raw_calibration(
    parts: &RigParts,
    size: Option<(u32, u32)>,
    problems: &mut FieldErrors,
) -> Option<Calibrated> {
    let mut found = FieldErrors::default();
    let (_, calibrated) = rig::parsed(parts, size, false, &mut found);
    for error in found.iter() {
        problems.add(&renamed(&error.field), error.message.clone());
    }
    let calibrated = calibrated?;
    let Some(raw) = calibrated.raw.as_deref() else {
        problems.add(
            "initial",
            "describes rectified images only (a rig's f, B, cx, cy): to start from it, \
             /calibrate needs the raw cameras (K, D, R, T), as its own opencv.yml or a ROS \
             CameraInfo pair gives them",
        );
        return None;
    };
    let raw_size = (raw.size.width, raw.size.height);
    if let Some((w, h)) = size.filter(|s| *s != raw_size) {
        problems.add(
            "initial",
            format!(
                "calibrates {} × {} images, but the views are {w} × {h}: start from a \
                 calibration of this camera at this resolution",
                raw_size.0, raw_size.1
            ),
        );
        return None;
    }
    Some(calibrated)
}

/// What the rest of the request must agree with: pairs, and the earlier lens `model`.
fn judge(model: engine::Model, asked: &Asked, problems: &mut FieldErrors) {
    if !asked.stereo {
        problems.add(
            "initial",
            "calibrates a pair again: send a right image for each left one",
        );
    }
    if let Some(choice) = asked.model
        && engine::Model::from(choice) != model
    {
        problems.add(
            "model",
            format!(
                "is {}, but the initial calibration's lenses are {}: a calibration started \
                 from it keeps its lens model (leave model out)",
                engine::Model::from(choice).name(),
                model.name()
            ),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reader's field names come back as the form's: the part itself, and a member
    /// inside one.
    #[test]
    fn the_readers_fields_are_named_as_the_form_names_them() {
        assert_eq!(renamed("calibration"), "initial");
        assert_eq!(renamed("right_calibration"), "initial_right");
        assert_eq!(renamed("calibration_unit"), "initial_unit");
        assert_eq!(renamed("rig.baseline_std"), "initial_rig.baseline_std");
        assert_eq!(renamed("rigid"), "rigid");
        assert_eq!(read_as("initial_right"), Some("right_calibration"));
        assert_eq!(read_as("left"), None);
    }
}
