//! One image's board, found for a live view: the corners by their ids on the board and the
//! outline they span, or why the board was not found. A camera held at a board is judged
//! frame by frame with it before a view is kept for a calibration.

use crate::calibration::boards::Target;
use crate::calibration::boards::charuco::markers::convex_hull;
use crate::calibration::boards::corners::Luma;
use crate::vision::decode::{self, DecodeError, DecodeLimits};

/// What one image shows of a board.
#[derive(Debug, Clone, PartialEq)]
pub struct Sighting {
    /// The image's width and height, in pixels.
    pub size: (u32, u32),
    /// Each corner found: its id on the board (OpenCV's order: row by row of inner corners,
    /// or a ChArUco board's corner ids) and its position in pixels.
    pub corners: Vec<(usize, [f64; 2])>,
    /// The convex hull of the corners found, in order around it: the part of the image the
    /// view covers.
    pub outline: Vec<[f64; 2]>,
    /// Why the board was not found (then `corners` is empty).
    pub miss: Option<String>,
    /// What the decoder forgave, in a sentence about the file.
    pub note: Option<String>,
}

impl Sighting {
    /// Whether the board was found.
    pub fn found(&self) -> bool {
        self.miss.is_none()
    }
}

/// Decodes `bytes` (PNG or JPEG) within `limits` and finds `board` in it, as a calibration
/// finds each view's.
pub fn sight(bytes: &[u8], board: &Target, limits: DecodeLimits) -> Result<Sighting, DecodeError> {
    let decoded = decode::decode(bytes, limits, false)?;
    let grey = decoded.grey;
    let luma = Luma::from_u16(grey.width, grey.height, &grey.data);
    let (corners, miss): (Vec<(usize, [f64; 2])>, _) = match board.find(&luma) {
        Ok(seen) => (
            seen.iter()
                .enumerate()
                .filter_map(|(id, c)| c.map(|p| (id, p)))
                .collect(),
            None,
        ),
        Err(miss) => (Vec::new(), Some(miss.to_string())),
    };
    let outline = convex_hull(corners.iter().map(|&(_, p)| p).collect());
    Ok(Sighting {
        size: (grey.width as u32, grey.height as u32),
        corners,
        outline,
        miss,
        note: decoded.note,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::boards::Board;
    use crate::calibration::boards::synthetic::{Style, poses, sample_rig, stereo_views};
    use crate::camera::Size;
    use crate::physics::LengthUnit;
    use crate::vision::encode;

    /// The hull of a grid is its four corners; inner and collinear points are left out.
    #[test]
    fn the_hull_of_a_grid_is_its_corners() {
        let grid: Vec<[f64; 2]> = (0..4)
            .flat_map(|y| (0..5).map(move |x| [f64::from(x), f64::from(y)]))
            .collect();
        let hull = convex_hull(grid);
        assert_eq!(hull, [[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]]);
        assert_eq!(convex_hull(vec![[1.0, 1.0], [1.0, 1.0]]), [[1.0, 1.0]]);
    }

    /// A rendered board's every corner is found within 0.25 px of where the lens put it, its
    /// outline is the four outer inner-corners; an image with no board says why.
    #[test]
    fn a_rendered_board_is_sighted_and_a_blank_one_is_not() {
        let (rig, size) = (
            sample_rig(),
            Size {
                width: 640,
                height: 480,
            },
        );
        let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).unwrap();
        let view = &stereo_views(
            &rig,
            size,
            &board,
            &poses(&rig, size, &board, 1, 30.0, 3),
            &Style::default(),
        )[0];
        let png = encode::png_grey(640, 480, &view.left.pixels);
        let limits = DecodeLimits {
            max_side: 8192,
            max_pixels: 1 << 25,
        };
        let seen = sight(&png, &Target::Chessboard(board), limits).unwrap();
        assert!(seen.found());
        assert_eq!(seen.size, (640, 480));
        assert_eq!(seen.corners.len(), 54);
        for &(id, [x, y]) in &seen.corners {
            let [tx, ty] = view.left_corners[id];
            assert!(
                (x - tx).hypot(y - ty) < 0.25,
                "corner {id}: ({x}, {y}) against ({tx}, {ty})"
            );
        }
        // The lens bends the board's edges: more than four points, the four outer corners
        // among them, and every corner inside or on it.
        for id in [0, 8, 45, 53] {
            let p = seen.corners[id].1;
            assert!(seen.outline.contains(&p), "corner {id} on the outline");
        }
        let o = &seen.outline;
        for &(id, p) in &seen.corners {
            for (i, &a) in o.iter().enumerate() {
                let b = o[(i + 1) % o.len()];
                let cross = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
                assert!(cross >= -1e-9, "corner {id} outside the outline");
            }
        }
        let blank = encode::png_grey(640, 480, &vec![128; 640 * 480]);
        let none = sight(&blank, &Target::Chessboard(board), limits).unwrap();
        assert!(!none.found() && none.corners.is_empty() && none.outline.is_empty());
        assert!(none.miss.is_some());
        assert!(sight(b"not an image", &Target::Chessboard(board), limits).is_err());
    }
}
