//! The library layers that were measured and not adopted, built only with their cargo features
//! to reproduce the measurement (README, Performance): tower-http's
//! `SetRequestId`/`PropagateRequestId` (UUID v4) around the edge (`library-request-id`), and on
//! each route group tower's `GlobalConcurrencyLimit` + `LoadShed` (shed with our 503 problem)
//! and tower-http's `TimeoutLayer::with_status_code` (a bare 503, without the 408 for a stalled
//! upload or a problem body) (`library-limits`); both as `library-layers`. tower-http's
//! `CatchPanic`, measured the same way, cost no more than the noise and is in the default build.
//!
//! Features: `library-request-id`, `library-limits`, or both as `library-layers`. Build with `cargo build --release --features …`, then measure the binary
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
