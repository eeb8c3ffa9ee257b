//! Middlebury 2014 `calib.txt`: `key=value` lines, the cameras as `[f 0 cx; 0 f cy; 0 0 1]`,
//! `doffs` and `baseline` in millimetres, `width`, `height` and `ndisp`; other keys (`isint`,
//! `vmin`, `vmax`, `dyavg`, `dymax`) are read and ignored.

use super::{Calibration, Format, ParseError, pixels, yaml::number};
use crate::numbers::Num;

/// A 3×3 matrix written `[a b c; d e f; g h i]`.
fn matrix(key: &str, value: &str, line: usize) -> Result<[[f64; 3]; 3], ParseError> {
    let expected = || {
        ParseError::at(
            line,
            format!("{key} must be a 3×3 matrix [a b c; d e f; g h i], got `{value}`"),
        )
    };
    let inner = value
        .trim()
        .strip_prefix('[')
        .and_then(|v| v.strip_suffix(']'))
        .ok_or_else(expected)?;
    let rows: Vec<Vec<f64>> = inner
        .split(';')
        .map(|row| {
            row.split_whitespace()
                .map(number)
                .collect::<Option<Vec<_>>>()
        })
        .collect::<Option<_>>()
        .ok_or_else(expected)?;
    if rows.len() != 3 || rows.iter().any(|r| r.len() != 3) {
        return Err(expected());
    }
    Ok([
        [rows[0][0], rows[0][1], rows[0][2]],
        [rows[1][0], rows[1][1], rows[1][2]],
        [rows[2][0], rows[2][1], rows[2][2]],
    ])
}

/// A whole number of pixels (`2964`, also `2964.0`).
fn whole(key: &str, value: &str, line: usize) -> Result<u32, ParseError> {
    number(value).and_then(pixels).ok_or_else(|| {
        ParseError::at(
            line,
            format!("{key} must be a whole number of pixels, got `{value}`"),
        )
    })
}

/// A number.
fn scalar(key: &str, value: &str, line: usize) -> Result<f64, ParseError> {
    number(value)
        .ok_or_else(|| ParseError::at(line, format!("{key} must be a number, got `{value}`")))
}

pub fn parse(text: &str) -> Result<Calibration, Vec<ParseError>> {
    let mut errors = Vec::new();
    // The keys present, refused or not: a refused key is not also reported missing.
    let mut seen: Vec<&str> = Vec::new();
    let mut cams: [Option<([[f64; 3]; 3], usize)>; 2] = [None, None];
    let (mut doffs, mut baseline, mut width, mut height, mut ndisp) =
        (None, None, None, None, None);
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = raw.trim();
        if content.is_empty() || content.starts_with('#') {
            continue;
        }
        let Some((key, value)) = content.split_once('=') else {
            errors.push(ParseError::at(
                line,
                format!("expected key=value, got `{content}`"),
            ));
            continue;
        };
        let (key, value) = (key.trim(), value.trim());
        seen.push(key);
        let read = match key {
            "cam0" | "cam1" => {
                matrix(key, value, line).map(|m| cams[usize::from(key == "cam1")] = Some((m, line)))
            }
            "doffs" => scalar(key, value, line).map(|v| doffs = Some(v)),
            "baseline" => scalar(key, value, line).map(|v| baseline = Some((v, line))),
            "width" => whole(key, value, line).map(|v| width = Some(v)),
            "height" => whole(key, value, line).map(|v| height = Some(v)),
            "ndisp" => whole(key, value, line).map(|v| ndisp = Some(v)),
            _ => Ok(()),
        };
        if let Err(error) = read {
            errors.push(error);
        }
    }
    for (key, missing) in [
        ("cam0", "cam0=[f 0 cx; 0 f cy; 0 0 1] is missing"),
        ("cam1", "cam1=[f 0 cx; 0 f cy; 0 0 1] is missing"),
        ("baseline", "baseline=... (in mm) is missing"),
    ] {
        if !seen.contains(&key) {
            errors.push(ParseError::whole(missing));
        }
    }
    let ([Some((cam0, line0)), Some((cam1, _))], Some((baseline, baseline_line))) =
        (cams, baseline)
    else {
        return Err(errors);
    };
    if !errors.is_empty() {
        return Err(errors);
    }
    let mut warnings = Vec::new();
    let derived = cam1[0][2] - cam0[0][2];
    let doffs = match doffs {
        Some(doffs) => {
            if (doffs - derived).abs() > 1e-3 * doffs.abs().max(1.0) {
                warnings.push(format!(
                    "doffs = {} but cam1's cx − cam0's cx = {}; doffs is used",
                    Num(doffs),
                    Num(derived)
                ));
            }
            doffs
        }
        None => {
            warnings.push(format!(
                "no doffs line: doffs = cam1's cx − cam0's cx = {} px is used",
                Num(derived)
            ));
            derived
        }
    };
    if (cam1[0][0] - cam0[0][0]).abs() > 1e-9 * cam0[0][0].abs() {
        warnings.push(format!(
            "cam0 and cam1 have different focal lengths ({} and {} px): a rectified pair \
             shares one; cam0's is used",
            Num(cam0[0][0]),
            Num(cam1[0][0])
        ));
    }
    let image_size = match (width, height) {
        (Some(w), Some(h)) => Some((w, h)),
        (None, None) => None,
        _ => {
            warnings
                .push("only one of width and height is given; the image size is left out".into());
            None
        }
    };
    let calibration = Calibration {
        format: Format::Middlebury,
        focal_px: cam0[0][0],
        focal_y_px: cam0[1][1],
        baseline,
        cx: cam0[0][2],
        cy: cam0[1][2],
        doffs,
        image_size,
        max_disparity_px: ndisp,
        warnings,
        raw: None,
        unit: None,
        rig_std: None,
    };
    let line = if baseline > 0.0 { line0 } else { baseline_line };
    calibration.checked(Some(line))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The matrix error says what was expected, on the line it was found.
    #[test]
    fn bad_matrix_names_the_line() {
        let errors =
            parse("cam0=[1 0 2; 0 1 3; 0 0 1]\r\ndoffs=0\r\ncam1=[1 0 2; 0 1 3]\r\n").unwrap_err();
        assert_eq!(errors[0].line, Some(3));
        assert!(
            errors[0]
                .message
                .starts_with("cam1 must be a 3×3 matrix [a b c; d e f; g h i]")
        );
        let errors = parse("cam0=[1 0 2; 0 1 3; 0 0 1]\ncam1=[1 0 2; 0 1 3; 0 0 1]\n").unwrap_err();
        assert!(errors[0].message.contains("baseline"));
    }
}
