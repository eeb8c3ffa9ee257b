//! `/chart-data`: series on the rig's curve, axis labels, the marker and the point cap.

use serde_json::json;

use crate::helpers::{assert_close, fields, ok_json, problem, spawn_app};

use crate::fixtures::seed_rig;

/// Both series lie on the curve, share ascending x, and carry labelled axes; the measured
/// point is the marker.
#[tokio::test]
async fn series_lie_on_the_curve_with_marker() {
    // Arrange
    let app = spawn_app().await;
    let mut request = seed_rig();
    request["x_left"] = json!(400);
    request["x_right"] = json!(350);
    request["points"] = json!(50);
    // Act
    let body = ok_json(app.post("/chart-data", &request).await).await;
    // Assert
    assert_eq!(body["x_axis"]["label"], "Disparity d (px)");
    assert_eq!(body["y_axis"]["label"], "Distance Z (mm)");
    assert_eq!(body["marker"], json!({"x": 50.0, "y": 105.0}));
    let series = body["series"].as_array().unwrap();
    assert_eq!(series[0]["name"], "distance");
    assert_eq!(series[1]["name"], "depth_error");
    let distance = series[0]["points"].as_array().unwrap();
    let error = series[1]["points"].as_array().unwrap();
    assert_eq!(distance.len(), 50);
    assert_eq!(error.len(), 50);
    let mut last_x = f64::NEG_INFINITY;
    for (p, e) in distance.iter().zip(error) {
        let (d, z) = (p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap());
        assert!(d > last_x, "x ascends");
        last_x = d;
        assert_close(z * d.abs(), 35.0 * 150.0, "Z·|d| = B·f");
        assert_eq!(e["x"], p["x"]);
        assert_close(e["y"].as_f64().unwrap(), z * z * 0.5 / (35.0 * 150.0), "ΔZ");
    }
    // The default range takes in the measured disparity.
    assert!(distance[0]["x"].as_f64().unwrap() <= 50.0 && last_x >= 50.0);
}

/// A distance range over GET, with doffs: points are in ascending disparity and on the curve.
#[tokio::test]
async fn distance_range_over_get_with_doffs() {
    let app = spawn_app().await;
    let body = ok_json(
        app.get("/chart-data?focal_length_px=1000&baseline=200&doffs=50&image_width=1000&image_height=800&distance_min=1000&distance_max=4000&points=7&spacing=log")
            .await,
    )
    .await;
    let points = body["series"][0]["points"].as_array().unwrap();
    assert_eq!(points.len(), 7);
    assert_close(
        points[0]["y"].as_f64().unwrap(),
        4000.0,
        "farthest first (smallest d)",
    );
    assert_close(points[6]["y"].as_f64().unwrap(), 1000.0, "nearest last");
    for p in points {
        let (d, z) = (p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap());
        assert_close(z * (d + 50.0).abs(), 200_000.0, "Z·|d+doffs| = B·f");
    }
    assert!(
        body.get("marker").is_none(),
        "no marker without a measurement"
    );
}

/// Half a measurement, too many points, or `steps` (a table member) are 422s naming them.
#[tokio::test]
async fn bad_chart_requests_are_named() {
    let app = spawn_app().await;
    let mut half = seed_rig();
    half["x_left"] = json!(400);
    let body = problem(app.post("/chart-data", &half).await, 422).await;
    assert_eq!(fields(&body), vec!["x_right"]);

    let mut many = seed_rig();
    many["points"] = json!(10_001);
    let body = problem(app.post("/chart-data", &many).await, 422).await;
    assert_eq!(fields(&body), vec!["points"]);

    let mut steps = seed_rig();
    steps["steps"] = json!(10);
    let body = problem(app.post("/chart-data", &steps).await, 422).await;
    assert_eq!(fields(&body), vec!["steps"]);
}
