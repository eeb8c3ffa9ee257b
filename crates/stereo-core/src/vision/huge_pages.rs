//! Large buffers (the 8-path aggregation's first-pass sums) asking the kernel for transparent
//! huge pages before they are first touched: a fresh 2 MiB page costs one fault where 4 KiB
//! pages cost 512, and on a virtual machine those faults are most of the time a fresh
//! volume takes (Motorcycle with 128 disparities: 260 ms of aggregation with 4 KiB pages,
//! 47 ms with huge pages). Where the kernel has THP off (`never`), or off Linux, the advice is
//! a no-op and the buffers are ordinary ones.
//!
//! Those buffers are then kept in a [`Pool`] for the next stripe or request, which writes
//! every cell before reading it: reused memory is neither cleared by the allocator nor faulted
//! in again. That matters where the buffers are above glibc's mapping threshold (5.9 MP at 400
//! disparities: 825 against 860–930 ms a request); on Motorcycle the server already got its
//! memory back from glibc without clearing, and gains nothing measurable.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

/// A `Vec` of `len` zeros, huge-page backed where the kernel allows. A large one comes
/// straight from the kernel already zeroed, so it is not written here at all.
pub fn zeroed<T: Copy + Default>(len: usize) -> Vec<T> {
    // `vec![0; n]` asks the allocator for zeroed memory (`calloc`), which maps fresh pages
    // for a large buffer and leaves them untouched until first written, after the advice.
    let mut v = vec![T::default(); len];
    advise(v.as_mut_ptr().cast(), len.saturating_mul(size_of::<T>()));
    v
}

/// The most bytes each [`Pool`] of the matcher keeps between uses, unless [`keep_at_most`]
/// says less: enough for the stripes of a 1080p pair in flight on a few cores, so that one
/// request after another reuses the same memory instead of having the kernel clear fresh
/// pages again.
pub const KEPT: usize = 96 << 20;

/// Caps what the matcher's pool ([`WORDS`]) keeps between uses at `bytes` (at most
/// [`KEPT`]), freeing what is kept beyond it: the server gives it a share of its memory
/// budget, since what it keeps is held outside any request's reservation.
pub fn keep_at_most(bytes: usize) {
    WORDS.set_limit(bytes.min(KEPT));
}

/// Tunes the process's memory as the service runs it with a heavy-memory budget of
/// `memory_budget` bytes: the pool keeps at most an eighth of it between uses
/// ([`keep_at_most`]), and glibc's thresholds are those of a warm server
/// ([`settle_allocator`]). The server calls it at start, and so does the command in process,
/// so that it goes as fast as the service it would otherwise call.
pub fn tune_for_budget(memory_budget: usize) {
    keep_at_most(memory_budget / 8);
    let _ = settle_allocator();
}

/// Bytes the pool keeps now.
pub fn kept() -> usize {
    WORDS.kept_bytes()
}

/// Frees kept buffers until the pool keeps at most `bytes`, its limit unchanged. (The costs
/// are made a row at a time inside the passes, [`super::cost::Cells::Made`]: no volume of
/// them is kept.)
pub fn release_to(bytes: usize) {
    WORDS.release_to(bytes);
}

/// The first aggregation pass's sums ([`super::sgm::aggregate`]).
pub static WORDS: Pool<u16> = Pool::new(KEPT);

/// Large buffers kept between uses, at most `limit` bytes of them together.
pub struct Pool<T> {
    kept: Mutex<Vec<Vec<T>>>,
    limit: AtomicUsize,
}

impl<T: Copy + Default> Pool<T> {
    /// An empty pool that keeps at most `limit` bytes.
    pub const fn new(limit: usize) -> Self {
        Self {
            kept: Mutex::new(Vec::new()),
            limit: AtomicUsize::new(limit),
        }
    }

    /// Keeps at most `limit` bytes from now on, freeing the smallest kept buffers beyond it.
    pub fn set_limit(&self, limit: usize) {
        self.limit.store(limit, Ordering::Relaxed);
        let freed = self.trim(&mut self.kept());
        drop(freed);
    }

    /// Bytes kept now.
    pub fn kept_bytes(&self) -> usize {
        self.kept()
            .iter()
            .map(|v| v.capacity().saturating_mul(size_of::<T>()))
            .sum()
    }

    /// Frees the smallest kept buffers until at most `bytes` are kept, leaving the limit as it
    /// is: for when the memory is wanted elsewhere now.
    pub fn release_to(&self, bytes: usize) {
        let freed = {
            let mut kept = self.kept();
            Self::trim_to(&mut kept, bytes)
        };
        drop(freed);
    }

    /// Sorts `kept` largest first and splits off the smallest that do not fit the limit
    /// together, to be freed by the caller outside the lock.
    fn trim(&self, kept: &mut Vec<Vec<T>>) -> Vec<Vec<T>> {
        Self::trim_to(kept, self.limit.load(Ordering::Relaxed))
    }

    /// [`Pool::trim`] to `limit` bytes.
    fn trim_to(kept: &mut Vec<Vec<T>>, limit: usize) -> Vec<Vec<T>> {
        kept.sort_unstable_by_key(|v| std::cmp::Reverse(v.capacity()));
        let mut total = 0usize;
        let fit = kept
            .iter()
            .take_while(|v| {
                total = total.saturating_add(v.capacity().saturating_mul(size_of::<T>()));
                total <= limit
            })
            .count();
        kept.split_off(fit)
    }

    fn kept(&self) -> std::sync::MutexGuard<'_, Vec<Vec<T>>> {
        self.kept.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// A `Vec` of `len` values for a caller that writes every one before reading it: the
    /// smallest kept buffer that holds `len`, with whatever it held, or else a fresh one of
    /// zeros ([`zeroed`]). When none holds `len`, the kept ones are all smaller and are freed
    /// first: a request whose buffers grow (coarse to fine) then holds no more at its peak
    /// than it would without the pool.
    pub fn take(&self, len: usize) -> Vec<T> {
        let (found, smaller) = {
            let mut kept = self.kept();
            let fits = (0..kept.len())
                .filter(|&i| kept[i].capacity() >= len)
                .min_by_key(|&i| kept[i].capacity());
            match fits {
                Some(i) => (Some(kept.swap_remove(i)), Vec::new()),
                None => (None, std::mem::take(&mut *kept)),
            }
        };
        // Freed outside the lock.
        drop(smaller);
        match found {
            Some(mut v) => {
                // Within the capacity: shortening writes nothing, lengthening only the tail.
                v.resize(len, T::default());
                v
            }
            None => zeroed(len),
        }
    }

    /// Keeps `buffer` for a later [`Pool::take`], freeing the smallest kept buffers while
    /// they hold more than the limit together (`buffer` itself when it alone does).
    pub fn give(&self, buffer: Vec<T>) {
        let bytes = buffer.capacity().saturating_mul(size_of::<T>());
        if bytes > self.limit.load(Ordering::Relaxed) {
            return;
        }
        let freed = {
            let mut kept = self.kept();
            kept.push(buffer);
            self.trim(&mut kept)
        };
        // Freed outside the lock.
        drop(freed);
    }
}

/// Advises `MADV_HUGEPAGE` for the whole pages inside `[start, start + bytes)`, untouched
/// memory that this process owns. Failure (no THP, an old kernel) changes nothing.
#[cfg(target_os = "linux")]
fn advise(start: *mut u8, bytes: usize) {
    const PAGE: usize = 4096;
    // Too small to hold a huge page: not worth a system call.
    if bytes < 4 << 20 {
        return;
    }
    let first = (start as usize).next_multiple_of(PAGE);
    let end = (start as usize + bytes) / PAGE * PAGE;
    if end > first {
        // SAFETY: the range lies inside an allocation this process owns (the vector's
        // capacity), and MADV_HUGEPAGE changes how its pages are backed, never their
        // contents or the mapping's validity.
        unsafe {
            libc::madvise(first as *mut libc::c_void, end - first, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise(_start: *mut u8, _bytes: usize) {}

/// glibc's mapping threshold (the allocation size from which `malloc` maps fresh pages from
/// the kernel, and `free` unmaps them).
pub const MMAP_THRESHOLD: usize = 32 << 20;
/// glibc's trim threshold (the free memory at the top of an arena it keeps rather than give
/// back to the kernel).
pub const TRIM_THRESHOLD: usize = 2 * MMAP_THRESHOLD;

/// Gives glibc's allocator, from the start, the thresholds it would move to by itself after
/// the first large request. glibc starts by mapping every allocation above 128 KiB afresh,
/// pages the kernel clears and faults in on first touch and takes back on `free`; the first
/// time it frees such a mapping it raises the threshold to that size (up to 32 MiB) and the
/// trim threshold to twice it. So a server that had answered one 5.9 MP request answered
/// Motorcycle's in 40.5 ms, and a fresh one in 45.4–46.0 ms, its decoded images, signatures,
/// maps and filters' copies (a few MiB each) faulted in again at every request. Setting
/// [`MMAP_THRESHOLD`] and [`TRIM_THRESHOLD`] at start makes every server the warm one; what
/// the allocator keeps is no more than the dynamic rule lets it keep once warm. A no-op on
/// other allocators. Whether glibc took both values (`false` where it is not the allocator).
pub fn settle_allocator() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: mallopt only sets the allocator's tuning parameters, under its own lock, and
        // answers 0 for a value it refuses.
        let (mmap, trim) = unsafe {
            (
                libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD as libc::c_int),
                libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD as libc::c_int),
            )
        };
        mmap == 1 && trim == 1
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    false
}

/// Bytes the allocator holds free in its arenas (glibc's `mallinfo2().fordblks`, resident or
/// already given back by a trim); 0 on other allocators.
pub fn allocator_free() -> usize {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: mallinfo2 only reads the allocator's statistics, under its own locks.
        unsafe { libc::mallinfo2() }.fordblks
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    0
}

/// Gives the free memory of every arena back to the kernel (glibc's `malloc_trim(0)`), at
/// most once every [`TRIM_EVERY`]: a trim walks every arena under its lock,
/// and the pages it gives back are faulted in again by the next request that needs them, so
/// it is for when the memory is wanted, not for every request. Whether it trimmed.
pub fn trim_allocator() -> bool {
    static LAST: Mutex<Option<Instant>> = Mutex::new(None);
    {
        let mut last = LAST.lock().unwrap_or_else(PoisonError::into_inner);
        if last.is_some_and(|at| at.elapsed() < TRIM_EVERY) {
            return false;
        }
        *last = Some(Instant::now());
    }
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free pages of the allocator's own arenas to the kernel,
    // under the arenas' locks; no allocation in use is touched.
    unsafe {
        libc::malloc_trim(0);
    }
    true
}

/// The least time between two [`trim_allocator`] calls that trim.
pub const TRIM_EVERY: Duration = Duration::from_millis(100);

#[cfg(test)]
mod tests {
    use super::*;

    /// A large buffer and a small one hold zeros, as many as asked for.
    #[test]
    fn buffers_hold_their_values() {
        assert_eq!(zeroed::<u8>(3), vec![0, 0, 0]);
        let zeros: Vec<u16> = zeroed(5 << 20);
        assert_eq!(zeros.len(), 5 << 20);
        assert!(zeros.iter().all(|&v| v == 0));
    }

    /// A buffer given back comes back to the next request of a size it holds, with its
    /// memory and its contents; a larger request gets a fresh zeroed one, and past the limit
    /// the smallest buffers are not kept.
    #[test]
    fn given_buffers_are_taken_again() {
        let pool: Pool<u16> = Pool::new(19_000);
        let mut first = pool.take(1000);
        first.fill(7);
        let at = first.as_ptr();
        pool.give(first);
        let again = pool.take(600);
        assert_eq!((again.as_ptr(), again.len()), (at, 600));
        assert!(again.iter().all(|&v| v == 7));
        pool.give(again);
        let longer = pool.take(1000);
        assert_eq!(longer.as_ptr(), at);
        assert!(longer[..600].iter().all(|&v| v == 7));
        assert!(longer[600..].iter().all(|&v| v == 0));
        let larger = pool.take(5000);
        assert_eq!(larger.len(), 5000);
        assert!(larger.iter().all(|&v| v == 0));
        // Both kept; a small request takes the smaller.
        let big = larger.as_ptr();
        pool.give(larger);
        pool.give(longer);
        let small = pool.take(10);
        assert_eq!(small.as_ptr(), at);
        let next = pool.take(10);
        assert_eq!(next.as_ptr(), big);
        // A request larger than every kept buffer frees them all.
        pool.give(pool.take(700));
        let huge = pool.take(6000);
        assert!(pool.kept().is_empty());
        drop(huge);
        // 10 000 + 8 000 bytes fit the limit (19 000); with the 2 000 of `small` they do not:
        // `small` goes. A buffer over the limit on its own is never kept.
        pool.give(vec![0u16; 4000]);
        pool.give(small);
        pool.give(next);
        pool.give(vec![0u16; 10_001]);
        let kept = || pool.kept().iter().map(Vec::capacity).collect::<Vec<_>>();
        assert_eq!(kept(), vec![5000, 4000]);
        // A lower limit frees the smallest first,
        pool.set_limit(12_000);
        assert_eq!(kept(), vec![5000]);
        // even after a take has left the kept out of order ([1000, 4000] here).
        pool.set_limit(21_000);
        pool.give(vec![0u16; 4000]);
        pool.give(vec![0u16; 1000]);
        let held = pool.take(4500);
        assert_eq!(held.capacity(), 5000);
        pool.set_limit(9_000);
        assert_eq!(kept(), vec![4000]);
        pool.set_limit(0);
        assert!(kept().is_empty());
    }

    /// Releasing frees the smallest kept buffers down to the bytes asked for and leaves the
    /// limit as it was: buffers given afterwards are kept up to it again.
    #[test]
    fn releasing_frees_the_smallest_and_keeps_the_limit() {
        let pool: Pool<u8> = Pool::new(10_000);
        for len in [1000, 4000, 3000] {
            pool.give(vec![0u8; len]);
        }
        assert_eq!(pool.kept_bytes(), 8000);
        pool.release_to(7500);
        assert_eq!(pool.kept_bytes(), 7000);
        pool.release_to(0);
        assert_eq!(pool.kept_bytes(), 0);
        pool.give(vec![0u8; 9000]);
        assert_eq!(pool.kept_bytes(), 9000, "the limit is still 10 000");
    }

    /// Blocks freed in the allocator's arenas are reported as free memory it holds.
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    #[test]
    fn freed_blocks_count_as_the_allocators_free_memory() {
        // Below the mapping threshold: from an arena, kept there when freed. Every other one
        // is kept, so that the freed ones cannot merge into the top and be given back.
        let blocks: Vec<Vec<u8>> = (0..64).map(|i| vec![i as u8; 64 << 10]).collect();
        let before = allocator_free();
        let kept: Vec<Vec<u8>> = blocks.into_iter().step_by(2).collect();
        let after = allocator_free();
        assert!(
            after >= before + 16 * (64 << 10),
            "{before} -> {after} bytes free"
        );
        assert_eq!(kept.len(), 32);
    }
}
