//! Camera resolutions under the default settings (1 GiB heavy budget), over a real socket: a
//! 6-megapixel pair at 400 disparities, a phone's 12-megapixel JPEG pair (4032 × 3024) at
//! every range from 16 to 400 and a 24-megapixel JPEG pair (6000 × 4000) at 64 and 256 are
//! admitted and matched, with the memory the process really used (its peak RSS) no more than
//! what the request reserved, and three 1920 × 1080 pairs at 256 disparities run side by side
//! without a 503.
//!
//! Minutes each: ignored by `cargo test`, run by `.ci/run` in the test build (whose engine is
//! optimised) as `cargo test --test api scale -- --ignored --test-threads=1` (one at a time, so
//! the peak RSS is this test's).

use reqwest::multipart::Form;
use stereo_core::pipeline::Product;
use stereo_core::pipeline::job::depth_map_bytes;
use stereo_core::vision::synthetic::{self, Pair, Scene};

/// What `/depth-map` reserves for a `w × h` pair over `count` disparities answering a
/// disparity NPY.
fn bytes_needed(w: usize, h: usize, count: usize) -> usize {
    depth_map_bytes(w, h, count, &[Product::DisparityNpy])
}

use stereo_core::vision::encode::png_grey;

use crate::depth_map::{image_part, jpeg_part, png};
use crate::helpers::spawn_app;

/// The layered scene at `width × height` with every disparity multiplied by `k`.
fn deep(width: usize, height: usize, k: f32) -> Pair {
    let mut scene: Scene = synthetic::layered(width, height);
    for plane in &mut scene.planes {
        plane.disparity = plane.disparity.map(|v| v * k);
    }
    synthetic::render(&scene)
}

fn form(pair: &Pair) -> Form {
    let (w, h) = (pair.left.width, pair.left.height);
    Form::new()
        .part("left", image_part(png(&pair.left_rgb, w, h)))
        .part("right", image_part(png(&pair.right_rgb, w, h)))
}

/// A line of /proc/self/status in bytes (`VmHWM`, `VmRSS`).
fn status_bytes(key: &str) -> usize {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = status
        .lines()
        .find(|l| l.starts_with(key))
        .unwrap_or_else(|| panic!("{key} in /proc/self/status"));
    let kib: usize = line
        .split_whitespace()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .unwrap();
    kib * 1024
}

/// Share of visible pixels with a disparity, and share of those more than 1 px off.
fn accuracy(pair: &Pair, map: &[f32]) -> (f64, f64) {
    let (mut visible, mut found, mut bad) = (0usize, 0usize, 0usize);
    for ((&d, &t), &seen) in map.iter().zip(&pair.truth).zip(&pair.visible) {
        if seen {
            visible += 1;
            if !d.is_nan() {
                found += 1;
                bad += usize::from((d - t).abs() > 1.0);
            }
        }
    }
    (
        found as f64 / visible as f64,
        bad as f64 / found.max(1) as f64,
    )
}

/// A pair as grey PNGs, as small as a pair of its size gets.
fn grey_pngs(pair: &Pair) -> Form {
    let (w, h) = (pair.left.width, pair.left.height);
    let grey = |g: &stereo_core::vision::Gray| -> Vec<u8> {
        g.data.iter().map(|&v| (v >> 8) as u8).collect()
    };
    Form::new()
        .part("left", image_part(png_grey(w, h, &grey(&pair.left))))
        .part("right", image_part(png_grey(w, h, &grey(&pair.right))))
}

/// A pair as a phone writes it: colour JPEGs at quality 95.
fn phone_jpegs(pair: &Pair) -> Form {
    let (w, h) = (pair.left.width, pair.left.height);
    Form::new()
        .part(
            "left",
            jpeg_part(synthetic::phone_jpeg(&pair.left_rgb, w, h, 1)),
        )
        .part(
            "right",
            jpeg_part(synthetic::phone_jpeg(&pair.right_rgb, w, h, 1)),
        )
}

/// Sends a `w × h` pair of the layered scene with disparities × `k`, as `encode` writes it, to
/// a server with the default settings, searching `count`
/// disparities: it must be a 200 with a map nearly complete and nearly all within a pixel, and
/// the process's peak RSS while serving it (above what it held before) no more than what the
/// request reserved besides its body.
async fn admitted_within_its_reservation(
    (w, h): (usize, usize),
    count: usize,
    k: f32,
    encode: fn(&Pair) -> Form,
) {
    let pair = deep(w, h, k);
    let form = encode(&pair);
    let app = spawn_app().await;
    // From here the peak RSS counts only what the request adds.
    std::fs::write("/proc/self/clear_refs", "5").expect("the peak RSS can be reset");
    let before = status_bytes("VmRSS");
    let response = app
        .post_form(
            &format!("/depth-map?max_disparity={count}&output=disparity.npy"),
            form,
        )
        .await;
    let peak = status_bytes("VmHWM").saturating_sub(before);
    assert_eq!(response.status(), 200);
    let body = response.bytes().await.unwrap();
    let map = crate::depth_map::npy_of(&body, (h, w));
    let (density, bad1) = accuracy(&pair, &map);
    assert!(density > 0.95, "density {density}");
    assert!(bad1 < 0.01, "bad-1.0 {bad1}");
    let reserved = bytes_needed(w, h, count);
    assert!(
        peak <= reserved,
        "peak RSS {} MiB above the {} MiB reserved",
        peak >> 20,
        reserved >> 20
    );
    eprintln!(
        "{w} x {h} at {count}: peak RSS +{} MiB, reserved {} MiB besides the body, \
         density {density:.4}, bad-1.0 {bad1:.4}",
        peak >> 20,
        reserved >> 20
    );
}

/// 3000 × 2000 (6 MP) at 400 disparities (planes 60 to 340 px apart) under the default budget.
#[tokio::test]
#[ignore = "6 MP at 400 disparities: run by .ci/run"]
async fn six_megapixels_at_400_disparities_are_answered_within_their_reservation() {
    admitted_within_its_reservation((3000, 2000), 400, 10.0, grey_pngs).await;
}

/// 4032 × 3024 (12.19 MP), what most phones write, as colour JPEGs under the default settings
/// at the ends of each way of matching: 16 and 64 disparities (searched at full size) and 400
/// (coarse to fine), the scene's planes 0.85 of the range apart at most: admitted at each (no
/// 413 for its pixels, none for its memory), matched within its reservation; and the
/// reservation never larger at a narrower range, at every range from 16 to 400.
#[tokio::test]
#[ignore = "a phone's 12 MP JPEG pair at three ranges: run by .ci/run"]
async fn a_phones_twelve_megapixel_jpeg_pair_is_answered_at_every_range() {
    for count in [16, 64, 400] {
        // The layered scene's planes lie 6 to 34 px apart before scaling.
        let k = 0.85 * count as f32 / 34.0;
        admitted_within_its_reservation((4032, 3024), count, k, phone_jpegs).await;
    }
    let reserved: Vec<usize> = (16..=400)
        .map(|count| bytes_needed(4032, 3024, count))
        .collect();
    assert!(reserved.windows(2).all(|r| r[0] <= r[1]), "{reserved:?}");
}

/// 6000 × 4000 (24 MP), what an APS-C camera writes, as colour JPEGs under the default
/// settings at 64 and 256 disparities: admitted, matched within its reservation, and the
/// reservation no larger at the narrower range.
#[tokio::test]
#[ignore = "a 24 MP JPEG pair at two ranges: run by .ci/run"]
async fn a_twenty_four_megapixel_jpeg_pair_is_answered_at_64_and_256() {
    for count in [64, 256] {
        let k = 0.85 * count as f32 / 34.0;
        admitted_within_its_reservation((6000, 4000), count, k, phone_jpegs).await;
    }
    let reserved = |count| bytes_needed(6000, 4000, count);
    assert!(reserved(64) <= reserved(256));
}

/// Three 1920 × 1080 pairs at 256 disparities sent at once: all three are answered 200, none
/// refused for memory or concurrency.
#[tokio::test]
#[ignore = "three 1080p pairs at 256 disparities: run by .ci/run"]
async fn three_full_hd_pairs_run_side_by_side() {
    let pair = deep(1920, 1080, 6.0);
    let app = spawn_app().await;
    let send = || app.post_form("/depth-map?max_disparity=256", form(&pair));
    let (a, b, c) = tokio::join!(send(), send(), send());
    for response in [a, b, c] {
        let status = response.status();
        assert_eq!(status, 200, "{}", response.text().await.unwrap());
    }
}
