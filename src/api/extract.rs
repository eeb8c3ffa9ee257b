//! Request extractors that decode a JSON body or a query string into a request type, and that
//! name *every* member serde refused rather than stopping at the first.
//!
//! Valid input takes one typed `serde_json` pass. Only when that fails is the input parsed again
//! as a map and each member checked on its own: each wrong type and each unknown member is
//! recorded in [`FieldErrors`], and the rest is still decoded, so that validation can add its own
//! findings and one answer names everything that is wrong.

use axum::{
    body::Bytes,
    extract::{FromRef, FromRequest, FromRequestParts, Request},
    http::{HeaderValue, Uri, header, request::Parts},
};
use percent_encoding::percent_decode_str;
use serde::de::DeserializeOwned;
use serde_json::{Map, Value};

use super::body_limit::BodyLimit;
use super::error::{ApiError, FieldError, FieldErrors};
use super::member_messages::{self, Complaint, ECHO};
use stereo_core::numbers::clip;

/// A JSON request body, decoded as far as it could be, with the members it refused and the
/// query parameters it would have ignored ([`unread_query`]). The rejection (400, 413, 415, or 422 for a body that is not an object) is an [`ApiError`].
#[derive(Debug)]
pub struct JsonBody<T>(pub T, pub FieldErrors);

/// Query-string parameters decoded with the same rules as a JSON body, so that `?baseline=150`
/// and `{"baseline": 150}` are one request. Numbers are recognised as JSON numbers; anything else
/// stays a string, so `abc`, `nan` or `inf` where a number belongs is a 422 naming that field.
#[derive(Debug)]
pub struct QueryParams<T>(pub T, pub FieldErrors);

impl<S, T> FromRequest<S> for JsonBody<T>
where
    S: Send + Sync,
    BodyLimit: FromRef<S>,
    T: DeserializeOwned,
{
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &S) -> Result<Self, Self::Rejection> {
        let mut problems = unread_query(req.uri());
        let bytes = json_bytes(req, BodyLimit::from_ref(state)).await?;
        let (value, refused) = decode_json(&bytes)?;
        problems.extend(refused);
        Ok(JsonBody(value, problems))
    }
}

/// Each query parameter of a request whose members come in its JSON body: it would be
/// ignored, so it is named instead (a caller who sent `?format=csv` must hear that it was).
pub fn unread_query(uri: &Uri) -> FieldErrors {
    let mut problems = FieldErrors::default();
    for pair in uri.query().unwrap_or_default().split('&') {
        let name = pair.split('=').next().unwrap_or_default();
        if !name.is_empty() {
            problems.add(
                &clip(name, ECHO),
                "is a query parameter, but this POST reads its members from the JSON body",
            );
        }
    }
    problems
}

/// The body of a request declared as JSON, within `limit`: 415 for another content type, 413
/// beyond the limit.
pub async fn json_bytes(req: Request, limit: BodyLimit) -> Result<Bytes, ApiError> {
    match req.headers().get(header::CONTENT_TYPE) {
        Some(ct) if ct.to_str().is_ok_and(is_json) => {}
        other => return Err(unsupported(other, "application/json")),
    }
    body_bytes(req, limit).await
}

/// The 415 for a body sent as `content_type` (or none) where `accepted` was expected.
pub fn unsupported(content_type: Option<&HeaderValue>, accepted: &'static str) -> ApiError {
    let got = content_type.map_or_else(
        || "no Content-Type".to_owned(),
        |ct| String::from_utf8_lossy(ct.as_bytes()).into_owned(),
    );
    ApiError::UnsupportedMediaType { got, accepted }
}

/// The body, whatever its type, within `limit`: 413 beyond it.
pub async fn body_bytes(req: Request, limit: BodyLimit) -> Result<Bytes, ApiError> {
    axum::body::to_bytes(req.into_body(), limit.bytes)
        .await
        .map_err(|error| {
            let too_large = std::error::Error::source(&error)
                .is_some_and(|source| source.is::<http_body_util::LengthLimitError>());
            if too_large {
                ApiError::PayloadTooLarge(limit)
            } else {
                ApiError::Malformed(FieldError::new(
                    "body",
                    format!("the body could not be read: {error}"),
                ))
            }
        })
}

/// A request type that can come as a query string: which of its members are lists, given
/// comma-separated (OpenAPI `style: form, explode: false`), such as `at_distances=500,1000`,
/// or repeated, `at_distances=500&at_distances=1000`, as many generated clients send them.
pub trait QueryForm: DeserializeOwned {
    /// The members that are lists.
    const LISTS: &'static [&'static str] = &[];
}

impl<S, T> FromRequestParts<S> for QueryParams<T>
where
    S: Send + Sync,
    T: QueryForm,
{
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, _state: &S) -> Result<Self, Self::Rejection> {
        decode_query(parts.uri.query().unwrap_or_default())
            .map(|(value, problems)| QueryParams(value, problems))
    }
}

/// A media type without its parameters: `text/plain` of `text/plain; charset=utf-8`.
pub fn essence(content_type: &str) -> &str {
    content_type.split(';').next().unwrap_or_default().trim()
}

/// `application/json`, or any `application/*+json`, with or without parameters.
pub fn is_json(content_type: &str) -> bool {
    let essence = essence(content_type);
    let starts = |prefix: &str| {
        essence
            .get(..prefix.len())
            .is_some_and(|head| head.eq_ignore_ascii_case(prefix))
    };
    let ends = |suffix: &str| {
        essence
            .len()
            .checked_sub(suffix.len())
            .and_then(|at| essence.get(at..))
            .is_some_and(|tail| tail.eq_ignore_ascii_case(suffix))
    };
    essence.eq_ignore_ascii_case("application/json") || (starts("application/") && ends("+json"))
}

/// Checks that a body is a JSON object before serde sees it: serde would read an array into a
/// struct by position, and only objects are requests.
pub fn expect_object(bytes: &[u8]) -> Result<(), ApiError> {
    if bytes.trim_ascii_start().first() == Some(&b'{') {
        return Ok(());
    }
    match serde_json::from_slice::<serde::de::IgnoredAny>(bytes) {
        Ok(_) => Err(ApiError::invalid("body", "must be a JSON object")),
        Err(error) => Err(malformed_json(&error)),
    }
}

/// Decodes a JSON body into `T` and the members it refused.
pub fn decode_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<(T, FieldErrors), ApiError> {
    expect_object(bytes)?;
    match serde_json::from_slice::<T>(bytes) {
        Ok(value) => Ok((value, FieldErrors::default())),
        // A typed pass can fail on valid JSON as a syntax error (serde_json reports a number
        // where a string belongs as `expected value`), so the body is read again to tell a
        // wrong member (422) from broken JSON (400).
        Err(error) => match serde_json::from_slice::<Map<String, Value>>(bytes) {
            Ok(map) => diagnose(map, &error, FieldErrors::default(), "body", None),
            Err(syntax) => Err(malformed_json(&syntax)),
        },
    }
}

/// Decodes one JSON object (such as an element of a batch) into `T`, naming every member it
/// refused; `T::default()` stands in for what could not be decoded at all.
pub fn decode_object<T: DeserializeOwned + Default>(map: Map<String, Value>) -> (T, FieldErrors) {
    match T::deserialize(&map) {
        Ok(value) => (value, FieldErrors::default()),
        Err(error) => match diagnose(map, &error, FieldErrors::default(), "", None) {
            Ok(decoded) => decoded,
            Err(ApiError::Invalid(errors)) => (T::default(), FieldErrors::from(errors)),
            Err(other) => (T::default(), FieldErrors::from(other.problem().errors)),
        },
    }
}

pub fn malformed_json(error: &serde_json::Error) -> ApiError {
    ApiError::Malformed(FieldError::new("body", format!("invalid JSON: {error}")))
}

/// Decodes a query string into `T` by way of a JSON object, with the parameters it refused.
pub fn decode_query<T: QueryForm>(query: &str) -> Result<(T, FieldErrors), ApiError> {
    let mut map = Map::new();
    let mut problems = FieldErrors::default();
    for pair in query.split('&').filter(|p| !p.is_empty()) {
        let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
        let key = decode_component(key)?;
        let value = decode_component(value)?;
        if T::LISTS.contains(&key.as_str()) {
            // Comma-separated (`explode: false`) or repeated (`at_distances=500&at_distances=
            // 1000`, as many generated clients send lists), or both: the items in order.
            let items = value
                .split(',')
                .filter(|item| !item.is_empty())
                .map(query_scalar);
            if let Value::Array(list) = map.entry(key).or_insert_with(|| Value::Array(Vec::new())) {
                list.extend(items);
            }
            continue;
        }
        if map.insert(key.clone(), query_scalar(&value)).is_some() {
            let field = if key.is_empty() { "query" } else { &key };
            problems.add(field, "is given more than once; give it once");
        }
    }
    match T::deserialize(&map) {
        Ok(value) => Ok((value, problems)),
        Err(error) => diagnose(map, &error, problems, "query", Some(query)),
    }
}

/// The text `query` gives for `key` (the last, as the decoded map keeps it), read again only
/// when a member refuses the number it reads as.
fn query_text(query: &str, key: &str) -> Option<Value> {
    query
        .split('&')
        .filter_map(|pair| {
            let (k, v) = pair.split_once('=').unwrap_or((pair, ""));
            (decode_component(k).ok()? == key).then_some(v)
        })
        .next_back()
        .and_then(|v| decode_component(v).ok())
        .map(Value::String)
}

/// A query value as JSON: a number when it reads as a JSON number, else a string.
fn query_scalar(value: &str) -> Value {
    match serde_json::from_str::<serde_json::Number>(value) {
        Ok(number) => Value::Number(number),
        Err(_) => Value::String(value.to_owned()),
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
                format!("`{}` does not percent-decode to UTF-8", clip(raw, ECHO)),
            ))
        })
}

/// Records every member of `map` that `T` refuses on its own, then decodes the rest. Request
/// types have only optional members, so a one-member object fails exactly when that member is
/// unknown or mistyped, and the rest decodes. A member with an empty name is reported under
/// `itself`, the name of the object as a whole (`body`, `query`, or `""` for a batch point,
/// which its index then names), so that every error names something.
///
/// In a query string every value is text: a member that refuses the number a value of `query`
/// reads as takes the text instead (a string member given `123`).
fn diagnose<T: DeserializeOwned>(
    mut map: Map<String, Value>,
    whole: &serde_json::Error,
    mut problems: FieldErrors,
    itself: &str,
    query: Option<&str>,
) -> Result<(T, FieldErrors), ApiError> {
    let alone = |key: &str, value: &Value| {
        T::deserialize(&Value::Object(Map::from_iter([(
            key.to_owned(),
            value.clone(),
        )])))
    };
    let mut refused = Vec::new();
    let mut as_text = Vec::new();
    for (key, value) in &map {
        let Err(error) = alone(key, value) else {
            continue;
        };
        let raw = query
            .filter(|_| value.is_number())
            .and_then(|query| query_text(query, key));
        match raw {
            Some(raw) if alone(key, &raw).is_ok() => as_text.push((key.clone(), raw)),
            _ => refused.push((
                key.clone(),
                member_messages::message(&error.to_string(), Some(value)),
            )),
        }
    }
    let retyped = !as_text.is_empty();
    map.extend(as_text);
    for (key, message) in refused {
        map.remove(&key);
        if key.is_empty() {
            problems.add(
                itself,
                format!("has a member with an empty name: {message}"),
            );
        } else {
            problems.add(&clip(&key, ECHO), message);
        }
    }
    match T::deserialize(&map) {
        Ok(value) if retyped || !problems.is_empty() => Ok((value, problems)),
        // Not attributable to one member alone, such as a member given twice.
        _ => {
            let text = whole.to_string();
            let field = match member_messages::parse(&text) {
                Complaint::Duplicate { name } if !name.is_empty() => clip(name, ECHO),
                _ => itself.to_owned(),
            };
            problems.add(&field, member_messages::message(&text, None));
            Err(problems.into_error())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, Default, Deserialize, PartialEq)]
    #[serde(deny_unknown_fields)]
    struct Probe {
        a: Option<f64>,
        n: Option<u32>,
        s: Option<String>,
        list: Option<Vec<f64>>,
    }

    impl QueryForm for Probe {
        const LISTS: &'static [&'static str] = &["list"];
    }

    /// The fields named, whether refused while still decoding the rest, or in a 422.
    fn fields<T>(result: Result<(T, FieldErrors), ApiError>) -> Vec<String> {
        let error = match result {
            Ok((_, problems)) => problems.into_error(),
            Err(error) => error,
        };
        match error {
            ApiError::Invalid(errors) => errors.into_iter().map(|e| e.field).collect(),
            other => panic!("expected 422, got {other:?}"),
        }
    }

    /// A good body decodes in one pass, with nothing refused.
    #[test]
    fn valid_json_decodes() {
        let (p, problems): (Probe, _) = decode_json(br#"{"a": 1.5, "n": 3}"#).unwrap();
        assert!(problems.is_empty());
        assert_eq!(
            p,
            Probe {
                a: Some(1.5),
                n: Some(3),
                ..Probe::default()
            }
        );
    }

    /// Every wrong member is named, not just the first, and the rest still decodes.
    #[test]
    fn every_bad_member_is_named() {
        let result = decode_json::<Probe>(br#"{"a": "1", "n": 2.5, "zz": 1, "s": "ok"}"#);
        assert_eq!(result.as_ref().unwrap().0.s.as_deref(), Some("ok"));
        assert_eq!(fields(result), vec!["a", "n", "zz"]);
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
        assert_eq!(fields(decode_json::<Probe>(b"[1]")), vec!["body"]);
        assert_eq!(
            fields(decode_json::<Probe>(br#"{"a": 1, "a": 2}"#)),
            vec!["a"]
        );
    }

    /// Query values become numbers when they are JSON numbers and strings otherwise.
    #[test]
    fn query_types() {
        let (p, problems): (Probe, _) = decode_query("a=2.5&n=7&s=hello+world%21").unwrap();
        assert!(problems.is_empty());
        assert_eq!(
            p,
            Probe {
                a: Some(2.5),
                n: Some(7),
                s: Some("hello world!".to_owned()),
                list: None,
            }
        );
        assert_eq!(
            fields(decode_query::<Probe>("a=nan&n=inf&s=x&a=3")),
            vec!["a", "n"]
        );
        assert_eq!(fields(decode_query::<Probe>("a=1&a=2")), vec!["a"]);
        assert!(matches!(
            decode_query::<Probe>("s=%FF"),
            Err(ApiError::Malformed(_))
        ));
    }

    /// A list member is comma-separated in a query string; an empty value is an empty list,
    /// and a bad item is named by its member.
    #[test]
    fn query_lists() {
        let (p, _): (Probe, _) = decode_query("list=500,1000,2e3").unwrap();
        assert_eq!(p.list, Some(vec![500.0, 1000.0, 2000.0]));
        let (p, _): (Probe, _) = decode_query("list=").unwrap();
        assert_eq!(p.list, Some(vec![]));
        let (p, _): (Probe, _) = decode_query("list=7").unwrap();
        assert_eq!(p.list, Some(vec![7.0]));
        assert_eq!(fields(decode_query::<Probe>("list=1,x&s=ok")), vec!["list"]);
        // Repeated, as generated clients send lists, and mixed with commas.
        let (p, problems): (Probe, _) = decode_query("list=500&list=1000,2000&list=").unwrap();
        assert!(problems.is_empty());
        assert_eq!(p.list, Some(vec![500.0, 1000.0, 2000.0]));
        // A scalar member with a comma is one (wrong) value, not a list.
        assert_eq!(fields(decode_query::<Probe>("a=1,2")), vec!["a"]);
    }

    /// One object decodes on its own with every refused member named, defaults standing in.
    #[test]
    fn objects_decode_alone() {
        let map = |json: &str| serde_json::from_str::<Map<String, Value>>(json).unwrap();
        let (p, problems): (Probe, _) = decode_object(map(r#"{"a": 2, "n": 3}"#));
        assert!(problems.is_empty());
        assert_eq!(p.n, Some(3));
        let (p, problems): (Probe, _) = decode_object(map(r#"{"a": "x", "n": 3, "q": 1}"#));
        assert_eq!(p.n, Some(3));
        assert_eq!(fields(Ok::<_, ApiError>(((), problems))), vec!["a", "q"]);
    }

    /// A misspelt member gets the nearest known name; a stranger one gets the list.
    #[test]
    fn unknown_members_get_suggestions() {
        let (_, problems) = decode_json::<Probe>(br#"{"aa": 1, "zzzzzz": 2}"#).unwrap();
        let ApiError::Invalid(errors) = problems.into_error() else {
            panic!("a 422");
        };
        assert_eq!(errors[0].message, "unknown field `aa`; did you mean `a`?");
        assert!(
            errors[1]
                .message
                .ends_with("the members here are a, n, s, list")
        );
    }

    /// A wrongly typed member of valid JSON is a 422 naming it, even where serde_json's typed
    /// pass calls it a syntax error; only broken JSON is a 400.
    #[test]
    fn valid_json_with_a_wrong_member_is_422() {
        #[derive(Debug, Default, Deserialize)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct Chosen {
            #[serde(default, deserialize_with = "crate::api::wire::de::member")]
            unit: Option<crate::api::wire::params::Unit>,
        }
        let error = match decode_json::<Chosen>(br#"{"unit": 5}"#) {
            Ok((_, problems)) => problems.into_error(),
            Err(error) => error,
        };
        let ApiError::Invalid(errors) = error else {
            panic!("a 422, got {error:?}");
        };
        assert_eq!(errors[0].field, "unit");
        assert_eq!(errors[0].message, "must be one of mm, cm, m, in, ft, got 5");
    }

    /// In a query string a string member takes digits as text.
    #[test]
    fn query_text_members_take_digits() {
        let (p, problems): (Probe, _) = decode_query("s=123&a=1").unwrap();
        assert!(problems.is_empty());
        assert_eq!(p.s.as_deref(), Some("123"));
        assert_eq!(p.a, Some(1.0));
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
