//! Stereo vision on images: the step before the formula, from a rectified pair to dense
//! disparities (the `/depth-map` engine) and correspondences.
//!
//! The rule for everything in this module, as for [`crate::physics`]: pure functions on pixel
//! buffers and plain numbers. No HTTP, no serde, no async in any signature: the heavy route
//! group's handlers decode the request, call in here on a blocking thread, and encode the
//! answer. That keeps the engine testable on synthetic images, benchmarkable on its own, and
//! usable from the fuzz target without a server.
//!
//! The matcher, stage by stage ([`disparity`]), at each level of a pyramid ([`pyramid`]) when
//! the range is wide: matched over the whole range at the coarsest level, and over a narrow
//! window around what the level above found everywhere below it:
//! - [`census`]: a 9 × 7 census transform of both images (62 bits a pixel), each pixel's
//!   neighbours compared with its Lee-filtered value, the neighbours 1 to 4 pixels apart as
//!   the pair is smooth over (the noise and that spacing measured once, [`PairNoise`]);
//! - [`cost`]: the Hamming cost of each pixel over its window, one byte a cell, made a row at
//!   a time where the passes read it ([`cost::Cells::Made`]), never stored as a volume;
//! - [`sgm`]: semi-global aggregation along 8 paths in two passes, the second handing each
//!   finished row to
//! - [`refine`]: winner-takes-all with uniqueness and a sub-pixel fit, the left-right check;
//!   then, over the whole map,
//! - [`filters`]: speckle removal, a 3 × 3 median, [`plane`]'s planes in flat holes (and σ_d
//!   widened where a value disagrees with its plane), [`sigma`]'s keep rule and optional
//!   filling.
//!
//! The image is matched in horizontal stripes ([`stripes`]), side by side on the cores. The hot
//! loops are dispatched between a portable and an AVX2 build by [`simd`], and the large
//! buffers come from [`huge_pages`] (on transparent huge pages where the kernel allows, kept
//! between stripes and requests in its pools).
//!
//! [`correspond`] (the `/match` engine) runs the same matcher on the rows some points need,
//! [`disparity_probed`] telling it what the matcher saw at each point, and judges each point's
//! match into a status and a confidence.
//!
//! Before it, for raw pairs: [`remap`] reads each raw image through its rectification map
//! (`camera::undistort_rectify_map`), as OpenCV's `remap`; after it, for pairs sent as
//! rectified, [`rows`] checks that matched corners lie on their rows.
//!
//! For a stream's maps, one after another: [`temporal`] averages each pixel with its last values
//! and carries holes over, as librealsense's temporal filter.
//!
//! Around it: [`decode`] reads PNG and JPEG under limits ([`jpeg`] strictly), [`encode`] writes PFM, NPY, 16-bit
//! PNG, the colour preview and PLY, and [`synthetic`] renders pairs with exact ground truth.

pub mod census;
pub mod correspond;
pub mod cost;
pub mod decode;
pub mod encode;
pub mod filters;
pub mod huge_pages;
pub mod jpeg;
mod matcher;
mod params;
pub mod pixels;
pub mod plane;
pub mod pyramid;
pub mod refine;
pub mod remap;
pub mod rows;
pub mod sgm;
pub mod sigma;
pub mod simd;
pub mod sparse;
pub mod stripes;
pub mod survey;
pub mod synthetic;
pub mod temporal;

pub use stripes::{
    MIN_STRIPE_ROWS, NARROW_STRIPE_ROWS, STRIPE_BYTES, STRIPE_MARGIN, STRIPE_ROWS, bytes_needed,
};

pub use params::{
    DEFAULT_MAX_DISPARITY, DEFAULT_MAX_DISPARITY_STD, MAX_DISPARITIES, MAX_DISPARITY_STD_BOUND,
    MAX_P2, ParamFault, Params, Preset, RangeEnd, Setting, Settings,
};

/// A grey image, 16 bits a pixel (8-bit sources are scaled by 257), row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Gray {
    pub width: usize,
    pub height: usize,
    pub data: Vec<u16>,
}

impl Gray {
    /// An image of `width × height` from its pixels; `data.len()` must be `width · height`.
    pub fn new(width: usize, height: usize, data: Vec<u16>) -> Self {
        debug_assert_eq!(data.len(), width * height);
        Self {
            width,
            height,
            data,
        }
    }
}

/// The work was abandoned: its request timed out or its client went away.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cancelled;

/// How the winning disparity is refined between whole pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Subpixel {
    /// Whole pixels only.
    Off,
    /// A parabola through the minimum and its neighbours (OpenCV's choice).
    Parabola,
    /// The equiangular (V) fit, which locks less to whole pixels.
    Equiangular,
}

/// A dense disparity map: one value a pixel, in pixels (`x_left − x_right`), NaN where invalid,
/// with each value's standard deviation ([`sigma`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Disparity {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f32>,
    /// σ_d of each value, in pixels; NaN where the value is.
    pub std: Vec<f32>,
    /// Which values the fill gave (`fill` asked for): empty when it was not.
    pub filled: Vec<bool>,
    /// Which pixels' census window was blank ([`census::blank`]): they matched nothing, and
    /// only a plane may have given them a value. Empty where the map's maker did not judge.
    pub blank: Vec<bool>,
}

pub use matcher::{PairNoise, Probe, Timings, disparity, disparity_probed, disparity_probed_in};
