//! `/table`: rows on the rig's curve, ranges, spacing and the row cap.

use serde_json::{Value, json};

use crate::helpers::{assert_close, fields, message_for, ok_json, problem, spawn_app};

fn rig() -> Value {
    json!({"focal_length_px": 700, "baseline": 120, "image_width": 800, "image_height": 600})
}

use crate::fixtures::with;

/// Every row satisfies Z·|d + doffs| = B·f and ΔZ = Z²·Δd/(f·B), for each kind of range,
/// each spacing, and a focal length given by FOV.
#[tokio::test]
async fn every_row_lies_on_the_curve() {
    let app = spawn_app().await;
    let fov_rig = json!({"horizontal_fov_deg": 60, "baseline": 0.12, "unit": "m",
                         "image_width": 1280, "image_height": 720, "doffs": 2.5,
                         "disparity_error_px": 0.1});
    for request in [
        with(
            rig(),
            json!({"distance_min": 500, "distance_max": 20000, "steps": 40}),
        ),
        with(
            rig(),
            json!({"disparity_min": 1, "disparity_max": 128, "steps": 40, "spacing": "log"}),
        ),
        with(
            fov_rig.clone(),
            json!({"distance_min": 0.5, "distance_max": 30, "spacing": "log"}),
        ),
        fov_rig,
    ] {
        let body = ok_json(app.post("/table", &request).await).await;
        let f = body["focal_length_px"].as_f64().unwrap();
        let b = body["baseline"].as_f64().unwrap();
        let dd = body["disparity_error_px"].as_f64().unwrap();
        let doffs = request["doffs"].as_f64().unwrap_or(0.0);
        let rows = body["rows"].as_array().unwrap();
        assert_eq!(rows.len() as u64, request["steps"].as_u64().unwrap_or(10));
        for row in rows {
            let z = row["distance"].as_f64().unwrap();
            let d = row["disparity_px"].as_f64().unwrap();
            assert_close(z * (d + doffs).abs(), f * b, "Z·|d+doffs| = B·f");
            assert_close(
                row["depth_error"].as_f64().unwrap(),
                z * z * dd / (f * b),
                "ΔZ",
            );
            assert_close(row["projection_factor"].as_f64().unwrap(), f / b, "f/B");
        }
    }
}

/// Rows come in ascending order of the ranged quantity and hit both ends.
#[tokio::test]
async fn rows_span_the_range_in_order() {
    let app = spawn_app().await;
    let body = ok_json(
        app.post(
            "/table",
            &with(
                rig(),
                json!({"distance_min": 1000, "distance_max": 5000, "steps": 5}),
            ),
        )
        .await,
    )
    .await;
    let distances: Vec<f64> = body["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["distance"].as_f64().unwrap())
        .collect();
    assert_eq!(distances, vec![1000.0, 2000.0, 3000.0, 4000.0, 5000.0]);
}

/// normalized_x is that of x_right = x_left − d, with x_left held at the request's value.
#[tokio::test]
async fn normalized_x_follows_the_right_image() {
    let app = spawn_app().await;
    let body = ok_json(
        app.get("/table?focal_length_px=700&baseline=120&image_width=800&image_height=600&disparity_min=10&disparity_max=20&steps=2&x_left=600")
            .await,
    )
    .await;
    assert_eq!(body["x_left"], 600.0);
    assert_close(
        body["rows"][0]["normalized_x"].as_f64().unwrap(),
        (590.0 - 400.0) / 400.0,
        "row 0",
    );
    assert_close(
        body["rows"][1]["normalized_x"].as_f64().unwrap(),
        (580.0 - 400.0) / 400.0,
        "row 1",
    );
}

/// More rows than the cap, both kinds of range at once, or a reversed range: 422 naming each.
#[tokio::test]
async fn bad_ranges_and_row_counts_are_named() {
    let app = spawn_app().await;
    let too_many = problem(
        app.post("/table", &with(rig(), json!({"steps": 10_001})))
            .await,
        422,
    )
    .await;
    assert_eq!(fields(&too_many), vec!["steps"]);

    let both = problem(
        app.post(
            "/table",
            &with(rig(), json!({"distance_min": 1, "disparity_max": 9})),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&both), vec!["distance_min", "disparity_max"]);

    let reversed = problem(
        app.get("/table?focal_length_px=700&baseline=120&image_width=800&image_height=600&distance_min=5000&distance_max=100")
            .await,
        422,
    )
    .await;
    assert_eq!(fields(&reversed), vec!["distance_max"]);

    let half = problem(
        app.post("/table", &with(rig(), json!({"disparity_min": 5})))
            .await,
        422,
    )
    .await;
    assert_eq!(fields(&half), vec!["disparity_max"]);

    let infinite = problem(
        app.post(
            "/table",
            &with(
                rig(),
                json!({"disparity_min": -3, "disparity_max": 10, "doffs": 2}),
            ),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&infinite), vec!["disparity_min"]);
}

/// `points` belongs to the chart, not the table: it is an unknown field here.
#[tokio::test]
async fn table_refuses_chart_members() {
    let app = spawn_app().await;
    let body = problem(
        app.post("/table", &with(rig(), json!({"points": 5}))).await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["points"]);
}

/// Asserts a CSV answer and returns its lines split into cells.
async fn csv(response: reqwest::Response) -> Vec<Vec<String>> {
    assert_eq!(response.status(), 200);
    let headers = response.headers();
    assert_eq!(
        headers["content-type"],
        "text/csv; charset=utf-8; header=present"
    );
    assert!(
        headers["content-disposition"]
            .to_str()
            .unwrap()
            .starts_with("attachment")
    );
    let text = response.text().await.unwrap();
    assert!(text.ends_with("\r\n"), "RFC 4180 line ends");
    text.lines()
        .map(|line| line.split(',').map(str::to_owned).collect())
        .collect()
}

/// The CSV has a header row naming the JSON row members, in order, and one line per JSON row
/// with the very same numbers.
#[tokio::test]
async fn csv_has_the_json_columns_and_numbers() {
    // Arrange
    let app = spawn_app().await;
    let query = "/table?focal_length_px=700&baseline=120&image_width=800&image_height=600&disparity_min=3&disparity_max=90&steps=7&spacing=log";

    // Act
    let json = ok_json(app.get(query).await).await;
    let lines = csv(app.get(&query.replacen("/table", "/table.csv", 1)).await).await;

    // Assert
    let rows = json["rows"].as_array().unwrap();
    let columns: Vec<&String> = rows[0].as_object().unwrap().keys().collect();
    assert_eq!(
        lines[0],
        [
            "distance_mm",
            "disparity_px",
            "normalized_x",
            "projection_factor_px_per_mm",
            "depth_error_mm",
            "relative_error"
        ],
        "header row: the JSON members in order, lengths with their unit"
    );
    assert_eq!(columns.len(), lines[0].len());
    assert_eq!(lines.len(), rows.len() + 1, "one line per row");
    for (line, row) in lines[1..].iter().zip(rows) {
        let relative = row["depth_error"].as_f64().unwrap() / row["distance"].as_f64().unwrap();
        assert_eq!(row["relative_error"].as_f64().unwrap(), relative);
        for (cell, column) in line.iter().zip(&columns) {
            assert_eq!(
                cell.parse::<f64>().unwrap(),
                row[column.as_str()].as_f64().unwrap(),
                "{column}"
            );
        }
    }
}

/// CSV has its own path, GET and POST, with one media type each; the JSON path also answers
/// CSV to `Accept: text/csv`, as curl users ask, and a browser's Accept gets JSON.
#[tokio::test]
async fn csv_has_its_own_path_and_accept_still_works() {
    // Arrange
    let app = spawn_app().await;
    let body = with(rig(), json!({"steps": 3}));
    let query = "focal_length_px=700&baseline=120&image_width=800&image_height=600&steps=3";

    // Act
    let by_path = csv(app.get(&format!("/table.csv?{query}")).await).await;
    let by_post_path = csv(app.post("/table.csv", &body).await).await;
    let by_accept = csv(app
        .get_with_header(&format!("/table?{query}"), "accept", "text/csv")
        .await)
    .await;
    let by_post_accept = csv(app
        .post_with_header("/table", &body, ("accept", "text/csv"))
        .await)
    .await;
    let csv_path_ignores_accept = csv(app
        .post_with_header("/table.csv", &body, ("accept", "application/json"))
        .await)
    .await;
    let browser = app
        .get_with_header(
            &format!("/table?{query}"),
            "accept",
            "text/html,application/xhtml+xml,*/*;q=0.8",
        )
        .await;

    // Assert
    assert_eq!(by_path.len(), 4, "a header and three rows");
    assert_eq!(by_path, by_post_path);
    assert_eq!(by_path, by_accept);
    assert_eq!(by_path, by_post_accept);
    assert_eq!(by_path, csv_path_ignores_accept);
    assert_eq!(browser.headers()["content-type"], "application/json");
    assert_eq!(browser.headers()["vary"], "accept");
}

/// `format`, the member CSV used to be asked with, in the body, the query or the URL of a
/// POST, is a 422 that says where CSV is now; no POST query parameter is silently ignored.
#[tokio::test]
async fn the_former_format_member_points_to_the_csv_path() {
    let app = spawn_app().await;
    let moved = "CSV has its own path now: /table.csv (or send Accept: text/csv)";
    for response in [
        app.post("/table?format=csv", &with(rig(), json!({"steps": 3})))
            .await,
        app.post("/table", &with(rig(), json!({"steps": 3, "format": "csv"})))
            .await,
        app.get(
            "/table?focal_length_px=700&baseline=120&image_width=800&image_height=600&format=csv",
        )
        .await,
    ] {
        let body = problem(response, 422).await;
        assert_eq!(fields(&body), vec!["format"]);
        assert_eq!(message_for(&body, "format"), moved);
    }
    let body = problem(app.post("/table.csv?steps=3", &rig()).await, 422).await;
    assert_eq!(fields(&body), vec!["steps"]);
    assert!(message_for(&body, "steps").contains("from the JSON body"));
}

/// A count beyond any whole number the API takes is told the member's own cap, not the
/// decoder's bound.
#[tokio::test]
async fn a_huge_count_is_told_its_own_cap() {
    let app = spawn_app().await;
    let query = "/table?focal_length_px=700&baseline=120&image_width=800&image_height=600\
                 &steps=99999999999999999999";
    let body = problem(app.get(query).await, 422).await;
    let message = message_for(&body, "steps");
    assert!(
        message.contains("from 1 to 10000 (the server's cap)"),
        "{message}"
    );
    assert!(!message.contains("2147483647"), "{message}");
    let chart = "/chart-data?focal_length_px=700&baseline=120&image_width=800\
                 &image_height=600&points=3000000000";
    let body = problem(app.get(chart).await, 422).await;
    assert!(
        message_for(&body, "points").contains("(the server's cap)"),
        "{body}"
    );
}
