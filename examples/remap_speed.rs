//! Times `vision::remap` on a 1280 × 720 grey image through a rectification map (a quick
//! check beside `scripts/evaluate/rectification`, which compares with `cv2.remap` in the same run).
//!
//!     cargo run --release --example remap_speed              # every interpolation
//!     ONLY_LINEAR=1 cargo run --release --example remap_speed  # bilinear grey, 200 runs

use std::time::Instant;

use nalgebra::{Matrix3, Rotation3, Vector3};
use stereo_core::camera::{Camera, Distortion, Intrinsics, Model, Size, undistort_rectify_map};
use stereo_core::vision::remap::{Fixed, Interpolation, RawImage, remap_fixed};

fn main() {
    let size = Size {
        width: 1280,
        height: 720,
    };
    let camera = Camera::new(
        Intrinsics {
            fx: 980.0,
            fy: 978.0,
            cx: 652.0,
            cy: 361.0,
        },
        Distortion::new(Model::PlumbBob, &[-0.21, 0.06, 0.001, -0.0007, -0.008]).unwrap(),
    )
    .unwrap();
    let rotation = *Rotation3::from_scaled_axis(Vector3::new(0.01, -0.02, 0.005)).matrix();
    let p = Matrix3::new(987.0, 0.0, 634.0, 0.0, 987.0, 359.0, 0.0, 0.0, 1.0);
    let t = Instant::now();
    let map = undistort_rectify_map(&camera, &rotation, &p, size);
    let t2 = Instant::now();
    let fixed = Fixed::new(&map);
    println!(
        "map: {:.2} ms, in fixed point: {:.2} ms",
        (t2 - t).as_secs_f64() * 1e3,
        t2.elapsed().as_secs_f64() * 1e3
    );
    let grey: Vec<u16> = (0..1280 * 720)
        .map(|i| ((i * 7919) % 65536) as u16)
        .collect();
    let rgb: Vec<u8> = (0..1280 * 720 * 3)
        .map(|i| ((i * 31) % 256) as u8)
        .collect();
    let only_linear = std::env::var("ONLY_LINEAR").is_ok();
    for how in [
        Interpolation::Linear,
        Interpolation::Nearest,
        Interpolation::Cubic,
    ] {
        if only_linear && how != Interpolation::Linear {
            continue;
        }
        let mut times = Vec::new();
        for _ in 0..if only_linear { 200 } else { 9 } {
            let t = Instant::now();
            let out = remap_fixed(
                RawImage {
                    width: 1280,
                    height: 720,
                    channels: 1,
                    data: &grey,
                },
                &fixed,
                how,
            );
            times.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(out);
        }
        times.sort_by(f64::total_cmp);
        let mut rgb_times = Vec::new();
        for _ in 0..9 {
            let t = Instant::now();
            let out = remap_fixed(
                RawImage {
                    width: 1280,
                    height: 720,
                    channels: 3,
                    data: &rgb,
                },
                &fixed,
                how,
            );
            rgb_times.push(t.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(out);
        }
        rgb_times.sort_by(f64::total_cmp);
        println!(
            "{how:?}: grey {:.2} ms (median of {}), rgb {:.2} ms (median of 9)",
            times[times.len() / 2],
            times.len(),
            rgb_times[4]
        );
    }
}
