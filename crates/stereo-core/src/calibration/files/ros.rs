//! ROS `CameraInfo`, one file per camera: the `camera_calibration` YAML of ROS 1
//! (`image_width`, `camera_matrix`, `projection_matrix` with `rows`, `cols`, `data`), a ROS 2
//! `ros2 topic echo` message (`width`, `height`, flat `k` and `p`) or a ROS 1 `rostopic echo`
//! (`K`, `P`). The right camera's projection carries the baseline: `P_r[3] = −f·B`.
//!
//! [`write`] writes one camera's `camera_calibration` YAML (`/calibrate`'s `ros-left.yaml`
//! and `ros-right.yaml`), which [`parse`] reads back to the same numbers.

use crate::camera::{Alpha, Camera};
use nalgebra::{Matrix3, Matrix3x4};

use super::yaml::{self, Node};
use super::{Calibration, Format, ParseError, RigStd, pixels, raw};
use crate::camera::{Model, Size};
use crate::numbers::Num;
use crate::physics::LengthUnit;

/// What one camera's file gives.
struct CameraFile {
    /// The 3×4 projection, row-major.
    p: Vec<f64>,
    p_line: usize,
    size: Option<(u32, u32)>,
    /// The rectified rig's σ our files add (`rig_focal_length_std_px`, `rig_baseline_std_m`).
    rig_std: Option<RigStd>,
    /// K, D and R with their lines, and the model the file names: the raw camera, when the
    /// file gives all three.
    raw: Option<RawCamera>,
}

struct RawCamera {
    k: (Vec<f64>, usize),
    d: (Vec<f64>, usize),
    r: (Vec<f64>, usize),
    model: Option<Model>,
}

/// A member given as a `{rows, cols, data}` map or as a flat list, under any of `names`:
/// its numbers and line, or `None` when absent.
fn member(doc: &Node, names: &[&str]) -> Result<Option<(Vec<f64>, usize)>, ParseError> {
    let Some((name, node)) = names.iter().find_map(|k| doc.get(k).map(|n| (*k, n))) else {
        return Ok(None);
    };
    let data = match node {
        Node::Map(..) => node.get("data").ok_or_else(|| {
            ParseError::at(node.line(), format!("{name} must have data: [numbers]"))
        })?,
        other => other,
    };
    Ok(Some((data.numbers(&format!("{name}.data"))?, data.line())))
}

/// The raw camera a CameraInfo describes, when it gives K, D and R.
fn raw_camera(doc: &Node) -> Result<Option<RawCamera>, ParseError> {
    let k = member(doc, &["camera_matrix", "k", "K"])?;
    let d = member(doc, &["distortion_coefficients", "d", "D"])?;
    let r = member(doc, &["rectification_matrix", "r", "R"])?;
    let model = match doc.get("distortion_model") {
        Some(node) => {
            let name = match node {
                Node::Scalar(text, _) => text.trim_matches(['"', '\'']).to_owned(),
                _ => String::new(),
            };
            Some(Model::from_name(&name).ok_or_else(|| {
                ParseError::at(
                    node.line(),
                    format!(
                        "distortion_model `{}` is not one this service knows: plumb_bob, \
                         rational_polynomial or equidistant",
                        crate::numbers::clip(&name, 40)
                    ),
                )
            })?)
        }
        None => None,
    };
    let (Some(k), Some(mut d), Some(r)) = (k, d, r) else {
        return Ok(None);
    };
    // An empty D (a CameraInfo with no distortion) is the model's zeros.
    if d.0.is_empty() {
        d.0 = vec![0.0; model.unwrap_or(Model::PlumbBob).coefficient_count()];
    }
    Ok(Some(RawCamera { k, d, r, model }))
}

fn camera(text: &str) -> Result<CameraFile, ParseError> {
    let doc = yaml::parse(text)?;
    if !matches!(doc, Node::Map(..)) {
        return Err(ParseError::whole(
            "expected a CameraInfo: a YAML map with projection_matrix (or p)",
        ));
    }
    let (name, node) = ["projection_matrix", "p", "P"]
        .into_iter()
        .find_map(|k| doc.get(k).map(|n| (k, n)))
        .ok_or_else(|| {
            ParseError::whole(
                "no projection matrix: expected projection_matrix (camera_calibration YAML) \
                 or p (a CameraInfo message)",
            )
        })?;
    let data = match node {
        Node::Map(..) => node.get("data").ok_or_else(|| {
            ParseError::at(node.line(), format!("{name} must have data: [12 numbers]"))
        })?,
        other => other,
    };
    let p = data.numbers(&format!("{name}.data"))?;
    if p.len() != 12 {
        return Err(ParseError::at(
            data.line(),
            format!(
                "{name} must be a 3×4 projection matrix of 12 numbers, got {}",
                p.len()
            ),
        ));
    }
    let extent = |keys: [&str; 2]| -> Result<Option<u32>, ParseError> {
        let Some((key, node)) = keys.into_iter().find_map(|k| doc.get(k).map(|n| (k, n))) else {
            return Ok(None);
        };
        let value = node.number(key)?;
        // CameraInfo leaves an unset size at 0.
        if value == 0.0 {
            return Ok(None);
        }
        pixels(value).map(Some).ok_or_else(|| {
            ParseError::at(
                node.line(),
                format!("{key} must be a whole number of pixels, got {}", Num(value)),
            )
        })
    };
    let width = extent(["image_width", "width"])?;
    let height = extent(["image_height", "height"])?;
    let std = |key: &str| -> Result<Option<f64>, ParseError> {
        let Some(node) = doc.get(key) else {
            return Ok(None);
        };
        let value = node.number(key)?;
        if value.is_finite() && value >= 0.0 {
            Ok(Some(value))
        } else {
            Err(ParseError::at(
                node.line(),
                format!(
                    "{key} must be a standard deviation, 0 or more, got {}",
                    Num(value)
                ),
            ))
        }
    };
    let rig_std = std("rig_focal_length_std_px")?
        .zip(std("rig_baseline_std_m")?)
        .map(|(focal_px, baseline)| RigStd { focal_px, baseline });
    Ok(CameraFile {
        p,
        p_line: data.line(),
        size: width.zip(height),
        rig_std,
        raw: raw_camera(&doc)?,
    })
}

/// The raw pair of two CameraInfos that both give K, D and R: the rectification is theirs
/// (R and P), or recomputed with `alpha` from the pose they imply.
fn raw_pair(
    left: &CameraFile,
    right: &CameraFile,
    alpha: Option<Alpha>,
    image_size: Option<(u32, u32)>,
) -> Result<Option<raw::Raw>, Vec<ParseError>> {
    let (Some(l), Some(r)) = (&left.raw, &right.raw) else {
        return Ok(None);
    };
    let camera = |c: &RawCamera| {
        raw::camera(&raw::CameraText {
            k_name: "camera_matrix",
            k: &c.k.0,
            k_line: c.k.1,
            d_name: "distortion_coefficients",
            d: &c.d.0,
            d_line: c.d.1,
            model: c.model,
        })
    };
    let (lc, rc) = (
        camera(l),
        camera(r).map_err(|e| e.into_iter().map(ParseError::in_right).collect::<Vec<_>>()),
    );
    let rl = raw::rotation(&l.r.0, "rectification_matrix", l.r.1);
    let rr = raw::rotation(&r.r.0, "rectification_matrix", r.r.1).map_err(ParseError::in_right);
    let (lc, rc, rl, rr) = match (lc, rc, rl, rr) {
        (Ok(a), Ok(b), Ok(c), Ok(d)) => (a, b, c, d),
        (a, b, c, d) => {
            let mut errors = Vec::new();
            errors.extend(a.err().into_iter().flatten());
            errors.extend(b.err().into_iter().flatten());
            errors.extend(c.err());
            errors.extend(d.err());
            return Err(errors);
        }
    };
    let Some(size) = left.size.or(right.size).or(image_size) else {
        // Without the raw size the raw images cannot be rectified; the rectified rig stands.
        return Ok(None);
    };
    let parts = raw::RawParts {
        left: lc,
        right: rc,
        extrinsics: None,
        given: Some(raw::Given {
            r: [rl, rr],
            p: [
                Matrix3x4::from_row_slice(&left.p),
                Matrix3x4::from_row_slice(&right.p),
            ],
            line: right.p_line,
        }),
        size: Some(Size {
            width: size.0,
            height: size.1,
        }),
        rectified_size: None,
        line: l.k.1,
    };
    raw::pair(parts, alpha).map(Some).map_err(|e| vec![e])
}

pub fn parse(
    text: &str,
    right_text: Option<&str>,
    alpha: Option<Alpha>,
    image_size: Option<(u32, u32)>,
) -> Result<Calibration, Vec<ParseError>> {
    let left = camera(text);
    let Some(right_text) = right_text else {
        let mut errors = vec![
            ParseError::whole(
                "is required for a ROS rig: the right camera's CameraInfo, beside the left \
                 camera's (its projection matrix holds the baseline)",
            )
            .in_right(),
        ];
        errors.extend(left.err());
        return Err(errors);
    };
    let right = camera(right_text).map_err(ParseError::in_right);
    let (left, right) = match (left, right) {
        (Ok(l), Ok(r)) => (l, r),
        (l, r) => return Err(l.err().into_iter().chain(r.err()).collect()),
    };
    let (pl, pr) = (&left.p, &right.p);
    let mut warnings = Vec::new();
    let f = pr[0];
    if (pl[0] - f).abs() > 1e-9 * f.abs() {
        warnings.push(format!(
            "the two projection matrices have different focal lengths ({} and {} px): a \
             rectified pair shares one; the right camera's is used",
            Num(pl[0]),
            Num(f)
        ));
    }
    if pl[3] != 0.0 {
        warnings.push(format!(
            "the left camera's P[3] is {} rather than 0; the baseline is (P_l[3] − P_r[3]) / f",
            Num(pl[3])
        ));
    }
    if left.size.is_some() && right.size.is_some() && left.size != right.size {
        warnings.push("the two cameras give different image sizes; the left one's is used".into());
    }
    let size = left.size.or(right.size);
    let raw = raw_pair(&left, &right, alpha, image_size)?;
    if left.raw.is_some() != right.raw.is_some() {
        warnings.push(
            "only one camera's CameraInfo gives K, D and R, so the raw cameras are not \
             described and only rectified images can be used"
                .into(),
        );
    }
    let calibration = match raw {
        // A recomputed rectification gives the rig; the files' own gives the same as P.
        Some(raw) if raw.computed => raw::calibration(Format::Ros, raw, warnings),
        Some(raw) => {
            let mut c = Calibration::from_projections(Format::Ros, pl, pr, f, size, warnings);
            c.raw = Some(Box::new(raw));
            c
        }
        None => Calibration::from_projections(Format::Ros, pl, pr, f, size, warnings),
    };
    if calibration.baseline < 0.0 {
        return Err(vec![
            ParseError::at(
                left.p_line,
                format!(
                    "the baseline from these files is negative ({} m): the first must be the \
                     left camera's CameraInfo and the second the right camera's; they look \
                     swapped",
                    Num(calibration.baseline)
                ),
            ),
            ParseError::at(
                right.p_line,
                "the right camera's P[3] = −f·B must be negative for a right camera",
            )
            .in_right(),
        ]);
    }
    let mut calibration = calibration;
    calibration.rig_std = right.rig_std.or(left.rig_std);
    calibration
        .checked(Some(right.p_line))
        .map_err(|errors| errors.into_iter().map(ParseError::in_right).collect())
}

/// One camera of a calibration as ROS `camera_calibration` writes it and
/// `camera_info_manager` reads it.
#[derive(Debug, Clone, Copy)]
pub struct CameraInfo<'a> {
    /// `camera_name`: `left` or `right`.
    pub name: &'a str,
    /// The raw images' size.
    pub size: Size,
    pub camera: &'a Camera,
    /// The rectifying rotation (R1 or R2).
    pub rotation: Matrix3<f64>,
    /// The rectified projection (P1 or P2), its translation in `unit`.
    pub projection: Matrix3x4<f64>,
    pub unit: LengthUnit,
    /// The rectified rig's σ (the baseline's in `unit`), written in metres as
    /// `rig_focal_length_std_px` and `rig_baseline_std_m`: keys `camera_calibration_parsers`
    /// and `camera_info_manager` do not read, and so leave alone.
    pub rig_std: Option<RigStd>,
}

impl<'a> CameraInfo<'a> {
    /// A camera calibrated alone: nothing to rectify, so R = I and P = [K | 0].
    pub fn alone(name: &'a str, size: Size, camera: &'a Camera, unit: LengthUnit) -> Self {
        let mut projection = Matrix3x4::zeros();
        projection
            .fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&camera.matrix());
        CameraInfo {
            name,
            size,
            camera,
            rotation: Matrix3::identity(),
            projection,
            unit,
            rig_std: None,
        }
    }
}

/// The camera's YAML: K, D with its model, the rectifying rotation and the rectified
/// projection, whose translation is written in metres, as ROS has it.
pub fn write(info: &CameraInfo<'_>) -> String {
    let mut p = info.projection;
    for row in 0..3 {
        p[(row, 3)] = info.unit.convert(p[(row, 3)], LengthUnit::Metre);
    }
    let list = |data: &[f64]| {
        data.iter()
            .map(|&v| yaml::write_number(v))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let d = info.camera.distortion();
    let std = info.rig_std.map_or_else(String::new, |std| {
        format!(
            "rig_focal_length_std_px: {}\nrig_baseline_std_m: {}\n",
            yaml::write_number(std.focal_px),
            yaml::write_number(info.unit.convert(std.baseline, LengthUnit::Metre))
        )
    });
    let text = format!(
        "image_width: {}\nimage_height: {}\ncamera_name: {}\ncamera_matrix:\n  rows: 3\n  \
         cols: 3\n  data: [{}]\ndistortion_model: {}\ndistortion_coefficients:\n  rows: 1\n  \
         cols: {}\n  data: [{}]\nrectification_matrix:\n  rows: 3\n  cols: 3\n  data: [{}]\n\
         projection_matrix:\n  rows: 3\n  cols: 4\n  data: [{}]\n",
        info.size.width,
        info.size.height,
        info.name,
        list(&yaml::row_major(&info.camera.matrix())),
        d.model().name(),
        d.coefficients().len(),
        list(d.coefficients()),
        list(&yaml::row_major(&info.rotation)),
        list(&yaml::row_major(&p)),
    );
    text + &std
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What [`write`] writes for both cameras, [`parse`] reads back to the same numbers: K, D,
    /// the rectifying rotations and the projections (whose translation is written in metres),
    /// and so the baseline in metres.
    #[test]
    fn written_camera_infos_read_back_the_same() {
        let (pair, size, rect) = crate::calibration::files::sample_pair();
        let info = |name, camera, rotation, projection| {
            write(&CameraInfo {
                name,
                size,
                camera,
                rotation,
                projection,
                unit: LengthUnit::Millimetre,
                rig_std: Some(RigStd {
                    focal_px: 0.25,
                    baseline: 12.5,
                }),
            })
        };
        let left = info("left", &pair.left, rect.r1, rect.p1);
        let right = info("right", &pair.right, rect.r2, rect.p2);
        let read = parse(&left, Some(&right), None, None).expect("our own files read");
        let raw = read.raw.expect("the raw cameras");
        for (ours, theirs) in [(&raw.pair.left, &pair.left), (&raw.pair.right, &pair.right)] {
            assert_eq!(ours.matrix(), theirs.matrix());
            assert_eq!(ours.distortion(), theirs.distortion());
        }
        // The reader rebuilds R1 R2 as rotations: equal to the last bits.
        let r = &raw.rectification;
        assert!((r.r1 - rect.r1).amax() < 1e-14 && (r.r2 - rect.r2).amax() < 1e-14);
        let mut p2 = rect.p2;
        p2[(0, 3)] /= 1000.0;
        assert!(
            (r.p2 - p2).amax() < 1e-12 && r.p1 == rect.p1,
            "{} vs {p2}",
            r.p2
        );
        // The rig's σ, its baseline's in metres as the files' lengths are.
        assert_eq!(
            read.rig_std,
            Some(RigStd {
                focal_px: 0.25,
                baseline: 0.0125
            })
        );
        let b = rect.p2[(0, 3)].abs() / rect.p2[(0, 0)] / 1000.0;
        assert!(
            (read.baseline - b).abs() < 1e-15,
            "{} m vs {b} m",
            read.baseline
        );
    }

    /// A camera calibrated alone is written with R = I and P = [K | 0], and reads back as a
    /// camera with that K and D.
    #[test]
    fn a_camera_alone_has_no_rectification() {
        let (pair, size, _) = crate::calibration::files::sample_pair();
        let info = CameraInfo::alone("left", size, &pair.left, LengthUnit::Millimetre);
        assert_eq!(info.rotation, Matrix3::identity());
        assert_eq!(info.projection.fixed_view::<3, 3>(0, 0), pair.left.matrix());
        assert_eq!(info.projection.column(3).amax(), 0.0);
        let text = write(&info);
        assert!(text.contains("camera_name: left\n"), "{text}");
        assert!(text.contains("distortion_model: plumb_bob\n"), "{text}");
        assert!(
            text.contains("rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]"),
            "{text}"
        );
    }
}
