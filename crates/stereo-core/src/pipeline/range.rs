//! The disparity range a pair is matched over, and what a user hears about it: the caller's
//! own, or the one the pair's coarse view finds ([`vision::survey`]) when none was given; the
//! pixels past a range that stops short refused, with a warning naming `max_disparity`; and
//! cameras that look swapped named.

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use crate::physics::Rig;
use crate::pipeline::Maps;
use crate::vision::decode::Decoded;
use crate::vision::survey::{self, Survey};
use crate::vision::{Cancelled, DEFAULT_MAX_DISPARITY, Disparity, Gray, MAX_DISPARITIES, Params};

/// Below this share of the image refused past a given range, nothing is said: a few pixels in
/// the range's last disparity are mismatches, not a scene that runs past it.
pub const SHORT_SHARE: f64 = 0.005;

/// Why a pair was not matched.
#[derive(Debug, Clone, PartialEq)]
pub enum Stopped {
    /// The caller cancelled (the client went away, the deadline passed).
    Cancelled,
    /// No range was given and the scene needs more disparities than one search covers:
    /// `needs` is the range `(min, max)` the pair's coarse view found.
    TooWide { needs: (i32, i32) },
}

impl From<Cancelled> for Stopped {
    fn from(_: Cancelled) -> Self {
        Stopped::Cancelled
    }
}

impl Stopped {
    /// What to tell the caller, naming what to send instead (`None` for a cancel).
    pub fn advice(&self) -> Option<String> {
        match self {
            Stopped::Cancelled => None,
            Stopped::TooWide { needs: (min, max) } => Some(format!(
                "was not given, and the pair's coarse view finds the scene needs disparities \
                 {min} .. {max}, more than the {MAX_DISPARITIES} one search covers: send \
                 min_disparity and max_disparity at most {MAX_DISPARITIES} apart around the \
                 distances you need (the nearer part: min_disparity={}, max_disparity={max}), \
                 or halve the images (and the rig's focal length with them)",
                max - MAX_DISPARITIES as i32
            )),
        }
    }
}

/// How the range was chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Chosen {
    /// The caller's (or the calibration file's `ndisp`).
    Given,
    /// Found from the pair: its coarse view's nearest match ([`survey::NEAR_QUANTILE`]), in
    /// pixels, with a margin: the range's end this pair `needs`, which a stream's range kept
    /// from its earlier frames may pass ([`Params::at_least`]).
    Found { near: f32, needs: i32 },
    /// No range was given and the coarse view matched too little of the pair to find one:
    /// the default [`DEFAULT_MAX_DISPARITY`].
    Default,
}

/// The range a pair was matched over, and why.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeUsed {
    pub min: i32,
    pub max: i32,
    pub chosen: Chosen,
    /// Where the start was found from the pair too: its coarse view's farthest matches
    /// ([`survey::FAR_QUANTILE`]), in pixels.
    pub start: Option<f32>,
}

impl RangeUsed {
    /// The reason, in a sentence's words.
    pub fn why(&self) -> String {
        let start = self
            .start
            .map(|far| {
                format!(
                    "; the start found from the pair too: its coarse view's farthest matches \
                     reach {far:.0} px ({:.1} % of them farther), less a margin, rounded down \
                     to 16 and never below 0",
                    100.0 * survey::FAR_QUANTILE
                )
            })
            .unwrap_or_default();
        self.end_why() + &start
    }

    /// The reason for the range's end.
    fn end_why(&self) -> String {
        match self.chosen {
            Chosen::Given => "given: max_disparity (or the calibration file's ndisp)".to_owned(),
            Chosen::Found { near, needs } => format!(
                "found from the pair: its coarse view's nearest matches reach {near:.0} px \
                 ({:.1} % of them nearer), with a margin{}",
                100.0 * (1.0 - survey::NEAR_QUANTILE),
                if self.max > needs {
                    format!(
                        "; searched to {}, the range the stream's recent frames needed, where \
                         this one needs {needs}",
                        self.max
                    )
                } else {
                    String::new()
                }
            ),
            Chosen::Default => format!(
                "the default 0 .. {DEFAULT_MAX_DISPARITY}: the pair's coarse view matched \
                 under {:.0} % of its pixels, too little to find the range from",
                100.0 * survey::MIN_MATCHED
            ),
        }
    }
}

/// A pair's range chosen, with its survey.
#[derive(Debug, Clone)]
pub struct Ranged {
    /// The parameters with the range used.
    pub params: Params,
    pub used: RangeUsed,
    survey: Option<Survey>,
    /// A raw pair that matched far better rectified the other way round: the share of its
    /// coarse view that matched so, and as sent ([`Ranged::check_raw`]).
    raw_swapped: Option<(f64, f64)>,
}

/// Rectifies a pair through `maps` when there are some (in place, [`Maps::rectify_pair`]),
/// then chooses its range ([`choose`]), a raw pair checked rectified the other way round too
/// ([`Ranged::check_raw`]). The rectification's time, the range, and the time choosing it
/// took.
pub fn rectify_and_choose(
    maps: Option<&Maps>,
    (left, right): (&mut Decoded, &mut Decoded),
    colour: bool,
    params: &Params,
    cancel: &AtomicBool,
) -> Result<(Option<Duration>, Ranged, Duration), Stopped> {
    let rectified = maps.map(|m| (m, m.rectify_pair(left, right, colour)));
    let started = Instant::now();
    let mut ranged = choose(&left.grey, &right.grey, params, cancel)?;
    if let Some((maps, (_, (raw_left, raw_right)))) = &rectified {
        ranged.check_raw(maps, raw_left, raw_right, cancel)?;
    }
    Ok((
        rectified.map(|(_, (took, _))| took),
        ranged,
        started.elapsed(),
    ))
}

/// Surveys a rectified pair and chooses the range it is matched over: the caller's when
/// `params` has one, else the one found ([`Survey::needs`]), else the default.
pub fn choose(
    left: &Gray,
    right: &Gray,
    params: &Params,
    cancel: &AtomicBool,
) -> Result<Ranged, Stopped> {
    let survey = survey::survey(left, right, cancel)?;
    let given = !params.range_found();
    let usable = survey.as_ref().filter(|s| s.usable());
    // The start given, or `None` to find it (with a usable survey).
    let start = (!params.min_found() || usable.is_none()).then(|| params.min_disparity());
    let (params, chosen) = match (usable, given) {
        (Some(s), true) if start.is_none() => {
            let max = params.max_disparity();
            let min = s.needs(None).map_or(0, |(min, _)| min).min(max - 16);
            (params.with_range(min, max), Chosen::Given)
        }
        (_, true) => (*params, Chosen::Given),
        (Some(s), false) => {
            let (min, needs) = s.needs(start).map_err(|needs| Stopped::TooWide { needs })?;
            let max = needs.max(params.least_max());
            // A stream's kept end may widen the range past one search: a start found moves
            // up, a start given stands and the end is held to one search from it.
            let (min, max) = if start.is_some() {
                (min, max.min(min + MAX_DISPARITIES as i32))
            } else {
                (min.min(max - 16).max(max - MAX_DISPARITIES as i32), max)
            };
            (
                params.with_range(min, max),
                Chosen::Found {
                    near: s.near,
                    needs,
                },
            )
        }
        (None, false) => {
            let min = params.min_disparity();
            (
                params.with_range(min, min + DEFAULT_MAX_DISPARITY),
                Chosen::Default,
            )
        }
    };
    Ok(Ranged {
        used: RangeUsed {
            min: params.min_disparity(),
            max: params.max_disparity(),
            chosen,
            start: usable.filter(|_| start.is_none()).map(|s| s.far),
        },
        params,
        survey,
        raw_swapped: None,
    })
}

impl Ranged {
    /// Refuses the pixels of `map` past the range ([`survey::refuse`]) and says what a user
    /// should hear: a given range the scene runs past (the share refused, how far the scene
    /// reaches, the nearest distance the range reaches with `rig`), and cameras that look
    /// swapped.
    pub fn judge(&self, map: &mut Disparity, rig: Option<Rig>) -> Vec<String> {
        let max = self.used.max;
        let past = self.past_share();
        // The coarse view's holes are grown into only where a given range does stop short.
        let grow = self.used.chosen == Chosen::Given && past >= SHORT_SHARE;
        // A start found past 0: the few pixels short of it are refused too (not counted in
        // the share below: they say nothing of the range's end).
        let start = (self.used.start.is_some() && self.used.min > 0).then_some(self.used.min);
        let refused = survey::refuse(map, self.survey.as_ref(), (start, max), grow);
        let mut said = Vec::new();
        // The share refused, or where only bands of the map were matched (`/match`), the
        // share the coarse view puts past the range.
        let share = (refused as f64 / map.data.len().max(1) as f64).max(past);
        let trusted = self.survey.as_ref().is_some_and(|s| s.usable());
        if self.used.chosen == Chosen::Given && trusted && share >= SHORT_SHARE {
            let reach = self
                .survey
                .as_ref()
                .map(|s| s.greatest)
                .filter(|&g| g >= max as f32);
            let nearest = rig
                .filter(|r| f64::from(max) + r.doffs() > 0.0)
                .map(|r| {
                    format!(
                        "; the nearest distance it reaches is Z_min = f·B / d_max = {} {}",
                        crate::numbers::short(r.fb() / (f64::from(max) + r.doffs())),
                        r.unit().symbol()
                    )
                })
                .unwrap_or_default();
            let advice = match reach.and_then(|g| survey_max(g, max)) {
                Some(m) => format!("send max_disparity={m} or leave it out"),
                None => "leave max_disparity out".to_owned(),
            };
            said.push(format!(
                "max_disparity {max} stops short of the scene: {:.1} % of the image matches at \
                 or past it{}, and those pixels are refused (left empty) rather than answered \
                 wrong{nearest}: {advice} to have the range found from the pair",
                share * 100.0,
                reach
                    .map(|g| format!(" (the pair's coarse view reaches {g:.0} px)"))
                    .unwrap_or_default(),
            ));
        }
        if let Some((other, sent)) = self.raw_swapped {
            said.push(format!(
                "left and right look swapped: rectified the other way round (the right image \
                 as the left camera's), {:.0} % of the pair's coarse view matches, against \
                 {:.0} % as sent; send the left camera's image as left and the right camera's \
                 as right",
                other * 100.0,
                sent * 100.0
            ));
        } else if let Some(s) = self.survey.as_ref().filter(|s| s.swapped()) {
            let evidence = match s.reversed {
                Some(r) if r >= survey::SWAPPED_GAIN * s.matched => format!(
                    "matched the other way round (right as left), {:.0} % of the pair's coarse \
                     view matches, against {:.0} % as sent",
                    r * 100.0,
                    s.matched * 100.0
                ),
                _ => format!(
                    "{:.0} % of the pair's matches lie at negative disparities (their median \
                     {:.0} px), where a rectified pair's lie at positive ones (x_left − x_right \
                     > 0)",
                    s.negative * 100.0,
                    s.negative_median
                ),
            };
            said.push(format!(
                "left and right look swapped: {evidence}; send the left camera's image as left \
                 and the right camera's as right"
            ));
        }
        said
    }

    /// The share of the image the pair's coarse view puts at or past the range's end
    /// ([`Survey::beyond`]): what a range that stops short leaves unmatched. 0 without a
    /// survey.
    pub fn past_share(&self) -> f64 {
        self.survey
            .as_ref()
            .map_or(0.0, |s| s.beyond(self.used.max))
    }

    /// Whether the pair's coarse view says the cameras look swapped (the warning
    /// [`Ranged::judge`] then writes).
    pub fn swapped(&self) -> bool {
        self.raw_swapped.is_some() || self.survey.as_ref().is_some_and(Survey::swapped)
    }

    /// For a raw pair rectified through `maps` (its raw grey frames `left` and `right`): where
    /// its coarse view matched under 1 / [`survey::SWAPPED_GAIN`] and does not already look
    /// swapped, the frames rectified the other way round ([`Maps::swapped_grey`]) are surveyed
    /// too, and a pair that matches at least [`survey::SWAPPED_GAIN`] times as much so is taken
    /// as swapped: a calibration that works only one way round.
    pub fn check_raw(
        &mut self,
        maps: &Maps,
        left: &Gray,
        right: &Gray,
        cancel: &AtomicBool,
    ) -> Result<(), Cancelled> {
        let matched = self.survey.as_ref().map_or(0.0, |s| s.matched);
        // Past 1 / SWAPPED_GAIN matched as sent, the other way round could never match so much
        // more.
        if self.swapped() || matched * survey::SWAPPED_GAIN >= 1.0 {
            return Ok(());
        }
        let (l, r) = maps.swapped_grey(left, right);
        if let Some(other) = survey::survey(&l, &r, cancel)?
            && other.usable()
            && !other.swapped()
            && other.matched >= survey::SWAPPED_GAIN * matched
        {
            self.raw_swapped = Some((other.matched, matched));
        }
        Ok(())
    }

    /// The range the pair's corners are looked for in by the row check: the one searched,
    /// its end widened to what the pair's coarse view reaches past it (a given range that
    /// stops short would otherwise match a near board's corners to their neighbours, off
    /// their rows, and call a rectified pair raw).
    pub fn rows_range(&self) -> (i32, i32) {
        let (min, max) = (self.params.min_disparity(), self.params.max_disparity());
        let reach = self
            .survey
            .as_ref()
            .filter(|s| s.usable() && s.greatest >= max as f32)
            .and_then(|s| survey_max(s.greatest, max - min));
        (min, reach.map_or(max, |r| max.max(min + r)))
    }

    /// Whether the pair's coarse view puts the pixel `(x, y)` past the range's end.
    pub fn past(&self, pixel: (usize, usize)) -> bool {
        self.survey
            .as_ref()
            .is_some_and(|s| s.past(pixel, self.used.max))
    }
}

/// The end of range to advise for a scene reaching `greatest` px past `max`: with a tenth's
/// margin, rounded up to 16, when one search covers it.
fn survey_max(greatest: f32, max: i32) -> Option<i32> {
    let m = ((greatest * 1.1 / 16.0).ceil() as i32 * 16).max(max + 16);
    (m as usize <= MAX_DISPARITIES).then_some(m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vision::synthetic;

    fn near_scene() -> synthetic::Pair {
        synthetic::render(&synthetic::nearer(640, 360, 5.0, 0.0))
    }

    /// No range given: the range is found from the pair and covers it; a given one stands.
    #[test]
    fn a_range_not_given_is_found_and_a_given_one_stands() {
        let pair = near_scene();
        let cancel = AtomicBool::new(false);
        let ranged = choose(&pair.left, &pair.right, &Params::default(), &cancel).unwrap();
        let truth = pair.seen_truth().into_iter().fold(0.0f32, f32::max);
        assert!(
            matches!(ranged.used.chosen, Chosen::Found { .. })
                && ranged.used.max as f32 > truth
                && (ranged.used.max as f32) < 1.3 * truth + 16.0,
            "{:?} for a truth reaching {truth}",
            ranged.used
        );
        let why = ranged.used.why();
        assert!(why.contains("(0.5 % of them nearer)"), "{why}");
        let given = Params::range(0, 80).unwrap();
        let ranged = choose(&pair.left, &pair.right, &given, &cancel).unwrap();
        assert_eq!(
            ranged.used,
            RangeUsed {
                min: 0,
                max: 80,
                chosen: Chosen::Given,
                start: None,
            }
        );
    }

    /// A scene near everywhere (disparities about 90–260 px) is searched from past 0 at the
    /// defaults, short of its farthest truth, and its range says why; a start given stands.
    #[test]
    fn a_scene_near_everywhere_is_searched_from_past_zero() {
        let pair = synthetic::render(&synthetic::nearer(640, 360, 5.0, 60.0));
        let least = pair.seen_truth().into_iter().fold(f32::MAX, f32::min);
        let cancel = AtomicBool::new(false);
        let ranged = choose(&pair.left, &pair.right, &Params::default(), &cancel).unwrap();
        assert!(
            ranged.used.min > 0 && (ranged.used.min as f32) < least,
            "{:?} for a truth from {least}",
            ranged.used
        );
        let why = ranged.used.why();
        assert!(why.contains("the start found from the pair too"), "{why}");
        let from_zero = Params::new(&crate::vision::Settings {
            min_disparity: Some(crate::vision::RangeEnd::Px(0)),
            ..Default::default()
        })
        .unwrap();
        let ranged = choose(&pair.left, &pair.right, &from_zero, &cancel).unwrap();
        assert_eq!((ranged.used.min, ranged.used.start), (0, None));
        // A stream's kept end one search past a given start: the start stands, the end is
        // held to one search from it.
        let below = Params::new(&crate::vision::Settings {
            min_disparity: Some(crate::vision::RangeEnd::Px(-32)),
            ..Default::default()
        })
        .unwrap()
        .at_least(MAX_DISPARITIES as i32);
        let ranged = choose(&pair.left, &pair.right, &below, &cancel).unwrap();
        assert_eq!(
            (ranged.used.min, ranged.used.max),
            (-32, MAX_DISPARITIES as i32 - 32)
        );
    }

    /// A given range that stops short is warned of by name, and the pixels past it refused:
    /// of those the matcher left with a disparity, none lies more than 2 px off the truth with
    /// σ_d under 1 px in more than 2 % of the image.
    #[test]
    fn a_short_range_is_named_and_its_pixels_refused() {
        let pair = near_scene();
        let cancel = AtomicBool::new(false);
        let given = Params::range(0, 80).unwrap();
        let ranged = choose(&pair.left, &pair.right, &given, &cancel).unwrap();
        let (mut map, _) =
            crate::vision::disparity(&pair.left, &pair.right, &ranged.params, &cancel).unwrap();
        let said = ranged.judge(&mut map, None);
        assert!(
            said.iter()
                .any(|s| s.starts_with("max_disparity 80 stops short")),
            "{said:?}"
        );
        let confident_wrong = map
            .data
            .iter()
            .zip(&map.std)
            .zip(pair.truth.iter().zip(&pair.visible))
            .filter(|((d, s), (t, seen))| {
                **seen && !d.is_nan() && **s < 1.0 && (**d - **t).abs() > 2.0
            })
            .count();
        let share = confident_wrong as f64 / map.data.len() as f64;
        assert!(share <= 0.02, "{:.1} % confidently wrong", share * 100.0);
    }
}
