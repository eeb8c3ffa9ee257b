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

pub mod model;

use std::sync::atomic::{AtomicBool, Ordering};

use self::model::{Drift, Fitted, Model, Observed, Param};
use crate::calibration::files::{Raw, RigStd, opencv, ros};
use crate::camera::{Alpha, RectifyOptions, stereo_rectify};
use crate::physics::{LengthUnit, Rig};
use crate::pipeline::Calibrated;
use crate::vision::Gray;
use crate::vision::decode::{self, DecodeError, DecodeLimits};
use crate::vision::remap::{self, Interpolation, RawImage};
use crate::vision::sparse::{SparseMatch, sparse_matches};

/// The most pairs one check takes.
pub const MAX_PAIRS: usize = 30;
/// The fewest matches over all pairs a check needs.
pub const MIN_MATCHES: usize = 30;
/// The rows a drift may move before the calibration no longer holds, by default (px).
pub const DEFAULT_TOLERANCE_PX: f64 = 0.2;
/// The distances (metres) at which a drift's effect is told.
pub const EFFECT_AT_M: [f64; 2] = [1.0, 5.0];

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
    /// Frames that could not be decoded, each named (`left[2]`).
    Undecodable(Vec<(String, DecodeError)>),
    Cancelled,
}

/// A value and its standard deviation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    pub value: f64,
    pub std: f64,
}

/// The rows' offsets (right − left, px) over a region.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rows {
    pub matches: usize,
    pub mean_px: f64,
    pub rms_px: f64,
    /// The 95th percentile of the offsets' size.
    pub p95_px: f64,
}

impl Rows {
    fn of(offsets: &[f64]) -> Rows {
        let n = offsets.len();
        if n == 0 {
            return Rows {
                matches: 0,
                mean_px: f64::NAN,
                rms_px: f64::NAN,
                p95_px: f64::NAN,
            };
        }
        let mut sizes: Vec<f64> = offsets.iter().map(|o| o.abs()).collect();
        sizes.sort_by(f64::total_cmp);
        Rows {
            matches: n,
            mean_px: offsets.iter().sum::<f64>() / n as f64,
            rms_px: (offsets.iter().map(|o| o * o).sum::<f64>() / n as f64).sqrt(),
            p95_px: sizes[((n as f64 * 0.95).ceil() as usize).clamp(1, n) - 1],
        }
    }
}

/// The rows over the whole image and over a 3 × 3 grid of it (row-major from the top left).
#[derive(Debug, Clone, PartialEq)]
pub struct RowSpread {
    pub whole: Rows,
    pub grid: Vec<Rows>,
}

/// The grid [`RowSpread`] is told over.
pub const GRID: usize = 3;

impl RowSpread {
    fn of(points: &[([f64; 2], f64)], size: (u32, u32)) -> RowSpread {
        let cell = |[x, y]: [f64; 2]| {
            let c = ((x / f64::from(size.0)) * GRID as f64).clamp(0.0, GRID as f64 - 1.0) as usize;
            let r = ((y / f64::from(size.1)) * GRID as f64).clamp(0.0, GRID as f64 - 1.0) as usize;
            r * GRID + c
        };
        let grid = (0..GRID * GRID)
            .map(|k| {
                let offsets: Vec<f64> = points
                    .iter()
                    .filter(|(p, _)| cell(*p) == k)
                    .map(|(_, o)| *o)
                    .collect();
                Rows::of(&offsets)
            })
            .collect();
        let all: Vec<f64> = points.iter().map(|(_, o)| *o).collect();
        RowSpread {
            whole: Rows::of(&all),
            grid,
        }
    }
}

/// What the drift does to a distance: the error of a distance measured with the calibration
/// as it was, at the centre of the image and the largest over it, beside the calibration's
/// own σ there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthEffect {
    /// The distance, in the rig's unit.
    pub distance: f64,
    /// What a distance measured at the image's centre reads less the truth.
    pub error_centre: f64,
    /// The largest error over the image, signed.
    pub error_largest: f64,
    /// σ of a distance from the calibration's own uncertainty (0 when unknown).
    pub calibration_std: f64,
}

/// What explains the rows.
#[derive(Debug, Clone, PartialEq)]
pub struct Correction {
    /// The right camera's turn since it was calibrated, about its x, y and z axes (degrees),
    /// where the matches see it.
    pub rotation_deg: [Option<Estimate>; 3],
    /// Its fy over the calibrated fy.
    pub focal_ratio: Option<Estimate>,
    /// Its cy's move (px).
    pub cy_shift_px: Option<Estimate>,
    /// What the frames cannot see, in sentences.
    pub unseen: Vec<String>,
}

/// A check's answer.
#[derive(Debug, Clone, PartialEq)]
pub struct Check {
    /// Whether the calibration holds: the drift moves no row by more than the tolerance (or
    /// by no more than its own 3σ).
    pub holds: bool,
    /// The matches found in each pair.
    pub matches: Vec<usize>,
    /// Matches left out of the fit (their rows far from every other's).
    pub outliers: usize,
    /// The matches' rows with the calibration as it was, and after the correction.
    pub before: RowSpread,
    pub after: RowSpread,
    /// The largest row the drift moves over the image (px), with its σ.
    pub largest_row_shift: Estimate,
    pub tolerance_px: f64,
    pub correction: Correction,
    pub depth_effect: Vec<DepthEffect>,
    /// The calibration corrected, with the σ it came with.
    pub corrected: Raw,
    pub unit: LengthUnit,
    pub rig_std: Option<RigStd>,
}

impl Check {
    /// The corrected calibration as OpenCV's FileStorage YAML.
    pub fn opencv_yml(&self) -> String {
        let c = &self.corrected;
        opencv::write(&opencv::StereoFile {
            size: c.size,
            pair: &c.pair,
            essential: c.pair.essential(),
            fundamental: c.pair.fundamental(),
            rectification: &c.rectification,
            target: None,
            unit: self.unit,
            rig_std: self.rig_std,
        })
    }

    /// The corrected calibration's left or right camera as ROS's `CameraInfo` YAML.
    pub fn ros_yaml(&self, right: bool) -> String {
        let c = &self.corrected;
        let r = &c.rectification;
        let (camera, name, rotation, projection) = if right {
            (&c.pair.right, "right", r.r2, r.p2)
        } else {
            (&c.pair.left, "left", r.r1, r.p1)
        };
        ros::write(&ros::CameraInfo {
            name,
            size: c.size,
            camera,
            rotation,
            projection,
            unit: self.unit,
            rig_std: self.rig_std,
        })
    }
}

/// A frame read through a float map (bilinear, as `cv2.remap` with `INTER_LINEAR`).
fn rectified(frame: &Gray, map: &crate::camera::Map) -> Gray {
    Gray::new(
        map.size.width as usize,
        map.size.height as usize,
        remap::remap(RawImage::grey(frame), map, Interpolation::Linear),
    )
}

/// The σ of the calibration a check carries into its corrected file: the rig's, in the
/// file's unit, when it has one.
fn rig_std(rig: &Rig, unit: LengthUnit) -> Option<RigStd> {
    (rig.focal_std_px() > 0.0 || rig.baseline_std() > 0.0).then(|| RigStd {
        focal_px: rig.focal_std_px(),
        baseline: rig.unit().convert(rig.baseline_std(), unit),
    })
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
    settings: Settings,
    cancel: &AtomicBool,
) -> Result<Check, Fault> {
    let n = frames.left.len().min(frames.right.len());
    check(calibrated, (0..n).map(|i| frames.pair(i)), settings, cancel)
}

/// Checks `calibrated` (a calibration of raw cameras) against raw `pairs` of any scene, one
/// pair in memory at a time.
pub fn check(
    calibrated: &Calibrated,
    pairs: impl Iterator<Item = Result<(Gray, Gray), Fault>>,
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
    let expected = (raw.size.width, raw.size.height);
    let (map_left, map_right) = super::rectify::float_maps(raw);
    let model = Model::new(raw);
    let rect_size = (raw.rectification.size.width, raw.rectification.size.height);
    let range = (-8, (rect_size.0 / 3) as i32);
    let mut matches: Vec<SparseMatch> = Vec::new();
    let mut per_pair = Vec::new();
    let mut first: Option<(Gray, Gray)> = None;
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
        let (l, r) = rayon::join(|| rectified(&l, &map_left), || rectified(&r, &map_right));
        let found = sparse_matches(&l, &r, range);
        per_pair.push(found.len());
        matches.extend(found);
        if first.is_none() {
            first = Some((l, r));
        }
    }
    if matches.len() < MIN_MATCHES
        && let Some((l, r)) = &first
    {
        // Few matches: are the cameras swapped? Then the scene lies at negative disparities.
        let swapped = sparse_matches(l, r, (-range.1, -range.0)).len();
        if swapped >= (MIN_MATCHES / 3).max(4 * per_pair[0]) {
            return Err(Fault::Swapped {
                found: per_pair[0],
                swapped,
            });
        }
    }
    // Each match's right point back in the raw right frame, where a drift acts.
    let seen: Vec<(SparseMatch, Observed)> = matches
        .iter()
        .filter_map(|m| {
            let right_raw = model.raw_of(m.right)?;
            Some((
                *m,
                Observed {
                    left_row: m.left[1],
                    right_raw,
                },
            ))
        })
        .collect();
    if seen.len() < MIN_MATCHES {
        return Err(Fault::TooFewMatches { per_pair });
    }
    let observed: Vec<Observed> = seen.iter().map(|(_, o)| *o).collect();
    let candidates = [
        Param::AboutX,
        Param::AboutZ,
        Param::FocalRatio,
        Param::CyShift,
    ];
    let (params, dropped) = model::separable(&model, &candidates, &observed);
    let fitted = model::fit(&model, &params, &observed).ok_or(Fault::Undetermined)?;
    if cancel.load(Ordering::Relaxed) {
        return Err(Fault::Cancelled);
    }
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
    let (largest_row_shift, depth_effect) = effects(&model, &fitted, rig, rect_size);
    let holds = largest_row_shift.value <= settings.tolerance_px
        || largest_row_shift.value <= 3.0 * largest_row_shift.std;
    let corrected = corrected(raw, &fitted.drift)?;
    Ok(Check {
        holds,
        matches: per_pair,
        outliers: seen.len() - before.len(),
        before: RowSpread::of(&before, rect_size),
        after: RowSpread::of(&after, rect_size),
        largest_row_shift,
        tolerance_px: settings.tolerance_px,
        correction: correction(&fitted, &dropped),
        depth_effect,
        corrected,
        unit: calibrated.file_unit,
        rig_std: rig_std(rig, calibrated.file_unit),
    })
}

/// The largest row shift over a 9 × 7 grid of the rectified image, and the disparity shifts
/// there made distance errors at [`EFFECT_AT_M`].
fn effects(
    model: &Model,
    fitted: &Fitted,
    rig: &Rig,
    (w, h): (u32, u32),
) -> (Estimate, Vec<DepthEffect>) {
    let mut largest = Estimate {
        value: 0.0,
        std: 0.0,
    };
    let mut columns: Vec<f64> = Vec::new();
    let (cx, cy) = (
        rig.cx().unwrap_or(f64::from(w) / 2.0),
        rig.cy().unwrap_or(f64::from(h) / 2.0),
    );
    let shift = |x: f64, y: f64| fitted.shift_at(model, model.raw_of([x, y])?);
    for j in 0..7 {
        for i in 0..9 {
            let (x, y) = (
                f64::from(w - 1) * f64::from(i) / 8.0,
                f64::from(h - 1) * f64::from(j) / 6.0,
            );
            let Some(([dx, dy], [_, sy])) = shift(x, y) else {
                continue;
            };
            if dy.abs() > largest.value {
                largest = Estimate {
                    value: dy.abs(),
                    std: sy,
                };
            }
            columns.push(dx);
        }
    }
    let centre = shift(cx, cy).map_or(0.0, |([dx, _], _)| dx);
    let widest = columns
        .iter()
        .copied()
        .fold(centre, |a, b| if b.abs() > a.abs() { b } else { a });
    let fb = rig.fb();
    let effects = EFFECT_AT_M
        .iter()
        .map(|&metres| {
            let z = LengthUnit::Metre.convert(metres, rig.unit());
            // Read with the old calibration, a disparity Δx too large: Z_read − Z ≈ −Z²·Δx/(f·B).
            let error = |dx: f64| -z * z * dx / fb;
            DepthEffect {
                distance: z,
                error_centre: error(centre),
                error_largest: error(widest),
                calibration_std: z * rig.calibration_relative_error(),
            }
        })
        .collect();
    (largest, effects)
}

/// The fit told as a correction, in degrees, with what the frames could not see.
fn correction(fitted: &Fitted, dropped: &[(Param, Param)]) -> Correction {
    let degrees = |p| {
        fitted.estimate(p).map(|(v, s)| Estimate {
            value: v.to_degrees(),
            std: s.to_degrees(),
        })
    };
    let plain = |p| {
        fitted
            .estimate(p)
            .map(|(value, std)| Estimate { value, std })
    };
    let mut unseen = vec![
        "a turn about y (yaw) or a change of baseline moves points along the rows only: it \
         offsets or scales every disparity, and needs a known distance to be seen"
            .to_owned(),
    ];
    for &(lost, with) in dropped {
        let name = |p| match p {
            Param::AboutX => "a turn about x",
            Param::AboutY => "a turn about y",
            Param::AboutZ => "a turn about z",
            Param::FocalRatio => "the vertical focal ratio",
            Param::CyShift => "a shift of the principal point's row",
        };
        unseen.push(format!(
            "{} moves these matches' rows as {} does; the frames cannot tell them apart, so \
             the correction gives it to {}",
            name(lost),
            name(with),
            name(with)
        ));
    }
    Correction {
        rotation_deg: [Param::AboutX, Param::AboutY, Param::AboutZ].map(degrees),
        focal_ratio: plain(Param::FocalRatio).map(|e| Estimate {
            value: 1.0 + e.value,
            std: e.std,
        }),
        cy_shift_px: plain(Param::CyShift),
        unseen,
    }
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
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::boards::synthetic::{raw_wall, sample_rig};
    use crate::camera::{Size, StereoPair};
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
            Settings::default(),
            &AtomicBool::new(false),
        );
        assert_eq!(refused.err(), Some(Fault::NotRaw));
        let (l, r) = frames[0].clone();
        let swapped = check(
            &calibrated(rig),
            [Ok((r, l))].into_iter(),
            Settings::default(),
            &AtomicBool::new(false),
        );
        assert!(matches!(swapped, Err(Fault::Swapped { .. })), "{swapped:?}");
    }
}
