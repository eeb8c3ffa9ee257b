//! Checkerboards for the evaluation against OpenCV (`scripts/evaluate/corners`) and for trying
//! other detectors:
//!
//!     cargo run --release --example boards -- render DIR [SEED] [VIEWS] [MODEL]
//!     cargo run --release --example boards -- refine DIR
//!     cargo run --release --example boards -- calibrate DIR
//!     cargo run --release --example boards -- charuco DIR
//!
//! `render` writes stereo views with exact truth: `left_NN.png`, `right_NN.png` and
//! `truth.json` (the rig, the board, each view's exact corners in OpenCV's order). `refine`
//! reads `DIR/starts.json` (`{"left_00.png": [[x, y], …], …}`, corners found by another
//! detector) and writes `DIR/refined.json` in the same shape, each corner refined by
//! `calibrate::corners::refine` with a window of half the distance to its nearest neighbour.
//! `calibrate` finds the board in every image of DIR (as `render` wrote it), calibrates the
//! pair and prints the result and its time as JSON. `charuco` reads `DIR/board.json`
//! (`squares_x`, `squares_y`, `square_size`, `marker_size`, `dictionary`, `legacy`) and each
//! `DIR/*.png`, and prints `{"file.png": {"ids": […], "points": [[x, y], …], "ms": …}, …}`:
//! the ChArUco corners found by `calibration::boards::charuco` and the time each took.

use std::path::PathBuf;

use nalgebra::{Rotation3, Vector3};
use serde_json::json;
use stereo_core::calibration::boards::Board;
use stereo_core::calibration::boards::charuco::{
    CharucoBoard, CharucoSpec, Dictionary, find_charuco,
};
use stereo_core::calibration::boards::corners::{self, Luma};
use stereo_core::calibration::boards::synthetic::{Style, poses, poses_across, stereo_views};
use stereo_core::camera::{Camera, Distortion, Intrinsics, Model, Size, StereoPair};
use stereo_core::physics::LengthUnit;
use stereo_core::vision::synthetic::Rng;

const USAGE: &str = "usage: boards render DIR [SEED] [VIEWS] [MODEL] [FOV_DEG] | boards refine DIR | boards calibrate DIR \
     | boards charuco DIR";

fn main() {
    let mut args = std::env::args().skip(1);
    match args.next().as_deref() {
        Some("render") => render(args),
        Some("refine") => refine(&PathBuf::from(args.next().expect(USAGE))),
        Some("calibrate") => calibrate(&PathBuf::from(args.next().expect(USAGE))),
        Some("charuco") => charuco(&PathBuf::from(args.next().expect(USAGE))),
        _ => panic!("{USAGE}"),
    }
}

fn refine(dir: &std::path::Path) {
    let starts: std::collections::BTreeMap<String, Vec<[f64; 2]>> =
        serde_json::from_slice(&std::fs::read(dir.join("starts.json")).expect("starts.json"))
            .expect("starts.json");
    let mut refined = serde_json::Map::new();
    for (name, points) in starts {
        let image = image::open(dir.join(&name)).expect("image").to_luma8();
        let luma = Luma::from_u8(
            image.width() as usize,
            image.height() as usize,
            image.as_raw(),
        );
        let corners: Vec<Option<[f64; 2]>> = corners::refine_all(&luma, &points)
            .iter()
            .map(|r| r.map(|r| r.point))
            .collect();
        refined.insert(name, json!(corners));
    }
    std::fs::write(
        dir.join("refined.json"),
        serde_json::to_vec(&refined).expect("json"),
    )
    .expect("write refined.json");
}

fn calibrate(dir: &std::path::Path) {
    use rayon::prelude::*;
    use stereo_core::calibration::boards::{self, Corners, whole};
    let truth: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("truth.json")).expect("truth.json"))
            .expect("truth.json");
    let model = Model::from_name(truth["model"].as_str().expect("model")).expect("model");
    let count = truth["views"].as_array().expect("views").len();
    let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).expect("board");
    let images: Vec<Luma> = (0..count)
        .flat_map(|i| ["left", "right"].map(|side| dir.join(format!("{side}_{i:02}.png"))))
        .map(|path| {
            let image = image::open(path).expect("image").to_luma8();
            Luma::from_u8(
                image.width() as usize,
                image.height() as usize,
                image.as_raw(),
            )
        })
        .collect();
    let started = std::time::Instant::now();
    let found: Vec<Option<Vec<[f64; 2]>>> = images
        .par_iter()
        .map(|luma| corners::find_board(luma, &board).ok())
        .collect();
    let views: Vec<Corners> = found
        .chunks(2)
        .map(|pair| Corners {
            left: pair[0].as_deref().map(whole),
            right: pair[1].as_deref().map(whole),
        })
        .collect();
    let detected = started.elapsed();
    let size = Size {
        width: images[0].width as u32,
        height: images[0].height as u32,
    };
    let fit =
        boards::calibrate(&board.object_points(), size, model, &views, true).expect("calibration");
    let total = started.elapsed();
    let pair = fit.pair().expect("pair");
    let cam = |c: &Camera| {
        let k = c.intrinsics();
        json!({"fx": k.fx, "fy": k.fy, "cx": k.cx, "cy": k.cy, "distortion": c.distortion().coefficients()})
    };
    let out = json!({
        "left": cam(&pair.left), "right": cam(&pair.right),
        "rotation": pair.rotation.matrix().transpose().as_slice(),
        "translation": pair.translation.as_slice(),
        "rms": fit.rms,
        "found": found.iter().filter(|f| f.is_some()).count(),
        "used": fit.views.iter().filter(|v| v.status == boards::ViewOutcome::Used).count(),
        "detect_ms": detected.as_secs_f64() * 1e3,
        "total_ms": total.as_secs_f64() * 1e3,
    });
    println!("{out}");
}

fn render(mut args: impl Iterator<Item = String>) {
    let out = PathBuf::from(args.next().expect(USAGE));
    let seed: u64 = args.next().map_or(1, |s| s.parse().expect("SEED"));
    let views: usize = args.next().map_or(15, |s| s.parse().expect("VIEWS"));
    let model = args
        .next()
        .map_or(Model::PlumbBob, |s| Model::from_name(&s).expect("MODEL"));
    // A field of view across (equidistant only): the lens's f is the width over that angle,
    // and the boards are held out to its edges.
    let fov: Option<f64> = args.next().map(|s| s.parse().expect("FOV_DEG"));
    std::fs::create_dir_all(&out).expect("create OUT_DIR");

    let mut rng = Rng::new(seed ^ 0xC0FFEE);
    let mut jitter = |scale: f64| (f64::from(rng.unit()) - 0.5) * 2.0 * scale;
    let size = Size {
        width: 640,
        height: 480,
    };
    let mut camera = |f: f64| {
        let coefficients: Vec<f64> = match model {
            Model::PlumbBob => vec![
                -0.25 + jitter(0.05),
                0.1 + jitter(0.03),
                jitter(0.001),
                jitter(0.001),
                jitter(0.01),
            ],
            Model::RationalPolynomial => vec![
                0.4 + jitter(0.05),
                -0.1 + jitter(0.02),
                jitter(0.001),
                jitter(0.001),
                0.0,
                0.6 + jitter(0.05),
                -0.05,
                0.0,
            ],
            Model::Equidistant => vec![-0.02 + jitter(0.01), 0.005, 0.0, 0.0],
        };
        let f = match (model, fov) {
            (Model::Equidistant, Some(fov)) => 320.0 / (fov / 2.0).to_radians(),
            (Model::Equidistant, None) => f * 0.55,
            _ => f,
        };
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
        rotation: Rotation3::from_scaled_axis(Vector3::new(
            jitter(0.02),
            jitter(0.03),
            jitter(0.01),
        )),
        translation: Vector3::new(-120.0 + jitter(5.0), jitter(2.0), jitter(2.0)),
    };
    let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).expect("board");
    let found = match fov {
        Some(fov) => poses_across(&pair, size, &board, (views, 40.0, seed), 0.8 * fov / 2.0),
        None => poses(&pair, size, &board, views, 40.0, seed),
    };
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
    std::fs::write(
        out.join("truth.json"),
        serde_json::to_vec_pretty(&truth).expect("json"),
    )
    .expect("write truth");
    println!("{} views in {}", rendered.len(), out.display());
}

fn charuco(dir: &std::path::Path) {
    let spec: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("board.json")).expect("board.json"))
            .expect("board.json is JSON");
    let number = |key: &str| spec[key].as_f64().expect(key);
    let board = CharucoBoard::new(CharucoSpec {
        squares_x: number("squares_x") as u32,
        squares_y: number("squares_y") as u32,
        square_size: number("square_size"),
        marker_size: number("marker_size"),
        dictionary: Dictionary::named(spec["dictionary"].as_str().expect("dictionary"))
            .expect("a known dictionary"),
        legacy: spec["legacy"].as_bool().unwrap_or(false),
        unit: LengthUnit::Millimetre,
    })
    .expect("a valid board");
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("DIR")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    files.sort();
    let mut out = serde_json::Map::new();
    for path in files {
        let image = image::open(&path).expect("png").to_luma8();
        let luma = Luma::from_u8(
            image.width() as usize,
            image.height() as usize,
            image.as_raw(),
        );
        let start = std::time::Instant::now();
        let found = find_charuco(&luma, &board);
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let name = path
            .file_name()
            .expect("name")
            .to_string_lossy()
            .into_owned();
        out.insert(
            name,
            json!({"ids": found.ids, "points": found.points, "markers": found.markers, "ms": ms}),
        );
    }
    println!("{}", serde_json::Value::Object(out));
}
