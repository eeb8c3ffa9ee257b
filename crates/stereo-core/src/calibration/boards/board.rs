//! The calibration target: a chessboard of `columns × rows` inner corners (OpenCV's
//! `patternSize`) with squares of `square_size` in a length unit, and its corners' positions
//! on the board's plane, in OpenCV's order (row by row).

use std::fmt;

use nalgebra::Vector3;

use crate::calibration::files::opencv::Target;
use crate::physics::LengthUnit;

/// The fewest inner corners a side may have (OpenCV's `findChessboardCorners` needs 3).
pub const MIN_CORNERS: u32 = 3;
/// The most inner corners a side may have: far beyond printed boards, small enough that no
/// board allocates more than a few kilobytes of points.
pub const MAX_CORNERS: u32 = 64;

/// A chessboard as the user printed it. Built by [`Board::new`], so its sides are within
/// [`MIN_CORNERS`]..=[`MAX_CORNERS`] and its square is positive and finite.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Board {
    columns: u32,
    rows: u32,
    square_size: f64,
    unit: LengthUnit,
}

/// A member of a board, as the faults name them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoardMember {
    Columns,
    Rows,
    SquareSize,
}

impl BoardMember {
    pub fn name(self) -> &'static str {
        match self {
            BoardMember::Columns => "columns",
            BoardMember::Rows => "rows",
            BoardMember::SquareSize => "square_size",
        }
    }
}

/// What is wrong with one member of a board.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardFault {
    pub member: BoardMember,
    pub message: String,
}

impl fmt::Display for BoardFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}", self.member.name(), self.message)
    }
}

impl Board {
    /// Checks a board: each side's inner corners within the bounds, a positive square.
    pub fn new(
        columns: u32,
        rows: u32,
        square_size: f64,
        unit: LengthUnit,
    ) -> Result<Board, Vec<BoardFault>> {
        let mut faults = Vec::new();
        for (member, n) in [(BoardMember::Columns, columns), (BoardMember::Rows, rows)] {
            if !(MIN_CORNERS..=MAX_CORNERS).contains(&n) {
                faults.push(BoardFault {
                    member,
                    message: format!(
                        "must be between {MIN_CORNERS} and {MAX_CORNERS} inner corners \
                         (a board of 10 × 7 squares has 9 × 6), not {n}"
                    ),
                });
            }
        }
        if !(square_size.is_finite() && square_size > 0.0) {
            faults.push(BoardFault {
                member: BoardMember::SquareSize,
                message: "must be a positive number".into(),
            });
        }
        if faults.is_empty() {
            Ok(Board {
                columns,
                rows,
                square_size,
                unit,
            })
        } else {
            Err(faults)
        }
    }

    pub fn columns(&self) -> u32 {
        self.columns
    }

    pub fn rows(&self) -> u32 {
        self.rows
    }

    pub fn square_size(&self) -> f64 {
        self.square_size
    }

    pub fn unit(&self) -> LengthUnit {
        self.unit
    }

    /// The board as `opencv.yml` records it.
    pub fn target(&self) -> Target {
        Target {
            columns: self.columns,
            rows: self.rows,
            square_size: self.square_size,
            unit: self.unit,
        }
    }

    /// How many inner corners the board has.
    pub fn corner_count(&self) -> usize {
        (self.columns * self.rows) as usize
    }

    /// Whether a half turn maps the board onto itself (both sides' square counts odd, so
    /// both inner-corner counts even), which leaves the corners' order ambiguous.
    pub fn is_symmetric(&self) -> bool {
        self.columns.is_multiple_of(2) && self.rows.is_multiple_of(2)
    }

    /// The inner corners on the board's plane (z = 0), row by row: corner (i, j) at
    /// (i·s, j·s, 0), as OpenCV's samples build their object points.
    pub fn object_points(&self) -> Vec<Vector3<f64>> {
        let s = self.square_size;
        (0..self.rows)
            .flat_map(|j| {
                (0..self.columns)
                    .map(move |i| Vector3::new(f64::from(i) * s, f64::from(j) * s, 0.0))
            })
            .collect()
    }

    /// Whether the board's square (p, q) is black, counting from the square whose corner is
    /// (0, 0) at its bottom right: p in −1..=columns, q in −1..=rows.
    pub fn is_black(p: i64, q: i64) -> bool {
        (p + q).rem_euclid(2) == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A board refuses too few corners and a square that is not positive, naming each.
    #[test]
    fn board_faults_name_the_member() {
        let faults = Board::new(2, 70, -1.0, LengthUnit::Millimetre).unwrap_err();
        let members: Vec<_> = faults.iter().map(|f| f.member).collect();
        assert_eq!(
            members,
            [
                BoardMember::Columns,
                BoardMember::Rows,
                BoardMember::SquareSize
            ]
        );
        assert!(faults[0].message.contains("not 2"));
    }

    /// The object points run row by row, x along the columns.
    #[test]
    fn object_points_in_opencv_order() {
        let board = Board::new(4, 3, 25.0, LengthUnit::Millimetre).unwrap();
        let points = board.object_points();
        assert_eq!(points.len(), 12);
        assert_eq!(points[1], Vector3::new(25.0, 0.0, 0.0));
        assert_eq!(points[4], Vector3::new(0.0, 25.0, 0.0));
        assert!(!board.is_symmetric());
        assert!(
            Board::new(8, 6, 1.0, LengthUnit::Metre)
                .unwrap()
                .is_symmetric()
        );
    }
}
