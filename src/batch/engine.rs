//! The `depth-map` command's frames matched in this process: the engine's
//! [`stereo_core::pipeline::depth_map`] called directly, with the depth job planned once for
//! each frame size the recording has (its rectification maps built once with it), and
//! each frame judged as the service judges it: the image limits, the pair's sizes, the memory
//! budget, the same sentences naming the same files.

use std::collections::HashMap;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::images::{job, limits};
use crate::api::wire::depth_map::{DepthMapOutput, DepthMapSummary};
use crate::api::wire::rig::CalibratedRig;
use crate::config::Config;
use stereo_core::pipeline::{self, Answer, DepthJob, Maps, RigInput};
use stereo_core::vision::Settings;
use stereo_core::vision::decode::{self, DecodeLimits};

/// A frame size's depth job, or the faults that refuse every frame of it.
type Resolution = Result<Arc<DepthJob>, Vec<FieldError>>;

/// What every frame of the run shares.
pub struct Engine {
    output: DepthMapOutput,
    settings: Settings,
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
    /// The engine of a run writing `output` with the matcher's `settings` and the rig's
    /// `calibration` (parsed by the run's preflight), under `config`'s image limits and memory
    /// budget.
    pub fn new(
        config: &Config,
        output: DepthMapOutput,
        settings: Settings,
        calibration: RigInput,
    ) -> Engine {
        // The matcher's buffer pools and glibc's thresholds as the service sets them, so that a
        // run in process goes as fast as the service it would otherwise call.
        stereo_core::vision::huge_pages::tune_for_budget(config.heavy.memory_budget);
        Engine {
            output,
            settings,
            calibration,
            limits: limits::decode_limits(config.heavy.max_image_pixels),
            memory_budget: config.heavy.memory_budget,
            resolved: Mutex::new(HashMap::new()),
        }
    }

    /// One pair's file (and warnings), or each fault as `file: sentence` (the service's
    /// sentences, its parts named by the pair's files).
    pub fn depth_map(
        &self,
        (left, right): (&Path, &Path),
        bytes: [&[u8]; 2],
    ) -> Result<Made, String> {
        let name = |field: &str| match field {
            "left" => left.display().to_string(),
            "right" => right.display().to_string(),
            other => other.to_owned(),
        };
        self.made(bytes).map_err(|faults| {
            faults
                .iter()
                .map(|f| format!("{}: {}", name(&f.field), f.message))
                .collect::<Vec<_>>()
                .join("; ")
        })
    }

    fn made(&self, [left, right]: [&[u8]; 2]) -> Result<Made, Vec<FieldError>> {
        let size = |name: &str, bytes: &[u8]| {
            decode::dimensions(bytes)
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
        let products = self.output.product().into_iter().collect();
        let need = planned.need(l, Answer::Files(products));
        if need.bytes(need.count) > self.memory_budget {
            return Err(limits::shrink(
                need.size,
                need.count,
                self.memory_budget,
                |n| need.bytes(n),
            ));
        }
        let started = Instant::now();
        let colour = self.output.product().is_some_and(|p| p.wants_colour());
        let decode = |name: &str, bytes: &[u8], colour: bool| {
            decode::decode(bytes, self.limits, colour)
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
        let request = planned.request(colour, self.output.wants_depth_std());
        let map = pipeline::depth_map(left, right, request, &AtomicBool::new(false)).map_err(
            |stopped| match stopped.advice() {
                Some(advice) => vec![FieldError::new("max_disparity", advice)],
                None => vec![FieldError::new("left", "was not matched: cancelled")],
            },
        )?;
        let bytes = match self.output.product() {
            Some(product) => product
                .encode(&map)
                .map_err(|e| vec![FieldError::new("output", e)])?,
            None => {
                let rig = planned.calibrated().map(|c| CalibratedRig::from(&c.rig));
                let summary = DepthMapSummary::of(&map, planned.params(), rig, decoded);
                serde_json::to_vec(&summary)
                    .map_err(|e| vec![FieldError::new("output", e.to_string())])?
            }
        };
        Ok((bytes, map.warnings))
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
