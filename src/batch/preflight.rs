//! The run's settings checked before the first frame is sent, as the service checks them:
//! the calibration read for the recording's frames (their size from the first frame whose
//! header reads), the disparity range against the matcher's rules and the calibration's
//! `ndisp`, and an output that needs depths given a calibration. Every fault is named at
//! once, and the run stops before it starts; what is left to go wrong is the frames' own.

use axum::body::Bytes;

use crate::api::error::FieldErrors;
use crate::api::images::{job, rig};
use crate::api::wire::depth_map::DepthMapOutput;
use crate::api::wire::images::RigParts;
use crate::config::DepthMapArgs;
use stereo_core::camera::LatlonOptions;
use stereo_core::pipeline::{RigInput, Sent};
use stereo_core::vision::{Preset, Settings};

/// The rig's parts as the run sends them: `(name, file name, bytes)` (a `--calibration` file
/// and its unit, or the files a bag's CameraInfo make), the names their faults take (the
/// `calibration` and `right_calibration` parts'), and the frames' size where known (the first
/// left frame whose header reads, or the CameraInfo's).
#[derive(Debug, Clone)]
pub struct Rig {
    pub parts: Vec<(String, Option<String>, Vec<u8>)>,
    pub labels: [String; 2],
    pub size: Option<(u32, u32)>,
}

/// Checks the run's settings: the calibration as the run's engine takes it, parsed once
/// (read for the frames' size), or `Err` naming every fault.
pub fn check(args: &DepthMapArgs, output: &str, rig: Option<&Rig>) -> Result<RigInput, String> {
    let mut problems = FieldErrors::default();
    let depths = serde_json::from_value::<DepthMapOutput>(output.into())
        .is_ok_and(DepthMapOutput::needs_rig);
    if rig.is_none() && depths {
        problems.add(
            "--output",
            format!("{output} is depths: give the rig's --calibration, or write disparities"),
        );
    }
    let (mut given, mut input, mut size) = (None, Some(RigInput::Nothing), None);
    let mut sent = Sent::Nothing;
    if let Some(sent_rig) = rig {
        size = sent_rig.size;
        let mut parts = RigParts::default();
        for (name, _, bytes) in &sent_rig.parts {
            parts.set(name, Bytes::copy_from_slice(bytes));
        }
        sent = parts.sent();
        let mut found = FieldErrors::default();
        (input, given) = rig::parsed(&parts, size, true, &mut found);
        for fault in found.iter() {
            let field = match fault.field.as_str() {
                "calibration" => sent_rig.labels[0].clone(),
                "right_calibration" => sent_rig.labels[1].clone(),
                "calibration_unit" => "--calibration-unit".to_owned(),
                other => format!("{} ({other})", sent_rig.labels[0]),
            };
            problems.add(&field, fault.message.clone());
        }
    }
    let mcap = super::sink::is_mcap(&args.out);
    if mcap && args.projection.as_deref() == Some("latlon") {
        problems.add(
            "--projection",
            format!(
                "latlon cannot be written to an .mcap --out: {}",
                job::ROS_NOT_LATLON
            ),
        );
    }
    let mut range = FieldErrors::default();
    let asked = job::Asked {
        rectify: None,
        alpha: None,
        latlon: latlon(args),
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

/// The latitude-longitude options `--projection` asks for (`auto` only where the lenses see
/// wide); `None` for the pinhole plane, which an .mcap `--out` (ROS images) always is.
pub fn latlon(args: &DepthMapArgs) -> Option<LatlonOptions> {
    let options = match args.projection.as_deref() {
        Some("latlon") => LatlonOptions::default(),
        Some("auto") => LatlonOptions {
            when_wide: true,
            ..LatlonOptions::default()
        },
        _ => return None,
    };
    options.unless_pinhole(super::sink::is_mcap(&args.out))
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
