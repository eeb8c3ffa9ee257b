//! The heavy work of an image request: one of the heavy group's compute slots taken (503 past
//! the concurrency limit) and the memory it needs reserved in the group's budget (503 while
//! others hold it, 413 naming what to shrink when it can never fit), both once its body has
//! arrived, then run on a blocking thread, off the async runtime, with a flag set when the
//! request is abandoned; the pair decoded there; and the stages it took, as `Server-Timing`.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use axum::body::Bytes;

use super::limits;
use super::parts::Parts;
use axum::extract::FromRequestParts;
use axum::http::{Extensions, request::Parts as RequestParts};

use super::HeavyState;
use crate::api::error::{ApiError, FieldError, RETRY_AFTER_SECS};
use crate::budget::{Refusal, Reservation, Slots};
use stereo_core::vision::Timings;
use stereo_core::vision::decode::{self, DecodeLimits, Decoded};

/// Sets its flag when dropped: the request's future was dropped (timed out, or its client
/// went away), so the blocking work should stop at its next check.
struct CancelOnDrop(Arc<AtomicBool>);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

/// The size of a request's work, to reserve its memory: a `size` pair searching `count`
/// disparities needs `need(count)` bytes.
pub struct Need<F: Fn(usize) -> usize> {
    pub size: (usize, usize),
    pub count: usize,
    pub need: F,
}

/// What the work gets besides its flag: when the work was queued, to report how long it
/// waited for a blocking thread.
pub struct Started {
    pub queued: Instant,
    pub running: Instant,
}

impl Started {
    /// How long the work waited for a thread.
    pub fn queue(&self) -> Duration {
        self.running.duration_since(self.queued)
    }
}

/// What an image request's work is admitted with: the memory the heavy group's guard reserved
/// for it (its body, so far), and the group's compute slots, one of which its work takes.
#[derive(Debug, Clone)]
pub struct Admitted {
    pub reservation: Reservation,
    pub slots: Slots,
}

impl Admitted {
    /// The guard's reservation (among a request's `extensions`) and the group's slots.
    pub fn of(extensions: &Extensions, state: &HeavyState) -> Result<Self, ApiError> {
        let reservation = extensions
            .get::<Reservation>()
            .cloned()
            .ok_or_else(|| ApiError::Internal("no memory reservation".to_owned()))?;
        Ok(Self {
            reservation,
            slots: state.slots.clone(),
        })
    }
}

/// An image handler that reads its body its own way takes its admission as an extractor.
impl FromRequestParts<HeavyState> for Admitted {
    type Rejection = ApiError;

    async fn from_request_parts(
        parts: &mut RequestParts,
        state: &HeavyState,
    ) -> Result<Self, ApiError> {
        Self::of(&parts.extensions, state)
    }
}

/// Takes a compute slot and reserves the memory the work needs (or says why not), then runs
/// `work` on a blocking thread, holding both until it ends. The flag `work` gets is set when
/// this future is dropped.
pub async fn run<T: Send + 'static>(
    admitted: Admitted,
    need: Need<impl Fn(usize) -> usize>,
    work: impl FnOnce(&AtomicBool, Started) -> T + Send + 'static,
) -> Result<T, ApiError> {
    let bytes = (need.need)(need.count);
    let too_large = |total| limits::shrink(need.size, need.count, total, &need.need);
    run_reserved(admitted, bytes, too_large, work).await
}

/// [`run`] for work whose size is known in bytes: `too_large(total)` names what to shrink when
/// it can never fit in the budget of `total` bytes.
pub async fn run_reserved<T: Send + 'static>(
    admitted: Admitted,
    bytes: usize,
    too_large: impl FnOnce(usize) -> Vec<FieldError>,
    work: impl FnOnce(&AtomicBool, Started) -> T + Send + 'static,
) -> Result<T, ApiError> {
    let Admitted { reservation, slots } = admitted;
    let Some(slot) = slots.take() else {
        return Err(ApiError::Overloaded {
            retry_after_secs: RETRY_AFTER_SECS,
        });
    };
    match reservation.grow(bytes) {
        Ok(()) => {}
        Err(Refusal::TooLarge { total, .. }) => return Err(ApiError::Oversized(too_large(total))),
        Err(busy) => return Err(ApiError::Memory(busy)),
    }
    let flag = Arc::new(AtomicBool::new(false));
    let _cancel = CancelOnDrop(Arc::clone(&flag));
    let queued = Instant::now();
    tokio::task::spawn_blocking(move || {
        let _held = (reservation, slot);
        let started = Started {
            queued,
            running: Instant::now(),
        };
        work(&flag, started)
    })
    .await
    .map_err(|e| {
        if e.is_panic() {
            std::panic::resume_unwind(e.into_panic())
        } else {
            ApiError::Internal("the image work was stopped".to_owned())
        }
    })
}

/// Both images of the pair decoded at once (on the matcher's pool) within `allowed`, each in
/// colour too when `colour` says so (`[left, right]`); a 422 naming each image that cannot be
/// decoded.
pub fn decode_pair(
    parts: &Parts,
    allowed: DecodeLimits,
    colour: [bool; 2],
) -> Result<(Decoded, Decoded), ApiError> {
    let read = |name: &str, colour: bool| {
        let bytes = parts.get(name).map_or(&[][..], Bytes::as_ref);
        decode::decode(bytes, allowed, colour)
            .map_err(|e| FieldError::new(name, limits::describe(&e, allowed)))
    };
    match rayon::join(|| read("left", colour[0]), || read("right", colour[1])) {
        (Ok(l), Ok(r)) => Ok((l, r)),
        (l, r) => Err(ApiError::Invalid(
            [l.err(), r.err()].into_iter().flatten().collect(),
        )),
    }
}

/// The stages of a match for `Server-Timing`: the body read, the wait for a thread and the
/// decode, the matcher's stages, then the route's own (`after`).
pub fn matcher_stages<'a>(
    [read, queue, decode]: [Duration; 3],
    matcher: &Timings,
    after: &[(&'a str, Duration)],
) -> Vec<(&'a str, Duration)> {
    let mut stages = vec![
        ("read", read),
        ("queue", queue),
        ("decode", decode),
        ("cost", matcher.cost),
        ("aggregate", matcher.aggregate),
        ("refine", matcher.refine),
    ];
    stages.extend_from_slice(after);
    stages
}
