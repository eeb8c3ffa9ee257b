//! Calibration from checkerboard images: the board, the corner finder, Zhang's first guess,
//! the Levenberg–Marquardt refinements of each camera and of the pair, and each parameter's
//! standard deviation. Pure: no HTTP, no serde.
//!
//! - [`board`]: the printed target and its corners' positions on its plane.
//! - [`corners`]: finding the inner corners, to hundredths of a pixel.
//! - [`synthetic`]: boards rendered through the camera model with exact truth.

pub mod board;
pub mod corners;
pub mod synthetic;

pub use board::{Board, BoardFault, BoardMember};
