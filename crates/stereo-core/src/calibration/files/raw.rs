//! Calibrations that describe the raw cameras (intrinsics K, distortion D, the pose between
//! them or each camera's rectifying rotation), as `stereoCalibrate`, ROS `CameraInfo` and
//! KITTI's raw `calib_cam_to_cam.txt` give them: each camera checked into a
//! [`crate::camera::Camera`], rotations checked to be rotations, and the rectification either
//! the file's own or computed as `cv2.stereoRectify` computes it with the caller's `alpha`.

use crate::camera::Alpha;
use nalgebra::{Matrix3, Matrix3x4, Rotation3, Vector3};

use super::{Calibration, Format, ParseError};
use crate::camera::{
    Camera, CameraFault, Distortion, GivenFault, Intrinsics, Latlon, LatlonFault, LatlonOptions,
    Model, Rectification, RectifyFault, RectifyOptions, Size, StereoPair, WIDE_FOV_DEG,
    stereo_rectify,
};
use crate::numbers::Num;

/// The largest distortion coefficient taken as meant: lenses users have stay within a few
/// units, and a coefficient of thousands is a unit or a copy mistake.
const MAX_COEFFICIENT: f64 = 1000.0;

/// How far a rotation may be from orthonormal (and its determinant from 1).
const ROTATION_TOLERANCE: f64 = 1e-6;

/// The raw cameras a calibration describes and the rectification that turns their images
/// into the rectified pair of the rig.
#[derive(Debug, Clone, PartialEq)]
pub struct Raw {
    /// Both cameras and the right one's pose: X_right = R·X_left + T, T in the file's unit.
    pub pair: StereoPair,
    /// The raw images' size.
    pub size: Size,
    pub rectification: Rectification,
    /// Whether the rectification was computed here (`stereoRectify` with the caller's
    /// `alpha`) rather than read from the file.
    pub computed: bool,
    /// When the frames are rectified to latitude-longitude (mrcal's) instead of the pinhole
    /// plane of `rectification`: the rectified system.
    pub latlon: Option<Latlon>,
}

impl Raw {
    /// Whether rectifying changes nothing: no distortion, no rotation, and the new cameras
    /// equal to the raw ones (a rig whose raw images are already rectified).
    pub fn is_identity(&self) -> bool {
        let same = |camera: &Camera, rotation: &Matrix3<f64>, p: &Matrix3x4<f64>| {
            let k = camera.intrinsics();
            camera.distortion().is_none()
                && (rotation - Matrix3::identity()).abs().max() < 1e-12
                && (p.fixed_view::<3, 3>(0, 0) - camera.matrix()).abs().max() < 1e-9 * k.fx
        };
        let r = &self.rectification;
        self.latlon.is_none()
            && self.size == r.size
            && same(&self.pair.left, &r.r1, &r.p1)
            && same(&self.pair.right, &r.r2, &r.p2)
    }

    /// The rectified images' size: the latitude-longitude system's, or the pinhole plane's.
    pub fn rectified_size(&self) -> Size {
        self.latlon.map_or(self.rectification.size, |l| l.size)
    }

    /// Whether the cameras together see wider than [`WIDE_FOV_DEG`] across the baseline or
    /// about it: the field of the latitude-longitude system that holds what both see.
    pub fn sees_wide(&self) -> bool {
        self.chosen_latlon().is_ok_and(|l| wide(&l))
    }

    /// The latitude-longitude system with the field and resolution the calibration gives.
    fn chosen_latlon(&self) -> Result<Latlon, LatlonFault> {
        Latlon::new(&self.pair, self.size, LatlonOptions::default())
    }

    /// The same cameras rectified to latitude-longitude, the field and resolution chosen
    /// as [`Latlon::new`] chooses them where `options` leave them out; with
    /// `options.when_wide`, only when they [see wide](Raw::sees_wide) (else as they were).
    pub fn with_latlon(self, options: LatlonOptions) -> Result<Raw, LatlonFault> {
        let chosen = options.chosen().then(|| self.chosen_latlon());
        if options.when_wide {
            let sees_wide = match &chosen {
                Some(chosen) => chosen.as_ref().is_ok_and(wide),
                None => self.sees_wide(),
            };
            if !sees_wide {
                return Ok(self);
            }
        }
        let latlon = chosen.unwrap_or_else(|| Latlon::new(&self.pair, self.size, options))?;
        Ok(Raw {
            latlon: Some(latlon),
            ..self
        })
    }
}

/// Whether a latitude-longitude field is wider than [`WIDE_FOV_DEG`] along either axis.
fn wide(latlon: &Latlon) -> bool {
    latlon.az_fov_deg.max(latlon.el_fov_deg) > WIDE_FOV_DEG
}

/// One camera as a file states it: K (row-major 3 × 3), D and the model the file names, if
/// it names one, with the lines to name in errors.
pub struct CameraText<'a> {
    /// What the file calls this camera (`M1`, `K_02`, the left `camera_matrix`…).
    pub k_name: &'a str,
    pub k: &'a [f64],
    pub k_line: usize,
    pub d_name: &'a str,
    pub d: &'a [f64],
    pub d_line: usize,
    pub model: Option<Model>,
}

/// The model of a distortion from its coefficient count, as OpenCV reads `distCoeffs`.
fn model_for(text: &CameraText) -> Result<Model, ParseError> {
    let n = text.d.len();
    match (text.model, n) {
        (Some(Model::Equidistant), 4) => Ok(Model::Equidistant),
        (Some(Model::Equidistant), _) => Err(ParseError::at(
            text.d_line,
            format!(
                "{} must hold the 4 equidistant (fisheye) coefficients k1 k2 k3 k4, got {n}",
                text.d_name
            ),
        )),
        (Some(Model::PlumbBob), 4 | 5) | (None, 4 | 5) => Ok(Model::PlumbBob),
        (Some(Model::RationalPolynomial), 8) | (None, 8) => Ok(Model::RationalPolynomial),
        (None, 12 | 14) => Err(ParseError::at(
            text.d_line,
            format!(
                "{} has {n} coefficients: OpenCV's thin-prism{} model is not one this service \
                 rectifies; it reads plumb_bob (5), rational_polynomial (8) and equidistant (4)",
                text.d_name,
                if n == 14 { " and tilted" } else { "" }
            ),
        )),
        (declared, _) => Err(ParseError::at(
            text.d_line,
            format!(
                "{} has {n} coefficients, which {}: plumb_bob has 4 or 5 (k1 k2 p1 p2 [k3]), \
                 rational_polynomial 8, equidistant 4",
                text.d_name,
                declared.map_or(
                    "fits no distortion model this service reads".to_owned(),
                    |m| { format!("is not what {m} has") }
                )
            ),
        )),
    }
}

/// The camera a file states, checked: a camera matrix `[fx 0 cx; 0 fy cy; 0 0 1]` with
/// positive focal lengths (a skew is refused), and coefficients that are finite and not
/// absurd.
pub fn camera(text: &CameraText) -> Result<Camera, Vec<ParseError>> {
    let mut errors = Vec::new();
    let k = text.k;
    let layout_ok = k.len() == 9 && k[3] == 0.0 && k[6] == 0.0 && k[7] == 0.0 && k[8] == 1.0;
    if !layout_ok {
        errors.push(ParseError::at(
            text.k_line,
            format!(
                "{} must be a camera matrix [fx 0 cx; 0 fy cy; 0 0 1]",
                text.k_name
            ),
        ));
    } else if k[1] != 0.0 {
        errors.push(ParseError::at(
            text.k_line,
            format!(
                "{} has a skew ({}): rectification here takes fx, fy, cx and cy, as \
                 initUndistortRectifyMap does; calibrate without skew",
                text.k_name,
                Num(k[1])
            ),
        ));
    }
    let model = model_for(text).map_err(|e| errors.push(e)).ok();
    if let Some(i) = text.d.iter().position(|c| !c.is_finite()) {
        errors.push(ParseError::at(
            text.d_line,
            format!("{}[{i}] is not a finite number", text.d_name),
        ));
    } else if let Some(i) = text.d.iter().position(|c| c.abs() > MAX_COEFFICIENT) {
        errors.push(ParseError::at(
            text.d_line,
            format!(
                "{}[{i}] is {}: distortion coefficients beyond ±{} describe no lens; check \
                 the file",
                text.d_name,
                Num(text.d[i]),
                Num(MAX_COEFFICIENT)
            ),
        ));
    }
    if !errors.is_empty() || !layout_ok {
        return Err(errors);
    }
    let model = model.ok_or_else(Vec::new)?;
    let distortion = Distortion::new(model, text.d)
        .map_err(|e| vec![ParseError::at(text.d_line, format!("{}: {e}", text.d_name))])?;
    Camera::new(
        Intrinsics {
            fx: k[0],
            fy: k[4],
            cx: k[2],
            cy: k[5],
        },
        distortion,
    )
    .map_err(|e| {
        let what = match e {
            CameraFault::Focal(name) => format!("{name} must be a positive finite number"),
            CameraFault::PrincipalPoint(name) => format!("{name} must be a finite number"),
            CameraFault::Distortion(d) => d.to_string(),
        };
        vec![ParseError::at(
            text.k_line,
            format!("{}: {what}", text.k_name),
        )]
    })
}

/// How far a rotation printed with `values`' decimals may be from orthonormal: 1e-6, or 5
/// units of the last decimal for a file that prints 4 to 6 (ROS YAMLs often print 5), whose
/// rounding alone moves RᵀR by a few units of the last decimal.
fn rotation_tolerance(values: &[f64]) -> f64 {
    let decimals = (0..=12).find(|&k| {
        let scale = 10f64.powi(k);
        values.iter().all(|v| {
            let s = v * scale;
            (s - s.round()).abs() <= 1e-6 * s.abs().max(1.0)
        })
    });
    // Fewer than 4 decimals is no calibrated rotation (the identity, printed with none, is
    // exact), so only 4 and more widen the tolerance.
    decimals
        .filter(|&k| k >= 4)
        .map_or(ROTATION_TOLERANCE, |k| {
            ROTATION_TOLERANCE.max(5.0 * 10f64.powi(-k))
        })
}

/// A 3 × 3 row-major rotation, checked: orthonormal and of determinant 1 within 1e-6 (or
/// within what the decimals the file prints allow), then made exactly orthonormal.
pub fn rotation(values: &[f64], name: &str, line: usize) -> Result<Matrix3<f64>, ParseError> {
    if values.len() != 9 || values.iter().any(|v| !v.is_finite()) {
        return Err(ParseError::at(
            line,
            format!("{name} must be a 3×3 rotation of 9 finite numbers"),
        ));
    }
    let m = Matrix3::from_row_slice(values);
    let off = (m.transpose() * m - Matrix3::identity()).abs().max();
    let det = m.determinant();
    let tolerance = rotation_tolerance(values);
    if off > tolerance || (det - 1.0).abs() > tolerance {
        return Err(ParseError::at(
            line,
            format!(
                "{name} is not a rotation: RᵀR differs from the identity by {} and det R = {} \
                 (both must be within {} of a rotation's)",
                Num(off),
                Num(det),
                Num(tolerance)
            ),
        ));
    }
    Ok(*Rotation3::from_matrix(&m).matrix())
}

/// A rectification a file gives: R1 R2 (row-major 3 × 3, checked) and P1 P2 (3 × 4).
pub struct Given {
    pub r: [Matrix3<f64>; 2],
    pub p: [Matrix3x4<f64>; 2],
    pub line: usize,
}

/// What a file gives toward the raw pair.
pub struct RawParts {
    pub left: Camera,
    pub right: Camera,
    /// R and T (X_right = R·X_left + T), when the file gives them.
    pub extrinsics: Option<(Matrix3<f64>, Vector3<f64>)>,
    pub given: Option<Given>,
    /// The raw images' size, and the rectified ones' when the file says (KITTI's `S_rect`).
    pub size: Option<Size>,
    pub rectified_size: Option<Size>,
    /// The line to name when something about the whole pair is wrong.
    pub line: usize,
}

/// The raw pair and its rectification: the file's own unless the caller asks for an `alpha`,
/// computed as `stereoRectify` does with that `alpha` (0 when the file gives none).
pub fn pair(parts: RawParts, alpha: Option<Alpha>) -> Result<Raw, ParseError> {
    let at = |message: String| ParseError::at(parts.line, message);
    let Some(size) = parts.size else {
        return Err(at(
            "the raw images' size is needed to rectify them, and the file does not give it: \
             add imageSize: [width, height] (OpenCV), image_width and image_height (ROS) or \
             S_0i (KITTI), or send the images with it"
                .into(),
        ));
    };
    let rectified_size = parts.rectified_size.unwrap_or(size);
    let fault = |e: RectifyFault| at(format!("this pair cannot be rectified: {e}"));
    let given = match &parts.given {
        Some(given) => {
            // The pose is not needed to use the file's rectification: any will do for now.
            let provisional = StereoPair {
                left: parts.left,
                right: parts.right,
                rotation: Rotation3::identity(),
                translation: Vector3::x(),
            };
            let rect = Rectification::given(&provisional, size, rectified_size, given.r, given.p)
                .map_err(|e| {
                ParseError::at(
                    given.line,
                    match e {
                        GivenFault::NoBaseline => "the right camera's projection holds no \
                                                       baseline (P2[0,3] = P1[0,3])"
                            .to_owned(),
                        GivenFault::Projection => "the projection matrices must have \
                                                       positive focal lengths and finite \
                                                       numbers"
                            .to_owned(),
                        GivenFault::Rectify(e) => {
                            format!("this rectification cannot be used: {e}")
                        }
                    },
                )
            })?;
            Some(rect)
        }
        None => None,
    };
    // The pose: the file's, or the one its rectification implies (a ROS pair).
    let Some((rotation, translation)) = parts
        .extrinsics
        .map(|(r, t)| (Rotation3::from_matrix_unchecked(r), t))
        .or_else(|| given.as_ref().map(Rectification::extrinsics))
    else {
        return Err(at(
            "the file gives the cameras but neither their pose (R and T) nor a rectification \
             (R1 R2 P1 P2)"
                .into(),
        ));
    };
    let pair = StereoPair {
        left: parts.left,
        right: parts.right,
        rotation,
        translation,
    };
    match (given, alpha) {
        (Some(rectification), None) => Ok(Raw {
            pair,
            size,
            rectification,
            computed: false,
            latlon: None,
        }),
        (_, alpha) => {
            let options = RectifyOptions {
                alpha: alpha.unwrap_or(Alpha::ZERO),
                new_size: Some(rectified_size),
                ..RectifyOptions::default()
            };
            let rectification = stereo_rectify(&pair, size, options).map_err(fault)?;
            Ok(Raw {
                pair,
                size,
                rectification,
                computed: true,
                latlon: None,
            })
        }
    }
}

/// The rectified rig's numbers of a raw pair, with the pair attached.
pub fn calibration(format: Format, raw: Raw, warnings: Vec<String>) -> Calibration {
    let r = &raw.rectification;
    let row = |p: &Matrix3x4<f64>| -> Vec<f64> { p.transpose().as_slice().to_vec() };
    let (p1, p2) = (row(&r.p1), row(&r.p2));
    let size = (r.size.width, r.size.height);
    let mut c = Calibration::from_projections(format, &p1, &p2, p2[0], Some(size), warnings);
    c.raw = Some(Box::new(raw));
    c
}
