//! Chessboards rendered through the camera model with exact truth, for the tests, the
//! evaluation against OpenCV and the benchmarks: a board at a known pose seen by a camera with
//! distortion, anti-aliased by supersampling, under uneven light, blurred and noisy. The truth
//! is each inner corner projected by the same model, so a detector's error is measurable to
//! thousandths of a pixel.

use nalgebra::{Isometry3, Rotation3, Translation3, Vector3};

use super::board::Board;
use crate::camera::{Camera, Size, StereoPair};
use crate::noise::Rng;

/// How a board is lit and imaged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Style {
    /// Reflectance of the black and white squares, 0..1.
    pub black: f64,
    pub white: f64,
    /// Grey level of full light on white (the exposure), before the light's unevenness.
    pub exposure: f64,
    /// The light's relative slope across the image in x and y (0.15: 15 % brighter at the
    /// right edge than in the middle, 15 % dimmer at the left), and its fall-off at the corners.
    pub slope: [f64; 2],
    pub vignetting: f64,
    /// Gaussian blur of the optics, σ in pixels (0 for none).
    pub blur: f64,
    /// Gaussian noise, σ in grey levels.
    pub noise: f64,
    /// Supersamples per pixel side.
    pub supersampling: u32,
    pub seed: u64,
}

impl Default for Style {
    fn default() -> Self {
        Style {
            black: 0.08,
            white: 0.85,
            exposure: 250.0,
            slope: [0.15, -0.1],
            vignetting: 0.2,
            blur: 0.7,
            noise: 1.5,
            supersampling: 4,
            seed: 1,
        }
    }
}

/// The ideal rays of a camera's sub-pixel samples, computed once and shared by every view it
/// renders (the undistortion is the costly part).
pub struct Rays {
    size: Size,
    n: u32,
    /// (x, y) of the normalized ray at each sample, NaN where the lens cannot be inverted.
    rays: Vec<[f32; 2]>,
}

impl Rays {
    pub fn new(camera: &Camera, size: Size, supersampling: u32) -> Rays {
        let n = supersampling.max(1);
        let (w, h) = (size.width * n, size.height * n);
        let mut rays = Vec::with_capacity((w * h) as usize);
        for sy in 0..h {
            for sx in 0..w {
                // Sample centres within the pixel; pixel (u, v) covers u ± 0.5 (OpenCV's).
                let u = (f64::from(sx) + 0.5) / f64::from(n) - 0.5;
                let v = (f64::from(sy) + 0.5) / f64::from(n) - 0.5;
                rays.push(match camera.normalize([u, v]) {
                    Some([x, y]) => [x as f32, y as f32],
                    None => [f32::NAN; 2],
                });
            }
        }
        Rays { size, n, rays }
    }
}

/// A rendered 8-bit grey image.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<u8>,
}

/// Renders `board` at `pose` (board to camera) as the camera whose `rays` are given.
pub fn render(board: &Board, pose: &Isometry3<f64>, rays: &Rays, style: &Style) -> Image {
    let s = board.square_size();
    let (cols, rows) = (i64::from(board.columns()), i64::from(board.rows()));
    // The printed sheet: the squares and one square of white margin around them.
    let (lo_x, hi_x) = (-2.0 * s, (cols as f64 + 1.0) * s);
    let (lo_y, hi_y) = (-2.0 * s, (rows as f64 + 1.0) * s);
    render_sheet(pose, rays, style, |bx, by| {
        if bx < lo_x || bx > hi_x || by < lo_y || by > hi_y {
            return None;
        }
        let (i, j) = ((bx / s).floor() as i64, (by / s).floor() as i64);
        Some((-1..=cols - 1).contains(&i) && (-1..=rows - 1).contains(&j) && Board::is_black(i, j))
    })
}

/// Renders a printed plane at `pose`: `black(x, y)` says whether the point (x, y) of the plane
/// is printed black, or `None` off the sheet (where the background shows).
pub fn render_sheet(
    pose: &Isometry3<f64>,
    rays: &Rays,
    style: &Style,
    black: impl Fn(f64, f64) -> Option<bool>,
) -> Image {
    let Size { width, height } = rays.size;
    let n = rays.n;
    // The plane in plain numbers (this loop runs for every sample): its normal and distance
    // in the camera's frame, and the rotation back to the board's frame.
    let rotation = pose.rotation.to_rotation_matrix();
    let m = rotation.matrix();
    let t = pose.translation.vector;
    let normal = [m[(0, 2)], m[(1, 2)], m[(2, 2)]];
    let reach = normal[0] * t.x + normal[1] * t.y + normal[2] * t.z;
    let reflectance = |x: f32, y: f32| -> f64 {
        if x.is_nan() {
            return 0.0;
        }
        let (x, y) = (f64::from(x), f64::from(y));
        let along = normal[0] * x + normal[1] * y + normal[2];
        let lambda = reach / along;
        if !(along.abs() > 1e-12 && lambda > 0.0) {
            return background(x, y);
        }
        // Board coordinates: Rᵀ·(λ·d − t).
        let q = [lambda * x - t.x, lambda * y - t.y, lambda - t.z];
        let bx = m[(0, 0)] * q[0] + m[(1, 0)] * q[1] + m[(2, 0)] * q[2];
        let by = m[(0, 1)] * q[0] + m[(1, 1)] * q[1] + m[(2, 1)] * q[2];
        match black(bx, by) {
            None => background(x, y),
            Some(true) => style.black,
            Some(false) => style.white,
        }
    };
    let row = (width * n) as usize;
    let area = f64::from(n * n);
    let mut light = vec![0.0f32; (width * height) as usize];
    for v in 0..height {
        for u in 0..width {
            let mut sum = 0.0;
            for sy in 0..n {
                let start = ((v * n + sy) as usize) * row + (u * n) as usize;
                for &[x, y] in &rays.rays[start..start + n as usize] {
                    sum += reflectance(x, y);
                }
            }
            let (du, dv) = (
                f64::from(u) / f64::from(width) - 0.5,
                f64::from(v) / f64::from(height) - 0.5,
            );
            let shade = (1.0 + style.slope[0] * 2.0 * du + style.slope[1] * 2.0 * dv)
                * (1.0 - style.vignetting * 2.0 * (du * du + dv * dv));
            light[(v * width + u) as usize] = (sum / area * style.exposure * shade) as f32;
        }
    }
    let blurred = gaussian(&light, width as usize, height as usize, style.blur);
    let mut rng = Rng::new(style.seed);
    let pixels = blurred
        .iter()
        .map(|&g| {
            (f64::from(g) + style.noise * f64::from(rng.normal()))
                .round()
                .clamp(0.0, 255.0) as u8
        })
        .collect();
    Image {
        width,
        height,
        pixels,
    }
}

/// A dim, softly patterned wall behind the board.
fn background(x: f64, y: f64) -> f64 {
    0.35 + 0.08 * (x * 7.0).sin() * (y * 5.0).cos()
}

/// Separable Gaussian blur with clamped edges.
fn gaussian(image: &[f32], width: usize, height: usize, sigma: f64) -> Vec<f32> {
    if sigma <= 0.0 {
        return image.to_vec();
    }
    let radius = (3.0 * sigma).ceil() as isize;
    let mut kernel: Vec<f32> = (-radius..=radius)
        .map(|k| (-(k * k) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let total: f32 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= total);
    let pass = |src: &[f32], along_x: bool| {
        let mut out = vec![0.0f32; src.len()];
        for y in 0..height {
            for x in 0..width {
                let mut acc = 0.0;
                for (k, w) in kernel.iter().enumerate() {
                    let o = k as isize - radius;
                    let (sx, sy) = if along_x {
                        ((x as isize + o).clamp(0, width as isize - 1) as usize, y)
                    } else {
                        (x, (y as isize + o).clamp(0, height as isize - 1) as usize)
                    };
                    acc += w * src[sy * width + sx];
                }
                out[y * width + x] = acc;
            }
        }
        out
    };
    pass(&pass(image, true), false)
}

/// The exact pixel of every inner corner (OpenCV's order) seen by `camera` at `pose`, or
/// `None` when one is behind it.
pub fn corners(board: &Board, pose: &Isometry3<f64>, camera: &Camera) -> Option<Vec<[f64; 2]>> {
    board
        .object_points()
        .iter()
        .map(|p| camera.project(&(pose * nalgebra::Point3::from(*p)).coords))
        .collect()
}

/// One stereo view: the board's pose in the left camera and what each camera saw.
pub struct StereoView {
    pub pose: Isometry3<f64>,
    pub left: Image,
    pub right: Image,
    pub left_corners: Vec<[f64; 2]>,
    pub right_corners: Vec<[f64; 2]>,
}

/// The board's pose seen by the right camera of `pair` when the left sees it at `pose`.
pub fn right_pose(pair: &StereoPair, pose: &Isometry3<f64>) -> Isometry3<f64> {
    let extrinsics =
        Isometry3::from_parts(Translation3::from(pair.translation), pair.rotation.into());
    extrinsics * pose
}

/// Random poses from which both cameras see the whole board with `margin` pixels to spare:
/// at distances where the board fills a quarter to a half of the image's width, tilted up to
/// `max_tilt_deg` about a random axis in its plane, turned a little about the view axis, and
/// placed over the whole image.
pub fn poses(
    pair: &StereoPair,
    size: Size,
    board: &Board,
    count: usize,
    max_tilt_deg: f64,
    seed: u64,
) -> Vec<Isometry3<f64>> {
    poses_aimed(pair, size, board, (count, max_tilt_deg, seed), None)
}

/// [`poses`] for a wide lens, out to its field's edges: each board's centre is aimed at an
/// azimuth within `reach_deg` of the axis (an elevation within the image's aspect of it),
/// and the board is turned to face the camera there before its tilt, as a person holding a
/// board at the edge of a fisheye's view does. (A pinhole's aim, in tangents, cannot reach
/// 90°.)
pub fn poses_across(
    pair: &StereoPair,
    size: Size,
    board: &Board,
    (count, max_tilt_deg, seed): (usize, f64, u64),
    reach_deg: f64,
) -> Vec<Isometry3<f64>> {
    poses_aimed(
        pair,
        size,
        board,
        (count, max_tilt_deg, seed),
        Some(reach_deg.to_radians()),
    )
}

/// [`poses`] and [`poses_across`]: aimed in tangents (`reach` None) or in angles.
fn poses_aimed(
    pair: &StereoPair,
    size: Size,
    board: &Board,
    (count, max_tilt_deg, seed): (usize, f64, u64),
    reach: Option<f64>,
) -> Vec<Isometry3<f64>> {
    let mut rng = Rng::new(seed);
    let mut unit = || f64::from(rng.unit());
    let s = board.square_size();
    let (bw, bh) = (
        f64::from(board.columns() + 1) * s,
        f64::from(board.rows() + 1) * s,
    );
    let centre = Vector3::new(
        f64::from(board.columns() - 1) * s / 2.0,
        f64::from(board.rows() - 1) * s / 2.0,
        0.0,
    );
    let f = pair.left.intrinsics().fx;
    let margin = 12.0;
    let fits = |camera: &Camera, pose: &Isometry3<f64>| {
        corners(board, pose, camera).is_some_and(|c| {
            c.iter().all(|&[u, v]| {
                u > margin
                    && v > margin
                    && u < f64::from(size.width) - 1.0 - margin
                    && v < f64::from(size.height) - 1.0 - margin
            })
        })
    };
    let mut found = Vec::with_capacity(count);
    let mut tries = 0;
    while found.len() < count && tries < count * 2000 {
        tries += 1;
        let fill = 0.3 + 0.3 * unit();
        let distance = f * bw.max(bh * 1.3) / (fill * f64::from(size.width));
        let axis_angle = unit() * std::f64::consts::TAU;
        let tilt = (max_tilt_deg * (0.2 + 0.8 * unit())).to_radians();
        let spin = (unit() - 0.5) * 0.5;
        let rotation = Rotation3::from_axis_angle(&Vector3::z_axis(), spin)
            * Rotation3::from_scaled_axis(
                Vector3::new(axis_angle.cos(), axis_angle.sin(), 0.0) * tilt,
            );
        let aim = [
            (unit() - 0.5) * 0.7 * f64::from(size.width) / f,
            (unit() - 0.5) * 0.7 * f64::from(size.height) / f,
        ];
        // Put the board's centre on the ray `aim` at `distance` (in angles: on the ray at
        // azimuth and elevation, the board turned to face along it).
        let (target, rotation) = match reach {
            None => (Vector3::new(aim[0], aim[1], 1.0) * distance, rotation),
            Some(reach) => {
                let aspect = f64::from(size.height) / f64::from(size.width);
                let (az, el) = (
                    (aim[0] / (0.35 * f64::from(size.width) / f)) * reach,
                    (aim[1] / (0.35 * f64::from(size.height) / f)) * reach * aspect,
                );
                let ray = Vector3::new(az.sin() * el.cos(), el.sin(), az.cos() * el.cos());
                let face = Rotation3::rotation_between(&Vector3::z(), &ray)
                    .unwrap_or_else(Rotation3::identity);
                (ray * distance, face * rotation)
            }
        };
        let translation = target - rotation * centre;
        let pose = Isometry3::from_parts(Translation3::from(translation), rotation.into());
        if fits(&pair.left, &pose) && fits(&pair.right, &right_pose(pair, &pose)) {
            found.push(pose);
        }
    }
    found
}

/// Renders `poses` as stereo views, with a fresh seed for each image and the exposure of the
/// right camera set apart from the left's.
pub fn stereo_views(
    pair: &StereoPair,
    size: Size,
    board: &Board,
    poses: &[Isometry3<f64>],
    style: &Style,
) -> Vec<StereoView> {
    let rays = [
        Rays::new(&pair.left, size, style.supersampling),
        Rays::new(&pair.right, size, style.supersampling),
    ];
    poses
        .iter()
        .enumerate()
        .map(|(i, pose)| stereo_view(pair, board, pose, i, &rays, style))
        .collect()
}

/// The `i`-th of [`stereo_views`], with the cameras' rays computed once by the caller.
pub fn stereo_view(
    pair: &StereoPair,
    board: &Board,
    pose: &Isometry3<f64>,
    i: usize,
    [left_rays, right_rays]: &[Rays; 2],
    style: &Style,
) -> StereoView {
    let right = right_pose(pair, pose);
    let seed = style.seed.wrapping_mul(1000).wrapping_add(2 * i as u64);
    let mut rng = Rng::new(seed);
    let mut vary = || 0.85 + 0.3 * f64::from(rng.unit());
    let left_style = Style {
        seed,
        exposure: style.exposure * vary(),
        ..*style
    };
    let right_style = Style {
        seed: seed + 1,
        exposure: style.exposure * vary(),
        slope: [-style.slope[0], style.slope[1]],
        ..*style
    };
    StereoView {
        pose: *pose,
        left: render(board, pose, left_rays, &left_style),
        right: render(board, &right, right_rays, &right_style),
        left_corners: corners(board, pose, &pair.left).unwrap_or_default(),
        right_corners: corners(board, &right, &pair.right).unwrap_or_default(),
    }
}

/// The rig the page's calibration sample is rendered with: two 640 × 480 cameras with barrel
/// distortion (k1 about −0.25), each a little different, turned a degree or two from
/// parallel, 120 mm apart. Its raw frames need rectifying before they can be matched.
pub fn sample_rig() -> StereoPair {
    let camera = |fx: f64, cx: f64, cy: f64, d: [f64; 5]| {
        Camera::new(
            crate::camera::Intrinsics {
                fx,
                fy: fx * 1.002,
                cx,
                cy,
            },
            crate::camera::Distortion::new(crate::camera::Model::PlumbBob, &d)
                .expect("five plumb_bob coefficients"),
        )
        .expect("a valid camera")
    };
    StereoPair {
        left: camera(805.0, 322.0, 243.0, [-0.25, 0.1, 0.0004, -0.0006, -0.01]),
        right: camera(798.0, 317.0, 238.0, [-0.23, 0.08, -0.0003, 0.0005, 0.0]),
        rotation: Rotation3::from_scaled_axis(Vector3::new(0.012, -0.025, 0.006)),
        translation: Vector3::new(-120.0, 1.5, -0.8),
    }
}

/// A textured wall in front of `pair`, turned about the vertical: in the frame of the pair's
/// rectified left camera (where a distance along the optical axis is measured) its points
/// are at depth Z = `distance` + `slope`·X, so a pixel x of the rectified left image sees
/// depth `distance` / (1 − `slope`·(x − cx)/f). Seen through each raw camera with its
/// distortion: the raw left and right frames. `None` when `pair` cannot be rectified.
pub fn raw_wall(
    pair: &StereoPair,
    size: Size,
    distance: f64,
    slope: f64,
    seed: u64,
) -> Option<[Image; 2]> {
    let rectification =
        crate::camera::stereo_rectify(pair, size, crate::camera::RectifyOptions::default()).ok()?;
    let r1 = rectification.r1;
    // A texture pixel is two thirds of a rectified pixel on the axis, so that the far side
    // of the wall, foreshortened, still holds nothing finer than a pixel can.
    let scale = rectification.p1[(0, 0)] / (1.5 * distance);
    let texture = crate::noise::Texture::new(seed);
    let centre = r1 * (-(pair.rotation.inverse() * pair.translation));
    let to_world = [r1, r1 * pair.rotation.matrix().transpose()];
    let origins = [Vector3::zeros(), centre];
    let cameras = [&pair.left, &pair.right];
    // One sample a pixel: the texture holds nothing above 0.4 cycles a pixel.
    let n = 1u32;
    let mut rng = Rng::new(seed ^ 0x5EED);
    let frames = [0, 1].map(|side| {
        let mut pixels = Vec::with_capacity((size.width * size.height) as usize);
        for v in 0..size.height {
            for u in 0..size.width {
                let mut sum = 0.0f64;
                for sy in 0..n {
                    for sx in 0..n {
                        let at = [
                            f64::from(u) + (f64::from(sx) + 0.5) / f64::from(n) - 0.5,
                            f64::from(v) + (f64::from(sy) + 0.5) / f64::from(n) - 0.5,
                        ];
                        let Some([x, y]) = cameras[side].normalize(at) else {
                            continue;
                        };
                        let ray = to_world[side] * Vector3::new(x, y, 1.0);
                        let o = origins[side];
                        let t = (distance + slope * o.x - o.z) / (ray.z - slope * ray.x);
                        let p = o + ray * t;
                        sum += f64::from(texture.at((p.x * scale) as f32, (p.y * scale) as f32));
                    }
                }
                let grey = 30.0 + 200.0 * sum / f64::from(n * n) + 1.0 * f64::from(rng.normal());
                pixels.push(grey.round().clamp(0.0, 255.0) as u8);
            }
        }
        Image {
            width: size.width,
            height: size.height,
            pixels,
        }
    });
    Some(frames)
}
