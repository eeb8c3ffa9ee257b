//! Operating the service over a real socket: request ids, metrics, probes, readiness during
//! drain, graceful shutdown, and the binary's command line and `healthcheck`.

use std::{process::Command, time::Duration};

use serde_json::json;
use stereo_distance::Config;
use tokio::io::AsyncWriteExt;

use crate::helpers::{TestApp, ok_json, problem, read_to_close, spawn_app, spawn_app_with};

const X_REQUEST_ID: &str = "x-request-id";
const EXAMPLE_QUERY: &str = "/distance?focal_length_px=35&baseline=150&image_width=800&image_height=600&x_left=400&x_right=350";

/// A caller's `x-request-id` comes back on the response and inside a problem body.
#[tokio::test]
async fn request_id_is_echoed() {
    // Arrange
    let app = spawn_app().await;

    // Act
    let ok = app
        .get_with_header(EXAMPLE_QUERY, X_REQUEST_ID, "trace-42")
        .await;
    let bad = app
        .get_with_header("/distance?baseline=-1", X_REQUEST_ID, "trace-43")
        .await;

    // Assert
    assert_eq!(ok.headers()[X_REQUEST_ID], "trace-42");
    assert_eq!(bad.headers()[X_REQUEST_ID], "trace-43");
    let problem = problem(bad, 422).await;
    assert_eq!(problem["request_id"], "trace-43");
}

/// Without an incoming id the server makes one (a UUID), sends it back, and quotes it in
/// problem bodies; two requests get different ids.
#[tokio::test]
async fn request_id_is_generated() {
    let app = spawn_app().await;
    let first = app.get("/nowhere").await;
    let second = app.get("/nowhere").await;
    let id = first.headers()[X_REQUEST_ID].to_str().unwrap().to_owned();
    assert_eq!(id.len(), 36, "a UUID: {id}");
    assert_ne!(second.headers()[X_REQUEST_ID].to_str().unwrap(), id);
    let problem = problem(first, 404).await;
    assert_eq!(problem["request_id"], id.as_str());
}

/// `/metrics` counts each request by method, route and status, with a latency histogram.
#[tokio::test]
async fn metrics_count_requests() {
    // Arrange
    let app = spawn_app().await;
    let ok = "{method=\"GET\",route=\"/distance\",status=\"200\"}";
    let invalid = "{method=\"POST\",route=\"/distance\",status=\"422\"}";

    // Act
    ok_json(app.get(EXAMPLE_QUERY).await).await;
    ok_json(app.get(EXAMPLE_QUERY).await).await;
    problem(app.post("/distance", &json!({"baseline": 0})).await, 422).await;
    let response = app.get("/metrics").await;

    // Assert
    assert_eq!(response.status(), 200);
    let content_type = response.headers()["content-type"].to_str().unwrap();
    assert!(content_type.starts_with("text/plain; version=0.0.4"));
    let text = response.text().await.unwrap();
    let value = |series: String| {
        text.lines().find_map(|line| {
            line.strip_prefix(series.as_str())?
                .trim()
                .parse::<f64>()
                .ok()
        })
    };
    assert_eq!(value(format!("http_requests_total{ok}")), Some(2.0));
    assert_eq!(value(format!("http_requests_total{invalid}")), Some(1.0));
    assert_eq!(
        value(format!("http_request_duration_seconds_count{ok}")),
        Some(2.0)
    );
    assert_eq!(value("http_requests_in_flight".to_owned()), Some(1.0));
}

/// Liveness and readiness answer 200 while serving.
#[tokio::test]
async fn probes_answer_while_serving() {
    let app = spawn_app().await;
    assert_eq!(ok_json(app.get("/healthz").await).await["status"], "ok");
    assert_eq!(ok_json(app.get("/readyz").await).await["status"], "ready");
}

/// Polls `/readyz` until it answers 503.
async fn wait_unready(app: &TestApp) -> reqwest::Response {
    for _ in 0..2_000 {
        let response = app.get("/readyz").await;
        if response.status() == 503 {
            return response;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    panic!("/readyz never went unready");
}

/// After a shutdown signal, during the shutdown delay, `/readyz` answers 503 problem+json while
/// `/healthz` and the API keep answering.
#[tokio::test]
async fn readiness_goes_off_during_drain() {
    // Arrange
    let mut app = spawn_app_with(Config {
        port: 0,
        shutdown_delay: Duration::from_secs(60),
        ..Config::default()
    })
    .await;

    // Act
    app.begin_shutdown();
    let readyz = wait_unready(&app).await;

    // Assert
    let problem = problem(readyz, 503).await;
    assert_eq!(problem["errors"][0]["message"], "draining");
    assert_eq!(app.get("/healthz").await.status(), 200);
    let body = ok_json(app.get(EXAMPLE_QUERY).await).await;
    assert_eq!(body["distance"], 105.0);
}

/// A request in flight when shutdown begins is finished and answered; new connections are
/// refused; then the server returns cleanly.
#[tokio::test]
async fn shutdown_drains_in_flight_requests() {
    // Arrange: a request whose body is half sent.
    let mut app = spawn_app().await;
    let (head, body) = crate::fixtures::example_one_request();
    let (first, rest) = body.as_bytes().split_at(10);
    let mut held = app.raw_partial(&head, first).await;
    app.wait_in_flight(2.0).await;

    // Act: shut down, wait until the listener is closed, then finish the request.
    app.begin_shutdown();
    let closed = app.listener_closed().await;
    held.write_all(rest).await.unwrap();
    let answer = read_to_close(&mut held).await;

    // Assert
    assert!(closed, "the listener closes on shutdown");
    assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
    assert!(answer.contains("\"distance\":105"), "{answer}");
    app.stopped().await.expect("a clean stop");
}

/// A connection opened before shutdown, whose client sends its request only after the
/// listener has closed, is still answered (it may have been waiting in the kernel's accept
/// queue or accepted and not yet read); a client cannot know that a fresh connection is about
/// to be closed, so closing it would lose the request.
#[tokio::test]
async fn a_connection_opened_before_shutdown_is_served() {
    // Arrange
    let mut app = spawn_app().await;
    let mut early = tokio::net::TcpStream::connect(app.socket).await.unwrap();

    // Act: shut down; once new connections are refused, send the request.
    app.begin_shutdown();
    let closed = app.listener_closed().await;
    let request =
        format!("GET {EXAMPLE_QUERY} HTTP/1.1\r\nHost: test\r\nConnection: keep-alive\r\n\r\n");
    early.write_all(request.as_bytes()).await.unwrap();
    let answer = read_to_close(&mut early).await;

    // Assert: answered, then closed (the server is stopping), and the server stops.
    assert!(closed, "the listener closes on shutdown");
    assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
    assert!(answer.contains("\"distance\":105"), "{answer}");
    app.stopped().await.expect("a clean stop");
}

/// A connection that never sends a request does not hold shutdown up: the header read timeout
/// closes it, and the server stops.
#[tokio::test]
async fn a_silent_connection_does_not_hold_shutdown() {
    let mut config = Config {
        port: 0,
        ..Config::default()
    };
    config.header_read_timeout = Duration::from_millis(300);
    config.shutdown_timeout = Duration::from_secs(30);
    let mut app = spawn_app_with(config).await;
    let mut silent = tokio::net::TcpStream::connect(app.socket).await.unwrap();

    app.begin_shutdown();

    app.stopped().await.expect("a clean stop");
    assert_eq!(
        read_to_close(&mut silent).await,
        "",
        "closed without an answer"
    );
}

const BINARY: &str = env!("CARGO_BIN_EXE_stereo-distance");

/// `stereo-distance healthcheck` exits 0 against a live server and 1 when nothing listens.
#[tokio::test]
async fn healthcheck_subcommand_probes_the_server() {
    let app = spawn_app().await;
    let port = app.socket.port().to_string();
    let probe = |port: String| {
        Command::new(BINARY)
            .args(["--port", &port, "healthcheck", "--timeout", "5s"])
            .env_clear()
            .output()
            .expect("the binary runs")
    };
    let live = tokio::task::spawn_blocking(move || probe(port))
        .await
        .unwrap();
    assert!(live.status.success(), "{live:?}");

    let free = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let free_port = free.local_addr().unwrap().port().to_string();
    drop(free);
    let dead = tokio::task::spawn_blocking(move || probe(free_port))
        .await
        .unwrap();
    assert_eq!(dead.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&dead.stderr).contains("unhealthy"));
}

/// A bad setting from the environment stops start-up with exit code 2 and a message that
/// names the option; `--help` documents every option with its variable.
#[test]
fn bad_configuration_is_refused_at_start() {
    let refused = Command::new(BINARY)
        .env_clear()
        .env("CONCURRENCY_LIMIT", "0")
        .output()
        .expect("the binary runs");
    assert_eq!(refused.status.code(), Some(2));
    let message = String::from_utf8_lossy(&refused.stderr);
    assert!(message.contains("concurrency-limit"), "{message}");
    assert!(message.contains("from 1 to"), "{message}");

    let help = Command::new(BINARY)
        .arg("--help")
        .env_clear()
        .output()
        .expect("the binary runs");
    assert!(help.status.success());
    let text = String::from_utf8_lossy(&help.stdout);
    for variable in [
        "HOST",
        "PORT",
        "LOG_FORMAT",
        "RUST_LOG",
        "CORS_ALLOWED_ORIGINS",
        "REQUEST_TIMEOUT",
        "HEADER_READ_TIMEOUT",
        "BODY_LIMIT",
        "CONCURRENCY_LIMIT",
        "MAX_TABLE_ROWS",
        "MAX_CHART_POINTS",
        "SHUTDOWN_DELAY",
        "SHUTDOWN_TIMEOUT",
    ] {
        assert!(
            text.contains(&format!("[env: {variable}")),
            "--help lacks {variable}"
        );
    }
}
