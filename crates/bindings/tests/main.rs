//! The C ABI's integration tests: one test binary (`cargo test -p
//! shadowcull-bindings --test main`), one module per area.

mod abi;
mod header;
