//! Stereo triangulation for a rectified camera pair: pure functions on plain numbers, with no HTTP
//! or serialisation anywhere in their signatures.
//!
//! Conventions used throughout:
//! - disparity `d = x_left − x_right` in pixels (signed);
//! - the *effective* disparity is `d + doffs`, where `doffs` is the principal-point offset between
//!   the two cameras (Middlebury's `doffs`, zero for most rigs);
//! - depth `Z = B·f_px / |d + doffs|`, in the unit of the baseline `B`;
//! - focal length `f_px` is always in pixels: a focal length in millimetres times a disparity in
//!   pixels is not a length, so millimetres must be converted first ([`FocalLength::to_pixels`]);
//! - depth error `ΔZ = Z²·Δd / (f_px·B)`, the first-order propagation of a disparity error `Δd`;
//! - `distance` is the depth `Z` along the optical axis; `range` is the straight line
//!   `√(X² + Y² + Z²)` from the left camera's optical centre to the point.

use std::fmt;

mod camera;
pub mod design;
mod plausible;
mod rig;

pub use camera::{
    CameraSpec, DEFAULT_DISPARITY_ERROR_PX, Fault, Focal, MM_ALONE, Member, RectifiedCamera,
};
pub use plausible::{Implausible, Length};
pub use rig::{DepthErrorTerms, Rig, RigSpec};

/// Relative depth error above which a measurement carries a [`Warning::LargeRelativeError`].
pub const LARGE_RELATIVE_ERROR: f64 = 0.1;

/// A unit of length for the baseline and every length derived from it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum LengthUnit {
    #[default]
    Millimetre,
    Centimetre,
    Metre,
    Inch,
    Foot,
}

impl LengthUnit {
    /// Every unit the service knows.
    pub const ALL: [LengthUnit; 5] = [
        LengthUnit::Millimetre,
        LengthUnit::Centimetre,
        LengthUnit::Metre,
        LengthUnit::Inch,
        LengthUnit::Foot,
    ];

    /// The symbol users type and read: `mm`, `cm`, `m`, `in`, `ft`.
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Millimetre => "mm",
            LengthUnit::Centimetre => "cm",
            LengthUnit::Metre => "m",
            LengthUnit::Inch => "in",
            LengthUnit::Foot => "ft",
        }
    }

    /// How many metres one of this unit is (exact by definition for in and ft).
    pub fn metres(self) -> f64 {
        match self {
            LengthUnit::Millimetre => 0.001,
            LengthUnit::Centimetre => 0.01,
            LengthUnit::Metre => 1.0,
            LengthUnit::Inch => 0.0254,
            LengthUnit::Foot => 0.3048,
        }
    }

    /// Converts `value` from this unit into `to`.
    pub fn convert(self, value: f64, to: LengthUnit) -> f64 {
        value * (self.metres() / to.metres())
    }
}

/// The ways a user can state the focal length; all of them end up in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FocalLength {
    /// Already in pixels (`fx` from a calibration).
    Pixels(f64),
    /// Millimetres plus the sensor's active width in millimetres.
    MillimetresWithSensorWidth { focal_mm: f64, sensor_width_mm: f64 },
    /// Millimetres plus the pixel pitch in micrometres.
    MillimetresWithPixelPitch { focal_mm: f64, pixel_pitch_um: f64 },
    /// Horizontal field of view in degrees, over the full image width.
    HorizontalFov { degrees: f64 },
}

impl FocalLength {
    /// The focal length in pixels for an image `image_width_px` pixels wide;
    /// [`PhysicsError::NotFinite`] when the conversion overflows.
    pub fn to_pixels(self, image_width_px: f64) -> Result<f64, PhysicsError> {
        finite(match self {
            FocalLength::Pixels(px) => px,
            FocalLength::MillimetresWithSensorWidth {
                focal_mm,
                sensor_width_mm,
            } => focal_mm * image_width_px / sensor_width_mm,
            FocalLength::MillimetresWithPixelPitch {
                focal_mm,
                pixel_pitch_um,
            } => focal_mm * 1000.0 / pixel_pitch_um,
            FocalLength::HorizontalFov { degrees } => {
                (image_width_px / 2.0) / (degrees.to_radians() / 2.0).tan()
            }
        })
    }
}

/// The field of view in degrees that a focal length of `focal_px` gives over `extent_px` pixels.
pub fn field_of_view_deg(focal_px: f64, extent_px: f64) -> f64 {
    (2.0 * (extent_px / 2.0 / focal_px).atan()).to_degrees()
}

/// The shortest baseline that keeps the depth error at `distance` within `max_depth_error`, for a
/// focal length of `focal_px` and a disparity error `Δd`: `B = Z²·Δd / (f_px·ΔZ)`, the depth
/// error formula solved for `B`. The result is in the unit of `distance` and `max_depth_error`.
pub fn baseline_for(
    focal_px: f64,
    distance: f64,
    max_depth_error: f64,
    disparity_error_px: f64,
) -> Result<f64, PhysicsError> {
    finite(distance * distance * disparity_error_px / (focal_px * max_depth_error))
}

/// One feature seen in both images: its disparity `d = x_left − x_right`, and where it is in
/// the left image (`None`: at the principal point, the default).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Correspondence {
    pub x_left: Option<f64>,
    pub disparity_px: f64,
    pub y: Option<f64>,
}

impl Correspondence {
    /// The feature at `x_left` in the left image and `x_right` in the right one, on row `y`.
    pub fn from_pair(x_left: f64, x_right: f64, y: f64) -> Self {
        Self {
            x_left: Some(x_left),
            disparity_px: x_left - x_right,
            y: Some(y),
        }
    }

    /// The feature at `(x, y)` in the left image with disparity `d`.
    pub fn at(x: f64, y: f64, disparity_px: f64) -> Self {
        Self {
            x_left: Some(x),
            disparity_px,
            y: Some(y),
        }
    }
}

impl Point3 {
    /// The straight-line distance from the origin (the left camera's optical centre):
    /// `√(x² + y² + z²)`, computed without intermediate overflow.
    pub fn norm(&self) -> f64 {
        self.x.hypot(self.y).hypot(self.z)
    }
}

/// A point in the left camera's frame: x right, y down, z forward, in the rig's unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// Something a caller should know about a result that is still computed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Warning {
    /// `d + doffs < 0`: the feature is to the left in the right image. The distance uses |d + doffs|.
    NegativeDisparity { effective_disparity_px: f64 },
    /// The depth error is a large fraction of the distance.
    LargeRelativeError { relative_error: f64 },
    /// The rig has no principal point (neither `cx`, `cy` nor the image size): the depth is
    /// known, the 3D point and the range are not.
    NoPrincipalPoint,
    /// The baseline is one no stereo rig has (under 1 mm or over 10 m): its unit was likely
    /// typed wrong, and every distance is off by the same factor.
    ImplausibleBaseline(Implausible),
}

impl Warning {
    /// A stable machine-readable code.
    pub fn code(&self) -> &'static str {
        match self {
            Warning::NegativeDisparity { .. } => "negative_disparity",
            Warning::LargeRelativeError { .. } => "large_relative_error",
            Warning::NoPrincipalPoint => "no_principal_point",
            Warning::ImplausibleBaseline(_) => "implausible_baseline",
        }
    }
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Warning::NegativeDisparity {
                effective_disparity_px,
            } => write!(
                f,
                "the effective disparity d + doffs = {} px is negative: the distance uses its \
                 absolute value, but check that the left and right images (or x_left and \
                 x_right) are not swapped",
                crate::numbers::Num(*effective_disparity_px)
            ),
            Warning::LargeRelativeError { relative_error } => write!(
                f,
                "the depth error is {:.1} % of the distance: the disparity is only a few times \
                 the matching error, so treat this distance as a rough estimate",
                relative_error * 100.0
            ),
            Warning::NoPrincipalPoint => f.write_str(
                "the depth needs only f, B and d; the 3D point, the range and normalized_x \
                 also need the principal point: give cx and cy, or image_width and \
                 image_height (the default principal point is the image centre)",
            ),
            Warning::ImplausibleBaseline(implausible) => implausible.fmt(f),
        }
    }
}

/// Why a computation has no finite answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PhysicsError {
    /// The effective disparity is zero: the point is at infinity.
    AtInfinity,
    /// A result overflowed (or an input was so small that it did).
    NotFinite,
}

impl fmt::Display for PhysicsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PhysicsError::AtInfinity => {
                f.write_str("the effective disparity d + doffs is zero: the point is at infinity")
            }
            PhysicsError::NotFinite => {
                f.write_str("the effective disparity d + doffs is too small for a finite distance")
            }
        }
    }
}

impl std::error::Error for PhysicsError {}

/// `value` when it is finite, else [`PhysicsError::NotFinite`].
pub fn finite(value: f64) -> Result<f64, PhysicsError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(PhysicsError::NotFinite)
    }
}

/// Everything the service reports about one correspondence.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    pub disparity_px: f64,
    pub effective_disparity_px: f64,
    /// Depth `Z` along the optical axis.
    pub distance: f64,
    /// Straight-line distance `√(X² + Y² + Z²)` from the left optical centre to the point,
    /// when the principal point is known.
    pub range: Option<f64>,
    pub distance_m: f64,
    pub depth_error: f64,
    /// The depth error's terms: disparity, focal length, baseline.
    pub depth_error_terms: DepthErrorTerms,
    pub relative_error: f64,
    pub normalized_x: Option<f64>,
    pub projection_factor: f64,
    /// The point in the left camera's frame, when the principal point is known.
    pub point: Option<Point3>,
    pub warnings: Vec<Warning>,
}

/// Triangulates one correspondence. Every number in an `Ok` result is finite.
pub fn measure(rig: &Rig, c: Correspondence) -> Result<Measurement, PhysicsError> {
    let disparity_px = c.disparity_px;
    let effective_disparity_px = disparity_px + rig.doffs();
    let distance = rig.distance_at(disparity_px)?;
    let depth_error_terms = rig.depth_error_terms_at(distance);
    for term in [
        depth_error_terms.disparity,
        depth_error_terms.focal_length,
        depth_error_terms.baseline,
    ] {
        finite(term)?;
    }
    let depth_error = finite(depth_error_terms.total())?;
    let relative_error = finite(depth_error / distance)?;
    let x_left = c.x_left.or(rig.cx());
    let y = c.y.or(rig.cy());
    let point = match (x_left, y) {
        (Some(x), Some(y)) => rig.point_at(x, y, distance).transpose()?,
        _ => None,
    };
    let range = point.map(|p| finite(p.norm())).transpose()?;
    let mut warnings = Vec::new();
    if effective_disparity_px < 0.0 {
        warnings.push(Warning::NegativeDisparity {
            effective_disparity_px,
        });
    }
    if relative_error > LARGE_RELATIVE_ERROR {
        warnings.push(Warning::LargeRelativeError { relative_error });
    }
    if point.is_none() {
        warnings.push(Warning::NoPrincipalPoint);
    }
    if let Some(implausible) = Implausible::baseline(rig.baseline(), rig.unit()) {
        warnings.push(Warning::ImplausibleBaseline(implausible));
    }
    Ok(Measurement {
        disparity_px,
        effective_disparity_px,
        distance,
        range,
        distance_m: finite(distance * rig.unit().metres())?,
        depth_error,
        depth_error_terms,
        relative_error,
        normalized_x: x_left
            .and_then(|x| rig.normalized_x(x))
            .map(finite)
            .transpose()?,
        projection_factor: finite(rig.projection_factor())?,
        point,
        warnings,
    })
}

/// How samples are spread between the ends of a range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Spacing {
    Linear,
    /// Geometric: equal ratios between neighbours (denser where the curve bends).
    Log,
}

/// The stretch of the disparity–distance curve to sample. Callers guarantee `0 < min < max` for
/// distances and `0 < min + doffs`, `min < max` for disparities.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SampleRange {
    /// Distances in the rig's unit; samples are spaced in distance.
    Distance { min: f64, max: f64 },
    /// Raw disparities in pixels; samples are spaced in effective disparity.
    Disparity { min: f64, max: f64 },
}

impl SampleRange {
    /// The range used when a caller gives none: raw disparities from the first whole pixel of
    /// positive effective disparity (at least 1 px) across a quarter of the image width
    /// `image_width`, which is the search range of a typical block matcher. It is widened to
    /// take in `measured`, the caller's own disparity, when that lies beyond it.
    pub fn default_for(
        rig: &Rig,
        image_width: f64,
        measured_disparity_px: Option<f64>,
    ) -> SampleRange {
        let min = 1.0_f64.max(1.0 - rig.doffs());
        let mut max = min + (image_width / 4.0 - 1.0).max(1.0);
        if let Some(d) = measured_disparity_px
            && d + rig.doffs() > 0.0
            && d * 1.25 > max
        {
            max = d * 1.25;
        }
        SampleRange::Disparity { min, max }
    }
}

/// `count` values from `min` to `max`, both ends included (just `min` when `count` is 1).
pub fn spaced(min: f64, max: f64, count: usize, spacing: Spacing) -> impl Iterator<Item = f64> {
    let last = count.saturating_sub(1).max(1) as f64;
    (0..count).map(move |i| {
        let t = i as f64 / last;
        let value = match spacing {
            Spacing::Linear => min + (max - min) * t,
            Spacing::Log => min * (max / min).powf(t),
        };
        // Land exactly on the ends despite rounding.
        if i + 1 == count && count > 1 {
            max
        } else {
            value
        }
    })
}

/// One point on the rig's disparity–distance curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub disparity_px: f64,
    pub distance: f64,
    pub depth_error: f64,
}

/// Samples the curve at `count` points across `range`, in the order of the ranged quantity
/// (ascending). Every number in an `Ok` result is finite.
pub fn sweep(
    rig: &Rig,
    range: SampleRange,
    count: usize,
    spacing: Spacing,
) -> Result<Vec<Sample>, PhysicsError> {
    let sample_at = |disparity_px: f64, distance: f64| -> Result<Sample, PhysicsError> {
        Ok(Sample {
            disparity_px: finite(disparity_px)?,
            distance: finite(distance)?,
            depth_error: finite(rig.depth_error_at(distance))?,
        })
    };
    match range {
        SampleRange::Distance { min, max } => spaced(min, max, count, spacing)
            .map(|z| sample_at(rig.disparity_at(z), z))
            .collect(),
        SampleRange::Disparity { min, max } => {
            spaced(min + rig.doffs(), max + rig.doffs(), count, spacing)
                .map(|effective| {
                    let d = effective - rig.doffs();
                    sample_at(d, rig.distance_at(d)?)
                })
                .collect()
        }
    }
}

/// A row of the sample table: the seed's columns plus the depth error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableRow {
    pub distance: f64,
    pub disparity_px: f64,
    /// Normalised x of the right-image feature, `x_right = x_left − d`, when the image width
    /// is known.
    pub normalized_x: Option<f64>,
    pub projection_factor: f64,
    pub depth_error: f64,
}

/// The sample table for `range`, with the left-image x held at `x_left`.
pub fn table(
    rig: &Rig,
    range: SampleRange,
    steps: usize,
    spacing: Spacing,
    x_left: f64,
) -> Result<Vec<TableRow>, PhysicsError> {
    let projection_factor = finite(rig.projection_factor())?;
    sweep(rig, range, steps, spacing)?
        .into_iter()
        .map(|s| {
            Ok(TableRow {
                distance: s.distance,
                disparity_px: s.disparity_px,
                normalized_x: rig
                    .normalized_x(x_left - s.disparity_px)
                    .map(finite)
                    .transpose()?,
                projection_factor,
                depth_error: s.depth_error,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An 800 × 600 rig in mm with its principal point at the centre, as stated.
    fn spec(focal_px: f64, baseline: f64) -> RigSpec {
        let mut spec = RigSpec::pixels(focal_px, baseline, LengthUnit::Millimetre);
        spec.camera.image_width = Some(800);
        spec.camera.image_height = Some(600);
        spec
    }

    fn rig(focal_px: f64, baseline: f64) -> Rig {
        build(&spec(focal_px, baseline))
    }

    fn build(spec: &RigSpec) -> Rig {
        Rig::new(spec).unwrap()
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0)
    }

    fn at(x_left: f64, x_right: f64) -> Correspondence {
        Correspondence::from_pair(x_left, x_right, 300.0)
    }

    /// The seed's first example, with f read as 35 px, is 105 mm away.
    #[test]
    fn seed_example_one_reproduces() {
        let m = measure(&rig(35.0, 150.0), at(400.0, 350.0)).unwrap();
        assert_eq!(m.disparity_px, 50.0);
        assert!(close(m.distance, 105.0));
        assert!(close(m.distance_m, 0.105));
        assert_eq!(m.normalized_x, Some(0.0));
        assert_eq!(m.range, Some(m.distance));
        assert!(close(m.projection_factor, 35.0 / 150.0));
        assert!(m.warnings.is_empty());
    }

    /// A negative disparity still gives a distance from |d|, with a warning.
    #[test]
    fn negative_disparity_uses_absolute_value_and_warns() {
        let mut s = spec(12.0, 50.0);
        s.camera.image_width = Some(640);
        s.cx = Some(400.0);
        let r = build(&s);
        let m = measure(&r, at(180.0, 195.0)).unwrap();
        assert_eq!(m.disparity_px, -15.0);
        assert!(close(m.distance, 40.0));
        assert!(close(m.normalized_x.unwrap(), -0.4375));
        assert_eq!(m.warnings[0].code(), "negative_disparity");
    }

    /// Zero effective disparity is a point at infinity, not a number.
    #[test]
    fn zero_disparity_is_at_infinity() {
        assert_eq!(
            measure(&rig(35.0, 150.0), at(400.0, 400.0)),
            Err(PhysicsError::AtInfinity)
        );
        let mut s = spec(35.0, 150.0);
        s.doffs = Some(-50.0);
        let r = build(&s);
        assert_eq!(measure(&r, at(400.0, 350.0)), Err(PhysicsError::AtInfinity));
    }

    /// A subnormal disparity overflows the distance; that is an error, never infinity.
    #[test]
    fn overflow_is_an_error() {
        let mut s = spec(1e6, 1e3);
        s.doffs = Some(1e-310);
        let r = build(&s);
        assert_eq!(measure(&r, at(400.0, 400.0)), Err(PhysicsError::NotFinite));
    }

    /// The doffs offset is added to the disparity before dividing.
    #[test]
    fn doffs_is_added_to_disparity() {
        let mut s = spec(1000.0, 200.0);
        s.doffs = Some(50.0);
        let r = build(&s);
        assert!(close(r.distance_at(50.0).unwrap(), 2000.0));
        assert!(close(r.disparity_at(2000.0), 50.0));
    }

    /// The depth error follows Z²·Δd/(f·B): 10 m at f = 1000 px, B = 100 mm, Δd = 0.5 is ±500 mm.
    #[test]
    fn depth_error_formula() {
        let r = rig(1000.0, 100.0);
        let m = measure(&r, at(510.0, 500.0)).unwrap();
        assert!(close(m.distance, 10_000.0));
        assert!(close(m.depth_error, 500.0));
        assert!(close(m.relative_error, 0.05));
    }

    /// A calibration's σ_f and σ_B add their terms in quadrature: at Z = 10 m, f = 1000 px,
    /// B = 100 mm, Δd = 0.5, σ_f = 20 px (2 %) and σ_B = 1 mm (1 %), the terms are 500, 200 and
    /// 100 mm and σ_Z = √(500² + 200² + 100²).
    #[test]
    fn calibration_uncertainty_adds_its_terms() {
        let mut s = spec(1000.0, 100.0);
        s.focal_std_px = Some(20.0);
        s.baseline_std = Some(1.0);
        let r = build(&s);
        let m = measure(&r, at(510.0, 500.0)).unwrap();
        assert!(close(m.depth_error_terms.disparity, 500.0));
        assert!(close(m.depth_error_terms.focal_length, 200.0));
        assert!(close(m.depth_error_terms.baseline, 100.0));
        assert!(close(m.depth_error, 300_000f64.sqrt()));
        assert!(close(m.relative_error, 300_000f64.sqrt() / 10_000.0));
        // Metres: the baseline's σ converts with the baseline, the terms stay the same share.
        let metres = r.in_unit(LengthUnit::Metre);
        assert!(close(metres.baseline_std(), 0.001));
        assert!(close(metres.depth_error_at(10.0), 0.3f64.sqrt()));
        // The relative error the calibration leaves is √(0.02² + 0.01²) at every distance, so a
        // 2 % budget is reached where the disparity term is √(0.02² − 0.02² − 0.01²): nowhere.
        assert!(close(r.calibration_relative_error(), 0.0005f64.sqrt()));
        assert_eq!(r.distance_at_relative_error(0.02), None);
        let z = r.distance_at_relative_error(0.05).unwrap();
        assert!(close(r.relative_error_at(z), 0.05));
    }

    /// A σ must be finite and 0 or more, and each fault names its member.
    #[test]
    fn calibration_uncertainty_is_checked() {
        let mut s = spec(1000.0, 100.0);
        s.focal_std_px = Some(-1.0);
        s.baseline_std = Some(f64::NAN);
        let faults = Rig::new(&s).unwrap_err();
        let names: Vec<_> = faults.iter().map(|f| f.member.name()).collect();
        assert_eq!(names, ["focal_length_std_px", "baseline_std"]);
        let without = measure(&rig(1000.0, 100.0), at(510.0, 500.0)).unwrap();
        assert_eq!(without.depth_error_terms.focal_length, 0.0);
        assert_eq!(without.depth_error_terms.baseline, 0.0);
    }

    /// The 3D point comes from the pinhole model around the principal point.
    #[test]
    fn point_in_left_camera_frame() {
        let mut s = spec(1000.0, 100.0);
        s.camera.image_width = Some(1000);
        s.camera.image_height = Some(800);
        s.cx = Some(500.0);
        s.cy = Some(400.0);
        let m = measure(&build(&s), Correspondence::from_pair(700.0, 600.0, 500.0)).unwrap();
        assert_eq!(
            m.point,
            Some(Point3 {
                x: 200.0,
                y: 100.0,
                z: 1000.0
            })
        );
        // X = 200, Y = 100, Z = 1000: the range is √(200² + 100² + 1000²) = 1024.695 mm.
        assert!(close(m.range.unwrap(), 1_050_000.0_f64.sqrt()));
    }

    /// Y uses fy, X uses fx: with fy = 2·fx the same pixel offset is half the height.
    #[test]
    fn vertical_focal_length_scales_y_only() {
        let mut s = spec(1000.0, 100.0);
        s.camera.focal_y_px = Some(2000.0);
        let m = measure(&build(&s), Correspondence::from_pair(500.0, 400.0, 400.0)).unwrap();
        let point = m.point.unwrap();
        assert!(close(point.x, 100.0));
        assert!(close(point.y, 50.0));
        assert!(close(m.distance, 1000.0));
    }

    /// Without an image width there is no normalised x, and the fields of view are unknown,
    /// but the distance is the same; without a principal point too, there is no 3D point or
    /// range, and a warning says so.
    #[test]
    fn image_size_is_only_needed_for_what_uses_it() {
        let mut s = spec(1000.0, 100.0);
        let with = measure(&build(&s), at(510.0, 500.0)).unwrap();
        s.camera.image_width = None;
        s.camera.image_height = None;
        s.cx = Some(400.0);
        s.cy = Some(300.0);
        let r = build(&s);
        let without = measure(&r, at(510.0, 500.0)).unwrap();
        assert_eq!(without.normalized_x, None);
        assert_eq!(without.distance, with.distance);
        assert_eq!(without.point, with.point);
        assert_eq!(r.fields_of_view_deg(), (None, None));
        let bare = build(&RigSpec::pixels(1000.0, 100.0, LengthUnit::Millimetre));
        let depth_only = measure(&bare, at(510.0, 500.0)).unwrap();
        assert_eq!(depth_only.distance, with.distance);
        assert_eq!((depth_only.point, depth_only.range), (None, None));
        assert_eq!(depth_only.warnings[0].code(), "no_principal_point");
    }

    /// The four focal options agree on the reference numbers, and the FOV inverts.
    #[test]
    fn focal_conversions() {
        let sensor = FocalLength::MillimetresWithSensorWidth {
            focal_mm: 4.0,
            sensor_width_mm: 6.4,
        };
        assert!(close(sensor.to_pixels(1280.0).unwrap(), 800.0));
        let pitch = FocalLength::MillimetresWithPixelPitch {
            focal_mm: 6.0,
            pixel_pitch_um: 3.0,
        };
        assert!(close(pitch.to_pixels(1920.0).unwrap(), 2000.0));
        let fov = FocalLength::HorizontalFov { degrees: 90.0 };
        assert!(close(fov.to_pixels(1280.0).unwrap(), 640.0));
        assert!(close(field_of_view_deg(640.0, 1280.0), 90.0));
        assert_eq!(FocalLength::Pixels(35.0).to_pixels(800.0), Ok(35.0));
    }

    /// Units convert through metres exactly enough to compose.
    #[test]
    fn units_compose() {
        assert!(close(
            LengthUnit::Inch.convert(100.0, LengthUnit::Metre),
            2.54
        ));
        assert!(close(LengthUnit::Foot.convert(1.0, LengthUnit::Inch), 12.0));
        for a in LengthUnit::ALL {
            for b in LengthUnit::ALL {
                let there = a.convert(7.0, b);
                assert!(close(b.convert(there, a), 7.0), "{a:?} -> {b:?}");
            }
        }
    }

    /// Spacing hits both ends and is geometric for Log.
    #[test]
    fn spacing_hits_the_ends() {
        let lin: Vec<f64> = spaced(1.0, 3.0, 3, Spacing::Linear).collect();
        assert_eq!(lin, vec![1.0, 2.0, 3.0]);
        let log: Vec<f64> = spaced(1.0, 100.0, 3, Spacing::Log).collect();
        assert!(close(log[1], 10.0));
        assert_eq!(log[2], 100.0);
        assert_eq!(
            spaced(5.0, 9.0, 1, Spacing::Linear).collect::<Vec<_>>(),
            vec![5.0]
        );
    }

    /// Every table row satisfies Z·|d + doffs| = B·f, for both kinds of range.
    #[test]
    fn table_rows_lie_on_the_curve() {
        let mut s = spec(700.0, 120.0);
        s.doffs = Some(3.0);
        let r = build(&s);
        for range in [
            SampleRange::Distance {
                min: 500.0,
                max: 20_000.0,
            },
            SampleRange::Disparity {
                min: 2.0,
                max: 90.0,
            },
        ] {
            for spacing in [Spacing::Linear, Spacing::Log] {
                let rows = table(&r, range, 25, spacing, 400.0).unwrap();
                assert_eq!(rows.len(), 25);
                for row in rows {
                    assert!(close(row.distance * (row.disparity_px + 3.0).abs(), r.fb()));
                    assert!(close(row.depth_error, r.depth_error_at(row.distance)));
                    let x_right = 400.0 - row.disparity_px;
                    assert!(close(row.normalized_x.unwrap(), (x_right - 400.0) / 400.0));
                }
            }
        }
    }

    /// The reference rig: f = 424 px, B = 50 mm and a search up to 126 px see from
    /// 168.25 mm; with Δd = 0.08 px the RMS depth error at 2 m is 15.09 mm.
    #[test]
    fn reference_rig_range_and_error() {
        let r = rig(424.0, 50.0).with_disparity_error(0.08).unwrap();
        let (near, far) = r.depth_range(0.08, 126.0).unwrap();
        assert!(close(near, 168.253_968_253_968_25));
        assert!((near - 168.25).abs() < 0.005);
        assert!(close(far, 424.0 * 50.0 / 0.08));
        assert!((r.depth_error_at(2000.0) - 15.09).abs() < 0.005);
        assert!(close(
            r.relative_error_at(2000.0),
            15.094_339_622_641_51 / 2000.0
        ));
        let (Some(h), Some(v)) = r.fields_of_view_deg() else {
            panic!("the test rig has an image size");
        };
        assert!(close(h, field_of_view_deg(424.0, 800.0)));
        assert!(v < h);
    }

    /// The distance where the relative error reaches a budget has exactly that error, and
    /// there is no such distance when Δd is zero.
    #[test]
    fn distance_at_relative_error_inverts() {
        let r = rig(1000.0, 100.0);
        let z = r.distance_at_relative_error(0.02).unwrap();
        assert!(close(r.relative_error_at(z), 0.02));
        assert!(close(r.depth_error_at(z) / z, 0.02));
        let r = r.with_disparity_error(0.0).unwrap();
        assert_eq!(r.distance_at_relative_error(0.02), None);
    }

    /// The baseline from `baseline_for` gives back the requested depth error at the distance.
    #[test]
    fn baseline_for_inverts_depth_error() {
        // 0.5 % at 5 m with f = 1000 px and Δd = 0.25 px needs B = 250 mm.
        let b = baseline_for(1000.0, 5000.0, 25.0, 0.25).unwrap();
        assert!(close(b, 250.0));
        let r = rig(1000.0, b).with_disparity_error(0.25).unwrap();
        assert!(close(r.depth_error_at(5000.0), 25.0));
        assert_eq!(
            baseline_for(1.0, 1e200, 1e-200, 1.0),
            Err(PhysicsError::NotFinite)
        );
    }

    /// The default range starts at one pixel of effective disparity and takes in the measurement.
    #[test]
    fn default_range_covers_measurement() {
        let r = rig(35.0, 150.0);
        assert_eq!(
            SampleRange::default_for(&r, 800.0, Some(50.0)),
            SampleRange::Disparity {
                min: 1.0,
                max: 200.0
            }
        );
        assert_eq!(
            SampleRange::default_for(&r, 800.0, Some(400.0)),
            SampleRange::Disparity {
                min: 1.0,
                max: 500.0
            }
        );
        let mut s = spec(35.0, 150.0);
        s.doffs = Some(-10.0);
        let r = build(&s);
        let SampleRange::Disparity { min, .. } = SampleRange::default_for(&r, 800.0, None) else {
            panic!("default range is in disparity");
        };
        assert_eq!(min + r.doffs(), 1.0);
    }
}
