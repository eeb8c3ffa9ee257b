//! The engine's use cases as plain functions over typed inputs, what the service's routes and
//! its `depth-map` command call: a calibration resolved once for a size and a rectify mode
//! ([`calibrated`]), raw frames rectified through maps built once ([`rectify`]), and a depth
//! map with each pixel's σ ([`depth`]; in latitude-longitude, [`latlon`]; in the raw left
//! frame, [`left_frame`]) and the files it is written as ([`files`]).
//!
//! A depth map from two images and a calibration file, without the service:
//!
//! ```
//! use std::sync::atomic::AtomicBool;
//! use stereo_core::calibration::files::{self, ReadOptions, Source};
//! use stereo_core::pipeline::{Calibrated, Product, Request, depth_map};
//! use stereo_core::vision::{Params, decode, encode, synthetic};
//!
//! // Two PNGs of a rendered scene (a box 22 px of disparity away), and the rig's Middlebury file.
//! let scene = synthetic::render(&synthetic::layered(160, 120));
//! let (left_png, right_png) = (encode::png_rgb(160, 120, &scene.left_rgb), encode::png_rgb(160, 120, &scene.right_rgb));
//! let calib = "cam0=[400 0 80; 0 400 60; 0 0 1]\ncam1=[400 0 80; 0 400 60; 0 0 1]\n\
//!              doffs=0\nbaseline=120\nwidth=160\nheight=120\nndisp=48\n";
//!
//! let source = Source { text: calib, right_text: None, format: None, kitti_pair: None, alpha: None, image_size: None };
//! let read = files::read(source, ReadOptions::default()).expect("a calibration");
//! let calibrated = Calibrated::from_file(read, Some((160, 120))).expect("for these images");
//! let limits = decode::DecodeLimits { max_side: 8192, max_pixels: 1 << 25 };
//! let left = decode::decode(&left_png, limits, false).expect("a PNG");
//! let right = decode::decode(&right_png, limits, false).expect("a PNG");
//! let params = Params::default();
//! let request = Request { params: &params, calibrated: Some(&calibrated), maps: None, colour: false, depth_std: true, sparse: false };
//! let map = depth_map(left, right, request, &AtomicBool::new(false)).expect("not cancelled");
//!
//! // The box, in the middle of the left image: Z = f·B / d = 400 × 120 mm / 22 px.
//! let z = map.depth.as_ref().unwrap()[60 * 160 + 48];
//! assert!((z - 400.0 * 120.0 / 22.0).abs() < 30.0, "{z}");
//! let npy = Product::DepthNpy.encode(&map).unwrap(); // what numpy.load reads
//! assert_eq!(&npy[1..6], b"NUMPY");
//! ```

pub mod calibrate;
pub mod calibrated;
pub mod check;
pub mod depth;
pub mod files;
pub mod job;
pub mod latlon;
pub mod left_frame;
pub mod matches;
pub mod range;
pub mod rectify;
pub mod rig_input;
pub mod spread;

pub use crate::vision::sgm::Paths;
pub use calibrated::{Calibrated, PlanFault, RectifyMode, Sent, SizeFault, plan, raw_rig};
pub use depth::{DepthMap, Matched, Request, depth_map, matched};
pub use files::Product;
pub use job::{Answer, DepthJob, JobFaults, Need, Rectify};
pub use range::{Chosen, RangeUsed, Stopped};
pub use rectify::Maps;
pub use rig_input::{AtFault, CalibrationFile, RigInput, StdBeside};
pub use spread::{Spread, Spreads, spread};
