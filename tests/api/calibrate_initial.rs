//! `POST /calibrate` with `initial`: an earlier calibration's lenses held, so that one view of
//! the board finds a knocked rig's R and T again, with how far it moved and its σ; and each
//! mistake with an earlier calibration named.

use nalgebra::{Rotation3, Vector3};
use reqwest::multipart::{Form, Part};
use stereo_core::camera::{RectifyOptions, StereoPair, stereo_rectify};

use crate::calibrate::{BOARD, SIZE, image, rendered_views, truth, views};
use crate::helpers::{TestApp, assert_names, message_for, ok_json, problem, spawn_app};

/// The truth knocked: the right camera turned 0.3° about y and 0.1° about x, and moved 1 mm
/// along the baseline.
fn knocked() -> StereoPair {
    let mut pair = truth();
    let turn = Rotation3::from_scaled_axis(Vector3::new(0.1, 0.3, 0.0).map(f64::to_radians));
    pair.rotation = turn * pair.rotation;
    pair.translation += Vector3::new(-1.0, 0.0, 0.0);
    pair
}

/// `count` views of the knocked rig, as PNG pairs.
fn knocked_views(count: usize, seed: u64) -> Vec<(Vec<u8>, Vec<u8>)> {
    rendered_views(&knocked(), count, seed)
}

pub(crate) fn views_form(views: &[(Vec<u8>, Vec<u8>)], board: &str) -> Form {
    let mut form = Form::new();
    for (i, (l, r)) in views.iter().enumerate() {
        form = form
            .part("left", image(l, &format!("left{i}.png")))
            .part("right", image(r, &format!("right{i}.png")));
    }
    form.text("board", board.to_owned())
}

fn initial_part(yaml: &str) -> Part {
    Part::bytes(yaml.as_bytes().to_vec()).file_name("opencv.yml")
}

/// The earlier calibration: the eight rendered views of the true rig, as `/calibrate`'s
/// opencv.yml (it carries its unit and σ).
async fn earlier(app: &TestApp) -> String {
    let mut form = Form::new();
    for (i, (l, r)) in views().iter().enumerate() {
        form = form
            .part("left", image(l, &format!("left{i}.png")))
            .part("right", image(r, &format!("right{i}.png")));
    }
    let response = app
        .post_form("/calibrate?output=opencv.yml", form.text("board", BOARD))
        .await;
    assert_eq!(response.status(), 200);
    response.text().await.unwrap()
}

/// R's turn from `a` to `b`, degrees about x, y, z.
fn turn_deg(a: &Rotation3<f64>, b: &Rotation3<f64>) -> Vector3<f64> {
    (b * a.inverse()).scaled_axis().map(f64::to_degrees)
}

fn rotation(summary: &serde_json::Value) -> Rotation3<f64> {
    let r = |i: usize, j: usize| summary["rotation"][i][j].as_f64().unwrap();
    Rotation3::from_matrix(&nalgebra::Matrix3::from_fn(r))
}

/// Three views of a knocked rig, with the earlier calibration's lenses held, find how it
/// turned since within 0.02° about each axis and its baseline within 0.3 %, its rows within
/// 0.1 px; the lenses are the earlier ones exactly; the rig's σ holds the earlier
/// calibration's. One view finds the turn within 3σ, says its σ are wide and why; without
/// `initial`, one view is refused as too few.
#[tokio::test]
async fn a_few_views_find_a_knocked_rigs_r_and_t_again() {
    let app = spawn_app().await;
    let yaml = earlier(&app).await;
    let before = ok_json(
        app.post_form("/calibrate", views_form(&views()[..], BOARD))
            .await,
    )
    .await;
    let knock = [0.1, 0.3, 0.0];
    let truth = knocked();
    let three = knocked_views(3, 21);
    let summary = ok_json(
        app.post_form(
            "/calibrate",
            views_form(&three, BOARD).part("initial", initial_part(&yaml)),
        )
        .await,
    )
    .await;
    let since = &summary["since_initial"];
    assert_eq!(since["refined"], "extrinsics", "{since}");
    for (axis, want) in knock.iter().enumerate() {
        let got = since["rotation_deg"][axis].as_f64().unwrap();
        assert!(
            (got - want).abs() < 0.02,
            "turned {got}° about axis {axis}, not {want}°"
        );
    }
    let t: Vec<f64> = (0..3)
        .map(|i| summary["translation"][i].as_f64().unwrap())
        .collect();
    let baseline = Vector3::from_column_slice(&t).norm();
    assert!(
        (baseline / truth.translation.norm() - 1.0).abs() < 0.003,
        "B {baseline} vs {}",
        truth.translation.norm()
    );
    assert!((since["baseline_after"].as_f64().unwrap() - baseline).abs() < 1e-9);
    assert!(
        summary["epipolar_error"].as_f64().unwrap() < 0.1,
        "{summary}"
    );
    // The lenses are held: the earlier calibration's, to the file's precision.
    for side in ["left", "right"] {
        for (a, b) in [(0, 0), (1, 1), (0, 2), (1, 2)] {
            let (got, was) = (
                summary[side]["camera_matrix"][a][b].as_f64().unwrap(),
                before[side]["camera_matrix"][a][b].as_f64().unwrap(),
            );
            assert!(
                (got - was).abs() < 1e-6,
                "{side} K[{a}][{b}] {got} vs {was}"
            );
        }
        assert_eq!(summary[side]["std"]["fx"], 0.0);
    }
    // The rig's σ keeps the earlier calibration's focal σ, which the held lenses carry.
    let earlier_std = before["rig_std"]["focal_length_px"].as_f64().unwrap();
    let std = summary["rig_std"]["focal_length_px"].as_f64().unwrap();
    assert!(std >= earlier_std * 0.999, "σ_f {std} vs {earlier_std}");
    let said = summary["warnings"].to_string();
    assert!(!said.contains("only 3 views"), "{said}");
    assert!(!said.contains("carries no σ"), "{said}");
    assert!(!said.contains("σ are wide"), "{said}");

    // One view: the turn within 3σ (and the earlier calibration's own 0.01°), and said to be
    // wide.
    for seed in [3, 8, 21] {
        let one = knocked_views(1, seed);
        let summary = ok_json(
            app.post_form(
                "/calibrate",
                views_form(&one, BOARD).part("initial", initial_part(&yaml)),
            )
            .await,
        )
        .await;
        for (axis, want) in knock.iter().enumerate() {
            let got = summary["since_initial"]["rotation_deg"][axis]
                .as_f64()
                .unwrap();
            let sigma = summary["rotation_std_deg"][axis].as_f64().unwrap();
            assert!(
                (got - want).abs() < 3.0 * sigma + 0.01,
                "seed {seed}: turned {got}° about axis {axis}, not {want}° (σ {sigma}°)"
            );
        }
        assert_eq!(summary["views"][0]["status"], "used");
        let said = summary["warnings"].to_string();
        assert!(
            said.contains("from 1 view: in a board at one distance"),
            "{said}"
        );
        assert!(!said.contains("only 1 views"), "{said}");
    }

    // Without the earlier calibration, one view calibrates nothing.
    let one = knocked_views(1, 21);
    let refused = problem(
        app.post_form("/calibrate", views_form(&one, BOARD)).await,
        422,
    )
    .await;
    assert!(
        message_for(&refused, "left").contains("needs at least 3"),
        "{refused}"
    );
}

/// `refine=all` starts every parameter from the earlier calibration and refines it over
/// three views of the knocked rig: R and the rectified focal length within 3σ of the truth,
/// the rows within 0.1 px, and the answer says all moved.
#[tokio::test]
async fn refine_all_starts_from_the_earlier_calibration() {
    let app = spawn_app().await;
    let yaml = earlier(&app).await;
    let three = knocked_views(3, 5);
    let summary = ok_json(
        app.post_form(
            "/calibrate?refine=all",
            views_form(&three, BOARD).part("initial", initial_part(&yaml)),
        )
        .await,
    )
    .await;
    assert_eq!(summary["since_initial"]["refined"], "all");
    let error = turn_deg(&knocked().rotation, &rotation(&summary));
    for axis in 0..3 {
        let sigma = summary["rotation_std_deg"][axis].as_f64().unwrap();
        assert!(
            error[axis].abs() < 3.0 * sigma + 0.01,
            "R off by {}° about axis {axis} (σ {sigma}°)",
            error[axis]
        );
    }
    let f = summary["rig"]["focal_length_px"].as_f64().unwrap();
    let f_std = summary["rig_std"]["focal_length_px"].as_f64().unwrap();
    let expected = stereo_rectify(&knocked(), SIZE, RectifyOptions::default())
        .unwrap()
        .p1[(0, 0)];
    assert!(
        (f - expected).abs() < 3.0 * f_std + 0.5,
        "f {f} ± {f_std} vs {expected}"
    );
    assert!(
        summary["epipolar_error"].as_f64().unwrap() < 0.1,
        "{summary}"
    );
    assert!(summary["left"]["std"]["fx"].as_f64().unwrap() > 0.0);
}

/// The mistakes a user makes with an earlier calibration are each named: one camera's views,
/// a `refine` or an `initial_unit` without one, another lens model asked, a file of
/// rectified images only, one of another size, a board in the wrong unit (the baseline
/// 10× the earlier one's) and the views swapped.
#[tokio::test]
async fn mistakes_with_an_earlier_calibration_are_named() {
    let app = spawn_app().await;
    let yaml = earlier(&app).await;
    let one = knocked_views(1, 21);

    let mut left_only = Form::new().part("left", image(&one[0].0, "left0.png"));
    left_only = left_only
        .text("board", BOARD)
        .part("initial", initial_part(&yaml));
    let named = problem(app.post_form("/calibrate", left_only).await, 422).await;
    assert!(
        message_for(&named, "initial").contains("send a right image"),
        "{named}"
    );

    let named = problem(
        app.post_form(
            "/calibrate?refine=all&model=equidistant",
            views_form(&one, BOARD).text("initial_unit", "mm"),
        )
        .await,
        422,
    )
    .await;
    assert_names(&named, &["refine", "initial_unit"]);

    let named = problem(
        app.post_form(
            "/calibrate?model=equidistant",
            views_form(&one, BOARD).part("initial", initial_part(&yaml)),
        )
        .await,
        422,
    )
    .await;
    assert!(
        message_for(&named, "model").contains("plumb_bob"),
        "{named}"
    );

    let middlebury = "cam0=[360 0 158; 0 360 121; 0 0 1]\ncam1=[360 0 158; 0 360 121; 0 0 1]\n\
                      doffs=0\nbaseline=60\nwidth=320\nheight=240\nndisp=64\n";
    let named = problem(
        app.post_form(
            "/calibrate",
            views_form(&one, BOARD).part("initial", initial_part(middlebury)),
        )
        .await,
        422,
    )
    .await;
    assert!(
        message_for(&named, "initial").contains("rectified images only"),
        "{named}"
    );

    let other_size = yaml.replace("imageSize: [ 320, 240 ]", "imageSize: [ 640, 480 ]");
    assert_ne!(other_size, yaml);
    let named = problem(
        app.post_form(
            "/calibrate",
            views_form(&one, BOARD).part("initial", initial_part(&other_size)),
        )
        .await,
        422,
    )
    .await;
    assert_names(&named, &["initial"]);

    let named = problem(
        app.post_form(
            "/calibrate",
            views_form(&one, BOARD).part("initial", initial_part("not: [a calibration")),
        )
        .await,
        422,
    )
    .await;
    assert_names(&named, &["initial"]);

    // The board's squares typed in cm: the baseline comes out 10× the earlier one's.
    let in_cm = r#"{"columns": 7, "rows": 5, "square_size": 20, "unit": "cm"}"#;
    let summary = ok_json(
        app.post_form(
            "/calibrate",
            views_form(&one, in_cm).part("initial", initial_part(&yaml)),
        )
        .await,
    )
    .await;
    let said = summary["warnings"].to_string();
    assert!(said.contains("× the initial calibration's 6.00"), "{said}");
    assert!(said.contains("came out 61."), "{said}");
    assert!(said.contains("unit typed wrong"), "{said}");

    // The earlier file's unit overridden wrongly: its reader's warnings come through, and
    // the baseline 1000× off is named.
    let summary = ok_json(
        app.post_form(
            "/calibrate",
            views_form(&one, BOARD)
                .part("initial", initial_part(&yaml))
                .text("initial_unit", "m"),
        )
        .await,
    )
    .await;
    let said = summary["warnings"].to_string();
    assert!(
        said.contains("the initial calibration: initial_unit m overrides"),
        "{said}"
    );
    assert!(said.contains("0.001× the initial calibration's"), "{said}");

    // Each view's left and right swapped: the right camera comes out on the left.
    let swapped: Vec<(Vec<u8>, Vec<u8>)> =
        one.iter().map(|(l, r)| (r.clone(), l.clone())).collect();
    let response = app
        .post_form(
            "/calibrate",
            views_form(&swapped, BOARD).part("initial", initial_part(&yaml)),
        )
        .await;
    let said = match response.status().as_u16() {
        200 => ok_json(response).await["warnings"].to_string(),
        _ => problem(response, 422).await.to_string(),
    };
    assert!(
        said.contains("swapped") || said.contains("left of the left"),
        "{said}"
    );
}

/// Past 60 views is a 422 naming the part, as the form's `maxItems` says.
#[tokio::test]
async fn past_sixty_views_is_named() {
    let app = spawn_app().await;
    let (l, r) = &views()[0];
    let mut form = Form::new();
    for i in 0..61 {
        form = form
            .part("left", image(l, &format!("left{i}.png")))
            .part("right", image(r, &format!("right{i}.png")));
    }
    let named = problem(
        app.post_form("/calibrate", form.text("board", BOARD)).await,
        422,
    )
    .await;
    assert!(
        message_for(&named, "left").contains("at most 60"),
        "{named}"
    );
    assert!(
        message_for(&named, "right").contains("at most 60"),
        "{named}"
    );
}
