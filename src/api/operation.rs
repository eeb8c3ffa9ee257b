//! The macros that declare a JSON resource's handlers from one description: `GET` and `POST`
//! of one request ([`json_operation!`]), and, for a resource that also answers CSV, its four
//! ([`data_operation!`]). The light routes use them, below the routes as [`super::csv`] is.

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
        $crate::api::operation::json_operation!(@handler $post, JsonBody, $request => $response,
            $answer, #[utoipa::path(post, path = $path, tag = $tag, $($post_doc)*,
                responses((status = 200, description = $ok, body = $response), BodyErrors))]);
        $crate::api::operation::json_operation!(@handler $get, QueryParams, $request => $response,
            $answer, #[utoipa::path(get, path = $path, tag = $tag, summary = $get_summary,
                description = concat!("The query-string form of POST ", $path, ": the same \
                                       members as query parameters, lists comma-separated or \
                                       repeated; the same answer."),
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

/// Declares the four handlers of a resource that answers JSON or CSV, each representation at
/// its own path with one media type, so that generated clients read each answer: `GET` and
/// `POST $path` answer JSON (or CSV to an `Accept: text/csv` header, for curl users), `GET`
/// and `POST $csv_path` answer CSV, `$csv(&answer)` sent as the attachment `$file`. A request
/// naming the former `format` member is told where CSV is now (`$moved`). The calling module
/// imports what [`json_operation!`] names, plus `HeaderMap`, `header`, `Response` and `csv`.
macro_rules! data_operation {
    (
        $answer:ident: $request:ident => $response:ident at $path:tt, tag $tag:tt, ok $ok:tt;
        csv $csv:ident as $file:literal at $csv_path:tt, ok $csv_ok:tt, moved $moved:tt;
        post $post:ident($($post_doc:tt)*);
        get $get:ident(summary = $get_summary:tt);
        post csv $post_csv:ident($($post_csv_doc:tt)*);
        get csv $get_csv:ident(summary = $get_csv_summary:tt);
    ) => {
        #[utoipa::path(post, path = $path, tag = $tag, $($post_doc)*,
            description = concat!("Answers JSON. The same answer as CSV is at POST ", $csv_path,
                                  " (an `Accept: text/csv` header here also gets CSV)."),
            responses((status = 200, description = $ok, body = $response), BodyErrors))]
        pub async fn $post(
            State(state): State<AppState>,
            headers: HeaderMap,
            JsonBody(request, mut problems): JsonBody<$request>,
        ) -> Result<Response, ApiError> {
            let format = csv::negotiate(headers.get(header::ACCEPT));
            $crate::api::operation::data_operation!(@respond $answer(&state, &request, problems),
                format, $csv, $file, $moved)
        }

        #[utoipa::path(get, path = $path, tag = $tag, summary = $get_summary,
            description = concat!("The query-string form of POST ", $path, ": the same members \
                                   as query parameters, lists comma-separated or repeated. \
                                   Answers JSON; CSV is at GET ", $csv_path, "."),
            params($request),
            responses((status = 200, description = $ok, body = $response), QueryErrors))]
        pub async fn $get(
            State(state): State<AppState>,
            headers: HeaderMap,
            QueryParams(request, mut problems): QueryParams<$request>,
        ) -> Result<Response, ApiError> {
            let format = csv::negotiate(headers.get(header::ACCEPT));
            $crate::api::operation::data_operation!(@respond $answer(&state, &request, problems),
                format, $csv, $file, $moved)
        }

        #[utoipa::path(post, path = $csv_path, tag = $tag, $($post_csv_doc)*,
            description = concat!("The answer of POST ", $path, " as CSV (RFC 4180): a header \
                                   row naming each column with its unit, such as \
                                   `distance_mm`, then one line per row."),
            responses((status = 200, description = $csv_ok, content_type = "text/csv",
                       body = String), BodyErrors))]
        pub async fn $post_csv(
            State(state): State<AppState>,
            JsonBody(request, mut problems): JsonBody<$request>,
        ) -> Result<Response, ApiError> {
            $crate::api::operation::data_operation!(@respond $answer(&state, &request, problems),
                csv::DataFormat::Csv, $csv, $file, $moved)
        }

        #[utoipa::path(get, path = $csv_path, tag = $tag, summary = $get_csv_summary,
            description = concat!("The query-string form of POST ", $csv_path, "."),
            params($request),
            responses((status = 200, description = $csv_ok, content_type = "text/csv",
                       body = String), QueryErrors))]
        pub async fn $get_csv(
            State(state): State<AppState>,
            QueryParams(request, mut problems): QueryParams<$request>,
        ) -> Result<Response, ApiError> {
            $crate::api::operation::data_operation!(@respond $answer(&state, &request, problems),
                csv::DataFormat::Csv, $csv, $file, $moved)
        }
    };
    (@respond $answer:ident(&$state:ident, &$request:ident, $problems:ident), $format:expr,
     $csv:ident, $file:literal, $moved:tt) => {{
        $problems.reword("format", $moved);
        $answer(&$state, &$request, $problems).map(|answer| {
            csv::respond($format, answer, $csv, concat!("attachment; filename=\"", $file, "\""))
        })
    }};
}

pub(crate) use {data_operation, json_operation};
