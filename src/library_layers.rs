//! The middleware made of library layers instead of the hand-written ones, built only with the
//! cargo feature `library-layers`, to measure what they cost (README, Performance):
//! tower-http's `SetRequestId`/`PropagateRequestId` (UUID v4) and `CatchPanic` around the edge,
//! and on each route group tower's `GlobalConcurrencyLimit` + `LoadShed` (shed with our 503
//! problem) and tower-http's `TimeoutLayer::with_status_code` (a bare 503, without the 408 for
//! a stalled upload or a problem body). The edge keeps the metrics, the access log and the
//! request id of problem bodies, which no library layer provides.
//!
//! Features: `library-request-id`, `library-catch-panic`, `library-limits`, or all three as
//! `library-layers`. Build with `cargo build --release --features …`, then measure the binary
//! beside the default one with `cargo bench --bench load -- --compare NAME=PATH`.

use crate::api::error::ApiError;

/// One route group behind the library's concurrency limit, load shedding and timeout.
#[cfg(feature = "library-limits")]
pub fn group(router: axum::Router, limit: usize, timeout: std::time::Duration) -> axum::Router {
    use axum::{error_handling::HandleErrorLayer, http::StatusCode};
    use tower::{
        BoxError, ServiceBuilder, limit::GlobalConcurrencyLimitLayer, load_shed::LoadShedLayer,
    };
    use tower_http::timeout::TimeoutLayer;

    router.layer(
        ServiceBuilder::new()
            .layer(HandleErrorLayer::new(|_: BoxError| async {
                ApiError::Overloaded {
                    retry_after_secs: crate::protect::RETRY_AFTER_SECS,
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
#[cfg(feature = "library-catch-panic")]
pub fn panic_answer(panic: Box<dyn std::any::Any + Send + 'static>) -> axum::response::Response {
    use axum::response::IntoResponse;

    let what = panic
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic".to_owned());
    tracing::error!(panic = %what, "handler panicked");
    ApiError::Internal(what).into_response()
}
