//! The census transform: each pixel becomes a 62-bit signature of which of its 9 × 7
//! neighbours are darker than it, so that matching compares local structure (Hamming distance)
//! instead of brightness, and a gain or offset between the two cameras changes nothing.

use rayon::prelude::*;

use super::Gray;

/// Width of the census window (odd).
pub const WIDTH: usize = 9;
/// Height of the census window (odd).
pub const HEIGHT: usize = 7;
/// Bits in a signature: every pixel of the window but the centre.
pub const BITS: u32 = (WIDTH * HEIGHT - 1) as u32;

/// The census signature of every pixel, row-major. Pixels past the border repeat the border.
pub fn transform(image: &Gray) -> Vec<u64> {
    let (w, h) = (image.width, image.height);
    let (rx, ry) = (WIDTH / 2, HEIGHT / 2);
    // The image with its border repeated, so that the inner loop never clamps.
    let pw = w + 2 * rx;
    let mut padded = vec![0u16; pw * (h + 2 * ry)];
    padded.par_chunks_mut(pw).enumerate().for_each(|(py, row)| {
        let y = py.saturating_sub(ry).min(h - 1);
        let src = &image.data[y * w..(y + 1) * w];
        for (px, out) in row.iter_mut().enumerate() {
            *out = src[px.saturating_sub(rx).min(w - 1)];
        }
    });
    let mut out = vec![0u64; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        signatures(&padded, pw, y, row);
    });
    out
}

crate::dispatch! {
    /// The signatures of row `y`, one window offset at a time across the whole row, so that
    /// the comparisons run on whole vectors of pixels. The first half of the bits (31) is
    /// gathered in one `u32` a pixel and the other half in another (twice the lanes of a `u64`), then joined.
    fn signatures(padded: &[u16], pw: usize, y: usize, row: &mut [u64]) {
        const HALF: usize = BITS as usize / 2;
        let (rx, ry) = (WIDTH / 2, HEIGHT / 2);
        let w = row.len();
        let centre = &padded[(y + ry) * pw + rx..(y + ry) * pw + rx + w];
        let offsets = (0..HEIGHT)
            .flat_map(|wy| (0..WIDTH).map(move |wx| (wy, wx)))
            .filter(|&(wy, wx)| (wy, wx) != (ry, rx));
        let mut halves = [vec![0u32; w], vec![0u32; w]];
        for (i, (wy, wx)) in offsets.enumerate() {
            let half = &mut halves[i / HALF];
            let line = &padded[(y + wy) * pw + wx..(y + wy) * pw + wx + w];
            for ((bits, &v), &c) in half.iter_mut().zip(line).zip(centre) {
                *bits = (*bits << 1) | u32::from(v < c);
            }
        }
        for ((sig, &hi), &lo) in row.iter_mut().zip(&halves[0]).zip(&halves[1]) {
            *sig = (u64::from(hi) << HALF) | u64::from(lo);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat image has no structure: every signature is zero.
    #[test]
    fn flat_image_has_empty_signatures() {
        let image = Gray::new(12, 10, vec![500; 120]);
        assert!(transform(&image).iter().all(|&s| s == 0));
    }

    /// A pixel brighter than all its neighbours sets all 62 bits; its neighbours see it as
    /// not darker, so their bit for it stays clear.
    #[test]
    fn a_bright_peak_sets_every_bit() {
        let mut data = vec![100u16; 15 * 11];
        data[5 * 15 + 7] = 200;
        let sig = transform(&Gray::new(15, 11, data));
        assert_eq!(sig[5 * 15 + 7].count_ones(), BITS);
        assert_eq!(sig[5 * 15 + 6], 0);
    }
}
