//! The matcher's parameters, built only through [`Params::new`], which holds the one set of
//! defaults and the bounds that keep the matcher's arithmetic safe. What it refuses is a list of
//! [`ParamFault`]s, each naming the [`Setting`] at fault, which the routes map onto their field
//! names.

use super::{Subpixel, cost, pyramid, sgm};
use crate::numbers::Num;

/// The end of the disparity search (exclusive) when neither the caller nor a calibration file
/// gives one: disparities `0 ..` this.
pub const DEFAULT_MAX_DISPARITY: i32 = 128;
/// The largest σ_d (px) kept when the caller gives no `max_disparity_std`
/// ([`super::sigma::keep`]): lenient, dropping only the values known to ±4 px or worse.
pub const DEFAULT_MAX_DISPARITY_STD: f64 = 4.0;
/// The largest `max_disparity_std` a caller may ask for, in pixels.
pub const MAX_DISPARITY_STD_BOUND: f64 = 64.0;
/// The most disparities one search covers.
pub const MAX_DISPARITIES: usize = 512;
/// The smallest and largest `min_disparity`.
pub const MIN_DISPARITY_BOUND: i32 = 4096;
/// The largest `P2`. The aggregation's `u16` path sums stay below `2 · PAD + P2`, which must
/// stay below the sentinel `FAR` of [`sgm`]: checked when this module compiles.
pub const MAX_P2: u16 = 1024;
const _: () = assert!((sgm::FAR as u32) > 2 * cost::PAD as u32 + MAX_P2 as u32);

/// A named set of the matcher's settings: what a setting not asked for takes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Preset {
    /// The tuned defaults: the most accurate maps (8 paths where the pair is noisy, 5 where
    /// its texture stands well above its noise, [`sgm::Paths::Auto`]).
    #[default]
    Accurate,
    /// For video: one pass on every pair ([`sgm::Paths::Lean`]) and no 3 × 3 median, for
    /// less time than `Accurate` (docs/matcher.md gives the measurements).
    Fast,
}

impl Preset {
    /// The preset's name, as the API spells it.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Accurate => "accurate",
            Preset::Fast => "fast",
        }
    }

    /// The paths the preset aggregates where `paths` is not asked for: a rule that each pair
    /// decides ([`sgm::Paths::for_pair`]).
    pub fn paths(self) -> sgm::Paths {
        match self {
            Preset::Accurate => sgm::Paths::Auto,
            Preset::Fast => sgm::Paths::Lean,
        }
    }

    /// The settings the preset stands for (`None`: the default).
    pub fn settings(self) -> Settings {
        match self {
            Preset::Accurate => Settings::default(),
            Preset::Fast => Settings {
                median: Some(false),
                ..Settings::default()
            },
        }
    }
}

/// The end of the search as a caller writes it: `auto` (found from the pair, [`super::survey`],
/// even where a calibration file has an `ndisp`) or a disparity in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RangeEnd {
    Auto,
    Px(i32),
}

impl RangeEnd {
    /// The disparity given, `None` for `auto`.
    pub fn px(self) -> Option<i32> {
        match self {
            RangeEnd::Auto => None,
            RangeEnd::Px(d) => Some(d),
        }
    }
}

impl std::str::FromStr for RangeEnd {
    type Err = String;

    /// `auto`, or a whole number of pixels.
    fn from_str(text: &str) -> Result<RangeEnd, String> {
        if text == "auto" {
            return Ok(RangeEnd::Auto);
        }
        text.parse::<i32>()
            .map(RangeEnd::Px)
            .map_err(|_| format!("must be auto or a whole number of pixels, got {text:?}"))
    }
}

impl std::fmt::Display for RangeEnd {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            RangeEnd::Auto => f.write_str("auto"),
            RangeEnd::Px(d) => write!(f, "{d}"),
        }
    }
}

/// The matcher's settings as asked for; each `None` takes its preset's, then the default.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Settings {
    /// The named set the settings not given come from; `None` is [`Preset::Accurate`].
    pub preset: Option<Preset>,
    /// The start: pixels, or [`RangeEnd::Auto`] to find it from the pair (the farthest matches
    /// with a margin); `None` finds it where the end is found too, else is 0.
    pub min_disparity: Option<RangeEnd>,
    /// The end of the search, exclusive: disparities `min_disparity .. max_disparity`;
    /// `None` and [`RangeEnd::Auto`] find it from the pair (`None` also takes a calibration
    /// file's `ndisp` where the caller has one, `Auto` does not).
    pub max_disparity: Option<RangeEnd>,
    pub p1: Option<u32>,
    pub p2: Option<u32>,
    pub p2_edge: Option<u32>,
    pub uniqueness: Option<u32>,
    pub lr_check: Option<bool>,
    pub lr_tolerance: Option<f64>,
    pub subpixel: Option<Subpixel>,
    pub speckle_size: Option<u32>,
    pub speckle_range: Option<f64>,
    /// Pixels whose σ_d exceeds this (px) are dropped.
    pub max_disparity_std: Option<f64>,
    pub median: Option<bool>,
    pub fill: Option<bool>,
    /// The paths aggregated: 4, 5 or 8 (`None`: the preset's, [`sgm::Paths::Auto`] or, for
    /// [`Preset::Fast`], [`sgm::Paths::Lean`]).
    pub paths: Option<u32>,
    /// A calibration file's `ndisp`: the end where `max_disparity` is `None` ([`Params::new`]).
    pub file_range: Option<u32>,
}

/// The settings a [`ParamFault`] can name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Setting {
    MinDisparity,
    MaxDisparity,
    P1,
    P2,
    P2Edge,
    Uniqueness,
    LrTolerance,
    SpeckleSize,
    SpeckleRange,
    MaxDisparityStd,
    Paths,
}

impl Setting {
    /// The setting's name, as the API spells it.
    pub fn name(self) -> &'static str {
        match self {
            Setting::MinDisparity => "min_disparity",
            Setting::MaxDisparity => "max_disparity",
            Setting::P1 => "p1",
            Setting::P2 => "p2",
            Setting::P2Edge => "p2_edge",
            Setting::Uniqueness => "uniqueness",
            Setting::LrTolerance => "lr_tolerance",
            Setting::SpeckleSize => "speckle_size",
            Setting::SpeckleRange => "speckle_range",
            Setting::MaxDisparityStd => "max_disparity_std",
            Setting::Paths => "paths",
        }
    }
}

/// A setting [`Params::new`] refused, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamFault {
    pub setting: Setting,
    pub message: String,
}

/// The matcher's parameters: a search range of 1 to [`MAX_DISPARITIES`] disparities and
/// penalties, thresholds and filters within the bounds the matcher is safe in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Params {
    pub(super) min_disparity: i32,
    pub(super) count: usize,
    pub(super) penalties: sgm::Penalties,
    pub(super) uniqueness: u32,
    pub(super) lr_tolerance: Option<f32>,
    pub(super) subpixel: Subpixel,
    pub(super) speckle_size: usize,
    pub(super) speckle_range: f32,
    pub(super) max_std: f64,
    pub(super) median: bool,
    pub(super) fill: bool,
    /// Whether holes in flat areas take the plane their surroundings imply ([`super::plane`]).
    pub(super) plane: bool,
    pub(super) paths: sgm::Paths,
    pub(super) preset: Preset,
    /// Whether the caller gave no end of range, so that it is found from the pair
    /// ([`super::survey`]); `min_disparity .. max_disparity` is then the default, until
    /// [`Params::with_range`] sets the one found.
    pub(super) found: bool,
    /// Whether the start is found from the pair too (`min_disparity` is 0 until it is).
    pub(super) min_found: bool,
    /// With `found`: the least end of range to search, whatever the pair's own needs (a
    /// stream's range kept from its earlier frames, [`Params::at_least`]); 0 for none.
    pub(super) at_least: i32,
    /// The pyramid's shape: [`pyramid::Shape::DEFAULT`] but in the tune build's grid.
    pub(super) shape: pyramid::Shape,
}

impl Default for Params {
    /// The tuned defaults (docs/matcher.md gives the measurements that chose
    /// them), searching `0 .. DEFAULT_MAX_DISPARITY`.
    fn default() -> Self {
        Self {
            min_disparity: 0,
            count: DEFAULT_MAX_DISPARITY as usize,
            penalties: sgm::Penalties {
                p1: 16,
                p2: 64,
                edge: 16,
            },
            uniqueness: 15,
            lr_tolerance: Some(1.0),
            subpixel: Subpixel::Equiangular,
            speckle_size: 100,
            speckle_range: 2.0,
            max_std: DEFAULT_MAX_DISPARITY_STD,
            median: true,
            fill: false,
            plane: true,
            paths: sgm::Paths::Auto,
            preset: Preset::Accurate,
            found: true,
            min_found: true,
            at_least: 0,
            shape: pyramid::Shape::DEFAULT,
        }
    }
}

/// Collects faults, one per setting.
#[derive(Default)]
struct Faults(Vec<ParamFault>);

impl Faults {
    fn add(&mut self, setting: Setting, message: String) {
        if !self.0.iter().any(|f| f.setting == setting) {
            self.0.push(ParamFault { setting, message });
        }
    }

    /// A whole number in `[lo, hi]`, or the default.
    fn whole(
        &mut self,
        setting: Setting,
        value: Option<u32>,
        default: u32,
        lo: u32,
        hi: u32,
    ) -> Option<u32> {
        let v = value.unwrap_or(default);
        if (lo..=hi).contains(&v) {
            Some(v)
        } else {
            self.add(setting, format!("must be from {lo} to {hi}, got {v}"));
            None
        }
    }

    /// A real number in `[0, hi]` (`(0, hi]` when `open_low`), or the default.
    fn real(
        &mut self,
        setting: Setting,
        value: Option<f64>,
        default: f64,
        open_low: bool,
        hi: f64,
    ) -> Option<f64> {
        let v = value.unwrap_or(default);
        let low_ok = if open_low { v > 0.0 } else { v >= 0.0 };
        if v.is_finite() && low_ok && v <= hi {
            Some(v)
        } else {
            let bracket = if open_low { "(" } else { "[" };
            self.add(
                setting,
                format!("must lie in {bracket}0, {hi}], got {}", Num(v)),
            );
            None
        }
    }
}

impl Params {
    /// Checks the settings and fills in the preset's and the defaults. Every fault is
    /// reported.
    pub fn new(asked: &Settings) -> Result<Params, Vec<ParamFault>> {
        let preset = asked.preset.unwrap_or_default();
        let mut s = asked.over(preset.settings());
        let file = s.file_range.map(|n| n.min(MAX_DISPARITIES as u32) as i32);
        s.max_disparity = s.max_disparity.or(file.map(RangeEnd::Px));
        let s = &s;
        let d = Params::default();
        let mut faults = Faults::default();
        let range = range(
            s.min_disparity.and_then(RangeEnd::px),
            s.max_disparity.and_then(RangeEnd::px),
            &mut faults,
        );
        let p1 = faults.whole(Setting::P1, s.p1, d.penalties.p1.into(), 1, 255);
        let p2 = faults.whole(Setting::P2, s.p2, d.penalties.p2.into(), 2, MAX_P2.into());
        if let (Some(p1), Some(p2)) = (p1, p2)
            && p2 <= p1
        {
            faults.add(
                Setting::P2,
                format!("must be greater than p1 ({p1}), got {p2}"),
            );
        }
        let edge = faults.whole(Setting::P2Edge, s.p2_edge, d.penalties.edge.into(), 0, 255);
        let uniqueness = faults.whole(Setting::Uniqueness, s.uniqueness, d.uniqueness, 0, 100);
        let speckle_size = faults.whole(
            Setting::SpeckleSize,
            s.speckle_size,
            d.speckle_size as u32,
            0,
            1_000_000,
        );
        let default_tolerance = d.lr_tolerance.map_or(1.0, f64::from);
        let tolerance = faults.real(
            Setting::LrTolerance,
            s.lr_tolerance,
            default_tolerance,
            false,
            64.0,
        );
        let speckle_range = faults.real(
            Setting::SpeckleRange,
            s.speckle_range,
            f64::from(d.speckle_range),
            true,
            64.0,
        );
        let max_std = faults.real(
            Setting::MaxDisparityStd,
            s.max_disparity_std,
            d.max_std,
            true,
            MAX_DISPARITY_STD_BOUND,
        );
        let paths = match s.paths {
            None => preset.paths(),
            Some(4) => sgm::Paths::Four,
            Some(5) => sgm::Paths::Five,
            Some(8) => sgm::Paths::Eight,
            Some(other) => {
                faults.add(Setting::Paths, format!("must be 4, 5 or 8, got {other}"));
                preset.paths()
            }
        };
        let lr_check = s.lr_check.unwrap_or(true);
        if !lr_check && s.lr_tolerance.is_some() {
            faults.add(
                Setting::LrTolerance,
                "applies only when lr_check is true".to_owned(),
            );
        }
        match (
            range,
            p1,
            p2,
            edge,
            uniqueness,
            speckle_size,
            tolerance,
            speckle_range,
            max_std,
        ) {
            (
                Some((min_disparity, count)),
                Some(p1),
                Some(p2),
                Some(edge),
                Some(uniqueness),
                Some(speckle_size),
                Some(tolerance),
                Some(speckle_range),
                Some(max_std),
            ) if faults.0.is_empty() => Ok(Params {
                min_disparity,
                count,
                penalties: sgm::Penalties {
                    p1: p1 as u16,
                    p2: p2 as u16,
                    edge: edge as u16,
                },
                uniqueness,
                lr_tolerance: lr_check.then_some(tolerance as f32),
                subpixel: s.subpixel.unwrap_or(d.subpixel),
                speckle_size: speckle_size as usize,
                speckle_range: speckle_range as f32,
                max_std,
                median: s.median.unwrap_or(d.median),
                fill: s.fill.unwrap_or(d.fill),
                plane: d.plane,
                paths,
                preset,
                found: s.max_disparity.and_then(RangeEnd::px).is_none(),
                min_found: match s.min_disparity {
                    Some(RangeEnd::Auto) => true,
                    Some(RangeEnd::Px(_)) => false,
                    None => s.max_disparity.and_then(RangeEnd::px).is_none(),
                },
                at_least: 0,
                shape: pyramid::Shape::DEFAULT,
            }),
            _ => Err(faults.0),
        }
    }

    /// The defaults with the search `min_disparity .. max_disparity`.
    pub fn range(min_disparity: i32, max_disparity: i32) -> Result<Params, Vec<ParamFault>> {
        Params::new(&Settings {
            min_disparity: Some(RangeEnd::Px(min_disparity)),
            max_disparity: Some(RangeEnd::Px(max_disparity)),
            ..Settings::default()
        })
    }

    /// These parameters searching `min_disparity .. max_disparity` (a range found from the
    /// pair: within the bounds of [`Params::new`], at most [`MAX_DISPARITIES`]).
    pub fn with_range(&self, min_disparity: i32, max_disparity: i32) -> Params {
        let count =
            (i64::from(max_disparity) - i64::from(min_disparity)).clamp(1, MAX_DISPARITIES as i64);
        Params {
            min_disparity,
            count: count as usize,
            found: false,
            min_found: false,
            ..*self
        }
    }

    /// Whether the range is to be found from the pair: the caller gave no `max_disparity`.
    pub fn range_found(&self) -> bool {
        self.found
    }

    /// Whether the range's start is to be found from the pair ([`Settings::min_disparity`]).
    pub fn min_found(&self) -> bool {
        self.min_found
    }

    /// These parameters, with a range to be found, searching at least to `max` (at most
    /// [`MAX_DISPARITIES`]) whatever the pair's own needs: a stream's range kept from its
    /// earlier frames. Parameters with a range given are returned as they are.
    pub fn at_least(&self, max: i32) -> Params {
        let at_least = max.clamp(0, MAX_DISPARITIES as i32) * i32::from(self.found);
        Params { at_least, ..*self }
    }

    /// The least end of range [`Params::at_least`] set (0 for none).
    pub fn least_max(&self) -> i32 {
        self.at_least
    }

    /// The most disparities these parameters may search, what a request is charged for: the
    /// range's own, or for a range to be found, [`MAX_DISPARITIES`] (the matcher's peak
    /// memory stops growing past [`super::pyramid::WHOLE`], so this costs little more).
    pub fn most_searched(&self) -> usize {
        if self.found {
            MAX_DISPARITIES
        } else {
            self.count
        }
    }

    /// The smallest disparity searched, in pixels.
    pub fn min_disparity(&self) -> i32 {
        self.min_disparity
    }
    /// The end of the search, exclusive.
    pub fn max_disparity(&self) -> i32 {
        self.min_disparity + self.count as i32
    }
    /// How many disparities are searched: `min_disparity .. max_disparity`.
    pub fn count(&self) -> usize {
        self.count
    }
    pub fn penalties(&self) -> sgm::Penalties {
        self.penalties
    }
    /// How much better (in percent) the best cost must be than any other more than one pixel
    /// away.
    pub fn uniqueness(&self) -> u32 {
        self.uniqueness
    }
    /// The left-right check's tolerance in pixels; `None` skips the check.
    pub fn lr_tolerance(&self) -> Option<f32> {
        self.lr_tolerance
    }
    pub fn subpixel(&self) -> Subpixel {
        self.subpixel
    }
    /// Regions smaller than this many pixels are removed (0: no speckle removal)…
    pub fn speckle_size(&self) -> usize {
        self.speckle_size
    }
    /// … where neighbours within this many pixels of disparity are one region.
    pub fn speckle_range(&self) -> f32 {
        self.speckle_range
    }
    /// The largest σ_d (px) a kept disparity may have.
    pub fn max_disparity_std(&self) -> f64 {
        self.max_std
    }
    /// A 3 × 3 median filter of the result.
    pub fn median(&self) -> bool {
        self.median
    }
    /// Fill invalid pixels from their row's background instead of leaving them invalid.
    pub fn fill(&self) -> bool {
        self.fill
    }
    /// The paths the aggregation sums.
    pub fn paths(&self) -> sgm::Paths {
        self.paths
    }
    /// The preset the settings not asked for came from.
    pub fn preset(&self) -> Preset {
        self.preset
    }
}

impl Settings {
    /// These settings, with `base`'s where these have none.
    fn over(&self, base: Settings) -> Settings {
        Settings {
            preset: self.preset.or(base.preset),
            min_disparity: self.min_disparity.or(base.min_disparity),
            max_disparity: self.max_disparity.or(base.max_disparity),
            p1: self.p1.or(base.p1),
            p2: self.p2.or(base.p2),
            p2_edge: self.p2_edge.or(base.p2_edge),
            uniqueness: self.uniqueness.or(base.uniqueness),
            lr_check: self.lr_check.or(base.lr_check),
            lr_tolerance: self.lr_tolerance.or(base.lr_tolerance),
            subpixel: self.subpixel.or(base.subpixel),
            speckle_size: self.speckle_size.or(base.speckle_size),
            speckle_range: self.speckle_range.or(base.speckle_range),
            max_disparity_std: self.max_disparity_std.or(base.max_disparity_std),
            median: self.median.or(base.median),
            fill: self.fill.or(base.fill),
            paths: self.paths.or(base.paths),
            file_range: self.file_range.or(base.file_range),
        }
    }
}

/// The search range `(min, count)` from its two ends, the one place where an end of range
/// becomes a count.
fn range(min: Option<i32>, max: Option<i32>, faults: &mut Faults) -> Option<(i32, usize)> {
    let min = min.unwrap_or(0);
    let mut ok = true;
    if !(-MIN_DISPARITY_BOUND..=MIN_DISPARITY_BOUND).contains(&min) {
        faults.add(
            Setting::MinDisparity,
            format!("must lie in [-{MIN_DISPARITY_BOUND}, {MIN_DISPARITY_BOUND}], got {min}"),
        );
        ok = false;
    }
    let max = max.unwrap_or(min.saturating_add(DEFAULT_MAX_DISPARITY));
    let count = i64::from(max) - i64::from(min);
    if count < 1 {
        faults.add(
            Setting::MaxDisparity,
            format!("must be greater than min_disparity ({min}), got {max}"),
        );
    } else if count > MAX_DISPARITIES as i64 {
        faults.add(
            Setting::MaxDisparity,
            format!(
                "searches {count} disparities from min_disparity {min}; at most \
                 {MAX_DISPARITIES} fit: narrow the range"
            ),
        );
    }
    let count = usize::try_from(count)
        .ok()
        .filter(|c| (1..=MAX_DISPARITIES).contains(c))?;
    ok.then_some((min, count))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(faults: &[ParamFault]) -> Vec<&'static str> {
        faults.iter().map(|f| f.setting.name()).collect()
    }

    /// No settings are the defaults, which search `0 .. DEFAULT_MAX_DISPARITY`.
    #[test]
    fn nothing_asked_is_the_defaults() {
        let p = Params::new(&Settings::default()).unwrap();
        assert_eq!(p, Params::default());
        assert_eq!(
            (p.min_disparity(), p.max_disparity()),
            (0, DEFAULT_MAX_DISPARITY)
        );
    }

    /// Every setting out of bounds is named once, with the bound; a start with the end to be
    /// found stands on its own (the end found past it).
    #[test]
    fn every_fault_is_named() {
        let faults = Params::new(&Settings {
            min_disparity: Some(RangeEnd::Px(5000)),
            p1: Some(0),
            p2: Some(2000),
            uniqueness: Some(101),
            lr_check: Some(false),
            lr_tolerance: Some(1.0),
            speckle_range: Some(0.0),
            ..Settings::default()
        })
        .unwrap_err();
        assert_eq!(
            names(&faults),
            [
                "min_disparity",
                "p1",
                "p2",
                "uniqueness",
                "speckle_range",
                "lr_tolerance"
            ]
        );
        assert!(faults[2].message.contains("from 2 to 1024"));
        // A start out of bounds with the end to be found names the start alone; with an end
        // given before it, the end too.
        let faults = Params::new(&Settings {
            min_disparity: Some(RangeEnd::Px(200)),
            ..Settings::default()
        });
        assert!(faults.is_ok(), "{faults:?}");
        let faults = Params::range(200, 100).unwrap_err();
        assert_eq!(names(&faults), ["max_disparity"]);
    }

    /// The range's count is end − start, from 1 to 512; p2 must exceed p1.
    #[test]
    fn the_range_and_the_penalties_hold_together() {
        let p = Params::range(-16, 496).unwrap();
        assert_eq!(p.count(), 512);
        assert_eq!(
            names(&Params::range(0, 513).unwrap_err()),
            ["max_disparity"]
        );
        assert_eq!(
            names(&Params::range(10, 10).unwrap_err()),
            ["max_disparity"]
        );
        let faults = Params::new(&Settings {
            p1: Some(40),
            p2: Some(40),
            ..Settings::default()
        })
        .unwrap_err();
        assert_eq!(faults[0].message, "must be greater than p1 (40), got 40");
    }

    /// A preset fills the settings not asked for; those asked for win over it.
    #[test]
    fn a_preset_fills_what_was_not_asked() {
        let fast = Params::new(&Settings {
            preset: Some(Preset::Fast),
            ..Settings::default()
        })
        .unwrap();
        assert_eq!(
            (fast.preset(), fast.paths(), fast.median()),
            (Preset::Fast, sgm::Paths::Lean, false)
        );
        assert_eq!(fast.penalties(), Params::default().penalties());
        let median = Params::new(&Settings {
            preset: Some(Preset::Fast),
            median: Some(true),
            ..Settings::default()
        })
        .unwrap();
        assert_eq!((median.paths(), median.median()), (sgm::Paths::Lean, true));
        let accurate = Params::new(&Settings::default()).unwrap();
        assert_eq!(
            (accurate.preset(), accurate.paths(), accurate.median()),
            (Preset::Accurate, sgm::Paths::Auto, true)
        );
    }
}
