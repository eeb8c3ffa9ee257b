//! Depths in latitude-longitude (`projection=latlon`): a disparity is an angle, and each
//! pixel's range follows from mrcal's `stereo_range`; its depth is the range's component along
//! the rectified axis, and its σ the range's σ through the angle's.

use crate::camera::Latlon;
use crate::physics::{
    DepthErrorTerms, Implausible, LARGE_RELATIVE_ERROR, Measurement, PhysicsError, Point3, Rig,
    Warning, finite,
};
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
            latlon_depth(latlon, (x, y), f64::from(d)).map_or(f32::NAN, |z| z as f32)
        })
        .collect()
}

/// The depth of disparity `d` at latitude-longitude pixel `(x, y)`: the range along its ray
/// ([`Latlon::range`]) times cos(az)·cos(el); `None` where the disparity is not positive.
pub fn latlon_depth(latlon: &Latlon, (x, y): (f64, f64), d: f64) -> Option<f64> {
    latlon.range(x, d).map(|r| r * along_axis(latlon, x, y))
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
            depth_error_terms(
                latlon,
                &rig,
                (x, y),
                (f64::from(d), f64::from(s)),
                f64::from(z),
            )
            .total() as f32
        })
        .collect()
}

/// The terms of σ_Z of the latitude-longitude depth `z` at `(x, y)` with disparity `d` and
/// its σ `s`: the range's σ from the angle's (σ_r = B·|cos az|·s / (f_x·sin²(d/f_x)), the
/// derivative of mrcal's range) along the axis as the depth is, and the rig's σ_f and σ_B
/// terms as a pinhole depth's.
fn depth_error_terms(
    latlon: &Latlon,
    rig: &Rig,
    (x, y): (f64, f64),
    (d, s): (f64, f64),
    z: f64,
) -> DepthErrorTerms {
    let angle = d / latlon.fx;
    let az = (x - latlon.cx) / latlon.fx;
    let sigma_r = latlon.baseline * az.cos().abs() * s / (latlon.fx * angle.sin().powi(2));
    let mut terms = rig.depth_error_terms_with(z, s);
    terms.disparity = sigma_r * along_axis(latlon, x, y);
    terms
}

/// `/distance`'s measurement of a match in latitude-longitude: left pixel `(x, y)`, disparity
/// `d` (its σ the `rig`'s Δd, the rig the latlon pair's at its centre). The range is mrcal's
/// along the pixel's ray ([`Latlon::range`]), the point on that ray in the rectified frame,
/// the distance its component along the rectified axis (as the map's depths), σ_Z as
/// [`latlon_depth_stds`]. A disparity that is not positive has no range: at infinity.
pub fn latlon_measure(
    latlon: &Latlon,
    rig: &Rig,
    (x, y): (f64, f64),
    d: f64,
) -> Result<Measurement, PhysicsError> {
    let range = latlon.range(x, d).ok_or(PhysicsError::AtInfinity)?;
    let ray = latlon.ray([x, y]);
    let distance = finite(range * along_axis(latlon, x, y))?;
    let depth_error_terms =
        depth_error_terms(latlon, rig, (x, y), (d, rig.disparity_error_px()), distance);
    let depth_error = finite(depth_error_terms.total())?;
    let relative_error = finite(depth_error / distance)?;
    let mut warnings = Vec::new();
    if relative_error > LARGE_RELATIVE_ERROR {
        warnings.push(Warning::LargeRelativeError { relative_error });
    }
    if let Some(implausible) = Implausible::baseline(rig.baseline(), rig.unit()) {
        warnings.push(Warning::ImplausibleBaseline(implausible));
    }
    Ok(Measurement {
        disparity_px: d,
        effective_disparity_px: d,
        distance,
        range: Some(range),
        distance_m: finite(distance * rig.unit().metres())?,
        depth_error,
        depth_error_terms,
        relative_error,
        normalized_x: Some(finite(ray.x / ray.z)?),
        projection_factor: finite(rig.projection_factor())?,
        point: Some(Point3 {
            x: range * ray.x,
            y: range * ray.y,
            z: distance,
        }),
        warnings,
    })
}
