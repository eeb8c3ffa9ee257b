//! One module per resource, each with its request and response types beside its handlers and
//! its own `router()`; [`light`] merges the JSON resources, [`heavy`] the image resources and
//! [`ops::router`] the probes, each group to be wrapped in its own limits by
//! [`crate::server::startup`].

pub mod board_calibration;
pub mod calibration_check;
pub mod chart;
pub mod depth_map;
pub mod depth_stream;
pub mod distance;
pub mod file_calibration;
pub mod matching;
pub mod ops;
pub mod rectify;
pub mod rig_design;
pub mod table;

use axum::http::{Method, Uri};

use utoipa_axum::router::OpenApiRouter;

use super::error::ApiError;
use super::images::HeavyState;
use super::state::AppState;

/// The JSON answers: microseconds of CPU and small bodies each.
pub fn light() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .merge(distance::router())
        .merge(table::router())
        .merge(chart::router())
        .merge(rig_design::router())
        .merge(file_calibration::router())
}

/// The image requests: megabytes in, milliseconds to seconds of CPU each.
pub fn heavy() -> OpenApiRouter<HeavyState> {
    OpenApiRouter::new()
        .merge(board_calibration::router())
        .merge(calibration_check::router())
        .merge(depth_map::router())
        .merge(depth_stream::router())
        .merge(matching::router())
        .merge(rectify::router())
}

/// Answers any path the API does not have.
pub async fn not_found(uri: Uri) -> ApiError {
    ApiError::NotFound(uri.path().to_owned())
}

/// Answers a known path asked with the wrong method (axum adds the `Allow` header).
pub async fn method_not_allowed(method: Method) -> ApiError {
    ApiError::MethodNotAllowed(method.to_string())
}
