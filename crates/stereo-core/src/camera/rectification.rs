//! What a rectification is: the raw pair it rectifies ([`StereoPair`]), `alpha` and the
//! options, and the result, [`Rectification`] (R1 R2 P1 P2 Q, the valid ROIs, the rectified
//! size) with the rectified rig it gives; also a rectification a file states
//! ([`Rectification::given`]). Both it and [`super::rectify::stereo_rectify`] build Q in one
//! place, [`Rectification::from_projections`].

use std::fmt;

use nalgebra::{Matrix3, Matrix3x4, Matrix4, Rotation3, Vector3};

use super::pinhole::Camera;
use crate::physics::{Fault, LengthUnit, Rig, RigSpec};

/// A stereo pair of raw cameras and the pose of the right one: X_right = R·X_left + T, with T
/// in the calibration's length unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StereoPair {
    pub left: Camera,
    pub right: Camera,
    pub rotation: Rotation3<f64>,
    pub translation: Vector3<f64>,
}

impl StereoPair {
    /// The essential matrix E = [T]ₓ R.
    pub fn essential(&self) -> Matrix3<f64> {
        let t = self.translation;
        let tx = Matrix3::new(0.0, -t.z, t.y, t.z, 0.0, -t.x, -t.y, t.x, 0.0);
        tx * self.rotation.matrix()
    }

    /// The fundamental matrix K₂⁻ᵀ E K₁⁻¹, scaled so that F₃₃ = 1 as OpenCV returns it.
    pub fn fundamental(&self) -> Matrix3<f64> {
        let inverse = |m: Matrix3<f64>| m.try_inverse().unwrap_or_else(Matrix3::zeros);
        let f = inverse(self.right.matrix()).transpose()
            * self.essential()
            * inverse(self.left.matrix());
        let scale = f[(2, 2)];
        if scale.abs() > 0.0 { f / scale } else { f }
    }
}

/// Which camera of a pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Left,
    Right,
}

impl Side {
    pub fn name(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
        }
    }
}

/// An image size in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Size {
    pub width: u32,
    pub height: u32,
}

/// A rectangle of whole pixels, as OpenCV's `Rect` (x, y, width, height).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Roi {
    pub x: i64,
    pub y: i64,
    pub width: i64,
    pub height: i64,
}

impl Roi {
    /// The part of `self` within `0..width × 0..height` (empty as all zeros, as OpenCV's `&`).
    pub(super) fn within(self, width: u32, height: u32) -> Roi {
        let x0 = self.x.max(0);
        let y0 = self.y.max(0);
        let x1 = (self.x + self.width).min(i64::from(width));
        let y1 = (self.y + self.height).min(i64::from(height));
        if x1 <= x0 || y1 <= y0 {
            Roi::default()
        } else {
            Roi {
                x: x0,
                y: y0,
                width: x1 - x0,
                height: y1 - y0,
            }
        }
    }
}

/// OpenCV's free scaling parameter `alpha`: 0 keeps only valid pixels, 1 keeps every raw
/// pixel. A value that exists is in 0..=1.
#[derive(Debug, Clone, Copy, Default, PartialEq, PartialOrd)]
pub struct Alpha(f64);

impl Alpha {
    /// Only valid pixels (OpenCV's default for a computed rectification).
    pub const ZERO: Alpha = Alpha(0.0);

    /// `value` if it is in 0..=1 (NaN is not).
    pub fn new(value: f64) -> Result<Self, AlphaOutOfRange> {
        if (0.0..=1.0).contains(&value) {
            Ok(Self(value))
        } else {
            Err(AlphaOutOfRange(value))
        }
    }

    /// The value, in 0..=1.
    pub fn get(self) -> f64 {
        self.0
    }
}

/// An `alpha` outside 0..=1, said as every caller says it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlphaOutOfRange(pub f64);

impl fmt::Display for AlphaOutOfRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "must be from 0 (only valid pixels) to 1 (every raw pixel), got {}",
            crate::numbers::Num(self.0)
        )
    }
}

/// How to rectify: `alpha`, OpenCV's `CALIB_ZERO_DISPARITY`, and the size of the rectified
/// images (the raw size when `None`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RectifyOptions {
    pub alpha: Alpha,
    pub zero_disparity: bool,
    pub new_size: Option<Size>,
}

impl Default for RectifyOptions {
    /// `alpha` 0 (only valid pixels) and `CALIB_ZERO_DISPARITY`, OpenCV's default flag.
    fn default() -> Self {
        RectifyOptions {
            alpha: Alpha::ZERO,
            zero_disparity: true,
            new_size: None,
        }
    }
}

/// Why a pair cannot be rectified.
#[derive(Debug, Clone, PartialEq)]
pub enum RectifyFault {
    /// The cameras are at the same place (|T| = 0 or not finite).
    NoBaseline,
    /// A zero image size.
    Size,
    /// The camera's distortion cannot be inverted at the edge of its image.
    NotInvertible(Side),
    /// The rectified image would hold no valid pixel.
    Degenerate,
}

impl fmt::Display for RectifyFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RectifyFault::NoBaseline => {
                f.write_str("the translation between the cameras must be finite and not zero")
            }
            RectifyFault::Size => f.write_str("the image size must not be zero"),
            RectifyFault::NotInvertible(side) => write!(
                f,
                "the {} camera's distortion cannot be inverted at the edges of its image",
                side.name()
            ),
            RectifyFault::Degenerate => {
                f.write_str("the rectified images would hold no valid pixel")
            }
        }
    }
}

/// Why a rectification has no rectified rig of the kind `/distance` takes.
#[derive(Debug, Clone, PartialEq)]
pub enum RigFault {
    /// The cameras are one above the other (OpenCV's vertical stereo); the rig is horizontal.
    Vertical,
    /// What `Rig::new` refused.
    Rig(Vec<Fault>),
}

/// The result of [`stereo_rectify`], in OpenCV's names and conventions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rectification {
    /// Rotation from the left raw camera to the left rectified one.
    pub r1: Matrix3<f64>,
    pub r2: Matrix3<f64>,
    /// The rectified cameras' projection matrices; P2's last column holds T·f.
    pub p1: Matrix3x4<f64>,
    pub p2: Matrix3x4<f64>,
    /// Disparity-to-depth reprojection.
    pub q: Matrix4<f64>,
    /// The `alpha` it was computed with; `None` for a rectification a file gave.
    pub alpha: Option<f64>,
    pub roi_left: Roi,
    pub roi_right: Roi,
    /// The rectified images' size.
    pub size: Size,
    /// Whether the cameras are one above the other (disparities along y).
    pub vertical: bool,
}

/// The inner (every pixel valid) and outer (every source pixel) rectangles of a camera's image
/// in the rectified one, from a 9 × 9 grid of its pixels as OpenCV's `icvGetRectangles`.
pub(super) struct Rectangles {
    pub(super) inner: [f64; 4],
    pub(super) outer: [f64; 4],
}

impl Rectangles {
    /// The valid region of interest: the inner rectangle rounded inwards, within the rectified
    /// image of `size` (the fisheye's and a file's own, which OpenCV does not scale).
    pub(super) fn inner_roi(&self, size: Size) -> Roi {
        Roi {
            x: self.inner[0].ceil() as i64,
            y: self.inner[1].ceil() as i64,
            width: self.inner[2].floor() as i64,
            height: self.inner[3].floor() as i64,
        }
        .within(size.width, size.height)
    }
}

pub(super) fn rectangles(
    camera: &Camera,
    rotation: &Matrix3<f64>,
    new_matrix: &Matrix3<f64>,
    size: Size,
    side: Side,
) -> Result<Rectangles, RectifyFault> {
    const N: u32 = 9;
    let (mut ix0, mut ix1, mut iy0, mut iy1) = (f64::MIN, f64::MAX, f64::MIN, f64::MAX);
    let (mut ox0, mut ox1, mut oy0, mut oy1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    let mut inverted = 0;
    for y in 0..N {
        for x in 0..N {
            let pixel = [
                f64::from(x) * f64::from(size.width - 1) / f64::from(N - 1),
                f64::from(y) * f64::from(size.height - 1) / f64::from(N - 1),
            ];
            // OpenCV's guess for the pixel (5 fixed-point steps), so that the rectangles and
            // the scale are OpenCV's; a pixel even that leaves undefined bounds nothing.
            let Some([px, py]) =
                project_ray(camera.normalize_as_opencv(pixel), rotation, new_matrix)
            else {
                continue;
            };
            inverted += 1;
            ox0 = ox0.min(px);
            ox1 = ox1.max(px);
            oy0 = oy0.min(py);
            oy1 = oy1.max(py);
            if x == 0 {
                ix0 = ix0.max(px);
            }
            if x == N - 1 {
                ix1 = ix1.min(px);
            }
            if y == 0 {
                iy0 = iy0.max(py);
            }
            if y == N - 1 {
                iy1 = iy1.min(py);
            }
        }
    }
    if inverted < N * N / 2 || [ix0, ix1, iy0, iy1].iter().any(|v| v.abs() == f64::MAX) {
        return Err(RectifyFault::NotInvertible(side));
    }
    Ok(Rectangles {
        inner: [ix0, iy0, ix1 - ix0, iy1 - iy0],
        outer: [ox0, oy0, ox1 - ox0, oy1 - oy0],
    })
}

/// The pixel in a new camera (`rotation`, `new_matrix`) of a raw camera's normalized point.
pub(super) fn project_ray(
    normalized: Option<[f64; 2]>,
    rotation: &Matrix3<f64>,
    new_matrix: &Matrix3<f64>,
) -> Option<[f64; 2]> {
    let [x, y] = normalized?;
    let ray = rotation * Vector3::new(x, y, 1.0);
    if ray.z <= f64::EPSILON {
        return None;
    }
    let p = new_matrix * (ray / ray.z);
    (p.x.is_finite() && p.y.is_finite()).then_some([p.x, p.y])
}

/// The reprojection matrix Q that `stereoRectify` writes, for rectified principal points
/// `c1`, `c2`, focal length `f` and the translation `t` along the baseline (x, or y when
/// `vertical`): `[1 0 0 −cx; 0 1 0 −cy; 0 0 0 f; 0 0 −1/t (c1 − c2)/t]`.
fn reprojection(c1: [f64; 2], c2: [f64; 2], f: f64, t: f64, vertical: bool) -> Matrix4<f64> {
    let shift = if vertical {
        c1[1] - c2[1]
    } else {
        c1[0] - c2[0]
    };
    Matrix4::new(
        1.0,
        0.0,
        0.0,
        -c1[0],
        0.0,
        1.0,
        0.0,
        -c1[1],
        0.0,
        0.0,
        0.0,
        f,
        0.0,
        0.0,
        -1.0 / t,
        shift / t,
    )
}

/// Why a rectification a file gives cannot be used.
#[derive(Debug, Clone, PartialEq)]
pub enum GivenFault {
    /// P2 holds no translation (P2[0,3] = P1[0,3] and P2[1,3] = P1[1,3]).
    NoBaseline,
    /// A focal length in P1 or P2 that is not positive, or a number that is not finite.
    Projection,
    Rectify(RectifyFault),
}

impl Rectification {
    /// A rectification from its rotations and projections, with Q as `stereoRectify` writes
    /// it (from P1's focal length and both principal points) for the translation `t` along
    /// the baseline: x, or y when `vertical`.
    pub(super) fn from_projections(
        [r1, r2]: [Matrix3<f64>; 2],
        [p1, p2]: [Matrix3x4<f64>; 2],
        (t, vertical): (f64, bool),
        [roi_left, roi_right]: [Roi; 2],
        alpha: Option<f64>,
        size: Size,
    ) -> Rectification {
        let (c1, c2) = ([p1[(0, 2)], p1[(1, 2)]], [p2[(0, 2)], p2[(1, 2)]]);
        Rectification {
            r1,
            r2,
            p1,
            p2,
            q: reprojection(c1, c2, p1[(0, 0)], t, vertical),
            alpha,
            roi_left,
            roi_right,
            size,
            vertical,
        }
    }

    /// The rectification a file states (ROS's R and P, KITTI's `R_rect` and `P_rect`,
    /// OpenCV's R1 R2 P1 P2 without recomputing them), with Q as `stereoRectify` would write
    /// it and the valid ROIs found on the same grid as [`super::rectify::stereo_rectify`]'s. `size` is the raw
    /// images', `new_size` the rectified ones'.
    pub fn given(
        pair: &StereoPair,
        size: Size,
        new_size: Size,
        [r1, r2]: [Matrix3<f64>; 2],
        [p1, p2]: [Matrix3x4<f64>; 2],
    ) -> Result<Rectification, GivenFault> {
        let f = p1[(0, 0)];
        if !(f.is_finite() && f > 0.0 && p2[(0, 0)] > 0.0 && p1[(1, 1)] > 0.0)
            || p1.iter().chain(p2.iter()).any(|v| !v.is_finite())
        {
            return Err(GivenFault::Projection);
        }
        if new_size.width == 0 || new_size.height == 0 || size.width == 0 || size.height == 0 {
            return Err(GivenFault::Rectify(RectifyFault::Size));
        }
        let tx = (p2[(0, 3)] - p1[(0, 3)]) / p2[(0, 0)];
        let ty = (p2[(1, 3)] - p1[(1, 3)]) / p2[(1, 1)];
        let vertical = tx == 0.0;
        let t = if vertical { ty } else { tx };
        if t == 0.0 || !t.is_finite() {
            return Err(GivenFault::NoBaseline);
        }
        let roi = |camera: &Camera, rotation: &Matrix3<f64>, p: &Matrix3x4<f64>, side| {
            let matrix = p.fixed_view::<3, 3>(0, 0).into_owned();
            Ok(rectangles(camera, rotation, &matrix, size, side)?.inner_roi(new_size))
        };
        let roi_left = roi(&pair.left, &r1, &p1, Side::Left).map_err(GivenFault::Rectify)?;
        let roi_right = roi(&pair.right, &r2, &p2, Side::Right).map_err(GivenFault::Rectify)?;
        Ok(Rectification::from_projections(
            [r1, r2],
            [p1, p2],
            (t, vertical),
            [roi_left, roi_right],
            None,
            new_size,
        ))
    }

    /// The raw pair these rectified cameras came from, when a file gives only R1 R2 P1 P2 (a
    /// ROS pair): X_right = R2ᵀ·R1·X_left + R2ᵀ·t, t the translation P2 holds.
    pub fn extrinsics(&self) -> (Rotation3<f64>, Vector3<f64>) {
        let f = self.p2[(0, 0)];
        let t = Vector3::new(
            (self.p2[(0, 3)] - self.p1[(0, 3)]) / f,
            (self.p2[(1, 3)] - self.p1[(1, 3)]) / self.p2[(1, 1)],
            self.p2[(2, 3)] - self.p1[(2, 3)],
        );
        let rotation = self.r2.transpose() * self.r1;
        (Rotation3::from_matrix(&rotation), self.r2.transpose() * t)
    }

    /// The rectified rig `/distance` takes: f = P1's focal length, B = |P2's T·f| / f in
    /// `unit` (the unit T was in), the left principal point, doffs = cx_right − cx_left, and
    /// the rectified images' size.
    pub fn rig(&self, unit: LengthUnit) -> Result<Rig, RigFault> {
        if self.vertical {
            return Err(RigFault::Vertical);
        }
        let focal = self.p1[(0, 0)];
        let mut spec = RigSpec::pixels(focal, self.p2[(0, 3)].abs() / focal, unit);
        spec.cx = Some(self.p1[(0, 2)]);
        spec.cy = Some(self.p1[(1, 2)]);
        spec.doffs = Some(self.p2[(0, 2)] - self.p1[(0, 2)]);
        spec.camera.image_width = Some(self.size.width);
        spec.camera.image_height = Some(self.size.height);
        Rig::new(&spec).map_err(RigFault::Rig)
    }
}
