//! The run's settings checked before the first frame is sent, as the service checks them:
//! the calibration read for the recording's frames (their size from the first frame whose
//! header reads), the disparity range against the matcher's rules and the calibration's
//! `ndisp`, and an output that needs depths given a calibration. Every fault is named at
//! once, and the run stops before it starts; what is left to go wrong is the frames' own.

use std::path::Path;

use crate::api::error::FieldErrors;
use crate::api::images::{job, rig};
use crate::api::wire::depth_map::DepthMapOutput;
use crate::api::wire::images::RigParts;
use crate::config::DepthMapArgs;
use stereo_core::pipeline::{RigInput, Sent};
use stereo_core::vision::decode;
use stereo_core::vision::{Preset, Settings};

/// Checks the run's settings for frames like `first_left` (the first of the recording's left
/// frames whose header reads; none when no frame's does): the calibration as the run's engine
/// takes it, parsed once (read for that size), or `Err` naming every fault.
pub fn check<'a>(
    args: &DepthMapArgs,
    output: &str,
    calibration: Option<&(String, Vec<u8>)>,
    left_frames: impl IntoIterator<Item = &'a Path>,
) -> Result<RigInput, String> {
    let mut problems = FieldErrors::default();
    let depths = serde_json::from_value::<DepthMapOutput>(output.into())
        .is_ok_and(DepthMapOutput::needs_rig);
    if calibration.is_none() && depths {
        problems.add(
            "--output",
            format!("{output} is depths: give the rig's --calibration, or write disparities"),
        );
    }
    let (mut given, mut input, mut size) = (None, Some(RigInput::Nothing), None);
    let mut sent = Sent::Nothing;
    if let Some((_, bytes)) = calibration {
        size = left_frames.into_iter().find_map(|path| {
            let bytes = std::fs::read(path).ok()?;
            decode::dimensions(&bytes).ok()
        });
        let parts = RigParts::calibration(bytes, args.calibration_unit.as_deref());
        sent = parts.sent();
        let mut found = FieldErrors::default();
        (input, given) = rig::parsed(&parts, size, true, &mut found);
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
    let asked = job::Asked {
        rectify: None,
        alpha: None,
        settings: settings(args),
        prefix: "",
    };
    job::plan(given, sent, size, asked, &mut range);
    for fault in range.iter() {
        problems.add(
            &format!("--{}", fault.field.replace('_', "-")),
            fault.message.clone(),
        );
    }
    if let Some(input) = input.filter(|_| problems.is_empty()) {
        return Ok(input);
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
