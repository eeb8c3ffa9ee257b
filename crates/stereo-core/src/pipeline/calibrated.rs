//! A request's calibration resolved once: a rig (from a rig's members or a calibration file)
//! made the rig of images of one size, then, when the pair is raw, the raw rig it is rectified
//! with (`alpha` applied as `cv2.stereoRectify` applies it). Each refusal is a [`SizeFault`] or
//! a [`PlanFault`] for the caller to name.

use std::fmt;

use crate::calibration::files::{Raw, Read};
use crate::camera::{Alpha, LatlonFault, LatlonOptions, RectifyOptions, stereo_rectify};
use crate::physics::{Fault as RigFault, Implausible, LengthUnit, Rig, RigSpec};

/// A rig with what its calibration file adds: the rig of the images (the rectified rig, for a
/// file of raw cameras), the file's disparity range and warnings, and the raw cameras.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibrated {
    /// The rig, for the images' size.
    pub rig: Rig,
    /// The calibration file's disparity range (Middlebury `ndisp`).
    pub max_disparity: Option<u32>,
    /// What the file's reader noticed, in sentences.
    pub warnings: Vec<String>,
    /// The raw cameras the calibration describes, when it does; their T in `file_unit`.
    pub raw: Option<Box<Raw>>,
    /// The unit of the file's lengths (the rig's own, for a rig given by its members).
    pub file_unit: LengthUnit,
}

/// The warning for a rig whose baseline no stereo camera has (a unit typed wrong), naming
/// the unit it was likely meant in ([`Implausible`]).
fn implausible(rig: &Rig) -> Option<String> {
    Implausible::baseline(rig.baseline(), rig.unit()).map(|i| i.to_string())
}

/// Why a calibration is not the calibration of images of a size.
#[derive(Debug, Clone, PartialEq)]
pub enum SizeFault {
    /// The file states another size: `calibrated` (the raw frames', for raw cameras).
    Mismatch {
        calibrated: (f64, f64),
        images: (u32, u32),
    },
    /// The rig made for the images' size is not a rig.
    Rig(Vec<RigFault>),
}

impl Calibrated {
    /// A rig given by its members: nothing to rectify.
    pub fn of_rig(rig: Rig) -> Self {
        Self {
            file_unit: rig.unit(),
            warnings: implausible(&rig).into_iter().collect(),
            rig,
            max_disparity: None,
            raw: None,
        }
    }

    /// A calibration file read, made the calibration of images of `size` (when known): raw
    /// frames of a raw calibration keep its rectified rig; a file without a size takes the
    /// images'; a file of another size is refused.
    pub fn from_file(read: Read, size: Option<(u32, u32)>) -> Result<Self, SizeFault> {
        let Read {
            rig,
            max_disparity_px,
            mut warnings,
            raw,
            file_unit,
            ..
        } = read;
        warnings.extend(implausible(&rig));
        let raw_size = raw.as_ref().map(|r| (r.size.width, r.size.height));
        let given = |rig| Calibrated {
            rig,
            max_disparity: max_disparity_px,
            warnings,
            raw,
            file_unit,
        };
        let Some((w, h)) = size else {
            return Ok(given(rig));
        };
        if raw_size == Some((w, h)) {
            return Ok(given(rig));
        }
        if let (Some(cw), Some(ch)) = (rig.image_width(), rig.image_height())
            && (cw, ch) != (f64::from(w), f64::from(h))
        {
            let calibrated = raw_size.map_or((cw, ch), |(rw, rh)| (f64::from(rw), f64::from(rh)));
            return Err(SizeFault::Mismatch {
                calibrated,
                images: (w, h),
            });
        }
        rig.with_image_size(w, h).map(given).map_err(SizeFault::Rig)
    }

    /// Whether frames of `size` are this calibration's raw frames, to be rectified.
    pub fn takes_raw_frames(&self, size: Option<(u32, u32)>) -> bool {
        self.raw.as_ref().is_some_and(|raw| {
            !raw.is_identity() && Some((raw.size.width, raw.size.height)) == size
        })
    }

    /// The same raw rig rectified again with `alpha`, as `cv2.stereoRectify` would.
    pub fn with_alpha(mut self, alpha: Alpha) -> Result<Self, PlanFault> {
        let Some(raw) = self.raw.as_deref() else {
            return Err(PlanFault::NotRaw);
        };
        let options = RectifyOptions {
            alpha,
            new_size: Some(raw.rectification.size),
            ..RectifyOptions::default()
        };
        let rectification = stereo_rectify(&raw.pair, raw.size, options)
            .map_err(|e| PlanFault::CannotRectify(e.to_string()))?;
        let rig = rectification
            .rig(self.file_unit)
            .map_err(|_| PlanFault::Vertical)?;
        self.raw = Some(Box::new(Raw {
            rectification,
            computed: true,
            latlon: None,
            ..raw.clone()
        }));
        self.rig = rig;
        Ok(self)
    }
}

impl Calibrated {
    /// The same raw rig rectified to latitude-longitude ([`crate::camera::Latlon`]), the field
    /// and resolution chosen where `options` leave them out. Its `rig` is the pinhole rig the
    /// latlon pair is at its centre column (f = pixels per radian, the baseline, the pixel of
    /// azimuth 0): what the range chosen from the pair and the refusals of a short range
    /// reason with; the depths themselves are the latlon system's ([`super::depth`]). With
    /// `options.when_wide`, cameras that do not see wide are kept on the pinhole plane.
    pub fn with_latlon(mut self, options: LatlonOptions) -> Result<Self, PlanFault> {
        let Some(raw) = self.raw.as_deref() else {
            return Err(PlanFault::NotRaw);
        };
        let raw = raw
            .clone()
            .with_latlon(options)
            .map_err(PlanFault::Latlon)?;
        // Narrow cameras asked for latlon only if wide (`when_wide`) stay as they are.
        let Some(l) = raw.latlon else {
            return Ok(self);
        };
        let mut spec = RigSpec::pixels(l.fx, l.baseline, self.file_unit);
        // The calibration's σ, as shares of f and B, carry over.
        spec.focal_std_px = Some(self.rig.focal_std_px() / self.rig.focal_px() * l.fx);
        spec.baseline_std = Some(self.rig.baseline_std());
        spec.cx = Some(l.cx);
        spec.cy = Some(l.cy);
        spec.camera.image_width = Some(l.size.width);
        spec.camera.image_height = Some(l.size.height);
        self.rig = Rig::new(&spec).map_err(|faults| {
            let said: Vec<String> = faults
                .iter()
                .map(|f| format!("{}: {}", f.member.name(), f.message))
                .collect();
            PlanFault::CannotRectify(format!(
                "its latitude-longitude field has no rig at its centre ({})",
                said.join("; ")
            ))
        })?;
        self.raw = Some(Box::new(raw));
        Ok(self)
    }
}

/// Whether a pair is rectified before it is matched.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RectifyMode {
    /// Never: the pair is matched as sent.
    No,
    /// Always: a calibration of raw cameras is required.
    Yes,
    /// When the calibration describes raw cameras and the frames are of their size.
    #[default]
    Auto,
}

/// What a request sent to describe its rig.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sent {
    /// Nothing.
    Nothing,
    /// A rig's members: a rectified rig, whatever else came with it.
    Rig,
    /// A calibration file.
    Calibration,
}

/// Why a pair cannot be rectified as asked.
#[derive(Debug, Clone, PartialEq)]
pub enum PlanFault {
    /// `alpha` was given but the pair is matched as sent.
    AlphaUnused,
    /// Rectifying was asked of a rig's members, which describe rectified images.
    RigIsRectified,
    /// Rectifying was asked without a calibration.
    NoCalibration,
    /// The calibration describes rectified images only.
    NotRaw,
    /// The frames are not of the raw cameras' size.
    WrongSize { images: (u32, u32), raw: (u32, u32) },
    /// `stereoRectify` refused the cameras.
    CannotRectify(String),
    /// The rectified cameras are one above the other.
    Vertical,
    /// `projection=latlon` was asked but the pair is matched as sent.
    LatlonUnused,
    /// `alpha` was given with `projection=latlon` (it sets the pinhole plane's field).
    AlphaWithLatlon,
    /// The cameras cannot be rectified to latitude-longitude as asked.
    Latlon(LatlonFault),
}

/// What a calibration that cannot rectify lacks.
pub const NOT_RAW: &str = "describes only rectified images (a Middlebury or KITTI odometry \
     file, a Q matrix, projections without the cameras): rectifying raw frames needs each \
     camera's K and D and their pose or rectification: a stereoCalibrate file (M1 D1 M2 D2 R \
     T), a ROS CameraInfo pair with K D R P, KITTI's calib_cam_to_cam.txt with K_0i D_0i \
     R_rect_0i, or /calibrate's opencv.yml";

impl fmt::Display for PlanFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PlanFault::AlphaUnused => f.write_str(
                "applies only when the pair is rectified here (rectify=yes, or auto with a \
                 calibration of raw cameras and frames of their size)",
            ),
            PlanFault::RigIsRectified => f.write_str(
                "describes rectified images only: rectifying needs a calibration part with the \
                 raw cameras",
            ),
            PlanFault::NoCalibration => f.write_str(
                "is required: the calibration of the raw cameras (a stereoCalibrate file, a ROS \
                 CameraInfo pair, KITTI's calib_cam_to_cam.txt or /calibrate's opencv.yml)",
            ),
            PlanFault::NotRaw => f.write_str(NOT_RAW),
            PlanFault::WrongSize {
                images: (w, h),
                raw: (rw, rh),
            } => write!(
                f,
                "is {w} × {h}, but the calibration's raw frames are {rw} × {rh}: send the frames \
                 the cameras deliver, at the calibrated size"
            ),
            PlanFault::CannotRectify(why) => write!(f, "cannot be rectified: {why}"),
            PlanFault::LatlonUnused => f.write_str(
                "latlon applies only when the pair is rectified here (rectify=yes, or auto with \
                 a calibration of raw cameras and frames of their size)",
            ),
            PlanFault::AlphaWithLatlon => f.write_str(
                "applies only with projection=pinhole (a latlon field is set by az_fov and \
                 el_fov)",
            ),
            PlanFault::Latlon(fault) => fault.fmt(f),
            PlanFault::Vertical => f.write_str(
                "the rectified cameras are one above the other (vertical stereo); this service \
                 measures horizontal disparities",
            ),
        }
    }
}

/// The raw rig a pair of `size` is rectified with, `alpha` applied; refused when what was
/// `sent` has no raw cameras of that size. `calibrated` is `None` when what was sent could not
/// be read (its faults already named): then nothing more is said.
pub fn raw_rig(
    calibrated: Option<&Calibrated>,
    sent: Sent,
    size: Option<(u32, u32)>,
    alpha: Option<Alpha>,
) -> Result<Option<Calibrated>, PlanFault> {
    match sent {
        Sent::Rig => return Err(PlanFault::RigIsRectified),
        Sent::Nothing => return Err(PlanFault::NoCalibration),
        Sent::Calibration => {}
    }
    let Some(given) = calibrated else {
        return Ok(None);
    };
    let Some(raw) = &given.raw else {
        return Err(PlanFault::NotRaw);
    };
    if let Some(images) = size
        && (raw.size.width, raw.size.height) != images
    {
        return Err(PlanFault::WrongSize {
            images,
            raw: (raw.size.width, raw.size.height),
        });
    }
    match alpha {
        Some(alpha) => given.clone().with_alpha(alpha).map(Some),
        None => Ok(Some(given.clone())),
    }
}

/// Whether a pair of `size` is rectified before matching (`mode`, with `alpha`, or to
/// latitude-longitude with `latlon`'s options): the raw rig to rectify with (whose `rig` is
/// then the rectified rig, `alpha` applied), or `None` to match the pair as sent. Latlon
/// `when_wide` (`projection=auto`) is a choice, never a fault: with `alpha`, or a pair matched
/// as sent, it is the pinhole plane.
pub fn plan(
    calibrated: Option<&Calibrated>,
    sent: Sent,
    size: Option<(u32, u32)>,
    mode: RectifyMode,
    alpha: Option<Alpha>,
    latlon: Option<LatlonOptions>,
) -> Result<Option<Calibrated>, PlanFault> {
    let wanted = match mode {
        RectifyMode::No => false,
        RectifyMode::Yes => true,
        // Before the frames' size is known (a stream's settings), raw cameras will be.
        RectifyMode::Auto => calibrated.is_some_and(|c| match size {
            Some(_) => c.takes_raw_frames(size),
            None => c.raw.as_ref().is_some_and(|raw| !raw.is_identity()),
        }),
    };
    let latlon = latlon.and_then(|l| l.unless_pinhole(alpha.is_some() || !wanted));
    if !wanted {
        return match (alpha, latlon) {
            (Some(_), _) => Err(PlanFault::AlphaUnused),
            (None, Some(_)) => Err(PlanFault::LatlonUnused),
            (None, None) => Ok(None),
        };
    }
    if alpha.is_some() && latlon.is_some() {
        return Err(PlanFault::AlphaWithLatlon);
    }
    match (raw_rig(calibrated, sent, size, alpha)?, latlon) {
        (Some(raw), Some(options)) => raw.with_latlon(options).map(Some),
        (raw, _) => Ok(raw),
    }
}
