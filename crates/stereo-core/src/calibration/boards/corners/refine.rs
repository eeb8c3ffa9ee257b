//! Sub-pixel corner refinement by fitting a model of a blurred chessboard corner to the pixels
//! around it: two straight edges through the corner at any angles (perspective), each a step
//! blurred by a Gaussian of fitted width (defocus), on a fitted brightness plane (uneven
//! light), by Levenberg–Marquardt on the grey levels (the least-squares estimate under pixel
//! noise). The model is point-symmetric about the corner, as the image of a corner is, so
//! neither blur nor the model's approximation where the edges meet at an oblique angle moves
//! the corner.

use nalgebra::{SMatrix, SVector};

use super::Luma;

/// The parameters: corner (x, y), the two edges' angles, blur σ, brightness a, contrast b,
/// brightness slopes gx, gy.
const P: usize = 9;

/// The widest window a blurred corner is fitted in, in pixels (a σ of 10 px).
pub const MAX_WINDOW: f64 = 30.0;

/// What a refinement gives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refined {
    pub point: [f64; 2],
    /// The two edges' directions (radians, modulo π).
    pub angles: [f64; 2],
    /// The fitted blur σ in pixels.
    pub blur: f64,
    /// |contrast| between the dark and light squares, in grey levels.
    pub contrast: f64,
    /// Root-mean-square residual of the fit, in grey levels.
    pub rms: f64,
}

/// erf to 1.2e-7 (Numerical Recipes' erfc by Chebyshev fit), odd as erf is.
fn erf(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let r = t
        * (-z * z - 1.265_512_23
            + t * (1.000_023_68
                + t * (0.374_091_96
                    + t * (0.096_784_18
                        + t * (-0.186_288_06
                            + t * (0.278_868_07
                                + t * (-1.135_203_98
                                    + t * (1.488_515_87
                                        + t * (-0.822_152_23 + t * 0.170_872_77)))))))))
            .exp();
    if x >= 0.0 { 1.0 - r } else { r - 1.0 }
}

/// A step blurred by σ across signed distance d: erf(d / (√2·σ)) and its derivatives by d and σ.
fn step(d: f64, sigma: f64) -> (f64, f64, f64) {
    let u = d / (std::f64::consts::SQRT_2 * sigma);
    let g = std::f64::consts::FRAC_2_SQRT_PI * (-u * u).exp();
    let by_d = g / (std::f64::consts::SQRT_2 * sigma);
    (erf(u), by_d, -by_d * d / sigma)
}

/// Grey level sampled bilinearly (the caller keeps within the image).
fn sample(image: &Luma, x: f64, y: f64) -> f64 {
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (i, j) = (x0 as usize, y0 as usize);
    let at = |i: usize, j: usize| f64::from(image.data[j * image.width + i]);
    let top = at(i, j) * (1.0 - fx) + at(i + 1, j) * fx;
    let bottom = at(i, j + 1) * (1.0 - fx) + at(i + 1, j + 1) * fx;
    top * (1.0 - fy) + bottom * fy
}

/// The directions of the two edges through `centre`, from where the grey level crosses its
/// mean on a circle of `radius` (four crossings, opposite ones paired).
fn edge_angles(image: &Luma, centre: [f64; 2], radius: f64) -> Option<[f64; 2]> {
    const N: usize = 64;
    let ring: Vec<f64> = (0..N)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / N as f64;
            sample(
                image,
                centre[0] + radius * a.cos(),
                centre[1] + radius * a.sin(),
            )
        })
        .collect();
    let mean = ring.iter().sum::<f64>() / N as f64;
    let mut crossings = Vec::new();
    for k in 0..N {
        let (a, b) = (ring[k] - mean, ring[(k + 1) % N] - mean);
        if (a < 0.0) != (b < 0.0) {
            let t = a / (a - b);
            crossings.push((k as f64 + t) * std::f64::consts::TAU / N as f64);
        }
    }
    if crossings.len() != 4 {
        return None;
    }
    // Opposite crossings belong to one edge: average each pair's direction modulo π.
    let direction = |a: f64, b: f64| {
        let (ca, cb) = (
            (2.0 * a).cos() + (2.0 * b).cos(),
            (2.0 * a).sin() + (2.0 * b).sin(),
        );
        cb.atan2(ca) / 2.0
    };
    Some([
        direction(crossings[0], crossings[2]),
        direction(crossings[1], crossings[3]),
    ])
}

/// Refines a corner found near `start` (within about a pixel) using the pixels within
/// `radius` of it, or `None` when no two-edge corner fits there (a blank patch, an edge, the
/// image border, a fit that wanders off).
pub fn refine(image: &Luma, start: [f64; 2], radius: f64) -> Option<Refined> {
    let r = if radius.is_finite() {
        radius.max(2.0)
    } else {
        2.0
    };
    let reach = (r + 2.0).ceil();
    if !(start[0].is_finite() && start[1].is_finite())
        || start[0] < reach
        || start[1] < reach
        || start[0] + reach + 1.0 >= image.width as f64
        || start[1] + reach + 1.0 >= image.height as f64
    {
        return None;
    }
    let angles = edge_angles(image, start, (0.6 * r).max(2.0))?;
    // The window: pixel centres within r of the start, weighted toward the corner.
    let (x0, y0) = (start[0].round() as i64, start[1].round() as i64);
    let ri = r.ceil() as i64;
    let spread = 2.0 * (0.75 * r).powi(2);
    let mut pixels = Vec::with_capacity(((2 * ri + 1) * (2 * ri + 1)) as usize);
    for j in y0 - ri..=y0 + ri {
        for i in x0 - ri..=x0 + ri {
            let (dx, dy) = (i as f64 - start[0], j as f64 - start[1]);
            let d2 = dx * dx + dy * dy;
            if d2 <= r * r {
                let value = f64::from(image.data[j as usize * image.width + i as usize]);
                pixels.push((i as f64, j as f64, value, (-d2 / spread).exp()));
            }
        }
    }
    let mean = pixels.iter().map(|p| p.2).sum::<f64>() / pixels.len() as f64;
    // Which quadrant is light decides the contrast's sign: the model's sign there.
    let probe = (angles[0] + angles[1]) / 2.0;
    let (pc, ps) = (probe.cos(), probe.sin());
    let side = sample(image, start[0] + 0.6 * r * pc, start[1] + 0.6 * r * ps)
        + sample(image, start[0] - 0.6 * r * pc, start[1] - 0.6 * r * ps)
        - 2.0 * mean;
    let sign_at_probe = {
        let n = |t: f64| [-t.sin(), t.cos()];
        let (n1, n2) = (n(angles[0]), n(angles[1]));
        (n1[0] * pc + n1[1] * ps).signum() * (n2[0] * pc + n2[1] * ps).signum()
    };
    let range = pixels.iter().map(|p| p.2).fold(f64::MIN, f64::max)
        - pixels.iter().map(|p| p.2).fold(f64::MAX, f64::min);
    let mut theta = [
        start[0],
        start[1],
        angles[0],
        angles[1],
        1.0,
        mean,
        0.5 * range * (side * sign_at_probe).signum(),
        0.0,
        0.0,
    ];
    let residuals = |theta: &[f64; P], jacobian: Option<&mut Vec<[f64; P]>>| -> (f64, Vec<f64>) {
        let [cx, cy, t1, t2, sigma, a, b, gx, gy] = *theta;
        let (n1, n2) = ([-t1.sin(), t1.cos()], [-t2.sin(), t2.cos()]);
        let (m1, m2) = ([-t1.cos(), -t1.sin()], [-t2.cos(), -t2.sin()]);
        let mut cost = 0.0;
        let mut res = Vec::with_capacity(pixels.len());
        let mut rows = Vec::new();
        let want = jacobian.is_some();
        for &(x, y, value, w) in &pixels {
            let (vx, vy) = (x - cx, y - cy);
            let (d1, d2) = (n1[0] * vx + n1[1] * vy, n2[0] * vx + n2[1] * vy);
            let (e1, e1d, e1s) = step(d1, sigma);
            let (e2, e2d, e2s) = step(d2, sigma);
            let model = a + b * e1 * e2 + gx * vx + gy * vy;
            let sw = w.sqrt();
            let e = (model - value) * sw;
            cost += e * e;
            res.push(e);
            if want {
                let dm1 = b * e1d * e2;
                let dm2 = b * e1 * e2d;
                rows.push([
                    sw * (-dm1 * n1[0] - dm2 * n2[0] - gx),
                    sw * (-dm1 * n1[1] - dm2 * n2[1] - gy),
                    sw * dm1 * (m1[0] * vx + m1[1] * vy),
                    sw * dm2 * (m2[0] * vx + m2[1] * vy),
                    sw * b * (e1s * e2 + e1 * e2s),
                    sw,
                    sw * e1 * e2,
                    sw * vx,
                    sw * vy,
                ]);
            }
        }
        if let Some(j) = jacobian {
            *j = rows;
        }
        (cost, res)
    };
    let (mut rows, mut trial_rows) = (Vec::new(), Vec::new());
    let (mut cost, mut res) = residuals(&theta, Some(&mut rows));
    let mut lambda = 1e-3;
    for _ in 0..30 {
        let mut jtj = SMatrix::<f64, P, P>::zeros();
        let mut jtr = SVector::<f64, P>::zeros();
        for (row, e) in rows.iter().zip(&res) {
            let j = SVector::<f64, P>::from_column_slice(row);
            jtr -= j * *e;
            jtj.ger(1.0, &j, &j, 1.0);
        }
        let mut improved = false;
        while lambda < 1e8 {
            let mut damped = jtj;
            for i in 0..P {
                damped[(i, i)] += lambda * jtj[(i, i)].max(1e-9);
            }
            let Some(step) = damped.cholesky().map(|c| c.solve(&jtr)) else {
                lambda *= 10.0;
                continue;
            };
            let mut next = theta;
            for i in 0..P {
                next[i] += step[i];
            }
            next[4] = next[4].clamp(0.2, r);
            // The trial's Jacobian comes with its cost (the exponentials are shared), kept
            // when the step is taken.
            let (c, trial) = residuals(&next, Some(&mut trial_rows));
            if c < cost {
                // A step under 10⁻⁴ px is a hundredth of the corners' error: converged.
                let small = step[0].abs().max(step[1].abs()) < 1e-4;
                theta = next;
                (cost, res) = (c, trial);
                std::mem::swap(&mut rows, &mut trial_rows);
                lambda = (lambda / 10.0).max(1e-9);
                improved = !small;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    let point = [theta[0], theta[1]];
    let moved = (point[0] - start[0]).hypot(point[1] - start[1]);
    let contrast = theta[6].abs() * 2.0;
    // The two edges must stay apart, the corner near where it started, the contrast real.
    let apart = ((theta[2] - theta[3]).rem_euclid(std::f64::consts::PI))
        .min(std::f64::consts::PI - (theta[2] - theta[3]).rem_euclid(std::f64::consts::PI));
    if !(moved <= 0.5 * r && apart > 0.15 && contrast > 4.0 && point.iter().all(|v| v.is_finite()))
    {
        return None;
    }
    let weight: f64 = pixels.iter().map(|p| p.3).sum();
    Some(Refined {
        point,
        angles: [theta[2], theta[3]],
        blur: theta[4],
        contrast,
        rms: (cost / weight).sqrt(),
    })
}

/// Refines every corner of one board found near `points`, each with a window of half the
/// distance to its nearest neighbour (3 to 8 px): wide enough for the edges, narrow enough
/// that no other corner enters it on small or steeply tilted squares.
///
/// A blurred corner needs a wider window: within about 2σ of it the blurred corner is a
/// smooth saddle, and a saddle shifted sideways is the same saddle on a brightness slope, so
/// the corner's position and the light's slope cannot be told apart. When the fitted blur is
/// over a third of the window and the squares leave room, the corner is fitted again in a
/// The corner expected at `predicted`, where the board's lines run along `directions` (unit
/// vectors) and its squares are `spacing` pixels, found from the pixels within `radius`
/// (clamped to 3–8 px) and checked: it must lie within a
/// quarter of a square of the prediction, have an edge along each direction within 15°, and
/// fit its model to a fifth of its contrast. `None` for anything else (a blank patch, an edge,
/// a junction of the background).
pub fn verify(
    image: &Luma,
    predicted: [f64; 2],
    directions: &[[f64; 2]],
    spacing: f64,
    radius: f64,
) -> Option<[f64; 2]> {
    if !spacing.is_finite() || spacing < 4.0 {
        return None;
    }
    let radius = radius.clamp(3.0, 8.0);
    let first = refine(image, predicted, radius)?;
    let found = refine(image, first.point, radius).unwrap_or(first);
    let moved = (found.point[0] - predicted[0]).hypot(found.point[1] - predicted[1]);
    let along = |line: &[f64; 2]| {
        found
            .angles
            .iter()
            .map(|a| (a.cos() * line[0] + a.sin() * line[1]).abs())
            .fold(0.0, f64::max)
            >= 15f64.to_radians().cos()
    };
    (moved <= 0.25 * spacing && directions.iter().all(along) && found.rms < 0.2 * found.contrast)
        .then_some(found.point)
}

/// window of 3σ (up to half the distance to the nearest corner, and [`MAX_WINDOW`]).
pub fn refine_all(image: &Luma, points: &[[f64; 2]]) -> Vec<Option<Refined>> {
    points
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let nearest = points
                .iter()
                .enumerate()
                .filter(|&(i, _)| i != k)
                .map(|(_, o)| (o[0] - p[0]).hypot(o[1] - p[1]))
                .fold(f64::INFINITY, f64::min);
            let room = 0.5 * nearest;
            let window = room.clamp(3.0, 8.0);
            let first = refine(image, *p, window)?;
            let wanted = (3.0 * first.blur).min(room).min(MAX_WINDOW);
            if wanted <= window {
                return Some(first);
            }
            Some(refine(image, first.point, wanted).unwrap_or(first))
        })
        .collect()
}
