//! What the depth streams (`/depth-stream`) share and are held to, and a stream's work between
//! the socket and the engine: its settings resolved once ([`Resolved`], the rig parsed once),
//! then each frame ([`Engine::frame`]) read in its layout, the depth job planned once a frame
//! size, the memory reserved before anything is decoded, [`pipeline::matched`], the temporal
//! filter in the frames' order, [`Matched::depth_map`], and the files asked for. Two frames
//! may be matched side by side; only the filter takes them one at a time. The socket, the
//! queue and the drops are the route's.

use std::collections::{BTreeSet, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use axum::body::Bytes;

use super::limits;
use super::maps::MapCache;
use super::parts::Parts;
use super::pools::{FramePools, lock};
use super::stream_frames::{files, in_frame, odd_width, pair_parts};
use super::{job, rig, work};
use crate::api::error::{ApiError, FieldError, FieldErrors};
use crate::api::wire::depth_map::{
    DepthMapOutput, DepthMapQuery, DepthMapSummary, MatcherParameters,
};
use crate::api::wire::depth_stream::{
    CalibrationWatch, FileAnswer, FrameTimes, Layout, SettingsAnswer, StreamLimitsAnswer,
    StreamSettings, TemporalCounts,
};
use crate::api::wire::images::RectifyMode;
use crate::api::wire::rig::CalibratedRig;
use crate::budget::{MemoryBudget, Refusal, Reservation, Slots};
use stereo_core::camera::LatlonOptions;
use stereo_core::pipeline::check::{self, Watch};
use stereo_core::pipeline::{
    self, Answer, Chosen, DepthJob, Maps, Matched, RangeUsed, Request, RigInput, Sent,
};
use stereo_core::vision::decode::{self, DecodeLimits, Decoded};
use stereo_core::vision::sparse::SparseMatch;
use stereo_core::vision::temporal::{self, Temporal};
use stereo_core::vision::{Params, Preset, Settings};

/// The streams' limits and what they share.
#[derive(Debug, Clone)]
pub struct Streams {
    /// The heavy group's memory budget, which the streams reserve from like requests.
    pub budget: MemoryBudget,
    /// The streams open at once (`--max-streams`): a slot each for its life.
    pub open: Slots,
    /// A stream that sends nothing for this long is closed (`--stream-idle-timeout`).
    pub idle_timeout: Duration,
    /// A stream whose client leaves an answer unread for this long is closed
    /// (`--write-timeout`).
    pub write_timeout: Duration,
    /// The largest frame message (`--stream-frame-limit`).
    pub max_frame_bytes: usize,
    /// The pools the streams' frames in work are matched in, one a frame.
    pub pools: Arc<FramePools>,
}

impl Default for Streams {
    fn default() -> Self {
        Self {
            budget: MemoryBudget::new(crate::config::DEFAULT_HEAVY_MEMORY_BUDGET),
            open: Slots::new(crate::config::DEFAULT_MAX_STREAMS),
            idle_timeout: crate::config::DEFAULT_STREAM_IDLE_TIMEOUT,
            write_timeout: crate::config::DEFAULT_WRITE_TIMEOUT,
            max_frame_bytes: crate::config::DEFAULT_STREAM_FRAME_LIMIT,
            pools: Arc::default(),
        }
    }
}

/// A stream's settings, checked once at its start.
#[derive(Debug)]
pub struct Resolved {
    pub layout: Layout,
    /// The matcher's settings as asked (the `fast` preset unless another is given), the job
    /// planned with them at each frame size.
    pub settings: Settings,
    /// The matcher's parameters as the settings answer gave them.
    pub params: Params,
    /// The files each answer carries, in order.
    pub outputs: Vec<DepthMapOutput>,
    /// The rig as the settings sent it, parsed once, made the rig of each frame size.
    pub input: RigInput,
    pub rectify: (Option<RectifyMode>, Option<f64>),
    /// Rectified to latitude-longitude with these (`options.projection`), or `None`.
    pub latlon: Option<LatlonOptions>,
    pub temporal: Option<temporal::Settings>,
    /// Whether a file asked for needs the left image's colour.
    pub colour: bool,
    /// Whether a file asked for needs each depth's σ_Z.
    pub depth_std: bool,
}

impl Resolved {
    /// The settings message's members judged together: the rig (parsed once, without a
    /// size), the matcher's settings (the `fast` preset unless another is
    /// given), and the files (each depth file needs a rig). The settings as resolved, or every
    /// member at fault.
    pub fn of(
        settings: StreamSettings,
        streams: &Streams,
    ) -> Result<(Resolved, SettingsAnswer), FieldErrors> {
        let mut problems = FieldErrors::default();
        let sent = settings.rig.sent();
        let rectify = (settings.options.rectify, settings.options.alpha);
        let mut asked = settings.options.settings();
        asked.preset = asked.preset.or(Some(Preset::Fast));
        let (input, calibrated) = rig::parsed(&settings.rig, None, true, &mut problems);
        let has_rig = sent != Sent::Nothing;
        let outputs = settings.outputs.unwrap_or_else(|| {
            if has_rig {
                vec![DepthMapOutput::DepthNpy, DepthMapOutput::DepthStdNpy]
            } else {
                vec![
                    DepthMapOutput::DisparityNpy,
                    DepthMapOutput::DisparityStdNpy,
                ]
            }
        });
        let latlon = stream_latlon(&settings.options, &outputs, &mut problems);
        let planned = job::plan(
            calibrated,
            sent,
            None,
            asked_of(asked, rectify, latlon),
            &mut problems,
        );
        for (i, output) in outputs.iter().enumerate() {
            if output.needs_rig() && !has_rig {
                problems.add_new(
                    format!("outputs[{i}]"),
                    format!(
                        "{} needs the rig: give rig (the members of /distance) or a \
                         calibration",
                        output.name()
                    ),
                );
            }
        }
        let (Some(planned), Some(input), true) = (planned, input, problems.is_empty()) else {
            return Err(problems);
        };
        let params = *planned.params();
        let calibrated = planned.calibrated();
        let answer = SettingsAnswer {
            kind: "settings",
            layout: settings.layout.name(),
            min_disparity: params.min_disparity(),
            max_disparity: (!params.range_found()).then(|| params.max_disparity()),
            parameters: MatcherParameters::of(&params, None),
            outputs: outputs.iter().map(|o| o.name()).collect(),
            rig: calibrated.map(|c| CalibratedRig::from(&c.rig)),
            temporal: settings.temporal.map(Into::into),
            limits: StreamLimitsAnswer {
                max_frame_bytes: streams.max_frame_bytes,
                idle_timeout_s: streams.idle_timeout.as_secs_f64(),
                write_timeout_s: streams.write_timeout.as_secs_f64(),
            },
            warnings: calibrated.map_or_else(Vec::new, |c| c.warnings.clone()),
        };
        let colour = outputs
            .iter()
            .filter_map(|o| o.needs())
            .any(pipeline::Product::wants_colour);
        let depth_std = outputs.iter().any(|o| o.wants_depth_std());
        let resolved = Resolved {
            layout: settings.layout,
            settings: asked,
            params,
            outputs,
            input,
            rectify,
            latlon,
            temporal: settings.temporal,
            colour,
            depth_std,
        };
        Ok((resolved, answer))
    }
}

/// What a stream asks of each frame size's job: its settings, rectified as its options say,
/// a setting's fault named `options.…`.
fn asked_of(
    settings: Settings,
    (rectify, alpha): (Option<RectifyMode>, Option<f64>),
    latlon: Option<LatlonOptions>,
) -> job::Asked<'static> {
    job::Asked {
        rectify,
        alpha,
        latlon,
        settings,
        prefix: "options.",
    }
}

/// The latitude-longitude options of a stream's `options` (as `/depth-map`'s query, each
/// fault named `options.…`): `projection=auto` gives way to the pinhole plane for a ROS
/// output, and an explicit `latlon` with one names that output.
fn stream_latlon(
    options: &DepthMapQuery,
    outputs: &[DepthMapOutput],
    problems: &mut FieldErrors,
) -> Option<LatlonOptions> {
    let mut said = FieldErrors::default();
    let latlon = job::latlon_options(options.projection, options.latlon(), &mut said);
    for fault in said.prefixed("options.") {
        problems.add_new(fault.field, fault.message);
    }
    let ros = outputs.iter().position(|o| o.ros().is_some());
    let latlon = latlon.and_then(|l| l.unless_pinhole(ros.is_some()));
    if let (Some(_), Some(i)) = (latlon, ros) {
        problems.add_new(format!("outputs[{i}]"), job::ROS_NOT_LATLON);
    }
    latlon
}

/// A frame as it arrived, its bytes held in the budget.
pub struct Frame {
    /// The binary messages received so far, this one included.
    pub id: u64,
    pub bytes: Bytes,
    pub arrived: Instant,
    pub held: Reservation,
}

/// One frame's answer: its times, summary and filter counts, and the files in order, their
/// bytes held in the budget until they are sent.
pub struct Done {
    pub times: FrameTimes,
    pub summary: DepthMapSummary,
    pub temporal: Option<TemporalCounts>,
    /// The calibration's check, on the frames that ran it.
    pub calibration: Option<CalibrationWatch>,
    pub files: Vec<(FileAnswer, Vec<u8>)>,
    pub held: Reservation,
}

/// What holds for the frames of one size: the depth job at that size (its rig, and the raw
/// rig and its maps when the frames are rectified), and the budget the maps and the filter's
/// state hold.
struct AtSize {
    size: (u32, u32),
    job: DepthJob,
    _held: Reservation,
}

/// The temporal filter and whose turn it is: the frames are matched side by side, but each
/// passes the filter in the order its work started (`next`), those already through (or
/// failed) in `done`.
struct Order {
    next: u64,
    done: BTreeSet<u64>,
    temporal: Option<Temporal>,
}

/// What a stream keeps from one frame to the next, shared by the frames in work.
pub struct Engine {
    resolved: Arc<Resolved>,
    budget: MemoryBudget,
    maps: Arc<MapCache>,
    limits: DecodeLimits,
    at: Mutex<Option<Arc<AtSize>>>,
    order: Mutex<Order>,
    turn: Condvar,
    /// The ends of range the stream's latest frames needed ([`KEPT_FRAMES`] of them), when
    /// each frame finds its own: the range searched is the widest of them, kept as the scene
    /// moves nearer (widened at once) and narrowed only once it has stayed further away.
    needs: Mutex<VecDeque<i32>>,
    /// The calibration's check over the latest frames of a raw stream, at the frames' size.
    watch: Mutex<Option<((u32, u32), Watch)>>,
}

/// How many of a stream's latest frames the range found is kept over.
const KEPT_FRAMES: usize = 30;

/// How long a frame waiting for its turn at the filter sleeps before it looks at its flag.
const TURN_POLL: Duration = Duration::from_millis(50);

/// A frame's place in the filter's order: taken once it has passed the filter, or given up
/// when it is dropped first (the frame failed), so that the frames after it go on.
struct Turn<'a> {
    engine: &'a Engine,
    seq: u64,
    done: bool,
}

impl Turn<'_> {
    /// Waits for this frame's turn (or its stream's end), steadies its disparities, and lets
    /// the next frame through.
    fn steady(&mut self, matched: &mut Matched, cancel: &AtomicBool) {
        let mut order = lock(&self.engine.order);
        while order.next != self.seq && !cancel.load(Ordering::Relaxed) {
            order = match self.engine.turn.wait_timeout(order, TURN_POLL) {
                Ok((order, _)) => order,
                Err(poisoned) => poisoned.into_inner().0,
            };
        }
        if let Some(filter) = order.temporal.as_mut() {
            matched.steady(filter);
        }
        self.pass(&mut order);
    }

    fn pass(&mut self, order: &mut Order) {
        self.done = true;
        order.done.insert(self.seq);
        while order.done.remove(&order.next) {
            order.next += 1;
        }
        self.engine.turn.notify_all();
    }
}

impl Drop for Turn<'_> {
    fn drop(&mut self) {
        if !self.done {
            let engine = self.engine;
            self.pass(&mut lock(&engine.order));
        }
    }
}

impl Engine {
    pub fn new(
        resolved: Arc<Resolved>,
        budget: MemoryBudget,
        maps: Arc<MapCache>,
        limits: DecodeLimits,
    ) -> Self {
        let temporal = resolved.temporal.map(Temporal::new);
        Engine {
            resolved,
            budget,
            maps,
            limits,
            at: Mutex::new(None),
            order: Mutex::new(Order {
                next: 0,
                done: BTreeSet::new(),
                temporal,
            }),
            turn: Condvar::new(),
            needs: Mutex::new(VecDeque::with_capacity(KEPT_FRAMES)),
            watch: Mutex::new(None),
        }
    }

    /// The parameters for the next frame: where the range is found from each frame, at least
    /// the widest the latest frames needed.
    fn params(&self, at: &AtSize) -> Params {
        let params = *at.job.params();
        match lock(&self.needs).iter().max() {
            Some(&kept) if params.range_found() => params.at_least(kept),
            _ => params,
        }
    }

    /// Keeps what a frame's range found needed, for the frames after it.
    fn keep(&self, used: &RangeUsed) {
        if let Chosen::Found { needs, .. } = used.chosen {
            let mut kept = lock(&self.needs);
            if kept.len() == KEPT_FRAMES {
                kept.pop_front();
            }
            kept.push_back(needs);
        }
    }

    /// Matches one frame, the `seq`-th whose work started (counting from 0); the stream goes
    /// on whatever it answers. Frames are matched side by side, and pass the temporal filter
    /// in `seq` order.
    pub fn frame(&self, frame: &Frame, seq: u64, cancel: &AtomicBool) -> Result<Done, ApiError> {
        let mut turn = Turn {
            engine: self,
            seq,
            done: false,
        };
        let queue = frame.arrived.elapsed();
        let size = self.size_of(&frame.bytes)?;
        let started = Instant::now();
        let at = self.at_size(size)?;
        let setup = started.elapsed();
        let held = self.reserve(&at, size)?;
        let started = Instant::now();
        let colour = self.resolved.colour;
        let (left, right) = self.decode(&frame.bytes, colour)?;
        let decode = started.elapsed();
        let resolved = &*self.resolved;
        let params = self.params(&at);
        let request = Request {
            params: &params,
            sparse: Watch::due(seq) && at.job.raw().is_some(),
            ..at.job.request(colour, resolved.depth_std)
        };
        let mut matched =
            pipeline::matched(left, right, request, cancel).map_err(ApiError::from)?;
        self.keep(&matched.range());
        let calibration = self.watched(&at, matched.take_sparse());
        turn.steady(&mut matched, cancel);
        let map = matched.depth_map(request);
        let started = Instant::now();
        let rig = at.job.calibrated().map(|c| CalibratedRig::from(&c.rig));
        let (summary, files) = rayon::join(
            || DepthMapSummary::of(&map, &resolved.params, rig, decode),
            || files(&map, &resolved.outputs),
        );
        let files = files?;
        let ms = |d: Duration| (d.as_secs_f64() * 1e4).round() / 10.0;
        let t = &map.timings;
        let filter = map.temporal.map_or(Duration::ZERO, |(_, d)| d);
        let times = FrameTimes {
            queue: ms(queue),
            decode: ms(decode),
            setup: ms(setup),
            rectify: map.rectify.map(ms),
            matching: ms(t.cost + t.aggregate + t.refine),
            temporal: ms(filter),
            encode: ms(started.elapsed() + map.depths),
            total: ms(frame.arrived.elapsed()),
        };
        let temporal = map.temporal.map(|(counts, _)| counts.into());
        drop(map);
        let bytes: usize = files.iter().map(|(_, f)| f.len()).sum();
        held.settle_alone(bytes.saturating_add(ANSWER_BYTES));
        Ok(Done {
            times,
            summary,
            temporal,
            calibration,
            files,
            held,
        })
    }

    /// The calibration's check with a frame's sparse matches added (none: not this frame's
    /// turn), over the latest checked frames of this size; `None` when not checked or when
    /// the frames so far do not determine it.
    fn watched(&self, at: &AtSize, sparse: Vec<SparseMatch>) -> Option<CalibrationWatch> {
        if sparse.is_empty() {
            return None;
        }
        let mut kept = lock(&self.watch);
        if kept.as_ref().is_none_or(|(size, _)| *size != at.size) {
            let watch = Watch::of(at.job.calibrated()?, check::Settings::default())?;
            *kept = Some((at.size, watch));
        }
        let (_, watch) = kept.as_mut()?;
        let check = watch.add(sparse).ok()?;
        Some(CalibrationWatch::of(
            &check,
            watch.frames(),
            at.job.calibrated()?,
        ))
    }

    /// What holds for frames of `size`: kept from the frame before, or resolved now.
    fn at_size(&self, size: (u32, u32)) -> Result<Arc<AtSize>, ApiError> {
        let mut at = lock(&self.at);
        if let Some(known) = at.as_ref().filter(|a| a.size == size) {
            return Ok(Arc::clone(known));
        }
        *at = None;
        let resolved = Arc::new(self.resolve(size)?);
        *at = Some(Arc::clone(&resolved));
        Ok(resolved)
    }

    /// The size of the pair a frame holds, from its headers (no pixel decoded).
    fn size_of(&self, bytes: &Bytes) -> Result<(u32, u32), ApiError> {
        let header = |name: &str, bytes: &[u8]| {
            decode::dimensions(bytes)
                .map_err(|e| ApiError::invalid(name, limits::describe(&e, self.limits)))
        };
        match self.resolved.layout {
            Layout::SideBySide => {
                let (w, h) = header("frame", bytes)?;
                if w % 2 != 0 || w / 2 < decode::MIN_SIDE {
                    return Err(odd_width(w as usize));
                }
                // Each half is one camera's image, held to one image's limits: two 4K images
                // side by side are as welcome as a 4K pair.
                if let Some(why) = limits::over_the_limits((w / 2, h), self.limits) {
                    return Err(ApiError::Oversized(vec![FieldError::new(
                        "frame",
                        format!("holds two images side by side, and each {why}"),
                    )]));
                }
                Ok((w / 2, h))
            }
            Layout::Pair => {
                let (left, right) = pair_parts(bytes)?;
                let l = header("frame.left", &left)?;
                let r = header("frame.right", &right)?;
                let mut problems = FieldErrors::default();
                limits::check_pair(l, r, self.limits, &mut problems).map_err(in_frame)?;
                problems.finish(Some(l)).map_err(in_frame)
            }
        }
    }

    /// The job at `size` (the rig made for the frames' size) and, when the frames
    /// are raw, the maps, their memory and the filter's reserved for the stream's life.
    fn resolve(&self, size: (u32, u32)) -> Result<AtSize, ApiError> {
        let resolved = &*self.resolved;
        let mut problems = FieldErrors::default();
        let asked = asked_of(resolved.settings, resolved.rectify, resolved.latlon);
        let planned = job::plan_at(&resolved.input, size, asked, &mut problems);
        let Some(planned) = planned.filter(|_| problems.is_empty()) else {
            return Err(problems.into_error());
        };
        let matched = planned.raw().map_or(size, |r| {
            let s = r.rectified_size();
            (s.width, s.height)
        });
        let pixels = matched.0 as usize * matched.1 as usize;
        let filter = self
            .resolved
            .temporal
            .map_or(0, |_| pixels.saturating_mul(temporal::BYTES_A_PIXEL));
        let maps_bytes = planned.raw().map_or(0, Maps::bytes_for);
        let held = self
            .budget
            .reserve(filter.saturating_add(maps_bytes))
            .map_err(ApiError::Memory)?;
        Ok(AtSize {
            size,
            job: planned.with_maps(|r| self.maps.get(r).0),
            _held: held,
        })
    }

    /// Reserves what matching a frame of `size` holds at its peak (a side-by-side frame's
    /// halves cut out besides).
    fn reserve(&self, at: &AtSize, size: (u32, u32)) -> Result<Reservation, ApiError> {
        let products = self.resolved.outputs.iter().filter_map(|o| o.needs());
        let need = at.job.need(size, Answer::Files(products.collect()));
        let split = match self.resolved.layout {
            Layout::SideBySide => (size.0 as usize * size.1 as usize).saturating_mul(4),
            Layout::Pair => 0,
        };
        let bytes = need.bytes(need.count).saturating_add(split);
        match self.budget.reserve(bytes) {
            Ok(held) => Ok(held),
            Err(Refusal::TooLarge { total, .. }) => Err(ApiError::Oversized(limits::shrink(
                need.size,
                need.count,
                total,
                |n| need.bytes(n),
            ))),
            Err(busy) => Err(ApiError::Memory(busy)),
        }
    }

    /// The frame's two images, decoded within the limits.
    fn decode(&self, bytes: &Bytes, colour: bool) -> Result<(Decoded, Decoded), ApiError> {
        match self.resolved.layout {
            Layout::SideBySide => {
                // The halves were judged against one image's limits (`size_of`); the whole
                // frame is two of them.
                let two = DecodeLimits {
                    max_side: self.limits.max_side.saturating_mul(2),
                    max_pixels: self.limits.max_pixels.saturating_mul(2),
                };
                let frame = decode::decode(bytes, two, colour)
                    .map_err(|e| ApiError::invalid("frame", limits::describe(&e, two)))?;
                decode::split_side_by_side(frame).map_err(odd_width)
            }
            Layout::Pair => {
                let (left, right) = pair_parts(bytes)?;
                let parts: Parts = [("left".to_owned(), left), ("right".to_owned(), right)]
                    .into_iter()
                    .collect();
                work::decode_pair(&parts, self.limits, [colour, false]).map_err(in_frame)
            }
        }
    }
}

/// What an answer's JSON and messages hold besides its files, at most.
const ANSWER_BYTES: usize = 64 * 1024;
