//! `POST /calibrate` over a real socket, on checkerboard pairs rendered through a known rig:
//! the summary's rig against the truth, the three files read back by `/calibration` into the
//! same rig, and bad input named part by part.

use std::sync::OnceLock;

use nalgebra::{Rotation3, Vector3};
use reqwest::multipart::{Form, Part};
use serde_json::json;
use stereo_core::calibration::boards::Board;
use stereo_core::calibration::boards::synthetic::{Style, poses, stereo_views};
use stereo_core::camera::{
    Camera, Distortion, Intrinsics, Model, RectifyOptions, Size, StereoPair, stereo_rectify,
};
use stereo_core::physics::LengthUnit;
use stereo_core::vision::encode;
use stereo_distance::config::Config;

use crate::helpers::{
    TestApp, assert_names, message_for, ok_json, problem, spawn_app, spawn_app_with,
};

pub(crate) const SIZE: Size = Size {
    width: 320,
    height: 240,
};

pub(crate) fn truth() -> StereoPair {
    let camera = |fx: f64, cx: f64| {
        Camera::new(
            Intrinsics {
                fx,
                fy: fx,
                cx,
                cy: 121.0,
            },
            Distortion::new(Model::PlumbBob, &[-0.15, 0.05, 0.0, 0.0, 0.0]).unwrap(),
        )
        .unwrap()
    };
    StereoPair {
        left: camera(360.0, 158.0),
        right: camera(362.0, 163.0),
        rotation: Rotation3::from_scaled_axis(Vector3::new(0.003, -0.01, 0.002)),
        translation: Vector3::new(-60.0, 0.5, 0.4),
    }
}

pub(crate) fn board() -> Board {
    Board::new(7, 5, 20.0, LengthUnit::Millimetre).unwrap()
}

/// Eight rendered pairs as PNG files (rendered once for every test here).
pub(crate) fn views() -> &'static Vec<(Vec<u8>, Vec<u8>)> {
    static VIEWS: OnceLock<Vec<(Vec<u8>, Vec<u8>)>> = OnceLock::new();
    VIEWS.get_or_init(|| rendered_views(&truth(), 8, 9))
}

/// `count` views of the board seen by `pair` (poses from `seed`), as PNG pairs.
pub(crate) fn rendered_views(
    pair: &StereoPair,
    count: usize,
    seed: u64,
) -> Vec<(Vec<u8>, Vec<u8>)> {
    let found = poses(pair, SIZE, &board(), count, 40.0, seed);
    let style = Style {
        supersampling: 3,
        ..Style::default()
    };
    stereo_views(pair, SIZE, &board(), &found, &style)
        .into_iter()
        .map(|v| {
            let png = |i: &stereo_core::calibration::boards::synthetic::Image| {
                gray_png(i.width as usize, i.height as usize, &i.pixels)
            };
            (png(&v.left), png(&v.right))
        })
        .collect()
}

/// An 8-bit grey image as a PNG (through the RGB encoder).
pub(crate) fn gray_png(width: usize, height: usize, grey: &[u8]) -> Vec<u8> {
    let rgb: Vec<u8> = grey.iter().flat_map(|&v| [v, v, v]).collect();
    encode::png_rgb(width, height, &rgb)
}

pub(crate) const BOARD: &str = r#"{"columns": 7, "rows": 5, "square_size": 20, "unit": "mm"}"#;

pub(crate) fn image(bytes: &[u8], name: &str) -> Part {
    Part::bytes(bytes.to_vec())
        .file_name(name.to_owned())
        .mime_str("image/png")
        .unwrap()
}

/// A form with the first `count` views (both cameras unless `left_only`) and `board`.
fn form(count: usize, left_only: bool, board: Option<&str>) -> Form {
    let mut form = Form::new();
    for (i, (l, r)) in views().iter().take(count).enumerate() {
        form = form.part("left", image(l, &format!("left{i}.png")));
        if !left_only {
            form = form.part("right", image(r, &format!("right{i}.png")));
        }
    }
    if let Some(board) = board {
        form = form.text("board", board.to_owned());
    }
    form
}

async fn calibrate(app: &TestApp, query: &str, form: Form) -> reqwest::Response {
    app.post_form(&format!("/calibrate{query}"), form).await
}

async fn text(response: reqwest::Response) -> String {
    assert_eq!(response.status(), 200);
    assert_eq!(
        response.headers()["content-type"].to_str().unwrap(),
        "application/x-yaml"
    );
    response.text().await.unwrap()
}

/// Eight rendered pairs calibrate to the true rectified rig: f within 0.3 %, B within 0.3 %,
/// each view used with a small RMS, standard deviations present and small, and a warning
/// that eight views are few.
#[tokio::test]
async fn calibrates_a_rendered_rig() {
    let app = spawn_app().await;
    let summary =
        ok_json(calibrate(&app, "?corners=true", form(8, false, Some(BOARD))).await).await;
    let expected = stereo_rectify(&truth(), SIZE, RectifyOptions::default())
        .unwrap()
        .rig(LengthUnit::Millimetre)
        .unwrap();
    let f = summary["rig"]["focal_length_px"].as_f64().unwrap();
    let b = summary["rig"]["baseline"].as_f64().unwrap();
    assert!(
        (f / expected.focal_px() - 1.0).abs() < 0.003,
        "f {f} vs {}",
        expected.focal_px()
    );
    assert!((b / expected.baseline() - 1.0).abs() < 0.003, "B {b}");
    assert_eq!(summary["views"].as_array().unwrap().len(), 8);
    for view in summary["views"].as_array().unwrap() {
        assert_eq!(view["status"], "used", "{view}");
        assert!(view["rms_left"].as_f64().unwrap() < 0.2);
        assert_eq!(view["corners_left"].as_array().unwrap().len(), 35);
    }
    assert!(summary["rms"].as_f64().unwrap() < 0.2);
    assert!(summary["epipolar_error"].as_f64().unwrap() < 0.2);
    let std_f = summary["rig_std"]["focal_length_px"].as_f64().unwrap();
    assert!(std_f > 0.0 && std_f < 2.0, "σ_f {std_f}");
    assert!(summary["left"]["std"]["fx"].as_f64().unwrap() > 0.0);
    assert_eq!(summary["left"]["distortion"].as_array().unwrap().len(), 5);
    assert!(
        summary["warnings"][0]
            .as_str()
            .unwrap()
            .contains("only 8 views")
    );
    assert_eq!(summary["image_width"], 320);
    assert_eq!(summary["rectification"]["alpha"], 0.0);

    // The rig carries its σ, and goes to /distance as it is: the depth error then holds the
    // calibration's terms, Z·σ_f/f and Z·σ_B/B.
    assert_eq!(
        summary["rig"]["focal_length_std_px"],
        summary["rig_std"]["focal_length_px"]
    );
    assert_eq!(
        summary["rig"]["baseline_std"],
        summary["rig_std"]["baseline"]
    );
    let std_b = summary["rig_std"]["baseline"].as_f64().unwrap();
    let mut request = summary["rig"].clone();
    request["disparity_px"] = json!(20.0);
    let answer = ok_json(app.post("/distance", &request).await).await;
    let z = answer["distance"].as_f64().unwrap();
    let terms = &answer["depth_error_terms"];
    let close = |got: f64, want: f64| (got - want).abs() <= 1e-9 * want.max(1e-12);
    assert!(
        close(terms["focal_length"].as_f64().unwrap(), z * std_f / f),
        "{terms}"
    );
    assert!(
        close(terms["baseline"].as_f64().unwrap(), z * std_b / b),
        "{terms}"
    );
    assert!(answer["depth_error"].as_f64().unwrap() > terms["disparity"].as_f64().unwrap());
}

/// The OpenCV file and the two ROS files, read back by `/calibration`, give the summary's rig,
/// with its σ (which the files carry as extra nodes).
#[tokio::test]
async fn the_files_read_back_into_the_same_rig() {
    let app = spawn_app().await;
    let summary = ok_json(calibrate(&app, "", form(6, false, Some(BOARD))).await).await;
    let opencv =
        text(calibrate(&app, "?output=opencv.yml", form(6, false, Some(BOARD))).await).await;
    assert!(opencv.starts_with("%YAML:1.0\n"));
    let left =
        text(calibrate(&app, "?output=ros-left.yaml", form(6, false, Some(BOARD))).await).await;
    let right =
        text(calibrate(&app, "?output=ros-right.yaml", form(6, false, Some(BOARD))).await).await;
    assert!(left.contains("distortion_model: plumb_bob"));
    for request in [
        json!({"text": opencv, "calibration_unit": "mm"}),
        json!({"text": left, "right_text": right, "unit": "mm"}),
    ] {
        let read = ok_json(app.post("/calibration", &request).await).await;
        for member in [
            "focal_length_px",
            "baseline",
            "cx",
            "cy",
            "doffs",
            "focal_length_std_px",
            "baseline_std",
        ] {
            let (got, want) = (
                read["rig"][member].as_f64().unwrap(),
                summary["rig"][member].as_f64().unwrap(),
            );
            assert!(
                (got - want).abs() <= 1e-6 * want.abs().max(1.0),
                "{member}: {got} vs {want}"
            );
        }
    }
}

/// Only `left` parts calibrate one camera: no pair members, no rig, and a warning that says
/// so and how to calibrate the pair.
#[tokio::test]
async fn left_parts_alone_calibrate_one_camera() {
    let app = spawn_app().await;
    let summary = ok_json(calibrate(&app, "", form(6, true, Some(BOARD))).await).await;
    let fx = summary["left"]["camera_matrix"][0][0].as_f64().unwrap();
    assert!((fx / 360.0 - 1.0).abs() < 0.005, "fx {fx}");
    assert!(summary.get("rig").is_none() && summary.get("right").is_none());
    let warnings = summary["warnings"].to_string();
    assert!(
        warnings.contains("only one camera's images were sent (no `right` parts)"),
        "{warnings}"
    );
    assert_eq!(summary["determined"], true);
}

/// Squares counted instead of inner corners (the 7 × 5 board given as 8 × 6), or a smaller
/// board named (6 × 4, where the views show 7 × 5): one 422 naming `board.columns` and
/// `board.rows` with the size the views show, not a miss per view.
#[tokio::test]
async fn a_board_counted_in_squares_is_named_once() {
    let app = spawn_app().await;
    for given in [
        r#"{"columns": 8, "rows": 6, "square_size": 20}"#,
        r#"{"columns": 6, "rows": 4, "square_size": 20}"#,
    ] {
        let p = problem(calibrate(&app, "", form(4, false, Some(given))).await, 422).await;
        assert_names(&p, &["board.columns", "board.rows"]);
        let said = message_for(&p, "board.columns");
        assert!(
            said.contains("of the 8 images show 7 this way: a chessboard of 7 × 5 inner corners"),
            "{given}: {said}"
        );
    }
}

/// Copies of one pair (six here) cannot determine a lens: refused with a 422 that names the cause
/// (near-identical poses, the focal length's σ as large as itself), where it used to be a
/// 200 with a low RMS.
#[tokio::test]
async fn copies_of_one_view_are_refused_as_undetermined() {
    // The solver works hardest on views that cannot determine it: room for a debug build
    // beside the other tests.
    let mut config = Config {
        port: 0,
        ..Config::default()
    };
    config.heavy.request_timeout = std::time::Duration::from_secs(300);
    let app = spawn_app_with(config).await;
    let (l, r) = &views()[0];
    let mut copies = Form::new().text("board", BOARD);
    for i in 0..6 {
        copies = copies
            .part("left", image(l, &format!("l{i}.png")))
            .part("right", image(r, &format!("r{i}.png")));
    }
    let p = problem(calibrate(&app, "", copies).await, 422).await;
    let said = message_for(&p, "left");
    assert!(said.contains("the calibration is not determined"), "{said}");
    assert!(said.contains("nearly one pose"), "{said}");
}

/// The summary says how precisely the calibration places a point in each image: a 16 × 12
/// grid of σ per camera, small where the views' corners fell, with its noise and model parts;
/// `cross_validate=true` calibrates halves of the views apart (8 splits) and reports their
/// difference over what their σ predict, not above the consistent range on renders.
/// A distance that is not one is named.
#[tokio::test]
async fn projection_uncertainty_and_cross_validation() {
    let app = spawn_app().await;
    let summary =
        ok_json(calibrate(&app, "?cross_validate=true", form(8, false, Some(BOARD))).await).await;
    let p = &summary["projection_uncertainty"];
    assert!(p["distance"].as_f64().unwrap() > 100.0, "{p}");
    for side in ["left", "right"] {
        let grid = p[side]["grid"].as_array().unwrap();
        assert_eq!(grid.len(), 12);
        assert_eq!(grid[0].as_array().unwrap().len(), 16);
        let median = p[side]["median_px"].as_f64().unwrap();
        let worst = p[side]["worst_px"].as_f64().unwrap();
        assert!(
            median > 0.0 && median < 0.5 && worst >= median,
            "{side}: {median} {worst}"
        );
    }
    for side in ["left", "right"] {
        let noise = p[side]["noise_median_px"].as_f64().unwrap();
        let model = p[side]["model_median_px"].as_f64().unwrap();
        assert!(noise > 0.0 && model >= 0.0, "{side}: {noise} {model}");
        assert_eq!(
            p[side]["model_error_dominates"],
            model > 1.5 * noise,
            "{side}: {noise} {model}"
        );
    }
    // Rendered through an exact model: the model's part does not dominate.
    assert_eq!(p["model_error_dominates"], false, "{p}");
    let c = &summary["cross_validation"];
    let ratio = c["ratio"].as_f64().unwrap();
    assert!(ratio > 0.0 && ratio <= 1.4, "{c}");
    assert_eq!(c["consistent"], (0.7..=1.4).contains(&ratio), "{c}");
    assert!(c["ratio_centre"].as_f64().unwrap() > 0.0 && c["ratio_edge"].as_f64().unwrap() > 0.0);
    let few =
        ok_json(calibrate(&app, "?cross_validate=true", form(4, false, Some(BOARD))).await).await;
    assert!(few.get("cross_validation").is_none());
    assert!(
        few["warnings"]
            .to_string()
            .contains("cross-validation needs two halves")
    );
    let p = problem(
        calibrate(
            &app,
            "?uncertainty_distance=-3",
            form(3, false, Some(BOARD)),
        )
        .await,
        422,
    )
    .await;
    assert_names(&p, &["uncertainty_distance"]);
}

/// A board with three bad members names all three at once.
#[tokio::test]
async fn every_bad_board_member_is_named_at_once() {
    let app = spawn_app().await;
    let board = r#"{"columns": 0, "rows": 100, "square_size": -1, "unit": "furlong"}"#;
    let p = problem(calibrate(&app, "", form(3, false, Some(board))).await, 422).await;
    assert_names(
        &p,
        &[
            "board.columns",
            "board.rows",
            "board.square_size",
            "board.unit",
        ],
    );
}

/// Bad forms are 4xx problems naming the part: counts that differ name `right`, a board with
/// too few columns names `board.columns`, a missing board names `board` (and one that is not
/// JSON says what JSON it takes), a bad alpha names `alpha`.
#[tokio::test]
async fn bad_forms_name_the_part() {
    let app = spawn_app().await;
    let mut uneven = form(3, false, Some(BOARD));
    uneven = uneven.part("left", image(&views()[3].0, "extra.png"));
    let p = problem(calibrate(&app, "", uneven).await, 422).await;
    assert!(message_for(&p, "right").contains("has 3 images but left has 4"));

    let p = problem(
        calibrate(
            &app,
            "?alpha=2",
            form(
                3,
                false,
                Some(r#"{"columns": 2, "rows": 5, "square_size": 0}"#),
            ),
        )
        .await,
        422,
    )
    .await;
    assert_names(&p, &["alpha", "board.columns", "board.square_size"]);

    let p = problem(calibrate(&app, "", form(3, false, None)).await, 422).await;
    assert_names(&p, &["board"]);

    // `board=9x6`, as a user may type it, is told the JSON the part takes, not the decoder's
    // words.
    let p = problem(calibrate(&app, "", form(3, false, Some("9x6"))).await, 422).await;
    assert_names(&p, &["board"]);
    let said = message_for(&p, "board");
    assert!(
        said.contains(r#"such as {"columns": 9, "rows": 6"#) && said.contains("not `9x6`"),
        "{said}"
    );
    assert!(!said.contains("line 1 column"), "{said}");
}

/// Images of another size name their view; views whose board is not found are each named
/// with the reason when fewer than three remain.
#[tokio::test]
async fn sizes_and_missing_boards_name_the_view() {
    let app = spawn_app().await;
    let small = gray_png(64, 48, &[200; 64 * 48]);
    let mut mixed = form(2, false, Some(BOARD));
    mixed = mixed
        .part("left", image(&views()[2].0, "l.png"))
        .part("right", image(&small, "r.png"));
    let p = problem(calibrate(&app, "", mixed).await, 422).await;
    assert_names(&p, &["right[2]"]);

    let blank = gray_png(320, 240, &[200; 320 * 240]);
    let mut few = form(2, false, Some(BOARD));
    few = few
        .part("left", image(&blank, "l.png"))
        .part("right", image(&views()[2].1, "r.png"));
    let p = problem(calibrate(&app, "", few).await, 422).await;
    assert!(message_for(&p, "left[2]").contains("board not found"));
    assert!(message_for(&p, "left").contains("2 usable views"));
}

/// On OpenCV's 13 real stereo photographs (tests/data/photographs/opencv-stereo), a lean model
/// on a real lens: the projection σ's model part outweighs its noise part, each camera says so
/// and a warning says what to do; the built-in cross-validation (8 splits) finds the halves as
/// far apart as the σ predicts. Four of the same photographs are too few views to tell the two
/// parts apart, and nothing is claimed.
#[tokio::test]
async fn real_photographs_show_model_error_and_a_true_sigma() {
    let app = spawn_app().await;
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/photographs/opencv-stereo");
    let names = [
        "01", "02", "03", "04", "05", "06", "07", "08", "09", "11", "12", "13", "14",
    ];
    let photographs = |count: usize| {
        let mut form = Form::new();
        for n in &names[..count] {
            for side in ["left", "right"] {
                let bytes = std::fs::read(dir.join(format!("{side}{n}.jpg"))).unwrap();
                let part = Part::bytes(bytes)
                    .file_name(format!("{side}{n}.jpg"))
                    .mime_str("image/jpeg")
                    .unwrap();
                form = form.part(side, part);
            }
        }
        form.text("board", r#"{"columns": 9, "rows": 6, "square_size": 25}"#)
    };
    let all = ok_json(calibrate(&app, "?cross_validate=true", photographs(13)).await).await;
    let p = &all["projection_uncertainty"];
    for side in ["left", "right"] {
        let (noise, model) = (
            p[side]["noise_median_px"].as_f64().unwrap(),
            p[side]["model_median_px"].as_f64().unwrap(),
        );
        assert!(model > 1.5 * noise, "{side}: noise {noise}, model {model}");
        assert_eq!(p[side]["model_error_dominates"], true, "{p}");
    }
    assert_eq!(p["model_error_dominates"], true);
    let warnings = all["warnings"].to_string();
    assert!(
        warnings.contains("model error dominates the left camera")
            && warnings.contains("rational_polynomial"),
        "{warnings}"
    );
    let c = &all["cross_validation"];
    let ratio = c["ratio"].as_f64().unwrap();
    assert!((0.7..=1.4).contains(&ratio), "{c}");
    assert_eq!(c["consistent"], true, "{c}");
    let few = ok_json(calibrate(&app, "", photographs(4)).await).await;
    let p = &few["projection_uncertainty"];
    assert_eq!(p["model_error_dominates"], false, "{p}");
    assert!(
        !few["warnings"]
            .to_string()
            .contains("model error dominates")
    );
}

/// The user's slips are named: a 20 mm board typed as 0.02 with `mm` names `square_size` and
/// the 0.06 mm baseline it calibrates, with metres as the likely unit, and says nothing of
/// swapped cameras; the same views with left and right swapped calibrate a right camera on the
/// left (T_x > 0), and the summary says the views look swapped, with no word about units.
#[tokio::test]
async fn wrong_units_and_swapped_views_are_named() {
    let app = spawn_app().await;
    let slip = r#"{"columns": 7, "rows": 5, "square_size": 0.02, "unit": "mm"}"#;
    let summary = ok_json(calibrate(&app, "", form(8, false, Some(slip))).await).await;
    let said = summary["warnings"].to_string();
    assert!(
        said.contains("the board's square_size is 0.02 mm, under 1 mm"),
        "{said}"
    );
    assert!(
        said.contains("the calibrated baseline is 0.06 mm"),
        "{said}"
    );
    assert!(said.contains("meant in m"), "{said}");
    assert!(!said.contains("swapped"), "{said}");

    let mut swapped = Form::new();
    for (i, (l, r)) in views().iter().enumerate() {
        swapped = swapped
            .part("left", image(r, &format!("right{i}.png")))
            .part("right", image(l, &format!("left{i}.png")));
    }
    let summary = ok_json(calibrate(&app, "", swapped.text("board", BOARD)).await).await;
    let said = summary["warnings"].to_string();
    assert!(
        said.contains("the right camera lies to the left of the left one"),
        "{said}"
    );
    assert!(said.contains("look swapped"), "{said}");
    assert!(!said.contains("under 1 mm"), "{said}");
}
