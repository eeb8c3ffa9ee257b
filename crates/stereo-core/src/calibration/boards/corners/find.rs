//! Finding a whole chessboard in one image: ChESS X-junctions and their grid labelling from
//! `calib-targets-chessboard`, the labels turned into the board's columns × rows in a fixed
//! order, then every corner refined by [`super::refine_all`].
//!
//! The order is OpenCV's (row by row, as [`Board::object_points`]) and is fixed by the board's
//! colours: corner (0, 0) has black squares on its upper left and lower right in the board's
//! own frame. When a half turn maps the board onto itself (both counts even), the colours
//! cannot tell the two orders apart, so the one whose rows run most nearly left to right in
//! the image is taken; two cameras side by side then agree.

use calib_targets_chessboard::{
    ChessboardDetector, ChessboardParams, GrayImageView, default_chess_config, detect_corners,
};

use super::grid::{self, Fitted, Grid};
use super::{Luma, refine_all};
use crate::calibration::boards::Board;

/// Why a board was not found in an image.
#[derive(Debug, Clone, PartialEq)]
pub enum Miss {
    /// The image is smaller than [`MIN_SIDE`] pixels a side: too small to hold a board.
    TooSmall,
    /// No grid of chessboard corners was found at all.
    NoGrid,
    /// A grid was found, but not the board's whole columns × rows.
    Incomplete {
        found: usize,
        columns: usize,
        rows: usize,
    },
    /// A chessboard larger than the board was found, whole: the board's size is wrong
    /// (squares counted instead of inner corners, or columns and rows mixed up).
    Larger { columns: usize, rows: usize },
    /// The squares' colours fit no orientation of the board (not a chessboard of this size,
    /// or too dark or washed out to tell).
    Colours,
}

impl std::fmt::Display for Miss {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Miss::TooSmall => write!(
                f,
                "the image is smaller than {MIN_SIDE} pixels a side, too small to hold a board"
            ),
            Miss::NoGrid => write!(f, "no chessboard corners were found"),
            Miss::Incomplete {
                found,
                columns,
                rows,
            } => write!(
                f,
                "found a grid of {columns}×{rows} inner corners ({found} of them), not the board's whole grid"
            ),
            Miss::Larger { columns, rows } => write!(
                f,
                "found a chessboard of {columns}×{rows} inner corners, larger than the board"
            ),
            Miss::Colours => write!(
                f,
                "the squares' colours do not fit the board in any orientation"
            ),
        }
    }
}

impl Miss {
    /// The whole chessboard found instead of the board, as (longer, shorter) inner corners:
    /// a complete grid of another size, or a larger chessboard.
    pub fn whole_grid(&self) -> Option<(usize, usize)> {
        match *self {
            Miss::Incomplete {
                found,
                columns,
                rows,
            } if found == columns * rows => Some((columns.max(rows), columns.min(rows))),
            Miss::Larger { columns, rows } => Some((columns.max(rows), columns.min(rows))),
            _ => None,
        }
    }
}

/// The smallest image side searched: three squares of a minimal board need more.
pub const MIN_SIDE: usize = 32;

/// The board's inner corners in `image`, in OpenCV's order, refined to sub-pixel.
pub fn find_board(image: &Luma, board: &Board) -> Result<Vec<[f64; 2]>, Miss> {
    if image.width < MIN_SIDE || image.height < MIN_SIDE {
        return Err(Miss::TooSmall);
    }
    let factor = image.width.max(image.height).div_ceil(DETECTION_SIDE);
    let ordered = match factor {
        0 | 1 => order(&detect_grid(image)?, image, board)?,
        _ => {
            // A large image is searched at a size where its corners are sharp for the
            // detector's fixed ring, and found there in a fraction of the time; a board
            // too small for that is searched at full size.
            let small = shrink(image, factor);
            match detect_grid(&small).and_then(|grid| order(&grid, &small, board)) {
                Ok(points) => {
                    // Refined on the small image first, so that the full-size fit starts
                    // a fraction of a pixel off, not the detector's error times `factor`.
                    let k = factor as f64;
                    let centre = (k - 1.0) / 2.0;
                    refined(&small, &points)
                        .iter()
                        .map(|p| [p[0] * k + centre, p[1] * k + centre])
                        .collect()
                }
                Err(_) => order(&detect_grid(image)?, image, board)?,
            }
        }
    };
    Ok(refined(image, &ordered))
}

/// The longest side the detector searches; a larger image is shrunk by a whole factor first.
pub const DETECTION_SIDE: usize = 1280;

/// Each point refined, or kept where the refinement finds no corner.
fn refined(image: &Luma, points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    refine_all(image, points)
        .into_iter()
        .zip(points)
        .map(|(refined, start)| refined.map_or(*start, |r| r.point))
        .collect()
}

/// The image shrunk by `factor` in each direction, each pixel the mean of a `factor` ×
/// `factor` block (the right and bottom remainders dropped). Pixel (i, j) of the result is
/// centred on (i·factor + (factor − 1)/2, j·factor + (factor − 1)/2) of the image.
fn shrink(image: &Luma, factor: usize) -> Luma {
    let (width, height) = (image.width / factor, image.height / factor);
    let mut data = vec![0.0f32; width * height];
    for j in 0..height {
        let out = &mut data[j * width..(j + 1) * width];
        for row in image.data[j * factor * image.width..]
            .chunks(image.width)
            .take(factor)
        {
            for (value, block) in out.iter_mut().zip(row.chunks_exact(factor)) {
                *value += block.iter().sum::<f32>();
            }
        }
    }
    let area = (factor * factor) as f32;
    data.iter_mut().for_each(|v| *v /= area);
    Luma {
        width,
        height,
        data,
    }
}

fn detect_grid(image: &Luma) -> Result<Grid, Miss> {
    let bytes: Vec<u8> = image
        .data
        .iter()
        .map(|&v| v.round().clamp(0.0, 255.0) as u8)
        .collect();
    let view = GrayImageView {
        width: image.width,
        height: image.height,
        data: &bytes,
    };
    let corners = detect_corners(&view, &default_chess_config());
    let detector =
        ChessboardDetector::new(ChessboardParams::default()).map_err(|_| Miss::NoGrid)?;
    let detection = detector.detect(&corners).ok_or(Miss::NoGrid)?;
    let labels: Vec<(i64, i64, [f64; 2])> = detection
        .corners
        .iter()
        .map(|c| {
            (
                i64::from(c.grid.u),
                i64::from(c.grid.v),
                [f64::from(c.position.x), f64::from(c.position.y)],
            )
        })
        .collect();
    let mut grid = Grid::from_labels(&labels).ok_or(Miss::NoGrid)?;
    // Make the labelling keep the image's handedness (u rightward, v downward), so that the
    // board's orientations below are all rotations.
    if grid.width > 1 && grid.height > 1 && handedness(&grid) < 0.0 {
        grid = grid.transposed();
    }
    Ok(grid)
}

/// The sign of the cross product of the grid's u and v steps, summed over its cells.
fn handedness(grid: &Grid) -> f64 {
    let mut sum = 0.0;
    for v in 0..grid.height - 1 {
        for u in 0..grid.width - 1 {
            if let (Some(a), Some(b), Some(c)) =
                (grid.at(u, v), grid.at(u + 1, v), grid.at(u, v + 1))
            {
                let (du, dv) = ([b[0] - a[0], b[1] - a[1]], [c[0] - a[0], c[1] - a[1]]);
                sum += du[0] * dv[1] - du[1] * dv[0];
            }
        }
    }
    sum
}

/// The four quarter turns that take board corner (i, j) to grid label (u, v).
#[derive(Debug, Clone, Copy)]
enum Turn {
    None,
    Half,
    Quarter,
    ThreeQuarters,
}

impl Turn {
    fn label(self, i: usize, j: usize, grid: &Grid) -> (usize, usize) {
        let (w, h) = (grid.width - 1, grid.height - 1);
        match self {
            Turn::None => (i, j),
            Turn::Half => (w - i, h - j),
            Turn::Quarter => (j, h - i),
            Turn::ThreeQuarters => (w - j, i),
        }
    }

    fn fits(self, grid: &Grid, columns: usize, rows: usize) -> bool {
        match self {
            Turn::None | Turn::Half => grid.width == columns && grid.height == rows,
            Turn::Quarter | Turn::ThreeQuarters => grid.width == rows && grid.height == columns,
        }
    }
}

fn order(grid: &Grid, image: &Luma, board: &Board) -> Result<Vec<[f64; 2]>, Miss> {
    let (columns, rows) = (board.columns() as usize, board.rows() as usize);
    let grid = match grid::fit(grid, image, columns, rows) {
        Fitted::Board(grid) => grid,
        Fitted::Short(grid) => {
            return Err(Miss::Incomplete {
                found: grid.labelled(),
                columns: grid.width,
                rows: grid.height,
            });
        }
        Fitted::Larger(grid) => {
            return Err(Miss::Larger {
                columns: grid.width,
                rows: grid.height,
            });
        }
    };
    let grid = &grid;
    let mut best: Option<(f64, Vec<[f64; 2]>)> = None;
    for turn in [Turn::None, Turn::Half, Turn::Quarter, Turn::ThreeQuarters] {
        if !turn.fits(grid, columns, rows) {
            continue;
        }
        let Some(points) = (0..rows)
            .flat_map(|j| (0..columns).map(move |i| (i, j)))
            .map(|(i, j)| {
                let (u, v) = turn.label(i, j, grid);
                grid.at(u, v)
            })
            .collect::<Option<Vec<_>>>()
        else {
            continue;
        };
        if contrast(&points, image, columns, rows) <= 0.0 {
            continue;
        }
        // Among orders the colours allow, the one whose rows run most nearly rightward.
        let rightward = points[columns - 1][0] - points[0][0];
        if best.as_ref().is_none_or(|(r, _)| rightward > *r) {
            best = Some((rightward, points));
        }
    }
    best.map(|(_, points)| points).ok_or(Miss::Colours)
}

/// Mean grey of the squares that should be white minus that of those that should be black,
/// sampled at each inner square's centre.
fn contrast(points: &[[f64; 2]], image: &Luma, columns: usize, rows: usize) -> f64 {
    let (mut white, mut black) = ((0.0, 0usize), (0.0, 0usize));
    for q in 0..rows - 1 {
        for p in 0..columns - 1 {
            let corner = |i: usize, j: usize| points[j * columns + i];
            let quad = [
                corner(p, q),
                corner(p + 1, q),
                corner(p, q + 1),
                corner(p + 1, q + 1),
            ];
            let centre = [
                quad.iter().map(|c| c[0]).sum::<f64>() / 4.0,
                quad.iter().map(|c| c[1]).sum::<f64>() / 4.0,
            ];
            let Some(grey) = patch_mean(image, centre) else {
                continue;
            };
            if Board::is_black(p as i64, q as i64) {
                black.0 += grey;
                black.1 += 1;
            } else {
                white.0 += grey;
                white.1 += 1;
            }
        }
    }
    if white.1 == 0 || black.1 == 0 {
        return 0.0;
    }
    white.0 / white.1 as f64 - black.0 / black.1 as f64
}

/// The mean grey of the 3 × 3 pixels around `centre`, or `None` outside the image.
fn patch_mean(image: &Luma, centre: [f64; 2]) -> Option<f64> {
    let (x, y) = (centre[0].round() as i64, centre[1].round() as i64);
    if x < 1 || y < 1 || x + 1 >= image.width as i64 || y + 1 >= image.height as i64 {
        return None;
    }
    let mut sum = 0.0;
    for dy in -1..=1 {
        for dx in -1..=1 {
            sum += f64::from(image.data[(y + dy) as usize * image.width + (x + dx) as usize]);
        }
    }
    Some(sum / 9.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Shrinking averages whole blocks and drops the remainders: a 5 × 3 ramp by 2 is 2 × 1,
    /// each pixel the mean of its 2 × 2 block.
    #[test]
    fn shrink_averages_blocks() {
        let image = Luma {
            width: 5,
            height: 3,
            data: (0..15).map(|v| v as f32).collect(),
        };
        let small = shrink(&image, 2);
        assert_eq!((small.width, small.height), (2, 1));
        assert_eq!(small.data, vec![3.0, 5.0]);
    }
}
