//! The run's settings checked before the first frame is sent, as the service checks them:
//! the calibration read for the recording's frames (their size from the first frame whose
//! header reads), the disparity range against the matcher's rules and the calibration's
//! `ndisp`, and an output that needs depths given a calibration. Every fault is named at
//! once, and the run stops before it starts; what is left to go wrong is the frames' own.

use std::path::Path;

use axum::body::Bytes;

use crate::api::error::FieldErrors;
use crate::api::images::{limits, parts::Parts, rig};
use crate::api::wire::depth_map::DepthMapOutput;
use crate::config::DepthMapArgs;
use stereo_core::vision::decode;
use stereo_core::vision::{Preset, Settings};

/// Checks the run's settings for frames like `first_left` (the first of the recording's left
/// frames whose header reads; none when no frame's does). `Err` names every fault.
pub fn check<'a>(
    args: &DepthMapArgs,
    output: &str,
    calibration: Option<&(String, Vec<u8>)>,
    left_frames: impl IntoIterator<Item = &'a Path>,
) -> Result<(), String> {
    let mut problems = FieldErrors::default();
    let depths = serde_json::from_value::<DepthMapOutput>(output.into())
        .is_ok_and(DepthMapOutput::needs_rig);
    if calibration.is_none() && depths {
        problems.add(
            "--output",
            format!("{output} is depths: give the rig's --calibration, or write disparities"),
        );
    }
    let mut ndisp = None;
    if let Some((_, bytes)) = calibration {
        let size = left_frames.into_iter().find_map(|path| {
            let bytes = std::fs::read(path).ok()?;
            decode::dimensions(&bytes).ok()
        });
        let mut parts = vec![("calibration".to_owned(), Bytes::from(bytes.clone()))];
        if let Some(unit) = &args.calibration_unit {
            parts.push(("calibration_unit".to_owned(), Bytes::from(unit.clone())));
        }
        let parts: Parts = parts.into_iter().collect();
        let mut found = FieldErrors::default();
        let given = rig::rig(&parts, size, true, &mut found);
        ndisp = given.and_then(|g| g.max_disparity);
        for fault in found.iter() {
            let field = match fault.field.as_str() {
                "calibration" | "right_calibration" => "--calibration".to_owned(),
                "calibration_unit" => "--calibration-unit".to_owned(),
                other => format!("--calibration ({other})"),
            };
            problems.add(&field, fault.message.clone());
        }
    }
    let mut range = FieldErrors::default();
    limits::params(settings(args), ndisp, &mut range);
    for fault in range.iter() {
        problems.add(
            &format!("--{}", fault.field.replace('_', "-")),
            fault.message.clone(),
        );
    }
    if problems.is_empty() {
        return Ok(());
    }
    let said: Vec<String> = problems
        .iter()
        .map(|p| format!("{}: {}", p.field, p.message))
        .collect();
    Err(format!(
        "the run's settings are refused, before any frame was sent:\n  {}",
        said.join("\n  ")
    ))
}

/// The matcher's settings the run's options ask for, as `/depth-map`'s query gives them.
pub fn settings(args: &DepthMapArgs) -> Settings {
    Settings {
        preset: [Preset::Accurate, Preset::Fast]
            .into_iter()
            .find(|p| args.preset.as_deref() == Some(p.name())),
        min_disparity: args.min_disparity,
        max_disparity: args.max_disparity,
        max_disparity_std: args.max_disparity_std,
        ..Settings::default()
    }
}
