//! Rig planning: `/rig` (what a rig and its disparity search can see, and how well) and
//! `/baseline` (the shortest baseline that meets a depth-error budget). Each is extract →
//! validate → physics → response, like every other route.

pub use crate::api::wire::rig_design as types;

use axum::extract::State;
use stereo_core::numbers::Num;
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{
    BaselineRequest, BaselineResponse, DepthErrorAt, ErrorBudget, MAX_AT_DISTANCES, RigRequest,
    RigResponse,
};
use crate::api::error::{ApiError, FieldErrors};
use crate::api::extract::{JsonBody, QueryParams};
use crate::api::operation::json_operation;
use crate::api::respond::Json;
use crate::api::state::AppState;
use crate::api::validate;
use crate::api::wire::openapi::{BodyErrors, QueryErrors};
use stereo_core::numbers::{percent, short};
use stereo_core::physics::design::{self, DepthBudget, DesignFault, Reach};
use stereo_core::physics::{self, Rig};

/// `GET` and `POST /rig` and `/baseline`.
pub fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new()
        .routes(routes!(get_rig, post_rig))
        .routes(routes!(get_baseline, post_baseline))
}

json_operation! {
    rig: RigRequest => RigResponse at "/rig", tag "planning", ok "What the rig can see, and how well.";
    post post_rig(
        summary = "Depth range, field of view and depth error of a rig and its disparity search",
        description = "min_distance = f·B / (max_disparity_px + doffs), max_distance = f·B / \
                       (min_disparity_px + doffs), the depth error ΔZ = Z²·Δd/(f·B) at the \
                       requested distances, and the distance up to which the relative error stays \
                       within a budget, Z = r·f·B/Δd.",
        request_body(content = RigRequest, examples(
            ("depth camera" = (summary = "A D435-like rig: 424 px, 50 mm, 126 px of search", value = json!({
                "focal_length_px": 424, "baseline": 50, "unit": "mm",
                "image_width": 848, "image_height": 480, "disparity_error_px": 0.08,
                "max_disparity_px": 126, "at_distances": [500, 1000, 2000, 4000],
                "max_relative_error": 0.02
            }))),
            ("f in mm with sensor width" = (summary = "A 4 mm lens on a 6.4 mm sensor, in metres", value = json!({
                "focal_length_mm": 4, "sensor_width_mm": 6.4, "baseline": 0.12, "unit": "m",
                "image_width": 1280, "image_height": 720, "max_disparity_px": 256,
                "min_disparity_px": 0.25
            })))
        ))
    );
    get get_rig(summary = "Rig planning (query-string form of POST /rig)");
}

json_operation! {
    baseline: BaselineRequest => BaselineResponse at "/baseline", tag "planning", ok "The baseline.";
    post post_baseline(
        summary = "The shortest baseline that meets a depth-error budget at a distance",
        description = "B = Z²·Δd / (f·ΔZ): the depth error formula solved for the baseline. With \
                       max_disparity_px, also the nearest distance that baseline lets the rig see.",
        request_body(content = BaselineRequest, examples(
            ("relative budget" = (summary = "0.5 % at 5 m with f = 1000 px", value = json!({
                "focal_length_px": 1000, "image_width": 1280, "image_height": 720, "unit": "mm",
                "disparity_error_px": 0.25, "target_distance": 5000, "max_relative_error": 0.005,
                "max_disparity_px": 128
            }))),
            ("absolute budget" = (summary = "±25 mm at 5 m with a 90° camera", value = json!({
                "horizontal_fov_deg": 90, "image_width": 800, "image_height": 600, "unit": "mm",
                "target_distance": 5000, "max_depth_error": 25
            })))
        ))
    );
    get get_baseline(summary = "The shortest baseline (query-string form of POST /baseline)");
}

/// A relative-error budget: a fraction in (0, 1].
fn budget(field: &str, value: f64, problems: &mut FieldErrors) -> Option<f64> {
    if value.is_finite() && value > 0.0 && value <= 1.0 {
        Some(value)
    } else {
        problems.add(
            field,
            format!(
                "must be a fraction in (0, 1] (0.02 means 2 %), got {}",
                Num(value)
            ),
        );
        None
    }
}

fn rig(
    _: &AppState,
    request: &RigRequest,
    mut problems: FieldErrors,
) -> Result<RigResponse, ApiError> {
    let rig = validate::rig(request.rig_spec(), &mut problems);
    let (min_disparity, max_disparity) = disparity_bounds(request, rig, &mut problems);
    let distances = at_distances(request.at_distances.as_deref(), &mut problems);
    let max_relative_error = relative_budget(request, rig, &mut problems);
    let (rig, ((min_disparity, max_disparity), distances)) =
        problems.finish(rig.zip(min_disparity.zip(max_disparity).zip(distances)))?;
    let max_relative_error = max_relative_error.flatten();
    let (min_distance, max_distance) = rig
        .depth_range(min_disparity, max_disparity)
        .map_err(blame(&["min_disparity_px", "max_disparity_px"]))?;
    let range = (min_distance, max_distance);
    let error_budget = max_relative_error
        .map(|r| {
            rig.budget_reach(r, range)
                .map(|reach| error_budget(&rig, r, reach, range))
                .ok_or(physics::PhysicsError::NotFinite)
                .map_err(blame(&["max_relative_error", "disparity_error_px"]))
        })
        .transpose()?;
    let (horizontal_fov_deg, vertical_fov_deg) = rig.fields_of_view_deg();
    Ok(RigResponse {
        unit: request.unit.unwrap_or_default(),
        focal_length_px: rig.focal_px(),
        horizontal_fov_deg,
        vertical_fov_deg,
        baseline: rig.baseline(),
        fb: rig.fb(),
        doffs: rig.doffs(),
        disparity_error_px: rig.disparity_error_px(),
        min_disparity_px: min_disparity,
        max_disparity_px: max_disparity,
        min_distance,
        max_distance,
        at_distances: distances
            .into_iter()
            .map(|z| rig.error_at(z, range).map(DepthErrorAt::from))
            .collect::<Result<_, _>>()
            .map_err(blame(&["at_distances"]))?,
        error_budget,
    })
}

/// The disparity range of `/rig`: `max_disparity_px` required, `min_disparity_px` defaulting
/// to the rig's disparity error, the one below the other and short of infinity.
fn disparity_bounds(
    request: &RigRequest,
    rig: Option<Rig>,
    problems: &mut FieldErrors,
) -> (Option<f64>, Option<f64>) {
    let max_disparity = problems
        .required("max_disparity_px", request.max_disparity_px)
        .and_then(|d| problems.positive("max_disparity_px", d));
    let min_disparity = match (request.min_disparity_px, rig) {
        (Some(d), _) => problems.positive("min_disparity_px", d),
        (None, Some(r)) if r.disparity_error_px() > 0.0 => Some(r.disparity_error_px()),
        (None, Some(_)) => {
            problems.add(
                "min_disparity_px",
                "is required when disparity_error_px is 0 (it defaults to disparity_error_px)",
            );
            None
        }
        (None, None) => None,
    };
    if let (Some(min), Some(max)) = (min_disparity, max_disparity)
        && min >= max
    {
        problems.add(
            "max_disparity_px",
            format!(
                "must be greater than min_disparity_px ({}), got {}",
                Num(min),
                Num(max)
            ),
        );
    }
    if let (Some(min), Some(r)) = (min_disparity, rig) {
        validate::short_of_infinity("min_disparity_px", min, &r, problems);
    }
    (min_disparity, max_disparity)
}

/// `/rig`'s `max_relative_error`, checked against the rig: a fraction, meaningful only with a
/// disparity error, and above what the calibration alone gives.
fn relative_budget(
    request: &RigRequest,
    rig: Option<Rig>,
    problems: &mut FieldErrors,
) -> Option<Option<f64>> {
    let max_relative_error = request
        .max_relative_error
        .map(|r| budget("max_relative_error", r, problems));
    if let (Some(Some(_)), Some(r)) = (max_relative_error, rig)
        && r.disparity_error_px() <= 0.0
    {
        problems.add(
            "disparity_error_px",
            "must be greater than 0 with max_relative_error: with no disparity error the \
             relative error is 0 at every distance",
        );
    }
    if let (Some(Some(budget)), Some(r)) = (max_relative_error, rig)
        && r.calibration_relative_error() >= budget
    {
        problems.add(
            "max_relative_error",
            format!(
                "cannot be met at any distance: the calibration alone (focal_length_std_px, \
                 baseline_std) gives a relative error of {}; allow more, or calibrate better",
                Num(r.calibration_relative_error())
            ),
        );
    }
    max_relative_error
}

/// The requested distances: each finite and positive, at most [`MAX_AT_DISTANCES`].
fn at_distances(values: Option<&[f64]>, problems: &mut FieldErrors) -> Option<Vec<f64>> {
    let values = values.unwrap_or_default();
    if values.len() > MAX_AT_DISTANCES {
        problems.add(
            "at_distances",
            format!(
                "holds {} distances; at most {MAX_AT_DISTANCES} are allowed",
                values.len()
            ),
        );
        return None;
    }
    let checked: Vec<Option<f64>> = values
        .iter()
        .enumerate()
        .map(|(i, &z)| problems.positive(&format!("at_distances[{i}]"), z))
        .collect();
    checked.into_iter().collect()
}

/// Turns a physics failure into a 422 naming `fields`.
fn blame(fields: &'static [&'static str]) -> impl Fn(physics::PhysicsError) -> ApiError {
    move |error| ApiError::from((error, fields))
}

/// Where the budget is passed, said in words against the range the search can see.
fn error_budget(
    rig: &Rig,
    budget: f64,
    (at, reach): (f64, Reach),
    (near, far): (f64, f64),
) -> ErrorBudget {
    let unit = rig.unit().symbol();
    let (r, z) = (percent(budget), |v: f64| format!("{} {unit}", short(v)));
    let summary = match reach {
        Reach::Whole => format!(
            "the relative depth error stays below {r} across the whole range the search sees, \
             {} to {} (it would reach {r} at {})",
            z(near),
            z(far),
            z(at)
        ),
        Reach::UpTo => format!(
            "the relative depth error is below {r} from {} up to {}",
            z(near),
            z(at)
        ),
        Reach::Nowhere {
            relative_error_at_near,
        } => format!(
            "the relative depth error exceeds {r} everywhere the search sees: it is already {} \
             at the nearest distance, {}",
            percent(relative_error_at_near),
            z(near)
        ),
    };
    ErrorBudget {
        max_relative_error: budget,
        distance: at,
        summary,
    }
}

/// `/baseline`'s depth-error budget: `max_depth_error`, or `max_relative_error` of the target
/// distance; one of them, not both.
fn depth_budget(request: &BaselineRequest, problems: &mut FieldErrors) -> Option<DepthBudget> {
    match (request.max_depth_error, request.max_relative_error) {
        (Some(_), Some(_)) => {
            for field in ["max_depth_error", "max_relative_error"] {
                problems.add(
                    field,
                    "give max_depth_error or max_relative_error, not both",
                );
            }
            None
        }
        (Some(dz), None) => problems
            .positive("max_depth_error", dz)
            .map(DepthBudget::Error),
        (None, Some(r)) => budget("max_relative_error", r, problems).map(DepthBudget::Relative),
        (None, None) => {
            problems.add(
                "max_depth_error",
                "a depth-error budget is required: give max_depth_error (a length in `unit`) \
                 or max_relative_error (a fraction of target_distance)",
            );
            None
        }
    }
}

/// The baseline's formula with the request's numbers in it.
fn formula(
    camera: &physics::RectifiedCamera,
    z: f64,
    dz: f64,
    baseline: f64,
    unit: &str,
) -> String {
    format!(
        "B = Z²·Δd / (f·ΔZ) = ({} {unit})² × {} px / ({} px × {} {unit}) = {} {unit}",
        short(z),
        short(camera.disparity_error_px()),
        short(camera.focal_px()),
        short(dz),
        short(baseline),
    )
}

fn baseline(
    _: &AppState,
    request: &BaselineRequest,
    mut problems: FieldErrors,
) -> Result<BaselineResponse, ApiError> {
    let camera = validate::camera(request.camera_spec(), &mut problems);
    let target = problems
        .required("target_distance", request.target_distance)
        .and_then(|z| problems.positive("target_distance", z));
    let budget = depth_budget(request, &mut problems);
    let max_disparity = request
        .max_disparity_px
        .map(|d| problems.positive("max_disparity_px", d));
    if let Some(c) = camera
        && c.disparity_error_px() <= 0.0
    {
        problems.add(
            "disparity_error_px",
            "must be greater than 0: with no disparity error any baseline meets the budget",
        );
    }
    let (camera, (target, budget)) = problems.finish(camera.zip(target.zip(budget)))?;
    let max_disparity = max_disparity.flatten();
    let design = design::baseline_design(camera, target, budget, max_disparity).map_err(
        |fault| match fault {
            DesignFault::Baseline(e) => blame(&["target_distance", "max_depth_error"])(e),
            DesignFault::MinDistance(e) => blame(&["max_disparity_px"])(e),
            DesignFault::Target(e) => blame(&["target_distance"])(e),
            DesignFault::Rig(faults) => {
                let mut fields = FieldErrors::default();
                validate::faults(faults, "", &mut fields);
                fields.into_error()
            }
        },
    )?;
    let unit = design.rig.unit().symbol();
    Ok(BaselineResponse {
        unit: request.unit.unwrap_or_default(),
        focal_length_px: camera.focal_px(),
        horizontal_fov_deg: design.rig.fields_of_view_deg().0,
        disparity_error_px: camera.disparity_error_px(),
        target_distance: target,
        max_depth_error: design.max_depth_error,
        max_relative_error: design.max_relative_error,
        baseline: design.rig.baseline(),
        disparity_at_target_px: design.disparity_at_target_px,
        formula: formula(
            &camera,
            target,
            design.max_depth_error,
            design.rig.baseline(),
            unit,
        ),
        max_disparity_px: max_disparity,
        min_distance: design.min_distance,
    })
}
