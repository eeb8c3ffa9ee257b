//! Numbers written for people: in formulas, summaries and chart labels (never in JSON values,
//! which keep full precision).

/// A number for reading: at most four decimals, no trailing zeros; scientific notation for
/// magnitudes below 10⁻³ or from 10¹² up.
pub fn short(value: f64) -> String {
    if value != 0.0 && !(1e-3..1e12).contains(&value.abs()) {
        return format!("{value:e}");
    }
    let text = format!("{value:.4}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" { "0" } else { text }.to_owned()
}

/// A fraction as a percentage for reading, such as `2 %` for 0.02.
pub fn percent(fraction: f64) -> String {
    format!("{} %", short(fraction * 100.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Formula numbers are short and readable.
    #[test]
    fn short_numbers() {
        assert_eq!(short(105.0), "105");
        assert_eq!(short(0.23333333), "0.2333");
        assert_eq!(short(-15.0), "-15");
        assert_eq!(short(0.0), "0");
        assert_eq!(short(1e-7), "1e-7");
        assert_eq!(short(2.5e12), "2.5e12");
    }

    /// Fractions read as percentages.
    #[test]
    fn percentages() {
        assert_eq!(percent(0.02), "2 %");
        assert_eq!(percent(0.007547169811320755), "0.7547 %");
    }
}
