//! What the image routes (`/depth-map`, `/match`, and the calibration and rectification routes
//! after them) share, one concern a file:
//! - [`form`]: the multipart form read after the request's admission, and
//!   [`form::ImagePair`], the extractor that opens every image route (parts, sizes, the pair's
//!   check, the rig);
//! - [`parts`]: the form's parts by name;
//! - [`board`]: the `board` part, a chessboard or a ChArUco board;
//! - [`rig`]: the rig from a `rig` part or a `calibration` file, through the one constructor
//!   every rig goes through;
//! - [`maps`]: the rectification maps of the raw rigs seen lately, cached within the budget;
//! - [`job`]: the engine's depth job planned with what a request sent, its refusals named,
//!   and the memory its work reserves;
//! - [`ros`]: a depth map as the ROS 2 messages `stereo_image_proc` publishes;
//! - [`output`]: a file answer with its media type and name, and `Server-Timing`;
//! - [`limits`]: what the server accepts: image sizes, the matcher's settings mapped onto the
//!   query's names, and what to shrink when a request cannot fit;
//! - [`pools`]: thread pools lent to a stream's frames in work, one a frame, so that two
//!   frames matched side by side do not wait on each other's tasks;
//! - [`stream`]: what the depth streams share and are held to (the budget, the cap on open
//!   streams, the idle and write timeouts, the frame limit), with [`stream_frames`], a frame's
//!   parts and files;
//! - [`work`]: a compute slot taken and the memory reserved when the work starts (not while
//!   the body arrives), the work run on a blocking thread that stops when its request is
//!   abandoned, the pair decoded, the matcher's stages for `Server-Timing`.
//!
//! It sits between [`super::validate`] and [`super::routes`]: the routes use it, it uses
//! none of them.

pub mod board;
pub mod form;
pub mod job;
pub mod limits;
pub mod maps;
pub mod output;
pub mod parts;
pub mod pools;
pub mod rig;
pub mod ros;
pub mod stream;
pub mod stream_frames;
pub mod work;

pub use form::{ImageForm, ImagePair, Job};
pub use parts::Parts;

use axum::extract::FromRef;

use crate::api::body_limit::{BodyLimit, LimitOption};

/// What the heavy group's handlers see. Its memory budget reaches them as the
/// [`crate::budget::Reservation`] the group's guard made for the request.
#[derive(Debug, Clone)]
pub struct HeavyState {
    pub body_limit: BodyLimit,
    /// The rectification maps of the raw rigs seen lately.
    pub maps: std::sync::Arc<maps::MapCache>,
    /// The group's concurrency limit: a slot taken by each request when its work starts.
    pub slots: crate::budget::Slots,
    /// The largest image decoded (`--max-image-pixels`, [`stereo_core::vision::decode::MAX_SIDE`] a side).
    pub image_limits: stereo_core::vision::decode::DecodeLimits,
    /// What the depth streams share and are held to.
    pub streams: stream::Streams,
}

impl Default for HeavyState {
    fn default() -> Self {
        Self {
            body_limit: BodyLimit {
                bytes: crate::config::DEFAULT_HEAVY_BODY_LIMIT,
                set_by: LimitOption::HeavyBody,
            },
            maps: std::sync::Arc::default(),
            slots: crate::budget::Slots::new(crate::config::default_heavy_concurrency()),
            image_limits: limits::decode_limits(crate::config::DEFAULT_MAX_IMAGE_PIXELS),
            streams: stream::Streams::default(),
        }
    }
}

impl FromRef<HeavyState> for BodyLimit {
    fn from_ref(state: &HeavyState) -> Self {
        state.body_limit
    }
}
