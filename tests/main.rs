//! The facade's integration tests: one test binary (`cargo test --test main`),
//! one module per area. The counting-allocator test `steady_alloc` is a second
//! binary: it runs without the test harness.
//!
//! Tests that need the shared corpus (`../shared/data` relative to the
//! workspace root) skip with a printed note when it is absent. The
//! diagnostics of the shared-job matrix are the `stencil_diagnose` example.

mod aggressive;
mod cli;
mod common;
mod culling;
mod culling_matrix;
mod extreme;
mod hybrid;
mod jobs;
mod pipeline;
mod raster_city;
mod reference;
mod stencil_exact;
mod stencil_wrap;
