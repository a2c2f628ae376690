//! Helpers shared by shadowcull's integration tests, benches and examples. A
//! dev-dependency only (`publish = false`): no library crate depends on it.
//!
//! - [`shared_data`], [`shared_file`], [`shared_jobs`]: the shared corpus
//!   (`../shared/data` beside the workspace root), `None` or empty with a
//!   printed note when it is absent, as in a user's clone;
//! - [`BenchScene`], [`street_city`]: the bench scenes (the procedural city, the
//!   box cities of `../shared/data/bench`) with their cameras, paths and lights;
//! - [`median`];
//! - [`brute_pairs`], [`bvh_pairs`]: baselines of sweep-and-prune;
//! - [`hierarchical_matches_brute_force`], [`check_hierarchical`]: the
//!   hierarchical stencil (H) against brute force (BF) on one view;
//! - [`scratch_dir`]: a fresh temporary directory per process and name,
//!   removed when dropped;
//! - `cli` (feature `cli`): the examples' option tables and `WxH` parser;
//! - [`proptest_config`]: proptest's configuration with the regressions
//!   beside each test module (`tests/<module>.proptest-regressions`).

#[cfg(feature = "cli")]
pub mod cli;
mod data;
pub mod engine;
mod pairs;
mod scenes;
mod stencil;
pub mod volume_checks;

pub use data::{scratch_dir, shared_data, shared_file, shared_jobs, workspace_root, ScratchDir};
pub use pairs::{brute_pairs, bvh_pairs};
pub use scenes::{street_city, BenchScene};
pub use stencil::{
    check_hierarchical, check_hierarchical_clamped, hierarchical_matches_brute_force,
    HierarchyCheck,
};

/// Proptest's configuration with `cases` cases (the `PROPTEST_*` environment
/// otherwise), its failures persisted beside the test's source file:
/// `tests/shadowgen.rs` keeps its seeds in `tests/shadowgen.proptest-regressions`.
///
/// Proptest's default (`SourceParallel`) puts them under a
/// `proptest-regressions/` directory beside the nearest directory holding a
/// `lib.rs` or `main.rs`, which, since every crate's integration tests are one
/// `tests/main.rs` binary, is `<crate>/proptest-regressions/<module>.txt`.
pub fn proptest_config(cases: u32) -> proptest::test_runner::Config {
    proptest::test_runner::Config {
        failure_persistence: Some(Box::new(
            proptest::test_runner::FileFailurePersistence::WithSource("proptest-regressions"),
        )),
        ..proptest::test_runner::Config::with_cases(cases)
    }
}

/// The upper median of `values` (the middle element of an odd count, the
/// upper of the two middle ones of an even count); `None` when empty.
///
/// # Panics
/// When two values are incomparable (a NaN).
pub fn median<T: Copy + PartialOrd>(values: &[T]) -> Option<T> {
    let mut v = values.to_vec();
    v.sort_by(|a, b| {
        a.partial_cmp(b)
            .expect("median of incomparable values (NaN)")
    });
    v.get(v.len() / 2).copied()
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn median_is_the_upper_middle() {
        assert_eq!(median::<f64>(&[]), None);
        assert_eq!(median(&[3.0]), Some(3.0));
        assert_eq!(median(&[4u64, 1, 3, 2]), Some(3));
        assert_eq!(median(&[5u64, 1, 3]), Some(3));
    }
}
