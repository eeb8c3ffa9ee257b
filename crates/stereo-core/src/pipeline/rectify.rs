//! Raw frames made rectified ones: a raw rig's maps (`initUndistortRectifyMap` for each
//! camera, in fixed point) built once and both frames of a pair read through them, as
//! `cv2.remap` reads them.

use std::time::{Duration, Instant};

use crate::calibration::files::Raw;
use crate::camera::{Map, undistort_rectify_map};
use crate::vision::Gray;
use crate::vision::decode::Decoded;
use crate::vision::remap::{self, Fixed, Interpolation, RawImage};

/// Both cameras' maps in fixed point, ready to read frames through.
#[derive(Debug)]
pub struct Maps {
    pub left: Fixed,
    pub right: Fixed,
}

/// Both cameras' float maps, as `initUndistortRectifyMap` makes them.
pub fn float_maps(raw: &Raw) -> (Map, Map) {
    let r = &raw.rectification;
    let k = |p: &nalgebra::Matrix3x4<f64>| p.fixed_view::<3, 3>(0, 0).into_owned();
    rayon::join(
        || undistort_rectify_map(&raw.pair.left, &r.r1, &k(&r.p1), r.size),
        || undistort_rectify_map(&raw.pair.right, &r.r2, &k(&r.p2), r.size),
    )
}

impl Maps {
    /// The maps of a raw rig's rectification.
    pub fn build(raw: &Raw) -> Maps {
        let (left, right) = float_maps(raw);
        let (left, right) = rayon::join(|| Fixed::new(&left), || Fixed::new(&right));
        Maps { left, right }
    }

    /// The bytes the maps hold.
    pub fn bytes(&self) -> usize {
        self.left.bytes() + self.right.bytes()
    }

    /// The most bytes building the maps of `raw` holds at once (both float maps and their
    /// fixed-point forms).
    pub fn bytes_for(raw: &Raw) -> usize {
        let s = raw.rectification.size;
        (s.width as usize) * (s.height as usize) * 28
    }

    /// Both frames of a pair read through the maps, in place: grey always, the left colours
    /// too when `colour` (a point cloud's). The time it took.
    pub fn rectify_pair(&self, left: &mut Decoded, right: &mut Decoded, colour: bool) -> Duration {
        let started = Instant::now();
        let grey = |d: &Decoded, map: &Fixed| {
            Gray::new(
                map.width,
                map.height,
                remap::remap_fixed(RawImage::grey(&d.grey), map, Interpolation::Linear),
            )
        };
        let (l, r) = rayon::join(|| grey(left, &self.left), || grey(right, &self.right));
        if colour && let Some(rgb) = left.rgb.as_deref() {
            let g = &left.grey;
            left.rgb = Some(remap::remap_fixed(
                RawImage {
                    width: g.width,
                    height: g.height,
                    channels: 3,
                    data: rgb,
                },
                &self.left,
                Interpolation::Linear,
            ));
        }
        left.grey = l;
        right.grey = r;
        started.elapsed()
    }
}
