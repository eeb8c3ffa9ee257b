//! Renders stereo checkerboard views with exact truth into a folder, for the evaluation
//! against OpenCV (`scripts/eval-calibration`) and for trying other detectors:
//!
//!     cargo run --release --example boards -- OUT_DIR [SEED] [VIEWS] [MODEL]
//!
//! writes `left_NN.png`, `right_NN.png` and `truth.json` (the rig, the board, each view's
//! exact corners in OpenCV's order).

use std::path::PathBuf;

use nalgebra::{Rotation3, Vector3};
use serde_json::json;
use stereo_distance::calibrate::Board;
use stereo_distance::calibrate::synthetic::{Style, poses, stereo_views};
use stereo_distance::camera::{Camera, Distortion, Intrinsics, Model, Size, StereoPair};
use stereo_distance::physics::LengthUnit;
use stereo_distance::vision::synthetic::Rng;

fn main() {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().expect("usage: boards OUT_DIR [SEED] [VIEWS] [MODEL]"));
    let seed: u64 = args.next().map_or(1, |s| s.parse().expect("SEED"));
    let views: usize = args.next().map_or(15, |s| s.parse().expect("VIEWS"));
    let model = args
        .next()
        .map_or(Model::PlumbBob, |s| Model::from_name(&s).expect("MODEL"));
    std::fs::create_dir_all(&out).expect("create OUT_DIR");

    let mut rng = Rng::new(seed ^ 0xC0FFEE);
    let mut jitter = |scale: f64| (f64::from(rng.unit()) - 0.5) * 2.0 * scale;
    let size = Size {
        width: 640,
        height: 480,
    };
    let mut camera = |f: f64| {
        let coefficients: Vec<f64> = match model {
            Model::PlumbBob => vec![-0.25 + jitter(0.05), 0.1 + jitter(0.03), jitter(0.001), jitter(0.001), jitter(0.01)],
            Model::RationalPolynomial => vec![
                0.4 + jitter(0.05), -0.1 + jitter(0.02), jitter(0.001), jitter(0.001), 0.0,
                0.6 + jitter(0.05), -0.05, 0.0,
            ],
            Model::Equidistant => vec![-0.02 + jitter(0.01), 0.005, 0.0, 0.0],
        };
        let f = if model == Model::Equidistant { f * 0.55 } else { f };
        Camera::new(
            Intrinsics {
                fx: f + jitter(10.0),
                fy: f + jitter(10.0),
                cx: 320.0 + jitter(8.0),
                cy: 240.0 + jitter(8.0),
            },
            Distortion::new(model, &coefficients).expect("distortion"),
        )
        .expect("camera")
    };
    let left = camera(800.0);
    let right = camera(800.0);
    let pair = StereoPair {
        left,
        right,
        rotation: Rotation3::from_scaled_axis(Vector3::new(jitter(0.02), jitter(0.03), jitter(0.01))),
        translation: Vector3::new(-120.0 + jitter(5.0), jitter(2.0), jitter(2.0)),
    };
    let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).expect("board");
    let found = poses(&pair, size, &board, views, 40.0, seed);
    let style = Style {
        seed,
        ..Style::default()
    };
    let rendered = stereo_views(&pair, size, &board, &found, &style);
    let mut truth_views = Vec::new();
    for (i, view) in rendered.iter().enumerate() {
        for (side, image) in [("left", &view.left), ("right", &view.right)] {
            image::GrayImage::from_raw(image.width, image.height, image.pixels.clone())
                .expect("image")
                .save(out.join(format!("{side}_{i:02}.png")))
                .expect("write png");
        }
        truth_views.push(json!({"left": view.left_corners, "right": view.right_corners}));
    }
    let cam = |c: &Camera| {
        let k = c.intrinsics();
        json!({"fx": k.fx, "fy": k.fy, "cx": k.cx, "cy": k.cy, "distortion": c.distortion().coefficients()})
    };
    let truth = json!({
        "model": model.name(),
        "image_width": size.width, "image_height": size.height,
        "board": {"columns": board.columns(), "rows": board.rows(), "square_size": board.square_size(), "unit": "mm"},
        "left": cam(&pair.left), "right": cam(&pair.right),
        "rotation": pair.rotation.matrix().transpose().as_slice(),
        "translation": pair.translation.as_slice(),
        "views": truth_views,
    });
    std::fs::write(out.join("truth.json"), serde_json::to_vec_pretty(&truth).expect("json")).expect("write truth");
    println!("{} views in {}", rendered.len(), out.display());
}
