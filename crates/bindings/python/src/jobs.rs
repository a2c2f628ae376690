//! Batch jobs from Python: `run_job` and `merge`, the library functions
//! behind `shadowcull run` and `shadowcull merge`, with the GIL released.

use crate::error::{bad, to_py};
use pyo3::prelude::*;
use shadowcull::byte_size::ByteSize;
use shadowcull::jobs::config::{default_job, Job};
use shadowcull::jobs::run::RunOptions;
use shadowcull::jobs::shard::Shard;
use std::path::PathBuf;

/// Runs the job at `path` (the bundled default job when None) into `out`;
/// returns `summary.json`'s content.
#[pyfunction]
#[pyo3(signature = (path, out, frames=None, shard=None, warmup=None, keyframe=None, max_memory=None))]
// Each parameter is a Python keyword argument of `run_job`: a struct would change the Python API.
#[allow(clippy::too_many_arguments)]
pub(crate) fn run_job(
    py: Python<'_>,
    path: Option<PathBuf>,
    out: PathBuf,
    frames: Option<u32>,
    shard: Option<(u32, u32)>,
    warmup: Option<u32>,
    keyframe: Option<u32>,
    max_memory: Option<String>,
) -> PyResult<String> {
    let max_memory = max_memory
        .map(|m| {
            m.parse::<ByteSize>()
                .map_err(|e| bad(format!("max_memory: {e}")))
        })
        .transpose()?;
    let shard = shard
        .map(|(index, count)| format!("{index}/{count}").parse::<Shard>().map_err(to_py))
        .transpose()?;
    let options = RunOptions {
        out_dir: out,
        max_frames: frames,
        shard,
        warmup,
        keyframe,
    };
    let summary = py
        .detach(|| {
            let mut job = match &path {
                Some(p) => Job::from_file(p)?,
                None => default_job(),
            };
            if let Some(size) = max_memory {
                job.pipeline.max_memory = Some(size);
            }
            shadowcull::jobs::run::run_job(&job, path.as_deref(), &options, &mut |_, _| {})
        })
        .map_err(to_py)?;
    serde_json::to_string(&summary).map_err(|e| bad(e.to_string()))
}

/// Merges shard directories into `out`; returns what it wrote as JSON.
#[pyfunction]
pub(crate) fn merge(py: Python<'_>, out: PathBuf, dirs: Vec<PathBuf>) -> PyResult<String> {
    let r = py
        .detach(|| shadowcull::jobs::merge::merge_shards(&out, &dirs))
        .map_err(to_py)?;
    Ok(serde_json::json!({
        "shards": r.shards,
        "frames": r.frames,
        "rows": r.rows,
        "images": r.images,
    })
    .to_string())
}

/// The options of preset `name` (`batch`, `gpu_host`) as JSON.
#[pyfunction]
pub(crate) fn preset_options(name: &str) -> PyResult<String> {
    let preset: shadowcull::Preset = name.parse().map_err(bad)?;
    serde_json::to_string(&preset.options()).map_err(|e| bad(e.to_string()))
}

/// The default pipeline options as JSON (the RON `pipeline` section's defaults).
#[pyfunction]
pub(crate) fn default_options() -> PyResult<String> {
    serde_json::to_string(&shadowcull::PipelineOptions::default()).map_err(|e| bad(e.to_string()))
}
