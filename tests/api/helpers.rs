//! Test support: spawning the application on a free port, and reading its answers.

use reqwest::{Client, Response, StatusCode, header::CONTENT_TYPE};
use serde_json::Value;
use stereo_distance::{Application, Config};

/// A running server and a client for it.
pub struct TestApp {
    pub address: String,
    pub client: Client,
}

/// Starts the application on 127.0.0.1 with a free port and the default limits.
pub async fn spawn_app() -> TestApp {
    spawn_app_with(Config {
        port: 0,
        ..Config::default()
    })
    .await
}

/// Starts the application with `config` (use port 0).
pub async fn spawn_app_with(config: Config) -> TestApp {
    let application = Application::build(config)
        .await
        .expect("the test server binds");
    let address = format!(
        "http://{}",
        application.local_addr().expect("bound address")
    );
    tokio::spawn(application.run_until(std::future::pending()));
    TestApp {
        address,
        client: Client::new(),
    }
}

impl TestApp {
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

    /// GETs `path` with the members of the JSON object `fields` as query parameters.
    pub async fn get_with(&self, path: &str, fields: &Value) -> Response {
        self.get(&format!("{path}?{}", to_query(fields))).await
    }
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
