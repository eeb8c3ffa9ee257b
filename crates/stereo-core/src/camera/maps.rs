//! Rectification maps as OpenCV's `initUndistortRectifyMap` (and `fisheye::` for the
//! equidistant model) makes them with `CV_32FC1`: for every pixel of the rectified image, the
//! raw pixel it comes from. They depend only on the camera, the rectifying rotation, the new
//! camera matrix and the size, so a caller computes them once per rig and reuses them.

use nalgebra::Matrix3;
use rayon::prelude::*;

use super::distortion::Model;
use super::pinhole::Camera;
use super::rectification::Size;

/// Where each rectified pixel is read from in the raw image, row-major `f32`, as OpenCV's
/// `map_x` and `map_y`.
#[derive(Debug, Clone, PartialEq)]
pub struct Map {
    pub size: Size,
    pub x: Vec<f32>,
    pub y: Vec<f32>,
}

impl Map {
    /// The bytes the map holds.
    pub fn bytes(&self) -> usize {
        (self.x.len() + self.y.len()) * std::mem::size_of::<f32>()
    }
}

/// The map of the rectified image of `size` seen by a camera turned by `rotation` (R1 or
/// R2) with the camera matrix `new_matrix` (the left 3 × 3 of P1 or P2), read from the raw
/// image of `camera`. A pixel whose ray points behind the raw camera maps to −∞ or +∞ (never
/// inside the image), as OpenCV's fisheye map does.
pub fn undistort_rectify_map(
    camera: &Camera,
    rotation: &Matrix3<f64>,
    new_matrix: &Matrix3<f64>,
    size: Size,
) -> Map {
    let (width, height) = (size.width as usize, size.height as usize);
    let inverse = (new_matrix * rotation)
        .try_inverse()
        .unwrap_or_else(Matrix3::zeros);
    let k = camera.intrinsics();
    let distortion = camera.distortion();
    let fisheye = distortion.model() == Model::Equidistant;
    let mut x = vec![0f32; width * height];
    let mut y = vec![0f32; width * height];
    x.par_chunks_mut(width.max(1))
        .zip(y.par_chunks_mut(width.max(1)))
        .enumerate()
        .for_each(|(row, (map_x, map_y))| {
            let i = row as f64;
            let mut ray = [
                i * inverse[(0, 1)] + inverse[(0, 2)],
                i * inverse[(1, 1)] + inverse[(1, 2)],
                i * inverse[(2, 1)] + inverse[(2, 2)],
            ];
            for (mx, my) in map_x.iter_mut().zip(map_y.iter_mut()) {
                let (u, v) = if fisheye && ray[2] <= 0.0 {
                    (
                        if ray[0] > 0.0 {
                            f64::NEG_INFINITY
                        } else {
                            f64::INFINITY
                        },
                        if ray[1] > 0.0 {
                            f64::NEG_INFINITY
                        } else {
                            f64::INFINITY
                        },
                    )
                } else {
                    let w = 1.0 / ray[2];
                    let [xd, yd] = distortion.apply(ray[0] * w, ray[1] * w);
                    (k.fx * xd + k.cx, k.fy * yd + k.cy)
                };
                *mx = u as f32;
                *my = v as f32;
                ray[0] += inverse[(0, 0)];
                ray[1] += inverse[(1, 0)];
                ray[2] += inverse[(2, 0)];
            }
        });
    Map { size, x, y }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::super::{Distortion, Intrinsics};
    use super::*;

    /// Each map entry is the raw pixel whose ray, turned by the rotation and projected by the
    /// new matrix, lands on that rectified pixel: projecting the map's rays back gives the
    /// rectified pixel within 1e-3 px for the three models.
    #[test]
    fn the_map_inverts_the_rectification() {
        let rotation =
            *nalgebra::Rotation3::from_scaled_axis(Vector3::new(0.01, -0.02, 0.005)).matrix();
        let new_matrix = Matrix3::new(700.0, 0.0, 330.0, 0.0, 700.0, 235.0, 0.0, 0.0, 1.0);
        let size = Size {
            width: 640,
            height: 480,
        };
        for (model, d) in [
            (Model::PlumbBob, vec![-0.2, 0.05, 0.001, -0.0005, 0.01]),
            (
                Model::RationalPolynomial,
                vec![0.5, -0.2, 0.0005, -0.0004, 0.01, 0.8, -0.1, 0.02],
            ),
            (Model::Equidistant, vec![-0.03, 0.006, -0.002, 0.0003]),
        ] {
            let camera = Camera::new(
                Intrinsics {
                    fx: 720.0,
                    fy: 718.0,
                    cx: 321.0,
                    cy: 239.0,
                },
                Distortion::new(model, &d).unwrap(),
            )
            .unwrap();
            let map = undistort_rectify_map(&camera, &rotation, &new_matrix, size);
            for (px, py) in [(0usize, 0usize), (320, 240), (639, 479), (100, 400)] {
                let i = py * 640 + px;
                let raw = [f64::from(map.x[i]), f64::from(map.y[i])];
                let back = camera.undistort_to(raw, &rotation, &new_matrix).unwrap();
                assert!(
                    (back[0] - px as f64).abs() < 1e-3 && (back[1] - py as f64).abs() < 1e-3,
                    "{model}: ({px}, {py}) maps to {raw:?}, which goes back to {back:?}"
                );
            }
        }
    }
}
