//! Shadowgen's integration tests: one test binary (`cargo test -p
//! shadowcull-shadowgen --test main`), one module per area. The proptest
//! regressions of a module sit beside its file (`shadowgen.proptest-regressions`).

mod shadowgen;
mod shared_data;
mod sweep_prune;
