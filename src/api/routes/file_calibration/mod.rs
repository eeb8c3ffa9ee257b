//! `/calibration`: reads a Middlebury, KITTI, ROS or OpenCV calibration file and answers the
//! rig in the members every other endpoint takes. The file comes in a JSON body's `text`, or
//! as the raw body with `Content-Type: text/plain` (`curl --data-binary @calib.txt`).

pub use crate::api::wire::file_calibration as types;

use axum::extract::{FromRequest, FromRequestParts, Request};
use axum::http::header;
use utoipa_axum::{router::OpenApiRouter, routes};

use self::types::{
    CalibratedRig, CalibrationFile, CalibrationQuery, CalibrationRequest, CalibrationResponse,
    RawCameras,
};
use crate::api::body_limit::BodyLimit;
use crate::api::error::{ApiError, FieldErrors};
use crate::api::extract::{self, QueryParams};
use crate::api::respond::Json;
use crate::api::state::AppState;
use crate::api::wire::calibration::add_read_faults;
use crate::api::wire::openapi::BodyErrors;
use axum::extract::FromRef;
use stereo_core::calibration::files::{self, ReadOptions, Source};
use stereo_core::physics::LengthUnit;
use stereo_core::vision::decode::MAX_SIDE;

/// `POST /calibration`.
pub fn router() -> OpenApiRouter<AppState> {
    OpenApiRouter::new().routes(routes!(post_calibration))
}

/// The media types `/calibration` reads.
const ACCEPTED: &str = "application/json, or text/plain for the file itself";

/// A calibration request from either body form, with what decoding refused.
pub struct CalibrationBody(CalibrationRequest, FieldErrors);

impl FromRequest<AppState> for CalibrationBody {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &AppState) -> Result<Self, Self::Rejection> {
        let (mut parts, body) = req.into_parts();
        let QueryParams(query, mut problems) =
            QueryParams::<CalibrationQuery>::from_request_parts(&mut parts, state).await?;
        let req = Request::from_parts(parts, body);
        let content_type = req.headers().get(header::CONTENT_TYPE).cloned();
        let media = content_type.as_ref().and_then(|ct| ct.to_str().ok());
        let limit = BodyLimit::from_ref(state);
        let mut request = match media {
            Some(ct) if extract::is_json(ct) => {
                let bytes = extract::json_bytes(req, limit).await?;
                let (request, refused) = extract::decode_json::<CalibrationRequest>(&bytes)?;
                problems.extend(refused);
                request
            }
            Some(ct) if extract::essence(ct).eq_ignore_ascii_case("text/plain") => {
                let bytes = extract::body_bytes(req, limit).await?;
                match String::from_utf8(bytes.to_vec()) {
                    Ok(text) => CalibrationRequest {
                        text: Some(text),
                        ..CalibrationRequest::default()
                    },
                    Err(e) => {
                        problems.add(
                            "text",
                            format!(
                                "must be UTF-8 text; byte {} is not",
                                e.utf8_error().valid_up_to()
                            ),
                        );
                        CalibrationRequest::default()
                    }
                }
            }
            _ => return Err(extract::unsupported(content_type.as_ref(), ACCEPTED)),
        };
        // The query's options apply to either form, and win over the body's.
        request.format = query.format.or(request.format);
        request.cameras = query.cameras.or(request.cameras);
        request.calibration_unit = query.calibration_unit.or(request.calibration_unit);
        // A body alpha the query overrides is still checked: it was sent.
        if query.alpha.is_some() {
            problems.alpha(request.alpha);
        }
        request.alpha = query.alpha.or(request.alpha);
        request.unit = query.unit.or(request.unit);
        // A body size the query overrides is still checked, as alpha is: it was sent.
        for (name, overridden, body) in [
            ("image_width", query.image_width, request.image_width),
            ("image_height", query.image_height, request.image_height),
        ] {
            if overridden.is_some() {
                side(name, body, &mut problems);
            }
        }
        request.image_width = query.image_width.or(request.image_width);
        request.image_height = query.image_height.or(request.image_height);
        Ok(CalibrationBody(request, problems))
    }
}

#[utoipa::path(
    post,
    path = "/calibration",
    tag = "calibration",
    summary = "Read a calibration file into a rig",
    description = "Reads a Middlebury 2014 `calib.txt`, a KITTI calibration \
                   (`calib_cam_to_cam.txt` or odometry `calib.txt`), a pair of ROS \
                   `CameraInfo` files or OpenCV's `stereoRectify` output (FileStorage YAML or \
                   XML), and answers the rig with the member names of `/distance`, so that a \
                   client can send it back with a disparity added.\n\n\
                   Formulas: Middlebury f = cam0[0,0], doffs and baseline (mm) as written; \
                   KITTI f = P_l[0,0], B = (P_l[0,3] − P_r[0,3]) / f (m), doffs = P_r[0,2] − \
                   P_l[0,2]; ROS f = P_r[0], B = −P_r[3] / P_r[0] (m), doffs = P_r[2] − P_l[2]; \
                   OpenCV f = Q[2,3], cx = −Q[0,3], cy = −Q[1,3], B = 1/Q[3,2], doffs = \
                   Q[3,3]/Q[3,2] (in `calibration_unit`, which is required).\n\n\
                   The file may also be the raw body with `Content-Type: text/plain`, with the \
                   options in the query (`?format=kitti&cameras=0-1`). A file that cannot be \
                   read is a 422 naming `text` (or `right_text`) with the line and what was \
                   expected there.",
    params(CalibrationQuery),
    request_body(
        description = "The calibration as JSON, or the file itself as `text/plain`.",
        content(
            (CalibrationRequest = "application/json", examples(
                ("middlebury" = (summary = "Middlebury 2014 calib.txt (mm)", value = json!({
                    "text": "cam0=[1000 0 640; 0 1000 360; 0 0 1]\n\
                             cam1=[1000 0 652; 0 1000 360; 0 0 1]\n\
                             doffs=12\nbaseline=120\nwidth=1280\nheight=720\nndisp=192\n"
                }))),
                ("kitti" = (summary = "KITTI odometry calib.txt, grey pair, answer in mm",
                            value = json!({
                    "text": "P0: 700 0 600 0 0 700 180 0 0 0 1 0\n\
                             P1: 700 0 600 -378 0 700 180 0 0 0 1 0\n\
                             P2: 700 0 600 42 0 700 180 0.2 0 0 1 0.003\n\
                             P3: 700 0 600 -336 0 700 180 2.2 0 0 1 0.003\n",
                    "cameras": "0-1", "unit": "mm"
                }))),
                ("ros" = (summary = "ROS CameraInfo pair (camera_calibration YAML)",
                          value = json!({
                    "text": "image_width: 640\nimage_height: 480\nprojection_matrix:\n  \
                             rows: 3\n  cols: 4\n  data: [500, 0, 320, 0, 0, 500, 240, 0, 0, 0, \
                             1, 0]\n",
                    "right_text": "image_width: 640\nimage_height: 480\nprojection_matrix:\n  \
                                   rows: 3\n  cols: 4\n  data: [500, 0, 322, -50, 0, 500, 240, \
                                   0, 0, 0, 1, 0]\n",
                    "format": "ros"
                }))),
                ("opencv" = (summary = "OpenCV FileStorage YAML after stereoRectify, T in mm",
                             value = json!({
                    "text": "%YAML:1.0\n---\nQ: !!opencv-matrix\n   rows: 4\n   cols: 4\n   \
                             dt: d\n   data: [ 1., 0., 0., -640., 0., 1., 0., -360., 0., 0., \
                             0., 900., 0., 0., 1.6666666666666666e-02, 0. ]\nimage_width: \
                             1280\nimage_height: 720\n",
                    "calibration_unit": "mm"
                })))
            )),
            (CalibrationFile = "text/plain")
        )
    ),
    responses(
        (status = 200, description = "The rig the file describes.", body = CalibrationResponse),
        BodyErrors
    )
)]
pub async fn post_calibration(
    CalibrationBody(request, problems): CalibrationBody,
) -> Result<Json<CalibrationResponse>, ApiError> {
    read(&request, problems).map(Json)
}

/// The raw images' size given beside the file: both members or neither, each from 1 to
/// [`MAX_SIDE`] pixels.
fn image_size(request: &CalibrationRequest, problems: &mut FieldErrors) -> Option<(u32, u32)> {
    let width = side("image_width", request.image_width, problems);
    let height = side("image_height", request.image_height, problems);
    match (request.image_width, request.image_height) {
        (Some(_), None) => problems.add("image_height", "is required with image_width"),
        (None, Some(_)) => problems.add("image_width", "is required with image_height"),
        _ => {}
    }
    width.zip(height)
}

/// One side of the image size, when given: from 1 to [`MAX_SIDE`] pixels, else named.
fn side(name: &str, value: Option<u32>, problems: &mut FieldErrors) -> Option<u32> {
    let v = value?;
    if (1..=MAX_SIDE).contains(&v) {
        Some(v)
    } else {
        problems.add(
            name,
            format!("must be from 1 to {MAX_SIDE} pixels, not {v}"),
        );
        None
    }
}

/// Reads the file and states the rig in the requested unit; each fault named by its member
/// (`text`, `right_text`, `calibration_unit`, or the rig's `rig.cx`…).
fn read(
    request: &CalibrationRequest,
    mut problems: FieldErrors,
) -> Result<CalibrationResponse, ApiError> {
    let text = problems.required("text", request.text.as_deref());
    let alpha = problems.alpha(request.alpha);
    let image_size = image_size(request, &mut problems);
    if !problems.is_empty() {
        return Err(problems.into_error());
    }
    let source = Source {
        text: text.unwrap_or_default(),
        right_text: request.right_text.as_deref(),
        format: request.format.unwrap_or_default().format(),
        kitti_pair: request.cameras.map(Into::into),
        alpha,
        image_size,
    };
    let options = ReadOptions {
        calibration_unit: request.calibration_unit.map(LengthUnit::from),
        unit: request.unit.map(LengthUnit::from),
    };
    match files::read(source, options) {
        Ok(read) => Ok(CalibrationResponse {
            format: read.format.into(),
            rig: CalibratedRig::from(&read.rig),
            max_disparity_px: read.max_disparity_px,
            warnings: read.warnings,
            raw_cameras: read.raw.is_some(),
            raw: read
                .raw
                .as_deref()
                .map(|raw| RawCameras::new(raw, read.file_unit)),
        }),
        Err(faults) => {
            add_read_faults(faults, ["text", "right_text"], &mut problems);
            Err(problems.into_error())
        }
    }
}
