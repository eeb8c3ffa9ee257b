//! Validation: turns the caller's optional, untrusted members into the physics module's types,
//! collecting every problem (with the field it belongs to) before giving up.

use super::error::FieldErrors;
use super::wire::params::RangeParams;
use stereo_core::camera::Alpha;
use stereo_core::numbers::Num;
use stereo_core::physics::{
    CameraSpec, Correspondence, Fault, Member, RectifiedCamera, Rig, RigSpec, SampleRange, Spacing,
};

/// The range checks validation makes: each records its own error and returns the value only
/// when it passed.
impl FieldErrors {
    /// The value, or an error saying it is required.
    pub fn required<T>(&mut self, field: &str, value: Option<T>) -> Option<T> {
        if value.is_none() {
            self.add(field, "is required");
        }
        value
    }

    /// `alpha` as a request states it, parsed once for every route that takes it: the value
    /// when given and in 0..=1, its fault named `alpha` when not.
    pub fn alpha(&mut self, value: Option<f64>) -> Option<Alpha> {
        match Alpha::new(value?) {
            Ok(alpha) => Some(alpha),
            Err(out) => {
                self.add("alpha", out.to_string());
                None
            }
        }
    }

    /// `value` if it is finite and greater than zero.
    pub fn positive(&mut self, field: &str, value: f64) -> Option<f64> {
        if value.is_finite() && value > 0.0 {
            Some(value)
        } else {
            self.add(field, format!("must be greater than 0, got {}", Num(value)));
            None
        }
    }

    /// `value` if it is finite and at least zero.
    pub fn non_negative(&mut self, field: &str, value: f64) -> Option<f64> {
        if value.is_finite() && value >= 0.0 {
            Some(value)
        } else {
            self.add(field, format!("must be 0 or more, got {}", Num(value)));
            None
        }
    }

    /// `value` if it lies in `[0, max]`; `what` names the bound for the message.
    pub fn within(&mut self, field: &str, value: f64, max: f64, what: &str) -> Option<f64> {
        if value.is_finite() && (0.0..=max).contains(&value) {
            Some(value)
        } else {
            self.add(
                field,
                format!("must lie in [0, {}] ({what}), got {}", Num(max), Num(value)),
            );
            None
        }
    }

    /// A whole count in `[min, cap]`, or `default` when absent.
    pub fn count(
        &mut self,
        field: &str,
        value: Option<u32>,
        default: usize,
        min: usize,
        cap: usize,
    ) -> Option<usize> {
        let Some(value) = value else {
            // A number beyond what any whole member takes was refused while decoding, against
            // that bound; name this member's own cap instead.
            let beyond = format!("must be at most {}", super::wire::de::MAX_WHOLE);
            let cap_words = format!("must be from {min} to {cap} (the server's cap)");
            let reworded = self
                .iter()
                .find(|e| e.field == field && e.message.starts_with(&beyond))
                .map(|e| e.message.replacen(&beyond, &cap_words, 1));
            if let Some(message) = reworded {
                self.reword(field, &message);
                return None;
            }
            return Some(default);
        };
        let value = value as usize;
        if (min..=cap).contains(&value) {
            Some(value)
        } else {
            self.add(
                field,
                format!("must be from {min} to {cap} (the server's cap), got {value}"),
            );
            None
        }
    }
}

/// The members a camera and a rig are stated in.
const MEMBERS: [Member; 13] = [
    Member::FocalLengthPx,
    Member::FocalLengthMm,
    Member::SensorWidthMm,
    Member::PixelSizeUm,
    Member::HorizontalFovDeg,
    Member::FocalLengthYPx,
    Member::ImageWidth,
    Member::ImageHeight,
    Member::DisparityErrorPx,
    Member::Baseline,
    Member::Cx,
    Member::Cy,
    Member::Doffs,
];

/// `camera` with the members already refused while decoding (a wrong type) marked
/// unreadable, so that their absence is not reported again.
fn marked(mut camera: CameraSpec, problems: &FieldErrors) -> CameraSpec {
    camera.unreadable = MEMBERS
        .into_iter()
        .filter(|m| problems.has(m.name()))
        .collect();
    camera
}

/// Records what a rig or camera constructor refused, each member named behind `prefix` (such
/// as `rig.`), with the constructor's own words.
pub fn faults(faults: Vec<Fault>, prefix: &str, problems: &mut FieldErrors) {
    for fault in faults {
        problems.add(&format!("{prefix}{}", fault.member.name()), fault.message);
    }
}

/// The camera a request states, through [`RectifiedCamera::new`].
pub fn camera(spec: CameraSpec, problems: &mut FieldErrors) -> Option<RectifiedCamera> {
    RectifiedCamera::new(&marked(spec, problems))
        .map_err(|f| faults(f, "", problems))
        .ok()
}

/// A rig as a request states it, the members `problems` already refused marked unreadable
/// (so that their absence is not reported again).
pub fn marked_rig(mut spec: RigSpec, problems: &FieldErrors) -> RigSpec {
    spec.camera = marked(spec.camera, problems);
    spec
}

/// The rig a request states, through [`Rig::new`], the one constructor every rig goes
/// through.
pub fn rig(mut spec: RigSpec, problems: &mut FieldErrors) -> Option<Rig> {
    spec.camera = marked(spec.camera, problems);
    Rig::new(&spec).map_err(|f| faults(f, "", problems)).ok()
}

/// `value`, or an error saying `field` is required `why` (unless `field` was already refused).
pub fn needed<T>(
    field: &str,
    value: Option<T>,
    why: &str,
    problems: &mut FieldErrors,
) -> Option<T> {
    if value.is_none() && !problems.has(field) {
        problems.add(field, format!("is required {why}"));
    }
    value
}

/// The image size as far as it is valid, so that coordinates are range-checked even when
/// another rig member is wrong.
#[derive(Debug, Clone, Copy, Default)]
pub struct Bounds {
    pub width: Option<f64>,
    pub height: Option<f64>,
}

impl Bounds {
    pub fn of(p: &CameraSpec) -> Self {
        let valid = |n: Option<u32>| n.filter(|&n| n > 0).map(f64::from);
        Self {
            width: valid(p.image_width),
            height: valid(p.image_height),
        }
    }
}

/// An x coordinate: in `[0, image_width]` when the width is known.
pub fn x_coordinate(
    field: &str,
    x: f64,
    bounds: Bounds,
    problems: &mut FieldErrors,
) -> Option<f64> {
    match bounds.width {
        Some(width) => problems.within(field, x, width, "the image width"),
        None => Some(x),
    }
}

/// A feature as the caller placed it: `x_left` with `x_right`, or a disparity (with an
/// optional `x_left`), and an optional row `y`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Feature {
    pub x_left: Option<f64>,
    pub x_right: Option<f64>,
    pub disparity_px: Option<f64>,
    pub y: Option<f64>,
}

impl Feature {
    /// A feature from the members a request gave.
    pub fn new(
        x_left: Option<f64>,
        x_right: Option<f64>,
        disparity_px: Option<f64>,
        y: Option<f64>,
    ) -> Self {
        Self {
            x_left,
            x_right,
            disparity_px,
            y,
        }
    }
}

/// The message for a feature that gives both `x_right` and `disparity_px`.
pub const X_RIGHT_OR_DISPARITY: &str =
    "give x_right or disparity_px, not both: disparity_px = x_left − x_right";

/// The disparity the feature states, whichever way: `x_left − x_right` (each within the image
/// width) or `disparity_px`; `x_left` is required with `x_right` and, with `disparity_px`,
/// optional (the rig's `cx` by default). Returns `(x_left, disparity_px)`.
pub fn disparity(
    feature: Feature,
    bounds: Bounds,
    problems: &mut FieldErrors,
) -> Option<(Option<f64>, f64)> {
    let x_left = feature
        .x_left
        .and_then(|x| x_coordinate("x_left", x, bounds, problems));
    match (feature.x_right, feature.disparity_px) {
        (Some(_), Some(_)) => {
            for field in ["x_right", "disparity_px"] {
                problems.add(field, X_RIGHT_OR_DISPARITY);
            }
            None
        }
        (Some(x_right), None) => {
            let x_left = problems.required("x_left", feature.x_left).and(x_left);
            let x_right = x_coordinate("x_right", x_right, bounds, problems);
            let (x_left, x_right) = (x_left?, x_right?);
            Some((Some(x_left), x_left - x_right))
        }
        (None, Some(d)) => match feature.x_left {
            Some(_) => Some((Some(x_left?), d)),
            None => Some((None, d)),
        },
        (None, None) => {
            problems.required("x_left", feature.x_left);
            problems.add(
                "x_right",
                "is required: give x_right (with x_left), or disparity_px",
            );
            None
        }
    }
}

/// One correspondence; a missing `x_left` (with a disparity) or `y` is the rig's principal
/// point's, applied when the point is placed.
pub fn correspondence(
    feature: Feature,
    bounds: Bounds,
    problems: &mut FieldErrors,
) -> Option<Correspondence> {
    let xd = disparity(feature, bounds, problems);
    let y = match (feature.y, bounds.height) {
        (Some(y), Some(height)) => problems
            .within("y", y, height, "the image height")
            .map(Some),
        (Some(y), None) => problems.non_negative("y", y).map(Some),
        (None, _) => Some(None),
    };
    let (x_left, disparity_px) = xd?;
    Some(Correspondence {
        x_left,
        disparity_px,
        y: y?,
    })
}

/// `min` if `min + doffs > 0`: a disparity search must stop short of the point at infinity.
pub fn short_of_infinity(
    field: &str,
    min: f64,
    rig: &Rig,
    problems: &mut FieldErrors,
) -> Option<f64> {
    if min + rig.doffs() > 0.0 {
        return Some(min);
    }
    problems.add(
        field,
        format!(
            "{field} + doffs must be greater than 0 (at d + doffs = 0 the point is at \
             infinity), got {} + {}",
            Num(min),
            Num(rig.doffs())
        ),
    );
    None
}

/// The sample range: distances, disparities, or the default around `measured`.
pub fn range(
    p: &RangeParams,
    rig: Option<&Rig>,
    measured_disparity_px: Option<f64>,
    problems: &mut FieldErrors,
) -> Option<(SampleRange, Spacing)> {
    let spacing: Spacing = p.spacing.unwrap_or_default().into();
    let distance = [
        ("distance_min", p.distance_min),
        ("distance_max", p.distance_max),
    ];
    let disparity = [
        ("disparity_min", p.disparity_min),
        ("disparity_max", p.disparity_max),
    ];
    let given = |pair: &[(&str, Option<f64>); 2]| pair.iter().any(|(_, v)| v.is_some());
    if given(&distance) && given(&disparity) {
        for (name, _) in distance
            .iter()
            .chain(&disparity)
            .filter(|(_, v)| v.is_some())
        {
            problems.add(
                name,
                "give distance_min/distance_max or disparity_min/disparity_max, not both",
            );
        }
        return None;
    }
    let rig = rig?;
    let ordered = |problems: &mut FieldErrors,
                   [(lo_name, lo), (hi_name, hi)]: [(&str, Option<f64>); 2]| {
        let lo = problems.required(lo_name, lo);
        let hi = problems.required(hi_name, hi);
        let (lo, hi) = (lo?, hi?);
        if hi > lo {
            Some((lo, hi))
        } else {
            problems.add(
                hi_name,
                format!(
                    "must be greater than {lo_name} ({}), got {}",
                    Num(lo),
                    Num(hi)
                ),
            );
            None
        }
    };
    let range = if given(&distance) {
        let (min, max) = ordered(problems, distance)?;
        let min = problems.positive("distance_min", min)?;
        SampleRange::Distance { min, max }
    } else if given(&disparity) {
        let (min, max) = ordered(problems, disparity)?;
        let min = short_of_infinity("disparity_min", min, rig, problems)?;
        SampleRange::Disparity { min, max }
    } else {
        let width = needed(
            "image_width",
            rig.image_width(),
            "for the default range (disparities across a quarter of the image width); or \
             give disparity_min and disparity_max, or distance_min and distance_max",
            problems,
        )?;
        SampleRange::default_for(rig, width, measured_disparity_px)
    };
    Some((range, spacing))
}

/// The fields to blame when a correspondence has no finite distance: the disparity as the
/// feature gave it, and `doffs` when it took part.
pub fn disparity_fields(rig: &Rig, feature: &Feature) -> &'static [&'static str] {
    match (feature.disparity_px.is_some(), rig.doffs() == 0.0) {
        (false, true) => &["x_left", "x_right"],
        (false, false) => &["x_left", "x_right", "doffs"],
        (true, true) => &["disparity_px"],
        (true, false) => &["disparity_px", "doffs"],
    }
}

/// The range fields to blame when a sweep overflows.
pub fn range_fields(range: RangeParams) -> &'static [&'static str] {
    if range.distance_min.is_some() {
        &["distance_min", "distance_max"]
    } else if range.disparity_min.is_some() {
        &["disparity_min", "disparity_max"]
    } else {
        &["baseline"]
    }
}
