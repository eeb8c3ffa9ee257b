//! Depths in latitude-longitude (`projection=latlon`): a disparity is an angle, and each
//! pixel's range follows from mrcal's `stereo_range`; its depth is the range's component along
//! the rectified axis, and its σ the range's σ through the angle's.

use crate::camera::Latlon;
use crate::physics::Rig;
use crate::vision::Disparity;

/// The depth of each pixel of a latitude-longitude map: the range along its ray from the left
/// camera ([`Latlon::range`], mrcal's `stereo_range`) times cos(az)·cos(el), its component
/// along the rectified axis; NaN where the disparity is invalid or not positive.
pub fn latlon_depths(map: &Disparity, latlon: &Latlon) -> Vec<f32> {
    let width = map.width.max(1);
    map.data
        .iter()
        .enumerate()
        .map(|(i, &d)| {
            let (x, y) = ((i % width) as f64, (i / width) as f64);
            match latlon.range(x, f64::from(d)) {
                Some(r) => (r * along_axis(latlon, x, y)) as f32,
                None => f32::NAN,
            }
        })
        .collect()
}

/// cos(az)·cos(el) of a latitude-longitude pixel: a range's share along the rectified axis.
pub(crate) fn along_axis(latlon: &Latlon, x: f64, y: f64) -> f64 {
    ((x - latlon.cx) / latlon.fx).cos() * ((y - latlon.cy) / latlon.fy).cos()
}

/// σ_Z of each latitude-longitude depth: the range's σ from the disparity's (an angle
/// σ_d/f_x: σ_r = B·|cos az|·σ_d / (f_x·sin²(d/f_x)), the derivative of mrcal's range),
/// along the axis as the depth is, with the rig's σ_f and σ_B terms as a pinhole depth's.
pub fn latlon_depth_stds(map: &Disparity, depth: &[f32], latlon: &Latlon, rig: Rig) -> Vec<f32> {
    let width = map.width.max(1);
    depth
        .iter()
        .zip(&map.std)
        .zip(&map.data)
        .enumerate()
        .map(|(i, ((&z, &s), &d))| {
            if z.is_nan() || s.is_nan() {
                return f32::NAN;
            }
            let (x, y) = ((i % width) as f64, (i / width) as f64);
            let angle = f64::from(d) / latlon.fx;
            let az = (x - latlon.cx) / latlon.fx;
            let sigma_r =
                latlon.baseline * az.cos().abs() * f64::from(s) / (latlon.fx * angle.sin().powi(2));
            let mut terms = rig.depth_error_terms_with(f64::from(z), f64::from(s));
            terms.disparity = sigma_r * along_axis(latlon, x, y);
            terms.total() as f32
        })
        .collect()
}
