//! Validation: turns the caller's optional, untrusted members into the physics module's types,
//! collecting every problem (with the field it belongs to) before giving up.

use super::error::FieldErrors;
use super::wire::params::{CameraParams, RangeParams, RigParams};
use crate::physics::{
    Correspondence, DEFAULT_DISPARITY_ERROR_PX, FocalLength, LengthUnit, Rig, SampleRange, Spacing,
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

    /// `value` if it is finite and greater than zero.
    pub fn positive(&mut self, field: &str, value: f64) -> Option<f64> {
        if value.is_finite() && value > 0.0 {
            Some(value)
        } else {
            self.add(field, format!("must be greater than 0, got {value}"));
            None
        }
    }

    /// `value` if it is finite and at least zero.
    pub fn non_negative(&mut self, field: &str, value: f64) -> Option<f64> {
        if value.is_finite() && value >= 0.0 {
            Some(value)
        } else {
            self.add(field, format!("must be 0 or more, got {value}"));
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
                format!("must lie in [0, {max}] ({what}), got {value}"),
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

const FOCAL_OPTIONS: &str = "give focal_length_px; or focal_length_mm with sensor_width_mm or \
                             pixel_size_um; or horizontal_fov_deg";

/// Why a focal length in millimetres is not enough on its own.
pub const MM_ALONE: &str = "a focal length in millimetres cannot be used on its own: \
    Z = B·f/d needs f in pixels, because d is in pixels and mm × mm / px is not a length. \
    Add sensor_width_mm (f_px = f_mm · image_width / sensor_width_mm) or pixel_size_um \
    (f_px = f_mm · 1000 / pixel_size_um), or give focal_length_px or horizontal_fov_deg instead";

/// Exactly one focal option, checked and converted to pixels.
fn focal_length(p: &CameraParams, width: Option<f64>, problems: &mut FieldErrors) -> Option<f64> {
    let modes: Vec<&str> = [
        ("focal_length_px", p.focal_length_px.is_some()),
        ("focal_length_mm", p.focal_length_mm.is_some()),
        ("horizontal_fov_deg", p.horizontal_fov_deg.is_some()),
    ]
    .into_iter()
    .filter_map(|(name, given)| given.then_some(name))
    .collect();
    if modes.len() > 1 {
        for name in &modes {
            problems.add(
                name,
                format!(
                    "give exactly one focal option, but {} were given",
                    modes.join(", ")
                ),
            );
        }
        return None;
    }
    for (name, value) in [
        ("sensor_width_mm", p.sensor_width_mm),
        ("pixel_size_um", p.pixel_size_um),
    ] {
        if value.is_some() && p.focal_length_mm.is_none() {
            problems.add(name, "only converts focal_length_mm, which was not given");
        }
    }
    let spec = if let Some(px) = p.focal_length_px {
        FocalLength::Pixels(problems.positive("focal_length_px", px)?)
    } else if let Some(mm) = p.focal_length_mm {
        let focal_mm = problems.positive("focal_length_mm", mm);
        match (p.sensor_width_mm, p.pixel_size_um) {
            (None, None) => {
                problems.add("focal_length_mm", MM_ALONE);
                return None;
            }
            (Some(_), Some(_)) => {
                for name in ["sensor_width_mm", "pixel_size_um"] {
                    problems.add(name, "give sensor_width_mm or pixel_size_um, not both");
                }
                return None;
            }
            (Some(sensor), None) => FocalLength::MillimetresWithSensorWidth {
                focal_mm: focal_mm?,
                sensor_width_mm: problems.positive("sensor_width_mm", sensor)?,
            },
            (None, Some(pitch)) => FocalLength::MillimetresWithPixelPitch {
                focal_mm: focal_mm?,
                pixel_pitch_um: problems.positive("pixel_size_um", pitch)?,
            },
        }
    } else if let Some(degrees) = p.horizontal_fov_deg {
        if !(degrees > 0.0 && degrees < 180.0) {
            problems.add(
                "horizontal_fov_deg",
                format!("must lie strictly between 0 and 180 degrees, got {degrees}"),
            );
            return None;
        }
        FocalLength::HorizontalFov { degrees }
    } else {
        // A focal member refused while decoding was already reported; do not add "required".
        let refused = [
            "focal_length_px",
            "focal_length_mm",
            "horizontal_fov_deg",
            "sensor_width_mm",
            "pixel_size_um",
        ];
        if !refused.iter().any(|field| problems.has(field)) {
            problems.add(
                "focal_length_px",
                format!("a focal length is required: {FOCAL_OPTIONS}"),
            );
        }
        return None;
    };
    match spec.to_pixels(width?) {
        Ok(focal_px) if focal_px > 0.0 => Some(focal_px),
        Ok(focal_px) => {
            problems.add(
                focal_field(p),
                format!("converts to {focal_px} px, which is not a usable focal length"),
            );
            None
        }
        Err(_) => {
            problems.add(
                focal_field(p),
                "converts to a focal length in pixels too large to represent",
            );
            None
        }
    }
}

/// The member the focal length was given in.
pub fn focal_field(p: &CameraParams) -> &'static str {
    if p.focal_length_mm.is_some() {
        "focal_length_mm"
    } else if p.horizontal_fov_deg.is_some() {
        "horizontal_fov_deg"
    } else {
        "focal_length_px"
    }
}

/// The image size, as whole pixels of at least 1.
fn image_extent(field: &str, value: Option<u32>, problems: &mut FieldErrors) -> Option<f64> {
    match problems.required(field, value)? {
        0 => {
            problems.add(field, "must be at least 1 pixel");
            None
        }
        n => Some(f64::from(n)),
    }
}

/// A validated camera: the focal length in pixels and what goes with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub focal_px: f64,
    pub unit: LengthUnit,
    pub image_width: f64,
    pub image_height: f64,
    pub disparity_error_px: f64,
}

impl Camera {
    /// The rig this camera makes with a second one `baseline` away, principal points at the
    /// image centre and no doffs.
    pub fn with_baseline(self, baseline: f64) -> Rig {
        Rig {
            focal_px: self.focal_px,
            baseline,
            unit: self.unit,
            image_width: self.image_width,
            image_height: self.image_height,
            cx: self.image_width / 2.0,
            cy: self.image_height / 2.0,
            doffs: 0.0,
            disparity_error_px: self.disparity_error_px,
        }
    }
}

/// Validates the camera members shared by every request.
pub fn camera(p: &CameraParams, problems: &mut FieldErrors) -> Option<Camera> {
    let width = image_extent("image_width", p.image_width, problems);
    let height = image_extent("image_height", p.image_height, problems);
    let focal_px = focal_length(p, width, problems);
    let disparity_error_px = problems.non_negative(
        "disparity_error_px",
        p.disparity_error_px.unwrap_or(DEFAULT_DISPARITY_ERROR_PX),
    );
    Some(Camera {
        focal_px: focal_px?,
        unit: p.unit.unwrap_or_default().into(),
        image_width: width?,
        image_height: height?,
        disparity_error_px: disparity_error_px?,
    })
}

/// Validates the rig members: the camera, the baseline and the principal points.
pub fn rig(p: &RigParams, problems: &mut FieldErrors) -> Option<Rig> {
    let camera = camera(&p.camera, problems);
    let bounds = Bounds::of(&p.camera);
    let baseline = problems
        .required("baseline", p.baseline)
        .and_then(|b| problems.positive("baseline", b));
    let cx = match (p.cx, bounds.width) {
        (Some(cx), Some(w)) => problems.within("cx", cx, w, "the image width"),
        (None, Some(w)) => Some(w / 2.0),
        _ => None,
    };
    let cy = match (p.cy, bounds.height) {
        (Some(cy), Some(h)) => problems.within("cy", cy, h, "the image height"),
        (None, Some(h)) => Some(h / 2.0),
        _ => None,
    };
    let doffs = p.doffs.unwrap_or(0.0);
    let (camera, baseline) = (camera?, baseline?);
    balanced(camera.focal_px, baseline, focal_field(&p.camera), problems)?;
    Some(Rig {
        cx: cx?,
        cy: cy?,
        doffs,
        ..camera.with_baseline(baseline)
    })
}

/// Refuses a focal length and baseline whose product or ratio leaves the range of an f64,
/// blaming both.
pub fn balanced(
    focal_px: f64,
    baseline: f64,
    focal: &str,
    problems: &mut FieldErrors,
) -> Option<()> {
    if (focal_px * baseline).is_normal() && (focal_px / baseline).is_normal() {
        return Some(());
    }
    for field in [focal, "baseline"] {
        problems.add(
            field,
            format!(
                "focal length ({focal_px} px) and baseline ({baseline}) are too far apart in \
                 magnitude: their product or ratio leaves the range of a 64-bit float"
            ),
        );
    }
    None
}

/// The image size as far as it is valid, so that coordinates are range-checked even when
/// another rig member is wrong.
#[derive(Debug, Clone, Copy, Default)]
pub struct Bounds {
    pub width: Option<f64>,
    pub height: Option<f64>,
}

impl Bounds {
    pub fn of(p: &CameraParams) -> Self {
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

/// The required pair `(x_left, x_right)`, each within the image width.
pub fn x_pair(
    (x_left, x_right): (Option<f64>, Option<f64>),
    bounds: Bounds,
    problems: &mut FieldErrors,
) -> Option<(f64, f64)> {
    let x_left = problems
        .required("x_left", x_left)
        .and_then(|x| x_coordinate("x_left", x, bounds, problems));
    let x_right = problems
        .required("x_right", x_right)
        .and_then(|x| x_coordinate("x_right", x, bounds, problems));
    Some((x_left?, x_right?))
}

/// One correspondence; `y` defaults to the rig's `cy` (absent when the rig is invalid).
pub fn correspondence(
    (x_left, x_right, y): (Option<f64>, Option<f64>, Option<f64>),
    bounds: Bounds,
    cy: Option<f64>,
    problems: &mut FieldErrors,
) -> Option<Correspondence> {
    let xs = x_pair((x_left, x_right), bounds, problems);
    let y = match (y, bounds.height) {
        (Some(y), Some(height)) => problems.within("y", y, height, "the image height"),
        (Some(y), None) => Some(y),
        (None, _) => cy,
    };
    let (x_left, x_right) = xs?;
    Some(Correspondence {
        x_left,
        x_right,
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
    if min + rig.doffs > 0.0 {
        return Some(min);
    }
    problems.add(
        field,
        format!(
            "{field} + doffs must be greater than 0 (at d + doffs = 0 the point is at \
             infinity), got {min} + {}",
            rig.doffs
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
                format!("must be greater than {lo_name} ({lo}), got {hi}"),
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
        SampleRange::default_for(rig, measured_disparity_px)
    };
    Some((range, spacing))
}

/// The fields to blame when a correspondence has no finite distance.
pub fn disparity_fields(rig: &Rig) -> &'static [&'static str] {
    if rig.doffs == 0.0 {
        &["x_left", "x_right"]
    } else {
        &["x_left", "x_right", "doffs"]
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
