//! Raw cameras over a real socket: `/calibration` reading the files that describe them
//! (a `stereoCalibrate` FileStorage, split or whole, a ROS `CameraInfo` pair with D K R P,
//! KITTI's raw `calib_cam_to_cam.txt`), and `POST /rectify` on pairs the tests render raw
//! through a known calibration, for plumb_bob, rational_polynomial and equidistant lenses;
//! every bad input named.

use nalgebra::{Matrix3, Rotation3, Vector3};
use reqwest::multipart::Form;
use serde_json::{Value, json};
use stereo_core::camera::{
    Camera, Distortion, Intrinsics, Model, RectifyOptions, Size, StereoPair, stereo_rectify,
};

use crate::depth_map::{floats, image_part, npz_entries};
use crate::helpers::{TestApp, assert_names, message_for, ok_json, problem, spawn_app};
use crate::raw_files::{
    H, W, extrinsics_yml, intrinsics_yml, rows, scene, stereo_calibrate_yml, yaml_matrix,
};

/// A raw pair of `model` with a right camera turned by about 1.5° and 60 mm to the right.
pub(crate) fn raw_pair(model: Model) -> StereoPair {
    let (f, d1, d2): (f64, Vec<f64>, Vec<f64>) = match model {
        Model::PlumbBob => (
            300.0,
            vec![-0.22, 0.05, 0.001, -0.0008, 0.0],
            vec![-0.2, 0.04, -0.0006, 0.0009, 0.0],
        ),
        Model::RationalPolynomial => (
            300.0,
            vec![-0.25, 0.07, 0.0008, -0.0004, -0.01, 0.04, -0.01, 0.002],
            vec![-0.24, 0.06, -0.0005, 0.0006, -0.009, 0.04, -0.01, 0.0018],
        ),
        Model::Equidistant => (
            180.0,
            vec![-0.02, 0.004, -0.001, 0.0002],
            vec![-0.018, 0.003, -0.0009, 0.0002],
        ),
    };
    let camera = |fx: f64, cx: f64, cy: f64, d: &[f64]| {
        Camera::new(
            Intrinsics {
                fx,
                fy: fx * 1.001,
                cx,
                cy,
            },
            Distortion::new(model, d).unwrap(),
        )
        .unwrap()
    };
    StereoPair {
        left: camera(f, 161.5, 118.2, &d1),
        right: camera(f * 1.004, 157.9, 121.4, &d2),
        rotation: Rotation3::from_scaled_axis(Vector3::new(0.012, -0.021, 0.009)),
        translation: Vector3::new(-60.0, 0.8, -0.9),
    }
}

const DISPARITY: f64 = 8.0;

/// The raw frames of `pair` seeing the scene: each raw pixel takes the scene's value where it
/// lands in the rectified image (the right one shifted by the disparity).
fn render_raw(pair: &StereoPair, rect: &stereo_core::camera::Rectification) -> [Vec<u8>; 2] {
    let k1 = rect.p1.fixed_view::<3, 3>(0, 0).into_owned();
    let k2 = rect.p2.fixed_view::<3, 3>(0, 0).into_owned();
    let mut out = [Vec::new(), Vec::new()];
    for (i, (camera, r, k, shift)) in [
        (&pair.left, &rect.r1, &k1, 0.0),
        (&pair.right, &rect.r2, &k2, -DISPARITY),
    ]
    .into_iter()
    .enumerate()
    {
        let mut img = vec![0u8; (W * H) as usize];
        for y in 0..H {
            for x in 0..W {
                let v = camera
                    .undistort_to([f64::from(x), f64::from(y)], r, k)
                    .map_or(0.0, |[xr, yr]| scene(xr - shift, yr));
                img[(y * W + x) as usize] = v.round().clamp(0.0, 255.0) as u8;
            }
        }
        out[i] = img;
    }
    out
}

pub(crate) fn grey_png(data: &[u8]) -> Vec<u8> {
    stereo_core::vision::encode::png_grey(W as usize, H as usize, data)
}

fn form(left: Vec<u8>, right: Vec<u8>, extra: &[(&str, String)]) -> Form {
    let mut form = Form::new()
        .part("left", image_part(left))
        .part("right", image_part(right));
    for (name, text) in extra {
        form = form.text(name.to_string(), text.clone());
    }
    form
}

/// `model`'s raw pair ([`raw_pair`]) seeing the scene, rendered, with its `stereoCalibrate`
/// file.
fn rendered(model: Model) -> ([Vec<u8>; 2], String) {
    let pair = raw_pair(model);
    let size = Size {
        width: W,
        height: H,
    };
    let rect = stereo_rectify(&pair, size, RectifyOptions::default()).unwrap();
    (render_raw(&pair, &rect), stereo_calibrate_yml(&pair))
}

/// The form of a raw pair's frames `left` and `right` (grey levels) with the calibration `yml`
/// in mm.
pub(crate) fn raw_form(left: &[u8], right: &[u8], yml: &str) -> Form {
    form(
        grey_png(left),
        grey_png(right),
        &[
            ("calibration", yml.to_owned()),
            ("calibration_unit", "mm".into()),
        ],
    )
}

pub(crate) async fn rectify(app: &TestApp, query: &str, form: Form) -> reqwest::Response {
    app.post_form(&format!("/rectify{query}"), form).await
}

/// For each model, the rectified left image `/rectify` makes from rendered raw frames matches
/// the scene within 1.5 grey levels on average in its valid region, where the raw frame itself
/// is tens of levels off; its size is the rectified size and the summary's rig is the
/// rectified rig.
#[tokio::test]
async fn rectified_frames_match_the_scene_for_every_model() {
    let app = spawn_app().await;
    for model in Model::ALL {
        let pair = raw_pair(model);
        let size = Size {
            width: W,
            height: H,
        };
        let rect = stereo_rectify(&pair, size, RectifyOptions::default()).unwrap();
        let [left, right] = render_raw(&pair, &rect);
        let yml = stereo_calibrate_yml(&pair);
        let parts = |l: &[u8], r: &[u8]| raw_form(l, r, &yml);
        let png = rectify(&app, "?output=left.png", parts(&left, &right)).await;
        assert_eq!(png.status(), 200, "{model}");
        assert_eq!(png.headers()["content-type"], "image/png");
        let image = image::load_from_memory(&png.bytes().await.unwrap())
            .unwrap()
            .into_luma8();
        assert_eq!(image.dimensions(), (W, H));
        let roi = rect.roi_left;
        let (mut ours, mut raw_err, mut n) = (0.0, 0.0, 0.0);
        for y in roi.y + 2..roi.y + roi.height - 2 {
            for x in roi.x + 2..roi.x + roi.width - 2 {
                let truth = scene(x as f64, y as f64);
                ours += (f64::from(image.get_pixel(x as u32, y as u32)[0]) - truth).abs();
                raw_err += (f64::from(left[(y as u32 * W + x as u32) as usize]) - truth).abs();
                n += 1.0;
            }
        }
        assert!(n > f64::from(W * H) * 0.5, "{model}: ROI {roi:?}");
        let (ours, raw_err) = (ours / n, raw_err / n);
        assert!(ours < 1.5, "{model}: mean error {ours} grey levels");
        assert!(
            raw_err > 10.0 * ours,
            "{model}: raw {raw_err} vs ours {ours}"
        );

        let summary = ok_json(rectify(&app, "", parts(&left, &right)).await).await;
        assert_eq!(summary["width"], W);
        assert_eq!(summary["raw"]["rectification_source"], "computed");
        assert_eq!(summary["raw"]["left"]["model"], model.name());
        let f = summary["rig"]["focal_length_px"].as_f64().unwrap();
        assert!((f - rect.p1[(0, 0)]).abs() < 1e-6 * f, "{model}: f {f}");
        let b = summary["rig"]["baseline"].as_f64().unwrap();
        let expected_b = -rect.p2[(0, 3)] / rect.p1[(0, 0)];
        assert!((b - expected_b).abs() < 1e-9 * b, "{model}: B {b}");
        assert!(summary["valid_fraction"]["left"].as_f64().unwrap() > 0.95);
    }
}

/// The second request of a rig finds its maps cached; `pair.png` is both images side by side
/// with lines every 32 rows; `maps.npz` holds the four float32 maps, whose left map sends
/// each rectified pixel to the raw pixel the camera model says.
#[tokio::test]
async fn outputs_cache_pair_and_maps() {
    let app = spawn_app().await;
    let pair = raw_pair(Model::PlumbBob);
    let size = Size {
        width: W,
        height: H,
    };
    let rect = stereo_rectify(&pair, size, RectifyOptions::default()).unwrap();
    let [left, right] = render_raw(&pair, &rect);
    let yml = stereo_calibrate_yml(&pair);
    let parts = || raw_form(&left, &right, &yml);
    let first = ok_json(rectify(&app, "", parts()).await).await;
    let second = ok_json(rectify(&app, "", parts()).await).await;
    assert_eq!(first["maps_cached"], false);
    assert_eq!(second["maps_cached"], true);
    assert_eq!(second["timings_ms"]["maps"], 0.0);

    let png = rectify(&app, "?output=pair.png", parts()).await;
    assert_eq!(png.status(), 200);
    let image = image::load_from_memory(&png.bytes().await.unwrap())
        .unwrap()
        .into_rgb8();
    assert_eq!(image.dimensions(), (2 * W, H));
    assert_eq!(image.get_pixel(5, 16).0, [0, 255, 0], "a line on row 16");
    assert_eq!(image.get_pixel(W + 5, 48).0, [0, 255, 0], "and on row 48");
    assert_ne!(image.get_pixel(W / 2, 30).0, [0, 255, 0]);

    let npz = rectify(&app, "?output=maps.npz", parts()).await;
    assert_eq!(npz.status(), 200);
    assert_eq!(npz.headers()["content-type"], "application/zip");
    let entries = npz_entries(&npz.bytes().await.unwrap());
    let names: Vec<&str> = entries.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "left_map_x.npy",
            "left_map_y.npy",
            "right_map_x.npy",
            "right_map_y.npy"
        ]
    );
    let header_end = |b: &[u8]| 10 + usize::from(u16::from_le_bytes([b[8], b[9]]));
    let mx = floats(&entries[0].1[header_end(&entries[0].1)..]);
    let my = floats(&entries[1].1[header_end(&entries[1].1)..]);
    assert_eq!(mx.len(), (W * H) as usize);
    let k1 = rect.p1.fixed_view::<3, 3>(0, 0).into_owned();
    for (x, y) in [(10u32, 12u32), (160, 120), (300, 220)] {
        let i = (y * W + x) as usize;
        let back = pair
            .left
            .undistort_to([f64::from(mx[i]), f64::from(my[i])], &rect.r1, &k1)
            .unwrap();
        assert!(
            (back[0] - f64::from(x)).abs() < 1e-3 && (back[1] - f64::from(y)).abs() < 1e-3,
            "({x}, {y}) -> {back:?}"
        );
    }
}

/// `/calibration` says a `stereoCalibrate` file describes raw cameras and computes R1 R2 P1
/// P2 Q as `cv2.stereoRectify` does: OpenCV 4.14's numbers for this pair (see
/// `crates/stereo-core/src/camera/tests.rs`) at alpha 0 and 1, to 1e-6 relative.
#[tokio::test]
async fn a_stereo_calibrate_file_is_rectified_as_opencv_does() {
    let app = spawn_app().await;
    let pair = stereo_core::camera::opencv_pair();
    let text = stereo_calibrate_yml(&pair).replace(
        &format!("imageSize: [ {W}, {H} ]"),
        "imageSize: [ 640, 480 ]",
    );
    for (alpha, f, roi_left) in [
        (0.0, 831.9577121731737, [0, 0, 639, 480]),
        (1.0, 726.6555664619012, [10, 20, 588, 435]),
    ] {
        let body = ok_json(
            app.post(
                "/calibration",
                &json!({"text": text, "calibration_unit": "mm", "alpha": alpha}),
            )
            .await,
        )
        .await;
        assert_eq!(body["raw_cameras"], true);
        let raw = &body["raw"];
        assert_eq!(raw["rectification_source"], "computed");
        assert_eq!(raw["alpha"], alpha);
        let ours = raw["P1"][0][0].as_f64().unwrap();
        assert!(
            (ours - f).abs() < 1e-6 * f,
            "alpha {alpha}: f {ours} vs {f}"
        );
        assert!((body["rig"]["focal_length_px"].as_f64().unwrap() - f).abs() < 1e-6 * f);
        assert!((raw["R1"][0][1].as_f64().unwrap() - -0.02087878374203865).abs() < 1e-12);
        let roi: Vec<i64> = serde_json::from_value(raw["roi_left"].clone()).unwrap();
        for (a, b) in roi.iter().zip(roi_left) {
            assert!((a - b).abs() <= 1, "alpha {alpha}: ROI {roi:?}");
        }
    }
}

/// `stereo_calib.cpp`'s split files, `intrinsics.yml` in `text` and `extrinsics.yml` in
/// `right_text`, read as one; without the image size in either, the error says what to add.
#[tokio::test]
async fn split_intrinsics_and_extrinsics_are_read_together() {
    let app = spawn_app().await;
    let pair = raw_pair(Model::PlumbBob);
    let body = ok_json(
        app.post(
            "/calibration",
            &json!({"text": intrinsics_yml(&pair, true), "right_text": extrinsics_yml(&pair),
                    "calibration_unit": "mm"}),
        )
        .await,
    )
    .await;
    assert_eq!(body["raw_cameras"], true);
    assert_eq!(body["raw"]["raw_width"], W);
    let t = body["raw"]["T"][0].as_f64().unwrap();
    assert!((t - -60.0).abs() < 1e-12);
    assert!(body["warnings"].as_array().unwrap().is_empty(), "{body}");

    let no_size = problem(
        app.post(
            "/calibration",
            &json!({"text": intrinsics_yml(&pair, false), "right_text": extrinsics_yml(&pair),
                    "calibration_unit": "mm"}),
        )
        .await,
        422,
    )
    .await;
    assert_names(&no_size, &["text"]);
    assert!(message_for(&no_size, "text").contains("imageSize"));
}

/// A ROS `CameraInfo` pair with D K R P describes raw cameras whose rectification is the
/// files' own (the rig stays the one of P); an `alpha` recomputes it from the pose R and P
/// imply. KITTI's raw file with K_0i D_0i R_rect_0i is raw too, with S_rect's size.
#[tokio::test]
async fn ros_and_kitti_raw_files_describe_raw_cameras() {
    let app = spawn_app().await;
    // The project's copies of the shared reference files.
    let read = |name: &str| {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/calibration")
            .join(name);
        std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    };
    let (left, right) = (read("ros_left.yaml"), read("ros_right.yaml"));
    let body = ok_json(
        app.post("/calibration", &json!({"text": left, "right_text": right}))
            .await,
    )
    .await;
    assert_eq!(body["raw_cameras"], true);
    assert_eq!(body["raw"]["rectification_source"], "file");
    assert_eq!(body["rig"]["focal_length_px"], 700.819);
    let recomputed = ok_json(
        app.post(
            "/calibration",
            &json!({"text": left, "right_text": right, "alpha": 0}),
        )
        .await,
    )
    .await;
    assert_eq!(recomputed["raw"]["rectification_source"], "computed");
    let b = recomputed["rig"]["baseline"].as_f64().unwrap();
    assert!((b - 0.12).abs() < 1e-3, "B {b}");

    let kitti = "S_02: 1.392000e+03 5.120000e+02\n\
        K_02: 9.597910e+02 0.000000e+00 6.960217e+02 0.000000e+00 9.569251e+02 2.241806e+02 0.000000e+00 0.000000e+00 1.000000e+00\n\
        D_02: -3.691481e-01 1.968681e-01 1.353473e-03 5.677587e-04 -6.770705e-02\n\
        R_02: 9.999758e-01 -5.267463e-03 -4.552439e-03 5.251945e-03 9.999804e-01 -3.413835e-03 4.570332e-03 3.389843e-03 9.999838e-01\n\
        T_02: 5.956621e-02 2.900141e-04 2.577209e-03\n\
        S_rect_02: 1.242000e+03 3.750000e+02\n\
        R_rect_02: 9.998817e-01 1.511453e-02 -2.841595e-03 -1.511724e-02 9.998853e-01 -9.338510e-04 2.827154e-03 9.766976e-04 9.999955e-01\n\
        P_rect_02: 7.215377e+02 0.000000e+00 6.095593e+02 4.485728e+01 0.000000e+00 7.215377e+02 1.728540e+02 2.163791e-01 0.000000e+00 0.000000e+00 1.000000e+00 2.745884e-03\n\
        S_03: 1.392000e+03 5.120000e+02\n\
        K_03: 9.037596e+02 0.000000e+00 6.957519e+02 0.000000e+00 9.019653e+02 2.242509e+02 0.000000e+00 0.000000e+00 1.000000e+00\n\
        D_03: -3.639558e-01 1.788651e-01 6.029694e-04 -3.922424e-04 -5.382460e-02\n\
        R_03: 9.995599e-01 1.699522e-02 -2.431313e-02 -1.704422e-02 9.998531e-01 -1.809756e-03 2.427880e-02 2.223358e-03 9.997028e-01\n\
        T_03: -4.731050e-01 5.551470e-03 -5.250882e-03\n\
        S_rect_03: 1.242000e+03 3.750000e+02\n\
        R_rect_03: 9.998321e-01 -7.193136e-03 1.685599e-02 7.232804e-03 9.999712e-01 -2.293585e-03 -1.683901e-02 2.415116e-03 9.998553e-01\n\
        P_rect_03: 7.215377e+02 0.000000e+00 6.095593e+02 -3.395242e+02 0.000000e+00 7.215377e+02 1.728540e+02 2.199936e+00 0.000000e+00 0.000000e+00 1.000000e+00 2.729905e-03\n";
    let body = ok_json(app.post("/calibration", &json!({"text": kitti})).await).await;
    assert_eq!(body["raw_cameras"], true, "{body}");
    assert_eq!(body["raw"]["raw_width"], 1392);
    assert_eq!(body["raw"]["rectified_width"], 1242);
    assert_eq!(body["rig"]["image_width"], 1242);
    assert_eq!(body["raw"]["left"]["D"][0], -0.3691481);
}

/// A file that cannot describe a raw camera is refused by its line: a rotation that is not
/// one, an absurd coefficient, an unknown model, a thin-prism D, and an alpha outside 0–1.
#[tokio::test]
async fn bad_raw_calibrations_are_named() {
    let app = spawn_app().await;
    let pair = raw_pair(Model::PlumbBob);
    let good = stereo_calibrate_yml(&pair);
    let cases: [(String, &str); 4] = [
        (
            intrinsics_yml(&pair, true)
                + &yaml_matrix("R", 3, 3, &[1.01, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])
                + &yaml_matrix("T", 3, 1, &[-60.0, 0.0, 0.0]),
            "not a rotation",
        ),
        (good.replace("-0.22,", "-2200.0,"), "describe no lens"),
        (
            good.replace(
                "%YAML:1.0\n---\n",
                "%YAML:1.0\n---\ndistortionModel: kannala\n",
            ),
            "not a distortion model",
        ),
        (
            good.replace(
                "D1: !!opencv-matrix\n   rows: 1\n   cols: 5",
                "D1: !!opencv-matrix\n   rows: 1\n   cols: 12",
            )
            .replace(
                "-0.0008, 0.0 ]",
                "-0.0008, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0 ]",
            ),
            "thin-prism",
        ),
    ];
    for (text, words) in cases {
        let body = problem(
            app.post(
                "/calibration",
                &json!({"text": text, "calibration_unit": "mm"}),
            )
            .await,
            422,
        )
        .await;
        assert_names(&body, &["text"]);
        assert!(
            message_for(&body, "text").contains(words),
            "{words}: {}",
            message_for(&body, "text")
        );
    }
    let body = problem(
        app.post(
            "/calibration",
            &json!({"text": good, "calibration_unit": "mm", "alpha": 1.5}),
        )
        .await,
        422,
    )
    .await;
    assert_names(&body, &["alpha"]);
}

/// `/rectify`'s bad input, each a 422 naming the part: a rectified-only calibration
/// (Middlebury), a rig part, no calibration, frames of another size (with the scale, and no
/// rig part suggested), an alpha outside 0–1, no right image, and a lone ROS file.
#[tokio::test]
async fn rectify_refuses_what_it_cannot_rectify() {
    let app = spawn_app().await;
    let pair = raw_pair(Model::PlumbBob);
    let yml = stereo_calibrate_yml(&pair);
    let img = grey_png(&vec![100u8; (W * H) as usize]);
    let half = stereo_core::vision::encode::png_grey(
        (W / 2) as usize,
        (H / 2) as usize,
        &vec![100u8; (W * H / 4) as usize],
    );
    let middlebury = "cam0=[300 0 160; 0 300 120; 0 0 1]\ncam1=[300 0 160; 0 300 120; 0 0 1]\n\
                      doffs=0\nbaseline=60\nwidth=320\nheight=240\n";
    let check = |body: &Value, field: &str, words: &str| {
        assert_names(body, &[field]);
        assert!(message_for(body, field).contains(words), "{body}");
    };
    let with = |extra: &[(&str, String)]| form(img.clone(), img.clone(), extra);
    let body = problem(
        rectify(&app, "", with(&[("calibration", middlebury.into())])).await,
        422,
    )
    .await;
    check(&body, "calibration", "describes only rectified");
    let body = problem(
        rectify(
            &app,
            "",
            with(&[(
                "rig",
                json!({"focal_length_px": 300, "baseline": 60}).to_string(),
            )]),
        )
        .await,
        422,
    )
    .await;
    check(&body, "rig", "raw cameras");
    let body = problem(rectify(&app, "", with(&[])).await, 422).await;
    check(&body, "calibration", "is required");
    let body = problem(
        rectify(
            &app,
            "",
            form(
                half.clone(),
                half,
                &[
                    ("calibration", yml.clone()),
                    ("calibration_unit", "mm".into()),
                ],
            ),
        )
        .await,
        422,
    )
    .await;
    check(&body, "calibration", "1/2 of the calibrated size");
    // /rectify takes no rig part, so it does not suggest one.
    assert!(
        !message_for(&body, "calibration").contains("rig part"),
        "{body}"
    );
    let yml2 = yml.clone();
    let body = problem(
        rectify(
            &app,
            "?alpha=1.5",
            with(&[("calibration", yml), ("calibration_unit", "mm".into())]),
        )
        .await,
        422,
    )
    .await;
    check(&body, "alpha", "from 0");
    // Without a right image, the pair (not a "rectified pair") is what is missing.
    let body = problem(
        rectify(
            &app,
            "",
            Form::new()
                .part("left", image_part(img.clone()))
                .text("calibration", yml2.clone()),
        )
        .await,
        422,
    )
    .await;
    assert_eq!(
        message_for(&body, "right"),
        "is required: the right image of the pair (PNG or JPEG)"
    );
    // A lone ROS CameraInfo is told of the form's part for the right camera, not of
    // /calibration's JSON members.
    let ros_left = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/calibration/ros_left.yaml"),
    )
    .expect("the ROS reference file");
    let body = problem(
        rectify(
            &app,
            "",
            with(&[
                ("calibration", ros_left),
                ("calibration_format", "ros".into()),
            ]),
        )
        .await,
        422,
    )
    .await;
    let said = message_for(&body, "right_calibration");
    assert!(said.contains("right camera's CameraInfo"), "{body}");
    assert!(!body.to_string().contains("right_text"), "{body}");
}

/// The synthetic layered scene as raw frames, with the calibration that describes them.
pub(crate) struct RawScene {
    pub(crate) truth: stereo_core::vision::synthetic::Pair,
    pub(crate) raw_left: Vec<u8>,
    pub(crate) raw_right: Vec<u8>,
    pub(crate) yml: String,
    pub(crate) pair: StereoPair,
    pub(crate) r: [Matrix3<f64>; 2],
    pub(crate) p: Matrix3<f64>,
}

/// The synthetic layered scene (160 × 120, rectified, exact truth) made raw through a
/// calibration whose rectification the file gives (R1 R2 P1 P2: the scene's own cameras,
/// f 500, B 100 mm), the raw cameras turned 1.1–1.4° with k1 −0.2.
pub(crate) fn raw_scene() -> RawScene {
    use crate::depth_map::pair as scene_pair;
    let truth = scene_pair();
    let (w, h) = (160usize, 120usize);
    // The rectified cameras: the scene's (f 500, B 100 mm, principal point at the centre).
    let (f, cx, cy, b) = (500.0, (w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0, 100.0);
    let p = Matrix3::new(f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0);
    let r1 = *Rotation3::from_scaled_axis(Vector3::new(0.015, -0.02, 0.008)).matrix();
    let r2 = *Rotation3::from_scaled_axis(Vector3::new(-0.012, 0.025, -0.006)).matrix();
    let camera = |fx: f64, k1: f64| {
        Camera::new(
            Intrinsics {
                fx,
                fy: fx,
                cx: cx + 1.5,
                cy: cy - 1.0,
            },
            Distortion::new(Model::PlumbBob, &[k1, 0.03, 0.0, 0.0, 0.0]).unwrap(),
        )
        .unwrap()
    };
    let (left_cam, right_cam) = (camera(505.0, -0.2), camera(503.0, -0.18));
    // Each raw pixel takes the rectified image where the camera model sends it (bilinear).
    let sample = |rgb: &[u8], x: f64, y: f64| -> [u8; 3] {
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |xi: f64, yi: f64, c: usize| -> f64 {
            let (xi, yi) = (xi.clamp(0.0, w as f64 - 1.0), yi.clamp(0.0, h as f64 - 1.0));
            f64::from(rgb[(yi as usize * w + xi as usize) * 3 + c])
        };
        std::array::from_fn(|c| {
            let v = at(x0, y0, c) * (1.0 - fx) * (1.0 - fy)
                + at(x0 + 1.0, y0, c) * fx * (1.0 - fy)
                + at(x0, y0 + 1.0, c) * (1.0 - fx) * fy
                + at(x0 + 1.0, y0 + 1.0, c) * fx * fy;
            v.round() as u8
        })
    };
    let raw = |cam: &Camera, r: &Matrix3<f64>, rgb: &[u8]| -> Vec<u8> {
        let mut out = Vec::with_capacity(w * h * 3);
        for y in 0..h {
            for x in 0..w {
                let [xr, yr] = cam.undistort_to([x as f64, y as f64], r, &p).unwrap();
                out.extend(sample(rgb, xr, yr));
            }
        }
        out
    };
    let raw_left = raw(&left_cam, &r1, &truth.left_rgb);
    let raw_right = raw(&right_cam, &r2, &truth.right_rgb);
    let pair = StereoPair {
        left: left_cam,
        right: right_cam,
        rotation: Rotation3::from_matrix(&(r2.transpose() * r1)),
        translation: r2.transpose() * Vector3::new(-b, 0.0, 0.0),
    };
    let p2 = [f, 0.0, cx, -f * b, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0];
    let yml = stereo_calibrate_yml(&pair).replace(
        &format!("imageSize: [ {W}, {H} ]"),
        &format!("imageSize: [ {w}, {h} ]"),
    ) + &yaml_matrix("R1", 3, 3, &rows(&r1))
        + &yaml_matrix("R2", 3, 3, &rows(&r2))
        + &yaml_matrix(
            "P1",
            3,
            4,
            &[f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
        )
        + &yaml_matrix("P2", 3, 4, &p2);
    RawScene {
        truth,
        raw_left,
        raw_right,
        yml,
        pair,
        r: [r1, r2],
        p,
    }
}

/// The synthetic layered scene (160 × 120, rectified, exact truth) made raw through a
/// calibration whose rectification the file gives (R1 R2 P1 P2: the scene's own cameras):
/// `/depth-map` with the default `rectify=auto` rectifies it, says so, and finds the scene's
/// disparities (median within 0.5 px of the rectified pair's, more than half the pixels
/// valid); `rectify=no` on the same raw frames matches far fewer and
/// warns;
/// `rectify=yes` with a Middlebury file names what is missing; the σ beside a raw
/// calibration keeps it rectifying.
#[tokio::test]
async fn depth_map_rectifies_raw_frames() {
    use crate::depth_map::rig as scene_rig;
    let app = spawn_app().await;
    let RawScene {
        truth,
        raw_left,
        raw_right,
        yml,
        ..
    } = raw_scene();
    let (w, h, f) = (160usize, 120usize, 500.0);
    let png = |rgb: &[u8]| stereo_core::vision::encode::png_rgb(w, h, rgb);
    let send = |query: &str, left: Vec<u8>, right: Vec<u8>, extra: Vec<(&'static str, String)>| {
        let form = form(left, right, &extra);
        let query = query.to_owned();
        let app = &app;
        async move { app.post_form(&format!("/depth-map{query}"), form).await }
    };
    let calibration = vec![
        ("calibration", yml.clone()),
        ("calibration_unit", "mm".to_owned()),
    ];
    let rectified = ok_json(
        send(
            "?max_disparity=48",
            png(&truth.left_rgb),
            png(&truth.right_rgb),
            vec![("rig", scene_rig().to_string())],
        )
        .await,
    )
    .await;
    let from_raw = ok_json(
        send(
            "?max_disparity=48",
            png(&raw_left),
            png(&raw_right),
            calibration.clone(),
        )
        .await,
    )
    .await;
    assert_eq!(from_raw["rectified"], true, "{from_raw}");
    assert_eq!(from_raw["width"], w);
    assert!(
        from_raw["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("rectified first")),
        "{from_raw}"
    );
    let valid = |b: &Value| b["valid_fraction"].as_f64().unwrap();
    let median = |b: &Value| b["disparity_px"]["median"].as_f64().unwrap();
    // The raw cameras, turned 1.1–1.4° and distorted, do not see the whole rectified view:
    // fewer pixels have a match, but those that do agree with the rectified pair's.
    assert!(valid(&from_raw) > 0.5, "{from_raw}");
    assert!(
        (median(&from_raw) - median(&rectified)).abs() < 0.5,
        "raw {} vs rectified {}",
        median(&from_raw),
        median(&rectified)
    );
    let f_rig = from_raw["rig"]["focal_length_px"].as_f64().unwrap();
    assert!((f_rig - f).abs() < 1e-9);

    // The calibration's σ beside its file is still a calibration of raw cameras: rectified
    // when asked, the σ carried (it once counted as a rig's members, and was refused).
    let mut with_std = calibration.clone();
    with_std.push(("rig", r#"{"focal_length_std_px": 1.5}"#.to_owned()));
    let with_std = ok_json(
        send(
            "?max_disparity=48&rectify=yes",
            png(&raw_left),
            png(&raw_right),
            with_std,
        )
        .await,
    )
    .await;
    assert_eq!(with_std["rectified"], true, "{with_std}");
    assert_eq!(with_std["rig"]["focal_length_std_px"], 1.5, "{with_std}");
    assert_eq!(with_std["valid_fraction"], from_raw["valid_fraction"]);

    let unrectified = ok_json(
        send(
            "?max_disparity=48&rectify=no",
            png(&raw_left),
            png(&raw_right),
            calibration.clone(),
        )
        .await,
    )
    .await;
    assert_eq!(unrectified["rectified"], false);
    assert!(
        valid(&unrectified) < valid(&from_raw) - 0.1,
        "{unrectified}"
    );
    assert!(
        unrectified["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("need rectifying")),
        "{unrectified}"
    );

    let middlebury = "cam0=[500 0 79.5; 0 500 59.5; 0 0 1]\ncam1=[500 0 79.5; 0 500 59.5; 0 0 1]\n\
                      doffs=0\nbaseline=100\nwidth=160\nheight=120\n";
    let body = problem(
        send(
            "?rectify=yes",
            png(&raw_left),
            png(&raw_right),
            vec![("calibration", middlebury.to_owned())],
        )
        .await,
        422,
    )
    .await;
    assert_names(&body, &["calibration"]);
    assert!(message_for(&body, "calibration").contains("K and D"));
}

/// `/match` on the raw frames of the layered scene: points clicked on the raw left frame are
/// matched where they land in the rectified image (`x_rectified`, `y_rectified` to 1e-6 px),
/// their disparities are the scene's within 0.5 px, and `x_right_raw`, `y_right_raw` is the
/// raw right pixel that the camera model takes to the rectified match (within 1e-3 px).
#[tokio::test]
async fn match_takes_points_on_the_raw_frame() {
    let app = spawn_app().await;
    let scene = raw_scene();
    let (w, h) = (160usize, 120usize);
    let [r1, r2] = scene.r;
    let k_inv = scene.p.try_inverse().unwrap();
    // Rectified points where the scene is visible and flat, taken back to the raw frame.
    let rect_points = [(60.0, 50.0), (100.0, 70.0), (80.0, 40.0), (120.0, 90.0)];
    let raw_points: Vec<[f64; 2]> = rect_points
        .iter()
        .map(|&(x, y)| {
            let ray = r1.transpose() * (k_inv * Vector3::new(x, y, 1.0));
            scene.pair.left.project(&ray).unwrap()
        })
        .collect();
    let points: Vec<Value> = raw_points
        .iter()
        .map(|[x, y]| json!({"x": x, "y": y}))
        .collect();
    let png = |rgb: &[u8]| stereo_core::vision::encode::png_rgb(w, h, rgb);
    let response = app
        .post_form(
            "/match?max_disparity=48",
            form(
                png(&scene.raw_left),
                png(&scene.raw_right),
                &[
                    ("calibration", scene.yml.clone()),
                    ("calibration_unit", "mm".into()),
                    ("points", Value::from(points).to_string()),
                ],
            ),
        )
        .await;
    let body = ok_json(response).await;
    assert_eq!(body["rectified"], true, "{body}");
    let mut ok = 0;
    for (i, m) in body["matches"].as_array().unwrap().iter().enumerate() {
        let (xr, yr) = rect_points[i];
        assert!(
            (m["x"].as_f64().unwrap() - raw_points[i][0]).abs() < 1e-9,
            "{m}"
        );
        assert!(
            (m["x_rectified"].as_f64().unwrap() - xr).abs() < 1e-3,
            "{m}"
        );
        assert!(
            (m["y_rectified"].as_f64().unwrap() - yr).abs() < 1e-3,
            "{m}"
        );
        if m["status"] != "ok" {
            continue;
        }
        ok += 1;
        let truth = f64::from(scene.truth.truth[yr as usize * w + xr as usize]);
        let d = m["disparity_px"].as_f64().unwrap();
        assert!((d - truth).abs() < 0.5, "point {i}: {d} vs {truth}");
        let (u, v) = (
            m["x_right_raw"].as_f64().unwrap(),
            m["y_right_raw"].as_f64().unwrap(),
        );
        let back = scene
            .pair
            .right
            .undistort_to([u, v], &r2, &scene.p)
            .unwrap();
        let x_right = m["x_right"].as_f64().unwrap();
        assert!(
            (back[0] - x_right).abs() < 1e-2 && (back[1] - yr).abs() < 1e-2,
            "point {i}: raw ({u}, {v}) goes back to {back:?}, not ({x_right}, {yr})"
        );
    }
    assert!(ok >= 3, "{body}");
}

/// Pairs sent as rectified whose right image sits rows lower (a rig whose rows do not line
/// up): 3 rows on a 320 × 240 pair, and 17 on a 480 × 360 one (found through the row check's
/// pyramid, as raw frames tens of rows apart are). `/depth-map`'s summary and `/match` (which
/// matches only the rows its point needs, so has no share of matched pixels to judge by) warn
/// that the matched corners lie that many px (±0.3) off their rows and that the frames need
/// rectifying; the same scenes with their rows in line get no such warning from either.
#[tokio::test]
async fn rows_that_do_not_line_up_are_warned() {
    use stereo_core::vision::synthetic;
    let app = spawn_app().await;
    for (w, h, shift) in [(320usize, 240usize, 3usize), (480, 360, 17)] {
        let scene = synthetic::render(&synthetic::layered(w, h));
        // The right image moved down by `shift` rows (the top rows repeat the first).
        let mut lowered = scene.right_rgb.clone();
        for y in 0..h {
            let from = y.saturating_sub(shift);
            lowered[y * w * 3..(y + 1) * w * 3]
                .copy_from_slice(&scene.right_rgb[from * w * 3..(from + 1) * w * 3]);
        }
        let png = |rgb: &[u8]| stereo_core::vision::encode::png_rgb(w, h, rgb);
        let rig = json!({"focal_length_px": 500, "baseline": 100, "unit": "mm"}).to_string();
        let warning = |body: &Value| -> Option<String> {
            body["warnings"]
                .as_array()
                .unwrap()
                .iter()
                .filter_map(Value::as_str)
                .find(|w| w.contains("off their rows"))
                .map(str::to_owned)
        };
        for (right, lowered) in [(&scene.right_rgb, false), (&lowered, true)] {
            let parts = [("rig", rig.clone())];
            let depth = ok_json(
                app.post_form(
                    "/depth-map?max_disparity=48",
                    form(png(&scene.left_rgb), png(right), &parts),
                )
                .await,
            )
            .await;
            let parts = [
                ("rig", rig.clone()),
                ("points", json!([{"x": w / 2, "y": h / 2}]).to_string()),
            ];
            let matched = ok_json(
                app.post_form(
                    "/match?max_disparity=48",
                    form(png(&scene.left_rgb), png(right), &parts),
                )
                .await,
            )
            .await;
            for body in [&depth, &matched] {
                assert_eq!(body["rectified"], false);
                match (lowered, warning(body)) {
                    (false, found) => assert_eq!(found, None, "{body}"),
                    (true, Some(text)) => {
                        // "matched corners lie 3.0 px off their rows (the median of N; …"
                        let at = text.find("corners lie ").unwrap() + "corners lie ".len();
                        let px: f64 = text[at..].split(' ').next().unwrap().parse().unwrap();
                        assert!((px - shift as f64).abs() <= 0.3, "{w}x{h}: {text}");
                        assert!(text.contains("need rectifying"), "{text}");
                    }
                    (true, None) => panic!("{w}x{h}: no row warning: {body}"),
                }
            }
        }
    }
}

/// A raw pair sent with its calibration is matched without a word about its cameras; sent
/// swapped (the right camera's frame as left), `/depth-map` says "left and right look
/// swapped", where it used to answer a sparse map silently.
#[tokio::test]
async fn a_raw_pair_sent_swapped_is_named() {
    let app = spawn_app().await;
    let ([left, right], yml) = rendered(Model::PlumbBob);
    let said = |body: &serde_json::Value| {
        body["warnings"]
            .to_string()
            .contains("left and right look swapped")
    };
    let sent = ok_json(
        app.post_form("/depth-map", raw_form(&left, &right, &yml))
            .await,
    )
    .await;
    assert!(!said(&sent), "{sent}");
    let swapped = ok_json(
        app.post_form("/depth-map", raw_form(&right, &left, &yml))
            .await,
    )
    .await;
    assert!(said(&swapped), "{swapped}");
}
