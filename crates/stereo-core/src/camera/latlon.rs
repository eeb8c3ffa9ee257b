//! Latitude-longitude rectification, as mrcal's `rectified_system` (`LENSMODEL_LATLON`),
//! `rectification_maps` and `stereo_range` make it: the rectified frame has x along the
//! baseline, z the cameras' mean view direction made normal to it; a rectified pixel is an
//! azimuth (the angle out of the y–z plane, along the baseline) and an elevation (the angle
//! of the epipolar plane about the baseline), each evenly spaced. Epipolar planes are rows at
//! every angle, so a pair rectifies over any field a lens sees (up to 180° across the
//! baseline), where a pinhole plane stretches the edges and cannot hold 90° off its axis.
//!
//! A disparity is an angle, d / f_x: the range along the left ray follows from the two
//! azimuths and the baseline by the law of sines, r = B·cos(az_left − d/f)/sin(d/f).

use std::fmt;

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::maps::Map;
use super::pinhole::Camera;
use super::rectification::{Size, StereoPair};

/// The most pixels a rectified image may hold, as a multiple of the raw image's.
pub const MAX_AREA_RATIO: f64 = 4.0;

/// The widest field a latitude-longitude image holds along either axis, in degrees.
pub const MAX_FOV_DEG: f64 = 180.0;

/// The field (degrees, across the baseline or about it, whichever is wider) past which
/// `projection=auto` rectifies to latitude-longitude: a pinhole plane stretches its edge by
/// 1/cos²(fov/2) against its centre, 2.4 × at 100°, 4 × at 120°, without bound towards 180°.
pub const WIDE_FOV_DEG: f64 = 100.0;

/// What a caller may set; each `None` is chosen from the calibration.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LatlonOptions {
    /// Only where the cameras see wider than [`WIDE_FOV_DEG`] (`projection=auto`); narrower
    /// rigs stay on the pinhole plane.
    pub when_wide: bool,
    /// The azimuth field (across the baseline), in degrees.
    pub az_fov_deg: Option<f64>,
    /// The elevation field, in degrees.
    pub el_fov_deg: Option<f64>,
    /// The resolution along both axes, in pixels per degree.
    pub pixels_per_degree: Option<f64>,
}

impl LatlonOptions {
    /// These options where the request needs the pinhole plane (`alpha` given, an output that
    /// holds only pinhole images, a pair matched as sent): `projection=auto` gives way to it,
    /// as a choice; an explicit `latlon` stays, to be refused by what needs the plane.
    pub fn unless_pinhole(self, pinhole: bool) -> Option<LatlonOptions> {
        (!(self.when_wide && pinhole)).then_some(self)
    }

    /// Whether the field and resolution are all left to the calibration.
    pub fn chosen(&self) -> bool {
        self.az_fov_deg.is_none() && self.el_fov_deg.is_none() && self.pixels_per_degree.is_none()
    }
}

/// Why a pair cannot be rectified to latitude-longitude.
#[derive(Debug, Clone, PartialEq)]
pub enum LatlonFault {
    /// The cameras are at the same place.
    NoBaseline,
    /// The raw image has no pixels.
    Size,
    /// A field or resolution that is not a positive finite number, or a field past 180°.
    Option(&'static str, f64),
    /// The two cameras' fields do not overlap.
    NoOverlap,
    /// The rectified image would be too large (its size).
    TooLarge(u32, u32),
    /// The field at the resolution asked for holds less than a pixel across.
    TooSmall,
}

impl fmt::Display for LatlonFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use crate::numbers::Num;
        match self {
            LatlonFault::NoBaseline => {
                f.write_str("the translation between the cameras must be finite and not zero")
            }
            LatlonFault::Size => f.write_str("the image size must not be zero"),
            LatlonFault::Option(name, v) if name.ends_with("fov") => write!(
                f,
                "{name} must be a number of degrees over 0 and at most {}, got {}",
                Num(MAX_FOV_DEG),
                Num(*v)
            ),
            LatlonFault::Option(name, v) => {
                write!(f, "{name} must be a positive number, got {}", Num(*v))
            }
            LatlonFault::NoOverlap => {
                f.write_str("the two cameras' fields of view do not overlap in the rectified frame")
            }
            LatlonFault::TooLarge(w, h) => write!(
                f,
                "the rectified image would be {w} × {h} pixels, over {} times the raw image: \
                 give a smaller pixels_per_degree or field of view",
                Num(MAX_AREA_RATIO)
            ),
            LatlonFault::TooSmall => f.write_str(
                "the rectified image would hold no pixel at this resolution and field: give a \
                 larger pixels_per_degree or field of view",
            ),
        }
    }
}

/// A latitude-longitude rectified pair: both cameras' rotations into it, its projection
/// and size, and the baseline. Both rectified cameras share the orientation and the
/// projection; the right one sits `baseline` along +x.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Latlon {
    /// Rotation from the left raw camera's frame to the rectified one (mrcal's
    /// `R_rect0_cam0`), and the right's (`R_rect1_cam1`).
    pub r1: Matrix3<f64>,
    pub r2: Matrix3<f64>,
    /// Pixels per radian of azimuth and of elevation.
    pub fx: f64,
    pub fy: f64,
    /// The pixel of azimuth 0 and elevation 0.
    pub cx: f64,
    pub cy: f64,
    pub size: Size,
    /// The distance between the cameras, in the unit of the pair's T.
    pub baseline: f64,
    /// The centre of the field and its extent, in degrees.
    pub az0_deg: f64,
    pub el0_deg: f64,
    pub az_fov_deg: f64,
    pub el_fov_deg: f64,
}

/// The unit ray of azimuth `az` and elevation `el` (radians) in the rectified frame
/// (mrcal's `unproject_latlon`).
pub fn ray_of(az: f64, el: f64) -> Vector3<f64> {
    let (sa, ca) = az.sin_cos();
    let (se, ce) = el.sin_cos();
    Vector3::new(sa, ca * se, ca * ce)
}

/// The azimuth and elevation (radians) of a ray in the rectified frame (mrcal's
/// `project_latlon` before its scale and offset).
pub fn angles_of(ray: &Vector3<f64>) -> [f64; 2] {
    [ray.x.atan2(ray.y.hypot(ray.z)), ray.y.atan2(ray.z)]
}

impl Latlon {
    /// The rectified system of `pair` (raw images of `raw_size`), as mrcal's
    /// `rectified_system` builds it for `LENSMODEL_LATLON`, with each field and the
    /// resolution chosen from the calibration where `options` leave them out:
    /// - the field: the range of azimuth and of elevation over which both cameras see
    ///   (each camera's over its image's border, the overlap of the two), centred on it;
    /// - the resolution: the left camera's at the field's centre (mrcal's default, −1).
    pub fn new(
        pair: &StereoPair,
        raw_size: Size,
        options: LatlonOptions,
    ) -> Result<Latlon, LatlonFault> {
        if raw_size.width == 0 || raw_size.height == 0 {
            return Err(LatlonFault::Size);
        }
        for (name, v) in [
            ("az_fov", options.az_fov_deg),
            ("el_fov", options.el_fov_deg),
            ("pixels_per_degree", options.pixels_per_degree),
        ] {
            let too_wide = name.ends_with("fov") && v.is_some_and(|v| v > MAX_FOV_DEG);
            if let Some(v) = v
                && (!(v.is_finite() && v > 0.0) || too_wide)
            {
                return Err(LatlonFault::Option(name, v));
            }
        }
        // mrcal's geometry: Rt01 takes the right camera's points to the left's, so
        // R01 = Rᵀ and t01 = −Rᵀ·T (the right camera's centre, seen from the left).
        let r01 = pair.rotation.matrix().transpose();
        let t01 = -(r01 * pair.translation);
        let baseline = t01.norm();
        if !(baseline.is_finite() && baseline > 0.0) {
            return Err(LatlonFault::NoBaseline);
        }
        let right = t01 / baseline;
        let forward01 = Vector3::z() + r01.column(2);
        let along = forward01.dot(&right);
        let forward = (forward01 - along * right).normalize();
        let down = forward.cross(&right);
        let r1 = Matrix3::from_rows(&[right.transpose(), down.transpose(), forward.transpose()]);
        let r2 = r1 * r01;

        let (az0, el0, az_fov, el_fov) = match (options.az_fov_deg, options.el_fov_deg) {
            (Some(a), Some(e)) => ((along / forward01.norm()).asin(), 0.0, a, e),
            _ => {
                let [az, el] = overlap(pair, raw_size, [&r1, &r2]).ok_or(LatlonFault::NoOverlap)?;
                let centre = |r: [f64; 2]| (r[0] + r[1]) / 2.0;
                let width = |r: [f64; 2]| (r[1] - r[0]).to_degrees();
                (
                    centre(az),
                    centre(el),
                    options.az_fov_deg.unwrap_or(width(az)),
                    options.el_fov_deg.unwrap_or(width(el)),
                )
            }
        };
        let [ppd_az, ppd_el] = match options.pixels_per_degree {
            Some(p) => [p, p],
            None => resolution(&pair.left, &r1, az0, el0).ok_or(LatlonFault::NoOverlap)?,
        };
        let (fx, fy) = (ppd_az.to_degrees(), ppd_el.to_degrees());
        let naz = (az_fov * ppd_az).round();
        let nel = (el_fov * ppd_el).round();
        let raw_area = f64::from(raw_size.width) * f64::from(raw_size.height);
        if !(naz >= 1.0 && nel >= 1.0) {
            return Err(LatlonFault::TooSmall);
        }
        if naz * nel > MAX_AREA_RATIO * raw_area {
            return Err(LatlonFault::TooLarge(
                naz.clamp(0.0, f64::from(u32::MAX)) as u32,
                nel.clamp(0.0, f64::from(u32::MAX)) as u32,
            ));
        }
        Ok(Latlon {
            r1,
            r2,
            fx,
            fy,
            cx: (naz - 1.0) / 2.0 - fx * az0,
            cy: (nel - 1.0) / 2.0 - fy * el0,
            size: Size {
                width: naz as u32,
                height: nel as u32,
            },
            baseline,
            az0_deg: az0.to_degrees(),
            el0_deg: el0.to_degrees(),
            az_fov_deg: az_fov,
            el_fov_deg: el_fov,
        })
    }

    /// The unit ray of a rectified pixel, in the rectified frame.
    pub fn ray(&self, [x, y]: [f64; 2]) -> Vector3<f64> {
        ray_of((x - self.cx) / self.fx, (y - self.cy) / self.fy)
    }

    /// The rectified pixel of a ray in the rectified frame.
    pub fn pixel(&self, ray: &Vector3<f64>) -> [f64; 2] {
        let [az, el] = angles_of(ray);
        [self.fx * az + self.cx, self.fy * el + self.cy]
    }

    /// mrcal's `stereo_range`: the range from the left camera of the point seen in left
    /// column `x` with disparity `d` (pixels, x_left − x_right), in the baseline's unit;
    /// `None` for a disparity that is not positive.
    pub fn range(&self, x: f64, d: f64) -> Option<f64> {
        if !(d > 0.0 && d.is_finite()) {
            return None;
        }
        let az = (x - self.cx) / self.fx;
        let angle = d / self.fx;
        let r = self.baseline * (az - angle).cos() / angle.sin();
        (r.is_finite() && r > 0.0).then_some(r)
    }

    /// The float maps of both cameras (mrcal's `rectification_maps`): for each rectified
    /// pixel, the raw pixel its ray is seen at; ±∞ where the raw camera cannot see it.
    pub fn maps(&self, pair: &StereoPair) -> (Map, Map) {
        rayon::join(
            || self.map(&pair.left, &self.r1),
            || self.map(&pair.right, &self.r2),
        )
    }

    fn map(&self, camera: &Camera, rect_from_cam: &Matrix3<f64>) -> Map {
        let (w, h) = (self.size.width as usize, self.size.height as usize);
        let cam_from_rect = rect_from_cam.transpose();
        let mut x = vec![0f32; w * h];
        let mut y = vec![0f32; w * h];
        x.par_chunks_mut(w.max(1))
            .zip(y.par_chunks_mut(w.max(1)))
            .enumerate()
            .for_each(|(row, (mx, my))| {
                for (col, (u, v)) in mx.iter_mut().zip(my.iter_mut()).enumerate() {
                    let ray = cam_from_rect * self.ray([col as f64, row as f64]);
                    let [px, py] = camera
                        .pixel_of_ray(&ray)
                        .filter(|p| p[0].is_finite() && p[1].is_finite())
                        .unwrap_or([f64::NEG_INFINITY; 2]);
                    *u = px as f32;
                    *v = py as f32;
                }
            });
        Map {
            size: self.size,
            x,
            y,
        }
    }
}

/// Where both cameras see, in the rectified frame: the azimuths and elevations of the rays
/// along each raw image's border (what a camera sees is bounded by its border: an angle's
/// extreme over the image lies on it), each camera's range of both, and the overlap of the
/// two cameras' (radians, within ±90°). Every direction both cameras see is inside it.
fn overlap(pair: &StereoPair, size: Size, rotations: [&Matrix3<f64>; 2]) -> Option<[[f64; 2]; 2]> {
    const SAMPLES: u32 = 256;
    let limit = (MAX_FOV_DEG / 2.0).to_radians();
    let mut az = [-limit, limit];
    let mut el = [-limit, limit];
    let (w, h) = (f64::from(size.width - 1), f64::from(size.height - 1));
    let along = |t: u32| f64::from(t) / f64::from(SAMPLES);
    let border = (0..=SAMPLES).flat_map(|t| {
        let (x, y) = (along(t) * w, along(t) * h);
        [[x, 0.0], [x, h], [0.0, y], [w, y]]
    });
    for (camera, rotation) in [(&pair.left, rotations[0]), (&pair.right, rotations[1])] {
        let (mut seen, mut a, mut e) = (
            0,
            [f64::INFINITY, f64::NEG_INFINITY],
            [f64::INFINITY, f64::NEG_INFINITY],
        );
        for pixel in border.clone() {
            let Some(ray) = camera.ray_of_pixel(pixel) else {
                continue;
            };
            let [ray_az, ray_el] = angles_of(&(rotation * ray));
            seen += 1;
            a = [a[0].min(ray_az), a[1].max(ray_az)];
            e = [e[0].min(ray_el), e[1].max(ray_el)];
        }
        if seen < 2 {
            return None;
        }
        az = [az[0].max(a[0]), az[1].min(a[1])];
        el = [el[0].max(e[0]), el[1].min(e[1])];
    }
    (az[1] > az[0] && el[1] > el[0]).then_some([az, el])
}

/// The left camera's pixels per degree of azimuth and of elevation at the field's centre
/// (mrcal's default resolution): |dq/daz| and |dq/del| there.
fn resolution(camera: &Camera, r1: &Matrix3<f64>, az0: f64, el0: f64) -> Option<[f64; 2]> {
    const H: f64 = 1e-6;
    let back = r1.transpose();
    let pixel = |az: f64, el: f64| camera.pixel_of_ray(&(back * ray_of(az, el)));
    let rate =
        |a: [f64; 2], b: [f64; 2]| ((b[0] - a[0]).hypot(b[1] - a[1]) / (2.0 * H)).to_radians();
    let along_az = rate(pixel(az0 - H, el0)?, pixel(az0 + H, el0)?);
    let along_el = rate(pixel(az0, el0 - H)?, pixel(az0, el0 + H)?);
    (along_az > 0.0 && along_el > 0.0 && along_az.is_finite() && along_el.is_finite())
        .then_some([along_az, along_el])
}

#[cfg(test)]
mod tests {
    use nalgebra::Rotation3;

    use super::super::{Distortion, Intrinsics, Model};
    use super::*;

    /// A rig of two 180° fisheyes (equidistant, f = 407 px over 1280 × 1280: θ = 90° at
    /// 640 px), 120 mm apart, the right one turned a little.
    fn fisheye_rig() -> (StereoPair, Size) {
        let camera = |fx: f64, d: &[f64]| {
            Camera::new(
                Intrinsics {
                    fx,
                    fy: fx * 1.001,
                    cx: 639.5,
                    cy: 641.0,
                },
                Distortion::new(Model::Equidistant, d).unwrap(),
            )
            .unwrap()
        };
        let pair = StereoPair {
            left: camera(407.4, &[0.01, -0.002, 0.0005, -0.0001]),
            right: camera(405.0, &[0.008, -0.001, 0.0002, 0.0]),
            rotation: Rotation3::from_scaled_axis(Vector3::new(0.01, -0.03, 0.008)),
            translation: Vector3::new(-120.0, 1.5, -2.0),
        };
        let size = Size {
            width: 1280,
            height: 1280,
        };
        (pair, size)
    }

    /// A fisheye's pixel and ray invert each other up to 89° and past 90° from its axis.
    #[test]
    fn a_fisheye_sees_past_ninety_degrees() {
        let (pair, _) = fisheye_rig();
        for deg in [0.0f64, 30.0, 60.0, 89.0, 95.0, 110.0] {
            let t = deg.to_radians();
            let ray = Vector3::new(t.sin() * 0.6, t.sin() * 0.8, t.cos());
            let pixel = pair.left.pixel_of_ray(&ray).unwrap();
            let back = pair.left.ray_of_pixel(pixel).unwrap();
            assert!(
                (back - ray).norm() < 1e-9,
                "{deg}°: {back:?} against {ray:?}"
            );
        }
    }

    /// A point seen by both cameras lands on the same rectified row in both (epipolar lines
    /// are rows), at every angle of a 180° field; its range from the disparity is the
    /// distance from the left camera, within 1e-6 of it.
    #[test]
    fn rows_agree_and_range_is_exact_over_the_field() {
        let (pair, size) = fisheye_rig();
        let system = Latlon::new(&pair, size, LatlonOptions::default()).unwrap();
        assert!(system.az_fov_deg > 170.0, "{system:?}");
        let mut seen = 0;
        for az in (-80..=80).step_by(10) {
            for el in (-70..=70).step_by(20) {
                for distance in [0.5, 3.0, 40.0] {
                    // A point at this direction from the left camera, in metres as mm.
                    let ray = ray_of(f64::from(az).to_radians(), f64::from(el).to_radians());
                    let p_rect = ray * distance * 1000.0;
                    let p_left = system.r1.transpose() * p_rect;
                    let p_right = pair.rotation * p_left + pair.translation;
                    let (Some(l), Some(r)) = (
                        pair.left.pixel_of_ray(&p_left),
                        pair.right.pixel_of_ray(&p_right),
                    ) else {
                        continue;
                    };
                    let rl = system.pixel(&(system.r1 * pair.left.ray_of_pixel(l).unwrap()));
                    let rr = system.pixel(&(system.r2 * pair.right.ray_of_pixel(r).unwrap()));
                    assert!(
                        (rl[1] - rr[1]).abs() < 1e-6,
                        "az {az} el {el}: rows {rl:?} {rr:?}"
                    );
                    let range = system.range(rl[0], rl[0] - rr[0]).unwrap();
                    assert!(
                        (range - p_left.norm()).abs() < 1e-6 * p_left.norm(),
                        "az {az} el {el} at {distance} m: {range} against {}",
                        p_left.norm()
                    );
                    seen += 1;
                }
            }
        }
        assert!(seen > 300, "{seen}");
    }

    /// Each map entry is the raw pixel whose ray lands on that rectified pixel, for both
    /// cameras; the centre of the field has the left camera's resolution there.
    #[test]
    fn the_maps_invert_the_rectification() {
        let (pair, size) = fisheye_rig();
        let system = Latlon::new(&pair, size, LatlonOptions::default()).unwrap();
        let (left, right) = system.maps(&pair);
        let (w, h) = (system.size.width as usize, system.size.height as usize);
        for (map, camera, rotation) in [
            (&left, &pair.left, &system.r1),
            (&right, &pair.right, &system.r2),
        ] {
            for (px, py) in [(w / 2, h / 2), (w / 10, h / 3), (w - w / 8, h - h / 6)] {
                let i = py * w + px;
                let raw = [f64::from(map.x[i]), f64::from(map.y[i])];
                let back = system.pixel(&(rotation * camera.ray_of_pixel(raw).unwrap()));
                assert!(
                    (back[0] - px as f64).abs() < 1e-3 && (back[1] - py as f64).abs() < 1e-3,
                    "({px}, {py}) maps to {raw:?}, which goes back to {back:?}"
                );
            }
        }
        // f = 407.4 px per radian at the centre of an equidistant lens: 7.11 px per degree.
        assert!(
            (system.fx.to_radians() - 407.4f64.to_radians()).abs() < 0.05,
            "{system:?}"
        );
    }

    /// Options out of range are refused by name; a field too fine for the raw image is
    /// refused with the size it would have had.
    #[test]
    fn bad_options_are_named() {
        let (pair, size) = fisheye_rig();
        let with = |a, e, p| LatlonOptions {
            when_wide: false,
            az_fov_deg: a,
            el_fov_deg: e,
            pixels_per_degree: p,
        };
        let fault = Latlon::new(&pair, size, with(Some(200.0), None, None)).unwrap_err();
        assert_eq!(fault, LatlonFault::Option("az_fov", 200.0));
        assert!(fault.to_string().contains("at most 180"), "{fault}");
        let fault = Latlon::new(&pair, size, with(None, None, Some(-1.0))).unwrap_err();
        assert_eq!(fault, LatlonFault::Option("pixels_per_degree", -1.0));
        let fault = Latlon::new(&pair, size, with(Some(180.0), Some(180.0), Some(100.0)));
        assert_eq!(fault, Err(LatlonFault::TooLarge(18000, 18000)));
        let fault = Latlon::new(&pair, size, with(None, None, Some(1e-6)));
        assert_eq!(fault, Err(LatlonFault::TooSmall));
        let mut same = pair;
        same.translation = Vector3::zeros();
        assert_eq!(
            Latlon::new(&same, size, LatlonOptions::default()),
            Err(LatlonFault::NoBaseline)
        );
    }
}
