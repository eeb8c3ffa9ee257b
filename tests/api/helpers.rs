//! Test support: spawning the application on a free port, and reading its answers.

use std::{io, net::SocketAddr, time::Duration};

use axum::Router;
use reqwest::{Client, Response, StatusCode, header::CONTENT_TYPE};
use serde_json::Value;
use stereo_distance::{Application, Config, api::HeavyState};
use tokio::{
    io::{AsyncReadExt, AsyncWriteExt},
    net::TcpStream,
    sync::oneshot,
    task::JoinHandle,
};

/// A running server and a client for it.
pub struct TestApp {
    pub address: String,
    pub socket: SocketAddr,
    pub client: Client,
    shutdown: Option<oneshot::Sender<()>>,
    server: Option<JoinHandle<io::Result<()>>>,
}

/// Starts the application on 127.0.0.1 with a free port and the default limits, except that
/// its heavy requests may take 2 minutes, not 30 s: a debug build calibrating on
/// two cores shared by the other tests is not what that bound protects against (the tests of
/// the bound set their own).
pub async fn spawn_app() -> TestApp {
    let mut config = Config {
        port: 0,
        ..Config::default()
    };
    config.heavy.request_timeout = Duration::from_secs(120);
    spawn_app_with(config).await
}

/// Starts the application with `config` (use port 0).
pub async fn spawn_app_with(config: Config) -> TestApp {
    spawn_app_with_heavy(config, Router::new()).await
}

/// Starts the application with `config` (use port 0) and `heavy` mounted in its heavy route
/// group.
pub async fn spawn_app_with_heavy(config: Config, heavy: Router<HeavyState>) -> TestApp {
    let application = Application::build_with(config, heavy)
        .await
        .expect("the test server binds");
    let socket = application.local_addr().expect("bound address");
    let (shutdown, stop) = oneshot::channel::<()>();
    let server = tokio::spawn(application.run_until(async {
        // A dropped sender (the test ended) is not a shutdown request.
        if stop.await.is_err() {
            std::future::pending::<()>().await;
        }
    }));
    TestApp {
        address: format!("http://{socket}"),
        socket,
        client: Client::new(),
        shutdown: Some(shutdown),
        server: Some(server),
    }
}

/// A bound on how long a test waits for something that must happen, so that a bug fails the
/// test instead of hanging it. It is never what a test asserts.
pub const PATIENCE: Duration = Duration::from_secs(20);

impl TestApp {
    /// Starts a graceful shutdown, as SIGTERM does.
    pub fn begin_shutdown(&mut self) {
        if let Some(shutdown) = self.shutdown.take() {
            shutdown.send(()).expect("the server is running");
        }
    }

    /// Polls until a new connection is refused (the listener has closed); false if it never
    /// is within [`PATIENCE`].
    pub async fn listener_closed(&self) -> bool {
        for _ in 0..2_000 {
            if TcpStream::connect(self.socket).await.is_err() {
                return true;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        false
    }

    /// Waits for the server task to finish and returns what `run_until` returned.
    pub async fn stopped(&mut self) -> io::Result<()> {
        let server = self.server.take().expect("the server was started");
        tokio::time::timeout(PATIENCE, server)
            .await
            .expect("the server stops")
            .expect("the server task did not panic")
    }

    /// The value of the metric line starting with `series` (name and labels), if present.
    pub async fn metric(&self, series: &str) -> Option<f64> {
        metric_at(&self.client, &self.address, series).await
    }

    /// Polls `/metrics` until `http_requests_in_flight` (which counts the poll itself) reaches
    /// `count`.
    pub async fn wait_in_flight(&self, count: f64) {
        wait_in_flight_at(&self.client, &self.address, count).await;
    }

    /// Opens a raw connection and sends `head` (request line and headers, with the blank line
    /// if wanted) and then `body_start`, leaving the rest of the request unsent.
    pub async fn raw_partial(&self, head: &str, body_start: &[u8]) -> TcpStream {
        let mut stream = TcpStream::connect(self.socket).await.expect("connects");
        stream.write_all(head.as_bytes()).await.expect("head sent");
        stream.write_all(body_start).await.expect("body start sent");
        stream.flush().await.expect("flushed");
        stream
    }

    /// POSTs `body` as JSON to `path`.
    pub async fn post(&self, path: &str, body: &Value) -> Response {
        self.client
            .post(format!("{}{path}", self.address))
            .json(body)
            .send()
            .await
            .expect("request is sent")
    }

    /// POSTs raw bytes with an optional Content-Type.
    pub async fn post_raw(
        &self,
        path: &str,
        content_type: Option<&str>,
        body: Vec<u8>,
    ) -> Response {
        let mut request = self
            .client
            .post(format!("{}{path}", self.address))
            .body(body);
        if let Some(content_type) = content_type {
            request = request.header(CONTENT_TYPE, content_type);
        }
        request.send().await.expect("request is sent")
    }

    /// GETs `path_and_query` as it is.
    pub async fn get(&self, path_and_query: &str) -> Response {
        self.client
            .get(format!("{}{path_and_query}", self.address))
            .send()
            .await
            .expect("request is sent")
    }

    /// POSTs `body` as JSON to `path_and_query` with one extra request header.
    pub async fn post_with_header(
        &self,
        path_and_query: &str,
        body: &Value,
        (name, value): (&str, &str),
    ) -> Response {
        self.client
            .post(format!("{}{path_and_query}", self.address))
            .header(name, value)
            .json(body)
            .send()
            .await
            .expect("request is sent")
    }

    /// GETs `path_and_query` with one extra request header.
    pub async fn get_with_header(&self, path_and_query: &str, name: &str, value: &str) -> Response {
        self.client
            .get(format!("{}{path_and_query}", self.address))
            .header(name, value)
            .send()
            .await
            .expect("request is sent")
    }

    /// POSTs a multipart `form` to `path_and_query`.
    pub async fn post_form(
        &self,
        path_and_query: &str,
        form: reqwest::multipart::Form,
    ) -> Response {
        self.client
            .post(format!("{}{path_and_query}", self.address))
            .multipart(form)
            .send()
            .await
            .expect("request is sent")
    }

    /// GETs `path` with the members of the JSON object `fields` as query parameters.
    pub async fn get_with(&self, path: &str, fields: &Value) -> Response {
        self.get(&format!("{path}?{}", to_query(fields))).await
    }
}

/// The value of the metric line starting with `series` (name and labels) on the server at
/// `address` (`http://host:port`), if present.
pub async fn metric_at(client: &Client, address: &str, series: &str) -> Option<f64> {
    let response = client.get(format!("{address}/metrics")).send().await;
    let text = response.expect("metrics").text().await.expect("metrics");
    text.lines()
        .find_map(|line| line.strip_prefix(series)?.trim().parse().ok())
}

/// Polls the `/metrics` of the server at `address` until `http_requests_in_flight` (which
/// counts the poll itself) reaches `count`, within [`PATIENCE`].
pub async fn wait_in_flight_at(client: &Client, address: &str, count: f64) {
    for _ in 0..2_000 {
        if metric_at(client, address, "http_requests_in_flight").await == Some(count) {
            return;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    panic!("http_requests_in_flight never reached {count}");
}

/// Reads a raw HTTP/1.1 answer until the peer closes (the requests send `Connection: close`),
/// within [`PATIENCE`].
pub async fn read_to_close(stream: &mut TcpStream) -> String {
    let mut answer = Vec::new();
    tokio::time::timeout(PATIENCE, stream.read_to_end(&mut answer))
        .await
        .expect("the server answers or closes")
        .ok();
    String::from_utf8_lossy(&answer).into_owned()
}

/// A JSON object's members as a query string (numbers and strings as they print).
pub fn to_query(fields: &Value) -> String {
    fields
        .as_object()
        .expect("query fields are an object")
        .iter()
        .map(|(key, value)| {
            let value = match value {
                Value::String(s) => s.clone(),
                other => other.to_string(),
            };
            format!("{key}={value}")
        })
        .collect::<Vec<_>>()
        .join("&")
}

/// Asserts a 200 JSON answer and returns its body.
pub async fn ok_json(response: Response) -> Value {
    let status = response.status();
    let body: Value = response.json().await.expect("body is JSON");
    assert_eq!(status, StatusCode::OK, "unexpected answer: {body}");
    body
}

/// Asserts a problem+json answer with `status` and a non-empty `errors`, and returns its body.
pub async fn problem(response: Response, status: u16) -> Value {
    assert_eq!(response.status().as_u16(), status);
    let content_type = response
        .headers()
        .get(CONTENT_TYPE)
        .expect("content-type is set")
        .to_str()
        .unwrap()
        .to_owned();
    assert_eq!(content_type, "application/problem+json");
    let body: Value = response.json().await.expect("problem is JSON");
    assert_eq!(body["status"], status);
    for member in ["type", "title", "detail"] {
        assert!(body[member].is_string(), "problem lacks {member}: {body}");
    }
    assert!(
        !body["errors"].as_array().expect("errors array").is_empty(),
        "errors is empty: {body}"
    );
    body
}

/// The `field` of every entry in a problem's `errors`.
pub fn fields(problem: &Value) -> Vec<String> {
    problem["errors"]
        .as_array()
        .expect("errors array")
        .iter()
        .map(|e| e["field"].as_str().expect("field is a string").to_owned())
        .collect()
}

/// The message given for `field` in a problem's `errors`.
/// Asserts that the problem names each of `expected` among its fields.
pub fn assert_names(problem: &Value, expected: &[&str]) {
    let named = fields(problem);
    for field in expected {
        assert!(
            named.contains(&(*field).to_owned()),
            "{field} not in {named:?}"
        );
    }
}

pub fn message_for<'a>(problem: &'a Value, field: &str) -> &'a str {
    problem["errors"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["field"] == field)
        .and_then(|e| e["message"].as_str())
        .unwrap_or_else(|| panic!("no error for {field}: {problem}"))
}

/// `actual` equals `expected` within 1e-6 relative (absolute near zero).
pub fn assert_close(actual: f64, expected: f64, what: &str) {
    let tolerance = 1e-6 * expected.abs().max(1e-6);
    assert!(
        (actual - expected).abs() <= tolerance,
        "{what}: got {actual}, expected {expected}"
    );
}

/// A number at a dotted path such as `point.x`.
pub fn number_at(body: &Value, path: &str) -> f64 {
    path.split('.')
        .fold(body, |value, key| &value[key])
        .as_f64()
        .unwrap_or_else(|| panic!("{path} is not a number in {body}"))
}

/// The numbers of a JSON array, nested arrays (a matrix's rows) read in order.
pub fn numbers(v: &Value) -> Vec<f64> {
    match v {
        Value::Array(items) => items.iter().flat_map(numbers).collect(),
        other => vec![
            other
                .as_f64()
                .unwrap_or_else(|| panic!("{other} is not a number")),
        ],
    }
}
