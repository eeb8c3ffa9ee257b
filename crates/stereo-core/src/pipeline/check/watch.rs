//! A stream watching its own calibration: every [`EVERY`]th frame of a raw stream gives its
//! rectified pair's sparse matches ([`crate::pipeline::Request::sparse`]); the latest
//! [`KEPT`] such frames' are fitted together as a check is ([`super::check`]'s fit), so that a
//! drift shows once it is past the tolerance, with its correction, and the matches of one
//! frame (a scene with little texture, a moment of motion) weigh little.

use std::collections::VecDeque;

use super::{Check, Fault, Settings, judge};
use crate::pipeline::Calibrated;
use crate::vision::sparse::SparseMatch;

/// Every how many frames a stream's pair is matched for the check.
pub const EVERY: u64 = 10;
/// How many checked frames are fitted together.
pub const KEPT: usize = 12;

/// What a stream keeps of its calibration's check.
#[derive(Debug, Clone)]
pub struct Watch {
    calibrated: Calibrated,
    settings: Settings,
    kept: VecDeque<Vec<SparseMatch>>,
}

impl Watch {
    /// A watch over `calibrated`, when it describes raw cameras side by side (a calibration
    /// of rectified images has nothing to check).
    pub fn of(calibrated: &Calibrated, settings: Settings) -> Option<Watch> {
        let raw = calibrated.raw.as_deref()?;
        (!raw.is_identity() && !raw.rectification.vertical).then(|| Watch {
            calibrated: calibrated.clone(),
            settings,
            kept: VecDeque::with_capacity(KEPT),
        })
    }

    /// Whether the `seq`-th frame (from 0) is matched for the check.
    pub fn due(seq: u64) -> bool {
        seq.is_multiple_of(EVERY)
    }

    /// The checked frames kept.
    pub fn frames(&self) -> usize {
        self.kept.len()
    }

    /// Adds a frame's matches and checks the latest [`KEPT`] frames' together.
    pub fn add(&mut self, matches: Vec<SparseMatch>) -> Result<Check, Fault> {
        if self.kept.len() == KEPT {
            self.kept.pop_front();
        }
        self.kept.push_back(matches);
        let raw = self.calibrated.raw.as_deref().ok_or(Fault::NotRaw)?;
        let all: Vec<SparseMatch> = self.kept.iter().flatten().copied().collect();
        let per_frame = self.kept.iter().map(Vec::len).collect();
        judge(&self.calibrated, raw, &all, &[], per_frame, self.settings)
    }
}
