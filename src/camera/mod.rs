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

pub mod distortion;
pub mod maps;
pub mod pinhole;
pub mod rectification;
pub mod rectify;

pub use distortion::{Distorted, Distortion, DistortionFault, Model};
pub use maps::{Map, undistort_rectify_map};
pub use pinhole::{Camera, CameraFault, Intrinsics};
pub use rectification::{
    Alpha, AlphaOutOfRange, GivenFault, Rectification, RectifyFault, RectifyOptions, RigFault, Roi,
    Side, Size, StereoPair,
};
pub use rectify::stereo_rectify;

#[cfg(test)]
mod tests;
