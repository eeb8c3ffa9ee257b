//! The matching cost volume: for every left pixel and every disparity it searches, how unlike
//! the right pixel it would match is: the Hamming distance of their census signatures (0 to
//! 62), plus half their absolute grey-level difference capped at [`AD_CAP`] (AD-Census, Mei et
//! al. 2011). The census compares a pixel's neighbours one by one, so sensor noise flips the
//! comparisons of near-equal ones; the grey levels themselves carry what noise does not erase.
//!
//! Layout, as OpenCV's `stereosgbm.cpp` lays out its `C` buffer: row-major pixels, and for each
//! pixel its disparities contiguous (`[y][x][d]`), so that the aggregation's inner loop over `d`
//! runs on whole SIMD registers. Each pixel searches its own window of the range ([`Windows`]):
//! the whole range at the coarsest level of the pyramid, a few registers around what the level
//! above found everywhere else, so that the cells a pixel costs do not grow with the range. A
//! window is a whole number of [`LANES`]; one byte a cell.

use rayon::prelude::*;

use super::census;

/// Windows are whole multiples of this many cells (one AVX2 register of `u16`).
pub const LANES: usize = 16;

/// The most the grey-level term adds: half the absolute difference of 8-bit grey levels, capped
/// here, so that a few very different pixels (a specular highlight, an occlusion) do not
/// outweigh the census.
pub const AD_CAP: u8 = 16;

/// The census part of the cost of a disparity whose right pixel falls outside the right image:
/// a little worse than an average mismatch of random texture (half the bits), so that a border
/// pixel prefers any real match that is better than chance, and path costs are not dragged far
/// off by the border.
pub const OUTSIDE_CENSUS: u8 = (census::BITS * 5 / 8) as u8;

/// The cost of a disparity whose right pixel falls outside the right image: the census part
/// above and half the grey-level term's cap.
pub const OUTSIDE: u8 = OUTSIDE_CENSUS + AD_CAP / 2;

/// The cost of the cells of a window past the last disparity searched: never chosen (above any
/// real cost, 62 + 16).
pub const PAD: u8 = 2 * census::BITS as u8;
const _: () = assert!(PAD as u32 > census::BITS + AD_CAP as u32);

/// An image's grey levels at 8 bits, which the cost's grey-level term compares.
pub fn levels(image: &super::Gray) -> Vec<u8> {
    image.data.iter().map(|&v| (v >> 8) as u8).collect()
}

/// `count` rounded up to whole SIMD registers.
pub fn stride(count: usize) -> usize {
    count.div_ceil(LANES) * LANES
}

/// Which disparities each pixel of a `width × height` block searches: pixel `i` (row-major)
/// searches the indices `first[i] .. first[i] + len` of the range, `len` a multiple of
/// [`LANES`], and its cells are `offsets[i] .. offsets[i + 1]` of the volume.
#[derive(Debug, Clone, PartialEq)]
pub struct Windows {
    pub first: Vec<u16>,
    pub offsets: Vec<u32>,
}

impl Windows {
    /// Every one of `pixels` pixels searches the whole range of `count` disparities.
    pub fn full(pixels: usize, count: usize) -> Windows {
        let n = stride(count) as u32;
        Windows {
            first: vec![0; pixels],
            offsets: (0..=pixels as u32).map(|i| i * n).collect(),
        }
    }

    /// Windows from each pixel's first index and length (a multiple of [`LANES`]).
    pub fn from_lengths(first: Vec<u16>, lengths: impl Iterator<Item = u16>) -> Windows {
        let mut offsets = Vec::with_capacity(first.len() + 1);
        let mut at = 0u32;
        offsets.push(0);
        for len in lengths {
            at += u32::from(len);
            offsets.push(at);
        }
        debug_assert_eq!(offsets.len(), first.len() + 1);
        Windows { first, offsets }
    }

    /// Cells in all.
    pub fn cells(&self) -> usize {
        self.offsets.last().map_or(0, |&c| c as usize)
    }

    /// Pixel `i`'s first index and its cells.
    #[inline(always)]
    pub fn of(&self, i: usize) -> (usize, std::ops::Range<usize>) {
        (
            usize::from(self.first[i]),
            self.offsets[i] as usize..self.offsets[i + 1] as usize,
        )
    }
}

/// A cost volume of `width × height` pixels, each with its window of the range; disparity
/// `min + j` at index `j`.
#[derive(Debug)]
pub struct Volume {
    pub width: usize,
    pub height: usize,
    /// The smallest disparity of the range, in pixels.
    pub min: i32,
    /// How many disparities the range holds: `min .. min + count`.
    pub count: usize,
    pub windows: Windows,
    pub data: Vec<u8>,
}

impl Volume {
    /// The costs of pixel `(x, y)`, one per disparity of its window, and the window's first
    /// index.
    pub fn at(&self, x: usize, y: usize) -> (usize, &[u8]) {
        let (first, cells) = self.windows.of(y * self.width + x);
        (first, &self.data[cells])
    }
}

/// The cost volume of two images of `width × height` (their census signatures and 8-bit grey
/// levels, [`levels`]), each pixel over its window.
pub fn volume(
    (left, right): (&[u64], &[u64]),
    grey: (&[u8], &[u8]),
    width: usize,
    height: usize,
    (min, count): (i32, usize),
    windows: Windows,
) -> Volume {
    // Every cell is written below, those past `count` included.
    let mut data = super::huge_pages::BYTES.take(windows.cells());
    let mut rows: Vec<&mut [u8]> = Vec::with_capacity(height);
    let mut rest = &mut data[..];
    for y in 0..height {
        let cells = windows.offsets[(y + 1) * width] - windows.offsets[y * width];
        let (row, after) = rest.split_at_mut(cells as usize);
        rows.push(row);
        rest = after;
    }
    rows.into_par_iter().enumerate().for_each(|(y, row)| {
        let pixels = y * width..(y + 1) * width;
        costs_of_row(
            (&left[pixels.clone()], &right[pixels.clone()]),
            (&grey.0[pixels.clone()], &grey.1[pixels.clone()]),
            (min as i64, count),
            &windows.first[pixels.clone()],
            &windows.offsets[pixels.start..=pixels.end],
            row,
        );
    });
    Volume {
        width,
        height,
        min,
        count,
        windows,
        data,
    }
}

crate::dispatch! {
    /// One row of the volume. For pixel `x`, the indices `j` of its window whose right pixel
    /// `x − min − j` is inside the image and which are in the range form one run, computed in
    /// one branch-free loop (vectorised popcounts and differences); the rest are [`OUTSIDE`], or
    /// [`PAD`] past the range.
    wide fn costs_of_row(
        census: (&[u64], &[u64]),
        grey: (&[u8], &[u8]),
        range: (i64, usize),
        first: &[u16],
        offsets: &[u32],
        row: &mut [u8],
    ) {
        let (min, count) = range;
        let (left, right) = census;
        let width = left.len() as i64;
        let base = offsets[0] as usize;
        // The right row reversed, so that each pixel's run of right pixels (x − d for growing
        // d) is read forwards, on whole vectors.
        let right_rev: Vec<u64> = right.iter().rev().copied().collect();
        let grey_rev: Vec<u8> = grey.1.iter().rev().copied().collect();
        let w = left.len();
        for x in 0..w {
            let cells = &mut row[offsets[x] as usize - base..offsets[x + 1] as usize - base];
            let f = i64::from(first[x]);
            let len = cells.len() as i64;
            // Indices in the range: f .. f + valid.
            let valid = (count as i64 - f).clamp(0, len) as usize;
            let (cells, padding) = cells.split_at_mut(valid);
            padding.fill(PAD);
            let (sig, level) = (left[x], grey.0[x]);
            // j such that 0 <= x - min - j < width, as k = j - f within the window.
            let xi = x as i64;
            let lo = (xi - min - width + 1 - f).clamp(0, valid as i64) as usize;
            let end = (xi - min + 1 - f).clamp(lo as i64, valid as i64) as usize;
            cells[..lo].fill(OUTSIDE);
            cells[end..].fill(OUTSIDE);
            if lo < end {
                // Right pixels from x − min − f − lo down to x − min − f − (end − 1).
                // In the reversed row, right pixel i is at w − 1 − i.
                let hi = (xi - min - f - lo as i64) as usize;
                let at = w - 1 - hi;
                let n = end - lo;
                let cells = &mut cells[lo..end];
                for (cell, &r) in cells.iter_mut().zip(&right_rev[at..at + n]) {
                    *cell = (sig ^ r).count_ones() as u8;
                }
                // The grey-level term in a second loop, on bytes (32 to a vector).
                for (cell, &g) in cells.iter_mut().zip(&grey_rev[at..at + n]) {
                    *cell += (level.abs_diff(g) >> 1).min(AD_CAP);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each cell is the Hamming distance to the right pixel `d` to the left, and cells whose
    /// right pixel is outside the image or past the range hold their constants.
    #[test]
    fn cells_are_hamming_distances() {
        let left = [0b1111u64, 0b1010, 0b0000];
        let right = [0b0000u64, 0b1111, 0b1000];
        let flat = [100u8; 3];
        let v = volume(
            (&left, &right),
            (&flat, &flat),
            3,
            1,
            (0, 2),
            Windows::full(3, 2),
        );
        assert_eq!(v.windows.cells(), 48);
        assert_eq!(&v.at(0, 0).1[..3], &[4, OUTSIDE, PAD]);
        assert_eq!(&v.at(1, 0).1[..2], &[2, 2]);
        assert_eq!(&v.at(2, 0).1[..2], &[1, 4]);
    }

    /// The grey-level term adds half the absolute difference, capped at AD_CAP.
    #[test]
    fn grey_levels_add_their_capped_difference() {
        let sig = [0u64; 2];
        let v = volume(
            (&sig, &sig),
            (&[0, 10], &[200, 3]),
            2,
            1,
            (0, 2),
            Windows::full(2, 2),
        );
        // Pixel 1 against right pixels 1 (|10 − 3| / 2 = 3) and 0 (|10 − 200| / 2, capped).
        assert_eq!(&v.at(1, 0).1[..2], &[3, AD_CAP]);
        assert_eq!(&v.at(0, 0).1[..2], &[AD_CAP, OUTSIDE]);
    }

    /// A window that starts inside the range holds the same costs as the full range at the
    /// same disparities, and PAD past the range's end.
    #[test]
    fn a_window_holds_the_full_ranges_cells() {
        let left: Vec<u64> = (0..40u64)
            .map(|i| i.wrapping_mul(0x9E37_79B9_7F4A_7C15))
            .collect();
        let right: Vec<u64> = (0..40u64)
            .map(|i| i.wrapping_mul(0xC2B2_AE3D_27D4_EB4F))
            .collect();
        let (gl, gr): (Vec<u8>, Vec<u8>) = (0..40u8).map(|i| (i.wrapping_mul(7), i * 3)).unzip();
        let both = ((&left[..], &right[..]), (&gl[..], &gr[..]));
        let full = volume(both.0, both.1, 40, 1, (-3, 30), Windows::full(40, 30));
        let narrow = Windows::from_lengths(vec![20; 40], std::iter::repeat_n(16, 40));
        let part = volume(both.0, both.1, 40, 1, (-3, 30), narrow);
        for x in 0..40 {
            let (f, cells) = part.at(x, 0);
            assert_eq!(f, 20);
            assert_eq!(&cells[..10], &full.at(x, 0).1[20..30], "pixel {x}");
            assert!(cells[10..].iter().all(|&c| c == PAD));
        }
    }
}
