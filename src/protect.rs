//! Protective pieces used by [`crate::edge`]: the body watcher behind the request timeout's
//! 408/503 choice, the `Retry-After` of a shed request, and CORS.

use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::task::{Context, Poll};
use std::time::Duration;

use axum::body::{Body, Bytes};
use axum::http::{HeaderValue, Method, header};
use http_body::{Frame, SizeHint};
use tower_http::cors::{AllowOrigin, CorsLayer};

use crate::telemetry::X_REQUEST_ID;

/// Seconds a shed client is asked to wait before retrying.
pub const RETRY_AFTER_SECS: u64 = 1;

/// A request body that records when it has been read to the end, so that a timeout can tell
/// a slow client (408) from a slow server (503).
pub struct Watched {
    received: Arc<AtomicBool>,
    inner: Body,
}

impl Watched {
    /// Wraps `inner`, setting `received` once it has been read to the end.
    pub fn new(received: Arc<AtomicBool>, inner: Body) -> Self {
        Self { received, inner }
    }
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
