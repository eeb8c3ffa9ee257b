//! One camera's Levenberg–Marquardt refinement (plumb_bob: fx fy cx cy k1 k2 p1 p2 k3 and
//! every view's pose), from the same Zhang start and on the same corners, by our solver
//! (`calibrate::solve::refine`, analytic Jacobians), the `levenberg-marquardt` crate (MINPACK's
//! LM, Jacobian by forward-mode dual numbers) and `tiny-solver` (its LM, autodiff factors).
//!
//!   solvers SET_DIR SUMMARY_JSON
//!
//! SET_DIR is a set `examples/boards.rs render` wrote (its `truth.json`); SUMMARY_JSON is
//! `/calibrate?corners=true`'s answer on it, whose corners every solver uses.

use std::collections::HashMap;
use std::time::Instant;

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use na34::{DMatrix, DVector, Dyn, Owned, SVector};
use num_dual::DualSVec64;
use stereo_distance::calibration::boards::solve::{Lens, Pose, State, ViewCorners, refine};
use stereo_distance::calibration::boards::zhang;
use stereo_distance::camera::{Distortion, Model, Size};
use tiny_solver::Optimizer;

const INTRINSICS: usize = 9;
const PER_VIEW: usize = INTRINSICS + 6;

/// One view's residuals (u, v per corner, projected − observed) for the intrinsics and a pose
/// (Rodrigues vector, translation), in any field: f64, or dual numbers for the Jacobian.
fn residuals<T: na34::RealField>(
    k: &[T],
    pose: &[T],
    object: &[[f64; 3]],
    seen: &[[f64; 2]],
) -> DVector<T> {
    let c = |x: f64| T::from_f64(x).unwrap();
    let (rx, ry, rz) = (pose[0].clone(), pose[1].clone(), pose[2].clone());
    let theta2 = rx.clone() * rx.clone() + ry.clone() * ry.clone() + rz.clone() * rz.clone();
    let theta = theta2.clone().sqrt();
    // R = I + a [r]x + b [r]x², a = sin θ / θ, b = (1 − cos θ) / θ².
    let (a, b) = if theta2.clone() < c(1e-16) {
        (c(1.0), c(0.5))
    } else {
        (
            theta.clone().sin() / theta.clone(),
            (c(1.0) - theta.clone().cos()) / theta2.clone(),
        )
    };
    let skew = na34::Matrix3::new(
        c(0.0),
        -rz.clone(),
        ry.clone(),
        rz.clone(),
        c(0.0),
        -rx.clone(),
        -ry.clone(),
        rx.clone(),
        c(0.0),
    );
    let r = na34::Matrix3::identity() + skew.clone() * a + skew.clone() * skew * b;
    let t = na34::Vector3::new(pose[3].clone(), pose[4].clone(), pose[5].clone());
    let mut out = DVector::from_element(2 * object.len(), c(0.0));
    for (i, (p, q)) in object.iter().zip(seen).enumerate() {
        let x = &r * na34::Vector3::new(c(p[0]), c(p[1]), c(p[2])) + &t;
        let (xn, yn) = (x[0].clone() / x[2].clone(), x[1].clone() / x[2].clone());
        let r2 = xn.clone() * xn.clone() + yn.clone() * yn.clone();
        let radial = c(1.0)
            + k[4].clone() * r2.clone()
            + k[5].clone() * r2.clone() * r2.clone()
            + k[8].clone() * r2.clone() * r2.clone() * r2.clone();
        let xy = xn.clone() * yn.clone();
        let xd = xn.clone() * radial.clone()
            + c(2.0) * k[6].clone() * xy.clone()
            + k[7].clone() * (r2.clone() + c(2.0) * xn.clone() * xn.clone());
        let yd = yn.clone() * radial
            + k[6].clone() * (r2 + c(2.0) * yn.clone() * yn)
            + c(2.0) * k[7].clone() * xy;
        out[2 * i] = k[0].clone() * xd + k[2].clone() - c(q[0]);
        out[2 * i + 1] = k[1].clone() * yd + k[3].clone() - c(q[1]);
    }
    out
}

/// The problem as the `levenberg-marquardt` crate takes it: all parameters in one vector.
struct Whole<'a> {
    params: DVector<f64>,
    object: &'a [[f64; 3]],
    views: &'a [Vec<[f64; 2]>],
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Whole<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.params.copy_from(x);
    }
    fn params(&self) -> DVector<f64> {
        self.params.clone()
    }
    fn residuals(&self) -> Option<DVector<f64>> {
        let k = &self.params.as_slice()[..INTRINSICS];
        let per = 2 * self.object.len();
        let mut out = DVector::zeros(per * self.views.len());
        for (v, seen) in self.views.iter().enumerate() {
            let pose = &self.params.as_slice()[INTRINSICS + 6 * v..INTRINSICS + 6 * v + 6];
            out.rows_mut(v * per, per)
                .copy_from(&residuals(k, pose, self.object, seen));
        }
        Some(out)
    }
    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let per = 2 * self.object.len();
        let n = self.params.len();
        let mut jac = DMatrix::zeros(per * self.views.len(), n);
        for (v, seen) in self.views.iter().enumerate() {
            let at = INTRINSICS + 6 * v;
            let mut x = SVector::<f64, PER_VIEW>::zeros();
            x.fixed_rows_mut::<INTRINSICS>(0)
                .copy_from_slice(&self.params.as_slice()[..INTRINSICS]);
            x.fixed_rows_mut::<6>(INTRINSICS)
                .copy_from_slice(&self.params.as_slice()[at..at + 6]);
            let (_, j) = num_dual::jacobian(
                |x: SVector<DualSVec64<PER_VIEW>, PER_VIEW>| {
                    residuals(
                        &x.as_slice()[..INTRINSICS],
                        &x.as_slice()[INTRINSICS..],
                        self.object,
                        seen,
                    )
                },
                &x,
            );
            for row in 0..per {
                for col in 0..INTRINSICS {
                    jac[(v * per + row, col)] = j[(row, col)];
                }
                for col in 0..6 {
                    jac[(v * per + row, at + col)] = j[(row, INTRINSICS + col)];
                }
            }
        }
        Some(jac)
    }
}

/// One view as a `tiny-solver` factor over the blocks `k` and `pose{i}`.
struct ViewFactor {
    object: Vec<[f64; 3]>,
    seen: Vec<[f64; 2]>,
}

impl<T: na34::RealField> tiny_solver::factors::Factor<T> for ViewFactor {
    fn residual_func(&self, params: &[DVector<T>]) -> DVector<T> {
        residuals(
            params[0].as_slice(),
            params[1].as_slice(),
            &self.object,
            &self.seen,
        )
    }
}

fn rodrigues(r: &nalgebra::Rotation3<f64>) -> [f64; 3] {
    let v = r.scaled_axis();
    [v.x, v.y, v.z]
}

fn report(name: &str, k: &[f64], rms: f64, iterations: String, ms: f64, truth: &serde_json::Value) {
    let f = |key: &str| truth[key].as_f64().unwrap();
    println!(
        "{name:<24} fx {:.4} (err {:.4} %)  cx {:.3} cy {:.3} (pp err {:.3} px)  k1 {:.5}  rms {:.5} px  {iterations:>16}  {ms:.1} ms",
        k[0],
        100.0 * (k[0] / f("fx") - 1.0).abs(),
        k[2],
        k[3],
        (k[2] - f("cx")).hypot(k[3] - f("cy")),
        k[4],
        rms
    );
}

fn main() {
    let mut args = std::env::args().skip(1);
    let dir = args.next().expect("SET_DIR");
    let summary = args.next().expect("SUMMARY_JSON");
    let read = |p: &str| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
    };
    let truth = read(&format!("{dir}/truth.json"));
    let ours = read(&summary);
    let board = &truth["board"];
    let (columns, rows) = (
        board["columns"].as_u64().unwrap() as usize,
        board["rows"].as_u64().unwrap() as usize,
    );
    let square = board["square_size"].as_f64().unwrap();
    let object: Vec<[f64; 3]> = (0..rows)
        .flat_map(|r| (0..columns).map(move |c| [c as f64 * square, r as f64 * square, 0.0]))
        .collect();
    let plane: Vec<[f64; 2]> = object.iter().map(|p| [p[0], p[1]]).collect();
    let views: Vec<Vec<[f64; 2]>> = ours["views"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|v| v["status"] == "used")
        .map(|v| serde_json::from_value(v["corners_left"].clone()).unwrap())
        .collect();
    let size = Size {
        width: truth["image_width"].as_u64().unwrap() as u32,
        height: truth["image_height"].as_u64().unwrap() as u32,
    };

    // The same start for all: Zhang's closed form, no distortion, each view's pose from its
    // homography.
    let homographies: Vec<_> = views
        .iter()
        .map(|v| zhang::homography(&plane, v).unwrap())
        .collect();
    let k = zhang::intrinsics(&homographies, size).unwrap();
    let poses: Vec<Pose> = homographies
        .iter()
        .map(|h| {
            let (rotation, translation) = zhang::pose(h, &k).unwrap();
            Pose {
                rotation,
                translation,
            }
        })
        .collect();
    let start_k = [k.fx, k.fy, k.cx, k.cy, 0.0, 0.0, 0.0, 0.0, 0.0];
    println!(
        "{} views of {} corners; Zhang's start fx {:.2} cx {:.2} cy {:.2}; truth fx {:.4} cx {:.3} cy {:.3}",
        views.len(),
        object.len(),
        k.fx,
        k.cx,
        k.cy,
        truth["left"]["fx"],
        truth["left"]["cx"],
        truth["left"]["cy"]
    );
    let corners = (views.len() * object.len()) as f64;
    let rms_of = |k: &[f64], poses: &[[f64; 6]]| {
        let sum: f64 = views
            .iter()
            .zip(poses)
            .map(|(v, p)| residuals(k, p, &object, v).norm_squared())
            .sum();
        (sum / corners).sqrt()
    };
    let start_poses: Vec<[f64; 6]> = poses
        .iter()
        .map(|p| {
            let r = rodrigues(&p.rotation);
            [
                r[0],
                r[1],
                r[2],
                p.translation.x,
                p.translation.y,
                p.translation.z,
            ]
        })
        .collect();

    // Ours (its time includes the covariance at the optimum).
    let object3: Vec<nalgebra::Vector3<f64>> = object
        .iter()
        .map(|p| nalgebra::Vector3::new(p[0], p[1], p[2]))
        .collect();
    let whole: Vec<Vec<Option<[f64; 2]>>> = views
        .iter()
        .map(|v| v.iter().copied().map(Some).collect())
        .collect();
    let seen: Vec<ViewCorners> = whole
        .iter()
        .map(|v| ViewCorners {
            left: Some(v.as_slice()),
            right: None,
        })
        .collect();
    let clock = Instant::now();
    let solution = refine(
        State {
            lenses: vec![Lens::new(k, &Distortion::none(Model::PlumbBob))],
            extrinsics: None,
            poses: poses.clone(),
        },
        &object3,
        &seen,
    )
    .unwrap();
    let ms = clock.elapsed().as_secs_f64() * 1e3;
    report(
        "ours",
        &solution.state.lenses[0].values[..INTRINSICS],
        solution.rms,
        format!("{} iterations", solution.iterations),
        ms,
        &truth["left"],
    );

    // levenberg-marquardt 0.15.
    let mut params = DVector::from_column_slice(&start_k);
    for p in &start_poses {
        params = params.push(p[0]);
        for &x in &p[1..] {
            params = params.push(x);
        }
    }
    let clock = Instant::now();
    let (solved, lm_report) = LevenbergMarquardt::new().minimize(Whole {
        params,
        object: &object,
        views: &views,
    });
    let ms = clock.elapsed().as_secs_f64() * 1e3;
    let kk = &solved.params.as_slice()[..INTRINSICS];
    let solved_poses: Vec<[f64; 6]> = (0..views.len())
        .map(|v| {
            let s = &solved.params.as_slice()[INTRINSICS + 6 * v..INTRINSICS + 6 * v + 6];
            [s[0], s[1], s[2], s[3], s[4], s[5]]
        })
        .collect();
    report(
        "levenberg-marquardt 0.15",
        kk,
        rms_of(kk, &solved_poses),
        format!("{} evaluations", lm_report.number_of_evaluations),
        ms,
        &truth["left"],
    );

    // tiny-solver 0.18.
    let mut problem = tiny_solver::Problem::new();
    let mut initial = HashMap::new();
    initial.insert("k".to_owned(), DVector::from_column_slice(&start_k));
    for (i, (v, p)) in views.iter().zip(&start_poses).enumerate() {
        let name = format!("pose{i}");
        problem.add_residual_block(
            2 * object.len(),
            &["k", name.as_str()],
            Box::new(ViewFactor {
                object: object.clone(),
                seen: v.clone(),
            }),
            None,
        );
        initial.insert(name, DVector::from_column_slice(p));
    }
    let clock = Instant::now();
    let result = tiny_solver::LevenbergMarquardtOptimizer::default()
        .optimize(&problem, &initial, None)
        .unwrap();
    let ms = clock.elapsed().as_secs_f64() * 1e3;
    let kk: Vec<f64> = result["k"].iter().copied().collect();
    let solved_poses: Vec<[f64; 6]> = (0..views.len())
        .map(|i| {
            let s = &result[&format!("pose{i}")];
            [s[0], s[1], s[2], s[3], s[4], s[5]]
        })
        .collect();
    report(
        "tiny-solver 0.18",
        &kk,
        rms_of(&kk, &solved_poses),
        "".to_owned(),
        ms,
        &truth["left"],
    );
}
