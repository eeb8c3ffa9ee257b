//! The HTTP API: routes, the OpenAPI document derived from them, and shared state.

pub mod batch;
pub mod csv;
pub mod error;
pub mod extract;
pub mod format;
pub mod handlers;
pub mod ops;
pub mod planning;
pub mod respond;
pub mod svg;
pub mod types;
pub mod validate;

use axum::{Extension, Router, extract::DefaultBodyLimit};
use utoipa::OpenApi;
use utoipa_axum::{router::OpenApiRouter, routes};
use utoipa_swagger_ui::SwaggerUi;

use self::{extract::BodyLimit, ops::OpsState};
use crate::config::Limits;

/// What every handler can see.
#[derive(Debug, Clone, Copy, Default)]
pub struct AppState {
    pub limits: Limits,
}

#[derive(OpenApi)]
#[openapi(
    info(
        title = "Stereo distance service",
        description = "Turns a stereo correspondence into a distance with its expected error, \
                       and shows how distance and error vary with disparity for a rig.\n\n\
                       Depth is Z = B·f_px / |d + doffs| with d = x_left − x_right in pixels; \
                       the focal length is always converted to pixels first. Every error is \
                       `application/problem+json` (RFC 9457) with an `errors` array naming \
                       every offending field.",
        license(name = "MIT")
    ),
    components(schemas(error::Problem, error::FieldError)),
    tags(
        (name = "distance", description = "Distance to one feature"),
        (name = "table", description = "Sample tables for a rig"),
        (name = "chart", description = "Chart data and the chart as SVG for a rig"),
        (name = "planning", description = "Rig planning: depth range, error budget, baseline"),
        (name = "operations", description = "Liveness, readiness and metrics")
    )
)]
struct ApiDoc;

/// The service's routers, split by how they are protected.
pub struct Routers {
    /// `/distance`, `/table`, `/chart-data`, `/openapi.json` and `/docs`: behind the
    /// concurrency limit and the request timeout.
    pub api: Router,
    /// `/healthz`, `/readyz` and `/metrics`: never shed, so probes answer under load.
    pub ops: Router,
}

/// Both routers and the OpenAPI document, built from the same handler annotations.
fn routes(state: AppState, ops: OpsState) -> (Routers, utoipa::openapi::OpenApi) {
    // `/distance` takes batches, so it has its own, larger body limit; being the inner layer,
    // it overrides the limit the server sets for every other route.
    let batch_limit = state.limits.batch_body_bytes;
    let distance = OpenApiRouter::new()
        .routes(routes!(handlers::get_distance, handlers::post_distance))
        .layer(DefaultBodyLimit::max(batch_limit))
        .layer(Extension(BodyLimit(batch_limit)));
    let (api, mut doc) = OpenApiRouter::with_openapi(ApiDoc::openapi())
        .merge(distance)
        .routes(routes!(handlers::get_table, handlers::post_table))
        .routes(routes!(handlers::get_chart_data, handlers::post_chart_data))
        .routes(routes!(handlers::get_chart_svg))
        .routes(routes!(planning::get_rig, planning::post_rig))
        .routes(routes!(planning::get_baseline, planning::post_baseline))
        .with_state(state)
        .split_for_parts();
    let (ops, ops_doc) = OpenApiRouter::new()
        .routes(routes!(ops::healthz))
        .routes(routes!(ops::readyz))
        .routes(routes!(ops::metrics))
        .with_state(ops)
        .split_for_parts();
    doc.merge(ops_doc);
    (Routers { api, ops }, doc)
}

/// The OpenAPI document of the service, as served at `/openapi.json`.
pub fn openapi() -> utoipa::openapi::OpenApi {
    routes(AppState::default(), OpsState::default()).1
}

/// The routers, with `/openapi.json` and Swagger UI at `/docs` added to the API's.
pub fn routers(state: AppState, ops: OpsState) -> Routers {
    let (routers, doc) = routes(state, ops);
    Routers {
        api: routers
            .api
            .merge(SwaggerUi::new("/docs").url("/openapi.json", doc)),
        ops: routers.ops,
    }
}
