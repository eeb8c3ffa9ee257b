//! The middleware every request passes through, written as two tower layers instead of a
//! stack of ten. [`Edge`] (outermost) gives the request its id, counts it in flight, catches a
//! panic as a 500, records the metrics, writes the access log line and echoes the id.
//! [`Guard`] (innermost, API routes only) sheds load past the concurrency limit (503 with
//! `Retry-After`), enforces the request timeout (408 or 503) and records the body limit.
//!
//! Why by hand: in axum, every `Router::layer` call boxes and clones each route's service on
//! every request, and each `from_fn` middleware adds a boxed future of its own. With ten such
//! layers the stack cost more than the handler; see the README's Performance section.

use std::{
    any::Any,
    convert::Infallible,
    future::Future,
    panic::AssertUnwindSafe,
    pin::Pin,
    sync::{
        Arc,
        atomic::{AtomicBool, AtomicUsize, Ordering},
    },
    task::{Context, Poll},
    time::{Duration, Instant},
};

use axum::{
    body::Body,
    extract::{MatchedPath, Request},
    response::{IntoResponse, Response},
};
use futures_util::FutureExt;
use http_body::Body as _;
use tower::{Layer, Service};

use crate::{
    api::{error::ApiError, extract::BodyLimit, ops::PROBE_ROUTES},
    config::AccessLog,
    metrics::{InFlight, Metrics, method_label},
    protect::{RETRY_AFTER_SECS, Watched},
    telemetry::{self, UNMATCHED_ROUTE, X_REQUEST_ID},
};

/// A boxed response future: one allocation per request and layer.
pub type ResponseFuture = Pin<Box<dyn Future<Output = Result<Response, Infallible>> + Send>>;

/// Takes a clone of `service` for a request, leaving a fresh clone in its place (the usual
/// tower idiom: the clone that was polled ready is the one called).
fn take<S: Clone>(service: &mut S) -> S {
    let clone = service.clone();
    std::mem::replace(service, clone)
}

/// The route template a request matched (`/distance`), or [`UNMATCHED_ROUTE`].
fn route_of(request: &Request) -> Option<MatchedPath> {
    request.extensions().get::<MatchedPath>().cloned()
}

// ---------------------------------------------------------------------------------------------
// Edge

/// Builds [`Edge`] services. What they share sits behind one `Arc`, because axum clones each
/// route's service for every request.
#[derive(Clone)]
pub struct EdgeLayer(Arc<EdgeShared>);

struct EdgeShared {
    metrics: Metrics,
    access_log: AccessLog,
}

impl EdgeLayer {
    pub fn new(metrics: Metrics, access_log: AccessLog) -> Self {
        Self(Arc::new(EdgeShared {
            metrics,
            access_log,
        }))
    }
}

impl<S> Layer<S> for EdgeLayer {
    type Service = Edge<S>;

    fn layer(&self, inner: S) -> Edge<S> {
        Edge {
            inner,
            layer: self.clone(),
        }
    }
}

/// Request id, in-flight gauge, panic → 500, metrics, access log. See the module docs.
#[derive(Clone)]
pub struct Edge<S> {
    inner: S,
    layer: EdgeLayer,
}

impl<S> Service<Request> for Edge<S>
where
    S: Service<Request, Error = Infallible> + Clone + Send + 'static,
    S::Response: IntoResponse,
    S::Future: Send + 'static,
{
    type Response = Response;
    type Error = Infallible;
    type Future = ResponseFuture;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), Infallible>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, request: Request) -> ResponseFuture {
        let inner = take(&mut self.inner);
        let shared = Arc::clone(&self.layer.0);
        Box::pin(edge(shared, inner, request))
    }
}

async fn edge<S>(
    layer: Arc<EdgeShared>,
    mut inner: S,
    request: Request,
) -> Result<Response, Infallible>
where
    S: Service<Request, Error = Infallible>,
    S::Response: IntoResponse,
{
    let started = Instant::now();
    let _in_flight = InFlight::enter(layer.metrics.in_flight());
    let method = method_label(request.method());
    let route = route_of(&request);
    let id = telemetry::request_id(request.headers());
    // A clone of the URI shares hyper's buffer: no copy unless a line is written.
    let uri = (layer.access_log != AccessLog::Off).then(|| request.uri().clone());

    let answer = AssertUnwindSafe(inner.call(request)).catch_unwind();
    let mut response = match telemetry::with_request_id(id.clone(), answer).await {
        Ok(Ok(response)) => response.into_response(),
        Ok(Err(never)) => match never {},
        Err(panic) => {
            let what = panic_message(panic.as_ref());
            tracing::error!(request_id = ?id, panic = %what, "handler panicked");
            telemetry::in_request(id.clone(), || ApiError::Internal(what).into_response())
        }
    };

    let seconds = started.elapsed().as_secs_f64();
    let route = route.as_ref().map_or(UNMATCHED_ROUTE, MatchedPath::as_str);
    let status = response.status();
    layer
        .metrics
        .observe(method, route, status.as_str(), seconds);
    if let Some(uri) = uri {
        telemetry::access_log(
            layer.access_log,
            method,
            route,
            uri.path(),
            status,
            seconds,
            &id,
        );
    }
    response.headers_mut().insert(X_REQUEST_ID.clone(), id);
    Ok(response)
}

fn panic_message(panic: &(dyn Any + Send)) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic".to_owned())
}

// ---------------------------------------------------------------------------------------------
// Guard

/// Builds [`Guard`] services, all sharing one count of API requests in flight.
#[derive(Clone)]
pub struct GuardLayer {
    shared: Arc<GuardShared>,
}

struct GuardShared {
    in_flight: AtomicUsize,
    limit: usize,
    timeout: Duration,
    body_limit: usize,
}

impl GuardLayer {
    /// At most `limit` API requests at once, each answered within `timeout`, with bodies of at
    /// most `body_limit` bytes unless a route sets its own.
    pub fn new(limit: usize, timeout: Duration, body_limit: usize) -> Self {
        Self {
            shared: Arc::new(GuardShared {
                in_flight: AtomicUsize::new(0),
                limit,
                timeout,
                body_limit,
            }),
        }
    }
}

impl<S> Layer<S> for GuardLayer {
    type Service = Guard<S>;

    fn layer(&self, inner: S) -> Guard<S> {
        Guard {
            inner,
            shared: Arc::clone(&self.shared),
        }
    }
}

/// Concurrency limit with shedding, request timeout, body limit; probes pass untouched.
#[derive(Clone)]
pub struct Guard<S> {
    inner: S,
    shared: Arc<GuardShared>,
}

/// A slot under the concurrency limit, given back when dropped.
struct Slot(Arc<GuardShared>);

impl Slot {
    fn take(shared: &Arc<GuardShared>) -> Option<Self> {
        let before = shared.in_flight.fetch_add(1, Ordering::AcqRel);
        let slot = Slot(Arc::clone(shared));
        (before < shared.limit).then_some(slot)
    }
}

impl Drop for Slot {
    fn drop(&mut self) {
        self.0.in_flight.fetch_sub(1, Ordering::AcqRel);
    }
}

impl<S> Service<Request> for Guard<S>
where
    S: Service<Request, Error = Infallible> + Clone + Send + 'static,
    S::Response: IntoResponse,
    S::Future: Send + 'static,
{
    type Response = Response;
    type Error = Infallible;
    type Future = ResponseFuture;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), Infallible>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, mut request: Request) -> ResponseFuture {
        let mut inner = take(&mut self.inner);
        let route = request.extensions().get::<MatchedPath>();
        if route.is_some_and(|r| PROBE_ROUTES.contains(&r.as_str())) {
            return Box::pin(
                async move { inner.call(request).await.map(IntoResponse::into_response) },
            );
        }
        let shared = Arc::clone(&self.shared);
        Box::pin(async move {
            let Some(_slot) = Slot::take(&shared) else {
                return Ok(ApiError::Overloaded {
                    retry_after_secs: RETRY_AFTER_SECS,
                }
                .into_response());
            };
            request
                .extensions_mut()
                .insert(BodyLimit(shared.body_limit));
            // Whether the body was all in when time ran out tells a slow client (408) from a
            // slow server (503). A request without a body has nothing to wait for.
            let received = if request.body().is_end_stream() {
                None
            } else {
                let received = Arc::new(AtomicBool::new(false));
                let watched = Arc::clone(&received);
                request = request.map(|body| Body::new(Watched::new(watched, body)));
                Some(received)
            };
            match tokio::time::timeout(shared.timeout, inner.call(request)).await {
                Ok(Ok(response)) => Ok(response.into_response()),
                Ok(Err(never)) => match never {},
                Err(_) => Ok(ApiError::Timeout {
                    after: shared.timeout,
                    body_received: received.is_none_or(|r| r.load(Ordering::Acquire)),
                }
                .into_response()),
            }
        })
    }
}
