//! `POST /match` over a real socket, on the project's own synthetic pairs (known ground
//! truth): each status where the scene makes it, the distances `/distance` gives, regions, bad
//! points and regions named, and the memory budget.

use reqwest::Response;
use reqwest::multipart::Form;
use serde_json::{Value, json};
use stereo_core::vision::sigma::MODEL;
use stereo_core::vision::synthetic::{self, Pair, Plane, Region, Scene};
use stereo_distance::Config;
use stereo_distance::config::HeavyLimits;

use crate::depth_map::{H, W, image_part, jpeg_part, pair, phone_photo, png, rig};
use crate::helpers::{
    TestApp, assert_names, fields, message_for, ok_json, problem, spawn_app, spawn_app_with,
};

/// A form with the pair, the rig, and `extra` parts as text.
fn form(pair: &Pair, extra: &[(&str, String)]) -> Form {
    let mut form = Form::new()
        .part("left", image_part(png(&pair.left_rgb, W, H)))
        .part("right", image_part(png(&pair.right_rgb, W, H)))
        .text("rig", rig().to_string());
    for (name, text) in extra {
        form = form.text(name.to_string(), text.clone());
    }
    form
}

async fn post_match(app: &TestApp, query: &str, form: Form) -> Response {
    app.client
        .post(format!("{}/match{query}", app.address))
        .multipart(form)
        .send()
        .await
        .expect("request is sent")
}

/// The 200 answer of `/match` on `pair` with the query `query` and `extra` parts.
async fn answer(app: &TestApp, pair: &Pair, query: &str, extra: &[(&str, String)]) -> Value {
    ok_json(post_match(app, query, form(pair, extra)).await).await
}

/// The matches of `points` ((x, y) pixels) on `pair`, with the query `query`.
async fn matches(app: &TestApp, pair: &Pair, query: &str, points: &[(usize, usize)]) -> Vec<Value> {
    let points: Vec<Value> = points
        .iter()
        .map(|&(x, y)| json!({"x": x, "y": y}))
        .collect();
    let body = answer(
        app,
        pair,
        query,
        &[("points", Value::from(points).to_string())],
    )
    .await;
    body["matches"].as_array().expect("matches").clone()
}

fn status(m: &Value) -> &str {
    m["status"].as_str().expect("status")
}

/// A point every 4 px across and 8 px down the image.
fn grid() -> Vec<(usize, usize)> {
    (4..H)
        .step_by(8)
        .flat_map(|y| (0..W).step_by(4).map(move |x| (x, y)))
        .collect()
}

/// On the layered scene: most visible points are `ok`, every `ok` point is visible and within
/// half a pixel of the truth, points the right camera cannot see are never `ok` and mostly
/// `occluded`, and the left edge, whose matches would lie left of the right image, is
/// `out_of_range`. Every point with a disparity has its σ_d and σ_Z = Z²·σ_d / (f·B); the
/// `ok` points' errors lie within their σ_d (rendered truth is easier than real images, so
/// nearly all), and the hidden points' σ_d are larger than the `ok` points'.
#[tokio::test]
async fn statuses_follow_the_scene() {
    // Arrange
    let app = spawn_app().await;
    let pair = pair();
    let points = grid();
    // Act
    let found = matches(&app, &pair, "?max_disparity=48", &points).await;
    // Assert
    let (mut visible, mut visible_ok, mut hidden, mut hidden_occluded) = (0, 0, 0, 0);
    let mut errors = Vec::new();
    let (mut within, mut ok_sigma, mut hidden_sigma) = (0, Vec::new(), Vec::new());
    for (&(x, y), m) in points.iter().zip(&found) {
        let i = y * W + x;
        if let Some(d) = m["disparity_px"].as_f64() {
            let s = m["disparity_std_px"]
                .as_f64()
                .expect("σ_d beside a disparity");
            assert!(s >= f64::from(MODEL.floor) - 5e-4, "{m}");
            match m["distance"].as_f64() {
                // σ_Z from σ_d as answered, without σ_f and σ_B.
                Some(z) => {
                    let sz = m["distance_std"].as_f64().expect("σ_Z beside a distance");
                    assert!((sz - z * z * s / 50_000.0).abs() <= 1e-9 * sz, "{m}");
                    assert!(!["occluded", "out_of_range"].contains(&status(m)), "{m}");
                }
                // A disparity that is not the point's match is answered without a distance,
                // and says why.
                None => {
                    assert!(["occluded", "out_of_range"].contains(&status(m)), "{m}");
                    assert!(
                        m["error"].as_str().unwrap().starts_with("no distance"),
                        "{m}"
                    );
                }
            }
            if status(m) == "ok" {
                ok_sigma.push(s);
                within += usize::from((d - f64::from(pair.truth[i])).abs() <= s);
            } else if !pair.visible[i] && x >= 8 {
                hidden_sigma.push(s);
            }
        }
        assert_eq!(
            (m["x"].as_f64(), m["y"].as_f64()),
            (Some(x as f64), Some(y as f64))
        );
        let c = m["confidence"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&c), "{m}");
        if x == 0 {
            assert_eq!(status(m), "out_of_range", "{m}");
        }
        if pair.visible[i] {
            visible += 1;
            if status(m) == "ok" {
                visible_ok += 1;
                let d = m["disparity_px"].as_f64().unwrap();
                errors.push((d - f64::from(pair.truth[i])).abs());
                assert!((m["x_right"].as_f64().unwrap() - (x as f64 - d)).abs() < 1e-9);
            }
        } else if x >= 8 {
            hidden += 1;
            assert_ne!(
                status(m),
                "ok",
                "({x}, {y}) is hidden from the right camera: {m}"
            );
            if status(m) == "occluded" {
                hidden_occluded += 1;
            }
        }
    }
    assert!(
        visible_ok * 10 >= visible * 8,
        "{visible_ok} of {visible} visible points ok"
    );
    let worst = errors.iter().copied().fold(0.0, f64::max);
    assert!(worst < 0.5, "an ok point is off by {worst} px");
    errors.sort_by(f64::total_cmp);
    assert!(
        errors[errors.len() / 2] < 0.15,
        "median error {}",
        errors[errors.len() / 2]
    );
    assert!(
        hidden >= 20 && hidden_occluded * 2 > hidden,
        "{hidden_occluded} of {hidden}"
    );
    assert!(
        within * 10 >= ok_sigma.len() * 9,
        "{within} of {} ok points within σ_d",
        ok_sigma.len()
    );
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    assert!(
        mean(&hidden_sigma) > 2.0 * mean(&ok_sigma),
        "hidden σ_d {} against ok {}",
        mean(&hidden_sigma),
        mean(&ok_sigma)
    );
}

/// A flat patch has no texture of its own: its centre is `textureless`, with the disparity
/// carried in from around it; textured points of the same plane are `ok`.
#[tokio::test]
async fn a_flat_patch_is_textureless() {
    // Arrange: a plane at 10 px, with a 40 × 40 grey square painted on it in both images.
    let app = spawn_app().await;
    let mut pair = plane_pair(10.0);
    for y in 40..80 {
        for x in 60..100 {
            let (l, r) = ((y * W + x) * 3, (y * W + x - 10) * 3);
            pair.left_rgb[l..l + 3].copy_from_slice(&[128; 3]);
            pair.right_rgb[r..r + 3].copy_from_slice(&[128; 3]);
        }
    }
    // Act
    let found = matches(&app, &pair, "?max_disparity=32", &[(80, 60), (130, 60)]).await;
    // Assert
    assert_eq!(status(&found[0]), "textureless", "{}", found[0]);
    assert!(found[0]["disparity_px"].is_number(), "{}", found[0]);
    assert_eq!(status(&found[1]), "ok", "{}", found[1]);
    assert!(found[0]["confidence"].as_f64() < found[1]["confidence"].as_f64());
}

/// Stripes that repeat every 7 px match equally well 7 px apart: `ambiguous`.
#[tokio::test]
async fn repeated_stripes_are_ambiguous() {
    // Arrange: the same column pattern on every row (its contrast varying by row), shifted by
    // 10 px.
    let app = spawn_app().await;
    const PATTERN: [u8; 7] = [30, 200, 90, 250, 10, 160, 120];
    let image = |shift: usize| -> Vec<u8> {
        (0..H)
            .flat_map(|y| {
                (0..W).map(move |x| {
                    let v = f32::from(PATTERN[(x + shift) % 7]);
                    let contrast = 0.6 + 0.4 * ((y % 5) as f32 / 4.0);
                    (128.0 + (v - 128.0) * contrast) as u8
                })
            })
            .flat_map(|v| [v; 3])
            .collect()
    };
    let mut pair = plane_pair(10.0);
    pair.left_rgb = image(0);
    pair.right_rgb = image(10);
    // Act
    let found = matches(&app, &pair, "?max_disparity=32", &[(80, 60), (100, 30)]).await;
    // Assert
    for m in &found {
        assert_eq!(status(m), "ambiguous", "{m}");
        assert!(m["confidence"].as_f64().unwrap() <= 0.5, "{m}");
    }
}

/// A point with no right pixel in the range has no disparity and is `out_of_range`. A surface
/// nearer than the range allows is mostly `occluded`, `out_of_range` or `ambiguous` (no match in
/// the range stands out), and seldom `ok` (the aggregation can carry a wrong but smooth match
/// into it: set the range from the rig).
#[tokio::test]
async fn matches_beyond_the_range_are_flagged() {
    let app = spawn_app().await;
    let pair = pair();
    // x = 10 with min_disparity 20: every right pixel would be left of the image.
    let found = matches(
        &app,
        &pair,
        "?min_disparity=20&max_disparity=40",
        &[(10, 60)],
    )
    .await;
    assert_eq!(status(&found[0]), "out_of_range", "{}", found[0]);
    assert_eq!(found[0]["confidence"], 0.0);
    assert!(found[0].get("disparity_px").is_none() && found[0].get("x_right").is_none());
    // The disc (centre (112, 60), radius 26) is at 26–30 px; the search stops at 20.
    let disc: Vec<(usize, usize)> = (36..86)
        .step_by(6)
        .flat_map(|y| (90..136).step_by(4).map(move |x| (x, y)))
        .filter(|&(x, y)| (x as f32 - 112.0).powi(2) + (y as f32 - 60.0).powi(2) < 400.0)
        .collect();
    let found = matches(&app, &pair, "?max_disparity=20", &disc).await;
    let count = |s: &str| found.iter().filter(|m| status(m) == s).count();
    assert!(
        count("ok") * 5 <= disc.len(),
        "{} of {} ok",
        count("ok"),
        disc.len()
    );
    assert!(
        (count("occluded") + count("out_of_range") + count("ambiguous")) * 2 > disc.len(),
        "{found:?}"
    );
}

/// Points off the left image are answered in their place as `outside_image`, and the points
/// between them are still matched.
#[tokio::test]
async fn points_off_the_image_are_their_own_status() {
    let app = spawn_app().await;
    let pair = pair();
    let points = json!([{"x": -3, "y": 10}, {"x": 100, "y": 100}, {"x": 160, "y": 10},
                        {"x": 5.5, "y": 119.6}]);
    let body = answer(
        &app,
        &pair,
        "?max_disparity=48",
        &[("points", points.to_string())],
    )
    .await;
    let found = body["matches"].as_array().unwrap();
    let statuses: Vec<&str> = found.iter().map(status).collect();
    assert_eq!(statuses[0], "outside_image");
    assert_eq!(statuses[2], "outside_image");
    assert_eq!(statuses[3], "outside_image");
    assert_eq!(statuses[1], "ok", "{}", found[1]);
    assert_eq!(body["ok"], 1);
    assert!(found[0].get("distance").is_none());
}

/// Points and regions may also come as repeated parts, one item or array each (as clients
/// generated from the OpenAPI document send a form's array), or as one lone item: joined in
/// order, answered as one array would be; a repeated part that is not JSON is named by its
/// place.
#[tokio::test]
async fn repeated_parts_are_one_list_in_order() {
    let app = spawn_app().await;
    let pair = pair();
    let one = answer(
        &app,
        &pair,
        "?max_disparity=48",
        &[(
            "points",
            json!([{"x": 100, "y": 100}, {"x": 40, "y": 60}, {"x": 120, "y": 30}]).to_string(),
        )],
    )
    .await;
    let repeated = answer(
        &app,
        &pair,
        "?max_disparity=48",
        &[
            ("points", json!({"x": 100, "y": 100}).to_string()),
            (
                "points",
                json!([{"x": 40, "y": 60}, {"x": 120, "y": 30}]).to_string(),
            ),
            (
                "regions",
                json!({"x": 32, "y": 35, "width": 30, "height": 40}).to_string(),
            ),
            (
                "regions",
                json!({"x": 90, "y": 20, "width": 10, "height": 10}).to_string(),
            ),
        ],
    )
    .await;
    assert_eq!(repeated["matches"], one["matches"]);
    let lone = answer(
        &app,
        &pair,
        "?max_disparity=48",
        &[("points", json!({"x": 100, "y": 100}).to_string())],
    )
    .await;
    assert_eq!(lone["matches"][0], one["matches"][0]);
    assert_eq!(repeated["regions"].as_array().unwrap().len(), 2);
    assert_eq!(repeated["regions"][0]["x"], 32.0);
    let body = problem(
        post_match(
            &app,
            "?max_disparity=48",
            form(
                &pair,
                &[
                    ("points", json!({"x": 1, "y": 1}).to_string()),
                    ("points", "{x: 2".to_owned()),
                ],
            ),
        )
        .await,
        422,
    )
    .await;
    assert_names(&body, &["points[part 2]"]);
}

/// A depth edge: points within the census window of a box's right edge, on either side, are
/// `inconsistent`; the box's middle is `ok`.
#[tokio::test]
async fn points_at_a_depth_edge_are_inconsistent() {
    // Arrange: a background at 8 px, a box at 20 px over columns 40..100, rows 20..100.
    let app = spawn_app().await;
    let mut scene = plane_scene(8.0);
    scene.planes.push(Plane {
        disparity: [20.0, 0.0, 0.0],
        region: Region::Rect {
            x0: 40.0,
            y0: 20.0,
            x1: 100.0,
            y1: 100.0,
        },
        seed: 9,
        tint: [1.0, 0.8, 0.7],
    });
    let pair = synthetic::render(&scene);
    // Act
    let found = matches(
        &app,
        &pair,
        "?max_disparity=32",
        &[(98, 60), (102, 60), (70, 60)],
    )
    .await;
    // Assert
    assert_eq!(status(&found[0]), "inconsistent", "{}", found[0]);
    assert_eq!(status(&found[1]), "inconsistent", "{}", found[1]);
    assert_eq!(status(&found[2]), "ok", "{}", found[2]);
}

/// Each match's distance is `/distance`'s for the same x, disparity and y with the same rig,
/// to the last digit; and its one error bar (`depth_error` = `distance_std`, with
/// `relative_error`) is `/distance`'s with Δd = the match's σ_d, not the rig's fixed Δd.
#[tokio::test]
async fn distances_are_those_of_distance() {
    let app = spawn_app().await;
    let pair = pair();
    let found = matches(&app, &pair, "?max_disparity=48", &[(50, 60), (130, 100)]).await;
    for m in &found {
        let d = m["disparity_px"].as_f64().expect("a disparity");
        let s = m["disparity_std_px"].as_f64().expect("a σ_d");
        let rig = json!({"focal_length_px": 500, "baseline": 100, "unit": "mm",
                         "image_width": W, "image_height": H,
                         "x_left": m["x"], "disparity_px": d, "y": m["y"]});
        let mut with_sigma = rig.clone();
        with_sigma["disparity_error_px"] = json!(s);
        let distance = ok_json(app.post("/distance", &with_sigma).await).await;
        let fixed = ok_json(app.post("/distance", &rig).await).await;
        assert_eq!(m["depth_error"], m["distance_std"], "{m}");
        assert_ne!(m["depth_error"], fixed["depth_error"], "{m}");
        assert!(
            (s - 0.5).abs() > 1e-3,
            "σ_d {s} would not tell the bars apart"
        );
        for field in [
            "distance",
            "range",
            "depth_error",
            "relative_error",
            "point",
        ] {
            assert_eq!(m[field], distance[field], "{field}: {m} against {distance}");
        }
        // Z = B·f / d with f = 500 px and B = 100 mm.
        let z = m["distance"].as_f64().unwrap();
        assert!((z - 50_000.0 / d).abs() < 1e-6 * z);
    }
}

/// A box on the box plane (22 px) answers its depth, B·f / 22, with p10 ≤ median ≤ p90 and the
/// point at the box's centre; a box off the image is `outside_image`; regions alone are a
/// request.
#[tokio::test]
async fn regions_answer_a_robust_distance() {
    // Arrange
    let app = spawn_app().await;
    let pair = pair();
    let regions = json!([{"x": 32, "y": 35, "width": 30, "height": 40},
                         {"x": 500, "y": 10, "width": 20, "height": 20}]);
    // Act
    let body = answer(
        &app,
        &pair,
        "?max_disparity=48",
        &[("regions", regions.to_string())],
    )
    .await;
    // Assert
    assert_eq!(body["matches"], json!([]));
    let on = &body["regions"][0];
    assert_eq!(on["status"], "ok");
    let z = on["distance"].as_f64().unwrap();
    let truth = 50_000.0 / 22.0;
    assert!((z - truth).abs() < 0.01 * truth, "{on}");
    let (p10, p90) = (
        on["distance_p10"].as_f64().unwrap(),
        on["distance_p90"].as_f64().unwrap(),
    );
    assert!(p10 <= z && z <= p90 && p90 - p10 < 0.05 * truth, "{on}");
    assert!(on["valid_fraction"].as_f64().unwrap() > 0.9, "{on}");
    assert_eq!(on["point"]["z"], on["distance"]);
    // The box's centre: pixels 32..62 and 35..75, so (46.5, 54.5), and cx = 80.
    let x = on["point"]["x"].as_f64().unwrap();
    assert!((x - (46.5 - 80.0) * z / 500.0).abs() < 1e-9, "{on}");
    assert!(on["range"].as_f64().unwrap() > z);
    assert!(on["depth_error"].as_f64().unwrap() > 0.0);
    // The median of 1 200 pixels (19 census windows) knows its disparity better than a pixel
    // does, and its σ_Z follows: Z²·σ_d / (f·B).
    let s = on["disparity_std_px"].as_f64().unwrap();
    assert!(s > 0.0 && s < 0.1, "{on}");
    let sz = on["distance_std"].as_f64().unwrap();
    assert!((sz - z * z * s / 50_000.0).abs() <= 1e-9 * sz, "{on}");
    assert_eq!(on["depth_error"], on["distance_std"]);
    let off = &body["regions"][1];
    assert_eq!(off["status"], "outside_image");
    assert!(off.get("distance").is_none());
}

/// Malformed points and regions are one 422 naming each member: a missing coordinate, a wrong
/// type, an unknown member, a box of no width, an item that is no object.
#[tokio::test]
async fn bad_points_and_regions_are_named() {
    let app = spawn_app().await;
    let pair = pair();
    let points = r#"[{"x": 1, "y": 2}, {"x": 1}, {"x": "a", "y": 2}, {"x": 1, "y": 2, "z": 3}, 7]"#;
    let regions = r#"[{"x": 0, "y": 0, "width": 0, "height": 5}]"#;
    let body = problem(
        post_match(
            &app,
            "",
            form(
                &pair,
                &[("points", points.into()), ("regions", regions.into())],
            ),
        )
        .await,
        422,
    )
    .await;
    assert_names(
        &body,
        &[
            "points[1].y",
            "points[2].x",
            "points[3].z",
            "points[4]",
            "regions[0].width",
        ],
    );
    assert_eq!(fields(&body).len(), 5, "{body}");
    assert!(message_for(&body, "points[1].y").contains("required"));
    assert!(message_for(&body, "regions[0].width").contains("greater than 0"));
}

/// No points and no regions, points that are no array, too many points, no rig and a wrong
/// rig: each named, once.
#[tokio::test]
async fn the_form_itself_is_checked() {
    let app = spawn_app().await;
    let pair = pair();
    let body = problem(post_match(&app, "", form(&pair, &[])).await, 422).await;
    assert_eq!(fields(&body), vec!["points"]);
    let body = problem(
        post_match(&app, "", form(&pair, &[("points", r#""(1, 2)""#.into())])).await,
        422,
    )
    .await;
    assert!(message_for(&body, "points").contains("array"), "{body}");
    let many = Value::from(vec![json!({"x": 1, "y": 1}); 10_001]).to_string();
    let body = problem(
        post_match(&app, "", form(&pair, &[("points", many)])).await,
        422,
    )
    .await;
    assert!(message_for(&body, "points").contains("10000"), "{body}");
    let no_rig = Form::new()
        .part("left", image_part(png(&pair.left_rgb, W, H)))
        .part("right", image_part(png(&pair.right_rgb, W, H)))
        .text("points", r#"[{"x": 1, "y": 2}]"#);
    let body = problem(post_match(&app, "", no_rig).await, 422).await;
    assert_eq!(fields(&body), vec!["rig"]);
    // A rig that is there but wrong is named by its member alone, not as missing.
    let bad_rig = Form::new()
        .part("left", image_part(png(&pair.left_rgb, W, H)))
        .part("right", image_part(png(&pair.right_rgb, W, H)))
        .text("rig", r#"{"focal_length_px": 500, "baseline": 0}"#)
        .text("points", r#"[{"x": 1, "y": 2}]"#);
    let body = problem(post_match(&app, "", bad_rig).await, 422).await;
    assert_eq!(fields(&body), vec!["rig.baseline"]);
}

/// A request that could never fit in the heavy group's memory budget is a 413 naming the image
/// and saying what to shrink; a narrower range that fits is answered.
#[tokio::test]
async fn a_request_beyond_the_memory_budget_is_413() {
    let app = spawn_app_with(Config {
        port: 0,
        heavy: HeavyLimits {
            memory_budget: 3 << 20,
            body_bytes: 1 << 20,
            ..HeavyLimits::default()
        },
        ..Config::default()
    })
    .await;
    let pair = pair();
    let points = || vec![("points", r#"[{"x": 50, "y": 60}]"#.to_owned())];
    let body = problem(
        post_match(&app, "?max_disparity=512", form(&pair, &points())).await,
        413,
    )
    .await;
    // The same words as /depth-map's: the image, and the range that would fit.
    assert_eq!(fields(&body), vec!["left", "max_disparity"]);
    assert!(message_for(&body, "left").contains("narrower"), "{body}");
    assert!(
        message_for(&body, "max_disparity").contains("at most"),
        "{body}"
    );
    let fits = post_match(&app, "?max_disparity=32", form(&pair, &points())).await;
    assert_eq!(fits.status(), 200);
}

/// One fronto-parallel textured plane at disparity `d` over the whole image, rendered.
fn plane_pair(d: f32) -> Pair {
    synthetic::render(&plane_scene(d))
}

/// One fronto-parallel textured plane at disparity `d` over the whole image.
fn plane_scene(d: f32) -> Scene {
    Scene {
        width: W,
        height: H,
        planes: vec![Plane {
            disparity: [d, 0.0, 0.0],
            region: Region::Everywhere,
            seed: 5,
            tint: [1.0, 1.0, 1.0],
        }],
        gain: 1.0,
        offset: 0.0,
        noise: 0.0,
        seed: 3,
    }
}

/// Phone photos with an EXIF orientation are matched as shown: the answer's size is the
/// turned one, and points match where they match on the pair as stored.
#[tokio::test]
async fn exif_orientation_is_applied() {
    let app = spawn_app().await;
    let pair = pair();
    let points =
        r#"[{"x": 40, "y": 30}, {"x": 120, "y": 30}, {"x": 60, "y": 90}, {"x": 120, "y": 90}]"#;
    let photos = Form::new()
        .part("left", jpeg_part(phone_photo(&pair.left_rgb)))
        .part("right", jpeg_part(phone_photo(&pair.right_rgb)))
        .text("rig", rig().to_string())
        .text("points", points);
    let body = ok_json(post_match(&app, "?max_disparity=48", photos).await).await;
    assert_eq!(
        (body["width"].as_u64(), body["height"].as_u64()),
        (Some(160), Some(120))
    );
    let stored = answer(
        &app,
        &pair,
        "?max_disparity=48",
        &[("points", points.to_owned())],
    )
    .await;
    let mut compared = 0;
    for (photo, png) in body["matches"]
        .as_array()
        .unwrap()
        .iter()
        .zip(stored["matches"].as_array().unwrap())
    {
        if status(photo) == "ok" && status(png) == "ok" {
            let d = |m: &Value| m["disparity_px"].as_f64().unwrap();
            assert!((d(photo) - d(png)).abs() < 0.5, "{photo} vs {png}");
            compared += 1;
        }
    }
    assert!(compared >= 2, "{body} {stored}");
}

/// A pair sent swapped (the right camera's image as left) has its scene at negative
/// disparities, below any range searched: no point is answered `ok` with a distance (each is
/// `out_of_range`, which withholds it, or keeps `ambiguous`), no box gets a median, and the
/// warnings name the swap; the same points and box the right way round are answered.
#[tokio::test]
async fn a_swapped_pair_answers_no_distance_and_says_why() {
    let app = spawn_app().await;
    let sent = pair();
    let points: Vec<Value> = grid()
        .into_iter()
        .step_by(7)
        .map(|(x, y)| json!({"x": x, "y": y}))
        .collect();
    let parts = |left: &[u8], right: &[u8]| {
        Form::new()
            .part("left", image_part(png(left, W, H)))
            .part("right", image_part(png(right, W, H)))
            .text("rig", rig().to_string())
            .text("points", Value::from(points.clone()).to_string())
            .text(
                "regions",
                json!([{"x": 40, "y": 30, "width": 80, "height": 60}]).to_string(),
            )
    };

    let right_way =
        ok_json(post_match(&app, "", parts(&sent.left_rgb, &sent.right_rgb)).await).await;
    let swapped = ok_json(post_match(&app, "", parts(&sent.right_rgb, &sent.left_rgb)).await).await;

    let ok = |body: &Value| {
        body["matches"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|m| status(m) == "ok" && m.get("distance").is_some())
            .count()
    };
    assert!(ok(&right_way) * 2 > points.len(), "{right_way}");
    assert!(
        right_way["regions"][0].get("distance").is_some(),
        "{right_way}"
    );
    assert!(!right_way["warnings"].to_string().contains("swapped"));
    assert!(
        swapped["warnings"]
            .to_string()
            .contains("left and right look swapped"),
        "{swapped}"
    );
    assert_eq!(ok(&swapped), 0, "{swapped}");
    for m in swapped["matches"].as_array().unwrap() {
        match status(m) {
            "ambiguous" => assert!(m["confidence"].as_f64() < Some(0.5), "{m}"),
            other => {
                assert!(["out_of_range", "outside_image"].contains(&other), "{m}");
                assert!(m.get("distance").is_none(), "{m}");
            }
        }
    }
    assert!(swapped["regions"][0].get("distance").is_none(), "{swapped}");
}
