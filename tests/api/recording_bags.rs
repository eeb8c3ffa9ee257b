//! `stereo-distance depth-map --bag` on recordings of the rendered scene written with
//! `stereo-ros`'s own writers (the Python libraries' bags are CI's `scripts/evaluate/bags`):
//! run as users run it, the binary with its stderr a pipe.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use stereo_ros::msg::{CameraInfo, Header, Image, Type};
use stereo_ros::out::McapOut;
use stereo_ros::{Bag, Kind, ros1};

use crate::depth_map::{H, W, pair};
use crate::helpers::spawn_app;

/// The rig: 400 px, 0.12 m, the principal point at the centre, no distortion.
const F: f64 = 400.0;
const BASELINE_M: f64 = 0.12;
const START: i64 = 1_700_000_000_000_000_000;
const FRAME: i64 = 33_333_333;

fn info(right: bool, stamp: i64) -> CameraInfo {
    let (cx, cy) = ((W / 2) as f64, (H / 2) as f64);
    let tx = if right { -F * BASELINE_M } else { 0.0 };
    let header = Header {
        stamp_ns: stamp,
        frame_id: format!("{}_optical", if right { "right" } else { "left" }),
    };
    CameraInfo::pinhole(header, [W as u32, H as u32], [F, F, cx, cy], tx)
}

fn image(rgb: &[u8], stamp: i64, right: bool) -> Image {
    Image {
        header: Header {
            stamp_ns: stamp,
            frame_id: format!("{}_optical", if right { "right" } else { "left" }),
        },
        height: H as u32,
        width: W as u32,
        encoding: "rgb8".into(),
        is_bigendian: false,
        step: (W * 3) as u32,
        data: rgb.to_vec(),
    }
}

/// The frames of `n` pairs, the right camera `skew` ns late, those in `dropped` (camera,
/// index) left out: (topic, type, stamp, message) in the order recorded.
fn frames(
    n: i64,
    skew: i64,
    dropped: &[(bool, i64)],
    kind: Kind,
) -> Vec<(String, Type, i64, Vec<u8>)> {
    let scene = pair();
    let mut out = Vec::new();
    for k in 0..n {
        for right in [false, true] {
            let stamp = START + k * FRAME + if right { skew } else { 0 };
            let side = if right { "right" } else { "left" };
            let rgb = if right {
                &scene.right_rgb
            } else {
                &scene.left_rgb
            };
            if !dropped.contains(&(right, k)) {
                let data = image(rgb, stamp, right).encode(kind);
                out.push((format!("/rig/{side}/image_raw"), Type::Image, stamp, data));
            }
            let data = info(right, stamp).encode(kind);
            out.push((
                format!("/rig/{side}/camera_info"),
                Type::CameraInfo,
                stamp,
                data,
            ));
        }
    }
    out
}

fn mcap(path: &Path, frames: &[(String, Type, i64, Vec<u8>)]) {
    let mut out = McapOut::create(path).unwrap();
    for (topic, t, stamp, data) in frames {
        out.write(topic, *t, *stamp as u64, data).unwrap();
    }
    out.finish().unwrap();
}

fn bag1(path: &Path, frames: &[(String, Type, i64, Vec<u8>)]) {
    let mut bag = ros1::Writer::new(std::fs::File::create(path).unwrap()).unwrap();
    for (topic, t, stamp, data) in frames {
        let id = bag.connection(topic, t.ros1_name(), "*", "").unwrap();
        bag.message(id, *stamp as u64, data).unwrap();
    }
    bag.finish().unwrap();
}

fn run(args: &[&str]) -> (Option<i32>, String) {
    let output: Output = Command::new(env!("CARGO_BIN_EXE_stereo-distance"))
        .arg("depth-map")
        .args(args)
        .output()
        .expect("the binary runs");
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

fn dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn median(values: impl Iterator<Item = f32>) -> f64 {
    let mut v: Vec<f32> = values.filter(|z| z.is_finite()).collect();
    v.sort_by(f32::total_cmp);
    f64::from(v[v.len() / 2])
}

/// A ROS 2 MCAP recording with its CameraInfo becomes an MCAP file of ROS 2 messages: every
/// pair on every topic under the namespace the cameras share, stamped as the left frame, in
/// its frame; the depth 32FC1 in metres at f·B/d of the scene; the disparity's f and t the
/// rig's.
#[test]
fn a_ros2_bag_becomes_ros2_depth_messages() {
    let dir = dir("bag-ros2");
    mcap(&dir.join("rig.mcap"), &frames(3, 0, &[], Kind::Cdr));
    let out = dir.join("depth.mcap");
    let (code, said) = run(&[
        "--bag",
        dir.join("rig.mcap").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{said}");
    assert!(
        said.contains("3 pairs of /rig/left/image_raw and /rig/right/image_raw"),
        "{said}"
    );
    assert!(said.contains("wrote 3 of 3 pairs"), "{said}");
    let truth = F * BASELINE_M / median(pair().seen_truth().into_iter());
    let mut topics = std::collections::BTreeMap::<String, usize>::new();
    for m in Bag::open(&out).unwrap().messages(None, 1 << 26) {
        let m = m.unwrap();
        *topics.entry(m.topic.clone()).or_default() += 1;
        assert_eq!(m.kind, Kind::Cdr);
        if m.topic == "/rig/depth/image_rect" {
            let depth = Image::decode(&m.data, Kind::Cdr).unwrap();
            assert_eq!(
                (depth.encoding.as_str(), depth.width, depth.height),
                ("32FC1", W as u32, H as u32)
            );
            assert_eq!(depth.header.frame_id, "left_optical");
            assert_eq!((m.log_time_ns as i64 - START) % FRAME, 0);
            let z = median(
                depth
                    .data
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            );
            assert!(
                (z - truth).abs() < 0.03 * truth,
                "median {z} m, truth {truth} m"
            );
        }
        if m.topic == "/rig/disparity" {
            let d = stereo_ros::msg::DisparityImage::decode(&m.data, Kind::Cdr).unwrap();
            assert!(
                (f64::from(d.f) - F).abs() < 1e-3 && (f64::from(d.t) - BASELINE_M).abs() < 1e-6
            );
        }
    }
    let want = [
        "depth/image_rect",
        "depth/image_rect_std",
        "disparity",
        "left/camera_info",
        "left/image_rect_color",
        "points2",
    ];
    let names: Vec<String> = want.iter().map(|t| format!("/rig/{t}")).collect();
    assert_eq!(topics.keys().cloned().collect::<Vec<_>>(), names);
    assert!(topics.values().all(|&n| n == 3), "{topics:?}");
}

/// A ROS 1 bag with a dropped frame on each camera and the right one 5 ms late: every true
/// pair written (into a folder, named by stamp), each orphan named with its nearest; the
/// same recording through a running service (`--server`) writes the same pairs.
#[tokio::test]
async fn a_ros1_bag_with_dropped_frames_pairs_by_stamp() {
    let dir = dir("bag-ros1");
    let recorded = frames(6, 5_000_000, &[(false, 2), (true, 4)], Kind::Ros1);
    bag1(&dir.join("rig.bag"), &recorded);
    let bag = dir.join("rig.bag");
    let (code, said) = run(&[
        "--bag",
        bag.to_str().unwrap(),
        "--out",
        dir.join("out").to_str().unwrap(),
        "--preset",
        "fast",
    ]);
    assert_eq!(code, Some(1), "orphans make the exit 1: {said}");
    assert!(said.contains("wrote 4 of 4 pairs"), "{said}");
    assert!(said.contains("2 frames unpaired"), "{said}");
    assert!(said.contains("skipped /rig/right/image_raw at 1700000000.071666666: the nearest left frame is 28.3 ms away"), "{said}");
    assert!(
        said.contains("skipped /rig/left/image_raw at 1700000000.133333332"),
        "{said}"
    );
    let mut written: Vec<String> = std::fs::read_dir(dir.join("out"))
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    written.sort();
    assert_eq!(written[0], "1700000000.000000000.depth.npy");
    assert_eq!(written.len(), 4);

    let app = spawn_app().await;
    let out = dir.join("served");
    let args = [
        "--bag".to_owned(),
        bag.display().to_string(),
        "--out".to_owned(),
        out.display().to_string(),
        "--preset".to_owned(),
        "fast".to_owned(),
        "--server".to_owned(),
        app.address.clone(),
    ];
    let (code, said) = tokio::task::spawn_blocking(move || {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        run(&args)
    })
    .await
    .unwrap();
    assert_eq!(code, Some(1), "{said}");
    assert!(said.contains("wrote 4 of 4 pairs"), "{said}");
    for name in &written {
        let here = crate::depth_map::npy(&std::fs::read(dir.join("out").join(name)).unwrap());
        let there = crate::depth_map::npy(&std::fs::read(out.join(name)).unwrap());
        assert_eq!(here.len(), there.len());
        assert!(
            here.iter()
                .zip(&there)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{name}"
        );
    }
}

/// A folder of pairs becomes an MCAP file too (stamped 0.1 s apart); what users get wrong is
/// named before any frame: a topic that is not there (with the topics that are), a file
/// that is no recording, `--output` with an MCAP file.
#[test]
fn folders_become_bags_and_mistakes_are_named() {
    let dir = dir("bag-mistakes");
    mcap(&dir.join("rig.mcap"), &frames(1, 0, &[], Kind::Cdr));
    let bag = dir.join("rig.mcap");
    let (code, said) = run(&[
        "--bag",
        bag.to_str().unwrap(),
        "--left-topic",
        "/cam0",
        "--out",
        dir.join("o").to_str().unwrap(),
    ]);
    assert_eq!(code, Some(1));
    assert!(said.contains("--left-topic /cam0: no such image topic in the bag; its image topics: /rig/left/image_raw, /rig/right/image_raw"), "{said}");
    std::fs::write(dir.join("notes.bag"), "not a bag").unwrap();
    let (_, said) = run(&[
        "--bag",
        dir.join("notes.bag").to_str().unwrap(),
        "--out",
        dir.join("o").to_str().unwrap(),
    ]);
    assert!(
        said.contains("is neither an MCAP file, a rosbag2 folder nor a ROS 1 bag"),
        "{said}"
    );
    let (_, said) = run(&[
        "--bag",
        bag.to_str().unwrap(),
        "--output",
        "disparity.pfm",
        "--out",
        dir.join("o.mcap").to_str().unwrap(),
    ]);
    assert!(said.contains("--output names a file a pair"), "{said}");

    let scene = pair();
    let frames = dir.join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    for n in 1..=2 {
        std::fs::write(
            frames.join(format!("left{n}.png")),
            stereo_core::vision::encode::png_rgb(W, H, &scene.left_rgb),
        )
        .unwrap();
        std::fs::write(
            frames.join(format!("right{n}.png")),
            stereo_core::vision::encode::png_rgb(W, H, &scene.right_rgb),
        )
        .unwrap();
    }
    let calib = dir.join("calib.txt");
    std::fs::write(&calib, format!("cam0=[400 0 {cx}; 0 400 {cy}; 0 0 1]\ncam1=[400 0 {cx}; 0 400 {cy}; 0 0 1]\ndoffs=0\nbaseline=120\nwidth={W}\nheight={H}\nndisp=48\n", cx = W / 2, cy = H / 2)).unwrap();
    let out = dir.join("from-folder.mcap");
    let (code, said) = run(&[
        "--frames",
        frames.to_str().unwrap(),
        "--calibration",
        calib.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--out-namespace",
        "/cams",
    ]);
    assert_eq!(code, Some(0), "{said}");
    let stamps: Vec<u64> = Bag::open(&out)
        .unwrap()
        .messages(Some(["/cams/points2".to_owned()].into()), 1 << 26)
        .map(|m| m.unwrap().log_time_ns)
        .collect();
    assert_eq!(stamps, vec![0, 100_000_000]);
}
