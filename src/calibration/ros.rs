//! ROS `CameraInfo`, one file per camera: the `camera_calibration` YAML of ROS 1
//! (`image_width`, `camera_matrix`, `projection_matrix` with `rows`, `cols`, `data`), a ROS 2
//! `ros2 topic echo` message (`width`, `height`, flat `k` and `p`) or a ROS 1 `rostopic echo`
//! (`K`, `P`). The right camera's projection carries the baseline: `P_r[3] = −f·B`.

use super::yaml::{self, Node};
use super::{Calibration, Format, ParseError, pixels};
use crate::numbers::Num;

/// What one camera's file gives.
struct Camera {
    /// The 3×4 projection, row-major.
    p: Vec<f64>,
    p_line: usize,
    size: Option<(u32, u32)>,
}

fn camera(text: &str) -> Result<Camera, ParseError> {
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
    Ok(Camera {
        p,
        p_line: data.line(),
        size: width.zip(height),
    })
}

pub fn parse(text: &str, right_text: Option<&str>) -> Result<Calibration, Vec<ParseError>> {
    let left = camera(text);
    let Some(right_text) = right_text else {
        let mut errors = vec![
            ParseError::whole(
                "a ROS rig needs both cameras' CameraInfo: the left camera's in text and the \
             right camera's in right_text (its projection matrix holds the baseline)",
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
    let calibration = Calibration::from_projections(Format::Ros, pl, pr, f, size, warnings);
    if calibration.baseline < 0.0 {
        return Err(vec![
            ParseError::at(
                left.p_line,
                format!(
                    "the baseline from these files is negative ({} m): text must be the left \
                     camera's CameraInfo and right_text the right camera's; they look swapped",
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
    calibration
        .checked(Some(right.p_line))
        .map_err(|errors| errors.into_iter().map(ParseError::in_right).collect())
}
