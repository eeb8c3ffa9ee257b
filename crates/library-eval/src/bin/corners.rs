//! Chessboard corners by `calib-targets` 0.16 and `chess-corners` 2.1 on a rendered set, against
//! the exact corners in its `truth.json`: `corners SET_DIR`.

use calib_targets::chessboard::ChessboardParams;
use calib_targets::detect;
use chess_corners::{Detector, DetectorConfig, ImageRefiner};
fn stats(name: &str, mut errs: Vec<f64>, counts: &[usize], el: std::time::Duration) {
    errs.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let n = errs.len();
    let full = counts.iter().filter(|&&c| c >= 54).count();
    println!(
        "{name}: {full}/{} images with all 54 matched; median {:.4} p95 {:.4} max {:.4} ({} corners) in {:?}",
        counts.len(),
        errs[n / 2],
        errs[n * 95 / 100],
        errs[n - 1],
        n,
        el
    );
}
fn main() {
    let dir = std::env::args().nth(1).unwrap();
    let truth: serde_json::Value =
        serde_json::from_slice(&std::fs::read(format!("{dir}/truth.json")).unwrap()).unwrap();
    let views = truth["views"].as_array().unwrap();
    let load = |i: usize, side: &str| {
        (
            image::open(format!("{dir}/{side}_{i:02}.png"))
                .unwrap()
                .to_luma8(),
            serde_json::from_value::<Vec<[f64; 2]>>(views[i][side].clone()).unwrap(),
        )
    };
    let nearest = |tr: &[[f64; 2]], x: f64, y: f64| {
        tr.iter()
            .map(|t| ((t[0] - x).powi(2) + (t[1] - y).powi(2)).sqrt())
            .fold(f64::MAX, f64::min)
    };
    // calib-targets
    {
        let cfg = detect::default_chess_config();
        let params = ChessboardParams::default();
        let (mut errs, mut counts) = (Vec::new(), Vec::new());
        let t0 = std::time::Instant::now();
        for i in 0..views.len() {
            for side in ["left", "right"] {
                let (img, tr) = load(i, side);
                let mut c = 0;
                if let Ok(det) = detect::detect_chessboard(&img, &cfg, &params) {
                    for k in &det.corners {
                        let e = nearest(&tr, k.position.x as f64, k.position.y as f64);
                        if e < 3.0 {
                            errs.push(e);
                            c += 1;
                        }
                    }
                }
                counts.push(c);
            }
        }
        stats(
            "calib-targets 0.16 detect_chessboard",
            errs,
            &counts,
            t0.elapsed(),
        );
    }
    for (name, cfg) in [
        (
            "chess-corners chess_multiscale",
            DetectorConfig::chess_multiscale(),
        ),
        (
            "chess-corners chess_multiscale + saddle_point",
            DetectorConfig::chess_multiscale().with_refiner(ImageRefiner::saddle_point()),
        ),
        ("chess-corners radon", DetectorConfig::radon()),
    ] {
        let mut det = Detector::new(cfg).unwrap();
        let (mut errs, mut counts) = (Vec::new(), Vec::new());
        let t0 = std::time::Instant::now();
        for i in 0..views.len() {
            for side in ["left", "right"] {
                let (img, tr) = load(i, side);
                let corners = det.detect(&img).unwrap();
                let mut c = 0;
                for k in &corners {
                    let e = nearest(&tr, k.x as f64, k.y as f64);
                    if e < 3.0 {
                        errs.push(e);
                        c += 1;
                    }
                }
                counts.push(c);
            }
        }
        stats(name, errs, &counts, t0.elapsed());
    }
}
