//! Does a calibration still hold? Raw pairs of any scene, rectified as the calibration
//! rectifies them, give sparse matches ([`crate::vision::sparse`]) whose rows should agree;
//! what the rows say is fitted as a drift of the right camera ([`model`]): a rotation about x
//! and z, and its vertical focal ratio and principal-point row where the matches can tell them
//! apart, each with its σ. The answer says whether the calibration holds (the drift moves no
//! row past a tolerance), the rows before and after, what the drift does to a distance, and
//! the corrected calibration.
//!
//! Rows cannot see a turn about y (a yaw) or a change of baseline: both move points along
//! the rows only, as a disparity offset and scale, and need a known distance.

pub mod known;
pub mod model;
pub mod report;
pub mod watch;

use std::sync::atomic::{AtomicBool, Ordering};

use self::known::Located;
pub use self::known::{Known, KnownPoint};
use self::model::{Drift, Model, Observed, Param};
pub use self::report::{
    Check, Correction, DepthEffect, DistanceCheck, EFFECT_AT_M, Errors, Estimate, GRID, RowSpread,
    Rows,
};
use self::report::{correction, distances, effects, rig_std};
pub use self::watch::Watch;
use crate::calibration::files::Raw;
use crate::camera::{Alpha, RectifyOptions, stereo_rectify};
use crate::physics::Implausible;
use crate::pipeline::Calibrated;
use crate::vision::Gray;
use crate::vision::decode::{self, DecodeError, DecodeLimits};
use crate::vision::remap::{self, Interpolation, RawImage};
use crate::vision::sparse::{SparseMatch, full_range, sparse_matches};

/// The most pairs one check takes.
pub const MAX_PAIRS: usize = 30;
/// The fewest matches over all pairs a check needs.
pub const MIN_MATCHES: usize = 30;
/// The rows a drift may move before the calibration no longer holds, by default (px).
pub const DEFAULT_TOLERANCE_PX: f64 = 0.2;

/// What a check is asked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// How far (px) the drift may move a row anywhere in the image and the calibration still
    /// hold.
    pub tolerance_px: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            tolerance_px: DEFAULT_TOLERANCE_PX,
        }
    }
}

/// Why a calibration could not be checked.
#[derive(Debug, Clone, PartialEq)]
pub enum Fault {
    /// The calibration describes rectified images only: there is nothing to rectify, and so
    /// nothing the frames could correct.
    NotRaw,
    /// The cameras are one above the other.
    Vertical,
    /// A pair's frames are not the calibration's raw size.
    Size {
        pair: usize,
        size: (usize, usize),
        expected: (u32, u32),
    },
    /// Too few matches, and the first pair matches far better with its frames swapped: the
    /// left camera's frames were sent as the right's.
    Swapped {
        found: usize,
        swapped: usize,
    },
    /// Too few matches over all pairs: the count in each.
    TooFewMatches {
        per_pair: Vec<usize>,
    },
    /// The matches leave the drift undetermined.
    Undetermined,
    /// The corrected calibration cannot be rectified.
    CannotRectify(String),
    /// A board or known distances were given, and no pair showed the board in both
    /// cameras (`board`) or matched a known point.
    NothingKnown {
        board: bool,
    },
    /// Frames that could not be decoded, each named (`left[2]`).
    Undecodable(Vec<(String, DecodeError)>),
    Cancelled,
}

/// A frame read through a float map (bilinear, as `cv2.remap` with `INTER_LINEAR`).
fn rectified(frame: &Gray, map: &crate::camera::Map) -> Gray {
    Gray::new(
        map.size.width as usize,
        map.size.height as usize,
        remap::remap(RawImage::grey(frame), map, Interpolation::Linear),
    )
}

/// The raw pairs a check reads: each frame's bytes, decoded one pair at a time.
pub struct Encoded<'a> {
    pub left: &'a [&'a [u8]],
    pub right: &'a [&'a [u8]],
    pub limits: DecodeLimits,
}

impl Encoded<'_> {
    /// The `i`-th pair, decoded to grey; its parts named (`left[i]`, `right[i]`) when they
    /// cannot be.
    fn pair(&self, i: usize) -> Result<(Gray, Gray), Fault> {
        let mut faults = Vec::new();
        let mut grey = |side: &str, bytes: &[u8]| match decode::decode(bytes, self.limits, false) {
            Ok(d) => Some(d.grey),
            Err(e) => {
                faults.push((format!("{side}[{i}]"), e));
                None
            }
        };
        let (l, r) = (grey("left", self.left[i]), grey("right", self.right[i]));
        match (l, r) {
            (Some(l), Some(r)) => Ok((l, r)),
            _ => Err(Fault::Undecodable(faults)),
        }
    }
}

/// Checks `calibrated` (a calibration of raw cameras) against raw pairs of any scene, sent
/// encoded (PNG or JPEG): [`check`] with the pairs decoded one at a time.
pub fn check_encoded(
    calibrated: &Calibrated,
    frames: &Encoded,
    known: &Known,
    settings: Settings,
    cancel: &AtomicBool,
) -> Result<Check, Fault> {
    let n = frames.left.len().min(frames.right.len());
    check(
        calibrated,
        (0..n).map(|i| frames.pair(i)),
        known,
        settings,
        cancel,
    )
}

/// What the pairs gave: the sparse matches, how many each pair gave, the known points, and
/// the first pair rectified (to tell swapped cameras).
struct Gathered {
    matches: Vec<SparseMatch>,
    per_pair: Vec<usize>,
    located: Vec<Located>,
    first: Option<(Gray, Gray)>,
}

/// Each pair checked for its size, the board found in its raw frames, then rectified, its
/// sparse matches and known points matched.
fn gather(
    calibrated: &Calibrated,
    raw: &Raw,
    model: &Model,
    pairs: impl Iterator<Item = Result<(Gray, Gray), Fault>>,
    known: &Known,
    cancel: &AtomicBool,
) -> Result<Gathered, Fault> {
    let expected = (raw.size.width, raw.size.height);
    let (map_left, map_right) = super::rectify::float_maps(raw);
    let range = search_range(raw);
    let mut got = Gathered {
        matches: Vec::new(),
        per_pair: Vec::new(),
        located: Vec::new(),
        first: None,
    };
    for (i, pair) in pairs.enumerate() {
        if cancel.load(Ordering::Relaxed) {
            return Err(Fault::Cancelled);
        }
        let (l, r) = pair?;
        for frame in [&l, &r] {
            if (frame.width as u64, frame.height as u64)
                != (u64::from(expected.0), u64::from(expected.1))
            {
                return Err(Fault::Size {
                    pair: i,
                    size: (frame.width, frame.height),
                    expected,
                });
            }
        }
        if let Some(target) = &known.board {
            let to_unit = target.unit().convert(1.0, calibrated.file_unit);
            got.located.extend(known::board_corners(
                target,
                &l,
                &r,
                &raw.pair.left,
                to_unit,
            ));
        }
        let (l, r) = rayon::join(|| rectified(&l, &map_left), || rectified(&r, &map_right));
        let points: Vec<KnownPoint> = known
            .points
            .iter()
            .filter(|p| p.pair == i)
            .copied()
            .collect();
        if !points.is_empty() {
            got.located
                .extend(known::distance_points(&points, raw, (&l, &r), range, |p| {
                    model.raw_of(p)
                }));
        }
        let found = sparse_matches(&l, &r, range);
        got.per_pair.push(found.len());
        got.matches.extend(found);
        if got.first.is_none() {
            got.first = Some((l, r));
        }
    }
    Ok(got)
}

/// The disparities searched: a little below zero to a third of the rectified width.
fn search_range(raw: &Raw) -> (i32, i32) {
    full_range(raw.rectification.size.width as usize)
}

/// Checks `calibrated` (a calibration of raw cameras) against raw `pairs` of any scene, one
/// pair in memory at a time, and what is `known` of distances in them.
pub fn check(
    calibrated: &Calibrated,
    pairs: impl Iterator<Item = Result<(Gray, Gray), Fault>>,
    known: &Known,
    settings: Settings,
    cancel: &AtomicBool,
) -> Result<Check, Fault> {
    let raw = calibrated.raw.as_deref().ok_or(Fault::NotRaw)?;
    if raw.is_identity() {
        return Err(Fault::NotRaw);
    }
    if raw.rectification.vertical {
        return Err(Fault::Vertical);
    }
    let model = Model::new(raw);
    let got = gather(calibrated, raw, &model, pairs, known, cancel)?;
    if got.matches.len() < MIN_MATCHES
        && got.located.is_empty()
        && let Some((l, r)) = &got.first
    {
        // Few matches: are the cameras swapped? Then the scene lies at negative disparities.
        let range = search_range(raw);
        let swapped = sparse_matches(l, r, (-range.1, -range.0)).len();
        if swapped >= (MIN_MATCHES / 3).max(4 * got.per_pair[0]) {
            return Err(Fault::Swapped {
                found: got.per_pair[0],
                swapped,
            });
        }
    }
    if !known.is_empty() && got.located.is_empty() {
        return Err(Fault::NothingKnown {
            board: known.board.is_some(),
        });
    }
    if cancel.load(Ordering::Relaxed) {
        return Err(Fault::Cancelled);
    }
    judge(
        calibrated,
        raw,
        &got.matches,
        &got.located,
        got.per_pair,
        settings,
    )
}

/// The matches' rows and the known points fitted as a drift, and what it means: the verdict,
/// the rows before and after, the correction and the corrected calibration. `per_pair` is
/// how many matches each pair gave.
fn judge(
    calibrated: &Calibrated,
    raw: &Raw,
    matches: &[SparseMatch],
    located: &[Located],
    per_pair: Vec<usize>,
    settings: Settings,
) -> Result<Check, Fault> {
    let model = Model::new(raw);
    let rect_size = (raw.rectification.size.width, raw.rectification.size.height);
    // Each match's right point back in the raw right frame, where a drift acts.
    let seen: Vec<(SparseMatch, Observed)> = matches
        .iter()
        .filter_map(|m| {
            let right_raw = model.raw_of(m.right)?;
            Some((
                *m,
                Observed::Row {
                    left_row: m.left[1],
                    right_raw,
                },
            ))
        })
        .collect();
    if seen.len() < MIN_MATCHES && located.is_empty() {
        return Err(Fault::TooFewMatches { per_pair });
    }
    let mut observed: Vec<Observed> = seen.iter().map(|(_, o)| *o).collect();
    observed.extend(located.iter().map(|k| Observed::Known {
        point: k.point,
        right_raw: k.right_raw,
    }));
    let candidates: &[Param] = if located.is_empty() {
        &[
            Param::AboutX,
            Param::AboutZ,
            Param::FocalRatio,
            Param::CyShift,
        ]
    } else {
        &[
            Param::AboutX,
            Param::AboutZ,
            Param::AboutY,
            Param::FocalRatio,
            Param::BaselineScale,
            Param::CyShift,
        ]
    };
    let (params, dropped) = model::separable(&model, candidates, &observed);
    let fitted = model::fit(&model, &params, &observed).ok_or(Fault::Undetermined)?;
    let kept = |i: usize| fitted.inliers[i] && fitted.residuals[i].is_finite();
    let before: Vec<([f64; 2], f64)> = seen
        .iter()
        .enumerate()
        .filter(|&(i, _)| kept(i))
        .map(|(_, (m, _))| (m.left, m.right[1] - m.left[1]))
        .collect();
    let after: Vec<([f64; 2], f64)> = seen
        .iter()
        .enumerate()
        .filter(|&(i, _)| kept(i))
        .map(|(i, (m, _))| (m.left, fitted.residuals[i]))
        .collect();
    let rig = &calibrated.rig;
    let shifts = effects(&model, &fitted, rig, rect_size);
    let within = |e: Estimate| e.value <= settings.tolerance_px || e.value <= 3.0 * e.std;
    let holds = within(shifts.rows) && within(shifts.disparity);
    let corrected = corrected(raw, &fitted.drift)?;
    // The known points the fit kept (a point matched wrongly lies far out).
    let trusted: Vec<Located> = located
        .iter()
        .enumerate()
        .filter(|&(j, _)| fitted.inliers[seen.len() + j])
        .map(|(_, k)| *k)
        .collect();
    let distance = distances(&trusted, raw, &corrected, calibrated);
    // A baseline no rig has (a unit typed wrong) makes every distance wrong by one factor:
    // the rows still tell, but no depth effect is told from it.
    let doubt = Implausible::baseline(rig.baseline(), rig.unit()).map(|i| i.to_string());
    Ok(Check {
        holds,
        matches: per_pair,
        outliers: seen.len() - before.len(),
        before: RowSpread::of(&before, rect_size),
        after: RowSpread::of(&after, rect_size),
        largest_row_shift: shifts.rows,
        largest_disparity_shift: shifts.disparity,
        tolerance_px: settings.tolerance_px,
        correction: correction(&fitted, &dropped, !located.is_empty()),
        depth_effect: if doubt.is_some() {
            Vec::new()
        } else {
            shifts.depth
        },
        baseline_doubt: doubt,
        distance,
        corrected,
        unit: calibrated.file_unit,
        rig_std: rig_std(rig, calibrated.file_unit),
    })
}

/// The raw cameras with the drift applied, rectified again as the calibration was (its
/// `alpha`, its rectified size).
fn corrected(raw: &Raw, drift: &Drift) -> Result<Raw, Fault> {
    let pair = drift
        .corrected(&raw.pair)
        .ok_or_else(|| Fault::CannotRectify("the corrected right camera is not a camera".into()))?;
    let alpha = raw
        .rectification
        .alpha
        .and_then(|a| Alpha::new(a).ok())
        .unwrap_or(Alpha::ZERO);
    let options = RectifyOptions {
        alpha,
        new_size: Some(raw.rectification.size),
        ..RectifyOptions::default()
    };
    let rectification = stereo_rectify(&pair, raw.size, options)
        .map_err(|e| Fault::CannotRectify(e.to_string()))?;
    Ok(Raw {
        pair,
        size: raw.size,
        rectification,
        computed: true,
        latlon: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::boards::synthetic::{raw_wall, sample_rig};
    use crate::camera::{Size, StereoPair};
    use crate::physics::LengthUnit;
    use nalgebra::Vector3;

    const SIZE: Size = Size {
        width: 640,
        height: 480,
    };

    /// The calibration of `pair`, as a file of raw cameras in millimetres gives it.
    fn calibrated(pair: StereoPair) -> Calibrated {
        let rectification =
            stereo_rectify(&pair, SIZE, RectifyOptions::default()).expect("rectifiable");
        let rig = rectification.rig(LengthUnit::Millimetre).expect("a rig");
        let mut c = Calibrated::of_rig(rig);
        c.raw = Some(Box::new(Raw {
            pair,
            size: SIZE,
            rectification,
            computed: true,
            latlon: None,
        }));
        c
    }

    /// `n` raw pairs of textured walls 0.8 to 4 m away, turned this way and that, seen by
    /// `pair`.
    fn walls(pair: &StereoPair, n: usize, seed: u64) -> Vec<(Gray, Gray)> {
        (0..n)
            .map(|i| {
                let distance = 800.0 + 3200.0 * (i as f64) / (n.max(2) - 1) as f64;
                let slope = [-0.3, 0.0, 0.3][i % 3];
                let [l, r] = raw_wall(pair, SIZE, distance, slope, seed + i as u64).expect("a rig");
                let grey = |img: crate::calibration::boards::synthetic::Image| {
                    Gray::new(
                        img.width as usize,
                        img.height as usize,
                        img.pixels.iter().map(|&p| u16::from(p) * 257).collect(),
                    )
                };
                (grey(l), grey(r))
            })
            .collect()
    }

    /// The rig turned by `degrees` about the right camera's axis `axis`.
    fn drifted(pair: &StereoPair, axis: Vector3<f64>, degrees: f64) -> StereoPair {
        Drift {
            rotation: axis * degrees.to_radians(),
            ..Drift::default()
        }
        .corrected(pair)
        .expect("a camera")
    }

    fn checked(pair: StereoPair, frames: &[(Gray, Gray)]) -> Check {
        check(
            &calibrated(pair),
            frames.iter().cloned().map(Ok),
            &Known::default(),
            Settings::default(),
            &AtomicBool::new(false),
        )
        .expect("checked")
    }

    /// An intact rig holds with its rows within 0.05 px; a drift of 0.05° about x, then
    /// about z, is found to ±0.01° and fails the check, and the corrected calibration, checked
    /// again on the same frames, holds with its rows within 0.1 px RMS.
    #[test]
    fn a_drift_of_five_hundredths_of_a_degree_is_found_and_corrected() {
        let rig = sample_rig();
        let intact = checked(rig, &walls(&rig, 3, 11));
        assert!(intact.holds, "{intact:?}");
        assert!(intact.before.whole.rms_px < 0.05, "{:?}", intact.before);
        assert!(
            intact.matches.iter().all(|&n| n >= 100),
            "{:?}",
            intact.matches
        );
        for (axis, index) in [(Vector3::x(), 0), (Vector3::z(), 2)] {
            let frames = walls(&drifted(&rig, axis, 0.05), 3, 11);
            let found = checked(rig, &frames);
            assert!(!found.holds, "{:?}", found.largest_row_shift);
            let turn = found.correction.rotation_deg[index].expect("seen");
            assert!((turn.value - 0.05).abs() < 0.01, "{turn:?}");
            assert!(found.after.whole.rms_px < 0.1, "{:?}", found.after);
            let again = checked(found.corrected.pair, &frames);
            assert!(again.holds, "{:?}", again.largest_row_shift);
            assert!(again.before.whole.rms_px < 0.1, "{:?}", again.before);
        }
    }

    /// A turn about y is named as unseen and never fitted; a cy shift is given to the turn
    /// about x it moves the rows with.
    #[test]
    fn what_the_rows_cannot_see_is_named() {
        let rig = sample_rig();
        let found = checked(rig, &walls(&rig, 2, 5));
        assert_eq!(found.correction.rotation_deg[1], None);
        assert_eq!(found.correction.cy_shift_px, None);
        assert!(
            found.correction.unseen[0].contains("yaw"),
            "{:?}",
            found.correction
        );
        assert!(
            found
                .correction
                .unseen
                .iter()
                .any(|u| u.contains("principal point's row")),
            "{:?}",
            found.correction
        );
    }

    /// Frames of another size are named by their pair; a calibration of rectified images
    /// only is refused; the left camera's frames sent as the right's are called swapped.
    #[test]
    fn wrong_frames_and_calibrations_are_named() {
        let rig = sample_rig();
        let frames = walls(&rig, 1, 3);
        let small = Gray::new(320, 240, vec![0; 320 * 240]);
        let sized = check(
            &calibrated(rig),
            [Ok(frames[0].clone()), Ok((small.clone(), small))].into_iter(),
            &Known::default(),
            Settings::default(),
            &AtomicBool::new(false),
        );
        assert!(
            matches!(
                sized,
                Err(Fault::Size {
                    pair: 1,
                    size: (320, 240),
                    expected: (640, 480)
                })
            ),
            "{sized:?}"
        );
        let rectified_only = Calibrated::of_rig(calibrated(rig).rig);
        let refused = check(
            &rectified_only,
            frames.iter().cloned().map(Ok),
            &Known::default(),
            Settings::default(),
            &AtomicBool::new(false),
        );
        assert_eq!(refused.err(), Some(Fault::NotRaw));
        let (l, r) = frames[0].clone();
        let swapped = check(
            &calibrated(rig),
            [Ok((r, l))].into_iter(),
            &Known::default(),
            Settings::default(),
            &AtomicBool::new(false),
        );
        assert!(matches!(swapped, Err(Fault::Swapped { .. })), "{swapped:?}");
    }

    /// One board view at 1 m fixes what rows cannot: a yaw of 0.1° since the calibration is
    /// recovered to ±0.02°, and the board corners' distance error falls from about 1.5 % to
    /// under a millimetre.
    #[test]
    fn one_board_view_recovers_a_yaw() {
        use crate::calibration::boards::synthetic::{Rays, Style, stereo_view};
        use crate::calibration::boards::{Board, Target};
        use nalgebra::{Isometry3, Rotation3, Translation3};
        let rig = sample_rig();
        let truth = drifted(&rig, Vector3::y(), 0.1);
        let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).expect("a board");
        let style = Style {
            supersampling: 2,
            ..Style::default()
        };
        let rays = [
            Rays::new(&truth.left, SIZE, style.supersampling),
            Rays::new(&truth.right, SIZE, style.supersampling),
        ];
        let pose = Isometry3::from_parts(
            Translation3::new(-100.0, -60.0, 1000.0),
            Rotation3::from_scaled_axis(Vector3::new(0.15, -0.2, 0.05)).into(),
        );
        let view = stereo_view(&truth, &board, &pose, 0, &rays, &style);
        let grey = |img: &crate::calibration::boards::synthetic::Image| {
            Gray::new(
                img.width as usize,
                img.height as usize,
                img.pixels.iter().map(|&p| u16::from(p) * 257).collect(),
            )
        };
        let known = Known {
            board: Some(Target::Chessboard(board)),
            points: Vec::new(),
        };
        let found = check(
            &calibrated(rig),
            [Ok((grey(&view.left), grey(&view.right)))].into_iter(),
            &known,
            Settings::default(),
            &AtomicBool::new(false),
        )
        .expect("checked");
        let yaw = found.correction.rotation_deg[1].expect("a yaw seen");
        assert!((yaw.value - 0.1).abs() < 0.02, "{yaw:?}");
        assert!(!found.holds, "{:?}", found.largest_disparity_shift);
        let distance = found.distance.expect("distances");
        assert_eq!(distance.points, 54);
        assert!(distance.before.mean.abs() > 10.0, "{distance:?}");
        assert!(distance.after.rms < 1.0, "{distance:?}");
        assert!(
            found
                .correction
                .unseen
                .iter()
                .any(|u| u.contains("baseline")),
            "{:?}",
            found.correction
        );
    }
}
