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

use super::yaml::{self, Node};
use super::{Calibration, Format, ParseError, pixels};
use crate::numbers::Num;

pub fn parse(text: &str) -> Result<Calibration, Vec<ParseError>> {
    let doc = if text.trim_start().starts_with('<') {
        xml(text)
    } else {
        yaml::parse(text)
    }
    .map_err(|e| vec![e])?;
    rig(&doc)
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
fn image_size(doc: &Node) -> Result<Option<(u32, u32)>, ParseError> {
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
        let values = node.numbers("imageSize")?;
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
    let size = image_size(doc);
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

/// Reads FileStorage XML into the same nodes as its YAML: each top-level element a member, a
/// matrix a map of `rows`, `cols`, `dt` and `data`, text of several numbers a list.
fn xml(text: &str) -> Result<Node, ParseError> {
    let line_of = |offset: usize| text[..offset].matches('\n').count() + 1;
    let start = text
        .find("<opencv_storage>")
        .ok_or_else(|| ParseError::whole("an OpenCV XML file must have <opencv_storage>"))?
        + "<opencv_storage>".len();
    let end = text[start..]
        .find("</opencv_storage>")
        .map(|e| start + e)
        .ok_or_else(|| ParseError::whole("<opencv_storage> is not closed"))?;
    let members = elements(text, start, end, &line_of)?
        .into_iter()
        .map(|(name, inner, at)| {
            let line = line_of(at);
            let node = if inner.contains('<') {
                let children = elements(text, at, at + inner.len(), &line_of)?
                    .into_iter()
                    .map(|(n, t, a)| (n, value(t, line_of(a))))
                    .collect();
                Node::Map(children, line)
            } else {
                value(inner, line)
            };
            Ok((name, node))
        })
        .collect::<Result<_, ParseError>>()?;
    Ok(Node::Map(members, 1))
}

/// Text as a scalar, or a list when it holds several words.
fn value(text: &str, line: usize) -> Node {
    let words: Vec<&str> = text.split_whitespace().collect();
    match words.as_slice() {
        [one] => Node::Scalar((*one).to_owned(), line),
        _ => Node::Seq(
            words
                .into_iter()
                .map(|w| Node::Scalar(w.to_owned(), line))
                .collect(),
            line,
        ),
    }
}

/// The elements directly inside `text[start..end]`: `(name, inner text, inner offset)`.
fn elements<'a>(
    text: &'a str,
    start: usize,
    end: usize,
    line_of: &dyn Fn(usize) -> usize,
) -> Result<Vec<(String, &'a str, usize)>, ParseError> {
    let mut out = Vec::new();
    let mut at = start;
    while let Some(open) = text[at..end].find('<').map(|o| at + o) {
        let rest = &text[open..end];
        if rest.starts_with("<!--") {
            at = rest
                .find("-->")
                .map(|c| open + c + 3)
                .ok_or_else(|| ParseError::at(line_of(open), "a comment <!-- is not closed"))?;
            continue;
        }
        let close_angle = rest
            .find('>')
            .ok_or_else(|| ParseError::at(line_of(open), "a tag is not closed with >"))?;
        let tag = &rest[1..close_angle];
        let name = tag.split_whitespace().next().unwrap_or_default();
        if name.is_empty() || name.starts_with('/') {
            return Err(ParseError::at(line_of(open), format!("unexpected <{tag}>")));
        }
        let inner_start = open + close_angle + 1;
        if tag.ends_with('/') {
            out.push((name.trim_end_matches('/').to_owned(), "", inner_start));
            at = inner_start;
            continue;
        }
        let closing = format!("</{name}>");
        let inner_end = text[inner_start..end]
            .find(&closing)
            .map(|e| inner_start + e)
            .ok_or_else(|| ParseError::at(line_of(open), format!("<{name}> is not closed")))?;
        out.push((name.to_owned(), &text[inner_start..inner_end], inner_start));
        at = inner_end + closing.len();
    }
    Ok(out)
}
