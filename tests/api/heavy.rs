//! The heavy route group's limits over a real socket, apart from any image route: a
//! test-only route is mounted in the group (`Application::build_with`) and driven past its body
//! limit, its concurrency limit and its memory budget, while the light group and the probes
//! keep answering.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use axum::{Router, extract::Query, routing::post};
use reqwest::header::RETRY_AFTER;
use serde::Deserialize;
use serde_json::{Value, json};
use stereo_distance::{
    Config,
    api::{
        HeavyState,
        error::ApiError,
        extract::JsonBody,
        images::work::{self, Admitted},
    },
    config::HeavyLimits,
};
use tokio::io::AsyncWriteExt;

use crate::{
    fixtures::{example_one, post_head},
    helpers::{
        TestApp, fields, message_for, ok_json, problem, read_to_close, spawn_app_with_heavy,
    },
};

const KIB: usize = 1024;

/// The test route's query: bytes to hold besides the body, as an image route holds its cost
/// volume once it knows the image size; or, with `hold`, work that takes a slot and runs until
/// [`RELEASE`] is set.
#[derive(Deserialize)]
struct Work {
    work: Option<usize>,
    hold: Option<bool>,
}

/// Ends the work of `POST /test/heavy?hold=true`.
static RELEASE: AtomicBool = AtomicBool::new(false);

/// `POST /test/heavy`: reads a JSON body within the group's body limit, grows its reservation
/// by `?work=`, and answers the body's `data` length and the bytes it holds; with `?hold=true`
/// its work takes one of the group's slots (as an image route's does) and holds it until
/// [`RELEASE`].
async fn upload(
    admitted: Admitted,
    Query(Work { work, hold }): Query<Work>,
    JsonBody(body, _): JsonBody<Value>,
) -> Result<axum::Json<Value>, ApiError> {
    if let Some(more) = work {
        admitted.reservation.grow(more).map_err(ApiError::Memory)?;
    }
    let bytes = admitted.reservation.bytes();
    if hold == Some(true) {
        work::run_reserved(
            admitted,
            0,
            |_| Vec::new(),
            |_, _| {
                while !RELEASE.load(Ordering::Acquire) {
                    std::thread::sleep(Duration::from_millis(5));
                }
            },
        )
        .await?;
    }
    let received = body["data"].as_str().map_or(0, str::len);
    Ok(axum::Json(json!({"received": received, "reserved": bytes})))
}

/// `POST /test/panic`: an image route whose work has a bug.
async fn panics(admitted: Admitted) -> Result<&'static str, ApiError> {
    work::run_reserved(
        admitted,
        1024,
        |_| Vec::new(),
        |_, _| panic!("a bug in an image handler"),
    )
    .await
}

/// A server whose heavy group has `heavy` limits and serves the test routes.
async fn spawn(heavy: HeavyLimits) -> TestApp {
    let config = Config {
        port: 0,
        heavy,
        ..Config::default()
    };
    let route = Router::<HeavyState>::new()
        .route("/test/heavy", post(upload))
        .route("/test/panic", post(panics));
    spawn_app_with_heavy(config, route).await
}

/// POSTs a JSON body of `len` bytes to the test route (`upload`), asking it to hold `work` bytes more.
async fn send(app: &TestApp, len: usize, work: Option<usize>) -> reqwest::Response {
    let path = match work {
        Some(work) => format!("/test/heavy?work={work}"),
        None => "/test/heavy".to_owned(),
    };
    app.post_raw(&path, Some("application/json"), body_of(len).into())
        .await
}

/// A JSON body of `len` bytes whose `data` member is `len - 12` letters.
fn body_of(len: usize) -> String {
    format!(r#"{{"data": "{}"}}"#, "x".repeat(len - 12))
}

/// The heavy group reads bodies up to its own limit, far above the light group's, and answers
/// a larger one 413 problem+json naming the body and the heavy limit.
#[tokio::test]
async fn heavy_body_limit_is_its_own() {
    // Arrange: the light group keeps its 64 KiB; the heavy group takes 256 KiB.
    let app = spawn(HeavyLimits {
        body_bytes: 256 * KIB,
        ..HeavyLimits::default()
    })
    .await;

    // Act
    let accepted = send(&app, 200 * KIB, None).await;
    let refused = send(&app, 300 * KIB, None).await;
    let light = app
        .post_raw(
            "/table",
            Some("application/json"),
            body_of(200 * KIB).into(),
        )
        .await;

    // Assert
    let accepted = ok_json(accepted).await;
    assert_eq!(accepted["received"], 200 * KIB - 12);
    assert_eq!(
        accepted["reserved"],
        200 * KIB,
        "the declared body is reserved"
    );
    let refused = problem(refused, 413).await;
    assert_eq!(fields(&refused), vec!["body"]);
    assert!(
        message_for(&refused, "body").contains(&(256 * KIB).to_string()),
        "{refused}"
    );
    let light = problem(light, 413).await;
    assert!(
        message_for(&light, "body").contains("65536"),
        "the light group keeps its own limit: {light}"
    );
}

/// A request whose body is still arriving holds no slot of the heavy group: with one slot,
/// another request is served meanwhile. Past the concurrency limit, a request whose work would
/// start is refused at once with 503 problem+json and `Retry-After`, while light requests and
/// probes still answer; the held requests complete, the half-sent one once its body arrives.
#[tokio::test]
async fn heavy_concurrency_limit_sheds_only_the_heavy_group() {
    // Arrange: one heavy slot; a request whose body is half sent.
    let app = spawn(HeavyLimits {
        concurrency_limit: 1,
        ..HeavyLimits::default()
    })
    .await;
    let body = body_of(4 * KIB);
    let (first, rest) = body.as_bytes().split_at(100);
    let mut held = app
        .raw_partial(&post_head("/test/heavy", body.len()), first)
        .await;
    app.wait_in_flight(2.0).await; // the held request and this /metrics poll
    let uploading = send(&app, 100, None).await;

    // Act: a request whose work holds the one slot, then another.
    let working = {
        let (client, address) = (app.client.clone(), app.address.clone());
        tokio::spawn(async move {
            client
                .post(format!("{address}/test/heavy?hold=true"))
                .header("content-type", "application/json")
                .body(body_of(100))
                .send()
                .await
                .unwrap()
                .status()
        })
    };
    for _ in 0..2000 {
        if app.metric("heavy_requests_working").await == Some(1.0) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let shed = app
        .post_raw(
            "/test/heavy?hold=true",
            Some("application/json"),
            body_of(100).into(),
        )
        .await;
    let light = app.post("/distance", &example_one()).await;
    let probe = app.get("/readyz").await;
    RELEASE.store(true, Ordering::Release);

    // Assert
    assert_eq!(ok_json(uploading).await["received"], 88);
    assert_eq!(working.await.unwrap(), 200);
    assert_eq!(shed.headers()[RETRY_AFTER], "1");
    let shed = problem(shed, 503).await;
    assert!(
        shed["detail"]
            .as_str()
            .unwrap()
            .contains("concurrency limit"),
        "{shed}"
    );
    assert_eq!(ok_json(light).await["distance"], 105.0);
    assert_eq!(probe.status(), 200);
    held.write_all(rest).await.unwrap();
    let answer = read_to_close(&mut held).await;
    assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
    assert!(answer.contains("\"received\":4084"), "{answer}");
}

/// The memory budget is shared by the heavy requests in flight: each reserves its declared body
/// on arrival, and a request that does not fit is refused 503 with `Retry-After`, as is a
/// handler's growth past what is free; a growth past the whole budget is a 413. Light requests
/// still answer, and once the held requests finish the budget is whole again.
#[tokio::test]
async fn heavy_memory_budget_refuses_what_does_not_fit() {
    // Arrange: a 1 MiB budget, two requests each holding 400 KiB of declared body.
    let app = spawn(HeavyLimits {
        body_bytes: 512 * KIB,
        memory_budget: 1024 * KIB,
        concurrency_limit: 8,
        ..HeavyLimits::default()
    })
    .await;
    let body = body_of(400 * KIB);
    let (first, rest) = body.as_bytes().split_at(100);
    let mut held = Vec::new();
    for _ in 0..2 {
        let stream = app
            .raw_partial(&post_head("/test/heavy", body.len()), first)
            .await;
        held.push(stream);
    }
    app.wait_in_flight(3.0).await;

    // Act
    let third = send(&app, 400 * KIB, None).await;
    let grows_past_free = send(&app, 100, Some(300 * KIB)).await;
    let grows_past_budget = send(&app, 100, Some(2048 * KIB)).await;
    let light = app.post("/distance", &example_one()).await;

    // Assert
    assert_eq!(third.headers()[RETRY_AFTER], "1");
    let third = problem(third, 503).await;
    assert!(
        third["detail"].as_str().unwrap().contains("memory budget"),
        "{third}"
    );
    assert_eq!(grows_past_free.headers()[RETRY_AFTER], "1");
    problem(grows_past_free, 503).await;
    let too_large = problem(grows_past_budget, 413).await;
    assert!(
        message_for(&too_large, "request").contains("at most 1 MiB fits"),
        "{too_large}"
    );
    assert_eq!(ok_json(light).await["distance"], 105.0);

    // The held requests finish and give their memory back: the third now fits, with its work.
    for mut stream in held {
        stream.write_all(rest).await.unwrap();
        let answer = read_to_close(&mut stream).await;
        assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
    }
    let retried = send(&app, 400 * KIB, Some(300 * KIB)).await;
    assert_eq!(ok_json(retried).await["reserved"], 700 * KIB);
}

/// A panic in an image route's work is a 500 problem carrying the request's id, counted in
/// the metrics; the slot and the memory it held are given back, so the group keeps serving.
#[tokio::test]
async fn a_panic_is_a_500_problem_and_frees_its_slot_and_memory() {
    // Arrange: one slot, and a budget that holds one body at a time.
    let app = spawn(HeavyLimits {
        body_bytes: 64 * KIB,
        memory_budget: 100 * KIB,
        concurrency_limit: 1,
        ..HeavyLimits::default()
    })
    .await;

    // Act
    let panicked = app
        .client
        .post(format!("{}/test/panic", app.address))
        .header("x-request-id", "bug-1")
        .body(body_of(60 * KIB))
        .send()
        .await
        .unwrap();
    let after = send(&app, 60 * KIB, None).await;

    // Assert
    assert_eq!(panicked.headers()["x-request-id"], "bug-1");
    let problem_body = problem(panicked, 500).await;
    assert_eq!(problem_body["request_id"], "bug-1");
    assert_eq!(
        message_for(&problem_body, "request"),
        "a bug in an image handler"
    );
    assert_eq!(ok_json(after).await["reserved"], 60 * KIB);
    assert_eq!(app.metric("heavy_requests_working").await, Some(0.0));
    assert_eq!(app.metric("heavy_memory_reserved_bytes").await, Some(0.0));
    let count = app
        .metric("http_requests_total{method=\"POST\",route=\"/test/panic\",status=\"500\"}")
        .await;
    assert_eq!(count, Some(1.0));
}
