//! The HTTP API. Its modules read one way, each using only those before it:
//! [`error`] ← [`extract`] ← [`wire`] ← [`validate`] ← [`images`] ← [`routes`].
//!
//! - [`error`]: [`error::ApiError`] rendered as problem+json, and [`error::FieldErrors`], the
//!   collector that names every offending field; [`body_limit`], the body limits a 413 names.
//! - [`extract`]: JSON-body and query-string extractors that record every refused member.
//! - [`wire`]: what every request and answer shares: deserialization rules, the request macros,
//!   the unvalidated members, the measured values, the OpenAPI glue.
//! - [`validate`]: the caller's members turned into the physics module's types, through their
//!   checking constructors ([`stereo_core::physics::Rig::new`]), the faults named as fields.
//! - [`images`]: what the image routes share: the multipart form and the [`images::ImagePair`]
//!   extractor, the rig from a part, raw pairs rectified, file answers and `Server-Timing`, the
//!   limits, the blocking work.
//! - [`routes`]: one module per resource (handlers, wire types, `router()`), merged into the
//!   route groups: light (JSON), heavy (images) and the probes. No route imports another.
//! - [`state`]: what the light group's handlers see ([`AppState`]; the heavy group's,
//!   [`HeavyState`], is the image routes' and lives in [`images`]).
//! - [`respond`], [`csv`], [`svg`]: JSON answers in one buffer, CSV answers, and the chart
//!   drawn as SVG.
//! - [`operation`]: the macros that declare a JSON resource's `GET` and `POST` handlers.
//! - [`member_messages`]: serde's refusal of a request member said in the API's words.

pub mod body_limit;
pub mod csv;
pub mod error;
pub mod extract;
pub mod images;
pub mod member_messages;
pub mod operation;
pub mod respond;
pub mod routes;
pub mod state;
pub mod svg;
pub mod validate;
pub mod wire;

pub use images::HeavyState;
pub use state::AppState;

use axum::{Router, http::header, routing::get};
use utoipa::OpenApi;
use utoipa_axum::router::OpenApiRouter;
use utoipa_swagger_ui::SwaggerUi;

use self::routes::ops::OpsState;

#[derive(OpenApi)]
#[openapi(
    info(
        title = "Stereo distance service",
        description = "Turns a stereo rig and what it sees into a distance you can trust, end \
                       to end: checkerboard or ChArUco pairs into a calibration with each \
                       parameter's σ and OpenCV and ROS files (`/calibrate`), raw frames \
                       rectified (`/rectify`), dense disparity and depth maps with each pixel's \
                       σ (`/depth-map`), a clicked point's match and a region's depth \
                       (`/match`), and a correspondence's distance with its error bar \
                       (`/distance`), with the tables, charts and rig planning around them.\n\n\
                       Depth is Z = B·f_px / |d + doffs| with d = x_left − x_right in pixels; \
                       the focal length is always converted to pixels first. `distance` is \
                       that depth Z, along the optical axis; `range` is the straight line \
                       √(X² + Y² + Z²) from the left camera to the point. `/calibration` reads \
                       a calibration file into the rig the other endpoints take. Every error is \
                       `application/problem+json` (RFC 9457) with an `errors` array naming \
                       every offending field.\n\n\
                       Live depth from a stereo camera, frame by frame over one WebSocket \
                       (`GET /depth-stream`, with a temporal filter), is described in AsyncAPI \
                       at [/asyncapi.yaml](/asyncapi.yaml).",
        license(name = "MIT", identifier = "MIT"),
        contact(name = "Stereo distance service maintainers")
    ),
    // Relative: the server that serves this document (Swagger UI, generators and
    // schemathesis resolve it against the document's own URL).
    servers((url = "/", description = "The server that serves this document")),
    // The bearer tokens (optional) are added with the other groups' paths: see `routes`.
    components(schemas(
        error::Problem,
        error::FieldError,
        wire::board_calibration::CalibrateOutput,
        wire::rectify::RectifyOutput,
        wire::rectify::InterpolationChoice,
        wire::images::RectifyMode,
        wire::images::ProjectionAsked,
        // The image routes' answers, which their `IntoResponses` name by reference.
        wire::images::FileBody,
        wire::depth_map::DepthMapSummary,
        wire::rectify::RectifySummary,
        wire::board_calibration::CalibrationSummary,
        wire::board_calibration::BoardAnswer,
        wire::calibration_check::CheckAnswer
    )),
    tags(
        (name = "calibration", description = "Calibration files read into a rig"),
        (name = "distance", description = "Distance to one feature"),
        (name = "table", description = "Sample tables for a rig"),
        (name = "chart", description = "Chart data and the chart as SVG for a rig"),
        (name = "planning", description = "Rig planning: depth range, error budget, baseline"),
        (name = "images", description = "Stereo pairs: raw frames rectified, dense disparity and depth maps, \
                                          points matched and regions measured"),
        (name = "operations", description = "Liveness, readiness and metrics")
    )
)]
struct ApiDoc;

/// The service's routers, one per route group, each to be wrapped in its own limits.
pub struct Routers {
    /// The JSON answers.
    pub light: Router,
    /// `/openapi.json` and `/docs`, open to all (the page's group).
    pub docs: Router,
    /// The image requests.
    pub heavy: Router,
    /// `/healthz`, `/readyz` and `/metrics`: never shed, so probes answer under load.
    pub probes: Router,
}

/// The routers and the OpenAPI document, built from the same handler annotations.
fn routes(
    state: AppState,
    heavy: HeavyState,
    ops: OpsState,
) -> (Routers, utoipa::openapi::OpenApi) {
    let (light, mut doc) = OpenApiRouter::with_openapi(ApiDoc::openapi())
        .merge(routes::light())
        .with_state(state)
        .split_for_parts();
    let (heavy, heavy_doc) = routes::heavy().with_state(heavy).split_for_parts();
    let (probes, probes_doc) = routes::ops::router().with_state(ops).split_for_parts();
    doc.merge(heavy_doc);
    doc.merge(probes_doc);
    wire::openapi::bearer_tokens(&mut doc);
    (
        Routers {
            light,
            docs: Router::new(),
            heavy,
            probes,
        },
        doc,
    )
}

/// The OpenAPI document of the service, as served at `/openapi.json`.
pub fn openapi() -> utoipa::openapi::OpenApi {
    routes(
        AppState::default(),
        HeavyState::default(),
        OpsState::default(),
    )
    .1
}

/// The routers, with `/openapi.json` and Swagger UI at `/docs` in their own.
pub fn routers(state: AppState, heavy: HeavyState, ops: OpsState) -> Routers {
    let (routers, doc) = routes(state, heavy, ops);
    let spec = axum::body::Bytes::from(openapi_text(&doc));
    let served = move || {
        let spec = spec.clone();
        async move { ([(header::CONTENT_TYPE, "application/json")], spec) }
    };
    Routers {
        docs: Router::new()
            .route("/openapi.json", get(served))
            .route("/asyncapi.yaml", get(asyncapi))
            .merge(
                SwaggerUi::new("/docs").config(utoipa_swagger_ui::Config::from("/openapi.json")),
            ),
        ..routers
    }
}

/// The AsyncAPI document of the live stream (`GET /depth-stream`, a WebSocket), as committed
/// in `openapi/asyncapi.yaml`.
pub const ASYNCAPI: &str = include_str!("../../openapi/asyncapi.yaml");

/// `GET /asyncapi.yaml`.
async fn asyncapi() -> impl axum::response::IntoResponse {
    ([(header::CONTENT_TYPE, "application/yaml")], ASYNCAPI)
}

/// The OpenAPI document as served at `/openapi.json` and committed as `openapi/openapi.json`,
/// byte for byte: pretty-printed JSON with a final newline.
pub fn openapi_text(doc: &utoipa::openapi::OpenApi) -> String {
    let mut text = doc
        .to_pretty_json()
        .unwrap_or_else(|e| format!("{{\"error\": \"the OpenAPI document: {e}\"}}"));
    text.push('\n');
    text
}
