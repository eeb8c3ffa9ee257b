//! `/depth-map` and `/depth-stream` answering ROS 2 messages in CDR (`output=depth.cdr`,
//! `disparity.cdr`, `depth_std.cdr`, `points.cdr`): what a ROS node or a Foxglove panel takes
//! without conversion, read back with `stereo-ros` and checked against the same map's NPY.

use futures_util::SinkExt;
use reqwest::multipart::Form;
use serde_json::json;
use stereo_ros::Kind;
use stereo_ros::msg::{DisparityImage, Image, PointCloud2};

use crate::depth_map::{H, W, image_part, npy, pair, png, rig};
use crate::depth_stream::{binary, open_with, side_by_side, text};
use crate::helpers::spawn_app;

fn form() -> Form {
    let pair = pair();
    Form::new()
        .part("left", image_part(png(&pair.left_rgb, W, H)))
        .part("right", image_part(png(&pair.right_rgb, W, H)))
        .text("rig", rig().to_string())
}

fn floats(image: &Image) -> Vec<f32> {
    image
        .data
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

/// Each CDR output is its ROS 2 message, `application/x-cdr`: the depth 32FC1 in metres
/// equal to `depth.npy`'s millimetres / 1000 with the same NaNs, σ_Z likewise, the
/// disparity's f·t/d the depth, and one point a depth; without a rig, a 422 naming it.
#[tokio::test]
async fn depth_map_answers_ros2_messages() {
    let app = spawn_app().await;
    let post = |query: &'static str, form: Form| {
        let app = &app;
        async move {
            app.client
                .post(format!(
                    "{}/depth-map?max_disparity=48&output={query}",
                    app.address
                ))
                .multipart(form)
                .send()
                .await
                .unwrap()
        }
    };
    let npy_mm = npy(&post("depth.npy", form()).await.bytes().await.unwrap());
    let answer = post("depth.cdr", form()).await;
    assert_eq!(answer.status(), 200);
    assert_eq!(answer.headers()["content-type"], "application/x-cdr");
    let depth = Image::decode(&answer.bytes().await.unwrap(), Kind::Cdr).unwrap();
    assert_eq!(
        (depth.encoding.as_str(), depth.width, depth.height),
        ("32FC1", W as u32, H as u32)
    );
    assert_eq!(depth.header.frame_id, "left_camera");
    let metres = floats(&depth);
    assert_eq!(metres.len(), npy_mm.len());
    for (m, mm) in metres.iter().zip(&npy_mm) {
        assert_eq!(m.is_nan(), mm.is_nan());
        if mm.is_finite() {
            assert!((f64::from(*m) - f64::from(*mm) / 1000.0).abs() <= 1e-6 * f64::from(*m));
        }
    }
    let std = Image::decode(
        &post("depth_std.cdr", form()).await.bytes().await.unwrap(),
        Kind::Cdr,
    )
    .unwrap();
    assert!(
        floats(&std)
            .iter()
            .zip(&metres)
            .all(|(s, z)| z.is_nan() || (s.is_finite() && *s > 0.0))
    );
    let d = DisparityImage::decode(
        &post("disparity.cdr", form()).await.bytes().await.unwrap(),
        Kind::Cdr,
    )
    .unwrap();
    assert_eq!((d.f, d.t), (500.0, 0.1));
    for (disparity, z) in floats(&d.image)
        .iter()
        .zip(&metres)
        .filter(|(_, z)| z.is_finite())
    {
        assert!((d.f * d.t / disparity - z).abs() <= 1e-4 * z);
    }
    let cloud = PointCloud2::decode(
        &post("points.cdr", form()).await.bytes().await.unwrap(),
        Kind::Cdr,
    )
    .unwrap();
    let names: Vec<&str> = cloud.fields.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["x", "y", "z", "rgb", "depth_std"]);
    assert_eq!(
        cloud.width as usize,
        metres.iter().filter(|z| z.is_finite()).count()
    );

    let pair = pair();
    let bare = Form::new()
        .part("left", image_part(png(&pair.left_rgb, W, H)))
        .part("right", image_part(png(&pair.right_rgb, W, H)));
    let refused = post("depth.cdr", bare).await;
    assert_eq!(refused.status(), 422);
    let problem: serde_json::Value = refused.json().await.unwrap();
    assert!(
        problem.to_string().contains("output=depth.cdr"),
        "{problem}"
    );
}

/// A stream asked for `depth.cdr` answers each frame with that message as its binary
/// message, named in the frame's files.
#[tokio::test]
async fn the_stream_answers_ros2_messages() {
    let app = spawn_app().await;
    let settings = json!({"rig": rig(), "options": {"max_disparity": 48}, "outputs": ["depth.cdr", "points.cdr"]});
    let (mut socket, resolved) = open_with(&app, settings).await;
    assert_eq!(
        resolved["outputs"],
        json!(["depth.cdr", "points.cdr"]),
        "{resolved}"
    );
    socket
        .send(tokio_tungstenite::tungstenite::Message::binary(
            side_by_side(&pair()),
        ))
        .await
        .unwrap();
    let answer = text(&mut socket).await;
    assert_eq!(answer["files"][0]["name"], "depth.cdr", "{answer}");
    assert_eq!(answer["files"][0]["media_type"], "application/x-cdr");
    let depth = Image::decode(&binary(&mut socket).await, Kind::Cdr).unwrap();
    assert_eq!(depth.encoding, "32FC1");
    let metres = floats(&depth);
    let finite = metres.iter().filter(|z| z.is_finite()).count();
    assert!(finite > W * H / 2);
    let cloud = PointCloud2::decode(&binary(&mut socket).await, Kind::Cdr).unwrap();
    assert_eq!(cloud.width as usize, finite);
}
