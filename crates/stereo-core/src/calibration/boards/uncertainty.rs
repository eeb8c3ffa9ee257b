//! How far to trust a calibration where it will be used, as mrcal asks: the σ (px) of where a
//! point at a given distance projects, over a grid across each image (cross-validation, in
//! [`super::cross_validation`], checks it against two calibrations of disjoint halves).
//!
//! The point is held fixed to the calibration boards (mrcal's mean over the boards' frames), so
//! that a principal point which moves while every board's pose moves with it moves nothing.
//! What a rigid move of the camera's frame explains near the image's centre is then taken out,
//! as mrcal's `projection_diff` takes it out of a comparison: a frame that moves is not a lens
//! that errs. The σ comes from how the parameters scatter when the views change (the geometric
//! mean of the jackknife and the sandwich over views, [`super::solve::Solution::view_covariance`]
//! and [`super::solve::Solution::sandwich_covariance`]): noise and what the lens model cannot
//! fit on a real lens both move it, and only the first shows in σ²·(JᵀJ)⁻¹. The
//! two parts are reported apart. Each σ is the worst direction's: the square root of the
//! 2 × 2 covariance's larger eigenvalue. Where no corners fell the distortion is
//! extrapolated, and the σ says so.

use nalgebra::{DMatrix, Matrix2, Rotation3, Vector3};

use super::fit::{Fit, ViewOutcome};
use super::solve::{Lens, Pose};
use crate::camera::{Camera, Size};

/// The grid's cells across and down each image.
pub const GRID: (usize, usize) = (16, 12);

/// One camera's projection σ over the grid.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraGrid {
    /// `grid[row][column]`, px; `None` where the lens cannot be inverted.
    pub grid: Vec<Vec<Option<f64>>>,
    pub median_px: f64,
    pub worst_px: f64,
    /// The median over the grid of the part the corners' noise explains (σ²·(JᵀJ)⁻¹).
    pub noise_median_px: f64,
    /// The median over the grid of the rest, what the lens model cannot fit:
    /// √(max(0, σ² − σ_noise²)) cell by cell.
    pub model_median_px: f64,
    /// The views whose scatter gave the σ.
    pub views: usize,
}

impl CameraGrid {
    /// Whether what the model cannot fit dominates: over the grid, more than [`DOMINATES`]
    /// times the noise's part, from at least [`SCATTER_VIEWS`] views. On an exact model the
    /// two parts come out about equal; a lean model on a real lens leaves twice the noise's
    /// part and more. Fewer views scatter too little to tell the two apart.
    pub fn model_error_dominates(&self) -> bool {
        self.views >= SCATTER_VIEWS && self.model_median_px > DOMINATES * self.noise_median_px
    }
}

/// The fewest views whose scatter can tell the model's part from the noise's (as many as
/// cross-validation's two halves need).
pub const SCATTER_VIEWS: usize = 6;

/// Both cameras' projection σ for points at `distance` (the board's unit).
#[derive(Debug, Clone, PartialEq)]
pub struct ProjectionUncertainty {
    pub distance: f64,
    pub left: CameraGrid,
    pub right: Option<CameraGrid>,
}

/// How many times the noise's part the model's must be to dominate.
pub const DOMINATES: f64 = 1.5;

/// The focus of [`super::cross_validation::projection_difference`]'s fit, as a share of the image's shorter side (mrcal's
/// default, a sixth).
pub const FOCUS: f64 = 1.0 / 6.0;

/// The median distance of the boards from the left camera over the views used.
pub fn board_distance(fit: &Fit) -> Option<f64> {
    let mut d: Vec<f64> = fit
        .views
        .iter()
        .filter(|v| v.status == ViewOutcome::Used)
        .filter_map(|v| v.pose.map(|p| p.translation.norm()))
        .collect();
    if d.is_empty() {
        return None;
    }
    d.sort_by(f64::total_cmp);
    Some(d[d.len() / 2])
}

/// The centre of cell (i, j) of the grid over an image of `size`.
pub(super) fn cell_centre(size: Size, i: usize, j: usize) -> [f64; 2] {
    [
        (i as f64 + 0.5) * f64::from(size.width) / GRID.0 as f64 - 0.5,
        (j as f64 + 0.5) * f64::from(size.height) / GRID.1 as f64 - 0.5,
    ]
}

/// One camera's projection of points fixed to the boards, as the whole state moves: the
/// lenses, the extrinsics and every board pose, in the joint covariance's order.
struct Model<'a> {
    fit: &'a Fit,
    right: bool,
    /// The lenses, the extrinsics (pairs) and where each block starts in the state.
    lenses: Vec<Lens>,
    extrinsics: Option<Pose>,
    global: usize,
}

impl<'a> Model<'a> {
    fn of(fit: &'a Fit, right: bool) -> Option<Model<'a>> {
        let mut lenses = vec![Lens::of(&fit.left.camera)];
        let mut extrinsics = None;
        if let (Some(r), Some(e)) = (fit.right.as_ref(), fit.extrinsics) {
            lenses.push(Lens::of(&r.camera));
            extrinsics = Some(Pose {
                rotation: e.rotation,
                translation: e.translation,
            });
        } else if right {
            return None;
        }
        let global =
            lenses.iter().map(Lens::len).sum::<usize>() + 6 * usize::from(extrinsics.is_some());
        let n = global + 6 * fit.joint.poses.len();
        (fit.joint.noise.nrows() == n && !fit.joint.poses.is_empty()).then_some(Model {
            fit,
            right,
            lenses,
            extrinsics,
            global,
        })
    }

    fn len(&self) -> usize {
        self.fit.joint.noise.nrows()
    }

    /// The camera's lens, the extrinsics (right camera) and the poses, moved by `step` (the
    /// whole state's).
    fn moved(&self, step: &[f64]) -> Option<(Camera, Option<Pose>, Vec<Pose>)> {
        let l0 = self.lenses[0].len();
        let camera = if self.right {
            self.lenses[1].moved(&step[l0..]).camera()?
        } else {
            self.lenses[0].moved(step).camera()?
        };
        let extrinsics = match (self.right, self.extrinsics) {
            (true, Some(e)) => Some(e.moved(&step[self.global - 6..self.global])),
            _ => None,
        };
        let poses = self
            .fit
            .joint
            .poses
            .iter()
            .enumerate()
            .map(|(i, p)| p.moved(&step[self.global + 6 * i..self.global + 6 * i + 6]))
            .collect();
        Some((camera, extrinsics, poses))
    }

    /// The point seen at `pixel` at `distance` from this camera, in each board's frame (the
    /// nominal state's): what stays fixed while the state moves, as mrcal holds it.
    fn anchors(&self, pixel: [f64; 2], distance: f64) -> Option<Vec<Vector3<f64>>> {
        let lens = &self.lenses[usize::from(self.right)];
        let [x, y] = lens.camera()?.normalize(pixel)?;
        let mut point = Vector3::new(x, y, 1.0).normalize() * distance;
        if let (true, Some(e)) = (self.right, self.extrinsics) {
            point = e.rotation.inverse() * (point - e.translation);
        }
        Some(
            self.fit
                .joint
                .poses
                .iter()
                .map(|p| p.rotation.inverse() * (point - p.translation))
                .collect(),
        )
    }

    /// Where the point whose board-frame copies are `anchors` projects in the moved state:
    /// the mean of its copies carried back by each moved pose (mrcal's mean over frames).
    fn project(
        moved: &(Camera, Option<Pose>, Vec<Pose>),
        anchors: &[Vector3<f64>],
    ) -> Option<[f64; 2]> {
        let (camera, extrinsics, poses) = moved;
        let mean = poses
            .iter()
            .zip(anchors)
            .map(|(p, a)| p.apply(a))
            .sum::<Vector3<f64>>()
            / anchors.len() as f64;
        let seen = match extrinsics {
            Some(e) => e.apply(&mean),
            None => mean,
        };
        camera.project(&seen)
    }

    /// Each cell's projection Jacobian by the whole state (2 rows per cell), by central
    /// differences scaled to each parameter's σ.
    fn jacobian(&self, anchors: &[Vec<Vector3<f64>>]) -> Option<DMatrix<f64>> {
        let n = self.len();
        let noise = &self.fit.joint.noise;
        let mut jacobian = DMatrix::<f64>::zeros(2 * anchors.len(), n);
        let mut step = vec![0.0; n];
        for i in 0..n {
            let h = 1e-3 * noise[(i, i)].max(0.0).sqrt().max(1e-9);
            step[i] = h;
            let plus = self.moved(&step)?;
            step[i] = -h;
            let minus = self.moved(&step)?;
            step[i] = 0.0;
            for (k, a) in anchors.iter().enumerate() {
                let (p, m) = (Self::project(&plus, a)?, Self::project(&minus, a)?);
                for c in 0..2 {
                    jacobian[(2 * k + c, i)] = (p[c] - m[c]) / (2.0 * h);
                }
            }
        }
        Some(jacobian)
    }
}

impl Model<'_> {
    /// `jacobian` with what a rigid motion of the camera's frame explains near the image's
    /// centre taken out of each cell: `J − M·(M_fᵀ·M_f)⁻¹·M_fᵀ·J_f`, where `M` is how each
    /// cell moves with the motion (ω, T) and `_f` keeps the cells within [`FOCUS`].
    fn aligned(
        &self,
        jacobian: &DMatrix<f64>,
        cells: &[Cell],
        size: Size,
        distance: f64,
    ) -> Option<DMatrix<f64>> {
        let camera = self.lenses[usize::from(self.right)].camera()?;
        let mut motion = DMatrix::<f64>::zeros(2 * cells.len(), 6);
        let mut focus = Vec::new();
        for (k, cell) in cells.iter().enumerate() {
            let [x, y] = camera.normalize(cell.2)?;
            let point = Vector3::new(x, y, 1.0).normalize() * distance;
            for p in 0..6 {
                let h = if p < 3 { 1e-6 } else { 1e-6 * distance };
                let mut step = [0.0; 6];
                step[p] = h;
                let at = |sign: f64| {
                    let s: Vec<f64> = step.iter().map(|v| sign * v).collect();
                    let pose = Pose {
                        rotation: Rotation3::identity(),
                        translation: Vector3::zeros(),
                    }
                    .moved(&s);
                    camera.project(&pose.apply(&point))
                };
                let (plus, minus) = (at(1.0)?, at(-1.0)?);
                for c in 0..2 {
                    motion[(2 * k + c, p)] = (plus[c] - minus[c]) / (2.0 * h);
                }
            }
            if in_focus(cell.2, size) {
                focus.push(k);
            }
        }
        if focus.len() < 3 {
            return None;
        }
        let rows: Vec<usize> = focus.iter().flat_map(|&k| [2 * k, 2 * k + 1]).collect();
        let mf = motion.select_rows(&rows);
        let jf = jacobian.select_rows(&rows);
        let mut normal = mf.transpose() * &mf;
        for p in 0..6 {
            normal[(p, p)] *= 1.0 + 1e-6;
        }
        let explained = normal.cholesky()?.solve(&(mf.transpose() * jf));
        Some(jacobian - motion * explained)
    }
}

/// Whether `pixel` lies within [`FOCUS`] of the shorter side from the image's centre, where a
/// rigid motion of the frame is fitted.
pub(super) fn in_focus(pixel: [f64; 2], size: Size) -> bool {
    let (w, h) = (f64::from(size.width), f64::from(size.height));
    (pixel[0] - (w - 1.0) / 2.0).hypot(pixel[1] - (h - 1.0) / 2.0) <= FOCUS * w.min(h)
}

/// The worst direction's σ of each cell from the projection Jacobian and a covariance.
fn worst_sigmas(jacobian: &DMatrix<f64>, covariance: &DMatrix<f64>) -> Vec<Option<f64>> {
    let spread = jacobian * covariance * jacobian.transpose();
    (0..jacobian.nrows() / 2)
        .map(|k| {
            let c = Matrix2::new(
                spread[(2 * k, 2 * k)],
                spread[(2 * k, 2 * k + 1)],
                spread[(2 * k + 1, 2 * k)],
                spread[(2 * k + 1, 2 * k + 1)],
            );
            let largest = c.symmetric_eigenvalues().max();
            largest.is_finite().then(|| largest.max(0.0).sqrt())
        })
        .collect()
}

/// The grid's cells whose pixel `model`'s camera can turn into a point at `distance`: each
/// cell's (column, row, pixel, the point's copies in the boards' frames).
type Cell = (usize, usize, [f64; 2], Vec<Vector3<f64>>);

fn grid_cells(model: &Model, size: Size, distance: f64) -> Vec<Cell> {
    let mut cells = Vec::with_capacity(GRID.0 * GRID.1);
    for j in 0..GRID.1 {
        for i in 0..GRID.0 {
            let pixel = cell_centre(size, i, j);
            if let Some(anchors) = model.anchors(pixel, distance) {
                cells.push((i, j, pixel, anchors));
            }
        }
    }
    cells
}

/// The median and largest of `values`, 0 when there are none.
pub(super) fn median_and_worst(values: &mut [f64]) -> (f64, f64) {
    values.sort_by(f64::total_cmp);
    match values {
        [] => (0.0, 0.0),
        _ => (values[values.len() / 2], values[values.len() - 1]),
    }
}

/// Lays per-cell values out on the grid.
fn laid_out(cells: &[Cell], values: &[Option<f64>]) -> Vec<Vec<Option<f64>>> {
    let mut grid = vec![vec![None; GRID.0]; GRID.1];
    for (c, &v) in cells.iter().zip(values) {
        grid[c.1][c.0] = v;
    }
    grid
}

fn camera_grid(fit: &Fit, right: bool, distance: f64) -> Option<CameraGrid> {
    let model = Model::of(fit, right)?;
    let cells = grid_cells(&model, fit.size, distance);
    let anchors: Vec<Vec<Vector3<f64>>> = cells.iter().map(|c| c.3.clone()).collect();
    let jacobian = model.jacobian(&anchors)?;
    // A rigid move of the camera's frame is not an error of the lens: it is taken out near the
    // centre, as a comparison of two calibrations takes it out. Without a centre to fit it on
    // (a tiny image), the points stay fixed to the boards alone.
    let aligned = model
        .aligned(&jacobian, &cells, fit.size, distance)
        .unwrap_or(jacobian);
    let noise = worst_sigmas(&aligned, &fit.joint.noise);
    // The views' own scatter holds the noise and what the model cannot fit; without it (fewer
    // than three views) the noise is all there is to say.
    // The jackknife runs high over few views and the sandwich low; their geometric mean is
    // the bias-reduced (CR2) estimate when the views weigh alike.
    let total = match (&fit.joint.views, &fit.joint.sandwich) {
        (Some(jackknife), Some(sandwich)) => worst_sigmas(&aligned, jackknife)
            .into_iter()
            .zip(worst_sigmas(&aligned, sandwich))
            .map(|(j, s)| Some((j? * s?).sqrt()))
            .collect(),
        (Some(jackknife), None) => worst_sigmas(&aligned, jackknife),
        _ => noise.clone(),
    };
    let model_part: Vec<f64> = total
        .iter()
        .zip(&noise)
        .filter_map(|(&t, &n)| Some((t?.powi(2) - n?.powi(2)).max(0.0).sqrt()))
        .collect();
    let grid = laid_out(&cells, &total);
    let mut values: Vec<f64> = total.iter().flatten().copied().collect();
    let (median_px, worst_px) = median_and_worst(&mut values);
    Some(CameraGrid {
        grid,
        median_px,
        worst_px,
        noise_median_px: median(noise.into_iter().flatten().collect()),
        model_median_px: median(model_part),
        views: fit.joint.poses.len(),
    })
}

/// The projection σ over each camera's grid, for points at `distance` (default: the boards'
/// median distance).
pub fn projection_uncertainty(fit: &Fit, distance: Option<f64>) -> Option<ProjectionUncertainty> {
    let distance = distance.or_else(|| board_distance(fit))?;
    Some(ProjectionUncertainty {
        distance,
        left: camera_grid(fit, false, distance)?,
        right: if fit.right.is_some() {
            Some(camera_grid(fit, true, distance)?)
        } else {
            None
        },
    })
}

/// The median of `values`, 0 when there are none.
pub(super) fn median(mut values: Vec<f64>) -> f64 {
    median_and_worst(&mut values).0
}
