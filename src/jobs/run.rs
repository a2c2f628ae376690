//! Batch runs: a job's frames and lights through the pipeline, with
//! statistics and images written as the run goes.
//!
//! `stats.csv` gets one row per frame and light as soon as it ends (flushed);
//! `summary.json` and every image are written atomically (temp file +
//! rename), so an interrupted run leaves valid files.

use crate::error::io_err;
use crate::jobs::config::{load_scene_for_job, resolve_lights, Job, SceneSpec};
use crate::jobs::frame::FrameRunner;
use crate::jobs::shard::{warmup_start, Shard, ShardManifest};
use crate::mask::Mask;
use crate::reference::ReferenceMask;
use crate::stats::{CheckStats, FrameRow, ReferenceStats, ShadowStats};
use crate::{Error, Result};
use scene::{Light, SceneCounts};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// How to run a job.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Output directory (created if missing). The run locks it and first
    /// removes what an earlier run left there (`stats.csv`, `summary.json`,
    /// `shard.json`, `frames/`); other files are left alone.
    pub out_dir: PathBuf,
    /// Stop after this many frames (F, the job's frames, is then at most this).
    pub max_frames: Option<u32>,
    /// Run only this shard's block of frames and write `shard.json`
    /// ([`crate::jobs::shard`]).
    pub shard: Option<Shard>,
    /// Warm-up frames before a shard's block; default the job's
    /// `pipeline.chcpp.revisit`.
    pub warmup: Option<u32>,
    /// Reset all coherent state every this many frames; overrides the job's
    /// `keyframe`.
    pub keyframe: Option<u32>,
}

impl Default for RunOptions {
    /// Into `out`, every frame, no shard, the job's keyframes.
    fn default() -> Self {
        RunOptions {
            out_dir: PathBuf::from("out"),
            max_frames: None,
            shard: None,
            warmup: None,
            keyframe: None,
        }
    }
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
    /// Lights per frame.
    pub lights: Vec<Light>,
    /// Time to load or generate the scene and flatten it (ms).
    pub load_ms: f64,
    /// Time to build the reference's triangle BVH (ms; 0 when no frame ran it).
    pub bvh_ms: f64,
    /// The process's peak resident set when the run ended, in bytes (Linux;
    /// left out elsewhere): the scene, every buffer, the reference when on.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_rss_bytes: Option<u64>,
    /// The memory estimate the run was admitted with ([`crate::memory`],
    /// from the loaded scene's counts and the resolved lights), in bytes:
    /// set beside `peak_rss_bytes`, it shows how far the guard was off.
    pub memory_estimate_bytes: u64,
    /// Everything derived from the rows (`frames`, means, medians, totals).
    #[serde(flatten)]
    pub rows: RowSummary,
}

/// The keys of `summary.json` derived from the `stats.csv` rows alone, so a
/// merge of shards recomputes them from the merged rows by the same rule.
#[derive(Clone, Debug, Default, Serialize)]
pub struct RowSummary {
    /// Frames run (the rows hold `frames ×` lights rows).
    pub frames: u32,
    /// Mean reference time per frame and light over the rows that ran it
    /// (ms; a row ran it when its reference classified any pixel).
    pub mean_reference_ms: f64,
    /// Mean pipeline time per frame and light (ms; the rows' `frame_ms`).
    pub mean_frame_ms: f64,
    /// Median whole-frame time: the wall time of [`crate::Pipeline::frame`]
    /// for all lights, the reference and file output excluded (ms; each
    /// frame's first row's `pipeline_frame_ms`).
    pub frame_ms_median: f64,
    /// Mean whole-frame time, as `frame_ms_median` (ms).
    pub frame_ms_mean: f64,
    /// Sum of every row's reference counters.
    pub totals: ReferenceStats,
    /// Sum of every row's pipeline counters (times summed too); written as
    /// its `stats.csv` columns ([`ShadowStats::columns`]).
    #[serde(serialize_with = "shadow_columns")]
    pub shadow_totals: ShadowStats,
    /// Sum of every row's comparison counters.
    pub check_totals: CheckStats,
}

/// `shadow_totals` as its flat `stats.csv` columns.
fn shadow_columns<S: serde::Serializer>(
    totals: &ShadowStats,
    s: S,
) -> std::result::Result<S::Ok, S::Error> {
    totals.columns().serialize(s)
}

impl RowSummary {
    /// The summary of `frames` frames whose rows are `rows`.
    pub fn of(frames: u32, rows: &[FrameRow]) -> RowSummary {
        let mut s = RowSummary {
            frames,
            ..Default::default()
        };
        let mut ref_rows = 0u32;
        let mut frame_times = Vec::with_capacity(frames as usize);
        let mut frame_ms_sum = 0.0;
        for (i, row) in rows.iter().enumerate() {
            let r = &row.reference;
            if r.lit + r.shadow + r.unlit + r.background > 0 {
                ref_rows += 1;
            }
            if i == 0 || rows[i - 1].frame != row.frame {
                frame_times.push(row.pipeline_frame_ms);
            }
            s.totals.add(r);
            s.shadow_totals.add(&row.shadow);
            s.check_totals.add(&row.check);
            frame_ms_sum += row.frame_ms;
        }
        if ref_rows > 0 {
            s.mean_reference_ms = s.totals.reference_ms / f64::from(ref_rows);
        }
        s.mean_frame_ms = frame_ms_sum / rows.len().max(1) as f64;
        s.frame_ms_median = crate::stats::median(&frame_times);
        s.frame_ms_mean = frame_times.iter().sum::<f64>() / frame_times.len().max(1) as f64;
        s
    }
}

/// The bundled default job's text, whose hash names it in `shard.json`.
const DEFAULT_JOB_TEXT: &str = include_str!("../../data/jobs/default_city.ron");

/// Runs `job` (read from `job_file`, or the bundled default when `None`),
/// calling `on_frame` after every frame-and-light row with the number of
/// frames the run writes.
///
/// With [`RunOptions::shard`] it runs the shard's warm-up frames and then its
/// block only, numbering frames as in the whole job, and writes `shard.json`
/// last, so a shard directory without one did not finish.
///
/// # Errors
/// Scene, job and I/O errors; [`Error::Options`] for a keyframe of 0.
pub fn run_job(
    job: &Job,
    job_file: Option<&Path>,
    options: &RunOptions,
    on_frame: &mut dyn FnMut(&FrameRow, u32),
) -> Result<RunSummary> {
    let started = Instant::now();
    let name = job_file
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| "<default>".into());
    let file = job_file.unwrap_or(Path::new("<default job>"));
    let keyframe = options.keyframe.or(job.keyframe);
    if keyframe == Some(0) {
        return Err(Error::Options {
            field: "keyframe".into(),
            message: "must be at least 1".into(),
        });
    }
    check_max_frames(options.max_frames)?;
    let frames = job
        .frame_count()
        .min(options.max_frames.unwrap_or(u32::MAX));
    let block = options.shard.map_or(0..frames, |s| s.range(frames));
    // Before the output directory is touched: a refused run leaves an
    // earlier run's results in place. A shard keeps its block's rows.
    let rows = block.len() as u32;
    check_job_memory(job, rows, 1, job.lights.len().max(1) as u32, None)?;
    let job_hash = match (options.shard, job_file) {
        (None, _) => String::new(),
        (Some(_), Some(p)) => {
            crate::jobs::shard::job_hash(&scene::load::read_input(p).map_err(io_err(p))?)
        }
        (Some(_), None) => crate::jobs::shard::job_hash(DEFAULT_JOB_TEXT.as_bytes()),
    };

    let out = &options.out_dir;
    // One writer at a time, and none of an earlier run's files left beside
    // this run's (a stale shard.json would vouch for them).
    let _lock = crate::jobs::out_dir::claim_for_run(out)?;
    let manifest = out.join("shard.json");

    let t0 = Instant::now();
    let (loaded, scene, path) = load_scene_for_job(job, job_file)?;
    let load_ms = ms(t0);
    let bounds = scene.bounds();
    let lights = resolve_lights(job, &loaded, &bounds, file)?;
    let memory_estimate_bytes =
        check_job_memory(job, rows, 1, lights.len() as u32, Some(&scene.counts()))?;
    let warmup = options.warmup.unwrap_or(job.pipeline.chcpp.revisit);
    let warm = warmup_start(block.start, warmup, keyframe)..block.start;
    let (w, h) = job.resolution;

    let counts = scene.counts();
    let warnings = scene.warnings().to_vec();
    let mut runner = FrameRunner::new(scene);
    runner.set_keyframe(keyframe);

    let frames_dir = out.join("frames");
    if job.outputs.masks || job.outputs.shaded || job.outputs.tile_image {
        std::fs::create_dir_all(&frames_dir).map_err(io_err(&frames_dir))?;
    }
    let csv_path = out.join("stats.csv");
    let mut csv =
        csv::Writer::from_writer(std::fs::File::create(&csv_path).map_err(io_err(&csv_path))?);
    FrameRow::write_csv_header(&mut csv)
        .map_err(std::io::Error::from)
        .and_then(|()| csv.flush())
        .map_err(io_err(&csv_path))?;

    // Warm-up: the pipeline only, to rebuild the history the single run has.
    let t_warm = Instant::now();
    for frame in warm.clone() {
        let camera = frame_camera(&path, frame, (w, h), file)?;
        runner.frame(frame, &camera, &lights, (w, h), &job.pipeline, false)?;
    }
    let warmup_ms = ms(t_warm);

    let written = block.len() as u32;
    let mut rows = Vec::with_capacity(block.len() * lights.len());
    for frame in block.clone() {
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
        for (li, lf) in results.iter().enumerate() {
            let row = &lf.row;
            if frame % job.outputs.image_every == 0 {
                write_images(job, &frames_dir, frame, li, lf)?;
            }
            // One write per row (a flush per record): a row is never split.
            row.write_csv(&mut csv)
                .map_err(std::io::Error::from)
                .and_then(|()| csv.flush())
                .map_err(io_err(&csv_path))?;
            row.emit();
            on_frame(row, written);
            rows.push(*row);
        }
    }
    let summary = RunSummary {
        job: name.clone(),
        scene: counts,
        bounds,
        warnings,
        resolution: job.resolution,
        lights,
        load_ms,
        bvh_ms: runner.bvh_ms,
        peak_rss_bytes: crate::memory::peak_rss_bytes(),
        memory_estimate_bytes,
        rows: RowSummary::of(written, &rows),
    };
    write_json(&out.join("summary.json"), &summary)?;
    if let Some(shard) = options.shard {
        let m = ShardManifest {
            job_path: name,
            job_hash,
            index: shard.index,
            count: shard.count,
            job_frames: frames,
            frames: [block.start, block.end],
            warmup,
            warmup_frames: warm.len() as u32,
            keyframe,
            version: env!("CARGO_PKG_VERSION").into(),
            load_ms,
            warmup_ms,
            wall_ms: ms(started),
        };
        write_json(&manifest, &m)?;
    }
    Ok(summary)
}

/// Writes `value` as pretty JSON to `path`, atomically.
pub(crate) fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    atomic(path, |tmp| {
        let text = serde_json::to_string_pretty(value).map_err(std::io::Error::other)?;
        std::fs::write(tmp, text)
    })
}

/// The images of one frame and light the job's `outputs` ask for.
fn write_images(
    job: &Job,
    frames_dir: &Path,
    frame: u32,
    li: usize,
    lf: &crate::jobs::frame::LightFrame,
) -> Result<()> {
    let (w, h) = job.resolution;
    if job.outputs.masks {
        if let Some(shadow) = &lf.shadow {
            let p = frames_dir.join(format!("{frame}_{li}_mask.png"));
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
    Ok(())
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

/// Refuses a job whose memory estimate ([`crate::memory`]) exceeds its
/// `pipeline.max_memory`: before the scene is loaded, with procedural
/// cities bounded by their parameters (files count 0 then, their size is
/// capped by the input limit), and after, with the loaded counts and the
/// resolved lights. `frames × lights × variants` rows are kept for the
/// summary. The per-frame estimate leaves out the reference when the job
/// never computes one. Returns the estimate, in bytes.
pub(crate) fn check_job_memory(
    job: &Job,
    frames: u32,
    variants: u32,
    lights: u32,
    counts: Option<&scene::SceneCounts>,
) -> Result<u64> {
    fn cities(spec: &SceneSpec) -> Result<(u64, u64)> {
        Ok(match spec {
            SceneSpec::City(p) => p.bounds()?,
            SceneSpec::Group(v) => v.iter().try_fold((0u64, 0u64), |(o, t), s| {
                let (so, st) = cities(s)?;
                Ok::<_, Error>((o.saturating_add(so), t.saturating_add(st)))
            })?,
            // One object, but the inner scene's work bounds it.
            SceneSpec::Merged(inner) => cities(inner)?,
            SceneSpec::Gltf(_) | SceneSpec::Obj(_) | SceneSpec::BoxCity(_) => (0, 0),
        })
    }
    let (objects, triangles) = match counts {
        Some(c) => (c.objects as u64, c.triangles as u64),
        None => cities(&job.scene)?,
    };
    let workload = crate::memory::Workload {
        width: job.resolution.0,
        height: job.resolution.1,
        lights,
        triangles,
        objects,
        rows: u64::from(frames) * u64::from(lights) * u64::from(variants),
    };
    let estimate = crate::memory::estimate(&job.pipeline, &workload);
    estimate.check(crate::memory::limit(&job.pipeline))?;
    Ok(estimate.total)
}

/// A frame cap of 0 is refused, as a job's `frames: 0` is: a run that
/// writes nothing is a mistake, not a success.
pub(crate) fn check_max_frames(max_frames: Option<u32>) -> Result<()> {
    if max_frames == Some(0) {
        return Err(Error::Options {
            field: "frames".into(),
            message: "must be at least 1 (as a job's `frames`)".into(),
        });
    }
    Ok(())
}

/// Writes `path` through a temporary file in the same directory and a rename.
/// On failure (a full disk, say) the temporary file is removed: an error
/// leaves neither a partial `path` nor a `path.tmp` behind.
pub(crate) fn atomic(path: &Path, write: impl FnOnce(&Path) -> std::io::Result<()>) -> Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    let result = write(&tmp)
        .map_err(io_err(&tmp))
        .and_then(|()| std::fs::rename(&tmp, path).map_err(io_err(path)));
    if result.is_err() {
        // Best effort: the write's own error is the one to report.
        let _ = std::fs::remove_file(&tmp);
    }
    result
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
                let base = object_colour(obj.slot());
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A write that fails half-way (a full disk) leaves no `.tmp` and no
    /// partial file; a write that succeeds leaves only the file.
    #[test]
    fn a_failed_write_leaves_no_temporary_file() {
        use std::io::Write as _;
        let dir = testkit::scratch_dir("atomic");
        let path = dir.join("0_0_mask.png");
        let e = atomic(&path, |tmp| {
            std::fs::File::create(tmp)?.write_all(b"half a PNG")?;
            Err(std::io::Error::new(
                std::io::ErrorKind::StorageFull,
                "no space left on device",
            ))
        })
        .unwrap_err();
        assert!(e.to_string().contains("0_0_mask.png.tmp"), "{e}");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        atomic(&path, |tmp| std::fs::write(tmp, b"a PNG")).unwrap();
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["0_0_mask.png"]);
    }
}
