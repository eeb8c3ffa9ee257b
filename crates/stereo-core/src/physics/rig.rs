//! The camera and the rectified rig, each built only through its checking constructor
//! ([`RectifiedCamera::new`], [`Rig::new`]): a value that exists is a valid one, whichever way its
//! members arrived (a JSON rig, a calibration file, a rig part of an image request). What the
//! constructors refuse is a list of [`Fault`]s, each naming the [`Member`] at fault, which the
//! HTTP layer maps onto its field names and nothing more.

use crate::numbers::Num;

use super::camera::{CameraSpec, Fault, Faults, Focal, Member, RectifiedCamera, camera};
use super::{LengthUnit, PhysicsError, Point3, field_of_view_deg, finite};

/// A rig as stated, before it is checked: the camera, the baseline and the principal points,
/// and how well a calibration knows the focal length and the baseline.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RigSpec {
    pub camera: CameraSpec,
    pub baseline: Option<f64>,
    pub cx: Option<f64>,
    pub cy: Option<f64>,
    pub doffs: Option<f64>,
    /// σ of the focal length in pixels (default 0: known exactly).
    pub focal_std_px: Option<f64>,
    /// σ of the baseline in the rig's unit (default 0).
    pub baseline_std: Option<f64>,
}

/// The depth error's three independent terms, each a standard deviation in the rig's unit:
/// `σ_Z² = disparity² + focal_length² + baseline²`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthErrorTerms {
    /// From the disparity's uncertainty: `Z²·σ_d / (f·B)`.
    pub disparity: f64,
    /// From the focal length's: `Z·σ_f / f`.
    pub focal_length: f64,
    /// From the baseline's: `Z·σ_B / B`.
    pub baseline: f64,
}

impl DepthErrorTerms {
    /// `σ_Z`, the terms added in quadrature.
    pub fn total(&self) -> f64 {
        self.disparity.hypot(self.focal_length).hypot(self.baseline)
    }
}

impl RigSpec {
    /// A rig stated in pixels: `f` (fx = fy) and `baseline` in `unit`, the rest as given
    /// afterwards.
    pub fn pixels(focal_px: f64, baseline: f64, unit: LengthUnit) -> Self {
        Self {
            camera: CameraSpec {
                focal: Focal {
                    px: Some(focal_px),
                    ..Focal::default()
                },
                unit,
                ..CameraSpec::default()
            },
            baseline: Some(baseline),
            ..Self::default()
        }
    }
}

/// A calibrated, rectified stereo rig. Lengths are in `unit`; pixel quantities in pixels.
/// Built only by [`Rig::new`] (or [`Rig::from_camera`]), so every rig that exists has a
/// positive focal length and baseline whose product and ratio are finite, a principal point
/// on its image, and a disparity error of 0 or more.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rig {
    camera: RectifiedCamera,
    baseline: f64,
    cx: Option<f64>,
    cy: Option<f64>,
    doffs: f64,
    focal_std_px: f64,
    baseline_std: f64,
}

impl Rig {
    /// Checks a rig: the camera ([`RectifiedCamera::new`]), a positive baseline whose product and ratio
    /// with the focal length are finite, a principal point within the image when its size is
    /// known (by default the image centre; unknown without a size, when only depths can be
    /// computed), a finite `doffs` (default 0).
    pub fn new(spec: &RigSpec) -> Result<Rig, Vec<Fault>> {
        let mut faults = Faults {
            found: Vec::new(),
            unreadable: &spec.camera.unreadable,
        };
        let camera = camera(&spec.camera, &mut faults);
        let width = spec.camera.image_width.filter(|&n| n > 0).map(f64::from);
        let height = spec.camera.image_height.filter(|&n| n > 0).map(f64::from);
        let baseline = match spec.baseline {
            None => {
                faults.add(Member::Baseline, "is required");
                None
            }
            Some(b) => faults.positive(Member::Baseline, b),
        };
        let cx = principal(Member::Cx, spec.cx, width, &mut faults);
        let cy = principal(Member::Cy, spec.cy, height, &mut faults);
        let doffs = spec.doffs.unwrap_or(0.0);
        if !doffs.is_finite() {
            faults.add(Member::Doffs, "must be a finite number");
        }
        let focal_std_px =
            faults.non_negative(Member::FocalLengthStdPx, spec.focal_std_px.unwrap_or(0.0));
        let baseline_std =
            faults.non_negative(Member::BaselineStd, spec.baseline_std.unwrap_or(0.0));
        if let (Some(camera), Some(baseline)) = (&camera, baseline) {
            balanced(camera, baseline, &mut faults);
        }
        let (
            Some(camera),
            Some(baseline),
            Some(cx),
            Some(cy),
            Some(focal_std_px),
            Some(baseline_std),
        ) = (camera, baseline, cx, cy, focal_std_px, baseline_std)
        else {
            return Err(faults.found);
        };
        if !faults.found.is_empty() {
            return Err(faults.found);
        }
        Ok(Rig {
            camera,
            baseline,
            cx,
            cy,
            doffs,
            focal_std_px,
            baseline_std,
        })
    }

    /// The rig a checked camera makes with a second one `baseline` away, principal points at
    /// the image centre (unknown without the image size) and no doffs.
    pub fn from_camera(camera: RectifiedCamera, baseline: f64) -> Result<Rig, Vec<Fault>> {
        let mut faults = Faults {
            found: Vec::new(),
            unreadable: &[],
        };
        balanced(&camera, baseline, &mut faults);
        if faults.found.is_empty() {
            faults.positive(Member::Baseline, baseline);
        }
        match baseline {
            baseline if faults.found.is_empty() => Ok(Rig {
                camera,
                baseline,
                cx: camera.image_width.map(|w| w / 2.0),
                cy: camera.image_height.map(|h| h / 2.0),
                doffs: 0.0,
                focal_std_px: 0.0,
                baseline_std: 0.0,
            }),
            _ => Err(faults.found),
        }
    }

    /// The same rig with its lengths in `unit`.
    pub fn in_unit(self, unit: LengthUnit) -> Rig {
        Rig {
            camera: RectifiedCamera {
                unit,
                ..self.camera
            },
            baseline: self.camera.unit.convert(self.baseline, unit),
            baseline_std: self.camera.unit.convert(self.baseline_std, unit),
            ..self
        }
    }

    /// The same rig with a disparity error of `px` (refused unless finite and 0 or more).
    pub fn with_disparity_error(self, px: f64) -> Result<Rig, Fault> {
        if px.is_finite() && px >= 0.0 {
            Ok(Rig {
                camera: RectifiedCamera {
                    disparity_error_px: px,
                    ..self.camera
                },
                ..self
            })
        } else {
            Err(Fault {
                member: Member::DisparityErrorPx,
                message: format!("must be 0 or more, got {}", Num(px)),
            })
        }
    }

    /// The same rig for images of `width × height` (its principal point must lie on them).
    pub fn with_image_size(self, width: u32, height: u32) -> Result<Rig, Vec<Fault>> {
        let mut faults = Faults {
            found: Vec::new(),
            unreadable: &[],
        };
        let (w, h) = (f64::from(width), f64::from(height));
        let cx = principal(Member::Cx, self.cx, Some(w), &mut faults);
        let cy = principal(Member::Cy, self.cy, Some(h), &mut faults);
        match (cx, cy) {
            (Some(cx), Some(cy)) if width > 0 && height > 0 && faults.found.is_empty() => Ok(Rig {
                camera: RectifiedCamera {
                    image_width: Some(w),
                    image_height: Some(h),
                    ..self.camera
                },
                cx,
                cy,
                ..self
            }),
            _ => Err(faults.found),
        }
    }

    /// The checked camera.
    pub fn camera(&self) -> RectifiedCamera {
        self.camera
    }
    /// Horizontal focal length `fx`, the one every disparity is measured with.
    pub fn focal_px(&self) -> f64 {
        self.camera.focal_px
    }
    /// Vertical focal length `fy`, for the point's Y (equal to `fx` for square pixels).
    pub fn focal_y_px(&self) -> f64 {
        self.camera.focal_y_px
    }
    pub fn baseline(&self) -> f64 {
        self.baseline
    }
    pub fn unit(&self) -> LengthUnit {
        self.camera.unit
    }
    /// The image size, when known: only the normalised x, the fields of view, the default
    /// principal point and the default sample range need it.
    pub fn image_width(&self) -> Option<f64> {
        self.camera.image_width
    }
    pub fn image_height(&self) -> Option<f64> {
        self.camera.image_height
    }
    /// The left camera's principal point x, when known.
    pub fn cx(&self) -> Option<f64> {
        self.cx
    }
    /// The left camera's principal point y, when known.
    pub fn cy(&self) -> Option<f64> {
        self.cy
    }
    /// Principal-point offset between the cameras, added to every disparity.
    pub fn doffs(&self) -> f64 {
        self.doffs
    }
    /// Disparity uncertainty Δd in pixels, for the depth error.
    pub fn disparity_error_px(&self) -> f64 {
        self.camera.disparity_error_px
    }

    /// σ of the focal length in pixels, from a calibration (0 when not stated).
    pub fn focal_std_px(&self) -> f64 {
        self.focal_std_px
    }
    /// σ of the baseline in `unit`, from a calibration (0 when not stated).
    pub fn baseline_std(&self) -> f64 {
        self.baseline_std
    }

    /// The same rig with the calibration's standard deviations of the focal length (px) and
    /// the baseline (in `unit`); refused unless each is finite and 0 or more.
    pub fn with_calibration_std(
        self,
        focal_std_px: f64,
        baseline_std: f64,
    ) -> Result<Rig, Vec<Fault>> {
        let mut faults = Faults {
            found: Vec::new(),
            unreadable: &[],
        };
        let focal = faults.non_negative(Member::FocalLengthStdPx, focal_std_px);
        let baseline = faults.non_negative(Member::BaselineStd, baseline_std);
        match (focal, baseline) {
            (Some(focal_std_px), Some(baseline_std)) => Ok(Rig {
                focal_std_px,
                baseline_std,
                ..self
            }),
            _ => Err(faults.found),
        }
    }

    /// `f_px·B`, the constant that turns an effective disparity into a depth.
    pub fn fb(&self) -> f64 {
        self.focal_px() * self.baseline
    }

    /// The seed calculator's "projection factor", `f_px / B`, in pixels per unit of length.
    pub fn projection_factor(&self) -> f64 {
        self.focal_px() / self.baseline
    }

    /// Depth for a raw disparity `d`: `Z = B·f_px / |d + doffs|`.
    pub fn distance_at(&self, disparity_px: f64) -> Result<f64, PhysicsError> {
        let effective = disparity_px + self.doffs;
        if effective == 0.0 {
            return Err(PhysicsError::AtInfinity);
        }
        finite(self.fb() / effective.abs())
    }

    /// The raw disparity `d` (positive effective disparity) at which a point lies at `distance`.
    pub fn disparity_at(&self, distance: f64) -> f64 {
        self.fb() / distance - self.doffs
    }

    /// The depth error's terms at `distance`: the disparity's `Z²·Δd / (f_px·B)`, the focal
    /// length's `Z·σ_f / f` and the baseline's `Z·σ_B / B`.
    pub fn depth_error_terms_at(&self, distance: f64) -> DepthErrorTerms {
        self.depth_error_terms_with(distance, self.disparity_error_px())
    }

    /// The depth error's terms at `distance` for a disparity known to `disparity_std_px` (a
    /// depth map's σ_d at that pixel): `Z²·σ_d / (f_px·B)`, `Z·σ_f / f` and `Z·σ_B / B`.
    pub fn depth_error_terms_with(&self, distance: f64, disparity_std_px: f64) -> DepthErrorTerms {
        DepthErrorTerms {
            disparity: distance * distance * disparity_std_px / self.fb(),
            focal_length: distance * self.focal_std_px / self.focal_px(),
            baseline: distance * self.baseline_std / self.baseline,
        }
    }

    /// Depth error at `distance`: `ΔZ = Z²·Δd / (f_px·B)`, or with a calibration's σ_f and
    /// σ_B, `√((Z²·Δd/(f·B))² + (Z·σ_f/f)² + (Z·σ_B/B)²)`.
    pub fn depth_error_at(&self, distance: f64) -> f64 {
        self.depth_error_terms_at(distance).total()
    }

    /// Relative depth error `ΔZ / Z` at `distance`.
    pub fn relative_error_at(&self, distance: f64) -> f64 {
        self.depth_error_at(distance) / distance
    }

    /// The relative error the calibration alone leaves at any distance: `√((σ_f/f)² + (σ_B/B)²)`.
    pub fn calibration_relative_error(&self) -> f64 {
        (self.focal_std_px / self.focal_px()).hypot(self.baseline_std / self.baseline)
    }

    /// The distance at which the relative error reaches `max_relative_error`:
    /// `Z = r·f_px·B / Δd`, or with a calibration's σ, `Z = √(r² − c²)·f_px·B / Δd` where `c` is
    /// [`Rig::calibration_relative_error`]. Closer points are better than `r`, farther ones
    /// worse. `None` when `Δd` is zero (the error never grows), when the calibration alone
    /// already reaches `r` (no distance is that good), or when the distance overflows.
    pub fn distance_at_relative_error(&self, max_relative_error: f64) -> Option<f64> {
        let calibration = self.calibration_relative_error();
        let room = (max_relative_error - calibration) * (max_relative_error + calibration);
        let distance = room.max(0.0).sqrt() * self.fb() / self.disparity_error_px();
        (distance.is_finite() && distance > 0.0 && self.disparity_error_px() > 0.0)
            .then_some(distance)
    }

    /// The horizontal and vertical fields of view in degrees, for a principal point at the image
    /// centre; each is `None` when its image extent is unknown.
    pub fn fields_of_view_deg(&self) -> (Option<f64>, Option<f64>) {
        (
            self.image_width()
                .map(|w| field_of_view_deg(self.focal_px(), w)),
            self.image_height()
                .map(|h| field_of_view_deg(self.focal_y_px(), h)),
        )
    }

    /// The depth range a disparity search from `min_disparity_px` to `max_disparity_px` (raw
    /// disparities, `doffs` is added) can see: `(f·B / (max + doffs), f·B / (min + doffs))`.
    /// Callers guarantee `0 < min + doffs < max + doffs`.
    pub fn depth_range(
        &self,
        min_disparity_px: f64,
        max_disparity_px: f64,
    ) -> Result<(f64, f64), PhysicsError> {
        Ok((
            self.distance_at(max_disparity_px)?,
            self.distance_at(min_disparity_px)?,
        ))
    }

    /// The seed's normalised coordinate: `(x − W/2) / (W/2)`, −1 at the left edge, +1 at the
    /// right; `None` when the image width is unknown.
    pub fn normalized_x(&self, x_px: f64) -> Option<f64> {
        let half = self.image_width()? / 2.0;
        Some((x_px - half) / half)
    }

    /// The point in the left camera's frame at pixel `(x, y)` of the left image and depth `z`,
    /// by the pinhole model around the principal point; `None` when the principal point is
    /// unknown.
    pub fn point_at(&self, x_px: f64, y_px: f64, z: f64) -> Option<Result<Point3, PhysicsError>> {
        let (cx, cy) = (self.cx?, self.cy?);
        Some((|| {
            Ok(Point3 {
                x: finite((x_px - cx) * z / self.focal_px())?,
                y: finite((y_px - cy) * z / self.focal_y_px())?,
                z,
            })
        })())
    }
}

/// A principal-point coordinate: within `[0, extent]` when the extent is known, else at least
/// 0; by default the image centre, unknown when the extent is.
fn principal(
    member: Member,
    value: Option<f64>,
    extent: Option<f64>,
    faults: &mut Faults,
) -> Option<Option<f64>> {
    let extent_name = match member {
        Member::Cx => "image_width",
        _ => "image_height",
    };
    match (value, extent) {
        (Some(c), Some(extent)) => {
            if c.is_finite() && (0.0..=extent).contains(&c) {
                Some(Some(c))
            } else {
                faults.add(
                    member,
                    format!(
                        "must lie in [0, {}] ({extent_name}), got {}",
                        Num(extent),
                        Num(c)
                    ),
                );
                None
            }
        }
        (Some(c), None) => faults.non_negative(member, c).map(Some),
        (None, Some(extent)) => Some(Some(extent / 2.0)),
        (None, None) => Some(None),
    }
}

/// Refuses a focal length and baseline whose product or ratio leaves the range of an f64,
/// blaming both.
fn balanced(camera: &RectifiedCamera, baseline: f64, faults: &mut Faults) {
    let focal_px = camera.focal_px;
    if (focal_px * baseline).is_normal() && (focal_px / baseline).is_normal() {
        return;
    }
    for member in [camera.focal_member, Member::Baseline] {
        faults.add(
            member,
            format!(
                "focal length ({} px) and baseline ({}) are too far apart in magnitude: \
                 their product or ratio leaves the range of a 64-bit float",
                Num(focal_px),
                Num(baseline)
            ),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(faults: &[Fault]) -> Vec<&'static str> {
        faults.iter().map(|f| f.member.name()).collect()
    }

    /// A rig with no size and no principal point is still a rig: it relates disparity and
    /// depth, and places no point.
    #[test]
    fn depth_needs_no_principal_point() {
        let rig = Rig::new(&RigSpec::pixels(700.0, 120.0, LengthUnit::Millimetre)).unwrap();
        assert_eq!(rig.distance_at(20.0), Ok(4200.0));
        assert_eq!(rig.point_at(1.0, 1.0, 4200.0), None);
        assert_eq!((rig.cx(), rig.cy()), (None, None));
    }

    /// Every fault is named, once, in the order the members are read.
    #[test]
    fn faults_name_every_member() {
        let mut spec = RigSpec::pixels(-1.0, 0.0, LengthUnit::Metre);
        spec.camera.image_width = Some(0);
        spec.cx = Some(900.0);
        spec.camera.image_height = Some(600);
        spec.cy = Some(601.0);
        let faults = Rig::new(&spec).unwrap_err();
        assert_eq!(
            names(&faults),
            ["image_width", "focal_length_px", "baseline", "cy"]
        );
        assert!(faults[3].message.contains("[0, 600] (image_height)"));
    }

    /// A focal length and baseline whose product overflows blame both; the stated focal member
    /// is the one named.
    #[test]
    fn unbalanced_rig_blames_focal_and_baseline() {
        let faults = Rig::new(&RigSpec::pixels(1e300, 1e300, LengthUnit::Millimetre)).unwrap_err();
        assert_eq!(names(&faults), ["focal_length_px", "baseline"]);
        assert!(faults[0].message.contains("too far apart"));
    }

    /// A rig given a size places its principal point at the centre; one outside the new size is
    /// refused.
    #[test]
    fn image_size_checks_the_principal_point() {
        let rig = Rig::new(&RigSpec::pixels(700.0, 120.0, LengthUnit::Millimetre)).unwrap();
        let sized = rig.with_image_size(640, 480).unwrap();
        assert_eq!((sized.cx(), sized.cy()), (Some(320.0), Some(240.0)));
        let mut spec = RigSpec::pixels(700.0, 120.0, LengthUnit::Millimetre);
        spec.cx = Some(1000.0);
        let faults = Rig::new(&spec)
            .unwrap()
            .with_image_size(640, 480)
            .unwrap_err();
        assert_eq!(names(&faults), ["cx"]);
    }
}
