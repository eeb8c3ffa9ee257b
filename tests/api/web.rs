//! The calculator page at `/` as HTTP sees it: embedded assets with their headers, every link
//! on the page answered by this server, caching by ETag, and the page's worked examples
//! agreeing with the API. The page's behaviour in a browser is tested in `tests/browser.rs`.

use std::collections::{BTreeMap, BTreeSet};

use reqwest::{
    StatusCode,
    header::{CACHE_CONTROL, CONTENT_TYPE, ETAG, IF_NONE_MATCH},
};

use serde_json::{Value, json};

use crate::helpers::{TestApp, assert_close, number_at, ok_json, problem, spawn_app};

/// Every `href="…"` and `src="…"` value in `html`, with `&amp;` decoded.
fn references(html: &str) -> Vec<String> {
    let mut found = Vec::new();
    for attribute in ["href=\"", "src=\""] {
        let mut rest = html;
        while let Some(start) = rest.find(attribute) {
            rest = &rest[start + attribute.len()..];
            let end = rest.find('"').expect("a closing quote");
            found.push(rest[..end].replace("&amp;", "&"));
            rest = &rest[end..];
        }
    }
    found
}

/// `GET /` is the calculator, with a policy that lets it load and call only this origin, and
/// its script, style sheet and icon are served with their types.
#[tokio::test]
async fn the_page_and_its_assets_are_served_from_the_binary() {
    // Arrange
    let app = spawn_app().await;

    // Act
    let page = app.get("/").await;

    // Assert
    assert_eq!(page.status(), StatusCode::OK);
    assert_eq!(page.headers()[CONTENT_TYPE], "text/html; charset=utf-8");
    let policy = page.headers()["content-security-policy"]
        .to_str()
        .unwrap()
        .to_owned();
    for directive in [
        "default-src 'none'",
        "script-src 'self'",
        "connect-src 'self'",
    ] {
        assert!(policy.contains(directive), "{policy}");
    }
    assert_eq!(page.headers()["x-content-type-options"], "nosniff");
    let html = page.text().await.unwrap();
    assert!(html.contains("<title>Stereo vision distance calculator</title>"));
    for (path, content_type) in [
        ("/js/app.js", "text/javascript; charset=utf-8"),
        ("/app.css", "text/css; charset=utf-8"),
        ("/favicon.svg", "image/svg+xml"),
    ] {
        assert!(
            references(&html).iter().any(|r| r == path),
            "the page loads {path}"
        );
        let asset = app.get(path).await;
        assert_eq!(asset.status(), StatusCode::OK, "{path}");
        assert_eq!(asset.headers()[CONTENT_TYPE], content_type, "{path}");
        assert_eq!(
            asset.headers()["x-content-type-options"],
            "nosniff",
            "{path}"
        );
        assert!(!asset.text().await.unwrap().is_empty(), "{path}");
    }
}

/// Every link and source on the page and its guide is local and answered 200 by this server:
/// the assets, the API documentation, the SVG chart and the worked examples' permalinks. Nothing comes
/// from a CDN.
#[tokio::test]
async fn every_link_on_the_page_is_local_and_answers() {
    // Arrange
    let app = spawn_app().await;
    let mut references = references(&app.get("/").await.text().await.unwrap());
    assert!(references.len() >= 10, "{references:?}");
    assert!(references.iter().any(|r| r == "/guide.html"));
    references.extend(self::references(
        &app.get("/guide.html").await.text().await.unwrap(),
    ));

    for reference in references {
        if reference.starts_with('#') {
            continue;
        }
        // Assert: local, and answered.
        assert!(
            reference.starts_with('/') && !reference.starts_with("//"),
            "{reference}"
        );
        let response = app.get(&reference).await;
        assert_eq!(response.status(), StatusCode::OK, "{reference}");
    }
}

/// The page's script, every ES module reachable from its entry `/js/app.js` by `import … from
/// './x.js'`, each answered 200 as JavaScript: the module graph the browser loads.
async fn page_script(app: &TestApp) -> BTreeMap<String, String> {
    let mut modules = BTreeMap::new();
    let mut pending = vec!["/js/app.js".to_owned()];
    while let Some(path) = pending.pop() {
        if modules.contains_key(&path) {
            continue;
        }
        let response = app.get(&path).await;
        assert_eq!(response.status(), StatusCode::OK, "{path}");
        assert_eq!(
            response.headers()[CONTENT_TYPE],
            "text/javascript; charset=utf-8",
            "{path}"
        );
        let text = response.text().await.unwrap();
        for (at, needle) in text.match_indices("from './") {
            let rest = &text[at + needle.len()..];
            pending.push(format!(
                "/js/{}",
                &rest[..rest.find('\'').expect("a closing quote")]
            ));
        }
        modules.insert(path, text);
    }
    modules
}

/// The script calls only the public API's documented routes: the page is a client of
/// `/distance`, `/table` and `/chart-data` (GET), `/depth-map`, `/match`, `/rectify`,
/// `/calibration`, `/calibrate`, `/board` and `/distance` (POST) and the `/depth-stream`
/// WebSocket (in the AsyncAPI document), with no physics or private endpoint of its own;
/// besides them it fetches only the samples' files. Every module is under 600 lines.
#[tokio::test]
async fn the_page_calls_only_the_public_api() {
    // Arrange
    let app = spawn_app().await;
    let modules = page_script(&app).await;
    let spec = ok_json(app.get("/openapi.json").await).await;

    // Act: every path the script calls, by how it calls it.
    let paths = |needle: &str| -> BTreeSet<String> {
        modules
            .values()
            .flat_map(|script| {
                script.match_indices(needle).map(|(at, needle)| {
                    let rest = &script[at + needle.len()..];
                    rest[..rest.find(['\'', '`']).expect("a closing quote")].to_owned()
                })
            })
            .collect()
    };
    let set = |paths: &[&str]| {
        paths
            .iter()
            .map(|p| (*p).to_owned())
            .collect::<BTreeSet<_>>()
    };
    let got = paths("call('");
    let posted: BTreeSet<String> = ["post('", "postJson('", "postWithProgress('"]
        .iter()
        .flat_map(|needle| paths(needle))
        .collect();
    // `call`, `post`, `postJson` and `postWithProgress` send to the path they are given,
    // `fetchPair` and `fetchJson` fetch a sample's files.
    let fetched: BTreeSet<String> = paths("fetch('").union(&paths("fetch(`")).cloned().collect();
    // The API's calls go through `fetchWithToken` (the access token, when the service asks).
    let authorised = paths("fetchWithToken(`");
    let files = paths("fetchPair((side) => [`");
    let described = paths("fetchJson('");

    // Assert
    assert!(modules.len() >= 6, "{:?}", modules.keys());
    for (path, script) in &modules {
        assert!(
            script.lines().count() <= 600,
            "{path} has {} lines",
            script.lines().count()
        );
    }
    assert_eq!(got, set(&["/chart-data", "/distance", "/table"]));
    assert_eq!(
        posted,
        set(&[
            "/board",
            "/calibrate",
            "/calibration",
            "/calibration/check",
            "/depth-map",
            "/distance",
            "/match",
            "/rectify"
        ])
    );
    assert_eq!(paths("openSocket('"), set(&["/depth-stream"]));
    let asyncapi = app.get("/asyncapi.yaml").await.text().await.unwrap();
    assert!(asyncapi.contains("address: /depth-stream"));
    assert_eq!(fetched, set(&["/sample/calib.txt"]));
    assert_eq!(authorised, set(&["${path}?${params}", "${path}?${query}"]));
    assert_eq!(files, set(&["/sample/${side}.png"]));
    // The calibration sample's files are the ones its description names, all its own.
    assert_eq!(described, set(&["/sample/boards/boards.json"]));
    let about = ok_json(app.get("/sample/boards/boards.json").await).await;
    for side in ["left", "right"] {
        let named = about[side]
            .as_array()
            .unwrap()
            .iter()
            .chain([&about["raw"][side]]);
        for path in named {
            assert!(
                path.as_str().unwrap().starts_with("/sample/boards/"),
                "{path}"
            );
        }
    }
    for path in &got {
        assert!(
            spec["paths"][path.as_str()]["get"].is_object(),
            "GET {path} is in the spec"
        );
    }
    for path in &posted {
        assert!(
            spec["paths"][path.as_str()]["post"].is_object(),
            "POST {path} is in the spec"
        );
    }
    for script in modules.values() {
        assert!(!script.contains("fetch('http") && !script.contains("fetch(\"http"));
    }
}

/// Assets carry a weak ETag and `no-cache`: a browser revalidating with the tag gets a 304
/// with no body, also for the gzip-encoded copy, and one holding another version gets the
/// asset.
#[tokio::test]
async fn assets_are_revalidated_by_etag() {
    // Arrange
    let app = spawn_app().await;
    let first = app.get("/js/app.js").await;
    assert_eq!(first.headers()[CACHE_CONTROL], "no-cache");
    let tag = first.headers()[ETAG].to_str().unwrap().to_owned();
    assert!(tag.starts_with("W/\"") && tag.ends_with('"'), "{tag}");

    let revalidate = |tag: String, encoding: &'static str| {
        app.client
            .get(format!("{}/js/app.js", app.address))
            .header(IF_NONE_MATCH, tag)
            .header("accept-encoding", encoding)
            .send()
    };

    // Act
    let same = revalidate(tag.clone(), "identity").await.unwrap();
    let gzip = revalidate(tag.clone(), "gzip").await.unwrap();
    let other = revalidate("\"0000000000000000\"".to_owned(), "identity")
        .await
        .unwrap();

    // Assert
    assert_eq!(same.status(), StatusCode::NOT_MODIFIED);
    assert_eq!(same.headers()[ETAG], tag.as_str());
    assert!(same.bytes().await.unwrap().is_empty());
    assert_eq!(gzip.status(), StatusCode::NOT_MODIFIED);
    assert_eq!(other.status(), StatusCode::OK);
    assert!(!other.text().await.unwrap().is_empty());
}

/// HEAD answers the page's headers with no body; any other method is a 405 problem naming it.
#[tokio::test]
async fn the_page_takes_get_and_head_only() {
    // Arrange
    let app = spawn_app().await;
    let url = format!("{}/", app.address);

    // Act
    let head = app.client.head(&url).send().await.unwrap();
    let post = app.client.post(&url).body("x").send().await.unwrap();

    // Assert
    assert_eq!(head.status(), StatusCode::OK);
    assert_eq!(head.headers()[CONTENT_TYPE], "text/html; charset=utf-8");
    assert!(head.bytes().await.unwrap().is_empty());
    let problem = problem(post, 405).await;
    assert_eq!(problem["errors"][0]["field"], "method");
}

/// The guide's (`/guide.html`, linked from the page) worked examples say what the API answers for their permalinks: 105 mm for
/// f = 35 px; about 30.4 m when the 35 is millimetres on 3.45 µm pixels; 40 mm, with the
/// negative-disparity warning, for the inspection example.
#[tokio::test]
async fn the_worked_examples_agree_with_the_api() {
    // Arrange
    let app = spawn_app().await;
    let html = app.get("/guide.html").await.text().await.unwrap();
    let examples: Vec<String> = references(&html)
        .into_iter()
        .filter(|r| r.starts_with("/?focal_mode="))
        .collect();
    assert_eq!(examples.len(), 3, "{examples:?}");

    // Act: each permalink's members, less the page's own `focal_mode`, sent to /distance.
    let mut answers = Vec::new();
    for example in &examples {
        let query: Vec<&str> = example[2..]
            .split('&')
            .filter(|pair| !pair.starts_with("focal_mode="))
            .collect();
        answers.push(ok_json(app.get(&format!("/distance?{}", query.join("&"))).await).await);
    }

    // Assert
    assert_close(number_at(&answers[0], "distance"), 105.0, "example 1");
    assert!(html.contains("Z = 150 mm × 35 px / 50 px = 105 mm"));
    assert_close(
        number_at(&answers[1], "distance"),
        30_434.782_608_695_65,
        "35 mm at 3.45 µm",
    );
    assert!(html.contains("about 30.4 m away"));
    assert_close(
        number_at(&answers[1], "focal_length_px"),
        10_144.927_536_231_884,
        "f in px",
    );
    assert!(html.contains("≈ 10 145 px"));
    assert_close(number_at(&answers[2], "distance"), 40.0, "example 2");
    assert_eq!(answers[2]["warnings"][0]["code"], "negative_disparity");
}

/// The sample pair is the project's own render of its layered scene (320 × 240, served as PNG
/// from the binary, no image file in it), with the rig and range the page loads; the service
/// matches it to the scene's known disparities.
#[tokio::test]
async fn the_sample_pair_is_rendered_by_the_project() {
    // Arrange
    let app = spawn_app().await;
    let (w, h) = stereo_distance::web::SAMPLE_SIZE;
    let scene =
        stereo_core::vision::synthetic::render(&stereo_core::vision::synthetic::layered(w, h));

    // Act
    let left = app.get("/sample/left.png").await;
    let right = app.get("/sample/right.png").await;
    let rig = ok_json(app.get("/sample/sample.json").await).await;
    let calib = app.get("/sample/calib.txt").await.text().await.unwrap();

    // Assert: the images are the render, pixel for pixel.
    for (response, rgb) in [(left, &scene.left_rgb), (right, &scene.right_rgb)] {
        assert_eq!(response.status(), StatusCode::OK);
        assert_eq!(response.headers()[CONTENT_TYPE], "image/png");
        assert!(response.headers().contains_key(ETAG));
        let image = image::load_from_memory(&response.bytes().await.unwrap())
            .unwrap()
            .into_rgb8();
        assert_eq!(image.dimensions(), (w as u32, h as u32));
        assert_eq!(image.as_raw(), rgb);
    }
    assert_eq!(rig["focal_length_px"], 400.0);
    assert_eq!(rig["baseline"], 120.0);
    assert_eq!(rig["unit"], "mm");
    assert_eq!(rig["image_width"], w);
    // The calibration file is the same rig, with the search range as its ndisp.
    let read = ok_json(app.post("/calibration", &json!({"text": calib})).await).await;
    assert_eq!(read["format"], "middlebury");
    assert_eq!(read["rig"]["focal_length_px"], 400.0);
    assert_eq!(read["rig"]["baseline"], 120.0);
    assert_eq!(read["max_disparity_px"], 48);
    let largest = scene.truth.iter().copied().fold(0.0f32, f32::max);
    assert!(largest < 48.0, "the range covers the scene: {largest}");
}

/// The sample's files go straight into the image routes: `sample.json` as the `rig` part and
/// `calib.txt` as the `calibration` part, whose `ndisp` (48) becomes the search range.
#[tokio::test]
async fn the_sample_files_are_parts_as_they_are() {
    let app = spawn_app().await;
    let mut parts = Vec::new();
    for path in [
        "/sample/left.png",
        "/sample/right.png",
        "/sample/sample.json",
        "/sample/calib.txt",
    ] {
        parts.push(app.get(path).await.bytes().await.unwrap().to_vec());
    }
    let form = |name: &str, index: usize| {
        reqwest::multipart::Form::new()
            .part("left", reqwest::multipart::Part::bytes(parts[0].clone()))
            .part("right", reqwest::multipart::Part::bytes(parts[1].clone()))
            .part(
                name.to_owned(),
                reqwest::multipart::Part::bytes(parts[index].clone()),
            )
    };
    let with_rig = ok_json(
        app.post_form("/depth-map?max_disparity=48", form("rig", 2))
            .await,
    )
    .await;
    let with_file = ok_json(app.post_form("/depth-map", form("calibration", 3)).await).await;
    assert_eq!(with_file["max_disparity"], 48);
    assert_eq!(with_rig["rig"], with_file["rig"]);
    assert_eq!(with_rig["distance"], with_file["distance"]);
    assert!(
        with_file["valid_fraction"].as_f64().unwrap() > 0.8,
        "{with_file}"
    );
}

/// The calibration sample is the project's own render: its board pairs, sent to `/calibrate`
/// as the page sends them, calibrate to the rig they were rendered with (f and B within
/// 0.5 %); its last view is refused with the reason (the right camera sees the board only in
/// part); `corners=true` gives each used view's residuals, small and one per corner; and the
/// raw wall, sent to `/match` with the calibration's `opencv.yml`, is rectified by the service
/// and measured at the depth it was rendered at, within 1 %.
#[tokio::test]
async fn the_calibration_sample_calibrates_and_measures_its_wall() {
    use reqwest::multipart::{Form, Part};

    // Arrange: the sample's files, fetched as the page fetches them.
    let app = spawn_app().await;
    let about = ok_json(app.get("/sample/boards/boards.json").await).await;
    let mut files = BTreeMap::new();
    let paths = about["left"]
        .as_array()
        .unwrap()
        .iter()
        .chain(about["right"].as_array().unwrap());
    for path in paths.chain([&about["raw"]["left"], &about["raw"]["right"]]) {
        let path = path.as_str().unwrap().to_owned();
        let response = app.get(&path).await;
        assert_eq!(response.status(), StatusCode::OK, "{path}");
        assert_eq!(response.headers()[CONTENT_TYPE], "image/png", "{path}");
        files.insert(path, response.bytes().await.unwrap().to_vec());
    }
    let part = |path: &Value| {
        let path = path.as_str().unwrap();
        let name = path.rsplit('/').next().unwrap().to_owned();
        Part::bytes(files[path].clone())
            .file_name(name)
            .mime_str("image/png")
            .unwrap()
    };
    let views = about["left"].as_array().unwrap().len();
    let boards = || {
        (0..views)
            .fold(Form::new(), |form, i| {
                form.part("left", part(&about["left"][i]))
                    .part("right", part(&about["right"][i]))
            })
            .text("board", about["board"].to_string())
    };

    // Act
    let summary = ok_json(app.post_form("/calibrate?corners=true", boards()).await).await;
    let yaml = app
        .post_form("/calibrate?output=opencv.yml", boards())
        .await;
    assert_eq!(yaml.status(), StatusCode::OK);
    let yaml = yaml.text().await.unwrap();

    // Assert: the rig it was rendered with.
    let truth = stereo_distance::web::board_sample_rig();
    let f = summary["rig"]["focal_length_px"].as_f64().unwrap();
    let b = summary["rig"]["baseline"].as_f64().unwrap();
    assert!(
        (f / truth.focal_px() - 1.0).abs() < 0.005,
        "f {f} against {}",
        truth.focal_px()
    );
    assert!(
        (b / truth.baseline() - 1.0).abs() < 0.005,
        "B {b} against {}",
        truth.baseline()
    );
    assert!(summary["rms"].as_f64().unwrap() < 0.2, "{}", summary["rms"]);
    let last = &summary["views"][views - 1];
    assert_eq!(last["status"], "board_not_found", "{last}");
    assert_eq!(last["failed"], json!(["right"]), "{last}");
    let all = summary["views"].as_array().unwrap();
    let used: Vec<&Value> = all.iter().filter(|v| v["status"] == "used").collect();
    assert_eq!(used.len(), views - 1);
    for view in &used {
        for side in ["left", "right"] {
            let residuals = view[format!("residuals_{side}")].as_array().unwrap();
            assert_eq!(residuals.len(), 54, "{side}");
            let worst = residuals
                .iter()
                .map(|r| r[0].as_f64().unwrap().hypot(r[1].as_f64().unwrap()))
                .fold(0.0, f64::max);
            assert!(worst < 1.0, "{side} residual {worst} px");
        }
    }

    // Act: the raw wall with the calibration's own file.
    let points = json!([{"x": 320, "y": 240}, {"x": 150, "y": 120}, {"x": 500, "y": 380}]);
    let form = Form::new()
        .part("left", part(&about["raw"]["left"]))
        .part("right", part(&about["raw"]["right"]))
        .part("calibration", Part::text(yaml).file_name("stereo.yml"))
        .text("points", points.to_string());
    let max = about["raw"]["max_disparity"].as_u64().unwrap();
    let answer = ok_json(
        app.post_form(&format!("/match?max_disparity={max}"), form)
            .await,
    )
    .await;

    // Assert: rectified by the service, and at the wall's depth there (Z = distance + slope·X
    // in the rectified left camera's frame).
    let distance = about["raw"]["distance"].as_f64().unwrap();
    let slope = about["raw"]["slope"].as_f64().unwrap();
    let cx = truth.cx().unwrap();
    for m in answer["matches"].as_array().unwrap() {
        assert_eq!(m["status"], "ok", "{m}");
        let x = m["x_rectified"].as_f64().unwrap();
        let expected = distance / (1.0 - slope * (x - cx) / truth.focal_px());
        let z = m["distance"].as_f64().unwrap();
        assert!(
            (z / expected - 1.0).abs() < 0.01,
            "{z} against {expected}: {m}"
        );
        assert!(m["x_right_raw"].is_number(), "{m}");
    }
}
