//! Validation: turns the caller's optional, untrusted members into the physics module's types,
//! collecting every problem (with the field it belongs to) before giving up.

use super::error::FieldErrors;
use super::wire::params::{CameraParams, RangeParams, RigParams};
use crate::numbers::Num;
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

/// Exactly one focal option, checked and converted to pixels. `width` is the image width when
/// it was given and valid; only the sensor-width and field-of-view options need it.
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
                format!(
                    "must lie strictly between 0 and 180 degrees, got {}",
                    Num(degrees)
                ),
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
    let width = match spec {
        FocalLength::MillimetresWithSensorWidth { .. } => needed(
            "image_width",
            width,
            "to convert focal_length_mm with sensor_width_mm (f_px = f_mm · image_width / \
             sensor_width_mm)",
            problems,
        )?,
        FocalLength::HorizontalFov { .. } => needed(
            "image_width",
            width,
            "to convert horizontal_fov_deg (f_px = (image_width / 2) / tan(hfov / 2))",
            problems,
        )?,
        FocalLength::Pixels(_) | FocalLength::MillimetresWithPixelPitch { .. } => 0.0,
    };
    match spec.to_pixels(width) {
        Ok(focal_px) if focal_px > 0.0 => Some(focal_px),
        Ok(focal_px) => {
            problems.add(
                focal_field(p),
                format!(
                    "converts to {} px, which is not a usable focal length",
                    Num(focal_px)
                ),
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

/// An image extent when given: whole pixels of at least 1. `None` when absent or refused (the
/// refusal is recorded).
fn image_extent(field: &str, value: Option<u32>, problems: &mut FieldErrors) -> Option<f64> {
    match value? {
        0 => {
            problems.add(field, "must be at least 1 pixel");
            None
        }
        n => Some(f64::from(n)),
    }
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

/// A validated camera: the focal lengths in pixels and what goes with them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub focal_px: f64,
    pub focal_y_px: f64,
    pub unit: LengthUnit,
    pub image_width: Option<f64>,
    pub image_height: Option<f64>,
    pub disparity_error_px: f64,
}

impl Camera {
    /// The rig this camera makes with a second one `baseline` away, principal points at the
    /// image centre (at 0 when the image size is unknown: a rig made this way places no
    /// points) and no doffs.
    pub fn with_baseline(self, baseline: f64) -> Rig {
        Rig {
            focal_px: self.focal_px,
            focal_y_px: self.focal_y_px,
            baseline,
            unit: self.unit,
            image_width: self.image_width,
            image_height: self.image_height,
            cx: self.image_width.map_or(0.0, |w| w / 2.0),
            cy: self.image_height.map_or(0.0, |h| h / 2.0),
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
    let focal_y_px = p
        .focal_length_y_px
        .map(|fy| problems.positive("focal_length_y_px", fy));
    let disparity_error_px = problems.non_negative(
        "disparity_error_px",
        p.disparity_error_px.unwrap_or(DEFAULT_DISPARITY_ERROR_PX),
    );
    let focal_px = focal_px?;
    Some(Camera {
        focal_px,
        focal_y_px: focal_y_px.unwrap_or(Some(focal_px))?,
        unit: p.unit.unwrap_or_default().into(),
        image_width: width,
        image_height: height,
        disparity_error_px: disparity_error_px?,
    })
}

/// What a request does with its rig, which decides whether it needs the principal point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Use {
    /// Places 3D points (`/distance`): `cx` and `cy` are needed, given or from the image size.
    Points,
    /// Only relates disparity and depth (`/rig`, `/table`, `/chart-data`): the principal
    /// point is checked when given, and is 0 when it is unknown, since nothing uses it.
    Depths,
}

/// A principal-point coordinate: within `[0, extent]` when the extent is known, else at least
/// 0; by default the image centre, which needs the extent when the rig places points.
fn principal(
    (field, extent_field): (&str, &str),
    value: Option<f64>,
    extent: Option<f64>,
    usage: Use,
    problems: &mut FieldErrors,
) -> Option<f64> {
    match (value, extent) {
        (Some(c), Some(extent)) => problems.within(field, c, extent, extent_field),
        (Some(c), None) => problems.non_negative(field, c),
        (None, Some(extent)) => Some(extent / 2.0),
        (None, None) if usage == Use::Depths => Some(0.0),
        (None, None) => needed(
            extent_field,
            None,
            &format!("for the default {field} (the image centre); or give {field}"),
            problems,
        ),
    }
}

/// Validates the rig members: the camera, the baseline and the principal points.
pub fn rig(p: &RigParams, usage: Use, problems: &mut FieldErrors) -> Option<Rig> {
    let camera = camera(&p.camera, problems);
    let bounds = Bounds::of(&p.camera);
    let baseline = problems
        .required("baseline", p.baseline)
        .and_then(|b| problems.positive("baseline", b));
    let cx = principal(("cx", "image_width"), p.cx, bounds.width, usage, problems);
    let cy = principal(("cy", "image_height"), p.cy, bounds.height, usage, problems);
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
                "focal length ({} px) and baseline ({}) are too far apart in magnitude: \
                 their product or ratio leaves the range of a 64-bit float",
                Num(focal_px),
                Num(baseline)
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

/// A feature as the caller placed it: `x_left` with `x_right`, or a disparity (with an
/// optional `x_left`), and an optional row `y`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Feature {
    pub x_left: Option<f64>,
    pub x_right: Option<f64>,
    pub disparity_px: Option<f64>,
    pub y: Option<f64>,
}

/// The message for a feature that gives both `x_right` and `disparity_px`.
pub const X_RIGHT_OR_DISPARITY: &str =
    "give x_right or disparity_px, not both: disparity_px = x_left − x_right";

/// The disparity the feature states, whichever way: `x_left − x_right` (each within the image
/// width) or `disparity_px`; `x_left` is required with `x_right` and, with `disparity_px`,
/// defaults to `cx_default` (the rig's `cx`, absent when the rig is invalid). Returns
/// `(x_left, disparity_px)`.
pub fn disparity(
    feature: Feature,
    bounds: Bounds,
    cx_default: Option<f64>,
    problems: &mut FieldErrors,
) -> Option<(f64, f64)> {
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
            Some((x_left, x_left - x_right))
        }
        (None, Some(d)) => match feature.x_left {
            Some(_) => Some((x_left?, d)),
            None => Some((cx_default?, d)),
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

/// One correspondence; `x_left` defaults to the rig's `cx` with a disparity, `y` to its `cy`
/// (`rig_centre` is absent when the rig is invalid).
pub fn correspondence(
    feature: Feature,
    bounds: Bounds,
    rig_centre: Option<(f64, f64)>,
    problems: &mut FieldErrors,
) -> Option<Correspondence> {
    let xd = disparity(feature, bounds, rig_centre.map(|c| c.0), problems);
    let y = match (feature.y, bounds.height) {
        (Some(y), Some(height)) => problems.within("y", y, height, "the image height"),
        (Some(y), None) => problems.non_negative("y", y),
        (None, _) => rig_centre.map(|c| c.1),
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
    if min + rig.doffs > 0.0 {
        return Some(min);
    }
    problems.add(
        field,
        format!(
            "{field} + doffs must be greater than 0 (at d + doffs = 0 the point is at \
             infinity), got {} + {}",
            Num(min),
            Num(rig.doffs)
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
            rig.image_width,
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
    match (feature.disparity_px.is_some(), rig.doffs == 0.0) {
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
