//! KITTI calibration files: the raw data's `calib_cam_to_cam.txt` (`P_rect_0i`, `S_rect_0i`)
//! and the odometry and object benchmarks' `calib.txt` (`P0`..`P3`), `key: numbers` lines.
//!
//! Every `P` is a rectified 3×4 projection `[f 0 cx tx·f; 0 f cy ty·f; 0 0 1 tz]` in metres
//! relative to the reference camera 0, so the baseline of a pair is the difference of the two
//! `P[0,3]` divided by f: for the colour pair `(P_rect_02[0,3] − P_rect_03[0,3]) / f`, not
//! `−P_rect_03[0,3] / f`, because camera 2 is itself 6 cm from camera 0.

use crate::camera::Alpha;
use nalgebra::{Matrix3, Matrix3x4, Vector3};

use super::{Calibration, Format, KittiPair, ParseError, pixels, raw, yaml::number};
use crate::camera::Size;
use crate::numbers::Num;

/// The numbers of a `key: numbers` line, with its line number.
struct Entry {
    values: Vec<f64>,
    line: usize,
}

fn entries(text: &str) -> Result<Vec<(String, Entry)>, Vec<ParseError>> {
    let mut out = Vec::new();
    let mut errors = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = raw.trim();
        if content.is_empty() || content.starts_with('#') {
            continue;
        }
        let Some((key, rest)) = content.split_once(':') else {
            errors.push(ParseError::at(
                line,
                format!("expected `key: numbers`, got `{content}`"),
            ));
            continue;
        };
        let key = key.trim();
        // Only the cameras, projections and sizes are read; `calib_time: 09-Jan-2012
        // 13:57:47` and other keys are not numbers and need not be.
        if !(key.starts_with('P')
            || ["S_", "K_", "D_", "R_", "T_"]
                .iter()
                .any(|p| key.starts_with(p)))
        {
            continue;
        }
        match rest
            .split_whitespace()
            .map(number)
            .collect::<Option<Vec<f64>>>()
        {
            Some(values) => out.push((key.to_owned(), Entry { values, line })),
            None => errors.push(ParseError::at(
                line,
                format!("{key} must be a list of numbers, got `{}`", rest.trim()),
            )),
        }
    }
    if errors.is_empty() {
        Ok(out)
    } else {
        Err(errors)
    }
}

/// The projection of camera `i`: `P_rect_0i` (raw data) or `Pi` (odometry, object).
fn projection(entries: &[(String, Entry)], i: u8) -> Option<(&str, &Entry)> {
    [format!("P_rect_0{i}"), format!("P{i}")]
        .into_iter()
        .find_map(|key| entries.iter().find(|(k, _)| *k == key))
        .map(|(k, e)| (k.as_str(), e))
}

pub fn parse(
    text: &str,
    pair: Option<KittiPair>,
    alpha: Option<Alpha>,
) -> Result<Calibration, Vec<ParseError>> {
    let entries = entries(text)?;
    let mut warnings = Vec::new();
    let has = |p: KittiPair| {
        let (l, r) = p.cameras();
        projection(&entries, l).is_some() && projection(&entries, r).is_some()
    };
    let pair = match pair {
        Some(pair) => pair,
        None if !has(KittiPair::Colour) && has(KittiPair::Grey) => {
            warnings.push(
                "the file has no colour pair (cameras 2 and 3), so the grey pair (cameras 0 \
                 and 1) is used"
                    .to_owned(),
            );
            KittiPair::Grey
        }
        None => KittiPair::Colour,
    };
    let (l, r) = pair.cameras();
    let (Some((left_key, left)), Some((right_key, right))) =
        (projection(&entries, l), projection(&entries, r))
    else {
        let other = match pair {
            KittiPair::Colour if has(KittiPair::Grey) => " (it has the grey pair: cameras \"0-1\")",
            KittiPair::Grey if has(KittiPair::Colour) => {
                " (it has the colour pair: cameras \"2-3\")"
            }
            _ => "",
        };
        return Err(vec![ParseError::whole(format!(
            "no projection for cameras {l} and {r}: expected lines P_rect_0{l}: and \
             P_rect_0{r}: (raw data) or P{l}: and P{r}: (odometry){other}"
        ))]);
    };
    let mut errors = Vec::new();
    for (key, entry) in [(left_key, left), (right_key, right)] {
        if entry.values.len() != 12 {
            errors.push(ParseError::at(
                entry.line,
                format!(
                    "{key} must be a 3×4 projection matrix of 12 numbers, got {}",
                    entry.values.len()
                ),
            ));
        }
    }
    if !errors.is_empty() {
        return Err(errors);
    }
    let (pl, pr) = (&left.values, &right.values);
    let f = pl[0];
    if (pr[0] - f).abs() > 1e-9 * f.abs() {
        warnings.push(format!(
            "{left_key} and {right_key} have different focal lengths ({} and {} px): a \
             rectified pair shares one; {left_key}'s is used",
            Num(f),
            Num(pr[0])
        ));
    }
    let size_key = format!("S_rect_0{l}");
    let image_size = match entries.iter().find(|(k, _)| *k == size_key) {
        Some((_, entry)) => match entry.values.as_slice() {
            [w, h] => match (pixels(*w), pixels(*h)) {
                (Some(w), Some(h)) => Some((w, h)),
                _ => {
                    return Err(vec![ParseError::at(
                        entry.line,
                        format!("{size_key} must be a width and a height in whole pixels"),
                    )]);
                }
            },
            _ => {
                return Err(vec![ParseError::at(
                    entry.line,
                    format!("{size_key} must be two numbers, the width and the height"),
                )]);
            }
        },
        None => None,
    };
    let raw = raw_pair(&entries, (l, r), [pl, pr], right.line, image_size, alpha)?;
    let calibration = match raw {
        Some(raw) if raw.computed => raw::calibration(Format::Kitti, raw, warnings),
        raw => {
            let mut c =
                Calibration::from_projections(Format::Kitti, pl, pr, f, image_size, warnings);
            c.raw = raw.map(Box::new);
            c
        }
    };
    calibration.checked(Some(right.line))
}

/// A camera's pose from camera 0: X_i = R·X_0 + T.
type Pose = (Matrix3<f64>, Vector3<f64>);

/// The raw pair of `calib_cam_to_cam.txt`, when it gives both cameras' `K_0i`, `D_0i` and
/// `R_rect_0i`: raw size `S_0i`, rectified size `S_rect_0i`, the pose from `R_0i` and `T_0i`
/// (each camera's from camera 0), the rectification `R_rect_0i` and `P_rect_0i`.
fn raw_pair(
    entries: &[(String, Entry)],
    (l, r): (u8, u8),
    [pl, pr]: [&[f64]; 2],
    p_line: usize,
    rectified: Option<(u32, u32)>,
    alpha: Option<Alpha>,
) -> Result<Option<raw::Raw>, Vec<ParseError>> {
    let get = |key: String| {
        entries
            .iter()
            .find(|(k, _)| *k == key)
            .map(|(k, e)| (k.clone(), e))
    };
    let camera_keys = |i: u8| {
        (
            get(format!("K_0{i}")),
            get(format!("D_0{i}")),
            get(format!("R_rect_0{i}")),
        )
    };
    let ((Some(kl), Some(dl), Some(rl)), (Some(kr), Some(dr), Some(rr))) =
        (camera_keys(l), camera_keys(r))
    else {
        return Ok(None);
    };
    let mut errors = Vec::new();
    let camera = |(k_name, k): &(String, &Entry), (d_name, d): &(String, &Entry)| {
        raw::camera(&raw::CameraText {
            k_name,
            k: &k.values,
            k_line: k.line,
            d_name,
            d: &d.values,
            d_line: d.line,
            model: None,
        })
    };
    let left = camera(&kl, &dl).map_err(|e| errors.extend(e)).ok();
    let right = camera(&kr, &dr).map_err(|e| errors.extend(e)).ok();
    let rect_l = raw::rotation(&rl.1.values, &rl.0, rl.1.line)
        .map_err(|e| errors.push(e))
        .ok();
    let rect_r = raw::rotation(&rr.1.values, &rr.0, rr.1.line)
        .map_err(|e| errors.push(e))
        .ok();
    let pose = |i: u8| -> Option<Result<Pose, ParseError>> {
        let (rk, r) = get(format!("R_0{i}"))?;
        let (tk, t) = get(format!("T_0{i}"))?;
        Some(
            raw::rotation(&r.values, &rk, r.line).and_then(|m| match t.values.as_slice() {
                [x, y, z] => Ok((m, Vector3::new(*x, *y, *z))),
                _ => Err(ParseError::at(t.line, format!("{tk} must hold 3 numbers"))),
            }),
        )
    };
    let extrinsics = match (pose(l), pose(r)) {
        (Some(Ok((rl, tl))), Some(Ok((rr, tr)))) => {
            let rotation = rr * rl.transpose();
            Some((rotation, tr - rotation * tl))
        }
        (a, b) => {
            errors.extend(a.and_then(Result::err));
            errors.extend(b.and_then(Result::err));
            None
        }
    };
    let size_key = format!("S_0{l}");
    let size = match get(size_key.clone()) {
        Some((_, entry)) => match entry.values.as_slice() {
            [w, h] => pixels(*w).zip(pixels(*h)),
            _ => None,
        }
        .map(Some)
        .ok_or_else(|| {
            vec![ParseError::at(
                entry.line,
                format!("{size_key} must be a width and a height in whole pixels"),
            )]
        })?,
        None => None,
    };
    if !errors.is_empty() {
        return Err(errors);
    }
    if size.is_none() {
        // Without the raw size the raw images cannot be rectified; the rectified rig stands.
        return Ok(None);
    }
    let (Some(left), Some(right), Some(rect_l), Some(rect_r)) = (left, right, rect_l, rect_r)
    else {
        return Err(errors);
    };
    let parts = raw::RawParts {
        left,
        right,
        extrinsics,
        given: Some(raw::Given {
            r: [rect_l, rect_r],
            p: [Matrix3x4::from_row_slice(pl), Matrix3x4::from_row_slice(pr)],
            line: p_line,
        }),
        size: size.map(|(width, height)| Size { width, height }),
        rectified_size: rectified.map(|(width, height)| Size { width, height }),
        line: kl.1.line,
    };
    raw::pair(parts, alpha).map(Some).map_err(|e| vec![e])
}
