//! Recordings written here read back here: MCAP through [`McapOut`] and [`Bag`], ROS 1 bags
//! through [`ros1::Writer`] and [`Bag`], with a cut-off file named after what it held.

use std::collections::BTreeSet;
use std::path::PathBuf;

use stereo_ros::msg::{self, CameraInfo, Header, Image, Type};
use stereo_ros::out::McapOut;
use stereo_ros::{Bag, Kind, ros1};

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("stereo-ros-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn image(i: i64) -> Image {
    Image {
        header: Header {
            stamp_ns: 1_000_000_000 + i * 33_000_000,
            frame_id: "left".into(),
        },
        height: 100,
        width: 100,
        encoding: "mono8".into(),
        step: 100,
        // Noise, so that the chunks' compression leaves them long.
        data: (0..10_000u64)
            .map(|k| {
                (((k + 1) * (i as u64 + 7)).wrapping_mul(6_364_136_223_846_793_005) >> 56) as u8
            })
            .collect(),
        ..Image::default()
    }
}

/// Every message written to an MCAP file reads back, in order, on the topics asked for.
#[test]
fn mcap_round_trips() {
    let path = temp("mcap").join("out.mcap");
    let mut out = McapOut::create(&path).unwrap();
    for i in 0..5 {
        let t = 1_000 + i as u64;
        out.write(
            "/left/image_raw",
            Type::Image,
            t,
            &image(i).encode(Kind::Cdr),
        )
        .unwrap();
        out.write(
            "/left/camera_info",
            Type::CameraInfo,
            t,
            &CameraInfo::default().encode(Kind::Cdr),
        )
        .unwrap();
    }
    out.finish().unwrap();
    let bag = Bag::open(&path).unwrap();
    assert_eq!(bag.kind(), "ROS 2 MCAP");
    let topics = BTreeSet::from(["/left/image_raw".to_owned()]);
    let read: Vec<_> = bag
        .messages(Some(topics), 1 << 20)
        .collect::<Result<_, _>>()
        .unwrap();
    assert_eq!(read.len(), 5);
    for (i, m) in read.iter().enumerate() {
        assert_eq!(m.type_name, "sensor_msgs/msg/Image");
        assert_eq!(m.log_time_ns, 1_000 + i as u64);
        assert_eq!(Image::decode(&m.data, m.kind).unwrap(), image(i as i64));
    }
    assert_eq!(bag.messages(None, 1 << 20).count(), 10);
}

/// A file cut off mid-chunk gives the messages of its whole chunks, then an error naming the
/// cut; a record longer than the limit is refused by name.
#[test]
fn a_cut_mcap_is_named() {
    let path = temp("cut").join("whole.mcap");
    let mut out = McapOut::create(&path).unwrap();
    for i in 0..6 {
        out.write(
            "/left/image_raw",
            Type::Image,
            i,
            &image(i as i64).encode(Kind::Cdr),
        )
        .unwrap();
        if i == 2 {
            out.flush().unwrap();
        }
    }
    out.finish().unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let cut = path.with_file_name("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let read: Vec<_> = Bag::open(&cut).unwrap().messages(None, 1 << 20).collect();
    let (ok, errors): (Vec<_>, Vec<_>) = read.into_iter().partition(|r| r.is_ok());
    assert_eq!(ok.len(), 3, "the first chunk's messages");
    assert_eq!(errors.len(), 1);
    let said = errors[0].clone().unwrap_err().0;
    assert!(
        said.contains("cut off") && said.contains("after 3 messages"),
        "{said}"
    );
    let small: Vec<_> = Bag::open(&path).unwrap().messages(None, 1000).collect();
    assert!(
        small.iter().any(|r| r.is_err()),
        "a 1000-byte limit refuses the chunks"
    );
}

/// A ROS 1 bag written here reads back with its topics, types and times; a file that is
/// no recording is named as such.
#[test]
fn ros1_round_trips() {
    let path = temp("ros1").join("rig.bag");
    let mut bag = ros1::Writer::new(std::fs::File::create(&path).unwrap()).unwrap();
    for i in 0..4 {
        let id = bag
            .connection(
                "/left/image_raw",
                "sensor_msgs/Image",
                "060021388200f6f0f447d0fcd9c64743",
                "",
            )
            .unwrap();
        bag.message(id, 2_000_000_000 + i, &image(i as i64).encode(Kind::Ros1))
            .unwrap();
    }
    bag.finish().unwrap();
    let read: Vec<_> = Bag::open(&path)
        .unwrap()
        .messages(None, 1 << 20)
        .collect::<Result<_, _>>()
        .unwrap();
    assert_eq!(read.len(), 4);
    assert_eq!(read[3].log_time_ns, 2_000_000_003);
    assert_eq!(read[3].type_name, "sensor_msgs/Image");
    assert_eq!(
        msg::header_of(&read[3].data, Kind::Ros1).unwrap().stamp_ns,
        image(3).header.stamp_ns
    );
    let other = path.with_file_name("notes.txt");
    std::fs::write(&other, "hello").unwrap();
    assert!(
        Bag::open(&other)
            .unwrap_err()
            .0
            .contains("neither an MCAP file")
    );
}

/// Any recording cut at any byte, or with any byte changed, reads as messages and then at
/// most one error naming the file: nothing panics and nothing allocates past the limit.
#[test]
fn damaged_recordings_never_panic() {
    let dir = temp("damaged");
    let mcap = dir.join("whole.mcap");
    let mut out = McapOut::create(&mcap).unwrap();
    for i in 0..3 {
        out.write(
            "/left/image_raw",
            Type::Image,
            i,
            &image(i as i64).encode(Kind::Cdr),
        )
        .unwrap();
        out.flush().unwrap();
    }
    out.finish().unwrap();
    let bag = dir.join("whole.bag");
    let mut writer = ros1::Writer::new(std::fs::File::create(&bag).unwrap()).unwrap();
    for i in 0..3 {
        let id = writer
            .connection("/left/image_raw", "sensor_msgs/Image", "*", "")
            .unwrap();
        writer
            .message(id, i, &image(i as i64).encode(Kind::Ros1))
            .unwrap();
    }
    writer.finish().unwrap();
    for whole in [mcap, bag] {
        let bytes = std::fs::read(&whole).unwrap();
        let damaged = whole.with_extension("damaged");
        let step = (bytes.len() / 97).max(1);
        for at in (0..bytes.len()).step_by(step) {
            for version in [bytes[..at].to_vec(), {
                let mut b = bytes.clone();
                b[at] ^= 0x5a;
                b
            }] {
                std::fs::write(&damaged, &version).unwrap();
                let Ok(recording) = Bag::open(&damaged) else {
                    continue;
                };
                let read: Vec<_> = recording.messages(None, 1 << 20).collect();
                let errors = read.iter().filter(|r| r.is_err()).count();
                assert!(errors <= 1, "{at}: {errors} errors");
                if let Some(Err(e)) = read.last() {
                    assert!(e.0.contains("damaged"), "{at}: {e}");
                }
                for m in read.into_iter().flatten() {
                    let _ = Image::decode(&m.data, m.kind);
                }
            }
        }
    }
}

/// Every message type decodes any bytes without panicking: a short, a long or a garbled
/// message is an error naming a field.
#[test]
fn garbled_messages_never_panic() {
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let good = image(1).encode(Kind::Cdr);
    for _ in 0..2000 {
        let mut bytes = good.clone();
        let n = (next() % 8) as usize;
        for _ in 0..n {
            let at = (next() as usize) % bytes.len();
            bytes[at] = next() as u8;
        }
        bytes.truncate((next() as usize) % (bytes.len() + 1));
        for kind in [Kind::Cdr, Kind::Ros1] {
            let _ = Image::decode(&bytes, kind);
            let _ = CameraInfo::decode(&bytes, kind);
            let _ = msg::DisparityImage::decode(&bytes, kind);
            let _ = msg::PointCloud2::decode(&bytes, kind);
            let _ = msg::CompressedImage::decode(&bytes, kind);
        }
    }
}

/// A folder of recordings lists its `.mcap` and `.bag` files and its rosbag2 folders by name
/// and nothing else; a rosbag2 folder and a file are each one recording (`None`).
#[test]
fn a_folder_of_recordings_is_listed() {
    let dir = temp("recordings");
    for f in ["b.bag", "a.mcap", "notes.txt"] {
        std::fs::write(dir.join(f), b"x").unwrap();
    }
    std::fs::create_dir_all(dir.join("c")).unwrap();
    std::fs::write(
        dir.join("c/metadata.yaml"),
        b"rosbag2_bagfile_information:\n",
    )
    .unwrap();
    std::fs::create_dir_all(dir.join("empty")).unwrap();
    let found = stereo_ros::bag::recordings(&dir).unwrap().unwrap();
    let names: Vec<_> = found
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["a.mcap", "b.bag", "c"]);
    assert_eq!(stereo_ros::bag::recordings(&dir.join("c")).unwrap(), None);
    assert_eq!(
        stereo_ros::bag::recordings(&dir.join("a.mcap")).unwrap(),
        None
    );
}
