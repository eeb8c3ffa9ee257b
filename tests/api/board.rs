//! `POST /board` over a real socket: the board found in a rendered pair (every corner, its
//! outline, whether the pair is a view), in a left image alone, missed in a blank image with
//! the reason, and bad input named part by part.

use reqwest::multipart::Form;
use serde_json::Value;

use crate::calibrate::{BOARD, gray_png, image, views};
use crate::depth_map::png_claiming;
use crate::helpers::{TestApp, assert_names, fields, ok_json, problem, spawn_app};

async fn board(app: &TestApp, form: Form) -> reqwest::Response {
    app.post_form("/board", form).await
}

/// Every inner corner of the 7 × 5 board found once, with its id, inside the image; the
/// outline passes through the four outer corners.
fn assert_whole_board(seen: &Value) {
    assert_eq!(seen["found"], true, "{seen}");
    let corners = seen["corners"].as_array().unwrap();
    assert_eq!(corners.len(), 35);
    let ids: Vec<u64> = corners.iter().map(|c| c["id"].as_u64().unwrap()).collect();
    assert_eq!(ids, (0..35).collect::<Vec<u64>>());
    for c in corners {
        let (x, y) = (c["x"].as_f64().unwrap(), c["y"].as_f64().unwrap());
        assert!(
            (0.0..320.0).contains(&x) && (0.0..240.0).contains(&y),
            "{c}"
        );
    }
    let outline = seen["outline"].as_array().unwrap();
    for id in [0, 6, 28, 34] {
        let corner = &corners[id];
        assert!(
            outline
                .iter()
                .any(|p| p[0] == corner["x"] && p[1] == corner["y"]),
            "corner {id} on the outline"
        );
    }
}

/// A rendered pair: both boards found whole, the pair a view, the detection's time in
/// `Server-Timing`; the left image alone is a view too, with no `right`.
#[tokio::test]
async fn a_rendered_pair_shows_the_whole_board() {
    let app = spawn_app().await;
    let (left, right) = &views()[0];
    let form = Form::new()
        .part("left", image(left, "left.png"))
        .part("right", image(right, "right.png"))
        .text("board", BOARD);
    let response = board(&app, form).await;
    assert!(
        response.headers()["server-timing"]
            .to_str()
            .unwrap()
            .contains("detect")
    );
    let answer = ok_json(response).await;
    assert_eq!(
        (answer["width"].as_u64(), answer["height"].as_u64()),
        (Some(320), Some(240))
    );
    assert_eq!(answer["view"], true);
    assert_whole_board(&answer["left"]);
    assert_whole_board(&answer["right"]);
    let alone = Form::new()
        .part("left", image(left, "left.png"))
        .text("board", BOARD);
    let answer = ok_json(board(&app, alone).await).await;
    assert_eq!(answer["view"], true);
    assert!(answer.get("right").is_none(), "{answer}");
}

/// A blank right image: the left board found, the right missed with its reason, and the pair
/// not a view.
#[tokio::test]
async fn a_blank_image_misses_the_board_and_says_why() {
    let app = spawn_app().await;
    let (left, _) = &views()[1];
    let blank = gray_png(320, 240, &vec![128; 320 * 240]);
    let form = Form::new()
        .part("left", image(left, "left.png"))
        .part("right", image(&blank, "right.png"))
        .text("board", BOARD);
    let answer = ok_json(board(&app, form).await).await;
    assert_eq!(answer["view"], false);
    assert_whole_board(&answer["left"]);
    let right = &answer["right"];
    assert_eq!(right["found"], false);
    assert_eq!(right["corners"], serde_json::json!([]));
    assert!(!right["reason"].as_str().unwrap().is_empty(), "{right}");
}

/// Bad input is named part by part: no left image and a board member out of range together;
/// two left images; a right image that is not one, and one of another size; a header past
/// the pixel limit is a 413 naming the part.
#[tokio::test]
async fn bad_input_is_named_part_by_part() {
    let app = spawn_app().await;
    let (left, right) = &views()[0];
    let body = problem(
        board(
            &app,
            Form::new().text("board", r#"{"columns": 1, "rows": 5, "square_size": 20}"#),
        )
        .await,
        422,
    )
    .await;
    assert_names(&body, &["left", "board.columns"]);
    let two = Form::new()
        .part("left", image(left, "a.png"))
        .part("left", image(left, "b.png"))
        .text("board", BOARD);
    assert_eq!(
        fields(&problem(board(&app, two).await, 422).await),
        ["left"]
    );
    let garbage = Form::new()
        .part("left", image(left, "left.png"))
        .part("right", image(b"not an image", "right.png"))
        .text("board", BOARD);
    assert_eq!(
        fields(&problem(board(&app, garbage).await, 422).await),
        ["right"]
    );
    let small = gray_png(160, 120, &vec![0; 160 * 120]);
    let other = Form::new()
        .part("left", image(left, "left.png"))
        .part("right", image(&small, "right.png"))
        .text("board", BOARD);
    let body = problem(board(&app, other).await, 422).await;
    assert_eq!(fields(&body), ["right"]);
    assert!(
        body["errors"][0]["message"]
            .as_str()
            .unwrap()
            .contains("160 × 120")
    );
    let huge = Form::new()
        .part("left", image(&png_claiming(30_000, 30_000), "left.png"))
        .part("right", image(right, "right.png"))
        .text("board", BOARD);
    assert_eq!(
        fields(&problem(board(&app, huge).await, 413).await),
        ["left"]
    );
}
