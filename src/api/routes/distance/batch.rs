//! `POST /distance` with many points: telling a batch from a single correspondence, decoding
//! each point on its own so that every fault is named, and answering per point.
//!
//! The request's *shape* is all or nothing, as the OpenAPI schema states it: a wrong envelope
//! or rig, no points or too many, or a point that is not an object of numbers `x_left` and
//! `x_right` (or `disparity_px`) and optional `y` (a wrong type, an unknown or missing member,
//! both `x_right` and `disparity_px`) is a 422 for the whole batch, naming `rig.…` and `points[17].x_left`. Such faults are programming errors in
//! the caller, and a schema-valid request is what clients validate against.
//!
//! The *values* are judged point by point: a coordinate off the image or a point at infinity
//! is that point's own `errors` inside a 200, and the others are still computed. Points come
//! from feature matchers, where a few bad matches per frame are normal; failing the frame for
//! them would make every client re-implement the checks this service exists to do.

use axum::extract::{FromRequest, Request};
use serde::Deserialize;
use serde_json::{Map, Value};

use crate::api::wire::distance::{
    BatchDistanceResponse, BatchPoint, DistanceRequest, PointDistance, PointFailure, PointOutcome,
    StereoRig,
};
use crate::{
    api::{
        body_limit::{BodyLimit, LimitOption},
        error::{ApiError, FieldErrors},
        extract::{self, decode_object, expect_object},
        state::AppState,
        validate::{self, Bounds, Feature},
        wire::{de::Object, measured::Measured},
    },
    config::Limits,
};
use stereo_core::physics;

/// A `POST /distance` body: one correspondence or a batch, each with what decoding refused.
#[derive(Debug)]
pub enum DistanceBody {
    One(DistanceRequest, FieldErrors),
    Batch(Batch),
}

/// A decoded batch. `problems` holds faults of the envelope and the rig (already named
/// `rig.…`); each point carries its own, still unprefixed.
#[derive(Debug, Default)]
pub struct Batch {
    pub rig: Option<StereoRig>,
    pub rig_problems: FieldErrors,
    pub points: Option<Vec<(BatchPoint, FieldErrors)>>,
    pub problems: FieldErrors,
}

/// Whether a body is a batch: it names `rig` or `points` at the top level (with any value,
/// even `null`). Skims the body without allocating.
#[derive(Deserialize)]
struct Shape {
    #[serde(default)]
    rig: Seen,
    #[serde(default)]
    points: Seen,
}

/// Whether a member was present at all.
#[derive(Default)]
struct Seen(bool);

impl<'de> Deserialize<'de> for Seen {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        serde::de::IgnoredAny::deserialize(deserializer).map(|_| Seen(true))
    }
}

/// The batch as it is when everything is well-formed: one typed pass.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Wire {
    rig: Object<StereoRig>,
    points: Vec<Object<BatchPoint>>,
}

/// A batch is larger than any other body, so `POST /distance` reads within the batch body
/// limit instead of the light group's.
impl FromRequest<AppState> for DistanceBody {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &AppState) -> Result<Self, Self::Rejection> {
        let unread = extract::unread_query(req.uri());
        let limit = BodyLimit {
            bytes: state.limits.batch_body_bytes,
            set_by: LimitOption::BatchBody,
        };
        let bytes = extract::json_bytes(req, limit).await?;
        expect_object(&bytes)?;
        let one = |mut problems: FieldErrors| {
            let (request, refused) = extract::decode_json(&bytes)?;
            problems.extend(refused);
            Ok(DistanceBody::One(request, problems))
        };
        if !may_be_batch(&bytes) {
            return one(unread);
        }
        let shape: Shape =
            serde_json::from_slice(&bytes).map_err(|e| extract::malformed_json(&e))?;
        if !(shape.rig.0 || shape.points.0) {
            return one(unread);
        }
        if let Ok(wire) = serde_json::from_slice::<Wire>(&bytes) {
            return Ok(DistanceBody::Batch(Batch {
                rig: Some(wire.rig.0),
                points: Some(
                    wire.points
                        .into_iter()
                        .map(|Object(p)| (p, FieldErrors::default()))
                        .collect(),
                ),
                problems: unread,
                ..Batch::default()
            }));
        }
        let map: Map<String, Value> =
            serde_json::from_slice(&bytes).map_err(|e| extract::malformed_json(&e))?;
        let mut batch = diagnose(map);
        batch.problems.extend(unread);
        Ok(DistanceBody::Batch(batch))
    }
}

/// Whether a body can name `rig` or `points` at all: only if those words appear in it in
/// quotes, or if it has escapes (`"\u0072ig"` is also `rig`). The common single-point body
/// fails this byte scan and skips the skim.
fn may_be_batch(bytes: &[u8]) -> bool {
    let has = |word: &[u8]| bytes.windows(word.len()).any(|w| w == word);
    has(b"\"rig\"") || has(b"\"points\"") || bytes.contains(&b'\\')
}

/// Decodes a batch member by member, so that each fault is named where it is.
fn diagnose(map: Map<String, Value>) -> Batch {
    let mut batch = Batch::default();
    for (key, value) in map {
        match (key.as_str(), value) {
            ("rig", Value::Object(rig)) => {
                let (rig, problems) = decode_object::<StereoRig>(rig);
                batch.rig = Some(rig);
                batch.rig_problems = problems;
            }
            ("points", Value::Array(points)) => {
                batch.points = Some(
                    points
                        .into_iter()
                        .map(|point| match point {
                            Value::Object(point) => decode_object::<BatchPoint>(point),
                            other => {
                                let mut problems = FieldErrors::default();
                                problems
                                    .add("", format!("must be an object, got {}", kind(&other)));
                                (BatchPoint::default(), problems)
                            }
                        })
                        .collect(),
                );
            }
            ("rig", other) => batch
                .problems
                .add("rig", format!("must be an object, got {}", kind(&other))),
            ("points", other) => batch
                .problems
                .add("points", format!("must be an array, got {}", kind(&other))),
            (other, _) => batch.problems.add(
                if other.is_empty() { "body" } else { other },
                format!("unknown field `{other}`; a batch has only `rig` and `points`"),
            ),
        }
    }
    batch
}

/// A JSON value's kind, for messages.
fn kind(value: &Value) -> &'static str {
    match value {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

/// Answers a batch: 422 when the envelope or rig is wrong, else one outcome per point.
pub fn answer(batch: Batch, limits: &Limits) -> Result<BatchDistanceResponse, ApiError> {
    let Batch {
        rig: spec,
        mut rig_problems,
        points,
        mut problems,
    } = batch;
    let rig = match &spec {
        Some(spec) => validate::rig(spec.rig_spec(), &mut rig_problems),
        None => {
            if !problems.has("rig") {
                problems.add("rig", "is required");
            }
            None
        }
    };
    for error in rig_problems.prefixed("rig.") {
        problems.add(error.field.trim_end_matches('.'), error.message);
    }
    check_points(points.as_deref(), limits, &mut problems);
    let (rig, points) = problems.finish(rig.zip(points))?;
    let spec = spec.unwrap_or_default();
    let bounds = Bounds::of(&spec.camera_spec());
    let results: Vec<PointOutcome> = points
        .into_iter()
        .enumerate()
        .map(|(index, (point, _))| measure(&rig, bounds, index, point))
        .collect();
    let failed = results
        .iter()
        .filter(|r| matches!(r, PointOutcome::Failed(_)))
        .count();
    Ok(BatchDistanceResponse {
        unit: spec.unit.unwrap_or_default(),
        focal_length_px: rig.focal_px(),
        baseline: rig.baseline(),
        disparity_error_px: rig.disparity_error_px(),
        count: results.len(),
        succeeded: results.len() - failed,
        failed,
        results,
    })
}

/// The batch's points: required, at least one, within the server's cap, each of the
/// schema's shape (what breaks it named).
fn check_points(
    points: Option<&[(BatchPoint, FieldErrors)]>,
    limits: &Limits,
    problems: &mut FieldErrors,
) {
    match points {
        None if !problems.has("points") => problems.add("points", "is required"),
        Some([]) => {
            problems.add("points", "must hold at least one point");
        }
        Some(points) if points.len() > limits.batch_points => problems.add(
            "points",
            format!(
                "holds {} points; at most {} (the server's cap) are allowed in one batch",
                points.len(),
                limits.batch_points
            ),
        ),
        _ => {}
    }
    if let Some(points) = points {
        for (index, (point, shape)) in points.iter().enumerate() {
            refuse_malformed(index, point, shape, problems);
        }
    }
}

/// Names, among the batch's own problems, what makes point `index` break the schema: what
/// decoding refused (not an object, a wrong type, an unknown member, `null`) and a missing
/// coordinate.
fn refuse_malformed(
    index: usize,
    point: &BatchPoint,
    shape: &FieldErrors,
    problems: &mut FieldErrors,
) {
    let prefix = format!("points[{index}]");
    for error in shape.iter() {
        match error.field.as_str() {
            "" => problems.add_new(prefix.clone(), error.message.clone()),
            field => problems.add_new(format!("{prefix}.{field}"), error.message.clone()),
        }
    }
    if shape.has("") {
        return;
    }
    let named = |field: &str| format!("{prefix}.{field}");
    match (point.x_right, point.disparity_px) {
        (Some(_), Some(_)) => {
            for field in ["x_right", "disparity_px"] {
                problems.add_new(named(field), validate::X_RIGHT_OR_DISPARITY);
            }
        }
        (Some(_), None) if point.x_left.is_none() && !shape.has("x_left") => {
            problems.add_new(named("x_left"), "is required with x_right");
        }
        (None, None) if !shape.has("x_right") && !shape.has("disparity_px") => {
            problems.add_new(
                named("x_right"),
                "is required: give x_right (with x_left), or disparity_px",
            );
        }
        _ => {}
    }
}

/// One well-formed point's outcome: its distance, or every error of its values, named
/// `points[index].…`.
fn measure(rig: &physics::Rig, bounds: Bounds, index: usize, point: BatchPoint) -> PointOutcome {
    let mut problems = FieldErrors::default();
    let feature = Feature {
        x_left: point.x_left,
        x_right: point.x_right,
        disparity_px: point.disparity_px,
        y: point.y,
    };
    let correspondence = validate::correspondence(feature, bounds, &mut problems);
    let measured = match correspondence {
        Some(c) if problems.is_empty() => physics::measure(rig, c).map_err(|e| {
            let mut problems = FieldErrors::default();
            for field in validate::disparity_fields(rig, &feature) {
                if *field != "doffs" {
                    problems.add(field, e.to_string());
                }
            }
            problems
        }),
        _ => Err(problems),
    };
    match measured {
        Ok(m) => PointOutcome::Measured(PointDistance {
            index,
            measured: Measured::from(&m),
        }),
        Err(problems) => failure(index, problems),
    }
}

/// A failed point, its errors named `points[index].field`.
fn failure(index: usize, problems: FieldErrors) -> PointOutcome {
    PointOutcome::Failed(PointFailure {
        index,
        errors: problems.prefixed(&format!("points[{index}].")),
    })
}

#[cfg(test)]
mod tests {
    use super::may_be_batch;

    /// Only a body that mentions `rig` or `points` in quotes, or has escapes, can be a batch.
    #[test]
    fn batch_candidates() {
        assert!(!may_be_batch(br#"{"focal_length_px": 35, "x_left": 400}"#));
        assert!(may_be_batch(br#"{"rig": {}, "points": []}"#));
        assert!(may_be_batch(br#"{"points": []}"#));
        assert!(may_be_batch(br#"{"\u0072ig": {}}"#));
        assert!(may_be_batch(br#"{"unit": "rig"}"#));
    }
}
