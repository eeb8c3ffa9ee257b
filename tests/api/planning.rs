//! `/rig` and `/baseline`: depth range, field of view, error at distances, the error budget,
//! and the baseline a budget needs, checked against the reference rig and the formulas.

use serde_json::{Value, json};

use crate::helpers::{assert_close, fields, message_for, number_at, ok_json, problem, spawn_app};

/// The reference: f = 424 px, B = 50 mm, a search up to 126 px, Δd = 0.08 px.
fn reference_rig() -> Value {
    json!({"focal_length_px": 424, "baseline": 50, "unit": "mm",
           "image_width": 848, "image_height": 480, "disparity_error_px": 0.08,
           "max_disparity_px": 126})
}

/// The reference rig sees from 168.25 mm, and its RMS error at 2 m is 15.09 mm, over POST and
/// GET alike; FOV, fb and the far limit follow from f, B and the default min disparity (Δd).
#[tokio::test]
async fn reference_rig_range_and_error() {
    // Arrange
    let app = spawn_app().await;
    let mut request = reference_rig();
    request["at_distances"] = json!([2000, 500]);

    // Act
    let post = ok_json(app.post("/rig", &request).await).await;
    let get = ok_json(
        app.get("/rig?focal_length_px=424&baseline=50&image_width=848&image_height=480&disparity_error_px=0.08&max_disparity_px=126&at_distances=2000,500")
            .await,
    )
    .await;

    // Assert
    assert_eq!(post, get, "GET and POST answer alike");
    assert!((number_at(&post, "min_distance") - 168.25).abs() < 0.005);
    assert_close(
        number_at(&post, "min_distance"),
        424.0 * 50.0 / 126.0,
        "f·B/max",
    );
    assert_close(
        number_at(&post, "max_distance"),
        424.0 * 50.0 / 0.08,
        "f·B/Δd",
    );
    assert_close(
        number_at(&post, "min_disparity_px"),
        0.08,
        "min defaults to Δd",
    );
    assert_close(number_at(&post, "fb"), 21_200.0, "f·B");
    assert_close(
        number_at(&post, "horizontal_fov_deg"),
        90.0,
        "2·atan(424/424)",
    );
    assert_close(
        number_at(&post, "vertical_fov_deg"),
        (2.0 * (240.0_f64 / 424.0).atan()).to_degrees(),
        "vertical FOV",
    );
    let at = post["at_distances"].as_array().unwrap();
    assert_eq!(at.len(), 2, "one entry per requested distance, in order");
    assert_eq!(at[0]["distance"], 2000.0);
    assert!((number_at(&at[0], "depth_error") - 15.09).abs() < 0.005);
    assert_close(number_at(&at[0], "disparity_px"), 10.6, "f·B/Z");
    assert_close(
        number_at(&at[0], "relative_error_pct"),
        100.0 * 15.094_339_622_641_51 / 2000.0,
        "percent",
    );
    assert_eq!(at[0]["in_range"], true);
    assert_close(
        number_at(&at[1], "depth_error"),
        500.0 * 500.0 * 0.08 / 21_200.0,
        "ΔZ",
    );
    assert!(post.get("error_budget").is_none(), "no budget asked for");
}

/// With a budget of 2 %, the answer gives Z = r·f·B/Δd and says it in words; the three cases
/// (inside the range, beyond it, before it) each read correctly.
#[tokio::test]
async fn error_budget_distance_and_summary() {
    let app = spawn_app().await;
    let mut request = reference_rig();
    request["max_relative_error"] = json!(0.02);
    let body = ok_json(app.post("/rig", &request).await).await;
    let budget = &body["error_budget"];
    assert_close(
        number_at(budget, "distance"),
        0.02 * 21_200.0 / 0.08,
        "r·f·B/Δd",
    );
    assert_eq!(
        budget["summary"],
        "the relative depth error is below 2 % from 168.254 mm up to 5300 mm"
    );

    // A search that stops at 10 px cannot see as far as the budget reaches.
    request["min_disparity_px"] = json!(10);
    let body = ok_json(app.post("/rig", &request).await).await;
    let summary = body["error_budget"]["summary"].as_str().unwrap();
    assert!(summary.starts_with("the relative depth error stays below 2 % across the whole range"));

    // A coarse matcher breaks a 0.1 % budget everywhere.
    request["max_relative_error"] = json!(0.001);
    request["disparity_error_px"] = json!(1);
    let body = ok_json(app.post("/rig", &request).await).await;
    let summary = body["error_budget"]["summary"].as_str().unwrap();
    assert!(summary.starts_with("the relative depth error exceeds 0.1 % everywhere"));
}

/// A calibration's σ shrinks the budget's reach, Z = √(r² − c²)·f·B/Δd with c = σ_f/f here;
/// a budget the calibration alone exceeds is a 422 that says so.
#[tokio::test]
async fn error_budget_counts_the_calibration() {
    let app = spawn_app().await;
    let mut request = reference_rig();
    let f = request["focal_length_px"].as_f64().unwrap();
    request["max_relative_error"] = json!(0.02);
    request["focal_length_std_px"] = json!(0.012 * f);
    let body = ok_json(app.post("/rig", &request).await).await;
    assert_close(
        number_at(&body["error_budget"], "distance"),
        0.016 * 21_200.0 / 0.08,
        "√(0.02² − 0.012²)·f·B/Δd",
    );
    request["focal_length_std_px"] = json!(0.03 * f);
    let body = problem(app.post("/rig", &request).await, 422).await;
    assert_eq!(fields(&body), vec!["max_relative_error"]);
    assert!(message_for(&body, "max_relative_error").contains("calibration alone"));
}

/// doffs is honoured in both ends of the range, and a distance beyond the range is flagged.
#[tokio::test]
async fn doffs_shifts_the_range() {
    let app = spawn_app().await;
    let mut request = reference_rig();
    request["doffs"] = json!(10);
    request["min_disparity_px"] = json!(2);
    request["at_distances"] = json!([100_000]);
    let body = ok_json(app.post("/rig", &request).await).await;
    assert_close(
        number_at(&body, "min_distance"),
        21_200.0 / 136.0,
        "f·B/(max+doffs)",
    );
    assert_close(
        number_at(&body, "max_distance"),
        21_200.0 / 12.0,
        "f·B/(min+doffs)",
    );
    assert_eq!(body["at_distances"][0]["in_range"], false);
    assert_close(
        number_at(&body["at_distances"][0], "disparity_px"),
        21_200.0 / 100_000.0 - 10.0,
        "raw disparity = f·B/Z − doffs",
    );
}

/// Bad planning input is a 422 naming every field: a missing search, an inverted one, a bad
/// distance by its index, a budget given as a percentage, and Δd = 0 with no min disparity.
#[tokio::test]
async fn bad_rig_requests_are_named() {
    let app = spawn_app().await;
    let mut request = reference_rig();
    request.as_object_mut().unwrap().remove("max_disparity_px");
    request["at_distances"] = json!([1000, -5, 0]);
    request["max_relative_error"] = json!(2);
    let body = problem(app.post("/rig", &request).await, 422).await;
    assert_eq!(
        fields(&body),
        vec![
            "max_disparity_px",
            "at_distances[1]",
            "at_distances[2]",
            "max_relative_error"
        ]
    );
    assert!(message_for(&body, "max_relative_error").contains("0.02 means 2 %"));

    let mut inverted = reference_rig();
    inverted["min_disparity_px"] = json!(200);
    let body = problem(app.post("/rig", &inverted).await, 422).await;
    assert_eq!(fields(&body), vec!["max_disparity_px"]);

    let mut exact = reference_rig();
    exact["disparity_error_px"] = json!(0);
    let body = problem(app.post("/rig", &exact).await, 422).await;
    assert_eq!(fields(&body), vec!["min_disparity_px"]);

    let mut past_infinity = reference_rig();
    past_infinity["doffs"] = json!(-5);
    past_infinity["min_disparity_px"] = json!(2);
    let body = problem(app.post("/rig", &past_infinity).await, 422).await;
    assert_eq!(fields(&body), vec!["min_disparity_px"]);
    assert!(message_for(&body, "min_disparity_px").contains("at infinity"));

    let body = problem(
        app.get("/rig?focal_length_mm=4&baseline=50&image_width=848&image_height=480&max_disparity_px=64&at_distances=1,x")
            .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["at_distances", "focal_length_mm"]);
}

/// The baseline for 0.5 % at 5 m with f = 1000 px and Δd = 0.25 px is 250 mm, whether the
/// budget is relative or absolute; a /distance call with that rig gets exactly that error back.
#[tokio::test]
async fn baseline_meets_the_budget() {
    // Arrange
    let app = spawn_app().await;
    let relative = json!({"focal_length_px": 1000, "image_width": 1280, "image_height": 720,
                          "disparity_error_px": 0.25, "target_distance": 5000,
                          "max_relative_error": 0.005, "max_disparity_px": 128});
    let mut absolute = relative.clone();
    absolute
        .as_object_mut()
        .unwrap()
        .remove("max_relative_error");
    absolute["max_depth_error"] = json!(25);

    // Act
    let by_fraction = ok_json(app.post("/baseline", &relative).await).await;
    let by_length = ok_json(app.post("/baseline", &absolute).await).await;

    // Assert
    assert_eq!(by_fraction, by_length);
    assert_close(number_at(&by_fraction, "baseline"), 250.0, "Z²·Δd/(f·ΔZ)");
    assert_close(number_at(&by_fraction, "max_depth_error"), 25.0, "r·Z");
    assert_close(
        number_at(&by_fraction, "disparity_at_target_px"),
        50.0,
        "f·B/Z",
    );
    assert_close(
        number_at(&by_fraction, "min_distance"),
        250_000.0 / 128.0,
        "f·B/max",
    );
    assert_eq!(
        by_fraction["formula"],
        "B = Z²·Δd / (f·ΔZ) = (5000 mm)² × 0.25 px / (1000 px × 25 mm) = 250 mm"
    );
    // Round trip: a feature at 5 m seen by this rig has a 25 mm depth error.
    let check = ok_json(
        app.post(
            "/distance",
            &json!({"focal_length_px": 1000, "baseline": 250, "image_width": 1280,
                    "image_height": 720, "disparity_error_px": 0.25,
                    "x_left": 690, "x_right": 640}),
        )
        .await,
    )
    .await;
    assert_close(number_at(&check, "distance"), 5000.0, "Z");
    assert_close(number_at(&check, "depth_error"), 25.0, "ΔZ at the target");
}

/// The focal length may be given any way, e.g. by FOV, and the unit carries through GET.
#[tokio::test]
async fn baseline_over_get_with_fov_in_metres() {
    let app = spawn_app().await;
    let body = ok_json(
        app.get("/baseline?horizontal_fov_deg=90&image_width=1280&image_height=720&unit=m&target_distance=10&max_depth_error=0.1")
            .await,
    )
    .await;
    assert_eq!(body["unit"], "m");
    assert_close(number_at(&body, "focal_length_px"), 640.0, "(W/2)/tan(45°)");
    assert_close(
        number_at(&body, "baseline"),
        100.0 * 0.5 / (640.0 * 0.1),
        "B",
    );
    assert!(body.get("min_distance").is_none(), "no search given");
}

/// Both budgets, none, a zero Δd, or f in mm alone: each a 422 naming the fields.
#[tokio::test]
async fn bad_baseline_requests_are_named() {
    let app = spawn_app().await;
    let camera = json!({"focal_length_px": 1000, "image_width": 1280, "image_height": 720,
                        "target_distance": 5000});
    let mut both = camera.clone();
    both["max_depth_error"] = json!(25);
    both["max_relative_error"] = json!(0.005);
    let body = problem(app.post("/baseline", &both).await, 422).await;
    assert_eq!(fields(&body), vec!["max_depth_error", "max_relative_error"]);

    let body = problem(app.post("/baseline", &camera).await, 422).await;
    assert_eq!(fields(&body), vec!["max_depth_error"]);

    let mut exact = camera.clone();
    exact["max_depth_error"] = json!(25);
    exact["disparity_error_px"] = json!(0);
    let body = problem(app.post("/baseline", &exact).await, 422).await;
    assert_eq!(fields(&body), vec!["disparity_error_px"]);

    let body = problem(
        app.post(
            "/baseline",
            &json!({"focal_length_mm": 4, "image_width": 1280, "image_height": 720,
                    "target_distance": 5000, "max_depth_error": 25, "baseline": 100}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["baseline", "focal_length_mm"]);
    assert!(message_for(&body, "focal_length_mm").contains("not a length"));
}

/// `at_distances` repeated, as generated clients send a list despite `explode: false`, is
/// the same request as the comma-separated form, items in order.
#[tokio::test]
async fn repeated_list_parameters_are_one_list() {
    // Arrange
    let app = spawn_app().await;
    let rig = "/rig?focal_length_px=424&baseline=50&image_width=848&image_height=480\
               &disparity_error_px=0.08&max_disparity_px=126";

    // Act
    let commas = ok_json(app.get(&format!("{rig}&at_distances=500,1000,2000")).await).await;
    let repeated = ok_json(
        app.get(&format!(
            "{rig}&at_distances=500&at_distances=1000&at_distances=2000"
        ))
        .await,
    )
    .await;
    let mixed = ok_json(
        app.get(&format!("{rig}&at_distances=500,1000&at_distances=2000"))
            .await,
    )
    .await;

    // Assert
    assert_eq!(repeated, commas);
    assert_eq!(mixed, commas);
    let distances: Vec<f64> = repeated["at_distances"]
        .as_array()
        .unwrap()
        .iter()
        .map(|at| number_at(at, "distance"))
        .collect();
    assert_eq!(distances, [500.0, 1000.0, 2000.0]);
}
