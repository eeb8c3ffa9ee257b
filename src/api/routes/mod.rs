//! One module per resource, each with its request and response types beside its handlers and
//! its own `router()`; [`light`] merges the JSON resources, [`heavy`] the image resources and
//! [`ops::router`] the probes, each group to be wrapped in its own limits by
//! [`crate::startup`].

pub mod calibration;
pub mod chart;
pub mod distance;
pub mod ops;
pub mod planning;
pub mod table;

use axum::http::{Method, Uri};

/// Declares the two handlers of a JSON operation, documented in one place: `POST` with the
/// request as a JSON body and `GET` with the same request as a query string, both answered by
/// `$answer(&state, &request, problems)`. The `POST` documentation gives the summary, any
/// description and the request body's examples; the `GET` form is documented from the same
/// request type. The calling module imports what the handlers name (`State`, `AppState`,
/// `JsonBody`, `QueryParams`, `Json`, `ApiError`, `BodyErrors`, `QueryErrors`).
macro_rules! json_operation {
    (
        $answer:ident: $request:ident => $response:ident at $path:tt, tag $tag:tt, ok $ok:tt;
        post $post:ident($($post_doc:tt)*);
        get $get:ident(summary = $get_summary:tt);
    ) => {
        $crate::api::routes::json_operation!(@handler $post, JsonBody, $request => $response,
            $answer, #[utoipa::path(post, path = $path, tag = $tag, $($post_doc)*,
                responses((status = 200, description = $ok, body = $response), BodyErrors))]);
        $crate::api::routes::json_operation!(@handler $get, QueryParams, $request => $response,
            $answer, #[utoipa::path(get, path = $path, tag = $tag, summary = $get_summary,
                params($request),
                responses((status = 200, description = $ok, body = $response), QueryErrors))]);
    };
    (@handler $name:ident, $extract:ident, $request:ident => $response:ident, $answer:ident,
     #[$doc:meta]) => {
        #[$doc]
        pub async fn $name(
            State(state): State<AppState>,
            $extract(request, problems): $extract<$request>,
        ) -> Result<Json<$response>, ApiError> {
            $answer(&state, &request, problems).map(Json)
        }
    };
}

/// Declares the two handlers of an operation that answers JSON or CSV, as
/// [`json_operation!`] does, plus the format choice: `format` in the body or query (`POST` may
/// also take `?format=`), else the `Accept` header; the CSV form is `$csv(&answer)`, sent as
/// the attachment `$file`. The calling module also imports `HeaderMap`, `header`, `Response`,
/// `csv` and `FormatQuery`.
macro_rules! data_operation {
    (
        $answer:ident: $request:ident => $response:ident, csv $csv:ident as $file:literal
        at $path:tt, tag $tag:tt, ok $ok:tt;
        post $post:ident($($post_doc:tt)*);
        get $get:ident(summary = $get_summary:tt);
    ) => {
        #[utoipa::path(post, path = $path, tag = $tag, $($post_doc)*,
            description = "JSON by default; CSV with `format: csv` in the body, \
                           `?format=csv` in the URL, or `Accept: text/csv`.",
            params(FormatQuery),
            responses((status = 200, description = $ok, content(
                ($response = "application/json"), (String = "text/csv"))), BodyErrors))]
        pub async fn $post(
            State(state): State<AppState>,
            QueryParams(query, query_problems): QueryParams<FormatQuery>,
            headers: HeaderMap,
            JsonBody(request, mut problems): JsonBody<$request>,
        ) -> Result<Response, ApiError> {
            problems.extend(query_problems);
            let format =
                csv::negotiate(query.format.or(request.format), headers.get(header::ACCEPT));
            $crate::api::routes::data_operation!(@respond $answer(&state, &request, problems),
                format, $csv, $file)
        }

        #[utoipa::path(get, path = $path, tag = $tag, summary = $get_summary,
            description = "JSON by default; CSV with `format=csv` or `Accept: text/csv`.",
            params($request),
            responses((status = 200, description = $ok, content(
                ($response = "application/json"), (String = "text/csv"))), QueryErrors))]
        pub async fn $get(
            State(state): State<AppState>,
            headers: HeaderMap,
            QueryParams(request, problems): QueryParams<$request>,
        ) -> Result<Response, ApiError> {
            let format = csv::negotiate(request.format, headers.get(header::ACCEPT));
            $crate::api::routes::data_operation!(@respond $answer(&state, &request, problems),
                format, $csv, $file)
        }
    };
    (@respond $answer:expr, $format:ident, $csv:ident, $file:literal) => {
        $answer.map(|answer| {
            csv::respond($format, answer, $csv, concat!("attachment; filename=\"", $file, "\""))
        })
    };
}

use utoipa_axum::router::OpenApiRouter;
pub(crate) use {data_operation, json_operation};

use super::{AppState, HeavyState, error::ApiError};

/// The JSON answers: microseconds of CPU and small bodies each.
pub fn light() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .merge(distance::router())
        .merge(table::router())
        .merge(chart::router())
        .merge(planning::router())
        .merge(calibration::router())
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
