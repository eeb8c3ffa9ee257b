//! ROS recordings without ROS: what a stereo rig records and what its depth maps answer, in
//! ROS 2's and ROS 1's own formats, for the service's `depth-map --bag` and its answers in
//! ROS 2 messages. No HTTP, serde or async.
//!
//! - [`wire`]: the two serialisations, CDR (ROS 2) and ROS 1's, with each length checked
//!   before anything is allocated;
//! - [`msg`]: `Image`, `CompressedImage`, `CameraInfo`, `DisparityImage`, `PointCloud2`,
//!   read and written in either, and their ROS 2 definitions;
//! - [`bag`]: a recording's messages in order, from an MCAP file, a rosbag2 folder or a
//!   ROS 1 bag, a record at a time;
//! - [`ros1`]: the ROS 1 bag's records, read and written;
//! - [`out`]: ROS 2 messages written to an MCAP file.

pub mod bag;
pub mod msg;
pub mod out;
pub mod ros1;
pub mod wire;

pub use bag::{Bag, BagError, Message};
pub use wire::Kind;
