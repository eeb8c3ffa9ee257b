//! Numbers written as text, in one place: into messages for people ([`Num`], the shortest form
//! that reads back as the same number, so that an echoed `1e308` stays `1e308` and not 309
//! digits), into CSV as the JSON writes them ([`push_json`]), and rounded for reading in
//! formulas, summaries and chart labels ([`short`], [`percent`]; never in JSON values, which
//! keep full precision unless they state theirs, [`round_to`]). Only this module calls ryu.
//! Beside them, what else a message echoes of a caller's text: cut short ([`clip`]), and a
//! name's near misses found ([`edit_distance`]).

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

/// Levenshtein's distance between two names, in characters: how a message finds the name a
/// caller meant (`M_1` for `M1`, `basline` for `baseline`).
pub fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let above = row[j + 1];
            row[j + 1] = (above + 1)
                .min(row[j] + 1)
                .min(diagonal + usize::from(ca != *cb));
            diagonal = above;
        }
    }
    row[b.len()]
}

/// Text echoed in a message, cut to at most `max` characters (with `…`), so that a caller's
/// long value cannot make a problem long.
pub fn clip(text: &str, max: usize) -> String {
    match text.char_indices().nth(max) {
        Some((at, _)) => format!("{}…", &text[..at]),
        None => text.to_owned(),
    }
}

/// A number for reading: at most four decimals, no trailing zeros; scientific notation for
/// magnitudes below 10⁻³ or from 10¹² up.
///
/// Rounds in binary (`round(v·10⁴)/10⁴`) and writes the shortest form ([`crate::numbers::Num`],
/// ryu's): ten times
/// cheaper than `format!("{:.4}")`, whose exact decimal expansion showed in the profile of
/// `/distance`. The two differ only on exact ties of the fifth decimal.
pub fn short(value: f64) -> String {
    if value != 0.0 && !(1e-3..1e12).contains(&value.abs()) {
        return format!("{value:e}");
    }
    Num(round_to(value, 4)).to_string()
}

/// `value` rounded to `places` decimals, for values an answer gives to a stated precision
/// (corners to 1/10 000 px, a view's spread to 1/1000).
pub fn round_to(value: f64, places: i32) -> f64 {
    let scale = 10f64.powi(places);
    (value * scale).round() / scale
}

/// A fraction as a percentage for reading, such as `2 %` for 0.02.
pub fn percent(fraction: f64) -> String {
    format!("{} %", short(fraction * 100.0))
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

    /// Formula numbers are short and readable.
    #[test]
    fn short_numbers() {
        assert_eq!(short(105.0), "105");
        assert_eq!(short(0.23333333), "0.2333");
        assert_eq!(short(-15.0), "-15");
        assert_eq!(short(0.0), "0");
        assert_eq!(short(1e-7), "1e-7");
        assert_eq!(short(2.5e12), "2.5e12");
        assert_eq!(short(0.001), "0.001");
        assert_eq!(short(-0.0), "0");
        assert_eq!(short(0.00104), "0.001");
        assert_eq!(short(168.254_237_288), "168.2542");
        assert_eq!(short(999_999_999_999.0), "999999999999");
        assert_eq!(short(5300.0), "5300");
    }

    /// Fractions read as percentages.
    #[test]
    fn percentages() {
        assert_eq!(percent(0.02), "2 %");
        assert_eq!(percent(0.007547169811320755), "0.7547 %");
    }
}
