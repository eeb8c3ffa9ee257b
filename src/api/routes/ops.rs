//! Operational endpoints for orchestrators and monitoring: liveness, readiness and metrics.
//! They form their own router, outside every route group's concurrency limit and timeout, so
//! that probes still answer under load.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use axum::extract::State;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

use utoipa_axum::{router::OpenApiRouter, routes};

use crate::api::error::ApiError;
use crate::api::respond::Json;
use crate::api::wire::openapi::{DRAINING, METHOD, ProbeErrors, problem_responses};
use crate::budget::{MemoryBudget, Slots};
use crate::observe::metrics::{Metrics, TEXT_FORMAT};

/// Whether the server wants traffic: false before it serves and while it drains.
#[derive(Debug, Clone, Default)]
pub struct Readiness(Arc<AtomicBool>);

impl Readiness {
    pub fn set(&self, ready: bool) {
        self.0.store(ready, Ordering::Release);
    }

    pub fn get(&self) -> bool {
        self.0.load(Ordering::Acquire)
    }
}

/// What the operational endpoints see.
#[derive(Debug, Clone, Default)]
pub struct OpsState {
    pub readiness: Readiness,
    pub metrics: Metrics,
    /// The image requests' memory budget and compute slots, read into the metrics when asked.
    pub heavy: Option<(MemoryBudget, Slots)>,
}

/// `/healthz`, `/readyz` and `/metrics`: a router of their own, never shed nor timed out,
/// because a probe must answer most of all when the API is overloaded.
pub fn router() -> OpenApiRouter<OpsState> {
    OpenApiRouter::new()
        .routes(routes!(healthz))
        .routes(routes!(readyz))
        .routes(routes!(metrics))
}

/// The body of a successful probe.
#[derive(Debug, Serialize, ToSchema)]
pub struct Health {
    /// `ok` for liveness, `ready` for readiness.
    #[schema(example = "ok")]
    pub status: &'static str,
}

struct NotReady;

impl utoipa::IntoResponses for NotReady {
    fn responses()
    -> std::collections::BTreeMap<String, utoipa::openapi::RefOr<utoipa::openapi::Response>> {
        problem_responses(&[METHOD, DRAINING])
    }
}

#[utoipa::path(
    get,
    path = "/healthz",
    tag = "operations",
    summary = "Liveness: the process is up and serving HTTP",
    description = "For a liveness probe: 200 while the process serves HTTP. Never shed, \
                   timed out or limited, so it answers under any load.",
    responses(
        (status = 200, description = "The process is alive.", body = Health),
        ProbeErrors
    )
)]
pub async fn healthz() -> Json<Health> {
    Json(Health { status: "ok" })
}

#[utoipa::path(
    get,
    path = "/readyz",
    tag = "operations",
    summary = "Readiness: the server wants traffic (503 while it drains for shutdown)",
    description = "For a readiness probe: 200 while the server wants traffic, 503 from \
                   the moment it begins to drain for shutdown, so that load balancers move \
                   traffic away before it stops.",
    responses(
        (status = 200, description = "Ready for traffic.", body = Health),
        NotReady
    )
)]
pub async fn readyz(State(state): State<OpsState>) -> Result<Json<Health>, ApiError> {
    if state.readiness.get() {
        Ok(Json(Health { status: "ready" }))
    } else {
        Err(ApiError::Draining)
    }
}

#[utoipa::path(
    get,
    path = "/metrics",
    tag = "operations",
    summary = "Prometheus metrics: requests, latency histograms and in-flight requests",
    description = "For a Prometheus scrape: `http_requests_total` and the \
                   `http_request_duration_seconds` histogram by method, route and status, \
                   `http_requests_in_flight`, and the image requests' gauges: \
                   `heavy_memory_reserved_bytes` of `heavy_memory_budget_bytes` (bodies, work \
                   and answers not yet sent) and `heavy_requests_working`.",
    responses((
        status = 200,
        description = "Metrics in the Prometheus text format, by method, route and status.",
        content_type = "text/plain; version=0.0.4; charset=utf-8",
        body = String
    ), ProbeErrors)
)]
pub async fn metrics(State(state): State<OpsState>) -> Response {
    if let Some((budget, slots)) = &state.heavy {
        state
            .metrics
            .set_heavy(budget.used(), budget.total(), slots.busy());
    }
    match state.metrics.render() {
        Ok(text) => ([(header::CONTENT_TYPE, TEXT_FORMAT)], text).into_response(),
        Err(error) => ApiError::Internal(error).into_response(),
    }
}
