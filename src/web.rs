//! The web calculator at `/`: one HTML page with its script (ES modules under `/js/`), style
//! sheet and icon, embedded in the binary (`include_str!`), so nothing is read from disk or
//! fetched from a CDN at run time.
//!
//! The page is a client of the public API (`/distance`, `/table`, `/chart-data`,
//! `/calibration`, `/calibrate`, `/rectify`, `/depth-map`, `/match`) and holds no physics or
//! stereo. Its sample pair (`/sample/left.png`, `/sample/right.png`, `/sample/sample.json`,
//! the rig as a `rig` part, and `/sample/calib.txt`, the same rig and its search range as a
//! Middlebury file) is rendered by [`stereo_core::vision::synthetic`] on first request, so the
//! binary holds code, not a picture; so is the calibration sample under `/sample/boards/` (board pairs seen through
//! two distorted cameras, and the raw pair of a wall at a known distance, from
//! [`stereo_core::calibration::boards::synthetic`]), each file rendered when first asked for. Each asset is
//! answered with an `ETag` (a hash of its bytes, so a new build is a new tag) and
//! `Cache-Control: no-cache`, so browsers revalidate and get a 304 until the binary changes.
//! The tag is weak because the compression layer may send the same asset gzip- or br-encoded,
//! and a strong tag must differ between such representations. The page carries a
//! Content-Security-Policy that allows only this origin.

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

use stereo_core::vision::{encode, synthetic};

/// One embedded file and how it is served.
#[derive(Debug, Clone, Copy)]
pub struct Asset {
    /// The route it is served at.
    pub path: &'static str,
    pub content_type: &'static str,
    pub body: &'static str,
}

/// Everything the page needs, and nothing from anywhere else.
/// The script is ES modules under `/js/`, loaded by `<script type="module">` from
/// `/js/app.js`, which imports the rest (one per mode, the state and events the modes share,
/// the rig form, drawing, the API).
pub const ASSETS: [Asset; 18] = [
    asset("/", HTML, include_str!("web/index.html")),
    asset("/guide.html", HTML, include_str!("web/guide.html")),
    asset("/js/app.js", JAVASCRIPT, include_str!("web/js/app.js")),
    asset("/js/api.js", JAVASCRIPT, include_str!("web/js/api.js")),
    asset(
        "/js/calibrate.js",
        JAVASCRIPT,
        include_str!("web/js/calibrate.js"),
    ),
    asset(
        "/js/calibrate-view.js",
        JAVASCRIPT,
        include_str!("web/js/calibrate-view.js"),
    ),
    asset("/js/check.js", JAVASCRIPT, include_str!("web/js/check.js")),
    asset("/js/draw.js", JAVASCRIPT, include_str!("web/js/draw.js")),
    asset(
        "/js/findings.js",
        JAVASCRIPT,
        include_str!("web/js/findings.js"),
    ),
    asset(
        "/js/images.js",
        JAVASCRIPT,
        include_str!("web/js/images.js"),
    ),
    asset("/js/live.js", JAVASCRIPT, include_str!("web/js/live.js")),
    asset(
        "/js/live-camera.js",
        JAVASCRIPT,
        include_str!("web/js/live-camera.js"),
    ),
    asset(
        "/js/numbers.js",
        JAVASCRIPT,
        include_str!("web/js/numbers.js"),
    ),
    asset("/js/rig.js", JAVASCRIPT, include_str!("web/js/rig.js")),
    asset("/js/store.js", JAVASCRIPT, include_str!("web/js/store.js")),
    asset("/js/util.js", JAVASCRIPT, include_str!("web/js/util.js")),
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

/// The calibration sample's views: rendered board pairs, and one more whose board the right
/// camera does not see whole (so that the page shows a view the service could not use).
pub const BOARD_VIEWS: usize = 12;
/// The calibration sample's raw wall: its depth on the rectified left camera's axis, mm, and
/// its slope (depth Z = distance + slope·X in that camera's frame).
pub const WALL_DISTANCE_MM: f64 = 2000.0;
pub const WALL_SLOPE: f64 = 0.5;

/// Where the calibration sample's files are served: `/sample/boards/left_NN.png` and
/// `right_NN.png` for each view, `raw_left.png` and `raw_right.png` (a slanted textured wall
/// [`WALL_DISTANCE_MM`] away on the axis, seen through the same raw cameras) and
/// `boards.json` (the board, the files and the wall's distance and slope).
pub fn board_files() -> Vec<String> {
    let mut files: Vec<String> = (0..=BOARD_VIEWS)
        .flat_map(|i| ["left", "right"].map(|side| format!("/sample/boards/{side}_{i:02}.png")))
        .collect();
    files.extend(
        ["raw_left.png", "raw_right.png", "boards.json"].map(|f| format!("/sample/boards/{f}")),
    );
    files
}

/// What every file of the calibration sample is rendered from: [`BOARD_VIEWS`] poses of a
/// 9 × 6 board of 25 mm squares seen by [`stereo_core::calibration::boards::synthetic::sample_rig`], one more
/// the right camera sees only in part, and the cameras' rays.
struct BoardSample {
    rig: stereo_core::camera::StereoPair,
    board: stereo_core::calibration::boards::Board,
    poses: Vec<nalgebra::Isometry3<f64>>,
    rays: [stereo_core::calibration::boards::synthetic::Rays; 2],
    style: stereo_core::calibration::boards::synthetic::Style,
}

/// The calibration sample's image size, and its board: inner corners along a row and a
/// column, and the squares' side in mm.
pub const BOARD_SIZE: stereo_core::camera::Size = stereo_core::camera::Size {
    width: 640,
    height: 480,
};
pub const BOARD: (u32, u32, f64) = (9, 6, 25.0);
/// The search range that covers the sample wall's disparities (about 39 to 59 px).
const WALL_MAX_DISPARITY: u32 = 96;

/// The rectified rig the calibration sample was rendered with (OpenCV's `stereoRectify`,
/// `alpha` 0, of [`stereo_core::calibration::boards::synthetic::sample_rig`]): what calibrating it should
/// give.
pub fn board_sample_rig() -> stereo_core::physics::Rig {
    let rig = stereo_core::calibration::boards::synthetic::sample_rig();
    stereo_core::camera::stereo_rectify(
        &rig,
        BOARD_SIZE,
        stereo_core::camera::RectifyOptions::default(),
    )
    .expect("the sample rig rectifies")
    .rig(stereo_core::physics::LengthUnit::Millimetre)
    .expect("a rectified rig with a baseline")
}

static BOARD_SAMPLE: OnceLock<BoardSample> = OnceLock::new();
/// Each view's rendered pair, and the wall's, rendered when first asked for.
static BOARD_VIEW_FILES: [OnceLock<[Served; 2]>; BOARD_VIEWS + 2] =
    [const { OnceLock::new() }; BOARD_VIEWS + 2];

fn board_sample() -> &'static BoardSample {
    BOARD_SAMPLE.get_or_init(|| {
        use stereo_core::calibration::boards::synthetic::{
            Rays, Style, corners, poses, right_pose, sample_rig,
        };
        let rig = sample_rig();
        let size = BOARD_SIZE;
        let (columns, rows, square) = BOARD;
        let board = stereo_core::calibration::boards::Board::new(
            columns,
            rows,
            square,
            stereo_core::physics::LengthUnit::Millimetre,
        )
        .expect("a 9 × 6 board");
        let mut found = poses(&rig, size, &board, BOARD_VIEWS, 40.0, 7);
        // The last view: the first one's board moved left until the right camera loses part
        // of it while the left still sees all of it.
        let (w, h) = (f64::from(size.width), f64::from(size.height));
        let inside = |c: &[[f64; 2]]| {
            c.iter()
                .all(|&[u, v]| u > 8.0 && v > 8.0 && u < w - 8.0 && v < h - 8.0)
        };
        let mut partial = found[0];
        for step in 0..400 {
            let mut pose = found[0];
            pose.translation.vector.x -= f64::from(step) * 2.0;
            let left = corners(&board, &pose, &rig.left).unwrap_or_default();
            let right = corners(&board, &right_pose(&rig, &pose), &rig.right).unwrap_or_default();
            if inside(&left) && right.iter().filter(|c| c[0] < 0.0).count() >= 6 {
                partial = pose;
                break;
            }
        }
        found.push(partial);
        let style = Style {
            supersampling: 2,
            seed: 7,
            ..Style::default()
        };
        let rays = [
            Rays::new(&rig.left, size, style.supersampling),
            Rays::new(&rig.right, size, style.supersampling),
        ];
        BoardSample {
            rig,
            board,
            poses: found,
            rays,
            style,
        }
    })
}

/// `boards.json`: the board, the model, each view's files and the raw wall's, with the
/// wall's distance and slope.
fn boards_json() -> Served {
    let paths = board_files();
    let views = BOARD_VIEWS + 1;
    let (columns, rows, square_size) = BOARD;
    let about = serde_json::json!({
        "board": {"columns": columns, "rows": rows, "square_size": square_size, "unit": "mm"},
        "model": "plumb_bob",
        "left": (0..views).map(|v| &paths[2 * v]).collect::<Vec<_>>(),
        "right": (0..views).map(|v| &paths[2 * v + 1]).collect::<Vec<_>>(),
        "raw": {
            "left": paths[2 * views], "right": paths[2 * views + 1],
            "distance": WALL_DISTANCE_MM, "slope": WALL_SLOPE, "unit": "mm",
            "max_disparity": WALL_MAX_DISPARITY,
        },
    });
    Served::of(JSON, about.to_string().into())
}

/// The calibration sample's image `i` (in [`board_files`] order), rendered on first use.
fn board_image(i: usize) -> Served {
    let png = |image: &stereo_core::calibration::boards::synthetic::Image| -> Bytes {
        encode::png_grey(image.width as usize, image.height as usize, &image.pixels).into()
    };
    let view = i / 2;
    let pair = BOARD_VIEW_FILES[view].get_or_init(|| {
        let images = if view <= BOARD_VIEWS {
            let sample = board_sample();
            let v = stereo_core::calibration::boards::synthetic::stereo_view(
                &sample.rig,
                &sample.board,
                &sample.poses[view],
                view,
                &sample.rays,
                &sample.style,
            );
            [v.left, v.right]
        } else {
            stereo_core::calibration::boards::synthetic::raw_wall(
                &stereo_core::calibration::boards::synthetic::sample_rig(),
                BOARD_SIZE,
                WALL_DISTANCE_MM,
                WALL_SLOPE,
                11,
            )
            .expect("the sample rig rectifies")
        };
        images.map(|image| Served::of(PNG, png(&image)))
    });
    pair[i % 2].clone()
}

async fn board_file(i: usize, headers: HeaderMap) -> Response {
    match tokio::task::spawn_blocking(move || board_image(i)).await {
        Ok(file) => file.answer(&headers),
        Err(_) => StatusCode::INTERNAL_SERVER_ERROR.into_response(),
    }
}

/// The page's routes (GET and HEAD).
pub fn router() -> Router {
    let router = ASSETS.into_iter().fold(Router::new(), |router, asset| {
        let served = Arc::new(Served::new(asset));
        router.route(
            asset.path,
            get(move |headers: HeaderMap| async move { served.answer(&headers) }),
        )
    });
    let router = SAMPLE_FILES
        .into_iter()
        .enumerate()
        .fold(router, |router, (i, path)| {
            router.route(path, get(move |headers: HeaderMap| sample_file(i, headers)))
        });
    // The images are rendered on first use; the description is built here, once.
    let mut paths = board_files();
    let about = Arc::new(boards_json());
    let router = router.route(
        &paths.pop().expect("boards.json comes last"),
        get(move |headers: HeaderMap| async move { about.answer(&headers) }),
    );
    paths
        .into_iter()
        .enumerate()
        .fold(router, |router, (i, path)| {
            router.route(&path, get(move |headers: HeaderMap| board_file(i, headers)))
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
