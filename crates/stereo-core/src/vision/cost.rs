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

/// Pixels' grey levels at 8 bits (an image's, or some of its rows'), which the cost's
/// grey-level term compares.
pub fn levels_of(pixels: &[u16]) -> Vec<u8> {
    pixels.iter().map(|&v| (v >> 8) as u8).collect()
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
pub struct Volume<'a> {
    pub width: usize,
    pub height: usize,
    /// The smallest disparity of the range, in pixels.
    pub min: i32,
    /// How many disparities the range holds: `min .. min + count`.
    pub count: usize,
    pub windows: Windows,
    pub cells: Cells<'a>,
}

/// A volume's cells: stored, one byte a cell, or made a row at a time where a pass reaches
/// the row, from what they are made of. Made, no cell leaves the cache: a stored volume is
/// written to memory and read back (on Motorcycle at 64 disparities, 26 MB a call, half the
/// cost stage's time), where making a row again costs less than reading it.
#[derive(Debug)]
pub enum Cells<'a> {
    Stored(Vec<u8>),
    Made(Rows<'a>),
}

/// What a volume's cells are made of, a row at a time: both images' census signatures and
/// 8-bit grey levels over the volume's pixels, and the range `(min, count)`.
#[derive(Debug, Clone, Copy)]
pub struct Rows<'a> {
    pub census: (&'a [u64], &'a [u64]),
    pub grey: (&'a [u8], &'a [u8]),
    pub width: usize,
    pub range: (i32, usize),
}

impl Rows<'_> {
    /// The cells of row `y` over each pixel's window (`windows`), into `row` (exactly the row's
    /// cells).
    pub fn fill(&self, windows: &Windows, y: usize, row: &mut [u8]) {
        let (width, (min, count)) = (self.width, self.range);
        let pixels = y * width..(y + 1) * width;
        costs_of_row(
            (
                &self.census.0[pixels.clone()],
                &self.census.1[pixels.clone()],
            ),
            (&self.grey.0[pixels.clone()], &self.grey.1[pixels.clone()]),
            (min as i64, count),
            &windows.first[pixels.clone()],
            &windows.offsets[pixels.start..=pixels.end],
            row,
        );
    }
}

impl Volume<'_> {
    /// The cells of row `y`, each pixel's window in turn: the stored ones, or made into
    /// `buffer` (at least the row's length).
    pub fn row<'b>(&'b self, y: usize, buffer: &'b mut [u8]) -> &'b [u8] {
        let w = self.width;
        let cells =
            self.windows.offsets[y * w] as usize..self.windows.offsets[(y + 1) * w] as usize;
        match &self.cells {
            Cells::Stored(data) => &data[cells],
            Cells::Made(rows) => {
                let row = &mut buffer[..cells.len()];
                rows.fill(&self.windows, y, row);
                row
            }
        }
    }

    /// The costs of pixel `(x, y)`, one per disparity of its window, and the window's first
    /// index; `buffer` holds its row when the cells are made.
    pub fn at<'b>(&'b self, x: usize, y: usize, buffer: &'b mut [u8]) -> (usize, &'b [u8]) {
        let (first, cells) = self.windows.of(y * self.width + x);
        let start = self.windows.offsets[y * self.width] as usize;
        let row = self.row(y, buffer);
        (first, &row[cells.start - start..cells.end - start])
    }
}

/// The cost volume made of `rows` over `height` rows, each pixel over its window, every cell
/// stored.
pub fn volume<'a>(rows: Rows<'a>, height: usize, windows: Windows) -> Volume<'a> {
    let mut data = vec![0; windows.cells()];
    let width = rows.width;
    let mut each: Vec<&mut [u8]> = Vec::with_capacity(height);
    let mut rest = &mut data[..];
    for y in 0..height {
        let cells = windows.offsets[(y + 1) * width] - windows.offsets[y * width];
        let (row, after) = rest.split_at_mut(cells as usize);
        each.push(row);
        rest = after;
    }
    each.into_par_iter()
        .enumerate()
        .for_each(|(y, row)| rows.fill(&windows, y, row));
    Volume {
        width,
        height,
        min: rows.range.0,
        count: rows.range.1,
        windows,
        cells: Cells::Stored(data),
    }
}

/// The cost volume made of `rows` over `height` rows, each pixel over its window, its cells
/// made a row at a time where a pass reads them ([`Cells::Made`]).
pub fn made<'a>(rows: Rows<'a>, height: usize, windows: Windows) -> Volume<'a> {
    Volume {
        width: rows.width,
        height,
        min: rows.range.0,
        count: rows.range.1,
        windows,
        cells: Cells::Made(rows),
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
            fill_any(padding, PAD);
            let (sig, level) = (left[x], grey.0[x]);
            // j such that 0 <= x - min - j < width, as k = j - f within the window.
            let xi = x as i64;
            let lo = (xi - min - width + 1 - f).clamp(0, valid as i64) as usize;
            let end = (xi - min + 1 - f).clamp(lo as i64, valid as i64) as usize;
            fill_any(&mut cells[..lo], OUTSIDE);
            fill_any(&mut cells[end..], OUTSIDE);
            if lo < end {
                // Right pixels from x − min − f − lo down to x − min − f − (end − 1).
                // In the reversed row, right pixel i is at w − 1 − i.
                let hi = (xi - min - f - lo as i64) as usize;
                let at = w - 1 - hi;
                let n = end - lo;
                let cells = &mut cells[lo..end];
                let (census, greys) = (&right_rev[at..at + n], &grey_rev[at..at + n]);
                // Whole chunks of 32 cells with both terms in registers, each cell stored once
                // (a chunk's popcounts stored a lane group at a time and read back whole would
                // wait for the stores), then the rest.
                let mut chunks = cells.chunks_exact_mut(CHUNK);
                for ((cells, census), greys) in (&mut chunks)
                    .zip(census.chunks_exact(CHUNK))
                    .zip(greys.chunks_exact(CHUNK))
                {
                    let mut counts = [0u8; CHUNK];
                    for (count, &r) in counts.iter_mut().zip(census) {
                        *count = (sig ^ r).count_ones() as u8;
                    }
                    for ((cell, &count), &g) in cells.iter_mut().zip(&counts).zip(greys) {
                        *cell = count + grey_term(level, g);
                    }
                }
                let done = n / CHUNK * CHUNK;
                let cells = chunks.into_remainder();
                for (cell, &r) in cells.iter_mut().zip(&census[done..]) {
                    *cell = (sig ^ r).count_ones() as u8;
                }
                for (cell, &g) in cells.iter_mut().zip(&greys[done..]) {
                    *cell += grey_term(level, g);
                }
            }
        }
    }
}

/// The cells [`costs_of_row`] makes together, both terms in registers.
const CHUNK: usize = 32;

/// The grey-level term of a cell: half the absolute difference of the two 8-bit levels, capped
/// at [`AD_CAP`], on bytes (the difference as the greater less the smaller: `abs_diff` was
/// widened to 32-bit lanes, a quarter of a register's bytes).
#[inline(always)]
fn grey_term(a: u8, b: u8) -> u8 {
    ((a.max(b) - a.min(b)) >> 1).min(AD_CAP)
}

/// `cells` set to `value`, without a call when there is nothing to set: a `fill` is a call to
/// `memset`, and most of a row's pixels have no padding and reach no edge (three empty calls a
/// pixel were 3 % of the matcher's CPU).
#[inline(always)]
fn fill_any(cells: &mut [u8], value: u8) {
    if !cells.is_empty() {
        cells.fill(value);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stored volume of one row of `width` pixels.
    fn row_volume<'a>(
        census: (&'a [u64], &'a [u64]),
        grey: (&'a [u8], &'a [u8]),
        width: usize,
        range: (i32, usize),
        windows: Windows,
    ) -> Volume<'a> {
        let rows = Rows {
            census,
            grey,
            width,
            range,
        };
        volume(rows, 1, windows)
    }

    /// Pixel `x`'s window's first index and cells, in row 0.
    fn cells(v: &Volume, x: usize) -> (usize, Vec<u8>) {
        let mut buffer = vec![0; v.windows.cells()];
        let (first, cells) = v.at(x, 0, &mut buffer);
        (first, cells.to_vec())
    }

    /// Each cell is the Hamming distance to the right pixel `d` to the left, and cells whose
    /// right pixel is outside the image or past the range hold their constants.
    #[test]
    fn cells_are_hamming_distances() {
        let left = [0b1111u64, 0b1010, 0b0000];
        let right = [0b0000u64, 0b1111, 0b1000];
        let flat = [100u8; 3];
        let v = row_volume(
            (&left, &right),
            (&flat, &flat),
            3,
            (0, 2),
            Windows::full(3, 2),
        );
        assert_eq!(v.windows.cells(), 48);
        assert_eq!(&cells(&v, 0).1[..3], &[4, OUTSIDE, PAD]);
        assert_eq!(&cells(&v, 1).1[..2], &[2, 2]);
        assert_eq!(&cells(&v, 2).1[..2], &[1, 4]);
    }

    /// The grey-level term adds half the absolute difference, capped at AD_CAP.
    #[test]
    fn grey_levels_add_their_capped_difference() {
        let sig = [0u64; 2];
        let v = row_volume(
            (&sig, &sig),
            (&[0, 10], &[200, 3]),
            2,
            (0, 2),
            Windows::full(2, 2),
        );
        // Pixel 1 against right pixels 1 (|10 − 3| / 2 = 3) and 0 (|10 − 200| / 2, capped).
        assert_eq!(&cells(&v, 1).1[..2], &[3, AD_CAP]);
        assert_eq!(&cells(&v, 0).1[..2], &[AD_CAP, OUTSIDE]);
    }

    /// Every cell of a row whose runs of right pixels span whole chunks and a rest (the range
    /// 80, runs up to 80 cells: two chunks of [`CHUNK`] and 16) is its definition: the
    /// signatures' Hamming distance plus half the grey levels' difference capped at
    /// [`AD_CAP`], [`OUTSIDE`] where the right pixel is outside the image, [`PAD`] past the
    /// range; at a negative least disparity too.
    #[test]
    fn long_runs_hold_each_cells_definition() {
        let w = 100;
        let mut rng = crate::vision::synthetic::Rng::new(17);
        let mut draw = || (rng.unit() * f32::from(u16::MAX)) as u64;
        let left: Vec<u64> = (0..w)
            .map(|_| draw() << 48 | draw() << 16 | draw())
            .collect();
        let right: Vec<u64> = (0..w)
            .map(|_| draw() << 40 | draw() << 8 | draw())
            .collect();
        let gl: Vec<u8> = (0..w).map(|_| (draw() >> 8) as u8).collect();
        let gr: Vec<u8> = (0..w).map(|_| (draw() >> 8) as u8).collect();
        for min in [0i32, -5] {
            let count = 80;
            let v = row_volume(
                (&left, &right),
                (&gl, &gr),
                w,
                (min, count),
                Windows::full(w, count),
            );
            let mut runs = 0;
            for x in 0..w {
                let (first, got) = cells(&v, x);
                assert_eq!(first, 0);
                let expected: Vec<u8> = (0..got.len())
                    .map(|j| {
                        let r = x as i32 - min - j as i32;
                        if j >= count {
                            PAD
                        } else if !(0..w as i32).contains(&r) {
                            OUTSIDE
                        } else {
                            let r = r as usize;
                            let hamming = (left[x] ^ right[r]).count_ones() as u8;
                            let half = (i16::from(gl[x]) - i16::from(gr[r])).unsigned_abs() / 2;
                            hamming + (half as u8).min(AD_CAP)
                        }
                    })
                    .collect();
                assert_eq!(got, expected, "pixel {x}, least disparity {min}");
                runs += usize::from(got.iter().filter(|&&c| c != OUTSIDE && c != PAD).count() > 64);
            }
            // Runs long enough for two chunks and a rest.
            assert!(runs > 10, "{runs}");
        }
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
        let full = row_volume(both.0, both.1, 40, (-3, 30), Windows::full(40, 30));
        let narrow = Windows::from_lengths(vec![20; 40], std::iter::repeat_n(16, 40));
        let part = row_volume(both.0, both.1, 40, (-3, 30), narrow);
        for x in 0..40 {
            let (f, here) = cells(&part, x);
            assert_eq!(f, 20);
            assert_eq!(&here[..10], &cells(&full, x).1[20..30], "pixel {x}");
            assert!(here[10..].iter().all(|&c| c == PAD));
        }
    }

    /// Cells made a row at a time are the stored volume's, row by row, over per-pixel windows.
    #[test]
    fn made_rows_are_the_stored_ones() {
        let (w, h) = (29, 5);
        let left: Vec<u64> = (0..(w * h) as u64)
            .map(|i| i.wrapping_mul(0x9E37_79B9_7F4A_7C15))
            .collect();
        let right: Vec<u64> = left.iter().map(|v| v.rotate_left(3) ^ 0x55).collect();
        let grey: Vec<u8> = (0..w * h).map(|i| (i * 37 % 251) as u8).collect();
        let rows = Rows {
            census: (&left, &right),
            grey: (&grey, &grey),
            width: w,
            range: (2, 40),
        };
        let windows = || {
            Windows::from_lengths(
                (0..w * h).map(|i| (i % 3 * 8) as u16).collect(),
                (0..w * h).map(|i| if i % 2 == 0 { 16 } else { 32 }),
            )
        };
        let stored = volume(rows, h, windows());
        let made = made(rows, h, windows());
        let (mut a, mut b) = (
            vec![0; stored.windows.cells()],
            vec![0; made.windows.cells()],
        );
        for y in 0..h {
            assert_eq!(stored.row(y, &mut a), made.row(y, &mut b), "row {y}");
        }
    }
}
