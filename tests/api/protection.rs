//! Protective layers over a real socket: body limit, load shedding, request and header
//! timeouts, CORS and compression.

use std::{io::Read, time::Duration};

use reqwest::header::{
    ACCEPT_ENCODING, ACCESS_CONTROL_ALLOW_ORIGIN, CONTENT_ENCODING, ORIGIN, RETRY_AFTER,
};
use serde_json::Value;
use stereo_distance::Config;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

use crate::helpers::{
    PATIENCE, fields, message_for, ok_json, problem, read_to_close, spawn_app, spawn_app_with,
};

fn config() -> Config {
    Config {
        port: 0,
        ..Config::default()
    }
}

use crate::fixtures::example_one_request;

/// A configured body limit is enforced with a 413 problem that names the body and the limit.
#[tokio::test]
async fn body_over_configured_limit_is_413() {
    // Arrange
    let mut config = config();
    config.limits.body_bytes = 1024;
    config.limits.batch_body_bytes = 2048;
    let app = spawn_app_with(config).await;
    let body = |spaces: usize| format!("{{\"baseline\": 150{}}}", " ".repeat(spaces));

    // Act
    let table = app
        .post_raw("/table", Some("application/json"), body(1500).into())
        .await;
    let distance = app
        .post_raw("/distance", Some("application/json"), body(2500).into())
        .await;

    // Assert
    let problem_body = problem(table, 413).await;
    assert_eq!(fields(&problem_body), vec!["body"]);
    assert!(message_for(&problem_body, "body").contains("1024"));
    let problem_body = problem(distance, 413).await;
    assert!(message_for(&problem_body, "body").contains("2048"));
}

/// Past the concurrency limit a request is refused at once with 503 problem+json and
/// `Retry-After`, while the request holding the slot still completes; probes are never shed.
#[tokio::test]
async fn over_concurrency_limit_is_503_with_retry_after() {
    // Arrange: a limit of 1, taken by a request whose body is only half sent.
    let mut config = config();
    config.concurrency_limit = 1;
    let app = spawn_app_with(config).await;
    let (head, body) = example_one_request();
    let (first, rest) = body.as_bytes().split_at(10);
    let mut held = app.raw_partial(&head, first).await;
    app.wait_in_flight(2.0).await; // the held request and this /metrics poll

    // Act
    let shed = app.get("/distance?x_left=1").await;
    let healthz = app.get("/healthz").await;

    // Assert
    assert_eq!(shed.headers()[RETRY_AFTER], "1");
    let problem = problem(shed, 503).await;
    assert!(
        problem["detail"]
            .as_str()
            .unwrap()
            .contains("concurrency limit")
    );
    assert_eq!(healthz.status(), 200);

    // The held request finishes normally once its body arrives.
    held.write_all(rest).await.unwrap();
    let answer = read_to_close(&mut held).await;
    assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
    assert!(answer.contains("\"distance\":105"), "{answer}");
    let count = app
        .metric("http_requests_total{method=\"GET\",route=\"/distance\",status=\"503\"}")
        .await;
    assert_eq!(count, Some(1.0));
}

/// A body that is still arriving at the request timeout gets a 408 problem naming the body.
#[tokio::test]
async fn slow_body_is_408() {
    // Arrange
    let mut config = config();
    config.request_timeout = Duration::from_millis(200);
    let app = spawn_app_with(config).await;
    let (head, body) = example_one_request();

    // Act: send half of the body and never the rest.
    let mut stream = app.raw_partial(&head, &body.as_bytes()[..10]).await;
    let answer = read_to_close(&mut stream).await;

    // Assert
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    assert!(
        answer.contains("content-type: application/problem+json"),
        "{answer}"
    );
    assert!(answer.contains("\"field\":\"body\""), "{answer}");
}

/// A client that dribbles its headers is disconnected by the header read timeout, without a
/// request ever reaching the API.
#[tokio::test]
async fn slow_headers_are_cut_off() {
    // Arrange
    let mut config = config();
    config.header_read_timeout = Duration::from_millis(200);
    let app = spawn_app_with(config).await;

    // Act: an unfinished head (no blank line), then wait for the server to act.
    let mut stream = app
        .raw_partial("GET /distance HTTP/1.1\r\nHost: test\r\n", b"")
        .await;
    let mut buffer = [0u8; 256];
    let read = tokio::time::timeout(PATIENCE, stream.read(&mut buffer))
        .await
        .expect("the server acts before the test's patience runs out");

    // Assert: the connection is closed (EOF or reset), with no HTTP answer.
    match read {
        Ok(n) => assert_eq!(n, 0, "got {:?}", String::from_utf8_lossy(&buffer[..n])),
        Err(error) => assert_eq!(error.kind(), std::io::ErrorKind::ConnectionReset),
    }
    assert_eq!(
        app.metric("http_requests_total{method=\"GET\",route=\"/distance\"")
            .await,
        None
    );
}

/// A preflight from an allowed origin is granted; one from another origin is not.
#[tokio::test]
async fn cors_preflight_allowed_and_refused() {
    // Arrange
    let mut config = config();
    config.cors_allowed_origins = vec!["https://app.example.com".to_owned()];
    let app = spawn_app_with(config).await;
    let preflight = |origin: &'static str| {
        app.client
            .request(
                reqwest::Method::OPTIONS,
                format!("{}/distance", app.address),
            )
            .header(ORIGIN, origin)
            .header("access-control-request-method", "POST")
            .header("access-control-request-headers", "content-type")
            .send()
    };

    // Act
    let allowed = preflight("https://app.example.com").await.unwrap();
    let refused = preflight("https://evil.example.com").await.unwrap();
    let simple = app
        .get_with_header("/healthz", ORIGIN.as_str(), "https://app.example.com")
        .await;

    // Assert
    assert_eq!(allowed.status(), 200);
    assert_eq!(
        allowed.headers()[ACCESS_CONTROL_ALLOW_ORIGIN],
        "https://app.example.com"
    );
    let methods = allowed.headers()["access-control-allow-methods"]
        .to_str()
        .unwrap();
    assert!(methods.contains("POST"), "{methods}");
    assert!(
        !refused.headers().contains_key(ACCESS_CONTROL_ALLOW_ORIGIN),
        "a foreign origin is not granted"
    );
    assert_eq!(
        simple.headers()[ACCESS_CONTROL_ALLOW_ORIGIN],
        "https://app.example.com"
    );
}

/// By default no origin is allowed: a preflight gets no CORS grant.
#[tokio::test]
async fn cors_is_off_by_default() {
    let app = spawn_app().await;
    let response = app
        .client
        .request(
            reqwest::Method::OPTIONS,
            format!("{}/distance", app.address),
        )
        .header(ORIGIN, "https://app.example.com")
        .header("access-control-request-method", "POST")
        .send()
        .await
        .unwrap();
    assert!(!response.headers().contains_key(ACCESS_CONTROL_ALLOW_ORIGIN));
}

/// A client that accepts gzip gets a gzip body that decodes to the same table; one that does
/// not gets plain JSON; brotli is offered too.
#[tokio::test]
async fn compresses_when_asked() {
    // Arrange
    let app = spawn_app().await;
    let url = "/table?focal_length_px=35&baseline=150&image_width=800&image_height=600&steps=1000";

    // Act
    let gzip = app
        .get_with_header(url, ACCEPT_ENCODING.as_str(), "gzip")
        .await;
    let brotli = app
        .get_with_header(url, ACCEPT_ENCODING.as_str(), "br")
        .await;
    let plain = ok_json(app.get(url).await).await;

    // Assert
    assert_eq!(gzip.status(), 200);
    assert_eq!(gzip.headers()[CONTENT_ENCODING], "gzip");
    assert_eq!(brotli.headers()[CONTENT_ENCODING], "br");
    let compressed = gzip.bytes().await.unwrap();
    let mut text = String::new();
    flate2::read::GzDecoder::new(&compressed[..])
        .read_to_string(&mut text)
        .expect("a valid gzip stream");
    let table: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(table["rows"].as_array().unwrap().len(), 1000);
    assert_eq!(table, plain);
    assert!(
        compressed.len() * 3 < text.len(),
        "gzip actually compresses"
    );
}
