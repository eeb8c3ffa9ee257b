//! Criterion benchmarks of the matcher's stages on a synthetic 741 × 500 pair (Motorcycle's
//! quarter size, no download), 64 disparities: census, the cost volume stored, aggregation
//! (the costs made inside its passes, as the matcher does), the
//! winner-takes-all of a row, the speckle filter and the median over the whole map, and the
//! whole `vision::disparity` with the best build the CPU runs (AVX-512 for the census and the
//! cost's row), the AVX2 build and the portable one; and coarse to fine at 256 disparities: halving, the prior's windows, the whole
//! matcher through the pyramid; and a depth map's summary (its spread) against a selection
//! over every value; and the survey that finds a pair's range beside the match it precedes. The comparison with OpenCV is `scripts/evaluate/matcher` (README,
//! Performance).
//!
//! ```text
//! cargo bench --bench vision
//! ```

use std::hint::black_box;
use std::sync::atomic::AtomicBool;

use criterion::{Criterion, criterion_group, criterion_main};
use stereo_core::pipeline;
use stereo_core::vision::{
    self, Params, census, cost, filters, pyramid, refine, sgm, simd, synthetic,
};

fn stages(c: &mut Criterion) {
    let pair = synthetic::render(&synthetic::Scene {
        noise: 0.01,
        ..synthetic::layered(741, 500)
    });
    let params = Params::range(0, 64).unwrap();
    let never = AtomicBool::new(false);
    let (w, h) = (pair.left.width, pair.left.height);
    let full = || cost::Windows::full(w * h, params.count());
    let cl = census::transform(&pair.left);
    let cr = census::transform(&pair.right);
    let (gl, gr) = (
        cost::levels_of(&pair.left.data),
        cost::levels_of(&pair.right.data),
    );
    let rows = cost::Rows {
        census: (&cl, &cr),
        grey: (&gl, &gr),
        width: w,
        range: (0, params.count()),
    };
    // The matcher's way: each row's costs made where the passes read it.
    let volume = cost::made(rows, h, full());
    let mut totals = Vec::new();
    sgm::aggregate(
        &volume,
        &pair.left.data,
        params.penalties(),
        sgm::Paths::Eight,
        &never,
        &mut |y, row| {
            if y == h / 2 {
                totals = row.to_vec();
            }
        },
    )
    .unwrap();

    let mut group = c.benchmark_group("matcher 741x500x64");
    group.sample_size(20);
    group.bench_function("census (both images)", |b| {
        b.iter(|| {
            (
                census::transform(black_box(&pair.left)),
                census::transform(black_box(&pair.right)),
            )
        })
    });
    group.bench_function("cost volume (every row made and stored)", |b| {
        b.iter(|| cost::volume(black_box(rows), h, full()))
    });
    for (paths, name) in [
        (
            sgm::Paths::Eight,
            "aggregate (8 paths, 2 passes, costs made in each, whole image, 1 thread)",
        ),
        (
            sgm::Paths::Five,
            "aggregate (5 paths, 1 pass, costs made in it, whole image, 1 thread)",
        ),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                sgm::aggregate(
                    black_box(&volume),
                    &pair.left.data,
                    params.penalties(),
                    paths,
                    &never,
                    &mut |_, row| {
                        black_box(row);
                    },
                )
            })
        });
    }
    group.bench_function("winner-takes-all (one row)", |b| {
        b.iter(|| {
            refine::winners(
                black_box(&totals),
                refine::RowWindows::of(&volume.windows, h / 2, w),
                params.count(),
                params.uniqueness(),
                params.subpixel(),
            )
        })
    });
    // The whole-map filters on the map as it leaves the stripes (no speckle filter, no median).
    let raw = Params::new(&vision::Settings {
        max_disparity: Some(vision::RangeEnd::Px(64)),
        speckle_size: Some(0),
        median: Some(false),
        ..vision::Settings::default()
    })
    .unwrap();
    let unfiltered = vision::disparity(&pair.left, &pair.right, &raw, &never)
        .unwrap()
        .0
        .data;
    group.bench_function("speckle filter (whole map, by bands)", |b| {
        b.iter_batched_ref(
            || unfiltered.clone(),
            |map| filters::speckles(map, w, 100, 2.0),
            criterion::BatchSize::LargeInput,
        )
    });
    group.bench_function("3 x 3 median (whole map)", |b| {
        b.iter(|| filters::median(black_box(&unfiltered), w))
    });
    for (name, simd_on, avx512) in [
        ("whole matcher, the best build present", true, true),
        ("whole matcher, AVX2 if present", true, false),
        ("whole matcher, portable", false, false),
    ] {
        simd::use_simd(simd_on);
        if simd_on {
            simd::use_avx512(avx512);
        }
        group.bench_function(name, |b| {
            b.iter(|| vision::disparity(&pair.left, &pair.right, &params, &never).unwrap())
        });
    }
    simd::use_simd(true);
    group.finish();

    // Coarse to fine: the pair halved, the prior's windows for every row, and the whole
    // matcher through the pyramid at 256 disparities (two levels above the finest).
    let mut group = c.benchmark_group("pyramid 741x500x256");
    group.sample_size(10);
    let wide = Params::range(0, 256).unwrap();
    group.bench_function("halve (both images)", |b| {
        b.iter(|| {
            (
                pyramid::halve(black_box(&pair.left)),
                pyramid::halve(black_box(&pair.right)),
            )
        })
    });
    let (coarse, _) = vision::disparity(
        &pyramid::halve(&pair.left),
        &pyramid::halve(&pair.right),
        &Params::range(0, 128).unwrap(),
        &never,
    )
    .unwrap();
    let prior = pyramid::Prior::new(&coarse, 0);
    group.bench_function("prior and its windows (whole image)", |b| {
        b.iter(|| pyramid::Prior::new(black_box(&coarse), 0).windows(0..h, w, (0, 256)))
    });
    black_box(prior);
    group.bench_function("whole matcher, 256 disparities, coarse to fine", |b| {
        b.iter(|| vision::disparity(&pair.left, &pair.right, &wide, &never).unwrap())
    });
    group.finish();
}

/// A depth map's summary: the spread (min, median, max) of a matched 1280 × 720 map's
/// disparities as `pipeline::spread` finds it (a histogram, then the median's bucket), against
/// the bare baseline, a selection over every finite value (what it replaced).
fn summary(c: &mut Criterion) {
    let pair = synthetic::render(&synthetic::Scene {
        noise: 0.01,
        ..synthetic::layered(1280, 720)
    });
    let never = AtomicBool::new(false);
    let (map, _) = vision::disparity(
        &pair.left,
        &pair.right,
        &Params::range(0, 128).unwrap(),
        &never,
    )
    .unwrap();
    let selection = |values: &[f32]| {
        let mut valid: Vec<f32> = values.iter().copied().filter(|v| v.is_finite()).collect();
        let mid = valid.len() / 2;
        let (_, median, _) = valid.select_nth_unstable_by(mid, f32::total_cmp);
        let median = *median;
        let (min, max) = valid
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            });
        (min, median, max)
    };
    let mut group = c.benchmark_group("summary, 1280 x 720");
    group.bench_function("spread (histogram)", |b| {
        b.iter(|| pipeline::spread(black_box(&map.data)))
    });
    group.bench_function("selection over every value (baseline)", |b| {
        b.iter(|| selection(black_box(&map.data)))
    });
    group.finish();
}

/// The survey that finds a pair's range (`vision::survey`), beside the match it comes before:
/// the synthetic pair at 741 × 500 and 1280 × 720, matched over 0..128, in turns.
fn survey(c: &mut Criterion) {
    let never = AtomicBool::new(false);
    for (w, h) in [(741, 500), (1280, 720)] {
        let pair = synthetic::render(&synthetic::Scene {
            noise: 0.01,
            ..synthetic::layered(w, h)
        });
        let params = Params::range(0, 128).unwrap();
        let mut group = c.benchmark_group(format!("range {w}x{h}"));
        group.sample_size(20);
        group.bench_function("survey", |b| {
            b.iter(|| vision::survey::survey(&pair.left, &pair.right, &never).unwrap())
        });
        group.bench_function("disparity 0..128", |b| {
            b.iter(|| vision::disparity(&pair.left, &pair.right, &params, &never).unwrap())
        });
        group.finish();
    }
}

criterion_group!(benches, stages, summary, survey);
criterion_main!(benches);
