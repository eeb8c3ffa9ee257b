//! The matching cost volume: for every left pixel and every disparity searched, how unlike the
//! right pixel it would match are their census signatures (Hamming distance, 0 to 62).
//!
//! Layout, as OpenCV's `stereosgbm.cpp` lays out its `C` buffer: row-major pixels, and for each
//! pixel its disparities contiguous (`[y][x][d]`), padded to a multiple of [`LANES`] so that the
//! aggregation's inner loop over `d` runs on whole SIMD registers. One byte a cell.

use rayon::prelude::*;

use super::census;

/// The disparity axis is padded to a multiple of this many cells (one AVX2 register of `u16`).
pub const LANES: usize = 16;

/// The cost of a disparity whose right pixel falls outside the right image: a little worse than
/// an average mismatch of random texture (half the bits), so that a border pixel prefers any
/// real match that is better than chance, and path costs are not dragged far off by the border.
pub const OUTSIDE: u8 = (census::BITS * 5 / 8) as u8;

/// The cost of the padding cells past the last disparity searched: never chosen.
pub const PAD: u8 = 2 * census::BITS as u8;

/// A cost volume of `width × height × stride` cells; disparity `min + k` at index `k`.
#[derive(Debug)]
pub struct Volume {
    pub width: usize,
    pub height: usize,
    /// The smallest disparity searched, in pixels.
    pub min: i32,
    /// How many disparities are searched: `min ..  min + count`.
    pub count: usize,
    /// Cells per pixel: `count` rounded up to a multiple of [`LANES`].
    pub stride: usize,
    pub data: Vec<u8>,
}

/// `count` rounded up to whole SIMD registers.
pub fn stride(count: usize) -> usize {
    count.div_ceil(LANES) * LANES
}

impl Volume {
    /// The costs of pixel `(x, y)`, one per padded disparity.
    pub fn at(&self, x: usize, y: usize) -> &[u8] {
        let start = (y * self.width + x) * self.stride;
        &self.data[start..start + self.stride]
    }
}

/// The cost volume of two census-transformed images of `width × height`.
pub fn volume(
    left: &[u64],
    right: &[u64],
    width: usize,
    height: usize,
    min: i32,
    count: usize,
) -> Volume {
    let stride = stride(count);
    // Every cell is written below, the padding past `count` included.
    let mut data = super::huge_pages::zeroed(width * height * stride);
    data.par_chunks_mut(width * stride)
        .enumerate()
        .for_each(|(y, row)| {
            costs_of_row(
                &left[y * width..(y + 1) * width],
                &right[y * width..(y + 1) * width],
                min as i64,
                count,
                row,
            );
        });
    Volume {
        width,
        height,
        min,
        count,
        stride,
        data,
    }
}

crate::dispatch! {
    /// One row of the volume. For pixel `x`, the disparities whose right pixel `x − d` is inside
    /// the image form one run of `k`, computed in one branch-free loop (vectorised popcounts);
    /// the rest are [`OUTSIDE`].
    fn costs_of_row(left: &[u64], right: &[u64], min: i64, count: usize, row: &mut [u8]) {
        let width = left.len() as i64;
        let stride = row.len() / left.len();
        for (x, cells) in row.chunks_exact_mut(stride).enumerate() {
            let (cells, padding) = cells.split_at_mut(count);
            padding.fill(PAD);
            let sig = left[x];
            // k such that 0 <= x - min - k < width.
            let first = (x as i64 - min - width + 1).clamp(0, count as i64) as usize;
            let end = (x as i64 - min + 1).clamp(first as i64, count as i64) as usize;
            cells[..first].fill(OUTSIDE);
            cells[end..].fill(OUTSIDE);
            if first < end {
                // Right pixels from x − min − first down to x − min − (end − 1).
                let hi = (x as i64 - min - first as i64) as usize;
                let lo = hi + 1 - (end - first);
                let run = &right[lo..=hi];
                for (cell, &r) in cells[first..end].iter_mut().zip(run.iter().rev()) {
                    *cell = (sig ^ r).count_ones() as u8;
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
        let v = volume(&left, &right, 3, 1, 0, 2);
        assert_eq!(v.stride, 16);
        assert_eq!(&v.at(0, 0)[..3], &[4, OUTSIDE, PAD]);
        assert_eq!(&v.at(1, 0)[..2], &[2, 2]);
        assert_eq!(&v.at(2, 0)[..2], &[1, 4]);
    }
}
