//! A calibration from board views, start to end: every image decoded and its board found over
//! the cores, a board the images contradict refused (a chessboard counted wrongly, a ChArUco
//! board described otherwise than printed), the views assembled and fitted (each camera, then
//! the pair), a calibration the views do not determine refused, the pair rectified with its
//! rig's σ, and, when asked, the report a user checks it by ([`report`]). Its faults are a
//! [`CalibrateFault`]; its files are OpenCV's and ROS's.
//!
//! A stereo rig calibrated from board images, without the service:
//!
//! ```
//! use std::sync::atomic::AtomicBool;
//! use stereo_core::calibration::boards::synthetic::{Style, poses, sample_rig, stereo_views};
//! use stereo_core::physics::LengthUnit;
//! use stereo_core::pipeline::calibrate::{Alpha, Board, Model, Settings, Size, Target, calibrate};
//! use stereo_core::vision::{decode::DecodeLimits, encode};
//!
//! // Ten PNG pairs of a 9 × 6 board (25 mm squares) seen by a rendered 640 × 480 rig, 120 mm apart.
//! let (rig, size) = (sample_rig(), Size { width: 640, height: 480 });
//! let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).unwrap();
//! let views = stereo_views(&rig, size, &board, &poses(&rig, size, &board, 10, 40.0, 7), &Style::default());
//! let png = |i: &stereo_core::calibration::boards::synthetic::Image| encode::png_grey(640, 480, &i.pixels);
//! let left: Vec<Vec<u8>> = views.iter().map(|v| png(&v.left)).collect();
//! let right: Vec<Vec<u8>> = views.iter().map(|v| png(&v.right)).collect();
//!
//! let settings = Settings {
//!     board: Target::Chessboard(board), model: Model::PlumbBob, alpha: Alpha::ZERO, size,
//!     limits: DecodeLimits { max_side: 8192, max_pixels: 1 << 25 },
//!     uncertainty: false, corners: false, cross_validate: false, uncertainty_distance: None,
//!     initial: None,
//! };
//! let (l, r): (Vec<&[u8]>, Vec<&[u8]>) = (left.iter().map(|v| &v[..]).collect(), right.iter().map(|v| &v[..]).collect());
//! let made = calibrate(&l, &r, &settings, &AtomicBool::new(false)).unwrap();
//!
//! assert!(made.fit.rms < 0.3, "{}", made.fit.rms);
//! let rig = made.rig().expect("a horizontal rig");           // what /distance takes
//! assert!((rig.baseline() - 120.0).abs() < 1.0, "{}", rig.baseline());
//! assert!(made.opencv_yml().unwrap().starts_with("%YAML:1.0")); // cv2.FileStorage reads it
//! ```

pub mod report;
pub mod settings;
pub mod sight;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use rayon::prelude::*;

pub use self::report::Report;
use self::report::rectified_rig;
pub use self::settings::{Initial, Settings};
pub use self::sight::{Sighting, sight};
pub use crate::calibration::boards::charuco::{CharucoBoard, CharucoSpec, Dictionary};
use crate::calibration::boards::corners::{Luma, Miss};
pub use crate::calibration::boards::report::{CharucoMistake, Coverage, Determination, tilt_deg};
use crate::calibration::boards::report::{Detections, agreed_charuco_mistake, agreed_other_size};
use crate::calibration::boards::{self, TargetMiss};
pub use crate::calibration::boards::{
    Board, CameraFit, Corners, Fit, FitFault, MAX_VIEWS, Seen, Start, Target, ViewOutcome,
    cross_validation, uncertainty,
};
use crate::calibration::files::{RigStd, opencv, ros};
use crate::camera::RectifyOptions;
pub use crate::camera::{Alpha, Model, Rectification, Size};
use crate::physics::Rig;
pub use crate::vision::decode::DecodeLimits;
use crate::vision::decode::{self, DecodeError};

/// A calibration and what it was made from.
#[derive(Debug, Clone)]
pub struct Calibration {
    pub fit: Fit,
    /// Each view's corners, as found.
    pub views: Vec<Corners>,
    /// Why each view's board was not found, left and right.
    pub reasons: Vec<[Option<String>; 2]>,
    /// Bouguet's rectification of the pair (`None` for one camera, or one that cannot be).
    pub rectification: Option<Rectification>,
    /// σ of the rectified rig's focal length (px) and baseline (the board's unit).
    pub rig_std: Option<[f64; 2]>,
    /// What a user checks it by.
    pub report: Report,
    /// How the pair moved since the earlier calibration it started from, when it did.
    pub since: Option<Since>,
    /// What the decoder forgave, each sentence naming its view (`left[2] has no …`).
    pub notes: Vec<String>,
    /// Finding the boards, solving, rectifying.
    pub times: [Duration; 3],
    settings: Settings,
}

/// How a pair calibrated again moved since its earlier calibration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Since {
    /// The right camera's turn relative to the left since then (R·R_earlierᵀ), degrees
    /// about x, y and z.
    pub rotation_deg: [f64; 3],
    /// The baseline |T| then and now, in the board's unit.
    pub baseline: [f64; 2],
}

/// A baseline that changed by more than this factor either way since the earlier
/// calibration is named: a unit typed wrong, or another rig.
const BASELINE_CHANGE: f64 = 1.25;

/// Why no calibration came of the views.
#[derive(Debug, Clone)]
pub enum CalibrateFault {
    /// The work was abandoned (its caller went away).
    Abandoned,
    /// Images that could not be decoded, each with its view's name (`left[3]`).
    Undecodable(Vec<(String, DecodeError)>),
    /// Most images show a whole chessboard of another size than the board's.
    OtherBoardSize {
        board: Board,
        found: (usize, usize),
        showing: usize,
        images: usize,
    },
    /// Most images show a ChArUco board printed otherwise than described.
    Charuco {
        board: CharucoBoard,
        mistake: CharucoMistake,
        images: usize,
    },
    /// The fit failed; each view's reason its board was not found.
    Fit {
        fault: FitFault,
        reasons: Vec<[Option<String>; 2]>,
        views: usize,
    },
    /// The views do not determine the calibration.
    Refused { cause: String, views: usize },
    /// The calibrated pair cannot be rectified, so it has no stereo file.
    NotRectifiable,
    /// An earlier calibration was given for one camera's views: it calibrates a pair again.
    InitialNeedsPair,
}

/// The bytes finding the boards of `images` images of `(width, height)` holds at once: per
/// image being worked on, its decoded buffer, the grey levels as f32 and u8, and the corner
/// detector's response maps (for ChArUco markers, the sums of the grey levels, the dark mask,
/// the blobs' labels and the flood's stack instead of the response maps).
pub fn bytes_needed(board: &Target, (width, height): (u32, u32), images: usize) -> usize {
    let threads = rayon::current_num_threads().clamp(1, images.max(1));
    let finding = match board {
        Target::Chessboard(_) => 16,
        Target::Charuco(_) => 8 + 1 + 4 + 8,
    };
    let per_image = (width as usize * height as usize).saturating_mul(10 + 4 + 1 + finding);
    threads.saturating_mul(per_image)
}

/// One image's board: decoded, found and refined, with what the decoder forgave (named by
/// the view).
type Found = Result<(Result<Seen, TargetMiss>, Option<String>), (String, DecodeError)>;

fn find(name: String, bytes: &[u8], board: &Target, limits: DecodeLimits) -> Found {
    let decoded = decode::decode(bytes, limits, false).map_err(|e| (name.clone(), e))?;
    let note = decoded.note.map(|note| format!("{name} {note}"));
    let grey = decoded.grey;
    let luma = Luma::from_u16(grey.width, grey.height, &grey.data);
    Ok((board.find(&luma), note))
}

/// Calibrates one camera (`right` empty) or a pair from the views' encoded images (PNG or
/// JPEG; the i-th left and right are one view). `cancel` abandons the work.
pub fn calibrate(
    left: &[&[u8]],
    right: &[&[u8]],
    settings: &Settings,
    cancel: &AtomicBool,
) -> Result<Calibration, CalibrateFault> {
    let started = Instant::now();
    let jobs: Vec<(String, &[u8])> = left
        .iter()
        .enumerate()
        .map(|(i, b)| (format!("left[{i}]"), *b))
        .chain(
            right
                .iter()
                .enumerate()
                .map(|(i, b)| (format!("right[{i}]"), *b)),
        )
        .collect();
    let found: Vec<Option<Found>> = jobs
        .into_par_iter()
        .map(|(name, bytes)| {
            (!cancel.load(Ordering::Relaxed))
                .then(|| find(name, bytes, &settings.board, settings.limits))
        })
        .collect();
    if found.iter().any(Option::is_none) {
        return Err(CalibrateFault::Abandoned);
    }
    let (mut undecodable, mut notes) = (Vec::new(), Vec::new());
    let mut misses: Vec<Result<Seen, TargetMiss>> = Vec::with_capacity(found.len());
    for f in found.into_iter().flatten() {
        match f {
            Ok((r, note)) => {
                misses.push(r);
                notes.extend(note);
            }
            Err(e) => {
                undecodable.push(e);
                misses.push(Err(TargetMiss::Chessboard(Miss::NoGrid)));
            }
        }
    }
    if !undecodable.is_empty() {
        return Err(CalibrateFault::Undecodable(undecodable));
    }
    refuse_the_wrong_board(&misses, &settings.board)?;
    let results: Vec<Result<Seen, String>> = misses
        .into_iter()
        .map(|r| r.map_err(|m| m.to_string()))
        .collect();
    let stereo = !right.is_empty();
    let n = left.len();
    let Detections { views, reasons } = Detections::assemble(&results, stereo);
    let detect = started.elapsed();
    let solving = Instant::now();
    let object = settings.board.object_points();
    let fitted = match &settings.initial {
        Some(initial) if stereo => {
            boards::recalibrate(&object, settings.size, &initial.start, &views)
        }
        Some(_) => return Err(CalibrateFault::InitialNeedsPair),
        None => boards::calibrate(&object, settings.size, settings.model, &views, stereo),
    };
    let fit = fitted.map_err(|fault| CalibrateFault::Fit {
        fault,
        reasons: reasons.clone(),
        views: n,
    })?;
    let determination = Determination::of(&fit);
    if determination.refused() {
        return Err(CalibrateFault::Refused {
            cause: determination.cause().unwrap_or_default(),
            views: n,
        });
    }
    let solve = solving.elapsed();
    let rectifying = Instant::now();
    let options = RectifyOptions {
        alpha: settings.alpha,
        ..RectifyOptions::default()
    };
    let rectification = fit.rectify(options);
    let rig_std = fit
        .rig_std(options)
        .map(|own| with_held(own, &fit, settings.initial.as_ref()));
    let rectify = rectifying.elapsed();
    let mut report = Report::of(
        (&fit, &views, settings),
        (rectification.as_ref(), rig_std),
        &notes,
        determination,
    );
    let since = settings.initial.as_ref().and_then(|i| since(&fit, i));
    report
        .warnings
        .extend(initial_warnings(&fit, settings, since.as_ref()));
    Ok(Calibration {
        fit,
        views,
        reasons,
        rectification,
        rig_std,
        report,
        since,
        notes,
        times: [detect, solve, rectify],
        settings: settings.clone(),
    })
}

/// The rig's σ with held lenses: the fit's own (the new views' noise through R and T) and
/// the earlier calibration's, which the held lenses carry, added in quadrature.
fn with_held(own: [f64; 2], fit: &Fit, initial: Option<&Initial>) -> [f64; 2] {
    let earlier = initial.and_then(|i| i.rig_std).filter(|_| fit.held);
    let baseline = fit.extrinsics.map_or(0.0, |e| e.translation.norm());
    match earlier {
        Some([focal, fraction]) => [own[0].hypot(focal), own[1].hypot(fraction * baseline)],
        None => own,
    }
}

/// How the pair moved since the earlier calibration.
fn since(fit: &Fit, initial: &Initial) -> Option<Since> {
    let e = fit.extrinsics?;
    let earlier = &initial.start.pair;
    let turn = (e.rotation * earlier.rotation.inverse()).scaled_axis();
    Some(Since {
        rotation_deg: [turn.x, turn.y, turn.z].map(f64::to_degrees),
        baseline: [earlier.translation.norm(), e.translation.norm()],
    })
}

/// What a user of an earlier calibration is told: lenses held without σ, and a baseline that
/// changed past [`BASELINE_CHANGE`] (a unit typed wrong in the board or the earlier file).
fn initial_warnings(fit: &Fit, settings: &Settings, since: Option<&Since>) -> Vec<String> {
    let mut warnings = Vec::new();
    let Some(initial) = &settings.initial else {
        return warnings;
    };
    warnings.extend(
        initial
            .warnings
            .iter()
            .map(|w| format!("the initial calibration: {w}")),
    );
    if fit.held && initial.rig_std.is_none() {
        warnings.push(
            "the lenses were held at the initial calibration's, which carries no σ: the rig's \
             σ counts only the new views, so it is too small (send the initial calibration's \
             σ beside it as `initial_rig`, or start from /calibrate's own opencv.yml, which \
             carries it)"
                .to_owned(),
        );
    }
    let used = fit
        .views
        .iter()
        .filter(|v| v.status == ViewOutcome::Used)
        .count();
    if fit.held && used < boards::fit::MIN_VIEWS {
        warnings.push(format!(
            "R and T were found again from {used} view{}: in a board at one distance a turn \
             about x trades off with a shift along y (and about y with z), so their σ are \
             wide; 3 views or more at different distances and tilts pin them down",
            if used == 1 { "" } else { "s" }
        ));
    }
    if let Some(s) = since {
        let [before, after] = s.baseline;
        let ratio = after / before.max(f64::MIN_POSITIVE);
        if !(1.0 / BASELINE_CHANGE..=BASELINE_CHANGE).contains(&ratio) {
            let unit = settings.board.unit().symbol();
            warnings.push(format!(
                "the baseline came out {} {unit}, {}× the initial calibration's {} {unit}: a \
                 unit typed wrong (the board's, or the initial's `initial_unit`), or another rig",
                crate::numbers::short(after),
                crate::numbers::short(ratio),
                crate::numbers::short(before),
            ));
        }
    }
    warnings
}

/// Refuses a board most images contradict: a chessboard of another size, a ChArUco board
/// printed otherwise.
fn refuse_the_wrong_board(
    misses: &[Result<Seen, TargetMiss>],
    board: &Target,
) -> Result<(), CalibrateFault> {
    let missed: Vec<Option<&TargetMiss>> = misses.iter().map(|r| r.as_ref().err()).collect();
    let images = missed.len();
    match board {
        Target::Chessboard(board) => match agreed_other_size(&missed, board) {
            Some((found, showing)) => Err(CalibrateFault::OtherBoardSize {
                board: *board,
                found,
                showing,
                images,
            }),
            None => Ok(()),
        },
        Target::Charuco(board) => match agreed_charuco_mistake(&missed) {
            Some(mistake) => Err(CalibrateFault::Charuco {
                board: *board,
                mistake,
                images,
            }),
            None => Ok(()),
        },
    }
}

impl Calibration {
    /// How it was made.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Whether a pair was calibrated (not one camera).
    pub fn stereo(&self) -> bool {
        self.fit.right.is_some()
    }

    /// The rectified rig `/distance` takes, carrying its σ; `None` for one camera, a pair
    /// that cannot be rectified, or one whose cameras are one above the other.
    pub fn rig(&self) -> Option<Rig> {
        rectified_rig(
            self.rectification.as_ref(),
            self.rig_std,
            &self.settings.board,
        )
    }

    fn std(&self) -> Option<RigStd> {
        self.rig_std
            .map(|[focal_px, baseline]| RigStd { focal_px, baseline })
    }

    /// OpenCV's FileStorage YAML of the pair (M1 D1 M2 D2 R T E F R1 R2 P1 P2 Q), as
    /// `cv2.FileStorage` reads it.
    pub fn opencv_yml(&self) -> Result<String, CalibrateFault> {
        let fit = &self.fit;
        let (Some(rectification), Some(pair), Some(essential), Some(fundamental)) = (
            self.rectification.as_ref(),
            fit.pair(),
            fit.essential(),
            fit.fundamental(),
        ) else {
            return Err(CalibrateFault::NotRectifiable);
        };
        Ok(opencv::write(&opencv::StereoFile {
            size: fit.size,
            pair: &pair,
            essential,
            fundamental,
            rectification,
            target: Some(self.settings.board.recorded()),
            unit: self.settings.board.unit(),
            rig_std: self.std(),
        }))
    }

    /// ROS's `CameraInfo` YAML of the left or the right camera (one camera alone: its own).
    pub fn ros_yaml(&self, right: bool) -> String {
        let fit = &self.fit;
        let unit = self.settings.board.unit();
        match (&self.rectification, fit.pair()) {
            (Some(r), Some(pair)) => {
                let (camera, name, rotation, projection) = if right {
                    (pair.right, "right", r.r2, r.p2)
                } else {
                    (pair.left, "left", r.r1, r.p1)
                };
                ros::write(&ros::CameraInfo {
                    name,
                    size: fit.size,
                    camera: &camera,
                    rotation,
                    projection,
                    unit,
                    rig_std: self.std(),
                })
            }
            _ => ros::write(&ros::CameraInfo::alone(
                "left",
                fit.size,
                &fit.left.camera,
                unit,
            )),
        }
    }
}
