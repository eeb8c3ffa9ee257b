//! The matcher on pairs the project renders itself with exact ground truth
//! (`vision::synthetic`): accuracy floors on planes that occlude one another, a slanted plane,
//! cameras that differ in gain and offset, and noise; and the AVX2 build giving the same answer
//! as the portable one. No download, no server.

use std::sync::atomic::AtomicBool;

use stereo_core::vision::{
    self, Params, Settings, Subpixel,
    synthetic::{self, Pair, Plane, Region, Scene},
};

/// How a disparity map compares with the truth on the pixels both cameras see.
#[derive(Debug)]
struct Score {
    /// Share of visible pixels with a disparity.
    density: f64,
    /// Share of visible pixels with a disparity more than 1 px off (among those with one).
    bad1: f64,
    /// Median absolute error of the visible pixels with a disparity.
    median_error: f64,
}

fn score(pair: &Pair, params: &Params) -> Score {
    let (map, _) =
        vision::disparity(&pair.left, &pair.right, params, &AtomicBool::new(false)).unwrap();
    let mut errors = Vec::new();
    let mut visible = 0usize;
    for ((&d, &t), &seen) in map.data.iter().zip(&pair.truth).zip(&pair.visible) {
        if !seen {
            continue;
        }
        visible += 1;
        if !d.is_nan() {
            errors.push((d - t).abs());
        }
    }
    let bad1 = errors.iter().filter(|&&e| e > 1.0).count() as f64 / errors.len() as f64;
    errors.sort_by(f32::total_cmp);
    Score {
        density: errors.len() as f64 / visible as f64,
        bad1,
        median_error: f64::from(errors[errors.len() / 2]),
    }
}

fn settings() -> Settings {
    Settings {
        max_disparity: Some(vision::RangeEnd::Px(48)),
        ..Settings::default()
    }
}

fn params() -> Params {
    Params::new(&settings()).unwrap()
}

/// Three planes, one slanted, two in front occluding it: nearly every visible pixel gets a
/// disparity, and nearly all of them within a pixel.
#[test]
fn layered_planes_are_matched() {
    let pair = synthetic::render(&synthetic::layered(320, 240));
    let s = score(&pair, &params());
    assert!(s.density > 0.96, "{s:?}");
    assert!(s.bad1 < 0.005, "{s:?}");
    assert!(s.median_error < 0.12, "{s:?}");
}

/// σ_d on rendered planes (with noise, so that the matcher errs somewhere): it is never
/// optimistic (at least 68 % of the valid pixels lie within it; renders are easier than the
/// real images it was fitted on, docs/matcher.md), and it sorts: the surer half of the pixels
/// errs less than the other, and mismatches (beyond 1 px) sit in the less sure half.
#[test]
fn sigma_is_not_optimistic_and_sorts_the_pixels() {
    let pair = synthetic::render(&Scene {
        noise: 0.04,
        ..synthetic::layered(320, 240)
    });
    let (map, _) =
        vision::disparity(&pair.left, &pair.right, &params(), &AtomicBool::new(false)).unwrap();
    let mut seen: Vec<(f32, f32)> = map
        .data
        .iter()
        .zip(&map.std)
        .zip(&pair.truth)
        .zip(&pair.visible)
        .filter(|(((d, _), _), v)| **v && !d.is_nan())
        .map(|(((d, s), t), _)| ((d - t).abs(), *s))
        .collect();
    assert!(seen.iter().all(|(_, s)| s.is_finite() && *s > 0.0));
    let within = seen.iter().filter(|(e, s)| e <= s).count();
    assert!(
        within * 100 >= seen.len() * 68,
        "{within} of {}",
        seen.len()
    );
    seen.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (surer, rest) = seen.split_at(seen.len() / 2);
    let mean = |v: &[(f32, f32)]| v.iter().map(|p| p.0).sum::<f32>() / v.len() as f32;
    assert!(
        mean(surer) < mean(rest),
        "{} against {}",
        mean(surer),
        mean(rest)
    );
    let bad = |v: &[(f32, f32)]| v.iter().filter(|p| p.0 > 1.0).count();
    assert!(
        bad(rest) > 2 * bad(surer),
        "{} against {}",
        bad(rest),
        bad(surer)
    );
}

/// A right camera with 30 % less gain and an offset changes nothing that matters: the census
/// compares orderings, not levels.
#[test]
fn a_gain_change_between_the_cameras_is_harmless() {
    let pair = synthetic::render(&Scene {
        gain: 0.7,
        offset: 0.12,
        ..synthetic::layered(320, 240)
    });
    let s = score(&pair, &params());
    assert!(s.density > 0.96, "{s:?}");
    assert!(s.bad1 < 0.005, "{s:?}");
}

/// Independent noise in each camera (2 % of full scale) costs some density, little accuracy.
#[test]
fn noisy_cameras_still_match() {
    let pair = synthetic::render(&Scene {
        noise: 0.02,
        ..synthetic::layered(320, 240)
    });
    let s = score(&pair, &params());
    assert!(s.density > 0.95, "{s:?}");
    assert!(s.bad1 < 0.005, "{s:?}");
}

/// On a steeply slanted plane the sub-pixel fit follows the truth between whole pixels, and
/// does so far better than whole pixels would (whose median error is near 0.25 px).
#[test]
fn subpixel_follows_a_slanted_plane() {
    let pair = synthetic::render(&Scene {
        planes: vec![Plane {
            disparity: [8.0, 0.05, 0.01],
            region: Region::Everywhere,
            seed: 11,
            tint: [1.0; 3],
        }],
        ..synthetic::layered(320, 200)
    });
    let fitted = score(&pair, &params());
    let whole = score(
        &pair,
        &Params::new(&Settings {
            subpixel: Some(Subpixel::Off),
            ..settings()
        })
        .unwrap(),
    );
    assert!(fitted.median_error < 0.1, "{fitted:?}");
    assert!(whole.median_error > 0.2, "{whole:?}");
    assert!(fitted.density > 0.9, "{fitted:?}");
}

/// The AVX2 build of the hot loops and the AVX-512 build of the census and the cost's row,
/// where the CPU has them, give maps bit-identical to the portable build's, with a disparity
/// count that fills whole registers (64) and one that leaves padded lanes (40).
#[test]
fn simd_and_portable_builds_agree() {
    let pair = synthetic::render(&Scene {
        noise: 0.01,
        ..synthetic::layered(200, 120)
    });
    for count in [40, 64] {
        let params = Params::range(0, count).unwrap();
        let run = |simd, avx512| {
            vision::simd::use_simd(simd);
            if simd {
                vision::simd::use_avx512(avx512);
            }
            vision::disparity(&pair.left, &pair.right, &params, &AtomicBool::new(false))
                .unwrap()
                .0
        };
        let portable = run(false, false);
        for (build, avx512) in [("AVX2", false), ("the best", true)] {
            let fast = run(true, avx512);
            let same = portable
                .data
                .iter()
                .zip(&fast.data)
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "{build} build disagrees with {count} disparities");
        }
        assert!(portable.data.iter().filter(|d| d.is_finite()).count() > 200 * 120 / 2);
    }
}

/// A cancelled search stops with `Cancelled` instead of an answer.
#[test]
fn a_cancelled_search_stops() {
    let pair = synthetic::render(&synthetic::layered(64, 48));
    let cancel = AtomicBool::new(true);
    assert_eq!(
        vision::disparity(&pair.left, &pair.right, &params(), &cancel).unwrap_err(),
        vision::Cancelled
    );
}

/// Tiny and degenerate inputs answer without panicking: one pixel, one row, a range wider
/// than the image, negative disparities.
#[test]
fn degenerate_inputs_do_not_panic() {
    for (w, h) in [(1, 1), (5, 1), (1, 9), (3, 3)] {
        let pair = synthetic::render(&synthetic::layered(w, h));
        for (min, count) in [(0, 1), (0, 64), (-8, 16)] {
            let p = Params::range(min, min + count).unwrap();
            let (map, _) =
                vision::disparity(&pair.left, &pair.right, &p, &AtomicBool::new(false)).unwrap();
            assert_eq!(map.data.len(), w * h);
        }
    }
}

/// The layered scene with every disparity multiplied by `k`.
fn deep(width: usize, height: usize, k: f32) -> Scene {
    let mut scene = synthetic::layered(width, height);
    for plane in &mut scene.planes {
        plane.disparity = plane.disparity.map(|v| v * k);
    }
    scene
}

/// A wide range goes through the pyramid (three coarser levels for 320 disparities): the planes, now 48 to
/// 272 px apart, are still matched nearly everywhere and within a pixel, as closely as the whole
/// range searched at every pixel finds them.
#[test]
fn a_wide_range_is_matched_coarse_to_fine() {
    assert_eq!(vision::pyramid::levels(960, 640, 320, false), 3);
    let pair = synthetic::render(&deep(960, 640, 8.0));
    let wide = Params::new(&Settings {
        max_disparity: Some(vision::RangeEnd::Px(320)),
        ..Settings::default()
    })
    .unwrap();
    let s = score(&pair, &wide);
    assert!(s.density > 0.95, "{s:?}");
    assert!(s.bad1 < 0.01, "{s:?}");
    assert!(s.median_error < 0.15, "{s:?}");
}

/// Below the coarsest level each pixel costs at most MAX_WINDOW cells, so the memory the
/// matcher reserves stops growing with the range: 512 disparities need no more per pixel than
/// 128 or 200 (the whole range at one level would need over 150 bytes a pixel at 512).
#[test]
fn memory_per_pixel_does_not_grow_with_the_range() {
    let (w, h) = (3000, 2000);
    let per_pixel = |count| vision::bytes_needed(w, h, count) as f64 / (w * h) as f64;
    assert!(
        per_pixel(400) <= per_pixel(200) * 1.01,
        "{} {}",
        per_pixel(400),
        per_pixel(200)
    );
    assert!(
        per_pixel(512) <= per_pixel(128) * 1.01,
        "{}",
        per_pixel(512)
    );
    assert!(per_pixel(512) < 80.0, "{}", per_pixel(512));
}

/// `image` upscaled `k` times by Catmull-Rom's cubic on pixel centres (OpenCV's `resize`
/// convention), the border repeated.
fn upscaled(image: &vision::Gray, k: usize) -> vision::Gray {
    let (w, h) = (image.width, image.height);
    let weights = synthetic::catmull_rom;
    let at = |x: isize, y: isize| {
        let x = x.clamp(0, w as isize - 1) as usize;
        let y = y.clamp(0, h as isize - 1) as usize;
        f32::from(image.data[y * w + x])
    };
    let mut data = Vec::with_capacity(w * h * k * k);
    for oy in 0..h * k {
        let sy = (oy as f32 + 0.5) / k as f32 - 0.5;
        let (y0, wy) = (sy.floor() as isize, weights(sy - sy.floor()));
        for ox in 0..w * k {
            let sx = (ox as f32 + 0.5) / k as f32 - 0.5;
            let (x0, wx) = (sx.floor() as isize, weights(sx - sx.floor()));
            let mut v = 0.0;
            for (j, wy) in wy.iter().enumerate() {
                for (i, wx) in wx.iter().enumerate() {
                    v += wx * wy * at(x0 + i as isize - 1, y0 + j as isize - 1);
                }
            }
            data.push(v.round().clamp(0.0, 65535.0) as u16);
        }
    }
    vision::Gray::new(w * k, h * k, data)
}

/// The share of the pixels marked `visible` whose disparity, matched on the pair with what is
/// `seen` of it, is missing or more than 1 px off the `truth`.
fn bad_or_missing(
    (left, right): (&vision::Gray, &vision::Gray),
    seen: vision::PairNoise,
    params: &Params,
    (truth, visible): (&[f32], &[bool]),
) -> f64 {
    let never = AtomicBool::new(false);
    let (map, _, _) = vision::disparity_probed_in(left, right, seen, params, &never, &[]).unwrap();
    let (mut n, mut bad) = (0usize, 0usize);
    for ((&d, &t), &visible) in map.data.iter().zip(truth).zip(visible) {
        if visible {
            n += 1;
            bad += usize::from(d.is_nan() || (d - t).abs() > 1.0);
        }
    }
    bad as f64 / n as f64
}

/// A pair smooth over several pixels (the layered scene upscaled 4 ×, its truth scaled with
/// it): the census spreads its samples (stride 3 here), and that halves the share of pixels
/// off by more than 1 px or missing against samples one pixel apart on the same pair (3.6 %
/// against 14.4 % when written).
#[test]
fn a_smooth_pair_is_matched_with_its_census_spread() {
    const K: usize = 4;
    let small = synthetic::render(&synthetic::layered(200, 120));
    let (left, right) = (upscaled(&small.left, K), upscaled(&small.right, K));
    let w = left.width;
    let (truth, visible): (Vec<f32>, Vec<bool>) = (0..left.data.len())
        .map(|i| {
            let (x, y) = ((i % w) / K, (i / w) / K);
            let s = y * small.left.width + x;
            (small.truth[s] * K as f32, small.visible[s])
        })
        .unzip();
    let params = Params::new(&Settings {
        max_disparity: Some(vision::RangeEnd::Px(160)),
        ..Settings::default()
    })
    .unwrap();
    let seen = vision::PairNoise::of(&left, &right);
    assert!(seen.stride >= 2, "{seen:?}");
    let bad1 = |seen| bad_or_missing((&left, &right), seen, &params, (&truth, &visible));
    let (spread, adjacent) = (bad1(seen), bad1(vision::PairNoise { stride: 1, ..seen }));
    assert!(
        spread < 0.5 * adjacent,
        "stride {}: {spread:.4} against {adjacent:.4} one pixel apart",
        seen.stride
    );
}

/// The layered scene at `contrast` times its contrast around mid-grey, with noise of σ
/// `sigma` grey levels in each image, quantised to 8 bits as a camera's.
fn faded(pair: &Pair, contrast: f32, sigma: f32) -> (vision::Gray, vision::Gray) {
    let mut rng = synthetic::Rng::new(23);
    let mut fade = |image: &vision::Gray| {
        let data = image
            .data
            .iter()
            .map(|&v| {
                let v = 128.0 + (f32::from(v) / 257.0 - 128.0) * contrast + sigma * rng.normal();
                v.round().clamp(0.0, 255.0) as u16 * 257
            })
            .collect();
        vision::Gray::new(image.width, image.height, data)
    };
    (fade(&pair.left), fade(&pair.right))
}

/// A faint pair (the layered scene at a tenth of its contrast under noise σ 3): its texture
/// is far weaker than its noise, so the matcher starts from a pyramid down to 16
/// disparities, and that leaves fewer visible pixels off by more than 1 px or missing than
/// matching it at its own size does (0.164 against 0.179 when written).
#[test]
fn a_faint_pair_is_matched_coarse_to_fine() {
    let pair = synthetic::render(&synthetic::layered(320, 240));
    let (left, right) = faded(&pair, 0.1, 3.0);
    let seen = vision::PairNoise::of(&left, &right);
    assert!(seen.faint, "{seen:?}");
    let truth = (pair.truth.as_slice(), pair.visible.as_slice());
    let bad1 = |seen| bad_or_missing((&left, &right), seen, &params(), truth);
    let (coarse_first, own_size) = (
        bad1(seen),
        bad1(vision::PairNoise {
            faint: false,
            ..seen
        }),
    );
    assert!(
        coarse_first < 0.95 * own_size,
        "{coarse_first:.4} coarse to fine against {own_size:.4} at its own size"
    );
}

/// At a fifth of the contrast under the same noise, or at full contrast, the layered scene is
/// not faint: matched at its own size, as before.
#[test]
fn a_noisy_but_textured_pair_is_not_faint() {
    let pair = synthetic::render(&synthetic::layered(320, 240));
    for contrast in [0.2, 1.0] {
        let (left, right) = faded(&pair, contrast, 3.0);
        let seen = vision::PairNoise::of(&left, &right);
        assert!(!seen.faint, "contrast {contrast}: {seen:?}");
    }
}
