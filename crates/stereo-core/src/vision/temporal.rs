//! The temporal filter of a stream's disparity maps, as librealsense's `temporal-filter` does it
//! in the disparity domain: each pixel's value averaged with its last one while the two agree
//! within δ (an exponential moving average of weight α), the new value taken where they do not
//! (motion), and a hole given its last value where the pixel's recent history is valid enough
//! (the persistence rule). σ_d follows what was averaged and what was carried.
//!
//! One rule is added to librealsense's: a hole never takes a last value nearer (larger) than
//! the farther of its row's nearest valid values by more than δ. A hole beside a near object is
//! usually what the object hides or has just uncovered, the background, so carrying the object's
//! old value into it would put the object where it no longer is.

use rayon::prelude::*;

use super::Disparity;

/// When a hole takes its pixel's last value: librealsense's persistence rules, over the
/// pixel's validity in the frames before this one (a frame counts as valid there when its value
/// agreed with the last within δ, or was the first).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Persistence {
    /// Never: holes stay holes.
    Off,
    /// Valid in each of the last 8 frames.
    ValidIn8Of8,
    /// Valid in 2 of the last 3.
    ValidIn2OfLast3,
    /// Valid in 2 of the last 4 (librealsense's default).
    #[default]
    ValidIn2OfLast4,
    /// Valid in 2 of the last 8.
    ValidIn2Of8,
    /// Valid in 1 of the last 2.
    ValidIn1OfLast2,
    /// Valid in 1 of the last 5.
    ValidIn1OfLast5,
    /// Valid in 1 of the last 8.
    ValidIn1Of8,
    /// Whenever the pixel has a last value.
    Always,
}

impl Persistence {
    /// Every rule, in librealsense's order (its `holes_fill` index 0 to 8).
    pub const ALL: [Persistence; 9] = [
        Persistence::Off,
        Persistence::ValidIn8Of8,
        Persistence::ValidIn2OfLast3,
        Persistence::ValidIn2OfLast4,
        Persistence::ValidIn2Of8,
        Persistence::ValidIn1OfLast2,
        Persistence::ValidIn1OfLast5,
        Persistence::ValidIn1Of8,
        Persistence::Always,
    ];

    /// The rule's name, as the API spells it.
    pub fn name(self) -> &'static str {
        match self {
            Persistence::Off => "off",
            Persistence::ValidIn8Of8 => "valid_8_of_8",
            Persistence::ValidIn2OfLast3 => "valid_2_of_last_3",
            Persistence::ValidIn2OfLast4 => "valid_2_of_last_4",
            Persistence::ValidIn2Of8 => "valid_2_of_8",
            Persistence::ValidIn1OfLast2 => "valid_1_of_last_2",
            Persistence::ValidIn1OfLast5 => "valid_1_of_last_5",
            Persistence::ValidIn1Of8 => "valid_1_of_8",
            Persistence::Always => "always",
        }
    }

    /// The rule a name spells.
    pub fn parse(name: &str) -> Option<Persistence> {
        Persistence::ALL.into_iter().find(|p| p.name() == name)
    }

    /// Whether a pixel whose validity in the frames before this one is `history` (bit 0 the
    /// frame just before, bit 1 the one before it, …) takes its last value.
    pub fn allows(self, history: u8) -> bool {
        let in_last = |frames: u32| (u32::from(history) & ((1 << frames) - 1)).count_ones();
        match self {
            Persistence::Off => false,
            Persistence::ValidIn8Of8 => history == u8::MAX,
            Persistence::ValidIn2OfLast3 => in_last(3) >= 2,
            Persistence::ValidIn2OfLast4 => in_last(4) >= 2,
            Persistence::ValidIn2Of8 => in_last(8) >= 2,
            Persistence::ValidIn1OfLast2 => in_last(2) >= 1,
            Persistence::ValidIn1OfLast5 => in_last(5) >= 1,
            Persistence::ValidIn1Of8 => in_last(8) >= 1,
            Persistence::Always => true,
        }
    }
}

/// The filter's settings. A value exists only when valid: [`Settings::new`] checks them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    alpha: f32,
    delta: f32,
    persistence: Persistence,
}

/// The default weight of the new value (librealsense's).
pub const DEFAULT_ALPHA: f32 = 0.4;
/// The default largest change, in pixels of disparity, that is taken for noise rather than
/// motion: several times the σ_d of a textured surface (0.1–0.3 px), below the step at an
/// object's edge.
pub const DEFAULT_DELTA: f32 = 1.0;

/// What is wrong with asked settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// α must lie in (0, 1].
    Alpha,
    /// δ must be positive and finite.
    Delta,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            alpha: DEFAULT_ALPHA,
            delta: DEFAULT_DELTA,
            persistence: Persistence::default(),
        }
    }
}

impl Settings {
    /// Settings from α (the new value's weight, in (0, 1]; 1 averages nothing), δ (pixels of
    /// disparity, positive) and the persistence rule; every fault named.
    pub fn new(alpha: f32, delta: f32, persistence: Persistence) -> Result<Settings, Vec<Fault>> {
        let mut faults = Vec::new();
        if !(alpha > 0.0 && alpha <= 1.0) {
            faults.push(Fault::Alpha);
        }
        if !(delta > 0.0 && delta.is_finite()) {
            faults.push(Fault::Delta);
        }
        if faults.is_empty() {
            Ok(Settings {
                alpha,
                delta,
                persistence,
            })
        } else {
            Err(faults)
        }
    }

    pub fn alpha(&self) -> f32 {
        self.alpha
    }

    pub fn delta(&self) -> f32 {
        self.delta
    }

    pub fn persistence(&self) -> Persistence {
        self.persistence
    }
}

/// What one frame's filtering did, counted in pixels.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    /// Values averaged with their last one.
    pub averaged: usize,
    /// Values taken as they came (no last value, or a change beyond δ).
    pub taken: usize,
    /// Holes given their last value.
    pub carried: usize,
}

/// The filter's state between the frames of one stream: each pixel's last value, its σ_d's
/// square, and its validity over the last 8 frames. Memory: 9 bytes a pixel.
#[derive(Debug, Clone)]
pub struct Temporal {
    settings: Settings,
    width: usize,
    height: usize,
    last: Vec<f32>,
    variance: Vec<f32>,
    history: Vec<u8>,
}

/// The bytes a pixel of a [`Temporal`]'s state takes.
pub const BYTES_A_PIXEL: usize = 9;

impl Temporal {
    /// A filter that has seen no frame yet.
    pub fn new(settings: Settings) -> Temporal {
        Temporal {
            settings,
            width: 0,
            height: 0,
            last: Vec::new(),
            variance: Vec::new(),
            history: Vec::new(),
        }
    }

    pub fn settings(&self) -> Settings {
        self.settings
    }

    /// Filters `map` in place, the stream's next frame, and keeps what the next one needs. A
    /// frame of another size starts the history again. Carried values are marked in
    /// `map.filled` (made, all false, if the map had none).
    pub fn apply(&mut self, map: &mut Disparity) -> Counts {
        let n = map.width * map.height;
        if (map.width, map.height) != (self.width, self.height) || self.last.len() != n {
            self.width = map.width;
            self.height = map.height;
            self.last = vec![f32::NAN; n];
            self.variance = vec![f32::NAN; n];
            self.history = vec![0; n];
        }
        if map.filled.len() != n {
            map.filled = vec![false; n];
        }
        let w = map.width.max(1);
        let settings = self.settings;
        map.data
            .par_chunks_mut(w)
            .zip(map.std.par_chunks_mut(w))
            .zip(map.filled.par_chunks_mut(w))
            .zip(self.last.par_chunks_mut(w))
            .zip(self.variance.par_chunks_mut(w))
            .zip(self.history.par_chunks_mut(w))
            .with_min_len(ROWS_A_TASK)
            .map(|(((((data, std), filled), last), variance), history)| {
                let row = Row {
                    data,
                    std,
                    filled,
                    last,
                    variance,
                    history,
                };
                row.apply(settings)
            })
            .reduce(Counts::default, |a, b| Counts {
                averaged: a.averaged + b.averaged,
                taken: a.taken + b.taken,
                carried: a.carried + b.carried,
            })
    }
}

/// The rows a task of the filter takes at least: a row is a few microseconds.
const ROWS_A_TASK: usize = 16;

/// One row of a frame and of the filter's state.
struct Row<'a> {
    data: &'a mut [f32],
    std: &'a mut [f32],
    filled: &'a mut [bool],
    last: &'a mut [f32],
    variance: &'a mut [f32],
    history: &'a mut [u8],
}

impl Row<'_> {
    /// Filters the row ([`Temporal::apply`]).
    fn apply(self, settings: Settings) -> Counts {
        let Settings {
            alpha,
            delta,
            persistence,
        } = settings;
        let mut counts = Counts::default();
        // The farther (smaller) of each hole's nearest valid values left and right in this
        // frame's row, as it came in (Middlebury's fill): the most a carried value may exceed
        // it by is δ.
        let mut background = self.data.to_vec();
        let width = background.len().max(1);
        super::filters::fill(&mut background, width);
        for (i, &bg) in background.iter().enumerate() {
            let value = self.data[i];
            let last = self.last[i];
            let earlier = self.history[i];
            if value.is_finite() {
                let sigma = self.std[i];
                let agrees = last.is_finite() && (value - last).abs() < delta;
                if agrees {
                    let v = alpha * value + (1.0 - alpha) * last;
                    // The σ of an average of errors that are not independent: consecutive
                    // frames of a still scene share their texture, their lighting and most of
                    // their matching error, so σ is the weighted mean of the two σs, not the
                    // independent errors' α²σ² + (1 − α)²σ_last², which would claim a σ the
                    // values do not hold (docs/live.md, "σ_d of an average").
                    let mixed = alpha * sigma + (1.0 - alpha) * self.variance[i].sqrt();
                    let var = mixed * mixed;
                    self.data[i] = v;
                    self.std[i] = var.sqrt();
                    self.last[i] = v;
                    self.variance[i] = var;
                    counts.averaged += 1;
                } else {
                    self.last[i] = value;
                    self.variance[i] = sigma * sigma;
                    counts.taken += 1;
                }
                // A jump is motion: the pixel is not yet steady there (librealsense's).
                let steady = agrees || !last.is_finite();
                self.history[i] = (earlier << 1) | u8::from(steady);
            } else {
                let fits = bg.is_nan() || last <= bg + delta;
                if last.is_finite() && fits && persistence.allows(earlier) {
                    self.data[i] = last;
                    self.std[i] = self.variance[i].sqrt();
                    self.filled[i] = true;
                    counts.carried += 1;
                }
                self.history[i] = earlier << 1;
            }
        }
        counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(values: &[f32], stds: &[f32]) -> Disparity {
        Disparity {
            width: values.len(),
            height: 1,
            data: values.to_vec(),
            std: stds.to_vec(),
            filled: Vec::new(),
            blank: Vec::new(),
        }
    }

    /// Within δ the value is the average of weight α, and σ_d is ασ + (1 − α)σ_last;
    /// beyond δ the new value and its σ are taken as they came.
    #[test]
    fn values_within_delta_are_averaged_and_jumps_taken() {
        let mut f = Temporal::new(Settings::new(0.25, 1.0, Persistence::Off).unwrap());
        let mut first = map(&[10.0, 20.0], &[0.4, 0.4]);
        assert_eq!(
            f.apply(&mut first),
            Counts {
                taken: 2,
                ..Counts::default()
            }
        );
        assert_eq!(first.data, [10.0, 20.0]);
        let mut second = map(&[10.8, 25.0], &[0.2, 0.3]);
        let counts = f.apply(&mut second);
        assert_eq!((counts.averaged, counts.taken), (1, 1));
        assert!((second.data[0] - (0.25 * 10.8 + 0.75 * 10.0)).abs() < 1e-6);
        assert!((second.std[0] - (0.25 * 0.2 + 0.75 * 0.4)).abs() < 1e-6);
        assert_eq!((second.data[1], second.std[1]), (25.0, 0.3));
        // The average is what the next frame is compared with.
        let mut third = map(&[10.2 + 0.99, 25.0], &[0.2, 0.3]);
        f.apply(&mut third);
        let last = 0.25 * 10.8 + 0.75 * 10.0;
        assert!((third.data[0] - (0.25 * (10.2 + 0.99) + 0.75 * last)).abs() < 1e-5);
        assert!(third.filled.iter().all(|&c| !c));
    }

    /// Each persistence rule against librealsense's definition, on every 8-frame history.
    #[test]
    fn persistence_rules_count_the_valid_frames() {
        for history in 0..=u8::MAX {
            let last = |k: u32| (history as u32 & ((1 << k) - 1)).count_ones();
            let expected = [
                false,
                history == 255,
                last(3) >= 2,
                last(4) >= 2,
                history.count_ones() >= 2,
                last(2) >= 1,
                last(5) >= 1,
                history != 0,
                true,
            ];
            for (rule, want) in Persistence::ALL.into_iter().zip(expected) {
                assert_eq!(rule.allows(history), want, "{rule:?} {history:08b}");
            }
        }
        for rule in Persistence::ALL {
            assert_eq!(Persistence::parse(rule.name()), Some(rule));
        }
        assert_eq!(Persistence::parse("valid_3_of_8"), None);
    }

    /// A hole takes its last value, marked filled, with the last σ, when its history meets the
    /// rule; one more hole and it does not (valid in 2 of the last 3).
    #[test]
    fn holes_take_their_last_value_as_persistence_allows() {
        let mut f = Temporal::new(Settings::new(0.5, 1.0, Persistence::ValidIn2OfLast3).unwrap());
        let nan = f32::NAN;
        f.apply(&mut map(&[8.0, 8.0], &[0.2, 0.2]));
        f.apply(&mut map(&[8.0, 8.0], &[0.2, 0.2]));
        let mut hole = map(&[8.0, nan], &[0.2, nan]);
        assert_eq!(f.apply(&mut hole).carried, 1);
        assert_eq!(hole.data[1], 8.0);
        assert!(hole.filled[1] && !hole.filled[0]);
        assert!((hole.std[1] - 0.2).abs() < 1e-6);
        // History now valid, valid, hole: 2 of the last 3 still.
        let mut again = map(&[8.0, nan], &[0.2, nan]);
        assert_eq!(f.apply(&mut again).carried, 1);
        // Valid, hole, hole: 1 of the last 3.
        let mut gone = map(&[8.0, nan], &[0.2, nan]);
        assert_eq!(f.apply(&mut gone).carried, 0);
        assert!(gone.data[1].is_nan() && !gone.filled[1]);
        // Off never carries.
        let mut off = Temporal::new(Settings::new(0.5, 1.0, Persistence::Off).unwrap());
        off.apply(&mut map(&[8.0], &[0.2]));
        let mut hole = map(&[nan], &[nan]);
        assert_eq!(off.apply(&mut hole).carried, 0);
    }

    /// A jump clears the pixel's steadiness: a hole right after motion is not carried where
    /// the rule wants two steady frames.
    #[test]
    fn a_jump_is_not_steady_history() {
        let mut f = Temporal::new(Settings::new(0.5, 1.0, Persistence::ValidIn2OfLast3).unwrap());
        let nan = f32::NAN;
        f.apply(&mut map(&[8.0], &[0.2]));
        f.apply(&mut map(&[20.0], &[0.2]));
        let mut hole = map(&[nan], &[nan]);
        assert_eq!(f.apply(&mut hole).carried, 0);
    }

    /// A hole whose last value is nearer than its row's farther valid neighbour by more than δ
    /// (a near object moved away, uncovering the background) stays a hole; one at the
    /// background's level is carried.
    #[test]
    fn a_hole_never_takes_a_nearer_objects_old_value() {
        let nan = f32::NAN;
        let mut f = Temporal::new(Settings::new(0.5, 1.0, Persistence::Always).unwrap());
        // Background at 5, an object at 30 over pixels 2..4.
        f.apply(&mut map(&[5.0, 5.0, 30.0, 30.0, 5.0], &[0.2; 5]));
        // The object moved right: pixels 2 and 3 are holes, 4 shows it.
        let mut moved = map(&[5.0, 5.0, nan, nan, 30.0], &[0.2, 0.2, nan, nan, 0.2]);
        assert_eq!(f.apply(&mut moved).carried, 0);
        assert!(moved.data[2].is_nan() && moved.data[3].is_nan());
        // A hole on the background keeps the background's value.
        let mut g = Temporal::new(Settings::new(0.5, 1.0, Persistence::Always).unwrap());
        g.apply(&mut map(&[5.0, 5.2, 5.4, 30.0], &[0.2; 4]));
        let mut hole = map(&[5.0, nan, 5.4, 30.0], &[0.2, nan, 0.2, 0.2]);
        assert_eq!(g.apply(&mut hole).carried, 1);
        assert_eq!(hole.data[1], 5.2);
    }

    /// A frame of another size starts again: nothing is averaged with or carried from the
    /// old size's pixels.
    #[test]
    fn another_size_starts_again() {
        let mut f = Temporal::new(Settings::default());
        f.apply(&mut map(&[8.0, 8.0], &[0.2, 0.2]));
        let mut bigger = map(&[8.5, 8.5, 8.5], &[0.2; 3]);
        let counts = f.apply(&mut bigger);
        assert_eq!((counts.averaged, counts.taken), (0, 3));
        assert_eq!(bigger.data, [8.5, 8.5, 8.5]);
    }

    /// α outside (0, 1] and δ not positive are each named.
    #[test]
    fn settings_name_each_fault() {
        assert_eq!(
            Settings::new(0.0, -1.0, Persistence::Off),
            Err(vec![Fault::Alpha, Fault::Delta])
        );
        assert_eq!(
            Settings::new(1.5, f32::INFINITY, Persistence::Off),
            Err(vec![Fault::Alpha, Fault::Delta])
        );
        assert_eq!(
            Settings::new(f32::NAN, 1.0, Persistence::Off),
            Err(vec![Fault::Alpha])
        );
        assert!(Settings::new(1.0, 0.5, Persistence::Always).is_ok());
        let d = Settings::default();
        assert_eq!(
            (d.alpha(), d.delta(), d.persistence()),
            (0.4, 1.0, Persistence::ValidIn2OfLast4)
        );
    }
}

#[cfg(test)]
mod sequence {
    use std::sync::atomic::AtomicBool;

    use super::*;
    use crate::vision::synthetic::{self, Region};
    use crate::vision::{Params, Preset};

    /// What a sequence of maps scored against its truth.
    #[derive(Debug)]
    struct Score {
        /// RMS of the frame-to-frame changes under 1 px where the truth did not change: the
        /// noise's flicker (a change over 1 px is a wrong match in one of the two frames, which
        /// `jumps` and `bad1` count).
        flicker: f64,
        /// The median frame-to-frame change there.
        median_change: f64,
        /// Share of those changes over 1 px, %.
        jumps: f64,
        /// Middlebury's bad-1.0 over the pixels both cameras see, holes filled from their row's
        /// background (as `scripts/evaluations/scoring.py` scores), %.
        bad1: f64,
        /// The share of those pixels with a value, %.
        density: f64,
    }

    /// `frames` renders of the layered scene, each with fresh sensor noise (σ 2 % of full
    /// scale); with `moving`, the box slides 2 px a frame and the disc 1 px a frame, coming
    /// nearer by 0.5 px of disparity a frame.
    fn sequence(frames: usize, moving: bool) -> Vec<synthetic::Pair> {
        (0..frames)
            .map(|t| {
                let mut scene = synthetic::layered(160, 120);
                scene.noise = 0.02;
                scene.seed = 100 + t as u64;
                if moving {
                    let s = t as f32;
                    if let Region::Rect { x0, x1, .. } = &mut scene.planes[1].region {
                        *x0 += 2.0 * s;
                        *x1 += 2.0 * s;
                    }
                    if let Region::Disc { cx, .. } = &mut scene.planes[2].region {
                        *cx -= s;
                    }
                    scene.planes[2].disparity[0] += 0.5 * s;
                }
                synthetic::render(&scene)
            })
            .collect()
    }

    /// Each pair matched (`preset=fast`, 48 disparities), in order through the filter when
    /// given.
    fn matched(pairs: &[synthetic::Pair], filter: Option<Settings>) -> Vec<Disparity> {
        let params = Params::new(&crate::vision::Settings {
            max_disparity: Some(crate::vision::RangeEnd::Px(48)),
            preset: Some(Preset::Fast),
            ..Default::default()
        })
        .unwrap();
        let never = AtomicBool::new(false);
        let mut temporal = filter.map(Temporal::new);
        pairs
            .iter()
            .map(|pair| {
                let (mut map, _) =
                    crate::vision::disparity(&pair.left, &pair.right, &params, &never).unwrap();
                if let Some(t) = temporal.as_mut() {
                    t.apply(&mut map);
                }
                map
            })
            .collect()
    }

    /// Scores the pairs' maps, through the filter when given.
    fn score(pairs: &[synthetic::Pair], filter: Option<Settings>) -> Score {
        let maps = matched(pairs, filter);
        let mut changes = Vec::new();
        let (mut off, mut valued, mut seen) = (0usize, 0usize, 0usize);
        for (t, (map, pair)) in maps.iter().zip(pairs).enumerate() {
            let mut filled = map.data.clone();
            crate::vision::filters::fill(&mut filled, map.width);
            for (i, (&d, &shown)) in map.data.iter().zip(&filled).enumerate() {
                if !pair.visible[i] {
                    continue;
                }
                seen += 1;
                valued += usize::from(d.is_finite());
                // NaN (a row with no value) counts as off.
                let right = (shown - pair.truth[i]).abs() <= 1.0;
                off += usize::from(!right);
                if t > 0 {
                    let (p, then) = (maps[t - 1].data[i], &pairs[t - 1]);
                    let still = then.visible[i] && then.truth[i] == pair.truth[i];
                    if still && p.is_finite() && d.is_finite() {
                        changes.push(f64::from((d - p).abs()));
                    }
                }
            }
        }
        let small: Vec<f64> = changes.iter().copied().filter(|&c| c <= 1.0).collect();
        changes.sort_by(f64::total_cmp);
        Score {
            flicker: (small.iter().map(|c| c * c).sum::<f64>() / small.len() as f64).sqrt(),
            median_change: changes[changes.len() / 2],
            jumps: 100.0 * (changes.len() - small.len()) as f64 / changes.len() as f64,
            bad1: 100.0 * off as f64 / seen as f64,
            density: 100.0 * valued as f64 / seen as f64,
        }
    }

    /// On a rendered sequence with sensor noise, the default filter cuts the frame-to-frame
    /// flicker of static surfaces at least 2 × (its RMS and its median), bad-1.0 does not rise
    /// beside the unfiltered stream and density does not fall, on a still scene and on one
    /// whose objects move (their edges included). Measured (`--nocapture` prints them): RMS
    /// flicker 0.127 → 0.043 px still and 0.129 → 0.046 moving, bad-1.0 1.30 → 1.30 % and
    /// 0.700 → 0.698 %; changes over 1 px on still surfaces 0.015 → 0.014 % and 0.055 → 0.088 %
    /// (holes carried next to the moving edges, reported, not floored).
    #[test]
    fn flicker_falls_and_errors_do_not_rise() {
        for moving in [false, true] {
            let pairs = sequence(8, moving);
            let raw = score(&pairs, None);
            let filtered = score(&pairs, Some(Settings::default()));
            let what = format!(
                "moving {moving}: changes over 1 px {:.3} → {:.3} %; raw {raw:?}, filtered {filtered:?}",
                raw.jumps, filtered.jumps
            );
            eprintln!("{what}");
            assert!(raw.flicker >= 2.0 * filtered.flicker, "{what}");
            assert!(raw.median_change >= 2.0 * filtered.median_change, "{what}");
            assert!(filtered.bad1 <= raw.bad1, "{what}");
            assert!(filtered.density >= raw.density, "{what}");
        }
    }

    /// Each frame's share of valued pixels both cameras see whose value lies within 1σ and 2σ
    /// of the truth, %.
    fn within_sigma(pairs: &[synthetic::Pair], filter: Settings) -> Vec<(f64, f64)> {
        matched(pairs, Some(filter))
            .iter()
            .zip(pairs)
            .map(|(map, pair)| {
                let (mut n, mut one, mut two) = (0usize, 0usize, 0usize);
                for (i, (&d, &s)) in map.data.iter().zip(&map.std).enumerate() {
                    if !pair.visible[i] || !d.is_finite() {
                        continue;
                    }
                    let off = (d - pair.truth[i]).abs();
                    n += 1;
                    one += usize::from(off <= s);
                    two += usize::from(off <= 2.0 * s);
                }
                (100.0 * one as f64 / n as f64, 100.0 * two as f64 / n as f64)
            })
            .collect()
    }

    /// σ_d still holds after the filter: in every frame of the still and the moving sequence,
    /// at least 75 % of the filtered values lie within 1σ of the truth and 90 % within 2σ (a
    /// normal error gives 68 and 95 %; single frames measure 84 and 99 %). Measured
    /// (`--nocapture`): 87.8 / 99.4 % still, 81–85 / 92–98 % moving. The independent errors'
    /// formula, α²σ² + (1 − α)²σ_last², gave 59 / 88 % here: frames share their errors.
    #[test]
    fn sigma_holds_after_the_filter() {
        for moving in [false, true] {
            let pairs = sequence(8, moving);
            let shares = within_sigma(&pairs, Settings::default());
            eprintln!("moving {moving}: within 1σ, 2σ per frame {shares:.1?}");
            for (t, &(one, two)) in shares.iter().enumerate() {
                assert!(
                    one >= 75.0,
                    "moving {moving}, frame {t}: {one:.1} % within 1σ"
                );
                assert!(
                    two >= 90.0,
                    "moving {moving}, frame {t}: {two:.1} % within 2σ"
                );
            }
        }
    }
}
