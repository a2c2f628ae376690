//! `shadowcull._native`: the Rust side of the Python package `shadowcull`.
//!
//! It wraps [`shadowcull::Pipeline`] and the batch-job functions and nothing
//! else (it shares no code with the C ABI). The Python surface —
//! keyword options, structured arrays, frame objects — lives in
//! `python/shadowcull/__init__.py`; this module takes and returns plain
//! values: numpy arrays for geometry, masks and ids, JSON text for options,
//! lights, cameras and statistics (the same serde types the RON jobs use, so
//! the names match the job schema exactly).
//!
//! Errors become `ValueError` (bad input) or `OSError` (files), carrying the
//! library's message. The GIL is released while a frame, a reference mask,
//! a scene load, a job or a merge runs.
#![forbid(unsafe_code)]

mod arrays;
mod error;
mod jobs;
mod pipeline;

use pyo3::prelude::*;

/// The native module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<pipeline::Pipeline>()?;
    m.add_function(wrap_pyfunction!(jobs::run_job, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::merge, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::default_options, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::preset_options, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
