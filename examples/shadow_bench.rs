//! One view, or one camera path, through the stencil shadow pipeline, timed per stage.
//!
//! `cargo run --release --example shadow_bench -- SCENE CAMERA WxH [--preset batch|gpu_host] [--stencil bf|db|h|hybrid|none|auto]
//! [--scissor on|off] [--occluders mesh|proxy] [--culling-resolution WxH] [--method auto|zpass|zfail|zpplus] [--counters 8|wide] [--tile 4|8|16]
//! [--full-shadow on|off] [--map N] [--culling none|frustum|exact|chc|chcpp|auto]
//! [--coverage conservative|point] [--threshold T] [--light-res N]
//! [--clamping none|continuous|discrete|auto] [--slices N]
//! [--clamping-receivers all|psr|fragment] [--count-fill]
//! [--two-sided] [--reference | --check-gpu] [--host-depth] [--mask OUT.png] [--reps R | --path NAME [--frames N]]`
//! (defaults `--tile 8 --counters 8 --map 2048 --full-shadow on --culling none
//! --coverage conservative --threshold 0 --light-res 1024 --reps 5`; `--threshold` is the
//! query threshold in samples, and `point` coverage or a threshold above 0 are aggressive;
//! `--bits` is another name for `--counters`; `--light-res` is the side in pixels of every
//! light view of the light pass, 8..=`raster::MAX_TARGET_SIZE`).
//!
//! SCENE is a box-city file (`../shared/data/bench/*.txt`; CAMERA one of its camera
//! names, its light), `city` (the bundled default job's procedural city; CAMERA
//! `street` or `bird`, the first pose of that path; a point light 1.5 scene
//! heights above the ground, the default job's first light, `LightSpec::AboveScene(1.5)`)
//! `engine` (the engine bench scene, `testkit::engine`: ~1,500 objects, ~100k triangles,
//! a sun, a moving point light and a spot, vehicles moving and objects added and
//! removed every frame; its path and camera are `engine`; with its three lights the
//! per-light keys are summed over them, `queries` and `waits` repeating the eye's
//! per light) or any scene file, with `--light x,y,z` (point light) or `--sun dx,dy,dz` (the
//! direction the light travels; either also replaces a box city's or `city`'s light)
//! and `--eye x,y,z --target x,y,z` (fovy 60° and near 0.1 unless `--fovy`, `--near`;
//! CAMERA may then be `-`). One light per run: every per-light key below is that light's.
//!
//! All frames of a run go through ONE `FrameRunner`, so all per-view state is kept from
//! frame to frame: silhouette caches, volume buffers, the eye view's and the light
//! views' culling (CHC) history.
//!
//! **One view** (without `--path`): renders the same view as R consecutive frames
//! (`--reps R`) with all per-view state kept (a static camera in a running
//! application); times are medians over them. Prints one JSON line on stdout with the
//! medians of `eye_ms` (the eye pass, culled with `--culling`, and the light pass's
//! receiver points), `light_ms` (the light
//! pass: light views and PSC; 0 without culling), `silhouette_ms`, `volume_ms`,
//! `stencil_ms`, `frame_ms` (the sum of those five) and `wall_ms` (the whole
//! `FrameRunner::frame` call without the reference: also work no stage time counts); `silhouette_cold_ms` (the first frame's
//! silhouette stage: empty cache) and `silhouette_cached_ms` (the median of the later
//! frames' silhouette stage: warm cache; with `--reps 1`, one extra frame); the
//! counters of the last frame, the steady state (`volume_triangles`,
//! `pixels_processed`, `stencil_updates`, `shadowed_pixels`, `h_fragments`,
//! `tile_tests`, `tiles_lit`, `tiles_shadow`, `tiles_boundary`, `bandwidth_bytes`,
//! `pixel_bytes`, `tile_bytes`, `silhouette_pixels`, `map_ms`, `psr`, `psc`,
//! `queries`, `waits`, `segments`, `bf_fill_unclamped`, `bf_fill_clamped`, ...) and with `--reference` (computed on the last frame)
//! `mismatch_pixels`, `mismatch_off_boundary`, `ambiguous_pixels`, `reference_ms`; with
//! `--check-gpu` (`Pipeline::check_gpu`, outside every timed stage: the frame's volumes
//! drawn by the brute-force stencil on an exact eye depth, as a GPU host draws them)
//! `mismatch_pixels`, `mismatch_off_boundary` (against the reference) and
//! `culled_vs_unculled_differing_pixels` (against every caster's volumes), summed over
//! the lights. `--host-depth` gives every frame the host's own depth
//! (`FrameInput::host_depth`: the frame's exact eye depth reduced to the culling size,
//! made outside every timed stage: every frame's before the first, or, for the engine
//! scene whose edits change it, before each frame, whose caches it leaves cold), as a
//! GPU host with a depth pre-pass would; the JSON's `host_depth` says so.
//!
//! **A camera path** (`--path NAME --frames N`, N defaults to 8): renders frames
//! 0..N of the scene's camera path NAME (`city` and box cities: `street`, a dolly down
//! the street, or `bird`, an orbit; other scenes: the paths their file names, if any);
//! CAMERA is ignored (write `-`; the JSON's `camera` is NAME), `--eye`/`--target` and
//! `--reps` do not apply. Prints one JSON line with `path`, `frames` and per frame, as
//! arrays in frame order, `frame_ms`, `wall_ms`, `eye_ms`, `light_ms`,
//! `silhouette_ms`, `volume_ms`, `stencil_ms`, `psr`, `psc`, `queries`, `waits`,
//! `pixels_processed`, `volume_triangles`, `shadowed_pixels`, `segments`, `sap_pairs`,
//! `bf_fill_unclamped`, `bf_fill_clamped` (with `--reference`,
//! computed on every frame, also `mismatch_pixels`, `mismatch_off_boundary`,
//! `ambiguous_pixels`, `reference_ms`); for each of these keys K also `K_median` and
//! `K_total`.
//!
//! Both print the settings (`scene`, `camera`, `width`, `height`, `stencil`, `culling`,
//! `light_resolution`, ...) and the scene size (`objects`, `triangles`).
//! `--mask` writes the last frame's raw stencil result as an 8-bit PNG: 255 where the
//! stencil is non-zero, 0 elsewhere, row 0 at the top. The stencil runs only at the
//! pixels whose class it decides (receivers the light reaches). Logs go to stderr.

use anyhow::{bail, Context};
use clap::ArgAction;
use glam::DVec3;
use raster::StencilBits;
use scene::load::Loaded;
use scene::{Camera, CameraPath, Light, LookAt, ObjectFlags, ObjectId, Scene};
use serde_json::{json, Map, Value};
use shadowcull::jobs::config::LightSpec;
use shadowcull::jobs::frame::{FrameRunner, LightFrame};
use shadowcull::pipeline::{
    eye, ClampReceiversSpec, ClampingSpec, CoverageSpec, CullingSpec, HostDepth, OccludersSpec,
    PipelineOptions, StencilBackend,
};
use shadowcull::stats::FrameRow;
use shadowgen::MethodChoice;
use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;
use testkit::cli::{name_of, one_of, parse_size};
use testkit::engine::EngineScene;
use testkit::median;

// The spellings of the flags that choose among fixed values: a new mode is one row
// here (the parser, its error message and the JSON name all come from the table).
const STENCILS: &[(&str, StencilBackend)] = &[
    ("bf", StencilBackend::Bf),
    ("db", StencilBackend::Db),
    ("h", StencilBackend::H),
    ("hybrid", StencilBackend::Hybrid),
    ("none", StencilBackend::None),
    ("auto", StencilBackend::Auto),
];
const CULLINGS: &[(&str, CullingSpec)] = &[
    ("none", CullingSpec::None),
    ("frustum", CullingSpec::Frustum),
    ("exact", CullingSpec::Exact),
    ("chc", CullingSpec::Chc),
    ("chcpp", CullingSpec::Chcpp),
    ("auto", CullingSpec::Auto),
];
const METHODS: &[(&str, MethodChoice)] = &[
    ("auto", MethodChoice::Auto),
    ("zpass", MethodChoice::ZPass),
    ("zfail", MethodChoice::ZFail),
    ("zpplus", MethodChoice::ZpPlus),
];
const COUNTERS: &[(&str, StencilBits)] = &[("8", StencilBits::Eight), ("wide", StencilBits::Wide)];
const CLAMPINGS: &[(&str, ClampingSpec)] = &[
    ("none", ClampingSpec::None),
    ("continuous", ClampingSpec::Continuous),
    ("discrete", ClampingSpec::Discrete),
    ("auto", ClampingSpec::Auto),
];
const CLAMP_RECEIVERS: &[(&str, ClampReceiversSpec)] = &[
    ("all", ClampReceiversSpec::All),
    ("psr", ClampReceiversSpec::Psr),
    ("fragment", ClampReceiversSpec::Fragment),
];
const COVERAGES: &[(&str, CoverageSpec)] = &[
    ("conservative", CoverageSpec::Conservative),
    ("point", CoverageSpec::Point),
];
const OCCLUDERS: &[(&str, OccludersSpec)] = &[
    ("mesh", OccludersSpec::Mesh),
    ("proxy", OccludersSpec::Proxy),
];
const TILES: &[(&str, u32)] = &[("4", 4), ("8", 8), ("16", 16)];
const ON_OFF: &[(&str, bool)] = &[("on", true), ("off", false)];

/// The default number of frames of `--path` (the default job's).
const DEFAULT_FRAMES: u32 = 8;

/// `x,y,z`.
fn parse_vec3(s: &str) -> Result<DVec3, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|c| c.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("must look like x,y,z: {e}"))?;
    match v[..] {
        [x, y, z] => Ok(DVec3::new(x, y, z)),
        _ => Err("must have three components".into()),
    }
}

/// A repetition count; 0 counts as 1.
fn parse_reps(s: &str) -> Result<usize, std::num::ParseIntError> {
    Ok(s.parse::<usize>()?.max(1))
}

/// `--map` and `--light-res`: a side in pixels, at least `min`.
fn side(min: i64) -> clap::builder::RangedI64ValueParser<u32> {
    clap::value_parser!(u32).range(min..=i64::from(raster::MAX_TARGET_SIZE))
}

/// The command line; the pipeline flags' defaults are [`PipelineOptions::default`]'s
/// (with `--preset`, the preset's: only the flags given override it).
#[derive(clap::Parser)]
#[command(
    about = "One view, or one camera path, through the stencil shadow pipeline, timed per stage \
             (one JSON line on stdout)",
    args_override_self = true
)]
struct Cli {
    /// A box-city file (`../shared/data/bench/*.txt`), `city` (the bundled default
    /// job's procedural city) or any scene file.
    scene: PathBuf,
    /// One of the scene's camera names (`-` with --eye/--target, or with --path,
    /// which ignores it).
    camera: String,
    /// Viewport, WxH.
    #[arg(value_name = "WxH", value_parser = parse_size)]
    size: (u32, u32),
    /// Start from a preset's options (`gpu_host`: `PipelineOptions::gpu_host`;
    /// `batch`: the defaults); the pipeline flags given override it.
    #[arg(long, value_name = "NAME")]
    preset: Option<shadowcull::Preset>,
    /// Stencil backend.
    #[arg(long, value_parser = one_of(STENCILS),
          default_value = name_of(STENCILS, &PipelineOptions::default().stencil))]
    stencil: StencilBackend,
    /// Per-volume scissor rectangles.
    #[arg(long, value_parser = one_of(ON_OFF), action = ArgAction::Set,
          default_value = name_of(ON_OFF, &PipelineOptions::default().scissor))]
    scissor: bool,
    /// Volume method per caster.
    #[arg(long, value_parser = one_of(METHODS),
          default_value = name_of(METHODS, &PipelineOptions::default().method))]
    method: MethodChoice,
    /// Stencil counter width.
    #[arg(long, visible_alias = "bits", value_parser = one_of(COUNTERS),
          default_value = name_of(COUNTERS, &PipelineOptions::default().counters))]
    counters: StencilBits,
    /// Tile size of the hierarchical stencil.
    #[arg(long, value_parser = one_of(TILES),
          default_value = name_of(TILES, &PipelineOptions::default().tile))]
    tile: u32,
    /// The hierarchical stencil's full-shadow bit.
    #[arg(long = "full-shadow", value_parser = one_of(ON_OFF), action = ArgAction::Set,
          default_value = name_of(ON_OFF, &PipelineOptions::default().full_shadow))]
    full_shadow: bool,
    /// Shadow-map size of the hybrid (texels per side, at least 16).
    #[arg(long = "map", value_name = "N", value_parser = side(16),
          default_value_t = PipelineOptions::default().map_size)]
    map_size: u32,
    /// Occlusion culling of the eye pass and the light views.
    #[arg(long, value_parser = one_of(CULLINGS),
          default_value = name_of(CULLINGS, &PipelineOptions::default().culling))]
    culling: CullingSpec,
    /// Shadow-volume clamping.
    #[arg(long, value_parser = one_of(CLAMPINGS),
          default_value = name_of(CLAMPINGS, &PipelineOptions::default().clamping))]
    clamping: ClampingSpec,
    /// The receivers clamping fits volumes to.
    #[arg(long = "clamping-receivers", value_parser = one_of(CLAMP_RECEIVERS),
          default_value = name_of(CLAMP_RECEIVERS, &PipelineOptions::default().clamping_receivers))]
    clamping_receivers: ClampReceiversSpec,
    /// Discrete clamping's number of slices (1 to 64).
    #[arg(long, default_value_t = PipelineOptions::default().slices)]
    slices: u32,
    /// Counts `bf_fill_unclamped` and `bf_fill_clamped` on any backend by
    /// extra brute-force passes (in `wall_ms`, not in `pipeline_frame_ms`).
    #[arg(long = "count-fill")]
    count_fill: bool,
    /// How culling samples pixels (`point` is aggressive).
    #[arg(long, value_parser = one_of(COVERAGES),
          default_value = name_of(COVERAGES, &PipelineOptions::default().coverage))]
    coverage: CoverageSpec,
    /// The query threshold in samples (above 0 is aggressive).
    #[arg(long = "threshold", value_name = "T",
          default_value_t = PipelineOptions::default().query_threshold)]
    query_threshold: u32,
    /// The side in pixels of every light view of the light pass (at least 8).
    #[arg(long = "light-res", value_name = "N", value_parser = side(8),
          default_value_t = PipelineOptions::default().light_resolution)]
    light_resolution: u32,
    /// Every triangle casts (back-facing ones flipped).
    #[arg(long = "two-sided")]
    two_sided: bool,
    /// The culling eye pass's size, WxH (the largest size within it with the
    /// viewport's aspect; default: the viewport's own).
    #[arg(long = "culling-resolution", value_name = "WxH", value_parser = parse_size)]
    culling_resolution: Option<(u32, u32)>,
    /// What the light views draw as occluders (`proxy`: each solid convex
    /// mesh's proxy).
    #[arg(long, value_parser = one_of(OCCLUDERS),
          default_value = name_of(OCCLUDERS, &PipelineOptions::default().occluders))]
    occluders: OccludersSpec,
    /// Compare with the ray-cast reference (the last frame of one view, every frame of a path).
    #[arg(long)]
    reference: bool,
    /// Check the volumes as a GPU host draws them (`Pipeline::check_gpu`,
    /// outside every timed stage): the brute-force stencil over exactly the
    /// frame's volumes on an exact eye depth, against the reference and
    /// against every caster's volumes; prints `mismatch_off_boundary` and
    /// `culled_vs_unculled_differing_pixels` (summed over the lights; the last
    /// frame of one view, every frame of a path).
    #[arg(long = "check-gpu", conflicts_with = "reference")]
    check_gpu: bool,
    /// Give every frame the host's own depth (`FrameInput::host_depth`), as
    /// a GPU host with a depth pre-pass would: the frame's exact eye depth,
    /// reduced to the culling size, made outside every timed stage. The
    /// eye pass then only queries it.
    #[arg(long = "host-depth")]
    host_depth: bool,
    /// Write the last frame's raw stencil result here as an 8-bit PNG (the
    /// stencil runs only at the pixels whose class it decides: receivers the
    /// light reaches).
    #[arg(long, value_name = "OUT.png")]
    mask: Option<PathBuf>,
    /// One view: frames rendered (the times are their medians).
    #[arg(long, value_name = "R", value_parser = parse_reps, default_value = "5",
          conflicts_with = "path")]
    reps: usize,
    /// A camera path of the scene (`street`, `bird`, or one the scene file names)
    /// instead of one view.
    #[arg(long, value_name = "NAME")]
    path: Option<String>,
    /// Frames 0..N of the camera path.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..),
          default_value_t = DEFAULT_FRAMES, requires = "path")]
    frames: u32,
    /// A point light at x,y,z (replaces the scene's light).
    #[arg(long, value_name = "x,y,z", value_parser = parse_vec3, allow_hyphen_values = true,
          conflicts_with = "sun")]
    light: Option<DVec3>,
    /// A directional light travelling along dx,dy,dz (replaces the scene's light).
    #[arg(long, value_name = "dx,dy,dz", value_parser = parse_vec3, allow_hyphen_values = true)]
    sun: Option<DVec3>,
    /// The eye of the view (with --target; instead of CAMERA).
    #[arg(long, value_name = "x,y,z", value_parser = parse_vec3, allow_hyphen_values = true,
          requires = "target", conflicts_with = "path")]
    eye: Option<DVec3>,
    /// The point the view looks at (with --eye).
    #[arg(long, value_name = "x,y,z", value_parser = parse_vec3, allow_hyphen_values = true,
          requires = "eye", conflicts_with = "path")]
    target: Option<DVec3>,
    /// Vertical field of view of --eye/--target, in degrees.
    #[arg(long, value_name = "DEG", default_value_t = 60.0)]
    fovy: f64,
    /// Near plane distance of --eye/--target.
    #[arg(long, value_name = "D", default_value_t = 0.1)]
    near: f64,
}

/// What a run does, from the command line.
struct Args {
    scene: PathBuf,
    camera: String,
    width: u32,
    height: u32,
    preset: Option<shadowcull::Preset>,
    pipeline: PipelineOptions,
    reference: bool,
    check_gpu: bool,
    host_depth: bool,
    mask: Option<PathBuf>,
    /// Frames of one view.
    reps: usize,
    /// `--path`: a camera path of the scene instead of one view.
    path: Option<String>,
    /// Frames of `--path`.
    frames: u32,
    light: Option<Light>,
    eye: Option<DVec3>,
    target: Option<DVec3>,
    fovy: f64,
    near: f64,
}

impl Args {
    /// The run `c` asks for; `given(id)` says whether the flag of field `id`
    /// was on the command line (only those override `--preset`).
    fn new(c: Cli, given: &dyn Fn(&str) -> bool) -> Args {
        let mut pipeline = PipelineOptions {
            reference_every: 0,
            instruction_set: shadowcull::raster::InstructionSet::cap_from_env(),
            ..c.preset.unwrap_or_default().options()
        };
        macro_rules! flags {
            ($($field:ident),*) => {
                $(if c.preset.is_none() || given(stringify!($field)) {
                    pipeline.$field = c.$field;
                })*
            };
        }
        flags!(
            stencil,
            scissor,
            method,
            counters,
            tile,
            full_shadow,
            map_size,
            culling,
            clamping,
            clamping_receivers,
            slices,
            count_fill,
            coverage,
            query_threshold,
            light_resolution,
            two_sided,
            occluders,
            culling_resolution
        );
        Args {
            scene: c.scene,
            camera: c.camera,
            width: c.size.0,
            height: c.size.1,
            preset: c.preset,
            pipeline,
            reference: c.reference,
            check_gpu: c.check_gpu,
            host_depth: c.host_depth,
            mask: c.mask,
            reps: c.reps,
            path: c.path,
            frames: c.frames,
            light: match (c.light, c.sun) {
                (Some(position), _) => Some(Light::Point {
                    position,
                    range: None,
                }),
                (None, Some(direction)) => Some(Light::Directional { direction }),
                (None, None) => None,
            },
            eye: c.eye,
            target: c.target,
            fovy: c.fovy,
            near: c.near,
        }
    }
}

/// The view from the flags when given, else the scene's named camera.
fn look(a: &Args, loaded: &Loaded) -> anyhow::Result<LookAt> {
    Ok(match (a.eye, a.target) {
        (Some(eye), Some(target)) => LookAt {
            eye,
            target,
            up: DVec3::Y,
            fov_y_deg: a.fovy,
            near: a.near,
        },
        (None, None) => {
            loaded
                .cameras
                .iter()
                .find(|(n, _)| *n == a.camera)
                .with_context(|| {
                    format!(
                        "no camera named {:?} in {} (give --eye and --target)",
                        a.camera,
                        a.scene.display()
                    )
                })?
                .1
        }
        _ => bail!("--eye and --target go together"),
    })
}

/// The scene's camera path `name`.
fn camera_path(a: &Args, loaded: &Loaded, name: &str) -> anyhow::Result<CameraPath> {
    if let Some((_, p)) = loaded.paths.iter().find(|(n, _)| n == name) {
        return Ok(p.clone());
    }
    let names: Vec<&str> = loaded.paths.iter().map(|(n, _)| n.as_str()).collect();
    if names.is_empty() {
        bail!(
            "{} names no camera paths (give CAMERA or --eye/--target for one view)",
            a.scene.display()
        );
    }
    bail!(
        "no camera path named {name:?} in {} (it has {})",
        a.scene.display(),
        names.join(", ")
    )
}

/// The light from the flags when given, else the scene's first light.
fn light(a: &Args, loaded: &Loaded) -> anyhow::Result<Light> {
    match a.light {
        Some(l) => Ok(l),
        None => Ok(loaded
            .lights
            .first()
            .with_context(|| {
                format!(
                    "{} names no light (give --light or --sun)",
                    a.scene.display()
                )
            })?
            .1),
    }
}

/// The bundled default job's procedural city, its first light (above the scene)
/// first in the light list.
fn city() -> anyhow::Result<Loaded> {
    // Its cameras `street` and `bird` are the first poses of its paths.
    let mut l = scene::procedural::city::city(&Default::default())?;
    let b = Scene::new(l.graph.clone())?.bounds();
    let above = LightSpec::AboveScene(1.5).resolve(&l, &b, 0, std::path::Path::new("city"))?;
    l.lights.insert(0, ("above".into(), above));
    Ok(l)
}

/// One frame's statistics row (the one light's) and the wall-clock time of the
/// frame without the reference.
struct Sample {
    row: FrameRow,
    wall_ms: f64,
    /// `--check-gpu`'s counts (zero without it).
    gpu: GpuCounts,
}

type Get<T> = fn(&Sample) -> T;

/// Per-frame times reported as series (path) or medians (one view).
const TIMES: [(&str, Get<f64>); 8] = [
    ("frame_ms", |s| s.row.frame_ms),
    ("pipeline_frame_ms", |s| s.row.pipeline_frame_ms),
    ("wall_ms", |s| s.wall_ms),
    ("eye_ms", |s| s.row.shadow.eye_ms),
    ("light_ms", |s| s.row.shadow.light_ms),
    ("silhouette_ms", |s| s.row.shadow.volumes.silhouette_ms),
    ("volume_ms", |s| s.row.shadow.volumes.volume_ms),
    ("stencil_ms", |s| s.row.shadow.stencil_ms),
];

/// Per-frame counters reported as series along a path.
const COUNTS: [(&str, Get<u64>); 11] = [
    ("psr", |s| s.row.shadow.psr),
    ("psc", |s| s.row.shadow.psc),
    ("queries", |s| s.row.shadow.queries),
    ("waits", |s| s.row.shadow.waits),
    ("pixels_processed", |s| {
        s.row.shadow.stencil.pixels_processed
    }),
    ("volume_triangles", |s| s.row.shadow.volume_triangles),
    ("shadowed_pixels", |s| s.row.shadow.shadowed_pixels),
    ("segments", |s| s.row.shadow.volumes.segments as u64),
    ("sap_pairs", |s| s.row.shadow.volumes.sap_pairs as u64),
    ("bf_fill_unclamped", |s| s.row.shadow.bf_fill_unclamped),
    ("bf_fill_clamped", |s| s.row.shadow.bf_fill_clamped),
];

/// Series along a path with `--reference`.
const REFERENCE_TIMES: [(&str, Get<f64>); 1] = [("reference_ms", |s| s.row.reference.reference_ms)];
const REFERENCE_COUNTS: [(&str, Get<u64>); 3] = [
    ("mismatch_pixels", |s| s.row.check.mismatch_pixels),
    ("mismatch_off_boundary", |s| {
        s.row.check.mismatch_off_boundary
    }),
    ("ambiguous_pixels", |s| s.row.check.ambiguous_pixels),
];

/// What changes between frames: the lights of frame `f` and the scene edits
/// made before it.
struct Frames<'a> {
    /// The lights of frame `f` (one, or the engine scene's three).
    lights: &'a dyn Fn(u32) -> Vec<Light>,
    /// Scene edits before frame `f` (the engine scene's), through the
    /// runner's pipeline.
    edit: &'a mut dyn FnMut(u32, &mut FrameRunner) -> anyhow::Result<()>,
    /// Whether `edit` changes the scene (else `--host-depth` makes every
    /// frame's depth before the first, so that making it does not leave the
    /// timed frames' caches cold).
    edits: bool,
}

/// One frame's rows summed over its lights: the per-light stage times and
/// counters add up (`queries` and `waits` repeat the eye's per light), the
/// frame's own figures (`eye_ms`, `psr`, `pipeline_frame_ms`) are kept once.
fn combined(rows: &[FrameRow]) -> FrameRow {
    let mut out = rows[0];
    for r in &rows[1..] {
        let (o, s) = (&mut out.shadow, &r.shadow);
        o.light_ms += s.light_ms;
        o.stencil_ms += s.stencil_ms;
        o.volumes.silhouette_ms += s.volumes.silhouette_ms;
        o.volumes.volume_ms += s.volumes.volume_ms;
        o.volumes.segments += s.volumes.segments;
        o.volumes.sap_pairs += s.volumes.sap_pairs;
        o.psc += s.psc;
        o.queries += s.queries;
        o.waits += s.waits;
        o.stencil.pixels_processed += s.stencil.pixels_processed;
        o.volume_triangles += s.volume_triangles;
        o.shadowed_pixels += s.shadowed_pixels;
        o.bf_fill_unclamped += s.bf_fill_unclamped;
        o.bf_fill_clamped += s.bf_fill_clamped;
        out.frame_ms += r.frame_ms - s.eye_ms;
        out.reference.reference_ms += r.reference.reference_ms;
        out.check.mismatch_pixels += r.check.mismatch_pixels;
        out.check.mismatch_off_boundary += r.check.mismatch_off_boundary;
        out.check.ambiguous_pixels += r.check.ambiguous_pixels;
    }
    out
}

/// `--check-gpu`'s counts of one frame, summed over its lights
/// ([`shadowcull::GpuCheck`]).
#[derive(Clone, Copy, Default)]
struct GpuCounts {
    mismatch_pixels: u64,
    mismatch_off_boundary: u64,
    culled_vs_unculled_differing_pixels: u64,
}

/// Every light's [`shadowcull::GpuCheck`] of the frame just run.
fn check_gpu(runner: &mut FrameRunner) -> anyhow::Result<GpuCounts> {
    let ids = runner.light_ids().to_vec();
    let pipeline = runner.pipeline_mut().context("a frame ran")?;
    let mut sum = GpuCounts::default();
    for id in ids {
        let c = pipeline.check_gpu(id)?;
        sum.mismatch_pixels += c.mismatch_pixels;
        sum.mismatch_off_boundary += c.mismatch_off_boundary;
        sum.culled_vs_unculled_differing_pixels += c.culled_vs_unculled_differing_pixels;
    }
    Ok(sum)
}

/// `--check-gpu`'s keys.
const GPU_COUNTS: [(&str, Get<u64>); 3] = [
    ("mismatch_pixels", |s| s.gpu.mismatch_pixels),
    ("mismatch_off_boundary", |s| s.gpu.mismatch_off_boundary),
    ("culled_vs_unculled_differing_pixels", |s| {
        s.gpu.culled_vs_unculled_differing_pixels
    }),
];

/// Runs `frames` frames through one persistent runner, frame `f` seen by
/// `camera(f)`, the reference on the frames `reference(f)` names; returns every
/// frame's sample (its lights' rows [`combined`]) and the last frame's
/// first light's result.
fn run(
    a: &Args,
    runner: &mut FrameRunner,
    changes: Frames<'_>,
    frames: u32,
    camera: &dyn Fn(u32) -> anyhow::Result<Camera>,
    reference: &dyn Fn(u32) -> bool,
) -> anyhow::Result<(Vec<Sample>, LightFrame)> {
    let mut samples = Vec::with_capacity(frames as usize);
    let mut last = None;
    let mut depths = match a.host_depth && !changes.edits {
        true => (0..frames)
            .map(|f| host_depth(a, runner.scene(), &camera(f)?).map(Some))
            .collect::<anyhow::Result<Vec<_>>>()?,
        false => Vec::new(),
    };
    for f in 0..frames {
        let cam = camera(f)?;
        (changes.edit)(f, runner)?;
        if a.host_depth {
            let depth = match depths.get_mut(f as usize) {
                Some(d) => d.take(),
                None => Some(host_depth(a, runner.scene(), &cam)?),
            };
            runner.set_host_depth(depth);
        }
        let t = Instant::now();
        let out = runner.frame(
            f,
            &cam,
            &(changes.lights)(f),
            (a.width, a.height),
            &a.pipeline,
            reference(f),
        )?;
        let rows: Vec<FrameRow> = out.iter().map(|lf| lf.row).collect();
        let row = combined(&rows);
        // The reference (and the BVH it builds on first use) is not the pipeline's.
        let wall_ms = t.elapsed().as_secs_f64() * 1e3 - row.reference.reference_ms;
        // One view checks its last frame, a path every frame.
        let gpu = match a.check_gpu && (a.path.is_some() || f + 1 == frames) {
            true => check_gpu(runner)?,
            false => GpuCounts::default(),
        };
        samples.push(Sample { row, wall_ms, gpu });
        last = out.into_iter().next();
    }
    Ok((samples, last.context("at least one frame and one light")?))
}

/// `--host-depth`: the exact eye depth of `scene` seen by `camera`, reduced
/// to the frame's culling size, as a host's depth pre-pass and its
/// min-reduction give it.
fn host_depth(a: &Args, scene: &Scene, camera: &Camera) -> anyhow::Result<HostDepth> {
    let (w, h) = (a.width, a.height);
    let eye = eye::eye_pass(scene, &eye::MeshCache::new(scene), camera, w, h)?;
    let mut rows = Vec::with_capacity(w as usize * h as usize);
    for y in 0..h {
        eye.target
            .for_each_in_row(y, |_, d, _| rows.push(d.max(0.0)));
    }
    let size = a.pipeline.culling_size((w, h));
    Ok(HostDepth::reduce(*camera, (w, h), &rows, size)?)
}

/// The settings and scene size, common to both modes.
fn settings(a: &Args, row: &FrameRow) -> Map<String, Value> {
    let p = &a.pipeline;
    let v = json!({
        "scene": a.scene.display().to_string(),
        "camera": a.path.as_deref().unwrap_or(&a.camera),
        "width": a.width,
        "height": a.height,
        "preset": a.preset.map(|p| serde_json::to_value(p).expect("a unit variant")),
        "stencil": name_of(STENCILS, &p.stencil),
        "scissor": p.scissor,
        "tile": p.tile,
        "counters": name_of(COUNTERS, &p.counters),
        "full_shadow": p.full_shadow,
        "map": p.map_size,
        "method": name_of(METHODS, &p.method),
        "culling": name_of(CULLINGS, &p.culling),
        "coverage": name_of(COVERAGES, &p.coverage),
        "clamping": name_of(CLAMPINGS, &p.clamping),
        "clamping_receivers": name_of(CLAMP_RECEIVERS, &p.clamping_receivers),
        "slices": p.slices,
        "count_fill": p.count_fill,
        "query_threshold": p.query_threshold,
        "light_resolution": p.light_resolution,
        "occluders": name_of(OCCLUDERS, &p.occluders),
        "culling_resolution": p.culling_resolution.map(|(w, h)| [w, h]),
        "culling_size": <[u32; 2]>::from(p.culling_size((a.width, a.height))),
        "host_depth": a.host_depth,
        "objects": row.scene.objects,
        "triangles": row.scene.triangles,
    });
    match v {
        Value::Object(m) => m,
        _ => unreachable!("json! of an object literal"),
    }
}

/// One view as `reps` frames: medians of the times, the last frame's counters.
fn one_view(
    a: &Args,
    runner: &mut FrameRunner,
    camera: &Camera,
    lights: &dyn Fn(u32) -> Vec<Light>,
) -> anyhow::Result<(Map<String, Value>, LightFrame)> {
    let reps = a.reps;
    let changes = Frames {
        lights,
        edit: &mut |_, _| Ok(()),
        edits: false,
    };
    let (samples, lf) = run(a, runner, changes, reps as u32, &|_| Ok(*camera), &|f| {
        a.reference && f + 1 == reps as u32
    })?;
    let silhouette_cached_ms = if samples.len() > 1 {
        median(
            &samples[1..]
                .iter()
                .map(|s| s.row.shadow.volumes.silhouette_ms)
                .collect::<Vec<_>>(),
        )
        .expect("samples")
    } else {
        // One more frame for the warm cache; not part of the reported counters.
        let out = runner.frame(
            reps as u32,
            camera,
            &lights(reps as u32),
            (a.width, a.height),
            &a.pipeline,
            false,
        )?;
        out[0].row.shadow.volumes.silhouette_ms
    };
    let row = &lf.row;
    let s = &row.shadow;
    let mut m = settings(a, row);
    m.insert("reps".into(), reps.into());
    for (key, get) in TIMES {
        m.insert(
            key.into(),
            median(&samples.iter().map(get).collect::<Vec<_>>())
                .expect("samples")
                .into(),
        );
    }
    m.insert(
        "silhouette_cold_ms".into(),
        samples[0].row.shadow.volumes.silhouette_ms.into(),
    );
    m.insert("silhouette_cached_ms".into(), silhouette_cached_ms.into());
    // The last frame's counters: its `stats.csv` columns but the stage times.
    for (key, cell) in s.columns().iter() {
        if !TIMES.iter().any(|(time, _)| time == key) {
            m.insert(key.to_string(), serde_json::to_value(cell)?);
        }
    }
    if a.check_gpu {
        let last = samples.last().expect("samples");
        for (key, get) in GPU_COUNTS {
            m.insert(key.into(), get(last).into());
        }
    }
    if a.reference {
        m.insert("mismatch_pixels".into(), row.check.mismatch_pixels.into());
        m.insert(
            "mismatch_off_boundary".into(),
            row.check.mismatch_off_boundary.into(),
        );
        m.insert("ambiguous_pixels".into(), row.check.ambiguous_pixels.into());
        m.insert("reference_ms".into(), row.reference.reference_ms.into());
    }
    Ok((m, lf))
}

/// Frames 0..N of `path`: per-frame series with their medians and totals.
fn along_path(
    a: &Args,
    runner: &mut FrameRunner,
    path: &CameraPath,
    changes: Frames<'_>,
) -> anyhow::Result<(Map<String, Value>, LightFrame)> {
    let frames = a.frames;
    let aspect = a.width as f64 / a.height as f64;
    let camera = |f: u32| -> anyhow::Result<Camera> {
        let pose = path
            .at(f)
            .with_context(|| format!("the camera path has no pose for frame {f}"))?;
        Ok(pose.camera(aspect)?)
    };
    let (samples, lf) = run(a, runner, changes, frames, &camera, &|_| a.reference)?;
    let mut m = settings(a, &lf.row);
    m.insert("path".into(), a.path.clone().into());
    m.insert("frames".into(), frames.into());
    let (ref_times, ref_counts) = match (a.reference, a.check_gpu) {
        (true, _) => (&REFERENCE_TIMES[..], &REFERENCE_COUNTS[..]),
        (false, true) => (&[][..], &GPU_COUNTS[..]),
        (false, false) => (&[][..], &[][..]),
    };
    for &(key, get) in TIMES.iter().chain(ref_times) {
        let v: Vec<f64> = samples.iter().map(get).collect();
        m.insert(format!("{key}_median"), median(&v).expect("frames").into());
        m.insert(format!("{key}_total"), v.iter().sum::<f64>().into());
        m.insert(key.into(), v.into());
    }
    for &(key, get) in COUNTS.iter().chain(ref_counts) {
        let v: Vec<u64> = samples.iter().map(get).collect();
        m.insert(format!("{key}_median"), median(&v).expect("frames").into());
        m.insert(format!("{key}_total"), v.iter().sum::<u64>().into());
        m.insert(key.into(), v.into());
    }
    Ok((m, lf))
}

/// The engine scene ([`EngineScene`]) as a loaded source: its graph, its
/// path `engine` (and camera `engine`, the path's first pose) and its three
/// lights at frame 0.
fn engine(e: &EngineScene) -> Loaded {
    let path = EngineScene::path();
    let names = ["sun", "point", "spot"];
    Loaded {
        graph: e.graph.clone(),
        cameras: vec![("engine".into(), path.at(0).expect("keyframes"))],
        paths: vec![("engine".into(), path)],
        lights: names
            .into_iter()
            .map(String::from)
            .zip(e.lights(0))
            .collect(),
    }
}

/// Applies the engine scene's edits before frame `f` to the runner's
/// pipeline; `added` maps the scene's handles of added objects to their ids.
fn engine_edits(
    e: &EngineScene,
    f: u32,
    runner: &mut FrameRunner,
    added: &mut HashMap<u32, ObjectId>,
) -> anyhow::Result<()> {
    let Some(p) = runner.pipeline_mut() else {
        return Ok(());
    };
    let edits = e.edits(f);
    for (i, m) in edits.moves {
        let id = p.scene().id_of(i as u32);
        p.set_transform(id, m)?;
    }
    for h in edits.removes {
        if let Some(id) = added.remove(&h) {
            p.remove_object(id)?;
        }
    }
    for (h, mesh, m) in edits.adds {
        added.insert(h, p.add_object(mesh, m, ObjectFlags::ALL)?);
    }
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let matches = <Cli as clap::CommandFactory>::command().get_matches();
    let cli = <Cli as clap::FromArgMatches>::from_arg_matches(&matches)?;
    let a = Args::new(cli, &|id| {
        matches.value_source(id) == Some(clap::parser::ValueSource::CommandLine)
    });
    let engine_scene = (a.scene.as_os_str() == "engine").then(|| EngineScene::new(1));
    let loaded = match (&engine_scene, a.scene.as_os_str() == "city") {
        (Some(e), _) => engine(e),
        (None, true) => city()?,
        (None, false) => scene::load::load_path(&a.scene)?,
    };
    let light = light(&a, &loaded)?;
    // The engine scene's three lights (its point light moves) unless a
    // flag gives one; else the one light.
    let lights = |f: u32| match (&engine_scene, a.light) {
        (Some(e), None) => e.lights(f).to_vec(),
        _ => vec![light],
    };
    let scene = std::sync::Arc::new(Scene::new(loaded.graph.clone())?);
    eprintln!(
        "shadow_bench: {} objects, {} triangles, {}x{}, {}",
        scene.objects().len(),
        scene.counts().drawn_triangles,
        a.width,
        a.height,
        match &a.path {
            Some(p) => format!("path {p}, {} frames", a.frames),
            None => format!("{} reps", a.reps),
        }
    );
    // What a light view drawing every object holds as occluders: full
    // meshes, and with `--occluders proxy` (outside the timed stages).
    let occluder_triangles =
        shadowcull::visibility::MeshData::from_scene(&scene).occluder_triangles(&scene);
    // One runner for every frame: per-view state persists as in a running application.
    let mut runner = FrameRunner::new(scene);
    let mut added = HashMap::new();
    let (mut line, last) = match &a.path {
        Some(name) => {
            let path = camera_path(&a, &loaded, name)?;
            let mut edit = |f: u32, runner: &mut FrameRunner| match &engine_scene {
                Some(e) => engine_edits(e, f, runner, &mut added),
                None => Ok(()),
            };
            let changes = Frames {
                lights: &lights,
                edit: &mut edit,
                edits: engine_scene.is_some(),
            };
            along_path(&a, &mut runner, &path, changes)?
        }
        None => {
            let camera = look(&a, &loaded)?.camera(a.width as f64 / a.height as f64)?;
            one_view(&a, &mut runner, &camera, &lights)?
        }
    };
    if let Some(path) = &a.mask {
        let shadow = last
            .shadow
            .as_ref()
            .context("--mask needs a stencil backend, not --stencil none")?;
        let bytes: Vec<u8> = shadow
            .raw_nonzero
            .iter()
            .map(|&s| if s { 255 } else { 0 })
            .collect();
        shadowcull::mask::write_grey_png(path, a.width, a.height, &bytes)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    line.insert(
        "occluder_triangles_mesh".into(),
        occluder_triangles.0.into(),
    );
    line.insert(
        "occluder_triangles_proxy".into(),
        occluder_triangles.1.into(),
    );
    println!("{}", Value::Object(line));
    Ok(())
}
