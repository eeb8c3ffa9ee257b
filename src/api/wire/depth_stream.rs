//! The messages of `GET /depth-stream` (a WebSocket): the settings message a client opens with,
//! read member by member so that one answer names every bad one, and the JSON messages the
//! server sends (the settings as resolved, each frame's answer, a frame's error). The binary
//! frames and the files each answer is followed by are described in `openapi/asyncapi.yaml`.

use axum::body::Bytes;
use serde::Serialize;
use serde_json::{Map, Value};

use super::calibration_check::CheckAnswer;
use super::de::request;
use super::depth_map::{DepthMapOutput, DepthMapQuery, DepthMapSummary, MatcherParameters};
use super::images::{RIG_PARTS, RigParts};
use super::rig::CalibratedRig;
use crate::api::error::{FieldErrors, Problem};
use crate::api::extract::decode_object;
use stereo_core::pipeline::{Calibrated, check};
use stereo_core::vision::temporal::{self, Counts, Persistence};

/// How the frames of a stream carry the pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Layout {
    /// One image a frame, the left image in its left half and the right in its right half:
    /// what most USB stereo cameras deliver (the default).
    #[default]
    SideBySide,
    /// Both images in one binary message: the left image's length in bytes (4 bytes,
    /// little-endian), the left image, then the right image.
    Pair,
}

impl Layout {
    pub fn name(self) -> &'static str {
        match self {
            Layout::SideBySide => "side_by_side",
            Layout::Pair => "pair",
        }
    }
}

/// The members of a settings message besides the rig's ([`RIG_PARTS`]).
pub const MEMBERS: [&str; 4] = ["layout", "options", "outputs", "temporal"];

/// A stream's settings as the client gave them, every member checked for its shape; what
/// depends on the frames (the rig at their size) is judged by the route.
#[derive(Debug, Default)]
pub struct StreamSettings {
    pub layout: Layout,
    /// `/depth-map`'s query parameters but `output`, as `options`.
    pub options: DepthMapQuery,
    /// The files each answer carries; `None` for the default (the depth and its σ with a
    /// rig, the disparity and its σ without).
    pub outputs: Option<Vec<DepthMapOutput>>,
    /// The members that describe the rig: `rig` as its JSON text, the calibration's as their
    /// text.
    pub rig: RigParts,
    /// The temporal filter, or `None` when it is turned off.
    pub temporal: Option<temporal::Settings>,
}

request! {
    /// The temporal filter's members, each defaulted when absent.
    pub struct TemporalMembers {
        alpha: f64,
        delta: f64,
        persistence: String,
    }
}

/// The most files one answer may carry.
pub const MAX_OUTPUTS: usize = 8;

impl StreamSettings {
    /// Reads a settings message, naming each member at fault.
    pub fn parse(text: &str) -> Result<StreamSettings, FieldErrors> {
        let mut problems = FieldErrors::default();
        let map = match serde_json::from_str::<Value>(text) {
            Ok(Value::Object(map)) => map,
            Ok(_) => {
                problems.add(
                    "settings",
                    "must be a JSON object: {\"layout\": …, \"options\": {…}, \"rig\": {…}}",
                );
                return Err(problems);
            }
            Err(e) => {
                problems.add("settings", format!("is not JSON: {e}"));
                return Err(problems);
            }
        };
        let mut settings = StreamSettings {
            temporal: Some(temporal::Settings::default()),
            ..StreamSettings::default()
        };
        for (key, value) in map {
            match key.as_str() {
                "layout" => match value.as_str() {
                    Some("side_by_side") => settings.layout = Layout::SideBySide,
                    Some("pair") => settings.layout = Layout::Pair,
                    _ => problems.add("layout", "must be \"side_by_side\" or \"pair\""),
                },
                "options" => settings.options = options(value, &mut problems),
                "outputs" => settings.outputs = outputs(&value, &mut problems),
                "temporal" => settings.temporal = temporal_members(value, &mut problems),
                "rig" => match value {
                    Value::Object(_) => {
                        settings.rig.set(&key, Bytes::from(value.to_string()));
                    }
                    _ => problems.add(
                        "rig",
                        "must be a JSON object with the members of /distance (or, beside a \
                         calibration, only its σ)",
                    ),
                },
                name if RIG_PARTS.contains(&name) => match value {
                    Value::String(text) => {
                        settings.rig.set(&key, Bytes::from(text));
                    }
                    _ => problems.add(name, "must be a string: the file's text or the option"),
                },
                _ => problems.add_new(
                    stereo_core::numbers::clip(&key, crate::api::member_messages::ECHO),
                    format!(
                        "is not a member of the settings; the members are {}, {}",
                        MEMBERS.join(", "),
                        RIG_PARTS.join(", ")
                    ),
                ),
            }
        }
        if problems.is_empty() {
            Ok(settings)
        } else {
            Err(problems)
        }
    }
}

/// `options`: `/depth-map`'s query parameters as a JSON object, but `output`.
fn options(value: Value, problems: &mut FieldErrors) -> DepthMapQuery {
    let Value::Object(mut map) = value else {
        problems.add(
            "options",
            "must be a JSON object of /depth-map's query parameters, such as {\"preset\": \
             \"fast\", \"max_disparity\": 128}",
        );
        return DepthMapQuery::default();
    };
    if map.remove("output").is_some() {
        problems.add(
            "options.output",
            "is chosen in a stream by the settings' outputs list, such as [\"depth.npy\"]",
        );
    }
    let (query, refused) = decode_object::<DepthMapQuery>(map);
    for error in refused.prefixed("options.") {
        problems.add_new(error.field, error.message);
    }
    query
}

/// `outputs`: the files each answer carries, each named once.
fn outputs(value: &Value, problems: &mut FieldErrors) -> Option<Vec<DepthMapOutput>> {
    let Some(items) = value.as_array().filter(|a| a.len() <= MAX_OUTPUTS) else {
        problems.add(
            "outputs",
            format!(
                "must be a list of at most {MAX_OUTPUTS} file names, such as [\"depth.npy\", \
                 \"depth_std.npy\"]"
            ),
        );
        return None;
    };
    let mut chosen = Vec::with_capacity(items.len());
    for (i, item) in items.iter().enumerate() {
        let field = format!("outputs[{i}]");
        match serde_json::from_value::<DepthMapOutput>(item.clone()) {
            Ok(DepthMapOutput::Summary) => problems.add_new(
                field,
                "the summary comes with every answer: list only the files to send after it",
            ),
            Ok(output) if chosen.contains(&output) => {
                problems.add_new(field, "is listed twice; list it once");
            }
            Ok(output) => chosen.push(output),
            Err(_) => problems.add_new(
                field,
                "must be one of disparity.pfm, disparity.png, disparity.npy, depth.npy, \
                 disparity_std.npy, disparity_std.pfm, depth_std.npy, arrays.npz, depth.png, \
                 preview.png, points.ply",
            ),
        }
    }
    Some(chosen)
}

/// `temporal`: `false` or `null` turns the filter off, `true` or `{}` takes its defaults,
/// and an object sets `alpha`, `delta` and `persistence`.
fn temporal_members(value: Value, problems: &mut FieldErrors) -> Option<temporal::Settings> {
    let map: Map<String, Value> = match value {
        Value::Null | Value::Bool(false) => return None,
        Value::Bool(true) => return Some(temporal::Settings::default()),
        Value::Object(map) => map,
        _ => {
            problems.add(
                "temporal",
                "must be false (off), true (the defaults) or an object of alpha, delta and \
                 persistence",
            );
            return None;
        }
    };
    let (members, refused) = decode_object::<TemporalMembers>(map);
    let ok = refused.is_empty();
    for error in refused.prefixed("temporal.") {
        problems.add_new(error.field, error.message);
    }
    if !ok {
        return None;
    }
    let persistence = match members.persistence.as_deref() {
        None => Some(Persistence::default()),
        Some(name) => Persistence::parse(name),
    };
    if persistence.is_none() {
        let names: Vec<&str> = Persistence::ALL.iter().map(|p| p.name()).collect();
        problems.add(
            "temporal.persistence",
            format!("must be one of {}", names.join(", ")),
        );
    }
    let alpha = members.alpha.map_or(temporal::DEFAULT_ALPHA, |a| a as f32);
    let delta = members.delta.map_or(temporal::DEFAULT_DELTA, |d| d as f32);
    match temporal::Settings::new(alpha, delta, persistence.unwrap_or_default()) {
        Ok(settings) => persistence.map(|_| settings),
        Err(faults) => {
            for fault in faults {
                let (field, message) = match fault {
                    temporal::Fault::Alpha => (
                        "temporal.alpha",
                        "must lie in (0, 1]: the new value's weight (1 averages nothing)",
                    ),
                    temporal::Fault::Delta => (
                        "temporal.delta",
                        "must be a positive number of pixels of disparity",
                    ),
                };
                problems.add(field, message);
            }
            None
        }
    }
}

/// The temporal filter as a stream uses it.
#[derive(Debug, Clone, Serialize)]
pub struct TemporalAnswer {
    pub alpha: f64,
    pub delta: f64,
    pub persistence: &'static str,
}

impl From<temporal::Settings> for TemporalAnswer {
    fn from(s: temporal::Settings) -> Self {
        let round = |v: f32| (f64::from(v) * 1e6).round() / 1e6;
        TemporalAnswer {
            alpha: round(s.alpha()),
            delta: round(s.delta()),
            persistence: s.persistence().name(),
        }
    }
}

/// What the stream takes and how long it waits.
#[derive(Debug, Clone, Serialize)]
pub struct StreamLimitsAnswer {
    /// The largest frame message, in bytes.
    pub max_frame_bytes: usize,
    /// A stream that sends nothing for this long is closed.
    pub idle_timeout_s: f64,
    /// A stream that leaves an answer unread for this long is closed.
    pub write_timeout_s: f64,
}

/// The answer to the settings message: the settings as the stream will use them.
#[derive(Debug, Clone, Serialize)]
pub struct SettingsAnswer {
    /// `settings`.
    #[serde(rename = "type")]
    pub kind: &'static str,
    pub layout: &'static str,
    /// The start of the search; where it is found (no `min_disparity` with no end given, or
    /// `auto`), each frame's own is found too (its summary says which), and this is 0.
    pub min_disparity: i32,
    /// The end of the search; null when none was given: each frame's range is then found from
    /// it (the frame's summary says which).
    pub max_disparity: Option<i32>,
    pub parameters: MatcherParameters,
    /// The files each frame's answer is followed by, in this order, one binary message each.
    pub outputs: Vec<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rig: Option<CalibratedRig>,
    /// The temporal filter, or null when it is off.
    pub temporal: Option<TemporalAnswer>,
    pub limits: StreamLimitsAnswer,
    /// What to know, such as a rig that will be resolved again at the frames' size.
    pub warnings: Vec<String>,
}

/// The stages of one frame, in milliseconds.
#[derive(Debug, Clone, Serialize)]
pub struct FrameTimes {
    /// Waiting for the previous frame's work and a compute slot.
    pub queue: f64,
    pub decode: f64,
    /// Resolving the rig and building the rectification maps: the first frame of a size only.
    pub setup: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rectify: Option<f64>,
    /// Census, aggregation and refinement together.
    #[serde(rename = "match")]
    pub matching: f64,
    pub temporal: f64,
    /// The depths, their σ and the files.
    pub encode: f64,
    /// From the frame's arrival to its answer.
    pub total: f64,
}

/// What the temporal filter did to one frame, in pixels.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct TemporalCounts {
    pub averaged: usize,
    pub taken: usize,
    /// Holes given their last value (marked filled in `arrays.npz`).
    pub carried: usize,
}

impl From<Counts> for TemporalCounts {
    fn from(c: Counts) -> Self {
        TemporalCounts {
            averaged: c.averaged,
            taken: c.taken,
            carried: c.carried,
        }
    }
}

/// One file of an answer: the binary message that follows it.
#[derive(Debug, Clone, Serialize)]
pub struct FileAnswer {
    pub name: &'static str,
    pub media_type: &'static str,
    pub bytes: usize,
}

/// One frame's answer, followed by one binary message per file listed in `files`.
#[derive(Debug, Clone, Serialize)]
pub struct FrameAnswer {
    /// `frame`.
    #[serde(rename = "type")]
    pub kind: &'static str,
    /// The frame's number: the binary messages the stream has received, counting from 1.
    pub id: u64,
    /// Frames dropped unmatched so far, because a newer one arrived while they waited.
    pub dropped_frames: u64,
    /// Answers dropped so far, because the client had not read those before them.
    pub dropped_answers: u64,
    pub times_ms: FrameTimes,
    pub summary: DepthMapSummary,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub temporal: Option<TemporalCounts>,
    /// The calibration's check, on the frames that ran it (every 10th of a raw stream).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibration_check: Option<CalibrationWatch>,
    pub files: Vec<FileAnswer>,
}

/// A raw stream's check of its calibration over its latest checked frames: what
/// `/calibration/check` answers, and the corrected calibration when it no longer holds.
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationWatch {
    /// The checked frames fitted together (every 10th frame, the latest 12).
    pub checked_frames: usize,
    #[serde(flatten)]
    pub check: CheckAnswer,
    /// The corrected calibration as OpenCV's FileStorage YAML, when it no longer holds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub corrected_opencv_yml: Option<String>,
}

impl CalibrationWatch {
    /// The check over `frames` checked frames of a stream calibrated by `calibrated`.
    pub fn of(check: &check::Check, frames: usize, calibrated: &Calibrated) -> Self {
        CalibrationWatch {
            checked_frames: frames,
            check: CheckAnswer::of(check, calibrated.rig.unit().into(), Vec::new()),
            corrected_opencv_yml: (!check.holds).then(|| check.opencv_yml()),
        }
    }
}

/// A frame that could not be matched; the stream goes on.
#[derive(Debug, Clone, Serialize)]
pub struct FrameError {
    /// `error`.
    #[serde(rename = "type")]
    pub kind: &'static str,
    /// The frame's number, or 0 for the settings message.
    pub id: u64,
    pub dropped_frames: u64,
    pub dropped_answers: u64,
    pub problem: Problem,
}
