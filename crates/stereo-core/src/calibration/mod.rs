//! Calibrations, in two parts: [`files`], the calibration files people already have
//! (Middlebury, KITTI, ROS, OpenCV) read into a checked rig, and written again as OpenCV and
//! ROS files; and [`boards`], a calibration made from checkerboard views (the board finder,
//! Zhang's first guess, the Levenberg–Marquardt refinements with each parameter's σ, and the
//! report a user checks it by). Pure: no HTTP, no serde.

pub mod boards;
pub mod files;
