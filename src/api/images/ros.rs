//! A depth map as the ROS 2 messages `stereo_image_proc` and `depth_image_proc` publish:
//! the disparities as a `stereo_msgs/DisparityImage` (`f` in pixels, `t` the baseline in
//! metres, so that Z = f·t/d), the depths and their σ as `sensor_msgs/Image` 32FC1 in metres
//! (REP 118: NaN where there is none), the points as a `sensor_msgs/PointCloud2` (x, y, z,
//! rgb, depth_std, in metres, the left camera's optical frame), and the rectified left image
//! with its `CameraInfo`, so that a viewer overlays them. The `depth-map` command writes
//! them into an MCAP file; the topics are `stereo_image_proc`'s, under a namespace.

use crate::api::wire::depth_map::{DepthMapOutput, RosOutput};
use stereo_core::pipeline::DepthMap;
use stereo_core::pipeline::files::points;
use stereo_ros::Kind;
use stereo_ros::msg::{
    CameraInfo, DisparityImage, FLOAT32, Header, Image, PointCloud2, PointField, RegionOfInterest,
    Type,
};

/// The topics a depth map is published on, under the namespace.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Topic {
    Disparity,
    Depth,
    DepthStd,
    Points,
    LeftImage,
    LeftInfo,
}

impl Topic {
    /// Every topic, in the order [`messages`] gives them.
    pub const ALL: [Topic; 6] = [
        Topic::Disparity,
        Topic::Depth,
        Topic::DepthStd,
        Topic::Points,
        Topic::LeftImage,
        Topic::LeftInfo,
    ];

    /// Its name under the namespace (`stereo_image_proc`'s).
    pub fn name(self) -> &'static str {
        match self {
            Topic::Disparity => "disparity",
            Topic::Depth => "depth/image_rect",
            Topic::DepthStd => "depth/image_rect_std",
            Topic::Points => "points2",
            Topic::LeftImage => "left/image_rect_color",
            Topic::LeftInfo => "left/camera_info",
        }
    }

    /// The message type published on it.
    pub fn message_type(self) -> Type {
        match self {
            Topic::Disparity => Type::DisparityImage,
            Topic::Depth | Topic::DepthStd | Topic::LeftImage => Type::Image,
            Topic::Points => Type::PointCloud2,
            Topic::LeftInfo => Type::CameraInfo,
        }
    }
}

impl From<RosOutput> for Topic {
    /// The topic whose message a CDR answer is.
    fn from(output: RosOutput) -> Topic {
        match output {
            RosOutput::Disparity => Topic::Disparity,
            RosOutput::Depth => Topic::Depth,
            RosOutput::DepthStd => Topic::DepthStd,
            RosOutput::Points => Topic::Points,
        }
    }
}

/// A 32FC1 image of `values` scaled by `scale`.
fn float_image(header: &Header, w: usize, h: usize, values: &[f32], scale: f64) -> Image {
    let mut data = Vec::with_capacity(values.len() * 4);
    for &v in values {
        data.extend_from_slice(&((f64::from(v) * scale) as f32).to_le_bytes());
    }
    Image {
        header: header.clone(),
        height: h as u32,
        width: w as u32,
        encoding: "32FC1".into(),
        is_bigendian: false,
        step: (w * 4) as u32,
        data,
    }
}

/// The answer of `output` for `map`: a CDR output's message (stamped now, in frame
/// `left_camera`), else the engine's file.
pub fn file(output: DepthMapOutput, map: &DepthMap) -> Result<Vec<u8>, String> {
    let Some(which) = output.ros() else {
        return match output.product() {
            Some(product) => product.encode(map),
            None => Err("the summary is not a file".to_owned()),
        };
    };
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos().min(i64::MAX as u128) as i64);
    let header = Header {
        stamp_ns: now,
        frame_id: "left_camera".to_owned(),
    };
    message(map, &header, Kind::Cdr, which.into())
}

/// The map's messages on [`Topic::ALL`], each with `header` (the pair's stamp and the left
/// camera's frame), serialised as `kind`; `Err` when the map has no rig (no depths).
pub fn messages(map: &DepthMap, header: &Header, kind: Kind) -> Result<Vec<Vec<u8>>, String> {
    Topic::ALL
        .into_iter()
        .map(|topic| message(map, header, kind, topic))
        .collect()
}

/// The message on `topic`.
fn message(map: &DepthMap, header: &Header, kind: Kind, topic: Topic) -> Result<Vec<u8>, String> {
    let (Some(rig), Some(depth)) = (map.rig, map.depth.as_deref()) else {
        return Err("ROS messages carry depths: give the rig's calibration".to_owned());
    };
    let d = &map.disparity;
    let (w, h) = (d.width, d.height);
    let metres = rig.unit().metres();
    let (f, fy) = (rig.focal_px(), rig.focal_y_px());
    let cx = rig.cx().unwrap_or(w as f64 / 2.0);
    let cy = rig.cy().unwrap_or(h as f64 / 2.0);
    let doffs = rig.doffs();
    Ok(match topic {
        Topic::Disparity => {
            // Z = f·t/d holds for the message's d: the pair's doffs is added in.
            let shifted: Vec<f32> = d.data.iter().map(|&v| v + doffs as f32).collect();
            DisparityImage {
                header: header.clone(),
                image: float_image(header, w, h, &shifted, 1.0),
                f: f as f32,
                t: (rig.baseline() * metres) as f32,
                valid_window: RegionOfInterest {
                    height: h as u32,
                    width: w as u32,
                    ..RegionOfInterest::default()
                },
                min_disparity: (f64::from(map.range.min) + doffs) as f32,
                max_disparity: (f64::from(map.range.max) + doffs) as f32,
                // The matcher's disparities are continuous: their smallest step is a float's.
                delta_d: 1.0 / 256.0,
            }
            .encode(kind)
        }
        Topic::Depth => float_image(header, w, h, depth, metres).encode(kind),
        Topic::DepthStd => {
            let nan = vec![f32::NAN; w * h];
            let depth_std = map.depth_std.as_deref().unwrap_or(&nan);
            float_image(header, w, h, depth_std, metres).encode(kind)
        }
        Topic::Points => cloud(map, header, metres).encode(kind),
        Topic::LeftImage => {
            let rgb = map.rgb.clone().unwrap_or_else(|| {
                d.data
                    .iter()
                    .flat_map(|&v| [if v.is_nan() { 0 } else { 128 }; 3])
                    .collect()
            });
            Image {
                header: header.clone(),
                height: h as u32,
                width: w as u32,
                encoding: "rgb8".into(),
                is_bigendian: false,
                step: (w * 3) as u32,
                data: rgb,
            }
            .encode(kind)
        }
        Topic::LeftInfo => {
            CameraInfo::pinhole(header.clone(), [w as u32, h as u32], [f, fy, cx, cy], 0.0)
                .encode(kind)
        }
    })
}

/// The valid points, in metres, with their colour packed as PCL packs it and their σ_Z.
fn cloud(map: &DepthMap, header: &Header, metres: f64) -> PointCloud2 {
    const STEP: usize = 20;
    let found = points(map);
    let mut data = Vec::with_capacity(found.len() * STEP);
    for p in &found {
        for v in p.xyz {
            data.extend_from_slice(&((f64::from(v) * metres) as f32).to_le_bytes());
        }
        let [r, g, b] = p.rgb.map(u32::from);
        data.extend_from_slice(&((r << 16) | (g << 8) | b).to_le_bytes());
        data.extend_from_slice(&((f64::from(p.depth_std) * metres) as f32).to_le_bytes());
    }
    let field = |name: &str, offset: u32| PointField {
        name: name.into(),
        offset,
        datatype: FLOAT32,
        count: 1,
    };
    PointCloud2 {
        header: header.clone(),
        height: 1,
        width: found.len() as u32,
        fields: vec![
            field("x", 0),
            field("y", 4),
            field("z", 8),
            field("rgb", 12),
            field("depth_std", 16),
        ],
        is_bigendian: false,
        point_step: STEP as u32,
        row_step: (found.len() * STEP) as u32,
        data,
        is_dense: true,
    }
}
