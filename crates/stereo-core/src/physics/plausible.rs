//! Lengths no stereo camera has, the sign of a unit typed wrong: a baseline under a millimetre
//! or over ten metres, a board's square under a millimetre. Each finding names the member, its
//! value and the unit the value most likely was meant in.

use std::fmt;

use super::LengthUnit;
use crate::numbers::{Num, round_to};

/// The narrowest baseline a stereo rig has, in metres (phone and microscope rigs are wider).
pub const MIN_BASELINE_M: f64 = 1e-3;
/// The widest baseline a stereo rig has, in metres (wide surveying rigs stay under it).
pub const MAX_BASELINE_M: f64 = 10.0;
/// The smallest square a printed board has, in metres.
pub const MIN_SQUARE_M: f64 = 1e-3;
/// The largest square a board has, in metres.
pub const MAX_SQUARE_M: f64 = 1.0;

/// The lengths checked, each with the range of values rigs and boards have.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Length {
    Baseline,
    SquareSize,
}

impl Length {
    /// The member as the API names it.
    pub fn name(self) -> &'static str {
        match self {
            Length::Baseline => "baseline",
            Length::SquareSize => "square_size",
        }
    }

    /// The plausible values, in metres.
    fn bounds(self) -> (f64, f64) {
        match self {
            Length::Baseline => (MIN_BASELINE_M, MAX_BASELINE_M),
            Length::SquareSize => (MIN_SQUARE_M, MAX_SQUARE_M),
        }
    }

    /// What has no such length, as a message says it.
    fn none_has(self) -> &'static str {
        match self {
            Length::Baseline => "no stereo camera has",
            Length::SquareSize => "no calibration board has",
        }
    }
}

/// A length no camera rig has, with the unit it was probably meant in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Implausible {
    pub member: Length,
    pub value: f64,
    pub unit: LengthUnit,
    /// Under the plausible range (true) or over it.
    pub under: bool,
    /// The unit that makes the value plausible, when one does.
    pub likely: Option<LengthUnit>,
}

impl Implausible {
    /// The baseline `value` in `unit`, when no stereo rig has it.
    pub fn baseline(value: f64, unit: LengthUnit) -> Option<Implausible> {
        Implausible::of(Length::Baseline, value, unit)
    }

    /// A board's square `value` in `unit`, when no board has it.
    pub fn square_size(value: f64, unit: LengthUnit) -> Option<Implausible> {
        Implausible::of(Length::SquareSize, value, unit)
    }

    fn of(member: Length, value: f64, unit: LengthUnit) -> Option<Implausible> {
        let (lo, hi) = member.bounds();
        let metres = value.abs() * unit.metres();
        if !metres.is_finite() || metres == 0.0 || (lo..=hi).contains(&metres) {
            return None;
        }
        // The unit whose reading of the value lands nearest the middle of the plausible range
        // (on a log scale), among those that make it plausible at all.
        let middle = (lo * hi).sqrt();
        let likely = LengthUnit::ALL
            .into_iter()
            .filter(|u| *u != unit)
            .filter(|u| (lo..=hi).contains(&(value.abs() * u.metres())))
            .min_by(|a, b| {
                let off = |u: &LengthUnit| (value.abs() * u.metres() / middle).ln().abs();
                off(a).total_cmp(&off(b))
            });
        Some(Implausible {
            member,
            value,
            unit,
            under: metres < lo,
            likely,
        })
    }
}

impl fmt::Display for Implausible {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (lo, hi) = self.member.bounds();
        let what = self.member.none_has();
        let bound = if self.under {
            format!("under {} mm", Num(lo * 1000.0))
        } else {
            format!("over {} m", Num(hi))
        };
        write!(
            f,
            "{} is {} {}, {bound}: {what} that, and every distance from it is off by the \
             same factor",
            self.member.name(),
            figures(self.value),
            self.unit.symbol()
        )?;
        match self.likely {
            Some(u) => write!(
                f,
                ". Was it meant in {} ({} {} = {} mm)? Then give the unit as \"{}\"",
                u.symbol(),
                figures(self.value),
                u.symbol(),
                figures(u.convert(self.value, LengthUnit::Millimetre)),
                u.symbol()
            ),
            None => f.write_str(". Check the value and its unit"),
        }
    }
}

/// `value` to three significant figures, as a message reads it.
fn figures(value: f64) -> Num {
    if value == 0.0 || !value.is_finite() {
        return Num(value);
    }
    let places = 2 - value.abs().log10().floor() as i32;
    Num(round_to(value, places))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The user's slip the issue names: a 25 mm board typed as 0.025 with `mm` gives a baseline
    /// of 0.083 mm; both are named, with metres as the likely unit.
    #[test]
    fn metres_typed_as_millimetres_are_named() {
        let b = Implausible::baseline(0.083_005_67, LengthUnit::Millimetre).unwrap();
        assert!(b.under);
        assert_eq!(b.likely, Some(LengthUnit::Metre));
        let said = b.to_string();
        assert!(
            said.starts_with("baseline is 0.083 mm, under 1 mm"),
            "{said}"
        );
        assert!(said.contains("meant in m (0.083 m = 83 mm)"), "{said}");
        let s = Implausible::square_size(0.025, LengthUnit::Millimetre).unwrap();
        assert_eq!(
            (s.member.name(), s.likely),
            ("square_size", Some(LengthUnit::Metre))
        );
    }

    /// Millimetres typed as metres: a 120 mm baseline given as 120 m is over 10 m, likely mm.
    #[test]
    fn millimetres_typed_as_metres_are_named() {
        let b = Implausible::baseline(120.0, LengthUnit::Metre).unwrap();
        assert!(!b.under);
        assert_eq!(b.likely, Some(LengthUnit::Millimetre));
        assert!(b.to_string().contains("over 10 m"));
    }

    /// Ordinary rigs and boards say nothing: 2 mm to 10 m baselines, 1 mm to 1 m squares, in
    /// any unit, and a sign (T_x is negative in OpenCV's convention) does not matter.
    #[test]
    fn plausible_lengths_say_nothing() {
        for (v, u) in [
            (120.0, LengthUnit::Millimetre),
            (-0.12, LengthUnit::Metre),
            (2.0, LengthUnit::Millimetre),
            (9.5, LengthUnit::Metre),
            (4.7, LengthUnit::Inch),
            (30.0, LengthUnit::Foot),
        ] {
            assert_eq!(Implausible::baseline(v, u), None, "{v} {u:?}");
        }
        assert_eq!(Implausible::square_size(25.0, LengthUnit::Millimetre), None);
        assert_eq!(Implausible::square_size(0.3, LengthUnit::Metre), None);
    }
}
