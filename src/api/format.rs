//! Numbers written for people: in formulas, summaries and chart labels (never in JSON values,
//! which keep full precision).

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
    crate::numbers::Num((value * 1e4).round() / 1e4).to_string()
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
