//! The range a pair needs, found before it is matched: the pair is matched on a coarse level
//! (a quarter or an eighth of its size) over a wide range of both signs, and what that level
//! matched says how far the scene's disparities reach ([`Survey::needs`]), whether the cameras
//! look swapped (most matches at negative disparities, [`Survey::swapped`]), and which pixels
//! lie beyond a range that stops short ([`refuse`]).
//!
//! The coarse level costs a few per cent of the full match: at a quarter of the size a pixel
//! stands for 16, and the matcher's own pyramid keeps its cells per pixel bounded whatever the
//! range.

use std::sync::atomic::AtomicBool;

use super::{Cancelled, Disparity, Gray, Params, Settings, census, pyramid};

/// The most disparities a found range holds, whatever the image: [`super::MAX_DISPARITIES`].
pub const CEILING: usize = super::MAX_DISPARITIES;
/// How many times more of the pair must match the other way round for it to look swapped.
pub const SWAPPED_GAIN: f64 = 1.5;
/// The coarse level is at least this many pixels wide (when the image is).
const COARSE_WIDTH: usize = 160;
/// … and this many rows tall.
const COARSE_HEIGHT: usize = 90;
/// The most times the pair is halved for the survey.
const MAX_LEVELS: usize = 3;
/// The share of the coarse pixels that must match for the survey to speak (of the range, of
/// pixels past a range, of swapped cameras): a pair that matches less is not a rectified pair
/// of one scene (raw frames, a wrong image), and what its few matches say is noise.
pub const MIN_MATCHED: f64 = 0.2;
/// The quantile of the matched disparities taken as the scene's nearest: the few pixels past
/// it are either mismatches or refused by the range's end ([`refuse`]).
pub const NEAR_QUANTILE: f64 = 0.995;
/// The quantile of the matched disparities taken as the scene's farthest, where the range's
/// start is found ([`Survey::needs`]).
pub const FAR_QUANTILE: f64 = 0.005;
/// Of the matches at least a coarse pixel from zero, the share at negative disparities past
/// which the cameras look swapped.
pub const SWAPPED_SHARE: f64 = 0.6;

/// What the coarse level matched, in full-size pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct Survey {
    /// How many times the pair was halved: a coarse pixel is `2^levels` full-size pixels.
    pub levels: usize,
    /// The share of the coarse pixels with something to match (their window reaching no blank
    /// pixel) that matched.
    pub matched: f64,
    /// The same share matched the other way round (right as left), when that was tried.
    pub reversed: Option<f64>,
    /// The [`NEAR_QUANTILE`] of the positive matches, and their greatest.
    pub near: f32,
    pub greatest: f32,
    /// The [`FAR_QUANTILE`] of the matches right of the nearest's width (full-size px).
    pub far: f32,
    /// The share, of the matches a coarse pixel or more from zero, at negative disparities,
    /// and their median (full-size px; 0 when none).
    pub negative: f64,
    pub negative_median: f32,
    /// The coarse map (disparities in coarse pixels).
    map: Disparity,
}

/// The coarse level of a `width × height` pair: halved while it stays at least
/// [`COARSE_WIDTH`] × [`COARSE_HEIGHT`], at most [`MAX_LEVELS`] times.
pub fn levels(width: usize, height: usize) -> usize {
    let mut n = 0;
    while n < MAX_LEVELS && width >> (n + 1) >= COARSE_WIDTH && height >> (n + 1) >= COARSE_HEIGHT {
        n += 1;
    }
    n
}

/// The widest range the survey searches either way, in full-size pixels: half the image's
/// width (a match further off leaves less than half the image seen by both cameras), at most
/// [`CEILING`], a multiple of 16.
pub fn reach(width: usize) -> usize {
    (width / 2)
        .div_ceil(16)
        .saturating_mul(16)
        .clamp(16, CEILING)
}

/// The pair matched on its coarse level over `−reach/4 .. reach` ([`reach`]: a quarter of the
/// negative side, for pairs whose disparities dip below zero; a search as wide on both sides
/// leaves near objects unmatched on the coarse level's few pixels), and when that matched
/// little or much of it negative, matched again the other way round (right as left), to tell
/// swapped cameras. `None` for a pair too small to halve and match.
pub fn survey(left: &Gray, right: &Gray, cancel: &AtomicBool) -> Result<Option<Survey>, Cancelled> {
    let levels = levels(left.width, left.height);
    // Halved from the caller's images: no copy of the full-size pair.
    let mut halved: Option<(Gray, Gray)> = None;
    for _ in 0..levels {
        let (l, r) = halved.as_ref().map_or((left, right), |(l, r)| (l, r));
        halved = Some(rayon::join(|| pyramid::halve(l), || pyramid::halve(r)));
    }
    let (l, r) = halved.as_ref().map_or((left, right), |(l, r)| (l, r));
    let scale = 1i32 << levels;
    let coarse_reach = (reach(left.width).div_ceil(scale as usize) as i32).max(8);
    let Ok(params) = Params::new(&Settings {
        min_disparity: Some(super::RangeEnd::Px(-coarse_reach / 4)),
        max_disparity: Some(super::RangeEnd::Px(coarse_reach)),
        median: Some(false),
        speckle_size: Some((100 >> (2 * levels)).max(4) as u32),
        ..Settings::default()
    }) else {
        return Ok(None);
    };
    let params = Params {
        plane: false,
        ..params
    };
    let (mut map, _) = super::disparity(l, r, &params, cancel)?;
    let seen = seeing(&mut map);
    let mut survey = Survey::of(map, levels, seen);
    if survey.matched < SUSPECT_MATCHED || survey.negative >= 1.0 - SWAPPED_SHARE {
        let (mut reversed, _) = super::disparity(r, l, &params, cancel)?;
        let seen = seeing(&mut reversed);
        let valid = reversed.data.iter().filter(|d| !d.is_nan()).count();
        survey.reversed = Some(valid as f64 / seen.max(1) as f64);
    }
    Ok(Some(survey))
}

/// Empties the coarse `map`'s pixels whose census window reaches one of its blank pixels (as
/// the matcher judged them, [`census::blank`]): the blank ones matched nothing, and the edge of
/// a blank region is a straight line along which a window ties (the scene's texture beside a
/// fisheye's black surround, halved into a ramp). Answers how many pixels are left to speak.
fn seeing(map: &mut Disparity) -> usize {
    let (w, h) = (map.width, map.height);
    if map.blank.len() != w * h {
        return w * h;
    }
    let blank = std::mem::take(&mut map.blank);
    let (rx, ry) = (census::WIDTH / 2, census::HEIGHT / 2);
    // Along the rows, then down the columns.
    let mut near = vec![false; w * h];
    for (out, row) in near.chunks_mut(w.max(1)).zip(blank.chunks(w.max(1))) {
        for (x, o) in out.iter_mut().enumerate() {
            *o = row[x.saturating_sub(rx)..(x + rx + 1).min(w)].contains(&true);
        }
    }
    let mut seen = 0;
    for y in 0..h {
        for x in 0..w {
            let touches = (y.saturating_sub(ry)..(y + ry + 1).min(h)).any(|v| near[v * w + x]);
            if touches {
                map.data[y * w + x] = f32::NAN;
                map.std[y * w + x] = f32::NAN;
            } else {
                seen += 1;
            }
        }
    }
    seen
}

/// Below this share of its coarse pixels matched, a pair is matched the other way round too
/// ([`survey`]).
pub const SUSPECT_MATCHED: f64 = 0.5;

impl Survey {
    /// What a coarse map matched says.
    fn of(map: Disparity, levels: usize, seen: usize) -> Survey {
        let scale = (1i32 << levels) as f32;
        let valid: Vec<f32> = map.data.iter().copied().filter(|d| !d.is_nan()).collect();
        let matched = valid.len() as f64 / seen.max(1) as f64;

        let mut positive: Vec<f32> = valid.iter().copied().filter(|&d| d >= 0.0).collect();
        positive.sort_by(f32::total_cmp);
        let near = quantile(&positive, NEAR_QUANTILE) * scale;
        // The farthest from the columns the right camera sees at every disparity up to the
        // nearest (left of them a pixel has no match, and the coarse level puts a mismatch there).
        let seen_from = (near / scale).ceil().max(0.0) as usize;
        let mut seen: Vec<f32> = map
            .data
            .chunks(map.width.max(1))
            .flat_map(|row| row.iter().skip(seen_from))
            .copied()
            .filter(|d| !d.is_nan())
            .collect();
        seen.sort_by(f32::total_cmp);
        let far = quantile(&seen, FAR_QUANTILE) * scale;
        let greatest = positive.last().copied().unwrap_or(0.0) * scale;
        let mut negatives: Vec<f32> = valid.iter().copied().filter(|&d| d <= -1.0).collect();
        let away = valid.iter().filter(|d| d.abs() >= 1.0).count();
        let negative = negatives.len() as f64 / away.max(1) as f64;
        negatives.sort_by(f32::total_cmp);
        let negative_median = quantile(&negatives, 0.5) * scale;
        Survey {
            levels,
            matched,
            reversed: None,
            near,
            greatest,
            far,
            negative,
            negative_median,
            map,
        }
    }

    /// Whether enough of the pair matched ([`MIN_MATCHED`]) to speak of its range.
    pub fn usable(&self) -> bool {
        self.matched >= MIN_MATCHED
    }

    /// The range `(min, max)` (exclusive) the scene needs: to the scene's nearest
    /// ([`NEAR_QUANTILE`]) with a margin of two coarse pixels and a tenth, rounded up to 16;
    /// from `min` where one is given, else from the scene's farthest ([`FAR_QUANTILE`]) less
    /// the same margin, rounded down to 16 and never below 0 (a scene that reaches far starts
    /// at 0); at least 16 disparities. `Err` with that range when it holds more than
    /// [`CEILING`].
    pub fn needs(&self, min: Option<i32>) -> Result<(i32, i32), (i32, i32)> {
        let coarse = 2.0 * (1u32 << self.levels) as f32;
        let max = ((self.near + coarse + 0.1 * self.near).max(16.0) / 16.0).ceil() as i32 * 16;
        let found = ((self.far - coarse - 0.1 * self.far.abs()) / 16.0).floor() as i32 * 16;
        let min = min.unwrap_or_else(|| found.clamp(0, max - 16));
        let max = max.max(min + 16);
        if (max - min) as usize > CEILING {
            Err((min, max))
        } else {
            Ok((min, max))
        }
    }

    /// Whether the left image looks like the right camera's: most matches at negative
    /// disparities ([`SWAPPED_SHARE`], at least two coarse pixels from zero), or the pair
    /// matched the other way round matching far more of it ([`SWAPPED_GAIN`]).
    pub fn swapped(&self) -> bool {
        let negative = self.usable()
            && self.negative >= SWAPPED_SHARE
            && self.negative_median <= -2.0 * (1u32 << self.levels) as f32;
        let reversed = self
            .reversed
            .is_some_and(|r| r >= MIN_MATCHED && r >= SWAPPED_GAIN * self.matched);
        negative || reversed
    }

    /// Whether the coarse level puts the full-size pixel `(x, y)` past `max`, by a coarse pixel
    /// or more (within one, its rounding may put a pixel just inside the range there).
    pub fn past(&self, (x, y): (usize, usize), max: i32) -> bool {
        if !self.usable() {
            return false;
        }
        let scale = (1u32 << self.levels) as f32;
        self.map.data[self.coarse_at((x, y))] >= max as f32 / scale + 1.0
    }

    /// The index in the coarse map of the coarse pixel holding the full-size pixel `(x, y)`.
    pub fn coarse_at(&self, (x, y): (usize, usize)) -> usize {
        let (cw, ch) = (self.map.width, self.map.height);
        ((y >> self.levels).min(ch - 1)) * cw + (x >> self.levels).min(cw - 1)
    }

    /// The share of the coarse pixels whose match lies past `max` (full-size px) by a coarse
    /// pixel or more.
    pub fn beyond(&self, max: i32) -> f64 {
        if !self.usable() {
            return 0.0;
        }
        let scale = (1u32 << self.levels) as f32;
        let past = self
            .map
            .data
            .iter()
            .filter(|&&d| d >= max as f32 / scale + 1.0)
            .count();
        past as f64 / self.map.data.len().max(1) as f64
    }
}

/// Which coarse pixels lie at or past `max` (coarse px): those matched there, and the holes
/// between two such matches along their row or their column (a near object's pixels that
/// the coarse level's checks left empty).
fn past_map(map: &Disparity, max: f32) -> Vec<bool> {
    let (w, h) = (map.width, map.height);
    // For each pixel, whether the nearest match before it (along the line) is past.
    let mut past: Vec<bool> = map.data.iter().map(|&d| d >= max).collect();
    let line = |cells: &[usize]| -> Vec<bool> {
        let mut before = vec![false; cells.len()];
        let mut last = false;
        for (i, &c) in cells.iter().enumerate() {
            let d = map.data[c];
            if !d.is_nan() {
                last = d >= max;
            }
            before[i] = last;
        }
        let mut both = vec![false; cells.len()];
        last = false;
        for (i, &c) in cells.iter().enumerate().rev() {
            let d = map.data[c];
            if !d.is_nan() {
                last = d >= max;
            }
            both[i] = d.is_nan() && last && before[i];
        }
        both
    };
    for y in 0..h {
        let cells: Vec<usize> = (0..w).map(|x| y * w + x).collect();
        for (c, hole) in cells.iter().zip(line(&cells)) {
            past[*c] |= hole;
        }
    }
    for x in 0..w {
        let cells: Vec<usize> = (0..h).map(|y| y * w + x).collect();
        for (c, hole) in cells.iter().zip(line(&cells)) {
            past[*c] |= hole;
        }
    }
    past
}

/// `past` grown into the holes of `map` it touches (4-connected): where a given range stops
/// short, a near object's pixels the coarse level left empty (a chessboard's repeated squares
/// match at several disparities) lie past the range with the matched ones around them.
/// The holes are grown from the pixels clearly past it only (at `clear` coarse px or more, two
/// past the range's end), not from those the coarse level's rounding puts there.
fn flood(map: &Disparity, past: &mut [bool], clear: f32) {
    let (w, h) = (map.width, map.height);
    let mut stack: Vec<usize> = (0..w * h).filter(|&i| map.data[i] >= clear).collect();
    while let Some(i) = stack.pop() {
        for j in crate::grid::four_neighbours(i, w, h) {
            if !past[j] && map.data[j].is_nan() {
                past[j] = true;
                stack.push(j);
            }
        }
    }
}

/// Marks as past the coarse level's smooth regions (4-connected matches within a coarse pixel
/// of each other) that the pixels past the range mostly enclose ([`ENCLOSED_SHARE`] of their
/// border): where a given range stops short, a chessboard's or a fence's repeated pattern
/// matches one period off, inside the range, on patches of a near surface whose rest lies
/// past it. A far surface seen only through holes in a near one is refused with it: with
/// a range that stops short, a pixel left empty is better than one answered wrong.
fn enclosed(map: &Disparity, past: &mut [bool]) {
    let (w, h) = (map.width, map.height);
    let mut label = vec![usize::MAX; w * h];
    let mut regions: Vec<Vec<usize>> = Vec::new();
    for seed in 0..w * h {
        if past[seed] || map.data[seed].is_nan() || label[seed] != usize::MAX {
            continue;
        }
        let id = regions.len();
        label[seed] = id;
        let mut region = vec![seed];
        let mut next = 0;
        while next < region.len() {
            let i = region[next];
            next += 1;
            for j in crate::grid::four_neighbours(i, w, h) {
                if label[j] == usize::MAX && !past[j] && (map.data[j] - map.data[i]).abs() <= 1.0 {
                    label[j] = id;
                    region.push(j);
                }
            }
        }
        regions.push(region);
    }
    for (id, region) in regions.iter().enumerate() {
        let (mut border, mut by_past) = (0usize, 0usize);
        for &i in region {
            let (x, y) = (i % w, i / w);
            // The image's edge counts as border not past: the region may go on beyond it.
            border += usize::from(x == 0) + usize::from(x + 1 == w);
            border += usize::from(y == 0) + usize::from(y + 1 == h);
            for j in crate::grid::four_neighbours(i, w, h) {
                if label[j] != id {
                    border += 1;
                    by_past += usize::from(past[j]);
                }
            }
        }
        if by_past as f64 >= ENCLOSED_SHARE * border as f64 {
            for &i in region {
                past[i] = true;
            }
        }
    }
}

/// The share of a coarse region's border past the range at which [`enclosed`] takes the
/// region as past too.
const ENCLOSED_SHARE: f64 = 0.5;

/// The `q` quantile of sorted values (0 for none).
fn quantile(sorted: &[f32], q: f64) -> f32 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// Refuses (leaves empty) the pixels of `map`, matched over `min .. max`, whose match lies
/// beyond the range: a disparity in the range's last pixel (the cost still falling at its
/// end), or a pixel the survey's coarse level put at or past `max` (its own coarse pixel or
/// any of the 3 × 3 around it, since the edge of a near object is blurred at the coarse
/// level).
///
/// With `grow` (a range the caller gave), the coarse level's holes that touch a pixel past the
/// range are taken as past too ([`flood`]). With `start` (a range's start found from the pair,
/// above 0), the pixels short of it are refused alike: a disparity in the range's first pixel,
/// or one the coarse level put a coarse pixel or more below it. Answers how many pixels with a
/// disparity were refused as past the end (those short of the start say nothing of the end).
pub fn refuse(
    map: &mut Disparity,
    survey: Option<&Survey>,
    (start, max): (Option<i32>, i32),
    grow: bool,
) -> usize {
    let (w, h) = (map.width, map.height);
    let end = (max - 1) as f32;
    let first = start.map_or(f32::NEG_INFINITY, |s| (s + 1) as f32);
    let survey = survey.filter(|s| s.usable());
    // The coarse disparity (coarse px) at or under which a pixel is short of the start.
    let under = survey
        .zip(start)
        .map(|(s, start)| start as f32 / (1u32 << s.levels) as f32 - 1.0);
    let near: Option<Vec<bool>> = survey.map(|s| {
        let scale = (1u32 << s.levels) as f32;
        let (cw, ch) = (s.map.width, s.map.height);
        let mut own = past_map(&s.map, max as f32 / scale + 1.0);
        if grow {
            flood(&s.map, &mut own, max as f32 / scale + 2.0);
            enclosed(&s.map, &mut own);
        }
        let mut near = vec![false; cw * ch];
        for y in 0..ch {
            for x in 0..cw {
                near[y * cw + x] = (y.saturating_sub(1)..(y + 2).min(ch))
                    .any(|v| (x.saturating_sub(1)..(x + 2).min(cw)).any(|u| own[v * cw + u]));
            }
        }
        near
    });
    let mut past = 0;
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let d = map.data[i];
            if d.is_nan() {
                continue;
            }
            let coarse = survey.map(|s| s.coarse_at((x, y)));
            let beyond = d >= end || near.as_ref().zip(coarse).is_some_and(|(n, c)| n[c]);
            let below = d < first
                || survey
                    .zip(coarse)
                    .zip(under)
                    .is_some_and(|((s, c), under)| s.map.data[c] <= under);
            if beyond || below {
                map.data[i] = f32::NAN;
                map.std[i] = f32::NAN;
                past += usize::from(beyond);
            }
        }
    }
    past
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vision::synthetic;

    /// The coarse level is a quarter or an eighth of the usual sizes, never under 160 × 90.
    #[test]
    fn the_coarse_level_keeps_enough_pixels() {
        assert_eq!(levels(640, 480), 2);
        assert_eq!(levels(1280, 720), 3);
        assert_eq!(levels(320, 240), 1);
        assert_eq!(levels(200, 100), 0);
        assert_eq!(reach(640), 320);
        assert_eq!(reach(2000), 512);
        assert_eq!(reach(20), 16);
    }

    /// A rendered scene whose disparities reach past 128 (the layered scene, its disparities
    /// 5 ×: 30–200 px) is found to need them, its range covering the truth's greatest and not
    /// far past it; swapped, it is named, and the right way round it is not.
    #[test]
    fn a_near_scene_is_found_and_a_swapped_one_named() {
        let pair = synthetic::render(&synthetic::nearer(640, 360, 5.0, 0.0));
        let truth = pair.seen_truth().into_iter().fold(0.0f32, f32::max);
        let cancel = AtomicBool::new(false);
        let s = survey(&pair.left, &pair.right, &cancel).unwrap().unwrap();
        let (_, max) = s.needs(None).unwrap();
        assert!(
            max as f32 > truth && (max as f32) < 1.3 * truth + 16.0,
            "{max} for a truth of {truth}: {:?}",
            (s.near, s.greatest, s.matched)
        );
        assert!(!s.swapped(), "{:?}", (s.negative, s.negative_median));
        let swapped = survey(&pair.right, &pair.left, &cancel).unwrap().unwrap();
        assert!(
            swapped.swapped(),
            "{:?}",
            (swapped.negative, swapped.negative_median)
        );
    }

    /// A scene that is near everywhere (the layered scene, its disparities 5 × and 60 px
    /// further: about 90–260 px) is found to start past 0, short of its farthest truth, and its
    /// range holds less than starting at 0 would; a scene that reaches far starts at 0.
    #[test]
    fn a_scene_near_everywhere_starts_past_zero() {
        let pair = synthetic::render(&synthetic::nearer(640, 360, 5.0, 60.0));
        let seen = pair.seen_truth();
        let (least, most) = seen
            .iter()
            .fold((f32::MAX, 0.0f32), |(a, b), &d| (a.min(d), b.max(d)));
        let cancel = AtomicBool::new(false);
        let s = survey(&pair.left, &pair.right, &cancel).unwrap().unwrap();
        let (min, max) = s.needs(None).unwrap();
        assert!(
            min > 0 && (min as f32) < least && max as f32 > most,
            "{min}..{max} for a truth of {least}..{most}: {:?}",
            (s.far, s.near)
        );
        assert_eq!(s.needs(Some(0)).unwrap().0, 0, "a given start is kept");
        let near = synthetic::render(&synthetic::layered(640, 360));
        let s = survey(&near.left, &near.right, &cancel).unwrap().unwrap();
        assert_eq!(s.needs(None).unwrap().0, 0, "{:?}", s.far);
    }

    /// A smooth patch the pixels past the range surround (a chessboard matched one period off)
    /// is taken as past; one that reaches the image's edge, with less than half its border
    /// past, is not.
    #[test]
    fn a_patch_the_past_pixels_enclose_is_past_too() {
        // 8 × 6 coarse pixels: a ring past (30) around a patch at 12 in columns 1..4; columns
        // 5..8 a far surface at 5 running to the image's edge.
        let (w, h) = (8, 6);
        let mut data = vec![5.0f32; w * h];
        for y in 0..h {
            for x in 0..5 {
                let ring = x == 0 || x == 4 || y == 0 || y + 1 == h;
                data[y * w + x] = if ring { 30.0 } else { 12.0 };
            }
        }
        let map = Disparity {
            width: w,
            height: h,
            data,
            std: vec![0.5; w * h],
            filled: Vec::new(),
            blank: Vec::new(),
        };
        let mut past: Vec<bool> = map.data.iter().map(|&d| d >= 21.0).collect();
        enclosed(&map, &mut past);
        assert!(past[2 * w + 2], "the enclosed patch at 12 is past");
        assert!(!past[2 * w + 6], "the far surface at the edge is not");
    }

    /// Black bands across both images (the dark beyond a fisheye's image circle, a clipped sky),
    /// above and below a near scene: the full match gives them no disparity, the survey neither
    /// takes them for matches at zero (its farthest stays near the scene's, no negatives) nor
    /// for swapped cameras, and a range that stops short of the scene leaves no pixel.
    #[test]
    fn blank_bands_are_neither_matched_nor_surveyed() {
        let (w, h) = (640, 360);
        let mut pair = synthetic::render(&synthetic::nearer(w, h, 5.0, 0.0));
        let whole = pair.clone();
        let band = |y: usize| !(90..270).contains(&y);
        for image in [&mut pair.left, &mut pair.right] {
            for (i, v) in image.data.iter_mut().enumerate() {
                if band(i / w) {
                    *v = 0;
                }
            }
        }
        let cancel = AtomicBool::new(false);
        let params = Params::new(&Settings {
            max_disparity: Some(super::super::RangeEnd::Px(256)),
            ..Settings::default()
        })
        .unwrap();
        let (map, _) = super::super::disparity(&pair.left, &pair.right, &params, &cancel).unwrap();
        // Rows whose whole 9 × 7 window lies in a band carry no disparity.
        let deep = |y: usize| band(y) && band(y.saturating_sub(3)) && band((y + 3).min(h - 1));
        let carried = (0..w * h)
            .filter(|&i| deep(i / w) && !map.data[i].is_nan())
            .count();
        assert_eq!(carried, 0, "pixels of the blank bands with a disparity");
        // The map says which pixels were blank: the bands' deep rows, and none of the scene's.
        assert!((0..w * h).filter(|&i| deep(i / w)).all(|i| map.blank[i]));
        assert!((96 * w..264 * w).all(|i| !map.blank[i]));
        // The scene's rows clear of the bands match as they do without them.
        let (unbanded, _) =
            super::super::disparity(&whole.left, &whole.right, &params, &cancel).unwrap();
        let clear = |m: &Disparity| (96 * w..264 * w).filter(|&i| !m.data[i].is_nan()).count();
        let (with, without) = (clear(&map), clear(&unbanded));
        assert!(
            with as f64 > 0.97 * without as f64,
            "{with} pixels of the scene matched with the bands, {without} without"
        );
        let s = survey(&pair.left, &pair.right, &cancel).unwrap().unwrap();
        // The farthest the scene's rows clear of the bands show.
        let least = (96 * w..264 * w)
            .filter(|&i| pair.visible[i])
            .map(|i| pair.truth[i])
            .fold(f32::MAX, f32::min);
        assert!(
            s.far > 0.5 * least && s.far < least + 4.0 && s.negative < 0.01 && !s.swapped(),
            "farthest {} for a truth from {least}; {:?}",
            s.far,
            (s.negative, s.negative_median)
        );
        // The share matched is of the pixels with something to match (of all, it would be
        // under a third): the pair is not suspected.
        assert!(s.matched > SUSPECT_MATCHED, "{}", s.matched);
        let mut short = map.clone();
        refuse(&mut short, Some(&s), (None, 16), true);
        let kept = short.data.iter().filter(|d| !d.is_nan()).count();
        assert_eq!(
            kept, 0,
            "pixels kept by a range of 16 px on a scene from {least} px"
        );
    }

    /// With a range that stops short of a near scene, the pixels past it are refused: those in
    /// the range's last pixel and those the coarse level puts past it.
    #[test]
    fn pixels_past_a_short_range_are_refused() {
        let mut map = Disparity {
            width: 4,
            height: 1,
            data: vec![10.0, 79.2, 40.0, f32::NAN],
            std: vec![0.5; 4],
            filled: Vec::new(),
            blank: Vec::new(),
        };
        assert_eq!(refuse(&mut map, None, (None, 80), false), 1);
        assert!(map.data[1].is_nan() && map.std[1].is_nan());
        assert_eq!((map.data[0], map.data[2]), (10.0, 40.0));
        // A start found at 32: the pixel in its first disparity is refused too.
        let mut map = Disparity {
            width: 3,
            height: 1,
            data: vec![32.4, 50.0, 33.5],
            std: vec![0.5; 3],
            filled: Vec::new(),
            blank: Vec::new(),
        };
        assert_eq!(refuse(&mut map, None, (Some(32), 80), false), 0);
        assert!(map.data[0].is_nan() && map.std[0].is_nan());
        assert_eq!((map.data[1], map.data[2]), (50.0, 33.5));
    }
}
