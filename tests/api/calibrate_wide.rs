//! `POST /calibrate?model=equidistant` on a 180° fisheye rig whose boards are held out to the
//! edges of its field (where OpenCV's `fisheye::stereoCalibrate` stops converging): each lens
//! and the pair against the rendered truth.

use nalgebra::{Matrix3, Rotation3, Vector3};
use serde_json::Value;
use stereo_core::calibration::boards::Board;
use stereo_core::calibration::boards::synthetic::{Style, poses_across, stereo_views};
use stereo_core::camera::{Camera, Distortion, Intrinsics, Model, Size, StereoPair};
use stereo_core::physics::LengthUnit;

use crate::calibrate::gray_png;
use crate::calibrate_initial::views_form;
use crate::helpers::{numbers, ok_json, spawn_app};

const SIZE: Size = Size {
    width: 640,
    height: 480,
};

/// A pair of equidistant lenses seeing 180° across 640 px (f = 204 px a radian), 120 mm apart.
fn wide_rig() -> StereoPair {
    let camera = |fx: f64, cx: f64, k1: f64| {
        Camera::new(
            Intrinsics {
                fx,
                fy: fx * 1.002,
                cx,
                cy: 238.0,
            },
            Distortion::new(Model::Equidistant, &[k1, 0.005, 0.0, 0.0]).unwrap(),
        )
        .unwrap()
    };
    StereoPair {
        left: camera(204.0, 321.0, -0.02),
        right: camera(203.0, 318.0, -0.015),
        rotation: Rotation3::from_scaled_axis(Vector3::new(0.004, -0.012, 0.003)),
        translation: Vector3::new(-120.0, 1.0, -0.8),
    }
}

fn matrix(v: &Value) -> Matrix3<f64> {
    Matrix3::from_row_slice(&numbers(v))
}

/// Fifteen views of a 9 × 6 board held out to 72° off the axis of a 180° fisheye pair:
/// `model=equidistant` finds the board in most of them, views out past 60° included, and
/// recovers each lens (f within 0.1 %, the principal point within 0.5 px) and the pair
/// (|T| within 0.2 %, R within 0.05°), the goals of the calibration evaluation.
#[tokio::test]
async fn a_180_degree_fisheye_rig_calibrates_from_boards_at_its_edges() {
    // Arrange
    let app = spawn_app().await;
    let pair = wide_rig();
    let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).unwrap();
    let poses = poses_across(&pair, SIZE, &board, (15, 40.0, 18), 72.0);
    let rendered = stereo_views(&pair, SIZE, &board, &poses, &Style::default());
    let png = |i: &stereo_core::calibration::boards::synthetic::Image| {
        gray_png(i.width as usize, i.height as usize, &i.pixels)
    };
    let views: Vec<_> = rendered
        .iter()
        .map(|v| (png(&v.left), png(&v.right)))
        .collect();
    let board_json = r#"{"columns": 9, "rows": 6, "square_size": 25, "unit": "mm"}"#;

    // Act
    let response = app
        .post_form(
            "/calibrate?model=equidistant",
            views_form(&views, board_json),
        )
        .await;
    let summary = ok_json(response).await;

    // Assert: the views used reach the field's edges.
    let used: Vec<bool> = summary["views"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["status"] == "used")
        .collect();
    assert!(used.iter().filter(|&&u| u).count() >= 11, "{summary}");
    let farthest = rendered
        .iter()
        .zip(&used)
        .filter(|(_, u)| **u)
        .flat_map(|(v, _)| &v.left_corners)
        .map(|&[x, y]| (x - 321.0).hypot(y - 238.0) / 204.0)
        .fold(0.0, f64::max)
        .to_degrees();
    assert!(
        farthest > 60.0,
        "the farthest corner used is {farthest}° off the axis"
    );
    // Each lens and the pair, against the truth.
    for (side, truth) in [("left", &pair.left), ("right", &pair.right)] {
        let k = matrix(&summary[side]["camera_matrix"]);
        let t = truth.intrinsics();
        assert!(
            (k[(0, 0)] / t.fx - 1.0).abs() < 1e-3,
            "{side} fx {}",
            k[(0, 0)]
        );
        assert!(
            (k[(1, 1)] / t.fy - 1.0).abs() < 1e-3,
            "{side} fy {}",
            k[(1, 1)]
        );
        let pp = (k[(0, 2)] - t.cx).hypot(k[(1, 2)] - t.cy);
        assert!(pp < 0.5, "{side} principal point {pp} px off");
    }
    let b = Vector3::from_row_slice(&numbers(&summary["translation"])).norm();
    assert!((b / pair.translation.norm() - 1.0).abs() < 2e-3, "|T| {b}");
    let r = Rotation3::from_matrix_unchecked(matrix(&summary["rotation"]));
    let off = (r * pair.rotation.inverse()).angle().to_degrees();
    assert!(off < 0.05, "R {off}° off");
    println!(
        "180° fisheye: {} of 15 views, out to {farthest:.0}°, rms {}",
        used.iter().filter(|&&u| u).count(),
        summary["rms"]
    );
}
