//! How far to trust a calibration where it will be used, as mrcal asks: the σ (px) of where a
//! point at a given distance projects, over a grid across each image, from the parameters'
//! covariance; and cross-validation, two calibrations from disjoint halves of the views
//! compared over the same grid against what their σ predict.
//!
//! The left camera defines the rig's frame, so its σ comes from its lens alone (a point on a
//! pixel's ray projects back to that pixel whatever its distance). The right camera's comes
//! from its lens and the extrinsics: a point at `distance` on the right camera's ray, fixed in
//! the left camera's frame, projected into the right image, which is what matching relies on.
//! Each σ is the worst direction's: the square root of the 2 × 2 covariance's larger
//! eigenvalue. Where no corners fell the distortion is extrapolated, and the σ says so.

use nalgebra::{DMatrix, Matrix2, Rotation3, Vector3};

use super::fit::{Corners, Fit, ViewOutcome, calibrate};
use super::solve::{Lens, Pose};
use crate::camera::{Camera, Model as LensModel, Size};

/// The grid's cells across and down each image.
pub const GRID: (usize, usize) = (16, 12);

/// One camera's projection σ over the grid.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraGrid {
    /// `grid[row][column]`, px; `None` where the lens cannot be inverted.
    pub grid: Vec<Vec<Option<f64>>>,
    pub median_px: f64,
    pub worst_px: f64,
}

/// Both cameras' projection σ for points at `distance` (the board's unit).
#[derive(Debug, Clone, PartialEq)]
pub struct ProjectionUncertainty {
    pub distance: f64,
    pub left: CameraGrid,
    pub right: Option<CameraGrid>,
}

/// How far two halves' calibrations project apart, against what their σ predict.
#[derive(Debug, Clone, PartialEq)]
pub struct CrossValidation {
    /// The median and largest distance between the halves' projections over both cameras'
    /// grids, px.
    pub median_px: f64,
    pub worst_px: f64,
    /// The same of the sum of the two halves' σ in each cell.
    pub predicted_median_px: f64,
    pub predicted_worst_px: f64,
}

impl CrossValidation {
    /// Whether the halves differ by no more than their σ predict.
    pub fn consistent(&self) -> bool {
        self.median_px <= self.predicted_median_px && self.worst_px <= 2.0 * self.predicted_worst_px
    }
}

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
fn cell_centre(size: Size, i: usize, j: usize) -> [f64; 2] {
    [
        (i as f64 + 0.5) * f64::from(size.width) / GRID.0 as f64 - 0.5,
        (j as f64 + 0.5) * f64::from(size.height) / GRID.1 as f64 - 0.5,
    ]
}

/// What one camera's projection depends on: the lens's parameters, then (for the right
/// camera) the extrinsics' (ω, T), as the covariance orders them.
struct Model {
    lens: Lens,
    /// The extrinsics, for the right camera: R, T.
    extrinsics: Option<Pose>,
    /// Where its parameters start in the covariance, and how many.
    at: usize,
    len: usize,
}

impl Model {
    fn of(fit: &Fit, right: bool) -> Option<Model> {
        let left = &fit.left.camera;
        let left_lens = Lens::new(left.intrinsics(), &left.distortion());
        if !right {
            return Some(Model {
                len: left_lens.len(),
                lens: left_lens,
                extrinsics: None,
                at: 0,
            });
        }
        let camera = &fit.right.as_ref()?.camera;
        let e = fit.extrinsics?;
        let lens = Lens::new(camera.intrinsics(), &camera.distortion());
        Some(Model {
            len: lens.len() + 6,
            lens,
            extrinsics: Some(Pose {
                rotation: e.rotation,
                translation: e.translation,
            }),
            at: left_lens.len(),
        })
    }

    fn camera(&self) -> Option<Camera> {
        self.lens.camera()
    }

    /// The point (in the left camera's frame, or the camera's own for the left one) whose
    /// image is `pixel`, at `distance` from the camera.
    fn point(&self, pixel: [f64; 2], distance: f64) -> Option<Vector3<f64>> {
        let [x, y] = self.camera()?.normalize(pixel)?;
        let ray = Vector3::new(x, y, 1.0).normalize() * distance;
        Some(match self.extrinsics {
            Some(pose) => pose.rotation.inverse() * (ray - pose.translation),
            None => ray,
        })
    }

    /// Where `point` projects with the parameters moved by `step`.
    fn project(&self, point: &Vector3<f64>, step: &[f64]) -> Option<[f64; 2]> {
        self.project_turned(point, step, Vector3::zeros())
    }

    /// Where `point`, first turned by the rotation vector `turn` about the frame's origin,
    /// projects with the parameters moved by `step`.
    fn project_turned(
        &self,
        point: &Vector3<f64>,
        step: &[f64],
        turn: Vector3<f64>,
    ) -> Option<[f64; 2]> {
        let point = &(Rotation3::from_scaled_axis(turn) * point);
        let camera = self.lens.moved(step).camera()?;
        let seen = match self.extrinsics {
            Some(pose) => pose.moved(&step[self.lens.len()..]).apply(point),
            None => *point,
        };
        camera.project(&seen)
    }

    /// The worst direction's σ of where each of `points` projects, with what a turn of the
    /// whole frame explains taken out: a lens whose principal point moves while its frame
    /// turns the other way projects every point where it did, so that part of the
    /// covariance is the frame's, not the lens's (mrcal's reasoning; here the turn that best
    /// explains the change over these points, as mrcal's `projection_diff` fits it).
    fn sigmas(&self, points: &[Vector3<f64>], covariance: &DMatrix<f64>) -> Option<Vec<f64>> {
        let cov = covariance.view((self.at, self.at), (self.len, self.len));
        let n = points.len();
        let mut jacobian = DMatrix::<f64>::zeros(2 * n, self.len);
        let mut turns = DMatrix::<f64>::zeros(2 * n, 3);
        let mut step = vec![0.0; self.len];
        for i in 0..self.len {
            let h = 1e-3 * cov[(i, i)].max(0.0).sqrt().max(1e-9);
            for (k, point) in points.iter().enumerate() {
                step[i] = h;
                let plus = self.project(point, &step)?;
                step[i] = -h;
                let minus = self.project(point, &step)?;
                for c in 0..2 {
                    jacobian[(2 * k + c, i)] = (plus[c] - minus[c]) / (2.0 * h);
                }
            }
            step[i] = 0.0;
        }
        for axis in 0..3 {
            let mut turn = Vector3::zeros();
            for (k, point) in points.iter().enumerate() {
                turn[axis] = 1e-6;
                let plus = self.project_turned(point, &step, turn)?;
                turn[axis] = -1e-6;
                let minus = self.project_turned(point, &step, turn)?;
                for c in 0..2 {
                    turns[(2 * k + c, axis)] = (plus[c] - minus[c]) / 2e-6;
                }
            }
        }
        // Take out of each column what a turn explains: J − T·(TᵀT)⁻¹·Tᵀ·J.
        let normal = (turns.transpose() * &turns).try_inverse()?;
        let explained = &turns * (normal * (turns.transpose() * &jacobian));
        let lens_only = jacobian - explained;
        let spread = &lens_only * cov * lens_only.transpose();
        (0..n)
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
}

/// The grid's cells whose pixel `model` can turn into a point at `distance`: each cell's
/// (column, row, pixel, point).
fn grid_points(
    model: &Model,
    size: Size,
    distance: f64,
) -> Vec<(usize, usize, [f64; 2], Vector3<f64>)> {
    let mut cells = Vec::with_capacity(GRID.0 * GRID.1);
    for j in 0..GRID.1 {
        for i in 0..GRID.0 {
            let pixel = cell_centre(size, i, j);
            if let Some(point) = model.point(pixel, distance) {
                cells.push((i, j, pixel, point));
            }
        }
    }
    cells
}

/// The median and largest of `values`, 0 when there are none.
fn median_and_worst(values: &mut [f64]) -> (f64, f64) {
    values.sort_by(f64::total_cmp);
    match values {
        [] => (0.0, 0.0),
        _ => (values[values.len() / 2], values[values.len() - 1]),
    }
}

fn camera_grid(fit: &Fit, right: bool, distance: f64) -> Option<CameraGrid> {
    let model = Model::of(fit, right)?;
    let cells = grid_points(&model, fit.size, distance);
    let points: Vec<Vector3<f64>> = cells.iter().map(|c| c.3).collect();
    let sigmas = model.sigmas(&points, &fit.covariance)?;
    let mut grid = vec![vec![None; GRID.0]; GRID.1];
    for (&(i, j, _, _), &sigma) in cells.iter().zip(&sigmas) {
        grid[j][i] = Some(sigma);
    }
    let mut values = sigmas;
    let (median_px, worst_px) = median_and_worst(&mut values);
    Some(CameraGrid {
        grid,
        median_px,
        worst_px,
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

/// Two calibrations of disjoint halves of the views compared over both cameras' grids: where
/// half `a` says a point at `distance` is seen, against where half `b` projects it after the
/// turn of the frame that best aligns the two (fitted over the grid, as mrcal's
/// `projection_diff` does), beside the sum of the two halves' σ there.
pub fn cross_validate(a: &Fit, b: &Fit, distance: f64) -> Option<CrossValidation> {
    let (mut differences, mut predicted) = (Vec::new(), Vec::new());
    let sides: &[bool] = if a.right.is_some() && b.right.is_some() {
        &[false, true]
    } else {
        &[false]
    };
    for &right in sides {
        let (ma, mb) = (Model::of(a, right)?, Model::of(b, right)?);
        let cells = grid_points(&ma, a.size, distance);
        let points: Vec<Vector3<f64>> = cells.iter().map(|c| c.3).collect();
        let zero = vec![0.0; mb.len];
        let miss = |turn: Vector3<f64>| -> Option<Vec<f64>> {
            let mut out = Vec::with_capacity(2 * cells.len());
            for (_, _, pixel, point) in &cells {
                let seen = mb.project_turned(point, &zero, turn)?;
                out.extend([seen[0] - pixel[0], seen[1] - pixel[1]]);
            }
            Some(out)
        };
        // Gauss–Newton on the turn, by central differences.
        let mut turn = Vector3::zeros();
        for _ in 0..4 {
            let r = DMatrix::from_vec(2 * cells.len(), 1, miss(turn)?);
            let mut j = DMatrix::<f64>::zeros(2 * cells.len(), 3);
            for axis in 0..3 {
                let mut d = Vector3::zeros();
                d[axis] = 1e-6;
                let (plus, minus) = (miss(turn + d)?, miss(turn - d)?);
                for k in 0..plus.len() {
                    j[(k, axis)] = (plus[k] - minus[k]) / 2e-6;
                }
            }
            let step = (j.transpose() * &j).try_inverse()? * (j.transpose() * r);
            turn -= Vector3::new(step[0], step[1], step[2]);
        }
        let residual = miss(turn)?;
        let (sa, sb) = (
            ma.sigmas(&points, &a.covariance)?,
            mb.sigmas(&points, &b.covariance)?,
        );
        for k in 0..cells.len() {
            differences.push(residual[2 * k].hypot(residual[2 * k + 1]));
            predicted.push(sa[k] + sb[k]);
        }
    }
    if differences.is_empty() {
        return None;
    }
    let (median_px, worst_px) = median_and_worst(&mut differences);
    let (predicted_median_px, predicted_worst_px) = median_and_worst(&mut predicted);
    Some(CrossValidation {
        median_px,
        worst_px,
        predicted_median_px,
        predicted_worst_px,
    })
}

/// Calibrates two disjoint halves of the views `fit` used (with the target's corners
/// `object`) (alternate ones, so that each half
/// spans the session) and compares them over the grid ([`cross_validate`]); `Err` with the
/// number of views used when the halves cannot both be calibrated (fewer than 6 views).
pub fn cross_validation(
    object: &[Vector3<f64>],
    model: LensModel,
    fit: &Fit,
    views: &[Corners],
    stereo: bool,
    distance: f64,
) -> Result<CrossValidation, usize> {
    let used: Vec<usize> = (0..fit.views.len())
        .filter(|&v| fit.views[v].status == ViewOutcome::Used)
        .collect();
    if used.len() < 6 {
        return Err(used.len());
    }
    let half = |parity: usize| -> Option<Fit> {
        let views: Vec<Corners> = views
            .iter()
            .enumerate()
            .map(|(v, c)| match used.iter().position(|&u| u == v) {
                Some(k) if k % 2 == parity => c.clone(),
                _ => Corners {
                    left: None,
                    right: None,
                },
            })
            .collect();
        calibrate(object, fit.size, model, &views, stereo).ok()
    };
    let (a, b) = (half(0).ok_or(used.len())?, half(1).ok_or(used.len())?);
    cross_validate(&a, &b, distance).ok_or(used.len())
}
