//! `POST /calibrate` with a ChArUco board over a real socket: pairs rendered through a known
//! rig, some with the board partly out of the left frame, calibrate to the truth with every
//! view counted; the corners come back with OpenCV's ids; bad boards are named member by
//! member.

use std::sync::OnceLock;

use nalgebra::{Rotation3, Vector3};
use reqwest::multipart::{Form, Part};
use stereo_core::calibration::boards::charuco::render::{partial_poses, render};
use stereo_core::calibration::boards::charuco::{CharucoBoard, CharucoSpec, Dictionary};
use stereo_core::calibration::boards::synthetic::{Image, Rays, Style, right_pose};
use stereo_core::camera::{Camera, Distortion, Intrinsics, Model, Size, StereoPair};
use stereo_core::physics::LengthUnit;

use crate::calibrate::gray_png;
use crate::helpers::{assert_names, message_for, ok_json, problem, spawn_app};

const SIZE: Size = Size {
    width: 480,
    height: 360,
};

const BOARD: &str = r#"{"type": "charuco", "squares_x": 7, "squares_y": 5, "square_size": 30,
    "marker_size": 22, "dictionary": "DICT_4X4_50", "unit": "mm"}"#;

fn charuco() -> CharucoBoard {
    CharucoBoard::new(CharucoSpec {
        squares_x: 7,
        squares_y: 5,
        square_size: 30.0,
        marker_size: 22.0,
        dictionary: Dictionary::Dict4x4_50,
        legacy: false,
        unit: LengthUnit::Millimetre,
    })
    .unwrap()
}

fn truth() -> StereoPair {
    let camera = |fx: f64, cx: f64| {
        Camera::new(
            Intrinsics {
                fx,
                fy: fx,
                cx,
                cy: 181.0,
            },
            Distortion::new(Model::PlumbBob, &[-0.18, 0.06, 0.0, 0.0, 0.0]).unwrap(),
        )
        .unwrap()
    };
    StereoPair {
        left: camera(470.0, 238.0),
        right: camera(472.0, 244.0),
        rotation: Rotation3::from_scaled_axis(Vector3::new(0.003, -0.01, 0.002)),
        translation: Vector3::new(-80.0, 0.5, 0.4),
    }
}

/// Nine rendered pairs as PNG files, the third, sixth and ninth with the board's middle on
/// the left image's right edge (rendered once for every test here).
fn views() -> &'static Vec<(Vec<u8>, Vec<u8>)> {
    static VIEWS: OnceLock<Vec<(Vec<u8>, Vec<u8>)>> = OnceLock::new();
    VIEWS.get_or_init(|| {
        let pair = truth();
        let board = charuco();
        let rays = [
            Rays::new(&pair.left, SIZE, 2),
            Rays::new(&pair.right, SIZE, 2),
        ];
        let style = Style {
            supersampling: 2,
            ..Style::default()
        };
        let png = |i: Image| gray_png(i.width as usize, i.height as usize, &i.pixels);
        partial_poses(&pair, SIZE, &board, 9, 4, 460.0)
            .unwrap()
            .iter()
            .map(|pose| {
                (
                    png(render(&board, pose, &rays[0], &style)),
                    png(render(&board, &right_pose(&pair, pose), &rays[1], &style)),
                )
            })
            .collect()
    })
}

fn form(board: &str) -> Form {
    let image = |bytes: &[u8], name: String| {
        Part::bytes(bytes.to_vec())
            .file_name(name)
            .mime_str("image/png")
            .unwrap()
    };
    let mut form = Form::new();
    for (i, (l, r)) in views().iter().enumerate() {
        form = form
            .part("left", image(l, format!("left{i}.png")))
            .part("right", image(r, format!("right{i}.png")));
    }
    form.text("board", board.to_owned())
}

/// Nine ChArUco pairs, three with the board partly out of the left frame, calibrate to the
/// truth (f within 0.3 %, the principal points within 1.5 px, |T| within 0.5 %): every view
/// is used, the partial ones with the corners they show; the summary gives the board back
/// with its ChArUco terms, and the corners with OpenCV's ids.
#[tokio::test]
async fn calibrates_from_charuco_views_whole_and_partial() {
    let app = spawn_app().await;
    let s = ok_json(app.post_form("/calibrate?corners=true", form(BOARD)).await).await;
    let truth = truth();
    let views = s["views"].as_array().unwrap();
    assert_eq!(views.len(), 9);
    let counts: Vec<(u64, u64)> = views
        .iter()
        .map(|v| {
            assert_eq!(v["status"], "used", "{v}");
            (
                v["corners_found_left"].as_u64().unwrap(),
                v["corners_found_right"].as_u64().unwrap(),
            )
        })
        .collect();
    let partial = counts.iter().filter(|c| c.0 < 24).count();
    assert!(partial >= 3, "{counts:?}");
    let ids = views[2]["ids_left"].as_array().unwrap();
    assert_eq!(ids.len() as u64, counts[2].0);
    assert_eq!(
        views[2]["corners_left"].as_array().unwrap().len(),
        ids.len()
    );
    assert!(ids.iter().all(|id| id.as_u64().unwrap() < 24));
    for (side, camera) in [("left", &truth.left), ("right", &truth.right)] {
        let k = &s[side]["camera_matrix"];
        let t = camera.intrinsics();
        let fx = k[0][0].as_f64().unwrap();
        assert!(
            (fx / t.fx - 1.0).abs() < 3e-3,
            "{side} fx {fx} against {}",
            t.fx
        );
        let (cx, cy) = (k[0][2].as_f64().unwrap(), k[1][2].as_f64().unwrap());
        assert!((cx - t.cx).hypot(cy - t.cy) < 1.5, "{side} ({cx}, {cy})");
    }
    let t: Vec<f64> = s["translation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let length = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
    assert!((length / 80.0 - 1.0).abs() < 5e-3, "|T| {length}");
    let board = &s["board"];
    assert_eq!(board["type"], "charuco");
    assert_eq!(board["squares_x"], 7);
    assert_eq!(board["columns"], 6);
    assert_eq!(board["dictionary"], "DICT_4X4_50");
}

/// Every fault of a ChArUco board is named at once: a board of 1 × 1 squares, a marker as
/// large as its square, a dictionary OpenCV has but the service does not, and a chessboard's
/// member beside them; a chessboard given a ChArUco member is told to say its type.
#[tokio::test]
async fn every_bad_charuco_member_is_named_at_once() {
    let app = spawn_app().await;
    let board = r#"{"type": "charuco", "squares_x": 1, "squares_y": 1, "square_size": 20,
        "marker_size": 20, "dictionary": "DICT_7X7_50", "columns": 9}"#;
    let p = problem(app.post_form("/calibrate", form(board)).await, 422).await;
    assert_names(
        &p,
        &[
            "board.columns",
            "board.dictionary",
            "board.marker_size",
            "board.squares_x",
            "board.squares_y",
        ],
    );
    assert!(message_for(&p, "board.dictionary").contains("DICT_4X4_50"));
    assert!(message_for(&p, "board.marker_size").contains("smaller than square_size"));
    let chess = r#"{"columns": 9, "rows": 6, "square_size": 25, "dictionary": "DICT_4X4_50"}"#;
    let p = problem(app.post_form("/calibrate", form(chess)).await, 422).await;
    assert_names(&p, &["board.dictionary"]);
    assert!(message_for(&p, "board.dictionary").contains("\"type\": \"charuco\""));
    let few = r#"{"type": "charuco", "squares_x": 12, "squares_y": 10, "square_size": 20,
        "marker_size": 15, "dictionary": "DICT_4X4_50"}"#;
    let p = problem(app.post_form("/calibrate", form(few)).await, 422).await;
    assert_names(&p, &["board.dictionary"]);
    assert!(message_for(&p, "board.dictionary").contains("holds 50 markers"));
}

/// Images that show what the board given cannot be are told once, naming the member: the
/// 7 × 5 print described as 6 × 4 squares (its corners, not its squares) shows markers the
/// smaller board does not have, which names `board.squares_x` and `board.squares_y`; described
/// with `DICT_5X5_100`, the images show none of its markers but `DICT_4X4_50`'s, which names
/// `board.dictionary`.
#[tokio::test]
async fn a_board_the_images_contradict_names_its_member() {
    let app = spawn_app().await;
    let corners = r#"{"type": "charuco", "squares_x": 6, "squares_y": 4, "square_size": 30,
        "marker_size": 22, "dictionary": "DICT_4X4_50"}"#;
    let p = problem(app.post_form("/calibrate", form(corners)).await, 422).await;
    assert_eq!(p["errors"].as_array().unwrap().len(), 2, "{p}");
    assert_names(&p, &["board.squares_x", "board.squares_y"]);
    let message = message_for(&p, "board.squares_x");
    assert!(message.contains("12 markers (ids 0 to 11)"), "{message}");
    assert!(message.contains("up to id 16"), "{message}");
    let dictionary = r#"{"type": "charuco", "squares_x": 7, "squares_y": 5, "square_size": 30,
        "marker_size": 22, "dictionary": "DICT_5X5_100"}"#;
    let p = problem(app.post_form("/calibrate", form(dictionary)).await, 422).await;
    assert_eq!(p["errors"].as_array().unwrap().len(), 1, "{p}");
    let message = message_for(&p, "board.dictionary");
    assert!(message.contains("markers of DICT_4X4_50"), "{message}");
}
