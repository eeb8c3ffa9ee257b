//! Numbers written as text, in one place: into messages for people ([`Num`], the shortest form
//! that reads back as the same number, so that an echoed `1e308` stays `1e308` and not 309
//! digits) and into CSV as the JSON writes them ([`push_json`]). Formulas' rounded numbers
//! (`api::format`) are written through [`Num`] too; only this module calls ryu.

use std::fmt;

/// A number echoed in a message: the shortest decimal that reads back as the same `f64`
/// (ryu), without a trailing `.0`, in scientific notation at the extremes (`1e308`,
/// `1e-300`). Pure code and the HTTP layer write numbers into messages only through it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let value = self.0;
        if !value.is_finite() {
            return write!(f, "{value}");
        }
        let mut buffer = ryu::Buffer::new();
        let text = buffer.format_finite(value);
        let text = text.strip_suffix(".0").unwrap_or(text);
        f.write_str(if text == "-0" { "0" } else { text })
    }
}

/// Appends `value` as the JSON answers write it: the shortest decimal that reads back as the
/// same `f64` (ryu), whole numbers with their `.0` (`105.0`). The CSV answers write through it.
pub fn push_json(out: &mut String, value: f64) {
    out.push_str(ryu::Buffer::new().format(value));
}

/// Text echoed in a message, cut to at most `max` characters (with `…`), so that a caller's
/// long value cannot make a problem long.
pub fn clip(text: &str, max: usize) -> String {
    match text.char_indices().nth(max) {
        Some((at, _)) => format!("{}…", &text[..at]),
        None => text.to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Echoed numbers are exact and short at every magnitude.
    #[test]
    fn echoed_numbers() {
        assert_eq!(Num(1e308).to_string(), "1e308");
        assert_eq!(Num(1e-300).to_string(), "1e-300");
        assert_eq!(Num(700.0).to_string(), "700");
        assert_eq!(Num(0.54).to_string(), "0.54");
        assert_eq!(Num(1242.5).to_string(), "1242.5");
        assert_eq!(Num(-3.0).to_string(), "-3");
        assert_eq!(Num(-0.0).to_string(), "0");
        assert_eq!(Num(0.1 + 0.2).to_string(), "0.30000000000000004");
        assert_eq!(Num(f64::INFINITY).to_string(), "inf");
    }

    /// Long text is cut at a character boundary.
    #[test]
    fn clipped_text() {
        assert_eq!(clip("short", 10), "short");
        assert_eq!(clip("ééééé", 3), "ééé…");
        assert_eq!(clip(&"x".repeat(1000), 40).chars().count(), 41);
    }
}
