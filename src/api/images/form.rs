//! The image routes' multipart form: every part read into [`Parts`] by name (an unknown,
//! repeated or unnamed part is named in the answer), the pair's sizes from their headers, and
//! [`ImagePair`], the extractor that opens every image route with the same steps in the same
//! order: the parts, the sizes, the pair's check, the rig.

use std::marker::PhantomData;
use std::time::{Duration, Instant};

use axum::body::Bytes;
use axum::extract::multipart::MultipartError;
use axum::extract::{FromRequest, Multipart, Request};
use axum::http::{StatusCode, header};

use super::HeavyState;
use super::parts::Parts;
use super::rig;
use super::{limits, work};
use crate::api::body_limit::BodyLimit;
use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::extract;
use stereo_core::pipeline::{Calibrated, Sent};
use stereo_core::vision::decode::{self, DecodeLimits};

/// The media type the image routes read.
pub const MULTIPART: &str = "multipart/form-data";

/// What one image route reads besides the pair and the rig's parts.
pub trait ImageForm {
    /// The route's own parts.
    const PARTS: &'static [&'static str];
    /// Whether the route takes a `rig` part (`/rectify` needs the raw cameras of a
    /// calibration, so its messages never suggest one).
    const TAKES_RIG: bool = true;
    /// The parts that hold JSON arrays and may also come as repeated parts, one item (or
    /// array) each, as clients generated from the OpenAPI document send a form's array: joined
    /// in order into one array ([`join_lists`]).
    const LISTS: &'static [&'static str] = &[];
}

/// The pair of an image request, read and judged before anything is decoded.
pub struct ImagePair<F> {
    pub parts: Parts,
    /// What was sent to describe the rig (parsed into [`ImagePair::rig`]).
    pub sent: Sent,
    /// The pair's size (the left image's), when its header could be read.
    pub size: Option<(u32, u32)>,
    /// The rig from the `rig` or `calibration` part, when one is given and valid.
    pub rig: Option<Calibrated>,
    /// Everything found wrong so far, each part named.
    pub problems: FieldErrors,
    /// The memory the heavy group's guard reserved for this request, to grow before the work,
    /// and the slots the work takes one of.
    pub admitted: work::Admitted,
    /// How long the body took to arrive and be read into parts.
    pub read: Duration,
    /// What the decoder takes (`--max-image-pixels`).
    pub limits: DecodeLimits,
    form: PhantomData<F>,
}

/// A heavy request's multipart form, read after its admission: every part in order, what
/// was wrong with them, and how long the body took. Both [`ImagePair`] and `/calibrate`'s
/// views are read through it.
pub struct Form {
    pub parts: Vec<(String, Bytes)>,
    pub problems: FieldErrors,
    pub admitted: work::Admitted,
    pub read: Duration,
}

impl Form {
    /// The repeated `left` and `right` parts taken out in their order (the i-th of each one
    /// view or pair), the other parts left in `parts`.
    pub fn take_views(&mut self) -> [Vec<Bytes>; 2] {
        let mut views = [Vec::new(), Vec::new()];
        self.parts.retain(|(name, bytes)| match name.as_str() {
            "left" => {
                views[0].push(bytes.clone());
                false
            }
            "right" => {
                views[1].push(bytes.clone());
                false
            }
            _ => true,
        });
        views
    }
}

/// What a route's form holds: the parts it reads, those of them that may repeat, and how
/// `curl` sends it (for the 415 of a body that is not a form).
pub struct FormSpec<'a> {
    pub known: &'a [&'a str],
    pub repeatable: &'a [&'a str],
    pub example: &'static str,
}

impl Form {
    /// Takes the request's admission ([`work::Admitted`]), then reads its form.
    pub async fn read(
        req: Request,
        state: &HeavyState,
        spec: FormSpec<'_>,
    ) -> Result<Self, ApiError> {
        let admitted = work::Admitted::of(req.extensions(), state)?;
        let content_type = req.headers().get(header::CONTENT_TYPE).cloned();
        let form = Multipart::from_request(req, state)
            .await
            .map_err(|_| not_multipart(content_type.as_ref(), spec.example))?;
        let mut problems = FieldErrors::default();
        let started = Instant::now();
        let parts = read_parts_with(
            form,
            spec.known,
            spec.repeatable,
            state.body_limit,
            &mut problems,
        )
        .await?;
        Ok(Form {
            parts,
            problems,
            admitted,
            read: started.elapsed(),
        })
    }
}

impl<F: ImageForm> FromRequest<HeavyState> for ImagePair<F> {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &HeavyState) -> Result<Self, ApiError> {
        let known = [&["left", "right"][..], F::PARTS, &rig::RIG_PARTS[..]].concat();
        let spec = FormSpec {
            known: &known,
            repeatable: F::LISTS,
            example: "multipart/form-data: the images as file parts (curl -F left=@left.png \
                      -F right=@right.png)",
        };
        let Form {
            parts,
            mut problems,
            admitted,
            read,
        } = Form::read(req, state, spec).await?;
        let parts: Parts = join_lists(parts, F::LISTS, &mut problems)
            .into_iter()
            .collect();
        let image_limits = state.image_limits;
        let left = image_size(&parts, "left", image_limits, &mut problems);
        let right = image_size(&parts, "right", image_limits, &mut problems);
        if let (Some(l), Some(r)) = (left, right) {
            limits::check_pair(l, r, image_limits, &mut problems)?;
        }
        let input = parts.rig_parts();
        let (_, rig) = rig::parsed(&input, left, F::TAKES_RIG, &mut problems);
        Ok(ImagePair {
            parts,
            sent: input.sent(),
            size: left,
            rig,
            problems,
            admitted,
            read,
            limits: image_limits,
            form: PhantomData,
        })
    }
}

impl<F> ImagePair<F> {
    /// Everything found wrong so far: `query`'s problems (the route's query string), then the
    /// form's.
    pub fn problems(&mut self, mut query: FieldErrors) -> FieldErrors {
        query.extend(std::mem::take(&mut self.problems));
        query
    }

    /// Takes a compute slot, reserves the memory `need` says and runs `work` on a blocking
    /// thread with the form's parts ([`work::run`]); the rig is the route's to plan with
    /// before (a depth job, or `/rectify`'s raw rig).
    pub async fn run<T: Send + 'static>(
        self,
        need: work::Need<impl Fn(usize) -> usize>,
        work: impl FnOnce(Job<'_>) -> T + Send + 'static,
    ) -> Result<T, ApiError> {
        let (parts, read, limits) = (self.parts, self.read, self.limits);
        work::run(self.admitted, need, move |cancel, started| {
            work(Job {
                parts: &parts,
                limits,
                cancel,
                waited: [read, started.queue()],
            })
        })
        .await
    }
}

/// What an image request's blocking work gets.
pub struct Job<'a> {
    pub parts: &'a Parts,
    /// What the decoder takes (`--max-image-pixels`).
    pub limits: DecodeLimits,
    /// Set when the request is abandoned: stop at the next check.
    pub cancel: &'a std::sync::atomic::AtomicBool,
    /// How long the body took to read and the work waited for a thread, for `Server-Timing`.
    pub waited: [Duration; 2],
}

/// The 415 for a body that is not a multipart form, saying what was sent: another media type,
/// none, or a form without its boundary.
fn not_multipart(
    content_type: Option<&axum::http::HeaderValue>,
    example: &'static str,
) -> ApiError {
    let is_form = content_type
        .and_then(|ct| ct.to_str().ok())
        .is_some_and(|ct| extract::essence(ct).eq_ignore_ascii_case(MULTIPART));
    if is_form {
        ApiError::UnsupportedMediaType {
            got: "multipart/form-data without a boundary parameter".to_owned(),
            accepted: "multipart/form-data with its boundary (as curl -F and browsers' FormData \
                       send it)",
        }
    } else {
        extract::unsupported(content_type, example)
    }
}

/// Reads every part of the form in order; the parts named in `repeatable` may come more than
/// once (a calibration's views), every other once. A part this route does not read, a part
/// given twice or one without a name is recorded in `problems`, naming it.
async fn read_parts_with(
    mut form: Multipart,
    known: &[&str],
    repeatable: &[&str],
    limit: BodyLimit,
    problems: &mut FieldErrors,
) -> Result<Vec<(String, Bytes)>, ApiError> {
    let mut parts: Vec<(String, Bytes)> = Vec::new();
    loop {
        let field = match form.next_field().await {
            Ok(Some(field)) => field,
            Ok(None) => break,
            Err(e) => return Err(multipart_error(&e, limit)),
        };
        let name = field.name().unwrap_or_default().to_owned();
        let bytes = field
            .bytes()
            .await
            .map_err(|e| multipart_error(&e, limit))?;
        if name.is_empty() {
            problems.add("body", "has a part without a name; name each part");
        } else if !known.contains(&name.as_str()) {
            problems.add_new(
                stereo_core::numbers::clip(&name, crate::api::member_messages::ECHO),
                format!(
                    "is not a part of this request; the parts are {}",
                    known.join(", ")
                ),
            );
        } else if !repeatable.contains(&name.as_str()) && parts.iter().any(|(n, _)| *n == name) {
            problems.add(&name, "is given more than once; give it once");
        } else {
            parts.push((name, bytes));
        }
    }
    Ok(parts)
}

/// The parts named in `lists` that came more than once, joined into one JSON array: each
/// part's array spread into it, any other JSON value one item of it, in order. A part that is
/// not JSON is named in `problems` (and the joined part left out). A part given once is left
/// as it came, for the route to judge.
pub fn join_lists(
    parts: Vec<(String, Bytes)>,
    lists: &[&str],
    problems: &mut FieldErrors,
) -> Vec<(String, Bytes)> {
    let repeated: Vec<&str> = lists
        .iter()
        .copied()
        .filter(|list| parts.iter().filter(|(n, _)| n == list).count() > 1)
        .collect();
    let mut out = Vec::with_capacity(parts.len());
    let mut items: Vec<Vec<serde_json::Value>> = vec![Vec::new(); repeated.len()];
    let mut broken = vec![false; repeated.len()];
    let mut seen = vec![0usize; repeated.len()];
    for (name, bytes) in parts {
        let Some(i) = repeated.iter().position(|list| *list == name) else {
            out.push((name, bytes));
            continue;
        };
        seen[i] += 1;
        match serde_json::from_slice::<serde_json::Value>(&bytes) {
            Ok(serde_json::Value::Array(more)) => items[i].extend(more),
            Ok(item) => items[i].push(item),
            Err(e) => {
                problems.add_new(
                    format!("{name}[part {}]", seen[i]),
                    format!("is not JSON: {e}"),
                );
                broken[i] = true;
            }
        }
    }
    for ((list, joined), broken) in repeated.iter().zip(items).zip(broken) {
        if !broken {
            let text = serde_json::Value::Array(joined).to_string();
            out.push(((*list).to_owned(), Bytes::from(text)));
        }
    }
    out
}

/// A multipart body that cannot be read: too large (413) or broken (400).
fn multipart_error(e: &MultipartError, limit: BodyLimit) -> ApiError {
    if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
        ApiError::PayloadTooLarge(limit)
    } else {
        ApiError::Malformed(FieldError::new(
            "body",
            format!(
                "is not a readable multipart/form-data body: {}",
                e.body_text()
            ),
        ))
    }
}

/// The size of one image of the pair, from its header (turned as its EXIF orientation turns
/// it), or why it cannot be read.
pub fn image_size(
    parts: &Parts,
    name: &str,
    allowed: DecodeLimits,
    problems: &mut FieldErrors,
) -> Option<(u32, u32)> {
    let Some(bytes) = parts.get(name) else {
        problems.add(
            name,
            format!("is required: the {name} image of the pair (PNG or JPEG)"),
        );
        return None;
    };
    match decode::dimensions(bytes) {
        Ok(size) => Some(size),
        Err(e) => {
            problems.add(name, limits::describe(&e, allowed));
            None
        }
    }
}
