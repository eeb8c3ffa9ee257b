//! `POST /depth-map` over a real socket, on the project's own synthetic pair (known ground
//! truth): the summary's numbers, every output read back as its users' tools read it, the
//! calibration part, content negotiation, and every kind of bad input named.

use reqwest::multipart::{Form, Part};
use reqwest::{Response, header::ACCEPT};
use serde_json::{Value, json};
use stereo_core::vision::{
    encode, sigma,
    synthetic::{self, Pair},
};
use stereo_distance::{Config, config::HeavyLimits};

use crate::helpers::{
    TestApp, assert_close, assert_names, fields, message_for, number_at, ok_json, problem,
    spawn_app, spawn_app_with,
};

pub(crate) const W: usize = 160;
pub(crate) const H: usize = 120;

/// The synthetic scene (planes at 6–38 px of disparity, occluding one another), rendered.
pub(crate) fn pair() -> Pair {
    synthetic::render(&synthetic::layered(W, H))
}

pub(crate) fn png(rgb: &[u8], w: usize, h: usize) -> Vec<u8> {
    encode::png_rgb(w, h, rgb)
}

/// The rig of the synthetic pair: f = 500 px, B = 100 mm, principal point at the centre.
pub(crate) fn rig() -> Value {
    json!({"focal_length_px": 500, "baseline": 100, "unit": "mm"})
}

/// A form with the pair, and `extra` parts as text.
fn form(pair: &Pair, extra: &[(&str, String)]) -> Form {
    let mut form = Form::new()
        .part("left", image_part(png(&pair.left_rgb, W, H)))
        .part("right", image_part(png(&pair.right_rgb, W, H)));
    for (name, text) in extra {
        form = form.text(name.to_string(), text.clone());
    }
    form
}

pub(crate) fn image_part(bytes: Vec<u8>) -> Part {
    Part::bytes(bytes)
        .file_name("image.png")
        .mime_str("image/png")
        .unwrap()
}

async fn depth_map(app: &TestApp, query: &str, form: Form) -> Response {
    app.client
        .post(format!("{}/depth-map{query}", app.address))
        .multipart(form)
        .send()
        .await
        .expect("request is sent")
}

pub(crate) fn floats(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

/// The NPZ `/depth-map` answers for the test pair searched below 48 px with the options in
/// `query` (each starting `&`), after checking it is a 200: its entries ([`npz_entries`]).
async fn arrays_of(app: &TestApp, pair: &Pair, query: &str) -> Vec<(String, Vec<u8>)> {
    let response = depth_map(
        app,
        &format!("?max_disparity=48&output=arrays.npz{query}"),
        form(pair, &[]),
    )
    .await;
    assert_eq!(response.status(), 200, "{query}");
    npz_entries(&response.bytes().await.unwrap())
}

/// The entries of a stored (uncompressed) zip, as `numpy.savez` writes NPZ files: each local
/// header's name and bytes, in order, until the central directory.
pub(crate) fn npz_entries(zip: &[u8]) -> Vec<(String, Vec<u8>)> {
    let u16_at = |i: usize| usize::from(u16::from_le_bytes([zip[i], zip[i + 1]]));
    let u32_at = |i: usize| u32::from_le_bytes(zip[i..i + 4].try_into().unwrap()) as usize;
    let mut entries = Vec::new();
    let mut at = 0;
    while u32_at(at) == 0x0403_4b50 {
        assert_eq!(u16_at(at + 8), 0, "stored, not deflated");
        let (size, name_len, extra) = (u32_at(at + 18), u16_at(at + 26), u16_at(at + 28));
        let name = String::from_utf8(zip[at + 30..at + 30 + name_len].to_vec()).unwrap();
        let data = at + 30 + name_len + extra;
        entries.push((name, zip[data..data + size].to_vec()));
        at = data + size;
    }
    assert_eq!(u32_at(at), 0x0201_4b50, "the central directory follows");
    entries
}

/// The float32 data of an NPY file, after checking its header says `(H, W)` little-endian
/// float32 in C order.
pub(crate) fn npy(bytes: &[u8]) -> Vec<f32> {
    npy_of(bytes, (H, W))
}

/// The float32 data of an NPY file, after checking its header says `(height, width)`
/// little-endian float32 in C order.
pub(crate) fn npy_of(bytes: &[u8], (height, width): (usize, usize)) -> Vec<f32> {
    assert_eq!(&bytes[..8], b"\x93NUMPY\x01\x00");
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(&bytes[10..10 + len]).unwrap();
    assert!(header.contains("'descr': '<f4'") && header.contains("'fortran_order': False"));
    assert!(
        header.contains(&format!("'shape': ({height}, {width})")),
        "{header}"
    );
    floats(&bytes[10 + len..])
}

/// The summary states the size, the range, the rig, and disparities and depths that agree
/// with the truth and with Z = B·f / d; `Server-Timing` names the five stages.
#[tokio::test]
async fn the_summary_agrees_with_the_truth() {
    // Arrange
    let app = spawn_app().await;
    let pair = pair();
    // Act
    let response = depth_map(
        &app,
        "?max_disparity=48",
        form(&pair, &[("rig", rig().to_string())]),
    )
    .await;
    // Assert
    let timing = response.headers()["server-timing"]
        .to_str()
        .unwrap()
        .to_owned();
    for stage in ["decode", "cost", "aggregate", "refine", "encode"] {
        assert!(timing.contains(&format!("{stage};dur=")), "{timing}");
    }
    let body = ok_json(response).await;
    assert_eq!(
        (body["width"].as_u64(), body["height"].as_u64()),
        (Some(160), Some(120))
    );
    assert_eq!(
        (
            body["min_disparity"].as_i64(),
            body["max_disparity"].as_i64()
        ),
        (Some(0), Some(48))
    );
    // The 28 px band on the left that the right camera cannot see, and the occlusions.
    assert!(body["valid_fraction"].as_f64().unwrap() > 0.8, "{body}");
    let mut truth = pair.seen_truth();
    truth.sort_by(f32::total_cmp);
    let median = f64::from(truth[truth.len() / 2]);
    let got = body["disparity_px"]["median"].as_f64().unwrap();
    assert!((got - median).abs() < 0.5, "median {got}, truth {median}");
    let (dmin, dmax) = (
        body["disparity_px"]["min"].as_f64().unwrap(),
        body["disparity_px"]["max"].as_f64().unwrap(),
    );
    // Z = B·f / d for the extremes: the nearest depth is the largest disparity's.
    let zmin = body["distance"]["min"].as_f64().unwrap();
    let zmax = body["distance"]["max"].as_f64().unwrap();
    assert!((zmin - 50_000.0 / dmax).abs() < 0.01 * zmin, "{body}");
    assert!((zmax - 50_000.0 / dmin).abs() < 0.01 * zmax, "{body}");
    assert_eq!(body["rig"]["cx"], 80.0);
    assert_eq!(body["rig"]["image_width"], 160);
    assert_eq!(body["parameters"]["p1"], 16);
}

/// Each output is what its tools read: PFM bottom-up with +inf holes, NPY (the same values),
/// KITTI's round(d·256), depth NPY and millimetre PNG (Z = B·f / d), σ_d as NPY and PFM (valid
/// exactly where the disparity is, at least the model's floor), σ_Z = Z²·σ_d / (f·B), the NPZ
/// of all of them, a preview the size of the images, and a PLY with one vertex per valid
/// depth, carrying its σ_Z.
#[tokio::test]
async fn every_output_reads_back() {
    let app = spawn_app().await;
    let pair = pair();
    let mut files = std::collections::HashMap::new();
    for output in [
        "disparity.pfm",
        "disparity.npy",
        "disparity.png",
        "depth.npy",
        "disparity_std.npy",
        "disparity_std.pfm",
        "depth_std.npy",
        "arrays.npz",
        "depth.png",
        "preview.png",
        "points.ply",
    ] {
        let response = depth_map(
            &app,
            &format!("?max_disparity=48&output={output}"),
            form(&pair, &[("rig", rig().to_string())]),
        )
        .await;
        assert_eq!(response.status(), 200, "{output}");
        assert_eq!(response.headers()["stereo-projection"], "pinhole");
        let disposition = response.headers()["content-disposition"].to_str().unwrap();
        assert!(
            disposition.contains(&format!("filename=\"{output}\"")),
            "{disposition}"
        );
        files.insert(output, response.bytes().await.unwrap().to_vec());
    }
    let disparity = npy(&files["disparity.npy"]);
    assert_eq!(disparity.len(), W * H);
    let valid = disparity.iter().filter(|d| !d.is_nan()).count();
    assert!(valid > W * H * 4 / 5);

    // PFM: header, then rows bottom to top, NaN written as +inf.
    let pfm = &files["disparity.pfm"];
    let header = format!("Pf\n{W} {H}\n-1\n");
    assert_eq!(&pfm[..header.len()], header.as_bytes());
    let rows = floats(&pfm[header.len()..]);
    for y in 0..H {
        for x in 0..W {
            let (p, n) = (rows[(H - 1 - y) * W + x], disparity[y * W + x]);
            assert!(p == n || (p.is_infinite() && n.is_nan()), "({x}, {y})");
        }
    }

    // KITTI: 16-bit, round(d·256), 0 where invalid.
    let kitti = image::load_from_memory(&files["disparity.png"])
        .unwrap()
        .into_luma16();
    for (k, d) in kitti.as_raw().iter().zip(&disparity) {
        let expected = if d.is_nan() {
            0
        } else {
            (d * 256.0).round() as u16
        };
        assert_eq!(*k, expected);
    }

    // Depth: Z = B·f / d in mm, in the NPY and, rounded, in the PNG.
    let depth = npy(&files["depth.npy"]);
    let depth_png = image::load_from_memory(&files["depth.png"])
        .unwrap()
        .into_luma16();
    for ((z, d), mm) in depth.iter().zip(&disparity).zip(depth_png.as_raw()) {
        if d.is_nan() {
            assert!(z.is_nan());
            assert_eq!(*mm, 0);
        } else {
            assert!((z - 50_000.0 / d).abs() <= 1e-3 * z);
            assert_eq!(f32::from(*mm), z.round());
        }
    }

    // σ_d: where the disparity is valid and nowhere else, never below the model's floor, and
    // mostly under a pixel on this clean pair; the PFM holds the same values bottom-up.
    let std = npy(&files["disparity_std.npy"]);
    for (s, d) in std.iter().zip(&disparity) {
        assert_eq!(s.is_nan(), d.is_nan());
        assert!(s.is_nan() || *s >= sigma::MODEL.floor - 1e-6, "{s}");
    }
    let mut sure: Vec<f32> = std.iter().copied().filter(|s| !s.is_nan()).collect();
    sure.sort_by(f32::total_cmp);
    assert!(
        sure[sure.len() / 2] < 0.5,
        "median σ_d {}",
        sure[sure.len() / 2]
    );
    let std_pfm = floats(&files["disparity_std.pfm"][header.len()..]);
    for y in 0..H {
        for x in 0..W {
            let (p, n) = (std_pfm[(H - 1 - y) * W + x], std[y * W + x]);
            assert!(p == n || (p.is_infinite() && n.is_nan()), "({x}, {y})");
        }
    }
    // σ_Z = Z²·σ_d / (f·B), f·B = 50 000, the rig having no σ_f or σ_B.
    let depth_std = npy(&files["depth_std.npy"]);
    for ((e, z), s) in depth_std.iter().zip(&depth).zip(&std) {
        if z.is_nan() {
            assert!(e.is_nan());
        } else {
            assert!((e - z * z * s / 50_000.0).abs() <= 1e-4 * e, "{e} at {z}");
        }
    }

    // NPZ: the same arrays, and `depth_error` the same σ_Z under its earlier name.
    let arrays = npz_entries(&files["arrays.npz"]);
    let names: Vec<&str> = arrays.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "disparity.npy",
            "disparity_std.npy",
            "depth.npy",
            "depth_std.npy",
            "depth_error.npy",
            "projection.npy"
        ]
    );
    // `projection`: a 0-d `<U7` array, UTF-32 code points after its header.
    let projection = &arrays[5].1;
    let text: Vec<u8> = projection[projection.len() - 28..]
        .chunks(4)
        .map(|c| c[0])
        .collect();
    assert_eq!(text, b"pinhole");
    assert_eq!(arrays[0].1, files["disparity.npy"]);
    assert_eq!(arrays[1].1, files["disparity_std.npy"]);
    assert_eq!(arrays[2].1, files["depth.npy"]);
    assert_eq!(arrays[3].1, files["depth_std.npy"]);
    assert_eq!(arrays[4].1, files["depth_std.npy"]);

    let preview = image::load_from_memory(&files["preview.png"])
        .unwrap()
        .into_rgb8();
    assert_eq!(preview.dimensions(), (W as u32, H as u32));

    // PLY: binary little-endian, x y z float, colour and σ_Z float, one vertex per valid
    // depth; the first vertex is the first valid pixel, placed as /distance places points,
    // and every vertex carries its pixel's depth_std.npy value.
    let ply = &files["points.ply"];
    let end = b"end_header\n";
    let at = ply.windows(end.len()).position(|w| w == end).unwrap() + end.len();
    let head = std::str::from_utf8(&ply[..at]).unwrap();
    assert!(head.starts_with("ply\nformat binary_little_endian 1.0\n"));
    assert!(head.contains("\ncomment projection pinhole\n"), "{head}");
    assert!(
        head.contains(&format!("element vertex {valid}\n")),
        "{head}"
    );
    assert!(
        head.contains("property uchar blue\nproperty float depth_std\nend_header"),
        "{head}"
    );
    assert_eq!(ply.len() - at, valid * 19);
    let first = disparity.iter().position(|d| !d.is_nan()).unwrap();
    let xyz = floats(&ply[at..at + 12]);
    let z = 50_000.0 / disparity[first];
    let (x, y) = ((first % W) as f32, (first / W) as f32);
    assert!((xyz[2] - z).abs() < 1e-3 * z);
    assert!((xyz[0] - (x - 80.0) * z / 500.0).abs() < 1e-2);
    assert!((xyz[1] - (y - 60.0) * z / 500.0).abs() < 1e-2);
    let stds: Vec<f32> = ply[at..]
        .chunks_exact(19)
        .map(|v| f32::from_le_bytes(v[15..19].try_into().unwrap()))
        .collect();
    let valid_stds: Vec<f32> = depth_std.iter().copied().filter(|s| !s.is_nan()).collect();
    assert_eq!(stds, valid_stds);
}

/// The summary's σ medians are those of the σ files (as numpy.nanmedian takes them), and a
/// rig's σ_f and σ_B reach every pixel's σ_Z: σ_Z² = (Z²·σ_d / (f·B))² + (Z·σ_f / f)² +
/// (Z·σ_B / B)².
#[tokio::test]
async fn sigma_reaches_the_summary_and_takes_the_rigs_calibration() {
    let app = spawn_app().await;
    let pair = pair();
    let calibrated = json!({"focal_length_px": 500, "baseline": 100, "unit": "mm",
                            "focal_length_std_px": 2.5, "baseline_std": 0.4});
    let mut files = Vec::new();
    for output in ["summary", "disparity_std.npy", "depth.npy", "depth_std.npy"] {
        let response = depth_map(
            &app,
            &format!("?max_disparity=48&output={output}"),
            form(&pair, &[("rig", calibrated.to_string())]),
        )
        .await;
        assert_eq!(response.status(), 200, "{output}");
        files.push(response.bytes().await.unwrap().to_vec());
    }
    let summary: Value = serde_json::from_slice(&files[0]).unwrap();
    let (std, depth, depth_std) = (npy(&files[1]), npy(&files[2]), npy(&files[3]));
    let median = |member: &str| summary[member]["median"].as_f64().unwrap();
    assert!(
        (median("disparity_std_px") - nanmedian(&std)).abs() < 1e-4,
        "{summary}"
    );
    assert!(
        (median("distance_std") - nanmedian(&depth_std)).abs() < 1e-4 * median("distance_std"),
        "{summary}"
    );
    for ((e, z), s) in depth_std.iter().zip(&depth).zip(&std) {
        if z.is_nan() {
            assert!(e.is_nan());
            continue;
        }
        let expected = ((z * z * s / 50_000.0).powi(2)
            + (z * 2.5 / 500.0).powi(2)
            + (z * 0.4 / 100.0).powi(2))
        .sqrt();
        assert!(
            (e - expected).abs() <= 1e-4 * expected,
            "{e} against {expected}"
        );
    }
}

/// A Middlebury calib.txt gives the rig and, by its ndisp, the search range, unless
/// `max_disparity=auto` asks for it found; a value neither `auto` nor a number is refused.
#[tokio::test]
async fn a_calibration_file_gives_the_rig_and_the_range() {
    let app = spawn_app().await;
    let calib = "cam0=[500 0 80; 0 500 60; 0 0 1]\ncam1=[500 0 80; 0 500 60; 0 0 1]\n\
                 doffs=0\nbaseline=100\nwidth=160\nheight=120\nndisp=48\n";
    let response = depth_map(
        &app,
        "",
        form(&pair(), &[("calibration", calib.to_owned())]),
    )
    .await;
    let body = ok_json(response).await;
    assert_eq!(body["max_disparity"], 48);
    assert_eq!(body["rig"]["focal_length_px"], 500.0);
    assert_eq!(body["rig"]["baseline"], 100.0);
    assert!(body["distance"]["median"].as_f64().unwrap() > 1000.0);
    assert_eq!(body["disparity_range"]["chosen"], "given", "{body}");
    // `max_disparity=auto` finds the range from the pair even with the file's ndisp.
    let with = || form(&pair(), &[("calibration", calib.to_owned())]);
    let body = ok_json(depth_map(&app, "?max_disparity=auto", with()).await).await;
    assert_eq!(body["disparity_range"]["chosen"], "found", "{body}");
    // Neither `auto` nor a number: a 422 naming the member and what it takes.
    let response = depth_map(&app, "?max_disparity=automatic", with()).await;
    assert_eq!(response.status(), 422);
    let body: serde_json::Value = response.json().await.unwrap();
    assert_eq!(body["errors"][0]["field"], "max_disparity", "{body}");
    assert!(
        body["errors"][0]["message"]
            .as_str()
            .unwrap()
            .contains("must be auto or a whole number"),
        "{body}"
    );
}

/// `Accept: image/x-portable-floatmap` answers the PFM; an explicit `output` wins.
#[tokio::test]
async fn accept_chooses_the_output() {
    let app = spawn_app().await;
    let response = app
        .client
        .post(format!("{}/depth-map?max_disparity=48", app.address))
        .header(ACCEPT, "image/x-portable-floatmap")
        .multipart(form(&pair(), &[]))
        .send()
        .await
        .unwrap();
    assert_eq!(
        response.headers()["content-type"],
        "image/x-portable-floatmap"
    );
    assert!(
        response
            .bytes()
            .await
            .unwrap()
            .starts_with(b"Pf\n160 120\n")
    );
}

/// A missing image, a part that is no image, an unknown part and a bad option are all named
/// in one 422.
#[tokio::test]
async fn every_bad_part_is_named() {
    let app = spawn_app().await;
    let form = Form::new()
        .part("left", Part::bytes(b"hello, not an image".to_vec()))
        .text("rigg", "{}")
        .text("rig", r#"{"focal_length_px": 500, "baseline": 0}"#);
    let body = problem(depth_map(&app, "?p1=20&p2=10", form).await, 422).await;
    assert_names(&body, &["left", "right", "rigg", "rig.baseline", "p2"]);
    assert!(message_for(&body, "left").contains("not an image"));
    assert!(message_for(&body, "right").contains("is required"));
    assert!(message_for(&body, "rigg").contains("not a part of this request"));
}

/// Two images of different sizes: the right one is named, with both sizes.
#[tokio::test]
async fn a_pair_of_two_sizes_names_the_right_image() {
    let app = spawn_app().await;
    let pair = pair();
    let small = synthetic::render(&synthetic::layered(150, H));
    let form = Form::new()
        .part("left", image_part(png(&pair.left_rgb, W, H)))
        .part("right", image_part(png(&small.right_rgb, 150, H)));
    let body = problem(depth_map(&app, "", form).await, 422).await;
    assert_eq!(fields(&body), vec!["right"]);
    assert!(message_for(&body, "right").contains("150 × 120"), "{body}");
}

/// Depth outputs need a rig; a rig for other images, or both a rig and a calibration, is
/// refused naming the parts.
#[tokio::test]
async fn rigs_are_checked_against_the_images() {
    let app = spawn_app().await;
    let pair = pair();
    let body = problem(
        depth_map(&app, "?output=depth.npy", form(&pair, &[])).await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["rig"]);
    let wrong = json!({"focal_length_px": 500, "baseline": 100, "image_width": 640});
    let body = problem(
        depth_map(&app, "", form(&pair, &[("rig", wrong.to_string())])).await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["rig.image_width"]);
    let body = problem(
        depth_map(
            &app,
            "",
            form(
                &pair,
                &[("rig", rig().to_string()), ("calibration", "x".into())],
            ),
        )
        .await,
        422,
    )
    .await;
    assert_names(
        &body,
        &["rig.focal_length_px", "rig.baseline", "calibration"],
    );
}

/// A calibration file from elsewhere carries no σ: a `rig` part beside it gives the
/// calibration's σ (and only that), and the depth's error bar takes it.
#[tokio::test]
async fn the_calibrations_sigma_is_given_beside_its_file() {
    let app = spawn_app().await;
    let calib = "cam0=[500 0 80; 0 500 60; 0 0 1]\ncam1=[500 0 80; 0 500 60; 0 0 1]\n\
                 doffs=0\nbaseline=100\nwidth=160\nheight=120\nndisp=48\n";
    let std = json!({"focal_length_std_px": 2.5, "baseline_std": 0.04, "unit": "cm"});
    let body = ok_json(
        depth_map(
            &app,
            "",
            form(
                &pair(),
                &[("calibration", calib.to_owned()), ("rig", std.to_string())],
            ),
        )
        .await,
    )
    .await;
    assert_eq!(body["rig"]["focal_length_px"], 500.0);
    assert_eq!(body["rig"]["focal_length_std_px"], 2.5);
    assert_close(
        number_at(&body, "rig.baseline_std"),
        0.4,
        "0.04 cm in the file's mm",
    );
}

/// Beside a calibration part, a `rig` part holding anything but the σ, or a σ of the wrong
/// kind, has every such member named.
#[tokio::test]
async fn a_rig_beside_a_calibration_names_each_member_it_may_not_hold() {
    let app = spawn_app().await;
    let calib = "cam0=[500 0 80; 0 500 60; 0 0 1]\ncam1=[500 0 80; 0 500 60; 0 0 1]\n\
                 doffs=0\nbaseline=100\nwidth=160\nheight=120\nndisp=48\n";
    let rig = json!({"baseline": 100, "focal_length_std_px": "two", "unit": "yard"});
    let body = problem(
        depth_map(
            &app,
            "",
            form(
                &pair(),
                &[("calibration", calib.to_owned()), ("rig", rig.to_string())],
            ),
        )
        .await,
        422,
    )
    .await;
    assert_names(
        &body,
        &["rig.baseline", "rig.focal_length_std_px", "rig.unit"],
    );
    assert!(message_for(&body, "rig.baseline").contains("given by the calibration part"));
}

/// The search range and the matcher's options are checked and named.
#[tokio::test]
async fn options_out_of_range_are_named() {
    let app = spawn_app().await;
    let body = problem(
        depth_map(
            &app,
            "?min_disparity=10&max_disparity=5&uniqueness=300&subpixel=cubic&fill=yes",
            form(&pair(), &[]),
        )
        .await,
        422,
    )
    .await;
    assert_names(&body, &["max_disparity", "uniqueness", "subpixel", "fill"]);
    let body = problem(
        depth_map(&app, "?max_disparity=1000", form(&pair(), &[])).await,
        422,
    )
    .await;
    assert!(message_for(&body, "max_disparity").contains("at most 512"));
}

/// `fill=true` marks what it gave: the NPZ's `filled` (NumPy bool) is true exactly where the
/// unfilled map has a hole and the filled one a value; the values matched are the same in
/// both; a filled pixel's σ_d is at least the fill's floor (a value taken, not matched). Without the
/// fill there is no `filled` entry.
#[tokio::test]
async fn a_filled_map_marks_what_the_fill_gave() {
    let app = spawn_app().await;
    let pair = pair();
    let mut arrays = Vec::new();
    for fill in ["false", "true"] {
        arrays.push(arrays_of(&app, &pair, &format!("&fill={fill}")).await);
    }
    let names = |entries: &[(String, Vec<u8>)]| -> Vec<String> {
        entries.iter().map(|(n, _)| n.clone()).collect()
    };
    assert_eq!(
        names(&arrays[0]),
        ["disparity.npy", "disparity_std.npy", "projection.npy"]
    );
    assert_eq!(
        names(&arrays[1]),
        [
            "disparity.npy",
            "disparity_std.npy",
            "filled.npy",
            "projection.npy"
        ]
    );
    let (holes, filled, std) = (
        npy(&arrays[0][0].1),
        npy(&arrays[1][0].1),
        npy(&arrays[1][1].1),
    );
    let mask = &arrays[1][2].1;
    assert_eq!(&mask[..8], b"\x93NUMPY\x01\x00");
    let len = u16::from_le_bytes([mask[8], mask[9]]) as usize;
    let header = std::str::from_utf8(&mask[10..10 + len]).unwrap();
    assert!(header.contains("'descr': '|b1'") && header.contains(&format!("'shape': ({H}, {W})")));
    let mask = &mask[10 + len..];
    assert_eq!(mask.len(), W * H);
    let mut count = 0;
    for i in 0..W * H {
        let gave = holes[i].is_nan() && !filled[i].is_nan();
        assert_eq!(mask[i], u8::from(gave), "pixel {i}");
        if gave {
            count += 1;
            assert!(
                std[i] >= sigma::FILLED_FLOOR,
                "a filled pixel's σ_d {}",
                std[i]
            );
        } else if !holes[i].is_nan() {
            assert_eq!(holes[i], filled[i]);
        }
    }
    assert!(count > 100, "{count} pixels filled");
}

/// `max_disparity_std` is the keep rule: the map asked with it holds exactly the default
/// map's pixels whose σ_d is at most the threshold, with the same values and σ; the summary
/// echoes it (4 px by default); out of (0, 64] or not a number, it is a 422 naming it.
#[tokio::test]
async fn max_disparity_std_keeps_what_sigma_allows() {
    let app = spawn_app().await;
    let pair = pair();
    let mut maps = Vec::new();
    for query in ["", "&max_disparity_std=0.25"] {
        let entries = arrays_of(&app, &pair, query).await;
        maps.push((npy(&entries[0].1), npy(&entries[1].1)));
    }
    let ((d, s), (strict, strict_s)) = (&maps[0], &maps[1]);
    let (mut kept, mut dropped) = (0, 0);
    for i in 0..d.len() {
        assert!(
            d[i].is_nan() || s[i] <= 4.0,
            "pixel {i}: σ {} kept by default",
            s[i]
        );
        if !d[i].is_nan() && s[i] <= 0.25 {
            kept += 1;
            assert_eq!((strict[i], strict_s[i]), (d[i], s[i]), "pixel {i}");
        } else {
            dropped += usize::from(!d[i].is_nan());
            assert!(strict[i].is_nan() && strict_s[i].is_nan(), "pixel {i}");
        }
    }
    assert!(
        kept > 1000 && dropped > 100,
        "{kept} kept, {dropped} dropped"
    );
    for (query, echoed) in [("", 4.0), ("&max_disparity_std=0.25", 0.25)] {
        let response =
            depth_map(&app, &format!("?max_disparity=48{query}"), form(&pair, &[])).await;
        let summary: serde_json::Value = response.json().await.unwrap();
        assert_eq!(summary["parameters"]["max_disparity_std"], echoed);
    }
    for bad in ["0", "65", "-1", "much"] {
        let body = problem(
            depth_map(&app, &format!("?max_disparity_std={bad}"), form(&pair, &[])).await,
            422,
        )
        .await;
        assert_names(&body, &["max_disparity_std"]);
    }
}

/// A fill that is neither true nor false, and a σ output asked of a route that has none
/// (`/rectify` answers images, `/match` answers points and takes no `output`), are each a 422
/// naming the parameter.
#[tokio::test]
async fn sigma_outputs_and_fill_are_checked_per_route() {
    let app = spawn_app().await;
    let body = problem(
        depth_map(&app, "?fill=maybe", form(&pair(), &[])).await,
        422,
    )
    .await;
    assert_names(&body, &["fill"]);
    for route in ["rectify", "match"] {
        let response = app
            .client
            .post(format!("{}/{route}?output=disparity_std.npy", app.address))
            .multipart(form(&pair(), &[("rig", rig().to_string())]))
            .send()
            .await
            .unwrap();
        let body = problem(response, 422).await;
        assert_names(&body, &["output"]);
    }
}

/// The share (%) of the visible pixels whose disparity in `map` is off the truth by more
/// than `by` px, a hole counting as off.
fn bad_share(pair: &Pair, map: &[f32], by: f32) -> f64 {
    let (mut seen, mut off) = (0usize, 0usize);
    for ((&d, &t), &visible) in map.iter().zip(&pair.truth).zip(&pair.visible) {
        if visible {
            seen += 1;
            off += usize::from(d.is_nan() || (d - t).abs() > by);
        }
    }
    100.0 * off as f64 / seen as f64
}

/// `preset=fast` is a named set of the matcher's settings (one pass, no median) that a setting
/// given overrides, reported as used; both presets keep their accuracy floors on the rendered
/// scene, and a preset or a path count that does not exist is a 422 naming it.
#[tokio::test]
async fn presets_are_named_sets_with_accuracy_floors() {
    let app = spawn_app().await;
    let pair = pair();
    let mut bad = Vec::new();
    for (query, preset, paths, median) in [
        // The rendered scene's textures are smooth at one pixel's scale: `accurate` takes 8.
        ("", "accurate", 8, true),
        // `fast` takes 5 there, where it takes 4 on a clear pair (Motorcycle).
        ("&preset=fast", "fast", 5, false),
        ("&preset=fast&paths=8&median=true", "fast", 8, true),
        ("&preset=accurate&paths=5", "accurate", 5, true),
        ("&preset=fast&paths=4", "fast", 4, false),
    ] {
        let body =
            ok_json(depth_map(&app, &format!("?max_disparity=48{query}"), form(&pair, &[])).await)
                .await;
        let used = &body["parameters"];
        assert_eq!(
            (
                used["preset"].as_str(),
                used["paths"].as_u64(),
                used["median"].as_bool()
            ),
            (Some(preset), Some(paths), Some(median)),
            "{query}: {used}"
        );
        let response = depth_map(
            &app,
            &format!("?max_disparity=48&output=disparity.npy{query}"),
            form(&pair, &[]),
        )
        .await;
        assert_eq!(response.status(), 200);
        let map = npy(&response.bytes().await.unwrap());
        bad.push((
            query,
            bad_share(&pair, &map, 1.0),
            bad_share(&pair, &map, 2.0),
        ));
    }
    // Measured, bad-1.0 / bad-2.0 of the visible pixels: 1.82 / 1.80 % (accurate, 8 paths),
    // 2.10 / 2.08 % (fast), 2.13 / 2.12 % (accurate with 5 paths).
    for (query, bad1, bad2) in &bad {
        assert!(
            *bad1 < 3.0 && *bad2 < 3.0,
            "{query}: bad-1.0 {bad1:.2} %, bad-2.0 {bad2:.2} %"
        );
    }
    let body = problem(
        depth_map(&app, "?preset=slow&paths=7", form(&pair, &[])).await,
        422,
    )
    .await;
    assert_names(&body, &["preset", "paths"]);
    assert_eq!(message_for(&body, "paths"), "must be 4, 5 or 8, got 7");
}

/// A JSON body is not a form: 415 naming the media type to send.
#[tokio::test]
async fn a_json_body_is_415() {
    let app = spawn_app().await;
    let response = app
        .post_raw("/depth-map", Some("application/json"), b"{}".to_vec())
        .await;
    let body = problem(response, 415).await;
    let message = message_for(&body, "content-type");
    assert!(message.contains("multipart/form-data"), "{message}");
    // What was sent, in the API's words (not the form parser's about a boundary).
    assert!(message.contains("got application/json"), "{message}");
    assert!(!message.contains("boundary"), "{message}");
    // A form without its boundary is told so.
    let response = app
        .post_raw("/depth-map", Some("multipart/form-data"), b"--x".to_vec())
        .await;
    let body = problem(response, 415).await;
    assert!(
        message_for(&body, "content-type").contains("without a boundary"),
        "{body}"
    );
}

/// A one-pixel PNG whose header claims `width × height` pixels.
pub(crate) fn png_claiming(width: u32, height: u32) -> Vec<u8> {
    let mut bytes = png(&[0, 0, 0], 1, 1);
    bytes[16..20].copy_from_slice(&width.to_be_bytes());
    bytes[20..24].copy_from_slice(&height.to_be_bytes());
    let mut crc = flate2::Crc::new();
    crc.update(&bytes[12..29]);
    bytes[29..33].copy_from_slice(&crc.sum().to_be_bytes());
    bytes
}

/// A pair of images whose headers claim `width × height` pixels.
fn pair_claiming(width: u32, height: u32) -> Form {
    Form::new()
        .part("left", image_part(png_claiming(width, height)))
        .part("right", image_part(png_claiming(width, height)))
}

/// A phone's 4032 × 3024 photograph (12.19 MP) passes the pixel cap by default: a request
/// whose only fault is its disparity range is refused for that alone. With
/// `--max-image-pixels 12000000` the same pair is a 413 naming both images and the cap. (The
/// whole request on such a JPEG pair is `scale.rs`'s, in release.)
#[tokio::test]
async fn the_pixel_cap_admits_a_phone_photo_and_is_an_option() {
    let app = spawn_app().await;
    let body = problem(
        depth_map(&app, "?max_disparity=4000", pair_claiming(4032, 3024)).await,
        422,
    )
    .await;
    assert_eq!(fields(&body), vec!["max_disparity"], "{body}");
    let capped = spawn_app_with(Config {
        port: 0,
        heavy: HeavyLimits {
            max_image_pixels: 12_000_000,
            ..HeavyLimits::default()
        },
        ..Config::default()
    })
    .await;
    let body = problem(
        depth_map(&capped, "?max_disparity=4000", pair_claiming(4032, 3024)).await,
        413,
    )
    .await;
    assert_eq!(fields(&body), vec!["left", "right"]);
    assert!(
        message_for(&body, "left").contains(
            "4032 × 3024 pixels; this server takes at most 8192 pixels a side and 12 megapixels"
        ),
        "{body}"
    );
}

/// A phone's 4032 × 3024 pair and a 24 MP camera's 6000 × 4000 pair are admitted under the
/// default 1 GiB budget at every range from 16 to 400 disparities: no 413 for their memory at
/// any of them (the pair, claimed by its headers, is then refused as damaged, naming both
/// images). The whole request at each range is `scale.rs`'s, in release.
#[tokio::test]
async fn a_phone_pair_and_a_24_megapixel_pair_are_admitted_at_every_range() {
    let app = spawn_app().await;
    for (w, h) in [(4032, 3024), (6000, 4000)] {
        for count in [16, 32, 48, 64, 96, 128, 256, 400] {
            let response = depth_map(
                &app,
                &format!("?max_disparity={count}"),
                pair_claiming(w, h),
            )
            .await;
            let body = problem(response, 422).await;
            assert_eq!(
                fields(&body),
                vec!["left", "right"],
                "{w} × {h} at {count}: {body}"
            );
            assert!(
                !body.to_string().contains("MiB"),
                "{w} × {h} at {count}: {body}"
            );
        }
    }
}

/// A small PNG whose header claims 20 000 × 20 000 pixels is a 413 naming the image, found
/// from the header alone; the service then answers normally.
#[tokio::test]
async fn an_image_claiming_too_many_pixels_is_413() {
    let app = spawn_app().await;
    let bytes = png_claiming(20_000, 20_000);
    let form = Form::new()
        .part("left", image_part(bytes.clone()))
        .part("right", image_part(bytes));
    let body = problem(depth_map(&app, "", form).await, 413).await;
    assert_eq!(fields(&body), vec!["left", "right"]);
    assert!(message_for(&body, "left").contains("20000 × 20000"));
    let again = depth_map(&app, "?max_disparity=48", form_of_pair()).await;
    assert_eq!(again.status(), 200);
}

/// A form past the heavy group's body limit is a 413 naming `body`, the limit in MiB, the
/// option that sets it, and how to send less: JPEG or smaller images.
#[tokio::test]
async fn a_form_past_the_body_limit_names_the_option_and_a_smaller_jpeg() {
    let mut config = Config {
        port: 0,
        ..Config::default()
    };
    config.heavy.body_bytes = 1024 * 1024;
    let app = spawn_app_with(config).await;
    let big = vec![7u8; 1536 * 1024];
    let form = Form::new()
        .part("left", image_part(big.clone()))
        .part("right", image_part(big));
    let body = problem(depth_map(&app, "", form).await, 413).await;
    assert_eq!(fields(&body), vec!["body"]);
    let message = message_for(&body, "body");
    assert!(message.contains("at most 1 MiB"), "{message}");
    assert!(
        message.contains("JPEG") && message.contains("--heavy-body-limit"),
        "{message}"
    );
    assert!(
        body["detail"]
            .as_str()
            .unwrap_or_default()
            .contains("HEAVY_BODY_LIMIT"),
        "{body}"
    );
}

fn form_of_pair() -> Form {
    form(&pair(), &[])
}

/// A request that could never fit in the memory budget is a 413 naming the image and the
/// range, with the largest range that would fit.
#[tokio::test]
async fn a_request_beyond_the_memory_budget_names_what_to_shrink() {
    let app = spawn_app_with(Config {
        port: 0,
        heavy: HeavyLimits {
            memory_budget: 3 << 20,
            body_bytes: 1 << 20,
            ..HeavyLimits::default()
        },
        ..Config::default()
    })
    .await;
    let body = problem(
        depth_map(&app, "?max_disparity=512", form_of_pair()).await,
        413,
    )
    .await;
    assert_eq!(fields(&body), vec!["left", "max_disparity"]);
    assert!(
        message_for(&body, "max_disparity").contains("at most"),
        "{body}"
    );
    let fits = depth_map(&app, "?max_disparity=32", form_of_pair()).await;
    assert_eq!(fits.status(), 200);
}

/// While another upload holds nearly all of the memory budget (its declared body is reserved on
/// admission), a pair that needs more than is left is a 503 with `Retry-After`; once that
/// upload is gone the same request is answered.
#[tokio::test]
async fn a_held_memory_budget_is_503_and_then_served() {
    // Arrange: a 64 MiB budget, and a connection declaring a 62 MiB form that never comes.
    let app = spawn_app_with(Config {
        port: 0,
        heavy: HeavyLimits {
            memory_budget: 64 << 20,
            body_bytes: 63 << 20,
            ..HeavyLimits::default()
        },
        ..Config::default()
    })
    .await;
    let head = format!(
        "POST /depth-map HTTP/1.1\r\nHost: test\r\nContent-Type: multipart/form-data; \
         boundary=x\r\nContent-Length: {}\r\n\r\n",
        62 << 20
    );
    let held = app.raw_partial(&head, b"--x\r\n").await;
    app.wait_in_flight(2.0).await;
    // Act
    let refused = depth_map(&app, "?max_disparity=48", form_of_pair()).await;
    // Assert
    assert!(refused.headers().contains_key("retry-after"));
    let body = problem(refused, 503).await;
    assert!(
        body["detail"].as_str().unwrap().contains("memory budget"),
        "{body}"
    );
    drop(held);
    let mut served = depth_map(&app, "?max_disparity=48", form_of_pair()).await;
    for _ in 0..50 {
        if served.status() == 200 {
            break;
        }
        // The held connection's reservation is given back when the server sees it close.
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
        served = depth_map(&app, "?max_disparity=48", form_of_pair()).await;
    }
    assert_eq!(served.status(), 200);
}

/// `rgb` (`W × H`, as shown) stored turned a quarter counter-clockwise in a JPEG whose EXIF
/// orientation (6) says to turn it back clockwise, as a phone writes a portrait photo.
pub(crate) fn phone_photo(rgb: &[u8]) -> Vec<u8> {
    let (w, h) = (W, H);
    let stored: Vec<u8> = (0..w * h)
        .flat_map(|i| {
            // The stored image is h wide and w tall: stored (x, y) is shown (w − 1 − y, x).
            let (x, y) = (i % h, i / h);
            let shown = (x * w + (w - 1 - y)) * 3;
            [rgb[shown], rgb[shown + 1], rgb[shown + 2]]
        })
        .collect();
    synthetic::phone_jpeg(&stored, h, w, 6)
}

/// A pair of phone photos with an EXIF orientation is read as a browser shows it: the summary
/// gives the turned size, a rig for that size is taken, and the disparities are the scene's.
#[tokio::test]
async fn exif_orientation_is_applied() {
    let app = spawn_app().await;
    let pair = pair();
    let photos = Form::new()
        .part("left", jpeg_part(phone_photo(&pair.left_rgb)))
        .part("right", jpeg_part(phone_photo(&pair.right_rgb)))
        .text(
            "rig",
            json!({"focal_length_px": 500, "baseline": 100, "image_width": W,
                   "image_height": H})
            .to_string(),
        );
    let body = ok_json(depth_map(&app, "?max_disparity=48", photos).await).await;
    assert_eq!(
        (body["width"].as_u64(), body["height"].as_u64()),
        (Some(160), Some(120))
    );
    assert!(body["valid_fraction"].as_f64().unwrap() > 0.75, "{body}");
    let straight = ok_json(
        depth_map(
            &app,
            "?max_disparity=48",
            form(&pair, &[("rig", rig().to_string())]),
        )
        .await,
    )
    .await;
    let median = |b: &Value| b["disparity_px"]["median"].as_f64().unwrap();
    assert!(
        (median(&body) - median(&straight)).abs() < 0.5,
        "{body} {straight}"
    );
}

pub(crate) fn jpeg_part(bytes: Vec<u8>) -> Part {
    Part::bytes(bytes)
        .file_name("photo.jpg")
        .mime_str("image/jpeg")
        .unwrap()
}

/// 5 000 unknown parts (and no images) are one 422 that names the first few and counts the rest, under 16 KiB
/// (not a megabyte naming each part twice).
#[tokio::test]
async fn a_problem_lists_a_few_and_counts_the_rest() {
    let app = spawn_app().await;
    // Written by hand: reqwest chains a form's parts into nested streams, too deep for 5 000.
    let mut body = Vec::new();
    for i in 0..5000 {
        body.extend_from_slice(
            format!("--b\r\ncontent-disposition: form-data; name=\"extra{i}\"\r\n\r\n1\r\n")
                .as_bytes(),
        );
    }
    body.extend_from_slice(b"--b--\r\n");
    let response = app
        .post_raw("/depth-map", Some("multipart/form-data; boundary=b"), body)
        .await;
    assert_eq!(response.status(), 422);
    let bytes = response.bytes().await.unwrap();
    assert!(bytes.len() < 16 * 1024, "{} bytes", bytes.len());
    let body: Value = serde_json::from_slice(&bytes).unwrap();
    let names = fields(&body);
    assert_eq!(names.len(), 11, "{body}");
    assert_eq!(names[0], "extra0");
    // 5 000 unknown parts, and the missing left and right images.
    assert!(message_for(&body, "body").contains("4992 more"), "{body}");
    assert!(
        body["detail"].as_str().unwrap().ends_with("and 4997 more"),
        "{body}"
    );
}

/// NumPy's median of a float32 array's valid values: the middle one, or the mean of the two
/// middle ones of an even count (`numpy.nanmedian`).
fn nanmedian(values: &[f32]) -> f64 {
    let mut valid: Vec<f64> = values
        .iter()
        .filter(|v| v.is_finite())
        .map(|&v| f64::from(v))
        .collect();
    valid.sort_by(f64::total_cmp);
    let n = valid.len();
    if n.is_multiple_of(2) {
        (valid[n / 2 - 1] + valid[n / 2]) / 2.0
    } else {
        valid[n / 2]
    }
}

/// The summary's medians are `numpy.nanmedian` of the NPY outputs, to the summary's 4
/// decimals.
#[tokio::test]
async fn the_summary_median_is_numpys() {
    let app = spawn_app().await;
    let pair = pair();
    let ask = |output: &'static str| {
        let form = form(&pair, &[("rig", rig().to_string())]);
        let app = &app;
        async move { depth_map(app, &format!("?max_disparity=48&output={output}"), form).await }
    };
    let summary = ok_json(ask("summary").await).await;
    let depth = npy(&ask("depth.npy").await.bytes().await.unwrap());
    let disparity = npy(&ask("disparity.npy").await.bytes().await.unwrap());
    for (name, values) in [("distance", &depth), ("disparity_px", &disparity)] {
        let got = summary[name]["median"].as_f64().unwrap();
        let numpy = nanmedian(values);
        assert!((got - numpy).abs() <= 0.5e-4, "{name}: {got} vs {numpy}");
    }
}

/// A rig whose baseline is in the wrong unit (0.1 mm for 100 mm) gets its depths all the same,
/// and the summary's warnings name `baseline` and the likely unit; the right rig's do not.
#[tokio::test]
async fn a_rig_in_the_wrong_unit_is_named() {
    let app = spawn_app().await;
    let pair = pair();
    let said = |rig: Value| {
        let form = form(&pair, &[("rig", rig.to_string())]);
        let app = &app;
        async move {
            let body = ok_json(depth_map(app, "?max_disparity=48", form).await).await;
            body["warnings"].to_string()
        }
    };
    let slip = said(json!({"focal_length_px": 500, "baseline": 0.1, "unit": "mm"})).await;
    assert!(slip.contains("baseline is 0.1 mm, under 1 mm"), "{slip}");
    assert!(slip.contains("meant in m"), "{slip}");
    let right = said(rig()).await;
    assert!(!right.contains("baseline is"), "{right}");
}

/// The synthetic scene five times nearer, 640 × 360: disparities 30–150 px, past the old
/// default of 128.
fn near_pair() -> (Pair, Form, Form, Form) {
    let near = synthetic::render(&synthetic::nearer(640, 360, 5.0, 0.0));
    let form = |a: &[u8], b: &[u8]| {
        Form::new()
            .part("left", image_part(png(a, 640, 360)))
            .part("right", image_part(png(b, 640, 360)))
            .text("rig", rig().to_string())
    };
    let sent = form(&near.left_rgb, &near.right_rgb);
    let again = form(&near.left_rgb, &near.right_rgb);
    let swapped = form(&near.right_rgb, &near.left_rgb);
    (near, sent, again, swapped)
}

/// A 640 × 360 near scene's disparity map from `/depth-map` with `query` (an NPY output) and
/// `form`, scored on its disc's central 60 × 60 px: how many answered, and how many of those
/// within 1 px of `near`'s truth.
async fn near_disc(app: &TestApp, query: &str, near: &Pair, form: Form) -> (usize, usize) {
    let response = depth_map(app, query, form).await;
    assert_eq!(response.status(), 200);
    let map = npy_of(&response.bytes().await.unwrap(), (360, 640));
    let (cx, cy) = (448, 180);
    let values: Vec<(f32, f32)> = (cy - 30..cy + 30)
        .flat_map(|y| (cx - 30..cx + 30).map(move |x| y * 640 + x))
        .filter(|&i| !map[i].is_nan())
        .map(|i| (map[i], near.truth[i]))
        .collect();
    let right = values.iter().filter(|(d, t)| (d - t).abs() <= 1.0).count();
    (values.len(), right)
}

/// With no range given, a scene nearer than 128 disparities reach is searched over the range
/// found from the pair (covering its 150 px, and said so), and its disc at 130–150 px is
/// answered right; a given max_disparity of 80 that stops short is named, with the nearest
/// distance it reaches, and the disc refused rather than answered; the pair sent swapped is
/// named, and the right way round is not.
#[tokio::test]
async fn the_range_is_found_a_short_one_refused_and_swapped_cameras_named() {
    let app = spawn_app().await;
    let (near, sent, again, swapped) = near_pair();
    let found = ok_json(depth_map(&app, "", sent).await).await;
    assert_eq!(found["disparity_range"]["chosen"], "found", "{found}");
    let max = found["max_disparity"].as_i64().unwrap();
    assert!((151..=224).contains(&max), "{found}");
    assert!(
        !found["warnings"].to_string().contains("swapped"),
        "{found}"
    );
    let (answered, right) = near_disc(&app, "?output=disparity.npy", &near, {
        let (_, f, _, _) = near_pair();
        f
    })
    .await;
    assert!(
        answered > 3000 && right as f64 >= 0.9 * answered as f64,
        "{right} of {answered}"
    );
    let short = ok_json(depth_map(&app, "?max_disparity=80", again).await).await;
    let said = short["warnings"].to_string();
    assert!(said.contains("max_disparity 80 stops short"), "{said}");
    assert!(said.contains("Z_min = f·B / d_max = 625 mm"), "{said}");
    // The pixels refused are the range's, not a sign of a raw pair.
    assert!(!said.contains("need rectifying"), "{said}");
    assert_eq!(short["disparity_range"]["chosen"], "given");
    let (answered, _) = near_disc(&app, "?max_disparity=80&output=disparity.npy", &near, {
        let (_, f, _, _) = near_pair();
        f
    })
    .await;
    assert!(
        answered < 100,
        "{answered} disc pixels answered past the range"
    );
    let swapped = ok_json(depth_map(&app, "", swapped).await).await;
    assert!(
        swapped["warnings"]
            .to_string()
            .contains("left and right look swapped"),
        "{swapped}"
    );
}

/// A scene near everywhere (the synthetic scene five times nearer and 60 px further: about
/// 90–210 px) at the defaults is searched from past 0, short of its farthest truth, and says
/// so; its disc is answered right. `min_disparity=0` searches from 0, and `min_disparity`
/// neither `auto` nor a number is a 422 naming it.
#[tokio::test]
async fn a_scene_near_everywhere_is_searched_from_the_start_it_needs() {
    let app = spawn_app().await;
    let near = synthetic::render(&synthetic::nearer(640, 360, 5.0, 60.0));
    let least = near.seen_truth().into_iter().fold(f32::MAX, f32::min);
    let form = || {
        Form::new()
            .part("left", image_part(png(&near.left_rgb, 640, 360)))
            .part("right", image_part(png(&near.right_rgb, 640, 360)))
    };
    let found = ok_json(depth_map(&app, "", form()).await).await;
    let min = found["min_disparity"].as_i64().unwrap();
    assert!(
        min > 0 && (min as f32) < least,
        "{min} for a truth from {least}: {found}"
    );
    assert!(
        found["disparity_range"]["why"]
            .as_str()
            .unwrap()
            .contains("the start found from the pair too"),
        "{found}"
    );
    let (answered, right) = near_disc(&app, "?output=disparity.npy", &near, form()).await;
    assert!(
        answered > 3000 && right as f64 >= 0.9 * answered as f64,
        "{right} of {answered}"
    );
    let from_zero = ok_json(depth_map(&app, "?min_disparity=0", form()).await).await;
    assert_eq!(from_zero["min_disparity"], 0, "{from_zero}");
    let response = depth_map(&app, "?min_disparity=far", form()).await;
    assert_eq!(response.status(), 422);
    let problem: serde_json::Value = response.json().await.unwrap();
    assert_eq!(problem["errors"][0]["field"], "min_disparity", "{problem}");
}
