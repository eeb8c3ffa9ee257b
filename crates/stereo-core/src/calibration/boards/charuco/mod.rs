//! ChArUco boards as OpenCV's `cv2.aruco.CharucoBoard` defines them: the squares, the markers
//! in the white squares with their ids, the inner corners' ids and positions on the board's
//! plane, and the legacy pattern. A board printed from OpenCV's `generateImage` is read with
//! OpenCV's ids and object points.
//!
//! - [`dictionary`]: the ArUco dictionaries' codes, from OpenCV's tables.
//! - [`markers`]: finding the markers in an image and reading their ids.
//! - [`find`]: the inner corners the markers point to, each found and refined in the image.
//! - [`render`]: boards rendered through a known rig, whole and partly out of the frame.

pub mod dictionary;
pub mod find;
pub mod markers;
pub mod render;

use nalgebra::Vector3;

pub use dictionary::Dictionary;
pub use find::{CharucoCorners, MIN_VIEW_CORNERS, find_charuco};

use crate::physics::LengthUnit;

/// The fewest squares a side may have: 3 × 3 squares hold 4 inner corners, the fewest a
/// pose can be taken from.
pub const MIN_SQUARES: u32 = 3;
/// The most squares a side may have (as a chessboard's 64 inner corners).
pub const MAX_SQUARES: u32 = 65;

/// A ChArUco board as the user printed it. Built by [`CharucoBoard::new`]: its sides within
/// [`MIN_SQUARES`]..=[`MAX_SQUARES`], its marker smaller than its square, and a dictionary
/// with a marker for each white square.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CharucoBoard {
    squares_x: u32,
    squares_y: u32,
    square_size: f64,
    marker_size: f64,
    dictionary: Dictionary,
    legacy: bool,
    unit: LengthUnit,
}

/// A member of a ChArUco board, as its faults name them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CharucoMember {
    SquaresX,
    SquaresY,
    SquareSize,
    MarkerSize,
    Dictionary,
}

impl CharucoMember {
    pub fn name(self) -> &'static str {
        match self {
            CharucoMember::SquaresX => "squares_x",
            CharucoMember::SquaresY => "squares_y",
            CharucoMember::SquareSize => "square_size",
            CharucoMember::MarkerSize => "marker_size",
            CharucoMember::Dictionary => "dictionary",
        }
    }
}

/// What is wrong with one member of a ChArUco board.
#[derive(Debug, Clone, PartialEq)]
pub struct CharucoFault {
    pub member: CharucoMember,
    pub message: String,
}

/// The board's parts as given, before they are checked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CharucoSpec {
    pub squares_x: u32,
    pub squares_y: u32,
    pub square_size: f64,
    pub marker_size: f64,
    pub dictionary: Dictionary,
    pub legacy: bool,
    pub unit: LengthUnit,
}

impl CharucoBoard {
    /// Checks a board and names every fault: sides out of bounds, a square or marker that is
    /// not positive, a marker not smaller than its square, too few markers in the dictionary.
    pub fn new(spec: CharucoSpec) -> Result<CharucoBoard, Vec<CharucoFault>> {
        let mut faults = Vec::new();
        let mut fault = |member, message: String| faults.push(CharucoFault { member, message });
        for (member, n) in [
            (CharucoMember::SquaresX, spec.squares_x),
            (CharucoMember::SquaresY, spec.squares_y),
        ] {
            if !(MIN_SQUARES..=MAX_SQUARES).contains(&n) {
                fault(
                    member,
                    format!(
                        "must be between {MIN_SQUARES} and {MAX_SQUARES} squares (a ChArUco \
                         board counts squares, not inner corners), not {n}"
                    ),
                );
            }
        }
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(spec.square_size) {
            fault(
                CharucoMember::SquareSize,
                "must be a positive number".into(),
            );
        }
        if !positive(spec.marker_size) {
            fault(
                CharucoMember::MarkerSize,
                "must be a positive number".into(),
            );
        } else if positive(spec.square_size) && spec.marker_size >= spec.square_size {
            fault(
                CharucoMember::MarkerSize,
                format!(
                    "must be smaller than square_size ({}): the marker sits inside a white \
                     square, with a margin",
                    spec.square_size
                ),
            );
        }
        let sides = (MIN_SQUARES..=MAX_SQUARES).contains(&spec.squares_x)
            && (MIN_SQUARES..=MAX_SQUARES).contains(&spec.squares_y);
        let markers = (spec.squares_x * spec.squares_y / 2) as usize;
        let held = spec.dictionary.codes().len();
        if sides && markers > held {
            fault(
                CharucoMember::Dictionary,
                format!(
                    "{} holds {held} markers, but a board of {} × {} squares needs {markers}: \
                     choose a larger dictionary or a smaller board",
                    spec.dictionary.name(),
                    spec.squares_x,
                    spec.squares_y
                ),
            );
        }
        if !faults.is_empty() {
            return Err(faults);
        }
        Ok(CharucoBoard {
            squares_x: spec.squares_x,
            squares_y: spec.squares_y,
            square_size: spec.square_size,
            marker_size: spec.marker_size,
            dictionary: spec.dictionary,
            legacy: spec.legacy,
            unit: spec.unit,
        })
    }

    pub fn squares(&self) -> (u32, u32) {
        (self.squares_x, self.squares_y)
    }

    pub fn square_size(&self) -> f64 {
        self.square_size
    }

    pub fn marker_size(&self) -> f64 {
        self.marker_size
    }

    pub fn dictionary(&self) -> Dictionary {
        self.dictionary
    }

    pub fn legacy(&self) -> bool {
        self.legacy
    }

    pub fn unit(&self) -> LengthUnit {
        self.unit
    }

    /// Whether square (x, y) is black (then it holds no marker). OpenCV's rule: the top-left
    /// square is black, except in the legacy pattern of a board with an even number of rows.
    pub fn is_black(&self, x: i64, y: i64) -> bool {
        if self.legacy && self.squares_y.is_multiple_of(2) {
            (y + 1).rem_euclid(2) == x.rem_euclid(2)
        } else {
            y.rem_euclid(2) == x.rem_euclid(2)
        }
    }

    /// The square (x, y) of each marker, by id: the white squares row by row.
    pub fn marker_squares(&self) -> Vec<(u32, u32)> {
        (0..self.squares_y)
            .flat_map(|y| (0..self.squares_x).map(move |x| (x, y)))
            .filter(|&(x, y)| !self.is_black(i64::from(x), i64::from(y)))
            .collect()
    }

    /// A marker's corners on the board's plane (x right, y down, from the board's top-left),
    /// clockwise from its top-left as OpenCV orders them.
    pub fn marker_corners(&self, (x, y): (u32, u32)) -> [[f64; 2]; 4] {
        let margin = (self.square_size - self.marker_size) / 2.0;
        let (x0, y0) = (
            f64::from(x) * self.square_size + margin,
            f64::from(y) * self.square_size + margin,
        );
        let m = self.marker_size;
        [[x0, y0], [x0 + m, y0], [x0 + m, y0 + m], [x0, y0 + m]]
    }

    /// How many inner corners the board has: (squares_x − 1)·(squares_y − 1).
    pub fn corner_count(&self) -> usize {
        ((self.squares_x - 1) * (self.squares_y - 1)) as usize
    }

    /// The inner corners per row: squares_x − 1.
    pub fn corner_columns(&self) -> usize {
        (self.squares_x - 1) as usize
    }

    /// Inner corner `id` on the board's plane (z = 0): OpenCV's
    /// `getChessboardCorners()[id]`, ((x + 1)·s, (y + 1)·s) for id = y·(squares_x − 1) + x.
    pub fn corner_point(&self, id: usize) -> Vector3<f64> {
        let columns = self.corner_columns();
        let (x, y) = ((id % columns) as f64, (id / columns) as f64);
        Vector3::new(
            (x + 1.0) * self.square_size,
            (y + 1.0) * self.square_size,
            0.0,
        )
    }

    /// Every inner corner on the board's plane, by id.
    pub fn object_points(&self) -> Vec<Vector3<f64>> {
        (0..self.corner_count())
            .map(|id| self.corner_point(id))
            .collect()
    }

    /// The printed grey level (0 black, 1 white) at (x, y) on the board's plane, for
    /// rendering; `None` off the board.
    pub fn shade(&self, x: f64, y: f64) -> Option<bool> {
        let s = self.square_size;
        let (w, h) = (f64::from(self.squares_x) * s, f64::from(self.squares_y) * s);
        if !(0.0..w).contains(&x) || !(0.0..h).contains(&y) {
            return None;
        }
        let (i, j) = ((x / s).floor() as i64, (y / s).floor() as i64);
        if self.is_black(i, j) {
            return Some(false);
        }
        let margin = (s - self.marker_size) / 2.0;
        let (u, v) = (x - i as f64 * s - margin, y - j as f64 * s - margin);
        let m = self.marker_size;
        if !(0.0..m).contains(&u) || !(0.0..m).contains(&v) {
            return Some(true);
        }
        // The marker: a black border one bit wide around the code's bits.
        let bits = self.dictionary.bits();
        let cells = bits + 2;
        let (c, r) = (
            ((u / m * cells as f64) as usize).min(cells - 1),
            ((v / m * cells as f64) as usize).min(cells - 1),
        );
        if c == 0 || r == 0 || c == cells - 1 || r == cells - 1 {
            return Some(false);
        }
        let id = self.marker_id((i as u32, j as u32))?;
        let code = self.dictionary.codes()[id];
        let bit = (r - 1) * bits + (c - 1);
        Some((code >> (bits * bits - 1 - bit)) & 1 == 1)
    }

    /// The id of the marker in square (x, y), if it holds one.
    pub fn marker_id(&self, (x, y): (u32, u32)) -> Option<usize> {
        if x >= self.squares_x || y >= self.squares_y || self.is_black(x.into(), y.into()) {
            return None;
        }
        // White squares before row y, then before x in row y.
        let whites_in = |row: u32, upto: u32| {
            (0..upto)
                .filter(|&i| !self.is_black(i.into(), row.into()))
                .count()
        };
        let before: usize = (0..y).map(|row| whites_in(row, self.squares_x)).sum();
        Some(before + whites_in(y, x))
    }
}

#[cfg(test)]
mod tests;
