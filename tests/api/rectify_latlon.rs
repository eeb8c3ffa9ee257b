//! `POST /rectify?projection=latlon` over a real socket: a 180° fisheye pair (whose pinhole
//! rectification no plane holds) rectified to latitude-longitude as mrcal does, its summary's
//! system rectifying points at every angle onto one row, its maps and images checked against
//! frames rendered through the lenses, and every option that does not apply named.

use nalgebra::Vector3;
use serde_json::Value;
use stereo_core::camera::synthetic::{FISHEYE_180_SIZE as SIZE, fisheye_180};
use stereo_core::camera::{Latlon, LatlonOptions, Model, StereoPair};

use crate::depth_map::{npy_of, npz_entries};
use crate::helpers::{assert_names, message_for, ok_json, problem, spawn_app};
use crate::rectify::{H, W, raw_form, raw_pair, rectify, scene, stereo_calibrate_yml};

/// A constant latlon disparity of the rendered scene, in pixels.
const DISPARITY: f64 = 6.0;

/// The raw frames of `pair` seeing [`scene`] laid over the latlon rectified images (the right
/// one shifted by [`DISPARITY`]): each raw pixel takes the scene's value where its ray lands
/// in the rectified image.
fn render(pair: &StereoPair, system: &Latlon) -> [Vec<u8>; 2] {
    [
        (&pair.left, &system.r1, 0.0),
        (&pair.right, &system.r2, -DISPARITY),
    ]
    .map(|(camera, rotation, shift)| {
        let mut img = vec![0u8; (W * H) as usize];
        for y in 0..H {
            for x in 0..W {
                let v = camera
                    .ray_of_pixel([f64::from(x), f64::from(y)])
                    .map_or(0.0, |ray| {
                        let [u, v] = system.pixel(&(rotation * ray));
                        scene(u - shift, v)
                    });
                img[(y * W + x) as usize] = v.round().clamp(0.0, 255.0) as u8;
            }
        }
        img
    })
}

fn matrix(v: &Value) -> nalgebra::Matrix3<f64> {
    let r: Vec<f64> = v
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    nalgebra::Matrix3::from_row_slice(&r)
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
    let pair = fisheye_180();
    let system = Latlon::new(&pair, SIZE, LatlonOptions::default()).unwrap();
    let [left, right] = render(&pair, &system);
    let yml = stereo_calibrate_yml(&pair);
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
    let pair = fisheye_180();
    let system = Latlon::new(&pair, SIZE, LatlonOptions::default()).unwrap();
    let [left, right] = render(&pair, &system);
    let yml = stereo_calibrate_yml(&pair);
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
