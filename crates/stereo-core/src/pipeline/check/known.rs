//! Known distances, what rows cannot give: a board's corners (the board's pose from the left
//! camera alone, its squares' size known) or points of the left image given with their true
//! distance. Each is a point in the left camera's frame and the raw right pixel that sees it,
//! which the fit reads beside the rows ([`super::model::Observed::Known`]), and whose distance
//! measured through a calibration's rectification is compared with the truth, before the
//! correction and after.

use nalgebra::Vector3;

use crate::calibration::boards::corners::Luma;
use crate::calibration::boards::{Seen, Target, board_pose};
use crate::calibration::files::Raw;
use crate::camera::Camera;
use crate::physics::LengthUnit;
use crate::vision::Gray;
use crate::vision::sparse::match_points;

/// A point of a pair's raw left image with its true distance (along the left camera's
/// optical axis), in the calibration's unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KnownPoint {
    /// The pair it is in, from 0.
    pub pair: usize,
    pub x: f64,
    pub y: f64,
    pub distance: f64,
}

/// What the check is told besides the frames: a board the pairs may show, and points with
/// their distance.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Known {
    pub board: Option<Target>,
    pub points: Vec<KnownPoint>,
}

impl Known {
    pub fn is_empty(&self) -> bool {
        self.board.is_none() && self.points.is_empty()
    }
}

/// A point in the left camera's frame (the calibration's unit) and the raw pixels that see
/// it in each camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Located {
    pub point: Vector3<f64>,
    pub left_raw: [f64; 2],
    pub right_raw: [f64; 2],
}

/// The board's corners that both raw frames show, placed in the left camera's frame by the
/// board's pose from the left corners alone ([`board_pose`]: the homography of the
/// undistorted corners, then their reprojection refined). `to_unit` converts the board's unit into the
/// calibration's. Empty when either camera does not find the board.
pub fn board_corners(
    target: &Target,
    left: &Gray,
    right: &Gray,
    camera: &Camera,
    to_unit: f64,
) -> Vec<Located> {
    let find = |g: &Gray| {
        target
            .find(&Luma::from_u16(g.width, g.height, &g.data))
            .ok()
    };
    let (Some(l), Some(r)) = rayon::join(|| find(left), || find(right)) else {
        return Vec::new();
    };
    // Each corner both cameras show: its place on the board (in the calibration's unit),
    // and its pixel in each camera.
    struct Both {
        object: Vector3<f64>,
        left: [f64; 2],
        right: [f64; 2],
    }
    let objects = target.object_points();
    let both: Vec<Both> = objects
        .iter()
        .zip(l.iter().zip(&r))
        .filter_map(|(o, (pl, pr))| {
            let (left, right) = ((*pl)?, (*pr)?);
            Some(Both {
                object: *o * to_unit,
                left,
                right,
            })
        })
        .collect();
    if both.len() < 6 {
        return Vec::new();
    }
    let objects: Vec<Vector3<f64>> = both.iter().map(|b| b.object).collect();
    let seen: Seen = both.iter().map(|b| Some(b.left)).collect();
    let Some(pose) = board_pose(camera, &objects, &seen) else {
        return Vec::new();
    };
    both.iter()
        .map(|b| Located {
            point: pose.apply(&b.object),
            left_raw: b.left,
            right_raw: b.right,
        })
        .collect()
}

/// The `points` of one pair matched in its rectified frames (`left`, `right`, rectified with
/// `raw`'s rectification) over disparities `range`: each placed at its distance along its
/// raw left ray, with the raw right pixel its match comes from. Points that do not match are
/// left out.
pub fn distance_points(
    points: &[KnownPoint],
    raw: &Raw,
    (left, right): (&Gray, &Gray),
    range: (i32, i32),
    raw_of: impl Fn([f64; 2]) -> Option<[f64; 2]>,
) -> Vec<Located> {
    let r = &raw.rectification;
    let k1 = r.p1.fixed_view::<3, 3>(0, 0).into_owned();
    // Each point's exact place in the rectified left image, and the whole pixel matched.
    type Placed = Option<([f64; 2], (usize, usize))>;
    let placed: Vec<Placed> = points
        .iter()
        .map(|p| {
            let at = raw.pair.left.undistort_to([p.x, p.y], &r.r1, &k1)?;
            let (x, y) = (at[0].round(), at[1].round());
            (x >= 0.0 && y >= 0.0).then_some((at, (x as usize, y as usize)))
        })
        .collect();
    let wanted: Vec<(usize, usize)> = placed.iter().flatten().map(|p| p.1).collect();
    let mut matched = match_points(left, right, &wanted, range).into_iter();
    points
        .iter()
        .zip(&placed)
        .filter_map(|(p, placed)| {
            let (at, _) = placed.as_ref()?;
            let m = matched.next()??;
            let [xn, yn] = raw.pair.left.normalize([p.x, p.y])?;
            // The match is the whole pixel's: moved by the point's fraction of a pixel, as
            // the disparity hardly changes within one.
            let right = [
                m.right[0] + at[0] - m.left[0],
                m.right[1] + at[1] - m.left[1],
            ];
            Some(Located {
                point: Vector3::new(xn, yn, 1.0) * p.distance,
                left_raw: [p.x, p.y],
                right_raw: raw_of(right)?,
            })
        })
        .collect()
}

/// A known point's distance as a calibration measures it (through its rectification: the
/// disparity of the two raw pixels rectified, made a depth by its rectified rig) less the
/// truth (the point's depth in the rectified left camera); `None` where it cannot be
/// rectified.
pub fn distance_error(raw: &Raw, unit: LengthUnit, k: &Located) -> Option<(f64, f64)> {
    let r = &raw.rectification;
    let rig = r.rig(unit).ok()?;
    let k1 = r.p1.fixed_view::<3, 3>(0, 0).into_owned();
    let k2 = r.p2.fixed_view::<3, 3>(0, 0).into_owned();
    let l = raw.pair.left.undistort_to(k.left_raw, &r.r1, &k1)?;
    let rr = raw.pair.right.undistort_to(k.right_raw, &r.r2, &k2)?;
    let measured = rig.distance_at(l[0] - rr[0]).ok()?;
    let truth = (r.r1 * k.point).z;
    Some((measured - truth, truth))
}
