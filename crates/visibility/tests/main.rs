//! The culling crate's integration tests: one test binary (`cargo test -p
//! shadowcull-visibility --test main`), one module per area.

mod culling;
