//! The subset of YAML that calibration files use, read with line numbers for the errors: block
//! maps and sequences by indentation, flow sequences `[a, b, c]` over several lines, plain and
//! quoted scalars, comments, and what OpenCV's FileStorage writes that standard YAML refuses
//! (the `%YAML:1.0` directive, `!!opencv-matrix` tags). Anchors, flow maps and multi-line
//! strings are not needed by any calibration format and are read as opaque scalars.

use super::ParseError;

/// Nesting deeper than this is refused, so that a hostile file cannot exhaust the stack.
const MAX_DEPTH: usize = 32;

/// A YAML value with the (1-based) line it starts on.
#[derive(Debug, Clone, PartialEq)]
pub enum Node {
    Scalar(String, usize),
    Seq(Vec<Node>, usize),
    Map(Vec<(String, Node)>, usize),
}

impl Node {
    /// The line the value starts on.
    pub fn line(&self) -> usize {
        match self {
            Node::Scalar(_, line) | Node::Seq(_, line) | Node::Map(_, line) => *line,
        }
    }

    /// The member `key` of a map.
    /// A key of this map that looks like a misspelt `key` (`M_1`, `m1`, `M-1` for `M1`: the
    /// same once case, `_`, `-` and spaces are set aside), clipped, with its line. Nearer
    /// misses by a character are left alone: `D2` is one off `D1` and is no typo.
    pub fn near_key(&self, key: &str) -> Option<(String, usize)> {
        let Node::Map(members, _) = self else {
            return None;
        };
        let plain = |s: &str| {
            s.chars()
                .filter(|c| !matches!(c, '_' | '-' | ' '))
                .collect::<String>()
                .to_ascii_lowercase()
        };
        let wanted = plain(key);
        members
            .iter()
            .filter(|(k, _)| k != key)
            .find(|(k, _)| plain(k) == wanted)
            .map(|(k, node)| (crate::numbers::clip(k, 40), node.line()))
    }

    pub fn get(&self, key: &str) -> Option<&Node> {
        match self {
            Node::Map(members, _) => members.iter().find(|(k, _)| k == key).map(|(_, v)| v),
            _ => None,
        }
    }

    /// The numbers of a sequence (or one scalar), each finite, or what is wrong, naming `what`.
    pub fn numbers(&self, what: &str) -> Result<Vec<f64>, ParseError> {
        let scalars: Vec<&Node> = match self {
            Node::Seq(items, _) => items.iter().collect(),
            other => vec![other],
        };
        scalars
            .into_iter()
            .map(|node| match node {
                Node::Scalar(text, line) => number(text).ok_or_else(|| {
                    ParseError::at(*line, format!("{what} must hold numbers, got `{text}`"))
                }),
                other => Err(ParseError::at(
                    other.line(),
                    format!("{what} must hold numbers, got a nested list or map"),
                )),
            })
            .collect()
    }

    /// A single number, naming `what` when it is not one.
    pub fn number(&self, what: &str) -> Result<f64, ParseError> {
        match self {
            Node::Scalar(text, line) => number(text).ok_or_else(|| {
                ParseError::at(*line, format!("{what} must be a number, got `{text}`"))
            }),
            other => Err(ParseError::at(
                other.line(),
                format!("{what} must be a number"),
            )),
        }
    }
}

/// A finite number as YAML and OpenCV write them (`1.`, `-3.5e+01`, `.5`).
pub fn number(text: &str) -> Option<f64> {
    let text = text.trim();
    let value: f64 = text.parse().ok()?;
    value.is_finite().then_some(value)
}

/// One meaningful line: its number, indentation and content (comments stripped).
#[derive(Debug)]
struct Line<'a> {
    number: usize,
    indent: usize,
    text: &'a str,
}

/// Reads a document into its top-level node (a map for every calibration format).
pub fn parse(source: &str) -> Result<Node, ParseError> {
    let lines: Vec<Line> = source
        .lines()
        .enumerate()
        .filter_map(|(i, raw)| {
            let raw = raw.trim_end_matches('\r');
            let text = strip_comment(raw).trim_end();
            let content = text.trim_start();
            let skip = content.is_empty()
                || content.starts_with('%')
                || content == "---"
                || content == "...";
            (!skip).then(|| Line {
                number: i + 1,
                indent: text.len() - content.len(),
                text: content,
            })
        })
        .collect();
    if let Some(tab) = source.lines().position(|l| l.starts_with('\t')) {
        return Err(ParseError::at(
            tab + 1,
            "YAML indentation must use spaces, not tabs",
        ));
    }
    let mut reader = Reader { lines, at: 0 };
    let Some(first) = reader.lines.first() else {
        return Err(ParseError::whole("the file is empty"));
    };
    let indent = first.indent;
    let node = reader.block(indent, 0)?;
    if let Some(rest) = reader.lines.get(reader.at) {
        return Err(ParseError::at(
            rest.number,
            format!("unexpected `{}`: the indentation does not match", rest.text),
        ));
    }
    Ok(node)
}

/// The line without a `#` comment (one at the start or after a space, outside quotes).
fn strip_comment(line: &str) -> &str {
    let mut quote = None;
    let mut previous = ' ';
    for (i, c) in line.char_indices() {
        match (quote, c) {
            (None, '"' | '\'') => quote = Some(c),
            (Some(q), c) if c == q => quote = None,
            (None, '#') if previous.is_whitespace() => return &line[..i],
            _ => {}
        }
        previous = c;
    }
    line
}

struct Reader<'a> {
    lines: Vec<Line<'a>>,
    at: usize,
}

impl Reader<'_> {
    /// The block starting at the current line, whose lines are indented by `indent`.
    fn block(&mut self, indent: usize, depth: usize) -> Result<Node, ParseError> {
        let line = &self.lines[self.at];
        if depth > MAX_DEPTH {
            return Err(ParseError::at(line.number, "the file is nested too deeply"));
        }
        if line.text == "-" || line.text.starts_with("- ") {
            self.sequence(indent, depth)
        } else {
            self.map(indent, depth)
        }
    }

    fn sequence(&mut self, indent: usize, depth: usize) -> Result<Node, ParseError> {
        let start = self.lines[self.at].number;
        let mut items = Vec::new();
        while let Some(line) = self.lines.get(self.at) {
            if line.indent != indent || !(line.text == "-" || line.text.starts_with("- ")) {
                break;
            }
            let (number, rest) = (line.number, line.text[1..].trim_start());
            self.at += 1;
            items.push(if rest.is_empty() {
                self.nested(indent, number, depth)?
            } else {
                self.value(rest, number, indent, depth)?
            });
        }
        Ok(Node::Seq(items, start))
    }

    fn map(&mut self, indent: usize, depth: usize) -> Result<Node, ParseError> {
        let start = self.lines[self.at].number;
        let mut members: Vec<(String, Node)> = Vec::new();
        while let Some(line) = self.lines.get(self.at) {
            if line.indent < indent {
                break;
            }
            if line.indent > indent {
                return Err(ParseError::at(
                    line.number,
                    format!("unexpected `{}`: the indentation does not match", line.text),
                ));
            }
            let number = line.number;
            let Some((key, rest)) = split_key(line.text) else {
                return Err(ParseError::at(
                    number,
                    format!("expected `key: value`, got `{}`", line.text),
                ));
            };
            self.at += 1;
            let rest = strip_tag(rest);
            // A sequence may sit at the key's own indentation (`k:` then `- 1.0`).
            let value = if rest.is_empty() {
                match self.lines.get(self.at) {
                    Some(next) if next.indent == indent && next.text.starts_with('-') => {
                        self.sequence(indent, depth + 1)?
                    }
                    _ => self.nested(indent, number, depth)?,
                }
            } else {
                self.value(rest, number, indent, depth)?
            };
            members.push((unquote(key).to_owned(), value));
        }
        Ok(Node::Map(members, start))
    }

    /// The block under a line that ended with `:` or `-`; an empty scalar when there is none.
    fn nested(&mut self, indent: usize, number: usize, depth: usize) -> Result<Node, ParseError> {
        match self.lines.get(self.at) {
            Some(next) if next.indent > indent => {
                let inner = next.indent;
                self.block(inner, depth + 1)
            }
            _ => Ok(Node::Scalar(String::new(), number)),
        }
    }

    /// A value written after `key:` or `- ` on line `number`.
    fn value(
        &mut self,
        rest: &str,
        number: usize,
        indent: usize,
        depth: usize,
    ) -> Result<Node, ParseError> {
        if !rest.starts_with('[') {
            if split_key(rest).is_some() && !rest.starts_with(['"', '\'', '{']) {
                // `- key: value` opens a map inside a sequence item.
                return Err(ParseError::at(
                    number,
                    format!("a map inside a list item is not supported here: `{rest}`"),
                ));
            }
            return Ok(Node::Scalar(unquote(rest).to_owned(), number));
        }
        // A flow sequence, possibly continued on the following (more indented) lines.
        let mut text = rest.to_owned();
        while !balanced(&text) {
            match self.lines.get(self.at) {
                Some(next) if next.indent > indent => {
                    text.push(' ');
                    text.push_str(next.text);
                    self.at += 1;
                }
                _ => {
                    return Err(ParseError::at(
                        number,
                        "a list opened with `[` is not closed with `]`",
                    ));
                }
            }
        }
        flow(&text, number, depth)
    }
}

/// Whether every `[` of `text` is closed.
fn balanced(text: &str) -> bool {
    let opened = text.matches('[').count();
    let closed = text.matches(']').count();
    closed >= opened
}

/// A flow sequence `[a, b, [c, d]]`.
fn flow(text: &str, number: usize, depth: usize) -> Result<Node, ParseError> {
    if depth > MAX_DEPTH {
        return Err(ParseError::at(number, "the file is nested too deeply"));
    }
    let inner = text
        .trim()
        .strip_prefix('[')
        .and_then(|t| t.strip_suffix(']'))
        .ok_or_else(|| ParseError::at(number, format!("expected a list `[...]`, got `{text}`")))?;
    let mut items = Vec::new();
    let (mut level, mut start) = (0usize, 0usize);
    for (i, c) in inner.char_indices() {
        match c {
            '[' => level += 1,
            ']' => level = level.saturating_sub(1),
            ',' if level == 0 => {
                items.push(&inner[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    items.push(&inner[start..]);
    let items: Vec<&str> = items.into_iter().map(str::trim).collect();
    if items.len() == 1 && items[0].is_empty() {
        return Ok(Node::Seq(Vec::new(), number));
    }
    items
        .into_iter()
        .map(|item| {
            if item.starts_with('[') {
                flow(item, number, depth + 1)
            } else {
                Ok(Node::Scalar(unquote(item).to_owned(), number))
            }
        })
        .collect::<Result<_, _>>()
        .map(|items| Node::Seq(items, number))
}

/// `(key, rest)` of `key: rest` or `key:`; `None` when the line is not a mapping entry.
fn split_key(text: &str) -> Option<(&str, &str)> {
    let (key, rest) = if let Some(key) = text.strip_suffix(':') {
        (key, "")
    } else {
        let at = text.find(": ")?;
        (&text[..at], &text[at + 2..])
    };
    let key = key.trim();
    (!key.is_empty() && !key.starts_with('[')).then_some((key, rest.trim()))
}

/// The value without a leading tag (`!!opencv-matrix`, `!<tag:...>`).
fn strip_tag(rest: &str) -> &str {
    if rest.starts_with('!') {
        rest.split_once(char::is_whitespace)
            .map_or("", |(_, value)| value.trim_start())
    } else {
        rest
    }
}

fn unquote(text: &str) -> &str {
    let text = text.trim();
    for q in ['"', '\''] {
        if let Some(inner) = text.strip_prefix(q).and_then(|t| t.strip_suffix(q)) {
            return inner;
        }
    }
    text
}

/// A number as the OpenCV and ROS files are written: the shortest form that reads back as
/// the same `f64`, always with a `.` or an exponent (as both OpenCV's and [`number`] read it).
pub fn write_number(v: f64) -> String {
    format!("{v:?}")
}

/// A matrix's numbers row by row, as OpenCV and ROS files list them.
pub fn row_major<const R: usize, const C: usize>(m: &nalgebra::SMatrix<f64, R, C>) -> Vec<f64> {
    m.transpose().as_slice().to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// OpenCV's header and tags, multi-line flow lists, nested maps and block lists.
    #[test]
    fn reads_the_calibration_subset() {
        let doc = parse(
            "%YAML:1.0\n---\nK1: !!opencv-matrix\n   rows: 3\n   data: [ 1., 0.,\n       \
             2.5e+01 ]\nroi:\n  x_offset: 0\nk:\n- 1.0\n- -2\nname: \"left cam\" # a comment\n",
        )
        .unwrap();
        let k1 = doc.get("K1").unwrap();
        assert_eq!(k1.get("rows").unwrap().number("rows").unwrap(), 3.0);
        assert_eq!(
            k1.get("data").unwrap().numbers("data").unwrap(),
            [1.0, 0.0, 25.0]
        );
        assert_eq!(k1.get("data").unwrap().line(), 5);
        assert_eq!(doc.get("k").unwrap().numbers("k").unwrap(), [1.0, -2.0]);
        assert_eq!(
            doc.get("roi").unwrap().get("x_offset"),
            Some(&Node::Scalar("0".into(), 8))
        );
        assert_eq!(doc.get("name"), Some(&Node::Scalar("left cam".into(), 12)));
    }

    /// Errors carry the line: an unclosed list, a bad number, a line that is not `key: value`.
    #[test]
    fn errors_name_the_line() {
        assert_eq!(parse("a: [1, 2\nb: 3\n").unwrap_err().line, Some(1));
        let doc = parse("a: 1\nb: [1, x]\n").unwrap();
        assert_eq!(
            doc.get("b").unwrap().numbers("b").unwrap_err().line,
            Some(2)
        );
        assert_eq!(parse("a: 1\njunk\n").unwrap_err().line, Some(2));
        assert_eq!(parse("a:\n\tb: 1\n").unwrap_err().line, Some(2));
        let deep = (0..100).fold(String::new(), |s, i| format!("{s}{}k{i}:\n", " ".repeat(i)));
        assert!(parse(&deep).unwrap_err().message.contains("deeply"));
    }
}
