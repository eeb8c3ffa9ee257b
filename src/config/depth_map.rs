//! The `depth-map` command's flags: the recording (folders, or a ROS bag with its topics and
//! the stamps' tolerance), the calibration, the output (a folder, or an MCAP file of ROS 2
//! messages under a namespace), the matcher's settings and how the pairs are sent.

use std::path::PathBuf;

use clap::Args;

use super::one_token;
use super::values::count;

/// What `stereo-distance depth-map` reads, how, and where it writes.
#[derive(Debug, Clone, PartialEq, Args)]
#[command(group(clap::ArgGroup::new("input").required(true).args(["left", "frames", "bag"])))]
pub struct DepthMapArgs {
    /// The left camera's frames (PNG or JPEG), paired with --right's by name: the same name,
    /// or the same but for the camera (left/right, l/r, cam0/cam1, im0/im1).
    #[arg(long, value_name = "DIR", requires = "right")]
    pub left: Option<PathBuf>,
    /// The right camera's frames.
    #[arg(long, value_name = "DIR", requires = "left")]
    pub right: Option<PathBuf>,
    /// One folder with both cameras' frames, paired by the camera in their names (left/right,
    /// l/r, cam0/cam1, im0/im1), as the page pairs them.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["left", "right"])]
    pub frames: Option<PathBuf>,
    /// A ROS recording: a ROS 2 bag (its .mcap file, or the rosbag2 folder with its
    /// metadata.yaml) or a ROS 1 .bag. Its frames are paired by header stamp, and each
    /// camera's CameraInfo (beside its images) is the calibration unless --calibration is
    /// given.
    #[arg(long, value_name = "REC", conflicts_with_all = ["left", "right", "frames"])]
    pub bag: Option<PathBuf>,
    /// The bag's left camera's image topic (sensor_msgs/Image or CompressedImage; default:
    /// the one image topic with `left` in its name).
    #[arg(long, value_name = "TOPIC", requires = "bag")]
    pub left_topic: Option<String>,
    /// The bag's right camera's image topic (default: the one with `right` in its name).
    #[arg(long, value_name = "TOPIC", requires = "bag")]
    pub right_topic: Option<String>,
    /// The most two frames' stamps may differ to be a pair, as `5ms` (default: a third of
    /// the left camera's median frame interval).
    #[arg(long, value_name = "TIME", requires = "bag", value_parser = humantime::parse_duration)]
    pub max_skew: Option<std::time::Duration>,
    /// This run's part of the work, I/N (I from 0), as a Kubernetes Indexed Job's pod takes
    /// it (I from its completion index): of a folder of N recordings (.mcap, .bag, rosbag2
    /// folders; the folder without a metadata.yaml), the I-th by name; of one recording, the
    /// I-th of N consecutive time ranges of its pairs.
    #[arg(long, value_name = "I/N", requires = "bag", value_parser = super::values::part)]
    pub part: Option<super::values::Part>,
    /// The namespace of an .mcap output's topics (default: the one the bag's camera topics
    /// share, else /stereo): NS/disparity, NS/depth/image_rect, NS/depth/image_rect_std,
    /// NS/points2, NS/left/image_rect_color, NS/left/camera_info.
    #[arg(long, value_name = "NS")]
    pub out_namespace: Option<String>,
    /// The rig's calibration file (as /depth-map's `calibration` part: OpenCV, ROS, KITTI,
    /// Middlebury); raw frames of raw cameras are rectified first. Without it, disparities only.
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// The calibration file's length unit, where the file does not say (mm, cm, m, in, ft).
    #[arg(long, value_name = "UNIT", requires = "calibration")]
    pub calibration_unit: Option<String>,
    /// Where the maps go: a folder, one file a pair named after its left frame
    /// (`0001.depth.npy`, or a bag frame's stamp, `1700000000.033000000.depth.npy`), or an
    /// .mcap file of ROS 2 messages (disparity, depth and its σ in metres, points, the
    /// rectified left image and its CameraInfo), stamped as the pairs were.
    #[arg(long, value_name = "DIR|FILE.mcap")]
    pub out: PathBuf,
    /// What to write for each pair, as /depth-map's `output` (default: depth.npy with a
    /// calibration, disparity.npy without).
    #[arg(long, value_name = "OUTPUT", value_parser = clap::builder::PossibleValuesParser::new(
        std::iter::once("summary").chain(stereo_core::pipeline::Product::ALL.map(|p| p.name()))
    ))]
    pub output: Option<String>,
    /// The matcher's preset: accurate (the default) or fast.
    #[arg(long, value_name = "PRESET", value_parser = ["accurate", "fast"])]
    pub preset: Option<String>,
    /// The smallest disparity searched, or `auto` to find it from each pair (default: auto
    /// where the end is found, else 0).
    #[arg(long, value_name = "PX|auto", allow_negative_numbers = true)]
    pub min_disparity: Option<stereo_core::vision::RangeEnd>,
    /// The search stops before this disparity, or `auto` to find it from each pair (default:
    /// the calibration's ndisp, else auto).
    #[arg(long, value_name = "PX|auto", allow_negative_numbers = true)]
    pub max_disparity: Option<stereo_core::vision::RangeEnd>,
    /// Leave out each pixel whose disparity's σ_d exceeds this many pixels (as /depth-map's
    /// `max_disparity_std`; default 4).
    #[arg(long, value_name = "PX")]
    pub max_disparity_std: Option<f64>,
    /// The rectified images' projection, as /depth-map's `projection`: pinhole (the
    /// default), latlon (latitude-longitude, for wide and fisheye lenses) or auto (latlon
    /// where the lenses see wider than 100°). An .mcap --out holds ROS images, which are
    /// pinhole: auto gives way there and latlon is refused.
    #[arg(long, value_name = "PROJECTION", value_parser = ["pinhole", "latlon", "auto"])]
    pub projection: Option<String>,
    /// Send the pairs to the service at this address (http://host:port) instead of matching
    /// them here: behind a Kubernetes Service, the heavy Deployment's replicas share them.
    #[arg(long, value_name = "URL")]
    pub server: Option<String>,
    /// Pairs in flight at once (default 2: the next is read and decoded while one is matched,
    /// 20 % more frames a second than one at a time on 2 cores).
    #[arg(long, value_name = "N", value_parser = count::<1, 64>)]
    pub jobs: Option<usize>,
    /// How many times a frame is sent again when the service cannot be reached (refused,
    /// reset) or answers 502, 503 or 504, waiting 0.5 s, 1 s, 2 s … up to 10 s between tries
    /// (with jitter), or as its Retry-After says (default 10: about 50 s, through a pod's
    /// restart or a rolling update); 0 stops at the first.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=100))]
    pub retries: Option<u32>,
    /// Count a pair the service warns about as failed, and write nothing for it (the
    /// warnings are printed either way).
    #[arg(long)]
    pub strict: bool,
    /// The bearer token sent with every frame to a --server that takes tokens.
    #[arg(long, env = "API_TOKEN", value_name = "TOKEN", hide_env_values = true,
          value_parser = one_token)]
    pub token: Option<String>,
}
