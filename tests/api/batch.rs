//! Batch `POST /distance`: many points with one rig, answered in order; a bad point is named by
//! its index while the good ones are still computed; the rig and the cap are checked first.

use serde_json::{Value, json};

use crate::helpers::{
    assert_close, fields, message_for, number_at, ok_json, problem, spawn_app, spawn_app_with,
};

use crate::fixtures::seed_rig as rig;

/// Every good point gets the same answer as a single request; results keep request order.
#[tokio::test]
async fn batch_matches_single_requests_in_order() {
    // Arrange
    let app = spawn_app().await;
    let points = json!([
        {"x_left": 400, "x_right": 350},
        {"x_left": 180, "x_right": 195, "y": 100},
        {"x_left": 700, "x_right": 690, "y": 599.5}
    ]);

    // Act
    let batch = ok_json(
        app.post("/distance", &json!({"rig": rig(), "points": points}))
            .await,
    )
    .await;

    // Assert
    assert_eq!(
        (&batch["count"], &batch["succeeded"], &batch["failed"]),
        (&json!(3), &json!(3), &json!(0))
    );
    assert_eq!(batch["unit"], "mm");
    let results = batch["results"].as_array().unwrap();
    for (i, point) in points.as_array().unwrap().iter().enumerate() {
        let mut single = rig();
        for (key, value) in point.as_object().unwrap() {
            single[key] = value.clone();
        }
        let one = ok_json(app.post("/distance", &single).await).await;
        let r = &results[i];
        assert_eq!(r["index"], i);
        for member in [
            "distance",
            "depth_error",
            "relative_error",
            "disparity_px",
            "point.x",
            "point.y",
            "point.z",
        ] {
            assert_close(number_at(r, member), number_at(&one, member), member);
        }
        assert_eq!(r["warnings"], one["warnings"]);
    }
    assert_close(number_at(&results[0], "distance"), 105.0, "seed example 1");
    assert_eq!(results[1]["warnings"][0]["code"], "negative_disparity");
}

/// A batch whose points are well-formed but some of whose values are bad is a 200: the good
/// points are computed and each bad one carries its own errors, named `points[i].field`,
/// whether a coordinate is off the image, negative, or the point is at infinity.
#[tokio::test]
async fn bad_values_are_named_by_index_and_good_points_computed() {
    let app = spawn_app().await;
    let mut points: Vec<Value> = (0..20)
        .map(|i| json!({"x_left": 400 + i, "x_right": 350}))
        .collect();
    points[3] = json!({"x_left": 400, "x_right": 400});
    points[5] = json!({"x_left": 900, "x_right": 350});
    points[8] = json!({"x_left": 400, "x_right": -2, "y": 700});
    let body = ok_json(
        app.post("/distance", &json!({"rig": rig(), "points": points}))
            .await,
    )
    .await;
    assert_eq!(
        (&body["count"], &body["succeeded"], &body["failed"]),
        (&json!(20), &json!(17), &json!(3))
    );
    let results = body["results"].as_array().unwrap();
    let errors = |i: usize| fields(&results[i]);
    assert_eq!(errors(3), vec!["points[3].x_left", "points[3].x_right"]);
    assert!(message_for(&results[3], "points[3].x_left").contains("infinity"));
    assert_eq!(errors(5), vec!["points[5].x_left"]);
    assert!(message_for(&results[5], "points[5].x_left").contains("image width"));
    assert_eq!(errors(8), vec!["points[8].x_right", "points[8].y"]);
    for (i, r) in results.iter().enumerate() {
        assert_eq!(r["index"], i, "results are in request order");
        if ![3, 5, 8].contains(&i) {
            assert_close(
                number_at(r, "distance"),
                5250.0 / (50.0 + i as f64),
                "Z = f·B/d",
            );
            assert!(r.get("errors").is_none());
        }
    }
}

/// A point that breaks the schema (a wrong type, an unknown or missing member, `null`, not an
/// object) makes the whole batch a 422 that names each fault by index, as the OpenAPI schema
/// says; nothing is computed.
#[tokio::test]
async fn malformed_points_refuse_the_batch() {
    let app = spawn_app().await;
    let mut points: Vec<Value> = (0..20)
        .map(|i| json!({"x_left": 400 + i, "x_right": 350}))
        .collect();
    points[17] = json!({"x_left": "abc", "x_right": 350});
    points[5] = json!({"x_left": 900, "x_right": 350, "z": 1});
    points[8] = json!(42);
    points[9] = json!({"x_right": 350, "y": null});
    let body = problem(
        app.post("/distance", &json!({"rig": rig(), "points": points}))
            .await,
        422,
    )
    .await;
    assert_eq!(
        fields(&body),
        vec![
            "points[5].z",
            "points[8]",
            "points[9].y",
            "points[9].x_left",
            "points[17].x_left"
        ]
    );
    assert_eq!(
        message_for(&body, "points[17].x_left"),
        "must be a number, got `abc`"
    );
    assert!(message_for(&body, "points[8]").contains("must be an object"));
    assert_eq!(
        message_for(&body, "points[9].x_left"),
        "is required with x_right"
    );
}

/// A batch with a bad rig, no points, or a non-array is refused whole (nothing could be
/// computed), naming `rig.…` fields and the envelope's.
#[tokio::test]
async fn bad_envelope_or_rig_is_422() {
    let app = spawn_app().await;
    let body = problem(
        app.post(
            "/distance",
            &json!({"rig": {"focal_length_mm": 4, "baseline": -1, "image_width": 800,
                            "image_height": 600, "colour": "red"},
                    "points": []}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(
        fields(&body),
        vec![
            "rig.colour",
            "rig.focal_length_mm",
            "rig.baseline",
            "points"
        ]
    );

    let body = problem(
        app.post("/distance", &json!({"points": {"x_left": 1}, "x_left": 3}))
            .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["points", "x_left", "rig"]);

    let body = problem(
        app.post(
            "/distance",
            &json!({"rig": null, "points": [{"x_left": 1, "x_right": 0}]}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["rig"]);
    assert_eq!(message_for(&body, "rig"), "must be an object, got null");
}

/// The cap is enforced with a 422 naming `points`; exactly the cap is served in full.
#[tokio::test]
async fn batch_cap_is_enforced() {
    let mut config = stereo_distance::Config {
        port: 0,
        ..Default::default()
    };
    config.limits.batch_points = 100;
    let app = spawn_app_with(config).await;
    let points = |n: usize| -> Vec<Value> {
        (0..n)
            .map(|_| json!({"x_left": 400, "x_right": 350}))
            .collect()
    };
    let body = problem(
        app.post("/distance", &json!({"rig": rig(), "points": points(101)}))
            .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["points"]);
    assert!(message_for(&body, "points").contains("at most 100"));
    let body = ok_json(
        app.post("/distance", &json!({"rig": rig(), "points": points(100)}))
            .await,
    )
    .await;
    assert_eq!(body["succeeded"], 100);
}

/// A full default batch of 10 000 points fits the default body limit and is answered whole.
#[tokio::test]
async fn ten_thousand_points_are_answered() {
    let app = spawn_app().await;
    let points: Vec<Value> = (0..10_000)
        .map(|i| json!({"x_left": 400.25 + f64::from(i % 300), "x_right": 350.125, "y": 123.5}))
        .collect();
    let body = ok_json(
        app.post("/distance", &json!({"rig": rig(), "points": points}))
            .await,
    )
    .await;
    assert_eq!(body["succeeded"], 10_000);
    let last = &body["results"][9_999];
    assert_eq!(last["index"], 9_999);
    assert_close(
        number_at(last, "disparity_px"),
        400.25 + 99.0 - 350.125,
        "d",
    );
}

/// A point given as an array is a 422 naming that point, whatever the rest of the batch
/// holds: serde would read `[620, 610, 200]` by position, but the schema says an object.
#[tokio::test]
async fn array_points_are_refused_by_index() {
    // Arrange
    let app = spawn_app().await;
    let batches = [
        (
            json!([[620, 610], [630, 600]]),
            vec!["points[0]", "points[1]"],
        ),
        (json!([[620, 610, 200]]), vec!["points[0]"]),
        (
            json!([[620, 610, 200], [620]]),
            vec!["points[0]", "points[1]"],
        ),
        (
            json!([{"x_left": 620, "x_right": 610}, [630, 600]]),
            vec!["points[1]"],
        ),
    ];
    for (points, expected) in batches {
        // Act
        let body = problem(
            app.post("/distance", &json!({"rig": rig(), "points": points}))
                .await,
            422,
        )
        .await;
        // Assert
        assert_eq!(fields(&body), expected, "{points}");
        for field in expected {
            assert_eq!(message_for(&body, field), "must be an object, got an array");
        }
    }
}

/// A rig given as an array is named as `rig`, not as focal options nobody sent.
#[tokio::test]
async fn array_rig_is_refused_as_rig() {
    let app = spawn_app().await;
    let body = problem(
        app.post(
            "/distance",
            &json!({"rig": [721.5, 0.54], "points": [{"x_left": 620, "x_right": 610}]}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["rig"]);
    assert_eq!(message_for(&body, "rig"), "must be an object, got an array");
}
