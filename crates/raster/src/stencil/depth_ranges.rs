//! Constant-time depth ranges over runs of blocks: a sparse table (the
//! range-minimum structure of Bender and Farach-Colton, "The LCA Problem
//! Revisited", 2000) over each band's row of block ranges.
//!
//! The hierarchical stencil's stage 1 asks, for every (piece, band) pair and
//! every (volume, band) pair, for `[min zmin, max zmax]` over the band's blocks
//! under the piece's pixel columns, to dismiss pieces that lie wholly on their
//! uncounted side [Aila04 §3.2.1]. Shadow-volume pieces are long slivers that
//! reach many bands, so the question is asked tens of thousands of times per
//! light; a fold over up to `width / 64` blocks per question was 3.5 % of the
//! default job's time. Level `j` of a row holds, per block `b`, the range over
//! blocks `b .. b + 2^j` (clamped at the row's end): any run of blocks is the
//! union of two overlapping runs of one level, and min and max are idempotent,
//! so a query reads two entries.

use crate::layout::BACKGROUND;

/// The empty range (no visited tile): `zmin = +∞`, `zmax = BACKGROUND`.
pub(crate) const EMPTY: [f32; 2] = [f32::INFINITY, BACKGROUND];

/// `[min, max]` of two ranges.
#[inline(always)]
pub(crate) fn union(a: [f32; 2], b: [f32; 2]) -> [f32; 2] {
    [a[0].min(b[0]), a[1].max(b[1])]
}

/// Levels above level 0 that rows of `n` entries need (`⌊log₂ n⌋`).
fn levels_above(n: usize) -> usize {
    n.max(1).ilog2() as usize
}

/// Sparse tables over rows of `n` ranges each: for row `r`, levels `1..=L`,
/// `L = ⌊log₂ n⌋` (level 0 is the row itself, kept by the caller).
#[derive(Clone, Debug, Default)]
pub(crate) struct DepthRanges {
    /// Per row, levels `1..=L`, each `n` entries.
    table: Vec<[f32; 2]>,
    n: usize,
}

impl DepthRanges {
    /// Rebuilds the tables for `rows` (a whole number of rows of `n` ranges),
    /// in the existing storage.
    pub fn build(&mut self, rows: &[[f32; 2]], n: usize) {
        self.n = n;
        self.table.clear();
        if n == 0 {
            return;
        }
        let levels = levels_above(n);
        self.table.resize(rows.len() / n * levels * n, EMPTY);
        if levels == 0 {
            return;
        }
        for (row, out) in rows
            .chunks_exact(n)
            .zip(self.table.chunks_exact_mut(levels * n))
        {
            let mut below = row;
            for (j, level) in out.chunks_exact_mut(n).enumerate() {
                let half = 1usize << j;
                for (b, o) in level.iter_mut().enumerate() {
                    *o = union(below[b], below[(b + half).min(n - 1)]);
                }
                // The next level is built from this one.
                below = level;
            }
        }
    }

    /// `[min zmin, max zmax]` over entries `b0..=b1` of row `r`, whose level 0
    /// is `row` (the caller's slice of that row).
    #[inline(always)]
    pub fn query(&self, r: usize, row: &[[f32; 2]], b0: usize, b1: usize) -> [f32; 2] {
        debug_assert!(b0 <= b1 && b1 < self.n && row.len() == self.n);
        let len = b1 - b0 + 1;
        let k = len.ilog2() as usize;
        if k == 0 {
            return row[b0];
        }
        let n = self.n;
        let level = &self.table[(r * levels_above(n) + k - 1) * n..][..n];
        union(level[b0], level[b1 + 1 - (1 << k)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn fold(row: &[[f32; 2]]) -> [f32; 2] {
        row.iter().fold(EMPTY, |a, &b| union(a, b))
    }

    fn range() -> impl Strategy<Value = [f32; 2]> {
        prop_oneof![
            1 => Just(EMPTY),
            6 => (0.0f32..=1.0, 0.0f32..=1.0).prop_map(|(a, b)| [a.min(b), a.max(b)]),
        ]
    }

    proptest! {
        /// Every run of every row gives the fold over it, for row lengths with
        /// and without a power of two.
        #[test]
        fn every_run_equals_the_fold(
            (n, rows) in (1usize..40).prop_flat_map(|n| (Just(n), prop::collection::vec(range(), n..=4 * n)))
        ) {
            let rows = &rows[..rows.len() / n * n];
            let mut t = DepthRanges::default();
            t.build(rows, n);
            for (r, row) in rows.chunks_exact(n).enumerate() {
                for b0 in 0..n {
                    for b1 in b0..n {
                        prop_assert_eq!(t.query(r, row, b0, b1), fold(&row[b0..=b1]), "row {} {}..={}", r, b0, b1);
                    }
                }
            }
        }
    }

    #[test]
    fn rebuilding_replaces_the_old_rows() {
        let mut t = DepthRanges::default();
        let a = [[0.1, 0.2], [0.3, 0.9], [0.0, 0.4]];
        t.build(&a, 3);
        assert_eq!(t.query(0, &a, 0, 2), [0.0, 0.9]);
        let b = [[0.5, 0.6], EMPTY];
        t.build(&b, 2);
        assert_eq!(t.query(0, &b, 0, 1), [0.5, 0.6]);
        assert_eq!(t.query(0, &b, 1, 1), EMPTY);
    }
}
