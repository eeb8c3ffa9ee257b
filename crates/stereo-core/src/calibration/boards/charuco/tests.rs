//! ChArUco boards: OpenCV's layout, ids and object points, the members' faults, and the
//! corners found on rendered boards against their exact truth, whole and partly out of frame.

use nalgebra::{Isometry3, Point3, Rotation3, Vector3};

use super::*;
use crate::calibration::boards::corners::Luma;
use crate::calibration::boards::synthetic::{Rays, Style};
use crate::camera::{Camera, Distortion, Intrinsics, Model, Size};

fn spec(squares_x: u32, squares_y: u32, legacy: bool) -> CharucoSpec {
    CharucoSpec {
        squares_x,
        squares_y,
        square_size: 30.0,
        marker_size: 22.0,
        dictionary: Dictionary::Dict4x4_50,
        legacy,
        unit: LengthUnit::Millimetre,
    }
}

/// The markers sit where OpenCV 4.14 puts them (`CharucoBoard((5, 4), 30, 22, DICT_4X4_50)`
/// `.getObjPoints()`, first corners printed from Python), in the modern and legacy patterns,
/// and the inner corners' ids and points are `getChessboardCorners()`'s.
#[test]
fn the_layout_is_opencvs() {
    let first_corner = |b: &CharucoBoard| -> Vec<[f64; 2]> {
        b.marker_squares()
            .iter()
            .map(|&sq| b.marker_corners(sq)[0])
            .collect()
    };
    let modern = CharucoBoard::new(spec(5, 4, false)).unwrap();
    assert_eq!(
        first_corner(&modern),
        [
            [34.0, 4.0],
            [94.0, 4.0],
            [4.0, 34.0],
            [64.0, 34.0],
            [124.0, 34.0],
            [34.0, 64.0],
            [94.0, 64.0],
            [4.0, 94.0],
            [64.0, 94.0],
            [124.0, 94.0]
        ]
    );
    let legacy = CharucoBoard::new(spec(5, 4, true)).unwrap();
    assert_eq!(
        first_corner(&legacy)[..5],
        [
            [4.0, 4.0],
            [64.0, 4.0],
            [124.0, 4.0],
            [34.0, 34.0],
            [94.0, 34.0]
        ]
    );
    // The legacy pattern differs only for an even number of rows.
    assert_eq!(
        CharucoBoard::new(spec(5, 5, true))
            .unwrap()
            .marker_squares(),
        CharucoBoard::new(spec(5, 5, false))
            .unwrap()
            .marker_squares()
    );
    assert_eq!(modern.marker_corners((1, 0))[2], [56.0, 26.0]);
    assert_eq!(modern.corner_count(), 12);
    assert_eq!(modern.corner_point(0), Vector3::new(30.0, 30.0, 0.0));
    assert_eq!(modern.corner_point(4), Vector3::new(30.0, 60.0, 0.0));
    assert_eq!(modern.marker_id((4, 1)), Some(4));
    assert_eq!(modern.marker_id((0, 0)), None);
}

/// The dictionaries are OpenCV's: their sizes, bits and correction, and the first code of
/// `DICT_4X4_50` as `Dictionary.getBitsFromByteList` gives it (1 white, row by row).
#[test]
fn the_dictionaries_are_opencvs() {
    let sizes: Vec<(usize, usize, u32)> = Dictionary::ALL
        .iter()
        .map(|d| (d.codes().len(), d.bits(), d.correction()))
        .collect();
    assert_eq!(sizes, [(50, 4, 1), (100, 5, 3), (250, 6, 5), (1024, 5, 1)]);
    assert_eq!(Dictionary::Dict4x4_50.codes()[0], 0xb532);
    assert_eq!(
        Dictionary::named("DICT_6X6_250"),
        Some(Dictionary::Dict6x6_250)
    );
    assert_eq!(Dictionary::named("DICT_7X7_50"), None);
}

/// Every fault of a board is named at once: sides too small, a marker as large as its square,
/// and a dictionary too small for the board.
#[test]
fn faults_name_each_member() {
    let members = |s: CharucoSpec| -> Vec<&'static str> {
        CharucoBoard::new(s)
            .unwrap_err()
            .iter()
            .map(|f| f.member.name())
            .collect()
    };
    assert_eq!(members(spec(1, 1, false)), ["squares_x", "squares_y"]);
    let big_marker = CharucoSpec {
        marker_size: 30.0,
        ..spec(5, 4, false)
    };
    assert_eq!(members(big_marker), ["marker_size"]);
    // 12 × 10 squares hold 60 markers; DICT_4X4_50 has 50.
    assert_eq!(members(spec(12, 10, false)), ["dictionary"]);
    let roomy = CharucoSpec {
        dictionary: Dictionary::Dict5x5_100,
        ..spec(12, 10, false)
    };
    assert!(CharucoBoard::new(roomy).is_ok());
}

fn camera(model: Model, coefficients: &[f64]) -> Camera {
    Camera::new(
        Intrinsics {
            fx: 620.0,
            fy: 621.0,
            cx: 322.0,
            cy: 238.0,
        },
        Distortion::new(model, coefficients).unwrap(),
    )
    .unwrap()
}

/// The board's corners found in a render of it at `pose`, against where the lens puts them:
/// (ids found, ids in the frame, worst error px).
fn found_against_truth(
    board: &CharucoBoard,
    camera: &Camera,
    pose: &Isometry3<f64>,
) -> (Vec<usize>, Vec<usize>, f64) {
    let size = Size {
        width: 640,
        height: 480,
    };
    let rays = Rays::new(camera, size, 3);
    let image = render::render(board, pose, &rays, &Style::default());
    let luma = Luma::from_u8(640, 480, &image.pixels);
    let found = find_charuco(&luma, board);
    let truth: Vec<Option<[f64; 2]>> = (0..board.corner_count())
        .map(|id| {
            camera
                .project(&(pose * Point3::from(board.corner_point(id))).coords)
                .filter(|p| p[0] > 6.0 && p[1] > 6.0 && p[0] < 634.0 && p[1] < 474.0)
        })
        .collect();
    let mut worst: f64 = 0.0;
    for (id, p) in found.ids.iter().zip(&found.points) {
        let t = truth[*id].expect("a corner found outside the frame");
        worst = worst.max((p[0] - t[0]).hypot(p[1] - t[1]));
    }
    let inside = (0..truth.len()).filter(|&i| truth[i].is_some()).collect();
    (found.ids, inside, worst)
}

/// A whole board tilted 30° through each lens model: every corner is found with its own id,
/// within 0.15 px of the truth.
#[test]
fn finds_every_corner_of_a_whole_board_with_its_id() {
    let board = CharucoBoard::new(CharucoSpec {
        squares_x: 8,
        squares_y: 6,
        square_size: 30.0,
        marker_size: 22.0,
        dictionary: Dictionary::Dict5x5_100,
        legacy: false,
        unit: LengthUnit::Millimetre,
    })
    .unwrap();
    let pose = Isometry3::from_parts(
        Vector3::new(-125.0, -80.0, 520.0).into(),
        (Rotation3::from_euler_angles(0.3, -0.35, 0.1)).into(),
    );
    for (model, k) in [
        (Model::PlumbBob, vec![-0.28, 0.09, 0.001, -0.0005, 0.0]),
        (
            Model::RationalPolynomial,
            vec![0.4, -0.1, 0.0, 0.0, 0.0, 0.7, -0.05, 0.0],
        ),
        (Model::Equidistant, vec![-0.05, 0.01, -0.004, 0.0]),
    ] {
        let (ids, inside, worst) = found_against_truth(&board, &camera(model, &k), &pose);
        assert_eq!(ids, inside, "{model:?}");
        assert_eq!(ids.len(), 35);
        assert!(worst < 0.15, "{model:?}: worst {worst:.3} px");
    }
}

/// A board half out of the frame, as ChArUco is for: the corners it shows are found with
/// their ids and none that it does not show.
#[test]
fn a_board_partly_out_of_the_frame_gives_the_corners_it_shows() {
    let board = CharucoBoard::new(CharucoSpec {
        squares_x: 10,
        squares_y: 7,
        square_size: 30.0,
        marker_size: 22.0,
        dictionary: Dictionary::Dict6x6_250,
        legacy: false,
        unit: LengthUnit::Millimetre,
    })
    .unwrap();
    // The board's left part runs off the image's right edge.
    let pose = Isometry3::from_parts(
        Vector3::new(30.0, -90.0, 480.0).into(),
        (Rotation3::from_euler_angles(-0.1, 0.25, 0.05)).into(),
    );
    let cam = camera(Model::PlumbBob, &[-0.2, 0.05, 0.0, 0.0, 0.0]);
    let (ids, inside, worst) = found_against_truth(&board, &cam, &pose);
    assert!(
        inside.len() < board.corner_count() && inside.len() >= 15,
        "{} inside",
        inside.len()
    );
    assert!(ids.iter().all(|id| inside.contains(id)));
    assert!(
        ids.len() + 6 >= inside.len(),
        "{} of {} found",
        ids.len(),
        inside.len()
    );
    assert!(worst < 0.15, "worst {worst:.3} px");
}

/// A pair calibrated from rendered ChArUco views, a third of them with the board partly out
/// of the left camera's frame (past its right edge): those views count too, and the rig comes back within the
/// chessboard's goals (f within 0.1 %, principal point within 1 px, |T| within 0.2 %, the
/// rotation within 0.05°).
#[test]
fn calibrates_a_pair_from_whole_and_partial_views() {
    use crate::calibration::boards::synthetic::right_pose;
    use crate::calibration::boards::{Corners, ViewOutcome, calibrate};
    use crate::camera::StereoPair;
    let board = CharucoBoard::new(CharucoSpec {
        squares_x: 9,
        squares_y: 7,
        square_size: 25.0,
        marker_size: 18.0,
        dictionary: Dictionary::Dict5x5_100,
        legacy: false,
        unit: LengthUnit::Millimetre,
    })
    .unwrap();
    let size = Size {
        width: 640,
        height: 480,
    };
    let left = camera(Model::PlumbBob, &[-0.25, 0.1, 0.0008, -0.0004, -0.02]);
    let right = Camera::new(
        Intrinsics {
            fx: 615.0,
            fy: 616.5,
            cx: 318.0,
            cy: 242.0,
        },
        Distortion::new(Model::PlumbBob, &[-0.22, 0.08, -0.0005, 0.0006, -0.01]).unwrap(),
    )
    .unwrap();
    let pair = StereoPair {
        left,
        right,
        rotation: Rotation3::from_scaled_axis(Vector3::new(0.01, -0.02, 0.005)),
        translation: Vector3::new(-120.0, 1.0, -1.5),
    };
    let rays = [
        Rays::new(&pair.left, size, 3),
        Rays::new(&pair.right, size, 3),
    ];
    let style = Style::default();
    let mut partial = 0;
    let views: Vec<Corners> = render::partial_poses(&pair, size, &board, 12, 5, 600.0)
        .unwrap()
        .iter()
        .map(|pose| {
            let seen = |side: usize, pose: &Isometry3<f64>| {
                let image = render::render(&board, pose, &rays[side], &style);
                let found = find_charuco(&Luma::from_u8(640, 480, &image.pixels), &board);
                found
                    .usable(board.corner_columns())
                    .then(|| found.seen(board.corner_count()))
            };
            let view = Corners {
                left: seen(0, pose),
                right: seen(1, &right_pose(&pair, pose)),
            };
            let count = |c: &Option<Vec<Option<[f64; 2]>>>| {
                c.as_ref().map_or(0, |c| c.iter().flatten().count())
            };
            if count(&view.left) < board.corner_count() && view.left.is_some() {
                partial += 1;
            }
            view
        })
        .collect();
    let counts: Vec<[usize; 2]> = views
        .iter()
        .map(|v| [&v.left, &v.right].map(|c| c.as_ref().map_or(0, |c| c.iter().flatten().count())))
        .collect();
    assert!(partial >= 3, "{partial} partial views: {counts:?}");
    let fit = calibrate(&board.object_points(), size, Model::PlumbBob, &views, true).unwrap();
    let used = fit
        .views
        .iter()
        .filter(|v| v.status == ViewOutcome::Used)
        .count();
    assert_eq!(used, 12, "{:?}", fit.views);
    let got = fit.pair().unwrap();
    for (truth, found) in [(&pair.left, &got.left), (&pair.right, &got.right)] {
        let (t, g) = (truth.intrinsics(), found.intrinsics());
        assert!(
            (g.fx / t.fx - 1.0).abs() < 1e-3,
            "fx {} against {}",
            g.fx,
            t.fx
        );
        assert!(
            (g.fy / t.fy - 1.0).abs() < 1e-3,
            "fy {} against {}",
            g.fy,
            t.fy
        );
        assert!(
            (g.cx - t.cx).hypot(g.cy - t.cy) < 1.0,
            "{g:?} against {t:?}"
        );
    }
    let t = got.translation.norm() / pair.translation.norm() - 1.0;
    assert!(t.abs() < 2e-3, "|T| off by {t}");
    let turn = (got.rotation * pair.rotation.inverse())
        .angle()
        .to_degrees();
    assert!(turn < 0.05, "rotation off by {turn}°");
    assert!(fit.rms < 0.2, "RMS {}", fit.rms);
}
