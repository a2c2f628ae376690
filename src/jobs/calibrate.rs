//! Calibration of clamping's cost model [Steiner §4.4.1, eqs. 4.2–4.3]: the
//! cost v per shadow-volume vertex and r per stencil pixel of this machine's
//! brute-force stencil, measured as the thesis suggests. The job's first
//! frame is drawn with `stencil: bf` at a tiny resolution, where vertex work
//! dominates (v = stencil time / volume vertices), and at the job's own,
//! where the pixels add their share (r = the extra time / pixels processed).
//! `shadowcull calibrate` prints the two as RON fields to paste into a job's
//! `pipeline`; the library never reads a calibration file.

use crate::jobs::config::{load_scene_for_job, resolve_lights, Job};
use crate::jobs::frame::FrameRunner;
use crate::jobs::run::frame_camera;
use crate::pipeline::{PipelineOptions, StencilBackend};
use crate::stats::median;
use crate::Result;
use std::path::Path;

/// The tiny resolution of the vertex-bound run.
pub const VERTEX_BOUND_SIZE: (u32, u32) = (8, 6);

/// What [`calibrate`] measured, in nanoseconds.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Calibration {
    /// v: nanoseconds per volume vertex (`pipeline.clamp_vertex_cost`).
    pub vertex_cost: f64,
    /// r: nanoseconds per stencil pixel processed (`pipeline.clamp_pixel_cost`).
    pub pixel_cost: f64,
    /// Volume vertices (three per triangle) of the measured frame.
    pub vertices: u64,
    /// Pixels processed at the job's resolution.
    pub pixels: u64,
    /// Median stencil times (ms), tiny and full resolution.
    pub stencil_ms: [f64; 2],
}

/// Measures v and r on `job`'s first frame and lights (median of `reps`
/// frames each), with the job's pipeline but the brute-force stencil and no
/// clamping. `job_file` names the job in errors and resolves its paths.
///
/// # Errors
/// Scene, job and pipeline errors; [`crate::Error::Job`] on `resolution`
/// when the frame has too little stencil work to measure.
pub fn calibrate(job: &Job, job_file: Option<&Path>, reps: u32) -> Result<Calibration> {
    let file = job_file.unwrap_or(Path::new("<default job>"));
    let (loaded, scene, path) = load_scene_for_job(job, job_file)?;
    let lights = resolve_lights(job, &loaded, &scene.bounds(), file)?;
    let options = PipelineOptions {
        stencil: StencilBackend::Bf,
        clamping: Default::default(),
        reference_every: 0,
        ..job.pipeline
    };
    let mut runner = FrameRunner::new(scene);
    let reps = reps.max(1);
    let mut measure = |size: (u32, u32), first: u32| -> Result<(f64, u64, u64)> {
        let camera = frame_camera(&path, 0, size, file)?;
        let mut times = Vec::new();
        let (mut vertices, mut pixels) = (0, 0);
        for rep in first..first + reps {
            let out = runner.frame(rep, &camera, &lights, size, &options, false)?;
            times.push(out.iter().map(|l| l.row.shadow.stencil_ms).sum::<f64>());
            vertices = out.iter().map(|l| 3 * l.row.shadow.volume_triangles).sum();
            pixels = out
                .iter()
                .map(|l| l.row.shadow.stencil.pixels_processed)
                .sum();
        }
        Ok((median(&times), vertices, pixels))
    };
    let (low_ms, vertices, _) = measure(VERTEX_BOUND_SIZE, 0)?;
    let (high_ms, _, pixels) = measure(job.resolution, reps)?;
    // Both costs must be measurable: volumes to draw, and more time at the
    // job's resolution than at the tiny one.
    if vertices == 0 || pixels == 0 || high_ms <= low_ms {
        return Err(crate::Error::Job {
            file: file.to_path_buf(),
            location: "resolution".into(),
            message: format!(
                "too little stencil work to measure ({vertices} volume vertices, {pixels} \
                 pixels, {high_ms:.3} ms at {}x{} against {low_ms:.3} ms at {}x{}): \
                 calibrate on a larger resolution or a view with more shadow",
                job.resolution.0, job.resolution.1, VERTEX_BOUND_SIZE.0, VERTEX_BOUND_SIZE.1
            ),
        });
    }
    let ns = 1e6;
    Ok(Calibration {
        vertex_cost: low_ms * ns / vertices as f64,
        pixel_cost: (high_ms - low_ms) * ns / pixels as f64,
        vertices,
        pixels,
        stencil_ms: [low_ms, high_ms],
    })
}
