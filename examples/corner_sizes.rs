//! Corner finding at camera resolutions: renders stereo checkerboards of any size, blur, noise
//! and contrast with exact corners, runs `calibrate::corners::find_board` on every left image
//! and prints how many boards were found, the median / p95 error against the truth and the time
//! per image; with an output folder it also writes both cameras' images and the left truth, for
//! `scripts/evaluations/corner_sizes.py` to run OpenCV on the same files and for `POST /calibrate` (the rig:
//! fx = fy = 1.25 × WIDTH at the image centre, k1 −0.2, k2 0.08, |T| 120 mm, R = I).
//!
//! ```sh
//! cargo run --release --example corner_sizes -- WIDTH HEIGHT BLUR NOISE BLACK WHITE VIEWS [OUT_DIR]
//! # BLUR: σ px; NOISE: σ grey levels; BLACK, WHITE: the squares' reflectance, 0..1
//! cargo run --release --example corner_sizes -- 4000 3000 8 2 0.08 0.85 6 target/corner-sizes/4000-b8
//! PYTHONPATH=scripts python3 -m evaluations.corner_sizes target/corner-sizes/4000-b8
//! ```
use nalgebra::{Rotation3, Vector3};
use std::process::ExitCode;
use std::time::Instant;
use stereo_core::calibration::boards::Board;
use stereo_core::calibration::boards::corners::{self, Luma};
use stereo_core::calibration::boards::synthetic::{Style, poses, stereo_views};
use stereo_core::camera::{Camera, Distortion, Intrinsics, Model, Size, StereoPair};
use stereo_core::physics::LengthUnit;

const USAGE: &str = "usage: corner_sizes WIDTH HEIGHT BLUR NOISE BLACK WHITE VIEWS [OUT_DIR]\n  BLUR: sigma px, NOISE: sigma grey levels, BLACK/WHITE: reflectance 0..1 (0.08 0.85)";

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{e}\n{USAGE}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 7 {
        return Err("too few arguments".into());
    }
    let num = |i: usize| -> Result<f64, String> {
        args[i]
            .parse()
            .map_err(|_| format!("argument {} is not a number: {}", i + 1, args[i]))
    };
    let (w, h) = (num(0)? as u32, num(1)? as u32);
    let (blur, noise, black, white) = (num(2)?, num(3)?, num(4)?, num(5)?);
    let n = num(6)? as usize;
    let out = args.get(7).cloned();

    // A wide-angle lens with barrel distortion, 1.25 × the width as focal length.
    let f = 1.25 * f64::from(w);
    let cam = Camera::new(
        Intrinsics {
            fx: f,
            fy: f,
            cx: f64::from(w) / 2.0,
            cy: f64::from(h) / 2.0,
        },
        Distortion::new(Model::PlumbBob, &[-0.2, 0.08, 0.0, 0.0, 0.0])
            .map_err(|e| e.to_string())?,
    )
    .map_err(|e| e.to_string())?;
    let pair = StereoPair {
        left: cam,
        right: cam,
        rotation: Rotation3::identity(),
        translation: Vector3::new(-120.0, 0.0, 0.0),
    };
    let size = Size {
        width: w,
        height: h,
    };
    let board = Board::new(9, 6, 25.0, LengthUnit::Millimetre).map_err(|e| format!("{e:?}"))?;
    let ps = poses(&pair, size, &board, n, 50.0, 7);
    let style = Style {
        blur,
        noise,
        black,
        white,
        supersampling: if w > 2000 { 2 } else { 4 },
        ..Style::default()
    };
    let views = stereo_views(&pair, size, &board, &ps, &style);
    let (mut found, mut errs, mut ms) = (0, Vec::new(), 0.0);
    for (i, v) in views.iter().enumerate() {
        let l = Luma::from_u8(
            v.left.width as usize,
            v.left.height as usize,
            &v.left.pixels,
        );
        let t = Instant::now();
        let r = corners::find_board(&l, &board);
        ms += t.elapsed().as_secs_f64() * 1e3;
        match r {
            Ok(c) => {
                found += 1;
                errs.extend(
                    c.iter()
                        .zip(&v.left_corners)
                        .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1])),
                );
            }
            Err(e) => eprintln!("view {i}: {e}"),
        }
        if let Some(o) = &out {
            std::fs::create_dir_all(o).map_err(|e| e.to_string())?;
            for (side, img) in [("left", &v.left), ("right", &v.right)] {
                image::GrayImage::from_raw(img.width, img.height, img.pixels.clone())
                    .ok_or("image buffer")?
                    .save(format!("{o}/{side}_{i:02}.png"))
                    .map_err(|e| e.to_string())?;
            }
            let truth = serde_json::to_string(&v.left_corners).map_err(|e| e.to_string())?;
            std::fs::write(format!("{o}/truth_{i:02}.json"), truth).map_err(|e| e.to_string())?;
        }
    }
    errs.sort_by(f64::total_cmp);
    let med = errs.get(errs.len() / 2).copied().unwrap_or(f64::NAN);
    let p95 = errs.get(errs.len() * 95 / 100).copied().unwrap_or(f64::NAN);
    println!(
        "{w}x{h} blur {blur} noise {noise} contrast {black}-{white}: ours found {found}/{} median {med:.4} p95 {p95:.4} px, {:.1} ms/image",
        views.len(),
        ms / views.len() as f64
    );
    Ok(())
}
