//! Rigs with known lenses for the tests and the evaluations: what a render is seen through when
//! the truth must be exact.

use nalgebra::{Rotation3, Vector3};

use super::{Camera, Distortion, Intrinsics, Model, Size, StereoPair};

/// The raw size of [`fisheye_180`]'s cameras.
pub const FISHEYE_180_SIZE: Size = Size {
    width: 320,
    height: 240,
};

/// Two equidistant fisheyes that see 180° across their 320 × 240 px (θ = 90° at 160 px from
/// the centre: f = 320/π), a little distorted, 60 mm apart, the right one turned by about
/// 1.5°: a rig whose pinhole rectification no plane holds.
pub fn fisheye_180() -> StereoPair {
    let camera = |fx: f64, cx: f64, cy: f64, d: &[f64]| {
        let intrinsics = Intrinsics {
            fx,
            fy: fx * 1.001,
            cx,
            cy,
        };
        let distortion = Distortion::new(Model::Equidistant, d).expect("four fisheye terms");
        Camera::new(intrinsics, distortion).expect("a valid camera")
    };
    let f = f64::from(FISHEYE_180_SIZE.width) / std::f64::consts::PI;
    StereoPair {
        left: camera(f, 159.5, 120.5, &[0.01, -0.002, 0.0005, -0.0001]),
        right: camera(f * 1.003, 160.8, 119.4, &[0.008, -0.001, 0.0002, 0.0]),
        rotation: Rotation3::from_scaled_axis(Vector3::new(0.012, -0.021, 0.009)),
        translation: Vector3::new(-60.0, 0.8, -0.9),
    }
}
