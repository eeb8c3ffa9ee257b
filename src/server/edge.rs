//! The middleware, written as two tower layers instead of a stack of ten. [`Edge`] (outermost,
//! every request) gives the request its id, counts it in flight, records the metrics, writes
//! the access log line and echoes the id; tower-http's `CatchPanic` right inside it turns a
//! panic into a 500 problem ([`panic_answer`]). [`Guard`] wraps one route
//! group with that group's limits: for the light group it sheds load past the group's
//! concurrency limit (503 with `Retry-After`); for the heavy group it admits a request only when
//! its body fits in the memory budget (503 with `Retry-After`) and keeps that memory counted
//! until the answer is sent (the heavy handlers take their compute slot when their work
//! starts); for both it cuts off a body slower than the minimum rate (408) and enforces the
//! request timeout (408 or 503). The probes are a router of their own that no guard wraps.
//!
//! Why by hand: in axum, every `Router::layer` call boxes and clones each route's service on
//! every request, and each `from_fn` middleware adds a boxed future of its own. With ten such
//! layers the stack cost more than the handler; see docs/performance.md.

use std::{
    any::Any,
    convert::Infallible,
    future::Future,
    pin::Pin,
    sync::Arc,
    task::{Context, Poll},
    time::{Duration, Instant},
};

use axum::{
    body::Body,
    extract::{MatchedPath, Request},
    response::{IntoResponse, Response},
};
use http_body::Body as _;
use tower::{Layer, Service};

use super::answer;
use super::watch::{MinRate, Progress, Watched};
use crate::{
    api::error::{ApiError, RETRY_AFTER_SECS},
    budget::{MemoryBudget, Refusal, Reservation, Slots},
    config::AccessLog,
    observe::metrics::{InFlight, Metrics, method_label},
    observe::telemetry::{self, UNMATCHED_ROUTE, X_REQUEST_ID},
};

/// A boxed response future: one allocation per request and layer.
pub type ResponseFuture = Pin<Box<dyn Future<Output = Result<Response, Infallible>> + Send>>;

/// Takes a clone of `service` for a request, leaving a fresh clone in its place (the usual
/// tower idiom: the clone that was polled ready is the one called).
fn take<S: Clone>(service: &mut S) -> S {
    let clone = service.clone();
    std::mem::replace(service, clone)
}

/// A service a hand-written layer can wrap: an axum route (or a layer around one).
pub trait Inner:
    Service<Request, Error = Infallible, Response: IntoResponse, Future: Send + 'static>
    + Send
    + 'static
{
}

impl<S> Inner for S where
    S: Service<Request, Error = Infallible, Response: IntoResponse, Future: Send + 'static>
        + Send
        + 'static
{
}

/// What a hand-written layer does with one request, given the inner service to call.
pub trait Wrap: Clone {
    fn wrap<S: Inner>(&self, inner: S, request: Request) -> ResponseFuture;
}

/// A service wrapped by the hand-written layer `W` ([`Edge`] or [`Guard`]).
#[derive(Clone)]
pub struct Wrapped<S, W> {
    inner: S,
    wrap: W,
}

impl<S, W: Clone> Wrapped<S, W> {
    fn new(inner: S, wrap: &W) -> Self {
        Self {
            inner,
            wrap: wrap.clone(),
        }
    }
}

impl<S: Inner + Clone, W: Wrap> Service<Request> for Wrapped<S, W> {
    type Response = Response;
    type Error = Infallible;
    type Future = ResponseFuture;

    fn poll_ready(&mut self, cx: &mut Context<'_>) -> Poll<Result<(), Infallible>> {
        self.inner.poll_ready(cx)
    }

    fn call(&mut self, request: Request) -> ResponseFuture {
        self.wrap.wrap(take(&mut self.inner), request)
    }
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
        Wrapped::new(inner, self)
    }
}

/// Request id, in-flight gauge, panic → 500, metrics, access log. See the module docs.
pub type Edge<S> = Wrapped<S, EdgeLayer>;

impl Wrap for EdgeLayer {
    fn wrap<S: Inner>(&self, inner: S, request: Request) -> ResponseFuture {
        Box::pin(edge(Arc::clone(&self.0), inner, request))
    }
}

async fn edge<S: Inner>(
    layer: Arc<EdgeShared>,
    mut inner: S,
    request: Request,
) -> Result<Response, Infallible> {
    let started = Instant::now();
    let _in_flight = InFlight::enter(layer.metrics.in_flight());
    let method = method_label(request.method());
    let route = route_of(&request);
    let id = telemetry::request_id(request.headers());
    // A clone of the URI shares hyper's buffer: no copy unless a line is written.
    let uri = (layer.access_log != AccessLog::Off).then(|| request.uri().clone());

    // A panic inside is caught by tower-http's CatchPanic, the next layer in, and answered by
    // [`panic_answer`] inside this scope, so it is counted and logged like any answer.
    let mut response = match telemetry::with_request_id(id.clone(), inner.call(request)).await {
        Ok(response) => response.into_response(),
        Err(never) => match never {},
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

/// What tower-http's `CatchPanic` answers for a panic in a handler: a 500 problem naming the
/// panic, with the request's id (it runs inside the edge's request scope), after logging it.
pub fn panic_answer(panic: Box<dyn Any + Send + 'static>) -> Response {
    let what = panic
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic".to_owned());
    tracing::error!(request_id = ?telemetry::current_request_id(), panic = %what, "handler panicked");
    ApiError::Internal(what).into_response()
}

// ---------------------------------------------------------------------------------------------
// Guard

/// Builds [`Guard`] services for one route group, all sharing its limits.
#[derive(Clone)]
pub struct GuardLayer {
    shared: Arc<GuardShared>,
}

struct GuardShared {
    /// The light group's requests in flight, a slot each from arrival; `None` for the heavy
    /// group, whose handlers take a slot when their work starts (`api::images::work`).
    slots: Option<Slots>,
    timeout: Duration,
    body_rate: MinRate,
    memory: Option<Admission>,
}

/// How the heavy group admits a request against its memory budget: by the body it declares, or
/// the body limit when it declares none (a chunked upload may be that large).
struct Admission {
    budget: MemoryBudget,
    body_limit: usize,
}

impl Admission {
    /// Reserves the body `request` declares (at most the body limit), and gives the handler a
    /// clone of the reservation as a request extension.
    fn admit(&self, request: &mut Request) -> Result<Reservation, Refusal> {
        let declared = request.body().size_hint().exact();
        let body = declared.map_or(self.body_limit, |n| {
            usize::try_from(n).map_or(self.body_limit, |n| n.min(self.body_limit))
        });
        let reservation = self.budget.reserve(body)?;
        request.extensions_mut().insert(reservation.clone());
        Ok(reservation)
    }
}

impl GuardLayer {
    /// At most `limit` requests of the group at once (a slot each from arrival), each answered
    /// within `timeout`, its body arriving at `body_rate` at least.
    pub fn new(limit: usize, timeout: Duration, body_rate: MinRate) -> Self {
        Self::with(Some(Slots::new(limit)), timeout, body_rate, None)
    }

    /// The heavy group's guard: each request admitted only when its body (at most
    /// `body_limit` bytes) fits in `budget`, answered within `timeout`, its body arriving at
    /// `body_rate` at least. The [`crate::budget::Reservation`] made for it is a request
    /// extension, for the handler to grow by what it will allocate; the answer holds it until
    /// sent ([`super::answer`]). No slot is taken here: a request whose body is still arriving
    /// holds none, and its handler takes one when its work starts.
    pub fn with_memory(
        timeout: Duration,
        body_rate: MinRate,
        budget: MemoryBudget,
        body_limit: usize,
    ) -> Self {
        Self::with(
            None,
            timeout,
            body_rate,
            Some(Admission { budget, body_limit }),
        )
    }

    fn with(
        slots: Option<Slots>,
        timeout: Duration,
        body_rate: MinRate,
        memory: Option<Admission>,
    ) -> Self {
        Self {
            shared: Arc::new(GuardShared {
                slots,
                timeout,
                body_rate,
                memory,
            }),
        }
    }
}

impl<S> Layer<S> for GuardLayer {
    type Service = Guard<S>;

    fn layer(&self, inner: S) -> Guard<S> {
        Wrapped::new(inner, self)
    }
}

/// One route group's concurrency limit with shedding, memory admission, minimum body rate and
/// request timeout.
pub type Guard<S> = Wrapped<S, GuardLayer>;

impl Wrap for GuardLayer {
    fn wrap<S: Inner>(&self, inner: S, request: Request) -> ResponseFuture {
        Box::pin(guard(Arc::clone(&self.shared), inner, request))
    }
}

async fn guard<S: Inner>(
    shared: Arc<GuardShared>,
    mut inner: S,
    mut request: Request,
) -> Result<Response, Infallible> {
    let started = Instant::now();
    let _slot = match shared.slots.as_ref().map(Slots::take) {
        Some(None) => {
            return Ok(ApiError::Overloaded {
                retry_after_secs: RETRY_AFTER_SECS,
            }
            .into_response());
        }
        slot => slot.flatten(),
    };
    // Held until the answer has been sent (the heavy group), whatever the handler does with
    // its own clone.
    let reservation = match shared.memory.as_ref().map(|m| m.admit(&mut request)) {
        Some(Err(refusal)) => return Ok(ApiError::Memory(refusal).into_response()),
        held => held.and_then(Result::ok),
    };
    // How far the body has come tells a body slower than the minimum rate, and, when time
    // runs out, a slow client (408) from a slow server (503). A request without a body has
    // nothing to wait for.
    let progress = if request.body().is_end_stream() {
        None
    } else {
        let progress = Arc::new(Progress::default());
        let watched = Arc::clone(&progress);
        request = request.map(|body| Body::new(Watched::new(watched, body)));
        Some(progress)
    };
    let answer = async {
        // Pinned here and awaited by reference, so that the call (and the body in it) still
        // lives when the timeout is judged: a body dropped counts as no longer waited for.
        let mut call = std::pin::pin!(tokio::time::timeout(shared.timeout, inner.call(request)));
        match call.as_mut().await {
            Ok(Ok(response)) => response.into_response(),
            Ok(Err(never)) => match never {},
            Err(_) => ApiError::Timeout {
                after: shared.timeout,
                body_received: progress.as_ref().is_none_or(|p| p.received()),
            }
            .into_response(),
        }
    };
    let too_slow = async {
        match &progress {
            Some(progress) => progress.too_slow(started, shared.body_rate).await,
            None => std::future::pending().await,
        }
    };
    // The answer first: a request whose body has all arrived is usually answered at its first
    // poll, before the rate's timer is ever set.
    let response = tokio::select! {
        biased;
        response = answer => response,
        () = too_slow => ApiError::SlowBody {
            received: progress.as_ref().map_or(0, |p| p.bytes()),
            after: started.elapsed(),
            min_rate: shared.body_rate.bytes_per_second,
        }
        .into_response(),
    };
    Ok(match reservation {
        Some(reservation) => answer::held(response, reservation),
        None => response,
    })
}
