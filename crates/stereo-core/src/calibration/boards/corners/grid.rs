//! The detector's labelled corners as a grid, and that grid fitted to the board: a corner the
//! detector missed (or one beyond the last it labelled, where the board runs to the image's
//! edge) is predicted from its neighbours in line and kept only where the image shows a
//! chessboard corner there, with its edges along the grid's lines; junctions beyond the board
//! (a monitor, a keyboard, a shirt) are left out by taking the board-sized window the
//! detector's labels fill best.

use super::Luma;
use super::refine::verify;

/// One labelled corner: where it is, and whether the detector labelled it or [`grow`] added it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Cell {
    pub point: [f64; 2],
    pub detected: bool,
}

/// Labelled corners: a dense table `cells[v][u]` over the labels' extent.
#[derive(Debug, Clone)]
pub(super) struct Grid {
    pub width: usize,
    pub height: usize,
    /// How many corners the detector labelled (before any were added or left out).
    pub found: usize,
    pub cells: Vec<Option<Cell>>,
}

impl Grid {
    /// The detector's labels `(u, v, position)`, which may start anywhere.
    pub fn from_labels(labels: &[(i64, i64, [f64; 2])]) -> Option<Grid> {
        let u0 = labels.iter().map(|l| l.0).min()?;
        let v0 = labels.iter().map(|l| l.1).min()?;
        let width = (labels.iter().map(|l| l.0).max()? - u0 + 1) as usize;
        let height = (labels.iter().map(|l| l.1).max()? - v0 + 1) as usize;
        if width > 4096 || height > 4096 {
            return None;
        }
        let mut cells = vec![None; width * height];
        for &(u, v, point) in labels {
            cells[(v - v0) as usize * width + (u - u0) as usize] = Some(Cell {
                point,
                detected: true,
            });
        }
        Some(Grid {
            width,
            height,
            found: labels.len(),
            cells,
        })
    }

    pub fn at(&self, u: usize, v: usize) -> Option<[f64; 2]> {
        self.cells[v * self.width + u].map(|c| c.point)
    }

    /// The position at (u, v) given as signed labels, `None` outside the grid.
    fn get(&self, u: i64, v: i64) -> Option<[f64; 2]> {
        if u < 0 || v < 0 || u >= self.width as i64 || v >= self.height as i64 {
            return None;
        }
        self.at(u as usize, v as usize)
    }

    pub fn labelled(&self) -> usize {
        self.cells.iter().flatten().count()
    }

    fn detected(&self) -> usize {
        self.cells.iter().flatten().filter(|c| c.detected).count()
    }

    /// The grid with its labels swapped: (u, v) becomes (v, u).
    pub fn transposed(&self) -> Grid {
        let mut cells = vec![None; self.width * self.height];
        for v in 0..self.height {
            for u in 0..self.width {
                cells[u * self.height + v] = self.cells[v * self.width + u];
            }
        }
        Grid {
            width: self.height,
            height: self.width,
            found: self.found,
            cells,
        }
    }

    /// The grid padded by `[left, top, right, bottom]` empty lines.
    fn padded(&self, pad: [usize; 4]) -> Grid {
        let width = self.width + pad[0] + pad[2];
        let height = self.height + pad[1] + pad[3];
        let mut cells = vec![None; width * height];
        for v in 0..self.height {
            for u in 0..self.width {
                cells[(v + pad[1]) * width + u + pad[0]] = self.cells[v * self.width + u];
            }
        }
        Grid {
            width,
            height,
            found: self.found,
            cells,
        }
    }

    /// The `width` × `height` window whose top-left label is (u0, v0).
    fn window(&self, u0: usize, v0: usize, width: usize, height: usize) -> Grid {
        let mut cells = Vec::with_capacity(width * height);
        for v in v0..v0 + height {
            cells.extend_from_slice(&self.cells[v * self.width + u0..v * self.width + u0 + width]);
        }
        Grid {
            width,
            height,
            found: self.found,
            cells,
        }
    }

    /// The grid without empty outer lines.
    fn trimmed(&self) -> Grid {
        let used = |u: usize, v: usize| self.cells[v * self.width + u].is_some();
        let columns: Vec<usize> = (0..self.width)
            .filter(|&u| (0..self.height).any(|v| used(u, v)))
            .collect();
        let rows: Vec<usize> = (0..self.height)
            .filter(|&v| (0..self.width).any(|u| used(u, v)))
            .collect();
        match (columns.first(), columns.last(), rows.first(), rows.last()) {
            (Some(&u0), Some(&u1), Some(&v0), Some(&v1)) => {
                self.window(u0, v0, u1 - u0 + 1, v1 - v0 + 1)
            }
            _ => self.window(0, 0, 0, 0),
        }
    }
}

/// Whether a grid of `width` × `height` fits in a board of `columns` × `rows`, in either
/// orientation.
fn fits_within(width: usize, height: usize, columns: usize, rows: usize) -> bool {
    (width <= columns && height <= rows) || (width <= rows && height <= columns)
}

/// What fitting the grid to the board gives.
#[derive(Debug)]
pub(super) enum Fitted {
    /// A grid of exactly the board's size (either orientation), every corner present.
    Board(Grid),
    /// No window of the board's size could be completed: the grid as far as it went.
    Short(Grid),
    /// Several windows of the board's size are complete and the detector labelled each as
    /// fully: the grid holds a larger chessboard than the one described.
    Larger(Grid),
}

/// Fits the detector's `grid` to a board of `columns` × `rows` inner corners in `image`.
pub(super) fn fit(grid: &Grid, image: &Luma, columns: usize, rows: usize) -> Fitted {
    let grown = grow(grid, image, columns, rows);
    let mut complete: Vec<(usize, Grid)> = Vec::new();
    let orientations = if columns == rows {
        vec![(columns, rows)]
    } else {
        vec![(columns, rows), (rows, columns)]
    };
    for (width, height) in orientations {
        if width > grown.width || height > grown.height {
            continue;
        }
        for v0 in 0..=grown.height - height {
            for u0 in 0..=grown.width - width {
                let window = grown.window(u0, v0, width, height);
                if window.labelled() == width * height {
                    complete.push((window.detected(), window));
                }
            }
        }
    }
    // The window the detector's own labels fill best; a tie between complete windows is a
    // larger chessboard, whose windows no evidence tells apart.
    complete.sort_by_key(|(labels, _)| std::cmp::Reverse(*labels));
    match complete.as_slice() {
        [] => Fitted::Short(grown),
        [(best, _), (second, _), ..] if best == second => Fitted::Larger(grown),
        _ => Fitted::Board(complete.swap_remove(0).1),
    }
}

/// The grid completed where the image shows the board's corners: each empty label with
/// neighbours in line is predicted from them and kept when a chessboard corner with an edge
/// along that line is found there. The grid grows past its outer lines only while it still
/// fits within the board, so a board whose outer squares run to the image's edge, or one
/// whose corner the detector missed, is whole again. Past the board's last corners the image
/// shows no such corner (its border makes an L, not an X), so nothing is added there.
fn grow(grid: &Grid, image: &Luma, columns: usize, rows: usize) -> Grid {
    let mut grid = grid.trimmed();
    for _ in 0..2 * columns.max(rows) {
        let spare_u = usize::from(fits_within(grid.width + 1, grid.height, columns, rows));
        let spare_v = usize::from(fits_within(grid.width, grid.height + 1, columns, rows));
        let mut next = grid.padded([spare_u, spare_v, spare_u, spare_v]);
        let mut added = false;
        for v in 0..next.height {
            for u in 0..next.width {
                if next.cells[v * next.width + u].is_some() {
                    continue;
                }
                if let Some(point) = predict_and_find(&next, image, u as i64, v as i64) {
                    next.cells[v * next.width + u] = Some(Cell {
                        point,
                        detected: false,
                    });
                    added = true;
                }
            }
        }
        grid = next.trimmed();
        if !added {
            break;
        }
    }
    grid
}

/// The corner at label (u, v), predicted from its neighbours in line and found in the image.
fn predict_and_find(grid: &Grid, image: &Luma, u: i64, v: i64) -> Option<[f64; 2]> {
    let mut predictions: Vec<([f64; 2], [f64; 2], f64)> = Vec::new();
    for (du, dv) in [(1, 0), (0, 1)] {
        let before = grid.get(u - du, v - dv);
        let after = grid.get(u + du, v + dv);
        if let (Some(a), Some(b)) = (before, after) {
            // Between two neighbours: their midpoint.
            predictions.push(([(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0], a, 0.5));
            continue;
        }
        for sign in [1, -1] {
            let (du, dv) = (du * sign, dv * sign);
            let (Some(a), Some(b)) = (grid.get(u + du, v + dv), grid.get(u + 2 * du, v + 2 * dv))
            else {
                continue;
            };
            // Beyond two in line: the next step, bent as the third bends it if there is one.
            let p = match grid.get(u + 3 * du, v + 3 * dv) {
                Some(c) => [
                    3.0 * a[0] - 3.0 * b[0] + c[0],
                    3.0 * a[1] - 3.0 * b[1] + c[1],
                ],
                None => [2.0 * a[0] - b[0], 2.0 * a[1] - b[1]],
            };
            predictions.push((p, b, 2.0));
        }
    }
    if predictions.is_empty() {
        return None;
    }
    let n = predictions.len() as f64;
    let predicted = [
        predictions.iter().map(|p| p.0[0]).sum::<f64>() / n,
        predictions.iter().map(|p| p.0[1]).sum::<f64>() / n,
    ];
    // Each prediction's line, from the neighbour it was taken from to the predicted point,
    // and the square's size along it (that neighbour is half a square away between two
    // neighbours, two squares away beyond two in line).
    let lines: Vec<([f64; 2], f64)> = predictions
        .iter()
        .filter_map(|&(p, from, steps)| {
            let d = [p[0] - from[0], p[1] - from[1]];
            let length = d[0].hypot(d[1]);
            (length > 0.0).then(|| ([d[0] / length, d[1] / length], length / steps))
        })
        .collect();
    let spacing = lines.iter().map(|l| l.1).fold(f64::INFINITY, f64::min);
    let directions: Vec<[f64; 2]> = lines.iter().map(|l| l.0).collect();
    verify(image, predicted, &directions, spacing, 0.4 * spacing)
}
