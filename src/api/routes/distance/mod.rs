//! `/distance`: the distance to one feature (GET and POST), or to a batch of features seen by
//! one rig (POST). Each request is extract → validate → physics → response.

pub mod batch;
pub use crate::api::wire::distance as types;

use axum::extract::State;
use utoipa_axum::{router::OpenApiRouter, routes};

use self::batch::DistanceBody;
use self::types::{DistanceInput, DistanceOutput, DistanceRequest, DistanceResponse};
use crate::api::error::{ApiError, FieldErrors};
use crate::api::extract::QueryParams;
use crate::api::respond::Json;
use crate::api::state::AppState;
use crate::api::validate::{self, Bounds, Feature};
use crate::api::wire::measured::Measured;
use crate::api::wire::openapi::{BodyErrors, QueryErrors};
use stereo_core::numbers::short;
use stereo_core::physics;

/// `GET` and `POST /distance`.
pub fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new().routes(routes!(get_distance, post_distance))
}

#[utoipa::path(
    post,
    path = "/distance",
    tag = "distance",
    summary = "Distance to one feature, or to a batch of features seen by one rig",
    description = "Z = B·f_px / |d + doffs| with d = x_left − x_right, in the unit of the \
                   baseline, with its expected error ΔZ = Z²·Δd/(f_px·B), the intermediate values \
                   and the feature's 3D point.\n\n\
                   A body with `rig` and `points` is a batch of up to 10 000 points (the \
                   server's cap), answered in order. A batch that breaks the schema (a wrong \
                   rig or envelope, or a point with a wrong type or an unknown or missing \
                   member) is a 422 naming each fault, such as `points[17].x_left`. Otherwise \
                   it is a 200 in which each point has its distance or, when its values fail \
                   against the rig (off the image, at infinity), its own `errors`; `failed` \
                   counts the latter.",
    request_body(content = DistanceInput, examples(
        ("focal length in px" = (summary = "The seed's example 1: f = 35 px, B = 150 mm, \
                                  d = 50 px, so Z = 105 mm", value = json!({
            "focal_length_px": 35, "baseline": 150, "unit": "mm",
            "x_left": 400, "x_right": 350, "image_width": 800, "image_height": 600
        }))),
        ("focal length in mm with sensor width" = (summary = "f = 4 mm · 1280 px / 6.4 mm = \
                                                   800 px, so Z = 1920 mm", value = json!({
            "focal_length_mm": 4, "sensor_width_mm": 6.4, "baseline": 120, "unit": "mm",
            "x_left": 700, "x_right": 650, "image_width": 1280, "image_height": 720
        }))),
        ("focal length in mm with pixel pitch" = (summary = "f = 3.6 mm · 1000 / 3 µm = \
                                                  1200 px, so Z = 2.4 m", value = json!({
            "focal_length_mm": 3.6, "pixel_size_um": 3, "baseline": 0.12, "unit": "m",
            "x_left": 1000, "x_right": 940, "image_width": 1920, "image_height": 1080
        }))),
        ("horizontal field of view" = (summary = "f = 400 px / tan 45° = 400 px, so \
                                       Z = 1300 mm", value = json!({
            "horizontal_fov_deg": 90, "baseline": 65, "unit": "mm",
            "x_left": 420, "x_right": 400, "image_width": 800, "image_height": 600,
            "doffs": 0, "y": 300, "disparity_error_px": 0.1
        }))),
        ("batch" = (summary = "Two features seen by one rig", value = json!({
            "rig": {"focal_length_px": 35, "baseline": 150, "unit": "mm",
                    "image_width": 800, "image_height": 600},
            "points": [{"x_left": 400, "x_right": 350}, {"x_left": 420, "x_right": 390, "y": 310}]
        })))
    )),
    responses(
        (status = 200, description = "The distance and its error, or one result per point \
                                      of a batch.", body = DistanceOutput),
        BodyErrors
    )
)]
pub async fn post_distance(
    State(state): State<AppState>,
    body: DistanceBody,
) -> Result<Json<DistanceOutput>, ApiError> {
    match body {
        DistanceBody::One(request, problems) => {
            distance(&request, problems).map(|r| Json(DistanceOutput::One(r)))
        }
        DistanceBody::Batch(batch) => {
            batch::answer(batch, &state.limits).map(|r| Json(DistanceOutput::Batch(r)))
        }
    }
}

#[utoipa::path(
    get,
    path = "/distance",
    tag = "distance",
    summary = "Distance to one feature (query-string form of POST /distance)",
    description = "The query-string form of POST /distance for one correspondence: the same \
                   members as query parameters, the same answer. Batches are POST only.",
    params(DistanceRequest),
    responses(
        (status = 200, description = "The distance and its error.", body = DistanceResponse),
        QueryErrors
    )
)]
pub async fn get_distance(
    QueryParams(request, problems): QueryParams<DistanceRequest>,
) -> Result<Json<DistanceResponse>, ApiError> {
    distance(&request, problems).map(Json)
}

fn distance(
    request: &DistanceRequest,
    mut problems: FieldErrors,
) -> Result<DistanceResponse, ApiError> {
    let params = request.rig_spec();
    let bounds = Bounds::of(&params.camera);
    let rig = validate::rig(params, &mut problems);
    let feature = Feature::new(
        request.x_left,
        request.x_right,
        request.disparity_px,
        request.y,
    );
    let correspondence = validate::correspondence(feature, bounds, &mut problems);
    let (rig, correspondence) = problems.finish(rig.zip(correspondence))?;
    let m = physics::measure(&rig, correspondence)
        .map_err(|e| ApiError::from((e, validate::disparity_fields(&rig, &feature))))?;
    let unit = rig.unit().symbol();
    Ok(DistanceResponse {
        formula: format!(
            "Z = B·f / |d + doffs| = {} {unit} × {} px / |{} px + {} px| = {} {unit}",
            short(rig.baseline()),
            short(rig.focal_px()),
            short(m.disparity_px),
            short(rig.doffs()),
            short(m.distance),
        ),
        measured: Measured::from(&m),
        unit: request.unit.unwrap_or_default(),
        distance_m: m.distance_m,
        disparity_error_px: rig.disparity_error_px(),
        effective_disparity_px: m.effective_disparity_px,
        focal_length_px: rig.focal_px(),
        baseline: rig.baseline(),
        normalized_x: m.normalized_x,
        projection_factor: m.projection_factor,
    })
}
