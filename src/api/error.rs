//! The one error type of the HTTP layer, [`ApiError`], rendered as RFC 9457
//! `application/problem+json`, and [`FieldErrors`], the collector that decoding and validation
//! fill so that one answer names every offending field. The bottom layer of the API: of
//! the API's modules it uses none ([`stereo_core::numbers`] writes its numbers).

use std::time::Duration;

use axum::{
    http::{HeaderValue, StatusCode, header},
    response::{IntoResponse, Response},
};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::api::body_limit::BodyLimit;
use crate::{budget::Refusal, observe::telemetry};
use stereo_core::physics::PhysicsError;

/// A byte count for people: `1.5 MiB`.
fn mib(bytes: usize) -> String {
    format!(
        "{} MiB",
        stereo_core::numbers::short(bytes as f64 / (1024.0 * 1024.0))
    )
}

/// Seconds a shed client, or one refused while the memory budget is held, is asked to wait
/// before retrying (`Retry-After`).
pub const RETRY_AFTER_SECS: u64 = 1;

/// The media type of every error body.
pub const PROBLEM_JSON: &str = "application/problem+json";

/// One offending input and what is wrong with it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct FieldError {
    /// The request field (JSON member or query parameter) at fault, such as `baseline`; `body`,
    /// `query`, `content-type`, `path` or `method` when the fault is not in one field.
    pub field: String,
    /// What is wrong and how to fix it.
    pub message: String,
}

impl FieldError {
    pub fn new(field: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            message: message.into(),
        }
    }
}

/// Collects every field error of a request before answering, so that one 422 names them all.
/// Decoding records what serde refused; validation (`api::validate`) adds its own checks.
#[derive(Debug, Default)]
pub struct FieldErrors(Vec<FieldError>);

impl From<Vec<FieldError>> for FieldErrors {
    fn from(errors: Vec<FieldError>) -> Self {
        Self(errors)
    }
}

impl FieldErrors {
    /// Records a problem with `field`, unless that field already has one (the first, such
    /// as a wrong type found while decoding, explains the rest).
    pub fn add(&mut self, field: &str, message: impl Into<String>) {
        if !self.0.iter().any(|e| e.field == field) {
            self.0.push(FieldError::new(field, message));
        }
    }

    /// Records a problem without looking for one already recorded for the field: for
    /// fields known to be new, such as a batch's `points[i]…`, of which there may be
    /// thousands.
    pub fn add_new(&mut self, field: String, message: impl Into<String>) {
        self.0.push(FieldError::new(field, message));
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The problems recorded so far.
    pub fn iter(&self) -> impl Iterator<Item = &FieldError> {
        self.0.iter()
    }

    /// Adds everything `other` recorded.
    pub fn extend(&mut self, other: FieldErrors) {
        for error in other.0 {
            self.add(&error.field, error.message);
        }
    }

    /// Everything recorded, each field name behind `prefix` (such as `points[3].`).
    pub fn prefixed(self, prefix: &str) -> Vec<FieldError> {
        self.0
            .into_iter()
            .map(|e| FieldError::new(format!("{prefix}{}", e.field), e.message))
            .collect()
    }

    /// Everything recorded, as a 422.
    pub fn into_error(self) -> ApiError {
        ApiError::Invalid(self.0)
    }

    /// Replaces the message recorded for `field`, if any, with `message`: for a member whose
    /// refusal needs more than the generic words, such as one that moved.
    pub fn reword(&mut self, field: &str, message: &str) {
        for error in self.0.iter_mut().filter(|e| e.field == field) {
            message.clone_into(&mut error.message);
        }
    }

    /// Whether `field` already has a problem recorded.
    pub fn has(&self, field: &str) -> bool {
        self.0.iter().any(|e| e.field == field)
    }

    /// `Ok(value)` when nothing was recorded, else every recorded error as a 422.
    pub fn finish<T>(self, value: Option<T>) -> Result<T, ApiError> {
        match value {
            Some(value) if self.0.is_empty() => Ok(value),
            _ if self.0.is_empty() => Err(ApiError::invalid("body", "is invalid")),
            _ => Err(self.into_error()),
        }
    }
}

/// An RFC 9457 problem details object with the list of every offending field. Each documented
/// error response carries examples of its own status (`wire::openapi`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Problem {
    /// A URI reference naming the kind of problem (`about:blank` for plain HTTP errors).
    #[serde(rename = "type")]
    pub problem_type: String,
    /// A short summary of the kind of problem.
    pub title: String,
    /// The HTTP status code.
    pub status: u16,
    /// A human-readable explanation of this occurrence.
    pub detail: String,
    /// Every offending field, each with its own message; never empty.
    pub errors: Vec<FieldError>,
    /// The request's `x-request-id` (the caller's, or one the server made up), to quote when
    /// reporting the problem.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(nullable = false)]
    pub request_id: Option<String>,
}

/// Everything that can go wrong with a request.
#[derive(Debug, Clone, PartialEq)]
pub enum ApiError {
    /// 400: the body is not JSON, or the query string cannot be decoded.
    Malformed(FieldError),
    /// 413: the body is larger than the limit.
    PayloadTooLarge(BodyLimit),
    /// 415: the body is not declared as a type the route reads (`got`; `accepted` names
    /// those it reads).
    UnsupportedMediaType { got: String, accepted: &'static str },
    /// 422: one or more fields are missing, of the wrong type, unknown or out of range.
    Invalid(Vec<FieldError>),
    /// 404: no such route.
    NotFound(String),
    /// 405: the route exists but not with this method.
    MethodNotAllowed(String),
    /// 408 when the body was still arriving at the deadline, 503 when the answer was late.
    Timeout {
        after: Duration,
        body_received: bool,
    },
    /// 408: the body arrived slower than the minimum rate (`min_rate` bytes a second on average
    /// once the grace period had passed): `received` bytes in `after`. The connection is closed.
    SlowBody {
        received: u64,
        after: Duration,
        min_rate: u64,
    },
    /// 503: more requests in flight than the concurrency limit; retry after the given seconds.
    Overloaded { retry_after_secs: u64 },
    /// 503 with `Retry-After` when the heavy requests in flight hold the memory budget; 413
    /// when this request alone needs more than the whole budget.
    Memory(Refusal),
    /// 503 from `/readyz`: the server is shutting down and wants no new traffic.
    Draining,
    /// 500: a bug; never expected, but answered in the same format.
    Internal(String),
    /// 413: the request's images or disparity range are beyond the server's limits; the
    /// errors name the parts and parameters to shrink.
    Oversized(Vec<FieldError>),
    /// 426: a WebSocket route asked without the upgrade (why, in axum's words).
    UpgradeRequired(String),
    /// 503: as many depth streams are open as the server allows (`limit`); retry later.
    TooManyStreams { limit: usize },
    /// 401: the service takes bearer tokens and the request brought none (`refused: false`)
    /// or one it does not know (`refused: true`).
    Unauthorized { refused: bool },
}

impl ApiError {
    pub fn invalid(field: impl Into<String>, message: impl Into<String>) -> Self {
        ApiError::Invalid(vec![FieldError::new(field, message)])
    }

    pub fn status(&self) -> StatusCode {
        match self {
            ApiError::Malformed(_) => StatusCode::BAD_REQUEST,
            ApiError::PayloadTooLarge(_) => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::UnsupportedMediaType { .. } => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            ApiError::Invalid(_) => StatusCode::UNPROCESSABLE_ENTITY,
            ApiError::NotFound(_) => StatusCode::NOT_FOUND,
            ApiError::MethodNotAllowed(_) => StatusCode::METHOD_NOT_ALLOWED,
            ApiError::Timeout {
                body_received: false,
                ..
            }
            | ApiError::SlowBody { .. } => StatusCode::REQUEST_TIMEOUT,
            ApiError::Memory(Refusal::TooLarge { .. }) => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::Timeout { .. }
            | ApiError::Overloaded { .. }
            | ApiError::Memory(Refusal::Busy { .. })
            | ApiError::Draining => StatusCode::SERVICE_UNAVAILABLE,
            ApiError::Internal(_) => StatusCode::INTERNAL_SERVER_ERROR,
            ApiError::Oversized(_) => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::Unauthorized { .. } => StatusCode::UNAUTHORIZED,
            ApiError::UpgradeRequired(_) => StatusCode::UPGRADE_REQUIRED,
            ApiError::TooManyStreams { .. } => StatusCode::SERVICE_UNAVAILABLE,
        }
    }

    /// The problem details body for this error.
    pub fn problem(&self) -> Problem {
        let status = self.status();
        let plain = |detail: String, errors: Vec<FieldError>| Problem {
            problem_type: "about:blank".to_owned(),
            title: status.canonical_reason().unwrap_or("Error").to_owned(),
            status: status.as_u16(),
            detail,
            errors,
            request_id: None,
        };
        match self {
            ApiError::Malformed(error) => Problem {
                problem_type: "urn:stereo-distance:problem:malformed-request".to_owned(),
                title: "Malformed request".to_owned(),
                status: status.as_u16(),
                detail: format!(
                    "the {} could not be decoded: {}",
                    error.field, error.message
                ),
                errors: vec![error.clone()],
                request_id: None,
            },
            ApiError::PayloadTooLarge(limit) => {
                let (detail, message) = limit.refusal();
                plain(detail, vec![FieldError::new("body", message)])
            }
            ApiError::UnsupportedMediaType { got, accepted } => plain(
                format!("the request body must be sent as {accepted}, not {got}"),
                vec![FieldError::new(
                    "content-type",
                    format!("must be {accepted}, got {got}"),
                )],
            ),
            ApiError::Invalid(errors) => {
                let detail = match errors.as_slice() {
                    [one] => format!("{}: {}", clipped(one).field, clipped(one).message),
                    _ => format!("{} fields are invalid: {}", errors.len(), names(errors)),
                };
                Problem {
                    problem_type: "urn:stereo-distance:problem:invalid-input".to_owned(),
                    title: "Invalid input".to_owned(),
                    status: status.as_u16(),
                    detail,
                    errors: listed(errors),
                    request_id: None,
                }
            }
            ApiError::Unauthorized { refused } => plain(
                if *refused {
                    "the bearer token was not accepted: ask the service's operator for a \
                     current one"
                        .to_owned()
                } else {
                    "this service takes requests with a bearer token only: send \
                     Authorization: Bearer <token>"
                        .to_owned()
                },
                vec![FieldError::new(
                    "authorization",
                    if *refused {
                        "is not a token this service accepts"
                    } else {
                        "is required: Bearer <token>"
                    },
                )],
            ),
            ApiError::NotFound(path) => plain(
                format!("there is no resource at {path}; see /openapi.json for the API"),
                vec![FieldError::new("path", format!("no route for {path}"))],
            ),
            ApiError::MethodNotAllowed(method) => plain(
                format!("{method} is not supported here; the Allow header lists what is"),
                vec![FieldError::new(
                    "method",
                    format!("{method} is not allowed"),
                )],
            ),
            ApiError::Timeout {
                after,
                body_received: false,
            } => plain(
                format!(
                    "the request body did not arrive within the {} ms the server waits",
                    after.as_millis()
                ),
                vec![FieldError::new(
                    "body",
                    "arrived too slowly; send the whole request at once",
                )],
            ),
            ApiError::Timeout { after, .. } => plain(
                format!(
                    "the server could not answer within {} ms; retry later",
                    after.as_millis()
                ),
                vec![FieldError::new("request", "timed out in the server")],
            ),
            ApiError::SlowBody {
                received,
                after,
                min_rate,
            } => plain(
                format!(
                    "the request body arrived at {:.0} B/s ({received} bytes in {:.1} s), slower \
                     than the {min_rate} B/s this server requires; the connection is closed",
                    *received as f64 / after.as_secs_f64().max(1e-3),
                    after.as_secs_f64()
                ),
                vec![FieldError::new(
                    "body",
                    format!("arrived too slowly: send it at {min_rate} bytes a second or faster"),
                )],
            ),
            ApiError::Overloaded { retry_after_secs } => plain(
                format!("the server is at its concurrency limit; retry after {retry_after_secs} s"),
                vec![FieldError::new(
                    "request",
                    "refused to protect the requests already in progress",
                )],
            ),
            ApiError::Memory(Refusal::Busy {
                requested,
                available,
            }) => plain(
                format!(
                    "the image requests in flight hold the server's memory budget: this one \
                     needs {}, {} is free now; retry after {RETRY_AFTER_SECS} s",
                    mib(*requested),
                    mib(*available)
                ),
                vec![FieldError::new(
                    "request",
                    "refused to protect the requests already in progress",
                )],
            ),
            ApiError::Memory(Refusal::TooLarge { requested, total }) => plain(
                format!(
                    "this request needs {} of memory, more than the server's whole budget of \
                     {} for image requests; send smaller images",
                    mib(*requested),
                    mib(*total)
                ),
                vec![FieldError::new(
                    "request",
                    format!("needs {}, at most {} fits", mib(*requested), mib(*total)),
                )],
            ),
            ApiError::UpgradeRequired(why) => plain(
                format!(
                    "this is a WebSocket: open it with a WebSocket client (GET with Upgrade: \
                     websocket); {why}"
                ),
                vec![FieldError::new("upgrade", "is required: websocket")],
            ),
            ApiError::TooManyStreams { limit } => plain(
                format!(
                    "the server has {limit} depth streams open, as many as it allows; retry \
                     after {RETRY_AFTER_SECS} s"
                ),
                vec![FieldError::new(
                    "stream",
                    "refused to protect the streams already open",
                )],
            ),
            ApiError::Draining => plain(
                "the server is shutting down and takes no new traffic".to_owned(),
                vec![FieldError::new("server", "draining")],
            ),
            ApiError::Oversized(errors) => plain(
                match errors.as_slice() {
                    [one] => format!("{}: {}", clipped(one).field, clipped(one).message),
                    _ => format!(
                        "the request is beyond the server's limits: {}",
                        names(errors)
                    ),
                },
                listed(errors),
            ),
            ApiError::Internal(what) => plain(
                "the server failed to answer this request; it has been logged".to_owned(),
                vec![FieldError::new("request", what.clone())],
            ),
        }
    }
}

/// The most errors a problem lists; the rest are counted in one more entry.
pub const MAX_LISTED: usize = 10;
/// The bytes of fields and messages a problem lists at most (the first error is always
/// listed): with the clipped `detail`, every problem stays under 16 KiB.
const LISTED_BYTES: usize = 11 * 1024;
/// The most field names the `detail` line names.
const MAX_NAMED: usize = 5;
/// The longest field name and message a problem repeats, in characters.
const MAX_FIELD: usize = 100;
const MAX_MESSAGE: usize = 600;

/// An error with its field and message clipped to what a problem repeats.
fn clipped(error: &FieldError) -> FieldError {
    FieldError::new(
        stereo_core::numbers::clip(&error.field, MAX_FIELD),
        stereo_core::numbers::clip(&error.message, MAX_MESSAGE),
    )
}

/// The first errors, clipped, at most [`MAX_LISTED`] of them in [`LISTED_BYTES`], and a count
/// of the rest.
fn listed(errors: &[FieldError]) -> Vec<FieldError> {
    let mut listed = Vec::new();
    let mut bytes = 0;
    for error in errors.iter().take(MAX_LISTED) {
        let error = clipped(error);
        // Each entry's JSON adds its keys, quotes and commas to the text.
        bytes += error.field.len() + error.message.len() + 32;
        if !listed.is_empty() && bytes > LISTED_BYTES {
            break;
        }
        listed.push(error);
    }
    if errors.len() > listed.len() {
        listed.push(FieldError::new(
            "body",
            format!(
                "and {} more problems not listed here: fix these and send it again",
                errors.len() - listed.len()
            ),
        ));
    }
    listed
}

/// The first [`MAX_NAMED`] fields' names, then how many more.
fn names(errors: &[FieldError]) -> String {
    let mut named: Vec<String> = errors
        .iter()
        .take(MAX_NAMED)
        .map(|e| clipped(e).field)
        .collect();
    if errors.len() > MAX_NAMED {
        named.push(format!("and {} more", errors.len() - MAX_NAMED));
    }
    named.join(", ")
}

impl From<(PhysicsError, &[&str])> for ApiError {
    /// A physics failure, blamed on the request fields that produced it.
    fn from((error, fields): (PhysicsError, &[&str])) -> Self {
        ApiError::Invalid(
            fields
                .iter()
                .map(|field| FieldError::new(*field, error.to_string()))
                .collect(),
        )
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        if let ApiError::Internal(what) = &self {
            tracing::error!(%what, "internal error");
        }
        let status = self.status();
        let mut problem = self.problem();
        problem.request_id = telemetry::current_request_id();
        let body = serde_json::to_vec(&problem).unwrap_or_default();
        let mut response = (status, body).into_response();
        let headers = response.headers_mut();
        headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(PROBLEM_JSON));
        match self {
            ApiError::Overloaded { retry_after_secs } => {
                headers.insert(header::RETRY_AFTER, HeaderValue::from(retry_after_secs));
            }
            ApiError::Memory(Refusal::Busy { .. }) | ApiError::TooManyStreams { .. } => {
                headers.insert(header::RETRY_AFTER, HeaderValue::from(RETRY_AFTER_SECS));
            }
            ApiError::UpgradeRequired(_) => {
                headers.insert(header::UPGRADE, HeaderValue::from_static("websocket"));
                headers.insert(header::CONNECTION, HeaderValue::from_static("Upgrade"));
            }
            // RFC 6750: the scheme, and `invalid_token` for a token that was sent.
            ApiError::Unauthorized { refused } => {
                headers.insert(
                    header::WWW_AUTHENTICATE,
                    HeaderValue::from_static(if refused {
                        "Bearer realm=\"stereo-distance\", error=\"invalid_token\""
                    } else {
                        "Bearer realm=\"stereo-distance\""
                    }),
                );
            }
            // The rest of the body is not waited for: the connection cannot be reused.
            ApiError::SlowBody { .. } => {
                headers.insert(header::CONNECTION, HeaderValue::from_static("close"));
            }
            _ => {}
        }
        response
    }
}

impl From<stereo_core::pipeline::Stopped> for ApiError {
    /// A cancel is the server's (the deadline's); a range the scene needs past what one search
    /// covers is a 422 naming `max_disparity`, with what to send instead.
    fn from(stopped: stereo_core::pipeline::Stopped) -> Self {
        match stopped.advice() {
            Some(advice) => ApiError::Invalid(vec![FieldError::new("max_disparity", advice)]),
            None => ApiError::Internal("cancelled".to_owned()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Thousands of errors are listed as the first few and a count, each clipped, so the
    /// problem stays under 16 KiB.
    #[test]
    fn problems_list_a_few_and_count_the_rest() {
        let errors: Vec<FieldError> = (0..5000)
            .map(|i| FieldError::new(format!("part{i}{}", "×".repeat(300)), "é".repeat(5000)))
            .collect();
        let problem = ApiError::Invalid(errors).problem();
        let listed = problem.errors.len() - 1;
        assert!((1..=MAX_LISTED).contains(&listed), "{listed}");
        let more = format!("{} more", 5000 - listed);
        assert!(problem.errors[listed].message.contains(&more));
        assert!(problem.detail.starts_with("5000 fields are invalid"));
        assert!(
            problem.detail.ends_with("and 4995 more"),
            "{}",
            problem.detail
        );
        assert!(serde_json::to_vec(&problem).unwrap().len() < 16 * 1024);
        // Short ASCII errors: ten listed, whole.
        let short: Vec<FieldError> = (0..50)
            .map(|i| FieldError::new(format!("points[{i}].x"), "is required"))
            .collect();
        let problem = ApiError::Invalid(short).problem();
        assert_eq!(problem.errors.len(), MAX_LISTED + 1);
        assert!(problem.errors[MAX_LISTED].message.contains("40 more"));
        assert_eq!(problem.errors[9].message, "is required");
    }

    /// A timeout is 408 while the body is still arriving and 503 once the answer is late;
    /// shedding is 503 with `Retry-After`; each names what to fix in `errors`.
    #[test]
    fn protective_errors_map_to_statuses() {
        let slow_body = ApiError::Timeout {
            after: Duration::from_secs(5),
            body_received: false,
        };
        let slow_answer = ApiError::Timeout {
            after: Duration::from_secs(5),
            body_received: true,
        };
        assert_eq!(slow_body.status(), StatusCode::REQUEST_TIMEOUT);
        assert_eq!(slow_body.problem().errors[0].field, "body");
        assert_eq!(slow_answer.status(), StatusCode::SERVICE_UNAVAILABLE);
        let trickle = ApiError::SlowBody {
            received: 6,
            after: Duration::from_secs(5),
            min_rate: 1024,
        };
        assert_eq!(trickle.status(), StatusCode::REQUEST_TIMEOUT);
        assert_eq!(trickle.problem().errors[0].field, "body");
        assert!(
            trickle
                .problem()
                .detail
                .contains("1 B/s (6 bytes in 5.0 s)"),
            "{}",
            trickle.problem().detail
        );
        assert_eq!(
            trickle.into_response().headers()[header::CONNECTION],
            "close"
        );
        assert!(slow_answer.problem().detail.contains("5000 ms"));

        let shed = ApiError::Overloaded {
            retry_after_secs: 1,
        }
        .into_response();
        assert_eq!(shed.status(), StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(shed.headers()[header::RETRY_AFTER], "1");
        assert_eq!(shed.headers()[header::CONTENT_TYPE], PROBLEM_JSON);
    }
}
