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
    /// The baseline's length over the calibrated one, less 1.
    BaselineScale,
}

impl Param {
    /// The step of the numerical derivative: a microradian, a millionth, a thousandth of a px.
    fn step(self) -> f64 {
        match self {
            Param::AboutX | Param::AboutY | Param::AboutZ => 1e-6,
            Param::FocalRatio | Param::BaselineScale => 1e-6,
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
    pub baseline_scale: f64,
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
            Param::BaselineScale => self.baseline_scale += value,
        }
    }

    /// The pair as it is now: the right camera's fy and cy moved, its pose turned about its
    /// own centre (R' = Exp(ω)·R, T' = Exp(ω)·T) and the baseline scaled.
    pub fn corrected(&self, pair: &StereoPair) -> Option<StereoPair> {
        let turn = Rotation3::from_scaled_axis(self.rotation);
        let right = moved_camera(&pair.right, self)?;
        Some(StereoPair {
            left: pair.left,
            right,
            rotation: turn * pair.rotation,
            translation: turn * pair.translation * (1.0 + self.baseline_scale),
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
        central(drift, params, |d| self.rectified(d, raw))
    }
}

/// How `f`'s two values move with each of `params` at `drift`, by central differences: one
/// `[∂f₀, ∂f₁]` a parameter; `None` where `f` has no value.
fn central(
    drift: &Drift,
    params: &[Param],
    f: impl Fn(&Drift) -> Option<[f64; 2]>,
) -> Option<Vec<[f64; 2]>> {
    params
        .iter()
        .map(|&p| {
            let h = p.step();
            let (mut up, mut down) = (*drift, *drift);
            up.add(p, h);
            down.add(p, -h);
            let (a, b) = (f(&up)?, f(&down)?);
            Some([(a[0] - b[0]) / (2.0 * h), (a[1] - b[1]) / (2.0 * h)])
        })
        .collect()
}

/// What the fit reads.
#[derive(Debug, Clone, Copy)]
pub enum Observed {
    /// A sparse match: the left point's rectified row, and the right point's raw pixel.
    Row { left_row: f64, right_raw: [f64; 2] },
    /// A point whose place in the left camera's frame is known (a board's corner, a point at
    /// a known distance; in the calibration's unit) and the raw right pixel that sees it.
    Known {
        point: Vector3<f64>,
        right_raw: [f64; 2],
    },
}

impl Observed {
    fn is_row(&self) -> bool {
        matches!(self, Observed::Row { .. })
    }
}

impl Model<'_> {
    /// Where the right camera, drifted by `drift`, sees `point` (left camera's frame).
    pub fn seen_at(&self, drift: &Drift, point: &Vector3<f64>) -> Option<[f64; 2]> {
        let pair = drift.corrected(&self.raw.pair)?;
        pair.right
            .project(&(pair.rotation * point + pair.translation))
    }

    /// What the fit minimises for one observation: a row's offset (right − left, px), or a
    /// known point's reprojection error in the raw right image (x, y).
    fn residual(&self, drift: &Drift, o: &Observed) -> Option<([f64; 2], usize)> {
        match *o {
            Observed::Row {
                left_row,
                right_raw,
            } => Some(([self.rectified(drift, right_raw)?[1] - left_row, 0.0], 1)),
            Observed::Known { point, right_raw } => {
                let p = self.seen_at(drift, &point)?;
                Some(([p[0] - right_raw[0], p[1] - right_raw[1]], 2))
            }
        }
    }

    /// The residual's derivatives in each of `params`, by central differences: one
    /// `[∂r₀, ∂r₁]` a parameter.
    fn residual_derivatives(
        &self,
        drift: &Drift,
        params: &[Param],
        o: &Observed,
    ) -> Option<Vec<[f64; 2]>> {
        central(drift, params, |d| Some(self.residual(d, o)?.0))
    }
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

/// The weighted normal matrix JᵀWJ over the kept observations at `drift` (a row's weight
/// `weights[0]`, a known point's `weights[1]`), JᵀWr, and each observation's residual (a
/// row's offset, a known point's error in x and y).
fn normal(
    model: &Model,
    drift: &Drift,
    params: &[Param],
    seen: &[Observed],
    keep: &[bool],
    weights: [f64; 2],
) -> (DMatrix<f64>, DVector<f64>, Vec<Option<[f64; 2]>>) {
    let n = params.len();
    let (mut jtj, mut jtr) = (DMatrix::zeros(n, n), DVector::zeros(n));
    let mut residuals = vec![None; seen.len()];
    for (i, o) in seen.iter().enumerate() {
        let (Some((r, m)), Some(d)) = (
            model.residual(drift, o),
            model.residual_derivatives(drift, params, o),
        ) else {
            continue;
        };
        residuals[i] = Some(r);
        if !keep[i] {
            continue;
        }
        let w = if o.is_row() { weights[0] } else { weights[1] };
        for (k, &rk) in r.iter().enumerate().take(m) {
            let j = DVector::from_iterator(n, d.iter().map(|g| g[k]));
            jtj += &j * j.transpose() * w;
            jtr += &j * rk * w;
        }
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
        let (jtj, _, _) = normal(model, &Drift::default(), &kept, seen, &all, [1.0, 1.0]);
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

/// The robust spread (1.4826 × the median size) of the residuals of one kind of
/// observation; `None` with none.
fn spread(residuals: &[Option<[f64; 2]>], seen: &[Observed], rows: bool) -> Option<f64> {
    let mut sizes: Vec<f64> = residuals
        .iter()
        .zip(seen)
        .filter(|(_, o)| o.is_row() == rows)
        .filter_map(|(r, o)| {
            r.map(|r| {
                if o.is_row() {
                    r[0].abs()
                } else {
                    r[0].hypot(r[1]) / std::f64::consts::SQRT_2
                }
            })
        })
        .collect();
    if sizes.is_empty() {
        return None;
    }
    sizes.sort_by(f64::total_cmp);
    Some(1.4826 * sizes[sizes.len() / 2])
}

/// Fits `params` to `seen`: Gauss–Newton from no drift, each kind of observation weighted by
/// its own robust spread, the observations more than 3.5 spreads (at least 0.05 px) from the
/// fit left out and the fit run again. `None` with too few observations or parameters they
/// cannot see.
pub fn fit(model: &Model, params: &[Param], seen: &[Observed]) -> Option<Fitted> {
    let n = params.len();
    if seen.len() < 2 * n + 4 {
        return None;
    }
    let mut keep = vec![true; seen.len()];
    let mut values = DVector::<f64>::zeros(n);
    let mut weights = [1.0, 1.0];
    for round in 0..4 {
        for _ in 0..3 {
            let drift = Drift::of(params, values.as_slice());
            let (jtj, jtr, _) = normal(model, &drift, params, seen, &keep, weights);
            let step = jtj.cholesky()?.solve(&jtr);
            values -= step;
        }
        let drift = Drift::of(params, values.as_slice());
        let (_, _, residuals) = normal(model, &drift, params, seen, &keep, weights);
        let sigma = [true, false].map(|rows| spread(&residuals, seen, rows));
        let bound = sigma.map(|s| s.map_or(f64::INFINITY, |s| (3.5 * s).max(0.05)));
        weights = sigma.map(|s| s.map_or(1.0, |s| 1.0 / s.max(0.01).powi(2)));
        let next: Vec<bool> = residuals
            .iter()
            .zip(seen)
            .map(|(r, o)| {
                let b = if o.is_row() { bound[0] } else { bound[1] };
                r.is_some_and(|r| r[0].abs() <= b && r[1].abs() <= b)
            })
            .collect();
        if next.iter().filter(|&&k| k).count() < 2 * n + 4 {
            return None;
        }
        if next == keep && round > 0 {
            break;
        }
        keep = next;
    }
    let drift = Drift::of(params, values.as_slice());
    let (_, _, residuals) = normal(model, &drift, params, seen, &keep, weights);
    // Weights from the kept residuals' own RMS, so that the covariance is in their units.
    let rms = [true, false].map(|rows| {
        let (sum, count) = residuals
            .iter()
            .zip(seen)
            .zip(&keep)
            .filter(|((r, o), k)| **k && o.is_row() == rows && r.is_some())
            .fold((0.0, 0usize), |(s, c), ((r, o), _)| {
                let r = r.expect("kept");
                let m = if o.is_row() { 1 } else { 2 };
                (
                    s + r[0] * r[0] + if m == 2 { r[1] * r[1] } else { 0.0 },
                    c + m,
                )
            });
        (count > 0).then(|| (sum / count as f64).sqrt().max(1e-3))
    });
    let weights = rms.map(|s| s.map_or(1.0, |s| 1.0 / (s * s)));
    let (jtj, _, _) = normal(model, &drift, params, seen, &keep, weights);
    let kept = keep.iter().filter(|&&k| k).count();
    let dof = (kept as f64 / (kept - n).max(1) as f64).max(1.0);
    let covariance = jtj.try_inverse()? * dof;
    Some(Fitted {
        params: params.to_vec(),
        drift,
        covariance,
        residuals: residuals
            .iter()
            .zip(&keep)
            .map(|(r, &k)| {
                if k {
                    r.map_or(f64::NAN, |r| r[0])
                } else {
                    f64::NAN
                }
            })
            .collect(),
        inliers: keep,
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
            Param::BaselineScale => self.drift.baseline_scale,
        };
        Some((value, self.covariance[(i, i)].max(0.0).sqrt()))
    }
}
