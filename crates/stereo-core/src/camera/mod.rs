//! The raw camera and the stereo pair as OpenCV models them: intrinsics, the distortion
//! models users have (`plumb_bob`, `rational_polynomial`, `equidistant`), projection and
//! undistortion, the pair's extrinsics (X_right = R·X_left + T) and Bouguet's rectification,
//! whose rectified rig is a [`crate::physics::Rig`]. Pure: no HTTP, no serde.
//!
//! - [`distortion`]: the models, their Jacobians and their inverses.
//! - [`pinhole`]: one camera, K and its distortion, pixels to rays and back.
//! - [`rectification`]: the pair, `alpha`, and a rectification (R1 R2 P1 P2 Q, ROIs) with
//!   its rig, computed or as a file gives it.
//! - [`rectify`]: `stereoRectify` (and fisheye's) computing it.
//! - [`maps`]: `initUndistortRectifyMap`: for each rectified pixel, the raw one it comes from.
//! - [`latlon`]: mrcal's latitude-longitude rectification, for lenses of any field.

pub mod distortion;
pub mod latlon;
pub mod maps;
pub mod pinhole;
pub mod rectification;
pub mod rectify;
pub mod synthetic;

pub use distortion::{Distorted, Distortion, DistortionFault, Model};
pub use latlon::{Latlon, LatlonFault, LatlonOptions, WIDE_FOV_DEG};
pub use maps::{Map, undistort_rectify_map};
pub use pinhole::{Camera, CameraFault, Intrinsics};
pub use rectification::{
    Alpha, AlphaOutOfRange, GivenFault, Rectification, RectifyFault, RectifyOptions, RigFault, Roi,
    Side, Size, StereoPair,
};
pub use rectify::stereo_rectify;

/// The pair `cv2.stereoRectify` was run on for the tests' reference values, and what the tests
/// of whatever takes a pair use (the calibration files' writers too):
/// K1 = [[812.5,0,331.2],[0,809,238.9],[0,0,1]], D1 = [-0.21,0.11,0.001,-0.0006,-0.03],
/// K2 = [[806,0,318.4],[0,804.5,243.7],[0,0,1]], D2 = [-0.19,0.08,-0.0008,0.0011,0.01],
/// R = Rodrigues([0.012,-0.021,0.006]), T = [-120,1.8,-2.4], size (640, 480). Public for the
/// integration tests, which check the service against the same reference.
pub fn opencv_pair() -> StereoPair {
    use nalgebra::{Rotation3, Vector3};
    let camera = |fx, fy, cx, cy, d: &[f64]| {
        Camera::new(
            Intrinsics { fx, fy, cx, cy },
            Distortion::new(Model::PlumbBob, d).unwrap(),
        )
        .unwrap()
    };
    StereoPair {
        left: camera(
            812.5,
            809.0,
            331.2,
            238.9,
            &[-0.21, 0.11, 0.001, -0.0006, -0.03],
        ),
        right: camera(
            806.0,
            804.5,
            318.4,
            243.7,
            &[-0.19, 0.08, -0.0008, 0.0011, 0.01],
        ),
        rotation: Rotation3::from_scaled_axis(Vector3::new(0.012, -0.021, 0.006)),
        translation: Vector3::new(-120.0, 1.8, -2.4),
    }
}

#[cfg(test)]
mod tests;
