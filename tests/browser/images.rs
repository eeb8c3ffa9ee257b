//! The page's Images mode in headless Chromium: a pair uploaded through the file inputs, its
//! depth map, hover, click and box on the project's synthetic scene (whose disparities are
//! known exactly), a calibration imported, the sample link, the keyboard, and a phone screen.
//! Every test also checks that the console holds no error (CSP violations included) and that
//! the page asked only this origin's documented paths.

use std::path::PathBuf;

use fantoccini::actions::{MOUSE_BUTTON_LEFT, PointerAction};
use fantoccini::key::Key;
use serde_json::{Value, json};
use stereo_core::vision::{encode, synthetic};

use crate::harness::Browser;

/// The uploaded scene's size: not the sample's, so the page must take the pair's own size.
const W: usize = 400;
const H: usize = 300;
/// The rig the tests type in: f·B = 48 000 px·mm.
const RIG: &str = "focal_mode=px&focal_length_px=400&baseline=120&unit=mm&max_disparity=48";
const FB: f64 = 48_000.0;
/// The σ model's floor (px), as the page shows σ_d: to 3 digits.
const FLOOR: f64 = stereo_core::vision::sigma::MODEL.floor as f64 - 5e-4;

/// Writes the layered synthetic pair (`W` × `H`) as PNG files and returns their paths.
fn synthetic_pair() -> [PathBuf; 2] {
    let pair = synthetic::render(&synthetic::layered(W, H));
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("e2e-pair");
    std::fs::create_dir_all(&dir).expect("a folder for the pair");
    let left = dir.join("synthetic-left.png");
    let right = dir.join("synthetic-right.png");
    std::fs::write(&left, encode::png_rgb(W, H, &pair.left_rgb)).expect("left written");
    std::fs::write(&right, encode::png_rgb(W, H, &pair.right_rgb)).expect("right written");
    [left, right]
}

/// The first number in `text` after `after`.
pub(crate) fn number_after(text: &str, after: &str) -> f64 {
    let rest = &text[text
        .find(after)
        .unwrap_or_else(|| panic!("{after:?} in {text:?}"))
        + after.len()..];
    let number: String = rest
        .trim_start()
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.' || *c == '-')
        .collect();
    number
        .parse()
        .unwrap_or_else(|_| panic!("a number after {after:?} in {text:?}"))
}

impl Browser {
    /// A 1280 × 1500 window on the images page with the rig in its address and the
    /// synthetic pair uploaded, once its depth map shows: the browser, the pair's files and
    /// the map's valid fraction.
    async fn with_synthetic_depth_map() -> (Browser, [PathBuf; 2], f64) {
        let [left, right] = synthetic_pair();
        let browser = Browser::start(1280, 1500).await;
        browser.open(&format!("/?mode=images&{RIG}")).await;
        browser.upload(&left, &right).await;
        let valid = browser.depth_map_shown().await;
        (browser, [left, right], valid)
    }

    /// Waits until the page has asked `/depth-map` with `member` (`name=value`) in its query,
    /// and then until its address (the permalink) keeps it.
    async fn asked_and_kept(&self, member: &str) {
        let script = format!(
            "return performance.getEntriesByType('resource').map(e => e.name)\
               .filter(n => n.includes('/depth-map?') && n.includes('{member}')).length"
        );
        self.until(&format!("a depth map asked with {member}"), || async {
            let asked = self.script(&script).await;
            (asked.as_u64() >= Some(1)).then_some(())
        })
        .await;
        self.until(&format!("{member} in the address"), || async {
            let at = self.script("return location.search").await;
            at.as_str()
                .is_some_and(|q| q.contains(member))
                .then_some(())
        })
        .await;
    }

    /// Opens Images mode from a permalink with `member` (`name=value`) added, sends `pair`,
    /// and waits until the service's refusal shows under the member's control and says
    /// `words`: that text.
    async fn refused_from_permalink(
        &self,
        member: &str,
        pair: &[PathBuf; 2],
        words: &str,
    ) -> String {
        self.open(&format!("/?mode=images&{RIG}&{member}")).await;
        self.upload(&pair[0], &pair[1]).await;
        self.depth_map_shown_or_refused().await;
        let name = member.split('=').next().unwrap_or(member);
        self.until(&format!("{name}'s error"), || async {
            let text = self.text(&format!("{name}-error")).await;
            text.contains(words).then_some(text)
        })
        .await
    }

    /// Waits until the depth map has been fetched and drawn, and returns the share of valid
    /// pixels the page reports.
    pub(crate) async fn depth_map_shown(&self) -> f64 {
        self.until("the depth map", || async {
            let valid = self
                .script(
                    "return document.body.dataset.depth === 'done' ? \
                       (document.getElementById('depth-status').dataset.valid ?? null) : null",
                )
                .await;
            valid.as_str().and_then(|v| v.parse().ok())
        })
        .await
    }

    /// Clicks "Show each pixel's σ" and returns what the depth view then shows: the colour
    /// bar's kind and unit and the view's caption.
    pub(crate) async fn toggle_sigma(&self) -> [String; 3] {
        self.find("show-sigma").await.click().await.expect("click");
        [
            self.attr("colour-bar", "data-kind")
                .await
                .unwrap_or_default(),
            self.attr("colour-bar", "data-unit")
                .await
                .unwrap_or_default(),
            self.text("depth-caption").await,
        ]
    }

    /// Points at pixel (`x`, `y`) of the left image and returns the hover read-out there.
    async fn hover_at(&self, x: f64, y: f64) -> String {
        let at = self.pointer_to("left-frame", x, y).await;
        self.mouse(vec![at]).await;
        self.until("the hover read-out", || async {
            let text = self.text("hover").await;
            text.starts_with('(').then_some(text)
        })
        .await
    }

    /// Waits until no `/match` request is in flight and the page has settled.
    pub(crate) async fn found(&self) {
        self.until_done("match").await;
        self.settled().await;
    }

    pub(crate) async fn upload(&self, left: &PathBuf, right: &PathBuf) {
        for (id, path) in [("left_image", left), ("right_image", right)] {
            self.find(id)
                .await
                .send_keys(path.to_str().expect("a UTF-8 path"))
                .await
                .expect("a file chosen");
        }
    }

    /// Waits until the last depth-map request has come back, whatever its answer.
    async fn depth_map_shown_or_refused(&self) {
        self.until_done("depth").await;
    }

    /// No console error or CSP violation, and every request went to this origin and to a
    /// path the service documents: its OpenAPI paths, the page's assets and the sample.
    pub(crate) async fn assert_clean(&self) {
        self.assert_clean_but(&[]).await;
    }

    /// As [`Browser::assert_clean`], except the console's note of each refused request with
    /// one of the `statuses` the test provoked.
    pub(crate) async fn assert_clean_but(&self, statuses: &[&str]) {
        let errors: Vec<String> = self
            .console_errors()
            .await
            .into_iter()
            .filter(|e| {
                !statuses
                    .iter()
                    .any(|s| e.contains(&format!("status of {s}")))
            })
            .collect();
        assert!(errors.is_empty(), "console errors: {errors:?}");
        let spec: Value = reqwest::get(format!("{}/openapi.json", self.base))
            .await
            .expect("the spec")
            .json()
            .await
            .expect("JSON");
        let mut documented: Vec<String> = spec["paths"]
            .as_object()
            .expect("paths")
            .keys()
            .cloned()
            .collect();
        documented.extend(
            stereo_distance::web::ASSETS
                .iter()
                .map(|a| a.path.to_owned()),
        );
        documented.extend(
            stereo_distance::web::SAMPLE_FILES
                .iter()
                .map(|p| (*p).to_owned()),
        );
        documented.extend(stereo_distance::web::board_files());
        for (origin, path) in self.requests().await {
            assert_eq!(origin, self.base, "a request to another origin: {path}");
            assert!(
                documented.contains(&path),
                "an undocumented request: {path}"
            );
        }
    }
}

/// Upload the synthetic pair through the file inputs: the depth map comes back and is drawn
/// with a colour bar in mm; hovering over the box (d = 22 px) reads B·f/22 ± σ_Z with the
/// pixel's σ_d from the arrays; "Show each pixel's σ" draws the σ map with its colour bar in mm;
/// a click there matches at x − 22 in the right image, marked on its row, the distance card
/// reads B·f/22 and splits the match's error bar into matching and calibration; a box dragged
/// on the disc reads its median; "Copy results" includes the match; a range typed short of
/// the scene is named in the status.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn an_uploaded_pair_is_matched_hovered_clicked_and_boxed() {
    // Arrange
    let [left, right] = synthetic_pair();
    let browser = Browser::start(1280, 1500).await;
    browser.open(&format!("/?mode=images&{RIG}")).await;
    assert_eq!(
        browser.attr("mode-images", "aria-current").await.as_deref(),
        Some("page")
    );

    // Act: choose both files.
    browser.upload(&left, &right).await;
    let valid = browser.depth_map_shown().await;

    // Assert: the depth map, its size taken from the pair, its colour bar in mm.
    assert!(valid > 0.85, "{valid} of the pixels valid");
    assert_eq!(browser.value("image_width").await, W.to_string());
    assert_eq!(browser.value("image_height").await, H.to_string());
    let status = browser.text("depth-status").await;
    assert!(
        status.starts_with(&format!("Depth map {W} × {H}:")),
        "{status}"
    );
    assert_eq!(
        browser.attr("colour-bar", "data-unit").await.as_deref(),
        Some("mm")
    );

    // Act: hover over the box, whose disparity is 22 px everywhere.
    let hover = browser.hover_at(120.0, 100.0).await;

    // Assert: B·f/22 within 1 %, "Z ± σ_Z", σ_Z = Z²·σ_d/(f·B) with the pixel's σ_d (read
    // to 3 digits), which on this clean render lies between the model's floor and a pixel.
    let z = number_after(&hover, ":");
    let truth = FB / 22.0;
    assert!((z - truth).abs() < 0.01 * truth, "{hover}");
    let error = number_after(&hover, "±");
    let sd = number_after(&hover[hover.find("d =").expect("d")..], "±");
    assert!((FLOOR..1.0).contains(&sd), "{hover}");
    assert!((error - z * z * sd / FB).abs() < 0.01 * error, "{hover}");
    assert!(
        hover.contains(" mm ± ") && hover.ends_with(" px"),
        "{hover}"
    );

    // Act / Assert: the σ toggle draws each σ_d on its fixed scale in px, and back.
    assert_eq!(
        browser.toggle_sigma().await,
        ["sigma", "px", "σ of each disparity"]
    );
    assert_eq!(browser.toggle_sigma().await, ["depth", "mm", "Depth map"]);

    // Act: click a pixel of the box.
    browser.click_pixel("left-frame", 120.0, 150.0).await;
    browser.found().await;

    // Assert: the match is ok, 22 px to the left on the same row, marked there and on its
    // row; the distance card reads B·f/22 from /distance.
    assert_eq!(browser.text("match-status").await, "ok");
    let x = browser
        .script("return Number(document.getElementById('left-marker').getAttribute('cx')) - 0.5")
        .await
        .as_f64()
        .expect("the left marker");
    assert!((x - 120.0).abs() <= 1.0, "clicked pixel {x}");
    let marker = browser
        .script(
            "const m = document.getElementById('right-marker'); \
             const e = document.getElementById('epipolar'); \
             return [Number(m.dataset.x), Number(m.dataset.y), Number(e.getAttribute('y1'))]",
        )
        .await;
    let [x_right, y, row]: [f64; 3] = serde_json::from_value(marker).expect("the right marker");
    assert!(
        (x - x_right - 22.0).abs() < 0.25,
        "x_right {x_right} for x {x}"
    );
    assert!(
        (y - 150.0).abs() <= 1.0 && row == y + 0.5,
        "row {row}, y {y}"
    );
    let distance = browser.text("distance").await;
    assert!(distance.ends_with(" mm"), "{distance}");
    let z = number_after(&distance, "");
    assert!((z - truth).abs() < 0.005 * truth, "{distance}");
    let confidence: f64 = browser
        .text("match-confidence")
        .await
        .parse()
        .expect("a number");
    assert!(confidence > 0.5, "{confidence}");
    assert!(browser.text("range").await.ends_with(" mm"));
    // The card's error bar from the match: all of it matching, the rig having no σ_f or σ_B.
    let split = browser
        .until("the error bar's split", || async {
            browser.attr("error-split", "data-matching").await
        })
        .await;
    let matching: f64 = split.parse().expect("a number");
    assert!(matching > 0.0, "{split}");
    assert_eq!(
        browser
            .attr("error-split", "data-calibration")
            .await
            .as_deref(),
        Some("0")
    );
    let line = browser.text("error-split").await;
    assert!(
        line.contains("matching ±") && line.contains("calibration ±"),
        "{line}"
    );
    // One error bar: the Distance card's ± is the match's σ_Z, not the default Δd = 0.5 px
    // (about twice the σ_d of this clean render), and the card says what it stands on.
    assert_eq!(
        browser.attr("depth-error", "data-basis").await.as_deref(),
        Some("sigma")
    );
    let card = number_after(&browser.text("depth-error").await, "±");
    let sigma = browser.text("match-sigma").await;
    let from_match = number_after(&sigma, "±");
    assert!(
        (card - from_match).abs() <= 0.005 * from_match,
        "card ± {card}, match {sigma}"
    );
    let detail = browser.text("distance-detail").await;
    assert!(detail.contains("± is σ"), "{detail}");

    // Act: drag a box on the disc, d = 30 − 4x/400: 27.2 px at its centre x = 280.
    let from = browser.pointer_to("left-frame", 265.0, 135.0).await;
    let to = browser.pointer_to("left-frame", 295.0, 165.0).await;
    browser
        .mouse(vec![
            from,
            PointerAction::Down {
                button: MOUSE_BUTTON_LEFT,
            },
            to,
            PointerAction::Up {
                button: MOUSE_BUTTON_LEFT,
            },
        ])
        .await;
    browser.found().await;

    // Assert
    let region = browser
        .until("the region's distance", || async {
            browser.attr("region-summary", "data-distance").await
        })
        .await;
    let median: f64 = region.parse().expect("a number");
    let disc = FB / 27.2;
    assert!(
        (median - disc).abs() < 0.01 * disc,
        "median {median}, truth {disc}"
    );
    let summary = browser.text("region-summary").await;
    assert!(summary.contains("p10–p90"), "{summary}");
    let width: f64 = browser
        .script("return Number(document.getElementById('box').getAttribute('width'))")
        .await
        .as_f64()
        .expect("the box");
    assert!((width - 31.0).abs() <= 2.0, "box width {width}");

    // Act / Assert: "Copy results" includes the match and the region.
    let copied = browser.copy_results().await;
    let copied = copied.as_str();
    assert!(copied.contains("Match: left ("), "{copied}");
    assert!(copied.contains("status ok"), "{copied}");
    assert!(copied.contains("Region: ("), "{copied}");
    assert!(copied.contains("mode=images"), "{copied}");

    // Act / Assert: a download is the service's file, saved under its name.
    browser
        .client
        .find(fantoccini::Locator::Css("button[data-output='points.ply']"))
        .await
        .expect("the PLY button")
        .click()
        .await
        .expect("click");
    let saved = browser
        .until("the download", || async {
            let text = browser.text("download-status").await;
            text.starts_with("Saved").then_some(text)
        })
        .await;
    assert!(saved.starts_with("Saved points.ply ("), "{saved}");

    // Act / Assert: a search that stops short of the scene (its box at 22 px) is named in the
    // status, as the service warns of it, rather than drawn as if it were right.
    browser.type_into("max_disparity", "16").await;
    let short = browser
        .until("the short range's warning", || async {
            let text = browser.text("depth-status").await;
            text.contains("Warnings: max_disparity 16 stops short of the scene")
                .then_some(text)
        })
        .await;
    assert!(short.contains("refused (left empty)"), "{short}");

    browser.assert_clean().await;
    browser.assert_no_alert().await;
    browser.screenshot("images-upload.png").await;
    browser.close().await;
}

/// Images mode without a rig (neither typed, imported nor in the address): the depth map is
/// drawn in disparities with a colour bar in px, hovering reads d in px, a click says that
/// distances need the rig instead of using the calculator's example, and the page offers the
/// calibration import; importing one turns the map into depths in mm.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn without_a_rig_the_page_shows_disparities_and_asks_for_one() {
    // Arrange
    let [left, right] = synthetic_pair();
    let browser = Browser::start(1280, 1500).await;
    browser.open("/?mode=images").await;

    // Act
    browser.upload(&left, &right).await;
    browser.depth_map_shown().await;

    // Assert: disparities, in px, and the plain words.
    assert_eq!(
        browser.attr("colour-bar", "data-unit").await.as_deref(),
        Some("px")
    );
    assert_eq!(browser.attr("rig-needed", "hidden").await, None);
    let bar = browser
        .script("return document.getElementById('colour-bar-title').textContent")
        .await;
    assert!(
        bar.as_str()
            .is_some_and(|t| t.contains("distances need the rig")),
        "{bar}"
    );
    let hover = browser.hover_at(120.0, 100.0).await;
    assert!((number_after(&hover, "d =") - 22.0).abs() < 0.3, "{hover}");
    assert!((FLOOR..1.0).contains(&number_after(&hover, "±")), "{hover}");
    assert!(
        hover.contains("need the rig") && !hover.contains("mm"),
        "{hover}"
    );
    let distance = browser.text("distance-detail").await;
    assert!(distance.starts_with("Distances need the rig"), "{distance}");
    assert_eq!(
        browser.attr("mini-result", "class").await.as_deref(),
        Some("mini-result")
    );

    // Act: a click asks for the rig, not /match with a made-up one.
    browser.click_pixel("left-frame", 120.0, 150.0).await;
    browser
        .until_text(
            "match-summary",
            "Distances need the rig: import a calibration file or type f and B under Rig.",
        )
        .await;
    let asked: Vec<String> = browser
        .requests()
        .await
        .into_iter()
        .map(|(_, path)| path)
        .collect();
    assert!(!asked.iter().any(|p| p.starts_with("/match")), "{asked:?}");
    // The /depth-map request carried no rig: the map has disparities only.
    assert!(browser.script("return document.body.dataset.depth").await == "done");

    // Act: the offered import, with the pair's own calibration file.
    browser
        .find("rig-needed-import")
        .await
        .click()
        .await
        .expect("click");
    assert_eq!(
        browser.attr("import", "open").await.as_deref(),
        Some("true")
    );
    let calib = format!(
        "cam0=[400 0 {cx}; 0 400 {cy}; 0 0 1]\ncam1=[400 0 {cx}; 0 400 {cy}; 0 0 1]\ndoffs=0\n\
         baseline=120\nwidth={W}\nheight={H}\nndisp=48\n",
        cx = W / 2,
        cy = H / 2
    );
    browser
        .find("calibration_text")
        .await
        .send_keys(&calib)
        .await
        .expect("typed");
    browser
        .find("import-button")
        .await
        .click()
        .await
        .expect("click");
    browser
        .until("the map in depths", || async {
            (browser.attr("colour-bar", "data-unit").await.as_deref() == Some("mm")).then_some(())
        })
        .await;

    // Assert: the rig is given, the notice gone, and a hover reads B·f/22 in mm.
    assert_eq!(
        browser.attr("rig-needed", "hidden").await.as_deref(),
        Some("true")
    );
    browser
        .mouse(vec![browser.pointer_to("left-frame", 121.0, 100.0).await])
        .await;
    let hover = browser
        .until("the hover in mm", || async {
            let text = browser.text("hover").await;
            text.contains(" mm ± ").then_some(text)
        })
        .await;
    let z = number_after(&hover, ":");
    assert!((z - FB / 22.0).abs() < 0.01 * FB / 22.0, "{hover}");
    browser.screenshot("images-no-rig.png").await;
    browser.assert_clean().await;
    browser.close().await;
}

/// A pair of two sizes shows the API's error next to the right image's input, a file that
/// is not an image shows it next to the left one's, and so does a PNG cut off mid-file.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn a_wrong_pair_is_refused_next_to_the_file_input() {
    // Arrange
    let [left, _] = synthetic_pair();
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("e2e-pair");
    let small = synthetic::render(&synthetic::layered(200, 150));
    let right = dir.join("small-right.png");
    std::fs::write(&right, encode::png_rgb(200, 150, &small.right_rgb)).expect("written");
    let text = dir.join("notes.png");
    std::fs::write(&text, "not an image at all").expect("written");
    let browser = Browser::start(1280, 1500).await;
    browser.open(&format!("/?mode=images&{RIG}")).await;

    // Act
    browser.upload(&left, &right).await;
    browser.depth_map_shown_or_refused().await;

    // Assert
    browser
        .until("the right image's error", || async {
            let hidden = browser.attr("right_image-error", "hidden").await;
            hidden.is_none().then_some(())
        })
        .await;
    let message = browser.text("right_image-error").await;
    assert!(
        message.contains("400") && message.contains("200"),
        "{message}"
    );
    assert_eq!(
        browser.attr("right_image", "aria-invalid").await.as_deref(),
        Some("true")
    );

    // Act: a text file as the left image.
    browser
        .find("left_image")
        .await
        .send_keys(text.to_str().unwrap())
        .await
        .expect("chosen");
    browser.depth_map_shown_or_refused().await;

    // Assert
    let message = browser
        .until("the left image's error", || async {
            let text = browser.text("left_image-error").await;
            (!text.is_empty()).then_some(text)
        })
        .await;
    assert!(message.contains("image"), "{message}");

    // Act: a left image cut off at 60 % of its bytes (an interrupted copy).
    let whole = std::fs::read(&left).expect("read");
    let cut = dir.join("cut-left.png");
    std::fs::write(&cut, &whole[..whole.len() * 6 / 10]).expect("written");
    let [_, good_right] = synthetic_pair();
    browser.upload(&cut, &good_right).await;
    browser.depth_map_shown_or_refused().await;

    // Assert: the service's words, next to the left image's input.
    let message = browser
        .until("the cut-off image's error", || async {
            let text = browser.text("left_image-error").await;
            text.contains("cut off").then_some(text)
        })
        .await;
    assert!(message.contains("send the whole file"), "{message}");
    browser.assert_clean_but(&["422", "413"]).await;
    browser.close().await;
}

/// Importing Middlebury's `calib.txt` (Motorcycle's, full size) fills f, B, doffs, the
/// principal point, the size and the search range, says it was read as Middlebury, and the
/// Numbers mode computes with it; a damaged file shows the line the service names.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn an_imported_middlebury_calibration_fills_the_fields() {
    // Arrange
    let browser = Browser::at_defaults().await;
    let calib = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/calibration/middlebury_motorcycle_calib.txt");
    browser
        .find("import")
        .await
        .click()
        .await
        .expect("open the import box");

    // Act
    browser
        .find("calibration_file")
        .await
        .send_keys(calib.to_str().unwrap())
        .await
        .expect("a file chosen");
    browser
        .until("the import", || async {
            let format = browser.attr("import-status", "data-format").await;
            format.filter(|f| f == "middlebury")
        })
        .await;
    browser.settled().await;

    // Assert
    for (id, value) in [
        ("focal", "3979.911"),
        ("baseline", "193.001"),
        ("doffs", "124.343"),
        ("cx", "1244.772"),
        ("cy", "1019.507"),
        ("image_width", "2964"),
        ("image_height", "2000"),
        ("max_disparity", "270"),
    ] {
        assert_eq!(browser.value(id).await, value, "#{id}");
    }
    assert_eq!(browser.value("focal_mode").await, "px");
    let status = browser.text("import-status").await;
    assert!(
        status.starts_with("Read as a Middlebury calibration"),
        "{status}"
    );
    // x_left 400, x_right 350: d = 50, Z = 193.001 × 3979.911 / (50 + 124.343).
    let expected = 193.001 * 3979.911 / (50.0 + 124.343);
    let distance = browser.text("distance").await;
    let z = number_after(&distance, "");
    assert!((z - expected).abs() < 1e-3 * expected, "{distance}");

    // Act: a damaged file.
    let text = browser.find("calibration_text").await;
    text.clear().await.expect("clear");
    text.send_keys("cam0=[3979.911 0 1244.772; 0 3979.911 1019.507; 0 0 1]\ncam1=[3979.911 0]\n")
        .await
        .expect("typed");
    browser
        .find("import-button")
        .await
        .click()
        .await
        .expect("click");
    let errors = browser
        .until("the import's error", || async {
            let text = browser.text("import-errors").await;
            (!text.is_empty()).then_some(text)
        })
        .await;

    // Assert: the line is named, next to the import box; the fields keep the last rig.
    assert!(errors.contains("text: line 2"), "{errors}");
    assert_eq!(browser.value("focal").await, "3979.911");
    browser.assert_clean_but(&["422"]).await;
    browser.close().await;
}

/// `/?mode=images&sample=1` opens with the sample pair, its rig and its depth map, which
/// blends over the left image; from the keyboard the crosshair moves and Enter matches, and
/// Space, arrows and Enter measure a box; "Reset defaults" keeps the pair's size; and the
/// console check used everywhere does catch a CSP violation.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn the_sample_link_opens_with_a_depth_map_and_works_from_the_keyboard() {
    // Arrange / Act
    let browser = Browser::start(1280, 1500).await;
    browser.open("/?mode=images&sample=1").await;
    let valid = browser.depth_map_shown().await;

    // Assert: the sample's rig and its depth map.
    assert!(valid > 0.85, "{valid}");
    assert_eq!(browser.value("focal").await, "400");
    assert_eq!(browser.value("baseline").await, "120");
    assert_eq!(browser.value("max_disparity").await, "48");
    let url = browser.client.current_url().await.expect("url");
    assert!(url.as_str().contains("sample=1"), "{url}");
    let bar = browser.text("colour-bar").await;
    assert!(bar.contains("Depth (mm)"), "{bar}");

    // Act / Assert: blended over the left image, at the slider's opacity.
    browser.find("blend").await.click().await.expect("click");
    let blend = browser
        .script(
            "return [document.getElementById('views').dataset.blend,                      document.getElementById('blend-canvas').style.opacity,                      getComputedStyle(document.getElementById('depth-frame')).display]",
        )
        .await;
    assert_eq!(blend, json!(["true", "0.6", "none"]));
    browser.find("blend").await.click().await.expect("click");

    // Act: focus the left image, move the crosshair from the centre (160, 120) onto the box
    // (x 48–144: d = 22), press Enter.
    let frame = browser.find("left-frame").await;
    frame.click().await.ok();
    browser.found().await;
    let shift_left = format!("{}{}", char::from(Key::Shift), char::from(Key::Left));
    for _ in 0..6 {
        frame.send_keys(&shift_left).await.expect("keys");
    }
    let crosshair = browser
        .script("const c = document.getElementById('crosshair'); return [Number(c.dataset.x), Number(c.dataset.y)]")
        .await;
    let [cx, _]: [f64; 2] = serde_json::from_value(crosshair).expect("the crosshair");
    frame
        .send_keys(&char::from(Key::Enter).to_string())
        .await
        .expect("Enter");
    browser.found().await;

    // Assert: matched at the crosshair, 22 px to the left.
    let marker = browser
        .script("const m = document.getElementById('right-marker'); return [Number(m.dataset.x)]")
        .await;
    let [x_right]: [f64; 1] = serde_json::from_value(marker).expect("the right marker");
    assert!((cx - x_right - 22.0).abs() < 0.25, "{cx} → {x_right}");
    let z = number_after(&browser.text("distance").await, "");
    assert!((z - FB / 22.0).abs() < 0.005 * FB / 22.0, "{z}");

    // Act: a box from the keyboard: Space, 8 px right and down, Enter.
    frame.send_keys(" ").await.expect("Space");
    for _ in 0..8 {
        frame
            .send_keys(&format!(
                "{}{}",
                char::from(Key::Right),
                char::from(Key::Down)
            ))
            .await
            .expect("keys");
    }
    frame
        .send_keys(&char::from(Key::Enter).to_string())
        .await
        .expect("Enter");
    browser.found().await;
    let median: f64 = browser
        .until("the region", || async {
            browser.attr("region-summary", "data-distance").await
        })
        .await
        .parse()
        .expect("a number");
    assert!((median - FB / 22.0).abs() < 0.01 * FB / 22.0, "{median}");
    browser.screenshot("images.png").await;

    // Act / Assert: "Reset defaults" restores the calculator's rig but keeps the pair's size,
    // so the pair is matched again (with no error) rather than refused.
    browser.find("reset").await.click().await.expect("click");
    browser.settled().await;
    assert_eq!(browser.value("focal").await, "35");
    assert_eq!(browser.value("image_width").await, "320");
    assert_eq!(browser.value("image_height").await, "240");
    browser.depth_map_shown().await;
    browser.assert_clean().await;

    // The console check sees a CSP violation: an image from another origin is refused and
    // reported.
    browser
        .script(
            "const i = document.createElement('img'); i.src = 'http://192.0.2.1/x.png'; \
             document.body.append(i);",
        )
        .await;
    let errors = browser
        .until("the CSP violation in the console", || async {
            let errors = browser.console_errors().await;
            (!errors.is_empty()).then_some(errors)
        })
        .await;
    assert!(
        errors.iter().any(|e| e.contains("Content Security Policy")),
        "{errors:?}"
    );
    browser.close().await;
}

/// On a 390 px phone the sample's images stack, one above the other, and nothing scrolls
/// sideways.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn the_images_stack_on_a_phone() {
    // Arrange / Act
    let browser = Browser::phone(390, 844).await;
    browser.open("/?mode=images&sample=1").await;
    browser.depth_map_shown().await;

    // Assert
    browser.assert_no_sideways_scroll().await;
    let stacked = browser
        .script(
            "const r = ['left-frame', 'depth-frame', 'right-frame']\
               .map(id => document.getElementById(id).getBoundingClientRect());\
             return r[0].bottom <= r[1].top && r[1].bottom <= r[2].top && r.every(b => b.right <= 390)",
        )
        .await;
    assert_eq!(stacked, json!(true), "the images stack within the screen");
    // Before any click the hint bar invites one, in its plain colours: nothing is wrong.
    browser.settled().await;
    assert_eq!(
        browser.text("distance-detail").await,
        "Click the left image for a distance."
    );
    assert_eq!(
        browser.attr("mini-result", "class").await.as_deref(),
        Some("mini-result")
    );
    // The table's caption stays put while the table scrolls sideways.
    let caption_outside = browser
        .script("return document.getElementById('table-caption').closest('.table-wrap') === null")
        .await;
    assert_eq!(caption_outside, json!(true));
    browser.assert_clean().await;
    browser
        .script("document.getElementById('views').scrollIntoView()")
        .await;
    browser.screenshot("images-phone.png").await;
    browser.close().await;
}

/// The matcher's preset: choosing Fast sends `preset=fast` with the depth map's request and
/// keeps it in the address; a permalink's made-up preset goes to the service, whose refusal
/// is shown next to the select.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn the_fast_preset_is_sent_kept_and_refused_when_made_up() {
    // Arrange
    let (browser, pair, _) = Browser::with_synthetic_depth_map().await;
    assert_eq!(browser.value("preset").await, "accurate");

    // Act
    browser.choose("preset", "fast").await;

    // Assert: a depth map asked with the preset, and the address keeps it.
    browser.asked_and_kept("preset=fast").await;
    let valid = browser.depth_map_shown().await;
    assert!(valid > 0.5, "{valid}");

    // Act and assert: a permalink with a preset that does not exist; the service's words,
    // next to the select.
    let error = browser
        .refused_from_permalink("preset=slow", &pair, "must be accurate or fast")
        .await;
    assert!(error.contains("`slow`"), "{error}");
    browser.assert_clean_but(&["422"]).await;
    browser.close().await;
}

/// The keep rule: a σ typed under the matcher goes with the depth map's request as
/// `max_disparity_std`, leaves fewer pixels valid and stays in the address; a permalink's
/// threshold of 0 goes to the service, whose refusal is shown next to the field.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn a_sigma_threshold_is_sent_kept_and_refused_when_zero() {
    // Arrange
    let (browser, pair, before) = Browser::with_synthetic_depth_map().await;

    // Act: the threshold pasted in (typed key by key, its prefix "0" would be asked first).
    browser
        .script(
            "const field = document.getElementById('max_disparity_std'); field.value = '0.25'; \
             field.dispatchEvent(new Event('input', { bubbles: true }))",
        )
        .await;

    // Assert: a depth map asked with the threshold, fewer pixels kept, the address keeps it.
    browser.asked_and_kept("max_disparity_std=0.25").await;
    let after = browser
        .until("fewer pixels kept", || async {
            let valid = browser.depth_map_shown().await;
            (valid < before - 0.01).then_some(valid)
        })
        .await;
    assert!(after > 0.05, "{before} -> {after}");

    // Act and assert: a permalink with a threshold of 0; the service's words, next to the
    // field.
    let error = browser
        .refused_from_permalink("max_disparity_std=0", &pair, "must lie in (0, 64]")
        .await;
    assert!(error.contains("got 0"), "{error}");
    browser.assert_clean_but(&["422"]).await;
    browser.close().await;
}

/// At a laptop's 1280 × 900, the first screen of Images mode holds the pair's file inputs and
/// the top of the views the depth map is drawn in, the matcher's options folded under their
/// summary (a permalink that gives one opens them); Calibrate mode's holds the board inputs
/// and its Calibrate button.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn a_laptops_first_screen_reaches_the_depth_map() {
    // Arrange
    let browser = Browser::start(1280, 900).await;

    // Act
    browser.open("/?mode=images").await;

    // Assert
    for id in ["left_image", "right_image"] {
        let (_, bottom, height) = browser.place(id).await;
        assert!(bottom < height, "#{id} ends at {bottom} of {height}");
    }
    let (top, _, height) = browser.place("views").await;
    assert!(top < height - 150.0, "the views start at {top} of {height}");
    assert_eq!(browser.attr("matcher-options", "open").await, None);
    browser.open("/?mode=images&max_disparity=48").await;
    assert!(browser.attr("matcher-options", "open").await.is_some());
    assert_eq!(browser.value("max_disparity").await, "48");

    browser.open("/?mode=calibrate").await;
    for id in ["board_files", "board_columns", "calibrate-button"] {
        let (_, bottom, height) = browser.place(id).await;
        assert!(bottom < height, "#{id} ends at {bottom} of {height}");
    }
    browser.assert_clean().await;
    browser.close().await;
}

/// The depth map's colour bar keeps every label inside it: with a rig whose scene lies 22 to
/// 60 m away, the far end's five digits read whole at the bar's left end (they read "0000",
/// cut, when centred on their tick).
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn the_colour_bars_labels_are_never_cut() {
    // Arrange: f·B = 480 000 px·mm, the scene's 8 to 22 px at 21.8 to 60 m.
    let [left, right] = synthetic_pair();
    let browser = Browser::start(1280, 1500).await;
    browser
        .open("/?mode=images&focal_mode=px&focal_length_px=400&baseline=1200&unit=mm&max_disparity=48")
        .await;

    // Act
    browser.upload(&left, &right).await;
    browser.depth_map_shown().await;

    // Assert: each label's box within the bar's 320 units, one of them five digits long.
    let labels = browser
        .script(
            "return [...document.querySelectorAll('#colour-bar text')].map(t => { \
             const b = t.getBBox(); return [t.textContent, b.x, b.x + b.width]; })",
        )
        .await;
    let labels = labels.as_array().expect("labels");
    assert!(labels.len() >= 3, "{labels:?}");
    for label in labels {
        let (from, to) = (label[1].as_f64().unwrap(), label[2].as_f64().unwrap());
        assert!(from >= -0.5 && to <= 320.5, "{label} leaves the bar");
    }
    assert!(
        labels.iter().any(|l| l[0]
            .as_str()
            .unwrap()
            .chars()
            .filter(char::is_ascii_digit)
            .count()
            >= 5),
        "{labels:?}"
    );
    browser.assert_clean().await;
    browser.close().await;
}
