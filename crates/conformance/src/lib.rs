//! What the service promises for *any* request, checked in process on arbitrary input: the
//! one oracle shared by the cargo-fuzz target (`fuzz/`) and the bounded random-input test
//! (`tests/hostile_input.rs`). A dev-only crate of the workspace: the service's own build
//! never compiles it.
//!
//! For every operation that reads input, the bytes are sent as a JSON body (`POST`) and as a
//! query string (`GET`), and to `/calibration` as a text body, through the full router,
//! middleware included. `/depth-map` gets them as a whole multipart body, and as both images
//! of a well-formed form (the image decoders' input); `/match` gets them as its body, as both
//! images, and as the `points` and the `regions` part of a synthetic pair's form. The
//! promises:
//! - no 5xx, and no panic (a panic would surface as a 500 from the edge layer);
//! - a 4xx is `application/problem+json` whose `status` is the HTTP status and whose
//!   `errors` names at least one field;
//! - a 2xx JSON answer holds no `null` (a non-finite number would serialise as `null`);
//!   a CSV or SVG answer is text.

use axum::{
    Router,
    body::{Body, to_bytes},
    http::{Method, Request, StatusCode, header},
};
use tower::ServiceExt;

use stereo_core::vision::{encode, synthetic};
use stereo_distance::{Config, api::routes::ops::OpsState, app};

/// The operations that read a body (`POST`) and a query (`GET`).
const BODY_PATHS: [&str; 8] = [
    "/distance",
    "/table",
    "/table.csv",
    "/chart-data",
    "/chart-data.csv",
    "/rig",
    "/baseline",
    "/calibration",
];
const QUERY_PATHS: [&str; 8] = [
    "/distance",
    "/table",
    "/table.csv",
    "/chart-data",
    "/chart-data.csv",
    "/chart.svg",
    "/rig",
    "/baseline",
];

/// The media types of the answers that are not JSON.
const FILE_TYPES: [&str; 6] = [
    "text/csv",
    "image/svg+xml",
    "image/png",
    "image/x-portable-floatmap",
    "application/x-npy",
    "application/x-ply",
];

/// Every output of `/depth-map`.
const OUTPUTS: [&str; 9] = [
    "summary",
    "disparity.pfm",
    "disparity.png",
    "disparity.npy",
    "depth.npy",
    "arrays.npz",
    "depth.png",
    "preview.png",
    "points.ply",
];

/// The multipart boundary of the forms sent.
const BOUNDARY: &str = "conformance-boundary";

/// A multipart form of `parts`: each a name, a file name for files, and the bytes.
fn form(parts: &[(&str, Option<&str>, &[u8])]) -> Vec<u8> {
    let mut body = Vec::new();
    for (name, file, bytes) in parts {
        let file = file.map_or(String::new(), |f| format!("; filename=\"{f}\""));
        body.extend_from_slice(
            format!(
                "--{BOUNDARY}\r\nContent-Disposition: form-data; name=\"{name}\"{file}\r\n\r\n"
            )
            .as_bytes(),
        );
        body.extend_from_slice(bytes);
        body.extend_from_slice(b"\r\n");
    }
    body.extend_from_slice(format!("--{BOUNDARY}--\r\n").as_bytes());
    body
}

/// A `POST` of a multipart `body` (parts separated by [`BOUNDARY`]) to `uri`.
fn multipart(uri: &str, body: Vec<u8>) -> Result<Request<Body>, String> {
    Request::builder()
        .method(Method::POST)
        .uri(uri)
        .header(
            header::CONTENT_TYPE,
            format!("multipart/form-data; boundary={BOUNDARY}"),
        )
        .body(Body::from(body))
        .map_err(|e| format!("building POST {uri}: {e}"))
}

/// The rig part of every form sent.
const RIG: &[u8] = br#"{"focal_length_px": 500, "baseline": 100}"#;

/// A well-formed `/depth-map` form whose two images are `image`, with a rig.
pub fn image_form(image: &[u8]) -> Vec<u8> {
    form(&[
        ("left", Some("left.png"), image),
        ("right", Some("right.png"), image),
        ("rig", None, RIG),
    ])
}

/// A `/match` form of a pair, points and regions, with a rig.
fn match_form(left: &[u8], right: &[u8], points: &[u8], regions: &[u8]) -> Vec<u8> {
    form(&[
        ("left", Some("left.png"), left),
        ("right", Some("right.png"), right),
        ("points", None, points),
        ("regions", None, regions),
        ("rig", None, RIG),
    ])
}

/// Points and regions that a small image answers: on it, off it, and at its edge.
const POINTS: &[u8] = br#"[{"x": 3, "y": 2}, {"x": -1, "y": 0}, {"x": 31.5, "y": 23.4}]"#;
const REGIONS: &[u8] = br#"[{"x": 0, "y": 0, "width": 4, "height": 4}, {"x": 30, "y": 20, "width": 90, "height": 1e9}]"#;

/// The application with its default configuration, on a single-threaded runtime.
pub struct Harness {
    runtime: tokio::runtime::Runtime,
    router: Router,
    /// A small synthetic pair, as PNG, for the forms whose other parts are the input.
    pair: [Vec<u8>; 2],
}

impl Default for Harness {
    fn default() -> Self {
        Self::new()
    }
}

impl Harness {
    pub fn new() -> Self {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("a current-thread runtime");
        let router = app(&Config::default(), OpsState::default());
        let (w, h) = (48, 32);
        let rendered = synthetic::render(&synthetic::layered(w, h));
        let pair = [
            encode::png_rgb(w, h, &rendered.left_rgb),
            encode::png_rgb(w, h, &rendered.right_rgb),
        ];
        Self {
            runtime,
            router,
            pair,
        }
    }

    /// Sends `input` to every operation, as a JSON body and as a query string, and returns the
    /// statuses of the answers; `Err` names the first broken promise.
    pub fn check(&self, input: &[u8]) -> Result<Vec<StatusCode>, String> {
        self.runtime.block_on(async {
            let mut statuses = Vec::new();
            for path in BODY_PATHS {
                let request = Request::builder()
                    .method(Method::POST)
                    .uri(path)
                    .header(header::CONTENT_TYPE, "application/json")
                    .body(Body::from(input.to_vec()))
                    .map_err(|e| format!("building POST {path}: {e}"))?;
                statuses.push(self.exchange(request).await?);
            }
            // A calibration file may also be the raw body.
            let request = Request::builder()
                .method(Method::POST)
                .uri("/calibration")
                .header(header::CONTENT_TYPE, "text/plain")
                .body(Body::from(input.to_vec()))
                .map_err(|e| format!("building POST /calibration: {e}"))?;
            statuses.push(self.exchange(request).await?);
            // The image route: the bytes as the multipart body itself, and as both images of a
            // form with a rig, asking for the output the first byte picks (every encoder runs).
            let output = OUTPUTS[usize::from(input.first().copied().unwrap_or(0)) % OUTPUTS.len()];
            for body in [input.to_vec(), image_form(input)] {
                let uri = format!("/depth-map?max_disparity=16&output={output}");
                statuses.push(self.exchange(multipart(&uri, body)?).await?);
            }
            // `/match`: the bytes as the body, as both images, and as the points and the regions
            // of a synthetic pair.
            let [left, right] = &self.pair;
            for body in [
                input.to_vec(),
                match_form(input, input, POINTS, REGIONS),
                match_form(left, right, input, REGIONS),
                match_form(left, right, POINTS, input),
            ] {
                statuses.push(
                    self.exchange(multipart("/match?max_disparity=8", body)?)
                        .await?,
                );
            }
            let query = as_query(input);
            for path in QUERY_PATHS {
                let Ok(request) = Request::get(format!("{path}?{query}")).body(Body::empty())
                else {
                    continue;
                };
                statuses.push(self.exchange(request).await?);
            }
            Ok(statuses)
        })
    }

    async fn exchange(&self, request: Request<Body>) -> Result<StatusCode, String> {
        let what = format!("{} {}", request.method(), request.uri());
        let response = self
            .router
            .clone()
            .oneshot(request)
            .await
            .map_err(|e| format!("{what}: {e}"))?;
        let status = response.status();
        let content_type = response
            .headers()
            .get(header::CONTENT_TYPE)
            .and_then(|v| v.to_str().ok())
            .unwrap_or_default()
            .to_owned();
        let body = to_bytes(response.into_body(), usize::MAX)
            .await
            .map_err(|e| format!("{what}: reading the answer: {e}"))?;
        let text = String::from_utf8_lossy(&body);
        if status.is_server_error() {
            return Err(format!("{what}: {status}: {text}"));
        }
        if status.is_client_error() {
            return problem(status, &content_type, &body)
                .map(|()| status)
                .map_err(|e| format!("{what}: {e}"));
        }
        if content_type.starts_with("application/json") {
            let value: serde_json::Value = serde_json::from_slice(&body)
                .map_err(|e| format!("{what}: {status} is not JSON ({e}): {text}"))?;
            if contains_null(&value) {
                return Err(format!("{what}: {status} holds a null: {text}"));
            }
        } else if !FILE_TYPES.iter().any(|t| content_type.starts_with(t)) {
            return Err(format!(
                "{what}: {status} with content type {content_type:?}"
            ));
        }
        Ok(status)
    }
}

/// Whether a 4xx is a well-formed problem that names a field.
fn problem(status: StatusCode, content_type: &str, body: &[u8]) -> Result<(), String> {
    if content_type != "application/problem+json" {
        return Err(format!("{status} with content type {content_type:?}"));
    }
    let value: serde_json::Value =
        serde_json::from_slice(body).map_err(|e| format!("{status} problem is not JSON: {e}"))?;
    if value["status"] != status.as_u16() {
        return Err(format!("{status} problem says status {}", value["status"]));
    }
    let names_a_field = value["errors"].as_array().is_some_and(|errors| {
        !errors.is_empty()
            && errors
                .iter()
                .all(|e| e["field"].as_str().is_some_and(|f| !f.is_empty()))
    });
    if names_a_field {
        Ok(())
    } else {
        Err(format!("{status} problem names no field: {value}"))
    }
}

fn contains_null(value: &serde_json::Value) -> bool {
    match value {
        serde_json::Value::Null => true,
        serde_json::Value::Array(items) => items.iter().any(contains_null),
        serde_json::Value::Object(members) => members.values().any(contains_null),
        _ => false,
    }
}

/// `input` as the query part of a URI: bytes a URI may carry in a query are kept as they are
/// (so `&`, `=`, `%` and `+` keep their meaning to the decoder), the rest percent-encoded.
pub fn as_query(input: &[u8]) -> String {
    let mut query = String::with_capacity(input.len());
    for &byte in input {
        let keep = byte.is_ascii_alphanumeric() || b"-._~!$&'()*+,;=:@/?%".contains(&byte);
        if keep {
            query.push(char::from(byte));
        } else {
            query.push_str(&format!("%{byte:02X}"));
        }
    }
    query
}
