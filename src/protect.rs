//! Protective layers: the request timeout (408/503), load shedding past the concurrency limit
//! (503 with `Retry-After`), CORS and response compression. Each answers in problem+json.

use std::{
    pin::Pin,
    sync::{
        Arc,
        atomic::{AtomicBool, Ordering},
    },
    task::{Context, Poll},
    time::Duration,
};

use axum::{
    BoxError,
    body::{Body, Bytes},
    extract::{Request, State},
    http::{HeaderValue, Method, header},
    middleware::Next,
    response::{IntoResponse, Response},
};
use http_body::{Frame, SizeHint};
use tower_http::cors::{AllowOrigin, CorsLayer};

use crate::{api::error::ApiError, telemetry::X_REQUEST_ID};

/// Seconds a shed client is asked to wait before retrying.
pub const RETRY_AFTER_SECS: u64 = 1;

/// Middleware: answers 408 when the request body is still arriving after `limit`, 503 when the
/// body was in but the answer was not ready.
pub async fn timeout(State(limit): State<Duration>, request: Request, next: Next) -> Response {
    let received = Arc::new(AtomicBool::new(false));
    let request = request.map(|body| {
        Body::new(Watched {
            received: Arc::clone(&received),
            inner: body,
        })
    });
    match tokio::time::timeout(limit, next.run(request)).await {
        Ok(response) => response,
        Err(_) => ApiError::Timeout {
            after: limit,
            body_received: received.load(Ordering::Acquire),
        }
        .into_response(),
    }
}

/// A request body that records when it has been read to the end.
struct Watched {
    received: Arc<AtomicBool>,
    inner: Body,
}

impl http_body::Body for Watched {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, axum::Error>>> {
        let polled = Pin::new(&mut self.inner).poll_frame(cx);
        if matches!(polled, Poll::Ready(None)) || self.inner.is_end_stream() {
            self.received.store(true, Ordering::Release);
        }
        polled
    }

    fn is_end_stream(&self) -> bool {
        self.inner.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.inner.size_hint()
    }
}

/// The answer when the load-shedding layer refuses a request (or, never expected, when another
/// layer fails).
pub async fn shed(error: BoxError) -> Response {
    if error.is::<tower::load_shed::error::Overloaded>() {
        ApiError::Overloaded {
            retry_after_secs: RETRY_AFTER_SECS,
        }
        .into_response()
    } else {
        ApiError::Internal(error.to_string()).into_response()
    }
}

/// CORS for `origins` (`*` alone allows any), or `None` when the list is empty: then no CORS
/// headers are sent and browsers keep the same-origin policy.
pub fn cors(origins: &[String]) -> Option<CorsLayer> {
    if origins.is_empty() {
        return None;
    }
    let allow_origin = if origins.iter().any(|o| o == "*") {
        AllowOrigin::any()
    } else {
        AllowOrigin::list(
            origins
                .iter()
                .filter_map(|origin| HeaderValue::from_str(origin).ok()),
        )
    };
    Some(
        CorsLayer::new()
            .allow_origin(allow_origin)
            .allow_methods([Method::GET, Method::POST])
            .allow_headers([header::CONTENT_TYPE, header::ACCEPT, X_REQUEST_ID.clone()])
            .expose_headers([X_REQUEST_ID.clone(), header::RETRY_AFTER])
            .max_age(Duration::from_secs(3600)),
    )
}
