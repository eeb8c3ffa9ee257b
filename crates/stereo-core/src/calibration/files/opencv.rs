//! OpenCV FileStorage after `stereoRectify`, as YAML (`%YAML:1.0`, `!!opencv-matrix`) or XML
//! (`<opencv_storage>`, `type_id="opencv-matrix"`). The rig comes from the reprojection matrix
//!
//! ```text
//! Q = [1 0 0 −cx; 0 1 0 −cy; 0 0 0 f; 0 0 −1/Tx (cx − cx')/Tx]
//! ```
//!
//! (f = Q[2,3], cx = −Q[0,3], cy = −Q[1,3], B = 1/Q[3,2], doffs = Q[3,3]/Q[3,2]), or from the
//! rectified projections `P1`, `P2` when there is no `Q` (B = −P2[0,3]/P2[0,0]). Lengths are in
//! the unit of the calibration target's squares, which the file does not record.
//!
//! [`write`] writes the file `/calibrate` answers (`opencv.yml`: M1 D1 M2 D2 R T E F R1 R2 P1
//! P2 Q, as `stereo_calib.cpp` writes `intrinsics.yml` and `extrinsics.yml`, in one file),
//! which [`parse`] reads back to the same numbers.

use std::fmt::Write;

use crate::camera::{Alpha, Rectification, StereoPair};
use nalgebra::{Matrix3, Matrix3x4, Vector3};

use super::xml;
use super::yaml::{self, Node};
use super::{Calibration, Format, ParseError, RigStd, pixels, raw};
use crate::camera::{Model, Size};
use crate::numbers::Num;
use crate::physics::LengthUnit;

/// One FileStorage text, YAML or XML.
fn document(text: &str) -> Result<Node, ParseError> {
    if text.trim_start().starts_with('<') {
        xml::parse(text)
    } else {
        yaml::parse(text)
    }
}

/// Reads one file, or two (`stereo_calib.cpp`'s `intrinsics.yml` and `extrinsics.yml`) read
/// as one. A file with the cameras (M1/K1 D1 M2/K2 D2) describes the raw pair: its rig is
/// that of its R1 R2 P1 P2, or of the rectification computed with `alpha` and the images'
/// size when it has none.
pub fn parse(
    text: &str,
    second: Option<&str>,
    alpha: Option<Alpha>,
    image_size: Option<(u32, u32)>,
) -> Result<Calibration, Vec<ParseError>> {
    let mut doc = document(text).map_err(|e| vec![e])?;
    if let Some(second) = second {
        let other = document(second).map_err(|e| vec![e.in_right()])?;
        if let (Node::Map(members, _), Node::Map(more, _)) = (&mut doc, other) {
            members.extend(more);
        }
    }
    let unit = match doc.get("unit") {
        Some(node) => Some(unit(node)?),
        None => None,
    };
    let mut calibration = match raw_parts(&doc, image_size)? {
        // A rectified file without the raw size: its rig stands, its raw cameras cannot be
        // used.
        Some(parts) if parts.size.is_none() && parts.given.is_some() => rig(&doc)?,
        Some(parts) => {
            let raw = raw::pair(parts, alpha).map_err(|e| vec![e])?;
            raw::calibration(Format::OpenCv, raw, Vec::new()).checked(None)?
        }
        None => rig(&doc)?,
    };
    calibration.unit = unit;
    calibration.rig_std = rig_std(&doc)?;
    Ok(calibration)
}

/// The rectified rig's σ our `opencv.yml` records (`rigFocalLengthStd` in pixels and
/// `rigBaselineStd` in the file's unit), when both are there.
fn rig_std(doc: &Node) -> Result<Option<RigStd>, Vec<ParseError>> {
    let mut errors = Vec::new();
    let mut read = |name: &str| {
        let node = doc.get(name)?;
        match node.number(name) {
            Ok(v) if v.is_finite() && v >= 0.0 => Some(v),
            Ok(v) => {
                errors.push(ParseError::at(
                    node.line(),
                    format!(
                        "{name} must be a standard deviation, 0 or more, got {}",
                        Num(v)
                    ),
                ));
                None
            }
            Err(e) => {
                errors.push(e);
                None
            }
        }
    };
    let (focal_px, baseline) = (read("rigFocalLengthStd"), read("rigBaselineStd"));
    if !errors.is_empty() {
        return Err(errors);
    }
    Ok(focal_px
        .zip(baseline)
        .map(|(focal_px, baseline)| RigStd { focal_px, baseline }))
}

/// The printed target a calibration was made with, as `opencv.yml` records it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    /// Inner corners along a row and a column (OpenCV's `patternSize`).
    pub columns: u32,
    pub rows: u32,
    pub square_size: f64,
    /// The unit of `square_size`, and so of T and P2's translation.
    pub unit: LengthUnit,
}

/// A stereo calibration as `opencv.yml` holds it.
#[derive(Debug, Clone, Copy)]
pub struct StereoFile<'a> {
    /// The raw images' size.
    pub size: Size,
    pub pair: &'a StereoPair,
    pub essential: Matrix3<f64>,
    pub fundamental: Matrix3<f64>,
    pub rectification: &'a Rectification,
    /// The board it was calibrated with, when it was (a corrected calibration has none).
    pub target: Option<Target>,
    /// The unit of T and P2's translation.
    pub unit: LengthUnit,
    /// The rectified rig's σ, written as `rigFocalLengthStd` and `rigBaselineStd` (nodes
    /// `cv2.FileStorage` reads and OpenCV's functions never look for).
    pub rig_std: Option<RigStd>,
}

/// OpenCV FileStorage YAML with M1 D1 M2 D2 R T E F R1 R2 P1 P2 Q, `imageSize` and the target
/// (`cv2.FileStorage(path, cv2.FILE_STORAGE_READ).getNode("M1").mat()`). Lengths are in
/// `unit`, which is recorded.
pub fn write(file: &StereoFile<'_>) -> String {
    let matrix = |out: &mut String, name: &str, rows: usize, cols: usize, data: &[f64]| {
        let data: Vec<String> = data.iter().map(|&v| yaml::write_number(v)).collect();
        let _ = writeln!(
            out,
            "{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {} ]",
            data.join(", ")
        );
    };
    let (pair, rect) = (file.pair, file.rectification);
    let mut out = String::from("%YAML:1.0\n---\n");
    let _ = writeln!(
        out,
        "imageSize: [ {}, {} ]",
        file.size.width, file.size.height
    );
    if let Some(target) = file.target {
        let _ = writeln!(
            out,
            "boardSize: [ {}, {} ]\nsquareSize: {}",
            target.columns,
            target.rows,
            yaml::write_number(target.unit.convert(target.square_size, file.unit)),
        );
    }
    let _ = writeln!(
        out,
        "unit: \"{}\"\ndistortionModel: \"{}\"",
        file.unit.symbol(),
        pair.left.distortion().model().name()
    );
    for (k, camera) in [(1, &pair.left), (2, &pair.right)] {
        let m = yaml::row_major(&camera.matrix());
        matrix(&mut out, &format!("M{k}"), 3, 3, &m);
        let d = camera.distortion();
        let d = d.coefficients();
        matrix(&mut out, &format!("D{k}"), 1, d.len(), d);
    }
    matrix(
        &mut out,
        "R",
        3,
        3,
        &yaml::row_major(pair.rotation.matrix()),
    );
    matrix(&mut out, "T", 3, 1, pair.translation.as_slice());
    matrix(&mut out, "E", 3, 3, &yaml::row_major(&file.essential));
    matrix(&mut out, "F", 3, 3, &yaml::row_major(&file.fundamental));
    matrix(&mut out, "R1", 3, 3, &yaml::row_major(&rect.r1));
    matrix(&mut out, "R2", 3, 3, &yaml::row_major(&rect.r2));
    matrix(&mut out, "P1", 3, 4, &yaml::row_major(&rect.p1));
    matrix(&mut out, "P2", 3, 4, &yaml::row_major(&rect.p2));
    matrix(&mut out, "Q", 4, 4, &yaml::row_major(&rect.q));
    if let Some(std) = file.rig_std {
        let _ = writeln!(
            out,
            "rigFocalLengthStd: {}\nrigBaselineStd: {}",
            yaml::write_number(std.focal_px),
            yaml::write_number(std.baseline)
        );
    }
    out
}

/// The `unit` our own `opencv.yml` records.
fn unit(node: &Node) -> Result<LengthUnit, Vec<ParseError>> {
    let text = match node {
        Node::Scalar(text, _) => text.trim_matches(['"', '\'']),
        _ => "",
    };
    LengthUnit::ALL
        .into_iter()
        .find(|u| u.symbol() == text)
        .ok_or_else(|| {
            vec![ParseError::at(
                node.line(),
                "unit must be one of mm, cm, m, in, ft",
            )]
        })
}

/// A matrix member of any shape: its numbers (row-major), line and (rows, cols).
fn any_matrix(doc: &Node, name: &str) -> Result<Option<(Vec<f64>, usize)>, ParseError> {
    let Some(node) = doc.get(name) else {
        return Ok(None);
    };
    let (Some(r), Some(c), Some(data)) = (node.get("rows"), node.get("cols"), node.get("data"))
    else {
        return Err(ParseError::at(
            node.line(),
            format!("{name} must be an opencv-matrix with rows, cols and data"),
        ));
    };
    let (r, c) = (
        r.number(&format!("{name}.rows"))?,
        c.number(&format!("{name}.cols"))?,
    );
    let values = data.numbers(&format!("{name}.data"))?;
    if (values.len() as f64) != r * c {
        return Err(ParseError::at(
            data.line(),
            format!(
                "{name}.data must hold rows × cols = {} numbers, got {}",
                Num(r * c),
                values.len()
            ),
        ));
    }
    Ok(Some((values, data.line())))
}

/// The first of `names` the file has.
fn first<'a>(doc: &Node, names: &[&'a str]) -> Option<&'a str> {
    names.iter().copied().find(|n| doc.get(n).is_some())
}

/// The raw pair's parts, when the file has the cameras.
fn raw_parts(
    doc: &Node,
    image_size: Option<(u32, u32)>,
) -> Result<Option<raw::RawParts>, Vec<ParseError>> {
    let names = [
        first(doc, &["M1", "K1", "cameraMatrix1"]),
        first(doc, &["D1", "distCoeffs1"]),
        first(doc, &["M2", "K2", "cameraMatrix2"]),
        first(doc, &["D2", "distCoeffs2"]),
    ];
    if names.iter().all(Option::is_none) {
        return Ok(None);
    }
    let mut errors = Vec::new();
    let wanted = [
        ("M1", "M1 (or K1)"),
        ("D1", "D1"),
        ("M2", "M2 (or K2)"),
        ("D2", "D2"),
    ];
    for (name, (key, what)) in names.iter().zip(wanted) {
        if name.is_some() {
            continue;
        }
        errors.push(match doc.near_key(key) {
            Some((typed, line)) => ParseError::at(
                line,
                format!("has no {what}, but has `{typed}`: did you mean {key}?"),
            ),
            None => ParseError::whole(format!(
                "the file describes raw cameras but has no {what}: a stereoCalibrate file \
                 needs M1 D1 M2 D2 (send intrinsics.yml and extrinsics.yml together)"
            )),
        });
    }
    let [Some(k1), Some(d1), Some(k2), Some(d2)] = names else {
        return Err(errors);
    };
    let model = match first(doc, &["distortionModel", "distortion_model"]) {
        Some(key) => {
            let node = doc.get(key).expect("found");
            let name = match node {
                Node::Scalar(text, _) => text.trim_matches(['"', '\'']).to_owned(),
                _ => String::new(),
            };
            match Model::from_name(&name) {
                Some(model) => Some(model),
                None => {
                    return Err(vec![ParseError::at(
                        node.line(),
                        format!(
                            "{key} `{}` is not a distortion model this service knows: \
                             plumb_bob, rational_polynomial or equidistant (fisheye)",
                            crate::numbers::clip(&name, 40)
                        ),
                    )]);
                }
            }
        }
        None => None,
    };
    let read = |name: &str| any_matrix(doc, name);
    let (k1v, d1v, k2v, d2v) = (read(k1), read(d1), read(k2), read(d2));
    let (r, t) = (matrix(doc, "R", 3, 3), any_matrix(doc, "T"));
    let given: Vec<_> = ["R1", "R2"]
        .iter()
        .map(|n| matrix(doc, n, 3, 3))
        .chain(["P1", "P2"].iter().map(|n| matrix(doc, n, 3, 4)))
        .collect();
    let size = image_size_of(doc);
    let mut take = |r: Result<Option<(Vec<f64>, usize)>, ParseError>| match r {
        Ok(v) => v,
        Err(e) => {
            errors.push(e);
            None
        }
    };
    let (k1v, d1v, k2v, d2v) = (take(k1v), take(d1v), take(k2v), take(d2v));
    let (r, t) = (take(r), take(t));
    let given: Vec<_> = given.into_iter().map(&mut take).collect();
    let size = match size {
        Ok(size) => size.or(image_size),
        Err(e) => {
            errors.push(e);
            None
        }
    };
    let (Some(k1v), Some(d1v), Some(k2v), Some(d2v)) = (k1v, d1v, k2v, d2v) else {
        return Err(errors);
    };
    let camera =
        |k_name, (k, k_line): &(Vec<f64>, usize), d_name, (d, d_line): &(Vec<f64>, usize)| {
            raw::camera(&raw::CameraText {
                k_name,
                k,
                k_line: *k_line,
                d_name,
                d,
                d_line: *d_line,
                model,
            })
        };
    let left = camera(k1, &k1v, d1, &d1v)
        .map_err(|e| errors.extend(e))
        .ok();
    let right = camera(k2, &k2v, d2, &d2v)
        .map_err(|e| errors.extend(e))
        .ok();
    let extrinsics = match (r, t) {
        (Some((r, line)), Some((t, t_line))) => {
            if t.len() != 3 {
                errors.push(ParseError::at(t_line, "T must hold 3 numbers"));
                None
            } else {
                raw::rotation(&r, "R", line)
                    .map_err(|e| errors.push(e))
                    .ok()
                    .map(|r| (r, Vector3::new(t[0], t[1], t[2])))
            }
        }
        (None, None) => None,
        (r, _) => {
            errors.push(ParseError::whole(format!(
                "the file has {} but not {}: the pose needs both",
                if r.is_some() { "R" } else { "T" },
                if r.is_some() { "T" } else { "R" }
            )));
            None
        }
    };
    let given = match given.as_slice() {
        [Some(r1), Some(r2), Some(p1), Some(p2)] => {
            let r1 = raw::rotation(&r1.0, "R1", r1.1)
                .map_err(|e| errors.push(e))
                .ok();
            let r2 = raw::rotation(&r2.0, "R2", r2.1)
                .map_err(|e| errors.push(e))
                .ok();
            r1.zip(r2).map(|(r1, r2)| raw::Given {
                r: [r1, r2],
                p: [
                    Matrix3x4::from_row_slice(&p1.0),
                    Matrix3x4::from_row_slice(&p2.0),
                ],
                line: p2.1,
            })
        }
        _ => None,
    };
    if !errors.is_empty() {
        return Err(errors);
    }
    let (Some(left), Some(right)) = (left, right) else {
        return Err(errors);
    };
    Ok(Some(raw::RawParts {
        left,
        right,
        extrinsics,
        given,
        size: size.map(|(width, height)| Size { width, height }),
        rectified_size: None,
        line: k1v.1,
    }))
}

/// A `rows × cols` matrix member, row-major, or what is wrong with it.
fn matrix(
    doc: &Node,
    name: &str,
    rows: usize,
    cols: usize,
) -> Result<Option<(Vec<f64>, usize)>, ParseError> {
    let Some(node) = doc.get(name) else {
        return Ok(None);
    };
    let expected = || {
        ParseError::at(
            node.line(),
            format!("{name} must be a {rows}×{cols} opencv-matrix with rows, cols and data"),
        )
    };
    let (Some(r), Some(c), Some(data)) = (node.get("rows"), node.get("cols"), node.get("data"))
    else {
        return Err(expected());
    };
    let (r, c) = (
        r.number(&format!("{name}.rows"))?,
        c.number(&format!("{name}.cols"))?,
    );
    if (r, c) != (rows as f64, cols as f64) {
        return Err(ParseError::at(
            node.line(),
            format!("{name} must be {rows}×{cols}, got {}×{}", Num(r), Num(c)),
        ));
    }
    let values = data.numbers(&format!("{name}.data"))?;
    if values.len() != rows * cols {
        return Err(ParseError::at(
            data.line(),
            format!(
                "{name}.data must hold {} numbers ({rows}×{cols}), got {}",
                rows * cols,
                values.len()
            ),
        ));
    }
    Ok(Some((values, data.line())))
}

/// The image size: `imageSize: [w, h]`, or `image_width` and `image_height`.
fn image_size_of(doc: &Node) -> Result<Option<(u32, u32)>, ParseError> {
    let whole = |node: &Node, what: &str| -> Result<u32, ParseError> {
        let v = node.number(what)?;
        pixels(v).ok_or_else(|| {
            ParseError::at(
                node.line(),
                format!("{what} must be a whole number of pixels, got {}", Num(v)),
            )
        })
    };
    if let Some(node) = doc.get("imageSize") {
        // C++ writes `[640, 480]`; Python's `fs.write("imageSize", np.array([640, 480]))`
        // writes a 2 × 1 `!!opencv-matrix`.
        let values = match node {
            Node::Map(..) => any_matrix(doc, "imageSize")?.map_or_else(Vec::new, |(v, _)| v),
            _ => node.numbers("imageSize")?,
        };
        let size = match values.as_slice() {
            [w, h] => pixels(*w).zip(pixels(*h)),
            _ => None,
        };
        return size.map(Some).ok_or_else(|| {
            ParseError::at(
                node.line(),
                "imageSize must be [width, height] in whole pixels",
            )
        });
    }
    match (doc.get("image_width"), doc.get("image_height")) {
        (Some(w), Some(h)) => Ok(Some((whole(w, "image_width")?, whole(h, "image_height")?))),
        _ => Ok(None),
    }
}

fn rig(doc: &Node) -> Result<Calibration, Vec<ParseError>> {
    let q = matrix(doc, "Q", 4, 4);
    let p1 = matrix(doc, "P1", 3, 4);
    let p2 = matrix(doc, "P2", 3, 4);
    let size = image_size_of(doc);
    let (q, p1, p2, image_size) = match (q, p1, p2, size) {
        (Ok(q), Ok(p1), Ok(p2), Ok(size)) => (q, p1, p2, size),
        (q, p1, p2, size) => {
            return Err([q.err(), p1.err(), p2.err(), size.err()]
                .into_iter()
                .flatten()
                .collect());
        }
    };
    let mut warnings = Vec::new();
    let from_p = match (&p1, &p2) {
        (Some((p1, _)), Some((p2, line))) => {
            if p2[3] == 0.0 && p2[7] != 0.0 {
                return Err(vec![ParseError::at(
                    *line,
                    "P2 is a vertical rig (P2[1,3] ≠ 0, P2[0,3] = 0): this service measures \
                     horizontal disparities",
                )]);
            }
            Some(Calibration::from_projections(
                Format::OpenCv,
                p1,
                p2,
                p1[0],
                image_size,
                Vec::new(),
            ))
        }
        _ => None,
    };
    let calibration = match (q, from_p) {
        (Some((q, line)), from_p) => {
            let (f, q32, q33) = (q[11], q[14], q[15]);
            if q32 == 0.0 {
                return Err(vec![ParseError::at(
                    line,
                    "Q[3,2] = −1/Tx is 0: the baseline would be infinite",
                )]);
            }
            let mut baseline = 1.0 / q32;
            if baseline < 0.0 {
                warnings.push(format!(
                    "Q[3,2] is negative ({}): the baseline is taken as its absolute value; \
                     check that the left camera was passed first to stereoRectify",
                    Num(q32)
                ));
                baseline = -baseline;
            }
            let from_q = Calibration {
                format: Format::OpenCv,
                focal_px: f,
                focal_y_px: from_p.as_ref().map_or(f, |p| p.focal_y_px),
                baseline,
                cx: -q[3],
                cy: -q[7],
                doffs: q33 / q32,
                image_size,
                max_disparity_px: None,
                warnings: Vec::new(),
                raw: None,
                unit: None,
                rig_std: None,
            };
            if let Some(p) = from_p {
                let differs = |a: f64, b: f64| (a - b).abs() > 1e-6 * a.abs().max(b.abs()).max(1.0);
                if differs(p.focal_px, from_q.focal_px)
                    || differs(p.baseline.abs(), from_q.baseline)
                    || differs(p.cx, from_q.cx)
                {
                    warnings.push(format!(
                        "Q and P1/P2 disagree (f {} vs {}, B {} vs {}); Q is used",
                        Num(from_q.focal_px),
                        Num(p.focal_px),
                        Num(from_q.baseline),
                        Num(p.baseline)
                    ));
                }
            }
            (from_q, Some(line))
        }
        (None, Some(p)) => (p, p2.as_ref().map(|(_, line)| *line)),
        (None, None) => {
            return Err(vec![ParseError::whole(
                "no rectified rig: expected Q (4×4), or P1 and P2 (3×4), as stereoRectify \
                 writes them",
            )]);
        }
    };
    let (mut calibration, line) = calibration;
    calibration.warnings = warnings;
    calibration.checked(line)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The file [`write`] writes of the sample pair, a 9 × 6 board of 25 mm, with `rig_std`.
    fn sample_file(rig_std: Option<RigStd>) -> String {
        let (pair, size, rect) = crate::calibration::files::sample_pair();
        write(&StereoFile {
            size,
            pair: &pair,
            essential: Matrix3::identity(),
            fundamental: Matrix3::identity(),
            rectification: &rect,
            target: Some(Target {
                columns: 9,
                rows: 6,
                square_size: 25.0,
                unit: LengthUnit::Millimetre,
            }),
            unit: LengthUnit::Millimetre,
            rig_std,
        })
    }

    /// What [`write`] writes, [`parse`] reads back to the same numbers: the unit, both
    /// cameras, R and T, the raw size and the file's own R1 R2 P1 P2 Q.
    #[test]
    fn a_written_file_reads_back_the_same() {
        let (pair, size, rect) = crate::calibration::files::sample_pair();
        let text = sample_file(Some(RigStd {
            focal_px: 0.25,
            baseline: 0.0125,
        }));
        let read = parse(&text, None, None, None).expect("our own file reads");
        assert_eq!(read.unit, Some(LengthUnit::Millimetre));
        assert_eq!(
            read.rig_std,
            Some(RigStd {
                focal_px: 0.25,
                baseline: 0.0125
            })
        );
        let raw = read.raw.expect("the raw cameras");
        assert_eq!((raw.size, raw.computed), (size, false));
        for (ours, theirs) in [(&raw.pair.left, &pair.left), (&raw.pair.right, &pair.right)] {
            assert_eq!(ours.matrix(), theirs.matrix());
            assert_eq!(ours.distortion(), theirs.distortion());
        }
        assert!((raw.pair.rotation.matrix() - pair.rotation.matrix()).amax() < 1e-15);
        assert_eq!(raw.pair.translation, pair.translation);
        // The reader rebuilds R1 R2 as rotations and Q from P1 P2: equal to the last bits.
        let r = &raw.rectification;
        let close = |a: &[f64], b: &[f64]| {
            a.iter()
                .zip(b)
                .all(|(a, b)| (a - b).abs() <= 1e-12 * b.abs().max(1.0))
        };
        assert!(
            close(r.r1.as_slice(), rect.r1.as_slice())
                && close(r.r2.as_slice(), rect.r2.as_slice())
        );
        assert_eq!((r.p1, r.p2), (rect.p1, rect.p2));
        assert!(
            close(r.q.as_slice(), rect.q.as_slice()),
            "{} vs {}",
            r.q,
            rect.q
        );
        let b = 120.0_f64.hypot(1.8).hypot(2.4);
        assert!(
            (read.baseline - b).abs() < 1e-12 * b,
            "{} vs |T| {b}",
            read.baseline
        );
    }

    /// A key misspelt the usual ways (`M_1`, `m2` for `M1`, `M2`) is named with its line and
    /// the key meant; a member simply missing still says which files to send together.
    #[test]
    fn a_misspelt_key_gets_a_did_you_mean() {
        let text = sample_file(None);
        let typo = text
            .replacen("\nM1:", "\nM_1:", 1)
            .replacen("\nM2:", "\nm2:", 1);
        let errors = parse(&typo, None, None, None).unwrap_err();
        let said: Vec<String> = errors.iter().map(ToString::to_string).collect();
        assert!(
            said.iter()
                .any(|e| e.contains("has `M_1`: did you mean M1?")),
            "{said:?}"
        );
        assert!(
            said.iter()
                .any(|e| e.contains("has `m2`: did you mean M2?")),
            "{said:?}"
        );
        assert!(errors.iter().all(|e| e.line.is_some()), "{said:?}");
        let gone = text.replacen("\nD2:", "\nXX:", 1);
        let said = parse(&gone, None, None, None).unwrap_err()[0].to_string();
        assert!(
            said.contains("has no D2")
                && said.contains("send intrinsics.yml and extrinsics.yml together"),
            "{said}"
        );
    }

    const Q: &str = "<Q type_id=\"opencv-matrix\"><rows>4</rows><cols>4</cols><dt>d</dt>\n\
                     <data>1. 0. 0. -640. 0. 1. 0. -360. 0. 0. 0. 900. 0. 0. 0.02 0.</data></Q>";

    /// A FileStorage XML file reads as its YAML does: f, cx, cy and B from Q.
    #[test]
    fn xml_reads_q() {
        let text = format!(
            "<?xml version=\"1.0\"?>\n<opencv_storage>\n<!-- a comment -->\n{Q}\n</opencv_storage>\n"
        );
        let c = parse(&text, None, None, None).unwrap();
        assert_eq!((c.focal_px, c.cx, c.cy), (900.0, 640.0, 360.0));
        assert!((c.baseline - 50.0).abs() < 1e-9);
    }

    /// Broken XML names its line; a DTD (entity expansion) is refused; another root is said.
    #[test]
    fn bad_xml_is_named() {
        let broken =
            format!("<?xml version=\"1.0\"?>\n<opencv_storage>\n{Q}\n<P1>\n</opencv_storage>\n");
        let e = &parse(&broken, None, None, None).unwrap_err()[0];
        assert_eq!(e.line, Some(6), "{e}");
        let dtd = "<?xml version=\"1.0\"?>\n<!DOCTYPE x [<!ENTITY a \"aaaa\">]>\n<opencv_storage>&a;</opencv_storage>";
        assert!(parse(dtd, None, None, None).is_err());
        let other = "<?xml version=\"1.0\"?>\n<storage></storage>";
        assert!(
            parse(other, None, None, None).unwrap_err()[0]
                .message
                .contains("<opencv_storage>")
        );
    }
}
