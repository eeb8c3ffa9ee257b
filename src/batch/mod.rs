//! `stereo-distance depth-map`: every pair of a recording's folder(s) to depth maps, as
//! `/depth-map` makes them, in this process (through the service's own router, its limits and
//! its cache of rectification maps) or sent to a running service (`--server`). Pairs already
//! written are skipped, so a stopped run resumes; each file is written under a temporary name
//! and renamed when whole. A file without a partner, or one the service cannot read, is named
//! with its reason and the rest go on; a calibration the service refuses, or a service that
//! cannot be reached, stops the run.
//!
//! - [`pairing`]: which files make a pair (by name, as the page pairs them);
//! - [`transport`]: the router in process, or HTTP/1.1 to a service;
//! - [`progress`]: the bar on a terminal, plain lines elsewhere.

pub mod pairing;
pub mod progress;
pub mod transport;

use std::collections::VecDeque;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use pairing::{FramePair, Unpaired, file_name};
use progress::Progress;
use transport::{Answer, Server, Transport};

use crate::config::{Config, DepthMapArgs};

/// How many times a pair refused with 503 (the service busy) is sent again.
const RETRIES: usize = 10;
/// The longest wait before sending again, whatever `Retry-After` says.
const LONGEST_WAIT: Duration = Duration::from_secs(10);

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Outcome {
    pub written: usize,
    pub already: usize,
    pub failed: usize,
    pub unpaired: usize,
}

/// Runs the command, reporting on stderr; the exit code is 0 when every file made a map,
/// 1 when some did not or the run stopped.
pub fn run(config: Config, args: DepthMapArgs) -> ExitCode {
    let runtime = match tokio::runtime::Runtime::new() {
        Ok(runtime) => runtime,
        Err(error) => {
            eprintln!("error: cannot start the async runtime: {error}");
            return ExitCode::FAILURE;
        }
    };
    let bar = std::io::stderr().is_terminal();
    match runtime.block_on(depth_maps(config, args, std::io::stderr(), bar)) {
        Ok(outcome) if outcome.failed == 0 && outcome.unpaired == 0 => ExitCode::SUCCESS,
        Ok(_) => ExitCode::FAILURE,
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::FAILURE
        }
    }
}

/// What every request of the run carries besides its pair.
struct Plan {
    path_and_query: String,
    calibration: Option<(String, Vec<u8>)>,
    calibration_unit: Option<String>,
    out: PathBuf,
    extension: String,
}

/// The run itself, reporting into `out` (a bar when `bar`). `Err` is what stopped it.
pub async fn depth_maps<W: std::io::Write>(
    mut config: Config,
    args: DepthMapArgs,
    out: W,
    bar: bool,
) -> Result<Outcome, String> {
    let (pairs, mut unpaired) = match (&args.frames, &args.left, &args.right) {
        (Some(folder), _, _) => {
            let (files, others) = images_in(folder)?;
            let (pairs, mut unpaired) = pairing::pair_one_folder(&files);
            unpaired.extend(others);
            (pairs, unpaired)
        }
        (None, Some(left), Some(right)) => {
            let (l, mut others) = images_in(left)?;
            let (r, more) = images_in(right)?;
            others.extend(more);
            let (pairs, mut unpaired) = pairing::pair_two_folders(&l, &r);
            unpaired.extend(others);
            (pairs, unpaired)
        }
        _ => return Err("give --left and --right, or --frames".to_owned()),
    };
    unpaired.sort_by(|a, b| a.path.cmp(&b.path));
    let output = args.output.clone().unwrap_or_else(|| {
        if args.calibration.is_some() {
            "depth.npy"
        } else {
            "disparity.npy"
        }
        .to_owned()
    });
    let calibration = match &args.calibration {
        Some(path) => Some((
            file_name(path),
            std::fs::read(path)
                .map_err(|e| format!("cannot read the calibration {}: {e}", path.display()))?,
        )),
        None => None,
    };
    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot make the folder {}: {e}", args.out.display()))?;
    let mut query = format!("/depth-map?output={output}");
    for (name, value) in [
        ("preset", args.preset.clone()),
        ("min_disparity", args.min_disparity.map(|d| d.to_string())),
        ("max_disparity", args.max_disparity.map(|d| d.to_string())),
        (
            "max_disparity_std",
            args.max_disparity_std.map(|s| s.to_string()),
        ),
    ] {
        if let Some(value) = value {
            query.push_str(&format!("&{name}={value}"));
        }
    }
    let plan = Arc::new(Plan {
        path_and_query: query,
        calibration,
        calibration_unit: args.calibration_unit.clone(),
        out: args.out.clone(),
        extension: if output == "summary" {
            "json".to_owned()
        } else {
            output
        },
    });

    let (todo, already): (Vec<FramePair>, Vec<FramePair>) =
        pairs.into_iter().partition(|p| !plan.target(p).exists());
    let mut progress = Progress::new(out, bar, todo.len());
    for lost in &unpaired {
        progress.say(&format!("skipped {}: {}", lost.path.display(), lost.reason));
    }
    if !already.is_empty() {
        progress.say(&format!(
            "{} of {} pairs already written in {}: skipped",
            already.len(),
            already.len() + todo.len(),
            plan.out.display()
        ));
    }
    let transport = match &args.server {
        Some(url) => Transport::Http(Server::parse(url)?),
        None => {
            // One frame may take longer here than a server lets a request take.
            config.heavy.request_timeout =
                config.heavy.request_timeout.max(Duration::from_secs(600));
            Transport::InProcess(crate::server::startup::app(
                &config,
                crate::api::routes::ops::OpsState::default(),
            ))
        }
    };
    let jobs = args.jobs.unwrap_or(2).clamp(1, todo.len().max(1));
    let total = todo.len();
    let queue = Arc::new(Mutex::new(VecDeque::from(todo)));
    let (sender, mut results) = tokio::sync::mpsc::channel(jobs * 2);
    let started = Instant::now();
    let mut workers = Vec::new();
    for _ in 0..jobs {
        let (queue, plan, sender, mut transport) = (
            queue.clone(),
            plan.clone(),
            sender.clone(),
            transport.clone(),
        );
        workers.push(tokio::spawn(async move {
            loop {
                let next = queue.lock().ok().and_then(|mut q| q.pop_front());
                let Some(pair) = next else { break };
                let result = one_pair(&mut transport, &plan, &pair).await;
                if sender.send((pair, result)).await.is_err() {
                    break;
                }
            }
        }));
    }
    drop(sender);
    let mut outcome = Outcome {
        already: already.len(),
        unpaired: unpaired.len(),
        ..Outcome::default()
    };
    let mut stopped = None;
    while let Some((pair, result)) = results.recv().await {
        match result {
            Ok(()) => {
                outcome.written += 1;
                progress.finished(true);
            }
            Err(Failure::Pair(why)) => {
                outcome.failed += 1;
                progress.say(&format!("failed {}: {why}", pair.name));
                progress.finished(false);
            }
            Err(Failure::Run(why)) => {
                stopped = Some(why);
                break;
            }
        }
    }
    for worker in &workers {
        worker.abort();
    }
    progress.close();
    let seconds = started.elapsed().as_secs_f64();
    let made = outcome.written + outcome.failed;
    let rate = if seconds > 0.0 && made > 0 {
        format!(
            "; {:.2} frames/s, {:.1} ms a frame",
            made as f64 / seconds,
            1e3 * seconds / made as f64
        )
    } else {
        String::new()
    };
    let files = if outcome.unpaired == 1 {
        "file"
    } else {
        "files"
    };
    progress.say(&format!(
        "wrote {} of {} pairs to {} ({} already there, {} failed, {} {files} unpaired) in {}{rate}",
        outcome.written,
        total,
        plan.out.display(),
        outcome.already,
        outcome.failed,
        outcome.unpaired,
        progress::clock(started.elapsed()),
    ));
    match stopped {
        Some(why) => Err(why),
        None => Ok(outcome),
    }
}

impl Plan {
    /// Where a pair's map goes.
    fn target(&self, pair: &FramePair) -> PathBuf {
        self.out.join(format!("{}.{}", pair.name, self.extension))
    }
}

/// Why a pair made no map: the pair's own fault, or one that stops the run.
enum Failure {
    Pair(String),
    Run(String),
}

/// One pair: read, sent (again while the service is busy), written under a temporary name
/// and renamed.
async fn one_pair(transport: &mut Transport, plan: &Plan, pair: &FramePair) -> Result<(), Failure> {
    let read = |path: PathBuf| async move {
        tokio::fs::read(&path)
            .await
            .map_err(|e| Failure::Pair(format!("cannot read {}: {e}", path.display())))
    };
    let left = read(pair.left.clone()).await?;
    let right = read(pair.right.clone()).await?;
    let mut parts: Vec<(&str, Option<String>, &[u8])> = vec![
        ("left", Some(file_name(&pair.left)), &left),
        ("right", Some(file_name(&pair.right)), &right),
    ];
    if let Some((name, bytes)) = &plan.calibration {
        parts.push(("calibration", Some(name.clone()), bytes));
    }
    if let Some(unit) = &plan.calibration_unit {
        parts.push(("calibration_unit", None, unit.as_bytes()));
    }
    let (body, content_type) = multipart(&parts);
    let mut tries = 0;
    let answer: Answer = loop {
        let answer = transport
            .post(&plan.path_and_query, &content_type, body.clone())
            .await
            .map_err(Failure::Run)?;
        if answer.status == 503 && tries < RETRIES {
            tries += 1;
            let wait = Duration::from_secs(answer.retry_after.unwrap_or(1)).min(LONGEST_WAIT);
            tokio::time::sleep(wait).await;
            continue;
        }
        break answer;
    };
    if answer.status != 200 {
        return Err(refusal(&answer, pair));
    }
    let target = plan.target(pair);
    let partial = plan
        .out
        .join(format!(".{}.{}.partial", pair.name, plan.extension));
    let written = async {
        tokio::fs::write(&partial, &answer.body).await?;
        tokio::fs::rename(&partial, &target).await
    };
    written
        .await
        .map_err(|e| Failure::Run(format!("cannot write {}: {e}", target.display())))
}

/// What a refusal says, each field named by the file it is about; a refusal of the
/// calibration or of the service's state stops the run.
fn refusal(answer: &Answer, pair: &FramePair) -> Failure {
    let problem: serde_json::Value = serde_json::from_slice(&answer.body).unwrap_or_default();
    let detail = problem["detail"].as_str().unwrap_or("").to_owned();
    let mut lines = Vec::new();
    let mut about_the_run = false;
    for error in problem["errors"].as_array().into_iter().flatten() {
        let field = error["field"].as_str().unwrap_or("");
        let message = error["message"].as_str().unwrap_or("");
        let what = match field {
            "left" => pair.left.display().to_string(),
            "right" => pair.right.display().to_string(),
            other => {
                about_the_run |= !other.starts_with("left") && !other.starts_with("right");
                other.to_owned()
            }
        };
        lines.push(format!("{what}: {message}"));
    }
    let said = if lines.is_empty() {
        format!("{} {detail}", answer.status)
    } else {
        lines.join("; ")
    };
    if about_the_run && answer.status != 413 {
        Failure::Run(format!(
            "the service refused the run's settings ({}): {said}",
            answer.status
        ))
    } else {
        Failure::Pair(said)
    }
}

/// A `multipart/form-data` body of `(name, file name, bytes)` parts, and its content type.
fn multipart(parts: &[(&str, Option<String>, &[u8])]) -> (Vec<u8>, String) {
    let boundary = format!("stereo-distance-{}", uuid::Uuid::new_v4().simple());
    let mut body = Vec::with_capacity(parts.iter().map(|p| p.2.len() + 200).sum());
    for (name, file, bytes) in parts {
        body.extend_from_slice(format!("--{boundary}\r\n").as_bytes());
        match file {
            Some(file) => body.extend_from_slice(
                format!(
                    "Content-Disposition: form-data; name=\"{name}\"; filename=\"{}\"\r\n\
                     Content-Type: application/octet-stream\r\n\r\n",
                    file.replace(['"', '\r', '\n'], "_")
                )
                .as_bytes(),
            ),
            None => body.extend_from_slice(
                format!("Content-Disposition: form-data; name=\"{name}\"\r\n\r\n").as_bytes(),
            ),
        }
        body.extend_from_slice(bytes);
        body.extend_from_slice(b"\r\n");
    }
    body.extend_from_slice(format!("--{boundary}--\r\n").as_bytes());
    (body, format!("multipart/form-data; boundary={boundary}"))
}

/// The folder's PNG and JPEG files, and its other files as unpaired (folders and hidden files
/// left alone).
fn images_in(folder: &Path) -> Result<(Vec<PathBuf>, Vec<Unpaired>), String> {
    let entries = std::fs::read_dir(folder)
        .map_err(|e| format!("cannot read the folder {}: {e}", folder.display()))?;
    let (mut images, mut others) = (Vec::new(), Vec::new());
    for entry in entries.flatten() {
        let path = entry.path();
        if !path.is_file() || file_name(&path).starts_with('.') {
            continue;
        }
        if pairing::is_image(&path) {
            images.push(path);
        } else {
            others.push(Unpaired {
                path,
                reason: "not a PNG or JPEG".to_owned(),
            });
        }
    }
    Ok((images, others))
}
