//! The web calculator at `/`: one HTML page with its script, style sheet and icon, embedded in
//! the binary (`include_str!`), so nothing is read from disk or fetched from a CDN at run time.
//!
//! The page is a client of the public API (`/distance`, `/table`, `/chart-data`,
//! `/calibration`, `/depth-map`, `/match`) and holds no physics or stereo. Its sample pair
//! (`/sample/left.png`, `/sample/right.png`, `/sample/sample.json`, the rig as a `rig` part, and
//! `/sample/calib.txt`, the same rig and its search range as a Middlebury file)
//! is rendered by [`crate::vision::synthetic`] on first request, so the binary holds code, not
//! a picture. Each asset is answered with an `ETag` (a hash of its bytes, so a new build is a new
//! tag) and `Cache-Control: no-cache`, so browsers revalidate and get a 304 until the binary
//! changes. The tag is weak because the compression layer may send the same asset gzip- or
//! br-encoded, and a strong tag must differ between such representations. The page carries a Content-Security-Policy that allows only this origin.

use std::sync::{Arc, OnceLock};

use axum::{
    Router,
    body::Bytes,
    http::{
        HeaderMap, HeaderName, HeaderValue, StatusCode,
        header::{CACHE_CONTROL, CONTENT_TYPE, ETAG, IF_NONE_MATCH},
    },
    response::{IntoResponse, Response},
    routing::get,
};

use crate::vision::{encode, synthetic};

/// One embedded file and how it is served.
#[derive(Debug, Clone, Copy)]
pub struct Asset {
    /// The route it is served at.
    pub path: &'static str,
    pub content_type: &'static str,
    pub body: &'static str,
}

/// Everything the page needs, and nothing from anywhere else.
pub const ASSETS: [Asset; 4] = [
    asset("/", HTML, include_str!("web/index.html")),
    asset("/app.js", JAVASCRIPT, include_str!("web/app.js")),
    asset("/app.css", CSS, include_str!("web/app.css")),
    asset("/favicon.svg", SVG, include_str!("web/favicon.svg")),
];

const HTML: &str = "text/html; charset=utf-8";
const CSS: &str = "text/css; charset=utf-8";
const SVG: &str = "image/svg+xml";
const PNG: &str = "image/png";
const JSON: &str = "application/json";
const TEXT: &str = "text/plain; charset=utf-8";
const JAVASCRIPT: &str = "text/javascript; charset=utf-8";

const fn asset(path: &'static str, content_type: &'static str, body: &'static str) -> Asset {
    Asset {
        path,
        content_type,
        body,
    }
}

/// Only this origin may provide scripts, styles, images and API answers; no framing.
const CONTENT_SECURITY_POLICY: &str = "default-src 'none'; script-src 'self'; style-src 'self'; \
     img-src 'self'; connect-src 'self'; form-action 'self'; base-uri 'none'; \
     frame-ancestors 'none'";

/// FNV-1a over the bytes: a stable tag that changes when the asset does.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |hash, byte| {
        (hash ^ u64::from(*byte)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The weak entity tag of an asset, as HTTP writes it: `W/"…"`.
pub fn etag(asset: &Asset) -> String {
    tag_of(asset.body.as_bytes())
}

fn tag_of(bytes: &[u8]) -> String {
    format!("W/\"{:016x}\"", fnv1a(bytes))
}

/// Whether an `If-None-Match` header names `tag` (or is `*`), by weak comparison: `W/` is
/// ignored on either side, as RFC 9110 asks for `If-None-Match`.
fn matches(if_none_match: Option<&HeaderValue>, tag: &str) -> bool {
    let tag = tag.trim_start_matches("W/");
    if_none_match
        .and_then(|value| value.to_str().ok())
        .is_some_and(|value| {
            value
                .split(',')
                .map(|candidate| candidate.trim().trim_start_matches("W/"))
                .any(|candidate| candidate == tag || candidate == "*")
        })
}

/// The headers of one asset's answers, built once when the router is.
#[derive(Debug, Clone)]
struct Served {
    body: Bytes,
    /// The tag as text, for comparing with `If-None-Match`.
    tag: String,
    /// What a 304 carries: the tag, the caching rule and `nosniff`.
    not_modified: HeaderMap,
    /// What a 200 carries: those, the content type and, for the page, its policies.
    ok: HeaderMap,
}

impl Served {
    fn new(asset: Asset) -> Self {
        Self::of(
            asset.content_type,
            Bytes::from_static(asset.body.as_bytes()),
        )
    }

    fn of(content_type: &'static str, body: Bytes) -> Self {
        let tag = tag_of(&body);
        let mut not_modified = HeaderMap::new();
        not_modified.insert(
            ETAG,
            HeaderValue::from_str(&tag).expect("hex digits in quotes are a valid header"),
        );
        not_modified.insert(CACHE_CONTROL, HeaderValue::from_static("no-cache"));
        not_modified.insert(
            HeaderName::from_static("x-content-type-options"),
            HeaderValue::from_static("nosniff"),
        );
        let mut ok = not_modified.clone();
        ok.insert(CONTENT_TYPE, HeaderValue::from_static(content_type));
        if content_type.starts_with("text/html") {
            ok.insert(
                HeaderName::from_static("content-security-policy"),
                HeaderValue::from_static(CONTENT_SECURITY_POLICY),
            );
            ok.insert(
                HeaderName::from_static("referrer-policy"),
                HeaderValue::from_static("same-origin"),
            );
        }
        Self {
            body,
            tag,
            not_modified,
            ok,
        }
    }

    fn answer(&self, request: &HeaderMap) -> Response {
        if matches(request.get(IF_NONE_MATCH), &self.tag) {
            (StatusCode::NOT_MODIFIED, self.not_modified.clone()).into_response()
        } else {
            (self.ok.clone(), self.body.clone()).into_response()
        }
    }
}

/// The sample pair's size: small enough to match in a few milliseconds and to show at its own
/// size beside its depth map.
pub const SAMPLE_SIZE: (usize, usize) = (320, 240);
/// The sample rig: f = 400 px and B = 120 mm, so the scene's disparities of 6 to 36 px are
/// 1.3 to 8 m away.
pub const SAMPLE_RIG: (f64, f64) = (400.0, 120.0);
/// The sample's search range, above the scene's largest disparity.
pub const SAMPLE_MAX_DISPARITY: u32 = 48;

static SAMPLE: OnceLock<[Served; 4]> = OnceLock::new();

/// The sample's file `i` (in [`SAMPLE_FILES`] order). The first request renders the pair once
/// per process, on a blocking thread, so the runtime's workers never wait on it.
async fn sample_file(i: usize, headers: HeaderMap) -> Response {
    if let Some(files) = SAMPLE.get() {
        return files[i].answer(&headers);
    }
    match tokio::task::spawn_blocking(sample).await {
        Ok(files) => files[i].answer(&headers),
        Err(_) => StatusCode::INTERNAL_SERVER_ERROR.into_response(),
    }
}

/// The sample's files, rendered on first use: the pair, its rig as the image routes' `rig`
/// part takes it, and the same rig with its search range as a Middlebury `calib.txt` (the
/// `calibration` part, whose `ndisp` is the default range).
fn sample() -> &'static [Served; 4] {
    SAMPLE.get_or_init(|| {
        let (w, h) = SAMPLE_SIZE;
        let pair = synthetic::render(&synthetic::layered(w, h));
        let (f, b) = SAMPLE_RIG;
        let rig = serde_json::json!({
            "focal_length_px": f, "baseline": b, "unit": "mm",
            "image_width": w, "image_height": h,
        });
        let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
        let calib = format!(
            "cam0=[{f} 0 {cx}; 0 {f} {cy}; 0 0 1]\ncam1=[{f} 0 {cx}; 0 {f} {cy}; 0 0 1]\n\
             doffs=0\nbaseline={b}\nwidth={w}\nheight={h}\nndisp={SAMPLE_MAX_DISPARITY}\n"
        );
        [
            Served::of(PNG, encode::png_rgb(w, h, &pair.left_rgb).into()),
            Served::of(PNG, encode::png_rgb(w, h, &pair.right_rgb).into()),
            Served::of(JSON, rig.to_string().into()),
            Served::of(TEXT, calib.into()),
        ]
    })
}

/// Where the sample's files are served: the pair, the rig (`rig` part), the calibration file
/// (`calibration` part).
pub const SAMPLE_FILES: [&str; 4] = [
    "/sample/left.png",
    "/sample/right.png",
    "/sample/sample.json",
    "/sample/calib.txt",
];

/// The page's routes (GET and HEAD).
pub fn router() -> Router {
    let router = ASSETS.into_iter().fold(Router::new(), |router, asset| {
        let served = Arc::new(Served::new(asset));
        router.route(
            asset.path,
            get(move |headers: HeaderMap| async move { served.answer(&headers) }),
        )
    });
    SAMPLE_FILES
        .into_iter()
        .enumerate()
        .fold(router, |router, (i, path)| {
            router.route(path, get(move |headers: HeaderMap| sample_file(i, headers)))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tag is weak, quoted hex, and differs between assets.
    #[test]
    fn tags_are_weak_quoted_and_distinct() {
        let tags: Vec<String> = ASSETS.iter().map(etag).collect();
        for tag in &tags {
            assert_eq!(tag.len(), 20, "{tag}");
            assert!(tag.starts_with("W/\"") && tag.ends_with('"'), "{tag}");
        }
        let mut unique = tags.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), tags.len());
    }

    /// `If-None-Match` matches a listed tag, a weak form of it, or `*`, and nothing else.
    #[test]
    fn if_none_match_is_read_as_a_list() {
        let tag = "W/\"0123456789abcdef\"";
        let header = |v: &'static str| Some(HeaderValue::from_static(v));
        assert!(matches(header("\"0123456789abcdef\"").as_ref(), tag));
        assert!(matches(
            header("\"x\", W/\"0123456789abcdef\"").as_ref(),
            tag
        ));
        assert!(matches(header("*").as_ref(), tag));
        assert!(!matches(header("\"fedcba9876543210\"").as_ref(), tag));
        assert!(!matches(None, tag));
    }

    /// The page asks for nothing outside this origin: no `http(s)://` or protocol-relative
    /// `src`/`href`, and no `@import` or `url(` of another host.
    #[test]
    fn assets_reference_only_this_origin() {
        for asset in ASSETS {
            for needle in [
                "src=\"http",
                "href=\"http",
                "src=\"//",
                "href=\"//",
                "@import",
                "url(http",
                "url(//",
            ] {
                assert!(
                    !asset.body.contains(needle),
                    "{} contains {needle}",
                    asset.path
                );
            }
        }
    }
}
