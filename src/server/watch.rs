//! The request body watcher behind the guard's body rules: a body that counts what has arrived
//! and records when it has all arrived, so that [`super::edge`] can cut off a body slower than
//! the minimum rate (408) and tell a slow client (408) from a slow server (503) at the timeout.

use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

use axum::body::Body;
use http_body::{Frame, SizeHint};

/// The slowest a request body may arrive: on average at least `bytes_per_second` from the
/// request's start, once `grace` has passed (as Kestrel's `MinRequestBodyDataRate`). A rate of
/// 0 switches the rule off.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MinRate {
    pub bytes_per_second: u64,
    pub grace: Duration,
}

impl MinRate {
    /// When a body that has brought `bytes` since its request started falls below the rate:
    /// `grace` after the start, or later once more has arrived.
    fn due(&self, started: Instant, bytes: u64) -> Option<Instant> {
        if self.bytes_per_second == 0 {
            return None;
        }
        let earned = Duration::from_secs_f64(bytes as f64 / self.bytes_per_second as f64);
        Some(started + self.grace.max(earned))
    }
}

/// How far a request body has come: bytes received, and whether it has all arrived (or the
/// server stopped reading it: from then on, nothing is the client's to be slow at).
#[derive(Debug, Default)]
pub struct Progress {
    bytes: AtomicU64,
    received: AtomicBool,
}

impl Progress {
    /// Whether the body has all arrived.
    pub fn received(&self) -> bool {
        self.received.load(Ordering::Acquire)
    }

    /// Bytes received so far.
    pub fn bytes(&self) -> u64 {
        self.bytes.load(Ordering::Acquire)
    }

    /// Completes when the body, still arriving, has come slower than `rate` since `started`;
    /// never once it has all arrived (nor when the rule is off).
    pub async fn too_slow(&self, started: Instant, rate: MinRate) {
        loop {
            let due = match rate.due(started, self.bytes()) {
                Some(due) if !self.received() => due,
                _ => return std::future::pending().await,
            };
            if Instant::now() >= due {
                return;
            }
            tokio::time::sleep_until(due.into()).await;
        }
    }
}

/// A request body that reports its [`Progress`].
pub struct Watched {
    progress: Arc<Progress>,
    inner: Body,
}

impl Watched {
    /// Wraps `inner`, counting into `progress`.
    pub fn new(progress: Arc<Progress>, inner: Body) -> Self {
        Self { progress, inner }
    }
}

impl Drop for Watched {
    /// A body dropped is no longer waited for (read to its end, or left unread by a handler
    /// that answered without it; a multipart reader may stop at the closing boundary without
    /// asking for the end of a chunked body).
    fn drop(&mut self) {
        self.progress.received.store(true, Ordering::Release);
    }
}

/// The wrapped body's frames, passed on as they come: its data and its errors.
impl http_body::Body for Watched {
    type Data = <Body as http_body::Body>::Data;
    type Error = <Body as http_body::Body>::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Self::Data>, Self::Error>>> {
        let polled = Pin::new(&mut self.inner).poll_frame(cx);
        if let Poll::Ready(Some(Ok(frame))) = &polled
            && let Some(data) = frame.data_ref()
        {
            self.progress
                .bytes
                .fetch_add(data.len() as u64, Ordering::AcqRel);
        }
        if matches!(polled, Poll::Ready(None)) || self.inner.is_end_stream() {
            self.progress.received.store(true, Ordering::Release);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The bytes of each frame are counted; the body counts as received at its end, or once
    /// dropped unread.
    #[tokio::test]
    async fn progress_counts_bytes_and_the_end() {
        use http_body_util::BodyExt;
        let progress = Arc::new(Progress::default());
        let mut body = Watched::new(Arc::clone(&progress), Body::from("twelve bytes"));
        assert!(!progress.received());
        let frame = body.frame().await.unwrap().unwrap();
        assert_eq!(frame.into_data().unwrap(), "twelve bytes");
        assert_eq!(progress.bytes(), 12);
        assert!(progress.received());

        let unread = Arc::new(Progress::default());
        let never = futures_util::stream::pending::<Result<axum::body::Bytes, std::io::Error>>();
        let body = Watched::new(Arc::clone(&unread), Body::from_stream(never));
        assert!(!unread.received());
        drop(body);
        assert!(unread.received(), "a dropped body is no longer waited for");
    }

    /// The rule falls due at the grace period while too little has arrived, later as bytes
    /// arrive (one second per `bytes_per_second`), and never when switched off.
    #[test]
    fn the_rate_falls_due_after_the_grace_and_the_bytes_earned() {
        let start = Instant::now();
        let rate = MinRate {
            bytes_per_second: 1000,
            grace: Duration::from_secs(5),
        };
        assert_eq!(rate.due(start, 0), Some(start + Duration::from_secs(5)));
        assert_eq!(rate.due(start, 4_999), Some(start + Duration::from_secs(5)));
        assert_eq!(
            rate.due(start, 12_000),
            Some(start + Duration::from_secs(12))
        );
        let off = MinRate {
            bytes_per_second: 0,
            ..rate
        };
        assert_eq!(off.due(start, 0), None);
    }
}
