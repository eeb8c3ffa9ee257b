//! `GET /depth-stream` over a real socket with a WebSocket client (tokio-tungstenite): the
//! settings answered as resolved, each frame answered in order with depth files that agree
//! with the truth and the temporal filter at work, both layouts, and hostile streams: garbage
//! frames, a frame claiming 30 000² pixels, settings with unknown members, a frame over the
//! limit, 1 000 frames sent without reading, 100 streams opened at once, an idle stream.

use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use stereo_core::vision::synthetic::Pair;
use stereo_distance::Config;
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::{self, Message};
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream, connect_async};

use crate::depth_map::{H, W, npy, pair, png, png_claiming, rig};
use crate::helpers::{PATIENCE, TestApp, fields, spawn_app, spawn_app_with};

pub(crate) type Socket = WebSocketStream<MaybeTlsStream<TcpStream>>;

/// Opens a stream.
async fn open(app: &TestApp) -> Socket {
    connect_async(format!("ws://{}/depth-stream", app.socket))
        .await
        .expect("the stream opens")
        .0
}

/// Opens a stream and sends `settings`, returning the stream and the answer.
pub(crate) async fn open_with(app: &TestApp, settings: Value) -> (Socket, Value) {
    let mut socket = open(app).await;
    socket
        .send(Message::text(settings.to_string()))
        .await
        .unwrap();
    let answer = text(&mut socket).await;
    (socket, answer)
}

/// The next message, within the test's patience.
async fn next(socket: &mut Socket) -> Option<Message> {
    tokio::time::timeout(PATIENCE, socket.next())
        .await
        .expect("a message within the patience")
        .and_then(Result::ok)
}

/// The next message, which must be JSON text.
pub(crate) async fn text(socket: &mut Socket) -> Value {
    match next(socket).await {
        Some(Message::Text(text)) => serde_json::from_str(text.as_str()).expect("JSON"),
        other => panic!("expected a text message, got {other:?}"),
    }
}

/// The next message, which must be binary.
pub(crate) async fn binary(socket: &mut Socket) -> Vec<u8> {
    match next(socket).await {
        Some(Message::Binary(bytes)) => bytes.to_vec(),
        other => panic!("expected a binary message, got {other:?}"),
    }
}

/// The close code the server ends the stream with.
async fn close_code(socket: &mut Socket) -> u16 {
    loop {
        match next(socket).await {
            Some(Message::Close(Some(frame))) => return u16::from(frame.code),
            Some(Message::Close(None)) | None => panic!("closed without a code"),
            Some(_) => {}
        }
    }
}

/// The pair side by side in one PNG, as a USB stereo camera delivers it.
pub(crate) fn side_by_side(pair: &Pair) -> Vec<u8> {
    let row = 3 * W;
    let mut rgb = Vec::with_capacity(2 * row * H);
    for y in 0..H {
        rgb.extend_from_slice(&pair.left_rgb[y * row..(y + 1) * row]);
        rgb.extend_from_slice(&pair.right_rgb[y * row..(y + 1) * row]);
    }
    png(&rgb, 2 * W, H)
}

/// A pair-layout frame: the left image's length (4 bytes, little-endian), left, right.
pub(crate) fn pair_frame(left: &[u8], right: &[u8]) -> Vec<u8> {
    let mut frame = (left.len() as u32).to_le_bytes().to_vec();
    frame.extend_from_slice(left);
    frame.extend_from_slice(right);
    frame
}

/// The share of the visible pixels with a disparity that lies more than 1 px from the truth.
fn bad_1(disparity: &[f32], pair: &Pair) -> f64 {
    let judged: Vec<f32> = (0..disparity.len())
        .filter(|&i| pair.visible[i] && disparity[i].is_finite())
        .map(|i| (disparity[i] - pair.truth[i]).abs())
        .collect();
    assert!(judged.len() > disparity.len() / 2, "most pixels matched");
    judged.iter().filter(|&&e| e > 1.0).count() as f64 / judged.len() as f64
}

/// The settings come back as resolved (the `fast` preset, the filter's defaults, the files);
/// then each side-by-side frame is answered in order with its id and its files, whose
/// disparities agree with the truth and whose depths are Z = f·B / d; from the second frame
/// on, the temporal filter averages, and the σ_d of a frame repeated exactly stays its own
/// (the average of a value with itself is known no better than the value).
#[tokio::test]
async fn each_frame_is_answered_in_order_with_its_depth() {
    let app = spawn_app().await;
    let pair = pair();
    let settings = json!({
        "layout": "side_by_side",
        "rig": rig(),
        "options": {"max_disparity": 48},
        "outputs": ["depth.npy", "disparity.npy"],
    });
    let (mut socket, resolved) = open_with(&app, settings).await;
    assert_eq!(resolved["type"], "settings", "{resolved}");
    assert_eq!(resolved["outputs"], json!(["depth.npy", "disparity.npy"]));
    assert_eq!(resolved["parameters"]["preset"], "fast");
    assert_eq!(resolved["max_disparity"], 48);
    assert_eq!(resolved["temporal"]["persistence"], "valid_2_of_last_4");
    assert_eq!(resolved["temporal"]["alpha"], 0.4);
    assert_eq!(resolved["rig"]["baseline"], 100.0);
    let frame = side_by_side(&pair);
    let mut std_medians = Vec::new();
    for id in 1..=3u64 {
        socket.send(Message::binary(frame.clone())).await.unwrap();
        let answer = text(&mut socket).await;
        assert_eq!(answer["type"], "frame", "{answer}");
        assert_eq!(answer["id"], id);
        assert_eq!(answer["dropped_frames"], 0);
        assert_eq!(answer["summary"]["width"], W);
        assert_eq!(answer["files"][0]["name"], "depth.npy");
        assert_eq!(answer["files"][1]["name"], "disparity.npy");
        let depth = npy(&binary(&mut socket).await);
        let disparity = npy(&binary(&mut socket).await);
        assert!(bad_1(&disparity, &pair) < 0.1, "frame {id}");
        for (z, d) in depth.iter().zip(&disparity).filter(|(_, d)| d.is_finite()) {
            let expected = 500.0 * 100.0 / d;
            assert!((z - expected).abs() <= 1e-4 * expected, "Z {z} for d {d}");
        }
        let counts = &answer["temporal"];
        if id == 1 {
            assert_eq!(counts["averaged"], 0, "{counts}");
        } else {
            assert!(counts["averaged"].as_u64().unwrap() > (W * H / 2) as u64);
        }
        std_medians.push(
            answer["summary"]["disparity_std_px"]["median"]
                .as_f64()
                .unwrap(),
        );
    }
    assert!(
        std_medians
            .iter()
            .all(|s| (s - std_medians[0]).abs() <= 1e-6 * std_medians[0]),
        "σ_d of a repeated frame stays its own: {std_medians:?}"
    );
    socket.close(None).await.unwrap();
}

/// Six frames sent at once, none read until all are sent: two are matched side by side and
/// the newest waits, each older waiting one dropped. Every frame is answered or counted as
/// dropped, the answers come in the frames' order, the last frame is always answered, and the
/// temporal filter saw the answered frames in order (every answer after the first averaged).
#[tokio::test]
async fn frames_sent_at_once_are_answered_in_order_or_dropped() {
    let app = spawn_app().await;
    let settings = json!({"options": {"max_disparity": 48}, "outputs": []});
    let (mut socket, _) = open_with(&app, settings).await;
    let frame = side_by_side(&pair());
    for _ in 0..6 {
        socket.send(Message::binary(frame.clone())).await.unwrap();
    }
    let mut ids = Vec::new();
    let last = loop {
        let answer = text(&mut socket).await;
        assert_eq!(answer["type"], "frame", "{answer}");
        let id = answer["id"].as_u64().unwrap();
        if !ids.is_empty() {
            assert!(
                answer["temporal"]["averaged"].as_u64().unwrap() > 0,
                "{answer}"
            );
        }
        ids.push(id);
        if id == 6 {
            break answer;
        }
    };
    assert!(ids.windows(2).all(|w| w[0] < w[1]), "in order: {ids:?}");
    let dropped = last["dropped_frames"].as_u64().unwrap();
    assert_eq!(
        ids.len() as u64 + dropped,
        6,
        "answered {ids:?}, dropped {dropped}"
    );
}

/// In the pair layout, a frame of garbage (422), a frame whose images claim 30 000² pixels
/// (413, judged from the headers before anything is decoded), a frame with a broken right
/// image (422) and a text message are each answered with an error naming the part, and the
/// stream goes on: the good frame after them is answered with its id.
#[tokio::test]
async fn bad_frames_are_named_and_the_stream_goes_on() {
    let app = spawn_app().await;
    let pair = pair();
    let settings = json!({"layout": "pair", "options": {"max_disparity": 48}, "temporal": false});
    let (mut socket, resolved) = open_with(&app, settings).await;
    assert_eq!(resolved["temporal"], Value::Null);
    assert_eq!(
        resolved["outputs"],
        json!(["disparity.npy", "disparity_std.npy"])
    );
    let left = png(&pair.left_rgb, W, H);
    let right = png(&pair.right_rgb, W, H);
    let huge = png_claiming(30_000, 30_000);
    let frames = [
        (b"not an image, nor a pair of them".to_vec(), "frame", 422),
        (pair_frame(&huge, &huge), "frame.left", 413),
        (pair_frame(&left, b"\x89PNG broken"), "frame.right", 422),
    ];
    for (id, (frame, field, status)) in (1u64..).zip(frames) {
        socket.send(Message::binary(frame)).await.unwrap();
        let answer = text(&mut socket).await;
        assert_eq!(answer["type"], "error", "{answer}");
        assert_eq!(answer["id"], id);
        assert_eq!(answer["problem"]["status"], status, "{answer}");
        assert!(
            fields(&answer["problem"]).contains(&field.to_owned()),
            "{answer}"
        );
    }
    socket
        .send(Message::text("{\"layout\": \"pair\"}"))
        .await
        .unwrap();
    let answer = text(&mut socket).await;
    assert_eq!(answer["type"], "error");
    assert_eq!(fields(&answer["problem"]), ["message"]);
    socket
        .send(Message::binary(pair_frame(&left, &right)))
        .await
        .unwrap();
    let answer = text(&mut socket).await;
    assert_eq!(answer["type"], "frame", "{answer}");
    assert_eq!(answer["id"], 4);
    assert_eq!(answer["summary"]["height"], H);
    let disparity = npy(&binary(&mut socket).await);
    assert!(bad_1(&disparity, &pair) < 0.1);
    let std = npy(&binary(&mut socket).await);
    assert!(std.iter().filter(|s| s.is_finite()).all(|&s| s > 0.0));
}

/// Settings are judged member by member: one answer names every bad member (an unknown one,
/// a wrong layout, a wrong option, `output` in a stream, the summary listed as a file, a
/// temporal rule that does not exist), then the stream closes with 1008. A depth file without
/// a rig is named too, and a frame before the settings closes the stream with 1003.
#[tokio::test]
async fn bad_settings_are_named_and_close_the_stream() {
    let app = spawn_app().await;
    let settings = json!({
        "layout": "diagonal",
        "options": {"max_disparity": "lots", "bogus": 1, "output": "depth.npy"},
        "outputs": ["summary", "disparity.npy", "disparity.npy"],
        "temporal": {"alpha": 2, "persistence": "sometimes"},
        "colour": true,
    });
    let (mut socket, answer) = open_with(&app, settings).await;
    assert_eq!(answer["type"], "error", "{answer}");
    assert_eq!(answer["problem"]["status"], 422);
    let named = fields(&answer["problem"]);
    for field in [
        "layout",
        "options.max_disparity",
        "options.bogus",
        "options.output",
        "outputs[0]",
        "outputs[2]",
        "temporal.alpha",
        "temporal.persistence",
        "colour",
    ] {
        assert!(named.contains(&field.to_owned()), "{field} in {named:?}");
    }
    assert_eq!(close_code(&mut socket).await, 1008);

    let (mut socket, answer) = open_with(&app, json!({"outputs": ["depth.npy"]})).await;
    assert_eq!(fields(&answer["problem"]), ["outputs[0]"]);
    assert_eq!(close_code(&mut socket).await, 1008);

    let mut socket = open(&app).await;
    socket.send(Message::binary(vec![1, 2, 3])).await.unwrap();
    let answer = text(&mut socket).await;
    assert_eq!(fields(&answer["problem"]), ["settings"]);
    assert_eq!(close_code(&mut socket).await, 1003);
}

/// The server's reserved heavy memory, from /metrics.
async fn reserved(app: &TestApp) -> u64 {
    let text = app.get("/metrics").await.text().await.unwrap();
    text.lines()
        .find_map(|l| l.strip_prefix("heavy_memory_reserved_bytes "))
        .and_then(|v| v.trim().parse::<f64>().ok())
        .expect("the gauge") as u64
}

/// A client that sends 1 000 frames and reads nothing (its socket's receive buffer kept
/// small) is neither buffered for nor waited on: the frames past the one in work are dropped,
/// its answers are dropped while the one before is unsent, and once an answer stays unsent
/// for the write timeout the stream is closed (the idle timeout is a minute, so nothing else
/// closes it); then every byte the stream held is back in the budget, and the server answered
/// others all along.
#[tokio::test]
async fn a_client_that_sends_and_never_reads_is_closed_and_freed() {
    let config = Config {
        port: 0,
        write_timeout: Duration::from_secs(1),
        ..Config::default()
    };
    let app = spawn_app_with(config).await;
    let tcp = tokio::net::TcpSocket::new_v4().unwrap();
    tcp.set_recv_buffer_size(4096).unwrap();
    let tcp = tcp.connect(app.socket).await.unwrap();
    let url = format!("ws://{}/depth-stream", app.socket);
    let (mut socket, _) = tokio_tungstenite::client_async(url, MaybeTlsStream::Plain(tcp))
        .await
        .expect("the stream opens");
    let settings = json!({
        "rig": rig(),
        "options": {"max_disparity": 48},
        "outputs": ["arrays.npz", "points.ply", "disparity.pfm", "disparity_std.pfm",
                    "depth.npy", "depth_std.npy", "disparity.npy", "preview.png"],
    });
    socket
        .send(Message::text(settings.to_string()))
        .await
        .unwrap();
    let frame = side_by_side(&pair());
    let mut sent = 0;
    for _ in 0..1000 {
        let send = tokio::time::timeout(PATIENCE, socket.send(Message::binary(frame.clone())));
        if !matches!(send.await, Ok(Ok(()))) {
            break;
        }
        sent += 1;
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    assert_eq!(app.get("/healthz").await.status(), 200);
    // What reached the client before the server gave up, then the end.
    let mut ids = Vec::new();
    loop {
        match tokio::time::timeout(PATIENCE, socket.next()).await {
            Ok(Some(Ok(Message::Text(text)))) => {
                let answer: Value = serde_json::from_str(text.as_str()).unwrap();
                ids.extend(answer["id"].as_u64());
            }
            Ok(Some(Ok(Message::Close(_)) | Err(_)) | None) => break,
            Ok(Some(Ok(_))) => {}
            Err(_) => panic!("the stream was not closed"),
        }
    }
    assert!(ids.windows(2).all(|w| w[0] < w[1]), "in order: {ids:?}");
    assert!(ids.len() < sent, "{} answers for {sent} frames", ids.len());
    let mut held = reserved(&app).await;
    for _ in 0..100 {
        if held == 0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
        held = reserved(&app).await;
    }
    assert_eq!(held, 0, "the stream's memory is back in the budget");
}

/// 100 streams opened at once: as many as `--max-streams` open, the rest are refused with 503,
/// `Retry-After` and a problem naming the stream; the open ones work, and once they close a
/// new one opens. A GET without the upgrade is a 426 problem.
#[tokio::test]
async fn a_hundred_streams_at_once_open_up_to_the_limit() {
    let mut config = Config {
        port: 0,
        ..Config::default()
    };
    config.heavy.max_streams = 3;
    let app = spawn_app_with(config).await;
    let url = format!("ws://{}/depth-stream", app.socket);
    let attempts =
        futures_util::future::join_all((0..100).map(|_| connect_async(url.clone()))).await;
    let mut open = Vec::new();
    for attempt in attempts {
        match attempt {
            Ok((socket, _)) => open.push(socket),
            Err(tungstenite::Error::Http(response)) => {
                assert_eq!(response.status(), 503);
                assert!(response.headers().contains_key("retry-after"));
                let body: Value =
                    serde_json::from_slice(response.body().as_deref().unwrap()).unwrap();
                assert_eq!(fields(&body), ["stream"]);
            }
            Err(other) => panic!("{other}"),
        }
    }
    assert_eq!(open.len(), 3);
    let frame = side_by_side(&pair());
    for socket in &mut open {
        let settings = json!({"options": {"max_disparity": 48}, "outputs": []});
        socket
            .send(Message::text(settings.to_string()))
            .await
            .unwrap();
        assert_eq!(text(socket).await["type"], "settings");
        socket.send(Message::binary(frame.clone())).await.unwrap();
        assert_eq!(text(socket).await["type"], "frame");
    }
    for mut socket in open {
        socket.close(None).await.unwrap();
        while next(&mut socket).await.is_some() {}
    }
    let mut reopened = None;
    for _ in 0..100 {
        if let Ok((socket, _)) = connect_async(url.clone()).await {
            reopened = Some(socket);
            break;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    assert!(reopened.is_some(), "a stream opens once the others closed");
    let response = app.get("/depth-stream").await;
    assert_eq!(response.status(), 426);
    assert_eq!(
        response.headers()["content-type"],
        "application/problem+json"
    );
}

/// A stream that sends nothing past `--stream-idle-timeout` is closed with 1001, and a frame
/// over `--stream-frame-limit` closes its stream with 1009.
#[tokio::test]
async fn idle_and_oversized_streams_are_closed() {
    let mut config = Config {
        port: 0,
        ..Config::default()
    };
    config.heavy.stream_idle_timeout = Duration::from_millis(500);
    config.heavy.stream_frame_bytes = 64 * 1024;
    let app = spawn_app_with(config).await;
    let (mut socket, resolved) = open_with(&app, json!({})).await;
    assert_eq!(resolved["limits"]["max_frame_bytes"], 64 * 1024);
    assert_eq!(close_code(&mut socket).await, 1001);

    let (mut socket, _) = open_with(&app, json!({})).await;
    let _ = socket.send(Message::binary(vec![0u8; 100 * 1024])).await;
    assert_eq!(close_code(&mut socket).await, 1009);
}

/// The AsyncAPI document is served at `/asyncapi.yaml` as committed, linked from the OpenAPI
/// document's description (so from `/docs`), and names every settings member the server reads
/// and every persistence rule and file it takes.
#[tokio::test]
async fn the_asyncapi_document_is_served_and_names_every_member() {
    let app = spawn_app().await;
    let response = app.get("/asyncapi.yaml").await;
    assert_eq!(response.status(), 200);
    assert_eq!(response.headers()["content-type"], "application/yaml");
    let served = response.text().await.unwrap();
    let committed = include_str!("../../openapi/asyncapi.yaml");
    assert_eq!(served, committed);
    assert!(served.starts_with("asyncapi: 3.0.0\n"));
    let openapi: Value = app.get("/openapi.json").await.json().await.unwrap();
    let description = openapi["info"]["description"].as_str().unwrap();
    assert!(
        description.contains("[/asyncapi.yaml](/asyncapi.yaml)"),
        "{description}"
    );
    let rig_members = stereo_distance::api::wire::images::RIG_PARTS;
    for member in stereo_distance::api::wire::depth_stream::MEMBERS
        .into_iter()
        .chain(rig_members)
    {
        assert!(
            served.contains(&format!("\n        {member}:")),
            "{member} is documented"
        );
    }
    for rule in stereo_core::vision::temporal::Persistence::ALL {
        assert!(served.contains(rule.name()), "{}", rule.name());
    }
    for file in [
        "depth.npy",
        "depth_std.npy",
        "depth.png",
        "arrays.npz",
        "points.ply",
    ] {
        assert!(served.contains(file), "{file}");
    }
}

/// With bearer tokens, a stream opens only with one: `Authorization: Bearer …` on the
/// upgrade request, as non-browser clients send it, or, as a browser can, a
/// `Sec-WebSocket-Protocol` entry `bearer.<base64url>` beside `depth-stream`, which the
/// server selects. Without one, or with a wrong one either way, the upgrade is a 401.
#[tokio::test]
async fn with_tokens_a_stream_needs_one() {
    use tokio_tungstenite::tungstenite::client::IntoClientRequest;
    let token = "stream-token-0123456789";
    let config = Config {
        port: 0,
        api_tokens: Some(stereo_distance::config::ApiTokens(vec![token.to_owned()])),
        ..Config::default()
    };
    let app = spawn_app_with(config).await;
    let url = format!("ws://{}/depth-stream", app.socket);
    match connect_async(url.clone()).await {
        Err(tungstenite::Error::Http(response)) => assert_eq!(response.status(), 401),
        other => panic!(
            "opened without a token: {:?}",
            other.map(|(_, r)| r.status())
        ),
    }
    let mut request = url.clone().into_client_request().unwrap();
    request
        .headers_mut()
        .insert("authorization", format!("Bearer {token}").parse().unwrap());
    let (mut socket, _) = connect_async(request).await.expect("opens with the token");
    socket.send(Message::text("{}")).await.unwrap();
    assert_eq!(text(&mut socket).await["type"], "settings");
    // The browser's carrier: the token base64url-encoded in a subprotocol entry.
    let offer = |token: &str| {
        use base64::Engine as _;
        let encoded = base64::engine::general_purpose::URL_SAFE_NO_PAD.encode(token);
        let mut request = url.clone().into_client_request().unwrap();
        request.headers_mut().insert(
            "sec-websocket-protocol",
            format!("depth-stream, bearer.{encoded}").parse().unwrap(),
        );
        request
    };
    let (mut socket, response) = connect_async(offer(token))
        .await
        .expect("opens with the token as a protocol entry");
    assert_eq!(
        response.headers()["sec-websocket-protocol"],
        "depth-stream",
        "the stream's protocol selected, never the token's entry"
    );
    socket.send(Message::text("{}")).await.unwrap();
    assert_eq!(text(&mut socket).await["type"], "settings");
    match connect_async(offer("not-the-token")).await {
        Err(tungstenite::Error::Http(response)) => assert_eq!(response.status(), 401),
        other => panic!(
            "opened with a wrong token: {:?}",
            other.map(|(_, r)| r.status())
        ),
    }
}

/// A side-by-side frame is two images, each judged by one image's limits: with
/// `--max-image-pixels` one image's size, the frame holding two of them is answered, and one
/// whose halves are each past the limit is refused (413 naming `frame`, judged from its
/// header) while the stream goes on.
#[tokio::test]
async fn a_side_by_side_frame_is_judged_by_its_halves() {
    let config = Config {
        port: 0,
        heavy: stereo_distance::config::HeavyLimits {
            max_image_pixels: W * H,
            ..Default::default()
        },
        ..Config::default()
    };
    let app = spawn_app_with(config).await;
    let pair = pair();
    let settings = json!({"options": {"max_disparity": 48}, "outputs": []});
    let (mut socket, resolved) = open_with(&app, settings).await;
    assert_eq!(resolved["type"], "settings", "{resolved}");
    socket
        .send(Message::binary(side_by_side(&pair)))
        .await
        .unwrap();
    let answer = text(&mut socket).await;
    assert_eq!(answer["type"], "frame", "{answer}");
    assert_eq!(answer["summary"]["width"], W);
    let wider = png_claiming(2 * (W as u32 + 2), H as u32);
    socket.send(Message::binary(wider)).await.unwrap();
    let answer = text(&mut socket).await;
    assert_eq!(answer["type"], "error", "{answer}");
    assert_eq!(answer["problem"]["status"], 413, "{answer}");
    assert_eq!(fields(&answer["problem"]), ["frame"]);
    let detail = answer["problem"]["errors"][0]["message"].as_str().unwrap();
    assert!(detail.contains("each is 162 × 120 pixels"), "{detail}");
    socket
        .send(Message::binary(side_by_side(&pair)))
        .await
        .unwrap();
    assert_eq!(text(&mut socket).await["id"], 3);
}

/// With no range given, the stream finds it from its frames and keeps it: a near frame's
/// range (past 128) is still searched on the far frame after it, and the far frame's summary
/// says the range is the stream's recent frames' and what it alone needs.
#[tokio::test]
async fn the_range_found_is_kept_over_the_streams_frames() {
    use stereo_core::vision::synthetic;
    let app = spawn_app().await;
    let settings = json!({"layout": "pair", "rig": rig(), "outputs": []});
    let (mut socket, resolved) = open_with(&app, settings).await;
    assert_eq!(resolved["max_disparity"], Value::Null, "{resolved}");
    let frame = |scale: f32| {
        let mut scene = synthetic::layered(640, 360);
        for plane in &mut scene.planes {
            plane.disparity = plane.disparity.map(|v| scale * v);
        }
        let p = synthetic::render(&scene);
        pair_frame(&png(&p.left_rgb, 640, 360), &png(&p.right_rgb, 640, 360))
    };
    socket.send(Message::binary(frame(5.0))).await.unwrap();
    let near = text(&mut socket).await;
    let near_max = near["summary"]["max_disparity"].as_i64().unwrap();
    assert!(near_max > 150, "{near}");
    assert_eq!(near["summary"]["disparity_range"]["chosen"], "found");
    socket.send(Message::binary(frame(1.0))).await.unwrap();
    let far = text(&mut socket).await;
    assert_eq!(far["summary"]["max_disparity"], near_max, "{far}");
    let why = far["summary"]["disparity_range"]["why"].as_str().unwrap();
    assert!(why.contains("the stream's recent frames needed"), "{why}");
    socket.close(None).await.unwrap();
}

/// A raw stream checks its calibration on its first frame and every 10th after: the rig
/// turned 0.05° about x since its calibration is found there (±0.01°), with the corrected
/// calibration in OpenCV's YAML; the frames between carry no check; the rig as calibrated
/// holds.
#[tokio::test]
async fn a_raw_stream_checks_its_calibration() {
    use crate::calibration_check::{opencv_yml, scenes};
    use stereo_core::calibration::boards::synthetic::sample_rig;
    let app = spawn_app().await;
    let calibration = opencv_yml(&sample_rig());
    for (frames, holds) in [(&scenes()[1], false), (&scenes()[0], true)] {
        let settings =
            json!({"layout": "pair", "calibration": calibration, "outputs": [], "temporal": false});
        let (mut socket, resolved) = open_with(&app, settings).await;
        assert_eq!(resolved["type"], "settings", "{resolved}");
        for (i, (l, r)) in frames.iter().take(2).enumerate() {
            socket
                .send(Message::binary(pair_frame(l, r)))
                .await
                .unwrap();
            let answer = text(&mut socket).await;
            let check = &answer["calibration_check"];
            if i > 0 {
                assert!(check.is_null(), "frame {i}: {answer}");
                continue;
            }
            assert_eq!(check["checked_frames"], 1, "{answer}");
            assert_eq!(check["holds"], holds, "{check}");
            if holds {
                assert!(check.get("corrected_opencv_yml").is_none(), "{check}");
            } else {
                let x = check["correction"]["rotation_deg"]["x"]["value"]
                    .as_f64()
                    .unwrap();
                assert!((x - 0.05).abs() < 0.01, "{check}");
                let yml = check["corrected_opencv_yml"]
                    .as_str()
                    .expect("the corrected file");
                assert!(yml.starts_with("%YAML:1.0"), "{yml}");
            }
        }
        socket.close(None).await.unwrap();
    }
}
