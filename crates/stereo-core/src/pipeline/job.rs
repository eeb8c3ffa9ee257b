//! One depth job for every caller (`/depth-map`, `/match`, a stream's frames, the `depth-map`
//! command): the rig planned once for frames of one size (the rectified rig for raw frames,
//! the raw rig inside it), the matcher's parameters with their defaults decided once
//! ([`Params::new`], the calibration file's `ndisp` among them), the rectification maps, and
//! the bytes a frame of the job holds at its peak.
//!
//! A job is planned where the request is judged (cheap: no image touched, no map built), then
//! given its maps where the work runs ([`DepthJob::with_maps`]), then asked for the
//! [`Request`] each frame is matched with.

use std::sync::Arc;

use super::{Calibrated, Maps, PlanFault, Product, RectifyMode, Request, Sent};
use crate::calibration::files::Raw;
use crate::camera::{Alpha, LatlonOptions};
use crate::vision::{self, ParamFault, Params, Settings};

/// A depth job: what every frame of one size is matched with.
#[derive(Debug, Clone)]
pub struct DepthJob {
    /// The rig the depths use: the rectified rig (its raw rig inside) when the frames are
    /// rectified first, the rig as given otherwise.
    calibrated: Option<Calibrated>,
    /// Whether the frames are raw, rectified through the maps before they are matched.
    rectifies: bool,
    params: Params,
    maps: Option<Arc<Maps>>,
}

/// Why a job cannot be planned: the rectify plan's refusal and each setting refused.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JobFaults {
    pub plan: Option<PlanFault>,
    pub settings: Vec<ParamFault>,
}

/// How the frames are rectified: the caller's mode and `alpha`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Rectify {
    pub mode: RectifyMode,
    pub alpha: Option<Alpha>,
    /// Rectify to latitude-longitude with these options (`None`: the pinhole plane).
    pub latlon: Option<LatlonOptions>,
}

/// What a job's answer holds besides the matcher's work.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Answer {
    /// A depth map written as these files (none: a summary).
    Files(Vec<Product>),
    /// Points' and regions' matches: the disparity map and its σ only.
    Matches,
}

impl DepthJob {
    /// The job for frames of `size` (`None` when it could not be read: the faults are still
    /// found) given the rig as read at that size (`given`, `None` for disparities alone or
    /// when what was `sent` could not be read), rectified as `rectify` asks, matched with
    /// `settings`. The calibration file's `ndisp` becomes the end of the search where
    /// `settings` give none.
    pub fn plan(
        given: Option<Calibrated>,
        sent: Sent,
        size: Option<(u32, u32)>,
        rectify: Rectify,
        mut settings: Settings,
    ) -> Result<DepthJob, JobFaults> {
        let planned = super::plan(
            given.as_ref(),
            sent,
            size,
            rectify.mode,
            rectify.alpha,
            rectify.latlon,
        );
        let (calibrated, rectifies, plan) = match planned {
            Ok(Some(raw)) => (Some(raw), true, None),
            Ok(None) => (given, false, None),
            Err(fault) => (given, false, Some(fault)),
        };
        settings.file_range = calibrated.as_ref().and_then(|c| c.max_disparity);
        match (plan, Params::new(&settings)) {
            (None, Ok(params)) => Ok(DepthJob {
                calibrated,
                rectifies,
                params,
                maps: None,
            }),
            (plan, params) => Err(JobFaults {
                plan,
                settings: params.err().unwrap_or_default(),
            }),
        }
    }

    /// The rig the depths use (the rectified rig for raw frames).
    pub fn calibrated(&self) -> Option<&Calibrated> {
        self.calibrated.as_ref()
    }

    /// The matcher's parameters, defaults decided.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The raw rig the frames are rectified with, when they are raw.
    pub fn raw(&self) -> Option<&Raw> {
        self.calibrated
            .as_ref()
            .filter(|_| self.rectifies)
            .and_then(|c| c.raw.as_deref())
    }

    /// The job with the maps of its raw rig (`maps` finds or builds them); a job of frames
    /// sent rectified needs none.
    pub fn with_maps(mut self, maps: impl FnOnce(&Raw) -> Arc<Maps>) -> DepthJob {
        self.maps = self.raw().map(maps);
        self
    }

    /// The request a frame is matched with: this job's parameters, rig and maps.
    pub fn request(&self, colour: bool, depth_std: bool) -> Request<'_> {
        Request {
            params: &self.params,
            calibrated: self.calibrated.as_ref(),
            maps: self.maps.as_deref(),
            colour,
            depth_std,
            sparse: false,
        }
    }

    /// The request for `/match`'s points and regions (a rig is needed there).
    pub fn matches_request(&self) -> Option<super::matches::Request<'_>> {
        Some(super::matches::Request {
            params: &self.params,
            calibrated: self.calibrated.as_ref()?,
            maps: self.maps.as_deref(),
        })
    }

    /// What a frame of `size` (as sent) holds at its peak to give `answer`, over the job's
    /// range: a raw frame is decoded at its own size and matched at the rectified size, with
    /// the maps' memory while they are built.
    pub fn need(&self, (width, height): (u32, u32), answer: Answer) -> Need {
        let (size, rectifying) = match self.raw() {
            Some(raw) => {
                let s = raw.rectified_size();
                ((s.width as usize, s.height as usize), rectifying_bytes(raw))
            }
            None => ((width as usize, height as usize), 0),
        };
        Need {
            size,
            count: self.params.most_searched(),
            rectifying,
            answer,
        }
    }
}

/// What a frame of a job holds at its peak, over `count` disparities or fewer (to say how
/// few would fit).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Need {
    /// The size matched (the rectified size of raw frames).
    pub size: (usize, usize),
    /// The disparities searched at most.
    pub count: usize,
    rectifying: usize,
    answer: Answer,
}

impl Need {
    /// The bytes matching over `count` disparities holds at its peak.
    pub fn bytes(&self, count: usize) -> usize {
        let (w, h) = self.size;
        let answer = match &self.answer {
            Answer::Files(products) => depth_map_bytes(w, h, count, products),
            Answer::Matches => {
                let after = w
                    .saturating_mul(h)
                    .saturating_mul(8)
                    .saturating_add(vision::bytes_needed(w, h, count));
                decode_then(w, h, after)
            }
        };
        answer.saturating_add(self.rectifying)
    }
}

/// The bytes the decoded pair holds: for each image, the decoder's buffer at up to 8 bytes a
/// pixel and the grey levels at 2.
pub fn decoded_bytes(width: usize, height: usize) -> usize {
    width.saturating_mul(height).saturating_mul(2 * (8 + 2))
}

/// The peak of a request that decodes a `width × height` pair and then holds `after` bytes
/// besides the pair's grey levels (2 bytes a pixel each, all that decoding leaves): the
/// decode's peak or the rest's, whichever is larger, since the decoder's buffers are freed
/// before the matcher starts.
pub fn decode_then(width: usize, height: usize, after: usize) -> usize {
    let grey = width.saturating_mul(height).saturating_mul(4);
    decoded_bytes(width, height).max(grey.saturating_add(after))
}

/// The bytes rectifying a raw pair holds: the decoded frames and the maps while they are built.
pub fn rectifying_bytes(raw: &Raw) -> usize {
    decoded_bytes(raw.size.width as usize, raw.size.height as usize)
        .saturating_add(Maps::bytes_for(raw))
}

/// What a depth map's answer holds a pixel before its files: the map and its σ and mask (9
/// bytes), the depths and their σ (8).
const MAP_BYTES_A_PIXEL: usize = 17;
/// What each file written from the map holds a pixel besides its own extra (up to 7 bytes).
const FILE_BYTES_A_PIXEL: usize = 7;

/// The bytes a depth map's work holds at its peak: the decoded pair ([`decode_then`]), then
/// the left image's colours for a point cloud, and the larger of the matcher's peak and the
/// answer's: the map, its depths and σ (17 bytes a pixel), and each file written from them
/// (up to 7 bytes a pixel, and the file's own extra; a summary counts as one). The matcher's
/// buffers are freed before the answer is made.
pub fn depth_map_bytes(w: usize, h: usize, count: usize, products: &[Product]) -> usize {
    let extra: usize = products.iter().map(|p| p.extra_bytes_per_pixel()).sum();
    let colour = if products.iter().any(|p| p.wants_colour()) {
        3
    } else {
        0
    };
    let pixels = w.saturating_mul(h);
    let a_pixel = MAP_BYTES_A_PIXEL + FILE_BYTES_A_PIXEL * products.len().max(1) + extra;
    let answer = pixels.saturating_mul(a_pixel);
    let after = pixels
        .saturating_mul(colour)
        .saturating_add(vision::bytes_needed(w, h, count).max(answer));
    decode_then(w, h, after)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::files::{self, ReadOptions, Source};
    use crate::vision::RangeEnd;

    /// A Middlebury calibration of rectified 160 × 120 images whose `ndisp` is 48.
    fn middlebury() -> Calibrated {
        let text = "cam0=[400 0 80; 0 400 60; 0 0 1]\ncam1=[400 0 80; 0 400 60; 0 0 1]\n\
                    doffs=0\nbaseline=120\nwidth=160\nheight=120\nndisp=48\n";
        let source = Source {
            text,
            right_text: None,
            format: None,
            kitti_pair: None,
            alpha: None,
            image_size: None,
        };
        let read = files::read(source, ReadOptions::default()).expect("a calibration");
        Calibrated::from_file(read, Some((160, 120))).expect("for these images")
    }

    /// The file's `ndisp` ends the search when no end is asked for, an end asked for wins,
    /// and `auto` finds it from the pair whatever the file says.
    #[test]
    fn the_files_range_is_the_default_end_decided_once() {
        let plan = |max_disparity| {
            let settings = Settings {
                max_disparity,
                ..Settings::default()
            };
            let job = DepthJob::plan(
                Some(middlebury()),
                Sent::Calibration,
                Some((160, 120)),
                Rectify::default(),
                settings,
            )
            .expect("a job");
            (job.params().max_disparity(), job.params().range_found())
        };
        assert_eq!(plan(None), (48, false));
        assert_eq!(plan(Some(RangeEnd::Px(64))), (64, false));
        assert!(plan(Some(RangeEnd::Auto)).1);
    }

    /// A plan's refusal and a setting's are both given, not the first alone.
    #[test]
    fn every_fault_is_given() {
        let settings = Settings {
            p1: Some(0),
            ..Settings::default()
        };
        let rectify = Rectify {
            mode: RectifyMode::Yes,
            alpha: None,
            latlon: None,
        };
        let faults = DepthJob::plan(None, Sent::Nothing, Some((160, 120)), rectify, settings)
            .expect_err("refused");
        assert_eq!(faults.plan, Some(PlanFault::NoCalibration));
        assert_eq!(faults.settings.len(), 1);
        assert_eq!(faults.settings[0].setting.name(), "p1");
    }

    /// A summary costs what one file does; a point cloud adds its colours and its extra, and
    /// a matched pair of rectified frames reserves nothing for rectifying.
    #[test]
    fn the_need_counts_the_files_asked_for() {
        let job = DepthJob::plan(
            Some(middlebury()),
            Sent::Calibration,
            Some((160, 120)),
            Rectify::default(),
            Settings::default(),
        )
        .expect("a job");
        assert!(job.raw().is_none());
        let summary = job.need((160, 120), Answer::Files(vec![]));
        let npy = job.need((160, 120), Answer::Files(vec![Product::DepthNpy]));
        let ply = job.need((160, 120), Answer::Files(vec![Product::PointsPly]));
        assert_eq!(summary.size, (160, 120));
        assert_eq!(summary.count, 48);
        assert_eq!(summary.bytes(48), npy.bytes(48));
        assert!(ply.bytes(48) > npy.bytes(48));
        assert!(summary.bytes(16) < summary.bytes(48));
    }
}
