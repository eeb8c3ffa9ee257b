//! KITTI calibration files: the raw data's `calib_cam_to_cam.txt` (`P_rect_0i`, `S_rect_0i`)
//! and the odometry and object benchmarks' `calib.txt` (`P0`..`P3`), `key: numbers` lines.
//!
//! Every `P` is a rectified 3×4 projection `[f 0 cx tx·f; 0 f cy ty·f; 0 0 1 tz]` in metres
//! relative to the reference camera 0, so the baseline of a pair is the difference of the two
//! `P[0,3]` divided by f: for the colour pair `(P_rect_02[0,3] − P_rect_03[0,3]) / f`, not
//! `−P_rect_03[0,3] / f`, because camera 2 is itself 6 cm from camera 0.

use super::{Calibration, Format, KittiPair, ParseError, pixels, yaml::number};
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
        // Only the projections and sizes are read; `calib_time: 09-Jan-2012 13:57:47` and
        // other keys are not numbers and need not be.
        if !(key.starts_with('P') || key.starts_with("S_rect")) {
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

pub fn parse(text: &str, pair: Option<KittiPair>) -> Result<Calibration, Vec<ParseError>> {
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
    Calibration::from_projections(Format::Kitti, pl, pr, f, image_size, warnings)
        .checked(Some(right.line))
}
