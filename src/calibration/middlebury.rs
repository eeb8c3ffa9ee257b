//! Middlebury 2014 `calib.txt`: `key=value` lines, the cameras as `[f 0 cx; 0 f cy; 0 0 1]`,
//! `doffs` and `baseline` in millimetres, `width`, `height` and `ndisp`; other keys (`isint`,
//! `vmin`, `vmax`, `dyavg`, `dymax`) are read and ignored.

use super::{Calibration, Format, ParseError, yaml::number};

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
    number(value)
        .filter(|v| v.fract() == 0.0 && *v >= 1.0 && *v <= f64::from(u32::MAX))
        .map(|v| v as u32)
        .ok_or_else(|| {
            ParseError::at(
                line,
                format!("{key} must be a whole number of pixels, got `{value}`"),
            )
        })
}

pub fn parse(text: &str) -> Result<Calibration, Vec<ParseError>> {
    let mut errors = Vec::new();
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
        let scalar = |errors: &mut Vec<ParseError>| {
            let parsed = number(value);
            if parsed.is_none() {
                errors.push(ParseError::at(
                    line,
                    format!("{key} must be a number, got `{value}`"),
                ));
            }
            parsed.map(|v| (v, line))
        };
        let mut record = |r: Result<u32, ParseError>| match r {
            Ok(v) => Some((v, line)),
            Err(e) => {
                errors.push(e);
                None
            }
        };
        match key {
            "cam0" | "cam1" => {
                let slot = usize::from(key == "cam1");
                match matrix(key, value, line) {
                    Ok(m) => cams[slot] = Some((m, line)),
                    Err(e) => errors.push(e),
                }
            }
            "doffs" => doffs = scalar(&mut errors),
            "baseline" => baseline = scalar(&mut errors),
            "width" => width = record(whole(key, value, line)),
            "height" => height = record(whole(key, value, line)),
            "ndisp" => ndisp = record(whole(key, value, line)),
            _ => {}
        }
    }
    for (slot, name) in [(0, "cam0"), (1, "cam1")] {
        if cams[slot].is_none() && !errors.iter().any(|e| e.message.starts_with(name)) {
            errors.push(ParseError::whole(format!(
                "{name}=[f 0 cx; 0 f cy; 0 0 1] is missing"
            )));
        }
    }
    if baseline.is_none() && !errors.iter().any(|e| e.message.starts_with("baseline")) {
        errors.push(ParseError::whole("baseline=... (in mm) is missing"));
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
        Some((doffs, _)) => {
            if (doffs - derived).abs() > 1e-3 * doffs.abs().max(1.0) {
                warnings.push(format!(
                    "doffs = {doffs} but cam1's cx − cam0's cx = {derived}; doffs is used"
                ));
            }
            doffs
        }
        None => {
            warnings.push(format!(
                "no doffs line: doffs = cam1's cx − cam0's cx = {derived} px is used"
            ));
            derived
        }
    };
    if (cam1[0][0] - cam0[0][0]).abs() > 1e-9 * cam0[0][0].abs() {
        warnings.push(format!(
            "cam0 and cam1 have different focal lengths ({} and {} px): a rectified pair \
             shares one; cam0's is used",
            cam0[0][0], cam1[0][0]
        ));
    }
    let image_size = match (width, height) {
        (Some((w, _)), Some((h, _))) => Some((w, h)),
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
        max_disparity_px: ndisp.map(|(n, _)| n),
        warnings,
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
