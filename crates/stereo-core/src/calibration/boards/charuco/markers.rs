//! Finding ArUco markers in a grey image and reading their ids, as OpenCV's `ArucoDetector`
//! does in outline: the image thresholded against its local mean at a few window sizes, each
//! dark blob whose outline is a quadrilateral taken as a candidate, its cells sampled through
//! the quadrilateral's homography, its border checked and its bits matched against the
//! dictionary in each of the four turns, with the dictionary's error correction.

use nalgebra::{Matrix3, Vector3};

use super::Dictionary;
use crate::calibration::boards::corners::Luma;
use crate::calibration::boards::zhang::homography;

/// A marker found in an image: its id and its corners in the image, in the marker's own
/// order (clockwise from its top-left, as OpenCV gives them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Marker {
    pub id: usize,
    pub corners: [[f64; 2]; 4],
}

/// How much darker than its neighbourhood's mean a pixel must be to count as dark (grey
/// levels; OpenCV's `adaptiveThreshConstant` is 7).
const DARKER_BY: f32 = 7.0;
/// The smallest marker side, in pixels, worth reading: below it a cell is under two pixels.
const MIN_SIDE: f64 = 10.0;
/// The share of a marker's border cells that may read white (OpenCV's
/// `maxErroneousBitsInBorderRate` is 0.35; a stricter share keeps out chessboard squares).
const BORDER_ERRORS: f64 = 0.2;
/// The least difference between the darkest and the lightest cell, in grey levels.
const MIN_CONTRAST: f64 = 20.0;

/// Every marker of `dictionary` in `image` whose id is below `ids` (the board's markers), at
/// most one per id: an id read in two places is left out, since a board has each once.
pub fn find_markers(image: &Luma, dictionary: Dictionary, ids: usize) -> Vec<Marker> {
    let (w, h) = (image.width, image.height);
    if w < 16 || h < 16 {
        return Vec::new();
    }
    let integral = Integral::of(image);
    let mut found: Vec<Marker> = Vec::new();
    let longest = w.max(h);
    // Windows from small markers to large ones: a marker's border is found by a window
    // about as wide as a few of its cells.
    let mut windows = vec![3usize, 7, 15];
    if longest > 1000 {
        windows.push(31);
    }
    for half in windows {
        let dark = integral.dark(image, half);
        for quad in quads(&dark, w, h) {
            if let Some(marker) = read(image, &quad, dictionary, ids) {
                found.push(marker);
            }
        }
    }
    // One per id: the same marker found at several windows is kept once; an id found in two
    // places is dropped.
    let mut kept: Vec<Marker> = Vec::new();
    let mut twice: Vec<usize> = Vec::new();
    for m in found {
        match kept.iter().find(|k| k.id == m.id) {
            Some(k) => {
                let apart = (0..4)
                    .map(|i| {
                        (k.corners[i][0] - m.corners[i][0]).hypot(k.corners[i][1] - m.corners[i][1])
                    })
                    .fold(0.0, f64::max);
                if apart > 3.0 {
                    twice.push(m.id);
                }
            }
            None => kept.push(m),
        }
    }
    kept.retain(|k| !twice.contains(&k.id));
    kept.sort_by_key(|k| k.id);
    kept
}

/// Sums of the image over rectangles in constant time.
struct Integral {
    width: usize,
    sums: Vec<f64>,
}

impl Integral {
    fn of(image: &Luma) -> Integral {
        let (w, h) = (image.width, image.height);
        let mut sums = vec![0.0; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = 0.0;
            for x in 0..w {
                row += f64::from(image.data[y * w + x]);
                sums[(y + 1) * (w + 1) + x + 1] = sums[y * (w + 1) + x + 1] + row;
            }
        }
        Integral { width: w, sums }
    }

    /// Each pixel darker than the mean of the (2·half + 1)² window around it (clipped at the
    /// image's edges) by [`DARKER_BY`].
    fn dark(&self, image: &Luma, half: usize) -> Vec<bool> {
        let (w, h) = (image.width, image.height);
        let stride = self.width + 1;
        let mut dark = vec![false; w * h];
        for y in 0..h {
            let (y0, y1) = (y.saturating_sub(half), (y + half + 1).min(h));
            for x in 0..w {
                let (x0, x1) = (x.saturating_sub(half), (x + half + 1).min(w));
                let sum = self.sums[y1 * stride + x1]
                    - self.sums[y0 * stride + x1]
                    - self.sums[y1 * stride + x0]
                    + self.sums[y0 * stride + x0];
                // Darker than the mean, without dividing: value + DARKER_BY < sum / area.
                let area = ((y1 - y0) * (x1 - x0)) as f64;
                dark[y * w + x] = f64::from(image.data[y * w + x] + DARKER_BY) * area < sum;
            }
        }
        dark
    }
}

/// The dark blobs (4-connected) whose outline is a convex quadrilateral of sides at least
/// [`MIN_SIDE`]: each quad's corners clockwise in the image (y down).
fn quads(dark: &[bool], w: usize, h: usize) -> Vec<[[f64; 2]; 4]> {
    let mut label = vec![u32::MAX; w * h];
    let mut quads = Vec::new();
    let mut stack = Vec::new();
    let mut rows: Vec<(usize, usize)> = Vec::new();
    let mut next = 0u32;
    let too_big = 0.9 * w.max(h) as f64;
    for start in 0..w * h {
        if !dark[start] || label[start] != u32::MAX {
            continue;
        }
        // Flood the blob, keeping each row's leftmost and rightmost pixel. The scan meets a
        // blob first at its top row, so its rows are counted from there.
        let top = start / w;
        let (mut lo_y, mut hi_y) = (usize::MAX, 0);
        rows.clear();
        label[start] = next;
        stack.push(start);
        let mut count = 0usize;
        while let Some(i) = stack.pop() {
            count += 1;
            let (x, y) = (i % w, i / w);
            lo_y = lo_y.min(y);
            hi_y = hi_y.max(y);
            let r = y - top;
            if r >= rows.len() {
                rows.resize(r + 1, (usize::MAX, 0));
            }
            let e = &mut rows[r];
            e.0 = e.0.min(x);
            e.1 = e.1.max(x);
            for j in crate::grid::four_neighbours(i, w, h) {
                if dark[j] && label[j] == u32::MAX {
                    label[j] = next;
                    stack.push(j);
                }
            }
        }
        next += 1;
        let height = (hi_y - lo_y + 1) as f64;
        let width = rows.iter().map(|s| s.1).max().unwrap_or(0) as f64
            - rows.iter().map(|s| s.0).min().unwrap_or(0) as f64
            + 1.0;
        if (count as f64) < MIN_SIDE * 2.0
            || height.max(width) < MIN_SIDE
            || height.max(width) > too_big
        {
            continue;
        }
        let spans: Vec<(usize, usize, usize)> = rows
            .iter()
            .enumerate()
            .map(|(r, &(a, b))| (top + r, a, b))
            .collect();
        if let Some(q) = quad_of(&spans) {
            quads.push(q);
        }
    }
    quads
}

/// The quadrilateral a blob's row spans outline, or `None` when the outline is not one: the
/// convex hull of the spans' ends, its four corners the farthest points, and the blob (holes
/// filled) covering the quadrilateral to within 12 % and every hull point near an edge.
fn quad_of(spans: &[(usize, usize, usize)]) -> Option<[[f64; 2]; 4]> {
    // Pixel edges, not centres: a blob of pixels x0..=x1 spans x0 − ½ to x1 + ½.
    let mut points: Vec<[f64; 2]> = Vec::with_capacity(4 * spans.len());
    for &(y, a, b) in spans {
        let (y, a, b) = (y as f64, a as f64, b as f64);
        points.extend([
            [a - 0.5, y - 0.5],
            [a - 0.5, y + 0.5],
            [b + 0.5, y - 0.5],
            [b + 0.5, y + 0.5],
        ]);
    }
    let hull = convex_hull(points);
    if hull.len() < 4 {
        return None;
    }
    let n = hull.len() as f64;
    let centre = [
        hull.iter().map(|p| p[0]).sum::<f64>() / n,
        hull.iter().map(|p| p[1]).sum::<f64>() / n,
    ];
    let dist = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    let farthest = |from: [f64; 2]| {
        hull.iter()
            .copied()
            .max_by(|a, b| dist(*a, from).total_cmp(&dist(*b, from)))
    };
    let p0 = farthest(centre)?;
    let p2 = farthest(p0)?;
    // Signed distance from the diagonal p0–p2: the farthest on each side.
    let side = |p: [f64; 2]| (p2[0] - p0[0]) * (p[1] - p0[1]) - (p2[1] - p0[1]) * (p[0] - p0[0]);
    // Clockwise in the image (y down) is a negative turn from the diagonal p0–p2.
    let p1 = hull
        .iter()
        .copied()
        .min_by(|a, b| side(*a).total_cmp(&side(*b)))?;
    let p3 = hull
        .iter()
        .copied()
        .max_by(|a, b| side(*a).total_cmp(&side(*b)))?;
    if side(p1) >= 0.0 || side(p3) <= 0.0 {
        return None;
    }
    let quad = [p0, p1, p2, p3];
    let sides: Vec<f64> = (0..4).map(|i| dist(quad[i], quad[(i + 1) % 4])).collect();
    let shortest = sides.iter().copied().fold(f64::INFINITY, f64::min);
    let longest = sides.iter().copied().fold(0.0, f64::max);
    if shortest < MIN_SIDE || longest > 4.0 * shortest {
        return None;
    }
    let area_of = |poly: &[[f64; 2]]| {
        let m = poly.len();
        (0..m)
            .map(|i| {
                let (a, b) = (poly[i], poly[(i + 1) % m]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum::<f64>()
            .abs()
            / 2.0
    };
    let quad_area = area_of(&quad);
    let filled: f64 = spans.iter().map(|s| (s.2 - s.1 + 1) as f64).sum();
    let perimeter: f64 = sides.iter().sum();
    // The hull runs round the pixels' staircase, outside the corners' quadrilateral by up to
    // about half a pixel along each side.
    if (filled / quad_area - 1.0).abs() > 0.12
        || area_of(&hull) - quad_area > 0.05 * quad_area + 0.75 * perimeter
    {
        return None;
    }
    // Every hull point near one of the four edges.
    let tolerance = (0.03 * perimeter).max(1.5);
    let near_edge = |p: &[f64; 2]| {
        (0..4).any(|i| {
            let (a, b) = (quad[i], quad[(i + 1) % 4]);
            let l = dist(a, b);
            ((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])).abs() / l <= tolerance
        })
    };
    hull.iter().all(near_edge).then_some(quad)
}

/// The convex hull (Andrew's monotone chain), counter-clockwise in x-right y-up terms,
/// without collinear points: a marker's quad here, a live view's outline in
/// [`crate::pipeline::calibrate::sight`].
pub fn convex_hull(mut points: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    points.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(points.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(points.iter())
        } else {
            Box::new(points.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// The marker `quad` shows, if it is one of the dictionary's: for each of the four corners
/// taken as the marker's top-left, its cells sampled, the border checked, and the bits matched
/// within the dictionary's correction. The id of the closest match, with the corners in the
/// marker's order.
fn read(image: &Luma, quad: &[[f64; 2]; 4], dictionary: Dictionary, ids: usize) -> Option<Marker> {
    let bits = dictionary.bits();
    let cells = bits + 2;
    let c = cells as f64;
    let h = homography(&[[0.0, 0.0], [c, 0.0], [c, c], [0.0, c]], quad)?;
    let values = cell_means(image, &h, cells)?;
    let lo = values.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if hi - lo < MIN_CONTRAST {
        return None;
    }
    let threshold = (lo + hi) / 2.0;
    let white = |r: usize, col: usize| values[r * cells + col] >= threshold;
    let border: Vec<bool> = (0..cells)
        .flat_map(|r| (0..cells).map(move |col| (r, col)))
        .filter(|&(r, col)| r == 0 || col == 0 || r == cells - 1 || col == cells - 1)
        .map(|(r, col)| white(r, col))
        .collect();
    let wrong = border.iter().filter(|&&b| b).count();
    if wrong as f64 > BORDER_ERRORS * border.len() as f64 {
        return None;
    }
    let codes = &dictionary.codes()[..ids.min(dictionary.codes().len())];
    let mut best: Option<(u32, usize, usize)> = None; // (distance, id, turn)
    for turn in 0..4 {
        // The marker's bit (r, col) seen with quad corner `turn` as its top-left.
        let mut code = 0u64;
        for r in 0..bits {
            for col in 0..bits {
                let (qr, qc) = match turn {
                    0 => (r, col),
                    1 => (col, bits - 1 - r),
                    2 => (bits - 1 - r, bits - 1 - col),
                    _ => (bits - 1 - col, r),
                };
                code = (code << 1) | u64::from(white(qr + 1, qc + 1));
            }
        }
        for (id, &known) in codes.iter().enumerate() {
            let d = (code ^ known).count_ones();
            if best.is_none_or(|b| d < b.0) {
                best = Some((d, id, turn));
            }
        }
    }
    let (distance, id, turn) = best?;
    (distance <= dictionary.correction()).then(|| Marker {
        id,
        corners: [
            quad[turn],
            quad[(turn + 1) % 4],
            quad[(turn + 2) % 4],
            quad[(turn + 3) % 4],
        ],
    })
}

/// The mean grey level of each of the `cells`² cells, sampled on a 4 × 4 grid over the middle
/// half of each cell (away from the blur of its neighbours) through the homography `h`.
fn cell_means(image: &Luma, h: &Matrix3<f64>, cells: usize) -> Option<Vec<f64>> {
    let mut values = Vec::with_capacity(cells * cells);
    for r in 0..cells {
        for col in 0..cells {
            let mut sum = 0.0;
            for sy in 0..4 {
                for sx in 0..4 {
                    let u = col as f64 + 0.25 + 0.5 * (sx as f64 + 0.5) / 4.0;
                    let v = r as f64 + 0.25 + 0.5 * (sy as f64 + 0.5) / 4.0;
                    let p = h * Vector3::new(u, v, 1.0);
                    sum += bilinear(image, p.x / p.z, p.y / p.z)?;
                }
            }
            values.push(sum / 16.0);
        }
    }
    Some(values)
}

/// The image at (x, y) by bilinear interpolation of the pixel centres, `None` outside.
fn bilinear(image: &Luma, x: f64, y: f64) -> Option<f64> {
    if !(x >= 0.0 && y >= 0.0) {
        return None;
    }
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    if x0 + 1 >= image.width || y0 + 1 >= image.height {
        return None;
    }
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let at = |xx: usize, yy: usize| f64::from(image.data[yy * image.width + xx]);
    Some(
        (1.0 - fy) * ((1.0 - fx) * at(x0, y0) + fx * at(x0 + 1, y0))
            + fy * ((1.0 - fx) * at(x0, y0 + 1) + fx * at(x0 + 1, y0 + 1)),
    )
}
