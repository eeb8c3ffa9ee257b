//! `/chart-data` and `/chart.svg`: distance and depth error against disparity for a rig, as
//! series for a chart library (GET and POST) or drawn as a self-contained SVG (GET).

pub mod svg;
pub mod types;

use axum::extract::State;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{Axis, ChartPoint, ChartRequest, ChartResponse, Series};
use super::json_operation;
use crate::api::AppState;
use crate::api::error::{ApiError, FieldErrors};
use crate::api::extract::{JsonBody, QueryParams};
use crate::api::format::short;
use crate::api::respond::Json;
use crate::api::validate::{self, Bounds};
use crate::api::wire::openapi::{BodyErrors, QueryErrors};
use crate::physics;

/// `GET` and `POST /chart-data`, `GET /chart.svg`.
pub fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(get_chart_data, post_chart_data))
        .routes(routes!(get_chart_svg))
}

/// The media type of `/chart.svg`.
pub const IMAGE_SVG: &str = "image/svg+xml";

json_operation! {
    chart: ChartRequest => ChartResponse at "/chart-data", tag "chart", ok "The chart series.";
    post post_chart_data(
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
        ))
    );
    get get_chart_data(summary = "Chart series (query-string form of POST /chart-data)");
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

fn chart(
    state: &AppState,
    request: &ChartRequest,
    mut problems: FieldErrors,
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
                .map_err(|e| ApiError::from((e, validate::disparity_fields(&rig))))
        })
        .transpose()?;
    let mut samples = physics::sweep(&rig, range, points, spacing)
        .map_err(|e| ApiError::from((e, validate::range_fields(request.range_params()))))?;
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
