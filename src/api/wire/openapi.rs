//! OpenAPI glue: the query parameters of a GET operation derived from its POST body schema,
//! and the problem+json error responses each kind of operation documents.

use std::collections::BTreeMap;

use axum::http::StatusCode;
use utoipa::openapi::{
    ContentBuilder, ObjectBuilder, RefOr, Required, ResponseBuilder, Type,
    header::HeaderBuilder,
    path::{Parameter, ParameterBuilder, ParameterIn, ParameterStyle},
    response::Response as OpenApiResponse,
    schema::Schema,
};

use crate::api::error::PROBLEM_JSON;

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
            let (description, list) = match &property {
                RefOr::T(Schema::Object(o)) => (o.description.clone(), false),
                RefOr::T(Schema::Array(a)) => (a.description.clone(), true),
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

/// The error responses an operation documents, for `#[utoipa::path(responses(...))]`.
pub fn problem_responses(
    statuses: &[(StatusCode, &str)],
) -> BTreeMap<String, RefOr<OpenApiResponse>> {
    statuses
        .iter()
        .map(|(status, description)| {
            let mut response = ResponseBuilder::new().description(*description);
            if *status == StatusCode::SERVICE_UNAVAILABLE && description.contains("Retry-After") {
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
            let response = response
                .content(
                    PROBLEM_JSON,
                    ContentBuilder::new()
                        .schema(Some(RefOr::Ref(utoipa::openapi::Ref::from_schema_name(
                            "Problem",
                        ))))
                        .build(),
                )
                .build();
            (status.as_u16().to_string(), RefOr::T(response))
        })
        .collect()
}

const BAD_QUERY: (StatusCode, &str) = (
    StatusCode::BAD_REQUEST,
    "The query string cannot be decoded (for example invalid percent-encoding).",
);
const BAD_JSON: (StatusCode, &str) = (StatusCode::BAD_REQUEST, "The body is not valid JSON.");
const TOO_LARGE: (StatusCode, &str) = (
    StatusCode::PAYLOAD_TOO_LARGE,
    "The body is larger than the configured limit (64 KiB by default; 2 MiB for POST /distance, \
     which takes batches).",
);
const NOT_JSON: (StatusCode, &str) = (
    StatusCode::UNSUPPORTED_MEDIA_TYPE,
    "The body is not declared as application/json.",
);
const INVALID: (StatusCode, &str) = (
    StatusCode::UNPROCESSABLE_ENTITY,
    "One or more fields are missing, of the wrong type, unknown or out of range, or the point \
     is at infinity; `errors` names every one.",
);
const TIMEOUT: (StatusCode, &str) = (
    StatusCode::REQUEST_TIMEOUT,
    "The request body did not arrive within the request timeout (5 s by default).",
);
const UNAVAILABLE: (StatusCode, &str) = (
    StatusCode::SERVICE_UNAVAILABLE,
    "The server is at its concurrency limit (with a `Retry-After` header) or could not answer \
     within the request timeout; retry later.",
);
pub const METHOD: (StatusCode, &str) = (
    StatusCode::METHOD_NOT_ALLOWED,
    "The path does not support this method.",
);

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
