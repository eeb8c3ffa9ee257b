//! A wide lens on the page: a raw 180° fisheye pair with its `stereoCalibrate` file pasted in,
//! rectified to latitude-longitude when that projection is chosen; its rows in the rectified
//! view, its depth over the whole field, and a click on the raw view measured along its ray.

use std::path::PathBuf;

use serde_json::Value;
use stereo_core::vision::encode;

use crate::harness::Browser;
use crate::raw_files::{DISPARITY, H, W, rendered};

/// The rendered pair written as PNG files.
fn wide_pair(frames: &[Vec<u8>; 2]) -> [PathBuf; 2] {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("e2e-wide");
    std::fs::create_dir_all(&dir).expect("a folder for the pair");
    ["left", "right"].map(|side| {
        let path = dir.join(format!("fisheye-{side}.png"));
        let i = usize::from(side == "right");
        std::fs::write(&path, encode::png_grey(W as usize, H as usize, &frames[i]))
            .expect("a frame written");
        path
    })
}

/// The page's arrays: their projection and size, and the share of the map whose disparity
/// is within 0.5 px of the rendered one, of all pixels and of those with one.
async fn arrays(browser: &Browser) -> Value {
    browser
        .script(&format!(
            "return import('/js/store.js').then(({{ pair }}) => {{\
               const a = pair.arrays; let valid = 0, right = 0;\
               for (const d of a.disparity) if (Number.isFinite(d)) {{\
                 valid += 1; if (Math.abs(d - {DISPARITY}) <= 0.5) right += 1; }}\
               return {{ projection: a.projection, width: a.width, height: a.height,\
                        valid: valid / a.disparity.length, right: right / valid }}; }});"
        ))
        .await
}

/// Waits until `#id`'s text holds `words`, and returns it.
async fn contains(browser: &Browser, id: &str, words: &str) -> String {
    browser
        .until(&format!("#{id} to say {words:?}"), || async {
            let text = browser.text(id).await;
            text.contains(words).then_some(text)
        })
        .await
}

/// A 180° fisheye pair, raw, with its calibration imported and `latlon` chosen under the
/// matcher's options: the depth map is the latitude-longitude system's (its size, and the
/// caption says so), nearly all of it right, the address keeps the choice; the rectified view
/// shows the latlon pair with its rows; a click there is not sent (its pixels are angles),
/// and a click on the raw view answers the distance along the ray, as mrcal's range gives it,
/// without handing latlon pixels to the pinhole calculator.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn a_fisheye_pair_is_matched_in_latlon_on_the_page() {
    // Arrange: the pair and its file.
    let (_, system, frames, yml) = rendered();
    let [left, right] = wide_pair(&frames);
    let browser = Browser::start(1280, 1600).await;
    browser.open("/?mode=images").await;
    browser.press("import").await;
    browser
        .script(&format!(
            "document.getElementById('calibration_text').value = {};",
            serde_json::to_string(&yml).unwrap()
        ))
        .await;
    browser.choose("calibration_unit", "mm").await;
    browser.press("import-button").await;
    let imported = browser
        .until("the import", || async {
            let text = browser.text("import-status").await;
            (text.starts_with("Read as") || text.starts_with("Not imported")).then_some(text)
        })
        .await;
    assert!(imported.starts_with("Read as"), "{imported}");
    let x_left_before = browser.value("x_left").await;

    // Act: latlon chosen, the pair uploaded.
    browser.unfold("matcher-options").await;
    browser.choose("projection", "latlon").await;
    browser.upload(&left, &right).await;
    browser.depth_map_shown().await;

    // Assert: a latlon map of the system's size, the field answered and right.
    let a = arrays(&browser).await;
    assert_eq!(a["projection"], "latlon", "{a}");
    assert_eq!(
        a["width"].as_u64(),
        Some(u64::from(system.size.width)),
        "{a}"
    );
    assert_eq!(
        a["height"].as_u64(),
        Some(u64::from(system.size.height)),
        "{a}"
    );
    assert!(a["valid"].as_f64().unwrap() >= 0.8, "{a}");
    assert!(a["right"].as_f64().unwrap() >= 0.95, "{a}");
    let caption = browser.text("depth-caption").await;
    assert!(caption.contains("latitude-longitude"), "{caption}");
    let address = browser.script("return location.search").await;
    assert!(
        address.as_str().unwrap().contains("projection=latlon"),
        "{address}"
    );

    // Act and assert: the rectified view is the latlon pair, its rows drawn.
    browser.press("frames-rectified").await;
    let shown = browser
        .script(
            "const c = document.getElementById('left-canvas'); \
             return [c.width, c.height, document.querySelectorAll('#left-overlay .epipolar-grid').length];",
        )
        .await;
    assert_eq!(
        shown[0].as_u64(),
        Some(u64::from(system.size.width)),
        "{shown}"
    );
    assert_eq!(
        shown[1].as_u64(),
        Some(u64::from(system.size.height)),
        "{shown}"
    );
    assert!(shown[2].as_u64().unwrap() >= 10, "{shown}");
    browser.screenshot("fisheye-latlon.png").await;
    browser.click_pixel("left-frame", 150.0, 160.0).await;
    contains(&browser, "status", "click or box the raw view").await;

    // Act: a click on the raw view, about 55° off the axis.
    browser.press("frames-raw").await;
    browser.click_pixel("left-frame", 60.0, 120.0).await;
    let summary = contains(&browser, "match-summary", "In latitude-longitude").await;

    // Assert: its distance is the range along its ray at the rendered disparity, in the
    // rectified frame's axis, as the map's; the calculator kept its own numbers.
    let m = browser
        .script("return import('/js/store.js').then(({ pair }) => pair.match);")
        .await;
    assert_eq!(m["status"], "ok", "{m}");
    let (x, y) = (
        m["x_rectified"].as_f64().unwrap(),
        m["y_rectified"].as_f64().unwrap(),
    );
    let truth = system.range(x, DISPARITY).unwrap() * system.ray([x, y]).z;
    let distance = m["distance"].as_f64().unwrap();
    assert!(
        (distance - truth).abs() < 0.02 * truth,
        "{distance} against {truth}: {summary}"
    );
    assert_eq!(browser.value("x_left").await, x_left_before);
    println!("latlon on the page: {a}; a raw click's distance {distance} against {truth}");
    browser.assert_clean_but(&[]).await;
    browser.close().await;
}
