//! The `depth-map` command's frames matched in this process: the engine's
//! [`stereo_core::pipeline::depth_map`] called directly, with the calibration read and resolved
//! once for each frame size the recording has (its rectification maps built once with it), and
//! each frame judged as the service judges it: the image limits, the pair's sizes, the memory
//! budget, the same sentences naming the same files.

use std::collections::HashMap;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use axum::body::Bytes;

use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::images::{limits, parts::Parts, raw, rig};
use crate::api::routes::depth_map;
use crate::api::wire::depth_map::{DepthMapOutput, DepthMapSummary};
use crate::api::wire::rig::CalibratedRig;
use crate::config::Config;
use stereo_core::pipeline::{self, Calibrated, Maps, Request, Sent};
use stereo_core::vision::decode::{self, DecodeLimits};
use stereo_core::vision::{Params, Settings};

/// A calibration resolved for one frame size: the rig (the rectified one for raw frames), the
/// maps of raw frames, and the matcher's parameters with the file's `ndisp`.
struct Resolved {
    calibrated: Option<Calibrated>,
    maps: Option<Maps>,
    params: Params,
}

/// A frame size's calibration and parameters, or the faults that refuse every frame of it.
type Resolution = Result<Arc<Resolved>, Vec<FieldError>>;

/// What every frame of the run shares.
pub struct Engine {
    output: DepthMapOutput,
    settings: Settings,
    /// The calibration's parts as the service reads them (`calibration`, `calibration_unit`).
    calibration: Option<Parts>,
    limits: DecodeLimits,
    memory_budget: usize,
    /// Each frame size's calibration, resolved the first time a frame of that size comes.
    resolved: Mutex<HashMap<(u32, u32), Resolution>>,
}

/// A pair's answer: its file's bytes and the warnings about it.
pub type Made = (Vec<u8>, Vec<String>);

impl Engine {
    /// The engine of a run writing `output` with the matcher's `settings`, the calibration file's
    /// bytes and unit when there is one, under `config`'s image limits and memory budget.
    pub fn new(
        config: &Config,
        output: DepthMapOutput,
        settings: Settings,
        calibration: Option<(&[u8], Option<&str>)>,
    ) -> Engine {
        let calibration = calibration.map(|(bytes, unit)| {
            let mut parts = vec![("calibration".to_owned(), Bytes::copy_from_slice(bytes))];
            if let Some(unit) = unit {
                parts.push(("calibration_unit".to_owned(), Bytes::from(unit.to_owned())));
            }
            parts.into_iter().collect()
        });
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
        let resolved = self.resolve(l)?;
        let need = raw::match_need(
            resolved.calibrated.as_ref().and_then(|c| c.raw.as_deref()),
            l,
            resolved.params.most_searched(),
            |w, h, n| depth_map::bytes_needed(w, h, n, self.output),
        );
        if (need.need)(need.count) > self.memory_budget {
            return Err(limits::shrink(
                need.size,
                need.count,
                self.memory_budget,
                &need.need,
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
        let request = Request {
            params: &resolved.params,
            calibrated: resolved.calibrated.as_ref(),
            maps: resolved.maps.as_ref(),
            colour,
            depth_std: self.output.wants_depth_std(),
        };
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
                let rig = resolved
                    .calibrated
                    .as_ref()
                    .map(|c| CalibratedRig::from(&c.rig));
                let summary = DepthMapSummary::of(&map, &resolved.params, rig, decoded);
                serde_json::to_vec(&summary)
                    .map_err(|e| vec![FieldError::new("output", e.to_string())])?
            }
        };
        Ok((bytes, map.warnings))
    }

    /// The calibration and parameters for frames of `size`, resolved once.
    fn resolve(&self, size: (u32, u32)) -> Resolution {
        let mut cache = self.resolved.lock().unwrap_or_else(|e| e.into_inner());
        cache
            .entry(size)
            .or_insert_with(|| self.resolved_for(size).map(Arc::new))
            .clone()
    }

    fn resolved_for(&self, size: (u32, u32)) -> Result<Resolved, Vec<FieldError>> {
        let mut problems = FieldErrors::default();
        let calibrated = self
            .calibration
            .as_ref()
            .and_then(|parts| rig::rig(parts, Some(size), true, &mut problems));
        let sent = if self.calibration.is_some() {
            Sent::Calibration
        } else {
            Sent::Nothing
        };
        let mode = pipeline::RectifyMode::Auto;
        let (calibrated, raw) =
            match pipeline::plan(calibrated.as_ref(), sent, Some(size), mode, None) {
                Ok(Some(rectifying)) => {
                    let raw = rectifying.raw.clone();
                    (Some(rectifying), raw)
                }
                Ok(None) => (calibrated, None),
                Err(fault) => {
                    problems.add("calibration", fault.to_string());
                    (None, None)
                }
            };
        let ndisp = calibrated.as_ref().and_then(|c| c.max_disparity);
        let params = limits::params(self.settings, ndisp, &mut problems);
        match params {
            Some(params) if problems.is_empty() => Ok(Resolved {
                maps: raw.as_deref().map(Maps::build),
                calibrated,
                params,
            }),
            _ => Err(problems.prefixed("")),
        }
    }
}
