//! `stereo-distance depth-map`: every pair of a recording's folder(s) to depth maps, as
//! `/depth-map` makes them, in this process (the engine's pipeline called directly, the
//! calibration resolved once a frame size, under the service's limits) or sent to a running
//! service (`--server`). Pairs already
//! written are skipped, so a stopped run resumes; each file is written once, under a
//! temporary name renamed when whole, when its answer arrives.
//!
//! What goes wrong is told apart: a fault in the run's settings (the calibration, the range,
//! the output) stops the run before the first frame is sent; a frame that cannot be read, or
//! that the service refuses by its parts (a 422 naming `left` or `right`), is named with its
//! reason and the rest go on; a service that restarts, refuses connections or answers 502,
//! 503 or 504 is waited for (`--retries`, with backoff and jitter, or its `Retry-After`), and
//! only one that stays away stops the run. The service's warnings are printed once each, and
//! grouped at the end; `--strict` makes a warned pair a failed one.
//!
//! - [`pairing`]: which files make a pair (by name, as the page pairs them);
//! - [`preflight`]: the run's settings checked before the first frame;
//! - [`engine`]: the engine in this process, the calibration resolved once a frame size;
//! - [`transport`]: HTTP/1.1 to a running service;
//! - [`retry`]: when and after how long a frame is sent again;
//! - [`said`]: the warnings, once each and grouped;
//! - [`progress`]: the bar on a terminal, plain lines elsewhere.

pub mod engine;
pub mod pairing;
pub mod preflight;
pub mod progress;
pub mod retry;
pub mod said;
pub mod transport;

use std::collections::VecDeque;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use engine::Engine;
use pairing::{FramePair, Unpaired, file_name};
use progress::Progress;
use retry::Policy;
use said::Said;
use transport::{Answer, Server};

use crate::api::wire::depth_map::DepthMapOutput;
use crate::config::{Config, DepthMapArgs};

/// Where a run's pairs are matched.
#[derive(Clone)]
enum Transport {
    /// The engine, in this process.
    InProcess(Arc<Engine>),
    /// A running service, over HTTP/1.1.
    Http(Server),
}

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
    policy: Policy,
    strict: bool,
}

/// What a worker tells the run: that it waits to send a frame again, or how a pair ended
/// (with the service's warnings about it).
enum Event {
    Waiting(String),
    Done {
        pair: FramePair,
        warnings: Vec<String>,
        result: Result<(), Failure>,
    },
}

/// The run itself, reporting into `out` (a bar when `bar`). `Err` is what stopped it.
pub async fn depth_maps<W: std::io::Write>(
    config: Config,
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
    let rig = preflight::check(
        &args,
        &output,
        calibration.as_ref(),
        pairs.iter().map(|p| p.left.as_path()),
    )?;
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
            output.clone()
        },
        policy: Policy {
            retries: args.retries.unwrap_or(retry::DEFAULT_RETRIES),
        },
        strict: args.strict,
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
        Some(url) => Transport::Http(Server::parse(url)?.with_token(args.token.clone())),
        None => {
            let output = serde_json::from_value::<DepthMapOutput>(output.as_str().into())
                .map_err(|e| format!("--output {output}: {e}"))?;
            Transport::InProcess(Arc::new(Engine::new(
                &config,
                output,
                preflight::settings(&args),
                rig,
            )))
        }
    };
    let jobs = args.jobs.unwrap_or(2).clamp(1, todo.len().max(1));
    let total = todo.len();
    let queue = Arc::new(Mutex::new(VecDeque::from(todo)));
    let (sender, mut events) = tokio::sync::mpsc::channel(jobs * 4);
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
                let (warnings, result) = one_pair(&mut transport, &plan, &pair, &sender).await;
                let done = Event::Done {
                    pair,
                    warnings,
                    result,
                };
                if sender.send(done).await.is_err() {
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
    let mut said = Said::default();
    let mut stopped = None;
    while let Some(event) = events.recv().await {
        let (pair, warnings, result) = match event {
            Event::Waiting(why) => {
                if bar {
                    progress.waiting(why);
                } else {
                    progress.say(&format!("waiting: {why}"));
                }
                continue;
            }
            Event::Done {
                pair,
                warnings,
                result,
            } => (pair, warnings, result),
        };
        for line in said.add(&pair.name, &warnings) {
            progress.say(&line);
        }
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
    for line in said.summary() {
        progress.say(&line);
    }
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

/// One pair: read, sent (again, after a wait, while the service cannot be reached or is
/// unavailable), and written under a temporary name and renamed when its answer arrives.
/// Gives the service's warnings with the result.
async fn one_pair(
    transport: &mut Transport,
    plan: &Plan,
    pair: &FramePair,
    events: &tokio::sync::mpsc::Sender<Event>,
) -> (Vec<String>, Result<(), Failure>) {
    let read = |path: PathBuf| async move {
        tokio::fs::read(&path)
            .await
            .map_err(|e| Failure::Pair(format!("cannot read {}: {e}", path.display())))
    };
    let (left, right) = match (
        read(pair.left.clone()).await,
        read(pair.right.clone()).await,
    ) {
        (Ok(left), Ok(right)) => (left, right),
        (Err(e), _) | (_, Err(e)) => return (Vec::new(), Err(e)),
    };
    let server = match transport {
        Transport::Http(server) => server,
        Transport::InProcess(engine) => {
            let (engine, files) = (engine.clone(), (pair.left.clone(), pair.right.clone()));
            let made = tokio::task::spawn_blocking(move || {
                engine.depth_map((&files.0, &files.1), [&left, &right])
            })
            .await
            .unwrap_or_else(|e| Err(format!("the engine failed: {e}")));
            return match made {
                Ok((bytes, warnings)) => {
                    let result = write(plan, pair, &warnings, &bytes).await;
                    (warnings, result)
                }
                Err(why) => (Vec::new(), Err(Failure::Pair(why))),
            };
        }
    };
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
    let mut retry = 0;
    let answer: Answer = loop {
        let (why, asked) = match server
            .post(&plan.path_and_query, &content_type, body.clone())
            .await
        {
            Ok(answer) if retry::retried_status(answer.status) => (
                format!("the service answered {}", status_words(answer.status)),
                answer.retry_after,
            ),
            Ok(answer) => break answer,
            Err(unreachable) => (unreachable, None),
        };
        retry += 1;
        let jitter = f64::from(uuid::Uuid::new_v4().as_u128() as u32) / f64::from(u32::MAX);
        let Some(wait) = plan.policy.wait(retry, asked, jitter) else {
            let tries = if retry == 1 {
                "on the only try".to_owned()
            } else {
                format!("on each of {retry} tries")
            };
            return (
                Vec::new(),
                Err(Failure::Run(format!(
                    "{why}, {tries} (--retries {})",
                    plan.policy.retries
                ))),
            );
        };
        let _ = events
            .send(Event::Waiting(format!(
                "{why}; sending {} again in {:.1} s (retry {retry} of {})",
                pair.name,
                wait.as_secs_f64(),
                plan.policy.retries
            )))
            .await;
        tokio::time::sleep(wait).await;
    };
    let warnings = answer.warnings.clone();
    if answer.status != 200 {
        return (warnings, Err(refusal(&answer, pair)));
    }
    let result = write(plan, pair, &warnings, &answer.body).await;
    (warnings, result)
}

/// A pair's file written under a temporary name and renamed when whole; under `--strict`, a
/// pair the service warned about is failed instead.
async fn write(
    plan: &Plan,
    pair: &FramePair,
    warnings: &[String],
    bytes: &[u8],
) -> Result<(), Failure> {
    if plan.strict && !warnings.is_empty() {
        return Err(Failure::Pair(
            "the service warned about it (--strict): not written".to_owned(),
        ));
    }
    let target = plan.target(pair);
    let partial = plan
        .out
        .join(format!(".{}.{}.partial", pair.name, plan.extension));
    let written = async {
        tokio::fs::write(&partial, bytes).await?;
        tokio::fs::rename(&partial, &target).await
    };
    written
        .await
        .map_err(|e| Failure::Run(format!("cannot write {}: {e}", target.display())))
}

fn status_words(status: u16) -> String {
    let reason = axum::http::StatusCode::from_u16(status)
        .ok()
        .and_then(|s| s.canonical_reason())
        .unwrap_or("");
    format!("{status} {reason}").trim_end().to_owned()
}

/// What a refusal says, each part named by the file it is about. The run's settings were
/// checked before the first frame, so a 422 or 413 is the pair's (an image that cannot be
/// read, a frame of another size); so is a 500 or a timeout of this frame's work. A refused
/// token (401, 403) or a request the service does not take (400, 404, 405, 415) would refuse
/// every frame alike: they stop the run.
fn refusal(answer: &Answer, pair: &FramePair) -> Failure {
    let problem: serde_json::Value = serde_json::from_slice(&answer.body).unwrap_or_default();
    let detail = problem["detail"].as_str().unwrap_or("").to_owned();
    let mut lines = Vec::new();
    for error in problem["errors"].as_array().into_iter().flatten() {
        let field = error["field"].as_str().unwrap_or("");
        let message = error["message"].as_str().unwrap_or("");
        let what = match field {
            "left" => pair.left.display().to_string(),
            "right" => pair.right.display().to_string(),
            other => other.to_owned(),
        };
        lines.push(format!("{what}: {message}"));
    }
    let said = if lines.is_empty() {
        format!("{} {detail}", status_words(answer.status))
            .trim_end()
            .to_owned()
    } else {
        lines.join("; ")
    };
    match answer.status {
        400..=407 | 409..=412 | 414..=421 => Failure::Run(format!(
            "the service refused the run ({}): {said}",
            status_words(answer.status)
        )),
        _ => Failure::Pair(said),
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
