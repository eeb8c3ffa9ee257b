//! The engine's depth job ([`stereo_core::pipeline::DepthJob`]) planned with what a request
//! sent, its refusals named by part or query parameter, and the memory its work reserves; and
//! the raw rig `/rectify` rectifies with.

use super::form::{ImageForm, ImagePair};
use super::rig;
use super::work::Need;
use crate::api::error::FieldErrors;
use crate::api::wire::images::RectifyMode;
use crate::api::wire::rectify::ProjectionAsked;
use stereo_core::calibration::files::Raw;
use stereo_core::camera::{Alpha, LatlonFault, LatlonOptions};
use stereo_core::pipeline::{self, Calibrated, DepthJob, PlanFault, Rectify, RigInput, Sent};
use stereo_core::vision::Settings;

impl From<RectifyMode> for pipeline::RectifyMode {
    fn from(mode: RectifyMode) -> Self {
        match mode {
            RectifyMode::Auto => pipeline::RectifyMode::Auto,
            RectifyMode::Yes => pipeline::RectifyMode::Yes,
            RectifyMode::No => pipeline::RectifyMode::No,
        }
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
        PlanFault::LatlonUnused => "projection",
        PlanFault::AlphaWithLatlon => "alpha",
        PlanFault::Latlon(fault) => latlon_field(fault),
    }
}

/// What a request asks of its job besides its rig: rectified as `rectify` (with `alpha`, as
/// the request states it), matched with `settings`, whose faults are named with `prefix`
/// (`options.` in a stream's settings).
pub struct Asked<'a> {
    pub rectify: Option<RectifyMode>,
    pub alpha: Option<f64>,
    /// Rectify to latitude-longitude with these options (`None`: the pinhole plane).
    pub latlon: Option<LatlonOptions>,
    pub settings: Settings,
    pub prefix: &'a str,
}

/// The depth job for frames of `size` with the rig `given` (made at that size from what was
/// `sent`), or `None` with each refusal in `problems`.
pub fn plan(
    given: Option<Calibrated>,
    sent: Sent,
    size: Option<(u32, u32)>,
    asked: Asked<'_>,
    problems: &mut FieldErrors,
) -> Option<DepthJob> {
    let mut said = FieldErrors::default();
    let rectify = Rectify {
        mode: asked.rectify.unwrap_or_default().into(),
        alpha: said.alpha(asked.alpha),
        latlon: asked.latlon,
    };
    let planned = match DepthJob::plan(given, sent, size, rectify, asked.settings) {
        Ok(job) => Some(job),
        Err(faults) => {
            if let Some(fault) = faults.plan {
                said.add(field(&fault), fault.to_string());
            }
            for fault in faults.settings {
                said.add_new(fault.setting.name().to_string(), fault.message);
            }
            None
        }
    };
    // The options' faults carry the prefix (`options.` in a stream's settings); the rig's
    // and the images' are named as their parts.
    for fault in said.prefixed("") {
        let part = ["rig", "left", "calibration"].contains(&fault.field.as_str());
        let prefix = if part { "" } else { asked.prefix };
        problems.add(&format!("{prefix}{}", fault.field), fault.message);
    }
    planned
}

/// The depth job for frames of `size` from a rig input parsed once (a stream's settings, the
/// command's flags), made the rig of that size first ([`rig::at`]).
pub fn plan_at(
    input: &RigInput,
    size: (u32, u32),
    asked: Asked<'_>,
    problems: &mut FieldErrors,
) -> Option<DepthJob> {
    let given = rig::at(input, Some(size), true, problems);
    plan(given, input.sent(), Some(size), asked, problems)
}

/// The depth job of an image route's pair ([`plan`]), its rig taken from the pair.
pub fn plan_pair<F: ImageForm>(
    pair: &mut ImagePair<F>,
    asked: Asked<'_>,
    problems: &mut FieldErrors,
) -> Option<DepthJob> {
    plan(pair.rig.take(), pair.sent, pair.size, asked, problems)
}

/// The memory a job's work reserves, as the heavy group's work takes it.
pub fn need(need: pipeline::Need) -> Need<impl Fn(usize) -> usize> {
    Need {
        size: need.size,
        count: need.count,
        need: move |count| need.bytes(count),
    }
}

/// The raw rig of the request, with `alpha` applied; `None` with the reasons in `problems`
/// when the form has no calibration of raw cameras for these images.
pub fn raw_rig(
    pair: &ImagePair<impl ImageForm>,
    alpha: Option<Alpha>,
    problems: &mut FieldErrors,
) -> Option<Calibrated> {
    match pipeline::raw_rig(pair.rig.as_ref(), pair.sent, pair.size, alpha) {
        Ok(calibrated) => calibrated,
        Err(fault) => {
            problems.add(field(&fault), fault.to_string());
            None
        }
    }
}

/// Why a ROS message is not answered for a latitude-longitude map.
pub const ROS_NOT_LATLON: &str = "ROS messages (DisparityImage, depth images, PointCloud2) \
     describe a pinhole rectification; with projection=latlon ask for depth.npy, arrays.npz \
     or points.ply";

/// The latitude-longitude options a query asks for: `Some` with `projection=latlon` (and
/// `auto`, then only for cameras that see wide); with the pinhole plane `None`, and each
/// latlon option given is named.
pub fn latlon_options(
    projection: Option<ProjectionAsked>,
    [az_fov, el_fov, pixels_per_degree]: [Option<f64>; 3],
    problems: &mut FieldErrors,
) -> Option<LatlonOptions> {
    match projection.unwrap_or_default() {
        ProjectionAsked::Pinhole => {
            let given = [
                ("az_fov", az_fov),
                ("el_fov", el_fov),
                ("pixels_per_degree", pixels_per_degree),
            ];
            for (name, _) in given.iter().filter(|(_, v)| v.is_some()) {
                problems.add(name, "applies only with projection=latlon");
            }
            None
        }
        asked @ (ProjectionAsked::Latlon | ProjectionAsked::Auto) => Some(LatlonOptions {
            when_wide: asked == ProjectionAsked::Auto,
            az_fov_deg: az_fov,
            el_fov_deg: el_fov,
            pixels_per_degree,
        }),
    }
}

/// The raw rig rectified to `latlon` (`/rectify`'s query), or kept on the pinhole plane;
/// `alpha` with latlon, and what the cameras cannot be rectified with, are named.
pub fn projected(
    raw: Raw,
    latlon: Option<LatlonOptions>,
    alpha: Option<f64>,
    problems: &mut FieldErrors,
) -> Option<Raw> {
    let Some(options) = latlon.and_then(|l| l.unless_pinhole(alpha.is_some())) else {
        return Some(raw);
    };
    if alpha.is_some() {
        problems.add("alpha", PlanFault::AlphaWithLatlon.to_string());
    }
    match raw.with_latlon(options) {
        Ok(raw) => Some(raw),
        Err(fault) => {
            problems.add(latlon_field(&fault), fault.to_string());
            None
        }
    }
}

/// The option a latitude-longitude refusal is about.
fn latlon_field(fault: &LatlonFault) -> &'static str {
    match fault {
        LatlonFault::Option(name, _) => name,
        LatlonFault::TooLarge(..) | LatlonFault::TooSmall => "pixels_per_degree",
        _ => "calibration",
    }
}
