//! Cross-validation of a calibration, as mrcal checks one: two calibrations from disjoint
//! halves of the views compared over the projection grid (the rigid motion between their
//! frames fitted near the centre, as mrcal's `projection_diff`), against what their
//! projection σ ([`super::uncertainty`]) predict for the difference of two independent
//! estimates.

use nalgebra::{DMatrix, DVector, Rotation3, Vector3};

use super::fit::{Corners, Fit, ViewOutcome, calibrate};
use super::solve::Pose;
use super::uncertainty::{
    GRID, cell_centre, in_focus, median, median_and_worst, projection_uncertainty,
};
use crate::camera::{Camera, Model as LensModel, Size};

/// A distance over the grids' cells, px: its median and its largest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OverCells {
    pub median: f64,
    pub worst: f64,
}

/// How far two halves' calibrations project apart, against what their σ predict.
#[derive(Debug, Clone, PartialEq)]
pub struct CrossValidation {
    /// The distance between the halves' projections over both cameras' grids.
    pub observed: OverCells,
    /// The sum of the two halves' σ in each cell.
    pub predicted: OverCells,
    /// Observed over predicted, cell by cell, the median: over the whole grid, over its
    /// centre, and over its edges.
    pub ratio: f64,
    pub ratio_centre: f64,
    pub ratio_edge: f64,
}

/// The range observed over predicted keeps for the σ to be called true.
pub const CONSISTENT: (f64, f64) = (0.7, 1.4);

impl CrossValidation {
    /// Whether the halves differ as their σ predict: observed over predicted within
    /// [`CONSISTENT`].
    pub fn consistent(&self) -> bool {
        (CONSISTENT.0..=CONSISTENT.1).contains(&self.ratio)
    }
}

/// Where camera `b` sees the points camera `a` sees at each of `pixels` at `distance`, after
/// the rigid motion between their frames that best aligns them near the image's centre
/// (within [`super::uncertainty::FOCUS`] of the shorter side), as mrcal's `projection_diff` fits it: each
/// pixel's distance, px.
pub fn projection_difference(
    a: &Camera,
    b: &Camera,
    size: Size,
    pixels: &[[f64; 2]],
    distance: f64,
) -> Option<Vec<f64>> {
    let points: Vec<Vector3<f64>> = pixels
        .iter()
        .map(|&q| {
            let [x, y] = a.normalize(q)?;
            Some(Vector3::new(x, y, 1.0).normalize() * distance)
        })
        .collect::<Option<_>>()?;
    let focus: Vec<usize> = (0..pixels.len())
        .filter(|&k| in_focus(pixels[k], size))
        .collect();
    if focus.len() < 3 {
        return None;
    }
    let moved = |motion: &[f64; 6], k: usize| -> Option<[f64; 2]> {
        let pose = Pose {
            rotation: Rotation3::from_scaled_axis(Vector3::new(motion[0], motion[1], motion[2])),
            translation: Vector3::new(motion[3], motion[4], motion[5]),
        };
        let q = b.project(&pose.apply(&points[k]))?;
        Some([q[0] - pixels[k][0], q[1] - pixels[k][1]])
    };
    let misses = |motion: &[f64; 6]| -> Option<DVector<f64>> {
        let mut out = Vec::with_capacity(2 * focus.len());
        for &k in &focus {
            out.extend(moved(motion, k)?);
        }
        Some(DVector::from_vec(out))
    };
    // Gauss–Newton with a little damping: at one distance a shift across the view and a turn
    // about the other axis look alike, and the damping picks the smaller of the two.
    let mut motion = [0.0; 6];
    for _ in 0..8 {
        let r = misses(&motion)?;
        let mut j = DMatrix::<f64>::zeros(r.len(), 6);
        for p in 0..6 {
            let h = if p < 3 { 1e-6 } else { 1e-6 * distance };
            let (mut plus, mut minus) = (motion, motion);
            plus[p] += h;
            minus[p] -= h;
            let column = (misses(&plus)? - misses(&minus)?) / (2.0 * h);
            j.set_column(p, &column);
        }
        let mut normal = j.transpose() * &j;
        for p in 0..6 {
            normal[(p, p)] *= 1.0 + 1e-6;
        }
        let step = normal.cholesky()?.solve(&(j.transpose() * r));
        for p in 0..6 {
            motion[p] -= step[p];
        }
    }
    (0..pixels.len())
        .map(|k| moved(&motion, k).map(|m| m[0].hypot(m[1])))
        .collect()
}

/// Whether a pixel lies in the image's centre (within half of the way to each edge, an
/// ellipse) for [`CrossValidation`]'s split.
fn central(pixel: [f64; 2], size: Size) -> bool {
    let (w, h) = (f64::from(size.width), f64::from(size.height));
    ((pixel[0] - (w - 1.0) / 2.0) / (w / 2.0)).hypot((pixel[1] - (h - 1.0) / 2.0) / (h / 2.0)) < 0.5
}

/// Two calibrations of disjoint halves of the views compared over both cameras' grids
/// ([`projection_difference`], each camera on its own), beside what their σ predict for the
/// difference of two independent estimates, √(σ_a² + σ_b²).
pub fn cross_validate(a: &Fit, b: &Fit, distance: f64) -> Option<CrossValidation> {
    let (mut differences, mut predicted) = (Vec::new(), Vec::new());
    let (mut ratios, mut centre, mut edge) = (Vec::new(), Vec::new(), Vec::new());
    let sides: &[bool] = if a.right.is_some() && b.right.is_some() {
        &[false, true]
    } else {
        &[false]
    };
    let (ga, gb) = (
        projection_uncertainty(a, Some(distance))?,
        projection_uncertainty(b, Some(distance))?,
    );
    for &right in sides {
        let (ca, cb, sa, sb) = if right {
            (
                &a.right.as_ref()?.camera,
                &b.right.as_ref()?.camera,
                ga.right.as_ref()?,
                gb.right.as_ref()?,
            )
        } else {
            (&a.left.camera, &b.left.camera, &ga.left, &gb.left)
        };
        let mut pixels = Vec::new();
        let mut sigmas = Vec::new();
        for j in 0..GRID.1 {
            for i in 0..GRID.0 {
                if let (Some(x), Some(y)) = (sa.grid[j][i], sb.grid[j][i]) {
                    pixels.push(cell_centre(a.size, i, j));
                    sigmas.push(x.hypot(y));
                }
            }
        }
        let d = projection_difference(ca, cb, a.size, &pixels, distance)?;
        for ((&d, &s), &q) in d.iter().zip(&sigmas).zip(&pixels) {
            differences.push(d);
            predicted.push(s);
            if s > 0.0 {
                let ratio = d / s;
                ratios.push(ratio);
                if central(q, a.size) {
                    centre.push(ratio);
                } else {
                    edge.push(ratio);
                }
            }
        }
    }
    if differences.is_empty() {
        return None;
    }
    let over_cells = |values: &mut Vec<f64>| {
        let (median, worst) = median_and_worst(values);
        OverCells { median, worst }
    };
    Some(CrossValidation {
        observed: over_cells(&mut differences),
        predicted: over_cells(&mut predicted),
        ratio: median(ratios),
        ratio_centre: median(centre),
        ratio_edge: median(edge),
    })
}

/// How many ways [`cross_validation`] splits the views into two halves.
pub const SPLITS: usize = 8;

/// Splits the views `fit` used (with the target's corners `object`) into two halves [`SPLITS`]
/// ways (alternate views, the first half against the second, then seeded shuffles), calibrates
/// each half and compares the two over the grid ([`cross_validate`]); the answer is each figure's
/// median over the splits, since one split is one draw of two calibrations' errors. `Err` with
/// the number of views used when fewer than 6 were used or no split's halves both calibrate.
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
    let count = used.len();
    if count < 6 {
        return Err(count);
    }
    let mut rng = crate::noise::Rng::new(69);
    let splits: Vec<Vec<bool>> = (0..SPLITS)
        .map(|k| match k {
            0 => (0..count).map(|i| i % 2 == 0).collect(),
            1 => (0..count).map(|i| i < count / 2).collect(),
            _ => {
                let mut order: Vec<usize> = (0..count).collect();
                for i in (1..count).rev() {
                    order.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
                }
                let mut half = vec![false; count];
                for &i in &order[..count / 2] {
                    half[i] = true;
                }
                half
            }
        })
        .collect();
    let half = |side: &[bool], want: bool| -> Option<Fit> {
        let views: Vec<Corners> = views
            .iter()
            .enumerate()
            .map(|(v, c)| match used.iter().position(|&u| u == v) {
                Some(k) if side[k] == want => c.clone(),
                _ => Corners {
                    left: None,
                    right: None,
                },
            })
            .collect();
        calibrate(object, fit.size, model, &views, stereo).ok()
    };
    let compared: Vec<CrossValidation> = splits
        .iter()
        .filter_map(|side| cross_validate(&half(side, true)?, &half(side, false)?, distance))
        .collect();
    if compared.is_empty() {
        return Err(count);
    }
    let figure = |f: fn(&CrossValidation) -> f64| median(compared.iter().map(f).collect());
    Ok(CrossValidation {
        observed: OverCells {
            median: figure(|c| c.observed.median),
            worst: figure(|c| c.observed.worst),
        },
        predicted: OverCells {
            median: figure(|c| c.predicted.median),
            worst: figure(|c| c.predicted.worst),
        },
        ratio: figure(|c| c.ratio),
        ratio_centre: figure(|c| c.ratio_centre),
        ratio_edge: figure(|c| c.ratio_edge),
    })
}
