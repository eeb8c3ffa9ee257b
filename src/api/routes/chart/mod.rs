//! `/chart-data`, `/chart-data.csv` and `/chart.svg`: distance and depth error against
//! disparity for a rig, as series for a chart library or a spreadsheet (GET and POST) or drawn
//! as a self-contained SVG (GET).

pub use crate::api::wire::chart as types;

use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{Axis, AxisScale, ChartPoint, ChartRequest, ChartResponse, Series};
use crate::api::csv;
use crate::api::error::{ApiError, FieldErrors};
use crate::api::extract::{JsonBody, QueryParams};
use crate::api::operation::data_operation;
use crate::api::state::AppState;
use crate::api::validate::{self, Bounds, Feature};
use crate::api::wire::openapi::{BodyErrors, QueryErrors};
use stereo_core::numbers::short;
use stereo_core::physics;

/// `GET` and `POST /chart-data` and `/chart-data.csv`, `GET /chart.svg`.
pub fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(get_chart_data, post_chart_data))
        .routes(routes!(get_chart_data_csv, post_chart_data_csv))
        .routes(routes!(get_chart_svg))
}

/// The media type of `/chart.svg`.
pub const IMAGE_SVG: &str = "image/svg+xml";

data_operation! {
    chart: ChartRequest => ChartResponse at "/chart-data", tag "chart", ok "The chart series.";
    csv chart_csv as "stereo-chart.csv" at "/chart-data.csv",
        ok "The chart series as CSV, one row per disparity.",
        moved "CSV has its own path now: /chart-data.csv (or send Accept: text/csv)";
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
    post csv post_chart_data_csv(
        summary = "Chart series as CSV",
        request_body(content = ChartRequest, examples(
            ("KITTI, measured disparity" = (summary = "A rig from /calibration, a disparity \
                                            from a matcher", value = json!({
                "focal_length_px": 721.5377, "baseline": 0.5327254, "unit": "m",
                "cx": 609.5593, "cy": 172.854, "disparity_px": 38.5,
                "disparity_min": 1, "disparity_max": 128, "spacing": "log", "scale": "log",
                "points": 20
            })))
        ))
    );
    get csv get_chart_data_csv(summary = "Chart series as CSV (query-string form)");
}

/// The series as CSV: one row per disparity, the distance and depth error in the chart's
/// unit and the relative error. (The marker is not a row; it is in the JSON answer.)
fn chart_csv(chart: &ChartResponse) -> String {
    let unit = &chart.y_axis.unit;
    let points = |name: &str| {
        chart
            .series
            .iter()
            .find(|s| s.name == name)
            .map_or(&[][..], |s| &s.points[..])
    };
    let (distance, error) = (points("distance"), points("depth_error"));
    csv::write(
        &[
            "disparity_px".to_owned(),
            csv::column("distance", unit),
            csv::column("depth_error", unit),
            "relative_error".to_owned(),
        ],
        distance
            .iter()
            .zip(error)
            .map(|(d, e)| [Some(d.x), Some(d.y), Some(e.y), Some(e.y / d.y)]),
    )
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
    QueryParams(request, mut problems): QueryParams<ChartRequest>,
) -> Result<Response, ApiError> {
    problems.reword(
        "format",
        "/chart.svg always answers SVG; /chart-data answers JSON and /chart-data.csv CSV",
    );
    let chart = chart(&state, &request, problems)?;
    Ok((
        [(header::CONTENT_TYPE, HeaderValue::from_static(IMAGE_SVG))],
        crate::api::svg::chart(&chart),
    )
        .into_response())
}

fn chart(
    state: &AppState,
    request: &ChartRequest,
    mut problems: FieldErrors,
) -> Result<ChartResponse, ApiError> {
    let params = request.rig_spec();
    let bounds = Bounds::of(&params.camera);
    let rig = validate::rig(params, &mut problems);
    let feature = Feature::new(request.x_left, request.x_right, request.disparity_px, None);
    let measured = if feature == Feature::default() {
        None
    } else {
        // The marker needs only the disparity: x_left places nothing here.
        validate::disparity(feature, bounds, &mut problems).map(|(_, d)| d)
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
                .map_err(|e| ApiError::from((e, validate::disparity_fields(&rig, &feature))))
        })
        .transpose()?;
    let mut samples = physics::sweep(&rig, range, points, spacing)
        .map_err(|e| ApiError::from((e, validate::range_fields(request.range_params()))))?;
    samples.sort_by(|a, b| a.disparity_px.total_cmp(&b.disparity_px));
    Ok(response(request, &rig, &samples, marker))
}

/// The chart of `rig`'s distance and depth error over `samples` (sorted by disparity), with
/// the measured point's `marker`.
fn response(
    request: &ChartRequest,
    rig: &physics::Rig,
    samples: &[physics::Sample],
    marker: Option<ChartPoint>,
) -> ChartResponse {
    let unit = rig.unit().symbol();
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
    ChartResponse {
        unit: request.unit.unwrap_or_default(),
        x_axis: Axis {
            label: "Disparity d (px)".to_owned(),
            unit: "px".to_owned(),
            scale: AxisScale::Linear,
        },
        y_axis: Axis {
            label: format!("Distance Z ({unit})"),
            unit: unit.to_owned(),
            scale: request.scale.unwrap_or_default(),
        },
        series: vec![
            series("distance", format!("Distance Z ({unit})"), |s| s.distance),
            series(
                "depth_error",
                format!(
                    "Depth error ΔZ ({unit}, Δd = {} px)",
                    short(rig.disparity_error_px())
                ),
                |s| s.depth_error,
            ),
        ],
        marker,
    }
}
