//! The `depth-map` command's frames matched in this process: the engine's
//! [`stereo_core::pipeline::depth_map`] called directly, with the depth job planned once for
//! each frame size the recording has (its rectification maps built once with it), and
//! each frame judged as the service judges it: the image limits, the pair's sizes, the memory
//! budget, the same sentences naming the same files.

use std::collections::HashMap;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::images::{job, limits, ros};
use crate::api::wire::depth_map::{DepthMapOutput, DepthMapSummary};
use crate::api::wire::rig::CalibratedRig;
use crate::config::Config;
use stereo_core::camera::LatlonOptions;
use stereo_core::pipeline::{self, Answer, DepthJob, DepthMap, Maps, Product, RigInput};
use stereo_core::vision::Settings;
use stereo_core::vision::decode::{self, DecodeLimits, Decoded};
use stereo_core::vision::encode;
use stereo_core::vision::pixels::{self, Layout};

/// A frame as it came: a PNG or JPEG file (a folder's, a `CompressedImage`'s), or pixels (a
/// ROS `Image`'s rows).
pub enum Frame {
    File(Vec<u8>),
    Pixels {
        width: u32,
        height: u32,
        layout: Layout,
        step: usize,
        data: Vec<u8>,
    },
}

impl Frame {
    /// Its size, from the file's header or the message's.
    fn size(&self) -> Result<(u32, u32), decode::DecodeError> {
        match self {
            Frame::File(bytes) => decode::dimensions(bytes),
            Frame::Pixels { width, height, .. } => Ok((*width, *height)),
        }
    }

    fn decode(&self, limits: DecodeLimits, colour: bool) -> Result<Decoded, decode::DecodeError> {
        match self {
            Frame::File(bytes) => decode::decode(bytes, limits, colour),
            Frame::Pixels {
                width,
                height,
                layout,
                step,
                data,
            } => pixels::read(*width, *height, *layout, *step, data, limits, colour),
        }
    }
}

impl Frame {
    /// The frame as a file a service reads: a PNG or JPEG as it came, pixels as a PNG (16-bit
    /// grey for 16-bit frames, else RGB).
    pub fn into_file(self) -> Result<Vec<u8>, String> {
        let (width, height, layout, step, data) = match self {
            Frame::File(bytes) => return Ok(bytes),
            Frame::Pixels {
                width,
                height,
                layout,
                step,
                data,
            } => (width, height, layout, step, data),
        };
        // The pixels are in memory already: their count is bounded by their bytes.
        let limits = DecodeLimits {
            max_side: u32::MAX,
            max_pixels: u64::MAX,
        };
        let sixteen = matches!(layout, Layout::Mono16 { .. } | Layout::Bayer16 { .. });
        let read = pixels::read(width, height, layout, step, &data, limits, !sixteen)
            .map_err(|e| limits::describe(&e, limits))?;
        let (w, h) = (width as usize, height as usize);
        Ok(match read.rgb {
            Some(rgb) => encode::png_rgb(w, h, &rgb),
            None => encode::png16(w, h, &read.grey.data),
        })
    }
}

/// Faults as `name: sentence`, the parts `left` and `right` named by `names`.
fn said(names: [&str; 2], faults: &[FieldError]) -> String {
    faults
        .iter()
        .map(|f| {
            let name = match f.field.as_str() {
                "left" => names[0],
                "right" => names[1],
                other => other,
            };
            format!("{name}: {}", f.message)
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// A frame size's depth job, or the faults that refuse every frame of it.
type Resolution = Result<Arc<DepthJob>, Vec<FieldError>>;

/// What every frame of the run shares.
pub struct Engine {
    output: DepthMapOutput,
    settings: Settings,
    /// Rectified to latitude-longitude with these (`--projection`), or `None`.
    latlon: Option<LatlonOptions>,
    /// The calibration, parsed once as the service parses it (by the run's preflight).
    calibration: RigInput,
    limits: DecodeLimits,
    memory_budget: usize,
    /// Each frame size's job, planned (its maps built) the first time a frame of that size
    /// comes.
    resolved: Mutex<HashMap<(u32, u32), Resolution>>,
}

/// A pair's answer: its file's bytes and the warnings about it.
pub type Made = (Vec<u8>, Vec<String>);

impl Engine {
    /// The engine of a run writing `output` with the matcher's `settings` (and, with `latlon`,
    /// rectified to latitude-longitude) and the rig's `calibration` (parsed by the run's
    /// preflight), under `config`'s image limits and memory budget.
    pub fn new(
        config: &Config,
        output: DepthMapOutput,
        (settings, latlon): (Settings, Option<LatlonOptions>),
        calibration: RigInput,
    ) -> Engine {
        // The matcher's buffer pools and glibc's thresholds as the service sets them, so that a
        // run in process goes as fast as the service it would otherwise call.
        stereo_core::vision::huge_pages::tune_for_budget(config.heavy.memory_budget);
        Engine {
            output,
            settings,
            latlon,
            calibration,
            limits: limits::decode_limits(config.heavy.max_image_pixels),
            memory_budget: config.heavy.memory_budget,
            resolved: Mutex::new(HashMap::new()),
        }
    }

    /// One pair's file (and warnings), or each fault as `file: sentence` (the service's
    /// sentences, its parts named by `names`, the pair's files or frames).
    pub fn depth_map(&self, names: [&str; 2], frames: [&Frame; 2]) -> Result<Made, String> {
        self.made(frames).map_err(|faults| said(names, &faults))
    }

    /// One pair's depth map, with the rig's depths and σ and the left image's colours (what
    /// ROS messages carry), or each fault as [`Engine::depth_map`] names them.
    pub fn ros_map(&self, names: [&str; 2], frames: [&Frame; 2]) -> Result<DepthMap, String> {
        let products = [Product::DepthNpy, Product::DepthStdNpy, Product::PointsPly];
        self.map(frames, &products)
            .map(|(map, _, _)| map)
            .map_err(|faults| said(names, &faults))
    }

    fn made(&self, frames: [&Frame; 2]) -> Result<Made, Vec<FieldError>> {
        let products: Vec<Product> = self.output.needs().into_iter().collect();
        let (map, planned, decoded) = self.map(frames, &products)?;
        let bytes = match self.output.is_file() {
            true => ros::file(self.output, &map).map_err(|e| vec![FieldError::new("output", e)])?,
            false => {
                let rig = planned.calibrated().map(|c| CalibratedRig::from(&c.rig));
                let summary = DepthMapSummary::of(&map, planned.params(), rig, decoded);
                serde_json::to_vec(&summary)
                    .map_err(|e| vec![FieldError::new("output", e.to_string())])?
            }
        };
        Ok((bytes, map.warnings))
    }

    /// The pair matched for `products` (its job, and how long decoding took), judged as the
    /// service judges a request: the limits, the pair's sizes, the memory budget.
    fn map(
        &self,
        [left, right]: [&Frame; 2],
        products: &[Product],
    ) -> Result<(DepthMap, Arc<DepthJob>, Duration), Vec<FieldError>> {
        let size = |name: &str, frame: &Frame| {
            frame
                .size()
                .map_err(|e| FieldError::new(name, limits::describe(&e, self.limits)))
        };
        let (l, r) = match (size("left", left), size("right", right)) {
            (Ok(l), Ok(r)) => (l, r),
            (l, r) => return Err([l.err(), r.err()].into_iter().flatten().collect()),
        };
        let mut problems = FieldErrors::default();
        if let Err(ApiError::Oversized(errors)) =
            limits::check_pair(l, r, self.limits, &mut problems)
        {
            return Err(errors);
        }
        if !problems.is_empty() {
            return Err(problems.prefixed(""));
        }
        let planned = self.resolve(l)?;
        let need = planned.need(l, Answer::Files(products.to_vec()));
        if need.bytes(need.count) > self.memory_budget {
            return Err(limits::shrink(
                need.size,
                need.count,
                self.memory_budget,
                |n| need.bytes(n),
            ));
        }
        let started = Instant::now();
        let colour = products.iter().any(|p| p.wants_colour());
        let decode = |name: &str, frame: &Frame, colour: bool| {
            frame
                .decode(self.limits, colour)
                .map_err(|e| FieldError::new(name, limits::describe(&e, self.limits)))
        };
        let (left, right) = match rayon::join(
            || decode("left", left, colour),
            || decode("right", right, false),
        ) {
            (Ok(l), Ok(r)) => (l, r),
            (l, r) => return Err([l.err(), r.err()].into_iter().flatten().collect()),
        };
        let decoded = started.elapsed();
        let depth_std = products.is_empty() || products.iter().any(|p| p.wants_depth_std());
        let request = planned.request(colour, depth_std);
        let map = pipeline::depth_map(left, right, request, &AtomicBool::new(false)).map_err(
            |stopped| match stopped.advice() {
                Some(advice) => vec![FieldError::new("max_disparity", advice)],
                None => vec![FieldError::new("left", "was not matched: cancelled")],
            },
        )?;
        Ok((map, planned, decoded))
    }

    /// The job for frames of `size`, planned once.
    fn resolve(&self, size: (u32, u32)) -> Resolution {
        let mut cache = self.resolved.lock().unwrap_or_else(|e| e.into_inner());
        cache
            .entry(size)
            .or_insert_with(|| self.planned(size).map(Arc::new))
            .clone()
    }

    fn planned(&self, size: (u32, u32)) -> Result<DepthJob, Vec<FieldError>> {
        let mut problems = FieldErrors::default();
        let asked = job::Asked {
            rectify: None,
            alpha: None,
            latlon: self.latlon,
            settings: self.settings,
            prefix: "",
        };
        let planned = job::plan_at(&self.calibration, size, asked, &mut problems);
        match planned {
            Some(planned) if problems.is_empty() => {
                Ok(planned.with_maps(|raw| Arc::new(Maps::build(raw))))
            }
            _ => Err(problems.prefixed("")),
        }
    }
}
