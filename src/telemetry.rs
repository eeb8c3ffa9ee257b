//! Logs and request ids: the tracing subscriber, the `x-request-id` that follows each request,
//! and the one structured log line written per request.

use std::time::Duration;

use axum::{
    extract::{MatchedPath, Request},
    http::{HeaderName, HeaderValue},
    middleware::Next,
    response::Response,
};
use tower_http::{
    classify::{ServerErrorsAsFailures, SharedClassifier},
    request_id::RequestId,
    trace::{DefaultOnBodyChunk, DefaultOnEos, DefaultOnRequest, MakeSpan, OnResponse, TraceLayer},
};
use tracing::{Level, Span};
use tracing_subscriber::EnvFilter;

use crate::config::LogFormat;

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
    let builder = tracing_subscriber::fmt().with_env_filter(filter);
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

/// Middleware: makes the request's id (set by `SetRequestIdLayer`) visible to
/// [`current_request_id`] while the request is served.
pub async fn scope_request_id(request: Request, next: Next) -> Response {
    match request.extensions().get::<RequestId>() {
        Some(id) => {
            let id = id.header_value().clone();
            REQUEST_ID.scope(id, next.run(request)).await
        }
        None => next.run(request).await,
    }
}

/// The route template a request matched (`/distance`), or [`UNMATCHED_ROUTE`].
pub fn route_of<B>(request: &axum::http::Request<B>) -> &str {
    request
        .extensions()
        .get::<MatchedPath>()
        .map_or(UNMATCHED_ROUTE, MatchedPath::as_str)
}

/// A span per request carrying its method, route, path and id.
#[derive(Debug, Clone, Copy)]
pub struct RequestSpan;

impl<B> MakeSpan<B> for RequestSpan {
    fn make_span(&mut self, request: &axum::http::Request<B>) -> Span {
        let request_id = request
            .extensions()
            .get::<RequestId>()
            .and_then(|id| id.header_value().to_str().ok())
            .unwrap_or("-");
        tracing::info_span!(
            "request",
            method = %request.method(),
            route = route_of(request),
            path = request.uri().path(),
            request_id,
        )
    }
}

/// Writes the request's one log line when its response is ready: status and latency, inside
/// the request's span (method, route, path, id).
#[derive(Debug, Clone, Copy)]
pub struct LogResponse;

impl<B> OnResponse<B> for LogResponse {
    fn on_response(self, response: &axum::http::Response<B>, latency: Duration, _: &Span) {
        let status = response.status().as_u16();
        let latency_ms = latency.as_secs_f64() * 1e3;
        if response.status().is_server_error() {
            tracing::warn!(status, latency_ms, "request served");
        } else {
            tracing::info!(status, latency_ms, "request served");
        }
    }
}

/// The per-request logging layer: a span per request and one line when its response is ready.
pub fn request_log() -> TraceLayer<
    SharedClassifier<ServerErrorsAsFailures>,
    RequestSpan,
    DefaultOnRequest,
    LogResponse,
    DefaultOnBodyChunk,
    DefaultOnEos,
    (),
> {
    TraceLayer::new_for_http()
        .make_span_with(RequestSpan)
        .on_request(DefaultOnRequest::new().level(Level::DEBUG))
        .on_response(LogResponse)
        .on_failure(())
}
