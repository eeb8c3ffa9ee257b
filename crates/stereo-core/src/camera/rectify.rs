//! Bouguet's rectification as OpenCV's `stereoRectify` computes it: the rotations R1, R2 that
//! make both cameras look the same way with the baseline along x (or y), the new camera
//! matrices P1, P2 and the reprojection matrix Q, scaled by `alpha` between only valid pixels
//! (0) and every source pixel (1), with the valid regions of interest. The rectified rig that
//! `/distance` takes comes from it ([`Rectification::rig`]); the maps that rectify images are
//! built from R and P by whoever remaps. The types it works with are in
//! [`super::rectification`].

use nalgebra::{Matrix3, Matrix3x4, Rotation3, Vector3};

use super::distortion::Model;
use super::pinhole::Camera;
use super::rectification::{
    Rectangles, Rectification, RectifyFault, RectifyOptions, Roi, Side, Size, StereoPair,
    rectangles,
};

/// Rectifies a stereo pair whose raw images are `size` as OpenCV does: `stereoRectify` for
/// the Brown models, `fisheye::stereoRectify` (with `alpha` as its `balance`) when both
/// cameras are equidistant. Raw pixels are undistorted as OpenCV's `undistortPoints` does
/// with its default criteria, so that R1 R2 P1 P2 Q equal OpenCV's to about 1e-8; the
/// fisheye ROIs, which OpenCV does not give, come from the same grid as the others.
pub fn stereo_rectify(
    pair: &StereoPair,
    size: Size,
    options: RectifyOptions,
) -> Result<Rectification, RectifyFault> {
    if size.width == 0 || size.height == 0 {
        return Err(RectifyFault::Size);
    }
    let new_size = options.new_size.unwrap_or(size);
    if new_size.width == 0 || new_size.height == 0 {
        return Err(RectifyFault::Size);
    }
    let t_norm = pair.translation.norm();
    if !(t_norm.is_finite() && t_norm > 0.0) {
        return Err(RectifyFault::NoBaseline);
    }
    // Rotate each camera half way, so that both look the same way.
    let half = Rotation3::from_scaled_axis(pair.rotation.scaled_axis() * -0.5);
    let r_r = *half.matrix();
    let t = r_r * pair.translation;
    let fisheye = pair.left.distortion().model() == Model::Equidistant
        && pair.right.distortion().model() == Model::Equidistant;
    // OpenCV's fisheye rectification is horizontal only.
    let idx = if fisheye || t.x.abs() > t.y.abs() {
        0
    } else {
        1
    };
    let c = t[idx];
    let mut uu = Vector3::zeros();
    uu[idx] = if c > 0.0 { 1.0 } else { -1.0 };
    // Then turn both about the axis that brings the baseline onto x (or y).
    let mut ww = t.cross(&uu);
    let nw = ww.norm();
    if nw > 0.0 {
        ww *= (c.abs() / t.norm()).clamp(-1.0, 1.0).acos() / nw;
    }
    let w_r = *Rotation3::from_scaled_axis(ww).matrix();
    let r1 = w_r * r_r.transpose();
    let r2 = w_r * r_r;
    let t = r2 * pair.translation;
    if fisheye {
        return fisheye_projections(pair, size, new_size, options, [r1, r2], t);
    }

    let (nx, ny) = (f64::from(size.width), f64::from(size.height));
    let ratio = if idx == 1 {
        f64::from(new_size.width) / nx / 2.0
    } else {
        f64::from(new_size.height) / ny / 2.0
    };
    let focal = |camera: &Camera| {
        let k = camera.intrinsics();
        if idx == 1 { k.fx } else { k.fy }
    };
    let mut fc_new = (focal(&pair.left) + focal(&pair.right)) * ratio;

    // Each rectified principal point centres the image's corners.
    let mut cc_new = [[0.0; 2]; 2];
    for (k, (camera, rotation, side)) in [
        (&pair.left, &r1, Side::Left),
        (&pair.right, &r2, Side::Right),
    ]
    .into_iter()
    .enumerate()
    {
        let (mut sum, mut count) = ([0.0; 2], 0.0);
        // Image corners the distortion cannot invert are left out of the mean (see
        // `rectangles`); a pair of opposite ones keeps the centre.
        for corner in [
            [0.0, 0.0],
            [nx - 1.0, ny - 1.0],
            [nx - 1.0, 0.0],
            [0.0, ny - 1.0],
        ] {
            let Some([x, y]) = camera.normalize_as_opencv(corner) else {
                continue;
            };
            count += 1.0;
            let ray = rotation * Vector3::new(x, y, 1.0);
            if ray.z.abs() <= f64::EPSILON {
                return Err(RectifyFault::Degenerate);
            }
            // OpenCV projects these corners into single-precision points.
            sum[0] += f64::from((fc_new * ray.x / ray.z) as f32);
            sum[1] += f64::from((fc_new * ray.y / ray.z) as f32);
        }
        if count == 0.0 {
            return Err(RectifyFault::NotInvertible(side));
        }
        cc_new[k] = [
            (nx - 1.0) / 2.0 - sum[0] / count,
            (ny - 1.0) / 2.0 - sum[1] / count,
        ];
    }
    if options.zero_disparity {
        let [left, right] = &mut cc_new;
        for (l, r) in left.iter_mut().zip(right.iter_mut()) {
            let mean = (*l + *r) * 0.5;
            *l = mean;
            *r = mean;
        }
    } else {
        // Keep the epipolar lines shared: the coordinate across the baseline.
        let across = 1 - idx;
        let mean = (cc_new[0][across] + cc_new[1][across]) * 0.5;
        cc_new[0][across] = mean;
        cc_new[1][across] = mean;
    }

    let matrix = |f: f64, cc: [f64; 2]| Matrix3::new(f, 0.0, cc[0], 0.0, f, cc[1], 0.0, 0.0, 1.0);
    let left_rect = rectangles(
        &pair.left,
        &r1,
        &matrix(fc_new, cc_new[0]),
        size,
        Side::Left,
    )?;
    let right_rect = rectangles(
        &pair.right,
        &r2,
        &matrix(fc_new, cc_new[1]),
        size,
        Side::Right,
    )?;

    // Scale so that alpha 0 keeps only valid pixels and alpha 1 every source pixel.
    let (nw_, nh_) = (f64::from(new_size.width), f64::from(new_size.height));
    let scaled = |cc: [f64; 2]| [nw_ * cc[0] / nx, nh_ * cc[1] / ny];
    let cc_scaled = [scaled(cc_new[0]), scaled(cc_new[1])];
    let fit = |rect: &[f64; 4], cc0: [f64; 2], cc: [f64; 2]| {
        [
            cc[0] / (cc0[0] - rect[0]),
            cc[1] / (cc0[1] - rect[1]),
            (nw_ - 1.0 - cc[0]) / (rect[0] + rect[2] - cc0[0]),
            (nh_ - 1.0 - cc[1]) / (rect[1] + rect[3] - cc0[1]),
        ]
    };
    let mut s0 = f64::MIN;
    let mut s1 = f64::MAX;
    for (rect, k) in [(&left_rect, 0), (&right_rect, 1)] {
        for v in fit(&rect.inner, cc_new[k], cc_scaled[k]) {
            s0 = s0.max(v);
        }
        for v in fit(&rect.outer, cc_new[k], cc_scaled[k]) {
            s1 = s1.min(v);
        }
    }
    let s = s0 * (1.0 - options.alpha.get()) + s1 * options.alpha.get();
    if !(s.is_finite() && s > 0.0) {
        return Err(RectifyFault::Degenerate);
    }
    fc_new *= s;
    let roi = |rect: &Rectangles, cc0: [f64; 2], cc: [f64; 2]| {
        Roi {
            x: ((rect.inner[0] - cc0[0]) * s + cc[0]).ceil() as i64,
            y: ((rect.inner[1] - cc0[1]) * s + cc[1]).ceil() as i64,
            width: (rect.inner[2] * s).floor() as i64,
            height: (rect.inner[3] * s).floor() as i64,
        }
        .within(new_size.width, new_size.height)
    };
    let roi_left = roi(&left_rect, cc_new[0], cc_scaled[0]);
    let roi_right = roi(&right_rect, cc_new[1], cc_scaled[1]);

    let [c1, c2] = cc_scaled;
    let mut p1 = Matrix3x4::zeros();
    p1[(0, 0)] = fc_new;
    p1[(1, 1)] = fc_new;
    p1[(0, 2)] = c1[0];
    p1[(1, 2)] = c1[1];
    p1[(2, 2)] = 1.0;
    let mut p2 = p1;
    p2[(0, 2)] = c2[0];
    p2[(1, 2)] = c2[1];
    p2[(idx, 3)] = t[idx] * fc_new;

    Ok(Rectification::from_projections(
        [r1, r2],
        [p1, p2],
        (t[idx], idx == 1),
        [roi_left, roi_right],
        Some(options.alpha.get()),
        new_size,
    ))
}

/// The widest angle from the rectified axis a fisheye's pinhole rectification reaches: the
/// middles of the image's sides beyond it are taken at it (lenses up to 160° across are
/// rectified as OpenCV does; latitude-longitude holds the wider ones, [`super::latlon`]).
pub const PINHOLE_MAX_ANGLE_DEG: f64 = 80.0;

/// The new camera matrix (fx, fy, cx, cy) of one fisheye camera as OpenCV's
/// `fisheye::estimateNewCameraMatrixForUndistortRectify` makes it (`fov_scale` 1): the
/// middles of the image's sides undistorted and rotated, and a focal length between the one
/// that keeps them all (`balance` 1) and the one that fills the image (`balance` 0).
fn fisheye_new_matrix(
    camera: &Camera,
    size: Size,
    rotation: &Matrix3<f64>,
    balance: f64,
    new_size: Size,
) -> [f64; 4] {
    let (w, h) = (size.width, size.height);
    let k = camera.intrinsics();
    let aspect = k.fx / k.fy;
    let mut points = [
        [f64::from(w / 2), 0.0],
        [f64::from(w), f64::from(h / 2)],
        [f64::from(w / 2), f64::from(h)],
        [0.0, f64::from(h / 2)],
    ];
    for p in &mut points {
        // OpenCV marks a point it cannot undistort at (−1e6, −1e6).
        *p = match camera.normalize_as_opencv(*p) {
            Some([x, y]) => {
                let r = rotation * Vector3::new(x, y, 1.0);
                let (across, limit) = (r.x.hypot(r.y), PINHOLE_MAX_ANGLE_DEG.to_radians().tan());
                if r.z <= 0.0 || across > limit * r.z {
                    // A lens that sees this far off the axis (a 180° fisheye) would put the
                    // point at infinity on the plane, and the new matrix with it (OpenCV's
                    // own gives a principal point thousands of pixels outside the image): the
                    // point is taken at the widest angle a pinhole plane holds, along its ray.
                    [r.x * limit / across, r.y * limit / across]
                } else {
                    [r.x / r.z, r.y / r.z]
                }
            }
            None => [-1e6, -1e6],
        };
        p[1] *= aspect;
    }
    let cn = [
        points.iter().map(|p| p[0]).sum::<f64>() / 4.0,
        points.iter().map(|p| p[1]).sum::<f64>() / 4.0,
    ];
    let (mut minx, mut miny, mut maxx, mut maxy) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for p in &points {
        minx = minx.min(p[0]);
        maxx = maxx.max(p[0]);
        miny = miny.min(p[1]);
        maxy = maxy.max(p[1]);
    }
    let (wf, hf) = (f64::from(w), f64::from(h));
    let fs = [
        wf * 0.5 / (cn[0] - minx),
        wf * 0.5 / (maxx - cn[0]),
        hf * 0.5 * aspect / (cn[1] - miny),
        hf * 0.5 * aspect / (maxy - cn[1]),
    ];
    let fmin = fs.iter().copied().fold(f64::MAX, f64::min);
    let fmax = fs.iter().copied().fold(f64::MIN, f64::max);
    let f = balance * fmin + (1.0 - balance) * fmax;
    let (mut fx, mut fy) = (f, f / aspect);
    let (mut cx, mut cy) = (
        -cn[0] * f + wf * 0.5,
        (-cn[1] * f + hf * aspect * 0.5) / aspect,
    );
    if new_size != size {
        let rx = f64::from(new_size.width) / wf;
        let ry = f64::from(new_size.height) / hf;
        fx *= rx;
        fy *= ry;
        cx *= rx;
        cy *= ry;
    }
    [fx, fy, cx, cy]
}

/// P1, P2, Q and the ROIs of two fisheye cameras as OpenCV's `fisheye::stereoRectify`
/// makes them, `alpha` as its `balance`.
fn fisheye_projections(
    pair: &StereoPair,
    size: Size,
    new_size: Size,
    options: RectifyOptions,
    [r1, r2]: [Matrix3<f64>; 2],
    t: Vector3<f64>,
) -> Result<Rectification, RectifyFault> {
    let k1 = fisheye_new_matrix(&pair.left, size, &r1, options.alpha.get(), new_size);
    let k2 = fisheye_new_matrix(&pair.right, size, &r2, options.alpha.get(), new_size);
    let fc_new = k1[1].min(k2[1]);
    let mut cc = [[k1[2], k1[3]], [k2[2], k2[3]]];
    if options.zero_disparity {
        let mean = [(cc[0][0] + cc[1][0]) * 0.5, (cc[0][1] + cc[1][1]) * 0.5];
        cc = [mean, mean];
    } else {
        let mean = (cc[0][1] + cc[1][1]) * 0.5;
        cc[0][1] = mean;
        cc[1][1] = mean;
    }
    if !(fc_new.is_finite() && fc_new > 0.0 && cc.iter().flatten().all(|v| v.is_finite())) {
        return Err(RectifyFault::Degenerate);
    }
    let matrix = |c: [f64; 2]| Matrix3::new(fc_new, 0.0, c[0], 0.0, fc_new, c[1], 0.0, 0.0, 1.0);
    let roi = |camera: &Camera, rotation: &Matrix3<f64>, c: [f64; 2], side| {
        Ok(rectangles(camera, rotation, &matrix(c), size, side)?.inner_roi(new_size))
    };
    let roi_left = roi(&pair.left, &r1, cc[0], Side::Left)?;
    let roi_right = roi(&pair.right, &r2, cc[1], Side::Right)?;
    let mut p1 = Matrix3x4::zeros();
    p1.fixed_view_mut::<3, 3>(0, 0).copy_from(&matrix(cc[0]));
    let mut p2 = Matrix3x4::zeros();
    p2.fixed_view_mut::<3, 3>(0, 0).copy_from(&matrix(cc[1]));
    p2[(0, 3)] = t.x * fc_new;
    Ok(Rectification::from_projections(
        [r1, r2],
        [p1, p2],
        (t.x, false),
        [roi_left, roi_right],
        Some(options.alpha.get()),
        new_size,
    ))
}
