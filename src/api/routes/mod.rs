//! One module per resource, each with its request and response types beside its handlers and
//! its own `router()`; [`light`] merges the JSON resources, [`heavy`] the image resources and
//! [`ops::router`] the probes, each group to be wrapped in its own limits by
//! [`crate::startup`].

pub mod chart;
pub mod distance;
pub mod ops;
pub mod planning;
pub mod table;

use axum::http::{Method, Uri};
use utoipa_axum::router::OpenApiRouter;

use super::{AppState, HeavyState, error::ApiError};

/// The JSON answers: microseconds of CPU and small bodies each.
pub fn light() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .merge(distance::router())
        .merge(table::router())
        .merge(chart::router())
        .merge(planning::router())
}

/// The image requests: megabytes in, milliseconds to seconds of CPU each. None is served yet;
/// the group, its limits and its memory budget are in place for them (tests mount a route of
/// their own here, see [`crate::startup::app_with`]).
pub fn heavy() -> OpenApiRouter<HeavyState> {
    OpenApiRouter::new()
}

/// Answers any path the API does not have.
pub async fn not_found(uri: Uri) -> ApiError {
    ApiError::NotFound(uri.path().to_owned())
}

/// Answers a known path asked with the wrong method (axum adds the `Allow` header).
pub async fn method_not_allowed(method: Method) -> ApiError {
    ApiError::MethodNotAllowed(method.to_string())
}
