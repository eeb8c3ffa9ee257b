//! Levenberg–Marquardt bundle adjustment over board views: one camera's intrinsics,
//! distortion and the board's pose in each view, or both cameras, the pair's R, T and the
//! board's pose in the left camera. Analytic Jacobians (from the distortion models'), normal
//! equations assembled view by view over the cores, and the covariance at the optimum.

use nalgebra::{DMatrix, DVector, Matrix2x3, Matrix3, Rotation3, Vector3};
use rayon::prelude::*;

use crate::camera::{Camera, Distortion, Intrinsics, Model};

/// One camera as the solver moves it: fx, fy, cx, cy, then the model's coefficients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lens {
    pub model: Model,
    pub values: [f64; 12],
}

impl Lens {
    pub fn new(intrinsics: Intrinsics, distortion: &Distortion) -> Lens {
        let mut values = [0.0; 12];
        values[..4].copy_from_slice(&[intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy]);
        let c = distortion.coefficients();
        values[4..4 + c.len()].copy_from_slice(c);
        Lens {
            model: distortion.model(),
            values,
        }
    }

    /// A camera's lens as the solver moves it.
    pub fn of(camera: &Camera) -> Lens {
        Lens::new(camera.intrinsics(), &camera.distortion())
    }

    /// How many parameters the lens has (4 + the model's coefficients).
    pub fn len(&self) -> usize {
        4 + self.model.coefficient_count()
    }

    pub fn is_empty(&self) -> bool {
        false
    }

    pub fn intrinsics(&self) -> Intrinsics {
        let v = self.values;
        Intrinsics {
            fx: v[0],
            fy: v[1],
            cx: v[2],
            cy: v[3],
        }
    }

    /// The lens with its parameters moved by the first `len()` values of `step`, in the
    /// covariance's order (fx fy cx cy, then the coefficients).
    pub fn moved(&self, step: &[f64]) -> Lens {
        let mut lens = *self;
        for (value, s) in lens.values.iter_mut().zip(step.iter().take(self.len())) {
            *value += s;
        }
        lens
    }

    pub fn camera(&self) -> Option<Camera> {
        let distortion = Distortion::new(self.model, &self.values[4..self.len()]).ok()?;
        Camera::new(self.intrinsics(), distortion).ok()
    }
}

/// A rigid motion: x ↦ rotation·x + translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub rotation: Rotation3<f64>,
    pub translation: Vector3<f64>,
}

impl Pose {
    pub fn apply(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * x + self.translation
    }

    /// The pose moved by a step (ω, T), as the covariance orders the extrinsics: a rotation
    /// ω applied on the left, then a translation.
    pub fn moved(&self, step: &[f64]) -> Pose {
        Pose {
            rotation: Rotation3::from_scaled_axis(Vector3::new(step[0], step[1], step[2]))
                * self.rotation,
            translation: self.translation + Vector3::new(step[3], step[4], step[5]),
        }
    }
}

/// The corners one view gives each camera, in the object points' order (`None` when that
/// camera's are not used; a corner `None` when it was not seen).
#[derive(Debug, Clone, Copy)]
pub struct ViewCorners<'a> {
    pub left: Option<&'a [Option<[f64; 2]>]>,
    pub right: Option<&'a [Option<[f64; 2]>]>,
}

/// Everything the solver moves: one lens (a single camera: every view's `left`) or two with
/// the pair's extrinsics, and the board's pose in the left camera per view. With `held`, the
/// lenses stay where they start (OpenCV's `CALIB_FIX_INTRINSIC`): only the extrinsics and the
/// poses move, and the lenses' rows of the covariance are zero.
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    pub lenses: Vec<Lens>,
    pub extrinsics: Option<Pose>,
    pub poses: Vec<Pose>,
    pub held: bool,
}

impl State {
    /// How many parameters are shared by all views (the lenses and the extrinsics).
    pub fn global_len(&self) -> usize {
        self.lenses.iter().map(Lens::len).sum::<usize>()
            + if self.extrinsics.is_some() { 6 } else { 0 }
    }

    fn len(&self) -> usize {
        self.global_len() + 6 * self.poses.len()
    }

    /// How many leading parameters are held (the lenses', when `held`).
    fn held_len(&self) -> usize {
        if self.held {
            self.lenses.iter().map(Lens::len).sum()
        } else {
            0
        }
    }

    fn moved(&self, step: &DVector<f64>) -> State {
        let mut next = self.clone();
        let mut at = 0;
        for lens in &mut next.lenses {
            for k in 0..lens.len() {
                lens.values[k] += step[at + k];
            }
            at += lens.len();
        }
        if let Some(e) = &mut next.extrinsics {
            *e = e.moved(&step.as_slice()[at..at + 6]);
            at += 6;
        }
        for pose in &mut next.poses {
            *pose = pose.moved(&step.as_slice()[at..at + 6]);
            at += 6;
        }
        next
    }
}

/// The squared residuals and corner count of one view in each camera.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ViewError {
    pub squared: [f64; 2],
    pub corners: [usize; 2],
}

impl ViewError {
    /// The RMS reprojection error (px) in camera `side` (0 left, 1 right), if it was seen.
    pub fn rms(&self, side: usize) -> Option<f64> {
        (self.corners[side] > 0).then(|| (self.squared[side] / self.corners[side] as f64).sqrt())
    }
}

/// The outcome of a refinement: the state at the optimum, each view's error, and the
/// covariance of every parameter (σ² (JᵀJ)⁻¹, σ² from the residuals) in the state's order:
/// the lenses, the extrinsics' (ω, T), then each pose's.
#[derive(Debug, Clone)]
pub struct Solution {
    pub state: State,
    pub views: Vec<ViewError>,
    pub rms: f64,
    pub covariance: Option<DMatrix<f64>>,
    /// The same parameters' covariance as the views themselves scatter it (the jackknife
    /// over views, see [`jackknife`]): what noise and what the model cannot fit both move,
    /// when the views are taken as a sample of the views a user could have taken.
    pub view_covariance: Option<DMatrix<f64>>,
    /// The view-cluster sandwich `(JᵀJ)⁻¹·Σ_v g_v·g_vᵀ·(JᵀJ)⁻¹` with `g_v = J_vᵀ·r_v`: the
    /// same scatter to first order, which runs low over few views where the jackknife runs
    /// high (their geometric mean is the bias-reduced CR2 estimate when the views weigh alike).
    pub sandwich_covariance: Option<DMatrix<f64>>,
    pub iterations: usize,
}

/// Why a refinement failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolveFault {
    /// The starting point puts the board behind a camera or the model cannot be evaluated.
    BadStart,
}

struct Linear {
    jtj: DMatrix<f64>,
    jtr: DVector<f64>,
    cost: f64,
    views: Vec<ViewError>,
    residuals: usize,
    /// Each view's share: its parameters' places in the state, its `J_vᵀ·J_v` over them
    /// (upper triangle) and its `J_vᵀ·r_v`.
    shares: Vec<(Vec<usize>, DMatrix<f64>, DVector<f64>)>,
}

/// One view's share of the normal equations on its own parameters.
struct Block {
    index: Vec<usize>,
    jtj: DMatrix<f64>,
    jtr: DVector<f64>,
    error: ViewError,
}

fn skew(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// A projected pixel with its derivatives by the point in the camera's frame and by each of
/// the lens's parameters.
struct Projected {
    pixel: [f64; 2],
    by_point: Matrix2x3<f64>,
    by_lens: [[f64; 2]; 12],
}

/// The pixel of a point in a camera's frame, with its derivatives; `None` behind the camera.
fn project(lens: &Lens, distortion: &Distortion, x: &Vector3<f64>) -> Option<Projected> {
    if x.z <= f64::EPSILON {
        return None;
    }
    let (iz, n) = (1.0 / x.z, [x.x / x.z, x.y / x.z]);
    let d = distortion.distort_with_derivatives(n);
    let [fx, fy, cx, cy] = [
        lens.values[0],
        lens.values[1],
        lens.values[2],
        lens.values[3],
    ];
    let pixel = [fx * d.point[0] + cx, fy * d.point[1] + cy];
    let dn = Matrix2x3::new(iz, 0.0, -n[0] * iz, 0.0, iz, -n[1] * iz);
    let bp = nalgebra::Matrix2::new(
        fx * d.by_point[0][0],
        fx * d.by_point[0][1],
        fy * d.by_point[1][0],
        fy * d.by_point[1][1],
    );
    let by_point = bp * dn;
    let mut by_lens = [[0.0; 2]; 12];
    by_lens[0] = [d.point[0], 0.0];
    by_lens[1] = [0.0, d.point[1]];
    by_lens[2] = [1.0, 0.0];
    by_lens[3] = [0.0, 1.0];
    for k in 0..lens.model.coefficient_count() {
        by_lens[4 + k] = [fx * d.by_coefficient[k][0], fy * d.by_coefficient[k][1]];
    }
    Some(Projected {
        pixel,
        by_point,
        by_lens,
    })
}

fn linearize(state: &State, object: &[Vector3<f64>], seen: &[ViewCorners]) -> Option<Linear> {
    let distortions: Vec<Distortion> = state
        .lenses
        .iter()
        .map(|l| Distortion::new(l.model, &l.values[4..l.len()]).ok())
        .collect::<Option<_>>()?;
    let n = state.len();
    let global = state.global_len();
    let offsets: Vec<usize> = state
        .lenses
        .iter()
        .scan(0, |at, l| {
            let o = *at;
            *at += l.len();
            Some(o)
        })
        .collect();
    let extrinsics_at =
        offsets.last().copied().unwrap_or(0) + state.lenses.last().map_or(0, Lens::len);
    let blocks: Vec<Block> = seen
        .par_iter()
        .enumerate()
        .map(|(v, view)| {
            let pose = state.poses[v];
            // Local parameters: lens 0, [lens 1, extrinsics], pose.
            let mut index: Vec<usize> = (0..state.lenses[0].len()).collect();
            let stereo = state.extrinsics.is_some() && state.lenses.len() == 2;
            if stereo {
                index.extend(offsets[1]..offsets[1] + state.lenses[1].len());
                index.extend(extrinsics_at..extrinsics_at + 6);
            }
            let pose_local = index.len();
            index.extend(global + 6 * v..global + 6 * v + 6);
            let m = index.len();
            let mut jtj = DMatrix::zeros(m, m);
            let mut jtr = DVector::zeros(m);
            let mut error = ViewError::default();
            let sides = [(0, view.left), (1, view.right)];
            for (side, corners) in sides {
                let Some(corners) = corners else { continue };
                if side == 1 && !stereo {
                    continue;
                }
                let lens = &state.lenses[side];
                let (lens_local, extr_local) = if side == 0 {
                    (0, None)
                } else {
                    (
                        state.lenses[0].len(),
                        Some(state.lenses[0].len() + lens.len()),
                    )
                };
                for (p, observed) in object
                    .iter()
                    .zip(corners)
                    .filter_map(|(p, c)| c.map(|c| (p, c)))
                {
                    let rp = pose.rotation * p;
                    let xl = rp + pose.translation;
                    let mut row = [[0.0f64; 2]; 36];
                    let (x, by_pose_rot, by_pose_t, by_extr) = match (side, state.extrinsics) {
                        (1, Some(e)) => {
                            let re = e.rotation.matrix();
                            let x = e.rotation * xl + e.translation;
                            (x, re * (-skew(&rp)), *re, Some(-skew(&(e.rotation * xl))))
                        }
                        _ => (xl, -skew(&rp), Matrix3::identity(), None),
                    };
                    let projected = project(lens, &distortions[side], &x)?;
                    let (pixel, by_x) = (projected.pixel, projected.by_point);
                    let r = [pixel[0] - observed[0], pixel[1] - observed[1]];
                    row[lens_local..lens_local + lens.len()]
                        .copy_from_slice(&projected.by_lens[..lens.len()]);
                    let rot = by_x * by_pose_rot;
                    let tr = by_x * by_pose_t;
                    for c in 0..3 {
                        row[pose_local + c] = [rot[(0, c)], rot[(1, c)]];
                        row[pose_local + 3 + c] = [tr[(0, c)], tr[(1, c)]];
                    }
                    if let (Some(at), Some(by_w)) = (extr_local, by_extr) {
                        let w = by_x * by_w;
                        for c in 0..3 {
                            row[at + c] = [w[(0, c)], w[(1, c)]];
                            row[at + 3 + c] = [by_x[(0, c)], by_x[(1, c)]];
                        }
                    }
                    for a in 0..m {
                        let ja = row[a];
                        if ja == [0.0, 0.0] {
                            continue;
                        }
                        jtr[a] += ja[0] * r[0] + ja[1] * r[1];
                        for b in a..m {
                            jtj[(a, b)] += ja[0] * row[b][0] + ja[1] * row[b][1];
                        }
                    }
                    error.squared[side] += r[0] * r[0] + r[1] * r[1];
                    error.corners[side] += 1;
                }
            }
            Some(Block {
                index,
                jtj,
                jtr,
                error,
            })
        })
        .collect::<Option<Vec<_>>>()?;
    let mut jtj = DMatrix::zeros(n, n);
    let mut jtr = DVector::zeros(n);
    let mut views = Vec::with_capacity(blocks.len());
    let mut shares = Vec::with_capacity(blocks.len());
    let mut cost = 0.0;
    let mut residuals = 0;
    for block in blocks {
        for (a, &ga) in block.index.iter().enumerate() {
            jtr[ga] += block.jtr[a];
            for (b, &gb) in block.index.iter().enumerate().skip(a) {
                let v = block.jtj[(a, b)];
                jtj[(ga, gb)] += v;
                if ga != gb {
                    jtj[(gb, ga)] += v;
                }
            }
        }
        cost += block.error.squared[0] + block.error.squared[1];
        residuals += 2 * (block.error.corners[0] + block.error.corners[1]);
        views.push(block.error);
        shares.push((block.index, block.jtj, block.jtr));
    }
    let mut linear = Linear {
        jtj,
        jtr,
        cost,
        views,
        residuals,
        shares,
    };
    hold(&mut linear, state.held_len());
    cost.is_finite().then_some(linear)
}

/// Holds the first `held` parameters where they are: their rows and columns of the normal
/// equations (each view's share too) become the identity's and their gradient zero, so that
/// every step leaves them and the other parameters' covariance is theirs given these.
fn hold(linear: &mut Linear, held: usize) {
    for i in 0..held {
        linear.jtj.row_mut(i).fill(0.0);
        linear.jtj.column_mut(i).fill(0.0);
        linear.jtj[(i, i)] = 1.0;
        linear.jtr[i] = 0.0;
    }
    for (index, jtj, jtr) in &mut linear.shares {
        for (a, _) in index.iter().enumerate().filter(|(_, g)| **g < held) {
            jtj.row_mut(a).fill(0.0);
            jtj.column_mut(a).fill(0.0);
            jtr[a] = 0.0;
        }
    }
}

/// Zeroes the first `held` rows and columns of a covariance: held parameters do not vary.
fn zero_held(covariance: Option<DMatrix<f64>>, held: usize) -> Option<DMatrix<f64>> {
    covariance.map(|mut c| {
        for i in 0..held {
            c.row_mut(i).fill(0.0);
            c.column_mut(i).fill(0.0);
        }
        c
    })
}

const MAX_ITERATIONS: usize = 200;

/// Refines `start` over the views `seen` (one per pose in `start`) of the board's points
/// `object` until the cost stops falling.
pub fn refine(
    start: State,
    object: &[Vector3<f64>],
    seen: &[ViewCorners],
) -> Result<Solution, SolveFault> {
    debug_assert_eq!(start.poses.len(), seen.len());
    let mut state = start;
    let mut linear = linearize(&state, object, seen).ok_or(SolveFault::BadStart)?;
    let mut lambda = 1e-3;
    let mut iterations = 0;
    while iterations < MAX_ITERATIONS && lambda < 1e12 {
        iterations += 1;
        let mut a = linear.jtj.clone();
        for i in 0..a.nrows() {
            a[(i, i)] += lambda * a[(i, i)].max(1e-12);
        }
        let Some(chol) = a.cholesky() else {
            lambda *= 10.0;
            continue;
        };
        let step = -chol.solve(&linear.jtr);
        let trial = state.moved(&step);
        match linearize(&trial, object, seen) {
            Some(next) if next.cost <= linear.cost => {
                let gain = (linear.cost - next.cost) / linear.cost.max(f64::MIN_POSITIVE);
                state = trial;
                linear = next;
                lambda = (lambda / 10.0).max(1e-12);
                if gain < 1e-12 {
                    break;
                }
            }
            _ => lambda *= 10.0,
        }
    }
    let n = state.len() - state.held_len();
    let dof = linear.residuals.saturating_sub(n).max(1) as f64;
    let sigma2 = linear.cost / dof;
    // Cholesky when JᵀJ is well conditioned; else (a model whose coefficients trade off, as
    // rational_polynomial's numerator and denominator do) the pseudo-inverse, which gives the
    // poorly determined combinations a large variance instead of failing.
    let covariance = match linear.jtj.clone().cholesky() {
        Some(c) => Some(c.inverse() * sigma2),
        None => linear
            .jtj
            .clone()
            .pseudo_inverse(1e-12 * linear.jtj.diagonal().max())
            .ok()
            .map(|p| p * sigma2),
    };
    let held = state.held_len();
    let view_covariance = zero_held(jackknife(&linear, state.global_len()), held);
    let sandwich_covariance = zero_held(
        covariance
            .as_ref()
            .and_then(|c| sandwich(&(c / sigma2), &linear.shares)),
        held,
    );
    let covariance = zero_held(covariance, held);
    let corners: usize = linear
        .views
        .iter()
        .map(|v| v.corners[0] + v.corners[1])
        .sum();
    Ok(Solution {
        rms: (linear.cost / corners.max(1) as f64).sqrt(),
        state,
        views: linear.views,
        covariance,
        view_covariance,
        sandwich_covariance,
        iterations,
    })
}

/// `B·Σ_v g_v·g_vᵀ·B` from the bread `B = (JᵀJ)⁻¹` and the views' shares; `None` with fewer
/// than three views or a bread that is not finite.
fn sandwich(
    bread: &DMatrix<f64>,
    shares: &[(Vec<usize>, DMatrix<f64>, DVector<f64>)],
) -> Option<DMatrix<f64>> {
    if shares.len() < 3 || bread.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let n = bread.nrows();
    let mut covariance = DMatrix::<f64>::zeros(n, n);
    for (index, _, jtr) in shares {
        let mut influence = DVector::<f64>::zeros(n);
        for (a, &ga) in index.iter().enumerate() {
            influence.axpy(jtr[a], &bread.column(ga), 1.0);
        }
        covariance.ger(1.0, &influence, &influence, 1.0);
    }
    Some(covariance)
}

/// The covariance of the whole state as the views scatter it: the jackknife over views,
/// `(G − 1)/G·Σ_v (δ_v − δ̄)(δ_v − δ̄)ᵀ`, where `δ_v` is the one-step change of the optimum
/// without view `v`: for the shared parameters `(S − S_v)⁻¹·g_v` with `S` the normal
/// equations' Schur complement over the poses, `S_v` view `v`'s share of it and `g_v` its
/// `J_vᵀ·r_v`; for each other view's pose what follows from them; view `v`'s own pose held.
/// `None` with fewer than three views or when leaving one out leaves the rest undetermined.
fn jackknife(linear: &Linear, global: usize) -> Option<DMatrix<f64>> {
    let g = linear.shares.len();
    if g < 3 {
        return None;
    }
    let h = &linear.jtj;
    let n = h.nrows();
    // Each view's pose block inverted, and H_pg (6 × global).
    let mut pose_inverse = Vec::with_capacity(g);
    let mut pose_global = Vec::with_capacity(g);
    let mut schur = h.view((0, 0), (global, global)).into_owned();
    for u in 0..g {
        let at = global + 6 * u;
        let inverse = h.view((at, at), (6, 6)).into_owned().try_inverse()?;
        let pg = h.view((at, 0), (6, global)).into_owned();
        schur -= pg.transpose() * &inverse * &pg;
        pose_inverse.push(inverse);
        pose_global.push(pg);
    }
    let mut changes = Vec::with_capacity(g);
    for (v, (index, jtj, jtr)) in linear.shares.iter().enumerate() {
        // View v's own share of the Schur complement: its (JᵀJ)_gg less its pose's part.
        let mut own = pose_global[v].transpose() * &pose_inverse[v] * &pose_global[v];
        own.neg_mut();
        let mut score = DVector::<f64>::zeros(global);
        for (a, &ga) in index.iter().enumerate().filter(|(_, i)| **i < global) {
            score[ga] = jtr[a];
            for (b, &gb) in index
                .iter()
                .enumerate()
                .skip(a)
                .filter(|(_, i)| **i < global)
            {
                own[(ga, gb)] += jtj[(a, b)];
                if ga != gb {
                    own[(gb, ga)] += jtj[(a, b)];
                }
            }
        }
        let shared = (&schur - own).cholesky()?.solve(&score);
        let mut change = DVector::<f64>::zeros(n);
        change.rows_mut(0, global).copy_from(&shared);
        for u in (0..g).filter(|&u| u != v) {
            let pose = -(&pose_inverse[u] * (&pose_global[u] * &shared));
            change.rows_mut(global + 6 * u, 6).copy_from(&pose);
        }
        changes.push(change);
    }
    let mean = changes.iter().sum::<DVector<f64>>() / g as f64;
    let mut covariance = DMatrix::<f64>::zeros(n, n);
    for change in &changes {
        let d = change - &mean;
        covariance.ger(1.0, &d, &d, 1.0);
    }
    let covariance = covariance * ((g - 1) as f64 / g as f64);
    covariance
        .iter()
        .all(|v| v.is_finite())
        .then_some(covariance)
}
