//! `stereo-distance depth-map`: every pair of a recording to depth maps, as `/depth-map`
//! makes them, in this process (the engine's pipeline called directly, the calibration
//! resolved once a frame size, under the service's limits) or sent to a running service
//! (`--server`). A recording is a folder of image pairs, two folders, or a ROS bag (a ROS 2
//! MCAP file or rosbag2 folder, a ROS 1 bag: [`bag`]), and the maps go to a folder, one file
//! a pair, or into an MCAP file of ROS 2 messages ([`sink`]). Pairs already written to a
//! folder are skipped, so a stopped run resumes; each file is written once, under a temporary
//! name renamed when whole, when its answer arrives.
//!
//! What goes wrong is told apart: a fault in the run's settings (the calibration, the range,
//! the output, a topic) stops the run before the first frame is sent; a frame that cannot be
//! read, or that the service refuses by its parts (a 422 naming `left` or `right`), is named
//! with its reason and the rest go on; a service that restarts, refuses connections or
//! answers 502, 503 or 504 is waited for (`--retries`, with backoff and jitter, or its
//! `Retry-After`), and only one that stays away stops the run. The service's warnings are
//! printed once each, and grouped at the end; `--strict` makes a warned pair a failed one.
//!
//! - [`source`]: what a run reads, and the feed of its pairs to the workers; [`work`], a pair
//!   and what a worker says about it;
//! - [`pairing`]: which files make a pair (by name, as the page pairs them);
//! - [`bag`]: which frames of a bag make a pair (by stamp), and its CameraInfo;
//! - [`preflight`]: the run's settings checked before the first frame;
//! - [`matching`]: a pair matched here or by the service, and written;
//! - [`engine`]: the engine in this process, the calibration resolved once a frame size;
//! - [`transport`]: HTTP/1.1 to a running service, and [`send`], a pair sent over it;
//! - [`retry`]: when and after how long a frame is sent again;
//! - [`sink`]: where the maps go, a folder or an MCAP file;
//! - [`said`]: the warnings, once each and grouped;
//! - [`progress`]: the bar on a terminal, plain lines elsewhere.

pub mod bag;
pub mod engine;
pub mod matching;
pub mod pairing;
pub mod preflight;
pub mod progress;
pub mod retry;
pub mod said;
pub mod send;
pub mod sink;
pub mod source;
pub mod transport;
pub mod work;

use std::io::IsTerminal;
use std::process::ExitCode;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use engine::Engine;
use matching::{Transport, one_pair};
use progress::Progress;
use retry::Policy;
use said::Said;
use send::Form;
use sink::Sink;
use source::{feed, recording};
use transport::Server;
use work::{Event, Failure};

use crate::api::wire::depth_map::DepthMapOutput;
use crate::config::{Config, DepthMapArgs};

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

/// The run itself, reporting into `out` (a bar when `bar`). `Err` is what stopped it.
pub async fn depth_maps<W: std::io::Write>(
    config: Config,
    args: DepthMapArgs,
    out: W,
    bar: bool,
) -> Result<Outcome, String> {
    let recording = recording(&args)?;
    let mcap = sink::is_mcap(&args.out);
    if mcap && args.output.is_some() {
        return Err(format!(
            "--output names a file a pair; --out {} is an MCAP file of ROS 2 messages (leave \
             --output out, or give a folder)",
            args.out.display()
        ));
    }
    if mcap && args.server.is_some() {
        return Err(
            "--out .mcap is written by the engine in this process: leave --server out, or give \
             a folder"
                .to_owned(),
        );
    }
    let output = args.output.clone().unwrap_or_else(|| {
        if recording.rig.is_some() || mcap {
            "depth.npy"
        } else {
            "disparity.npy"
        }
        .to_owned()
    });
    let rig = preflight::check(&args, &output, recording.rig.as_ref())?;
    let sink = if mcap {
        if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)
                .map_err(|e| format!("cannot make the folder {}: {e}", parent.display()))?;
        }
        Sink::Mcap {
            file: Mutex::new(sink::Ordered::create(&args.out)?),
            path: args.out.clone(),
            namespace: recording.namespace.clone(),
        }
    } else {
        std::fs::create_dir_all(&args.out)
            .map_err(|e| format!("cannot make the folder {}: {e}", args.out.display()))?;
        Sink::Folder {
            out: args.out.clone(),
            extension: if output == "summary" {
                "json".to_owned()
            } else {
                output.clone()
            },
        }
    };
    let mut query = format!("/depth-map?output={output}");
    for (name, value) in [
        ("preset", args.preset.clone()),
        ("min_disparity", args.min_disparity.map(|d| d.to_string())),
        ("max_disparity", args.max_disparity.map(|d| d.to_string())),
        (
            "max_disparity_std",
            args.max_disparity_std.map(|s| s.to_string()),
        ),
        ("projection", args.projection.clone()),
    ] {
        if let Some(value) = value {
            query.push_str(&format!("&{name}={value}"));
        }
    }
    let form = Arc::new(Form {
        path_and_query: query,
        parts: recording
            .rig
            .as_ref()
            .map(|r| r.parts.clone())
            .unwrap_or_default(),
        policy: Policy {
            retries: args.retries.unwrap_or(retry::DEFAULT_RETRIES),
        },
        strict: args.strict,
    });
    let sink = Arc::new(sink);

    let names = recording.pairs.names();
    let done: std::collections::HashSet<String> = names
        .iter()
        .filter(|n| sink.target(n).is_some_and(|t| t.exists()))
        .cloned()
        .collect();
    let total = names.len() - done.len();
    let mut progress = Progress::new(out, bar, total);
    if let Some(about) = &recording.about {
        progress.say(about);
    }
    for (what, why) in &recording.unpaired {
        progress.say(&format!("skipped {what}: {why}"));
    }
    if !done.is_empty() {
        progress.say(&format!(
            "{} of {} pairs already written in {}: skipped",
            done.len(),
            names.len(),
            sink.place().display()
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
                (preflight::settings(&args), preflight::latlon(&args)),
                rig,
            )))
        }
    };
    let jobs = args.jobs.unwrap_or(2).clamp(1, total.max(1));
    let feed = Arc::new(feed(recording.pairs, &done, jobs));
    let (sender, mut events) = tokio::sync::mpsc::channel(jobs * 4);
    let started = Instant::now();
    let mut workers = Vec::new();
    for _ in 0..jobs {
        let (feed, form, sink, sender, mut transport) = (
            feed.clone(),
            form.clone(),
            sink.clone(),
            sender.clone(),
            transport.clone(),
        );
        workers.push(tokio::spawn(async move {
            while let Some(work) = feed.next().await {
                let (seq, name) = (work.pair.seq, work.pair.name.clone());
                let (warnings, result) =
                    one_pair(&mut transport, &form, &sink, work, &sender).await;
                let done = Event::Done {
                    seq,
                    name,
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
        already: done.len(),
        unpaired: recording.unpaired.len(),
        ..Outcome::default()
    };
    let mut said = Said::default();
    let mut stopped = None;
    while let Some(event) = events.recv().await {
        let (name, warnings, result) = match event {
            Event::Waiting(why) => {
                if bar {
                    progress.waiting(why);
                } else {
                    progress.say(&format!("waiting: {why}"));
                }
                continue;
            }
            Event::Done {
                seq,
                name,
                warnings,
                result,
            } => {
                if result.is_err() {
                    // The MCAP output writes in the run's order: a failed pair is passed.
                    if let Err(why) = sink.messages(seq, None) {
                        stopped = Some(why);
                        break;
                    }
                }
                (name, warnings, result)
            }
        };
        for line in said.add(&name, &warnings) {
            progress.say(&line);
        }
        match result {
            Ok(()) => {
                outcome.written += 1;
                progress.finished(true);
            }
            Err(Failure::Pair(why)) => {
                outcome.failed += 1;
                progress.say(&format!("failed {name}: {why}"));
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
    if let Err(why) = sink.close() {
        stopped.get_or_insert(why);
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
    let (left_out, files) = match (&recording.about, outcome.unpaired) {
        (Some(_), 1) => ("frame", "unpaired"),
        (Some(_), _) => ("frames", "unpaired"),
        (None, 1) => ("file", "unpaired"),
        (None, _) => ("files", "unpaired"),
    };
    progress.say(&format!(
        "wrote {} of {} pairs to {} ({} already there, {} failed, {} {left_out} {files}) in {}{rate}",
        outcome.written,
        total,
        sink.place().display(),
        outcome.already,
        outcome.failed,
        outcome.unpaired,
        progress::clock(started.elapsed()),
    ));
    if let (Some(cut), None) = (&recording.cut, &stopped) {
        stopped = Some(format!(
            "{cut}: the {} pairs before it were processed",
            outcome.written + outcome.already
        ));
    }
    match stopped {
        Some(why) => Err(why),
        None => Ok(outcome),
    }
}
