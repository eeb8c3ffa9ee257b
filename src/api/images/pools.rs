//! Thread pools lent to the frames a stream has in work, one a frame, so that two frames
//! matched side by side never wait on each other's tasks.
//!
//! In one shared rayon pool, a worker waiting for its half of a `join` runs whatever task it
//! can steal, another frame's long stripe among them. Its own frame then cannot go on until
//! that stripe ends, while the other worker may have nothing left to run: on 2 cores a stream
//! with two frames in work kept 1.80 cores busy (docs/live.md). A frame in a pool of its own
//! steals only its own tasks, and the operating system shares the cores between the pools'
//! threads.

use std::sync::{Mutex, MutexGuard, PoisonError};

use rayon::ThreadPool;

/// A lock that a panic elsewhere did not spoil (what the streams' and pools' mutexes guard is
/// whole between statements).
pub fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The pools lent at once, at most: each has a thread a core, so this bounds the threads
/// they add. A frame that finds none free runs in the global pool, as a request does.
pub const MOST: usize = 4;

/// Pools made when first needed and kept for the next frame.
#[derive(Debug, Default)]
pub struct FramePools {
    state: Mutex<Lent>,
}

#[derive(Debug, Default)]
struct Lent {
    free: Vec<ThreadPool>,
    made: usize,
}

impl FramePools {
    /// Runs `work` in a pool of its own (one free, or made while fewer than [`MOST`] exist),
    /// else, when all are lent or one cannot be made, where it is called.
    pub fn run<T: Send>(&self, work: impl FnOnce() -> T + Send) -> T {
        let loan = Loan {
            pools: self,
            pool: self.lend(),
        };
        match &loan.pool {
            Some(pool) => pool.install(work),
            None => work(),
        }
    }

    fn lend(&self) -> Option<ThreadPool> {
        let mut state = lock(&self.state);
        if let Some(pool) = state.free.pop() {
            return Some(pool);
        }
        if state.made >= MOST {
            return None;
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(rayon::current_num_threads())
            .thread_name(|i| format!("frame-pool-{i}"))
            .build()
            .ok()?;
        state.made += 1;
        Some(pool)
    }

    /// The pools made so far.
    #[cfg(test)]
    fn made(&self) -> usize {
        lock(&self.state).made
    }
}

/// A pool on loan (or none), given back when its frame's work ends, even by a panic.
struct Loan<'a> {
    pools: &'a FramePools,
    pool: Option<ThreadPool>,
}

impl Drop for Loan<'_> {
    fn drop(&mut self) {
        if let Some(pool) = self.pool.take() {
            lock(&self.pools.state).free.push(pool);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Barrier;

    /// Work in flight at once gets pools of its own, up to `MOST`, each with a thread a core;
    /// past them work runs where it is called; a pool given back is lent again, not made anew.
    #[test]
    fn each_frame_in_work_gets_its_own_pool_up_to_the_cap() {
        let pools = FramePools::default();
        let at_once = MOST + 2;
        let barrier = Barrier::new(at_once);
        let names: Vec<Option<String>> = std::thread::scope(|s| {
            let handles: Vec<_> = (0..at_once)
                .map(|_| {
                    s.spawn(|| {
                        pools.run(|| {
                            barrier.wait();
                            let name = std::thread::current().name().map(str::to_owned);
                            barrier.wait();
                            (name, rayon::current_num_threads())
                        })
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| {
                    let (name, threads) = h.join().unwrap();
                    if name.is_some() {
                        assert_eq!(threads, rayon::current_num_threads());
                    }
                    name
                })
                .collect()
        });
        let in_pools = names
            .iter()
            .filter(|n| n.as_deref().is_some_and(|n| n.starts_with("frame-pool-")))
            .count();
        assert_eq!(in_pools, MOST, "{names:?}");
        assert_eq!(pools.made(), MOST);
        // Given back: the next work borrows one again.
        let name = pools.run(|| std::thread::current().name().map(str::to_owned));
        assert!(name.is_some_and(|n| n.starts_with("frame-pool-")));
        assert_eq!(pools.made(), MOST);
    }

    /// A panic in the work gives its pool back.
    #[test]
    fn a_panicking_frame_gives_its_pool_back() {
        let pools = FramePools::default();
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            pools.run(|| panic!("a frame's work failed"))
        }));
        assert!(caught.is_err());
        assert_eq!(pools.made(), 1);
        let name = pools.run(|| std::thread::current().name().map(str::to_owned));
        assert!(name.is_some_and(|n| n.starts_with("frame-pool-")));
        assert_eq!(pools.made(), 1);
    }
}
