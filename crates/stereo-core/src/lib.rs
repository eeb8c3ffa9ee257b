//! The stereo engine, without the service: a stereo rig's physics, its cameras and their
//! rectification, calibration from files and from checkerboard or ChArUco views, and the
//! census/SGM matcher with a σ per pixel. Plain functions over plain types: no HTTP, no serde,
//! no async, which this crate's manifest makes the compiler's to enforce.
//!
//! Layout, each layer using only those above it (the service's `tests/layout.rs` holds the code
//! to it):
//! - [`numbers`]: every number written as text (messages, CSV), short and exact.
//! - [`grid`]: a pixel's neighbours on a row-major grid, for flood fills.
//! - [`noise`]: seeded random numbers and noise textures, for the renders with exact truth.
//! - [`physics`]: the triangulation model: the camera and the rectified rig, each built only
//!   through its checking constructor (`Rig::new`), focal conversions,
//!   `Z = B·f_px / |d + doffs|`, depth error, 3D point and range, sweeps for tables and charts.
//! - [`camera`]: the raw camera and the pair: intrinsics, the distortion models (`plumb_bob`,
//!   `rational_polynomial`, `equidistant`), projection and undistortion, `stereoRectify`
//!   (R1 R2 P1 P2 Q, `alpha`, ROIs), whose rectified rig is a `physics::Rig`, and
//!   `initUndistortRectifyMap`'s maps.
//! - [`calibration`], in two parts:
//!   - [`calibration::files`]: calibration files (Middlebury, KITTI, ROS, OpenCV) read into a
//!     checked rig (`files::read`) with the raw cameras they describe, and the OpenCV and ROS
//!     files written, each format's reader and writer in one file;
//!   - [`calibration::boards`]: a calibration from board views: the chessboard and the ChArUco
//!     board (`boards::charuco`), the board finder and the sub-pixel corner refinement, Zhang's
//!     first guess, the Levenberg–Marquardt refinements of each camera and of the pair with each
//!     parameter's deviation, the projection uncertainty (`boards::uncertainty`), the target a
//!     user aims for (`boards::target`), the report (coverage, tilt, warnings), and boards
//!     rendered with exact corners.
//! - [`vision`]: the matcher: its parameters checked by `vision::Params::new` (the one set of
//!   defaults, and the search range's arithmetic), census costs, SGM, refinement (coarse to fine
//!   through `vision::pyramid` for ranges over 64), each disparity's σ (`vision::sigma`),
//!   correspondences of points and regions, decoding and encoding (PNG, JPEG, PFM, NPY, NPZ,
//!   PLY), remapping raw frames through rectification maps (`vision::remap`), and the check that
//!   a pair sent as rectified has its rows in line (`vision::rows`).
//! - [`pipeline`]: the use cases over all of these, as plain functions: a calibration resolved
//!   once for a size, a rectify mode and `alpha` (`pipeline::calibrated`), raw frames
//!   rectified through maps built once (`pipeline::rectify`), and a depth map with its depths,
//!   σ_Z, points and files (`pipeline::depth`).
//!
//! Using the engine from a Rust program: add `stereo-core` (this folder) as a path or git
//! dependency; [`pipeline`] opens with a depth map from two images and a calibration file.

pub mod calibration;
pub mod camera;
pub mod grid;
pub mod noise;
pub mod numbers;
pub mod physics;
pub mod pipeline;
pub mod vision;
