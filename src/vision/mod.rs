//! Stereo vision on images: the step before the formula, from a rectified pair to dense
//! disparities (the `/depth-map` engine) and correspondences.
//!
//! The rule for everything in this module, as for [`crate::physics`]: pure functions on pixel
//! buffers and plain numbers. No HTTP, no serde, no async in any signature: the heavy route
//! group's handlers decode the request, call in here on a blocking thread, and encode the
//! answer. That keeps the engine testable on synthetic images, benchmarkable on its own, and
//! usable from the fuzz target without a server.
//!
//! The matcher, stage by stage ([`disparity`]):
//! - [`census`]: a 9 × 7 census transform of both images (62 bits a pixel);
//! - [`cost`]: the Hamming cost volume, `[y][x][d]`, one byte a cell;
//! - [`sgm`]: semi-global aggregation along 8 paths, two passes on two cores;
//! - [`refine`]: winner-takes-all with uniqueness and a sub-pixel fit, the left-right check,
//!   speckle removal, a 3 × 3 median and optional filling.
//!
//! Around it: [`decode`] reads PNG and JPEG under limits, [`encode`] writes PFM, NPY, 16-bit
//! PNG, the colour preview and PLY, and [`synthetic`] renders pairs with exact ground truth.

pub mod census;
pub mod cost;
pub mod decode;
pub mod encode;
pub mod refine;
pub mod sgm;
pub mod simd;
pub mod synthetic;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use rayon::prelude::*;

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

/// The matcher's parameters. [`Params::default`] holds the tuned defaults; the README's
/// Performance section gives the measurements that chose them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Params {
    /// The smallest disparity searched, in pixels.
    pub min_disparity: i32,
    /// How many disparities are searched: `min_disparity .. min_disparity + count`.
    pub count: usize,
    pub penalties: sgm::Penalties,
    /// How much better (in percent) the best cost must be than any other more than one pixel
    /// away.
    pub uniqueness: u32,
    /// The left-right check's tolerance in pixels; `None` skips the check.
    pub lr_tolerance: Option<f32>,
    pub subpixel: Subpixel,
    /// Regions smaller than this many pixels are removed (0: no speckle removal)…
    pub speckle_size: usize,
    /// … where neighbours within this many pixels of disparity are one region.
    pub speckle_range: f32,
    /// A 3 × 3 median filter of the result.
    pub median: bool,
    /// Fill invalid pixels from their row's background instead of leaving them invalid.
    pub fill: bool,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            min_disparity: 0,
            count: 64,
            penalties: sgm::Penalties {
                p1: 12,
                p2: 64,
                edge: 16,
            },
            uniqueness: 5,
            lr_tolerance: Some(1.0),
            subpixel: Subpixel::Equiangular,
            speckle_size: 100,
            speckle_range: 2.0,
            median: true,
            fill: false,
        }
    }
}

/// A dense disparity map: one value a pixel, in pixels (`x_left − x_right`), NaN where invalid.
#[derive(Debug, Clone, PartialEq)]
pub struct Disparity {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f32>,
}

/// How long each stage took.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Timings {
    /// Census transform and cost volume.
    pub cost: Duration,
    pub aggregate: Duration,
    /// Winner-takes-all, left-right check and the filters.
    pub refine: Duration,
}

/// The bytes the matcher holds at its peak for a `width × height` pair searching `count`
/// disparities: the cost volume (one byte a cell) and the two passes' sums (two bytes a cell
/// each), plus per-pixel buffers (census signatures, grey images, the disparity maps).
pub fn bytes_needed(width: usize, height: usize, count: usize) -> usize {
    let pixels = width.saturating_mul(height);
    pixels
        .saturating_mul(cost::stride(count))
        .saturating_mul(5)
        .saturating_add(pixels.saturating_mul(48))
}

/// The disparity map of a rectified pair (the same size), or [`Cancelled`] when `cancel` was set
/// before the matcher finished; it is checked between stages and between rows.
pub fn disparity(
    left: &Gray,
    right: &Gray,
    params: &Params,
    cancel: &AtomicBool,
) -> Result<(Disparity, Timings), Cancelled> {
    let (w, h) = (left.width, left.height);
    let checkpoint = || {
        if cancel.load(Ordering::Relaxed) {
            Err(Cancelled)
        } else {
            Ok(())
        }
    };
    let mut timings = Timings::default();

    let started = Instant::now();
    let (cl, cr) = rayon::join(|| census::transform(left), || census::transform(right));
    checkpoint()?;
    let volume = cost::volume(&cl, &cr, w, h, params.min_disparity, params.count);
    drop((cl, cr));
    timings.cost = started.elapsed();
    checkpoint()?;

    let started = Instant::now();
    let sums = sgm::aggregate(&volume, left, params.penalties, cancel)?;
    let stride = volume.stride;
    drop(volume);
    timings.aggregate = started.elapsed();
    checkpoint()?;

    let started = Instant::now();
    let row = w * stride;
    let mut data: Vec<f32> = sums
        .forward
        .par_chunks(row)
        .zip(sums.backward.par_chunks(row))
        .flat_map_iter(|(f, b)| {
            let mut won = refine::winners(
                f,
                b,
                w,
                stride,
                params.count,
                params.uniqueness,
                params.subpixel,
            );
            if let Some(tolerance) = params.lr_tolerance {
                refine::left_right(&mut won.left, &won.right, tolerance);
            }
            won.left
        })
        .collect();
    drop(sums);
    checkpoint()?;
    refine::speckles(&mut data, w, params.speckle_size, params.speckle_range);
    if params.median {
        data = refine::median(&data, w);
    }
    if params.fill {
        refine::fill(&mut data, w);
    }
    let min = params.min_disparity as f32;
    for d in &mut data {
        *d += min;
    }
    timings.refine = started.elapsed();
    Ok((
        Disparity {
            width: w,
            height: h,
            data,
        },
        timings,
    ))
}
