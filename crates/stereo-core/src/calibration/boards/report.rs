//! What a user checks a calibration by, as Kalibr's report and OpenCV's tutorials give it:
//! each view's detections assembled with why a board was not found, where the corners fell
//! over each image (coverage), how far the board tilted, and the warnings that say what to
//! shoot again.

use super::Board;
use super::charuco::Dictionary;
use super::fit::{Corners, Fit, Seen, ViewFit, ViewOutcome};
use super::target::TargetMiss;
use crate::camera::Size;
use crate::numbers::round_to;

/// Below this many views used, a calibration is not to be trusted.
pub const MIN_GOOD_VIEWS: usize = 10;
/// The least span of the corners over each image, as a fraction of its width and height.
pub const MIN_SPAN: f64 = 0.6;
/// The least tilt some view must show for the focal length to be determined, degrees.
pub const MIN_TILT_DEG: f64 = 15.0;
/// Above this RMS, in pixels, something is wrong with the board or the images.
pub const HIGH_RMS_PX: f64 = 1.0;

/// The boards found in each view, and why not where they were not.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Detections {
    pub views: Vec<Corners>,
    /// Per view, why the left and the right board were not found.
    pub reasons: Vec<[Option<String>; 2]>,
}

impl Detections {
    /// The views of `found`: the left images' results, then (for a pair) the right ones',
    /// each the corners or why the board was not found.
    pub fn assemble(found: &[Result<Seen, String>], stereo: bool) -> Detections {
        let n = if stereo { found.len() / 2 } else { found.len() };
        let right = |i: usize| stereo.then(|| &found[n + i]);
        let views = (0..n)
            .map(|i| Corners {
                left: found[i].as_ref().ok().cloned(),
                right: right(i).and_then(|r| r.as_ref().ok().cloned()),
            })
            .collect();
        let reasons = (0..n)
            .map(|i| {
                [
                    found[i].as_ref().err().cloned(),
                    right(i).and_then(|r| r.as_ref().err().cloned()),
                ]
            })
            .collect();
        Detections { views, reasons }
    }
}

/// Above this σ of a focal length, as a fraction of it, a calibration is not determined: a
/// warning says why and the summary's `determined` is false. Careful calibrations reach
/// 0.05 % (OpenCV's own 13 pairs, 0.05 %; 3 views of a tilted board, about 0.5 %).
pub const UNDETERMINED_FRACTION: f64 = 0.02;
/// Above this σ of a focal length, as a fraction of it, the calibration is refused (a 422):
/// it says nothing about the lens.
pub const REFUSED_FRACTION: f64 = 0.2;
/// Views whose boards all lie within this angle of one another are one pose repeated.
pub const ALIKE_DEG: f64 = 2.0;

/// Whether the views determine the model: the parameters whose σ is too large a share of
/// their value, and whether the views show one pose over and over.
#[derive(Debug, Clone, PartialEq)]
pub struct Determination {
    /// Each poorly determined parameter as "left fx = 1315.7 ± 1284.8 px".
    pub parameters: Vec<String>,
    /// The largest σ of a focal length as a fraction of it.
    pub worst_fraction: f64,
    /// When every view's board lies within [`ALIKE_DEG`] and 5 % of its distance of the
    /// first's: the largest angle (degrees) and shift (fraction of the distance) between them.
    pub alike: Option<(f64, f64)>,
}

impl Determination {
    pub fn of(fit: &Fit) -> Determination {
        let mut parameters = Vec::new();
        let mut worst_fraction: f64 = 0.0;
        let cameras = [("left", Some(&fit.left)), ("right", fit.right.as_ref())];
        for (side, camera) in cameras {
            let Some(camera) = camera else { continue };
            let k = camera.camera.matrix();
            for (name, value, std) in [
                ("fx", k[(0, 0)], camera.std[0]),
                ("fy", k[(1, 1)], camera.std[1]),
            ] {
                let fraction = if value.abs() > 0.0 && std.is_finite() {
                    std / value.abs()
                } else {
                    f64::INFINITY
                };
                worst_fraction = worst_fraction.max(fraction);
                if fraction > UNDETERMINED_FRACTION {
                    parameters.push(format!("{side} {name} = {value:.1} ± {std:.1} px"));
                }
            }
        }
        let poses: Vec<_> = fit
            .views
            .iter()
            .filter(|v| v.status == ViewOutcome::Used)
            .filter_map(|v| v.pose.as_ref())
            .collect();
        // Held lenses need no variety of poses: R and T follow from any view.
        let alike = match poses.split_first() {
            _ if fit.held => None,
            Some((first, rest)) if !rest.is_empty() => {
                let distance = first.translation.norm().max(f64::MIN_POSITIVE);
                let angle = rest
                    .iter()
                    .map(|p| (p.rotation * first.rotation.inverse()).angle().to_degrees())
                    .fold(0.0, f64::max);
                let shift = rest
                    .iter()
                    .map(|p| (p.translation - first.translation).norm() / distance)
                    .fold(0.0, f64::max);
                (angle < ALIKE_DEG && shift < 0.05).then_some((angle, shift))
            }
            _ => None,
        };
        Determination {
            parameters,
            worst_fraction,
            alike,
        }
    }

    /// Whether the views determine the model.
    pub fn determined(&self) -> bool {
        self.parameters.is_empty() && self.alike.is_none()
    }

    /// Whether the calibration is beyond use: refused.
    pub fn refused(&self) -> bool {
        self.worst_fraction.is_nan() || self.worst_fraction > REFUSED_FRACTION
    }

    /// What is wrong and what to do, or `None` when the views determine the model.
    pub fn cause(&self) -> Option<String> {
        if self.determined() {
            return None;
        }
        let mut causes = Vec::new();
        if !self.parameters.is_empty() {
            causes.push(format!(
                "{} (a σ over {:.0} % of the value)",
                self.parameters.join(", "),
                UNDETERMINED_FRACTION * 100.0
            ));
        }
        if let Some((angle, shift)) = self.alike {
            causes.push(format!(
                "the views show the board in nearly one pose (within {angle:.1}° and {:.1} % \
                 of its distance of one another)",
                shift * 100.0
            ));
        }
        Some(format!(
            "the calibration is not determined: {}. Views that repeat one pose do not \
             constrain the lens: move and tilt the board between shots, 10 to 20 views at \
             different places and tilts (20–45°), filling the image",
            causes.join("; ")
        ))
    }
}

/// The chessboard most images show instead of the board described: when more than half of
/// the images miss the board because they show one whole chessboard of another size (the
/// same size in each, either way round), that size, as (columns, rows) in the board's own
/// orientation where it can be told, with how many images show it. A user who counted squares instead of inner corners,
/// or swapped a board's sizes for another board's, is told once, not once an image.
pub fn agreed_other_size(
    misses: &[Option<&TargetMiss>],
    board: &Board,
) -> Option<((usize, usize), usize)> {
    let sizes: Vec<(usize, usize)> = misses
        .iter()
        .flatten()
        .filter_map(|m| m.whole_grid())
        .collect();
    let (&size, count) = sizes
        .iter()
        .map(|s| (s, sizes.iter().filter(|t| *t == s).count()))
        .max_by_key(|&(_, count)| count)?;
    if 2 * count <= misses.len() || count < 2 {
        return None;
    }
    // In the board's orientation: the longer side along the longer member.
    let (columns, rows) = (board.columns() as usize, board.rows() as usize);
    let oriented = if columns >= rows {
        size
    } else {
        (size.1, size.0)
    };
    Some((oriented, count))
}

/// A ChArUco board described otherwise than it was printed, as more than half of the images
/// (and at least 2) say.
#[derive(Debug, Clone, PartialEq)]
pub enum CharucoMistake {
    /// The images show markers the board does not have: `highest` is the largest id seen.
    Larger { highest: usize, images: usize },
    /// The images show no marker of the board's dictionary but markers of `dictionary`.
    Dictionary {
        dictionary: Dictionary,
        images: usize,
    },
}

/// The ChArUco board's mistake most images agree on: more than half of them, and at least 2,
/// show markers the board does not have, or another dictionary's. A user who gave the
/// corners for the squares, or the wrong dictionary, is told once, naming the member.
pub fn agreed_charuco_mistake(misses: &[Option<&TargetMiss>]) -> Option<CharucoMistake> {
    let agreed = |count: usize| count >= 2 && 2 * count > misses.len();
    let foreign: Vec<usize> = misses
        .iter()
        .flatten()
        .filter_map(|m| match m {
            TargetMiss::ForeignIds { ids, .. } => ids.last().copied(),
            _ => None,
        })
        .collect();
    if agreed(foreign.len()) {
        return Some(CharucoMistake::Larger {
            highest: foreign.iter().copied().max().unwrap_or(0),
            images: foreign.len(),
        });
    }
    let others: Vec<Dictionary> = misses
        .iter()
        .flatten()
        .filter_map(|m| match m {
            TargetMiss::OtherDictionary { dictionary, .. } => Some(*dictionary),
            _ => None,
        })
        .collect();
    let (&dictionary, images) = others
        .iter()
        .map(|d| (d, others.iter().filter(|e| *e == d).count()))
        .max_by_key(|&(_, count)| count)?;
    agreed(images).then_some(CharucoMistake::Dictionary { dictionary, images })
}

/// Where one camera's corners fell over the views used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coverage {
    /// [min, max] of the corners' x, as fractions of the width, to a thousandth.
    pub x: [f64; 2],
    /// [min, max] of the corners' y, as fractions of the height, to a thousandth.
    pub y: [f64; 2],
    /// The share of a 4 × 4 grid of cells over the image that hold a corner, 0–1.
    pub cells: f64,
}

impl Coverage {
    /// The left (or `right`) camera's corners over the views `fit` used.
    pub fn of(views: &[Corners], fit: &Fit, right: bool, size: Size) -> Coverage {
        let (w, h) = (f64::from(size.width), f64::from(size.height));
        let mut x = [f64::INFINITY, f64::NEG_INFINITY];
        let mut y = [f64::INFINITY, f64::NEG_INFINITY];
        let mut cells = [false; 16];
        for (view, v) in views.iter().zip(&fit.views) {
            if v.status != ViewOutcome::Used {
                continue;
            }
            let corners = if right { &view.right } else { &view.left };
            for c in corners.iter().flatten().flatten() {
                let (fx, fy) = ((c[0] / w).clamp(0.0, 1.0), (c[1] / h).clamp(0.0, 1.0));
                x = [x[0].min(fx), x[1].max(fx)];
                y = [y[0].min(fy), y[1].max(fy)];
                let cell = ((fy * 4.0).min(3.0) as usize) * 4 + (fx * 4.0).min(3.0) as usize;
                cells[cell] = true;
            }
        }
        Coverage {
            x: [round_to(x[0], 3), round_to(x[1], 3)],
            y: [round_to(y[0], 3), round_to(y[1], 3)],
            cells: cells.iter().filter(|&&c| c).count() as f64 / 16.0,
        }
    }

    /// Whether the corners span less than [`MIN_SPAN`] of the image either way.
    pub fn narrow(&self) -> bool {
        self.x[1] - self.x[0] < MIN_SPAN || self.y[1] - self.y[0] < MIN_SPAN
    }
}

/// The board's tilt from facing the left camera in one view, degrees to a hundredth, where
/// its pose was estimated.
pub fn tilt_deg(view: &ViewFit) -> Option<f64> {
    view.pose.map(|p| {
        let z = p.rotation * nalgebra::Vector3::z();
        round_to(z.z.abs().clamp(0.0, 1.0).acos().to_degrees(), 2)
    })
}

/// [min, max] of the board's tilt over the views with a pose.
pub fn tilt_range(fit: &Fit) -> [f64; 2] {
    let tilts: Vec<f64> = fit.views.iter().filter_map(tilt_deg).collect();
    [
        tilts.iter().copied().fold(f64::INFINITY, f64::min),
        tilts.iter().copied().fold(0.0, f64::max),
    ]
}

/// What the rectification of a pair came to, for the warnings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rectified {
    /// One camera: nothing to rectify.
    Alone,
    /// The fitted distortion cannot be inverted over the image.
    Failed,
    /// Rectified, but the cameras are one above the other.
    Vertical,
    /// Rectified into a horizontal rig.
    Horizontal,
}

/// What to shoot again, or check: too few views, corners that missed the image's edges, a
/// board that never tilted, a high RMS, views left out, a pair that could not be rectified.
pub fn warnings(
    fit: &Fit,
    determination: &Determination,
    coverage: [Option<&Coverage>; 2],
    tilt_range: [f64; 2],
    rectified: Rectified,
) -> Vec<String> {
    let mut warnings: Vec<String> = determination.cause().into_iter().collect();
    let used = fit
        .views
        .iter()
        .filter(|v| v.status == ViewOutcome::Used)
        .count();
    // Held lenses (a pair calibrated again from an earlier one) need neither many views nor
    // coverage nor tilt: those fit a lens.
    let lens = !fit.held;
    if lens && used < MIN_GOOD_VIEWS {
        warnings.push(format!(
            "only {used} views were used: 10 to 20 views at different places and tilts give a \
             trustworthy calibration"
        ));
    }
    for (name, c) in ["left", "right"].into_iter().zip(coverage).filter(|_| lens) {
        if let Some(c) = c.filter(|c| c.narrow()) {
            warnings.push(format!(
                "the corners covered only x {:.2}–{:.2} and y {:.2}–{:.2} of the {name} image: \
                 show the board near the edges and corners too, where the distortion is \
                 strongest",
                c.x[0], c.x[1], c.y[0], c.y[1]
            ));
        }
    }
    if lens && tilt_range[1] < MIN_TILT_DEG {
        warnings.push(format!(
            "the board never tilted more than {:.0}°: tilt it 20–45° in some views, or the \
             focal length is poorly determined",
            tilt_range[1]
        ));
    }
    if fit.rms > HIGH_RMS_PX {
        warnings.push(format!(
            "the RMS error is {:.2} px (a good calibration is below 0.5): check that the board is \
             flat, the images sharp and the board's size right",
            fit.rms
        ));
    }
    let outliers: Vec<String> = fit
        .views
        .iter()
        .enumerate()
        .filter(|(_, v)| v.status == ViewOutcome::Outlier)
        .map(|(i, _)| i.to_string())
        .collect();
    if !outliers.is_empty() {
        warnings.push(format!(
            "views {} were left out: their error was far above the others'",
            outliers.join(", ")
        ));
    }
    match rectified {
        Rectified::Failed => warnings.push(
            "the pair could not be rectified: the fitted distortion cannot be inverted over the \
             image (show the board near the image's corners so that the distortion is measured \
             there); no rectification or rig"
                .to_owned(),
        ),
        Rectified::Vertical => warnings.push(
            "the cameras are one above the other: no horizontal rig for /distance".to_owned(),
        ),
        Rectified::Alone => warnings.push(
            "only one camera's images were sent (no `right` parts): this calibrates that camera \
             alone, with no rig, rectification or distance; send a `right` image for each \
             `left` one to calibrate a stereo pair"
                .to_owned(),
        ),
        Rectified::Horizontal => {}
    }
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::boards::solve::Pose;
    use crate::camera::{Camera, Distortion, Intrinsics, Model};
    use nalgebra::{Rotation3, Vector3};

    const SIZE: Size = Size {
        width: 400,
        height: 200,
    };

    /// A fit of one camera over `views`, each used or not, the board tilted by its angle
    /// (degrees) about the x axis.
    fn fit(views: &[(ViewOutcome, f64)], rms: f64) -> Fit {
        let camera = Camera::new(
            Intrinsics {
                fx: 500.0,
                fy: 500.0,
                cx: 200.0,
                cy: 100.0,
            },
            Distortion::new(Model::PlumbBob, &[0.0; 5]).expect("no distortion"),
        )
        .expect("a camera");
        Fit {
            model: Model::PlumbBob,
            size: SIZE,
            left: CameraFit {
                camera,
                std: vec![0.0; 9],
                rms,
            },
            right: None,
            extrinsics: None,
            views: views
                .iter()
                .map(|&(status, tilt)| ViewFit {
                    status,
                    rms_left: Some(rms),
                    rms_right: None,
                    pose: Some(Pose {
                        rotation: Rotation3::from_axis_angle(&Vector3::x_axis(), tilt.to_radians()),
                        translation: Vector3::new(0.0, 0.0, 500.0),
                    }),
                })
                .collect(),
            rms,
            joint: Default::default(),
            held: false,
        }
    }

    use super::super::fit::CameraFit;

    /// The left images' results come first, then the right ones': each view gets its two
    /// boards, or why each was not found.
    #[test]
    fn detections_pair_the_ith_left_with_the_ith_right() {
        let found = [
            Ok(vec![Some([1.0, 2.0])]),
            Err("no board".to_owned()),
            Err("blurred".to_owned()),
            Ok(vec![Some([3.0, 4.0])]),
        ];
        let d = Detections::assemble(&found, true);
        assert_eq!(d.views.len(), 2);
        assert_eq!(d.views[0].left, Some(vec![Some([1.0, 2.0])]));
        assert_eq!(d.views[0].right, None);
        assert_eq!(d.views[1].right, Some(vec![Some([3.0, 4.0])]));
        assert_eq!(d.reasons[0], [None, Some("blurred".to_owned())]);
        assert_eq!(d.reasons[1], [Some("no board".to_owned()), None]);
        let alone = Detections::assemble(&found[..2], false);
        assert_eq!(alone.views.len(), 2);
        assert_eq!(alone.reasons[1], [Some("no board".to_owned()), None]);
    }

    /// Coverage counts only the views used: their span as fractions of the image, and the
    /// 4 × 4 cells they touch.
    #[test]
    fn coverage_spans_the_views_used() {
        let f = fit(
            &[(ViewOutcome::Used, 0.0), (ViewOutcome::Outlier, 0.0)],
            0.2,
        );
        let views = [
            Corners {
                left: Some(vec![Some([40.0, 20.0]), None, Some([360.0, 180.0])]),
                right: None,
            },
            Corners {
                left: Some(vec![Some([0.0, 0.0]), Some([399.0, 199.0]), None]),
                right: None,
            },
        ];
        let c = Coverage::of(&views, &f, false, SIZE);
        assert_eq!((c.x, c.y), ([0.1, 0.9], [0.1, 0.9]));
        assert_eq!(c.cells, 2.0 / 16.0);
        assert!(!c.narrow());
        let right = Coverage::of(&views, &f, true, SIZE);
        assert_eq!(right.cells, 0.0);
    }

    /// The tilt is the angle between the board's normal and the optical axis.
    #[test]
    fn tilt_is_the_boards_angle_to_the_axis() {
        let f = fit(
            &[(ViewOutcome::Used, 30.0), (ViewOutcome::Used, -10.0)],
            0.2,
        );
        assert_eq!(tilt_deg(&f.views[0]), Some(30.0));
        assert_eq!(tilt_range(&f), [10.0, 30.0]);
    }

    /// Too few views, a narrow coverage, a board that never tilted, a high RMS, an outlier and
    /// a failed rectification each give their warning; a good calibration gives none.
    #[test]
    fn warnings_say_what_to_shoot_again() {
        let mut views: Vec<_> = (0..12)
            .map(|k| (ViewOutcome::Used, 20.0 + 2.0 * k as f64))
            .collect();
        let good = fit(&views, 0.2);
        let wide = Coverage {
            x: [0.05, 0.95],
            y: [0.05, 0.95],
            cells: 1.0,
        };
        let none = warnings(
            &good,
            &Determination::of(&good),
            [Some(&wide), None],
            tilt_range(&good),
            Rectified::Horizontal,
        );
        assert!(none.is_empty(), "{none:?}");
        let alone = warnings(
            &good,
            &Determination::of(&good),
            [Some(&wide), None],
            tilt_range(&good),
            Rectified::Alone,
        );
        assert_eq!(alone.len(), 1);
        assert!(
            alone[0].contains("only one camera's images were sent"),
            "{alone:?}"
        );
        views.truncate(4);
        views.push((ViewOutcome::Outlier, 5.0));
        let poor = fit(&views, 1.5);
        let narrow = Coverage {
            x: [0.4, 0.6],
            ..wide
        };
        let all = warnings(
            &poor,
            &Determination::of(&poor),
            [Some(&wide), Some(&narrow)],
            [3.0, 8.0],
            Rectified::Failed,
        );
        let said = |what: &str| all.iter().any(|w| w.contains(what));
        assert!(said("only 4 views were used"), "{all:?}");
        assert!(said("of the right image"), "{all:?}");
        assert!(!said("of the left image"), "{all:?}");
        assert!(said("never tilted more than 8°"), "{all:?}");
        assert!(said("RMS error is 1.50 px"), "{all:?}");
        assert!(said("views 4 were left out"), "{all:?}");
        assert!(said("could not be rectified"), "{all:?}");
        assert_eq!(all.len(), 6);
    }

    /// A focal length whose σ is over 2 % of it is not determined (a warning naming it, the
    /// calibration kept); over 20 % it is refused; views in one pose are not determined
    /// whatever the σ; views at different tilts with a small σ are determined.
    #[test]
    fn a_calibration_the_views_do_not_constrain_is_not_determined() {
        let tilts: Vec<_> = (0..12)
            .map(|k| (ViewOutcome::Used, 20.0 + 2.0 * k as f64))
            .collect();
        let mut f = fit(&tilts, 0.05);
        f.left.std[0] = 1.0;
        let fine = Determination::of(&f);
        assert!(fine.determined() && !fine.refused() && fine.cause().is_none());
        f.left.std[0] = 25.0;
        let poor = Determination::of(&f);
        assert!(!poor.determined() && !poor.refused());
        let cause = poor.cause().unwrap();
        assert!(cause.contains("left fx = 500.0 ± 25.0 px"), "{cause}");
        f.left.std[1] = 400.0;
        assert!(Determination::of(&f).refused());
        let same = fit(&[(ViewOutcome::Used, 30.0); 12], 0.05);
        let repeated = Determination::of(&same);
        assert!(!repeated.determined() && !repeated.refused());
        assert!(repeated.cause().unwrap().contains("nearly one pose"));
    }
}
