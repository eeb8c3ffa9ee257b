//! Route handlers: each is extract → validate → physics → response, and nothing else.

use axum::{
    extract::State,
    http::{HeaderMap, HeaderValue, Method, Uri, header},
    response::{IntoResponse, Response},
};

use super::{
    AppState,
    batch::{self, DistanceBody},
    csv,
    error::{ApiError, BodyErrors, QueryErrors},
    extract::{JsonBody, QueryParams},
    format::short,
    respond::Json,
    svg,
    types::{
        Axis, ChartPoint, ChartRequest, ChartResponse, DistanceInput, DistanceOutput,
        DistanceRequest, DistanceResponse, FormatQuery, Series, TableFormat, TableRequest,
        TableResponse, TableRow, Warning,
    },
    validate::{self, Bounds, Problems},
};
use crate::physics::{self, Rig};

/// The media type of `/chart.svg`.
pub const IMAGE_SVG: &str = "image/svg+xml";

#[utoipa::path(
    post,
    path = "/distance",
    tag = "distance",
    summary = "Distance to one feature, or to a batch of features seen by one rig",
    description = "Z = B·f_px / |d + doffs| with d = x_left − x_right, in the unit of the \
                   baseline, with its expected error ΔZ = Z²·Δd/(f_px·B), the intermediate values \
                   and the feature's 3D point.\n\n\
                   A body with `rig` and `points` is a batch of up to 10 000 points (the \
                   server's cap), answered in order. A batch that breaks the schema (a wrong \
                   rig or envelope, or a point with a wrong type or an unknown or missing \
                   member) is a 422 naming each fault, such as `points[17].x_left`. Otherwise \
                   it is a 200 in which each point has its distance or, when its values fail \
                   against the rig (off the image, at infinity), its own `errors`; `failed` \
                   counts the latter.",
    request_body(content = DistanceInput, examples(
        ("focal length in px" = (summary = "The seed's example 1: f = 35 px, B = 150 mm, \
                                  d = 50 px, so Z = 105 mm", value = json!({
            "focal_length_px": 35, "baseline": 150, "unit": "mm",
            "x_left": 400, "x_right": 350, "image_width": 800, "image_height": 600
        }))),
        ("focal length in mm with sensor width" = (summary = "f = 4 mm · 1280 px / 6.4 mm = \
                                                   800 px, so Z = 1920 mm", value = json!({
            "focal_length_mm": 4, "sensor_width_mm": 6.4, "baseline": 120, "unit": "mm",
            "x_left": 700, "x_right": 650, "image_width": 1280, "image_height": 720
        }))),
        ("focal length in mm with pixel pitch" = (summary = "f = 3.6 mm · 1000 / 3 µm = \
                                                  1200 px, so Z = 2.4 m", value = json!({
            "focal_length_mm": 3.6, "pixel_size_um": 3, "baseline": 0.12, "unit": "m",
            "x_left": 1000, "x_right": 940, "image_width": 1920, "image_height": 1080
        }))),
        ("horizontal field of view" = (summary = "f = 400 px / tan 45° = 400 px, so \
                                       Z = 1300 mm", value = json!({
            "horizontal_fov_deg": 90, "baseline": 65, "unit": "mm",
            "x_left": 420, "x_right": 400, "image_width": 800, "image_height": 600,
            "doffs": 0, "y": 300, "disparity_error_px": 0.1
        }))),
        ("batch" = (summary = "Two features seen by one rig", value = json!({
            "rig": {"focal_length_px": 35, "baseline": 150, "unit": "mm",
                    "image_width": 800, "image_height": 600},
            "points": [{"x_left": 400, "x_right": 350}, {"x_left": 420, "x_right": 390, "y": 310}]
        })))
    )),
    responses(
        (status = 200, description = "The distance and its error, or one result per point \
                                      of a batch.", body = DistanceOutput),
        BodyErrors
    )
)]
pub async fn post_distance(
    State(state): State<AppState>,
    body: DistanceBody,
) -> Result<Json<DistanceOutput>, ApiError> {
    match body {
        DistanceBody::One(request, problems) => {
            distance(&request, problems).map(|r| Json(DistanceOutput::One(r)))
        }
        DistanceBody::Batch(batch) => {
            batch::answer(batch, &state.limits).map(|r| Json(DistanceOutput::Batch(r)))
        }
    }
}

#[utoipa::path(
    get,
    path = "/distance",
    tag = "distance",
    summary = "Distance to one feature (query-string form of POST /distance)",
    params(DistanceRequest),
    responses(
        (status = 200, description = "The distance and its error.", body = DistanceResponse),
        QueryErrors
    )
)]
pub async fn get_distance(
    QueryParams(request, problems): QueryParams<DistanceRequest>,
) -> Result<Json<DistanceResponse>, ApiError> {
    distance(&request, problems).map(Json)
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

#[utoipa::path(
    post,
    path = "/chart-data",
    tag = "chart",
    summary = "Chart series of distance and depth error against disparity",
    request_body(content = ChartRequest, examples(
        ("measured point" = (summary = "The seed's example 1 marked on the curve",
                             value = json!({
            "focal_length_px": 35, "baseline": 150, "unit": "mm",
            "image_width": 800, "image_height": 600,
            "x_left": 400, "x_right": 350, "points": 100
        }))),
        ("distance range" = (summary = "f in mm with a pixel pitch, from 1 m to 30 m",
                             value = json!({
            "focal_length_mm": 3.6, "pixel_size_um": 3, "baseline": 0.12, "unit": "m",
            "image_width": 1920, "image_height": 1080,
            "distance_min": 1, "distance_max": 30, "spacing": "log", "points": 50
        })))
    )),
    responses(
        (status = 200, description = "The chart series.", body = ChartResponse),
        BodyErrors
    )
)]
pub async fn post_chart_data(
    State(state): State<AppState>,
    JsonBody(request, problems): JsonBody<ChartRequest>,
) -> Result<Json<ChartResponse>, ApiError> {
    chart(&state, &request, problems).map(Json)
}

#[utoipa::path(
    get,
    path = "/chart-data",
    tag = "chart",
    summary = "Chart series (query-string form of POST /chart-data)",
    params(ChartRequest),
    responses(
        (status = 200, description = "The chart series.", body = ChartResponse),
        QueryErrors
    )
)]
pub async fn get_chart_data(
    State(state): State<AppState>,
    QueryParams(request, problems): QueryParams<ChartRequest>,
) -> Result<Json<ChartResponse>, ApiError> {
    chart(&state, &request, problems).map(Json)
}

#[utoipa::path(
    get,
    path = "/chart.svg",
    tag = "chart",
    summary = "The chart as a self-contained SVG image",
    description = "Takes the same query as GET /chart-data and draws it: distance (left axis) \
                   and depth error (right axis) against disparity, with labelled axes in units \
                   and the measured point marked. No scripts, fonts or links: ready to embed.",
    params(ChartRequest),
    responses(
        (status = 200, description = "The chart.", content_type = "image/svg+xml", body = String),
        QueryErrors
    )
)]
pub async fn get_chart_svg(
    State(state): State<AppState>,
    QueryParams(request, problems): QueryParams<ChartRequest>,
) -> Result<Response, ApiError> {
    let chart = chart(&state, &request, problems)?;
    Ok((
        [(header::CONTENT_TYPE, HeaderValue::from_static(IMAGE_SVG))],
        svg::chart(&chart),
    )
        .into_response())
}

/// Answers any path the API does not have.
pub async fn not_found(uri: Uri) -> ApiError {
    ApiError::NotFound(uri.path().to_owned())
}

/// Answers a known path asked with the wrong method (axum adds the `Allow` header).
pub async fn method_not_allowed(method: Method) -> ApiError {
    ApiError::MethodNotAllowed(method.to_string())
}

/// The fields to blame when a correspondence has no finite distance.
fn disparity_fields(rig: &Rig) -> &'static [&'static str] {
    if rig.doffs == 0.0 {
        &["x_left", "x_right"]
    } else {
        &["x_left", "x_right", "doffs"]
    }
}

fn distance(
    request: &DistanceRequest,
    mut problems: Problems,
) -> Result<DistanceResponse, ApiError> {
    let params = request.rig_params();
    let rig = validate::rig(&params, &mut problems);
    let correspondence = validate::correspondence(
        (request.x_left, request.x_right, request.y),
        Bounds::of(&params.camera),
        rig.map(|r| r.cy),
        &mut problems,
    );
    let (rig, correspondence) = problems.finish(rig.zip(correspondence))?;
    let m = physics::measure(&rig, correspondence)
        .map_err(|e| ApiError::from((e, disparity_fields(&rig))))?;
    let unit = rig.unit.symbol();
    Ok(DistanceResponse {
        formula: format!(
            "Z = B·f / |d + doffs| = {} {unit} × {} px / |{} px + {} px| = {} {unit}",
            short(rig.baseline),
            short(rig.focal_px),
            short(m.disparity_px),
            short(rig.doffs),
            short(m.distance),
        ),
        distance: m.distance,
        unit: request.unit.unwrap_or_default(),
        distance_m: m.distance_m,
        depth_error: m.depth_error,
        relative_error: m.relative_error,
        disparity_error_px: rig.disparity_error_px,
        disparity_px: m.disparity_px,
        effective_disparity_px: m.effective_disparity_px,
        focal_length_px: rig.focal_px,
        baseline: rig.baseline,
        normalized_x: m.normalized_x,
        projection_factor: m.projection_factor,
        point: m.point.into(),
        warnings: m.warnings.iter().map(Warning::from).collect(),
    })
}

fn table(
    state: &AppState,
    request: &TableRequest,
    mut problems: Problems,
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
        .map_err(|e| ApiError::from((e, range_fields(request.range_params()))))?;
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

/// The range fields to blame when a sweep overflows.
fn range_fields(range: super::types::RangeParams) -> &'static [&'static str] {
    if range.distance_min.is_some() {
        &["distance_min", "distance_max"]
    } else if range.disparity_min.is_some() {
        &["disparity_min", "disparity_max"]
    } else {
        &["baseline"]
    }
}

fn chart(
    state: &AppState,
    request: &ChartRequest,
    mut problems: Problems,
) -> Result<ChartResponse, ApiError> {
    let params = request.rig_params();
    let rig = validate::rig(&params, &mut problems);
    let measured = match (request.x_left, request.x_right) {
        (None, None) => None,
        pair => validate::x_pair(pair, Bounds::of(&params.camera), &mut problems)
            .map(|(x_left, x_right)| x_left - x_right),
    };
    let range = validate::range(
        &request.range_params(),
        rig.as_ref(),
        measured,
        &mut problems,
    );
    let points = problems.count("points", request.points, 100, 2, state.limits.chart_points);
    let (rig, ((range, spacing), points)) = problems.finish(rig.zip(range.zip(points)))?;
    let marker = measured
        .map(|d| {
            rig.distance_at(d)
                .map(|z| ChartPoint { x: d, y: z })
                .map_err(|e| ApiError::from((e, disparity_fields(&rig))))
        })
        .transpose()?;
    let mut samples = physics::sweep(&rig, range, points, spacing)
        .map_err(|e| ApiError::from((e, range_fields(request.range_params()))))?;
    samples.sort_by(|a, b| a.disparity_px.total_cmp(&b.disparity_px));
    let unit = rig.unit.symbol();
    let series = |name: &str, label: String, y: fn(&physics::Sample) -> f64| Series {
        name: name.to_owned(),
        label,
        unit: unit.to_owned(),
        points: samples
            .iter()
            .map(|s| ChartPoint {
                x: s.disparity_px,
                y: y(s),
            })
            .collect(),
    };
    Ok(ChartResponse {
        unit: request.unit.unwrap_or_default(),
        x_axis: Axis {
            label: "Disparity d (px)".to_owned(),
            unit: "px".to_owned(),
        },
        y_axis: Axis {
            label: format!("Distance Z ({unit})"),
            unit: unit.to_owned(),
        },
        series: vec![
            series("distance", format!("Distance Z ({unit})"), |s| s.distance),
            series(
                "depth_error",
                format!(
                    "Depth error ΔZ ({unit}, Δd = {} px)",
                    short(rig.disparity_error_px)
                ),
                |s| s.depth_error,
            ),
        ],
        marker,
    })
}
