//! `/table`: the sample table of distance against disparity for a rig (GET and POST), as JSON
//! or CSV.

pub mod csv;
pub mod types;

use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{FormatQuery, TableFormat, TableRequest, TableResponse, TableRow};
use crate::api::AppState;
use crate::api::error::{ApiError, FieldErrors};
use crate::api::extract::{JsonBody, QueryParams};
use crate::api::respond::Json;
use crate::api::validate::{self, Bounds};
use crate::api::wire::openapi::{BodyErrors, QueryErrors};
use crate::physics;

/// `GET` and `POST /table`.
pub fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new().routes(routes!(get_table, post_table))
}

#[utoipa::path(
    post,
    path = "/table",
    tag = "table",
    summary = "Sample table of distance against disparity for a rig",
    description = "JSON by default; CSV with `format: csv` in the body, `?format=csv` in the \
                   URL, or `Accept: text/csv`.",
    params(FormatQuery),
    request_body(content = TableRequest, examples(
        ("disparity range" = (summary = "The seed's rig over 10 to 100 px", value = json!({
            "focal_length_px": 35, "baseline": 150, "unit": "mm",
            "image_width": 800, "image_height": 600,
            "disparity_min": 10, "disparity_max": 100, "steps": 10
        }))),
        ("distance range, log spacing" = (summary = "A 90° camera from 0.5 m to 20 m",
                                          value = json!({
            "horizontal_fov_deg": 90, "baseline": 0.065, "unit": "m",
            "image_width": 800, "image_height": 600,
            "distance_min": 0.5, "distance_max": 20, "spacing": "log", "steps": 12
        }))),
        ("CSV" = (summary = "f in mm with a sensor width, as CSV", value = json!({
            "focal_length_mm": 4, "sensor_width_mm": 6.4, "baseline": 120,
            "image_width": 1280, "image_height": 720, "format": "csv", "steps": 5
        })))
    )),
    responses(
        (status = 200, description = "The sample table.", content(
            (TableResponse = "application/json"),
            (String = "text/csv")
        )),
        BodyErrors
    )
)]
pub async fn post_table(
    State(state): State<AppState>,
    QueryParams(query, query_problems): QueryParams<FormatQuery>,
    headers: HeaderMap,
    JsonBody(request, mut problems): JsonBody<TableRequest>,
) -> Result<Response, ApiError> {
    problems.extend(query_problems);
    let format = csv::negotiate(query.format.or(request.format), headers.get(header::ACCEPT));
    table(&state, &request, problems).map(|t| table_response(t, format))
}

#[utoipa::path(
    get,
    path = "/table",
    tag = "table",
    summary = "Sample table (query-string form of POST /table)",
    description = "JSON by default; CSV with `format=csv` or `Accept: text/csv`.",
    params(TableRequest),
    responses(
        (status = 200, description = "The sample table.", content(
            (TableResponse = "application/json"),
            (String = "text/csv")
        )),
        QueryErrors
    )
)]
pub async fn get_table(
    State(state): State<AppState>,
    headers: HeaderMap,
    QueryParams(request, problems): QueryParams<TableRequest>,
) -> Result<Response, ApiError> {
    let format = csv::negotiate(request.format, headers.get(header::ACCEPT));
    table(&state, &request, problems).map(|t| table_response(t, format))
}

/// The table in the negotiated format. Both vary with `Accept`, which caches must know.
fn table_response(table: TableResponse, format: TableFormat) -> Response {
    let vary = (header::VARY, HeaderValue::from_static("accept"));
    match format {
        TableFormat::Json => ([vary], Json(table)).into_response(),
        TableFormat::Csv => (
            [
                vary,
                (
                    header::CONTENT_TYPE,
                    HeaderValue::from_static(csv::TEXT_CSV),
                ),
                (
                    header::CONTENT_DISPOSITION,
                    HeaderValue::from_static("attachment; filename=\"stereo-table.csv\""),
                ),
            ],
            csv::table(&table),
        )
            .into_response(),
    }
}

fn table(
    state: &AppState,
    request: &TableRequest,
    mut problems: FieldErrors,
) -> Result<TableResponse, ApiError> {
    let params = request.rig_params();
    let rig = validate::rig(&params, &mut problems);
    let range = validate::range(&request.range_params(), rig.as_ref(), None, &mut problems);
    let steps = problems.count("steps", request.steps, 10, 1, state.limits.table_rows);
    let x_left = match request.x_left {
        Some(x) => validate::x_coordinate("x_left", x, Bounds::of(&params.camera), &mut problems),
        None => rig.map(|r| r.image_width / 2.0),
    };
    let (rig, ((range, spacing), (steps, x_left))) =
        problems.finish(rig.zip(range.zip(steps.zip(x_left))))?;
    let rows = physics::table(&rig, range, steps, spacing, x_left)
        .map_err(|e| ApiError::from((e, validate::range_fields(request.range_params()))))?;
    Ok(TableResponse {
        unit: request.unit.unwrap_or_default(),
        focal_length_px: rig.focal_px,
        baseline: rig.baseline,
        disparity_error_px: rig.disparity_error_px,
        x_left,
        rows: rows
            .into_iter()
            .map(|r| TableRow {
                distance: r.distance,
                disparity_px: r.disparity_px,
                normalized_x: r.normalized_x,
                projection_factor: r.projection_factor,
                depth_error: r.depth_error,
            })
            .collect(),
    })
}
