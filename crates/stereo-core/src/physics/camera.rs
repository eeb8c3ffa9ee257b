//! The camera as stated and as checked: the [`Member`]s a camera and a rig are stated in, the
//! [`Fault`]s a constructor names them by, the focal length in any of its four forms converted
//! to pixels, and [`RectifiedCamera::new`], the one way to a [`RectifiedCamera`].

use crate::numbers::Num;

use super::{FocalLength, LengthUnit};

/// Default disparity uncertainty Δd, in pixels: the ±0.5 px quantisation of integer-pixel
/// matching. Subpixel matchers reach about 0.1 px and should pass their own figure.
pub const DEFAULT_DISPARITY_ERROR_PX: f64 = 0.5;

/// The members a camera and a rig are stated in, as every request and file names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Member {
    FocalLengthPx,
    FocalLengthMm,
    SensorWidthMm,
    PixelSizeUm,
    HorizontalFovDeg,
    FocalLengthYPx,
    ImageWidth,
    ImageHeight,
    DisparityErrorPx,
    Baseline,
    Cx,
    Cy,
    Doffs,
    FocalLengthStdPx,
    BaselineStd,
}

impl Member {
    /// The member's name, as the API and the documentation spell it.
    pub fn name(self) -> &'static str {
        match self {
            Member::FocalLengthPx => "focal_length_px",
            Member::FocalLengthMm => "focal_length_mm",
            Member::SensorWidthMm => "sensor_width_mm",
            Member::PixelSizeUm => "pixel_size_um",
            Member::HorizontalFovDeg => "horizontal_fov_deg",
            Member::FocalLengthYPx => "focal_length_y_px",
            Member::ImageWidth => "image_width",
            Member::ImageHeight => "image_height",
            Member::DisparityErrorPx => "disparity_error_px",
            Member::Baseline => "baseline",
            Member::Cx => "cx",
            Member::Cy => "cy",
            Member::Doffs => "doffs",
            Member::FocalLengthStdPx => "focal_length_std_px",
            Member::BaselineStd => "baseline_std",
        }
    }
}

/// One member a constructor refused, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Fault {
    pub member: Member,
    pub message: String,
}

/// The faults found so far, one per member (the first explains the rest), and the members the
/// caller gave but that could not be read (whose absence is then not reported again).
pub(super) struct Faults<'a> {
    pub(super) found: Vec<Fault>,
    pub(super) unreadable: &'a [Member],
}

impl Faults<'_> {
    pub(super) fn has(&self, member: Member) -> bool {
        self.unreadable.contains(&member) || self.found.iter().any(|f| f.member == member)
    }

    pub(super) fn add(&mut self, member: Member, message: impl Into<String>) {
        if !self.found.iter().any(|f| f.member == member) {
            self.found.push(Fault {
                member,
                message: message.into(),
            });
        }
    }

    pub(super) fn positive(&mut self, member: Member, value: f64) -> Option<f64> {
        if value.is_finite() && value > 0.0 {
            Some(value)
        } else {
            self.add(
                member,
                format!("must be greater than 0, got {}", Num(value)),
            );
            None
        }
    }

    pub(super) fn non_negative(&mut self, member: Member, value: f64) -> Option<f64> {
        if value.is_finite() && value >= 0.0 {
            Some(value)
        } else {
            self.add(member, format!("must be 0 or more, got {}", Num(value)));
            None
        }
    }

    /// `value`, or a fault saying `member` is required `why` (unless it was unreadable).
    pub(super) fn needed<T>(&mut self, member: Member, value: Option<T>, why: &str) -> Option<T> {
        if value.is_none() && !self.has(member) {
            self.add(member, format!("is required {why}"));
        }
        value
    }
}

const FOCAL_OPTIONS: &str = "give focal_length_px; or focal_length_mm with sensor_width_mm or \
                             pixel_size_um; or horizontal_fov_deg";

/// Why a focal length in millimetres is not enough on its own.
pub const MM_ALONE: &str = "a focal length in millimetres cannot be used on its own: \
    Z = B·f/d needs f in pixels, because d is in pixels and mm × mm / px is not a length. \
    Add sensor_width_mm (f_px = f_mm · image_width / sensor_width_mm) or pixel_size_um \
    (f_px = f_mm · 1000 / pixel_size_um), or give focal_length_px or horizontal_fov_deg instead";

/// The focal length as it was stated: exactly one of pixels, millimetres (with a sensor width
/// or a pixel pitch) or a horizontal field of view.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Focal {
    pub px: Option<f64>,
    pub mm: Option<f64>,
    pub sensor_width_mm: Option<f64>,
    pub pixel_size_um: Option<f64>,
    pub horizontal_fov_deg: Option<f64>,
}

impl Focal {
    /// The member the focal length was stated in.
    pub fn member(&self) -> Member {
        if self.mm.is_some() {
            Member::FocalLengthMm
        } else if self.horizontal_fov_deg.is_some() {
            Member::HorizontalFovDeg
        } else {
            Member::FocalLengthPx
        }
    }
}

/// A camera as stated, before it is checked.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CameraSpec {
    pub focal: Focal,
    pub focal_y_px: Option<f64>,
    pub unit: LengthUnit,
    pub image_width: Option<u32>,
    pub image_height: Option<u32>,
    pub disparity_error_px: Option<f64>,
    /// Members the caller gave that could not be read (a wrong type): already reported, so
    /// their absence is not reported again.
    pub unreadable: Vec<Member>,
}

/// A camera of the rectified rig as triangulation sees it, checked: the focal lengths in
/// pixels and what goes with them (the raw camera, with K and distortion, is
/// [`crate::camera::Camera`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RectifiedCamera {
    pub(super) focal_px: f64,
    pub(super) focal_y_px: f64,
    pub(super) focal_member: Member,
    pub(super) unit: LengthUnit,
    pub(super) image_width: Option<f64>,
    pub(super) image_height: Option<f64>,
    pub(super) disparity_error_px: f64,
}

impl RectifiedCamera {
    /// Checks a camera: exactly one focal option (converted to pixels), image extents of at
    /// least a pixel, a positive fy, a disparity error of 0 or more.
    pub fn new(spec: &CameraSpec) -> Result<RectifiedCamera, Vec<Fault>> {
        let mut faults = Faults {
            found: Vec::new(),
            unreadable: &spec.unreadable,
        };
        let camera = camera(spec, &mut faults);
        match camera {
            Some(camera) if faults.found.is_empty() => Ok(camera),
            _ => Err(faults.found),
        }
    }

    pub fn focal_px(&self) -> f64 {
        self.focal_px
    }
    pub fn focal_y_px(&self) -> f64 {
        self.focal_y_px
    }
    /// The member the focal length was stated in, to blame for it.
    pub fn focal_member(&self) -> Member {
        self.focal_member
    }
    pub fn unit(&self) -> LengthUnit {
        self.unit
    }
    pub fn image_width(&self) -> Option<f64> {
        self.image_width
    }
    pub fn image_height(&self) -> Option<f64> {
        self.image_height
    }
    pub fn disparity_error_px(&self) -> f64 {
        self.disparity_error_px
    }
}

/// An image extent when given: whole pixels of at least 1.
fn image_extent(member: Member, value: Option<u32>, faults: &mut Faults) -> Option<f64> {
    match value? {
        0 => {
            faults.add(member, "must be at least 1 pixel");
            None
        }
        n => Some(f64::from(n)),
    }
}

pub(super) fn camera(spec: &CameraSpec, faults: &mut Faults) -> Option<RectifiedCamera> {
    let width = image_extent(Member::ImageWidth, spec.image_width, faults);
    let height = image_extent(Member::ImageHeight, spec.image_height, faults);
    let focal_px = focal_length(&spec.focal, width, faults);
    let focal_y_px = spec
        .focal_y_px
        .map(|fy| faults.positive(Member::FocalLengthYPx, fy));
    let disparity_error_px = faults.non_negative(
        Member::DisparityErrorPx,
        spec.disparity_error_px
            .unwrap_or(DEFAULT_DISPARITY_ERROR_PX),
    );
    let focal_px = focal_px?;
    Some(RectifiedCamera {
        focal_px,
        focal_y_px: focal_y_px.unwrap_or(Some(focal_px))?,
        focal_member: spec.focal.member(),
        unit: spec.unit,
        image_width: width,
        image_height: height,
        disparity_error_px: disparity_error_px?,
    })
}

/// Exactly one focal option, checked and converted to pixels. `width` is the image width when
/// it was given and valid; only the sensor-width and field-of-view options need it.
fn focal_length(p: &Focal, width: Option<f64>, faults: &mut Faults) -> Option<f64> {
    let modes: Vec<&str> = [
        (Member::FocalLengthPx, p.px.is_some()),
        (Member::FocalLengthMm, p.mm.is_some()),
        (Member::HorizontalFovDeg, p.horizontal_fov_deg.is_some()),
    ]
    .into_iter()
    .filter_map(|(member, given)| given.then_some(member.name()))
    .collect();
    if modes.len() > 1 {
        for member in [
            Member::FocalLengthPx,
            Member::FocalLengthMm,
            Member::HorizontalFovDeg,
        ] {
            if modes.contains(&member.name()) {
                faults.add(
                    member,
                    format!(
                        "give exactly one focal option, but {} were given",
                        modes.join(", ")
                    ),
                );
            }
        }
        return None;
    }
    for (member, value) in [
        (Member::SensorWidthMm, p.sensor_width_mm),
        (Member::PixelSizeUm, p.pixel_size_um),
    ] {
        if value.is_some() && p.mm.is_none() {
            faults.add(member, "only converts focal_length_mm, which was not given");
        }
    }
    let spec = if let Some(px) = p.px {
        FocalLength::Pixels(faults.positive(Member::FocalLengthPx, px)?)
    } else if let Some(mm) = p.mm {
        let focal_mm = faults.positive(Member::FocalLengthMm, mm);
        match (p.sensor_width_mm, p.pixel_size_um) {
            (None, None) => {
                faults.add(Member::FocalLengthMm, MM_ALONE);
                return None;
            }
            (Some(_), Some(_)) => {
                for member in [Member::SensorWidthMm, Member::PixelSizeUm] {
                    faults.add(member, "give sensor_width_mm or pixel_size_um, not both");
                }
                return None;
            }
            (Some(sensor), None) => FocalLength::MillimetresWithSensorWidth {
                focal_mm: focal_mm?,
                sensor_width_mm: faults.positive(Member::SensorWidthMm, sensor)?,
            },
            (None, Some(pitch)) => FocalLength::MillimetresWithPixelPitch {
                focal_mm: focal_mm?,
                pixel_pitch_um: faults.positive(Member::PixelSizeUm, pitch)?,
            },
        }
    } else if let Some(degrees) = p.horizontal_fov_deg {
        if !(degrees > 0.0 && degrees < 180.0) {
            faults.add(
                Member::HorizontalFovDeg,
                format!(
                    "must lie strictly between 0 and 180 degrees, got {}",
                    Num(degrees)
                ),
            );
            return None;
        }
        FocalLength::HorizontalFov { degrees }
    } else {
        // A focal member that was given but unreadable was already reported.
        let focal = [
            Member::FocalLengthPx,
            Member::FocalLengthMm,
            Member::HorizontalFovDeg,
            Member::SensorWidthMm,
            Member::PixelSizeUm,
        ];
        if !focal.iter().any(|&member| faults.has(member)) {
            faults.add(
                Member::FocalLengthPx,
                format!("a focal length is required: {FOCAL_OPTIONS}"),
            );
        }
        return None;
    };
    let width = match spec {
        FocalLength::MillimetresWithSensorWidth { .. } => faults.needed(
            Member::ImageWidth,
            width,
            "to convert focal_length_mm with sensor_width_mm (f_px = f_mm · image_width / \
             sensor_width_mm)",
        )?,
        FocalLength::HorizontalFov { .. } => faults.needed(
            Member::ImageWidth,
            width,
            "to convert horizontal_fov_deg (f_px = (image_width / 2) / tan(hfov / 2))",
        )?,
        FocalLength::Pixels(_) | FocalLength::MillimetresWithPixelPitch { .. } => 0.0,
    };
    match spec.to_pixels(width) {
        Ok(focal_px) if focal_px > 0.0 => Some(focal_px),
        Ok(focal_px) => {
            faults.add(
                p.member(),
                format!(
                    "converts to {} px, which is not a usable focal length",
                    Num(focal_px)
                ),
            );
            None
        }
        Err(_) => {
            faults.add(
                p.member(),
                "converts to a focal length in pixels too large to represent",
            );
            None
        }
    }
}
