//! One stream's socket: the settings message, then frames read as fast as they come (the
//! newest waiting, older ones dropped) while up to two are matched on blocking threads, and
//! answers, in the frames' order,
//! handed to a writer that drops those its client has not read and gives up on a client that
//! reads nothing for the write timeout.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use axum::body::Bytes;
use axum::extract::ws::{CloseFrame, Message, WebSocket};
use futures_util::stream::{FuturesUnordered, SplitSink, SplitStream};
use futures_util::{SinkExt, StreamExt};
use tokio::sync::mpsc::{self, error::TrySendError};
use tokio::task::JoinHandle;
use tokio::time::{Instant, sleep, sleep_until, timeout};

use crate::api::error::ApiError;
use crate::api::images::HeavyState;
use crate::api::images::pools::FramePools;
use crate::api::images::stream::{Done, Engine, Frame, Resolved, Streams};
use crate::api::wire::depth_stream::{FrameAnswer, FrameError, StreamSettings};
use crate::budget::{Reservation, Slot, Slots};

/// What a stream holds for its life: its place among the open streams and its frame limit
/// in the budget.
type Admission = (Slot, Reservation);

/// An answer on its way to the writer: its messages, and the budget its bytes hold.
struct Outgoing(Vec<Message>, Option<Reservation>);

/// What the socket brought.
enum Incoming {
    Text(String),
    Binary(Bytes),
    /// The client closed the stream or went away.
    Gone,
    /// A message over the frame limit.
    TooLarge,
}

/// The answers' side of a stream: the channel to the writer and what was dropped.
struct Replies {
    out: mpsc::Sender<Outgoing>,
    dropped_frames: u64,
    dropped_answers: u64,
    write_timeout: Duration,
}

/// The answers that may wait for the writer, besides the one it is writing: one for each
/// frame in work, so that a client that reads as fast as it sends loses none; past them, an
/// answer is dropped.
const ANSWERS_WAITING: usize = IN_WORK;

/// How long a frame waits for a compute slot before it looks again.
const SLOT_POLL: Duration = Duration::from_millis(5);

/// Runs a stream until its client closes it, goes silent or stops reading.
pub async fn run(socket: WebSocket, state: HeavyState, admission: Admission) {
    let (sink, mut incoming) = socket.split();
    let streams = state.streams.clone();
    let (out, rx) = mpsc::channel(ANSWERS_WAITING);
    let writer = tokio::spawn(write(sink, rx, streams.write_timeout));
    let mut replies = Replies {
        out,
        dropped_frames: 0,
        dropped_answers: 0,
        write_timeout: streams.write_timeout,
    };
    let first = timeout(streams.idle_timeout, next(&mut incoming)).await;
    let resolved = match first {
        Ok(Incoming::Text(text)) => settings(&text, &state, &mut replies).await,
        Ok(Incoming::Binary(_)) => {
            let e = ApiError::invalid(
                "settings",
                "must come first, as a text message: the frames follow it",
            );
            replies.fail(e, 1003, "settings first").await;
            None
        }
        Ok(Incoming::TooLarge) => {
            replies.close(1009, "a message over the frame limit").await;
            None
        }
        Ok(Incoming::Gone) => None,
        Err(_) => {
            replies
                .close(1001, "no settings within the idle timeout")
                .await;
            None
        }
    };
    if let Some(resolved) = resolved {
        frames(&mut incoming, resolved, &state, &mut replies).await;
    }
    drop(replies);
    let _ = writer.await;
    drop(admission);
}

/// The settings message answered: the settings as resolved, or the problem and a close.
async fn settings(text: &str, state: &HeavyState, replies: &mut Replies) -> Option<Arc<Resolved>> {
    let resolved =
        StreamSettings::parse(text).and_then(|settings| Resolved::of(settings, &state.streams));
    match resolved {
        Ok((resolved, answer)) => {
            let text = serde_json::to_string(&answer).unwrap_or_default();
            replies
                .send(Outgoing(vec![Message::text(text)], None))
                .await;
            Some(Arc::new(resolved))
        }
        Err(problems) => {
            replies
                .fail(problems.into_error(), 1008, "invalid settings")
                .await;
            None
        }
    }
}

/// The frames, until the stream ends: each read as it comes, the newest kept while others are
/// matched, each answer offered to the writer in the frames' order.
async fn frames(
    incoming: &mut SplitStream<WebSocket>,
    resolved: Arc<Resolved>,
    state: &HeavyState,
    replies: &mut Replies,
) {
    let streams = &state.streams;
    let engine = Engine::new(
        resolved,
        streams.budget.clone(),
        Arc::clone(&state.maps),
        state.image_limits,
    );
    let mut work = InWork::new(engine, Arc::clone(&streams.pools));
    let (mut received, mut heard) = (0u64, Instant::now());
    let out = replies.out.clone();
    loop {
        work.start(&state.slots);
        tokio::select! {
            message = next(incoming) => {
                heard = Instant::now();
                match message {
                    Incoming::Binary(bytes) => {
                        received += 1;
                        replies.arrive(received, bytes, &mut work.pending, streams);
                    }
                    Incoming::Text(_) => replies.offer_error(received, ApiError::invalid(
                        "message",
                        "frames are binary messages; the settings come once, first",
                    )),
                    Incoming::Gone => break,
                    Incoming::TooLarge => {
                        replies.close(1009, "a frame over the frame limit").await;
                        break;
                    }
                }
            }
            Some(joined) = work.running.next(), if !work.running.is_empty() => {
                let Ok(finished) = joined else {
                    replies.close(1011, "the frame's work failed").await;
                    break;
                };
                for (id, result) in work.finished(finished) {
                    replies.answer(id, result);
                }
                heard = Instant::now();
            }
            () = sleep(SLOT_POLL), if work.waiting() => {}
            () = sleep_until(heard + streams.idle_timeout) => {
                replies.close(1001, "idle past the idle timeout").await;
                break;
            }
            () = out.closed() => break,
        }
    }
}

/// The most frames of one stream in work at once: one matched while the next is decoded and
/// matched beside it, as two requests in flight are.
const IN_WORK: usize = 2;

/// A frame's work as it ends: its place in the order work started, its id, its answer.
type Finished = (u64, u64, Result<Done, ApiError>);

/// The frames of a stream between their arrival and their answers: the newest waiting, at
/// most [`IN_WORK`] on blocking threads (each matched in a pool of its own when one is free,
/// [`FramePools`]), and the answers that ended before an earlier one held back until it has.
struct InWork {
    engine: Arc<Engine>,
    pools: Arc<FramePools>,
    cancel: Arc<AtomicBool>,
    pending: Option<Frame>,
    running: FuturesUnordered<JoinHandle<Finished>>,
    started: u64,
    ready: BTreeMap<u64, (u64, Result<Done, ApiError>)>,
    next_out: u64,
}

impl InWork {
    fn new(engine: Engine, pools: Arc<FramePools>) -> Self {
        InWork {
            engine: Arc::new(engine),
            pools,
            cancel: Arc::new(AtomicBool::new(false)),
            pending: None,
            running: FuturesUnordered::new(),
            started: 0,
            ready: BTreeMap::new(),
            next_out: 0,
        }
    }

    /// Starts the waiting frame's work when there is room and a compute slot is free (else it
    /// keeps waiting, and may be replaced by a newer one).
    fn start(&mut self, slots: &Slots) {
        if self.running.len() >= IN_WORK || self.pending.is_none() {
            return;
        }
        let Some(slot) = slots.take() else {
            return;
        };
        let Some(frame) = self.pending.take() else {
            return;
        };
        let seq = self.started;
        self.started += 1;
        let (engine, cancel) = (Arc::clone(&self.engine), Arc::clone(&self.cancel));
        let pools = Arc::clone(&self.pools);
        self.running.push(tokio::task::spawn_blocking(move || {
            let _slot = slot;
            let result = pools.run(|| engine.frame(&frame, seq, &cancel));
            (seq, frame.id, result)
        }));
    }

    /// Whether a frame waits for a compute slot.
    fn waiting(&self) -> bool {
        self.pending.is_some() && self.running.len() < IN_WORK
    }

    /// A frame's work ended: the answers now due, in order.
    fn finished(&mut self, (seq, id, result): Finished) -> Vec<(u64, Result<Done, ApiError>)> {
        self.ready.insert(seq, (id, result));
        let mut due = Vec::new();
        while let Some(answer) = self.ready.remove(&self.next_out) {
            due.push(answer);
            self.next_out += 1;
        }
        due
    }
}

impl Drop for InWork {
    /// The stream ended: the work still running stops at its next check.
    fn drop(&mut self) {
        self.cancel.store(true, Ordering::Relaxed);
    }
}

impl Replies {
    /// A frame arrived: its bytes reserved (an error answer when the budget is held), then
    /// kept as the newest, the one it replaces counted as dropped.
    fn arrive(&mut self, id: u64, bytes: Bytes, pending: &mut Option<Frame>, streams: &Streams) {
        match streams.budget.reserve(bytes.len()) {
            Ok(held) => {
                let frame = Frame {
                    id,
                    bytes,
                    arrived: std::time::Instant::now(),
                    held,
                };
                if pending.replace(frame).is_some() {
                    self.dropped_frames += 1;
                }
            }
            Err(refusal) => self.offer_error(id, ApiError::Memory(refusal)),
        }
    }

    /// A frame's answer (the JSON, then each file) or its error, offered to the writer.
    fn answer(&mut self, id: u64, result: Result<Done, ApiError>) {
        let done = match result {
            Ok(done) => done,
            Err(e) => return self.offer_error(id, e),
        };
        let (files, bytes): (Vec<_>, Vec<_>) = done.files.into_iter().unzip();
        let answer = FrameAnswer {
            kind: "frame",
            id,
            dropped_frames: self.dropped_frames,
            dropped_answers: self.dropped_answers,
            times_ms: done.times,
            summary: done.summary,
            temporal: done.temporal,
            calibration_check: done.calibration,
            files,
        };
        let text = serde_json::to_string(&answer).unwrap_or_default();
        let mut messages = Vec::with_capacity(bytes.len() + 1);
        messages.push(Message::text(text));
        messages.extend(bytes.into_iter().map(Message::binary));
        self.offer(Outgoing(messages, Some(done.held)));
    }

    fn error_message(&self, id: u64, e: &ApiError) -> Message {
        let error = FrameError {
            kind: "error",
            id,
            dropped_frames: self.dropped_frames,
            dropped_answers: self.dropped_answers,
            problem: e.problem(),
        };
        Message::text(serde_json::to_string(&error).unwrap_or_default())
    }

    fn offer_error(&mut self, id: u64, e: ApiError) {
        let message = self.error_message(id, &e);
        self.offer(Outgoing(vec![message], None));
    }

    /// Hands an answer to the writer, or drops it when those before it are still unsent.
    fn offer(&mut self, outgoing: Outgoing) {
        if let Err(TrySendError::Full(_)) = self.out.try_send(outgoing) {
            self.dropped_answers += 1;
        }
    }

    /// Sends an answer, waiting for the writer (at most the write timeout).
    async fn send(&self, outgoing: Outgoing) {
        let _ = timeout(self.write_timeout, self.out.send(outgoing)).await;
    }

    /// An error about the stream itself, then a close with `code`.
    async fn fail(&self, e: ApiError, code: u16, reason: &'static str) {
        let message = self.error_message(0, &e);
        self.send(Outgoing(vec![message], None)).await;
        self.close(code, reason).await;
    }

    async fn close(&self, code: u16, reason: &'static str) {
        let frame = CloseFrame {
            code,
            reason: reason.into(),
        };
        self.send(Outgoing(vec![Message::Close(Some(frame))], None))
            .await;
    }
}

/// The next message that matters: pings and pongs are answered by the socket itself.
async fn next(incoming: &mut SplitStream<WebSocket>) -> Incoming {
    loop {
        return match incoming.next().await {
            Some(Ok(Message::Text(text))) => Incoming::Text(text.as_str().to_owned()),
            Some(Ok(Message::Binary(bytes))) => Incoming::Binary(bytes),
            Some(Ok(Message::Ping(_) | Message::Pong(_))) => continue,
            Some(Ok(Message::Close(_))) | None => Incoming::Gone,
            Some(Err(e)) if e.to_string().contains("too long") => Incoming::TooLarge,
            Some(Err(_)) => Incoming::Gone,
        };
    }
}

/// Writes each answer whole, giving up (and so closing the socket) when one stays unsent for
/// the write timeout; the budget an answer holds is given back once it is written.
async fn write(
    mut sink: SplitSink<WebSocket, Message>,
    mut answers: mpsc::Receiver<Outgoing>,
    limit: Duration,
) {
    while let Some(Outgoing(messages, held)) = answers.recv().await {
        let sent = timeout(limit, async {
            for message in messages {
                sink.feed(message).await?;
            }
            sink.flush().await
        })
        .await;
        drop(held);
        if !matches!(sent, Ok(Ok(()))) {
            return;
        }
    }
    let _ = timeout(limit, sink.close()).await;
}
