//! Slow and stalled clients over a real socket: uploads that trickle hold no image slot and are
//! cut off with 408 by the minimum body rate, and clients that never read their answers keep
//! the process within its memory budget until the write timeout cuts them off and frees what
//! they held.
//!
//! A test binary of its own, with a counting global allocator: the live heap it reads is this
//! server's and its clients', no other test binary's; the tests here take turns
//! ([`one_at_a_time`]) so that neither counts the other's.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use axum::extract::Query;
use axum::response::{IntoResponse, Response};
use axum::{Router, routing::post};
use reqwest::multipart::{Form, Part};
use serde::Deserialize;
use stereo_core::vision::{encode, synthetic};
use stereo_distance::api::HeavyState;
use stereo_distance::api::error::ApiError;
use stereo_distance::api::images::work::{self, Admitted};
use stereo_distance::config::{Config, HeavyLimits};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpSocket, TcpStream};

#[path = "api/helpers.rs"]
#[allow(dead_code)]
mod helpers;

use helpers::{PATIENCE, TestApp, metric_at, problem, spawn_app_with_heavy};

/// Counts the bytes the process holds on its heap now, and the most it has held.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(bytes: usize) {
    let live = LIVE.fetch_add(bytes, Ordering::Relaxed) + bytes;
    PEAK.fetch_max(live, Ordering::Relaxed);
}

// SAFETY: every call is passed on to the system allocator unchanged; the counters only watch.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's layout, passed on.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's layout, passed on.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: a block this allocator gave, with its layout.
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: a block this allocator gave, with its layout, and the caller's new size.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
            grew(new_size);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

const MIB: usize = 1 << 20;

/// Makes the tests of this binary take turns, so that each reads only its own heap.
async fn one_at_a_time() -> tokio::sync::MutexGuard<'static, ()> {
    static TURN: tokio::sync::Mutex<()> = tokio::sync::Mutex::const_new(());
    TURN.lock().await
}

/// The synthetic pair (planes at 6–38 px of disparity) as a `/depth-map` form.
fn pair_form() -> Form {
    let (w, h) = (160, 120);
    let pair = synthetic::render(&synthetic::layered(w, h));
    let part = |rgb: &[u8]| {
        Part::bytes(encode::png_rgb(w, h, rgb))
            .file_name("image.png")
            .mime_str("image/png")
            .unwrap()
    };
    Form::new()
        .part("left", part(&pair.left_rgb))
        .part("right", part(&pair.right_rgb))
}

/// A `/depth-map` of the synthetic pair; its status.
async fn depth_map(app: &TestApp) -> u16 {
    app.client
        .post(format!("{}/depth-map?max_disparity=48", app.address))
        .multipart(pair_form())
        .send()
        .await
        .expect("request is sent")
        .status()
        .as_u16()
}

/// The first bytes of a form whose `Content-Length` says 30 MB: the head and the start of the
/// `left` part.
fn slow_upload_head(addr: &str) -> String {
    format!(
        "POST /depth-map HTTP/1.1\r\nHost: {addr}\r\nContent-Type: multipart/form-data; \
         boundary=XYZ\r\nContent-Length: 30000000\r\n\r\n--XYZ\r\nContent-Disposition: \
         form-data; name=\"left\"; filename=\"left.png\"\r\nContent-Type: image/png\r\n\r\n"
    )
}

/// Sixteen uploads that declare 30 MB and send a byte every 2 s hold none of the four image
/// slots: real `/depth-map` requests sent meanwhile are all answered 200. With the default
/// minimum body rate (1 KiB/s once 5 s have passed) each slow upload is answered 408, naming
/// its body, and its connection closed, within 15 s of its start.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn slow_uploads_hold_no_image_slot_and_are_cut_off() {
    let _turn = one_at_a_time().await;
    // Arrange: the 2-core defaults (4 image slots), the default body rate.
    let config = Config {
        port: 0,
        heavy: HeavyLimits {
            concurrency_limit: 4,
            ..HeavyLimits::default()
        },
        ..Config::default()
    };
    let app = spawn_app_with_heavy(config, Router::new()).await;
    let started = Instant::now();
    let mut slow = Vec::new();
    for _ in 0..16 {
        let stream = app
            .raw_partial(&slow_upload_head(&app.socket.to_string()), b"\x89")
            .await;
        slow.push(tokio::spawn(trickle(stream)));
    }
    app.wait_in_flight(17.0).await; // the 16 uploads and this /metrics poll

    // Act: real image requests while the uploads trickle.
    let mut statuses = Vec::new();
    for _ in 0..6 {
        statuses.push(depth_map(&app).await);
    }
    let mut answers = Vec::new();
    for task in slow {
        answers.push(task.await.expect("the trickle task ends"));
    }

    // Assert
    assert_eq!(statuses, vec![200; 6], "every real image request is served");
    for (answer, closed_after) in answers {
        assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
        assert!(answer.contains("\"field\":\"body\""), "{answer}");
        assert!(answer.contains("slower than the 1024 B/s"), "{answer}");
        assert!(
            closed_after < Duration::from_secs(15),
            "closed {closed_after:?} after the test began"
        );
    }
    assert!(
        started.elapsed() >= Duration::from_secs(5),
        "not before the grace period"
    );
}

/// Sends a byte of `stream`'s body every 2 s until the server answers and closes; returns the
/// answer and when the connection was closed, from the start of the trickle.
async fn trickle(stream: TcpStream) -> (String, Duration) {
    let started = Instant::now();
    let (mut reader, mut writer) = stream.into_split();
    let reading = tokio::spawn(async move {
        let mut answer = Vec::new();
        let _ = reader.read_to_end(&mut answer).await;
        answer
    });
    let mut reading = std::pin::pin!(tokio::time::timeout(PATIENCE, reading));
    let answer = loop {
        tokio::select! {
            answer = &mut reading => break answer,
            () = tokio::time::sleep(Duration::from_secs(2)) => {
                // A write after the server has closed may fail: the answer is what counts.
                let _ = writer.write_all(b"P").await;
            }
        }
    };
    let answer = answer
        .expect("the server closes the connection")
        .expect("the reader ends");
    (
        String::from_utf8_lossy(&answer).into_owned(),
        started.elapsed(),
    )
}

/// The test route's query: how large an answer to make.
#[derive(Deserialize)]
struct Answer {
    bytes: usize,
}

/// `POST /test/answer?bytes=N`: an image route's shape, without the images. Its work takes a
/// slot and reserves `N` bytes, as `/depth-map` reserves its answer's, and makes an answer of
/// `N` bytes (each page written, so that it is real memory).
async fn answer(
    admitted: Admitted,
    Query(Answer { bytes }): Query<Answer>,
) -> Result<Response, ApiError> {
    let made = work::run_reserved(
        admitted,
        bytes,
        |_| Vec::new(),
        move |_, _| vec![b'a'; bytes],
    )
    .await?;
    Ok(made.into_response())
}

/// Opens a connection with a 4 KiB receive buffer and sends `request`; reads nothing.
async fn stalled(socket: std::net::SocketAddr, request: &str) -> TcpStream {
    let client = TcpSocket::new_v4().unwrap();
    client.set_recv_buffer_size(4096).unwrap();
    let mut stream = client.connect(socket).await.expect("connects");
    stream.write_all(request.as_bytes()).await.unwrap();
    stream
}

/// Forty-eight clients ask for an 8 MiB answer each and never read it. The answers made are
/// held in the 64 MiB budget until sent, so eight are made (the rest are refused 503 with
/// `Retry-After`) and the heap grows by no more than the budget; a light request is
/// answered meanwhile and an image request refused 503 while the budget is full. After the
/// write timeout (2 s here) the stalled connections are reset, the budget is whole again, the
/// heap is back where it began, and a real `/depth-map` is served 200.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stalled_readers_stay_within_the_budget_until_cut_off() {
    let _turn = one_at_a_time().await;
    // Arrange
    let budget = 64 * MIB;
    let config = Config {
        port: 0,
        write_timeout: Duration::from_secs(2),
        heavy: HeavyLimits {
            memory_budget: budget,
            body_bytes: MIB,
            // Slots are not what this test is about: every reader's work may start at once.
            concurrency_limit: 64,
            ..HeavyLimits::default()
        },
        ..Config::default()
    };
    let route = Router::<HeavyState>::new().route("/test/answer", post(answer));
    let app = spawn_app_with_heavy(config, route).await;
    assert_eq!(
        depth_map(&app).await,
        200,
        "warm: the matcher's first buffers"
    );
    let reserved = || metric_at(&app.client, &app.address, "heavy_memory_reserved_bytes");
    let request = format!(
        "POST /test/answer?bytes={} HTTP/1.1\r\nHost: test\r\nContent-Length: 0\r\n\
         Connection: close\r\n\r\n",
        8 * MIB
    );
    let baseline = LIVE.load(Ordering::Relaxed);
    PEAK.store(baseline, Ordering::Relaxed);

    // Act: 48 stalled readers, then requests while they stall.
    let mut readers = Vec::new();
    for _ in 0..48 {
        readers.push(stalled(app.socket, &request).await);
    }
    // Every reader's request answered (its answer on its way, or refused).
    let answered = |status: &'static str| {
        let series = format!(
            "http_requests_total{{method=\"POST\",route=\"/test/answer\",status=\"{status}\"}}"
        );
        let app = &app;
        async move { app.metric(&series).await.unwrap_or(0.0) }
    };
    for _ in 0..2000 {
        if answered("200").await + answered("503").await == 48.0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let held = reserved().await.unwrap_or(0.0);
    let light = app
        .post(
            "/distance",
            &serde_json::json!({"focal_length_px": 35, "baseline": 150, "x_left": 400, "x_right": 350}),
        )
        .await;
    let heavy = app
        .client
        .post(format!("{}/test/answer?bytes={}", app.address, 8 * MIB))
        .send()
        .await
        .unwrap();
    let peak = PEAK.load(Ordering::Relaxed);

    // Assert: within the budget while they stall.
    assert_eq!(
        held, budget as f64,
        "eight answers of 8 MiB held, the whole budget"
    );
    assert!(
        peak - baseline <= budget + 8 * MIB,
        "the heap grew by {} MiB with a {} MiB budget",
        (peak - baseline) / MIB,
        budget / MIB
    );
    assert_eq!(light.status(), 200);
    assert_eq!(heavy.headers()["retry-after"], "1");
    let refused = problem(heavy, 503).await;
    assert!(
        refused["detail"]
            .as_str()
            .unwrap()
            .contains("memory budget"),
        "{refused}"
    );

    // Assert: cut off after the write timeout, and everything they held freed.
    let mut freed = false;
    for _ in 0..2000 {
        if reserved().await == Some(0.0) {
            freed = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert!(
        freed,
        "the budget is whole again once the readers are cut off"
    );
    assert!(
        LIVE.load(Ordering::Relaxed) < baseline + 4 * MIB,
        "the heap holds {} MiB more than before the readers",
        (LIVE.load(Ordering::Relaxed) - baseline) / MIB
    );
    let (mut whole, mut cut) = (0, 0);
    for mut reader in readers {
        let mut got = Vec::new();
        let _ = tokio::time::timeout(PATIENCE, reader.read_to_end(&mut got)).await;
        let text = String::from_utf8_lossy(&got[..got.len().min(200)]).into_owned();
        if text.starts_with("HTTP/1.1 503") {
            whole += 1;
        } else {
            assert!(text.starts_with("HTTP/1.1 200"), "{text}");
            assert!(got.len() < 8 * MIB, "an answer cut off arrives in part");
            cut += 1;
        }
    }
    assert_eq!(whole + cut, 48);
    assert_eq!(cut, 8, "the eight answers made were cut off");
    assert_eq!(depth_map(&app).await, 200);
}
