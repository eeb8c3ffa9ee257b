//! The horizontal stripes the matcher works in, side by side on the cores, and the memory it
//! holds at its peak: how tall a stripe is for an image's width and range, and the bytes a
//! pair needs, reserved from the service's budget before a request is decoded.

use std::ops::Range;

use super::{cost, pyramid};

/// Rows a stripe keeps at most: the image is matched in horizontal stripes of this many rows
/// (fewer for a wide image searching a wide window, [`rows`]), side by side on the cores. The
/// count depends on the image's width and the range alone, so a pair gives the same map on
/// any machine.
pub const STRIPE_ROWS: usize = 256;
/// Rows of context above and below a stripe, matched but not kept, so that the vertical and
/// diagonal paths reach a stripe's edge rows from outside it (their influence fades within a
/// few dozen rows).
pub const STRIPE_MARGIN: usize = 24;

/// Rows a stripe keeps at most below the pyramid's coarsest level, where each pixel searches a
/// window ([`pyramid`]): half as many, so that the stripes in flight hold half the memory.
pub const NARROW_STRIPE_ROWS: usize = STRIPE_ROWS / 2;

/// The most bytes one stripe holds while it is matched (the first pass's sums and its windows,
/// [`BYTES_A_CELL`] and [`BYTES_A_PIXEL`]), context rows included. A stripe of
/// [`STRIPE_ROWS`] rows over a 1920-pixel row at 64 disparities holds 94 MB; a phone's
/// 4032-pixel row at the same range would hold 200 MB a stripe, two in flight, which with the
/// per-pixel buffers passes the default 1 GiB budget. So a stripe that would hold more is made
/// shorter ([`rows`]): at 4032 × 64 it keeps 106 rows, matching 154.
pub const STRIPE_BYTES: usize = 96 << 20;
/// The fewest rows a stripe keeps, however wide the image and its window: below it the
/// context rows would be more than half of what is matched.
pub const MIN_STRIPE_ROWS: usize = 48;
/// What a stripe holds for each cell of its volume: the first pass's sums (two bytes; the
/// 8-path aggregation's, which a pair may need). The costs themselves are made a row at a time
/// where the passes read them ([`super::cost::Cells::Made`]), never stored.
pub const BYTES_A_CELL: usize = 2;
/// What a stripe holds for each of its pixels besides its cells: the window's first index and
/// offset (six bytes, eight counted), both images' census signatures (16), the left image's
/// census centres and both images' 8-bit grey levels (6), and while the signatures are made,
/// the padded rows and the right image's centres (4). Each stripe makes its own signatures
/// ([`super::census::transform_rows`]), so no image's are held whole.
pub const BYTES_A_PIXEL: usize = 34;
/// What the matcher holds for each pixel of the finest level besides its stripes, at the
/// larger of its two phases. While the stripes are matched: the disparities and the winners'
/// variances they write in place (8), and the coarser level's prior and halved images (under
/// 4). Then the filters: the map, its variances, and the speckle filter's runs (20 at most,
/// where every pixel is a run of its own, [`super::filters::speckles`]; far less on a map of
/// surfaces), σ and the plane fill's masks after the variances go
/// (under 14), the fill's mask (1). Counted with room: measured, a 24 MP pair's peak is
/// 19 bytes a pixel with its stripes (docs/matcher.md).
const BYTES_A_FINE_PIXEL: usize = 24;

/// Rows a stripe keeps over a level `width` pixels wide whose pixels search `window` cells:
/// [`STRIPE_ROWS`] (or [`NARROW_STRIPE_ROWS`] when `narrow`, below the coarsest level), fewer
/// when that stripe would hold more than [`STRIPE_BYTES`], and never fewer than
/// [`MIN_STRIPE_ROWS`].
pub fn rows(width: usize, window: usize, narrow: bool) -> usize {
    let most = if narrow {
        NARROW_STRIPE_ROWS
    } else {
        STRIPE_ROWS
    };
    let per_row = width
        .saturating_mul(
            window
                .saturating_mul(BYTES_A_CELL)
                .saturating_add(BYTES_A_PIXEL),
        )
        .max(1);
    (STRIPE_BYTES / per_row)
        .saturating_sub(2 * STRIPE_MARGIN)
        .clamp(MIN_STRIPE_ROWS, most)
}

/// How many stripes of `rows` rows an image `height` rows tall has ([`stripes`]).
fn count(height: usize, rows: usize) -> usize {
    let n = height.div_ceil(rows.max(1));
    if n > 1 && height - (n - 1) * rows < rows / 4 {
        n - 1
    } else {
        n
    }
}

/// Stripe `i` of the `n` of an image `height` rows tall, `rows` rows a stripe: `(rows kept,
/// rows matched)`.
fn stripe(i: usize, n: usize, height: usize, rows: usize) -> (Range<usize>, Range<usize>) {
    let start = i * rows;
    let end = if i + 1 == n {
        height
    } else {
        (start + rows).min(height)
    };
    let context = start.saturating_sub(STRIPE_MARGIN)..(end + STRIPE_MARGIN).min(height);
    (start..end, context)
}

/// The stripes of an image `height` rows tall, `rows` rows a stripe: `(rows kept, rows
/// matched)`, the second containing the first. A last stripe shorter than a quarter of `rows`
/// joins the one before it.
pub fn stripes(height: usize, rows: usize) -> Vec<(Range<usize>, Range<usize>)> {
    let n = count(height, rows);
    (0..n).map(|i| stripe(i, n, height, rows)).collect()
}

/// The most rows any stripe matches: the first, second and last stripes are the only ones
/// whose context differs.
fn tallest(height: usize, rows: usize) -> usize {
    let n = count(height, rows);
    [0, 1, n.saturating_sub(2), n.saturating_sub(1)]
        .into_iter()
        .filter(|&i| i < n)
        .map(|i| stripe(i, n, height, rows).1.len())
        .max()
        .unwrap_or(0)
}

/// The bytes the matcher holds at its peak for a `width × height` pair searching `count`
/// disparities (`range`), over the levels of its pyramid ([`pyramid`]): [`BYTES_A_FINE_PIXEL`] for each
/// pixel of the finest level, and, for the level whose stripes hold the most, each stripe in
/// flight at once (one a core, [`rows`] rows tall). Below the coarsest level a pixel's window
/// holds at most [`pyramid::MAX_WINDOW`] cells, whatever the range.
///
/// A faint pair's further levels ([`pyramid::levels`]) are not counted: they turn the
/// coarsest level counted here into one of per-pixel windows, on fewer rows a stripe, and add
/// smaller ones, so they hold less.
fn peak(width: usize, height: usize, range: usize) -> usize {
    let levels = pyramid::levels(width, height, range, false);
    let (mut w, mut h, mut n) = (width, height, range);
    let mut stripes_peak = 0usize;
    for level in 0..=levels {
        let narrow = level < levels;
        let window = if narrow {
            pyramid::MAX_WINDOW.min(cost::stride(n))
        } else {
            cost::stride(n)
        };
        let tall = rows(w, window, narrow);
        // At most one stripe a thread: this holds only because `match_stripe` (and
        // `census::transform_rows` in it) runs no nested rayon job, in which a waiting thread
        // could take up another stripe and hold its memory too.
        let in_flight = count(h, tall).min(rayon::current_num_threads()).max(1);
        let held = w
            .saturating_mul(tallest(h, tall))
            .saturating_mul(
                window
                    .saturating_mul(BYTES_A_CELL)
                    .saturating_add(BYTES_A_PIXEL),
            )
            .saturating_mul(in_flight);
        stripes_peak = stripes_peak.max(held);
        (w, h, n) = (w.div_ceil(2), h.div_ceil(2), pyramid::halve_range(0, n).1);
    }
    width
        .saturating_mul(height)
        .saturating_mul(BYTES_A_FINE_PIXEL)
        .saturating_add(stripes_peak)
}

/// The bytes a `width × height` pair searching `count` disparities is charged: the most the
/// matcher holds at its peak ([`peak`]) over this range and every narrower one, so that what
/// a request needs never grows when its range narrows. (A range just wider than the widest
/// searched whole, [`pyramid::WHOLE`] or [`pyramid::NARROW`] past [`pyramid::WHOLE_CELLS`],
/// is matched coarse to fine and holds less than one just narrower, searched whole at full
/// size; such a range is charged the narrower one's peak.)
pub fn bytes_needed(width: usize, height: usize, count: usize) -> usize {
    (1..=count.max(1))
        .map(|c| peak(width, height, c))
        .max()
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stripes cover the image once, each kept range inside its context with the margin
    /// on both sides where the image allows, and a short last stripe joins the one before.
    #[test]
    fn stripes_cover_the_image_once() {
        for (height, rows) in [(500, 256), (3024, 76), (100, 256), (300, 128), (257, 256)] {
            let all = stripes(height, rows);
            let mut next = 0;
            for (kept, context) in &all {
                assert_eq!(kept.start, next);
                next = kept.end;
                assert_eq!(context.start, kept.start.saturating_sub(STRIPE_MARGIN));
                assert_eq!(context.end, (kept.end + STRIPE_MARGIN).min(height));
            }
            assert_eq!(next, height);
            let last = &all[all.len() - 1].0;
            assert!(all.len() == 1 || last.len() >= rows / 4, "{height} {rows}");
            let most = all.iter().map(|(_, c)| c.len()).max().unwrap();
            assert_eq!(tallest(height, rows), most, "{height} {rows}");
        }
        assert_eq!(stripes(257, 256).len(), 1);
    }

    /// A stripe is as tall as before up to 1080p at 64 disparities, shorter for a phone's
    /// 4032-pixel rows, and never under the floor.
    #[test]
    fn wide_rows_make_shorter_stripes() {
        assert_eq!(rows(741, 64, false), STRIPE_ROWS);
        assert_eq!(rows(1280, 64, false), STRIPE_ROWS);
        assert_eq!(rows(1920, 64, false), STRIPE_ROWS);
        assert_eq!(rows(1280, 48, true), NARROW_STRIPE_ROWS);
        assert_eq!(rows(4032, 64, false), 106);
        assert!(rows(4032, 48, true) <= NARROW_STRIPE_ROWS);
        assert_eq!(rows(8192, 512, false), MIN_STRIPE_ROWS);
        for (w, window) in [(1920, 64), (4032, 32), (4032, 64), (6000, 48)] {
            let per_row = w * (BYTES_A_CELL * window + BYTES_A_PIXEL);
            let held = (rows(w, window, false) + 2 * STRIPE_MARGIN) * per_row;
            assert!(held <= STRIPE_BYTES, "{w} {window}: {held}");
        }
    }

    /// What a pair is charged never grows as its range narrows, at every size from a
    /// quarter-size Middlebury pair to 24 MP, though the peak itself does (128 disparities
    /// searched whole against 129 coarse to fine).
    #[test]
    fn the_charge_never_grows_as_the_range_narrows() {
        for (w, h) in [(741, 500), (1280, 720), (4032, 3024), (6000, 4000)] {
            let mut before = 0;
            for count in 1..=512 {
                let now = bytes_needed(w, h, count);
                assert!(
                    now >= before,
                    "{w} × {h}: {count} needs {now}, {} {before}",
                    count - 1
                );
                assert!(now >= peak(w, h, count));
                before = now;
            }
        }
        assert!(peak(741, 500, 128) > peak(741, 500, 129));
        assert!(peak(4032, 3024, 64) > peak(4032, 3024, 65));
        assert!(peak(741, 500, 64) < peak(741, 500, 128));
    }
}
