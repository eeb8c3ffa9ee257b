//! Criterion benchmarks of the pure physics core (one triangulation, a 10 000-row sample table,
//! a 10 000-point batch) and of one request through the router in process, with and without
//! the middleware stack, to split the cost of a request between the stack and the handler.
//! No socket here; `benches/load.rs` measures the service over one.
//!
//! Run: `cargo bench --bench core` (reports under `target/criterion/`).

use std::hint::black_box;

use axum::{
    Router,
    body::{Body, to_bytes},
    http::{Request, header},
};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use stereo_core::physics::{
    self, Correspondence, LengthUnit, Rig, RigSpec, SampleRange, Spacing, measure,
};
use stereo_distance::{
    Config,
    api::{self, AppState, HeavyState, routes::ops::OpsState},
    app,
};
use tower::ServiceExt;

/// The seed's example 1 (f = 35 px, B = 150 mm, 800×600), with a realistic Δd.
fn rig() -> Rig {
    let mut spec = RigSpec::pixels(35.0, 150.0, LengthUnit::Millimetre);
    spec.camera.image_width = Some(800);
    spec.camera.image_height = Some(600);
    spec.camera.disparity_error_px = Some(0.25);
    Rig::new(&spec).expect("the seed's rig is valid")
}

/// 10 000 correspondences spread over the image, as a feature matcher would produce them.
fn correspondences(count: usize) -> Vec<Correspondence> {
    (0..count)
        .map(|i| {
            let x_left = 100.0 + (i % 600) as f64;
            Correspondence::from_pair(
                x_left,
                x_left - 1.0 - (i % 97) as f64 * 0.5,
                (i % 600) as f64,
            )
        })
        .collect()
}

fn single_distance(c: &mut Criterion) {
    let rig = rig();
    let point = Correspondence::from_pair(400.0, 350.0, 300.0);
    c.bench_function("measure/single", |b| {
        b.iter(|| measure(black_box(&rig), black_box(point)))
    });
}

fn table_10k(c: &mut Criterion) {
    let rig = rig();
    let range = SampleRange::Disparity {
        min: 1.0,
        max: 200.0,
    };
    let mut group = c.benchmark_group("table");
    group.throughput(Throughput::Elements(10_000));
    group.bench_function("10k_rows", |b| {
        b.iter(|| {
            physics::table(
                black_box(&rig),
                black_box(range),
                10_000,
                Spacing::Linear,
                400.0,
            )
        })
    });
    group.finish();
}

fn batch_10k(c: &mut Criterion) {
    let rig = rig();
    let points = correspondences(10_000);
    let mut group = c.benchmark_group("batch");
    group.throughput(Throughput::Elements(points.len() as u64));
    group.bench_function("10k_points", |b| {
        b.iter(|| {
            black_box(&points)
                .iter()
                .map(|&p| measure(&rig, p))
                .collect::<Vec<_>>()
        })
    });
    group.finish();
}

/// The seed's example 1 as a `POST /distance` body.
const DISTANCE_BODY: &str = r#"{"focal_length_px": 35, "baseline": 150, "unit": "mm", "x_left": 400, "x_right": 350, "image_width": 800, "image_height": 600}"#;

/// One `POST /distance` through `router`, body read to the end.
async fn post_distance(router: Router) -> usize {
    let request = Request::post("/distance")
        .header(header::CONTENT_TYPE, "application/json")
        .body(Body::from(DISTANCE_BODY))
        .expect("a valid request");
    let response = router.oneshot(request).await.expect("infallible");
    assert!(response.status().is_success());
    to_bytes(response.into_body(), usize::MAX)
        .await
        .map_or(0, |b| b.len())
}

fn router(c: &mut Criterion) {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("a runtime");
    let config = Config::default();
    let full = app(&config, OpsState::default());
    let routes = api::routers(
        AppState {
            limits: config.limits,
        },
        HeavyState::default(),
        OpsState::default(),
    )
    .light;
    let mut group = c.benchmark_group("router");
    group.bench_function("post_distance/full_stack", |b| {
        b.iter(|| runtime.block_on(post_distance(full.clone())))
    });
    group.bench_function("post_distance/routes_only", |b| {
        b.iter(|| runtime.block_on(post_distance(routes.clone())))
    });
    group.finish();
}

criterion_group!(benches, single_distance, table_10k, batch_10k, router);
criterion_main!(benches);
