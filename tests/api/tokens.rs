//! Bearer tokens over a real socket: none, wrong, right and rotated; the probes, the page,
//! `/docs` and `/openapi.json` open, `/metrics` and every API route (light and heavy)
//! closed; the 401's problem and `WWW-Authenticate`; the `depth-map` command sending its
//! token (flag or variable); and the server's log never holding a token.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::Duration;

use reqwest::multipart::Form;
use stereo_distance::Config;
use stereo_distance::config::ApiTokens;

use crate::helpers::{PATIENCE, TestApp, message_for, problem, spawn_app_with};

const OLD: &str = "old-token-0123456789abcdef";
const NEW: &str = "new-token-fedcba9876543210";
const FIXED: &str = "fixed/token+from=env-0123";
const DISTANCE: &str = "/distance?focal_length_px=800&baseline=120&unit=mm&x_left=420&x_right=380";

fn tokens_file(name: &str, text: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("tokens");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

async fn get(app: &TestApp, path: &str, token: Option<&str>) -> reqwest::Response {
    match token {
        Some(token) => {
            app.get_with_header(path, "authorization", &format!("Bearer {token}"))
                .await
        }
        None => app.get(path).await,
    }
}

/// Without a token a request is a 401 problem naming `authorization`, with
/// `WWW-Authenticate: Bearer realm="stereo-distance"`; with a wrong one the same with
/// `error="invalid_token"`; with any token given (the file's or the variable's, the scheme in
/// any case) it is answered. The heavy routes are closed before their body is read; the
/// probes, the page, `/docs` and `/openapi.json` stay open; `/metrics` needs a token.
#[tokio::test]
async fn none_wrong_and_right_tokens() {
    let file = tokens_file("tokens-1", &format!("# the file's\n{OLD}\n"));
    let app = spawn_app_with(Config {
        port: 0,
        api_tokens_file: Some(file),
        api_tokens: Some(ApiTokens(vec![FIXED.to_owned()])),
        ..Config::default()
    })
    .await;
    let none = get(&app, DISTANCE, None).await;
    assert_eq!(
        none.headers()["www-authenticate"],
        r#"Bearer realm="stereo-distance""#
    );
    let body = problem(none, 401).await;
    assert!(message_for(&body, "authorization").contains("required"));
    let wrong = get(&app, DISTANCE, Some("not-a-token-we-know-0000")).await;
    assert_eq!(
        wrong.headers()["www-authenticate"],
        r#"Bearer realm="stereo-distance", error="invalid_token""#
    );
    let body = problem(wrong, 401).await;
    assert!(message_for(&body, "authorization").contains("not a token"));
    for token in [OLD, FIXED] {
        assert_eq!(get(&app, DISTANCE, Some(token)).await.status(), 200);
    }
    let lower = app
        .get_with_header(DISTANCE, "authorization", &format!("bearer {OLD}"))
        .await;
    assert_eq!(lower.status(), 200);
    let basic = app
        .get_with_header(DISTANCE, "authorization", "Basic dXNlcjpwYXNz")
        .await;
    assert_eq!(basic.status(), 401);
    // A heavy route: refused whatever its body.
    let form = Form::new().text("left", "x").text("right", "y");
    let heavy = app.post_form("/depth-map", form).await;
    assert_eq!(heavy.status(), 401);
    for open in ["/healthz", "/readyz", "/", "/openapi.json", "/docs/"] {
        assert_eq!(get(&app, open, None).await.status(), 200, "{open}");
    }
    assert_eq!(get(&app, "/metrics", None).await.status(), 401);
    assert_eq!(get(&app, "/metrics", Some(FIXED)).await.status(), 200);
}

/// A token rotated through the file: the new one is added beside the old (both work), then
/// the old one removed (only the new works), each seen within the reload period without a
/// restart; a file that stops reading keeps the tokens it had.
#[tokio::test]
async fn a_token_rotated_in_the_file() {
    let file = tokens_file("tokens-2", &format!("{OLD}\n"));
    let app = spawn_app_with(Config {
        port: 0,
        api_tokens_file: Some(file.clone()),
        api_tokens_reload: Duration::from_millis(50),
        ..Config::default()
    })
    .await;
    let status = |token: &'static str| {
        let app = &app;
        async move { get(app, DISTANCE, Some(token)).await.status().as_u16() }
    };
    assert_eq!((status(OLD).await, status(NEW).await), (200, 401));
    std::fs::write(&file, format!("{OLD}\n{NEW}\n")).unwrap();
    wait_until(|| async { status(NEW).await == 200 }).await;
    assert_eq!(status(OLD).await, 200);
    std::fs::write(&file, format!("{NEW}\n")).unwrap();
    wait_until(|| async { status(OLD).await == 401 }).await;
    assert_eq!(status(NEW).await, 200);
    std::fs::write(&file, "short\n").unwrap();
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(status(NEW).await, 200);
}

async fn wait_until<F, Fut>(mut done: F)
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = bool>,
{
    let started = std::time::Instant::now();
    while !done().await {
        assert!(started.elapsed() < PATIENCE, "never happened");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// The `depth-map` command against the binary serving with `API_TOKENS` (access log of every
/// request on): without a token the run stops at the first frame with the 401's words;
/// with `--token` or `API_TOKEN` every pair is written. The server's log, which holds a line
/// for each of those requests, holds no token.
#[test]
fn the_command_sends_its_token_and_the_log_holds_none() {
    let mut server = Command::new(env!("CARGO_BIN_EXE_stereo-distance"))
        .env_clear()
        .env("HOST", "127.0.0.1")
        .env("PORT", "0")
        .env("LOG_FORMAT", "json")
        .env("ACCESS_LOG", "all")
        .env("API_TOKENS", format!("{OLD},{NEW}"))
        .stdout(Stdio::piped())
        .spawn()
        .expect("the binary starts");
    let stdout = server.stdout.take().unwrap();
    let (log, lines) = std::sync::mpsc::channel();
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if log.send(line).is_err() {
                break;
            }
        }
    });
    let address = lines
        .iter()
        .find_map(|line| {
            let rest = line.split("serving on http://").nth(1)?;
            rest.split([' ', '"']).next().map(str::to_owned)
        })
        .expect("the binary logs its address");
    let url = format!("http://{address}");
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("recording-tokens");
    let _ = std::fs::remove_dir_all(&dir);
    for side in ["left", "right"] {
        std::fs::create_dir_all(dir.join(side)).unwrap();
    }
    let pair = crate::depth_map::pair();
    let (w, h) = (crate::depth_map::W, crate::depth_map::H);
    for n in 1..=2 {
        std::fs::write(
            dir.join(format!("left/000{n}.png")),
            stereo_core::vision::encode::png_rgb(w, h, &pair.left_rgb),
        )
        .unwrap();
        std::fs::write(
            dir.join(format!("right/000{n}.png")),
            stereo_core::vision::encode::png_rgb(w, h, &pair.right_rgb),
        )
        .unwrap();
    }
    let run = |out: &str, extra: &[&str], env: Option<&str>| {
        let mut command = crate::recording::command(
            &dir,
            out,
            &[&["--server", &url, "--max-disparity", "48"], extra].concat(),
        );
        command.env_remove("API_TOKEN");
        if let Some(token) = env {
            command.env("API_TOKEN", token);
        }
        let output = command.output().unwrap();
        (
            output.status.code(),
            String::from_utf8_lossy(&output.stderr).into_owned(),
        )
    };
    let (code, said) = run("none", &[], None);
    assert_eq!(code, Some(1), "{said}");
    assert!(
        said.contains("401 Unauthorized") && said.contains("authorization"),
        "{said}"
    );
    let (code, said) = run("flag", &["--token", OLD], None);
    assert_eq!(code, Some(0), "{said}");
    assert!(said.contains("wrote 2 of 2 pairs"), "{said}");
    let (code, said) = run("variable", &[], Some(NEW));
    assert_eq!(code, Some(0), "{said}");
    let (code, said) = run("wrong", &["--token", "wrong-token-0123456789"], None);
    assert_eq!(code, Some(1), "{said}");
    server.kill().unwrap();
    let _ = server.wait();
    reader.join().unwrap();
    let logged: Vec<String> = lines.try_iter().collect();
    let served = logged
        .iter()
        .filter(|l| l.contains("request served"))
        .count();
    assert!(served >= 5, "{logged:?}");
    assert!(
        logged.iter().all(|l| !l.contains(OLD) && !l.contains(NEW)),
        "a token in the log: {logged:?}"
    );
}
