//! The lens distortion models users have, in OpenCV's order and ROS's names: `plumb_bob`
//! (k1 k2 p1 p2 k3), `rational_polynomial` (k1 k2 p1 p2 k3 k4 k5 k6) and the `equidistant`
//! fisheye (k1 k2 k3 k4). Each maps an ideal normalized point (X/Z, Y/Z) to the distorted one,
//! with its Jacobians, and back by Newton's method with a convergence check.

use std::fmt;

/// Which distortion model, by the names ROS's `camera_info` gives them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Model {
    /// Brown–Conrady as OpenCV's default: k1 k2 p1 p2 k3.
    PlumbBob,
    /// OpenCV's `CALIB_RATIONAL_MODEL`: k1 k2 p1 p2 k3 k4 k5 k6.
    RationalPolynomial,
    /// OpenCV's `fisheye` module (equidistant, θ_d = θ(1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸)).
    Equidistant,
}

impl Model {
    /// Every model, in the order the API lists them.
    pub const ALL: [Model; 3] = [
        Model::PlumbBob,
        Model::RationalPolynomial,
        Model::Equidistant,
    ];

    /// The name ROS's `camera_info` (and this service) gives the model.
    pub fn name(self) -> &'static str {
        match self {
            Model::PlumbBob => "plumb_bob",
            Model::RationalPolynomial => "rational_polynomial",
            Model::Equidistant => "equidistant",
        }
    }

    /// The model a name stands for (ROS's names; `fisheye` too, as OpenCV calls it).
    pub fn from_name(name: &str) -> Option<Model> {
        match name {
            "plumb_bob" => Some(Model::PlumbBob),
            "rational_polynomial" => Some(Model::RationalPolynomial),
            "equidistant" | "fisheye" => Some(Model::Equidistant),
            _ => None,
        }
    }

    /// How many coefficients the model has.
    pub fn coefficient_count(self) -> usize {
        match self {
            Model::PlumbBob => 5,
            Model::RationalPolynomial => 8,
            Model::Equidistant => 4,
        }
    }
}

impl fmt::Display for Model {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Why a distortion cannot be built.
#[derive(Debug, Clone, PartialEq)]
pub enum DistortionFault {
    /// More coefficients than the model has.
    TooMany { model: Model, given: usize },
    /// A coefficient (0-based, OpenCV's order) that is not a finite number.
    NotFinite { index: usize },
}

impl fmt::Display for DistortionFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DistortionFault::TooMany { model, given } => write!(
                f,
                "{model} has {} coefficients, {given} were given",
                model.coefficient_count()
            ),
            DistortionFault::NotFinite { index } => {
                write!(f, "coefficient {} is not a finite number", index + 1)
            }
        }
    }
}

/// A distortion: its model and coefficients in OpenCV's order (those not given are 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distortion {
    model: Model,
    coefficients: [f64; 8],
}

/// A distorted point with its derivatives: by the ideal point (2 × 2, row-major) and by each
/// coefficient in OpenCV's order (`by_coefficient[i]` = (∂x_d/∂c_i, ∂y_d/∂c_i)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distorted {
    pub point: [f64; 2],
    pub by_point: [[f64; 2]; 2],
    pub by_coefficient: [[f64; 2]; 8],
}

/// Newton's iterations allowed when undistorting, and the residual (in normalized units,
/// about 1e-9 px at any focal length users have) that counts as converged.
const UNDISTORT_ITERATIONS: usize = 50;
const UNDISTORT_TOLERANCE: f64 = 1e-13;

impl Distortion {
    /// A distortion of `model` with up to its number of coefficients, in OpenCV's order (a
    /// shorter list is padded with zeros, as OpenCV reads 4 of plumb_bob's 5).
    pub fn new(model: Model, coefficients: &[f64]) -> Result<Distortion, DistortionFault> {
        if coefficients.len() > model.coefficient_count() {
            return Err(DistortionFault::TooMany {
                model,
                given: coefficients.len(),
            });
        }
        if let Some(index) = coefficients.iter().position(|c| !c.is_finite()) {
            return Err(DistortionFault::NotFinite { index });
        }
        let mut all = [0.0; 8];
        all[..coefficients.len()].copy_from_slice(coefficients);
        Ok(Distortion {
            model,
            coefficients: all,
        })
    }

    /// No distortion, in `model`'s terms.
    pub fn none(model: Model) -> Distortion {
        Distortion {
            model,
            coefficients: [0.0; 8],
        }
    }

    pub fn model(&self) -> Model {
        self.model
    }

    /// The model's coefficients in OpenCV's order.
    pub fn coefficients(&self) -> &[f64] {
        &self.coefficients[..self.model.coefficient_count()]
    }

    /// Whether every coefficient is 0.
    pub fn is_none(&self) -> bool {
        self.coefficients.iter().all(|&c| c == 0.0)
    }

    /// The distorted normalized point of the ideal one (x, y) = (X/Z, Y/Z).
    pub fn distort(&self, p: [f64; 2]) -> [f64; 2] {
        self.distort_with_derivatives(p).point
    }

    /// The distorted point with its derivatives by the point and by the coefficients.
    pub fn distort_with_derivatives(&self, [x, y]: [f64; 2]) -> Distorted {
        match self.model {
            Model::PlumbBob | Model::RationalPolynomial => self.brown(x, y),
            Model::Equidistant => self.equidistant(x, y),
        }
    }

    /// Brown–Conrady with the rational radial term (plumb_bob is the case k4 = k5 = k6 = 0).
    fn brown(&self, x: f64, y: f64) -> Distorted {
        let [k1, k2, p1, p2, k3, k4, k5, k6] = self.coefficients;
        let r2 = x * x + y * y;
        let r4 = r2 * r2;
        let r6 = r4 * r2;
        let num = 1.0 + k1 * r2 + k2 * r4 + k3 * r6;
        let den = 1.0 + k4 * r2 + k5 * r4 + k6 * r6;
        let radial = num / den;
        let d_num = k1 + 2.0 * k2 * r2 + 3.0 * k3 * r4;
        let d_den = k4 + 2.0 * k5 * r2 + 3.0 * k6 * r4;
        // d radial / d r².
        let d_radial = (d_num * den - num * d_den) / (den * den);
        let xy = x * y;
        let point = [
            x * radial + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy,
        ];
        let by_point = [
            [
                radial + 2.0 * x * x * d_radial + 2.0 * p1 * y + 6.0 * p2 * x,
                2.0 * xy * d_radial + 2.0 * p1 * x + 2.0 * p2 * y,
            ],
            [
                2.0 * xy * d_radial + 2.0 * p1 * x + 2.0 * p2 * y,
                radial + 2.0 * y * y * d_radial + 6.0 * p1 * y + 2.0 * p2 * x,
            ],
        ];
        let radial_by = |term: f64| [x * term, y * term];
        let by_numerator = |r: f64| radial_by(r / den);
        let by_denominator = |r: f64| radial_by(-num * r / (den * den));
        let by_coefficient = [
            by_numerator(r2),
            by_numerator(r4),
            [2.0 * xy, r2 + 2.0 * y * y],
            [r2 + 2.0 * x * x, 2.0 * xy],
            by_numerator(r6),
            by_denominator(r2),
            by_denominator(r4),
            by_denominator(r6),
        ];
        Distorted {
            point,
            by_point,
            by_coefficient,
        }
    }

    /// OpenCV's fisheye model on the normalized point.
    fn equidistant(&self, x: f64, y: f64) -> Distorted {
        let [k1, k2, k3, k4, ..] = self.coefficients;
        let r = x.hypot(y);
        let theta = r.atan();
        let t2 = theta * theta;
        let poly = 1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)));
        let theta_d = theta * poly;
        // θ/r → 1 and the scale's derivative → 0 at the centre (the scale is even in r).
        let (over_r, scale, d_scale_dr) = if r > 1e-12 {
            let d_theta_d = (poly
                + t2 * (2.0 * k1 + t2 * (4.0 * k2 + t2 * (6.0 * k3 + t2 * 8.0 * k4))))
                / (1.0 + r * r);
            (theta / r, theta_d / r, (d_theta_d * r - theta_d) / (r * r))
        } else {
            (1.0, poly, 0.0)
        };
        let point = [x * scale, y * scale];
        let (ux, uy) = if r > 1e-12 {
            (x / r, y / r)
        } else {
            (0.0, 0.0)
        };
        let by_point = [
            [scale + x * d_scale_dr * ux, x * d_scale_dr * uy],
            [y * d_scale_dr * ux, scale + y * d_scale_dr * uy],
        ];
        let mut by_coefficient = [[0.0; 2]; 8];
        let mut power = t2;
        for slot in by_coefficient.iter_mut().take(4) {
            let term = over_r * power;
            *slot = [x * term, y * term];
            power *= t2;
        }
        Distorted {
            point,
            by_point,
            by_coefficient,
        }
    }

    /// The ideal normalized point whose distortion is `target`, or `None` when the iteration
    /// does not converge (a point outside the region where the model is invertible).
    pub fn undistort(&self, target: [f64; 2]) -> Option<[f64; 2]> {
        if self.is_none() {
            return Some(target);
        }
        match self.model {
            Model::Equidistant => self.undistort_equidistant(target),
            _ => self.undistort_newton(target),
        }
    }

    /// Newton's method in 2D from the distorted point, each step checked to reduce the residual.
    fn undistort_newton(&self, target: [f64; 2]) -> Option<[f64; 2]> {
        let mut p = target;
        for _ in 0..UNDISTORT_ITERATIONS {
            let d = self.distort_with_derivatives(p);
            let e = [d.point[0] - target[0], d.point[1] - target[1]];
            if e[0].abs().max(e[1].abs()) < UNDISTORT_TOLERANCE {
                return Some(p);
            }
            let [[a, b], [c, dd]] = d.by_point;
            let det = a * dd - b * c;
            if !det.is_finite() || det.abs() < 1e-12 {
                return None;
            }
            let step = [(dd * e[0] - b * e[1]) / det, (a * e[1] - c * e[0]) / det];
            p = [p[0] - step[0], p[1] - step[1]];
            if !(p[0].is_finite() && p[1].is_finite()) {
                return None;
            }
        }
        let d = self.distort(p);
        let residual = (d[0] - target[0]).abs().max((d[1] - target[1]).abs());
        (residual < 1e-9).then_some(p)
    }

    /// The ideal point as OpenCV's `undistortPoints` finds it with its default criteria, so
    /// that `stereoRectify` and its rectangles come out as OpenCV's do: for the Brown models 5
    /// fixed-point steps `x = (x_d − Δ(x)) / radial(x)` (giving up at a negative radial term,
    /// as OpenCV does), for the fisheye Newton on θ for at most 10 steps or until the step is
    /// below 1e-8. Not the exact inverse: [`Distortion::undistort`] is.
    pub fn undistort_as_opencv(&self, target: [f64; 2]) -> Option<[f64; 2]> {
        let [x0, y0] = target;
        let [k1, k2, p1, p2, k3, k4, k5, k6] = self.coefficients;
        let out = match self.model {
            Model::PlumbBob | Model::RationalPolynomial => {
                let (mut x, mut y) = (x0, y0);
                for _ in 0..5 {
                    let r2 = x * x + y * y;
                    let icdist = (1.0 + ((k6 * r2 + k5) * r2 + k4) * r2)
                        / (1.0 + ((k3 * r2 + k2) * r2 + k1) * r2);
                    if icdist < 0.0 {
                        (x, y) = (x0, y0);
                        break;
                    }
                    let dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
                    let dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
                    x = (x0 - dx) * icdist;
                    y = (y0 - dy) * icdist;
                }
                [x, y]
            }
            Model::Equidistant => {
                let [k1, k2, k3, k4, ..] = self.coefficients;
                let theta_d = x0.hypot(y0);
                if theta_d <= 1e-8 {
                    return Some(target);
                }
                let mut theta = theta_d;
                for _ in 0..10 {
                    let t2 = theta * theta;
                    let fix = (theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
                        - theta_d)
                        / (1.0
                            + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + 9.0 * t2 * k4))));
                    theta -= fix;
                    if fix.abs() < 1e-8 {
                        break;
                    }
                }
                if theta.abs() >= std::f64::consts::FRAC_PI_2 || theta < 0.0 {
                    return None;
                }
                let scale = theta.tan() / theta_d;
                [x0 * scale, y0 * scale]
            }
        };
        (out[0].is_finite() && out[1].is_finite()).then_some(out)
    }

    /// The distorted point alone, without derivatives: what a rectification map evaluates
    /// for every pixel.
    #[inline]
    pub fn apply(&self, x: f64, y: f64) -> [f64; 2] {
        let [k1, k2, p1, p2, k3, k4, k5, k6] = self.coefficients;
        match self.model {
            Model::PlumbBob | Model::RationalPolynomial => {
                let (x2, y2) = (x * x, y * y);
                let r2 = x2 + y2;
                let xy2 = 2.0 * x * y;
                let kr = (1.0 + ((k3 * r2 + k2) * r2 + k1) * r2)
                    / (1.0 + ((k6 * r2 + k5) * r2 + k4) * r2);
                [
                    x * kr + p1 * xy2 + p2 * (r2 + 2.0 * x2),
                    y * kr + p1 * (r2 + 2.0 * y2) + p2 * xy2,
                ]
            }
            Model::Equidistant => {
                let [k1, k2, k3, k4, ..] = self.coefficients;
                let r = (x * x + y * y).sqrt();
                let theta = r.atan();
                let t2 = theta * theta;
                let theta_d = theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))));
                let scale = if r == 0.0 { 1.0 } else { theta_d / r };
                [x * scale, y * scale]
            }
        }
    }

    /// The fisheye inverse: Newton on θ alone (θ_d = |target|), as OpenCV's fisheye does.
    fn undistort_equidistant(&self, target: [f64; 2]) -> Option<[f64; 2]> {
        let [k1, k2, k3, k4, ..] = self.coefficients;
        let theta_d = target[0].hypot(target[1]);
        if theta_d < 1e-12 {
            return Some(target);
        }
        let mut theta = theta_d;
        for _ in 0..UNDISTORT_ITERATIONS {
            let t2 = theta * theta;
            let f = theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))) - theta_d;
            if f.abs() < UNDISTORT_TOLERANCE {
                break;
            }
            let df = 1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)));
            if df <= 1e-12 {
                return None;
            }
            theta -= f / df;
        }
        let t2 = theta * theta;
        let residual = theta * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))) - theta_d;
        if !(0.0..std::f64::consts::FRAC_PI_2).contains(&theta) || residual.abs() > 1e-9 {
            return None;
        }
        let scale = theta.tan() / theta_d;
        Some([target[0] * scale, target[1] * scale])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lenses() -> Vec<Distortion> {
        vec![
            Distortion::new(Model::PlumbBob, &[-0.28, 0.09, 0.0012, -0.0008, -0.012]).unwrap(),
            Distortion::new(
                Model::RationalPolynomial,
                &[0.9, -0.3, 0.001, 0.0005, 0.02, 1.2, -0.2, 0.05],
            )
            .unwrap(),
            Distortion::new(Model::Equidistant, &[-0.02, 0.004, -0.001, 0.0002]).unwrap(),
        ]
    }

    /// Undistorting inverts distorting to 1e-12 over the field of view each model is used for.
    #[test]
    fn undistort_inverts_distort() {
        for lens in lenses() {
            let reach = if lens.model() == Model::Equidistant {
                2.5
            } else {
                0.6
            };
            for i in -10..=10 {
                for j in -10..=10 {
                    let p = [reach * i as f64 / 10.0, reach * j as f64 / 10.0 * 0.8];
                    let d = lens.distort(p);
                    let back = lens
                        .undistort(d)
                        .unwrap_or_else(|| panic!("{lens:?} at {p:?}"));
                    assert!(
                        (back[0] - p[0]).abs() < 1e-11 && (back[1] - p[1]).abs() < 1e-11,
                        "{:?}: {p:?} → {d:?} → {back:?}",
                        lens.model()
                    );
                }
            }
        }
    }

    /// The analytic derivatives match central differences, by the point and by each
    /// coefficient.
    #[test]
    fn derivatives_match_finite_differences() {
        let h = 1e-7;
        // Central differences of the distorted point, compared with one analytic column.
        let check = |what: &str, plus: [f64; 2], minus: [f64; 2], analytic: [f64; 2]| {
            for row in 0..2 {
                let numeric = (plus[row] - minus[row]) / (2.0 * h);
                assert!(
                    (numeric - analytic[row]).abs() < 1e-6,
                    "{what}, row {row}: {numeric} vs {}",
                    analytic[row]
                );
            }
        };
        for lens in lenses() {
            for p in [[0.31, -0.22], [-0.05, 0.4], [0.0, 0.0], [1e-9, 0.0]] {
                let d = lens.distort_with_derivatives(p);
                for (k, step) in [[h, 0.0], [0.0, h]].iter().enumerate() {
                    check(
                        &format!("{:?} by p{k} at {p:?}", lens.model()),
                        lens.distort([p[0] + step[0], p[1] + step[1]]),
                        lens.distort([p[0] - step[0], p[1] - step[1]]),
                        [d.by_point[0][k], d.by_point[1][k]],
                    );
                }
                for c in 0..lens.model().coefficient_count() {
                    let (mut up, mut down) = (lens, lens);
                    up.coefficients[c] += h;
                    down.coefficients[c] -= h;
                    check(
                        &format!("{:?} by c{c} at {p:?}", lens.model()),
                        up.distort(p),
                        down.distort(p),
                        d.by_coefficient[c],
                    );
                }
            }
        }
    }

    /// A model takes at most its own number of coefficients, all finite, and pads the rest.
    #[test]
    fn coefficients_are_checked_and_padded() {
        assert_eq!(
            Distortion::new(Model::Equidistant, &[0.1; 5]),
            Err(DistortionFault::TooMany {
                model: Model::Equidistant,
                given: 5
            })
        );
        assert_eq!(
            Distortion::new(Model::PlumbBob, &[0.1, f64::NAN]),
            Err(DistortionFault::NotFinite { index: 1 })
        );
        let short = Distortion::new(Model::PlumbBob, &[0.1, 0.2, 0.0, 0.0]).unwrap();
        assert_eq!(short.coefficients(), &[0.1, 0.2, 0.0, 0.0, 0.0]);
        assert_eq!(Model::from_name("fisheye"), Some(Model::Equidistant));
    }
}
