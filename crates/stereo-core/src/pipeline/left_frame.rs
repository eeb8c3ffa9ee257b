//! A depth map in the left camera's own pixels (`left_depth.npy`): each raw left pixel's ray
//! followed into the rectified map (pinhole or latitude-longitude), the range found there, and
//! the depth along the left camera's own optical axis.

use rayon::prelude::*;

use super::depth::DepthMap;
use super::latlon::along_axis;

/// The depths at the raw left frame's pixels, row-major, with its width and height: for each
/// pixel, its ray (the left camera's lens model) is taken into the rectified image, the range
/// of the nearest rectified pixel's depth is laid along the ray, and the depth is that range's
/// component along the left camera's optical axis. NaN where the lens cannot take the ray
/// there, where the rectified image does not reach, where the map has no depth, and where
/// the point is not in front of the camera. A pair sent as rectified is its own left frame:
/// its depths as they are. `None` without depths (no rig).
pub fn left_depths(map: &DepthMap) -> Option<(usize, usize, Vec<f32>)> {
    let depth = map.depth.as_deref()?;
    let (mw, mh) = (map.disparity.width, map.disparity.height);
    let Some(raw) = &map.raw else {
        return Some((mw, mh, depth.to_vec()));
    };
    let (w, h) = (raw.size.width as usize, raw.size.height as usize);
    let p1 = &raw.rectification.p1;
    let (fx, fy, cx, cy) = (p1[(0, 0)], p1[(1, 1)], p1[(0, 2)], p1[(1, 2)]);
    let at = |x: usize, y: usize| -> f32 {
        let Some(ray) = raw.pair.left.ray_of_pixel([x as f64, y as f64]) else {
            return f32::NAN;
        };
        let ray = ray.normalize();
        // The rectified pixel the ray lands on, and the share of its range its depth is.
        let landed = match &map.latlon {
            Some(l) => {
                let [u, v] = l.pixel(&(l.r1 * ray));
                Some((u, v))
            }
            None => {
                let r = raw.rectification.r1 * ray;
                (r.z > f64::EPSILON).then(|| (fx * r.x / r.z + cx, fy * r.y / r.z + cy))
            }
        };
        let Some((u, v)) = landed else {
            return f32::NAN;
        };
        let (u, v) = ((u + 0.5).floor(), (v + 0.5).floor());
        if !(u >= 0.0 && v >= 0.0 && u < mw as f64 && v < mh as f64) || ray.z <= 0.0 {
            return f32::NAN;
        }
        let z = f64::from(depth[v as usize * mw + u as usize]);
        let share = match &map.latlon {
            Some(l) => along_axis(l, u, v),
            None => 1.0 / ((u - cx) / fx).hypot((v - cy) / fy).hypot(1.0),
        };
        (z / share * ray.z) as f32
    };
    let mut out = vec![f32::NAN; w * h];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, value) in row.iter_mut().enumerate() {
                *value = at(x, y);
            }
        });
    Some((w, h, out))
}
