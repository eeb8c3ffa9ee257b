//! One rig, whichever way it arrives: a rig that `/distance` refuses is refused by
//! `/calibration`, `/depth-map` and `/match` with the same message, its members named `rig.…`
//! where the rig is a part or an answer, and a valid rig is answered alike everywhere.

use reqwest::multipart::Form;
use serde_json::{Value, json};

use crate::depth_map::{H, W, image_part, pair, png};
use crate::helpers::{TestApp, fields, message_for, ok_json, problem, spawn_app};

/// Motorcycle's `calib.txt` with its principal point moved off its own 2964-px-wide image.
const OFF_IMAGE: &str = "cam0=[3979.911 0 3100; 0 3979.911 1019.507; 0 0 1]\n\
                         cam1=[3979.911 0 3224.343; 0 3979.911 1019.507; 0 0 1]\n\
                         doffs=124.343\nbaseline=193.001\nwidth=2964\nheight=2000\nndisp=270\n";

/// The same rig as `/distance` members.
fn off_image_members() -> Value {
    json!({"focal_length_px": 3979.911, "baseline": 193.001, "cx": 3100, "cy": 1019.507,
           "doffs": 124.343, "image_width": 2964, "image_height": 2000, "disparity_px": 100})
}

/// The synthetic pair with `extra` text parts, and points for `/match`.
fn form(extra: &[(&str, String)], points: bool) -> Form {
    let pair = pair();
    let mut form = Form::new()
        .part("left", image_part(png(&pair.left_rgb, W, H)))
        .part("right", image_part(png(&pair.right_rgb, W, H)));
    if points {
        form = form.text("points", r#"[{"x": 80, "y": 60}]"#);
    }
    for (name, text) in extra {
        form = form.text(name.to_string(), text.clone());
    }
    form
}

/// `/depth-map` and `/match` on the synthetic pair with `extra` parts: each answer's problem.
async fn image_problems(app: &TestApp, extra: &[(&str, String)]) -> [Value; 2] {
    let depth = app
        .post_form("/depth-map?output=depth.npy", form(extra, false))
        .await;
    let matched = app.post_form("/match", form(extra, true)).await;
    [problem(depth, 422).await, problem(matched, 422).await]
}

/// A calibration file whose principal point lies off its own image: `/distance` refuses the
/// same members by `cx`; `/calibration`, and the `calibration` part of `/depth-map` and
/// `/match`, refuse the file by `rig.cx`, with the same message.
#[tokio::test]
async fn a_principal_point_off_the_image_is_refused_everywhere() {
    let app = spawn_app().await;
    let distance = problem(app.post("/distance", &off_image_members()).await, 422).await;
    assert_eq!(fields(&distance), ["cx"]);
    let message = message_for(&distance, "cx").to_owned();
    assert!(message.contains("[0, 2964]"), "{message}");

    let calibration = problem(
        app.post("/calibration", &json!({"text": OFF_IMAGE})).await,
        422,
    )
    .await;
    assert_eq!(fields(&calibration), ["rig.cx"]);
    assert_eq!(message_for(&calibration, "rig.cx"), message);

    for answer in image_problems(&app, &[("calibration", OFF_IMAGE.to_owned())]).await {
        assert_eq!(fields(&answer), ["rig.cx"], "{answer}");
        assert_eq!(message_for(&answer, "rig.cx"), message);
    }
}

/// A focal length and baseline whose product overflows: `/distance` names both; the `rig`
/// part of `/depth-map` and `/match` names both as `rig.…`, with the same message.
#[tokio::test]
async fn a_rig_out_of_range_is_refused_everywhere() {
    let app = spawn_app().await;
    let rig = json!({"focal_length_px": 1e300, "baseline": 1e300, "unit": "mm"});
    let mut members = rig.clone();
    members["disparity_px"] = json!(10);
    members["image_width"] = json!(W);
    members["image_height"] = json!(H);
    let distance = problem(app.post("/distance", &members).await, 422).await;
    assert_eq!(fields(&distance), ["focal_length_px", "baseline"]);
    let message = message_for(&distance, "baseline").to_owned();
    assert!(message.contains("too far apart"), "{message}");

    for answer in image_problems(&app, &[("rig", rig.to_string())]).await {
        assert_eq!(
            fields(&answer),
            ["rig.focal_length_px", "rig.baseline"],
            "{answer}"
        );
        assert_eq!(message_for(&answer, "rig.baseline"), message);
    }
}

/// A valid calibration file gives the same rig through `/calibration` as through the image
/// routes' `calibration` part (echoed in their answers, sized to the images).
#[tokio::test]
async fn a_valid_file_gives_the_same_rig_everywhere() {
    let app = spawn_app().await;
    let text = format!(
        "cam0=[500 0 80; 0 500 60; 0 0 1]\ncam1=[500 0 80; 0 500 60; 0 0 1]\ndoffs=0\n\
         baseline=100\nwidth={W}\nheight={H}\nndisp=48\n"
    );
    let read = ok_json(app.post("/calibration", &json!({"text": text})).await).await;
    let summary = ok_json(
        app.post_form("/depth-map", form(&[("calibration", text.clone())], false))
            .await,
    )
    .await;
    assert_eq!(summary["rig"], read["rig"]);
    assert_eq!(summary["max_disparity"], 48);
    let matched = ok_json(
        app.post_form("/match", form(&[("calibration", text)], true))
            .await,
    )
    .await;
    assert_eq!(matched["rig"], read["rig"]);
}
