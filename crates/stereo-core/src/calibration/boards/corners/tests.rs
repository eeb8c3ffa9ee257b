//! The refinement's accuracy on rendered boards with exact corners.

use nalgebra::{Rotation3, Vector3};

use super::*;
use crate::calibration::boards::Board;
use crate::calibration::boards::synthetic::{Style, poses, stereo_views};
use crate::camera::{Camera, Distortion, Intrinsics, Model, Size, StereoPair};
use crate::noise::Rng;
use crate::physics::LengthUnit;

fn pair(model: Model, coefficients: &[f64], f: f64) -> StereoPair {
    pair_centred(model, coefficients, f, [322.0, 237.0])
}

fn pair_centred(model: Model, coefficients: &[f64], f: f64, [cx, cy]: [f64; 2]) -> StereoPair {
    let camera = Camera::new(
        Intrinsics {
            fx: f,
            fy: f * 1.002,
            cx,
            cy,
        },
        Distortion::new(model, coefficients).unwrap(),
    )
    .unwrap();
    StereoPair {
        left: camera,
        right: camera,
        rotation: Rotation3::from_scaled_axis(Vector3::new(0.01, -0.02, 0.005)),
        translation: Vector3::new(-120.0, 1.0, -1.5),
    }
}

/// A board turned by `angle` about its normal and its own `centre`, the centre 600 mm in
/// front of the left camera, a little right of and below its axis.
fn turned_about_its_centre(angle: f64, centre: Vector3<f64>) -> nalgebra::Isometry3<f64> {
    let turn = Rotation3::from_axis_angle(&Vector3::z_axis(), angle);
    nalgebra::Isometry3::from_parts(
        (Vector3::new(60.0, 10.0, 600.0) - turn * centre).into(),
        turn.into(),
    )
}
/// The median and 95th percentile of the refined corners' distance from the truth, started
/// up to a pixel off in each axis, through `refine_all` (the window from the local spacing).
fn errors(pair: &StereoPair, style: &Style, views: usize, seed: u64) -> (f64, f64, usize) {
    let size = Size {
        width: 640,
        height: 480,
    };
    let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).unwrap();
    let found = poses(pair, size, &board, views, 45.0, seed);
    let rendered = stereo_views(pair, size, &board, &found, style);
    let mut rng = Rng::new(seed);
    let mut errors = Vec::new();
    let mut failed = 0;
    for view in &rendered {
        for (image, truth) in [
            (&view.left, &view.left_corners),
            (&view.right, &view.right_corners),
        ] {
            let luma = Luma::from_u8(image.width as usize, image.height as usize, &image.pixels);
            let starts: Vec<[f64; 2]> = truth
                .iter()
                .map(|t| {
                    [
                        t[0] + 2.0 * f64::from(rng.unit()) - 1.0,
                        t[1] + 2.0 * f64::from(rng.unit()) - 1.0,
                    ]
                })
                .collect();
            for (refined, t) in refine_all(&luma, &starts).iter().zip(truth) {
                match refined {
                    Some(r) => errors.push((r.point[0] - t[0]).hypot(r.point[1] - t[1])),
                    None => failed += 1,
                }
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    let n = errors.len();
    (errors[n / 2], errors[n * 95 / 100], failed)
}

/// On boards under perspective, plumb_bob distortion, σ 0.7 px blur and 1.5 grey levels of
/// noise, the median corner error is at most 0.02 px (the issue asks 0.05; OpenCV's
/// `cornerSubPix` 11 × 11 reaches 0.031 on such boards), and every corner refines.
#[test]
fn refines_rendered_corners_to_hundredths_of_a_pixel() {
    let pair = pair(Model::PlumbBob, &[-0.25, 0.1, 0.001, -0.0005, -0.01], 800.0);
    let (median, p95, failed) = errors(&pair, &Style::default(), 3, 7);
    eprintln!("plumb_bob: median {median:.4} px, p95 {p95:.4} px, failed {failed}");
    assert!(median <= 0.02, "median {median}");
    assert!(p95 <= 0.06, "p95 {p95}");
    assert_eq!(failed, 0);
}

/// Heavier blur (σ 1.5 px), 2 grey levels of noise and a dim exposure through a fisheye
/// lens: the median stays within 0.05 px, unbiased by the blur.
#[test]
fn blur_and_a_fisheye_do_not_bias_the_corner() {
    let pair = pair(Model::Equidistant, &[-0.02, 0.004, 0.0, 0.0], 440.0);
    let style = Style {
        blur: 1.5,
        noise: 2.0,
        exposure: 160.0,
        seed: 3,
        ..Style::default()
    };
    assert_median_within(0.05, "fisheye, blurred", &pair, &style, 3, 11);
}

/// Every corner of `views` rendered views refined, with the median within `limit` px.
fn assert_median_within(
    limit: f64,
    label: &str,
    pair: &StereoPair,
    style: &Style,
    views: usize,
    seed: u64,
) {
    let (median, p95, failed) = errors(pair, style, views, seed);
    eprintln!("{label}: median {median:.4} px, p95 {p95:.4} px, failed {failed}");
    assert!(median <= limit, "median {median}");
    assert_eq!(failed, 0);
}

/// A start that is not a number, or one too near the border for the window, is refused,
/// never read outside the image.
#[test]
fn refuses_starts_it_cannot_use() {
    let luma = Luma::from_u8(32, 32, &[128; 32 * 32]);
    for start in [
        [f64::NAN, 16.0],
        [16.0, f64::INFINITY],
        [1.0, 16.0],
        [16.0, 31.0],
    ] {
        assert_eq!(refine(&luma, start, 4.0), None, "{start:?}");
    }
    assert_eq!(refine(&luma, [16.0, 16.0], f64::NAN), None);
}

/// Renders `views` stereo views of `board` and returns, for each image, the found corners
/// (or the miss) beside the truth.
type Found = Vec<(Result<Vec<[f64; 2]>, Miss>, Vec<[f64; 2]>)>;

fn find_rendered(board: &Board, poses: &[nalgebra::Isometry3<f64>], pair: &StereoPair) -> Found {
    let size = Size {
        width: 640,
        height: 480,
    };
    let rendered = stereo_views(pair, size, board, poses, &Style::default());
    let mut out = Vec::new();
    for view in rendered {
        for (image, truth) in [
            (view.left, view.left_corners),
            (view.right, view.right_corners),
        ] {
            let luma = Luma::from_u8(image.width as usize, image.height as usize, &image.pixels);
            out.push((find_board(&luma, board), truth));
        }
    }
    out
}

fn worst_error(found: &[[f64; 2]], truth: &[[f64; 2]]) -> f64 {
    found
        .iter()
        .zip(truth)
        .map(|(f, t)| (f[0] - t[0]).hypot(f[1] - t[1]))
        .fold(0.0, f64::max)
}

/// Every image of a 9 × 6 board seen through a distorted lens from random tilted poses is
/// found, with all 54 corners in OpenCV's order (each within 0.15 px of the truth, so none
/// is swapped), in both cameras.
#[test]
fn finds_the_whole_board_in_opencv_order() {
    let pair = pair(Model::PlumbBob, &[-0.25, 0.1, 0.001, -0.0005, -0.01], 800.0);
    let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).unwrap();
    let size = Size {
        width: 640,
        height: 480,
    };
    let found = find_rendered(&board, &poses(&pair, size, &board, 4, 45.0, 21), &pair);
    assert_eq!(found.len(), 8);
    for (k, (result, truth)) in found.iter().enumerate() {
        let corners = result.as_ref().unwrap_or_else(|m| panic!("image {k}: {m}"));
        assert_eq!(corners.len(), 54);
        let worst = worst_error(corners, truth);
        assert!(worst < 0.15, "image {k}: worst corner {worst} px");
    }
}

/// A board held upside down is still ordered from its own corner (0, 0): the colours decide
/// where a 9 × 6 board starts, not the image.
#[test]
fn an_upside_down_board_keeps_its_order() {
    let pair = pair(Model::PlumbBob, &[-0.1, 0.02, 0.0, 0.0, 0.0], 800.0);
    let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).unwrap();
    let pose = turned_about_its_centre(std::f64::consts::PI, Vector3::new(100.0, 62.5, 0.0));
    let found = find_rendered(&board, &[pose], &pair);
    for (result, truth) in &found {
        let corners = result.as_ref().expect("board found");
        // Neighbours are 30 px apart: 0.5 px tells the order (an axis-aligned board's
        // supersampled edges are a tenth of a pixel off, a rendering artefact).
        let worst = worst_error(corners, truth);
        assert!(worst < 0.5, "worst {worst}");
    }
}

/// An 8 × 6 board looks the same after a half turn; upside down, both cameras then order it
/// the same way (rows running rightward in the image), each the truth's order reversed.
#[test]
fn a_symmetric_board_is_ordered_alike_in_both_cameras() {
    let pair = pair(Model::PlumbBob, &[-0.1, 0.02, 0.0, 0.0, 0.0], 800.0);
    let board = Board::new(8, 6, 25.0, LengthUnit::Millimetre).unwrap();
    let pose = turned_about_its_centre(std::f64::consts::PI - 0.2, Vector3::new(87.5, 62.5, 0.0));
    let found = find_rendered(&board, &[pose], &pair);
    for (result, truth) in &found {
        let corners = result.as_ref().expect("board found");
        let reversed: Vec<[f64; 2]> = truth.iter().rev().copied().collect();
        assert!(worst_error(corners, &reversed) < 0.5);
        assert!(corners[7][0] > corners[0][0], "rows run rightward");
    }
}

/// A board of another size in the image is a miss that says what was found, not a
/// wrong ordering: a smaller board named is a larger chessboard found, a larger one (the
/// squares counted) the whole grid found and no more; a blank image has no grid; an image too small to hold one is not searched.
#[test]
fn a_board_of_another_size_is_a_miss() {
    let pair = pair(Model::PlumbBob, &[-0.1, 0.02, 0.0, 0.0, 0.0], 800.0);
    let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).unwrap();
    let size = Size {
        width: 640,
        height: 480,
    };
    let views = find_rendered(&board, &poses(&pair, size, &board, 1, 20.0, 5), &pair);
    let other = Board::new(7, 6, 25.0, LengthUnit::Millimetre).unwrap();
    let rendered = stereo_views(
        &pair,
        size,
        &board,
        &poses(&pair, size, &board, 1, 20.0, 5),
        &Style::default(),
    );
    let luma = Luma::from_u8(640, 480, &rendered[0].left.pixels);
    assert!(views[0].0.is_ok());
    assert_eq!(
        find_board(&luma, &other),
        Err(Miss::Larger {
            columns: 9,
            rows: 6
        })
    );
    // Squares counted instead of inner corners: the grid does not grow past the board's
    // last corners into its border, and the whole 9 × 6 grid found is named.
    let squares = Board::new(10, 7, 25.0, LengthUnit::Millimetre).unwrap();
    assert_eq!(
        find_board(&luma, &squares),
        Err(Miss::Incomplete {
            found: 54,
            columns: 9,
            rows: 6
        })
    );
    let blank = Luma::from_u8(64, 48, &[200; 64 * 48]);
    assert_eq!(find_board(&blank, &board), Err(Miss::NoGrid));
    for (w, h) in [(1, 1), (31, 200), (200, 2)] {
        let tiny = Luma::from_u8(w, h, &vec![0; w * h]);
        assert_eq!(find_board(&tiny, &board), Err(Miss::TooSmall), "{w} × {h}");
    }
}

/// A corner blurred by σ 4 px is fitted again in a window of 3σ: in the 8 px window alone a
/// blurred corner's shift looks like a slope of the light, and the median error was 0.07 px
/// on these boards; with the wider window it stays within 0.05 px.
#[test]
fn a_heavily_blurred_corner_is_fitted_in_a_wider_window() {
    let pair = pair(Model::PlumbBob, &[-0.2, 0.08, 0.0, 0.0, 0.0], 800.0);
    let style = Style {
        blur: 4.0,
        noise: 2.0,
        seed: 5,
        ..Style::default()
    };
    assert_median_within(0.05, "blur 4 px", &pair, &style, 3, 13);
}

/// A 1920 × 1080 image is searched at half size and refined at full size: the whole board
/// is found in OpenCV's order, with the median corner within 0.05 px of the truth.
#[test]
fn a_large_image_is_searched_shrunk_and_refined_at_full_size() {
    let size = Size {
        width: 1920,
        height: 1080,
    };
    assert_eq!(size.width.div_ceil(super::find::DETECTION_SIDE as u32), 2);
    let pair = pair_centred(
        Model::PlumbBob,
        &[-0.2, 0.08, 0.0, 0.0, 0.0],
        2300.0,
        [955.0, 545.0],
    );
    let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).unwrap();
    let style = Style {
        blur: 2.0,
        supersampling: 2,
        ..Style::default()
    };
    let found = poses(&pair, size, &board, 1, 40.0, 3);
    let mut errors = Vec::new();
    for view in stereo_views(&pair, size, &board, &found, &style) {
        for (image, truth) in [
            (view.left, view.left_corners),
            (view.right, view.right_corners),
        ] {
            let luma = Luma::from_u8(image.width as usize, image.height as usize, &image.pixels);
            let corners = find_board(&luma, &board).unwrap();
            assert!(worst_error(&corners, &truth) < 0.3);
            errors.extend(
                corners
                    .iter()
                    .zip(&truth)
                    .map(|(c, t)| (c[0] - t[0]).hypot(c[1] - t[1])),
            );
        }
    }
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    eprintln!(
        "1920 x 1080: median {median:.4} px over {} corners",
        errors.len()
    );
    assert!(median <= 0.05, "median {median}");
}

/// OpenCV's 13 stereo pairs of real 640 × 480 photographs (`samples/data`, shipped by
/// Debian's `opencv-doc`; Apache-2.0 / BSD-3-Clause): a 9 × 6 board held by a person in an
/// office, beside a monitor that shows checkerboards, close and barrel-distorted or tilted
/// about 35°. OpenCV's `findChessboardCorners` finds the board in all 26 images, and so does
/// the finder: the monitor's and the shirt's junctions never join the board's grid, and a
/// corner the detector missed is found where its neighbours put it.
#[test]
fn finds_every_board_in_real_photographs() {
    let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).unwrap();
    let dir = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../tests/data/photographs/opencv-stereo"
    );
    let mut missed = Vec::new();
    for side in ["left", "right"] {
        for n in [
            "01", "02", "03", "04", "05", "06", "07", "08", "09", "11", "12", "13", "14",
        ] {
            let name = format!("{side}{n}.jpg");
            let image = image::open(format!("{dir}/{name}")).unwrap().to_luma8();
            let luma = Luma::from_u8(
                image.width() as usize,
                image.height() as usize,
                image.as_raw(),
            );
            match find_board(&luma, &board) {
                Ok(corners) => assert_eq!(corners.len(), 54, "{name}"),
                Err(miss) => missed.push(format!("{name}: {miss}")),
            }
        }
    }
    assert!(missed.is_empty(), "{missed:#?}");
}
