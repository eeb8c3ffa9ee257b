//! The form `/calibrate` and `/board` read (the views' images in order, the board and an
//! earlier calibration's parts), and the refusal of views that need more memory than the
//! heavy budget has.

use axum::body::Bytes;
use axum::extract::{FromRequest, Request};

use super::initial::{INITIAL_PARTS, read_as};
use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::images::HeavyState;
use crate::api::images::form::{Form, FormSpec};
use crate::api::images::rig::RigParts;
use crate::api::images::work;
use stereo_core::pipeline::calibrate as engine;

/// The form's parts: the views' images in order, the board, the earlier calibration's parts
/// (as the image routes' calibration parts), and what was wrong.
pub struct Upload {
    pub left: Vec<Bytes>,
    pub right: Vec<Bytes>,
    pub board: Option<Bytes>,
    pub initial: RigParts,
    pub problems: FieldErrors,
    pub admitted: work::Admitted,
    /// What the decoder takes (`--max-image-pixels`).
    pub limits: engine::DecodeLimits,
}

impl FromRequest<HeavyState> for Upload {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &HeavyState) -> Result<Self, ApiError> {
        let known: Vec<&str> = ["left", "right", "board"]
            .into_iter()
            .chain(INITIAL_PARTS.iter().map(|(ours, _)| *ours))
            .collect();
        let spec = FormSpec {
            known: &known,
            repeatable: &["left", "right"],
            example: "multipart/form-data: the views as repeated file parts (curl -F \
                      left=@l0.png -F right=@r0.png -F left=@l1.png … -F \
                      board='{\"columns\":9,…}')",
        };
        let mut form = Form::read(req, state, spec).await?;
        let [left, right] = form.take_views();
        let mut upload = Upload {
            left,
            right,
            board: None,
            initial: RigParts::default(),
            problems: form.problems,
            admitted: form.admitted,
            limits: state.image_limits,
        };
        for (name, bytes) in form.parts {
            match name.as_str() {
                "board" => upload.board = Some(bytes),
                other => {
                    if let Some(name) = read_as(other) {
                        upload.initial.set(name, bytes);
                    }
                }
            }
        }
        Ok(upload)
    }
}

impl Upload {
    /// The upload of a route that takes no earlier calibration (`/board`): each `initial…`
    /// part sent is named.
    pub fn without_initial(mut self) -> Upload {
        super::initial::strays(
            &self.initial,
            "applies to /calibrate only: /board finds one image's board",
            &mut self.problems,
        );
        self
    }
}

/// The error of images whose boards need more memory than the heavy budget has in all: `what`
/// (`views need`) `bytes` `why` (`to calibrate`), `total` there is.
pub fn over_the_budget(
    size: (u32, u32),
    what: &str,
    why: &str,
    bytes: usize,
    total: usize,
) -> Vec<FieldError> {
    vec![FieldError::new(
        "left",
        format!(
            "{} × {} {what} {} MiB {why}, more than the {} MiB this server has for image \
             requests: send smaller images",
            size.0,
            size.1,
            bytes / (1024 * 1024),
            total / (1024 * 1024)
        ),
    )]
}
