//! The middleware made of library layers instead of the hand-written ones, built only with the
//! cargo feature `library-layers`, to measure what they cost (README, Performance):
//! tower-http's `SetRequestId`/`PropagateRequestId` (UUID v4) and `CatchPanic` around the edge,
//! and on each route group tower's `GlobalConcurrencyLimit` + `LoadShed` (shed with our 503
//! problem) and tower-http's `TimeoutLayer::with_status_code` (a bare 503, without the 408 for
//! a stalled upload or a problem body). The edge keeps the metrics, the access log and the
//! request id of problem bodies, which no library layer provides.
//!
//! `cargo build --release --features library-layers`, then
//! `cargo bench --bench load -- --service-bin …` with that binary beside the default one.

use std::{any::Any, time::Duration};

use axum::{
    Router,
    error_handling::HandleErrorLayer,
    http::StatusCode,
    response::{IntoResponse, Response},
};
use tower::{
    BoxError, ServiceBuilder, limit::GlobalConcurrencyLimitLayer, load_shed::LoadShedLayer,
};
use tower_http::timeout::TimeoutLayer;

use crate::{api::error::ApiError, protect::RETRY_AFTER_SECS};

/// One route group behind the library's concurrency limit, load shedding and timeout.
pub fn group(router: Router, limit: usize, timeout: Duration) -> Router {
    router.layer(
        ServiceBuilder::new()
            .layer(HandleErrorLayer::new(|_: BoxError| async {
                ApiError::Overloaded {
                    retry_after_secs: RETRY_AFTER_SECS,
                }
            }))
            .layer(LoadShedLayer::new())
            .layer(GlobalConcurrencyLimitLayer::new(limit))
            .layer(TimeoutLayer::with_status_code(
                StatusCode::SERVICE_UNAVAILABLE,
                timeout,
            )),
    )
}

/// What tower-http's `CatchPanic` answers for a panic: the same 500 problem as the edge's guard.
pub fn panic_answer(panic: Box<dyn Any + Send + 'static>) -> Response {
    let what = panic
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic".to_owned());
    tracing::error!(panic = %what, "handler panicked");
    ApiError::Internal(what).into_response()
}
