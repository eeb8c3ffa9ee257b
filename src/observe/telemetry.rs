//! Logs and request ids: the tracing subscriber, the `x-request-id` that follows each request
//! (the caller's, or a UUID v4 made here), and the access log line written per request.

use std::{future::Future, io::IsTerminal};

use axum::http::{HeaderMap, HeaderName, HeaderValue, StatusCode};
use tracing_subscriber::EnvFilter;

use crate::config::{AccessLog, LogFormat};

/// The header that carries the request id in and out.
pub static X_REQUEST_ID: HeaderName = HeaderName::from_static("x-request-id");

/// The route label of a request that matched no route.
pub const UNMATCHED_ROUTE: &str = "unmatched";

tokio::task_local! {
    /// The id of the request being served, for error bodies built deep inside the handler.
    static REQUEST_ID: HeaderValue;
}

/// Installs the global subscriber: `filter` in EnvFilter syntax, lines in `format`.
pub fn init(format: LogFormat, filter: &str) -> Result<(), String> {
    let filter = EnvFilter::try_new(filter).map_err(|error| error.to_string())?;
    // Colours only on a terminal: escape codes in a file or a collector are noise.
    let builder = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::stdout().is_terminal());
    let result = match format {
        LogFormat::Pretty => builder.try_init(),
        LogFormat::Json => builder
            .json()
            .flatten_event(true)
            .with_current_span(true)
            .with_span_list(false)
            .try_init(),
    };
    result.map_err(|error| error.to_string())
}

/// The request id of the request being served, if any.
pub fn current_request_id() -> Option<String> {
    REQUEST_ID
        .try_with(|id| id.to_str().ok().map(str::to_owned))
        .ok()
        .flatten()
}

/// Runs `future` as the request with id `id`: [`current_request_id`] sees it throughout.
pub async fn with_request_id<F: Future>(id: HeaderValue, future: F) -> F::Output {
    REQUEST_ID.scope(id, future).await
}

/// Runs `f` as the request with id `id`, synchronously.
pub fn in_request<R>(id: HeaderValue, f: impl FnOnce() -> R) -> R {
    REQUEST_ID.sync_scope(id, f)
}

/// The longest caller-supplied request id that is kept; a longer one is replaced.
pub const MAX_REQUEST_ID_LEN: usize = 200;

/// The request's id: the caller's `x-request-id` when it has one of printable ASCII of at most
/// [`MAX_REQUEST_ID_LEN`] bytes, otherwise a new random UUID v4.
pub fn request_id(headers: &HeaderMap) -> HeaderValue {
    match headers.get(&X_REQUEST_ID) {
        Some(id) if !id.is_empty() && id.len() <= MAX_REQUEST_ID_LEN && id.to_str().is_ok() => {
            id.clone()
        }
        _ => new_request_id(),
    }
}

/// A random UUID v4 (RFC 9562) in its 36-character hyphenated form, from the `uuid` crate's
/// fast thread-local generator (no system call per id).
pub fn new_request_id() -> HeaderValue {
    let mut text = [0u8; uuid::fmt::Hyphenated::LENGTH];
    let text = uuid::Uuid::new_v4().hyphenated().encode_lower(&mut text);
    HeaderValue::from_str(text).expect("hex digits and hyphens are a valid header value")
}

/// Writes the access log line of one answered request, if `policy` asks for it: `info` for
/// answers below 500, `warn` for server errors. The target is `access`, so that a filter such
/// as `info,access=off` can silence it too.
pub fn access_log(
    policy: AccessLog,
    method: &str,
    route: &str,
    path: &str,
    status: StatusCode,
    seconds: f64,
    request_id: &HeaderValue,
) {
    let wanted = match policy {
        AccessLog::Off => false,
        AccessLog::Errors => status.as_u16() >= 400,
        AccessLog::All => true,
    };
    if !wanted {
        return;
    }
    let status = status.as_u16();
    let latency_ms = seconds * 1e3;
    let request_id = request_id.to_str().unwrap_or("-");
    if status >= 500 {
        tracing::warn!(target: "access", method, route, path, status, latency_ms, request_id, "request served");
    } else {
        tracing::info!(target: "access", method, route, path, status, latency_ms, request_id, "request served");
    }
}
