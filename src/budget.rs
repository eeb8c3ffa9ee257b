//! What the heavy (image) requests in flight share: a memory budget and the compute slots.
//!
//! Memory: each request reserves what it will hold before it allocates it, and a request that
//! does not fit is refused at once (503 with `Retry-After`) instead of pushing the process out
//! of memory. The heavy group's guard reserves the request body on admission (its declared
//! length, or the body limit when none is declared); a handler grows its [`Reservation`] by what
//! it sizes from the decoded headers (the decoded pair, the matcher's stripes in flight) before
//! allocating; once the answer is made, the reservation is settled ([`Reservation::settle_alone`]) to the
//! answer's size and held until the answer has been handed to the connection, so that answers
//! waiting for a slow reader count too. A reservation is given back when its last clone is
//! dropped, so work moved to a blocking thread keeps its memory reserved until that work ends,
//! even if the request that started it was abandoned.
//!
//! Slots: [`Slots`] counts the requests doing work at once (a [`Slot`] each, taken when the work
//! starts, not while the body is still arriving), and refuses one past its limit.

use std::sync::{
    Arc,
    atomic::{AtomicUsize, Ordering},
};

/// A budget of bytes, shared by every clone.
#[derive(Debug, Clone)]
pub struct MemoryBudget(Arc<Shared>);

struct Shared {
    total: usize,
    used: AtomicUsize,
    /// What is kept outside the reservations and gives way to them.
    spare: Option<&'static dyn Spare>,
}

impl std::fmt::Debug for Shared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Shared")
            .field("total", &self.total)
            .field("used", &self.used)
            .finish_non_exhaustive()
    }
}

/// The share of the budget (one part in this many) that [`Spare`]s leave free beside the
/// reservations, for the memory no reservation counts: connection buffers, the chunks of
/// answers on their way, the multipart reader's copies.
pub const UNCOUNTED: usize = 32;

/// Memory a cache keeps outside any reservation, which gives way to them: whenever the
/// reservations grow, the cache is told to keep no more than the budget leaves free, so that
/// what is reserved and what is kept together stay within the budget.
pub trait Spare: Send + Sync {
    /// Bytes kept now.
    fn kept(&self) -> usize;
    /// Frees what is kept beyond `bytes`.
    fn release_to(&self, bytes: usize);
}

/// What the server keeps between requests outside every reservation, as a [`Spare`]: the
/// matcher's buffer pool ([`stereo_core::vision::huge_pages`]) and the free memory the allocator
/// holds in its arenas. When the reservations leave too little room for both, the pool frees
/// what does not fit and the allocator gives its free pages back to the kernel (at most every
/// [`stereo_core::vision::huge_pages::TRIM_EVERY`]), so that the process stays within the
/// budget rather than the budget plus what the last requests left behind.
pub struct Leftovers;

impl Spare for Leftovers {
    fn kept(&self) -> usize {
        use stereo_core::vision::huge_pages;
        huge_pages::kept().saturating_add(huge_pages::allocator_free())
    }

    fn release_to(&self, bytes: usize) {
        use stereo_core::vision::huge_pages;
        huge_pages::release_to(bytes);
        huge_pages::trim_allocator();
    }
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
        Self::build(total, None)
    }

    /// A budget of `total` bytes, none reserved, that `spare` gives way to.
    pub fn with_spare(total: usize, spare: &'static dyn Spare) -> Self {
        Self::build(total, Some(spare))
    }

    fn build(total: usize, spare: Option<&'static dyn Spare>) -> Self {
        Self(Arc::new(Shared {
            total,
            used: AtomicUsize::new(0),
            spare,
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
            .map(|used| self.make_room(used.saturating_add(bytes)))
            .map_err(|used| Refusal::Busy {
                requested: bytes,
                available: self.total.saturating_sub(used),
            })
    }

    /// Has the spare keep no more than what `used` bytes reserved leave of the total, less a
    /// [`UNCOUNTED`] share for what no reservation counts.
    fn make_room(&self, used: usize) {
        if let Some(spare) = self.spare {
            let room = self
                .total
                .saturating_sub(used)
                .saturating_sub(self.total / UNCOUNTED);
            if spare.kept() > room {
                spare.release_to(room);
            }
        }
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

impl Reservation {
    /// Holds exactly `bytes` from now on, if this is the hold's only clone (no work still runs
    /// with it): gives back what is held beyond them, or holds more even past the budget's
    /// total. For memory that already exists (an answer made), which must be counted whatever
    /// the budget says, so that new requests are refused until it is freed. Returns whether it
    /// settled; a hold that work still shares is left as it is.
    pub fn settle_alone(&self, bytes: usize) -> bool {
        if Arc::strong_count(&self.0) != 1 {
            return false;
        }
        let held = self.0.bytes.swap(bytes, Ordering::AcqRel);
        if bytes < held {
            self.0.budget.used.fetch_sub(held - bytes, Ordering::AcqRel);
        } else {
            let used = self.0.budget.used.fetch_add(bytes - held, Ordering::AcqRel);
            self.0.budget.make_room(used + (bytes - held));
        }
        true
    }
}

impl Drop for Held {
    fn drop(&mut self) {
        let bytes = *self.bytes.get_mut();
        self.budget.used.fetch_sub(bytes, Ordering::AcqRel);
    }
}

/// A count of the requests doing work at once, shared by every clone, with its limit.
#[derive(Debug, Clone)]
pub struct Slots(Arc<SlotCount>);

#[derive(Debug)]
struct SlotCount {
    limit: usize,
    busy: AtomicUsize,
}

/// One of the [`Slots`], given back when dropped.
#[derive(Debug)]
pub struct Slot(Arc<SlotCount>);

impl Slots {
    /// `limit` slots, none taken.
    pub fn new(limit: usize) -> Self {
        Self(Arc::new(SlotCount {
            limit,
            busy: AtomicUsize::new(0),
        }))
    }

    /// A slot, or `None` when all `limit` are taken.
    pub fn take(&self) -> Option<Slot> {
        self.0
            .busy
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |busy| {
                (busy < self.0.limit).then_some(busy + 1)
            })
            .ok()
            .map(|_| Slot(Arc::clone(&self.0)))
    }

    /// Slots taken now.
    pub fn busy(&self) -> usize {
        self.0.busy.load(Ordering::Acquire)
    }

    /// How many there are.
    pub fn limit(&self) -> usize {
        self.0.limit
    }
}

impl Drop for Slot {
    fn drop(&mut self) {
        self.0.busy.fetch_sub(1, Ordering::AcqRel);
    }
}

impl MemoryBudget {
    /// The whole budget, in bytes.
    pub fn total(&self) -> usize {
        self.0.total
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

    /// Settling gives back what an answer does not hold, and counts an answer larger than what
    /// was held even past the total, so that nothing else fits until it is freed.
    #[test]
    fn settling_holds_exactly_the_answer() {
        let budget = MemoryBudget::new(1000);
        let held = budget.reserve(600).unwrap();
        let work = held.clone();
        assert!(!held.settle_alone(150), "work still shares the hold");
        assert_eq!(budget.used(), 600);
        drop(work);
        assert!(held.settle_alone(150));
        assert_eq!((held.bytes(), budget.used()), (150, 150));
        assert!(held.settle_alone(1200));
        assert_eq!((held.bytes(), budget.used()), (1200, 1200));
        assert_eq!(budget.reserve(1).unwrap_err(), busy(1, 0));
        drop(held);
        assert_eq!(budget.used(), 0);
    }

    /// A spare that keeps more than the reservations leave free is told to give way, down to
    /// what is free; one that fits is left alone.
    #[test]
    fn the_spare_gives_way_to_reservations() {
        struct Kept(AtomicUsize);
        impl Spare for Kept {
            fn kept(&self) -> usize {
                self.0.load(Ordering::Acquire)
            }
            fn release_to(&self, bytes: usize) {
                self.0.fetch_min(bytes, Ordering::AcqRel);
            }
        }
        static KEPT: Kept = Kept(AtomicUsize::new(300));
        let budget = MemoryBudget::with_spare(3200, &KEPT);
        let first = budget.reserve(2000).unwrap();
        assert_eq!(KEPT.kept(), 300, "2000 + 300 fit in 3200 - 100 uncounted");
        first.grow(850).unwrap();
        assert_eq!(KEPT.kept(), 250, "3200 - 100 uncounted - 2850");
        first.settle_alone(3200);
        assert_eq!(KEPT.kept(), 0);
    }

    /// Slots are taken up to the limit and no further, and given back when dropped.
    #[test]
    fn slots_are_bounded_and_given_back() {
        let slots = Slots::new(2);
        let first = slots.take().expect("a first slot");
        let second = slots.clone().take().expect("a second slot");
        assert!(slots.take().is_none(), "a third past the limit of 2");
        assert_eq!(slots.busy(), 2);
        drop(first);
        let third = slots.take().expect("a slot once one is given back");
        drop((second, third));
        assert_eq!(slots.busy(), 0);
    }
}
