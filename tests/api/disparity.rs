//! What a matcher's user sends: a disparity instead of two x coordinates, a rig without an
//! image size, a vertical focal length; and what a robot needs back: the straight-line range
//! beside the depth. Also the CSV and log-axis forms of the chart.

use serde_json::{Value, json};

use crate::fixtures::with;
use crate::helpers::{assert_close, fields, message_for, number_at, ok_json, problem, spawn_app};

/// The KITTI colour rig as `/calibration` answers it: f in px with cx, cy and no image size.
fn kitti_rig() -> Value {
    json!({"focal_length_px": 721.5377, "baseline": 0.5327254, "unit": "m",
           "cx": 609.5593, "cy": 172.854, "doffs": 0})
}

/// `disparity_px` gives the same distance as the x pair with that difference, and `x_left`
/// (default `cx`) only places the point.
#[tokio::test]
async fn disparity_replaces_x_right() {
    // Arrange
    let app = spawn_app().await;
    let pair = with(
        kitti_rig(),
        json!({"x_left": 700, "x_right": 661.5, "y": 200}),
    );
    let disparity = with(
        kitti_rig(),
        json!({"x_left": 700, "disparity_px": 38.5, "y": 200}),
    );
    let centred = with(kitti_rig(), json!({"disparity_px": 38.5}));

    // Act
    let pair = ok_json(app.post("/distance", &pair).await).await;
    let disparity = ok_json(app.post("/distance", &disparity).await).await;
    let centred = ok_json(app.get_with("/distance", &centred).await).await;

    // Assert: Z = 721.5377 × 0.5327254 / 38.5 = 9.98397 m.
    let z = 721.5377 * 0.5327254 / 38.5;
    for answer in [&pair, &disparity, &centred] {
        assert_close(number_at(answer, "distance"), z, "distance");
        assert_eq!(number_at(answer, "disparity_px"), 38.5);
    }
    assert_eq!(pair["point"], disparity["point"]);
    // At the principal point the point is on the optical axis: range = depth.
    assert_eq!(number_at(&centred, "point.x"), 0.0);
    assert_eq!(number_at(&centred, "point.y"), 0.0);
    assert_eq!(
        number_at(&centred, "range"),
        number_at(&centred, "distance")
    );
}

/// `x_right` and `disparity_px` together is a 422 naming both; neither names `x_right`.
#[tokio::test]
async fn x_right_and_disparity_exclude_each_other() {
    let app = spawn_app().await;
    let both = with(
        kitti_rig(),
        json!({"x_left": 700, "x_right": 661.5, "disparity_px": 38.5}),
    );
    let body = problem(app.post("/distance", &both).await, 422).await;
    assert_eq!(fields(&body), ["x_right", "disparity_px"]);
    assert!(message_for(&body, "disparity_px").contains("not both"));

    let neither = with(kitti_rig(), json!({"x_left": 700}));
    let body = problem(app.post("/distance", &neither).await, 422).await;
    assert_eq!(fields(&body), ["x_right"]);
    assert!(message_for(&body, "x_right").contains("disparity_px"));

    let no_left = with(kitti_rig(), json!({"x_right": 661.5}));
    let body = problem(app.get_with("/distance", &no_left).await, 422).await;
    assert_eq!(fields(&body), ["x_left"]);
}

/// `range` is √(X² + Y² + Z²): 5 m deep, 3 m right and 0 m down is a range of √34 m.
#[tokio::test]
async fn range_is_the_straight_line_to_the_point() {
    // Arrange: f = 1000 px, B = 0.1 m, d = 20 px → Z = 5 m; x − cx = 600 px → X = 3 m.
    let app = spawn_app().await;
    let request = json!({"focal_length_px": 1000, "baseline": 0.1, "unit": "m",
                         "cx": 640, "cy": 360, "x_left": 1240, "disparity_px": 20, "y": 360});

    // Act
    let body = ok_json(app.post("/distance", &request).await).await;

    // Assert
    assert_close(number_at(&body, "distance"), 5.0, "depth");
    assert_close(number_at(&body, "point.x"), 3.0, "X");
    assert_close(number_at(&body, "range"), 34f64.sqrt(), "range");
    assert!(
        body.get("normalized_x").is_none(),
        "no image width, no normalized_x"
    );
}

/// Y uses `focal_length_y_px`: the same 100 px below cy is half as far down with fy = 2·fx.
#[tokio::test]
async fn vertical_focal_length_places_y() {
    let app = spawn_app().await;
    let base = json!({"focal_length_px": 1000, "baseline": 100, "cx": 500, "cy": 400,
                      "x_left": 500, "disparity_px": 100, "y": 500});
    let square = ok_json(app.post("/distance", &base).await).await;
    let tall = ok_json(
        app.post(
            "/distance",
            &with(base.clone(), json!({"focal_length_y_px": 2000})),
        )
        .await,
    )
    .await;
    assert_close(number_at(&square, "point.y"), 100.0, "Y with fy = fx");
    assert_close(number_at(&tall, "point.y"), 50.0, "Y with fy = 2 fx");
    assert_eq!(square["distance"], tall["distance"]);

    let bad = with(base, json!({"focal_length_y_px": -3}));
    let body = problem(app.post("/distance", &bad).await, 422).await;
    assert_eq!(fields(&body), ["focal_length_y_px"]);
}

/// The image size is needed only by the forms that use it: a field of view, a sensor width,
/// a default principal point.
#[tokio::test]
async fn image_size_is_required_only_where_it_is_used() {
    let app = spawn_app().await;
    let fov = json!({"horizontal_fov_deg": 90, "baseline": 65, "cx": 400, "cy": 300,
                     "x_left": 420, "x_right": 400});
    let body = problem(app.post("/distance", &fov).await, 422).await;
    assert_eq!(fields(&body), ["image_width"]);
    assert!(message_for(&body, "image_width").contains("horizontal_fov_deg"));

    let sensor = json!({"focal_length_mm": 4, "sensor_width_mm": 6.4, "baseline": 120,
                        "cx": 640, "cy": 360, "x_left": 700, "x_right": 650});
    let body = problem(app.post("/distance", &sensor).await, 422).await;
    assert_eq!(fields(&body), ["image_width"]);

    // Without cy (or the image height) the depth is answered; the point and the range, which
    // need the principal point, are left out and a warning says so.
    let no_cy = json!({"focal_length_px": 700, "baseline": 120, "cx": 640,
                       "x_left": 700, "x_right": 650});
    let body = ok_json(app.post("/distance", &no_cy).await).await;
    assert_close(
        number_at(&body, "distance"),
        700.0 * 120.0 / 50.0,
        "distance",
    );
    assert!(
        body.get("point").is_none() && body.get("range").is_none(),
        "{body}"
    );
    assert_eq!(body["warnings"][0]["code"], "no_principal_point");

    // The pixel pitch needs no width: f = 3.6 mm · 1000 / 3 µm = 1200 px.
    let pitch = json!({"focal_length_mm": 3.6, "pixel_size_um": 3, "baseline": 0.12,
                       "unit": "m", "cx": 960, "cy": 540, "disparity_px": 60});
    let body = ok_json(app.post("/distance", &pitch).await).await;
    assert_close(number_at(&body, "distance"), 2.4, "distance");

    // /rig answers without the fields of view when it has no image size.
    let rig = ok_json(
        app.get("/rig?focal_length_px=424&baseline=50&max_disparity_px=64")
            .await,
    )
    .await;
    assert!(rig.get("horizontal_fov_deg").is_none());
    assert!(rig.get("vertical_fov_deg").is_none());
    assert_close(number_at(&rig, "fb"), 21_200.0, "f·B");
}

/// Batch points take `disparity_px` too; a point with both it and `x_right` refuses the batch.
#[tokio::test]
async fn batch_points_take_a_disparity() {
    let app = spawn_app().await;
    let batch = json!({"rig": kitti_rig(), "points": [
        {"disparity_px": 38.5}, {"x_left": 700, "x_right": 661.5}, {"x_left": 10, "disparity_px": 0}
    ]});
    let body = ok_json(app.post("/distance", &batch).await).await;
    assert_eq!(body["succeeded"], 2);
    assert_eq!(
        body["results"][0]["distance"],
        body["results"][1]["distance"]
    );
    assert_eq!(
        body["results"][2]["errors"][0]["field"],
        "points[2].disparity_px"
    );

    let both = json!({"rig": kitti_rig(), "points": [
        {"disparity_px": 38.5}, {"x_left": 700, "x_right": 661.5, "disparity_px": 38.5}
    ]});
    let body = problem(app.post("/distance", &both).await, 422).await;
    assert_eq!(
        fields(&body),
        ["points[1].x_right", "points[1].disparity_px"]
    );
}

/// The chart marks a disparity, answers CSV with units in the header, and draws a log axis.
#[tokio::test]
async fn chart_takes_a_disparity_and_answers_csv_and_log() {
    // Arrange
    let app = spawn_app().await;
    let query = "/chart-data?focal_length_px=721.5377&baseline=0.5327254&unit=m&cx=609.5593\
                 &cy=172.854&disparity_px=38.5&disparity_min=1&disparity_max=128&points=5";

    // Act
    let json = ok_json(app.get(query).await).await;
    let csv = app
        .get(&query.replacen("/chart-data", "/chart-data.csv", 1))
        .await;
    let svg = app
        .get(&format!("/chart.svg{}&scale=log", &query[11..]))
        .await;

    // Assert
    assert_close(
        number_at(&json, "marker.y"),
        721.5377 * 0.5327254 / 38.5,
        "marker",
    );
    assert_eq!(json["y_axis"]["scale"], "linear");
    assert!(
        csv.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/csv")
    );
    let text = csv.text().await.unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[0],
        "disparity_px,distance_m,depth_error_m,relative_error"
    );
    assert_eq!(lines.len(), 6);
    let first: Vec<f64> = lines[1].split(',').map(|c| c.parse().unwrap()).collect();
    assert_eq!(first[0], 1.0);
    assert_close(first[1], 721.5377 * 0.5327254, "distance at d = 1 px");
    assert_close(first[3], first[2] / first[1], "relative error");
    assert_eq!(svg.status(), 200);
    let svg = svg.text().await.unwrap();
    assert!(svg.contains(r#"data-y-scale="log""#));
    // 2.99 m to 384 m on whole decades: 1 m to 1000 m.
    assert!(svg.contains(r#"data-y-min="1" data-y-max="1000""#), "{svg}");

    let body = problem(
        app.get(&format!("/chart.svg{}&format=csv", &query[11..]))
            .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), ["format"]);
    assert!(message_for(&body, "format").contains("/chart.svg always answers SVG"));
}

/// The depth needs only f, B and d: without the image size or a principal point `/distance`
/// answers Z = 700 × 120 / 20 = 4200 mm, leaves out the point, the range and the normalized x,
/// and says why in a warning.
#[tokio::test]
async fn depth_needs_no_image_size() {
    let app = spawn_app().await;
    let body = ok_json(
        app.get("/distance?focal_length_px=700&baseline=120&disparity_px=20")
            .await,
    )
    .await;
    assert_close(number_at(&body, "distance"), 4200.0, "distance");
    assert_close(
        number_at(&body, "depth_error"),
        4200.0 * 4200.0 * 0.5 / 84_000.0,
        "error",
    );
    for absent in ["point", "range", "normalized_x"] {
        assert!(body.get(absent).is_none(), "{absent} in {body}");
    }
    assert_eq!(body["warnings"][0]["code"], "no_principal_point");
    assert!(
        body["warnings"][0]["message"]
            .as_str()
            .unwrap()
            .contains("give cx and cy")
    );
}
