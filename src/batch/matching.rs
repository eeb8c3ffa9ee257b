//! A pair matched: its frames read, matched by the engine in this process or sent to the
//! service, and its map written where the run's maps go; its warnings with the result.

use std::path::PathBuf;
use std::sync::Arc;

use stereo_ros::msg::Header;

use super::engine::{Engine, Frame};
use super::send::{self, Form};
use super::sink::Sink;
use super::transport::Server;
use super::work::{Event, Failure, Input, Pair, Work};

/// Where a run's pairs are matched.
#[derive(Clone)]
pub enum Transport {
    /// The engine, in this process.
    InProcess(Arc<Engine>),
    /// A running service, over HTTP/1.1.
    Http(Server),
}

/// One pair: its frames read, matched here or sent to the service, and its map written.
/// Gives the service's warnings with the result.
pub async fn one_pair(
    transport: &mut Transport,
    form: &Form,
    sink: &Arc<Sink>,
    work: Work,
    events: &tokio::sync::mpsc::Sender<Event>,
) -> (Vec<String>, Result<(), Failure>) {
    let Work { pair, input } = work;
    let (frames, header) = match input {
        Input::Broken(why) => return (Vec::new(), Err(Failure::Pair(why))),
        Input::Files(left, right, header) => {
            let read = |path: PathBuf| async move {
                tokio::fs::read(&path)
                    .await
                    .map_err(|e| Failure::Pair(format!("cannot read {}: {e}", path.display())))
            };
            match (read(left).await, read(right).await) {
                (Ok(l), Ok(r)) => ([Frame::File(l), Frame::File(r)], header),
                (Err(e), _) | (_, Err(e)) => return (Vec::new(), Err(e)),
            }
        }
        Input::Frames(frames, header) => (*frames, header),
    };
    matched(transport, form, sink, &pair, frames, header, events).await
}

/// A pair's frames matched (here or by the service) and its map written.
async fn matched(
    transport: &mut Transport,
    form: &Form,
    sink: &Arc<Sink>,
    work: &Pair,
    frames: [Frame; 2],
    header: Header,
    events: &tokio::sync::mpsc::Sender<Event>,
) -> (Vec<String>, Result<(), Failure>) {
    let engine = match transport {
        Transport::Http(server) => {
            return match send::send(server, form, work, frames, events).await {
                Ok(answer) if form.strict && !answer.warnings.is_empty() => {
                    (answer.warnings, Err(warned()))
                }
                Ok(answer) => {
                    let result = sink
                        .file(&work.name, &answer.body)
                        .await
                        .map_err(Failure::Run);
                    (answer.warnings, result)
                }
                Err(failure) => (Vec::new(), Err(failure)),
            };
        }
        Transport::InProcess(engine) => engine.clone(),
    };
    let names = work.names.clone();
    let ros = matches!(**sink, Sink::Mcap { .. });
    let (sink_ros, header, strict, seq) = (sink.clone(), header, form.strict, work.seq);
    // A pair that could not be matched is its own fault; a write that failed stops the run.
    let made = tokio::task::spawn_blocking(move || {
        let names = [names[0].as_str(), names[1].as_str()];
        let frames = [&frames[0], &frames[1]];
        if !ros {
            return engine.depth_map(names, frames).map_err(Failure::Pair);
        }
        let map = engine.ros_map(names, frames).map_err(Failure::Pair)?;
        if !strict || map.warnings.is_empty() {
            sink_ros
                .messages(seq, Some((&map, &header)))
                .map_err(Failure::Run)?;
        }
        Ok((Vec::new(), map.warnings))
    })
    .await
    .unwrap_or_else(|e| Err(Failure::Pair(format!("the engine failed: {e}"))));
    match made {
        Ok((_, warnings)) if strict && !warnings.is_empty() => (warnings, Err(warned())),
        Ok((_, warnings)) if ros => (warnings, Ok(())),
        Ok((bytes, warnings)) => {
            let result = sink.file(&work.name, &bytes).await.map_err(Failure::Run);
            (warnings, result)
        }
        Err(failure) => (Vec::new(), Err(failure)),
    }
}

/// A pair the service warned about, under `--strict`.
fn warned() -> Failure {
    Failure::Pair("the service warned about it (--strict): not written".to_owned())
}
