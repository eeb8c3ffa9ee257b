//! `/distance`: the reference cases over POST and GET, and the physics as a user sees it.
//!
//! The reference numbers are those of `shared/vectors/distance.json` (worked by hand from the
//! formulas), carried here so that a clone without `shared/` still checks them; when the shared
//! file is present beside the project it is run as well.

use serde_json::{Value, json};

use crate::helpers::{
    TestApp, assert_close, fields, message_for, number_at, ok_json, problem, spawn_app,
};

/// One reference case in the shared vector format.
fn case(name: &str, request: Value, expect: Value) -> Value {
    json!({"name": name, "request": request, "expect": expect})
}

fn error_case(name: &str, request: Value, status: u16, fields: &[&str]) -> Value {
    json!({"name": name, "request": request, "expect_error": {"status": status, "fields": fields}})
}

/// The reference cases: successes first, then errors.
fn reference_cases() -> Vec<Value> {
    vec![
        json!({
            "name": "seed example 1 (robot), f read as pixels",
            "request": {"focal_length_px": 35, "baseline": 150, "unit": "mm", "x_left": 400,
                        "x_right": 350, "image_width": 800, "image_height": 600},
            "expect": {"distance": 105, "unit": "mm", "distance_m": 0.105, "disparity_px": 50,
                       "focal_length_px": 35, "normalized_x": 0,
                       "projection_factor": 0.23333333333333334}
        }),
        json!({
            "name": "seed example 2 (inspection), negative disparity warns",
            "request": {"focal_length_px": 12, "baseline": 50, "unit": "mm", "x_left": 180,
                        "x_right": 195, "image_width": 640, "image_height": 480},
            "expect": {"distance": 40, "disparity_px": -15, "normalized_x": -0.4375,
                       "projection_factor": 0.24},
            "expect_nonempty": ["warnings"]
        }),
        case(
            "f in mm with sensor width: 4 * 1280 / 6.4 = 800 px",
            json!({"focal_length_mm": 4, "sensor_width_mm": 6.4, "baseline": 120, "unit": "mm",
                   "x_left": 700, "x_right": 660, "image_width": 1280, "image_height": 720}),
            json!({"focal_length_px": 800, "disparity_px": 40, "distance": 2400}),
        ),
        case(
            "f in mm with pixel pitch: 6 mm / 3 um = 2000 px, metres in and out",
            json!({"focal_length_mm": 6, "pixel_size_um": 3, "baseline": 0.1, "unit": "m",
                   "x_left": 1000, "x_right": 975, "image_width": 1920, "image_height": 1080}),
            json!({"focal_length_px": 2000, "distance": 8, "distance_m": 8, "unit": "m"}),
        ),
        case(
            "horizontal FOV: 640 / tan(45 deg) = 640 px",
            json!({"horizontal_fov_deg": 90, "baseline": 7.5, "unit": "cm", "x_left": 640,
                   "x_right": 608, "image_width": 1280, "image_height": 800}),
            json!({"focal_length_px": 640, "distance": 150, "distance_m": 1.5}),
        ),
        case(
            "doffs: Z = B f / (d + doffs)",
            json!({"focal_length_px": 1000, "baseline": 200, "unit": "mm", "x_left": 500,
                   "x_right": 450, "doffs": 50, "image_width": 1000, "image_height": 800}),
            json!({"disparity_px": 50, "distance": 2000}),
        ),
        case(
            "depth error: 1e8 * 0.5 / 1e5 = 500 mm",
            json!({"focal_length_px": 1000, "baseline": 100, "unit": "mm", "x_left": 510,
                   "x_right": 500, "disparity_error_px": 0.5, "image_width": 1000,
                   "image_height": 800}),
            json!({"distance": 10000, "depth_error": 500}),
        ),
        case(
            "3D point from (x_left, y) around the image centre",
            json!({"focal_length_px": 1000, "baseline": 100, "unit": "mm", "x_left": 700,
                   "x_right": 600, "y": 500, "image_width": 1000, "image_height": 800}),
            json!({"distance": 1000, "point.x": 200, "point.y": 100, "point.z": 1000}),
        ),
        case(
            "inches",
            json!({"focal_length_px": 500, "baseline": 4, "unit": "in", "x_left": 300,
                   "x_right": 280, "image_width": 640, "image_height": 480}),
            json!({"distance": 100, "distance_m": 2.54}),
        ),
        error_case(
            "f in mm alone",
            json!({"focal_length_mm": 35, "baseline": 150, "x_left": 400, "x_right": 350,
                   "image_width": 800, "image_height": 600}),
            422,
            &["focal_length_mm"],
        ),
        error_case(
            "no focal length",
            json!({"baseline": 150, "x_left": 400, "x_right": 350, "image_width": 800,
                   "image_height": 600}),
            422,
            &[],
        ),
        error_case(
            "two focal lengths",
            json!({"focal_length_px": 35, "horizontal_fov_deg": 60, "baseline": 150,
                   "x_left": 400, "x_right": 350, "image_width": 800, "image_height": 600}),
            422,
            &["focal_length_px", "horizontal_fov_deg"],
        ),
        error_case(
            "every bad field at once",
            json!({"focal_length_px": -1, "baseline": 0, "x_left": 900, "x_right": 350,
                   "image_width": 800, "image_height": 600}),
            422,
            &["focal_length_px", "baseline", "x_left"],
        ),
        error_case(
            "zero disparity",
            json!({"focal_length_px": 35, "baseline": 150, "x_left": 400, "x_right": 400,
                   "image_width": 800, "image_height": 600}),
            422,
            &[],
        ),
        error_case(
            "misspelt field",
            json!({"focal_lenght_px": 35, "focal_length_px": 35, "baseline": 150,
                   "x_left": 400, "x_right": 350, "image_width": 800, "image_height": 600}),
            422,
            &["focal_lenght_px"],
        ),
        error_case(
            "unknown unit",
            json!({"focal_length_px": 35, "baseline": 150, "unit": "furlong", "x_left": 400,
                   "x_right": 350, "image_width": 800, "image_height": 600}),
            422,
            &["unit"],
        ),
        error_case(
            "non-integer image size",
            json!({"focal_length_px": 35, "baseline": 150, "x_left": 400, "x_right": 350,
                   "image_width": 800.5, "image_height": 600}),
            422,
            &["image_width"],
        ),
    ]
}

/// Checks one answer against a case's `expect`, `expect_nonempty` or `expect_error`.
async fn check(response: reqwest::Response, case: &Value, how: &str) {
    let name = format!("{} ({how})", case["name"]);
    if let Some(expect) = case.get("expect_error") {
        let status = expect["status"].as_u64().unwrap() as u16;
        let body = problem(response, status).await;
        let named = fields(&body);
        for field in expect["fields"].as_array().into_iter().flatten() {
            let field = field.as_str().unwrap();
            assert!(
                named.iter().any(|n| n == field),
                "{name}: {field} not named in {body}"
            );
        }
        return;
    }
    let body = ok_json(response).await;
    for (path, expected) in case["expect"].as_object().unwrap() {
        match expected {
            Value::String(s) => assert_eq!(body[path], *s, "{name}: {path}"),
            number => assert_close(
                number_at(&body, path),
                number.as_f64().unwrap(),
                &format!("{name}: {path}"),
            ),
        }
    }
    for member in case["expect_nonempty"].as_array().into_iter().flatten() {
        let member = member.as_str().unwrap();
        assert!(
            !body[member].as_array().is_none_or(Vec::is_empty),
            "{name}: {member} is empty"
        );
    }
}

async fn run_cases(app: &TestApp, cases: &[Value]) {
    for case in cases {
        check(app.post("/distance", &case["request"]).await, case, "POST").await;
        check(
            app.get_with("/distance", &case["request"]).await,
            case,
            "GET",
        )
        .await;
    }
}

/// Every reference case reproduces, over POST and over GET with the same fields.
#[tokio::test]
async fn reference_cases_reproduce_over_post_and_get() {
    let app = spawn_app().await;
    run_cases(&app, &reference_cases()).await;
}

/// The shared reference file, when it is beside the project, reproduces too.
#[tokio::test]
async fn shared_reference_file_reproduces_when_present() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/vectors/distance.json"
    );
    let Ok(text) = std::fs::read_to_string(path) else {
        eprintln!("{path} is absent; the carried copy of its cases still runs");
        return;
    };
    let file: Value = serde_json::from_str(&text).expect("the shared vectors are JSON");
    let app = spawn_app().await;
    for list in ["cases", "errors"] {
        run_cases(&app, file[list].as_array().expect("a list of cases")).await;
    }
}

/// The seed's two examples, with f in px, give 105 mm and 40 mm, with every output named.
#[tokio::test]
async fn seed_examples_give_105_and_40_mm() {
    // Arrange
    let app = spawn_app().await;
    let first = crate::fixtures::example_one();
    // Act
    let body = ok_json(app.post("/distance", &first).await).await;
    // Assert
    assert_eq!(body["distance"], 105.0);
    assert_eq!(body["unit"], "mm");
    assert_eq!(body["disparity_error_px"], 0.5, "the default Δd is echoed");
    assert_close(
        body["depth_error"].as_f64().unwrap(),
        105.0 * 105.0 * 0.5 / (35.0 * 150.0),
        "ΔZ",
    );
    assert_eq!(body["warnings"], json!([]));
    assert!(
        body["formula"].as_str().unwrap().contains("= 105 mm"),
        "{}",
        body["formula"]
    );

    let second = ok_json(
        app.get("/distance?focal_length_px=12&baseline=50&x_left=180&x_right=195&image_width=640&image_height=480")
            .await,
    )
    .await;
    assert_eq!(second["distance"], 40.0);
    assert_eq!(second["warnings"][0]["code"], "negative_disparity");
}

/// A focal length in mm alone is refused with an explanation of the units and what to add.
#[tokio::test]
async fn focal_length_in_mm_alone_explains_why() {
    let app = spawn_app().await;
    let body = problem(
        app.post(
            "/distance",
            &json!({"focal_length_mm": 35, "baseline": 150, "x_left": 400, "x_right": 350,
                    "image_width": 800, "image_height": 600}),
        )
        .await,
        422,
    )
    .await;
    let message = message_for(&body, "focal_length_mm");
    assert!(message.contains("not a length"), "{message}");
    assert!(
        message.contains("sensor_width_mm") && message.contains("pixel_size_um"),
        "{message}"
    );
}

/// The defaults: unit mm, principal point at the centre, y = cy, doffs 0.
#[tokio::test]
async fn defaults_and_principal_point() {
    let app = spawn_app().await;
    let base = json!({"focal_length_px": 1000, "baseline": 100, "x_left": 700, "x_right": 600,
                      "image_width": 1000, "image_height": 800});
    let body = ok_json(app.post("/distance", &base).await).await;
    assert_eq!(body["point"], json!({"x": 200.0, "y": 0.0, "z": 1000.0}));
    assert_eq!(body["effective_disparity_px"], 100.0);

    let mut moved = base.clone();
    moved["cx"] = json!(600);
    moved["cy"] = json!(300);
    moved["y"] = json!(500);
    let body = ok_json(app.post("/distance", &moved).await).await;
    assert_eq!(body["point"], json!({"x": 100.0, "y": 200.0, "z": 1000.0}));
}

/// Feet: the distance is in the baseline's unit and distance_m converts it.
#[tokio::test]
async fn feet_convert_to_metres() {
    let app = spawn_app().await;
    let body = ok_json(
        app.get("/distance?focal_length_px=500&baseline=0.5&unit=ft&x_left=300&x_right=275&image_width=640&image_height=480")
            .await,
    )
    .await;
    assert_eq!(body["unit"], "ft");
    assert_close(body["distance"].as_f64().unwrap(), 10.0, "distance");
    assert_close(body["distance_m"].as_f64().unwrap(), 3.048, "distance_m");
}

/// A small disparity carries a warning that the error is large, and Δd is echoed.
#[tokio::test]
async fn large_relative_error_warns() {
    let app = spawn_app().await;
    let body = ok_json(
        app.post(
            "/distance",
            &json!({"focal_length_px": 700, "baseline": 120, "x_left": 402, "x_right": 400,
                    "disparity_error_px": 0.25, "image_width": 800, "image_height": 600}),
        )
        .await,
    )
    .await;
    assert_eq!(body["disparity_error_px"], 0.25);
    assert_close(
        body["relative_error"].as_f64().unwrap(),
        0.125,
        "relative error",
    );
    assert_eq!(body["warnings"][0]["code"], "large_relative_error");
}

/// A rig with a calibration's σ (as `/calibrate` answers it) widens `depth_error` by the focal
/// length's and the baseline's terms, over POST and GET alike, and breaks it down: at Z = 10 m
/// (f = 1000 px, B = 100 mm, Δd = 0.5) σ_f = 20 px and σ_B = 1 mm add 200 and 100 mm to the
/// disparity's 500 mm, in quadrature.
#[tokio::test]
async fn calibration_uncertainty_reaches_the_depth_error() {
    let app = spawn_app().await;
    let request = json!({"focal_length_px": 1000, "baseline": 100, "x_left": 510, "x_right": 500,
                         "focal_length_std_px": 20, "baseline_std": 1,
                         "image_width": 1000, "image_height": 800});
    for body in [
        ok_json(app.post("/distance", &request).await).await,
        ok_json(app.get_with("/distance", &request).await).await,
    ] {
        assert_close(number_at(&body, "distance"), 10_000.0, "distance");
        assert_close(
            number_at(&body, "depth_error_terms.disparity"),
            500.0,
            "disparity term",
        );
        assert_close(
            number_at(&body, "depth_error_terms.focal_length"),
            200.0,
            "focal term",
        );
        assert_close(
            number_at(&body, "depth_error_terms.baseline"),
            100.0,
            "baseline term",
        );
        assert_close(
            number_at(&body, "depth_error"),
            300_000f64.sqrt(),
            "depth_error",
        );
        assert_close(
            number_at(&body, "relative_error"),
            0.0547722557505,
            "relative_error",
        );
    }
    // Without them the breakdown still says where the error comes from: the disparity only.
    let plain = ok_json(
        app.post(
            "/distance",
            &json!({"focal_length_px": 1000, "baseline": 100, "x_left": 510, "x_right": 500,
                    "image_width": 1000, "image_height": 800}),
        )
        .await,
    )
    .await;
    assert_close(number_at(&plain, "depth_error"), 500.0, "depth_error");
    assert_eq!(plain["depth_error_terms"]["focal_length"], 0.0);
    assert_eq!(plain["depth_error_terms"]["baseline"], 0.0);
    // A batch's rig takes them too, for every point.
    let batch = ok_json(
        app.post(
            "/distance",
            &json!({"rig": {"focal_length_px": 1000, "baseline": 100, "baseline_std": 1,
                            "image_width": 1000, "image_height": 800},
                    "points": [{"x_left": 510, "x_right": 500}, {"disparity_px": 20}]}),
        )
        .await,
    )
    .await;
    assert_close(
        number_at(&batch["results"][0], "depth_error_terms.baseline"),
        100.0,
        "batch 0",
    );
    assert_close(
        number_at(&batch["results"][1], "depth_error_terms.baseline"),
        50.0,
        "batch 1",
    );
}

/// A negative or non-numeric σ is a 422 naming each member.
#[tokio::test]
async fn calibration_uncertainty_is_checked() {
    let app = spawn_app().await;
    let body = problem(
        app.post(
            "/distance",
            &json!({"focal_length_px": 1000, "baseline": 100, "x_left": 510, "x_right": 500,
                    "focal_length_std_px": -2, "baseline_std": -1,
                    "image_width": 1000, "image_height": 800}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["focal_length_std_px", "baseline_std"]);
    assert!(message_for(&body, "baseline_std").contains("0 or more"));
}

/// Zero effective disparity (with doffs) is a 422 blaming the disparity inputs.
#[tokio::test]
async fn point_at_infinity_names_disparity_fields() {
    let app = spawn_app().await;
    let body = problem(
        app.post(
            "/distance",
            &json!({"focal_length_px": 700, "baseline": 120, "x_left": 450, "x_right": 400,
                    "doffs": -50, "image_width": 800, "image_height": 600}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["x_left", "x_right", "doffs"]);
    assert!(message_for(&body, "x_left").contains("infinity"));
}

/// A subnormal disparity that would overflow Z is a 422, never null or infinity.
#[tokio::test]
async fn overflowing_distance_is_refused() {
    let app = spawn_app().await;
    let body = problem(
        app.post(
            "/distance",
            &json!({"focal_length_px": 1e6, "baseline": 1e3, "x_left": 0, "x_right": 0,
                    "doffs": 1e-310, "image_width": 800, "image_height": 600}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["x_left", "x_right", "doffs"]);

    let body = problem(
        app.post(
            "/distance",
            &json!({"focal_length_px": 1e300, "baseline": 1e10, "x_left": 10, "x_right": 0,
                    "image_width": 800, "image_height": 600}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["focal_length_px", "baseline"]);
}

/// A baseline no stereo rig has (0.083 mm: a 25 mm board typed as 0.025 with `mm`) is still
/// answered, with an `implausible_baseline` warning naming the member and metres as the likely
/// unit; a 120 mm baseline says nothing of the kind.
#[tokio::test]
async fn a_baseline_in_the_wrong_unit_is_named() {
    let app = spawn_app().await;
    let at = |baseline: f64| {
        json!({"focal_length_px": 800, "baseline": baseline, "unit": "mm",
               "disparity_px": 170, "image_width": 640, "image_height": 480})
    };
    let slip = ok_json(app.post("/distance", &at(0.083)).await).await;
    assert_close(
        slip["distance"].as_f64().unwrap(),
        0.083 * 800.0 / 170.0,
        "distance",
    );
    let warning = slip["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .find(|w| w["code"] == "implausible_baseline")
        .unwrap_or_else(|| panic!("no implausible_baseline in {slip}"));
    let message = warning["message"].as_str().unwrap();
    assert!(
        message.starts_with("baseline is 0.083 mm, under 1 mm"),
        "{message}"
    );
    assert!(
        message.contains("meant in m (0.083 m = 83 mm)"),
        "{message}"
    );
    let right = ok_json(app.post("/distance", &at(120.0)).await).await;
    assert_eq!(right["warnings"], json!([]), "{right}");
}
