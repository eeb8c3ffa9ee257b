//! One raw camera: its intrinsics (fx, fy, cx, cy) and lens distortion, checked once when
//! built, projecting 3D points to pixels and pixels back to normalized rays.

use std::fmt;

use nalgebra::{Matrix3, Vector3};

use super::distortion::{Distortion, DistortionFault, Model};

/// The pinhole intrinsics in pixels, as OpenCV's camera matrix holds them (no skew).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

impl Intrinsics {
    /// The 3 × 3 camera matrix K.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.fx, 0.0, self.cx, //
            0.0, self.fy, self.cy, //
            0.0, 0.0, 1.0,
        )
    }
}

/// Why a camera cannot be built.
#[derive(Debug, Clone, PartialEq)]
pub enum CameraFault {
    /// fx or fy is not a positive finite number (named `"fx"` or `"fy"`).
    Focal(&'static str),
    /// cx or cy is not finite.
    PrincipalPoint(&'static str),
    Distortion(DistortionFault),
}

impl fmt::Display for CameraFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CameraFault::Focal(name) => write!(f, "{name} must be a positive finite number"),
            CameraFault::PrincipalPoint(name) => write!(f, "{name} must be a finite number"),
            CameraFault::Distortion(fault) => write!(f, "distortion: {fault}"),
        }
    }
}

/// A raw (unrectified) camera: intrinsics and distortion. Built by [`Camera::new`], so its
/// focal lengths are positive and every number finite.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    intrinsics: Intrinsics,
    distortion: Distortion,
}

impl Camera {
    pub fn new(intrinsics: Intrinsics, distortion: Distortion) -> Result<Camera, CameraFault> {
        for (name, f) in [("fx", intrinsics.fx), ("fy", intrinsics.fy)] {
            if !(f.is_finite() && f > 0.0) {
                return Err(CameraFault::Focal(name));
            }
        }
        for (name, c) in [("cx", intrinsics.cx), ("cy", intrinsics.cy)] {
            if !c.is_finite() {
                return Err(CameraFault::PrincipalPoint(name));
            }
        }
        Ok(Camera {
            intrinsics,
            distortion,
        })
    }

    pub fn intrinsics(&self) -> Intrinsics {
        self.intrinsics
    }

    pub fn distortion(&self) -> Distortion {
        self.distortion
    }

    /// The camera matrix K.
    pub fn matrix(&self) -> Matrix3<f64> {
        self.intrinsics.matrix()
    }

    /// The pixel of an ideal normalized point (X/Z, Y/Z): distortion, then K.
    pub fn pixel_of_normalized(&self, p: [f64; 2]) -> [f64; 2] {
        let [xd, yd] = self.distortion.distort(p);
        let k = self.intrinsics;
        [k.fx * xd + k.cx, k.fy * yd + k.cy]
    }

    /// The pixel where a point in the camera's frame is seen, or `None` behind the camera.
    pub fn project(&self, point: &Vector3<f64>) -> Option<[f64; 2]> {
        if point.z <= f64::EPSILON {
            return None;
        }
        Some(self.pixel_of_normalized([point.x / point.z, point.y / point.z]))
    }

    /// The pixel where a ray (a direction in the camera's frame, any length) is seen. A
    /// fisheye (`equidistant`) sees every ray but the one straight behind it, past 90° from
    /// its axis too (θ = atan2(r, z)); the other models only rays in front of the camera.
    pub fn pixel_of_ray(&self, ray: &Vector3<f64>) -> Option<[f64; 2]> {
        if self.distortion.model() != Model::Equidistant {
            return self.project(ray);
        }
        let r = ray.x.hypot(ray.y);
        let theta = r.atan2(ray.z);
        if !theta.is_finite() || theta >= std::f64::consts::PI - 1e-9 {
            return None;
        }
        let scale = if r == 0.0 {
            0.0
        } else {
            equidistant(self.distortion.coefficients(), theta) / r
        };
        let k = self.intrinsics;
        Some([k.fx * ray.x * scale + k.cx, k.fy * ray.y * scale + k.cy])
    }

    /// The unit ray seen at a pixel ([`Camera::pixel_of_ray`]'s inverse): for a fisheye,
    /// past 90° from its axis too. `None` where the distortion cannot be inverted: past the
    /// fold of a lens model whose distortion turns back (a rational or Brown model whose
    /// mapping stops rising, a fisheye whose θ_d(θ) does), where a pixel has two rays or none.
    pub fn ray_of_pixel(&self, pixel: [f64; 2]) -> Option<Vector3<f64>> {
        let k = self.intrinsics;
        let (x, y) = ((pixel[0] - k.cx) / k.fx, (pixel[1] - k.cy) / k.fy);
        if self.distortion.model() != Model::Equidistant {
            let [x, y] = self.normalize(pixel)?;
            let [[a, b], [c, d]] = self.distortion.distort_with_derivatives([x, y]).by_point;
            if a * d - b * c <= 0.0 {
                return None;
            }
            return Some(Vector3::new(x, y, 1.0).normalize());
        }
        let theta_d = x.hypot(y);
        if theta_d < 1e-15 {
            return Some(Vector3::z());
        }
        let c = self.distortion.coefficients();
        // Newton on θ_d(θ) = θ(1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸), from θ = θ_d.
        let mut theta = theta_d;
        for _ in 0..50 {
            let (value, slope) = (equidistant(c, theta), equidistant_slope(c, theta));
            if slope <= 0.0 || !slope.is_finite() {
                return None;
            }
            let step = (value - theta_d) / slope;
            theta -= step;
            if step.abs() < 1e-14 {
                break;
            }
        }
        let converged = (equidistant(c, theta) - theta_d).abs() < 1e-9
            && theta > 0.0
            && theta < std::f64::consts::PI
            && equidistant_slope(c, theta) > 0.0;
        if !converged {
            return None;
        }
        let (sin, cos) = theta.sin_cos();
        Some(Vector3::new(sin * x / theta_d, sin * y / theta_d, cos))
    }

    /// The ideal normalized point (X/Z, Y/Z) seen at a pixel, or `None` where the distortion
    /// cannot be inverted.
    pub fn normalize(&self, pixel: [f64; 2]) -> Option<[f64; 2]> {
        let k = self.intrinsics;
        self.distortion
            .undistort([(pixel[0] - k.cx) / k.fx, (pixel[1] - k.cy) / k.fy])
    }

    /// The normalized point OpenCV's `undistortPoints` gives for a pixel with its default
    /// criteria ([`Distortion::undistort_as_opencv`]).
    pub fn normalize_as_opencv(&self, pixel: [f64; 2]) -> Option<[f64; 2]> {
        let k = self.intrinsics;
        self.distortion
            .undistort_as_opencv([(pixel[0] - k.cx) / k.fx, (pixel[1] - k.cy) / k.fy])
    }

    /// OpenCV's `undistortPoints` with `R` and `P`: the pixel in a new (rectified) camera
    /// whose rotation from this one is `rotation` and whose matrix is `new_matrix`.
    pub fn undistort_to(
        &self,
        pixel: [f64; 2],
        rotation: &Matrix3<f64>,
        new_matrix: &Matrix3<f64>,
    ) -> Option<[f64; 2]> {
        let [x, y] = self.normalize(pixel)?;
        let ray = rotation * Vector3::new(x, y, 1.0);
        if ray.z <= f64::EPSILON {
            return None;
        }
        let p = new_matrix * (ray / ray.z);
        Some([p.x, p.y])
    }
}

/// The fisheye's θ_d for an angle θ from the axis: θ(1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸).
fn equidistant(c: &[f64], theta: f64) -> f64 {
    let t2 = theta * theta;
    theta * (1.0 + t2 * (c[0] + t2 * (c[1] + t2 * (c[2] + t2 * c[3]))))
}

/// dθ_d/dθ.
fn equidistant_slope(c: &[f64], theta: f64) -> f64 {
    let t2 = theta * theta;
    1.0 + t2 * (3.0 * c[0] + t2 * (5.0 * c[1] + t2 * (7.0 * c[2] + t2 * 9.0 * c[3])))
}

#[cfg(test)]
mod tests {
    use super::super::distortion::Model;
    use super::*;

    /// A pixel projected from a 3D point normalizes back to that point's ray.
    #[test]
    fn project_then_normalize_is_the_ray() {
        let camera = Camera::new(
            Intrinsics {
                fx: 812.5,
                fy: 809.0,
                cx: 331.2,
                cy: 238.9,
            },
            Distortion::new(Model::PlumbBob, &[-0.21, 0.11, 0.001, -0.0006, -0.03]).unwrap(),
        )
        .unwrap();
        let point = Vector3::new(0.21, -0.13, 1.4);
        let pixel = camera.project(&point).unwrap();
        let ray = camera.normalize(pixel).unwrap();
        assert!((ray[0] - 0.15).abs() < 1e-12 && (ray[1] + 0.13 / 1.4).abs() < 1e-12);
        assert_eq!(camera.project(&Vector3::new(0.0, 0.0, -1.0)), None);
    }

    /// A camera refuses a focal length that is not positive and a principal point that is
    /// not finite, naming which.
    #[test]
    fn checks_its_members() {
        let none = Distortion::none(Model::PlumbBob);
        let k = |fx, cy| Intrinsics {
            fx,
            fy: 500.0,
            cx: 320.0,
            cy,
        };
        assert_eq!(
            Camera::new(k(0.0, 240.0), none),
            Err(CameraFault::Focal("fx"))
        );
        assert_eq!(
            Camera::new(k(500.0, f64::INFINITY), none),
            Err(CameraFault::PrincipalPoint("cy"))
        );
    }
}
