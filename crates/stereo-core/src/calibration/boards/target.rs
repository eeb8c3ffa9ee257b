//! The target a calibration is shot against: a chessboard, found whole in each image, or a
//! ChArUco board, whose views count with the corners they show. Both give their corners in
//! the order of their object points, so the calibration itself does not tell them apart.

use nalgebra::Vector3;

use super::Board;
use super::charuco::markers::find_markers;
use super::charuco::{CharucoBoard, CharucoCorners, Dictionary, MIN_VIEW_CORNERS, find_charuco};
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
    /// ([`MIN_VIEW_CORNERS`] over two rows and two columns) and the image shows no markers
    /// the board does not have.
    pub fn find(&self, image: &Luma) -> Result<Seen, TargetMiss> {
        match self {
            Target::Chessboard(b) => find_board(image, b)
                .map(|c| whole(&c))
                .map_err(TargetMiss::Chessboard),
            Target::Charuco(b) => {
                let found = find_charuco(image, b);
                if shows_another_board(&found) {
                    return Err(TargetMiss::ForeignIds {
                        ids: found.foreign,
                        markers: b.marker_squares().len(),
                    });
                }
                if found.usable(b.corner_columns()) {
                    return Ok(found.seen(b.corner_count()));
                }
                if found.markers == 0
                    && let Some((dictionary, markers)) = other_dictionary(image, b.dictionary())
                {
                    return Err(TargetMiss::OtherDictionary {
                        dictionary,
                        markers,
                    });
                }
                Err(TargetMiss::FewCorners {
                    corners: found.ids.len(),
                    markers: found.markers,
                    needed: MIN_VIEW_CORNERS,
                })
            }
        }
    }
}

/// Whether the markers read say the board printed is another than the one described: two
/// or more ids the board does not have, a fifth or more of the markers read. (One stray id
/// can be a misread; several distinct ones are a larger board, or another board's layout.)
fn shows_another_board(found: &CharucoCorners) -> bool {
    let foreign = found.foreign.len();
    foreign >= 2 && 5 * foreign >= found.markers + foreign
}

/// The markers to read before an image is said to show another dictionary's.
const OTHER_DICTIONARY_MARKERS: usize = 4;

/// The other dictionary whose markers an image shows, with how many were read, when the
/// board's own dictionary read none.
fn other_dictionary(image: &Luma, own: Dictionary) -> Option<(Dictionary, usize)> {
    Dictionary::ALL
        .into_iter()
        .filter(|&d| d != own)
        .map(|d| (d, find_markers(image, d, d.codes().len()).len()))
        .filter(|&(_, n)| n >= OTHER_DICTIONARY_MARKERS)
        .max_by_key(|&(_, n)| n)
}

/// Why a target was not found in an image.
#[derive(Debug, Clone, PartialEq)]
pub enum TargetMiss {
    /// The chessboard was not found whole, and why.
    Chessboard(Miss),
    /// A ChArUco board's markers gave too few corners for the view to count (fewer than
    /// `needed`, or all on one row or column of the board).
    FewCorners {
        corners: usize,
        markers: usize,
        needed: usize,
    },
    /// The image shows markers of the board's dictionary with `ids` the board does not have
    /// (it has `markers`, ids 0 to `markers` − 1): a larger board, or another.
    ForeignIds { ids: Vec<usize>, markers: usize },
    /// No marker of the board's dictionary, but `markers` of `dictionary`.
    OtherDictionary {
        dictionary: Dictionary,
        markers: usize,
    },
}

impl TargetMiss {
    /// The whole chessboard of another size found instead of the board, as (longer,
    /// shorter) inner corners.
    pub fn whole_grid(&self) -> Option<(usize, usize)> {
        match self {
            TargetMiss::Chessboard(miss) => miss.whole_grid(),
            _ => None,
        }
    }
}

impl std::fmt::Display for TargetMiss {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TargetMiss::Chessboard(miss) => miss.fmt(f),
            TargetMiss::FewCorners {
                corners,
                markers,
                needed,
            } => write!(
                f,
                "read {markers} markers and found {corners} corners beside them: a view \
                 counts from {needed} corners over two rows and two columns of the board"
            ),
            TargetMiss::ForeignIds { ids, markers } => write!(
                f,
                "shows markers {} that the board does not have (its {markers} markers are \
                 ids 0 to {}): is the board larger than its squares_x × squares_y?",
                list(ids),
                markers.saturating_sub(1)
            ),
            TargetMiss::OtherDictionary {
                dictionary,
                markers,
            } => write!(
                f,
                "no marker of the board's dictionary was read, but {markers} of {}",
                dictionary.name()
            ),
        }
    }
}

/// "24, 25 and 31", the first 8 ids and how many more.
fn list(ids: &[usize]) -> String {
    let shown: Vec<String> = ids.iter().take(8).map(usize::to_string).collect();
    let more = ids.len().saturating_sub(8);
    match (shown.len(), more) {
        (_, m) if m > 0 => format!("{} and {m} more", shown.join(", ")),
        (0, _) => String::new(),
        (1, _) => shown[0].clone(),
        (n, _) => format!("{} and {}", shown[..n - 1].join(", "), shown[n - 1]),
    }
}
