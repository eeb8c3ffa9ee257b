//! A ChArUco board's inner corners in an image, from its markers: each corner beside a marker
//! that was read is predicted through the homography of the markers around it (OpenCV's
//! local homography interpolation), then found and refined as a chessboard corner and kept
//! only when it is one (the same check the chessboard finder applies to a predicted corner).
//! A view that shows part of the board gives the corners it shows, with their ids.

use super::CharucoBoard;
use super::markers::{Marker, find_markers};
use crate::calibration::boards::corners::{Luma, verify};
use crate::calibration::boards::zhang::homography;

/// The corners found in one image: OpenCV's ids (row by row over the inner corners) in
/// increasing order, with their image positions, and how many markers were read.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CharucoCorners {
    pub ids: Vec<usize>,
    pub points: Vec<[f64; 2]>,
    /// How many of the board's markers were read.
    pub markers: usize,
    /// The ids of the dictionary's markers read that the board does not have (beyond its
    /// last marker), in increasing order.
    pub foreign: Vec<usize>,
}

/// The fewest corners a view of a ChArUco board counts with, and they must not all lie on
/// one of the board's rows or columns: a pose needs four points off a line, and six leave a
/// margin for one that is poorly placed. (OpenCV's `calibrateCameraCharuco` takes a view
/// from 4 corners; a view of fewer than 6 adds little but its pose's six unknowns.)
pub const MIN_VIEW_CORNERS: usize = 6;

impl CharucoCorners {
    /// Whether the view counts: at least [`MIN_VIEW_CORNERS`], over two rows and two columns
    /// of the board (`columns` inner corners a row).
    pub fn usable(&self, columns: usize) -> bool {
        let spans = |key: &dyn Fn(usize) -> usize| {
            let first = self.ids.first().map(|&id| key(id));
            self.ids.iter().any(|&id| Some(key(id)) != first)
        };
        self.ids.len() >= MIN_VIEW_CORNERS && spans(&|id| id % columns) && spans(&|id| id / columns)
    }

    /// The corners in the board's order, `None` for those not found (`count` inner corners).
    pub fn seen(&self, count: usize) -> Vec<Option<[f64; 2]>> {
        let mut seen = vec![None; count];
        for (&id, &p) in self.ids.iter().zip(&self.points) {
            if let Some(slot) = seen.get_mut(id) {
                *slot = Some(p);
            }
        }
        seen
    }
}

/// How far (in squares, from the corner) a marker helps predict a corner: the markers of the
/// 4 × 4 squares around it, so that a lens's bending is followed.
const REACH: f64 = 2.0;

/// A marker read, with its square and its corners on the board's plane.
type Placed<'a> = (&'a Marker, (u32, u32), [[f64; 2]; 4]);

/// Every inner corner of `board` that `image` shows beside a marker that was read.
pub fn find_charuco(image: &Luma, board: &CharucoBoard) -> CharucoCorners {
    let squares = board.marker_squares();
    // The whole dictionary is read, as OpenCV reads it, so that markers the board does not
    // have are told apart from no markers at all.
    let dictionary = board.dictionary();
    let markers = find_markers(image, dictionary, dictionary.codes().len());
    let s = board.square_size();
    let (mine, others): (Vec<&Marker>, Vec<&Marker>) =
        markers.iter().partition(|m| m.id < squares.len());
    let mut foreign: Vec<usize> = others.iter().map(|m| m.id).collect();
    foreign.sort_unstable();
    // Each marker read, with its square and its corners on the board's plane.
    let placed: Vec<Placed> = mine
        .iter()
        .map(|m| (*m, squares[m.id], board.marker_corners(squares[m.id])))
        .collect();
    let columns = board.corner_columns();
    let mut found = CharucoCorners {
        markers: placed.len(),
        foreign,
        ..CharucoCorners::default()
    };
    for id in 0..board.corner_count() {
        let (cx, cy) = ((id % columns) as u32, (id / columns) as u32);
        // The corner is the meeting of squares (cx, cy) to (cx + 1, cy + 1).
        let beside = placed
            .iter()
            .filter(|(_, (x, y), _)| (cx..=cx + 1).contains(x) && (cy..=cy + 1).contains(y))
            .count();
        if beside == 0 {
            continue;
        }
        let corner = [f64::from(cx + 1) * s, f64::from(cy + 1) * s];
        let (mut plane, mut seen) = (Vec::new(), Vec::new());
        for (m, (x, y), on_board) in &placed {
            let centre = [(f64::from(*x) + 0.5) * s, (f64::from(*y) + 0.5) * s];
            if (centre[0] - corner[0]).abs() <= REACH * s
                && (centre[1] - corner[1]).abs() <= REACH * s
            {
                plane.extend_from_slice(on_board);
                seen.extend_from_slice(&m.corners);
            }
        }
        let Some(h) = homography(&plane, &seen) else {
            continue;
        };
        let map = |p: [f64; 2]| {
            let v = h * nalgebra::Vector3::new(p[0], p[1], 1.0);
            [v.x / v.z, v.y / v.z]
        };
        let predicted = map(corner);
        // The board's two lines through the corner, and a square's size along each.
        let mut directions = Vec::with_capacity(2);
        let mut spacing = f64::INFINITY;
        for step in [[s, 0.0], [0.0, s]] {
            let a = map([corner[0] - step[0], corner[1] - step[1]]);
            let b = map([corner[0] + step[0], corner[1] + step[1]]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let length = d[0].hypot(d[1]);
            if !(length.is_finite() && length > 0.0) {
                continue;
            }
            directions.push([d[0] / length, d[1] / length]);
            spacing = spacing.min(length / 2.0);
        }
        if directions.len() < 2 {
            continue;
        }
        // The window stays within the white margins around the markers beside the corner.
        let margin = spacing * (s - board.marker_size()) / (2.0 * s);
        if let Some(point) = verify(image, predicted, &directions, spacing, 1.2 * margin) {
            found.ids.push(id);
            found.points.push(point);
        }
    }
    found
}
