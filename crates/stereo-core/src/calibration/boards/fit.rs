//! The calibration itself, as OpenCV's `calibrateCamera` then `stereoCalibrate` with
//! `USE_INTRINSIC_GUESS` do it: each camera from Zhang's first guess refined on its own, views
//! whose error is far above the others' left out, then both cameras and R, T refined together
//! over the pairs, with each parameter's standard deviation, the epipolar check and the
//! rectified rig's uncertainty.

use nalgebra::{DMatrix, DMatrixView, Matrix3, Rotation3, Vector3};

use super::solve::{Lens, Pose, Solution, SolveFault, State, ViewCorners, refine};
use super::zhang;
use crate::camera::{
    Camera, Distortion, Model, Rectification, RectifyOptions, Size, StereoPair, stereo_rectify,
};

/// The fewest views a calibration takes.
pub const MIN_VIEWS: usize = 3;

/// A view whose RMS is above this many times the median, and above [`OUTLIER_FLOOR_PX`], is
/// left out as an outlier.
pub const OUTLIER_RATIO: f64 = 3.0;
pub const OUTLIER_FLOOR_PX: f64 = 0.5;

/// One camera's corners in one view, in the order of the target's object points: `None` for
/// a corner it did not see (a ChArUco board partly out of the frame). A chessboard found
/// gives every corner.
pub type Seen = Vec<Option<[f64; 2]>>;

/// Every corner of a chessboard found whole: each seen.
pub fn whole(points: &[[f64; 2]]) -> Seen {
    points.iter().copied().map(Some).collect()
}

/// The corners found in one view (`None` where the board was not found).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Corners {
    pub left: Option<Seen>,
    pub right: Option<Seen>,
}

/// What became of one view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ViewOutcome {
    Used,
    BoardNotFound,
    Outlier,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewFit {
    pub status: ViewOutcome,
    pub rms_left: Option<f64>,
    pub rms_right: Option<f64>,
    /// The board's pose in the left camera, where it was estimated.
    pub pose: Option<Pose>,
}

/// One calibrated camera: the camera, the standard deviation of each parameter (fx, fy, cx,
/// cy, then the coefficients in OpenCV's order) and its RMS over the views used.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraFit {
    pub camera: Camera,
    pub std: Vec<f64>,
    pub rms: f64,
}

/// The pair's extrinsics (X_right = R·X_left + T) with their standard deviations: the
/// rotation's about each axis in radians, the translation's per axis in the board's unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extrinsics {
    pub rotation: Rotation3<f64>,
    pub translation: Vector3<f64>,
    pub rotation_std: [f64; 3],
    pub translation_std: [f64; 3],
}

#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    pub model: Model,
    pub size: Size,
    pub left: CameraFit,
    pub right: Option<CameraFit>,
    pub extrinsics: Option<Extrinsics>,
    pub views: Vec<ViewFit>,
    /// The RMS reprojection error (px) over every corner used, both cameras.
    pub rms: f64,
    /// Every parameter's covariance, the boards' poses included.
    pub joint: Joint,
    /// Whether the lenses were held at an earlier calibration's
    /// ([`super::again::Start::hold`]): their σ are zero here, the earlier calibration's own.
    pub held: bool,
}

/// The whole state's covariance: the shared parameters (see [`Fit::covariance`]), then each
/// used view's board pose (ω, T) in the order of `poses`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Joint {
    /// The boards' poses in the left camera, one per view used.
    pub poses: Vec<Pose>,
    /// From the corners' noise: σ²·(JᵀJ)⁻¹, σ² from the residuals.
    pub noise: DMatrix<f64>,
    /// As the views scatter it (see [`super::solve::Solution::view_covariance`]); `None`
    /// when it could not be formed.
    pub views: Option<DMatrix<f64>>,
    /// The views' sandwich (see [`super::solve::Solution::sandwich_covariance`]).
    pub sandwich: Option<DMatrix<f64>>,
}

/// Why a calibration could not be made.
#[derive(Debug, Clone, PartialEq)]
pub enum FitFault {
    /// Fewer than `needed` views ([`MIN_VIEWS`], or [`super::again::MIN_VIEWS_HELD`] with the
    /// lenses held) are usable (board found in every camera, not an outlier).
    TooFewViews { usable: usize, needed: usize },
    /// The views' homographies give no camera matrix (the boards are all alike or degenerate).
    NoFirstGuess,
    /// The refinement could not start or its covariance is singular (the views do not
    /// determine the parameters).
    Degenerate,
}

impl std::fmt::Display for FitFault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FitFault::TooFewViews { usable, needed } => write!(
                f,
                "{usable} usable views; a calibration needs at least {needed}"
            ),
            FitFault::NoFirstGuess => write!(
                f,
                "the boards' homographies give no camera matrix: show the board at different tilts"
            ),
            FitFault::Degenerate => write!(
                f,
                "the views do not determine the camera's parameters: show the board at different tilts and places"
            ),
        }
    }
}

impl From<SolveFault> for FitFault {
    fn from(_: SolveFault) -> Self {
        FitFault::Degenerate
    }
}

/// Calibrates one camera (`stereo` false: each view's `left`) or a pair (views whose board was
/// found in both cameras) from the target's corners on its plane (`object`, z = 0) and the
/// views' corners in that order. Each camera uses every corner it saw; a pair's joint fit
/// does not need a corner seen by both, since each camera's residuals hold on their own.
pub fn calibrate(
    object: &[Vector3<f64>],
    size: Size,
    model: Model,
    views: &[Corners],
    stereo: bool,
) -> Result<Fit, FitFault> {
    let object = object.to_vec();
    let found: Vec<bool> = views
        .iter()
        .map(|v| v.left.is_some() && (!stereo || v.right.is_some()))
        .collect();
    let mut used: Vec<usize> = (0..views.len()).filter(|&v| found[v]).collect();
    if used.len() < MIN_VIEWS {
        return Err(FitFault::TooFewViews {
            usable: used.len(),
            needed: MIN_VIEWS,
        });
    }
    let left_of = |v: usize| views[v].left.as_deref().unwrap_or_default();
    let right_of = |v: usize| views[v].right.as_deref().unwrap_or_default();
    let mono_left = single(&object, size, model, &mut used, &left_of)?;
    if !stereo {
        return finish(size, model, views, &found, mono_left, false);
    }
    let mono_right = single(&object, size, model, &mut used, &right_of)?;
    // Both single fits' views may have shrunk; keep the views both kept.
    let keep: Vec<usize> = used.clone();
    let pose_of = |solution: &Solution, kept: &[usize], v: usize| {
        kept.iter()
            .position(|&k| k == v)
            .map(|i| solution.state.poses[i])
    };
    let left_kept = &mono_left.1;
    let right_kept = &mono_right.1;
    let mut poses = Vec::new();
    let mut relative = Vec::new();
    for &v in &keep {
        let (Some(l), Some(r)) = (
            pose_of(&mono_left.0, left_kept, v),
            pose_of(&mono_right.0, right_kept, v),
        ) else {
            continue;
        };
        relative.push(right_from_left(&l, &r));
        poses.push(l);
    }
    let extrinsics = average(&relative).ok_or(FitFault::Degenerate)?;
    let state = State {
        lenses: vec![mono_left.0.state.lenses[0], mono_right.0.state.lenses[0]],
        extrinsics: Some(extrinsics),
        poses,
        held: false,
    };
    let joint = together(state, &object, views, keep, MIN_VIEWS)?;
    finish(size, model, views, &found, joint, true)
}

/// Both cameras, R, T and the poses refined together from `state` over the views `kept` (one
/// pose each), repeated without the views whose error is far above the others' while at
/// least `fewest` remain. Returns the solution and the views it kept.
pub(super) fn together(
    mut state: State,
    object: &[Vector3<f64>],
    views: &[Corners],
    mut kept: Vec<usize>,
    fewest: usize,
) -> Result<(Solution, Vec<usize>), FitFault> {
    loop {
        let seen: Vec<ViewCorners> = kept
            .iter()
            .map(|&v| ViewCorners {
                left: views[v].left.as_deref(),
                right: views[v].right.as_deref(),
            })
            .collect();
        let solution = refine(state.clone(), object, &seen)?;
        let rms: Vec<f64> = solution
            .views
            .iter()
            .map(|e| e.rms(0).unwrap_or(0.0).max(e.rms(1).unwrap_or(0.0)))
            .collect();
        let out = outliers(&rms);
        if out.is_empty() || kept.len() - out.len() < fewest {
            return Ok((solution, kept));
        }
        state = solution.state;
        for &i in out.iter().rev() {
            kept.remove(i);
            state.poses.remove(i);
        }
    }
}

/// The positions (in `rms`) of views whose RMS is far above the median.
fn outliers(rms: &[f64]) -> Vec<usize> {
    let mut sorted = rms.to_vec();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let limit = (OUTLIER_RATIO * median).max(OUTLIER_FLOOR_PX);
    (0..rms.len()).filter(|&i| rms[i] > limit).collect()
}

/// One camera over the views `used` (which loses its outliers): Zhang's guess, then the
/// refinement, repeated without the outliers. Returns the solution and the views it kept.
fn single<'a>(
    object: &[Vector3<f64>],
    size: Size,
    model: Model,
    used: &mut Vec<usize>,
    corners_of: &dyn Fn(usize) -> &'a [Option<[f64; 2]>],
) -> Result<(Solution, Vec<usize>), FitFault> {
    let homographies: Vec<_> = used
        .iter()
        .map(|&v| {
            let (plane, seen): (Vec<[f64; 2]>, Vec<[f64; 2]>) = object
                .iter()
                .zip(corners_of(v))
                .filter_map(|(p, c)| c.map(|c| ([p.x, p.y], c)))
                .unzip();
            zhang::homography(&plane, &seen)
        })
        .collect();
    let valid: Vec<_> = homographies.iter().flatten().copied().collect();
    let k = zhang::intrinsics(&valid, size).ok_or(FitFault::NoFirstGuess)?;
    let mut kept = Vec::new();
    let mut poses = Vec::new();
    for (&v, h) in used.iter().zip(&homographies) {
        if let Some((rotation, translation)) = h.as_ref().and_then(|h| zhang::pose(h, &k)) {
            kept.push(v);
            poses.push(Pose {
                rotation,
                translation,
            });
        }
    }
    if kept.len() < MIN_VIEWS {
        return Err(FitFault::TooFewViews {
            usable: kept.len(),
            needed: MIN_VIEWS,
        });
    }
    let mut state = State {
        lenses: vec![Lens::new(k, &Distortion::none(model))],
        extrinsics: None,
        poses,
        held: false,
    };
    loop {
        let seen: Vec<ViewCorners> = kept
            .iter()
            .map(|&v| ViewCorners {
                left: Some(corners_of(v)),
                right: None,
            })
            .collect();
        let solution = refine(state.clone(), object, &seen)?;
        let rms: Vec<f64> = solution
            .views
            .iter()
            .map(|e| e.rms(0).unwrap_or(0.0))
            .collect();
        let out = outliers(&rms);
        if out.is_empty() || kept.len() - out.len() < MIN_VIEWS {
            used.retain(|v| kept.contains(v));
            return Ok((solution, kept));
        }
        state = solution.state;
        for &i in out.iter().rev() {
            kept.remove(i);
            state.poses.remove(i);
        }
    }
}

/// The right camera's pose from the left's (X_right = R·X_left + T) from one board's pose in
/// each.
pub(super) fn right_from_left(left: &Pose, right: &Pose) -> Pose {
    let rotation = right.rotation * left.rotation.inverse();
    Pose {
        rotation,
        translation: right.translation - rotation * left.translation,
    }
}

/// The mean of several rigid motions: the rotation matrices' mean projected back onto the
/// rotations, the translations' component-wise median.
pub(super) fn average(poses: &[Pose]) -> Option<Pose> {
    if poses.is_empty() {
        return None;
    }
    let sum: Matrix3<f64> = poses.iter().map(|p| *p.rotation.matrix()).sum();
    let rotation = Rotation3::from_matrix_eps(
        &(sum / poses.len() as f64),
        1e-12,
        100,
        Rotation3::identity(),
    );
    let median = |k: usize| {
        let mut v: Vec<f64> = poses.iter().map(|p| p.translation[k]).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    Some(Pose {
        rotation,
        translation: Vector3::new(median(0), median(1), median(2)),
    })
}

/// The fit from the final solution over the views `kept`.
pub(super) fn finish(
    size: Size,
    model: Model,
    views: &[Corners],
    found: &[bool],
    (solution, kept): (Solution, Vec<usize>),
    stereo: bool,
) -> Result<Fit, FitFault> {
    let covariance = solution.covariance.clone().ok_or(FitFault::Degenerate)?;
    let std = |at: usize, len: usize| -> Vec<f64> {
        (at..at + len)
            .map(|i| covariance[(i, i)].max(0.0).sqrt())
            .collect()
    };
    let lenses = &solution.state.lenses;
    let camera_fit = |side: usize, at: usize| -> Result<CameraFit, FitFault> {
        let squared: f64 = solution.views.iter().map(|e| e.squared[side]).sum();
        let corners: usize = solution.views.iter().map(|e| e.corners[side]).sum();
        Ok(CameraFit {
            camera: lenses[side].camera().ok_or(FitFault::Degenerate)?,
            std: std(at, lenses[side].len()),
            rms: (squared / corners.max(1) as f64).sqrt(),
        })
    };
    let left = camera_fit(0, 0)?;
    let (right, extrinsics) = if stereo {
        let right = camera_fit(1, lenses[0].len())?;
        let at = lenses[0].len() + lenses[1].len();
        let e = solution.state.extrinsics.ok_or(FitFault::Degenerate)?;
        let s = std(at, 6);
        (
            Some(right),
            Some(Extrinsics {
                rotation: e.rotation,
                translation: e.translation,
                rotation_std: [s[0], s[1], s[2]],
                translation_std: [s[3], s[4], s[5]],
            }),
        )
    } else {
        (None, None)
    };
    let view_fits = (0..views.len())
        .map(|v| {
            if let Some(i) = kept.iter().position(|&k| k == v) {
                let e = solution.views[i];
                ViewFit {
                    status: ViewOutcome::Used,
                    rms_left: e.rms(0),
                    rms_right: e.rms(1),
                    pose: Some(solution.state.poses[i]),
                }
            } else {
                ViewFit {
                    status: if found[v] {
                        ViewOutcome::Outlier
                    } else {
                        ViewOutcome::BoardNotFound
                    },
                    rms_left: None,
                    rms_right: None,
                    pose: None,
                }
            }
        })
        .collect();
    Ok(Fit {
        model,
        size,
        left,
        right,
        extrinsics,
        views: view_fits,
        rms: solution.rms,
        joint: Joint {
            poses: solution.state.poses.clone(),
            views: solution.view_covariance.clone(),
            sandwich: solution.sandwich_covariance.clone(),
            noise: covariance,
        },
        held: false,
    })
}

impl Fit {
    /// The covariance of the shared parameters: the left lens, then the right lens and the
    /// extrinsics' (ω, T) for a pair (the joint covariance less its poses).
    pub fn covariance(&self) -> DMatrixView<'_, f64> {
        let shared = self.joint.noise.nrows() - 6 * self.joint.poses.len();
        self.joint.noise.view((0, 0), (shared, shared))
    }

    /// The calibrated pair, when two cameras were calibrated.
    pub fn pair(&self) -> Option<StereoPair> {
        let (right, e) = (self.right.as_ref()?, self.extrinsics?);
        Some(StereoPair {
            left: self.left.camera,
            right: right.camera,
            rotation: e.rotation,
            translation: e.translation,
        })
    }

    /// The essential matrix E = [T]ₓ R.
    pub fn essential(&self) -> Option<Matrix3<f64>> {
        Some(self.pair()?.essential())
    }

    /// The fundamental matrix K₂⁻ᵀ E K₁⁻¹, scaled so that F₃₃ = 1 as OpenCV returns it.
    pub fn fundamental(&self) -> Option<Matrix3<f64>> {
        Some(self.pair()?.fundamental())
    }

    /// The mean distance (px) of each corner from its partner's epipolar line, both ways, over
    /// the views used, after undistortion: OpenCV's `stereo_calib.cpp` check.
    pub fn epipolar_error(&self, views: &[Corners]) -> Option<f64> {
        let pair = self.pair()?;
        let f = self.fundamental()?;
        let ideal = |camera: &Camera, p: [f64; 2]| {
            let n = camera.normalize(p)?;
            let k = camera.intrinsics();
            Some(Vector3::new(k.fx * n[0] + k.cx, k.fy * n[1] + k.cy, 1.0))
        };
        let (mut sum, mut count) = (0.0, 0usize);
        for (view, fit) in views.iter().zip(&self.views) {
            if fit.status != ViewOutcome::Used {
                continue;
            }
            let (Some(left), Some(right)) = (&view.left, &view.right) else {
                continue;
            };
            for (l, r) in left.iter().zip(right) {
                let (Some(l), Some(r)) = (l, r) else {
                    continue;
                };
                let (pl, pr) = (ideal(&pair.left, *l)?, ideal(&pair.right, *r)?);
                let line_r = f * pl;
                let line_l = f.transpose() * pr;
                sum += (line_r.dot(&pr) / line_r.xy().norm()).abs()
                    + (line_l.dot(&pl) / line_l.xy().norm()).abs();
                count += 1;
            }
        }
        (count > 0).then(|| sum / count as f64)
    }

    /// Each seen corner's residual in a view used, px: where the calibrated model projects
    /// the target's corner (`object`) minus where it was found (`[left, right]`, `None` for a
    /// camera whose board was not found or a view left out). What Kalibr's report draws as
    /// arrows.
    pub fn residuals(
        &self,
        object: &[Vector3<f64>],
        index: usize,
        view: &Corners,
    ) -> [Option<Vec<[f64; 2]>>; 2] {
        let fit = self.views.get(index);
        let Some(pose) = fit
            .filter(|f| f.status == ViewOutcome::Used)
            .and_then(|f| f.pose)
        else {
            return [None, None];
        };
        let side = |camera: &Camera, found: &Option<Seen>, right: bool| {
            let found = found.as_ref()?;
            found
                .iter()
                .zip(object)
                .filter_map(|(c, p)| c.map(|c| (c, p)))
                .map(|(c, p)| {
                    let mut x = pose.apply(p);
                    if right {
                        let e = self.extrinsics?;
                        x = e.rotation * x + e.translation;
                    }
                    let [u, v] = camera.project(&x)?;
                    Some([u - c[0], v - c[1]])
                })
                .collect::<Option<Vec<_>>>()
        };
        [
            side(&self.left.camera, &view.left, false),
            self.right
                .as_ref()
                .and_then(|r| side(&r.camera, &view.right, true)),
        ]
    }

    /// Bouguet's rectification of the calibrated pair.
    pub fn rectify(&self, options: RectifyOptions) -> Option<Rectification> {
        stereo_rectify(&self.pair()?, self.size, options).ok()
    }

    /// The standard deviations of the rectified rig's focal length (px) and baseline (board
    /// unit), propagated from the covariance through `stereoRectify` by central differences.
    pub fn rig_std(&self, options: RectifyOptions) -> Option<[f64; 2]> {
        let pair = self.pair()?;
        let e = self.extrinsics?;
        let lenses = [Lens::of(&pair.left), Lens::of(&pair.right)];
        let covariance = self.covariance();
        let n = covariance.nrows();
        let outputs = |step: &[f64]| -> Option<[f64; 2]> {
            let left = lenses[0].moved(step);
            let right = lenses[1].moved(&step[left.len()..]);
            let at = left.len() + right.len();
            let pose = Pose {
                rotation: e.rotation,
                translation: e.translation,
            }
            .moved(&step[at..]);
            let moved = StereoPair {
                left: left.camera()?,
                right: right.camera()?,
                rotation: pose.rotation,
                translation: pose.translation,
            };
            let r = stereo_rectify(&moved, self.size, options).ok()?;
            Some([r.p1[(0, 0)], pose.translation.norm()])
        };
        let mut gradient = DMatrix::zeros(2, n);
        for i in 0..n {
            let h = 1e-4 * covariance[(i, i)].max(0.0).sqrt().max(1e-9);
            let mut step = vec![0.0; n];
            step[i] = h;
            let plus = outputs(&step)?;
            step[i] = -h;
            let minus = outputs(&step)?;
            for k in 0..2 {
                gradient[(k, i)] = (plus[k] - minus[k]) / (2.0 * h);
            }
        }
        let cov = &gradient * covariance * gradient.transpose();
        Some([cov[(0, 0)].max(0.0).sqrt(), cov[(1, 1)].max(0.0).sqrt()])
    }
}
