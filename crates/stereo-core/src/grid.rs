//! Row-major pixel grids: a pixel's 4-connected neighbours, what every flood fill over an
//! image (a marker's dark blobs, the survey's holes) walks.

/// The indices of pixel `i`'s left, right, upper and lower neighbours that lie on a
/// `width × height` grid.
pub fn four_neighbours(i: usize, width: usize, height: usize) -> impl Iterator<Item = usize> {
    let (x, y) = (i % width, i / width);
    [
        (x > 0).then(|| i - 1),
        (x + 1 < width).then(|| i + 1),
        (y > 0).then(|| i - width),
        (y + 1 < height).then(|| i + width),
    ]
    .into_iter()
    .flatten()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A corner has two neighbours, an edge three, the inside four, all on the grid.
    #[test]
    fn neighbours_stay_on_the_grid() {
        assert_eq!(four_neighbours(0, 3, 3).collect::<Vec<_>>(), [1, 3]);
        assert_eq!(four_neighbours(1, 3, 3).collect::<Vec<_>>(), [0, 2, 4]);
        assert_eq!(four_neighbours(4, 3, 3).collect::<Vec<_>>(), [3, 5, 1, 7]);
        assert_eq!(four_neighbours(8, 3, 3).collect::<Vec<_>>(), [7, 5]);
    }
}
