//! ChArUco boards rendered with exact truth through a known rig, for the tests, the
//! evaluation and the page's end-to-end tests: a board on its white sheet as a camera sees
//! it, and stereo poses of which some put part of the board out of the left frame.

use nalgebra::{Isometry3, Point3, Translation3};

use super::CharucoBoard;
use crate::calibration::boards::board::Board;
use crate::calibration::boards::synthetic::{Image, Rays, Style, poses, render_sheet};
use crate::camera::{Size, StereoPair};

/// Renders `board` at `pose` (board to camera) on a sheet with one square of white margin
/// around it, as the camera whose `rays` are given.
pub fn render(board: &CharucoBoard, pose: &Isometry3<f64>, rays: &Rays, style: &Style) -> Image {
    let s = board.square_size();
    let (sx, sy) = board.squares();
    let (w, h) = (f64::from(sx) * s, f64::from(sy) * s);
    render_sheet(pose, rays, style, |bx, by| {
        if bx < -s || by < -s || bx > w + s || by > h + s {
            return None;
        }
        Some(board.shade(bx, by) == Some(false))
    })
}

/// `count` poses (board to left camera) from which both cameras see the whole board, tilted
/// up to 40°, drawn from `seed`; every third is then moved sideways so that the board's middle
/// lands on the left image's column `edge_x`, which puts part of the board out of that frame
/// (the right camera, to the right of the left one, sees more of it). None for a board too
/// small for a chessboard of its inner corners (2 × 2).
pub fn partial_poses(
    pair: &StereoPair,
    size: Size,
    board: &CharucoBoard,
    count: usize,
    seed: u64,
    edge_x: f64,
) -> Option<Vec<Isometry3<f64>>> {
    let s = board.square_size();
    let (sx, sy) = board.squares();
    // A chessboard of the same inner corners, whose corner 0 is the ChArUco corner 0.
    let chess = Board::new(sx - 1, sy - 1, s, board.unit()).ok()?;
    let middle = Point3::new(f64::from(sx) * s / 2.0, f64::from(sy) * s / 2.0, 0.0);
    let k = pair.left.intrinsics();
    let poses = poses(pair, size, &chess, count, 40.0, seed);
    let moved = poses
        .iter()
        .enumerate()
        .map(|(i, pose)| {
            let mut pose = pose * Translation3::new(-s, -s, 0.0);
            if i % 3 == 2 {
                let centre = pose * middle;
                pose.translation.vector.x += (edge_x - k.cx) * centre.z / k.fx - centre.x;
            }
            pose
        })
        .collect();
    Some(moved)
}
