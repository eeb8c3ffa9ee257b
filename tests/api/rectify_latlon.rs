//! `POST /rectify?projection=latlon` over a real socket: a 180° fisheye pair (whose pinhole
//! rectification no plane holds) rectified to latitude-longitude as mrcal does, its summary's
//! system rectifying points at every angle onto one row, its maps and images checked against
//! frames rendered through the lenses, and every option that does not apply named.

use nalgebra::Vector3;
use serde_json::Value;
use stereo_core::camera::Model;
use stereo_core::camera::synthetic::fisheye_180;

use crate::depth_map::{npy_of, npz_entries};
use crate::helpers::{assert_names, message_for, numbers, ok_json, problem, spawn_app};
use crate::raw_files::{DISPARITY, H, W, rendered, scene, stereo_calibrate_yml};
use crate::rectify::{raw_form, raw_pair, rectify};

fn matrix(v: &Value) -> nalgebra::Matrix3<f64> {
    nalgebra::Matrix3::from_row_slice(&numbers(v))
}

/// A 180° fisheye pair's calibration is read and rectified to latlon: the field chosen is
/// the whole 180° across, the resolution the lens's own (f px per radian); points at every
/// angle and at 0.3, 2 and 30 m land on one row in both rectified cameras through the
/// summary's system, and the range from their disparity is their distance from the left
/// camera (to 1e-9). The pinhole plane of the same file is rectified too, not refused.
#[tokio::test]
async fn a_180_degree_fisheye_rectifies_to_latlon_rows() {
    let app = spawn_app().await;
    let pair = fisheye_180();
    let yml = stereo_calibrate_yml(&pair);
    let grey = vec![128u8; (W * H) as usize];
    let form = || raw_form(&grey, &grey, &yml);
    let pinhole = ok_json(rectify(&app, "", form()).await).await;
    assert_eq!(pinhole["projection"], "pinhole");
    assert!(pinhole.get("latlon").is_none(), "{pinhole}");

    let summary = ok_json(rectify(&app, "?projection=latlon", form()).await).await;
    assert_eq!(summary["projection"], "latlon");
    let s = &summary["latlon"];
    let number = |k: &str| s[k].as_f64().unwrap();
    assert!(
        number("az_fov_deg") > 175.0 && number("az_fov_deg") <= 180.0,
        "{s}"
    );
    assert!(number("el_fov_deg") > 120.0, "{s}");
    let f = f64::from(W) / std::f64::consts::PI;
    assert!((number("fx") / f - 1.0).abs() < 0.02, "{s}");
    assert_eq!(s["unit"], "mm");
    assert!((number("baseline") - pair.translation.norm()).abs() < 1e-9);
    let (r1, r2) = (matrix(&s["r1"]), matrix(&s["r2"]));
    let (fx, fy, cx, cy) = (number("fx"), number("fy"), number("cx"), number("cy"));
    let pixel = |ray: Vector3<f64>| {
        let az = ray.x.atan2(ray.y.hypot(ray.z));
        let el = ray.y.atan2(ray.z);
        [fx * az + cx, fy * el + cy]
    };
    let mut seen = 0;
    for az in (-85..=85).step_by(17) {
        for el in (-60..=60).step_by(15) {
            for metres in [0.3, 2.0, 30.0] {
                let (a, e) = (f64::from(az).to_radians(), f64::from(el).to_radians());
                let ray = Vector3::new(a.sin(), a.cos() * e.sin(), a.cos() * e.cos());
                let p_left = r1.transpose() * ray * metres * 1000.0;
                let p_right = pair.rotation * p_left + pair.translation;
                let (l, r) = (pixel(r1 * p_left), pixel(r2 * p_right));
                assert!((l[1] - r[1]).abs() < 1e-9, "az {az} el {el}: {l:?} {r:?}");
                let (angle, azimuth) = ((l[0] - r[0]) / fx, (l[0] - cx) / fx);
                let range = number("baseline") * (azimuth - angle).cos() / angle.sin();
                assert!((range / p_left.norm() - 1.0).abs() < 1e-9, "{range}");
                seen += 1;
            }
        }
    }
    assert_eq!(seen, 11 * 9 * 3);
}

/// The maps and the rectified images of a rendered 180° pair: `maps.npz` has the summary's
/// size and takes each rectified pixel to the raw pixel the engine's own latlon system
/// (`stereo_core::camera::Latlon`, mrcal's construction) gives; `left.png` and `right.png`
/// are the scene laid over the rectified images within 2 grey levels on average where the
/// raw frames see; over 75 % of the rectified image is seen (the field is the box of azimuth
/// and elevation around all both cameras see, so a fisheye's round edge leaves corners).
#[tokio::test]
async fn latlon_maps_and_images_are_the_scene() {
    let app = spawn_app().await;
    let (pair, system, [left, right], yml) = rendered();
    let form = || raw_form(&left, &right, &yml);
    let summary = ok_json(rectify(&app, "?projection=latlon", form()).await).await;
    let (w, h) = (system.size.width, system.size.height);
    assert_eq!(
        (summary["width"].as_u64(), summary["height"].as_u64()),
        (Some(w.into()), Some(h.into()))
    );
    assert!(
        summary["valid_fraction"]["left"].as_f64().unwrap() > 0.75,
        "{summary}"
    );

    let npz = rectify(&app, "?projection=latlon&output=maps.npz", form()).await;
    assert_eq!(npz.status(), 200);
    let entries = npz_entries(&npz.bytes().await.unwrap());
    let shape = (h as usize, w as usize);
    let (mx, my) = (npy_of(&entries[0].1, shape), npy_of(&entries[1].1, shape));
    assert_eq!(mx.len(), (w * h) as usize);
    for (x, y) in [
        (w / 2, h / 2),
        (w / 20, h / 2),
        (w - w / 20, h / 3),
        (w / 3, h / 10),
    ] {
        let i = (y * w + x) as usize;
        let ray = system.r1.transpose() * system.ray([f64::from(x), f64::from(y)]);
        let raw = pair.left.pixel_of_ray(&ray).unwrap();
        assert!(
            (f64::from(mx[i]) - raw[0]).abs() < 1e-3 && (f64::from(my[i]) - raw[1]).abs() < 1e-3,
            "({x}, {y}): {}, {} against {raw:?}",
            mx[i],
            my[i]
        );
    }

    // The right image at x shows what the left sees at x + d.
    for (side, shift) in [("left", 0.0), ("right", -DISPARITY)] {
        let png = rectify(
            &app,
            &format!("?projection=latlon&output={side}.png"),
            form(),
        )
        .await;
        assert_eq!(png.status(), 200);
        let image = image::load_from_memory(&png.bytes().await.unwrap())
            .unwrap()
            .into_luma8();
        assert_eq!(image.dimensions(), (w, h));
        let (mut sum, mut n) = (0.0, 0usize);
        // Inside the field both frames see, away from its edges (where a raw pixel spans
        // many rectified ones) and from the scene's shift.
        for y in h / 8..h - h / 8 {
            for x in w / 8..w - w / 8 {
                let got = f64::from(image.get_pixel(x, y).0[0]);
                sum += (got - scene(f64::from(x) - shift, f64::from(y)).round()).abs();
                n += 1;
            }
        }
        let mean = sum / n as f64;
        assert!(mean < 2.0, "{side}: {mean} grey levels off on average");
    }
}

/// Options that do not apply are named: `alpha` with latlon, a field or resolution with the
/// pinhole plane; a field past 180°, a resolution that is not positive, and one that would
/// make the rectified image too large, each by its name.
#[tokio::test]
async fn latlon_options_are_named() {
    let app = spawn_app().await;
    let pair = fisheye_180();
    let yml = stereo_calibrate_yml(&pair);
    let grey = vec![128u8; (W * H) as usize];
    let form = || raw_form(&grey, &grey, &yml);
    for (query, field, says) in [
        (
            "?projection=latlon&alpha=0.5",
            "alpha",
            "projection=pinhole",
        ),
        ("?az_fov=120", "az_fov", "projection=latlon"),
        (
            "?pixels_per_degree=3",
            "pixels_per_degree",
            "projection=latlon",
        ),
        ("?projection=latlon&az_fov=200", "az_fov", "at most 180"),
        ("?projection=latlon&el_fov=0", "el_fov", "over 0"),
        (
            "?projection=latlon&pixels_per_degree=-2",
            "pixels_per_degree",
            "positive",
        ),
        (
            "?projection=latlon&pixels_per_degree=40",
            "pixels_per_degree",
            "the rectified image would be 70",
        ),
        (
            "?projection=sphere",
            "projection",
            "must be one of pinhole, latlon, auto",
        ),
    ] {
        let body = problem(rectify(&app, query, form()).await, 422).await;
        assert_names(&body, &[field]);
        let message = message_for(&body, field);
        assert!(message.contains(says), "{query}: {message}");
    }
}

/// `projection=auto` rectifies the 180° fisheye to latlon and a 56° plumb-bob rig on the
/// pinhole plane, each answer saying which; with `alpha` the fisheye stays on the pinhole plane,
/// as it does for `/depth-map`'s ROS outputs (answered, not refused as with latlon).
#[tokio::test]
async fn auto_picks_latlon_for_wide_lenses_only() {
    let app = spawn_app().await;
    let grey = vec![128u8; (W * H) as usize];
    let wide = stereo_calibrate_yml(&fisheye_180());
    let narrow = stereo_calibrate_yml(&raw_pair(Model::PlumbBob));
    for (yml, query, want) in [
        (&wide, "?projection=auto", "latlon"),
        (&narrow, "?projection=auto", "pinhole"),
        (&wide, "?projection=auto&alpha=0", "pinhole"),
    ] {
        let summary = ok_json(rectify(&app, query, raw_form(&grey, &grey, yml)).await).await;
        assert_eq!(summary["projection"], want, "{query}: {summary}");
    }
    for (query, want) in [
        ("/depth-map?projection=auto&max_disparity=16", "latlon"),
        (
            "/depth-map?projection=auto&max_disparity=16&output=depth.cdr",
            "pinhole",
        ),
    ] {
        let answer = app.post_form(query, raw_form(&grey, &grey, &wide)).await;
        assert_eq!(answer.status(), 200, "{query}");
        assert_eq!(answer.headers()["stereo-projection"], want, "{query}");
    }
}

/// `/depth-map?projection=latlon` on the rendered 180° pair: the map is the latlon system's
/// size, says `projection: latlon` with the system, its disparities are the scene's 6 px,
/// and `depth.npy` is each pixel's range from mrcal's formula, B·cos(az − d/fx)/sin(d/fx),
/// times cos(az)·cos(el), within 0.5 % over the middle of the field; the files say latlon; the
/// pair sent swapped is named so.
#[tokio::test]
async fn depth_map_in_latlon() {
    let app = spawn_app().await;
    let (_, system, [left, right], yml) = rendered();
    let form = || raw_form(&left, &right, &yml);
    let post = |query: &'static str| app.post_form(query, form());
    let summary = ok_json(post("/depth-map?projection=latlon&max_disparity=32").await).await;
    assert_eq!(summary["projection"], "latlon");
    assert_eq!(summary["rectified"], true);
    assert_eq!(summary["width"].as_u64(), Some(system.size.width.into()));
    assert!((summary["latlon"]["fx"].as_f64().unwrap() / system.fx - 1.0).abs() < 1e-6);
    let median = summary["disparity_px"]["median"].as_f64().unwrap();
    assert!((median - DISPARITY).abs() < 0.1, "{summary}");

    let npy = post("/depth-map?projection=latlon&max_disparity=32&output=depth.npy").await;
    assert_eq!(npy.status(), 200);
    assert_eq!(npy.headers()["stereo-projection"], "latlon");
    let (w, h) = (system.size.width as usize, system.size.height as usize);
    let depth = npy_of(&npy.bytes().await.unwrap(), (h, w));
    assert_eq!(depth.len(), w * h);
    let (mut checked, mut off) = (0, Vec::new());
    for y in (h / 4..3 * h / 4).step_by(7) {
        for x in (w / 4..3 * w / 4).step_by(7) {
            let z = f64::from(depth[y * w + x]);
            if z.is_nan() {
                continue;
            }
            let az = (x as f64 - system.cx) / system.fx;
            let el = (y as f64 - system.cy) / system.fy;
            let angle = DISPARITY / system.fx;
            let range = system.baseline * (az - angle).cos() / angle.sin();
            off.push((z / (range * az.cos() * el.cos()) - 1.0).abs());
            checked += 1;
        }
    }
    off.sort_by(f64::total_cmp);
    assert!(checked > 200, "{checked}");
    assert!(off[off.len() / 2] < 0.005, "median {}", off[off.len() / 2]);

    // The files that can say their projection say it: the PLY in a comment with the system,
    // the NPZ in `projection` and `latlon` (f_az, f_el, cx, cy).
    let ply = post("/depth-map?projection=latlon&max_disparity=32&output=points.ply").await;
    let ply = ply.bytes().await.unwrap();
    let head = String::from_utf8_lossy(&ply[..ply.len().min(1024)]).into_owned();
    assert!(
        head.contains("comment projection latlon: pixel (x, y) is azimuth (x - "),
        "{head}"
    );
    let npz = post("/depth-map?projection=latlon&max_disparity=32&output=arrays.npz").await;
    let entries = npz_entries(&npz.bytes().await.unwrap());
    let entry = |name: &str| &entries.iter().find(|(n, _)| n == name).unwrap().1;
    let text = entry("projection.npy");
    let data = &text[text.len() - 24..];
    let chars: Vec<u8> = data.chunks(4).map(|c| c[0]).collect();
    assert_eq!(chars, b"latlon");
    let system_npy = entry("latlon.npy");
    let values: Vec<f64> = system_npy[system_npy.len() - 32..]
        .chunks(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    for (got, want) in values
        .iter()
        .zip([system.fx, system.fy, system.cx, system.cy])
    {
        assert!(
            (got - want).abs() < 1e-6 * want.abs().max(1.0),
            "{values:?}"
        );
    }

    // Sent the other way round, at the defaults, the cameras are named swapped.
    let swapped = app
        .post_form(
            "/depth-map?projection=latlon",
            raw_form(&right, &left, &yml),
        )
        .await;
    let warnings = ok_json(swapped).await["warnings"].to_string();
    assert!(warnings.contains("look swapped"), "{warnings}");
}

/// What latlon cannot do with `/depth-map` is named: the ROS messages (a pinhole
/// rectification's), a pair matched as sent, `alpha` beside it, its options without it.
#[tokio::test]
async fn depth_map_latlon_refusals_are_named() {
    let app = spawn_app().await;
    let pair = fisheye_180();
    let yml = stereo_calibrate_yml(&pair);
    let grey = vec![128u8; (W * H) as usize];
    for (query, field, says) in [
        (
            "?projection=latlon&output=depth.cdr",
            "output",
            "pinhole rectification",
        ),
        (
            "?projection=latlon&rectify=no",
            "projection",
            "rectified here",
        ),
        ("?projection=latlon&alpha=0", "alpha", "projection=pinhole"),
        ("?el_fov=90", "el_fov", "projection=latlon"),
    ] {
        let body = problem(
            app.post_form(&format!("/depth-map{query}"), raw_form(&grey, &grey, &yml))
                .await,
            422,
        )
        .await;
        assert_names(&body, &[field]);
        let message = message_for(&body, field);
        assert!(message.contains(says), "{query}: {message}");
    }
}

/// The median of a map's finite values.
fn median(values: &[f32]) -> f64 {
    let mut v: Vec<f32> = values.iter().copied().filter(|d| d.is_finite()).collect();
    assert!(!v.is_empty(), "no finite value");
    v.sort_by(f32::total_cmp);
    f64::from(v[v.len() / 2])
}

/// `/depth-stream` with `options.projection=latlon` on the rendered 180° pair: each frame is
/// matched in the latlon system (its size, `projection: latlon`, the scene's 6 px); `auto`
/// gives way to the pinhole plane for a ROS output, and what latlon cannot do is named under
/// `options.` or the output's index.
#[tokio::test]
async fn a_stream_matches_in_latlon() {
    use crate::depth_stream::{binary, open_with, pair_frame, text};
    use crate::helpers::fields;
    use crate::rectify::grey_png;
    use futures_util::SinkExt;
    use tokio_tungstenite::tungstenite::Message;
    let app = spawn_app().await;
    let (_, system, [left, right], yml) = rendered();
    let settings = |options: Value, outputs: Value| {
        serde_json::json!({"layout": "pair", "calibration": yml, "calibration_unit": "mm",
            "options": options, "outputs": outputs, "temporal": false})
    };
    let options = serde_json::json!({"projection": "latlon", "max_disparity": 32});
    let (mut socket, resolved) = open_with(
        &app,
        settings(options, serde_json::json!(["disparity.npy"])),
    )
    .await;
    assert_eq!(resolved["type"], "settings", "{resolved}");
    let frame = pair_frame(&grey_png(&left), &grey_png(&right));
    socket.send(Message::binary(frame)).await.unwrap();
    let answer = text(&mut socket).await;
    assert_eq!(answer["type"], "frame", "{answer}");
    assert_eq!(answer["summary"]["projection"], "latlon", "{answer}");
    let (w, h) = (system.size.width as usize, system.size.height as usize);
    assert_eq!(answer["summary"]["width"].as_u64(), Some(w as u64));
    let disparity = npy_of(&binary(&mut socket).await, (h, w));
    assert!((median(&disparity) - DISPARITY).abs() < 0.1);
    socket.close(None).await.unwrap();

    let auto = serde_json::json!({"projection": "auto", "max_disparity": 32});
    let (_, resolved) = open_with(&app, settings(auto, serde_json::json!(["depth.cdr"]))).await;
    assert_eq!(resolved["type"], "settings", "{resolved}");
    for (options, outputs, field) in [
        (
            serde_json::json!({"projection": "latlon"}),
            serde_json::json!(["disparity.npy", "depth.cdr"]),
            "outputs[1]",
        ),
        (
            serde_json::json!({"projection": "latlon", "rectify": "no"}),
            serde_json::json!([]),
            "options.projection",
        ),
        (
            serde_json::json!({"projection": "latlon", "alpha": 0}),
            serde_json::json!([]),
            "options.alpha",
        ),
        (
            serde_json::json!({"el_fov": 90}),
            serde_json::json!([]),
            "options.el_fov",
        ),
    ] {
        let (_, answer) = open_with(&app, settings(options.clone(), outputs)).await;
        assert_eq!(answer["type"], "error", "{options}: {answer}");
        assert_eq!(fields(&answer["problem"]), [field], "{options}: {answer}");
    }
}

/// The `depth-map` command with `--projection latlon` writes maps of the latlon system's size
/// whose disparities are the rendered scene's; `auto` sees the 180° lenses as wide; an .mcap
/// `--out` (ROS images, pinhole) refuses latlon before a frame is read.
#[test]
fn the_command_matches_in_latlon() {
    use crate::recording::command;
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("recording-latlon");
    let _ = std::fs::remove_dir_all(&dir);
    let (pair, system, [left, right], _) = rendered();
    for (side, image) in [("left", &left), ("right", &right)] {
        std::fs::create_dir_all(dir.join(side)).unwrap();
        std::fs::write(
            dir.join(side).join("0001.png"),
            crate::rectify::grey_png(image),
        )
        .unwrap();
    }
    let calibration = dir.join("calib.yml");
    std::fs::write(&calibration, stereo_calibrate_yml(&pair)).unwrap();
    let (w, h) = (system.size.width as usize, system.size.height as usize);
    for projection in ["latlon", "auto"] {
        let out = format!("out-{projection}");
        let args = [
            "--calibration",
            calibration.to_str().unwrap(),
            "--calibration-unit",
            "mm",
            "--output",
            "disparity.npy",
            "--max-disparity",
            "32",
            "--projection",
            projection,
        ];
        let run = command(&dir, &out, &args).output().unwrap();
        let said = String::from_utf8_lossy(&run.stderr).into_owned();
        assert_eq!(run.status.code(), Some(0), "{said}");
        let bytes = std::fs::read(dir.join(&out).join("0001.disparity.npy")).unwrap();
        let disparity = npy_of(&bytes, (h, w));
        assert!((median(&disparity) - DISPARITY).abs() < 0.1, "{projection}");
    }
    let args = [
        "--calibration",
        calibration.to_str().unwrap(),
        "--calibration-unit",
        "mm",
        "--projection",
        "latlon",
    ];
    let run = command(&dir, "out.mcap", &args).output().unwrap();
    let said = String::from_utf8_lossy(&run.stderr).into_owned();
    assert_ne!(run.status.code(), Some(0), "{said}");
    assert!(
        said.contains("--projection: latlon cannot be written to an .mcap --out"),
        "{said}"
    );
    assert!(!dir.join("out.mcap").exists());
}

/// `/match?projection=latlon` on the rendered 180° pair: points clicked on the raw left frame,
/// from the centre to 60° off it, land where their rays fall in the latlon system
/// (`x_rectified`), match the scene's 6 px, and their `range` is mrcal's `stereo_range` along
/// the ray and `distance` its component along the rectified axis; each match's raw right
/// pixel is where the right lens sees the matched ray. `auto` matches there too; a range that
/// stops short of the scene answers every point `out_of_range`.
#[tokio::test]
async fn match_in_latlon() {
    let app = spawn_app().await;
    let (pair, system, [left, right], yml) = rendered();
    let (w, h) = (f64::from(system.size.width), f64::from(system.size.height));
    // Latlon pixels from the centre out to 60° of azimuth each way, and up and down.
    let degrees = system.fx.to_radians();
    let wanted: Vec<[f64; 2]> = [(0.0, 0.0), (-60.0, 0.0), (45.0, 10.0), (20.0, -30.0)]
        .iter()
        .map(|&(az, el)| [system.cx + az * degrees, system.cy + el * degrees])
        .filter(|&[u, v]| u > 40.0 && u < w - 40.0 && v > 20.0 && v < h - 20.0)
        .collect();
    assert_eq!(wanted.len(), 4, "{wanted:?} in {w} × {h}");
    let raw: Vec<Value> = wanted
        .iter()
        .map(|&p| {
            let ray = system.r1.transpose() * system.ray(p);
            let [x, y] = pair.left.project(&ray).unwrap();
            serde_json::json!({"x": x, "y": y})
        })
        .collect();
    let points = serde_json::to_string(&raw).unwrap();
    // A box of 40 px around the centre's raw pixel.
    let (cx, cy) = (raw[0]["x"].as_f64().unwrap(), raw[0]["y"].as_f64().unwrap());
    let boxed = serde_json::json!([{"x": cx - 20.0, "y": cy - 20.0, "width": 40, "height": 40}]);
    for projection in ["latlon", "auto"] {
        let form = raw_form(&left, &right, &yml)
            .text("points", points.clone())
            .text("regions", boxed.to_string());
        let query = format!("/match?projection={projection}&max_disparity=32");
        let answer = ok_json(app.post_form(&query, form).await).await;
        assert_eq!(answer["projection"], "latlon", "{answer}");
        assert_eq!(answer["rectified"], true);
        assert!((answer["latlon"]["fx"].as_f64().unwrap() / system.fx - 1.0).abs() < 1e-6);
        for (m, &[u, v]) in answer["matches"].as_array().unwrap().iter().zip(&wanted) {
            assert_eq!(m["status"], "ok", "{m}");
            let got = |k: &str| m[k].as_f64().unwrap_or_else(|| panic!("{k} in {m}"));
            assert!((got("x_rectified") - u).abs() < 0.01, "{m}");
            assert!((got("y_rectified") - v).abs() < 0.01, "{m}");
            let d = got("disparity_px");
            assert!((d - DISPARITY).abs() < 0.15, "{m}");
            let (az, el) = ((u - system.cx) / system.fx, (v - system.cy) / system.fy);
            let angle = d / system.fx;
            let range = system.baseline * (az - angle).cos() / angle.sin();
            assert!((got("range") / range - 1.0).abs() < 1e-3, "{m}: {range}");
            let depth = range * az.cos() * el.cos();
            assert!((got("distance") / depth - 1.0).abs() < 1e-3, "{m}: {depth}");
            assert!(got("distance_std") > 0.0, "{m}");
            let seen = system.r2.transpose() * system.ray([u - d, v]);
            let [xr, yr] = pair.right.project(&seen).unwrap();
            assert!((got("x_right_raw") - xr).abs() < 1e-3, "{m}: {xr}");
            assert!((got("y_right_raw") - yr).abs() < 1e-3, "{m}: {yr}");
        }
        // The box's median is the scene's at its centre: 6 px, at the range mrcal gives.
        let region = &answer["regions"][0];
        let d = region["disparity_px"].as_f64().unwrap();
        assert!((d - DISPARITY).abs() < 0.15, "{region}");
        let angle = d / system.fx;
        let [u, v] = wanted[0];
        let (az, el) = ((u - system.cx) / system.fx, (v - system.cy) / system.fy);
        let depth = system.baseline * (az - angle).cos() / angle.sin() * az.cos() * el.cos();
        let distance = region["distance"].as_f64().unwrap();
        assert!((distance / depth - 1.0).abs() < 0.01, "{region}: {depth}");
        let [p10, p90] = ["distance_p10", "distance_p90"].map(|k| region[k].as_f64().unwrap());
        assert!(p10 <= distance && distance <= p90, "{region}");
    }
    // A range that stops short of the scene's 6 px answers no point as matched.
    let form = raw_form(&left, &right, &yml).text("points", points);
    let answer = ok_json(
        app.post_form("/match?projection=latlon&max_disparity=4", form)
            .await,
    )
    .await;
    for m in answer["matches"].as_array().unwrap() {
        assert_eq!(m["status"], "out_of_range", "{m}");
    }
}

/// `output=left_depth.npy`: the latlon map laid back on the raw left frame, of the frame's
/// size; at each raw pixel the depth is the range mrcal's formula gives for the scene's 6 px
/// at the pixel's latlon column, along the left lens's own axis (the ray's z), within 1 % over
/// the middle of the frame; matched on the pinhole plane, the same pixels get the same depths.
#[tokio::test]
async fn depth_in_the_left_cameras_own_pixels() {
    let app = spawn_app().await;
    let (pair, system, [left, right], yml) = rendered();
    let response = app
        .post_form(
            "/depth-map?projection=latlon&max_disparity=32&output=left_depth.npy",
            raw_form(&left, &right, &yml),
        )
        .await;
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["stereo-projection"], "latlon");
    let (w, h) = (W as usize, H as usize);
    let depth = npy_of(&response.bytes().await.unwrap(), (h, w));
    let (mut checked, mut off) = (0, Vec::new());
    for y in (h / 4..3 * h / 4).step_by(5) {
        for x in (w / 4..3 * w / 4).step_by(5) {
            let z = f64::from(depth[y * w + x]);
            if z.is_nan() {
                continue;
            }
            let ray = pair
                .left
                .ray_of_pixel([x as f64, y as f64])
                .unwrap()
                .normalize();
            // mrcal's stereo_range (checked against mrcal itself in the rectification
            // evaluation) at the raw pixel's latlon column.
            let [u, _] = system.pixel(&(system.r1 * ray));
            let range = system.range(u, DISPARITY).unwrap();
            off.push((z / (range * ray.z) - 1.0).abs());
            checked += 1;
        }
    }
    off.sort_by(f64::total_cmp);
    assert!(checked > 200, "{checked}");
    assert!(off[off.len() / 2] < 0.01, "median {}", off[off.len() / 2]);
    let pinhole = app
        .post_form(
            "/depth-map?max_disparity=32&output=left_depth.npy",
            raw_form(&left, &right, &yml),
        )
        .await;
    assert_eq!(pinhole.status(), 200);
    // Matched on the pinhole plane, the same raw pixels get the same depths.
    let flat = npy_of(&pinhole.bytes().await.unwrap(), (h, w));
    let mut ratios: Vec<f64> = flat
        .iter()
        .zip(&depth)
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .map(|(a, b)| (f64::from(*a) / f64::from(*b) - 1.0).abs())
        .collect();
    ratios.sort_by(f64::total_cmp);
    assert!(ratios.len() > w * h / 10, "{} pixels in both", ratios.len());
    assert!(
        ratios[ratios.len() / 2] < 0.02,
        "{}",
        ratios[ratios.len() / 2]
    );
}
