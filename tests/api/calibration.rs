//! `/calibration`: every reference calibration reproduces its rig over HTTP, the rig goes back
//! to `/distance` as it is, and every kind of bad file is a 422 that names the file and line.
//!
//! The reference files and `expected.json` are the project's copies of
//! `shared/vectors/calibration/` (in `tests/data/calibration/`); when the shared folder is
//! beside the project, its cases are run as well.

use std::path::{Path, PathBuf};

use serde_json::{Map, Value, json};

use crate::helpers::{
    TestApp, assert_close, fields, message_for, number_at, ok_json, problem, spawn_app,
};

fn data(dir: &Path, name: &str) -> String {
    std::fs::read_to_string(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn own_vectors() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/calibration")
}

/// The folders of reference vectors: the project's copy, and the shared one when present.
fn vector_dirs() -> Vec<PathBuf> {
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/vectors/calibration");
    let mut dirs = vec![own_vectors()];
    if shared.join("expected.json").is_file() {
        dirs.push(shared);
    }
    dirs
}

/// The JSON request of a case: `text_file` and `right_text_file` read into `text` and
/// `right_text`, other members as they are.
fn request_of(dir: &Path, case: &Value) -> Value {
    let mut request = Map::new();
    for (key, value) in case["request"].as_object().unwrap() {
        match key.as_str() {
            "text_file" => request.insert("text".into(), data(dir, value.as_str().unwrap()).into()),
            "right_text_file" => request.insert(
                "right_text".into(),
                data(dir, value.as_str().unwrap()).into(),
            ),
            _ => request.insert(key.clone(), value.clone()),
        };
    }
    Value::Object(request)
}

async fn calibrate(app: &TestApp, request: &Value) -> Value {
    ok_json(app.post("/calibration", request).await).await
}

/// Every case of `expected.json`: the format, `max_disparity_px`, and exactly the expected rig
/// members (1e-6 relative; 1e-4 for a KITTI baseline, whose tz terms move it by 2e-5); then
/// the answered rig, sent back to `/distance` with a disparity, gives Z = B·f / (d + doffs),
/// and the case's own distance where it gives one.
#[tokio::test]
async fn reference_calibrations_reproduce_and_round_trip() {
    let app = spawn_app().await;
    for dir in vector_dirs() {
        let expected: Value = serde_json::from_str(&data(&dir, "expected.json")).unwrap();
        let cases = expected["cases"].as_array().unwrap();
        assert!(cases.len() >= 6, "{dir:?} has the cases");
        for case in cases {
            // Arrange
            let name = case["name"].as_str().unwrap();
            let request = request_of(&dir, case);

            // Act
            let body = calibrate(&app, &request).await;

            // Assert
            assert_eq!(body["format"], case["format"], "{name}: format");
            if let Some(ndisp) = case.get("max_disparity_px") {
                assert_eq!(&body["max_disparity_px"], ndisp, "{name}: max_disparity_px");
            } else if body["format"] != "middlebury" {
                assert!(body.get("max_disparity_px").is_none(), "{name}: none given");
            }
            let rig = body["rig"].as_object().unwrap();
            let want = case["rig"].as_object().unwrap();
            let mut got: Vec<&String> = rig.keys().collect();
            let mut wanted: Vec<&String> = want.keys().collect();
            got.sort();
            wanted.sort();
            assert_eq!(got, wanted, "{name}: exactly the members the file gives");
            for (member, value) in want {
                if let Some(text) = value.as_str() {
                    assert_eq!(rig[member], text, "{name}: {member}");
                    continue;
                }
                let (got, want) = (rig[member].as_f64().unwrap(), value.as_f64().unwrap());
                let tolerance = if body["format"] == "kitti" && member == "baseline" {
                    1e-4
                } else {
                    1e-6
                };
                assert!(
                    (got - want).abs() <= tolerance * want.abs().max(1e-12),
                    "{name}: {member} = {got}, expected {want}"
                );
            }
            // The rig goes back to /distance unchanged, with a disparity added.
            let d = case["then"]["disparity_px"].as_f64().unwrap_or(50.0);
            let mut distance_request = body["rig"].clone();
            distance_request["disparity_px"] = json!(d);
            let answer = ok_json(app.post("/distance", &distance_request).await).await;
            let fb = number_at(&body, "rig.focal_length_px") * number_at(&body, "rig.baseline");
            let z = fb / (d + number_at(&body, "rig.doffs"));
            assert_close(number_at(&answer, "distance"), z, name);
            assert_eq!(answer["unit"], body["rig"]["unit"], "{name}: unit");
            if let Some(distance) = case["then"]["distance"].as_f64() {
                assert!(
                    (number_at(&answer, "distance") - distance).abs() <= 1e-6 * distance,
                    "{name}: the case's distance"
                );
            }
        }
        for case in expected["errors"].as_array().unwrap() {
            let name = case["name"].as_str().unwrap();
            let status = case["status"].as_u64().unwrap() as u16;
            let body = problem(
                app.post("/calibration", &request_of(&dir, case)).await,
                status,
            )
            .await;
            let want: Vec<String> = serde_json::from_value(case["fields"].clone()).unwrap();
            assert_eq!(fields(&body), want, "{name}");
        }
    }
}

/// The KITTI colour baseline is (P_rect_02[0,3] − P_rect_03[0,3]) / f = 0.5327 m, not the
/// −P_rect_03[0,3] / f = 0.4706 m that ignores camera 2's own offset.
#[tokio::test]
async fn kitti_baseline_takes_both_projections() {
    let app = spawn_app().await;
    let text = data(&own_vectors(), "kitti_raw_calib_cam_to_cam.txt");
    let body = calibrate(&app, &json!({"text": text})).await;
    let baseline = number_at(&body, "rig.baseline");
    assert!((baseline - (44.85728 + 339.5242) / 721.5377).abs() < 1e-9);
    assert!((baseline - 339.5242 / 721.5377).abs() > 0.06);
}

/// Each single-file format can be sent as the raw file with `Content-Type: text/plain`, its
/// options in the query.
#[tokio::test]
async fn raw_text_bodies_with_query_options() {
    let app = spawn_app().await;
    let dir = own_vectors();
    for (query, file, format, baseline) in [
        ("", "middlebury_motorcycle_calib.txt", "middlebury", 193.001),
        (
            "?unit=m",
            "middlebury_motorcycle_calib.txt",
            "middlebury",
            0.193001,
        ),
        (
            "?cameras=0-1",
            "kitti_raw_calib_cam_to_cam.txt",
            "kitti",
            0.5371506,
        ),
        (
            "?calibration_unit=mm",
            "opencv_stereo.yml",
            "opencv",
            60.002083297165605,
        ),
        (
            "?calibration_unit=mm&unit=cm",
            "opencv_stereo_p1p2.xml",
            "opencv",
            12.0,
        ),
    ] {
        let response = app
            .post_raw(
                &format!("/calibration{query}"),
                Some("text/plain; charset=utf-8"),
                data(&dir, file).into_bytes(),
            )
            .await;
        let body = ok_json(response).await;
        assert_eq!(body["format"], format, "{file}{query}");
        assert!(
            (number_at(&body, "rig.baseline") - baseline).abs() < 1e-6 * baseline,
            "{file}{query}: {body}"
        );
    }
}

/// OpenCV's XML after stereoRectify, read from P1 and P2: fy ≠ fx is answered as
/// `focal_length_y_px`, and doffs is P2[0,2] − P1[0,2].
#[tokio::test]
async fn opencv_xml_from_projections() {
    let app = spawn_app().await;
    let text = data(&own_vectors(), "opencv_stereo_p1p2.xml");
    let body = calibrate(&app, &json!({"text": text, "calibration_unit": "mm"})).await;
    assert_eq!(
        body["rig"],
        json!({"focal_length_px": 900.0, "focal_length_y_px": 905.0, "baseline": 120.0,
               "unit": "mm", "cx": 640.0, "cy": 360.0, "doffs": 10.0,
               "image_width": 1280, "image_height": 720})
    );
}

/// The stereo file's cameras and R, T alone (no rectification, no size): the first 37 lines
/// of `opencv_stereo.yml`.
fn bare_stereo_file() -> String {
    data(&own_vectors(), "opencv_stereo.yml")
        .lines()
        .take(37)
        .collect::<Vec<_>>()
        .join("\n")
}

/// OpenCV's `stereo_calib` sample writes its cameras without the image size: `/calibration`
/// takes `image_width` and `image_height` beside the text (in the JSON body or the query),
/// and reads `imageSize` as C++ writes it (`[1280, 720]`) and as Python's `fs.write` writes
/// it (a 2 × 1 `!!opencv-matrix`); all three give the rig of the file with its size.
#[tokio::test]
async fn a_bare_file_takes_the_image_size_beside_it() {
    let app = spawn_app().await;
    let full = calibrate(
        &app,
        &json!({"text": data(&own_vectors(), "opencv_stereo.yml"), "calibration_unit": "mm", "alpha": 0}),
    )
    .await;
    let bare = bare_stereo_file();
    let refused = problem(
        app.post(
            "/calibration",
            &json!({"text": bare, "calibration_unit": "mm"}),
        )
        .await,
        422,
    )
    .await;
    assert!(
        message_for(&refused, "text").contains("image_width"),
        "{refused}"
    );
    let python = format!(
        "{bare}\nimageSize: !!opencv-matrix\n   rows: 2\n   cols: 1\n   dt: i\n   data: [ 1280, 720 ]\n"
    );
    let cpp = format!("{bare}\nimageSize: [ 1280, 720 ]\n");
    for request in [
        json!({"text": bare, "calibration_unit": "mm", "image_width": 1280, "image_height": 720}),
        json!({"text": python, "calibration_unit": "mm"}),
        json!({"text": cpp, "calibration_unit": "mm"}),
    ] {
        let body = calibrate(&app, &request).await;
        assert_eq!(body["raw_cameras"], true, "{request}");
        for member in [
            "focal_length_px",
            "baseline",
            "cx",
            "cy",
            "image_width",
            "image_height",
        ] {
            assert_close(
                number_at(&body, &format!("rig.{member}")),
                number_at(&full, &format!("rig.{member}")),
                member,
            );
        }
    }
    let query = app
        .post_raw(
            "/calibration?calibration_unit=mm&image_width=1280&image_height=720",
            Some("text/plain"),
            bare.clone().into_bytes(),
        )
        .await;
    assert_eq!(ok_json(query).await["rig"]["image_width"], 1280);
    let half = problem(
        app.post(
            "/calibration",
            &json!({"text": bare, "calibration_unit": "mm", "image_width": 0}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&half), ["image_width", "image_height"]);
    // A body size the query overrides is still checked: it was sent.
    let overridden = problem(
        app.post(
            "/calibration?image_width=1280&image_height=720",
            &json!({"text": bare, "calibration_unit": "mm", "image_height": 0}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&overridden), ["image_height"]);
}

/// A ROS 2 `ros2 topic echo` pair (flat `k`, `p`, block lists) reads like the ROS 1 YAML;
/// swapped files are refused, naming both.
#[tokio::test]
async fn ros2_messages_and_swapped_files() {
    let app = spawn_app().await;
    let dir = own_vectors();
    let (left, right) = (data(&dir, "ros2_left.yaml"), data(&dir, "ros2_right.yaml"));
    let body = calibrate(&app, &json!({"text": left, "right_text": right})).await;
    assert_eq!(body["format"], "ros");
    assert_close(number_at(&body, "rig.baseline"), 0.12, "B = 60 / 500 m");
    assert_close(number_at(&body, "rig.doffs"), 4.0, "doffs");
    assert_eq!(body["rig"]["image_width"], 640);

    let swapped = json!({"text": right, "right_text": left});
    let body = problem(app.post("/calibration", &swapped).await, 422).await;
    assert_eq!(fields(&body), ["text", "right_text"]);
    assert!(message_for(&body, "text").contains("swapped"));
}

/// Bad files name the file, the line and what was expected there; nothing is a 500.
#[tokio::test]
async fn bad_files_name_the_line() {
    let app = spawn_app().await;
    let cases = [
        (
            json!({"text": "cam0=[1 0 2; 0 1 3; 0 0 1]\r\ndoffs=3\r\ncam1=[1 0 2; 0 1 3]\r\nbaseline=5\r\n"}),
            "text",
            "line 3: cam1 must be a 3×3 matrix [a b c; d e f; g h i]",
        ),
        (
            json!({"text": "P_rect_02: 1 0 2 0 0 1 3 0 0 0 1 0\nP_rect_03: 1 0 2 x 0 1 3 0 0 0 1 0\n"}),
            "text",
            "line 2: P_rect_03 must be a list of numbers",
        ),
        (
            json!({"text": "P_rect_02: 1 0 2 0 0 1 3 0 0 0 1 0\nP_rect_03: 1 0 2 -1\n"}),
            "text",
            "line 2: P_rect_03 must be a 3×4 projection matrix of 12 numbers, got 4",
        ),
        (
            json!({"text": "%YAML:1.0\n---\nQ: !!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   data: [ 1., 0., 0. ]\n",
                   "calibration_unit": "mm"}),
            "text",
            "line 7: Q.data must hold 16 numbers (4×4), got 3",
        ),
        (
            json!({"text": "projection_matrix:\n  data: [1, 0, 2, 0, 0, 1, 3, 0, 0, 0, 1, 0]\n",
                   "right_text": "projection_matrix:\n  data: [1, 0, 2, -1, 0, 1, 3\n"}),
            "right_text",
            "line 2: a list opened with `[` is not closed with `]`",
        ),
        (
            json!({"text": "P0: 1 0 2 0 0 1 3 0 0 0 1 0\nP1: 1 0 2 -1 0 1 3 0 0 0 1 0\n",
                   "cameras": "2-3"}),
            "text",
            "no projection for cameras 2 and 3",
        ),
        (
            json!({"text": "cam0=[1 0 2; 0 1 3; 0 0 1]\ncam1=[1 0 2; 0 1 3; 0 0 1]\nbaseline=-4\n"}),
            "text",
            "the baseline must be greater than 0, got -4",
        ),
    ];
    for (request, field, message) in cases {
        let body = problem(app.post("/calibration", &request).await, 422).await;
        assert_eq!(fields(&body), [field], "{request}");
        assert!(
            message_for(&body, field).starts_with(message)
                || message_for(&body, field).contains(message),
            "{}: {}",
            message,
            message_for(&body, field)
        );
    }
}

/// The envelope: `text` is required, members are checked, another content type is a 415 that
/// names both accepted types, and a text body must be UTF-8.
#[tokio::test]
async fn envelope_errors() {
    let app = spawn_app().await;
    let body = problem(
        app.post("/calibration", &json!({"format": "kitti"})).await,
        422,
    )
    .await;
    assert_eq!(fields(&body), ["text"]);

    let body = problem(
        app.post(
            "/calibration",
            &json!({"text": "x", "format": "yaml", "cameras": "1-2", "colour": true}),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), ["format", "cameras", "colour"]);

    let body = problem(
        app.post_raw("/calibration", Some("image/png"), b"cam0=".to_vec())
            .await,
        415,
    )
    .await;
    assert!(message_for(&body, "content-type").contains("text/plain"));

    let body = problem(
        app.post_raw("/calibration", Some("text/plain"), vec![0xff, 0xfe])
            .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), ["text"]);

    let body = problem(
        app.post_raw(
            "/calibration?cameras=9-9",
            Some("text/plain"),
            b"P0: 1".to_vec(),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(fields(&body), ["cameras"]);
}

/// Options that do not apply to the file's format are reported, not silently dropped.
#[tokio::test]
async fn options_that_do_not_apply_are_warned_about() {
    let app = spawn_app().await;
    let text = data(&own_vectors(), "middlebury_motorcycle_calib.txt");
    let body = calibrate(
        &app,
        &json!({"text": text, "cameras": "0-1", "right_text": "x", "calibration_unit": "cm"}),
    )
    .await;
    let warnings = body["warnings"].to_string();
    assert!(warnings.contains("cameras applies only to KITTI"));
    assert!(warnings.contains("right_text is read only for ROS"));
    assert!(warnings.contains("overrides this format's own unit, mm"));
    assert_eq!(body["rig"]["unit"], "cm");
    assert_close(
        number_at(&body, "rig.baseline"),
        193.001,
        "cm as the file's unit",
    );
}
