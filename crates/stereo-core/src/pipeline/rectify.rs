//! Raw frames made rectified ones: a raw rig's maps (`initUndistortRectifyMap` for each
//! camera, in fixed point) built once and both frames of a pair read through them, as
//! `cv2.remap` reads them; the rectified frames as PNG (one, or both side by side), and the
//! float maps as NPZ.

use std::time::{Duration, Instant};

use crate::calibration::files::Raw;
use crate::camera::{Map, undistort_rectify_map};
use crate::vision::decode::Decoded;
pub use crate::vision::remap::Interpolation;
use crate::vision::remap::{self, Fixed, RawImage};
use crate::vision::{Gray, encode};

/// Both cameras' maps in fixed point, ready to read frames through.
#[derive(Debug)]
pub struct Maps {
    pub left: Fixed,
    pub right: Fixed,
}

/// Both cameras' float maps, as `initUndistortRectifyMap` makes them (or mrcal's
/// `rectification_maps`, for latitude-longitude).
pub fn float_maps(raw: &Raw) -> (Map, Map) {
    if let Some(latlon) = &raw.latlon {
        return latlon.maps(&raw.pair);
    }
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
        let s = raw.rectified_size();
        (s.width as usize) * (s.height as usize) * 28
    }

    /// Both frames of a pair read through the maps, in place: grey always, the left colours
    /// too when `colour` (a point cloud's). The time it took, and the raw grey frames the
    /// rectified ones replaced.
    pub fn rectify_pair(
        &self,
        left: &mut Decoded,
        right: &mut Decoded,
        colour: bool,
    ) -> (Duration, (Gray, Gray)) {
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
        let raw = (
            std::mem::replace(&mut left.grey, l),
            std::mem::replace(&mut right.grey, r),
        );
        (started.elapsed(), raw)
    }
}

impl Maps {
    /// One rectified frame as PNG (`right` for the right camera's): RGB when the frame has
    /// colour, else grey, 8 bits when the frame was (every level a multiple of 257), 16
    /// otherwise.
    pub fn png(&self, image: &Decoded, right: bool, how: Interpolation) -> Vec<u8> {
        let map = if right { &self.right } else { &self.left };
        let (w, h) = (map.width, map.height);
        let g = &image.grey;
        if has_colour(image) {
            let rgb = image.rgb.as_deref().unwrap_or_default();
            let out = remap::remap_fixed(
                RawImage {
                    width: g.width,
                    height: g.height,
                    channels: 3,
                    data: rgb,
                },
                map,
                how,
            );
            return encode::png_rgb(w, h, &out);
        }
        let out = remap::remap_fixed(RawImage::grey(g), map, how);
        if g.data.iter().all(|v| v % 257 == 0) {
            // Exact for 8-bit frames (v = 257·g); rounded for the in-between levels remapping
            // made.
            let bytes: Vec<u8> = out
                .iter()
                .map(|&v| ((u32::from(v) + 128) / 257) as u8)
                .collect();
            encode::png_grey(w, h, &bytes)
        } else {
            encode::png16(w, h, &out)
        }
    }

    /// Both rectified frames side by side in colour as PNG, with a green line every 32 rows
    /// (rows that line up are what rectification is for).
    pub fn side_by_side_png(&self, left: &Decoded, right: &Decoded, how: Interpolation) -> Vec<u8> {
        let rgb = |d: &Decoded, map| {
            let g = &d.grey;
            remap::remap_fixed(
                RawImage {
                    width: g.width,
                    height: g.height,
                    channels: 3,
                    data: d.rgb.as_deref().unwrap_or_default(),
                },
                map,
                how,
            )
        };
        let (l, r) = rayon::join(|| rgb(left, &self.left), || rgb(right, &self.right));
        let (w, h) = (self.left.width, self.left.height);
        let mut out = vec![0u8; w * 2 * h * 3];
        for y in 0..h {
            let row = &mut out[y * w * 6..(y + 1) * w * 6];
            row[..w * 3].copy_from_slice(&l[y * w * 3..(y + 1) * w * 3]);
            row[w * 3..].copy_from_slice(&r[y * w * 3..(y + 1) * w * 3]);
            if y % 32 == 16 {
                for p in row.chunks_exact_mut(3) {
                    p.copy_from_slice(&[0, 255, 0]);
                }
            }
        }
        encode::png_rgb(w * 2, h, &out)
    }

    /// Raw grey frames rectified the other way round: `right` through the left camera's map
    /// and `left` through the right's, as if the cameras had been sent swapped.
    pub fn swapped_grey(&self, left: &Gray, right: &Gray) -> (Gray, Gray) {
        let grey = |g: &Gray, map: &Fixed| {
            Gray::new(
                map.width,
                map.height,
                remap::remap_fixed(RawImage::grey(g), map, Interpolation::Linear),
            )
        };
        rayon::join(|| grey(right, &self.left), || grey(left, &self.right))
    }

    /// The share of each rectified image that raw frames of `(width, height)` fill, to 4
    /// decimals, left and right.
    pub fn valid_shares(&self, (width, height): (usize, usize)) -> [f64; 2] {
        [&self.left, &self.right].map(|m| (m.valid_share(width, height) * 1e4).round() / 1e4)
    }
}

/// Whether a decoded image has colour (any pixel whose channels differ).
fn has_colour(d: &Decoded) -> bool {
    d.rgb
        .as_deref()
        .is_some_and(|rgb| rgb.chunks_exact(3).any(|p| p[0] != p[1] || p[1] != p[2]))
}

/// Both cameras' float maps as NumPy's NPZ (`left_map_x`, `left_map_y`, `right_map_x`,
/// `right_map_y`, float32), what `cv2.remap` takes.
pub fn maps_npz(raw: &Raw) -> Result<Vec<u8>, String> {
    let (left, right) = float_maps(raw);
    let (w, h) = (left.size.width as usize, left.size.height as usize);
    let entries = [
        ("left_map_x", encode::npy(w, h, &left.x)),
        ("left_map_y", encode::npy(w, h, &left.y)),
        ("right_map_x", encode::npy(w, h, &right.x)),
        ("right_map_y", encode::npy(w, h, &right.y)),
    ];
    drop((left, right));
    encode::npz(&entries).map_err(|e| format!("the NPZ was not written: {e}"))
}
