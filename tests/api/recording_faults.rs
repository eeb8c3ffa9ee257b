//! `stereo-distance depth-map` when things go wrong, run as its users run it (the binary, its
//! stderr a pipe): a server killed in the middle of a run and started again, broken frames
//! under a calibration without a size, settings that are wrong, a service that is not there,
//! and the service's warnings (printed once, grouped, and failing a pair under `--strict`).

use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use stereo_core::vision::encode;

use crate::depth_map::{H, W, pair};
use crate::recording::command;

/// The size-less calibration of [`crate::damaged`], written into `dir`; its path.
fn sizeless_calibration(dir: &Path) -> PathBuf {
    let path = dir.join("stereo.yml");
    std::fs::write(&path, crate::damaged::sizeless_calibration()).unwrap();
    path
}

/// A fresh folder `name` under the test's tmpdir with `left/` and `right/`, `n` good pairs
/// of the rendered scene (`0001.png` …) in it.
fn folder(name: &str, n: usize) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    for side in ["left", "right"] {
        std::fs::create_dir_all(dir.join(side)).unwrap();
    }
    let pair = pair();
    let (left, right) = (
        encode::png_rgb(W, H, &pair.left_rgb),
        encode::png_rgb(W, H, &pair.right_rgb),
    );
    for i in 1..=n {
        std::fs::write(dir.join(format!("left/{i:04}.png")), &left).unwrap();
        std::fs::write(dir.join(format!("right/{i:04}.png")), &right).unwrap();
    }
    dir
}

fn run(dir: &Path, extra: &[&str]) -> (Output, String) {
    let output = command(dir, "out", extra)
        .output()
        .expect("the binary runs");
    let said = String::from_utf8_lossy(&output.stderr).into_owned();
    (output, said)
}

/// The files in `dir/out`, sorted.
fn written(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir.join("out"))
        .map(|entries| {
            entries
                .flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    names
}

/// The server binary on `port`, once it says it serves; its log drained.
fn serve(port: u16) -> Child {
    let mut child = Command::new(env!("CARGO_BIN_EXE_stereo-distance"))
        .env_clear()
        .env("HOST", "127.0.0.1")
        .env("PORT", port.to_string())
        .env("LOG_FORMAT", "json")
        .stdout(Stdio::piped())
        .spawn()
        .expect("the binary starts");
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    lines
        .by_ref()
        .map_while(Result::ok)
        .find(|line| line.contains("serving on http://"))
        .expect("the binary serves");
    std::thread::spawn(move || lines.for_each(drop));
    child
}

/// A server killed (SIGKILL, as a node lost or a pod evicted) once a few pairs are written,
/// and started again on its port 1.5 s later: the run waits, says on its lines that it waits
/// and why, sends the frames that were in flight again, and ends with every pair written once
/// (every file there, none left half-written) and exit 0.
#[test]
fn a_server_restarted_in_the_middle_of_a_run_loses_no_frame() {
    const PAIRS: usize = 16;
    let dir = folder("recording-restart", PAIRS);
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let mut server = serve(port);
    let url = format!("http://127.0.0.1:{port}");
    let client = command(
        &dir,
        "out",
        &["--server", &url, "--max-disparity", "48", "--retries", "8"],
    )
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    let started = Instant::now();
    while written(&dir).len() < 3 {
        assert!(
            started.elapsed() < Duration::from_secs(120),
            "nothing written"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    server.kill().unwrap();
    server.wait().unwrap();
    let at_kill = written(&dir).len();
    std::thread::sleep(Duration::from_millis(1500));
    let mut again = serve(port);
    let output = client.wait_with_output().unwrap();
    again.kill().unwrap();
    let _ = again.wait();
    let said = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(at_kill < PAIRS, "the run ended before the kill: {said}");
    assert_eq!(output.status.code(), Some(0), "{said}");
    assert!(said.contains("waiting: "), "{said}");
    assert!(said.contains("again in"), "{said}");
    assert!(
        said.contains(&format!("wrote {PAIRS} of {PAIRS} pairs")),
        "{said}"
    );
    let names = written(&dir);
    let expected: Vec<String> = (1..=PAIRS)
        .map(|i| format!("{i:04}.disparity.npy"))
        .collect();
    assert_eq!(names, expected, "{said}");
}

/// A folder with an unreadable left frame, a truncated one and a corrupt right one among good
/// pairs, under a calibration without a size: the good pairs are all written, each bad one
/// is named by its file with the service's reason, and the run goes on to the end (exit 1);
/// the same against a running service.
#[tokio::test]
async fn broken_frames_are_named_and_skipped() {
    let app = crate::helpers::spawn_app().await;
    for (name, server) in [
        ("recording-broken", None),
        ("recording-broken-server", Some(app.address.clone())),
    ] {
        let dir = folder(name, 5);
        let calibration = sizeless_calibration(&dir);
        std::fs::write(dir.join("left/0002.png"), b"not a picture at all").unwrap();
        let whole = std::fs::read(dir.join("left/0003.png")).unwrap();
        std::fs::write(dir.join("left/0003.png"), &whole[..whole.len() * 6 / 10]).unwrap();
        let mut corrupt = std::fs::read(dir.join("right/0005.png")).unwrap();
        let at = corrupt.len() / 2;
        corrupt[at] ^= 0x10;
        std::fs::write(dir.join("right/0005.png"), corrupt).unwrap();
        let mut args = vec![
            "--calibration".to_owned(),
            calibration.to_string_lossy().into_owned(),
            "--calibration-unit".to_owned(),
            "mm".to_owned(),
            "--max-disparity".to_owned(),
            "48".to_owned(),
        ];
        if let Some(url) = &server {
            args.extend(["--server".to_owned(), url.clone()]);
        }
        let dir_for = dir.clone();
        let (output, said) = tokio::task::spawn_blocking(move || {
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            run(&dir_for, &args)
        })
        .await
        .unwrap();
        assert_eq!(output.status.code(), Some(1), "{said}");
        assert_eq!(
            written(&dir),
            ["0001.depth.npy", "0004.depth.npy"],
            "{name}: {said}"
        );
        for (pair, file, words) in [
            ("0002", "left/0002.png", "is not an image"),
            ("0003", "left/0003.png", "is cut off"),
            ("0005", "right/0005.png", "could not be decoded"),
        ] {
            let line = said
                .lines()
                .find(|l| l.starts_with(&format!("failed {pair}:")))
                .unwrap_or_else(|| panic!("{name}: {pair} not named: {said}"));
            assert!(line.contains(file) && line.contains(words), "{line}");
        }
        assert!(said.contains("wrote 2 of 5 pairs"), "{name}: {said}");
        assert!(said.contains("3 failed"), "{said}");
    }
}

/// A fault in the run's settings stops it before the first frame is sent, naming every
/// fault by its option: a range that is not one, and depths asked for without a
/// calibration; a calibration file that cannot be read is named too. Nothing is written.
#[test]
fn a_settings_fault_stops_the_run_before_the_first_frame() {
    let dir = folder("recording-settings", 2);
    let (output, said) = run(
        &dir,
        &[
            "--min-disparity",
            "64",
            "--max-disparity",
            "32",
            "--output",
            "depth.npy",
        ],
    );
    assert_eq!(output.status.code(), Some(1), "{said}");
    assert!(said.contains("the run's settings are refused"), "{said}");
    assert!(said.contains("--output: depth.npy is depths"), "{said}");
    assert!(
        said.contains("--max-disparity") || said.contains("--min-disparity"),
        "{said}"
    );
    assert!(!said.contains("wrote "), "{said}");
    assert!(written(&dir).is_empty());
    let bad = dir.join("bad.yml");
    std::fs::write(&bad, "%YAML:1.0\n---\nM1: [1, 2]\n").unwrap();
    let (output, said) = run(&dir, &["--calibration", bad.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(1), "{said}");
    assert!(said.contains("--calibration: "), "{said}");
    assert!(written(&dir).is_empty());
}

/// A service that is not there is tried again as `--retries` says, each wait said, and
/// then the run stops with its address.
#[test]
fn a_service_that_stays_away_stops_the_run_after_its_retries() {
    let dir = folder("recording-nowhere", 2);
    let (output, said) = run(
        &dir,
        &[
            "--server",
            "http://127.0.0.1:1",
            "--retries",
            "2",
            "--jobs",
            "1",
        ],
    );
    assert_eq!(output.status.code(), Some(1), "{said}");
    let waits = said
        .lines()
        .filter(|l| l.starts_with("waiting: cannot connect to 127.0.0.1:1"))
        .count();
    assert_eq!(waits, 2, "{said}");
    assert!(said.contains("(retry 2 of 2)"), "{said}");
    assert!(
        said.contains("error: cannot connect to 127.0.0.1:1")
            && said.contains("on each of 3 tries"),
        "{said}"
    );
}

/// The service's warnings reach the user: pairs that look raw (the right frame's grey levels
/// inverted: only a sliver matches) get the advice to rectify, printed for the first pair and
/// then grouped with how many pairs said it; the maps are written (exit 0). Under
/// `--strict` the same pairs fail and nothing is written.
#[test]
fn warnings_are_printed_once_grouped_and_strict_fails_them() {
    let dir = folder("recording-warnings", 3);
    let mut inverted = pair();
    inverted.right_rgb.iter_mut().for_each(|v| *v = 255 - *v);
    for i in 1..=3 {
        std::fs::write(
            dir.join(format!("right/{i:04}.png")),
            encode::png_rgb(W, H, &inverted.right_rgb),
        )
        .unwrap();
    }
    // One pair at a time, so that 0001 is the first to say it.
    let (output, said) = run(&dir, &["--max-disparity", "48", "--jobs", "1"]);
    assert_eq!(output.status.code(), Some(0), "{said}");
    let told: Vec<&str> = said.lines().filter(|l| l.starts_with("warning ")).collect();
    assert_eq!(told.len(), 1, "{said}");
    assert!(
        told[0].starts_with("warning 0001: ") && told[0].contains("need rectifying"),
        "{said}"
    );
    assert!(
        said.contains("the warning first said of 0001 was said of 3 pairs: 0001, 0002, 0003"),
        "{said}"
    );
    assert_eq!(written(&dir).len(), 3);
    std::fs::remove_dir_all(dir.join("out")).unwrap();
    let (output, said) = run(&dir, &["--max-disparity", "48", "--strict"]);
    assert_eq!(output.status.code(), Some(1), "{said}");
    assert_eq!(
        said.lines().filter(|l| l.contains("(--strict)")).count(),
        3,
        "{said}"
    );
    assert!(said.contains("wrote 0 of 3 pairs"), "{said}");
    assert!(written(&dir).is_empty());
}
