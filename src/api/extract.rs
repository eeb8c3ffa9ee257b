//! Request extractors that decode a JSON body or a query string into a request type, and that
//! name *every* field serde refused rather than stopping at the first.
//!
//! Valid input takes one typed `serde_json` pass. Only when that fails is the input parsed again
//! as a map and each member checked on its own, so each wrong type and each unknown field gets its
//! own entry in the problem's `errors`.

use axum::{
    body::Bytes,
    extract::{FromRequest, FromRequestParts, Request},
    http::{StatusCode, header, request::Parts},
};
use percent_encoding::percent_decode_str;
use serde::de::DeserializeOwned;
use serde_json::{Map, Value};

use super::error::{ApiError, FieldError};

/// A JSON request body, decoded and type-checked; the rejection is always an [`ApiError`].
#[derive(Debug, Clone)]
pub struct JsonBody<T>(pub T);

/// Query-string parameters decoded with the same rules as a JSON body, so that `?baseline=150`
/// and `{"baseline": 150}` are one request. Numbers are recognised as JSON numbers; anything else
/// stays a string, so `abc`, `nan` or `inf` where a number belongs is a 422 naming that field.
#[derive(Debug, Clone)]
pub struct QueryParams<T>(pub T);

impl<S, T> FromRequest<S> for JsonBody<T>
where
    S: Send + Sync,
    T: DeserializeOwned,
{
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &S) -> Result<Self, Self::Rejection> {
        let content_type = req
            .headers()
            .get(header::CONTENT_TYPE)
            .map(|v| String::from_utf8_lossy(v.as_bytes()).into_owned());
        match content_type.as_deref() {
            Some(ct) if is_json(ct) => {}
            Some(ct) => return Err(ApiError::UnsupportedMediaType(ct.to_owned())),
            None => return Err(ApiError::UnsupportedMediaType("no Content-Type".to_owned())),
        }
        let limit = body_limit(&req);
        let bytes = Bytes::from_request(req, state).await.map_err(|rejection| {
            if rejection.status() == StatusCode::PAYLOAD_TOO_LARGE {
                ApiError::PayloadTooLarge(limit)
            } else {
                ApiError::Malformed(FieldError::new("body", rejection.body_text()))
            }
        })?;
        decode_json(&bytes).map(JsonBody)
    }
}

impl<S, T> FromRequestParts<S> for QueryParams<T>
where
    S: Send + Sync,
    T: DeserializeOwned,
{
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, _state: &S) -> Result<Self, Self::Rejection> {
        decode_query(parts.uri.query().unwrap_or_default()).map(QueryParams)
    }
}

/// The body limit in force, recorded by [`crate::startup`] as a request extension.
#[derive(Debug, Clone, Copy)]
pub struct BodyLimit(pub usize);

fn body_limit(req: &Request) -> usize {
    req.extensions()
        .get::<BodyLimit>()
        .map_or(crate::config::DEFAULT_BODY_LIMIT, |l| l.0)
}

/// `application/json`, or any `application/*+json`, with or without parameters.
fn is_json(content_type: &str) -> bool {
    let essence = content_type
        .split(';')
        .next()
        .unwrap_or_default()
        .trim()
        .to_ascii_lowercase();
    essence == "application/json"
        || (essence.starts_with("application/") && essence.ends_with("+json"))
}

/// Decodes a JSON body into `T`, naming every offending member on failure.
pub fn decode_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    match serde_json::from_slice::<T>(bytes) {
        Ok(value) => Ok(value),
        Err(error) if error.is_data() => match serde_json::from_slice::<Value>(bytes) {
            Ok(Value::Object(map)) => Err(diagnose::<T>(&map, &error, Vec::new())),
            Ok(_) => Err(ApiError::invalid("body", "must be a JSON object")),
            Err(syntax) => Err(malformed_json(&syntax)),
        },
        Err(error) => Err(malformed_json(&error)),
    }
}

fn malformed_json(error: &serde_json::Error) -> ApiError {
    ApiError::Malformed(FieldError::new("body", format!("invalid JSON: {error}")))
}

/// Decodes a query string into `T` by way of a JSON object, naming every offending parameter.
pub fn decode_query<T: DeserializeOwned>(query: &str) -> Result<T, ApiError> {
    let mut map = Map::new();
    let mut repeated = Vec::new();
    for pair in query.split('&').filter(|p| !p.is_empty()) {
        let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
        let key = decode_component(key)?;
        let value = decode_component(value)?;
        let value = match serde_json::from_str::<serde_json::Number>(&value) {
            Ok(number) => Value::Number(number),
            Err(_) => Value::String(value),
        };
        if map.insert(key.clone(), value).is_some() && !repeated.contains(&key) {
            repeated.push(key);
        }
    }
    let repeated: Vec<FieldError> = repeated
        .into_iter()
        .map(|key| FieldError::new(key, "is given more than once; give it once"))
        .collect();
    match T::deserialize(&Value::Object(map.clone())) {
        Ok(value) if repeated.is_empty() => Ok(value),
        Ok(_) => Err(ApiError::Invalid(repeated)),
        Err(error) => Err(diagnose::<T>(&map, &error, repeated)),
    }
}

/// Percent-decodes one `application/x-www-form-urlencoded` component (`+` is a space).
fn decode_component(raw: &str) -> Result<String, ApiError> {
    let spaced = raw.replace('+', " ");
    percent_decode_str(&spaced)
        .decode_utf8()
        .map(|s| s.into_owned())
        .map_err(|_| {
            ApiError::Malformed(FieldError::new(
                "query",
                format!("`{raw}` does not percent-decode to UTF-8"),
            ))
        })
}

/// Finds every member of `map` that `T` refuses on its own. Request types have only optional
/// members, so a one-member object fails exactly when that member is unknown or mistyped.
fn diagnose<T: DeserializeOwned>(
    map: &Map<String, Value>,
    whole: &serde_json::Error,
    mut errors: Vec<FieldError>,
) -> ApiError {
    for (key, value) in map {
        let single = Value::Object(Map::from_iter([(key.clone(), value.clone())]));
        if let Err(error) = T::deserialize(&single) {
            errors.push(FieldError::new(key.clone(), plain_message(&error)));
        }
    }
    if errors.is_empty() {
        // Not attributable to one member alone, such as a member given twice.
        let message = plain_message(whole);
        let field = message
            .strip_prefix("duplicate field `")
            .and_then(|rest| rest.split('`').next())
            .unwrap_or("body")
            .to_owned();
        errors.push(FieldError::new(field, message));
    }
    ApiError::Invalid(errors)
}

/// serde's message without its position suffix, with Rust type names in words.
fn plain_message(error: &serde_json::Error) -> String {
    let text = error.to_string();
    let text = text
        .split(" at line ")
        .next()
        .unwrap_or(text.as_str())
        .to_owned();
    text.replace("expected f64", "expected a number")
        .replace("expected u32", "expected a whole number")
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, Deserialize, PartialEq)]
    #[serde(deny_unknown_fields)]
    struct Probe {
        a: Option<f64>,
        n: Option<u32>,
        s: Option<String>,
    }

    fn fields(error: ApiError) -> Vec<String> {
        match error {
            ApiError::Invalid(errors) => errors.into_iter().map(|e| e.field).collect(),
            other => panic!("expected 422, got {other:?}"),
        }
    }

    /// A good body decodes in one pass.
    #[test]
    fn valid_json_decodes() {
        let p: Probe = decode_json(br#"{"a": 1.5, "n": 3}"#).unwrap();
        assert_eq!(
            p,
            Probe {
                a: Some(1.5),
                n: Some(3),
                s: None
            }
        );
    }

    /// Every wrong member is named, not just the first.
    #[test]
    fn every_bad_member_is_named() {
        let err = decode_json::<Probe>(br#"{"a": "1", "n": 2.5, "zz": 1, "s": "ok"}"#).unwrap_err();
        assert_eq!(fields(err), vec!["a", "n", "zz"]);
    }

    /// Broken JSON is a 400, a non-object a 422, and a duplicate member is named.
    #[test]
    fn syntax_and_shape_errors() {
        assert!(matches!(
            decode_json::<Probe>(b"{\"a\": "),
            Err(ApiError::Malformed(_))
        ));
        assert!(matches!(
            decode_json::<Probe>(b"{\"a\": 1e999}"),
            Err(ApiError::Malformed(_))
        ));
        assert_eq!(
            fields(decode_json::<Probe>(b"[1]").unwrap_err()),
            vec!["body"]
        );
        assert_eq!(
            fields(decode_json::<Probe>(br#"{"a": 1, "a": 2}"#).unwrap_err()),
            vec!["a"]
        );
    }

    /// Query values become numbers when they are JSON numbers and strings otherwise.
    #[test]
    fn query_types() {
        let p: Probe = decode_query("a=2.5&n=7&s=hello+world%21").unwrap();
        assert_eq!(
            p,
            Probe {
                a: Some(2.5),
                n: Some(7),
                s: Some("hello world!".to_owned())
            }
        );
        let err = decode_query::<Probe>("a=nan&n=inf&s=x&a=3").unwrap_err();
        assert_eq!(fields(err), vec!["a", "n"]);
        let err = decode_query::<Probe>("a=1&a=2").unwrap_err();
        assert_eq!(fields(err), vec!["a"]);
        assert!(matches!(
            decode_query::<Probe>("s=%FF"),
            Err(ApiError::Malformed(_))
        ));
    }

    /// JSON media types are recognised with parameters and suffixes.
    #[test]
    fn json_content_types() {
        assert!(is_json("application/json"));
        assert!(is_json("Application/JSON; charset=utf-8"));
        assert!(is_json("application/problem+json"));
        assert!(!is_json("text/plain"));
        assert!(!is_json("application/x-www-form-urlencoded"));
    }
}
