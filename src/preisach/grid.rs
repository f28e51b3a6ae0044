//! Grid size and the one cell-indexing convention (see the module docs of [`crate::preisach`]).

/// Number of equal input intervals of the Preisach grid (the paper's discretization level).
pub const LEVELS: usize = 25;

/// Number of cells: `LEVELS (LEVELS + 1) / 2` (300 squares and 25 diagonal half-squares).
pub const CELL_COUNT: usize = LEVELS * (LEVELS + 1) / 2;

/// Index of cell `(i, j)` (β in interval `i`, α in interval `j`, `i <= j`) in a weight vector:
/// alpha-major, `j (j + 1) / 2 + i`.
pub const fn cell_index(i: usize, j: usize) -> usize {
    j * (j + 1) / 2 + i
}

/// The cell `(i, j)` stored at `index` (inverse of [`cell_index`]); `None` past the last cell.
pub const fn cell_of_index(index: usize) -> Option<(usize, usize)> {
    let mut j = 0;
    while j < LEVELS {
        let first = j * (j + 1) / 2;
        if index < first + j + 1 {
            return Some((index - first, j));
        }
        j += 1;
    }
    None
}
