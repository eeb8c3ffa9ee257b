//! The refinement's accuracy on rendered boards with exact corners.

use nalgebra::{Rotation3, Vector3};

use super::*;
use crate::calibrate::Board;
use crate::calibrate::synthetic::{Style, poses, stereo_views};
use crate::camera::{Camera, Distortion, Intrinsics, Model, Size, StereoPair};
use crate::physics::LengthUnit;
use crate::vision::synthetic::Rng;

fn pair(model: Model, coefficients: &[f64], f: f64) -> StereoPair {
    let camera = Camera::new(
        Intrinsics {
            fx: f,
            fy: f * 1.002,
            cx: 322.0,
            cy: 237.0,
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
    let (median, p95, failed) = errors(&pair, &style, 3, 11);
    eprintln!("fisheye, blurred: median {median:.4} px, p95 {p95:.4} px, failed {failed}");
    assert!(median <= 0.05, "median {median}");
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
