//! The memory budget shared by the heavy (image) requests in flight: each one reserves what it
//! will hold before it allocates it, and a request that does not fit is refused at once (503 with
//! `Retry-After`) instead of pushing the process out of memory.
//!
//! The heavy group's guard reserves the request body on admission (its declared length, or the
//! body limit when none is declared); a handler grows its [`Reservation`] by what it sizes from
//! the decoded headers (the decoded pair, the matcher's stripes in flight) before allocating. A
//! reservation is given back when its last clone is dropped, so work moved to a blocking thread
//! keeps its memory reserved until that work ends, even if the request that started it was
//! abandoned.

use std::sync::{
    Arc,
    atomic::{AtomicUsize, Ordering},
};

/// A budget of bytes, shared by every clone.
#[derive(Debug, Clone)]
pub struct MemoryBudget(Arc<Shared>);

#[derive(Debug)]
struct Shared {
    total: usize,
    used: AtomicUsize,
}

/// Why a reservation was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// It would fit in the budget, but the requests in flight hold too much of it now: retry
    /// later.
    Busy { requested: usize, available: usize },
    /// It is larger than the whole budget: it will never fit, however long the client waits.
    TooLarge { requested: usize, total: usize },
}

impl MemoryBudget {
    /// A budget of `total` bytes, none reserved.
    pub fn new(total: usize) -> Self {
        Self(Arc::new(Shared {
            total,
            used: AtomicUsize::new(0),
        }))
    }

    /// Bytes reserved by the requests in flight.
    pub fn used(&self) -> usize {
        self.0.used.load(Ordering::Acquire)
    }

    /// Reserves `bytes`, or says why not.
    pub fn reserve(&self, bytes: usize) -> Result<Reservation, Refusal> {
        self.0.take(bytes)?;
        Ok(Reservation(Arc::new(Held {
            budget: Arc::clone(&self.0),
            bytes: AtomicUsize::new(bytes),
        })))
    }
}

impl Shared {
    /// Adds `bytes` to what is used, if the total allows it.
    fn take(&self, bytes: usize) -> Result<(), Refusal> {
        if bytes > self.total {
            return Err(Refusal::TooLarge {
                requested: bytes,
                total: self.total,
            });
        }
        self.used
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |used| {
                used.checked_add(bytes).filter(|&after| after <= self.total)
            })
            .map(|_| ())
            .map_err(|used| Refusal::Busy {
                requested: bytes,
                available: self.total.saturating_sub(used),
            })
    }
}

/// Bytes held against a [`MemoryBudget`]; cloning shares the same hold, which is given back when
/// the last clone is dropped.
#[derive(Debug, Clone)]
pub struct Reservation(Arc<Held>);

#[derive(Debug)]
struct Held {
    budget: Arc<Shared>,
    bytes: AtomicUsize,
}

impl Reservation {
    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.0.bytes.load(Ordering::Acquire)
    }

    /// Holds `more` bytes besides those already held, or says why not (nothing changes then).
    /// `TooLarge` compares the whole hold, what is held plus `more`, with the budget.
    pub fn grow(&self, more: usize) -> Result<(), Refusal> {
        let held = self.bytes();
        if held.saturating_add(more) > self.0.budget.total {
            return Err(Refusal::TooLarge {
                requested: held.saturating_add(more),
                total: self.0.budget.total,
            });
        }
        self.0.budget.take(more)?;
        self.0.bytes.fetch_add(more, Ordering::AcqRel);
        Ok(())
    }
}

impl Drop for Held {
    fn drop(&mut self) {
        let bytes = *self.bytes.get_mut();
        self.budget.used.fetch_sub(bytes, Ordering::AcqRel);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn busy(requested: usize, available: usize) -> Refusal {
        Refusal::Busy {
            requested,
            available,
        }
    }

    fn too_large(requested: usize, total: usize) -> Refusal {
        Refusal::TooLarge { requested, total }
    }

    /// Reservations add up to the total and no further; dropping the last clone gives the bytes
    /// back.
    #[test]
    fn reservations_add_up_and_are_given_back() {
        let budget = MemoryBudget::new(1000);
        let first = budget.reserve(600).unwrap();
        assert_eq!(budget.reserve(500).unwrap_err(), busy(500, 400));
        let second = budget.reserve(400).unwrap();
        assert_eq!(budget.used(), 1000);
        let shared = first.clone();
        drop(first);
        assert_eq!(budget.used(), 1000, "a clone still holds the bytes");
        drop(shared);
        drop(second);
        assert_eq!(budget.used(), 0);
    }

    /// Growing holds more bytes when they are free, refuses (changing nothing) when they are not,
    /// and calls a hold larger than the whole budget too large rather than busy.
    #[test]
    fn growing_is_bounded_by_the_budget() {
        let budget = MemoryBudget::new(1000);
        let held = budget.reserve(100).unwrap();
        held.grow(300).unwrap();
        assert_eq!((held.bytes(), budget.used()), (400, 400));
        let other = budget.reserve(500).unwrap();
        assert_eq!(held.grow(200).unwrap_err(), busy(200, 100));
        assert_eq!((held.bytes(), budget.used()), (400, 900));
        assert_eq!(held.grow(700).unwrap_err(), too_large(1100, 1000));
        drop(other);
        drop(held);
        assert_eq!(budget.used(), 0);
        assert_eq!(budget.reserve(1001).unwrap_err(), too_large(1001, 1000));
    }
}
