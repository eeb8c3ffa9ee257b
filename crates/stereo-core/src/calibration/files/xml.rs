//! OpenCV FileStorage XML read into the same [`Node`]s as its YAML, so that one reader of
//! `stereoRectify` and `stereoCalibrate` files serves both.

use super::ParseError;
use super::yaml::Node;

/// Reads FileStorage XML (with roxmltree, which refuses DTDs and so entity expansion) into
/// the same nodes as its YAML: each element of `<opencv_storage>` a member, a matrix a map of
/// `rows`, `cols`, `dt` and `data`, text of several numbers a list.
pub fn parse(text: &str) -> Result<Node, ParseError> {
    let doc = roxmltree::Document::parse(text)
        .map_err(|e| ParseError::at(e.pos().row as usize, format!("not well-formed XML: {e}")))?;
    let root = doc.root_element();
    if root.tag_name().name() != "opencv_storage" {
        return Err(ParseError::whole(
            "an OpenCV XML file must have <opencv_storage> as its root element",
        ));
    }
    let line = |node: roxmltree::Node| doc.text_pos_at(node.range().start).row as usize;
    let leaf = |node: roxmltree::Node| {
        let text: Vec<&str> = node
            .descendants()
            .filter(roxmltree::Node::is_text)
            .filter_map(|t| t.text())
            .collect();
        value(&text.join(" "), line(node))
    };
    let members = root
        .children()
        .filter(roxmltree::Node::is_element)
        .map(|member| {
            let children: Vec<_> = member
                .children()
                .filter(roxmltree::Node::is_element)
                .collect();
            let node = if children.is_empty() {
                leaf(member)
            } else {
                Node::Map(
                    children
                        .into_iter()
                        .map(|c| (c.tag_name().name().to_owned(), leaf(c)))
                        .collect(),
                    line(member),
                )
            };
            (member.tag_name().name().to_owned(), node)
        })
        .collect();
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
