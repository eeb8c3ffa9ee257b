//! The rectification maps ([`Maps`]) of the raw rigs seen lately, shared by `/rectify` and the raw pairs
//! of the image routes: maps depend only on the cameras, the rectification and the sizes, so
//! a stream of frames from one rig pays for them once. The cache is bounded (entries and
//! bytes), and each entry holds a reservation of its bytes in the heavy group's memory budget,
//! given back when it is evicted; an entry that does not fit the budget now is built and used
//! but not kept.

use std::collections::VecDeque;
use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};
use std::sync::{Arc, Mutex};

use crate::budget::{MemoryBudget, Reservation};
use stereo_core::calibration::files::Raw;
use stereo_core::pipeline::Maps;

/// What the maps of a raw rig depend on, hashed: both cameras, R1 R2 P1 P2 and the sizes.
pub fn key(raw: &Raw) -> u64 {
    let mut h = DefaultHasher::new();
    let mut put = |values: &[f64]| values.iter().for_each(|v| v.to_bits().hash(&mut h));
    for camera in [&raw.pair.left, &raw.pair.right] {
        put(camera.matrix().as_slice());
        put(camera.distortion().coefficients());
    }
    let r = &raw.rectification;
    put(r.r1.as_slice());
    put(r.r2.as_slice());
    put(r.p1.as_slice());
    put(r.p2.as_slice());
    if let Some(l) = &raw.latlon {
        put(l.r1.as_slice());
        put(l.r2.as_slice());
        put(&[
            l.fx,
            l.fy,
            l.cx,
            l.cy,
            l.size.width.into(),
            l.size.height.into(),
        ]);
    }
    let mut h2 = h.finish();
    for (camera, side) in [(&raw.pair.left, 1u64), (&raw.pair.right, 2)] {
        h2 ^= (camera.distortion().model() as u64 + 1) << (8 * side);
    }
    let sizes = [raw.size.width, raw.size.height, r.size.width, r.size.height];
    let mut h = DefaultHasher::new();
    (h2, sizes).hash(&mut h);
    h.finish()
}

/// A cached rig: its key, its maps and the budget they hold.
type Entry = (u64, Arc<Maps>, Option<Reservation>);

/// The cache: the most recent entries first.
#[derive(Debug)]
pub struct MapCache {
    budget: Option<MemoryBudget>,
    max_entries: usize,
    entries: Mutex<VecDeque<Entry>>,
}

/// How many rigs' maps are kept.
pub const MAX_ENTRIES: usize = 4;

impl MapCache {
    /// A cache of at most `max_entries` rigs, reserving each in `budget` when there is one.
    pub fn new(budget: Option<MemoryBudget>, max_entries: usize) -> Self {
        Self {
            budget,
            max_entries,
            entries: Mutex::new(VecDeque::new()),
        }
    }

    /// The maps of `raw`, from the cache or built now (then kept if the budget allows), and
    /// whether they came from the cache.
    pub fn get(&self, raw: &Raw) -> (Arc<Maps>, bool) {
        let key = key(raw);
        if let Ok(mut entries) = self.entries.lock()
            && let Some(i) = entries.iter().position(|(k, ..)| *k == key)
        {
            let entry = entries.remove(i).expect("found");
            let maps = Arc::clone(&entry.1);
            entries.push_front(entry);
            return (maps, true);
        }
        let maps = Arc::new(Maps::build(raw));
        if self.max_entries == 0 {
            return (maps, false);
        }
        let reservation = match &self.budget {
            Some(budget) => match budget.reserve(maps.bytes()) {
                Ok(r) => Some(r),
                Err(_) => return (maps, false),
            },
            None => None,
        };
        if let Ok(mut entries) = self.entries.lock() {
            if !entries.iter().any(|(k, ..)| *k == key) {
                entries.push_front((key, Arc::clone(&maps), reservation));
            }
            entries.truncate(self.max_entries);
        }
        (maps, false)
    }

    /// The bytes the cached maps hold.
    pub fn bytes(&self) -> usize {
        self.entries
            .lock()
            .map_or(0, |e| e.iter().map(|(_, m, _)| m.bytes()).sum())
    }
}

impl Default for MapCache {
    fn default() -> Self {
        Self::new(None, MAX_ENTRIES)
    }
}
