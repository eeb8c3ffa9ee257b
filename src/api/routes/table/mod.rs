//! `/table` and `/table.csv`: the sample table of distance against disparity for a rig (GET
//! and POST), as JSON or CSV.

pub use crate::api::wire::table as types;

use axum::extract::State;
use axum::http::{HeaderMap, header};
use axum::response::Response;
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{TableRequest, TableResponse, TableRow};
use crate::api::csv;
use crate::api::error::{ApiError, FieldErrors};
use crate::api::extract::{JsonBody, QueryParams};
use crate::api::operation::data_operation;
use crate::api::state::AppState;
use crate::api::validate::{self, Bounds};
use crate::api::wire::openapi::{BodyErrors, QueryErrors};
use stereo_core::physics;

/// `GET` and `POST /table` and `/table.csv`.
pub fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(get_table, post_table))
        .routes(routes!(get_table_csv, post_table_csv))
}

data_operation! {
    table: TableRequest => TableResponse at "/table", tag "table", ok "The sample table.";
    csv table_csv as "stereo-table.csv" at "/table.csv", ok "The sample table as CSV.",
        moved "CSV has its own path now: /table.csv (or send Accept: text/csv)";
    post post_table(
        summary = "Sample table of distance against disparity for a rig",
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
            })))
        ))
    );
    get get_table(summary = "Sample table (query-string form of POST /table)");
    post csv post_table_csv(
        summary = "Sample table as CSV",
        request_body(content = TableRequest, examples(
            ("f in mm" = (summary = "f in mm with a sensor width", value = json!({
                "focal_length_mm": 4, "sensor_width_mm": 6.4, "baseline": 120,
                "image_width": 1280, "image_height": 720, "steps": 5
            })))
        ))
    );
    get csv get_table_csv(summary = "Sample table as CSV (query-string form)");
}

/// The header row: the members of a JSON [`TableRow`] in the same order, each length with
/// its unit (`distance_mm`) and the projection factor in pixels per unit; `normalized_x` only
/// when the rows have it.
fn table_columns(table: &TableResponse) -> Vec<String> {
    let unit = stereo_core::physics::LengthUnit::from(table.unit).symbol();
    let mut columns = vec![csv::column("distance", unit), "disparity_px".to_owned()];
    if table.rows.first().is_some_and(|r| r.normalized_x.is_some()) {
        columns.push("normalized_x".to_owned());
    }
    columns.extend([
        csv::column("projection_factor_px_per", unit),
        csv::column("depth_error", unit),
        "relative_error".to_owned(),
    ]);
    columns
}

/// The table as CSV.
fn table_csv(table: &TableResponse) -> String {
    let with_x = table.rows.first().is_some_and(|r| r.normalized_x.is_some());
    csv::write(
        &table_columns(table),
        table.rows.iter().map(|r| {
            [Some(r.distance), Some(r.disparity_px)]
                .into_iter()
                .chain(with_x.then_some(r.normalized_x))
                .chain([
                    Some(r.projection_factor),
                    Some(r.depth_error),
                    Some(r.relative_error),
                ])
        }),
    )
}

fn table(
    state: &AppState,
    request: &TableRequest,
    mut problems: FieldErrors,
) -> Result<TableResponse, ApiError> {
    let params = request.rig_spec();
    let bounds = Bounds::of(&params.camera);
    let rig = validate::rig(params, &mut problems);
    let range = validate::range(&request.range_params(), rig.as_ref(), None, &mut problems);
    let steps = problems.count("steps", request.steps, 10, 1, state.limits.table_rows);
    let x_left = match request.x_left {
        Some(x) => validate::x_coordinate("x_left", x, bounds, &mut problems),
        None => rig.map(|r| r.image_width().map_or(r.cx().unwrap_or(0.0), |w| w / 2.0)),
    };
    let (rig, ((range, spacing), (steps, x_left))) =
        problems.finish(rig.zip(range.zip(steps.zip(x_left))))?;
    let rows = physics::table(&rig, range, steps, spacing, x_left)
        .map_err(|e| ApiError::from((e, validate::range_fields(request.range_params()))))?;
    Ok(TableResponse {
        unit: request.unit.unwrap_or_default(),
        focal_length_px: rig.focal_px(),
        baseline: rig.baseline(),
        disparity_error_px: rig.disparity_error_px(),
        x_left,
        rows: rows
            .into_iter()
            .map(|r| TableRow {
                distance: r.distance,
                disparity_px: r.disparity_px,
                normalized_x: r.normalized_x,
                projection_factor: r.projection_factor,
                depth_error: r.depth_error,
                relative_error: r.depth_error / r.distance,
            })
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::wire::params::Unit;

    /// The header names the JSON members with their units, and each number is the JSON's
    /// number; `normalized_x` is left out when the image width was not given.
    #[test]
    fn csv_rows() {
        let row = TableRow {
            distance: 105.0,
            disparity_px: 50.0,
            normalized_x: Some(-0.125),
            projection_factor: 0.23333333333333334,
            depth_error: 1.05,
            relative_error: 0.01,
        };
        let mut table = TableResponse {
            unit: Unit::Mm,
            focal_length_px: 35.0,
            baseline: 150.0,
            disparity_error_px: 0.5,
            x_left: 400.0,
            rows: vec![row],
        };
        assert_eq!(
            table_csv(&table),
            "distance_mm,disparity_px,normalized_x,projection_factor_px_per_mm,depth_error_mm,\
             relative_error\r\n105.0,50.0,-0.125,0.23333333333333334,1.05,0.01\r\n"
        );
        let json = serde_json::to_value(row).unwrap();
        let keys: Vec<&str> = json
            .as_object()
            .unwrap()
            .keys()
            .map(String::as_str)
            .collect();
        let columns = table_columns(&table);
        assert_eq!(keys.len(), columns.len());
        for (key, column) in keys.iter().zip(&columns) {
            assert!(column.starts_with(key), "{column} is not {key} with a unit");
        }
        table.unit = Unit::M;
        table.rows[0].normalized_x = None;
        assert_eq!(
            table_columns(&table),
            [
                "distance_m",
                "disparity_px",
                "projection_factor_px_per_m",
                "depth_error_m",
                "relative_error"
            ]
        );
    }
}
