//! `depth-map --bag`: a recording's pairs. One pass over the bag finds its image topics
//! (the left and right ones named, or told by `left`/`right` in their names), their frames'
//! header stamps, and each camera's first `CameraInfo` (the calibration, as `image_geometry`
//! reads it, unless `--calibration` is given). The stamps are paired, each left frame with
//! the right frame nearest it when each is the other's nearest and they are within the
//! tolerance (`--max-skew`, by default a third of the left camera's frame interval); every
//! frame left out is named with its nearest. A second pass reads the paired frames, one pair
//! at a time, in the recording's order.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use stereo_core::vision::pixels::{Layout, Mosaic};
use stereo_ros::msg::{self, CameraInfo, CompressedImage, Image, Type};
use stereo_ros::{Bag, Message};

use stereo_core::numbers::{Num, round_to};
use stereo_core::physics::{Implausible, LengthUnit};

use super::engine::Frame;

/// A pair found by stamp: its name (the left stamp, `secs.nanosecs`), the left frame's
/// header, and each frame's place among its topic's messages.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StampPair {
    pub name: String,
    pub header: msg::Header,
    pub left: usize,
    pub right: usize,
    /// The right frame's stamp, in nanoseconds.
    pub right_stamp: i64,
}

/// A frame left out, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Orphan {
    pub what: String,
    pub reason: String,
}

/// What the survey found.
pub struct Survey {
    pub bag: Bag,
    pub left: String,
    pub right: String,
    pub pairs: Vec<StampPair>,
    pub orphans: Vec<Orphan>,
    /// The tolerance used, in nanoseconds.
    pub max_skew_ns: i64,
    /// Each camera's first CameraInfo, from the topic beside its images.
    pub info: [Option<(String, CameraInfo)>; 2],
    /// Why the bag could not be read to its end, when it could not.
    pub cut: Option<String>,
}

/// A stamp as a pair's name: `secs.nanosecs`.
pub fn stamp_name(ns: i64) -> String {
    format!(
        "{}.{:09}",
        ns.div_euclid(1_000_000_000),
        ns.rem_euclid(1_000_000_000)
    )
}

/// The `camera_info` topic beside an image topic (`/cam/left/image_raw` and
/// `/cam/left/image_raw/compressed` → `/cam/left/camera_info`), as image_transport pairs them.
pub fn info_topic(image: &str) -> String {
    let base = image.strip_suffix("/compressed").unwrap_or(image);
    match base.rfind('/') {
        Some(at) => format!("{}/camera_info", &base[..at]),
        None => "camera_info".to_owned(),
    }
}

/// The namespace the outputs' topics go under when the cameras' topics share none (and for a
/// folder of pairs): `stereo_image_proc`'s.
pub const DEFAULT_NAMESPACE: &str = "/stereo";

/// The namespace two cameras' topics share (`/stereo/left/image_raw`, `/stereo/right/…` →
/// `/stereo`), or [`DEFAULT_NAMESPACE`] when they share none.
pub fn namespace_of(left: &str, right: &str) -> String {
    let (l, r): (Vec<&str>, Vec<&str>) = (left.split('/').collect(), right.split('/').collect());
    let shared: Vec<&str> = l
        .iter()
        .zip(&r)
        .take_while(|(a, b)| a == b)
        .map(|(a, _)| *a)
        .collect();
    let ns = shared.join("/");
    if ns.trim_matches('/').is_empty() {
        DEFAULT_NAMESPACE.to_owned()
    } else {
        ns
    }
}

/// Which of `images` (the bag's image topics) is the camera named `side`: the one asked for,
/// else the only one whose name has `side` in it.
fn choose(
    asked: Option<&str>,
    side: &str,
    images: &BTreeMap<String, usize>,
) -> Result<String, String> {
    let listed = || {
        if images.is_empty() {
            "it has no sensor_msgs/Image or CompressedImage topic".to_owned()
        } else {
            format!(
                "its image topics: {}",
                images.keys().cloned().collect::<Vec<_>>().join(", ")
            )
        }
    };
    if let Some(topic) = asked {
        return if images.contains_key(topic) {
            Ok(topic.to_owned())
        } else {
            Err(format!(
                "--{side}-topic {topic}: no such image topic in the bag; {}",
                listed()
            ))
        };
    }
    let named: Vec<&String> = images
        .keys()
        .filter(|t| t.to_lowercase().contains(side))
        .collect();
    match named.as_slice() {
        [one] => Ok((*one).clone()),
        [] => Err(format!(
            "no image topic names the {side} camera: give --{side}-topic; {}",
            listed()
        )),
        many => {
            // A camera's raw and compressed topics both: the raw one.
            let raw: Vec<&&String> = many.iter().filter(|t| !t.ends_with("compressed")).collect();
            match raw.as_slice() {
                [one] => Ok((**one).clone()),
                _ => Err(format!(
                    "{} image topics name the {side} camera: give --{side}-topic; {}",
                    many.len(),
                    listed()
                )),
            }
        }
    }
}

/// The survey's pass over the bag at `path`.
pub fn survey(
    path: &Path,
    asked: [Option<&str>; 2],
    max_skew_ns: Option<i64>,
    limit: usize,
) -> Result<Survey, String> {
    let bag = Bag::open(path).map_err(|e| e.0)?;
    let mut stamps: BTreeMap<String, Vec<i64>> = BTreeMap::new();
    let mut infos: BTreeMap<String, CameraInfo> = BTreeMap::new();
    let mut types: BTreeMap<String, String> = BTreeMap::new();
    let mut cut = None;
    for message in bag.messages(None, limit) {
        let m = match message {
            Ok(m) => m,
            Err(e) => {
                cut = Some(e.0);
                break;
            }
        };
        let kind = Type::from_name(&m.type_name);
        types.entry(m.topic.clone()).or_insert(m.type_name.clone());
        match kind {
            Some(Type::Image | Type::CompressedImage) => {
                let stamp = msg::header_of(&m.data, m.kind)
                    .map_err(|e| format!("{}: a frame's header does not read: {e}", m.topic))?
                    .stamp_ns;
                stamps.entry(m.topic).or_default().push(stamp);
            }
            Some(Type::CameraInfo) if !infos.contains_key(&m.topic) => {
                let info = CameraInfo::decode(&m.data, m.kind)
                    .map_err(|e| format!("{}: the CameraInfo does not read: {e}", m.topic))?;
                infos.insert(m.topic, info);
            }
            _ => {}
        }
    }
    let images: BTreeMap<String, usize> =
        stamps.iter().map(|(t, s)| (t.clone(), s.len())).collect();
    let left = choose(asked[0], "left", &images);
    let right = choose(asked[1], "right", &images);
    let (left, right) = match (left, right) {
        (Ok(l), Ok(r)) if l != r => (l, r),
        (Ok(l), Ok(_)) => {
            return Err(format!("--left-topic and --right-topic are both {l}"));
        }
        (l, r) => {
            let faults: Vec<String> = [l.err(), r.err()].into_iter().flatten().collect();
            return Err(format!(
                "{} ({}): {}",
                path.display(),
                bag.kind(),
                faults.join("; ")
            ));
        }
    };
    let (l, r) = (&stamps[&left], &stamps[&right]);
    let skew = max_skew_ns.unwrap_or_else(|| default_skew(l));
    let (pairs, orphans) = pair_stamps(l, r, skew, [&left, &right]);
    let info = [&left, &right].map(|t| {
        let topic = info_topic(t);
        infos.get(&topic).cloned().map(|i| (topic, i))
    });
    Ok(Survey {
        bag,
        left,
        right,
        pairs,
        orphans,
        max_skew_ns: skew,
        info,
        cut,
    })
}

/// A third of the median interval between a camera's frames (10 ms when it has fewer than
/// two).
fn default_skew(stamps: &[i64]) -> i64 {
    let mut gaps: Vec<i64> = stamps.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    if gaps.is_empty() {
        return 10_000_000;
    }
    gaps.sort_unstable();
    (gaps[gaps.len() / 2] / 3).max(1)
}

fn ms(ns: i64) -> String {
    format!("{:.1} ms", ns as f64 / 1e6)
}

/// Pairs the two cameras' stamps (each in its topic's order): a left and a right frame are a
/// pair when they are within `skew` and each is the other's nearest; every other frame is an
/// orphan, named with how far its nearest frame of the other camera is.
pub fn pair_stamps(
    left: &[i64],
    right: &[i64],
    skew: i64,
    topics: [&str; 2],
) -> (Vec<StampPair>, Vec<Orphan>) {
    let order = |s: &[i64]| {
        let mut o: Vec<usize> = (0..s.len()).collect();
        o.sort_by_key(|&i| (s[i], i));
        o
    };
    let (lo, ro) = (order(left), order(right));
    let nearest = |stamp: i64, other: &[i64], sorted: &[usize]| -> Option<i64> {
        let at = sorted.partition_point(|&i| other[i] < stamp);
        [at.checked_sub(1), Some(at)]
            .into_iter()
            .flatten()
            .filter_map(|k| sorted.get(k))
            .map(|&k| (other[k] - stamp).abs())
            .min()
    };
    let orphan = |side: usize, stamp: i64, other: &[i64], sorted: &[usize]| {
        let far = nearest(stamp, other, sorted)
            .map(|d| {
                format!(
                    "the nearest {} frame is {} away",
                    ["right", "left"][side],
                    ms(d)
                )
            })
            .unwrap_or_else(|| format!("the {} camera has no frames", ["right", "left"][side]));
        Orphan {
            what: format!("{} at {}", topics[side], stamp_name(stamp)),
            reason: format!("{far}, past the {} allowed (--max-skew)", ms(skew)),
        }
    };
    let (mut pairs, mut orphans) = (Vec::new(), Vec::new());
    let (mut i, mut j) = (0, 0);
    while i < lo.len() && j < ro.len() {
        let (a, b) = (left[lo[i]], right[ro[j]]);
        let gap = (a - b).abs();
        let closer_right = ro.get(j + 1).is_some_and(|&k| (right[k] - a).abs() < gap);
        let closer_left = lo.get(i + 1).is_some_and(|&k| (left[k] - b).abs() < gap);
        if gap <= skew && !closer_right && !closer_left {
            pairs.push(StampPair {
                name: stamp_name(a),
                header: msg::Header {
                    stamp_ns: a,
                    frame_id: String::new(),
                },
                left: lo[i],
                right: ro[j],
                right_stamp: b,
            });
            i += 1;
            j += 1;
        } else if a < b || (a == b && closer_left) {
            orphans.push(orphan(0, a, right, &ro));
            i += 1;
        } else {
            orphans.push(orphan(1, b, left, &lo));
            j += 1;
        }
    }
    orphans.extend(lo[i..].iter().map(|&k| orphan(0, left[k], right, &ro)));
    orphans.extend(ro[j..].iter().map(|&k| orphan(1, right[k], left, &lo)));
    // The data pass reads each topic once, in order: a pair whose frames were recorded out
    // of their stamps' order is left out (named), never paired with a neighbour's image.
    pairs.sort_by_key(|p| p.left);
    let mut last_right = None;
    pairs.retain(|p| {
        let in_order = last_right.is_none_or(|r| p.right > r);
        if in_order {
            last_right = Some(p.right);
        } else {
            orphans.push(Orphan {
                what: format!("{} at {}", topics[0], p.name),
                reason: "its right frame was recorded before the previous pair's".to_owned(),
            });
        }
        in_order
    });
    (pairs, orphans)
}

/// A frame's ROS image encoding as the engine's layout.
fn layout(encoding: &str, big_endian: bool) -> Option<Layout> {
    let mosaic = |m: &str| match m {
        "rggb" => Some(Mosaic::Rggb),
        "bggr" => Some(Mosaic::Bggr),
        "gbrg" => Some(Mosaic::Gbrg),
        "grbg" => Some(Mosaic::Grbg),
        _ => None,
    };
    Some(match encoding.to_ascii_lowercase().as_str() {
        "mono8" | "8uc1" => Layout::Mono8,
        "mono16" | "16uc1" => Layout::Mono16 { big_endian },
        "rgb8" | "8uc3" => Layout::Rgb8,
        "bgr8" => Layout::Bgr8,
        "rgba8" => Layout::Rgba8,
        "bgra8" | "8uc4" => Layout::Bgra8,
        other => {
            let rest = other.strip_prefix("bayer_")?;
            let (pattern, bits) = rest.split_at(rest.len().min(4));
            match bits {
                "8" => Layout::Bayer8(mosaic(pattern)?),
                "16" => Layout::Bayer16 {
                    mosaic: mosaic(pattern)?,
                    big_endian,
                },
                _ => return None,
            }
        }
    })
}

/// A recorded image message as the engine's frame, or why it is not one.
pub fn frame(m: &Message) -> Result<(msg::Header, Frame), String> {
    match Type::from_name(&m.type_name) {
        Some(Type::Image) => {
            let image = Image::decode(&m.data, m.kind).map_err(|e| e.0)?;
            let layout = layout(&image.encoding, image.is_bigendian).ok_or_else(|| {
                format!(
                    "its encoding `{}` is not one read here: mono8, mono16, rgb8, bgr8, rgba8, \
                     bgra8, bayer_rggb8 (bggr, gbrg, grbg; 8 or 16 bits)",
                    image.encoding
                )
            })?;
            Ok((
                image.header,
                Frame::Pixels {
                    width: image.width,
                    height: image.height,
                    layout,
                    step: image.step as usize,
                    data: image.data,
                },
            ))
        }
        Some(Type::CompressedImage) => {
            let image = CompressedImage::decode(&m.data, m.kind).map_err(|e| e.0)?;
            Ok((image.header, Frame::File(image.data)))
        }
        _ => Err(format!("{} is not an image type", m.type_name)),
    }
}

/// The calibration two CameraInfos give, as `ros2 topic echo` prints them: the files the
/// service reads as a ROS pair (`calibration`, `right_calibration`). A CameraInfo that names
/// a distortion model but gives no D, or has no K or P, is refused by topic.
pub fn calibration(
    info: &[Option<(String, CameraInfo)>; 2],
    topics: [&str; 2],
) -> Result<[String; 2], String> {
    let mut files = Vec::new();
    let mut faults = Vec::new();
    for (side, found) in info.iter().enumerate() {
        let Some((topic, info)) = found else {
            faults.push(format!(
                "the bag has no {} (the {} camera's CameraInfo, beside {}): give --calibration",
                info_topic(topics[side]),
                ["left", "right"][side],
                topics[side]
            ));
            continue;
        };
        if info.k.iter().all(|&v| v == 0.0) || info.p.iter().all(|&v| v == 0.0) {
            faults.push(format!(
                "{topic}: its K or P is all zeros (an uncalibrated camera): give --calibration"
            ));
            continue;
        }
        if info.d.is_empty() {
            faults.push(format!(
                "{topic}: it has no D (distortion) for its distortion_model `{}`; publish the \
                 camera's coefficients (zeros for a lens without distortion), or give \
                 --calibration",
                info.distortion_model
            ));
            continue;
        }
        let list = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:?}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        files.push(format!(
            "height: {}\nwidth: {}\ndistortion_model: \"{}\"\nd: [{}]\nk: [{}]\nr: [{}]\np: [{}]\n",
            info.height,
            info.width,
            info.distortion_model,
            list(&info.d),
            list(&info.k),
            list(&info.r),
            list(&info.p)
        ));
    }
    if faults.is_empty()
        && let [Some((_, left)), Some((topic, right))] = info
        && let Some(fault) = baseline_fault(left, right, topic)
    {
        faults.push(fault);
    }
    if !faults.is_empty() {
        return Err(faults.join("; "));
    }
    let right = files.pop().unwrap_or_default();
    let left = files.pop().unwrap_or_default();
    Ok([left, right])
}

/// A baseline no stereo rig has, from the two projections' P[0,3] = −f·B: ROS gives B in
/// metres, so a P[0,3] written in millimetres reads as a baseline a thousand times too wide,
/// and every depth would be too. The bag's user cannot name another unit, so this refuses
/// the rig and says what to fix, where a calibration file would have taken a unit.
fn baseline_fault(left: &CameraInfo, right: &CameraInfo, topic: &str) -> Option<String> {
    let tx = |i: &CameraInfo| if i.p[0] != 0.0 { i.p[3] / i.p[0] } else { 0.0 };
    let baseline = tx(left) - tx(right);
    let found = Implausible::baseline(baseline, LengthUnit::Metre)?;
    let likely = match found.likely {
        Some(u) => format!(
            " It reads as a plausible {} {} if P[0,3] was written in {}.",
            Num(round_to(baseline.abs(), 4)),
            u.symbol(),
            u.symbol()
        ),
        None => String::new(),
    };
    Some(format!(
        "{topic}: its P[0,3] = {} gives a baseline of {} m, {}: no stereo camera has that, and \
         every depth from it would be off by the same factor. ROS gives P[0,3] = −f·B with B in \
         metres.{likely} Fix the cameras' CameraInfo, or give --calibration with \
         --calibration-unit",
        Num(right.p[3]),
        Num(round_to(baseline.abs(), 4)),
        if found.under {
            "under 1 mm"
        } else {
            "over 10 m"
        },
    ))
}

/// The paired frames, read in the recording's order: each pair's left and right messages,
/// or why one could not be read.
pub struct Frames {
    left: stereo_ros::bag::Messages,
    right: stereo_ros::bag::Messages,
    at: [usize; 2],
}

impl Frames {
    pub fn new(survey: &Survey, limit: usize) -> Frames {
        let topic = |t: &str| Some(BTreeSet::from([t.to_owned()]));
        Frames {
            left: survey.bag.messages(topic(&survey.left), limit),
            right: survey.bag.messages(topic(&survey.right), limit),
            at: [0, 0],
        }
    }

    /// The messages of `pair` (whose places come after the last pair's).
    pub fn read(&mut self, pair: &StampPair) -> Result<[Message; 2], String> {
        let mut take = |side: usize, want: usize| -> Result<Message, String> {
            let messages = if side == 0 {
                &mut self.left
            } else {
                &mut self.right
            };
            loop {
                let m = messages
                    .next()
                    .ok_or_else(|| "the bag ended before this frame".to_owned())?
                    .map_err(|e| e.0)?;
                self.at[side] += 1;
                if self.at[side] - 1 == want {
                    return Ok(m);
                }
            }
        };
        Ok([take(0, pair.left)?, take(1, pair.right)?])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    /// A CameraInfo pair whose right P[0,3] is −f·B with B in millimetres (a baseline of 120
    /// m read in metres) is refused by its topic, saying ROS's unit and what to fix; the same
    /// pair in metres gives the two files.
    #[test]
    fn a_baseline_in_millimetres_is_refused() {
        let info = |tx: f64, topic: &str| {
            let header = msg::Header::default();
            let i = CameraInfo::pinhole(header, [640, 480], [500.0, 500.0, 320.0, 240.0], tx);
            Some((topic.to_owned(), i))
        };
        let topics = ["/stereo/left/image_raw", "/stereo/right/image_raw"];
        let mm = [
            info(0.0, "/stereo/left/camera_info"),
            info(-500.0 * 120.0, "/stereo/right/camera_info"),
        ];
        let said = calibration(&mm, topics).unwrap_err();
        assert!(
            said.starts_with("/stereo/right/camera_info: its P[0,3] = -60000 gives a baseline of 120 m, over 10 m"),
            "{said}"
        );
        assert!(said.contains("B in metres"), "{said}");
        assert!(
            said.contains("120 mm if P[0,3] was written in mm"),
            "{said}"
        );
        assert!(said.contains("--calibration-unit"), "{said}");
        let m = [
            info(0.0, "/stereo/left/camera_info"),
            info(-500.0 * 0.12, "/stereo/right/camera_info"),
        ];
        let [left, right] = calibration(&m, topics).unwrap();
        assert!(right.contains("p: [500.0, 0.0, 320.0, -60.0,"), "{right}");
        assert!(left.contains("p: [500.0, 0.0, 320.0, 0.0,"), "{left}");
    }

    /// Frames within the tolerance pair; a dropped frame's partner is an orphan named with
    /// its nearest, never paired with a neighbour's image.
    #[test]
    fn stamps_pair_and_orphans_are_named() {
        // 30 fps, the right camera 5 ms late, left frame 3 and right frame 6 dropped.
        let left: Vec<i64> = (0..10).filter(|&k| k != 3).map(|k| k * 33 * MS).collect();
        let right: Vec<i64> = (0..10)
            .filter(|&k| k != 6)
            .map(|k| k * 33 * MS + 5 * MS)
            .collect();
        let skew = default_skew(&left);
        assert_eq!(skew, 11 * MS);
        let (pairs, orphans) = pair_stamps(&left, &right, skew, ["/l", "/r"]);
        assert_eq!(pairs.len(), 8);
        assert!(
            pairs
                .iter()
                .all(|p| (right[p.right] - left[p.left]) == 5 * MS)
        );
        assert_eq!(orphans.len(), 2, "{orphans:?}");
        assert!(orphans[0].what.starts_with("/r at 0.104"), "{orphans:?}");
        assert!(
            orphans[0]
                .reason
                .contains("nearest left frame is 28.0 ms away"),
            "{orphans:?}"
        );
        assert!(orphans[1].what.starts_with("/l at 0.198"), "{orphans:?}");
    }

    /// Topics are found by the camera in their names, and a wrong name lists the topics.
    #[test]
    fn topics_are_chosen_and_named() {
        let images = BTreeMap::from([
            ("/stereo/left/image_raw".to_owned(), 3),
            ("/stereo/right/image_raw".to_owned(), 3),
            ("/stereo/right/image_raw/compressed".to_owned(), 3),
        ]);
        assert_eq!(
            choose(None, "left", &images).unwrap(),
            "/stereo/left/image_raw"
        );
        assert_eq!(
            choose(None, "right", &images).unwrap(),
            "/stereo/right/image_raw"
        );
        let err = choose(Some("/cam0"), "left", &images).unwrap_err();
        assert!(err.contains("no such image topic") && err.contains("/stereo/left/image_raw"));
        assert_eq!(
            info_topic("/stereo/left/image_raw/compressed"),
            "/stereo/left/camera_info"
        );
        assert_eq!(
            namespace_of("/stereo/left/image_raw", "/stereo/right/image_raw"),
            "/stereo"
        );
        assert_eq!(namespace_of("/left", "/right"), "/stereo");
    }

    /// Every encoding the issue names maps onto a layout; others are refused.
    #[test]
    fn encodings() {
        assert_eq!(
            layout("bayer_grbg8", false),
            Some(Layout::Bayer8(Mosaic::Grbg))
        );
        assert_eq!(
            layout("bayer_rggb16", true),
            Some(Layout::Bayer16 {
                mosaic: Mosaic::Rggb,
                big_endian: true
            })
        );
        assert_eq!(
            layout("mono16", false),
            Some(Layout::Mono16 { big_endian: false })
        );
        assert_eq!(layout("yuv422", false), None);
        assert_eq!(layout("32FC1", false), None);
    }
}
