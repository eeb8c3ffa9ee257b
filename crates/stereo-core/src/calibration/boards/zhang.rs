//! The first guess the refinement starts from: each view's homography from the board's plane
//! to the image (normalised DLT), the camera matrix from them in Zhang's closed form (with
//! OpenCV's principal-point-at-the-centre solution when the views cannot fix the principal
//! point), and each view's pose from its homography.

use nalgebra::{Matrix3, Rotation3, SMatrix, SVector, Vector3};

use crate::camera::{Intrinsics, Size};

/// The homography taking the plane's (X, Y, 1) to the image's (u, v, 1), from at least four
/// correspondences in general position; `None` when they are degenerate.
pub fn homography(plane: &[[f64; 2]], image: &[[f64; 2]]) -> Option<Matrix3<f64>> {
    if plane.len() < 4 || plane.len() != image.len() {
        return None;
    }
    let (tp, _) = normalizer(plane)?;
    let (ti, ti_inv) = normalizer(image)?;
    let mut ata = SMatrix::<f64, 9, 9>::zeros();
    for (p, q) in plane.iter().zip(image) {
        let a = tp * Vector3::new(p[0], p[1], 1.0);
        let b = ti * Vector3::new(q[0], q[1], 1.0);
        let (x, y) = (a.x / a.z, a.y / a.z);
        let (u, v) = (b.x / b.z, b.y / b.z);
        let rows = [
            SVector::<f64, 9>::from([-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u]),
            SVector::<f64, 9>::from([0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v]),
        ];
        for r in rows {
            ata += r * r.transpose();
        }
    }
    let h = smallest_eigenvector(ata)?;
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let hm = ti_inv * hn * tp;
    let scale = hm[(2, 2)];
    if !scale.is_finite() || scale.abs() < 1e-300 {
        return Some(hm);
    }
    Some(hm / scale).filter(|m| m.iter().all(|v| v.is_finite()))
}

/// Hartley's normalisation: centroid to the origin, mean distance √2. Returns the transform
/// and its inverse.
fn normalizer(points: &[[f64; 2]]) -> Option<(Matrix3<f64>, Matrix3<f64>)> {
    let n = points.len() as f64;
    let cx = points.iter().map(|p| p[0]).sum::<f64>() / n;
    let cy = points.iter().map(|p| p[1]).sum::<f64>() / n;
    let mean = points
        .iter()
        .map(|p| (p[0] - cx).hypot(p[1] - cy))
        .sum::<f64>()
        / n;
    if !(mean.is_finite() && mean > 0.0) {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / mean;
    let t = Matrix3::new(s, 0.0, -s * cx, 0.0, s, -s * cy, 0.0, 0.0, 1.0);
    let inv = Matrix3::new(1.0 / s, 0.0, cx, 0.0, 1.0 / s, cy, 0.0, 0.0, 1.0);
    Some((t, inv))
}

fn smallest_eigenvector<const N: usize>(m: SMatrix<f64, N, N>) -> Option<SVector<f64, N>>
where
    nalgebra::Const<N>: nalgebra::DimMin<nalgebra::Const<N>, Output = nalgebra::Const<N>>
        + nalgebra::DimSub<nalgebra::Const<1>>,
    nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<
            <nalgebra::Const<N> as nalgebra::DimSub<nalgebra::Const<1>>>::Output,
        >,
{
    if !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    let eigen = m.symmetric_eigen();
    let k = eigen.eigenvalues.imin();
    Some(eigen.eigenvectors.column(k).into_owned())
}

/// The camera matrix (zero skew) from three or more views' homographies by Zhang's closed
/// form; when that has no valid solution (too few or too alike views) or puts the principal
/// point off the image, OpenCV's `initIntrinsicParams2D`: the principal point at the image's
/// centre and fx, fy from the vanishing points.
pub fn intrinsics(homographies: &[Matrix3<f64>], size: Size) -> Option<Intrinsics> {
    zhang(homographies, size).or_else(|| centred(homographies, size))
}

fn zhang(homographies: &[Matrix3<f64>], size: Size) -> Option<Intrinsics> {
    if homographies.len() < 3 {
        return None;
    }
    let v = |h: &Matrix3<f64>, i: usize, j: usize| {
        SVector::<f64, 6>::from([
            h[(0, i)] * h[(0, j)],
            h[(0, i)] * h[(1, j)] + h[(1, i)] * h[(0, j)],
            h[(1, i)] * h[(1, j)],
            h[(2, i)] * h[(0, j)] + h[(0, i)] * h[(2, j)],
            h[(2, i)] * h[(1, j)] + h[(1, i)] * h[(2, j)],
            h[(2, i)] * h[(2, j)],
        ])
    };
    // Scale the image so that the six unknowns are of one magnitude.
    let s = 1.0 / f64::from(size.width.max(size.height));
    let scale = Matrix3::new(s, 0.0, 0.0, 0.0, s, 0.0, 0.0, 0.0, 1.0);
    let mut vtv = SMatrix::<f64, 6, 6>::zeros();
    for h in homographies {
        let h = scale * h;
        let h = h / h.norm();
        let rows = [v(&h, 0, 1), v(&h, 0, 0) - v(&h, 1, 1)];
        for r in rows {
            vtv += r * r.transpose();
        }
    }
    // Zero skew.
    vtv[(1, 1)] += 1.0;
    let b = smallest_eigenvector(vtv)?;
    let (b11, b12, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4], b[5]);
    let den = b11 * b22 - b12 * b12;
    let v0 = (b12 * b13 - b11 * b23) / den;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let alpha = (lambda / b11).sqrt();
    let beta = (lambda * b11 / den).sqrt();
    let gamma = -b12 * alpha * alpha * beta / lambda;
    let u0 = gamma * v0 / beta - b13 * alpha * alpha / lambda;
    let k = Intrinsics {
        fx: alpha / s,
        fy: beta / s,
        cx: u0 / s,
        cy: v0 / s,
    };
    let (w, h) = (f64::from(size.width), f64::from(size.height));
    let plausible = [k.fx, k.fy, k.cx, k.cy].iter().all(|v| v.is_finite())
        && k.fx > 0.0
        && k.fy > 0.0
        && (k.fx / k.fy - 1.0).abs() < 0.5
        && k.cx > 0.1 * w
        && k.cx < 0.9 * w
        && k.cy > 0.1 * h
        && k.cy < 0.9 * h;
    plausible.then_some(k)
}

fn centred(homographies: &[Matrix3<f64>], size: Size) -> Option<Intrinsics> {
    let (cx, cy) = (
        (f64::from(size.width) - 1.0) / 2.0,
        (f64::from(size.height) - 1.0) / 2.0,
    );
    let shift = Matrix3::new(1.0, 0.0, -cx, 0.0, 1.0, -cy, 0.0, 0.0, 1.0);
    let (mut ata, mut atb) = (
        nalgebra::Matrix2::<f64>::zeros(),
        nalgebra::Vector2::zeros(),
    );
    for h in homographies {
        let h = shift * h;
        let (a, b) = (h.column(0).into_owned(), h.column(1).into_owned());
        let n = [a, b, (a + b) * 0.5, (a - b) * 0.5].map(|v| v / v.norm());
        for (p, q) in [(n[0], n[1]), (n[2], n[3])] {
            let row = nalgebra::Vector2::new(p.x * q.x, p.y * q.y);
            ata += row * row.transpose();
            atb += row * (-p.z * q.z);
        }
    }
    let f = ata.try_inverse()? * atb;
    let (fx, fy) = ((1.0 / f.x).abs().sqrt(), (1.0 / f.y).abs().sqrt());
    (fx.is_finite() && fy.is_finite() && fx > 0.0 && fy > 0.0).then_some(Intrinsics {
        fx,
        fy,
        cx,
        cy,
    })
}

/// The board's pose (rotation, translation) in the camera from a homography and K, with the
/// board in front of the camera.
pub fn pose(homography: &Matrix3<f64>, k: &Intrinsics) -> Option<(Rotation3<f64>, Vector3<f64>)> {
    let m = k.matrix().try_inverse()? * homography;
    let (m1, m2, m3) = (
        m.column(0).into_owned(),
        m.column(1).into_owned(),
        m.column(2).into_owned(),
    );
    let mut lambda = 2.0 / (m1.norm() + m2.norm());
    if m3.z * lambda < 0.0 {
        lambda = -lambda;
    }
    let (r1, r2, t) = (m1 * lambda, m2 * lambda, m3 * lambda);
    let r = Matrix3::from_columns(&[r1, r2, r1.cross(&r2)]);
    let svd = r.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let mut rot = u * vt;
    if rot.determinant() < 0.0 {
        let mut u = u;
        u.column_mut(2).neg_mut();
        rot = u * vt;
    }
    let valid = rot.iter().chain(t.iter()).all(|v| v.is_finite());
    valid.then(|| (Rotation3::from_matrix_unchecked(rot), t))
}
