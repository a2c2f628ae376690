//! `shadowcull`: run RON batch jobs and inspect scenes.
//!
//! - `shadowcull run [JOB.ron] [--out DIR] [--frames N] [--shard I/N [--warmup W]]
//!   [--keyframe K] [--preset batch|gpu_host] [--log-format text|json]`
//! - `shadowcull merge OUT SHARD_DIR...`
//! - `shadowcull compare JOB.ron [--out DIR] [--frames N]`
//! - `shadowcull inspect SCENE [--json]`
//! - every command: `--max-input-size SIZE` (default 4G; only regular files
//!   are read), `--max-memory SIZE` (default 3/4 of the machine's memory)
//!
//! Exit status 0 on success (also when the reader of stdout stopped reading,
//! as with `| head`), 1 on any error (one line on stderr naming the file), 2
//! on a usage error (a bad or missing argument; clap's message and usage).

use anyhow::Context as _;
use clap::{Parser, Subcommand, ValueEnum};
use shadowcull::jobs::compare::{compare_job, CompareOptions};
use shadowcull::jobs::config::{default_job, Job};
use shadowcull::jobs::merge::merge_shards;
use shadowcull::jobs::run::{run_job, RunOptions};
use shadowcull::stats::FrameRow;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "shadowcull",
    version,
    about = "Shadow-volume culling middleware: batch jobs and scene inspection"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Largest input file read (job, scene, glTF buffer): bytes, or a number
    /// with K, M or G (default 4G). Only regular files are ever read.
    #[arg(long, global = true, value_name = "SIZE")]
    max_input_size: Option<shadowcull::byte_size::ByteSize>,
    /// Most memory a run may need, by its estimate (`run`, `compare`): bytes,
    /// or a number with K, M or G; overrides the job's `pipeline.max_memory`
    /// (default: three quarters of the machine's memory).
    #[arg(long, global = true, value_name = "SIZE")]
    max_memory: Option<shadowcull::byte_size::ByteSize>,
    /// Caps the rasterizer's instruction set (portable, avx2, avx512);
    /// overrides the job's `pipeline.instruction_set`. Without it,
    /// SHADOWCULL_RASTER_SCALAR=1 caps at portable and SHADOWCULL_RASTER_AVX2=1
    /// at AVX2. Results are identical at every level.
    #[arg(long, global = true, value_name = "LEVEL")]
    instruction_set: Option<shadowcull::raster::InstructionSet>,
}

/// What the global flags override in every pipeline of a job.
#[derive(Clone, Copy)]
struct Overrides {
    /// `run --preset`: replaces the job's `pipeline` section.
    preset: Option<shadowcull::Preset>,
    max_memory: Option<shadowcull::byte_size::ByteSize>,
    instruction_set: Option<shadowcull::raster::InstructionSet>,
}

impl Overrides {
    fn of(cli: &Cli) -> Overrides {
        let preset = match &cli.command {
            Command::Run { preset, .. } => *preset,
            _ => None,
        };
        Overrides {
            preset,
            max_memory: cli.max_memory,
            instruction_set: cli
                .instruction_set
                .or_else(shadowcull::raster::InstructionSet::cap_from_env),
        }
    }

    /// Applies the overrides: the preset to the job's pipeline (not to
    /// `compare`'s variants, which are each their own), then the other
    /// flags to it and to every variant.
    fn apply(self, job: &mut Job) {
        if let Some(preset) = self.preset {
            job.pipeline = preset.options();
        }
        let pipelines = std::iter::once(&mut job.pipeline)
            .chain(job.pipelines.iter_mut().map(|v| &mut v.pipeline));
        for p in pipelines {
            if let Some(size) = self.max_memory {
                p.max_memory = Some(size);
            }
            if let Some(isa) = self.instruction_set {
                p.instruction_set = Some(isa);
            }
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Run a RON job (default: the bundled procedural-city job).
    Run {
        /// The job file; omitted: the bundled default (procedural city, street path).
        job: Option<PathBuf>,
        /// Output directory (created if missing).
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Stop after the first N frames.
        #[arg(long)]
        frames: Option<u32>,
        /// Run only shard I of N (0-based): frames ⌊I·F/N⌋ up to ⌊(I+1)·F/N⌋ of
        /// the job's F frames; writes shard.json for `merge`.
        #[arg(long, value_name = "I/N")]
        shard: Option<shadowcull::jobs::shard::Shard>,
        /// Warm-up frames run before the shard's block (no reference, no
        /// output); default: the job's `pipeline.chcpp.revisit`.
        #[arg(long, value_name = "W", requires = "shard")]
        warmup: Option<u32>,
        /// Reset all coherent state (culling histories, caches) every K
        /// frames; overrides the job's `keyframe`.
        #[arg(long, value_name = "K", value_parser = clap::value_parser!(u32).range(1..))]
        keyframe: Option<u32>,
        /// Replace the job's `pipeline` section with a preset's options
        /// (`gpu_host`: no CPU stencil and no reference, for a renderer that
        /// draws the volumes itself; `batch`: the defaults); the other flags
        /// then apply.
        #[arg(long, value_name = "NAME")]
        preset: Option<shadowcull::Preset>,
        /// How per-frame statistics are logged: plain text on stderr, or JSON lines on stdout.
        #[arg(long, value_enum, default_value_t = LogFormat::Text)]
        log_format: LogFormat,
    },
    /// Merge the output directories of `run --shard` into the single run's
    /// stats.csv, frames/ and summary.json.
    Merge {
        /// The merged output directory (created if missing).
        out: PathBuf,
        /// The shard directories, in any order; together they must cover the job once.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
    },
    /// Run the job's `pipelines` variants on the same frames; write compare.csv and compare.svg.
    Compare {
        /// The job file.
        job: PathBuf,
        /// Output directory (created if missing).
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Stop after the first N frames.
        #[arg(long)]
        frames: Option<u32>,
    },
    /// Measure clamping's cost model on this machine (brute-force stencil:
    /// ns per volume vertex and per pixel) on a job's first frame, and print
    /// `clamp_vertex_cost` and `clamp_pixel_cost` for the job's `pipeline`.
    Calibrate {
        /// The job file; omitted: the bundled default.
        job: Option<PathBuf>,
        /// Frames measured per resolution (their median counts).
        #[arg(long, default_value_t = 5)]
        reps: u32,
    },
    /// Print a scene's objects, meshes, triangles, bounds, topology and load warnings.
    Inspect {
        /// A .gltf, .glb, .obj, directory of .obj, or box-city .txt file.
        scene: PathBuf,
        /// Print one JSON object on stdout.
        #[arg(long)]
        json: bool,
        /// Also list every object: id, node name, mesh, drawn triangles, world bounds.
        #[arg(long)]
        objects: bool,
    },
}

#[derive(Clone, Copy, ValueEnum, PartialEq)]
enum LogFormat {
    Text,
    Json,
}

fn main() -> ExitCode {
    // A bug must still end with one line and status 1, never a backtrace.
    std::panic::set_hook(Box::new(|info| {
        eprintln!("error: internal error: {info}");
    }));
    let cli = Cli::parse();
    if let Some(size) = cli.max_input_size {
        shadowcull::scene::load::set_max_input_bytes(size.0);
    }
    match std::panic::catch_unwind(|| dispatch(cli)) {
        Ok(Ok(())) => ExitCode::SUCCESS,
        // A reader that stopped reading (`shadowcull inspect … | head`) ends
        // the output normally, as for any Unix filter.
        Ok(Err(e)) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Ok(Err(e)) => {
            eprintln!("error: {}", one_line(&e));
            ExitCode::from(1)
        }
        Err(_) => ExitCode::from(1),
    }
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

fn one_line(e: &anyhow::Error) -> String {
    let mut s = String::new();
    for (i, cause) in e.chain().enumerate() {
        let text = cause.to_string();
        if i > 0 && s.contains(&text) {
            continue;
        }
        if i > 0 {
            s.push_str(": ");
        }
        s.push_str(&text);
    }
    s.replace('\n', " ")
}

fn dispatch(cli: Cli) -> anyhow::Result<()> {
    let overrides = Overrides::of(&cli);
    match cli.command {
        Command::Run {
            job,
            out,
            frames,
            shard,
            warmup,
            keyframe,
            log_format,
            preset: _,
        } => {
            let options = RunOptions {
                out_dir: out,
                max_frames: frames,
                shard,
                warmup,
                keyframe,
            };
            run(job.as_deref(), options, log_format, overrides)
        }
        Command::Merge { out, shards } => {
            let r = merge_shards(&out, &shards)?;
            eprintln!(
                "shadowcull: merged {} shards: {} frames, {} rows, {} images; wrote {}",
                r.shards,
                r.frames,
                r.rows,
                r.images,
                out.display()
            );
            Ok(())
        }
        Command::Compare { job, out, frames } => compare(&job, out, frames, overrides),
        Command::Calibrate { job, reps } => {
            let mut j = match &job {
                Some(p) => Job::from_file(p)?,
                None => default_job(),
            };
            overrides.apply(&mut j);
            let c = shadowcull::jobs::calibrate::calibrate(&j, job.as_deref(), reps)?;
            eprintln!(
                "shadowcull: {} volume vertices, {} pixels processed; stencil {:.3} ms at {}x{}, {:.3} ms at {}x{}",
                c.vertices,
                c.pixels,
                c.stencil_ms[0],
                shadowcull::jobs::calibrate::VERTEX_BOUND_SIZE.0,
                shadowcull::jobs::calibrate::VERTEX_BOUND_SIZE.1,
                c.stencil_ms[1],
                j.resolution.0,
                j.resolution.1
            );
            // Shortest round-trip text: never rounds a small cost to 0.
            println!("clamp_vertex_cost: {:?},", c.vertex_cost);
            println!("clamp_pixel_cost: {:?},", c.pixel_cost);
            Ok(())
        }
        Command::Inspect {
            scene,
            json,
            objects,
        } => inspect(&scene, json, objects),
    }
}

fn compare(
    job_file: &Path,
    out: PathBuf,
    frames: Option<u32>,
    overrides: Overrides,
) -> anyhow::Result<()> {
    let mut job = Job::from_file(job_file)?;
    overrides.apply(&mut job);
    let options = CompareOptions {
        out_dir: out.clone(),
        max_frames: frames,
    };
    let rows = compare_job(&job, Some(job_file), &options)?;
    eprintln!(
        "{:<16} {:>9} {:>9} {:>16} {:>10} {:>10}",
        "variant", "frame_ms", "stencil", "pixels_processed", "mismatch", "ambiguous"
    );
    for r in &rows {
        eprintln!(
            "{:<16} {:>9.2} {:>9.2} {:>16} {:>10} {:>10}",
            r.name,
            r.frame_ms,
            r.stencil_ms,
            r.pixels_processed,
            r.mismatch_pixels,
            r.ambiguous_pixels
        );
    }
    eprintln!("shadowcull: wrote {}", out.join("compare.csv").display());
    Ok(())
}

fn run(
    job_file: Option<&Path>,
    options: RunOptions,
    log_format: LogFormat,
    overrides: Overrides,
) -> anyhow::Result<()> {
    use tracing_subscriber::prelude::*;
    let mut job = match job_file {
        Some(p) => Job::from_file(p)?,
        None => default_job(),
    };
    overrides.apply(&mut job);
    let tty = std::io::stderr().is_terminal();
    match log_format {
        LogFormat::Json => {
            let layer = tracing_subscriber::fmt::layer()
                .json()
                .flatten_event(true)
                .with_writer(std::io::stdout);
            tracing_subscriber::registry().with(layer).init();
        }
        LogFormat::Text if !tty => {
            let layer = tracing_subscriber::fmt::layer()
                .with_writer(std::io::stderr)
                .with_ansi(false);
            tracing_subscriber::registry().with(layer).init();
        }
        LogFormat::Text => {}
    }
    let bar = (tty && log_format == LogFormat::Text).then(|| {
        let b = indicatif::ProgressBar::new(0);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} frame-lights  {msg}  [{elapsed}<{eta}]",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    if let Some(b) = &bar {
        b.set_message("loading scene");
    } else if log_format == LogFormat::Text {
        eprintln!(
            "shadowcull: loading {}",
            job_file
                .map(|p| p.display().to_string())
                .unwrap_or("the default city job".into())
        );
    }
    let nlights = job.lights.len().max(1) as u64;
    let mut on_frame = |row: &FrameRow, frames: u32| {
        if let Some(b) = &bar {
            b.set_length(frames as u64 * nlights);
            b.inc(1);
            b.set_message(format!(
                "frame {} light {}: pipeline {:.0} ms, reference {:.0} ms",
                row.frame, row.light, row.frame_ms, row.reference.reference_ms
            ));
        }
    };
    let summary = run_job(&job, job_file, &options, &mut on_frame)?;
    let out = &options.out_dir;
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    // The loaders' warnings (dropped faces, polygons not triangulated,
    // ignored extensions), also in summary.json.
    for w in &summary.warnings {
        eprintln!("shadowcull: warning: {w}");
    }
    if log_format == LogFormat::Text {
        eprintln!(
            "shadowcull: {} objects, {} triangles; {} frames × {} lights; mean pipeline {:.1} ms, mean reference {:.1} ms; {} mismatched pixels ({} off a shadow boundary); wrote {}",
            summary.scene.objects,
            summary.scene.triangles,
            summary.rows.frames,
            summary.lights.len(),
            summary.rows.mean_frame_ms,
            summary.rows.mean_reference_ms,
            summary.rows.check_totals.mismatch_pixels,
            summary.rows.check_totals.mismatch_off_boundary,
            out.display()
        );
    }
    Ok(())
}

fn inspect(path: &Path, json: bool, list_objects: bool) -> anyhow::Result<()> {
    use std::io::Write as _;
    // Written through a handle, so that a closed pipe (`| head`) is an error
    // `main` treats as a normal end, not a panic.
    let mut out = std::io::stdout().lock();
    let shown = path.display().to_string();
    let with_file = |e: String| {
        if e.contains(&shown) {
            e
        } else {
            format!("{shown}: {e}")
        }
    };
    let loaded =
        scene::load::load_path(path).map_err(|e| anyhow::anyhow!(with_file(e.to_string())))?;
    let scene =
        scene::Scene::new(loaded.graph).map_err(|e| anyhow::anyhow!(with_file(e.to_string())))?;
    let c = scene.counts();
    let b = scene.bounds();
    let bounds = if b.is_empty() {
        serde_json::json!(null)
    } else {
        serde_json::json!({ "min": [b.min.x, b.min.y, b.min.z], "max": [b.max.x, b.max.y, b.max.z] })
    };
    let object_list: Vec<serde_json::Value> = if list_objects {
        scene
            .objects()
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let mesh = &scene.graph().meshes()[o.mesh.index()];
                let b = o.world_bounds;
                serde_json::json!({
                    "id": i,
                    "name": scene.graph().nodes()[o.node.0 as usize].name,
                    "mesh": mesh.name(),
                    "triangles": mesh.triangles().len(),
                    "bounds": { "min": [b.min.x, b.min.y, b.min.z], "max": [b.max.x, b.max.y, b.max.z] },
                })
            })
            .collect()
    } else {
        Vec::new()
    };
    if json {
        let mut v = serde_json::json!({
            "file": shown,
            "objects": c.objects,
            "meshes": c.meshes,
            "triangles": c.triangles,
            "drawn_triangles": c.drawn_triangles,
            "vertices": c.vertices,
            "bounds": bounds,
            "boundary_edges": c.topology.boundary_edges,
            "non_manifold_edges": c.topology.non_manifold_edges,
            "inconsistent_edges": c.topology.inconsistent_edges,
            "degenerate_triangles": c.topology.degenerate_triangles,
            "warnings": scene.warnings(),
        });
        if list_objects {
            v["object_list"] = serde_json::Value::Array(object_list);
        }
        writeln!(
            out,
            "{}",
            serde_json::to_string(&v).context("encoding JSON")?
        )?;
    } else {
        writeln!(out, "{shown}")?;
        writeln!(out, "  objects              {}", c.objects)?;
        writeln!(out, "  meshes               {}", c.meshes)?;
        writeln!(
            out,
            "  triangles            {} ({} drawn)",
            c.triangles, c.drawn_triangles
        )?;
        writeln!(out, "  vertices             {}", c.vertices)?;
        if b.is_empty() {
            writeln!(out, "  bounds               (empty)")?;
        } else {
            writeln!(
                out,
                "  bounds               {:?} .. {:?}",
                b.min.to_array(),
                b.max.to_array()
            )?;
        }
        writeln!(out, "  boundary edges       {}", c.topology.boundary_edges)?;
        writeln!(
            out,
            "  non-manifold edges   {}",
            c.topology.non_manifold_edges
        )?;
        writeln!(
            out,
            "  inconsistent edges   {}",
            c.topology.inconsistent_edges
        )?;
        writeln!(
            out,
            "  degenerate triangles {}",
            c.topology.degenerate_triangles
        )?;
        writeln!(out, "  warnings             {}", scene.warnings().len())?;
        for w in scene.warnings() {
            writeln!(out, "    - {w}")?;
        }
        for o in &object_list {
            writeln!(
                out,
                "  object {} `{}` mesh `{}`: {} triangles, bounds {} .. {}",
                o["id"],
                o["name"].as_str().unwrap_or(""),
                o["mesh"].as_str().unwrap_or(""),
                o["triangles"],
                o["bounds"]["min"],
                o["bounds"]["max"]
            )?;
        }
    }
    Ok(())
}
