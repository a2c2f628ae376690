//! Batch runs: a job's frames and lights through the pipeline, with
//! statistics and images written as the run goes.
//!
//! `stats.csv` gets one row per frame and light as soon as it ends (flushed);
//! `summary.json` and every image are written atomically (temp file +
//! rename), so an interrupted run leaves valid files.

use crate::config::{load_scene_for_job, resolve_lights, Job};
use crate::error::io_err;
use crate::frame::FrameRunner;
use crate::mask::Mask;
use crate::reference::ReferenceMask;
use crate::stats::{CheckStats, FrameRow, ReferenceStats, ShadowStats};
use crate::{Error, Result};
use scene::{Light, SceneCounts};
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How to run a job.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Output directory (created if missing; other files in it are left alone).
    pub out_dir: PathBuf,
    /// Stop after this many frames.
    pub max_frames: Option<u32>,
}

/// What `summary.json` holds.
#[derive(Clone, Debug, Serialize)]
pub struct RunSummary {
    /// The job file, or `<default>`.
    pub job: String,
    /// Scene counts.
    pub scene: SceneCounts,
    /// Scene bounds.
    pub bounds: scene::Aabb,
    /// Load warnings.
    pub warnings: Vec<String>,
    /// Viewport.
    pub resolution: (u32, u32),
    /// Frames run.
    pub frames: u32,
    /// Lights per frame.
    pub lights: Vec<Light>,
    /// Time to load or generate the scene and flatten it (ms).
    pub load_ms: f64,
    /// Time to build the reference's triangle BVH (ms; 0 when no frame ran it).
    pub bvh_ms: f64,
    /// Mean reference time per frame and light over the frames that ran it (ms).
    pub mean_reference_ms: f64,
    /// Mean pipeline time per frame and light (ms; the rows' `frame_ms`).
    pub mean_frame_ms: f64,
    /// Median whole-frame time: the wall time of [`crate::Pipeline::frame`]
    /// for all lights, the reference and file output excluded (ms).
    pub frame_ms_median: f64,
    /// Mean whole-frame time, as `frame_ms_median` (ms).
    pub frame_ms_mean: f64,
    /// Sum of every row's reference counters.
    pub totals: ReferenceStats,
    /// Sum of every row's pipeline counters (times summed too).
    pub shadow_totals: ShadowStats,
    /// Sum of every row's comparison counters.
    pub check_totals: CheckStats,
}

/// Runs `job` (read from `job_file`, or the bundled default when `None`),
/// calling `on_frame` after every frame-and-light row.
///
/// # Errors
/// Scene, job and I/O errors.
pub fn run_job(
    job: &Job,
    job_file: Option<&Path>,
    options: &RunOptions,
    on_frame: &mut dyn FnMut(&FrameRow, u32),
) -> Result<RunSummary> {
    let name = job_file
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| "<default>".into());
    let file = job_file.unwrap_or(Path::new("<default job>"));

    let t0 = Instant::now();
    let (loaded, scene, path) = load_scene_for_job(job, job_file)?;
    let load_ms = ms(t0);
    let bounds = scene.bounds();
    let lights = resolve_lights(job, &loaded, &bounds, file)?;
    let frames = job
        .frame_count()
        .min(options.max_frames.unwrap_or(u32::MAX));
    let (w, h) = job.resolution;

    let counts = scene.counts();
    let warnings = scene.warnings().to_vec();
    let mut runner = FrameRunner::new(scene);
    let mut frame_times = Vec::with_capacity(frames as usize);

    let out = &options.out_dir;
    std::fs::create_dir_all(out).map_err(io_err(out))?;
    let frames_dir = out.join("frames");
    if job.outputs.masks || job.outputs.shaded || job.outputs.tile_image {
        std::fs::create_dir_all(&frames_dir).map_err(io_err(&frames_dir))?;
    }
    let csv_path = out.join("stats.csv");
    let mut csv = std::fs::File::create(&csv_path).map_err(io_err(&csv_path))?;
    writeln!(csv, "{}", FrameRow::csv_header()).map_err(io_err(&csv_path))?;

    let mut totals = ReferenceStats::default();
    let mut shadow_totals = ShadowStats::default();
    let mut check_totals = CheckStats::default();
    let mut ref_runs = 0u32;
    let mut frame_ms_sum = 0.0;
    for frame in 0..frames {
        let camera = frame_camera(&path, frame, (w, h), file)?;
        let every = job.pipeline.reference_every;
        let with_reference = every > 0 && frame % every == 0;
        let results = runner.frame(
            frame,
            &camera,
            &lights,
            (w, h),
            &job.pipeline,
            with_reference,
        )?;
        if let Some(first) = results.first() {
            frame_times.push(first.row.pipeline_frame_ms);
        }
        for (li, lf) in results.iter().enumerate() {
            let row = &lf.row;
            if frame % job.outputs.image_every == 0 {
                if job.outputs.masks {
                    let p = frames_dir.join(format!("{frame}_{li}_mask.png"));
                    if let Some(shadow) = &lf.shadow {
                        atomic(&p, |tmp| shadow.mask.write_png(tmp))?;
                    }
                    if let Some(r) = &lf.reference {
                        let p = frames_dir.join(format!("{frame}_{li}_reference.png"));
                        atomic(&p, |tmp| r.mask.write_png(tmp))?;
                    }
                }
                if let (true, Some(t)) = (
                    job.outputs.tile_image,
                    lf.shadow.as_ref().and_then(|s| s.tiles.as_ref()),
                ) {
                    // [Aila04 Fig. 1]: lit, shadow and boundary tiles of the frame.
                    let p = frames_dir.join(format!("{frame}_{li}_tiles.png"));
                    let rgb = t.rgb(w, h);
                    atomic(&p, |tmp| {
                        crate::mask::write_png(tmp, w, h, png::ColorType::Rgb, &rgb)
                    })?;
                }
                if let (true, Some(r), Some(s)) = (job.outputs.shaded, &lf.reference, &lf.shadow) {
                    let p = frames_dir.join(format!("{frame}_{li}_shaded.png"));
                    atomic(&p, |tmp| write_shaded(&s.mask, r, tmp))?;
                }
            }
            if lf.reference.is_some() {
                ref_runs += 1;
            }
            totals.add(&row.reference);
            shadow_totals.add(&row.shadow);
            check_totals.add(&row.check);
            frame_ms_sum += row.frame_ms;
            writeln!(csv, "{}", row.csv_row())
                .and_then(|_| csv.flush())
                .map_err(io_err(&csv_path))?;
            row.emit();
            on_frame(row, frames);
        }
    }
    let rows = (frames as usize * lights.len()).max(1) as f64;
    let summary = RunSummary {
        job: name,
        scene: counts,
        bounds,
        warnings,
        resolution: job.resolution,
        frames,
        lights,
        load_ms,
        bvh_ms: runner.bvh_ms,
        mean_reference_ms: if ref_runs > 0 {
            totals.reference_ms / ref_runs as f64
        } else {
            0.0
        },
        mean_frame_ms: frame_ms_sum / rows,
        frame_ms_median: crate::stats::median(&frame_times),
        frame_ms_mean: frame_times.iter().sum::<f64>() / frame_times.len().max(1) as f64,
        totals,
        shadow_totals,
        check_totals,
    };
    let sp = out.join("summary.json");
    atomic(&sp, |tmp| {
        let text = serde_json::to_string_pretty(&summary).map_err(std::io::Error::other)?;
        std::fs::write(tmp, text)
    })?;
    Ok(summary)
}

/// The camera of `frame` for a `width × height` viewport.
pub(crate) fn frame_camera(
    path: &scene::CameraPath,
    frame: u32,
    (w, h): (u32, u32),
    file: &Path,
) -> Result<scene::Camera> {
    let pose = path.at(frame).ok_or_else(|| Error::Job {
        file: file.to_path_buf(),
        location: "camera".into(),
        message: format!("no pose for frame {frame}"),
    })?;
    pose.camera(w as f64 / h as f64).map_err(|e| Error::Job {
        file: file.to_path_buf(),
        location: format!("camera (frame {frame})"),
        message: e.to_string(),
    })
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Writes `path` through a temporary file in the same directory and a rename.
pub(crate) fn atomic(path: &Path, write: impl FnOnce(&Path) -> std::io::Result<()>) -> Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    write(&tmp).map_err(io_err(&tmp))?;
    std::fs::rename(&tmp, path).map_err(io_err(path))
}

/// A shaded RGB image: each object a muted colour of its own, Lambert-lit
/// (the reference's cosines) where `mask` says lit, ambient only in shadow and
/// unlit; background dark blue.
fn write_shaded(mask: &Mask, r: &ReferenceMask, path: &Path) -> std::io::Result<()> {
    use crate::mask::PixelClass;
    let mut rgb = Vec::with_capacity(mask.pixels.len() * 3);
    for (i, class) in mask.pixels.iter().enumerate() {
        let px = match (class, r.primitive[i]) {
            (PixelClass::Background, _) | (_, None) => [38, 44, 64],
            (c, Some((obj, _))) => {
                let base = object_colour(obj.0);
                let k = match c {
                    PixelClass::Lit => 0.3 + 0.7 * r.lambert[i],
                    PixelClass::Shadow => 0.3,
                    _ => 0.22,
                };
                // Display gamma so shadows read as shadows, not as black.
                base.map(|v| {
                    (255.0 * (v as f32 / 255.0 * k).powf(1.0 / 2.2))
                        .round()
                        .clamp(0.0, 255.0) as u8
                })
            }
        };
        rgb.extend_from_slice(&px);
    }
    crate::mask::write_png(path, mask.width, mask.height, png::ColorType::Rgb, &rgb)
}

fn object_colour(id: u32) -> [u8; 3] {
    let mut h = id.wrapping_mul(0x9E37_79B9) ^ 0x5bd1_e995;
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    [
        160 + (h & 0x5f) as u8,
        160 + ((h >> 8) & 0x5f) as u8,
        160 + ((h >> 16) & 0x5f) as u8,
    ]
}
