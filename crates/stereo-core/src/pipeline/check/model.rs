//! What a drift of the right camera does to where its pixels land in the rectified frame the
//! calibration makes: a small rotation of the camera (about its x, y and z axes), a change of
//! its vertical focal length and of its principal point's row. The check fits these to the
//! rows of sparse matches by Gauss–Newton (numerical derivatives through the lens model),
//! keeping only the parameters the matches can tell apart, with their covariance.
//!
//! The left camera is the reference: a drift of both cameras shows as the right one's
//! relative to the left.

use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Vector3};

use crate::calibration::files::Raw;
use crate::camera::{Camera, Intrinsics, StereoPair};

/// One parameter of a drift.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Param {
    /// The right camera turned about its x axis (pitch), in radians.
    AboutX,
    /// About its y axis (yaw): moves points along the rows, so rows alone hardly see it.
    AboutY,
    /// About its optical axis (roll).
    AboutZ,
    /// The right camera's fy over the calibrated fy, less 1.
    FocalRatio,
    /// The right camera's cy moved, in pixels.
    CyShift,
}

impl Param {
    /// The step of the numerical derivative: a microradian, a millionth, a thousandth of a px.
    fn step(self) -> f64 {
        match self {
            Param::AboutX | Param::AboutY | Param::AboutZ => 1e-6,
            Param::FocalRatio => 1e-6,
            Param::CyShift => 1e-3,
        }
    }
}

/// A drift: the right camera's rotation since it was calibrated (a rotation vector in its own
/// frame, X_right_now = Exp(rotation)·X_right_then), its fy ratio less 1 and its cy shift.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Drift {
    pub rotation: Vector3<f64>,
    pub focal_ratio: f64,
    pub cy_shift: f64,
}

impl Drift {
    /// The drift whose `params` take `values` (the others zero).
    pub fn of(params: &[Param], values: &[f64]) -> Drift {
        let mut drift = Drift::default();
        for (&p, &v) in params.iter().zip(values) {
            drift.add(p, v);
        }
        drift
    }

    fn add(&mut self, param: Param, value: f64) {
        match param {
            Param::AboutX => self.rotation.x += value,
            Param::AboutY => self.rotation.y += value,
            Param::AboutZ => self.rotation.z += value,
            Param::FocalRatio => self.focal_ratio += value,
            Param::CyShift => self.cy_shift += value,
        }
    }

    /// The pair as it is now: the right camera's fy and cy moved, and its pose turned about
    /// its own centre (R' = Exp(ω)·R, T' = Exp(ω)·T).
    pub fn corrected(&self, pair: &StereoPair) -> Option<StereoPair> {
        let turn = Rotation3::from_scaled_axis(self.rotation);
        let right = moved_camera(&pair.right, self)?;
        Some(StereoPair {
            left: pair.left,
            right,
            rotation: turn * pair.rotation,
            translation: turn * pair.translation,
        })
    }
}

/// The right camera with the drift's fy ratio and cy shift.
fn moved_camera(camera: &Camera, drift: &Drift) -> Option<Camera> {
    let k = camera.intrinsics();
    Camera::new(
        Intrinsics {
            fy: k.fy * (1.0 + drift.focal_ratio),
            cy: k.cy + drift.cy_shift,
            ..k
        },
        camera.distortion(),
    )
    .ok()
}

/// The calibration's right camera and rectification, to move pixels between its raw and its
/// rectified image.
pub struct Model<'a> {
    raw: &'a Raw,
    /// The rectified right camera's matrix (P2's left 3 × 3).
    k2: Matrix3<f64>,
}

impl<'a> Model<'a> {
    pub fn new(raw: &'a Raw) -> Model<'a> {
        Model {
            raw,
            k2: raw.rectification.p2.fixed_view::<3, 3>(0, 0).into_owned(),
        }
    }

    /// The raw right pixel the calibration rectifies to `rectified`.
    pub fn raw_of(&self, rectified: [f64; 2]) -> Option<[f64; 2]> {
        let ray = self.k2.try_inverse()? * Vector3::new(rectified[0], rectified[1], 1.0);
        let camera_ray = self.raw.rectification.r2.transpose() * ray;
        self.raw.pair.right.project(&camera_ray)
    }

    /// Where the raw right pixel `raw` lands in the calibration's rectified frame if the
    /// right camera drifted by `drift` since.
    pub fn rectified(&self, drift: &Drift, raw: [f64; 2]) -> Option<[f64; 2]> {
        let camera = moved_camera(&self.raw.pair.right, drift)?;
        let [x, y] = camera.normalize(raw)?;
        let then = Rotation3::from_scaled_axis(drift.rotation).inverse() * Vector3::new(x, y, 1.0);
        let ray = self.raw.rectification.r2 * then;
        if ray.z <= f64::EPSILON {
            return None;
        }
        let p = self.k2 * (ray / ray.z);
        Some([p.x, p.y])
    }

    /// How the rectified position of `raw` moves with each of `params` at `drift`: one row
    /// `[∂x, ∂y]` a parameter, by central differences.
    pub fn derivatives(
        &self,
        drift: &Drift,
        params: &[Param],
        raw: [f64; 2],
    ) -> Option<Vec<[f64; 2]>> {
        params
            .iter()
            .map(|&p| {
                let h = p.step();
                let (mut up, mut down) = (*drift, *drift);
                up.add(p, h);
                down.add(p, -h);
                let (a, b) = (self.rectified(&up, raw)?, self.rectified(&down, raw)?);
                Some([(a[0] - b[0]) / (2.0 * h), (a[1] - b[1]) / (2.0 * h)])
            })
            .collect()
    }
}

/// One match as the fit reads it: the left point's rectified row, and the right point's raw
/// pixel.
#[derive(Debug, Clone, Copy)]
pub struct Observed {
    pub left_row: f64,
    pub right_raw: [f64; 2],
}

/// A fit of a drift to rows.
#[derive(Debug, Clone)]
pub struct Fitted {
    pub params: Vec<Param>,
    pub drift: Drift,
    /// The parameters' covariance, in their order.
    pub covariance: DMatrix<f64>,
    /// Which matches were kept (the others' residuals lay far out).
    pub inliers: Vec<bool>,
    /// Each match's row offset left after the fit (right − left), in pixels.
    pub residuals: Vec<f64>,
}

/// The normal matrix JᵀJ of the rows over the kept matches at `drift`, and Jᵀr.
fn normal(
    model: &Model,
    drift: &Drift,
    params: &[Param],
    seen: &[Observed],
    keep: &[bool],
) -> (DMatrix<f64>, DVector<f64>, Vec<f64>) {
    let n = params.len();
    let (mut jtj, mut jtr) = (DMatrix::zeros(n, n), DVector::zeros(n));
    let mut residuals = vec![f64::NAN; seen.len()];
    for (i, o) in seen.iter().enumerate() {
        let (Some(at), Some(d)) = (
            model.rectified(drift, o.right_raw),
            model.derivatives(drift, params, o.right_raw),
        ) else {
            continue;
        };
        let r = at[1] - o.left_row;
        residuals[i] = r;
        if !keep[i] {
            continue;
        }
        let j = DVector::from_iterator(n, d.iter().map(|g| g[1]));
        jtj += &j * j.transpose();
        jtr += &j * r;
    }
    (jtj, jtr, residuals)
}

/// The parameters' correlations from a normal matrix's inverse; `None` when it is singular.
fn correlations(jtj: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let c = jtj.clone().try_inverse()?;
    let n = c.nrows();
    Some(DMatrix::from_fn(n, n, |i, j| {
        c[(i, j)] / (c[(i, i)] * c[(j, j)]).sqrt()
    }))
}

/// The correlation past which two parameters count as one.
pub const INSEPARABLE: f64 = 0.98;

/// Of `candidates` (in order of priority), those the matches can tell apart: the last of any
/// two that correlate past [`INSEPARABLE`] is dropped, and dropped ones are named with the
/// kept one they move with.
pub fn separable(
    model: &Model,
    candidates: &[Param],
    seen: &[Observed],
) -> (Vec<Param>, Vec<(Param, Param)>) {
    let mut kept = candidates.to_vec();
    let mut dropped = Vec::new();
    let all = vec![true; seen.len()];
    while kept.len() > 1 {
        let (jtj, _, _) = normal(model, &Drift::default(), &kept, seen, &all);
        let Some(corr) = correlations(&jtj) else {
            // Singular: the last parameter cannot be seen at all.
            let last = kept.pop().expect("more than one");
            dropped.push((last, kept[0]));
            continue;
        };
        // The lowest-priority parameter that moves with one before it.
        let found = (1..kept.len()).rev().find_map(|j| {
            (0..j)
                .find(|&i| corr[(i, j)].abs() > INSEPARABLE)
                .map(|i| (j, i))
        });
        match found {
            Some((j, i)) => {
                dropped.push((kept[j], kept[i]));
                kept.remove(j);
            }
            None => break,
        }
    }
    (kept, dropped)
}

/// Fits `params` to the rows of `seen`: Gauss–Newton from no drift, the matches whose row
/// lies more than 3.5 robust σ (at least 0.05 px) from the fit left out and the fit run
/// again. `None` with too few matches or parameters the matches cannot see.
pub fn fit(model: &Model, params: &[Param], seen: &[Observed]) -> Option<Fitted> {
    let n = params.len();
    if seen.len() < 2 * n + 4 {
        return None;
    }
    let mut keep = vec![true; seen.len()];
    let mut values = DVector::<f64>::zeros(n);
    for round in 0..4 {
        for _ in 0..3 {
            let drift = Drift::of(params, values.as_slice());
            let (jtj, jtr, _) = normal(model, &drift, params, seen, &keep);
            let step = jtj.cholesky()?.solve(&jtr);
            values -= step;
        }
        let drift = Drift::of(params, values.as_slice());
        let (_, _, residuals) = normal(model, &drift, params, seen, &keep);
        // The robust spread of every match's residual (NaN: not mappable, left out).
        let mut sorted: Vec<f64> = residuals
            .iter()
            .filter(|r| r.is_finite())
            .map(|r| r.abs())
            .collect();
        if sorted.len() < 2 * n + 4 {
            return None;
        }
        sorted.sort_by(f64::total_cmp);
        let sigma = 1.4826 * sorted[sorted.len() / 2];
        let bound = (3.5 * sigma).max(0.05);
        let next: Vec<bool> = residuals.iter().map(|r| r.abs() <= bound).collect();
        if next == keep && round > 0 {
            break;
        }
        keep = next;
    }
    let drift = Drift::of(params, values.as_slice());
    let (jtj, _, residuals) = normal(model, &drift, params, seen, &keep);
    let kept: Vec<f64> = residuals
        .iter()
        .zip(&keep)
        .filter(|&(r, &k)| k && r.is_finite())
        .map(|(r, _)| *r)
        .collect();
    if kept.len() < 2 * n + 4 {
        return None;
    }
    let variance = kept.iter().map(|r| r * r).sum::<f64>() / (kept.len() - n) as f64;
    let covariance = jtj.try_inverse()? * variance;
    Some(Fitted {
        params: params.to_vec(),
        drift,
        covariance,
        inliers: keep,
        residuals,
    })
}

impl Fitted {
    /// How far the drift moves the raw right pixel `raw` in the rectified frame, `[Δx, Δy]`,
    /// with the σ of each.
    pub fn shift_at(&self, model: &Model, raw: [f64; 2]) -> Option<([f64; 2], [f64; 2])> {
        let now = model.rectified(&self.drift, raw)?;
        let then = model.rectified(&Drift::default(), raw)?;
        let d = model.derivatives(&self.drift, &self.params, raw)?;
        let std = [0, 1].map(|axis| {
            let j = DVector::from_iterator(d.len(), d.iter().map(|g| g[axis]));
            (j.transpose() * &self.covariance * &j)[(0, 0)]
                .max(0.0)
                .sqrt()
        });
        Some(([now[0] - then[0], now[1] - then[1]], std))
    }

    /// The value and σ of a parameter, when it was fitted.
    pub fn estimate(&self, param: Param) -> Option<(f64, f64)> {
        let i = self.params.iter().position(|&p| p == param)?;
        let value = match param {
            Param::AboutX => self.drift.rotation.x,
            Param::AboutY => self.drift.rotation.y,
            Param::AboutZ => self.drift.rotation.z,
            Param::FocalRatio => self.drift.focal_ratio,
            Param::CyShift => self.drift.cy_shift,
        };
        Some((value, self.covariance[(i, i)].max(0.0).sqrt()))
    }
}
