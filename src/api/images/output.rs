//! How an image route answers: a file with its `Content-Type` and `Content-Disposition`
//! ([`file`]), documented as binary ([`FileBody`]), the `Server-Timing` header of its
//! stages ([`set_server_timing`]), the `Stereo-Projection` header of a depth map's pixels
//! ([`set_projection`]) and the `Stereo-Warnings` header of its warnings
//! ([`set_warnings`]), which a file answer has nowhere else to say.

use std::time::Duration;

pub use crate::api::wire::images::FileBody;
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};

/// Whether a browser shows a file answer or saves it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Disposition {
    /// Shown in place (a picture).
    Inline,
    /// Saved under its name (data for a tool).
    Attachment,
}

/// A file answer: `bytes` with their media type and the name to save them under.
pub fn file(bytes: Vec<u8>, media_type: &'static str, name: &str, how: Disposition) -> Response {
    let mut response = bytes.into_response();
    let headers = response.headers_mut();
    headers.insert(header::CONTENT_TYPE, HeaderValue::from_static(media_type));
    let how = match how {
        Disposition::Inline => "inline",
        Disposition::Attachment => "attachment",
    };
    if let Ok(v) = HeaderValue::from_str(&format!("{how}; filename=\"{name}\"")) {
        headers.insert(header::CONTENT_DISPOSITION, v);
    }
    response
}

/// `Server-Timing: read;dur=1.2, queue;dur=0.0, …`: each stage's time in milliseconds, in the
/// order given.
pub fn set_server_timing(response: &mut Response, stages: &[(&str, Duration)]) {
    let text = stages
        .iter()
        .map(|(name, d)| format!("{name};dur={:.1}", d.as_secs_f64() * 1e3))
        .collect::<Vec<_>>()
        .join(", ");
    if let Ok(v) = HeaderValue::from_str(&text) {
        response.headers_mut().insert("server-timing", v);
    }
}

/// The header that carries an image answer's warnings.
pub const WARNINGS_HEADER: &str = "stereo-warnings";

/// `Stereo-Warnings: ["…", …]`: the answer's warnings as a JSON array of strings, in ASCII
/// (other characters escaped as `\uXXXX`), so that a file answer says what a summary's
/// `warnings` says; no header when there are none.
pub fn set_warnings(response: &mut Response, warnings: &[String]) {
    if warnings.is_empty() {
        return;
    }
    let json = serde_json::to_string(warnings).unwrap_or_default();
    // JSON's own escapes for what a header cannot carry (only inside strings, in JSON text).
    let mut text = String::with_capacity(json.len());
    for c in json.chars() {
        if c == ' ' || c.is_ascii_graphic() {
            text.push(c);
        } else {
            for unit in c.encode_utf16(&mut [0; 2]) {
                text.push_str(&format!("\\u{unit:04x}"));
            }
        }
    }
    if let Ok(v) = HeaderValue::from_str(&text) {
        response.headers_mut().insert(WARNINGS_HEADER, v);
    }
}

/// The header that names the projection a depth map's pixels are in.
pub const PROJECTION_HEADER: &str = "stereo-projection";

/// `Stereo-Projection: pinhole` or `latlon`: what a depth map's pixels are, for files (NPY,
/// PFM, PNG) that cannot say it themselves.
pub fn set_projection(response: &mut Response, projection: &'static str) {
    response
        .headers_mut()
        .insert(PROJECTION_HEADER, HeaderValue::from_static(projection));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The header is JSON in ASCII that reads back to the warnings, quotes, σ and emoji too.
    #[test]
    fn warnings_ride_in_a_json_header() {
        let said = vec!["σ_d is \"high\" \\ here".to_owned(), "a 🙂 b".to_owned()];
        let mut r = file(vec![1], "image/png", "x.png", Disposition::Inline);
        set_warnings(&mut r, &said);
        let text = r.headers()[WARNINGS_HEADER].to_str().unwrap();
        assert!(text.is_ascii());
        let back: Vec<String> = serde_json::from_str(text).unwrap();
        assert_eq!(back, said);
        let mut quiet = file(vec![1], "image/png", "x.png", Disposition::Inline);
        set_warnings(&mut quiet, &[]);
        assert!(!quiet.headers().contains_key(WARNINGS_HEADER));
    }

    /// A file answer carries its media type and name, inline or as an attachment.
    #[test]
    fn a_file_answer_names_its_type_and_file() {
        let r = file(vec![1, 2], "image/png", "left.png", Disposition::Inline);
        assert_eq!(r.headers()[header::CONTENT_TYPE], "image/png");
        assert_eq!(
            r.headers()[header::CONTENT_DISPOSITION],
            "inline; filename=\"left.png\""
        );
        let r = file(
            vec![],
            "application/zip",
            "maps.npz",
            Disposition::Attachment,
        );
        assert_eq!(
            r.headers()[header::CONTENT_DISPOSITION],
            "attachment; filename=\"maps.npz\""
        );
    }

    /// `Server-Timing` lists the stages in order, in milliseconds to a tenth.
    #[test]
    fn server_timing_lists_the_stages_in_milliseconds() {
        let mut r = Vec::<u8>::new().into_response();
        set_server_timing(
            &mut r,
            &[
                ("read", Duration::from_micros(1250)),
                ("queue", Duration::ZERO),
            ],
        );
        assert_eq!(r.headers()["server-timing"], "read;dur=1.2, queue;dur=0.0");
    }
}
