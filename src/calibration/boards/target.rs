//! The target a calibration is shot against: a chessboard, found whole in each image, or a
//! ChArUco board, whose views count with the corners they show. Both give their corners in
//! the order of their object points, so the calibration itself does not tell them apart.

use nalgebra::Vector3;

use super::Board;
use super::charuco::{CharucoBoard, MIN_VIEW_CORNERS, find_charuco};
use super::corners::{Luma, Miss, find_board};
use super::fit::{Seen, whole};
use crate::calibration::files::opencv;
use crate::physics::LengthUnit;

/// The printed target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Target {
    Chessboard(Board),
    Charuco(CharucoBoard),
}

impl Target {
    /// The corners on the board's plane (z = 0), in the order the views give them.
    pub fn object_points(&self) -> Vec<Vector3<f64>> {
        match self {
            Target::Chessboard(b) => b.object_points(),
            Target::Charuco(b) => b.object_points(),
        }
    }

    pub fn unit(&self) -> LengthUnit {
        match self {
            Target::Chessboard(b) => b.unit(),
            Target::Charuco(b) => b.unit(),
        }
    }

    pub fn square_size(&self) -> f64 {
        match self {
            Target::Chessboard(b) => b.square_size(),
            Target::Charuco(b) => b.square_size(),
        }
    }

    /// The inner corners along a row and along a column.
    pub fn inner_corners(&self) -> (u32, u32) {
        match self {
            Target::Chessboard(b) => (b.columns(), b.rows()),
            Target::Charuco(b) => {
                let (x, y) = b.squares();
                (x - 1, y - 1)
            }
        }
    }

    /// The target as `opencv.yml` records it: its inner corners (a ChArUco board's squares
    /// less one each way), square and unit.
    pub fn recorded(&self) -> opencv::Target {
        let (columns, rows) = self.inner_corners();
        opencv::Target {
            columns,
            rows,
            square_size: self.square_size(),
            unit: self.unit(),
        }
    }

    /// How many corners the target has.
    pub fn corner_count(&self) -> usize {
        let (c, r) = self.inner_corners();
        (c * r) as usize
    }

    /// The target's corners in `image`: a chessboard's all or none; a ChArUco board's those
    /// found beside the markers read, when they are enough for the view to count
    /// ([`MIN_VIEW_CORNERS`] over two rows and two columns).
    pub fn find(&self, image: &Luma) -> Result<Seen, Miss> {
        match self {
            Target::Chessboard(b) => find_board(image, b).map(|c| whole(&c)),
            Target::Charuco(b) => {
                let found = find_charuco(image, b);
                if found.usable(b.corner_columns()) {
                    Ok(found.seen(b.corner_count()))
                } else {
                    Err(Miss::FewCorners {
                        corners: found.ids.len(),
                        markers: found.markers,
                        needed: MIN_VIEW_CORNERS,
                    })
                }
            }
        }
    }
}
