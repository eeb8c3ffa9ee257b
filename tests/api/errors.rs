//! Every error class answers application/problem+json naming what is wrong; nothing is a 500.

use serde_json::{Value, json};

use crate::{
    fixtures::{example_one, seed_rig, with},
    helpers::{fields, message_for, problem, spawn_app},
};

/// A body that is not JSON is a 400 naming the body, with the parser's position.
#[tokio::test]
async fn malformed_json_is_400() {
    let app = spawn_app().await;
    for body in [
        &b"{\"baseline\": 150,"[..],
        b"not json",
        b"{\"baseline\": NaN}",
        b"{\"baseline\": 1e999}",
        b"",
    ] {
        let problem = problem(
            app.post_raw("/distance", Some("application/json"), body.to_vec())
                .await,
            400,
        )
        .await;
        assert_eq!(fields(&problem), vec!["body"]);
    }
}

/// JSON that is not an object is a 422 naming the body.
#[tokio::test]
async fn non_object_json_is_422() {
    let app = spawn_app().await;
    let body = problem(app.post("/table", &json!([1, 2, 3])).await, 422).await;
    assert_eq!(fields(&body), vec!["body"]);
}

/// A missing or non-JSON content type is a 415 naming it.
#[tokio::test]
async fn wrong_content_type_is_415() {
    let app = spawn_app().await;
    for content_type in [
        None,
        Some("text/plain"),
        Some("application/x-www-form-urlencoded"),
    ] {
        let body = problem(
            app.post_raw("/distance", content_type, example_one().to_string().into())
                .await,
            415,
        )
        .await;
        assert_eq!(fields(&body), vec!["content-type"]);
    }
    // A JSON content type with parameters is fine.
    let ok = app
        .post_raw(
            "/distance",
            Some("application/json; charset=utf-8"),
            example_one().to_string().into(),
        )
        .await;
    assert_eq!(ok.status(), 200);
}

/// A body over the 64 KiB limit is a 413 naming the body and the option that raises the
/// limit; `/distance`, which takes batches, has its own 2 MiB limit, and names its own.
#[tokio::test]
async fn oversized_body_is_413() {
    let app = spawn_app().await;
    let padding = " ".repeat(70 * 1024);
    let body = format!("{{\"baseline\": 150{padding}}}");
    let table = problem(
        app.post_raw("/table", Some("application/json"), body.clone().into())
            .await,
        413,
    )
    .await;
    assert_eq!(fields(&table), vec!["body"]);
    assert!(message_for(&table, "body").contains("65536"));
    assert!(message_for(&table, "body").contains("--body-limit"));
    // The same body is within /distance's limit: it is decoded and found wanting.
    let within = app
        .post_raw("/distance", Some("application/json"), body.into())
        .await;
    assert_eq!(within.status(), 422);

    let padding = " ".repeat(2 * 1024 * 1024);
    let body = format!("{{\"baseline\": 150{padding}}}");
    let batch = problem(
        app.post_raw("/distance", Some("application/json"), body.into())
            .await,
        413,
    )
    .await;
    assert!(message_for(&batch, "body").contains("2097152"));
    assert!(message_for(&batch, "body").contains("--batch-body-limit"));
}

/// A string where a number belongs is a 422 naming it, in JSON and in a query alike; so are
/// `abc`, `nan` and `inf` in a query.
#[tokio::test]
async fn wrong_types_are_422_naming_each_field() {
    let app = spawn_app().await;
    let body = problem(
        app.post(
            "/distance",
            &json!({"focal_length_px": 35, "baseline": "150", "x_left": true, "x_right": 350,
                    "image_width": 800, "image_height": -600}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["baseline", "x_left", "image_height"]);

    let body = problem(
        app.get("/distance?focal_length_px=abc&baseline=nan&x_left=inf&x_right=350&image_width=800&image_height=600")
            .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["focal_length_px", "baseline", "x_left"]);
}

/// Missing members are all named at once.
#[tokio::test]
async fn missing_fields_are_all_named() {
    let app = spawn_app().await;
    let body = problem(
        app.post("/distance", &json!({"focal_length_px": 35})).await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["baseline", "x_left", "x_right"]);
    assert_eq!(message_for(&body, "baseline"), "is required");
    // The image size is not required: without it the depth is answered (without the point).
    assert!(message_for(&body, "x_right").contains("or disparity_px"));
}

/// Out-of-range values are named: coordinates outside the image, FOV outside (0, 180), a zero
/// image size, a negative Δd, and sensor and pitch together.
#[tokio::test]
async fn out_of_range_values_are_named() {
    let app = spawn_app().await;
    let body = problem(
        app.post(
            "/distance",
            &json!({"horizontal_fov_deg": 180, "baseline": 150, "x_left": -1, "x_right": 801,
                    "y": 601, "image_width": 800, "image_height": 600, "cx": 900, "cy": -5,
                    "disparity_error_px": -0.1}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(
        fields(&body),
        vec![
            "horizontal_fov_deg",
            "disparity_error_px",
            "cx",
            "cy",
            "x_left",
            "x_right",
            "y"
        ]
    );

    let body = problem(
        app.post(
            "/distance",
            &json!({"focal_length_mm": 4, "sensor_width_mm": 6.4, "pixel_size_um": 3,
                    "baseline": 150, "x_left": 1, "x_right": 0, "image_width": 0,
                    "image_height": 600}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(
        fields(&body),
        vec!["image_width", "sensor_width_mm", "pixel_size_um"]
    );
}

/// A repeated query parameter, and one that does not percent-decode, are refused.
#[tokio::test]
async fn bad_query_strings() {
    let app = spawn_app().await;
    let body = problem(
        app.get("/distance?focal_length_px=35&baseline=150&baseline=15&x_left=400&x_right=350&image_width=800&image_height=600")
            .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["baseline"]);

    let body = problem(app.get("/distance?unit=%FF").await, 400).await;
    assert_eq!(fields(&body), vec!["query"]);
}

/// Unknown paths are 404 and wrong methods 405 (with Allow), in the same format.
#[tokio::test]
async fn not_found_and_method_not_allowed() {
    let app = spawn_app().await;
    problem(app.get("/nowhere").await, 404).await;

    let response = app
        .client
        .delete(format!("{}/distance", app.address))
        .send()
        .await
        .unwrap();
    let allow = response.headers()["allow"].to_str().unwrap().to_owned();
    assert!(allow.contains("GET") && allow.contains("POST"), "{allow}");
    let body = problem(response, 405).await;
    assert_eq!(fields(&body), vec!["method"]);
}

/// Decoding and validation findings come in one answer: an unknown member, a wrong type and an
/// out-of-range value are all named, and a refused member is not also called missing.
#[tokio::test]
async fn decoding_and_validation_errors_are_named_together() {
    let app = spawn_app().await;
    let body = problem(
        app.post(
            "/distance",
            &json!({"focal_length_px": 35, "baseline": 0, "x_left": "400", "x_right": 900,
                    "image_width": 800, "image_height": 600, "focal_lenght": 3}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(
        fields(&body),
        vec!["x_left", "focal_lenght", "baseline", "x_right"]
    );
    assert_eq!(
        message_for(&body, "x_left"),
        "must be a number, got `400`",
        "a string is not a number, whatever it holds"
    );

    let body = problem(
        app.get(
            "/table?horizontal_fov_deg=wide&baseline=150&image_width=800&image_height=600&steps=0",
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["horizontal_fov_deg", "steps"]);
}

/// Optional members are optional, not nullable: an explicit null is a 422 naming the member.
#[tokio::test]
async fn null_is_not_a_value() {
    let app = spawn_app().await;
    let body = problem(
        app.post(
            "/distance",
            &with(example_one(), json!({"unit": null, "doffs": null})),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["unit", "doffs"]);
}

/// JSON Schema's `integer` is any number without a fractional part, so `800.0` is accepted as
/// the whole number 800, in a body and in a query; `800.5`, a negative count and one beyond
/// the schema's `int32` are each named.
#[tokio::test]
async fn whole_numbers_may_carry_a_zero_fraction() {
    let app = spawn_app().await;
    let body = with(
        example_one(),
        json!({"image_width": 800.0, "image_height": 6e2}),
    );

    let response = app.post("/distance", &body).await;
    assert_eq!(response.status(), 200);
    let answer: Value = response.json().await.unwrap();
    assert_eq!(answer["distance"], 105.0);

    let response = app
        .get("/table?focal_length_px=35&baseline=150&image_width=800.0&image_height=600&steps=4.0")
        .await;
    assert_eq!(response.status(), 200);
    let table: Value = response.json().await.unwrap();
    assert_eq!(table["rows"].as_array().unwrap().len(), 4);

    let body = problem(
        app.post(
            "/table",
            &json!({"focal_length_px": 35, "baseline": 150, "image_width": 800.5,
                    "image_height": -600, "steps": 2147483648u64}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["image_width", "image_height", "steps"]);
    assert_eq!(
        message_for(&body, "image_width"),
        "must be a whole number, got 800.5"
    );
    assert!(message_for(&body, "image_height").contains("must not be negative"));
    // Beyond any whole member: told steps' own cap (issue 29), not the decoder's bound.
    assert!(message_for(&body, "steps").contains("from 1 to 10000 (the server's cap)"));
}

/// A member with an empty name is refused under the name of what holds it (the body, the
/// query, the rig, a batch point), so that every error names a field.
#[tokio::test]
async fn an_empty_member_name_is_named_by_its_holder() {
    let app = spawn_app().await;
    let mut body = example_one();
    body[""] = json!(1);
    let problem_body = problem(app.post("/distance", &body).await, 422).await;
    assert_eq!(fields(&problem_body), vec!["body"]);
    assert!(message_for(&problem_body, "body").contains("empty name"));

    let response = app
        .get("/distance?focal_length_px=35&baseline=150&image_width=800&image_height=600&x_left=400&x_right=350&=1")
        .await;
    assert_eq!(fields(&problem(response, 422).await), vec!["query"]);

    let rig = with(seed_rig(), json!({"": 1}));
    let batch = json!({"rig": rig, "points": [{"x_left": 400, "x_right": 350, "": 2}], "": 3});
    let problem_body = problem(app.post("/distance", &batch).await, 422).await;
    assert_eq!(fields(&problem_body), vec!["body", "rig", "points[0]"]);
}

/// The messages people read say what was expected in the API's own words, never serde's
/// (`unknown variant`, `invalid type`, `expected f64`), over a query string and a JSON body.
#[tokio::test]
async fn messages_are_in_the_apis_own_words() {
    // Arrange
    let app = spawn_app().await;
    let kitti = "focal_length_px=721.5377&baseline=0.54&x_left=620&x_right=610\
                 &image_width=1242&image_height=375";
    let cases = [
        (
            "unit=meters",
            "unit",
            "must be one of mm, cm, m, in, ft, got `meters`",
        ),
        ("unit=5", "unit", "must be one of mm, cm, m, in, ft, got 5"),
        (
            "baseline=0,54",
            "baseline",
            "must be a number, got `0,54`; use a dot for decimals",
        ),
        ("baseline=wide", "baseline", "must be a number, got `wide`"),
        (
            "image_width=1242.5",
            "image_width",
            "must be a whole number, got 1242.5",
        ),
    ];
    for (change, field, expected) in cases {
        let name = change.split('=').next().unwrap();
        let query: Vec<&str> = kitti
            .split('&')
            .filter(|pair| !pair.starts_with(&format!("{name}=")))
            .chain([change])
            .collect();

        // Act
        let body = problem(
            app.get(&format!("/distance?{}", query.join("&"))).await,
            422,
        )
        .await;

        // Assert
        assert_eq!(fields(&body), [field], "{change}");
        assert_eq!(message_for(&body, field), expected, "{change}");
    }

    let body = problem(
        app.post(
            "/distance",
            &json!({"focal_length_px": 721.5377, "baseline": 0.54, "unit": {"mm": null},
                    "spacing": 3, "x_left": 620, "x_right": 610, "cx": 600, "cy": 180}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), ["unit", "spacing"]);
    assert_eq!(
        message_for(&body, "unit"),
        "must be one of mm, cm, m, in, ft, got an object"
    );
    for text in [message_for(&body, "unit"), message_for(&body, "spacing")] {
        for serde_words in ["variant", "invalid type", "expected", "f64", "u32"] {
            assert!(!text.contains(serde_words), "{text}");
        }
    }
}

/// Numbers in messages are written short: a baseline of 1e308 is echoed as `1e308`, and the
/// problem stays under 1 KiB (it was 1 768 bytes spelling out 309 digits four times).
#[tokio::test]
async fn huge_numbers_are_echoed_short() {
    let app = spawn_app().await;
    let response = app
        .post(
            "/distance",
            &json!({"focal_length_px": 721.5377, "baseline": 1e308, "x_left": 620,
                    "x_right": 610, "image_width": 1242, "image_height": 375}),
        )
        .await;
    let bytes = response.content_length();
    let body = problem(response, 422).await;
    assert_eq!(fields(&body), ["focal_length_px", "baseline"]);
    assert!(message_for(&body, "baseline").contains("baseline (1e308)"));
    assert!(bytes.is_some_and(|n| n < 1024), "{bytes:?} bytes");

    let long = "9".repeat(5000);
    let body = problem(
        app.get(&format!("/distance?baseline={long}x&focal_length_px=700"))
            .await,
        422,
    )
    .await;
    assert!(body.to_string().len() < 1024, "{body}");
}

/// A `POST` reads its members from the JSON body; a query parameter it would ignore is named
/// instead, on every body-reading operation (single and batch `/distance`, `/rig`).
#[tokio::test]
async fn post_query_parameters_are_named_not_ignored() {
    let app = spawn_app().await;
    for (path, body) in [
        ("/distance?unit=m", example_one()),
        (
            "/distance?unit=m",
            json!({"rig": seed_rig(), "points": [{"x_left": 400, "x_right": 350}]}),
        ),
        (
            "/rig?unit=m",
            json!({"focal_length_px": 424, "baseline": 50, "image_width": 848,
                   "image_height": 480, "max_disparity_px": 126}),
        ),
    ] {
        let body = problem(app.post(path, &body).await, 422).await;
        assert_eq!(fields(&body), ["unit"], "{path}");
        assert!(message_for(&body, "unit").contains("reads its members from the JSON body"));
    }
}
