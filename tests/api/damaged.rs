//! Damaged image files on every image route: a JPEG or PNG cut off (an interrupted copy) or
//! corrupt (a bad sector, a garbled transfer) is a 422 naming its part, on `/depth-map`,
//! `/match`, `/rectify` and `/calibrate`; a JPEG whose scans are whole but whose end-of-image
//! marker is missing is read, with a warning naming the part.

use reqwest::multipart::{Form, Part};
use serde_json::Value;
use stereo_core::vision::{encode, synthetic};

use crate::depth_map::{H, W, pair};
use crate::helpers::{TestApp, message_for, ok_json, problem, spawn_app};

/// A calibration of the raw cameras without `imageSize` (the images give it): f = 400 px,
/// the principal point at the centre, no distortion, B = 120 mm.
pub(crate) fn sizeless_calibration() -> String {
    let matrix = |name: &str, rows: usize, cols: usize, data: &str| {
        format!(
            "{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {data} ]\n"
        )
    };
    let k = format!("400., 0., {}., 0., 400., {}., 0., 0., 1.", W / 2, H / 2);
    let mut text = String::from("%YAML:1.0\n---\n");
    for i in [1, 2] {
        text += &matrix(&format!("M{i}"), 3, 3, &k);
        text += &matrix(&format!("D{i}"), 1, 5, "0., 0., 0., 0., 0.");
    }
    text += &matrix("R", 3, 3, "1., 0., 0., 0., 1., 0., 0., 0., 1.");
    text += &matrix("T", 3, 1, "-120., 0., 0.");
    text
}

/// The ways a file is damaged, each with the words its 422 says.
#[derive(Debug, Clone, Copy)]
enum Damage {
    /// The first 60 % of the file.
    Cut,
    /// Its data overwritten mid-file: a JPEG's with a marker no standard defines, a PNG's
    /// with one bit flipped (its checksum fails).
    Corrupt,
}

impl Damage {
    fn apply(self, bytes: &[u8], png: bool) -> Vec<u8> {
        let n = bytes.len();
        let mut out = bytes.to_vec();
        match self {
            Damage::Cut => out.truncate(n * 6 / 10),
            Damage::Corrupt if png => out[n * 6 / 10] ^= 0x10,
            Damage::Corrupt => out[n * 6 / 10..n * 6 / 10 + 2].copy_from_slice(&[0xFF, 0x05]),
        }
        out
    }

    fn words(self) -> &'static str {
        match self {
            Damage::Cut => "is cut off",
            Damage::Corrupt => "could not be decoded",
        }
    }
}

fn part(bytes: Vec<u8>, png: bool) -> Part {
    let (name, mime) = if png {
        ("frame.png", "image/png")
    } else {
        ("frame.jpg", "image/jpeg")
    };
    Part::bytes(bytes).file_name(name).mime_str(mime).unwrap()
}

/// The rendered pair in one format: (left, right).
fn good_pair(png: bool) -> (Vec<u8>, Vec<u8>) {
    let pair = pair();
    if png {
        (
            encode::png_rgb(W, H, &pair.left_rgb),
            encode::png_rgb(W, H, &pair.right_rgb),
        )
    } else {
        (
            synthetic::jpeg(&pair.left_rgb, W, H, 92),
            synthetic::jpeg(&pair.right_rgb, W, H, 92),
        )
    }
}

/// A raw pair's form with the size-less calibration: `left` as given, the right good.
fn raw_form(left: Vec<u8>, right: Vec<u8>, png: bool) -> Form {
    Form::new()
        .part("left", part(left, png))
        .part("right", part(right, png))
        .text("calibration", sizeless_calibration())
        .text("calibration_unit", "mm")
}

/// OpenCV's real photographs as a `/calibrate` form: pairs 01 and 02, the second left
/// replaced by `second_left` (in `png` or JPEG).
fn board_form(second_left: impl Fn(&[u8]) -> (Vec<u8>, bool)) -> Form {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/photographs/opencv-stereo");
    let mut form = Form::new();
    for n in ["01", "02"] {
        for side in ["left", "right"] {
            let bytes = std::fs::read(dir.join(format!("{side}{n}.jpg"))).unwrap();
            let (bytes, png) = if n == "02" && side == "left" {
                second_left(&bytes)
            } else {
                (bytes, false)
            };
            form = form.part(side, part(bytes, png));
        }
    }
    form.text("board", r#"{"columns": 9, "rows": 6, "square_size": 25}"#)
}

/// The 422 of `response`, checked to name `field` with `words`.
async fn names(response: reqwest::Response, field: &str, words: &str, what: &str) {
    let body = problem(response, 422).await;
    let message = message_for(&body, field);
    assert!(message.contains(words), "{what}: {field}: {message}");
}

/// Every image route answers a cut-off or corrupt JPEG and PNG with a 422 naming the part
/// and saying which: `/depth-map` and `/match` raw (rectified first) and rectified,
/// `/rectify`, and `/calibrate` naming the view (`left[1]`).
#[tokio::test]
async fn truncated_and_corrupt_images_are_named_on_every_route() {
    let app = spawn_app().await;
    let rig = r#"{"focal_length_px": 400, "baseline": 120, "unit": "mm"}"#;
    for png in [false, true] {
        let (left, right) = good_pair(png);
        for damage in [Damage::Cut, Damage::Corrupt] {
            let bad = damage.apply(&left, png);
            let what = format!("{damage:?} {}", if png { "PNG" } else { "JPEG" });
            let routes: [(&str, Form); 5] = [
                (
                    "/depth-map?max_disparity=48",
                    raw_form(bad.clone(), right.clone(), png),
                ),
                (
                    "/depth-map?max_disparity=48&output=disparity.npy",
                    Form::new()
                        .part("left", part(bad.clone(), png))
                        .part("right", part(right.clone(), png))
                        .text("rig", rig),
                ),
                (
                    "/match?max_disparity=48",
                    raw_form(bad.clone(), right.clone(), png)
                        .text("points", r#"[{"x": 80, "y": 60}]"#),
                ),
                ("/rectify", raw_form(bad.clone(), right.clone(), png)),
                (
                    "/rectify?output=left.png",
                    raw_form(bad.clone(), right.clone(), png),
                ),
            ];
            for (route, form) in routes {
                let response = app.post_form(route, form).await;
                names(response, "left", damage.words(), &format!("{route} {what}")).await;
            }
            let form = board_form(|photo| {
                let bytes = if png {
                    let grey = image::load_from_memory(photo).unwrap().to_luma8();
                    encode::png_grey(640, 480, grey.as_raw())
                } else {
                    photo.to_vec()
                };
                (damage.apply(&bytes, png), png)
            });
            let response = app.post_form("/calibrate", form).await;
            names(
                response,
                "left[1]",
                damage.words(),
                &format!("/calibrate {what}"),
            )
            .await;
        }
    }
}

/// A JPEG without its end-of-image marker (the last two bytes gone) but with whole scans is
/// read: `/depth-map` answers 200 with the same map as the whole file's, and says so in the
/// summary's warnings and, for a file answer, in its `Stereo-Warnings` header (JSON);
/// `/rectify`'s summary says it too.
#[tokio::test]
async fn a_missing_end_marker_is_a_warning() {
    let app = spawn_app().await;
    let (left, right) = good_pair(false);
    let unended = left[..left.len() - 2].to_vec();
    let rig = r#"{"focal_length_px": 400, "baseline": 120, "unit": "mm"}"#;
    let form = |left: &[u8]| {
        Form::new()
            .part("left", part(left.to_vec(), false))
            .part("right", part(right.clone(), false))
            .text("rig", rig)
    };
    let summary = ok_json(
        app.post_form("/depth-map?max_disparity=48", form(&unended))
            .await,
    )
    .await;
    let warnings: Vec<&str> = summary["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(Value::as_str)
        .collect();
    assert!(
        warnings
            .iter()
            .any(|w| w.starts_with("left has no end-of-image marker")),
        "{warnings:?}"
    );
    let file = app
        .post_form(
            "/depth-map?max_disparity=48&output=disparity.npy",
            form(&unended),
        )
        .await;
    assert_eq!(file.status(), 200);
    let header: Vec<String> =
        serde_json::from_str(file.headers()["stereo-warnings"].to_str().unwrap()).unwrap();
    assert!(
        header[0].starts_with("left has no end-of-image marker"),
        "{header:?}"
    );
    let from_unended = file.bytes().await.unwrap();
    let whole = app
        .post_form(
            "/depth-map?max_disparity=48&output=disparity.npy",
            form(&left),
        )
        .await;
    assert!(!whole.headers().contains_key("stereo-warnings"));
    assert_eq!(whole.bytes().await.unwrap(), from_unended);
    let rectified = ok_json(
        app.post_form("/rectify", raw_form(unended, right.clone(), false))
            .await,
    )
    .await;
    assert!(
        rectified["warnings"]
            .to_string()
            .contains("left has no end-of-image marker"),
        "{rectified}"
    );
}

/// A file answer carries the summary's own warnings: a pair that looks raw (only a sliver
/// matched) sent as rectified gets the advice to rectify in the NPY's `Stereo-Warnings`; the
/// summary's note that a raw pair was rectified is not a warning there.
#[tokio::test]
async fn a_file_answer_carries_the_summarys_warnings() {
    let app: TestApp = spawn_app().await;
    let (left, _) = good_pair(true);
    let mut other = pair();
    other.right_rgb.iter_mut().for_each(|v| *v = 255 - *v);
    let right = encode::png_rgb(W, H, &other.right_rgb);
    let form = || {
        Form::new()
            .part("left", part(left.clone(), true))
            .part("right", part(right.clone(), true))
    };
    let summary = ok_json(app.post_form("/depth-map?max_disparity=48", form()).await).await;
    let said = summary["warnings"].clone();
    assert!(said.to_string().contains("need rectifying"), "{said}");
    let file = app
        .post_form("/depth-map?max_disparity=48&output=disparity.npy", form())
        .await;
    let header: Value =
        serde_json::from_str(file.headers()["stereo-warnings"].to_str().unwrap()).unwrap();
    assert_eq!(header, said);
    // A raw pair rectified with its calibration: the summary says it was, the header does not
    // (nothing was wrong with what was sent).
    let (left, right) = good_pair(true);
    let raw = ok_json(
        app.post_form(
            "/depth-map?max_disparity=48&rectify=yes",
            raw_form(left.clone(), right.clone(), true),
        )
        .await,
    )
    .await;
    assert!(
        raw["warnings"].to_string().contains("rectified first"),
        "{raw}"
    );
    let file = app
        .post_form(
            "/depth-map?max_disparity=48&rectify=yes&output=depth.npy",
            raw_form(left, right, true),
        )
        .await;
    assert_eq!(file.status(), 200);
    assert!(!file.headers().contains_key("stereo-warnings"));
}

/// A 1 × 1 pair (a thumbnail, a placeholder, a bug in the client) is refused on every image
/// route with a 422 naming both images and the smallest size matched, not matched into a map
/// with a warning.
#[tokio::test]
async fn a_pair_too_small_to_match_is_named_on_every_route() {
    let app = spawn_app().await;
    let dot = encode::png_grey(1, 1, &[128]);
    let rig = r#"{"focal_length_px": 400, "baseline": 120, "unit": "mm"}"#;
    for route in ["/depth-map", "/match", "/rectify"] {
        let form = Form::new()
            .part("left", part(dot.clone(), true))
            .part("right", part(dot.clone(), true))
            .text("rig", rig)
            .text("points", r#"[{"x": 0, "y": 0}]"#);
        let response = app.post_form(route, form).await;
        let body = problem(response, 422).await;
        for side in ["left", "right"] {
            let said = message_for(&body, side);
            assert!(
                said.contains("is 1 × 1 pixels") && said.contains("smaller than 32 pixels a side"),
                "{route} {side}: {body}"
            );
        }
    }
}
