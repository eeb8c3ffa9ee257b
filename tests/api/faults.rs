//! Faults and limits over a real socket, as hostile or unlucky clients produce them: deep
//! nesting and numbers beyond f64, many connections past the concurrency limit, and a SIGTERM
//! to the real binary under load.

use std::{
    net::SocketAddr,
    process::{Child, Command, Stdio},
    sync::{
        Arc,
        atomic::{AtomicBool, AtomicUsize, Ordering},
    },
    time::Duration,
};

use reqwest::header::RETRY_AFTER;
use stereo_distance::Config;
use tokio::{
    io::{AsyncReadExt, AsyncWriteExt},
    net::TcpStream,
};

use crate::helpers::{
    PATIENCE, fields, problem, read_to_close, spawn_app, spawn_app_with, wait_in_flight_at,
};

/// Example 1 of the seed, with `baseline` replaced by `baseline`.
fn body_with_baseline(baseline: &str) -> String {
    format!(
        r#"{{"focal_length_px":35,"baseline":{baseline},"image_width":800,"image_height":600,"x_left":400,"x_right":350}}"#
    )
}

use crate::fixtures::example_one_request as example_request;

/// Nesting far past serde_json's recursion limit, numbers beyond f64 and 10 000-digit numbers
/// are each a 400 or 422 problem naming what is wrong, never a 500 or a crash, in a body, a
/// batch and a query; the server answers normally afterwards.
#[tokio::test]
async fn deep_nesting_and_huge_numbers_are_400_or_422() {
    let app = spawn_app().await;
    let deep_array = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000));
    let deep_object = format!("{}1{}", r#"{"a":"#.repeat(5_000), "}".repeat(5_000));
    let rig = r#""rig":{"focal_length_px":35,"baseline":150,"image_width":800,"image_height":600}"#;
    let cases: Vec<(&str, String, u16, &str)> = vec![
        (
            "nested member",
            body_with_baseline(&deep_array),
            400,
            "body",
        ),
        ("nested objects", deep_object, 400, "body"),
        ("unclosed nesting", "[".repeat(500_000), 400, "body"),
        (
            "nested batch point",
            format!(r#"{{{rig},"points":[{deep_array}]}}"#),
            400,
            "body",
        ),
        ("1e400", body_with_baseline("1e400"), 400, "body"),
        ("-1e400", body_with_baseline("-1e400"), 400, "body"),
        (
            "10 000 digits",
            body_with_baseline(&"9".repeat(10_000)),
            400,
            "body",
        ),
        (
            "huge exponent",
            body_with_baseline("1e99999999999999999999"),
            400,
            "body",
        ),
        (
            "underflow to 0",
            body_with_baseline("1e-400"),
            422,
            "baseline",
        ),
        (
            "huge finite",
            body_with_baseline("1.7976931348623157e308"),
            422,
            "focal_length_px",
        ),
    ];
    for (name, body, status, field) in cases {
        let response = app
            .post_raw("/distance", Some("application/json"), body.into_bytes())
            .await;
        let problem = problem(response, status).await;
        assert!(
            fields(&problem).contains(&field.to_owned()),
            "{name}: {problem}"
        );
    }

    for query in [
        "baseline=1e400".to_owned(),
        format!("baseline={}", "9".repeat(5_000)),
        "baseline=-1e400".to_owned(),
    ] {
        let response = app
            .get(&format!(
                "/distance?focal_length_px=35&image_width=800&image_height=600\
                 &x_left=400&x_right=350&{query}"
            ))
            .await;
        let problem = problem(response, 422).await;
        assert_eq!(fields(&problem), vec!["baseline"], "{query}");
    }

    let after = app
        .post_raw(
            "/distance",
            Some("application/json"),
            body_with_baseline("150").into_bytes(),
        )
        .await;
    assert_eq!(after.status(), 200);
}

/// With every slot of a concurrency limit of 4 held, 32 concurrent requests are each shed at
/// once with a 503 problem and `Retry-After` (answered while the slots are still held, so they
/// were not queued); once the slots are released, the held requests finish and 32 concurrent
/// requests are all served.
#[tokio::test]
async fn many_connections_past_the_limit_are_shed_not_queued() {
    // Arrange: four requests hold the four slots with half-sent bodies.
    let mut config = Config {
        port: 0,
        ..Config::default()
    };
    config.concurrency_limit = 4;
    let app = spawn_app_with(config).await;
    let (head, body) = example_request();
    let (first, rest) = body.as_bytes().split_at(10);
    let mut held = Vec::new();
    for _ in 0..4 {
        held.push(app.raw_partial(&head, first).await);
    }
    app.wait_in_flight(5.0).await; // the held four and this poll (probes are never shed)

    // Act: 32 requests at once.
    let client = reqwest::Client::new();
    let url = format!("{}/distance", app.address);
    let burst = |client: reqwest::Client, url: String| async move {
        let requests = (0..32).map(|_| {
            client
                .post(&url)
                .header("content-type", "application/json")
                .body(body_with_baseline("150"))
                .send()
        });
        futures_util::future::join_all(requests).await
    };
    let shed = burst(client.clone(), url.clone()).await;

    // Assert: all shed, with the advice to retry; the slots are still held.
    for response in shed {
        let response = response.expect("answered, not dropped");
        assert_eq!(response.headers()[RETRY_AFTER], "1");
        let body = problem(response, 503).await;
        assert_eq!(fields(&body), vec!["request"], "{body}");
        assert!(
            body["detail"]
                .as_str()
                .unwrap()
                .contains("concurrency limit")
        );
    }
    for mut stream in held {
        stream.write_all(rest).await.unwrap();
        let answer = read_to_close(&mut stream).await;
        assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
        assert!(answer.contains("\"distance\":105"), "{answer}");
    }
    for response in burst(client, url).await {
        assert_eq!(response.expect("answered").status(), 200);
    }
}

/// The fate of one request of the load during shutdown.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fate {
    /// A complete 200 with the right distance.
    Answered,
    /// The connection was refused: the listener had closed.
    Refused,
    /// Connected, but reset or closed before any byte of an answer: the client knows it was
    /// not answered (the kernel's accept queue is dropped with the listener).
    Reset,
    /// Anything else: a wrong status or body, a partial answer. Never acceptable.
    Wrong,
}

/// Sends example 1 on a new connection and classifies the outcome.
async fn one_request(address: SocketAddr) -> Fate {
    let Ok(mut stream) = TcpStream::connect(address).await else {
        return Fate::Refused;
    };
    let (head, body) = example_request();
    if stream
        .write_all(format!("{head}{body}").as_bytes())
        .await
        .is_err()
    {
        return Fate::Reset;
    }
    let mut answer = Vec::new();
    let read = tokio::time::timeout(PATIENCE, stream.read_to_end(&mut answer))
        .await
        .expect("every request ends: answered or cut off, never left hanging");
    let text = String::from_utf8_lossy(&answer);
    match read {
        _ if text.starts_with("HTTP/1.1 200") && text.contains("\"distance\":105") => {
            Fate::Answered
        }
        _ if answer.is_empty() => Fate::Reset,
        _ => {
            eprintln!("wrong answer: {text}");
            Fate::Wrong
        }
    }
}

/// Starts the real binary on a free port and returns it with the address it logged.
fn start_binary() -> (Child, SocketAddr) {
    use std::io::{BufRead, BufReader};
    let mut child = Command::new(env!("CARGO_BIN_EXE_stereo-distance"))
        .env_clear()
        .env("HOST", "127.0.0.1")
        .env("PORT", "0")
        .env("LOG_FORMAT", "json")
        .env("SHUTDOWN_TIMEOUT", "20s")
        .stdout(Stdio::piped())
        .spawn()
        .expect("the binary starts");
    let stdout = child.stdout.take().unwrap();
    let mut lines = BufReader::new(stdout).lines();
    let address = lines
        .by_ref()
        .map_while(Result::ok)
        .find_map(|line| {
            let rest = line.split("serving on http://").nth(1)?;
            rest.split([' ', '"']).next()?.parse().ok()
        })
        .expect("the binary logs its address");
    // Keep draining the log so that the binary never blocks on a full pipe.
    std::thread::spawn(move || lines.for_each(drop));
    (child, address)
}

/// SIGTERM to the real binary under load: the eight requests in flight (bodies half sent)
/// are finished and answered, the process exits 0, and every request of the concurrent load
/// ends visibly: a correct 200, a refused connection, or a reset before any answer. None gets
/// a wrong or partial answer, and none is left hanging.
#[tokio::test]
async fn sigterm_under_load_drains_in_flight_and_loses_nothing() {
    // Arrange: the binary, eight requests in flight, eight clients in a loop.
    let (mut child, address) = start_binary();
    let (head, body) = example_request();
    let (first, rest) = body.as_bytes().split_at(10);
    let mut held = Vec::new();
    for _ in 0..8 {
        let mut stream = TcpStream::connect(address).await.unwrap();
        stream.write_all(head.as_bytes()).await.unwrap();
        stream.write_all(first).await.unwrap();
        held.push(stream);
    }
    // The eight held requests and the poll itself.
    wait_in_flight_at(&reqwest::Client::new(), &format!("http://{address}"), 9.0).await;

    let answered = Arc::new(AtomicUsize::new(0));
    let refused = Arc::new(AtomicBool::new(false));
    let clients: Vec<_> = (0..8)
        .map(|_| {
            let (answered, refused) = (answered.clone(), refused.clone());
            tokio::spawn(async move {
                let mut fates = Vec::new();
                loop {
                    let fate = one_request(address).await;
                    fates.push(fate);
                    match fate {
                        Fate::Answered => {
                            answered.fetch_add(1, Ordering::Relaxed);
                        }
                        Fate::Refused => {
                            refused.store(true, Ordering::Relaxed);
                            return fates;
                        }
                        Fate::Reset | Fate::Wrong => {}
                    }
                    // Stop once the server is gone, even if this client kept being reset.
                    if refused.load(Ordering::Relaxed) {
                        return fates;
                    }
                }
            })
        })
        .collect();
    while answered.load(Ordering::Relaxed) < 200 {
        tokio::time::sleep(Duration::from_millis(5)).await;
    }

    // Act: SIGTERM, then the held requests send the rest of their bodies.
    let pid = child.id().to_string();
    let kill = Command::new("sh")
        .args(["-c", &format!("kill -TERM {pid}")])
        .status()
        .unwrap();
    assert!(kill.success());
    let mut answers = Vec::new();
    for mut stream in held {
        let rest = rest.to_vec();
        answers.push(tokio::spawn(async move {
            stream.write_all(&rest).await.unwrap();
            read_to_close(&mut stream).await
        }));
    }

    // Assert: every in-flight request answered; the process exits cleanly.
    for answer in answers {
        let answer = answer.await.unwrap();
        assert!(answer.starts_with("HTTP/1.1 200"), "{answer}");
        assert!(answer.contains("\"distance\":105"), "{answer}");
    }
    let status = tokio::task::spawn_blocking(move || child.wait())
        .await
        .unwrap()
        .unwrap();
    assert!(status.success(), "exit status after SIGTERM: {status}");

    // Every request of the load ended visibly, and none wrongly.
    let mut fates = Vec::new();
    for client in clients {
        fates.extend(
            tokio::time::timeout(PATIENCE, client)
                .await
                .expect("the clients stop")
                .unwrap(),
        );
    }
    let count = |fate| fates.iter().filter(|&&f| f == fate).count();
    eprintln!(
        "load during SIGTERM: {} answered, {} reset before an answer, {} refused",
        count(Fate::Answered),
        count(Fate::Reset),
        count(Fate::Refused)
    );
    assert_eq!(count(Fate::Wrong), 0, "no wrong or partial answers");
    assert!(count(Fate::Answered) >= 200);
    assert!(
        count(Fate::Refused) >= 1,
        "the clients stop at a refused connection"
    );
}
