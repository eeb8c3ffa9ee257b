//! End-to-end tests of the calculator page at `/`, in headless Chromium driven over WebDriver
//! (chromedriver and the `fantoccini` client) against the real server on 127.0.0.1.
//!
//! They need Debian's `chromium` and `chromium-driver` (`/usr/bin/chromium`,
//! `/usr/bin/chromedriver`; `CHROMIUM` and `CHROMEDRIVER` override the paths), so plain
//! `cargo test` skips them; `.ci/run` installs both and runs
//! `cargo test --test browser -- --ignored --test-threads=1`. Screenshots are written to
//! `target/tmp/e2e/` (`E2E_ARTIFACTS` overrides), and kept as the run's artifacts.

mod calibrate;
mod harness;
mod images;
mod live;
mod photographs;
#[path = "../api/raw_files.rs"]
#[allow(dead_code)]
mod raw_files;
mod tokens;
mod wide;

use fantoccini::{Locator, key::Key};
use serde_json::json;

use harness::{Browser, vertices};

/// The seed's example 1, with f read as pixels, as the form holds it.
const EXAMPLE_ONE: [(&str, &str); 6] = [
    ("focal", "35"),
    ("baseline", "150"),
    ("x_left", "400"),
    ("x_right", "350"),
    ("image_width", "800"),
    ("image_height", "600"),
];

/// The seed's example 2 (f = 12 px, B = 50 mm, 180/195, 640×480: 40 mm) as a permalink.
const EXAMPLE_TWO: &str = "/?focal_mode=px&focal_length_px=12&baseline=50&unit=mm&x_left=180\
                           &x_right=195&image_width=640&image_height=480";

/// The text fields the page has, with the default each must hold after "Reset defaults".
const DEFAULT_FIELDS: [(&str, &str); 13] = [
    ("focal", "35"),
    ("sensor_width_mm", ""),
    ("pixel_size_um", ""),
    ("baseline", "150"),
    ("x_left", "400"),
    ("x_right", "350"),
    ("image_width", "800"),
    ("image_height", "600"),
    ("y", ""),
    ("disparity_error_px", ""),
    ("doffs", ""),
    ("cx", ""),
    ("cy", ""),
];

/// Typing the seed's example 1 into the form shows 105 mm with its error and intermediate
/// values; the page starts from another permalink, so the answer cannot be left over.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn example_one_typed_in_reads_105_mm() {
    // Arrange: the seed's example 2 is on the page.
    let browser = Browser::start(1280, 1800).await;
    browser.open(EXAMPLE_TWO).await;
    browser.until_text("distance", "40 mm").await;
    assert_eq!(browser.value("focal").await, "12");

    // Act
    for (id, value) in EXAMPLE_ONE {
        browser.type_into(id, value).await;
    }

    // Assert
    browser.until_text("distance", "105 mm").await;
    browser.settled().await;
    assert_eq!(browser.text("depth-error").await, "± 1.05 mm");
    // The calculator has no match: its error bar stands on a fixed Δd, and says so.
    assert_eq!(
        browser.attr("depth-error", "data-basis").await.as_deref(),
        Some("fixed")
    );
    let detail = browser.text("distance-detail").await;
    assert!(
        detail.ends_with("for a fixed Δd = 0.5 px (the default)"),
        "{detail}"
    );
    assert_eq!(browser.text("disparity_px").await, "50 px");
    assert_eq!(browser.text("focal_length_px").await, "35 px");
    assert_eq!(browser.text("normalized_x").await, "0");
    assert_eq!(browser.text("projection_factor").await, "0.233333 px/mm");
    assert_eq!(browser.text("point").await, "(0, 0, 105) mm");
    assert_eq!(
        browser.text("formula").await,
        "Z = B·f / |d + doffs| = 150 mm × 35 px / |50 px + 0 px| = 105 mm"
    );
    assert_eq!(browser.text("warnings").await, "None.");
    // The address is the permalink of what was typed.
    let url = browser.client.current_url().await.expect("url");
    let query: Vec<(String, String)> = url.query_pairs().into_owned().collect();
    for (key, value) in [
        ("focal_mode", "px"),
        ("focal_length_px", "35"),
        ("baseline", "150"),
        ("x_left", "400"),
        ("x_right", "350"),
        ("image_width", "800"),
        ("image_height", "600"),
    ] {
        assert!(
            query.contains(&(key.to_owned(), value.to_owned())),
            "{key}={value} in {url}"
        );
    }
    browser.assert_no_alert().await;
    browser.screenshot("calculator.png").await;
    browser.close().await;
}

/// Choosing "millimetres + sensor width" with no sensor width (using only the keyboard) puts
/// the API's explanation next to the focal-length field, marks it invalid, and opens no alert;
/// adding the sensor width clears it and gives the converted distance.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn focal_length_in_mm_without_sensor_width_is_refused_inline() {
    // Arrange
    let browser = Browser::at_defaults().await;
    assert_eq!(
        browser.attr("focal-error", "hidden").await.as_deref(),
        Some("true")
    );

    // Act: the focal mode select, from the keyboard: one step down is "mm + sensor width".
    let mode = browser.find("focal_mode").await;
    mode.send_keys(&char::from(Key::Down).to_string())
        .await
        .expect("arrow down");
    browser
        .until("the focal mode to change", || async {
            (browser.value("focal_mode").await == "mm-sensor").then_some(())
        })
        .await;

    // Assert
    let error = browser
        .until("the inline focal-length error", || async {
            let text = browser.text("focal-error").await;
            (!text.is_empty()).then_some(text)
        })
        .await;
    assert!(
        error.contains("a focal length in millimetres cannot be used on its own"),
        "{error}"
    );
    assert_eq!(
        browser.attr("focal", "aria-invalid").await.as_deref(),
        Some("true")
    );
    assert!(
        browser
            .attr("focal", "aria-describedby")
            .await
            .is_some_and(|ids| ids.contains("focal-error")),
        "the error is announced with the field"
    );
    assert_eq!(browser.text("focal-label").await, "Focal length f (mm)");
    assert!(
        browser
            .find("sensor_width_mm")
            .await
            .is_displayed()
            .await
            .expect("shown")
    );
    assert_eq!(browser.text("distance").await, "–");
    browser.assert_no_alert().await;
    browser.screenshot("focal-mm-error.png").await;

    // Act: the sensor width the message asks for (35 mm × 800 px / 6.4 mm = 4375 px).
    browser.type_into("sensor_width_mm", "6.4").await;

    // Assert: the error is gone and the distance is B·f_px/d = 150 × 4375 / 50.
    browser.until_text("distance", "13125 mm").await;
    browser.settled().await;
    assert_eq!(browser.text("focal-error").await, "");
    assert_eq!(browser.attr("focal", "aria-invalid").await, None);
    assert_eq!(browser.text("focal_length_px").await, "4375 px (converted)");
    browser.close().await;
}

/// The chart is drawn from /chart-data: both curves have the 120 points the page asks for,
/// the axes are titled with units, and the measured point lies on the distance curve.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn the_chart_draws_both_curves_and_marks_the_measured_point() {
    // Arrange / Act: the page as it loads.
    let browser = Browser::at_defaults().await;

    // Assert
    let chart = browser.find("chart").await;
    let curve = |class: &'static str| {
        let chart = chart.clone();
        async move {
            let line = chart
                .find(Locator::Css(&format!("polyline.{class}")))
                .await
                .expect("the curve is drawn");
            vertices(
                &line
                    .attr("points")
                    .await
                    .expect("points")
                    .unwrap_or_default(),
            )
        }
    };
    let distance = curve("distance").await;
    let error = curve("depth-error").await;
    assert_eq!(distance.len(), 120);
    assert_eq!(error.len(), 120);
    // Distance falls as disparity grows: each vertex is right of and not above the last
    // (SVG y grows downwards).
    for pair in distance.windows(2) {
        assert!(pair[1].0 > pair[0].0 && pair[1].1 >= pair[0].1, "{pair:?}");
    }
    let titles: Vec<String> = {
        let mut texts = Vec::new();
        for t in chart
            .find_all(Locator::Css("text.axis-title"))
            .await
            .expect("titles")
        {
            texts.push(t.text().await.expect("title text"));
        }
        texts
    };
    assert!(titles.iter().any(|t| t == "Disparity d (px)"), "{titles:?}");
    assert!(titles.iter().any(|t| t.contains("(mm)")), "{titles:?}");
    let marker = browser.find("chart-marker").await;
    let cx: f64 = marker
        .attr("cx")
        .await
        .expect("cx")
        .expect("cx")
        .parse()
        .expect("number");
    let cy: f64 = marker
        .attr("cy")
        .await
        .expect("cy")
        .expect("cy")
        .parse()
        .expect("number");
    let after = distance
        .iter()
        .position(|v| v.0 >= cx)
        .expect("the marker is inside the curve");
    let (a, b) = (distance[after - 1], distance[after]);
    let on_curve = a.1 + (b.1 - a.1) * (cx - a.0) / (b.0 - a.0);
    assert!(
        (cy - on_curve).abs() < 2.0,
        "marker at {cy}, curve at {on_curve}"
    );
    assert!(
        browser
            .text("chart-caption")
            .await
            .contains("d = 50 px, Z = 105 mm")
    );

    // The linear view draws the error on its own right-hand axis.
    browser.find("log").await.click().await.expect("toggle");
    browser
        .until("the linear chart", || async {
            let titles = browser
                .script("return [...document.querySelectorAll('#chart text.axis-title')].map(t => t.textContent)")
                .await;
            titles
                .as_array()
                .is_some_and(|t| t.iter().any(|t| t == "Depth error ΔZ (mm)"))
                .then_some(())
        })
        .await;
    assert_eq!(curve("distance").await.len(), 120);
    browser.close().await;
}

/// The table comes from /table (10 rows by default, 5 when asked), its CSV link downloads the
/// same table as CSV, and "Copy results" puts a plain-text summary on the clipboard.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn the_table_downloads_as_csv_and_results_copy_as_text() {
    // Arrange
    let browser = Browser::at_defaults().await;

    // Act / Assert: the table.
    let cells = browser
        .script("return [...document.querySelectorAll('#table-body tr')].map(r => [...r.cells].map(c => c.textContent))")
        .await;
    let cells = cells.as_array().expect("rows");
    assert_eq!(cells.len(), 10);
    // The first row is d = 1 px: Z = 150 × 35 / 1 and ΔZ = Z² × 0.5 / (35 × 150).
    assert_eq!(
        cells[0],
        json!(["5250", "1", "-0.0025", "0.233333", "2625"])
    );
    browser.choose("rows", "5").await;
    browser
        .until("5 rows", || async {
            let n = browser
                .script("return document.querySelectorAll('#table-body tr').length")
                .await;
            (n == json!(5)).then_some(())
        })
        .await;
    browser.settled().await;
    let href = browser.attr("csv", "href").await.expect("a link");
    assert!(href.starts_with("/table.csv?"), "{href}");
    let csv = reqwest::get(format!("{}{href}", browser.base))
        .await
        .expect("the CSV link answers");
    assert_eq!(csv.status(), 200);
    assert!(
        csv.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/csv"),
        "{:?}",
        csv.headers()
    );
    let body = csv.text().await.expect("csv text");
    let lines: Vec<&str> = body.lines().collect();
    assert_eq!(
        lines[0],
        "distance_mm,disparity_px,normalized_x,projection_factor_px_per_mm,depth_error_mm,\
         relative_error"
    );
    assert_eq!(lines.len(), 6, "a header and 5 rows: {body}");

    // Act / Assert: Copy results.
    let copied = browser.copy_results().await;
    let copied = copied.as_str();
    assert!(
        copied.starts_with("Stereo distance: 105 mm ± 1.05 mm"),
        "{copied}"
    );
    assert!(copied.contains("Disparity d: 50 px"), "{copied}");
    assert!(copied.contains("Permalink: http://"), "{copied}");
    browser.close().await;
}

/// "Reset defaults" restores every field, the focal mode and the unit after they were all
/// changed, and the distance is the seed's 105 mm again.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn reset_defaults_restores_the_form() {
    // Arrange: everything changed from the defaults, including an error.
    let browser = Browser::at_defaults().await;
    browser
        .find("optional")
        .await
        .click()
        .await
        .expect("open the optional fields");
    browser.choose("focal_mode", "fov").await;
    browser.choose("unit", "m").await;
    for (id, value) in [
        ("focal", "90"),
        ("baseline", "0.12"),
        ("x_left", "700"),
        ("x_right", "650"),
        ("image_width", "1280"),
        ("image_height", "720"),
        ("disparity_error_px", "0.1"),
        ("doffs", "abc"),
    ] {
        browser.type_into(id, value).await;
    }
    browser
        .until("the doffs error", || async {
            (!browser.text("doffs-error").await.is_empty()).then_some(())
        })
        .await;

    // Act
    browser.find("reset").await.click().await.expect("reset");

    // Assert
    browser.until_text("distance", "105 mm").await;
    browser.settled().await;
    for (id, value) in DEFAULT_FIELDS {
        assert_eq!(browser.value(id).await, value, "#{id}");
    }
    assert_eq!(browser.value("focal_mode").await, "px");
    assert_eq!(browser.value("unit").await, "mm");
    assert_eq!(browser.text("focal-label").await, "Focal length f (px)");
    assert_eq!(
        browser.attr("doffs-error", "hidden").await.as_deref(),
        Some("true")
    );
    assert_eq!(browser.attr("doffs", "aria-invalid").await, None);
    assert_eq!(
        browser.text("status").await,
        "Defaults restored. Distance 105 mm ± 1.05 mm."
    );
    browser.close().await;
}

/// A permalink reproduces the page: the state of a changed form, opened afresh from its
/// address, comes back field for field with the same distance.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn a_permalink_reproduces_the_page() {
    // Arrange
    let browser = Browser::at_defaults().await;
    browser.choose("focal_mode", "mm-pitch").await;
    browser.type_into("pixel_size_um", "3.45").await;
    browser.choose("unit", "m").await;
    browser.type_into("baseline", "0.15").await;
    browser.type_into("x_right", "360").await;
    browser.settled().await;
    let distance = browser.text("distance").await;
    assert!(distance.ends_with(" m"), "{distance}");
    let link = browser.attr("permalink", "href").await.expect("href");

    // Act: a fresh page from the address alone.
    browser
        .client
        .goto(&format!("{}/healthz", browser.base))
        .await
        .expect("away from the page");
    browser.open(&link).await;

    // Assert
    browser.until_text("distance", &distance).await;
    assert_eq!(browser.value("focal_mode").await, "mm-pitch");
    assert_eq!(browser.value("pixel_size_um").await, "3.45");
    assert_eq!(browser.value("unit").await, "m");
    assert_eq!(browser.value("baseline").await, "0.15");
    assert_eq!(browser.value("x_right").await, "360");
    browser.close().await;
}

/// A permalink naming a unit the API refuses (`unit=meters`) shows the API's error next to
/// the unit field and computes nothing, never millimetres nobody chose; the same holds for the
/// page's own choices (`focal_mode`, `rows`, `scale`). Choosing real values computes again.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn unknown_choices_in_a_permalink_are_refused_next_to_their_control() {
    // Arrange
    let browser = Browser::start(1280, 1400).await;
    let kitti = "focal_length_px=721.5377&baseline=0.54&x_left=620&x_right=610\
                 &image_width=1242&image_height=375";

    // Act: the unit the issue found turned into millimetres.
    browser
        .open(&format!("/?focal_mode=px&{kitti}&unit=meters"))
        .await;

    // Assert
    browser
        .until_text(
            "unit-error",
            "must be one of mm, cm, m, in, ft, got `meters`",
        )
        .await;
    assert_eq!(
        browser.attr("unit", "aria-invalid").await.as_deref(),
        Some("true")
    );
    assert_eq!(
        browser.value("unit").await,
        "meters",
        "the control shows what was asked"
    );
    assert_eq!(browser.text("distance").await, "–");
    assert!(!browser.text("status").await.contains("mm"));
    browser.assert_no_alert().await;

    // Act: choosing a unit computes in it, and the unknown option is gone.
    browser.choose("unit", "m").await;
    browser.settled().await;

    // Assert: 721.5377 × 0.54 / 10 px.
    browser.until_text("distance", "38.963 m").await;
    assert!(
        browser
            .find("unit-error")
            .await
            .attr("hidden")
            .await
            .expect("attr")
            .is_some()
    );
    let options = browser
        .script("return document.querySelectorAll('#unit option[data-unknown]').length")
        .await;
    assert_eq!(options, serde_json::json!(0));

    // Act: the page's own choices, all wrong at once.
    browser
        .open(&format!(
            "/?focal_mode=pixels&{kitti}&unit=m&rows=7&scale=cubic"
        ))
        .await;

    // Assert
    browser
        .until_text(
            "focal_mode-error",
            "must be one of px, mm-sensor, mm-pitch, fov, got `pixels`",
        )
        .await;
    assert_eq!(
        browser.text("rows-error").await,
        "must be one of 5, 10, 20, 50, got `7`"
    );
    assert_eq!(
        browser.text("log-error").await,
        "must be linear or log, got `cubic`"
    );
    assert_eq!(browser.text("distance").await, "–");
    assert_eq!(
        browser.value("focal").await,
        "721.5377",
        "the focal value is kept"
    );

    // Act: choose each.
    browser.choose("focal_mode", "px").await;
    browser.choose("rows", "5").await;
    browser.find("log").await.click().await.expect("tick");
    browser.settled().await;

    // Assert
    browser.until_text("distance", "38.963 m").await;
    let rows = browser
        .script("return document.querySelectorAll('#table-body tr').length")
        .await;
    assert_eq!(rows, serde_json::json!(5));
    browser.close().await;
}

/// On a phone-width screen nothing scrolls sideways, every control has a label a screen
/// reader reads, and the results are still computed.
#[tokio::test]
#[ignore = "needs chromium and chromedriver; .ci/run runs it"]
async fn the_page_fits_a_phone_and_every_control_is_labelled() {
    // Arrange / Act
    let browser = Browser::phone(390, 844).await;
    browser.open("/").await;

    // Assert
    browser.until_text("distance", "105 mm").await;
    assert_eq!(browser.script("return window.innerWidth").await, json!(390));
    // The distance stays in sight at the bottom of the screen while the form is filled in.
    assert_eq!(browser.text("mini-result").await, "Z = 105 mm ± 1.05 mm");
    let in_view = browser
        .script(
            "const r = document.getElementById('mini-result').getBoundingClientRect();\
             return r.top >= 0 && r.bottom <= window.innerHeight + 1;",
        )
        .await;
    assert_eq!(in_view, json!(true), "the sticky distance is on screen");
    browser.assert_no_sideways_scroll().await;
    let unlabelled = browser
        .script(
            "return [...document.querySelectorAll('input, select, button')]\
               .filter(c => c.labels.length === 0 && !c.getAttribute('aria-label') && !c.textContent.trim())\
               .map(c => c.id)",
        )
        .await;
    assert_eq!(unlabelled, json!([]), "controls without a label");
    let chart_label = browser
        .script("return document.getElementById('chart-desc').textContent")
        .await;
    assert!(
        chart_label
            .as_str()
            .is_some_and(|t| t.contains("the measured point is at d = 50 px, Z = 105 mm")),
        "{chart_label}"
    );
    browser.screenshot("calculator-phone.png").await;
    browser.close().await;
}
