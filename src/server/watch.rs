//! The request body watcher behind the request timeout's 408/503 choice: a body that records
//! when it has been read to the end, so that [`super::edge`] can tell a slow client from a
//! slow server.

use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::task::{Context, Poll};

use axum::body::{Body, Bytes};
use http_body::{Frame, SizeHint};

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
