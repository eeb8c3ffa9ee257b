//! The HTTP API: routes, the OpenAPI document derived from them, and shared state.

pub mod error;
pub mod extract;
pub mod handlers;
pub mod types;
pub mod validate;

use axum::Router;
use utoipa::OpenApi;
use utoipa_axum::{router::OpenApiRouter, routes};
use utoipa_swagger_ui::SwaggerUi;

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
        (name = "chart", description = "Chart data for a rig")
    )
)]
struct ApiDoc;

/// The API routes with their OpenAPI document, built from the same handler annotations.
fn routes(state: AppState) -> (Router, utoipa::openapi::OpenApi) {
    OpenApiRouter::with_openapi(ApiDoc::openapi())
        .routes(routes!(handlers::get_distance, handlers::post_distance))
        .routes(routes!(handlers::get_table, handlers::post_table))
        .routes(routes!(handlers::get_chart_data, handlers::post_chart_data))
        .with_state(state)
        .split_for_parts()
}

/// The OpenAPI document of the service, as served at `/openapi.json`.
pub fn openapi() -> utoipa::openapi::OpenApi {
    routes(AppState::default()).1
}

/// The API router: the routes, `/openapi.json`, Swagger UI at `/docs`, and problem+json
/// answers for unknown paths and methods.
pub fn router(state: AppState) -> Router {
    let (api, doc) = routes(state);
    api.merge(SwaggerUi::new("/docs").url("/openapi.json", doc))
        .fallback(handlers::not_found)
        .method_not_allowed_fallback(handlers::method_not_allowed)
}
