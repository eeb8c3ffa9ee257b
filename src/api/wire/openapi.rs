//! OpenAPI glue: the query parameters of a GET operation derived from its POST body schema,
//! and the problem+json error responses each kind of operation documents, each status with
//! examples of its own rendered from the errors the server answers.

use std::collections::BTreeMap;

use axum::http::StatusCode;
use utoipa::openapi::{
    ContentBuilder, ObjectBuilder, RefOr, Required, ResponseBuilder, Type,
    example::ExampleBuilder,
    header::HeaderBuilder,
    path::{Parameter, ParameterBuilder, ParameterIn, ParameterStyle},
    response::Response as OpenApiResponse,
    schema::Schema,
};

use crate::api::body_limit::{BodyLimit, LimitOption};
use crate::api::error::RETRY_AFTER_SECS;
use crate::api::error::{ApiError, FieldError, PROBLEM_JSON};
use crate::api::extract::{QueryForm, decode_query, malformed_json};
use crate::config::{
    DEFAULT_BODY_LIMIT, DEFAULT_BODY_RATE_GRACE, DEFAULT_MIN_BODY_RATE, DEFAULT_REQUEST_TIMEOUT,
};

/// The probes, open to all whether or not the service takes tokens: the kubelet asks them, and
/// they say nothing but "up" (`/metrics`, beside them, needs a token when tokens are set).
pub const OPEN_PROBES: [&str; 2] = ["/healthz", "/readyz"];

/// Documents each member of a request body schema as a query parameter, so that the GET form of
/// an operation is described by the very type its POST form takes.
pub fn query_parameters(schema: RefOr<Schema>) -> Vec<Parameter> {
    let RefOr::T(Schema::Object(object)) = schema else {
        return Vec::new();
    };
    object
        .properties
        .into_iter()
        .map(|(name, property)| {
            let property = single_choice(property);
            let (description, list) = match &property {
                RefOr::T(Schema::Object(o)) => (o.description.clone(), false),
                RefOr::T(Schema::Array(a)) => (a.description.clone(), true),
                RefOr::T(Schema::OneOf(o)) => (o.description.clone(), false),
                _ => (None, false),
            };
            let required = if object.required.contains(&name) {
                Required::True
            } else {
                Required::False
            };
            ParameterBuilder::new()
                .name(name)
                .parameter_in(ParameterIn::Query)
                .required(required)
                .description(description)
                .schema(Some(property))
                // Lists are comma-separated in a query string: `at_distances=500,1000`.
                .style(list.then_some(ParameterStyle::Form))
                .explode(list.then_some(false))
                .build()
        })
        .collect()
}

/// A `oneOf` of one inline schema (what an optional enum member with a `default` becomes)
/// made that schema itself, the default and description moved onto it: a composition of one
/// says nothing, and linters refuse it.
fn single_choice(property: RefOr<Schema>) -> RefOr<Schema> {
    let RefOr::T(Schema::OneOf(one)) = &property else {
        return property;
    };
    match one.items.as_slice() {
        [RefOr::T(Schema::Object(object))] => {
            let mut object = object.clone();
            object.default = one.default.clone().or(object.default);
            object.description = one.description.clone().or(object.description);
            RefOr::T(Schema::Object(object))
        }
        _ => property,
    }
}

/// One documented error response: its status, what it means, and its examples, each the
/// problem the server really answers for one case (rendered by [`ApiError::problem`]), so that
/// every status shows its own `status`, `title` and `errors`.
#[derive(Clone, Copy)]
pub struct ErrorDoc {
    pub status: StatusCode,
    pub description: &'static str,
    pub examples: fn() -> Vec<(&'static str, ApiError)>,
}

/// The request id shown in examples.
const EXAMPLE_REQUEST_ID: &str = "5b0f9b5c-3c1e-4c8e-9d0a-7f1c2e4b8a61";

/// The error responses an operation documents, for `#[utoipa::path(responses(...))]`.
pub fn problem_responses(docs: &[ErrorDoc]) -> BTreeMap<String, RefOr<OpenApiResponse>> {
    docs.iter()
        .map(|doc| {
            let mut response = ResponseBuilder::new().description(doc.description);
            if doc.status == StatusCode::SERVICE_UNAVAILABLE
                && doc.description.contains("Retry-After")
            {
                response = response.header(
                    "Retry-After",
                    HeaderBuilder::new()
                        .schema(
                            ObjectBuilder::new()
                                .schema_type(Type::Integer)
                                .minimum(Some(0)),
                        )
                        .description(Some(
                            "Seconds to wait before retrying; sent when the request was shed \
                             at the concurrency limit.",
                        ))
                        .build(),
                );
            }
            let examples = (doc.examples)().into_iter().map(|(name, error)| {
                debug_assert_eq!(error.status(), doc.status, "{name}");
                let mut problem = error.problem();
                problem.request_id = Some(EXAMPLE_REQUEST_ID.to_owned());
                let example = ExampleBuilder::new()
                    .summary(name)
                    .value(serde_json::to_value(problem).ok())
                    .build();
                let key: String = name
                    .chars()
                    .map(|c| {
                        if c.is_ascii_alphanumeric() {
                            c.to_ascii_lowercase()
                        } else {
                            '-'
                        }
                    })
                    .collect();
                (key, example)
            });
            let response = response
                .content(
                    PROBLEM_JSON,
                    ContentBuilder::new()
                        .schema(Some(RefOr::Ref(utoipa::openapi::Ref::from_schema_name(
                            "Problem",
                        ))))
                        .examples_from_iter(examples)
                        .build(),
                )
                .build();
            (doc.status.as_u16().to_string(), RefOr::T(response))
        })
        .collect()
}

/// The 400 of a body that is not JSON: serde_json's own words for a truncated body.
fn broken_json() -> Vec<(&'static str, ApiError)> {
    let error = serde_json::from_str::<serde_json::Value>(r#"{"baseline": 150,"#)
        .err()
        .map_or_else(
            || ApiError::Malformed(FieldError::new("body", "invalid JSON")),
            |e| malformed_json(&e),
        );
    vec![("A truncated body", error)]
}

/// The 400 of a query string that does not percent-decode.
fn broken_query() -> Vec<(&'static str, ApiError)> {
    let error = match decode_query::<NoMembers>("unit=%FF") {
        Err(error) => error,
        Ok(_) => ApiError::Malformed(FieldError::new("query", "cannot be decoded")),
    };
    vec![("Invalid percent-encoding", error)]
}

/// A request type without members, to decode a query string for an example.
#[derive(serde::Deserialize)]
struct NoMembers {}

impl QueryForm for NoMembers {}

/// The 422 an example request gets: a zero baseline, an unknown unit and an `x_left` off an
/// 800 px image (`tests/api/openapi.rs` sends it and compares).
fn invalid_example() -> ApiError {
    ApiError::Invalid(vec![
        FieldError::new("unit", "must be one of mm, cm, m, in, ft, got `meters`"),
        FieldError::new("baseline", "must be greater than 0, got 0"),
        FieldError::new("x_left", "must lie in [0, 800] (the image width), got 900"),
    ])
}

const BAD_QUERY: ErrorDoc = ErrorDoc {
    status: StatusCode::BAD_REQUEST,
    description: "The query string cannot be decoded (for example invalid percent-encoding).",
    examples: broken_query,
};
const BAD_JSON: ErrorDoc = ErrorDoc {
    status: StatusCode::BAD_REQUEST,
    description: "The body is not valid JSON.",
    examples: broken_json,
};
const TOO_LARGE: ErrorDoc = ErrorDoc {
    status: StatusCode::PAYLOAD_TOO_LARGE,
    description: "The body is larger than the configured limit (64 KiB by default; 2 MiB for \
                  POST /distance, which takes batches).",
    examples: || {
        vec![(
            "A body over the default limit",
            ApiError::PayloadTooLarge(BodyLimit {
                bytes: DEFAULT_BODY_LIMIT,
                set_by: LimitOption::Body,
            }),
        )]
    },
};
const NOT_JSON: ErrorDoc = ErrorDoc {
    status: StatusCode::UNSUPPORTED_MEDIA_TYPE,
    description: "The body is not declared as application/json.",
    examples: || {
        vec![(
            "A form body",
            ApiError::UnsupportedMediaType {
                got: "application/x-www-form-urlencoded".to_owned(),
                accepted: "application/json",
            },
        )]
    },
};
const INVALID: ErrorDoc = ErrorDoc {
    status: StatusCode::UNPROCESSABLE_ENTITY,
    description: "One or more fields are missing, of the wrong type, unknown or out of range, \
                  or the point is at infinity; `errors` names every one.",
    examples: || vec![("Three fields at fault", invalid_example())],
};
const TIMEOUT: ErrorDoc = ErrorDoc {
    status: StatusCode::REQUEST_TIMEOUT,
    description: "The request body did not arrive within the request timeout (5 s by default, \
                  30 s for images), or arrived slower than the minimum rate (1 KiB/s on average \
                  once the first 5 s have passed, by default); then the connection is closed.",
    examples: || {
        vec![
            (
                "A body still arriving at the deadline",
                ApiError::Timeout {
                    after: DEFAULT_REQUEST_TIMEOUT,
                    body_received: false,
                },
            ),
            (
                "A body slower than the minimum rate",
                ApiError::SlowBody {
                    received: 3,
                    after: DEFAULT_BODY_RATE_GRACE,
                    min_rate: DEFAULT_MIN_BODY_RATE as u64,
                },
            ),
        ]
    },
};
const UNAVAILABLE: ErrorDoc = ErrorDoc {
    status: StatusCode::SERVICE_UNAVAILABLE,
    description: "The server is at its concurrency limit (with a `Retry-After` header) or could \
                  not answer within the request timeout; retry later.",
    examples: || {
        vec![
            (
                "Shed at the concurrency limit",
                ApiError::Overloaded {
                    retry_after_secs: RETRY_AFTER_SECS,
                },
            ),
            (
                "No answer within the timeout",
                ApiError::Timeout {
                    after: DEFAULT_REQUEST_TIMEOUT,
                    body_received: true,
                },
            ),
        ]
    },
};
const UNAUTHORIZED: ErrorDoc = ErrorDoc {
    status: StatusCode::UNAUTHORIZED,
    description: "The service was given bearer tokens and the request brought none, or one it \
                  does not accept; `WWW-Authenticate: Bearer` says so (with \
                  `error=\"invalid_token\"` for a token refused).",
    examples: || {
        vec![
            ("No token", ApiError::Unauthorized { refused: false }),
            ("A token refused", ApiError::Unauthorized { refused: true }),
        ]
    },
};

/// The bearer tokens in the document: the `bearerAuth` scheme, and every operation but the
/// probes declaring it, optional (`[{bearerAuth: []}, {}]`: the service asks for a token only
/// when it was given some) and documenting its 401 with `WWW-Authenticate`; the probes need
/// none (`[{}]`).
pub fn bearer_tokens(doc: &mut utoipa::openapi::OpenApi) {
    use utoipa::openapi::security::{
        HttpAuthScheme, HttpBuilder, SecurityRequirement, SecurityScheme,
    };
    let components = doc.components.get_or_insert_with(Default::default);
    components.add_security_scheme(
        "bearerAuth",
        SecurityScheme::Http(
            HttpBuilder::new()
                .scheme(HttpAuthScheme::Bearer)
                .description(Some(
                    "A token the service was given (`--api-tokens-file`, `API_TOKENS`); a \
                     service given none takes requests without one.",
                ))
                .build(),
        ),
    );
    let mut unauthorized = problem_responses(&[UNAUTHORIZED]);
    let Some(RefOr::T(mut response)) = unauthorized.remove("401") else {
        return;
    };
    response.headers.insert(
        "WWW-Authenticate".to_owned(),
        HeaderBuilder::new()
            .schema(ObjectBuilder::new().schema_type(Type::String))
            .description(Some("`Bearer realm=\"stereo-distance\"`, with `error=\"invalid_token\"` for a token refused."))
            .build(),
    );
    for (path, item) in doc.paths.paths.iter_mut() {
        let open = OPEN_PROBES.contains(&path.as_str());
        for operation in [&mut item.get, &mut item.post].into_iter().flatten() {
            if open {
                operation.security = Some(vec![SecurityRequirement::default()]);
            } else {
                operation
                    .responses
                    .responses
                    .insert("401".to_owned(), RefOr::T(response.clone()));
            }
        }
    }
    doc.security = Some(vec![
        SecurityRequirement::new("bearerAuth", Vec::<String>::new()),
        SecurityRequirement::default(),
    ]);
}

pub const METHOD: ErrorDoc = ErrorDoc {
    status: StatusCode::METHOD_NOT_ALLOWED,
    description: "The path does not support this method.",
    examples: || vec![("DELETE", ApiError::MethodNotAllowed("DELETE".to_owned()))],
};
pub const DRAINING: ErrorDoc = ErrorDoc {
    status: StatusCode::SERVICE_UNAVAILABLE,
    description: "The server is starting or draining before shutdown; send traffic elsewhere.",
    examples: || vec![("Draining", ApiError::Draining)],
};

/// Error responses of an operation that reads a JSON body.
pub struct BodyErrors;

impl utoipa::IntoResponses for BodyErrors {
    fn responses() -> BTreeMap<String, RefOr<OpenApiResponse>> {
        problem_responses(&[
            BAD_JSON,
            METHOD,
            TIMEOUT,
            TOO_LARGE,
            NOT_JSON,
            INVALID,
            UNAVAILABLE,
        ])
    }
}

/// An answer's body in the document: a component schema, by its type.
pub fn named<T: utoipa::ToSchema>() -> RefOr<Schema> {
    utoipa::openapi::Ref::from_schema_name(T::name()).into()
}

/// An answer's body in the document: text.
pub fn text() -> RefOr<Schema> {
    ObjectBuilder::new().schema_type(Type::String).into()
}

/// The responses of an image operation: its 200, `description` with the `Server-Timing` of its
/// stages and a body for each media type in `bodies`, then [`ImageErrors`]. Declared for each
/// route by [`image_answers!`].
pub fn image_responses(
    description: &str,
    bodies: Vec<(&str, RefOr<Schema>)>,
) -> BTreeMap<String, RefOr<OpenApiResponse>> {
    let timing = HeaderBuilder::new()
        .schema(ObjectBuilder::new().schema_type(Type::String))
        .description(Some("Stage times in milliseconds."))
        .build();
    let ok = bodies.into_iter().fold(
        ResponseBuilder::new()
            .description(description)
            .header("Server-Timing", timing),
        |ok, (media, schema)| ok.content(media, ContentBuilder::new().schema(Some(schema)).build()),
    );
    let mut responses = <ImageErrors as utoipa::IntoResponses>::responses();
    responses.insert("200".to_owned(), ok.build().into());
    responses
}

/// Declares an image route's responses for `#[utoipa::path(responses(…))]`:
/// `image_answers! { pub struct Answers: "what the 200 is" { "media/type" => body, … } }`,
/// each body [`named`] or [`text`] (see [`image_responses`]).
macro_rules! image_answers {
    (
        $(#[$meta:meta])*
        pub struct $name:ident: $description:literal { $($media:literal => $body:expr),+ $(,)? }
    ) => {
        $(#[$meta])*
        pub struct $name;

        impl ::utoipa::IntoResponses for $name {
            fn responses() -> ::std::collections::BTreeMap<
                String,
                ::utoipa::openapi::RefOr<::utoipa::openapi::response::Response>,
            > {
                $crate::api::wire::openapi::image_responses(
                    $description,
                    vec![$(($media, $body)),+],
                )
            }
        }
    };
}

pub(crate) use image_answers;

/// Error responses of an image operation (multipart form, query options, memory budget).
pub struct ImageErrors;

impl utoipa::IntoResponses for ImageErrors {
    fn responses() -> BTreeMap<String, RefOr<OpenApiResponse>> {
        problem_responses(&[
            BAD_FORM,
            METHOD,
            TIMEOUT,
            IMAGES_TOO_LARGE,
            NOT_FORM,
            INVALID_IMAGES,
            IMAGES_UNAVAILABLE,
        ])
    }
}

const BAD_FORM: ErrorDoc = ErrorDoc {
    status: StatusCode::BAD_REQUEST,
    description: "The multipart body or the query string cannot be decoded.",
    examples: || {
        vec![(
            "A body cut short",
            ApiError::Malformed(FieldError::new(
                "body",
                "is not a readable multipart/form-data body: Failed to read stream",
            )),
        )]
    },
};
const IMAGES_TOO_LARGE: ErrorDoc = ErrorDoc {
    status: StatusCode::PAYLOAD_TOO_LARGE,
    description: "The body is larger than the heavy group's limit (32 MiB by default), an image \
                  is beyond 8192 px a side or `--max-image-pixels` (34 megapixels by default), or the request would need more \
                  memory than the heavy group's whole budget; `errors` names what to shrink.",
    examples: || {
        vec![(
            "Images too large",
            ApiError::Oversized(vec![FieldError::new(
                "left",
                "is 20000 × 20000 pixels; this server takes at most 8192 pixels a side and 34 \
                 megapixels: send smaller images (scale the rig with them)",
            )]),
        )]
    },
};
const NOT_FORM: ErrorDoc = ErrorDoc {
    status: StatusCode::UNSUPPORTED_MEDIA_TYPE,
    description: "The body is not multipart/form-data.",
    examples: || {
        vec![(
            "A JSON body",
            ApiError::UnsupportedMediaType {
                got: "Invalid `boundary` for `multipart/form-data` request".to_owned(),
                accepted: "multipart/form-data",
            },
        )]
    },
};
const INVALID_IMAGES: ErrorDoc = ErrorDoc {
    status: StatusCode::UNPROCESSABLE_ENTITY,
    description: "A part is missing, unknown, not a PNG or JPEG, the pair's sizes differ, the \
                  rig or calibration is at fault, or an option is out of range; `errors` names \
                  every part and parameter.",
    examples: || {
        vec![(
            "A pair of two sizes and a bad rig",
            ApiError::Invalid(vec![
                FieldError::new(
                    "right",
                    "is 740 × 500 pixels but the left image is 741 × 500: a rectified pair has \
                     one size",
                ),
                FieldError::new("rig.baseline", "must be greater than 0, got 0"),
            ]),
        )]
    },
};
const IMAGES_UNAVAILABLE: ErrorDoc = ErrorDoc {
    status: StatusCode::SERVICE_UNAVAILABLE,
    description: "The heavy group is at its concurrency limit or its memory budget is held by \
                  the image requests in flight (with `Retry-After`), or the answer took longer \
                  than the heavy request timeout (30 s by default); retry later.",
    examples: || {
        vec![
            (
                "Shed at the concurrency limit",
                ApiError::Overloaded {
                    retry_after_secs: RETRY_AFTER_SECS,
                },
            ),
            (
                "Memory held by other requests",
                ApiError::Memory(crate::budget::Refusal::Busy {
                    requested: 120 << 20,
                    available: 40 << 20,
                }),
            ),
        ]
    },
};

/// Error responses of a probe, which reads nothing and is never shed or timed out.
pub struct ProbeErrors;

impl utoipa::IntoResponses for ProbeErrors {
    fn responses() -> BTreeMap<String, RefOr<OpenApiResponse>> {
        problem_responses(&[METHOD])
    }
}

/// Error responses of an operation that reads the query string.
pub struct QueryErrors;

impl utoipa::IntoResponses for QueryErrors {
    fn responses() -> BTreeMap<String, RefOr<OpenApiResponse>> {
        problem_responses(&[BAD_QUERY, METHOD, TIMEOUT, INVALID, UNAVAILABLE])
    }
}
