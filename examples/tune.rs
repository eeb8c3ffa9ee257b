//! Tunes the matcher's defaults: runs it on a pair with ground truth under a grid of parameters
//! and prints Middlebury's bad-0.5/1.0/2.0 (holes filled from the row's background first) and
//! density for each.
//!
//! ```text
//! cargo run --profile tune --example tune -- LEFT.png RIGHT.png TRUTH.f32 [COUNT] [KEY=V1,V2 …]
//! ```
//! `TRUTH.f32` is the ground truth as raw little-endian float32, row-major, +inf where unknown.
//! Keys: p1, p2, edge, uniq, lr, speckle, median (0/1), sub (off/parabola/equiangular),
//! paths (5/8/auto), preset (accurate/fast), and the pyramid's narrow, whole and window (cells).
//! `TUNE_RUNS=N` times each setting N times and reports the median run.
//! `TUNE_SIMD=portable` runs the portable build of the hot loops, `TUNE_SIMD=avx2` the AVX2
//! build where the CPU has AVX-512 too.

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use stereo_core::vision::{self, Params, Settings, Subpixel, filters, simd};

mod common;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match std::env::var("TUNE_SIMD").as_deref() {
        Ok("portable") => simd::use_simd(false),
        Ok("avx2") => simd::use_avx512(false),
        _ => {}
    }
    let (left, right) = common::read_pair(&args[0], &args[1]);
    let truth: Vec<f32> = std::fs::read(&args[2])
        .unwrap()
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    let count: i32 = args.get(3).map_or(64, |c| c.parse().unwrap());
    // Each setting with its pyramid's `narrow` and `window` when asked (else the preset's).
    let mut grid: Vec<(Settings, [Option<usize>; 3])> = vec![(
        Settings {
            max_disparity: Some(stereo_core::vision::RangeEnd::Px(count)),
            ..Settings::default()
        },
        [None; 3],
    )];
    for spec in args.iter().skip(4) {
        let (key, values) = spec.split_once('=').unwrap();
        grid = grid
            .into_iter()
            .flat_map(|p| {
                values.split(',').map(move |v| {
                    let (mut p, mut shape) = p;
                    match key {
                        "preset" => {
                            p.preset = Some(match v {
                                "fast" => vision::Preset::Fast,
                                _ => vision::Preset::Accurate,
                            })
                        }
                        "narrow" => shape[0] = v.parse().ok(),
                        "window" => shape[1] = v.parse().ok(),
                        "whole" => shape[2] = v.parse().ok(),
                        "p1" => p.p1 = v.parse().ok(),
                        "p2" => p.p2 = v.parse().ok(),
                        "edge" => p.p2_edge = v.parse().ok(),
                        "uniq" => p.uniqueness = v.parse().ok(),
                        "lr" => {
                            let t = v.parse().ok().filter(|t: &f64| *t >= 0.0);
                            p.lr_check = Some(t.is_some());
                            p.lr_tolerance = t;
                        }
                        "speckle" => p.speckle_size = v.parse().ok(),
                        "median" => p.median = Some(v == "1"),
                        "paths" => {
                            p.paths = v.parse().ok();
                        }
                        "sub" => {
                            p.subpixel = Some(match v {
                                "off" => Subpixel::Off,
                                "parabola" => Subpixel::Parabola,
                                _ => Subpixel::Equiangular,
                            })
                        }
                        other => panic!("unknown key {other}"),
                    }
                    (p, shape)
                })
            })
            .collect();
    }
    let w = left.grey.width;
    let seen = vision::PairNoise::of(&left.grey, &right.grey);
    println!(
        "noise {:.2} / {:.2} grey levels, clarity {:.1}, census stride {}{}",
        seen.left / 257.0,
        seen.right / 257.0,
        seen.clarity,
        seen.stride,
        if seen.faint { ", faint" } else { "" }
    );
    let runs: usize = std::env::var("TUNE_RUNS")
        .ok()
        .and_then(|r| r.parse().ok())
        .unwrap_or(1)
        .max(1);
    for (settings, [narrow, window, whole]) in grid {
        let params = Params::new(&settings).expect("the grid's settings are within bounds");
        let shape = params.shape();
        let params = params.with_shape(vision::pyramid::Shape {
            narrow: narrow.unwrap_or(shape.narrow),
            whole: whole.unwrap_or(shape.whole),
            window: window.unwrap_or(shape.window),
        });
        let mut runs: Vec<_> = (0..runs)
            .map(|_| {
                let started = Instant::now();
                let (map, t) =
                    vision::disparity(&left.grey, &right.grey, &params, &AtomicBool::new(false))
                        .unwrap();
                (started.elapsed(), map, t)
            })
            .collect();
        runs.sort_by_key(|r| r.0);
        let (total, map, t) = runs.swap_remove(runs.len() / 2);
        let density =
            map.data.iter().filter(|d| !d.is_nan()).count() as f64 / map.data.len() as f64;
        let mut filled = map.data.clone();
        filters::fill(&mut filled, w);
        let (mut n, mut bad) = (0usize, [0usize; 3]);
        for (&d, &g) in filled.iter().zip(&truth) {
            if !g.is_finite() {
                continue;
            }
            n += 1;
            let e = if d.is_nan() {
                f32::INFINITY
            } else {
                (d - g).abs()
            };
            for (b, t) in bad.iter_mut().zip([0.5, 1.0, 2.0]) {
                *b += usize::from(e > t);
            }
        }
        let pct = |b: usize| 100.0 * b as f64 / n as f64;
        println!(
            "{:?} {:?} p1 {:3} p2 {:3} edge {:3} uniq {:2} lr {:?} speckle {:3} median {} sub {:?}: \
             bad0.5 {:5.2} bad1 {:5.2} bad2 {:5.2} dens {:5.1}  {:4.0} ms (cost {:.0} agg {:.0} refine {:.0}) cells {:.1}/px",
            params.shape(),
            params.paths(),
            params.penalties().p1,
            params.penalties().p2,
            params.penalties().edge,
            params.uniqueness(),
            params.lr_tolerance(),
            params.speckle_size(),
            u8::from(params.median()),
            params.subpixel(),
            pct(bad[0]),
            pct(bad[1]),
            pct(bad[2]),
            100.0 * density,
            total.as_secs_f64() * 1e3,
            t.cost.as_secs_f64() * 1e3,
            t.aggregate.as_secs_f64() * 1e3,
            t.refine.as_secs_f64() * 1e3,
            t.cells as f64 / (w * left.grey.height) as f64,
        );
    }
}
