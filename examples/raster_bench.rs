//! Box-city occlusion benchmark of the tile rasterizer, comparable with Intel's
//! Masked Software Occlusion Culling on the same input.
//!
//! `cargo run --release --example raster_bench -- ../shared/data/bench/city_16384.txt street 1920x1080 [--threads N] [--reps R] [--query any|count] [--cull back|none] [--tile 4|8|16]`
//!
//! Loads the box city, sorts the boxes front to back by the distance from the eye to
//! the box centre, then per repetition clears the depth target, rasterizes every box
//! as an occluder (standard coverage; back faces culled as a GPU or MOC would,
//! `--cull none` draws all 12 triangles) and queries every box's AABB (all faces)
//! against the result. Prints one JSON line on stdout: medians over the repetitions of
//! `occluder_ms` (clear + rasterize, sorting excluded) and `query_ms`, the number of
//! `visible_boxes` (query passed ≥ 1 sample), `threads`, and counters. Logs go to stderr.

use anyhow::Context;
use glam::{DMat4, Vec3, Vec4};
use raster::{
    aabb_corners, Coverage, CullMode, DepthTarget, DrawItem, QueryMode, QueryOptions, TileSize,
    AABB_TRIANGLES,
};
use std::path::PathBuf;
use std::time::Instant;
use testkit::cli::{name_of, one_of, parse_size};
use testkit::median;

// The spellings of the flags that choose among fixed values: the parser, its
// error message and the JSON name all come from these tables.
const QUERIES: &[(&str, QueryMode)] = &[("any", QueryMode::Any), ("count", QueryMode::Count)];
const CULLS: &[(&str, CullMode)] = &[("back", CullMode::Back), ("none", CullMode::None)];
const TILES: &[(&str, TileSize)] = &[
    ("4", TileSize::T4),
    ("8", TileSize::T8),
    ("16", TileSize::T16),
];

/// A repetition count; 0 counts as 1.
fn parse_reps(s: &str) -> Result<usize, std::num::ParseIntError> {
    Ok(s.parse::<usize>()?.max(1))
}

/// The command line.
#[derive(clap::Parser)]
#[command(
    about = "Box-city occlusion benchmark of the tile rasterizer (one JSON line on stdout)",
    args_override_self = true
)]
struct Args {
    /// The box-city file (`../shared/data/bench/*.txt`).
    #[arg(value_name = "CITY.txt")]
    path: PathBuf,
    /// One of the city's camera names.
    camera: String,
    /// Viewport, WxH.
    #[arg(value_name = "WxH", value_parser = parse_size)]
    size: (u32, u32),
    /// Rasterizer threads.
    #[arg(long, value_name = "N", default_value_t = 1)]
    threads: usize,
    /// Repetitions; the times are their medians.
    #[arg(long, value_name = "R", value_parser = parse_reps, default_value = "31")]
    reps: usize,
    /// What a query returns: any passing sample or the count.
    #[arg(long = "query", value_parser = one_of(QUERIES), default_value = "any")]
    mode: QueryMode,
    /// Tile edge length in pixels.
    #[arg(long, value_parser = one_of(TILES), default_value = "8")]
    tile: TileSize,
    /// Which occluder faces a draw skips.
    #[arg(long, value_parser = one_of(CULLS), default_value = "back")]
    cull: CullMode,
}

fn main() -> anyhow::Result<()> {
    let a = <Args as clap::Parser>::parse();
    let (width, height) = a.size;
    let loaded = scene::load::box_city::load_box_city(&a.path)?;
    let look = loaded
        .cameras
        .iter()
        .find(|(n, _)| *n == a.camera)
        .with_context(|| format!("no camera named {:?} in {}", a.camera, a.path.display()))?
        .1;
    let cam = look.camera(width as f64 / height as f64)?;
    let graph = &loaded.graph;
    // Box k is node k with one mesh in world coordinates; the ground is not an occluder.
    let mut boxes: Vec<(Vec3, Vec3)> = Vec::new();
    for node in graph.nodes() {
        if node.name == "ground" {
            continue;
        }
        for m in &node.meshes {
            let b = graph.meshes()[m.index()].bounds();
            boxes.push((b.min, b.max));
        }
    }
    let eye = cam.position;
    boxes.sort_by(|p, q| {
        let d = |b: &(Vec3, Vec3)| ((b.0 + b.1).as_dvec3() * 0.5 - eye).length_squared();
        d(p).total_cmp(&d(q))
    });
    let clip_from_world = scene::transform::clip_from_local(&cam, &DMat4::IDENTITY);
    let corners: Vec<[Vec4; 8]> = boxes.iter().map(|&(lo, hi)| aabb_corners(lo, hi)).collect();
    let items: Vec<DrawItem> = corners
        .iter()
        .enumerate()
        .map(|(k, c)| DrawItem {
            clip_from_local: clip_from_world,
            positions: c,
            triangles: &AABB_TRIANGLES,
            object: k as u32,
            cull: a.cull,
        })
        .collect();
    eprintln!(
        "raster_bench: {} boxes, camera {}, {}x{}, {} thread(s), {} reps",
        boxes.len(),
        a.camera,
        width,
        height,
        a.threads,
        a.reps
    );
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.max(1))
        .build()?;
    let mut target = DepthTarget::new(width, height, a.tile, false)?;
    target.set_threads(a.threads.max(1));
    if let Some(cap) = shadowcull::raster::InstructionSet::cap_from_env() {
        target.set_instruction_set(cap);
    }
    let opts = QueryOptions {
        coverage: Coverage::Standard,
        mode: a.mode,
    };
    let mut results = Vec::with_capacity(boxes.len());
    let (mut occ, mut qry) = (Vec::new(), Vec::new());
    let mut draw_stats = raster::RasterStats::default();
    let mut query_stats = raster::RasterStats::default();
    pool.install(|| -> anyhow::Result<()> {
        eprintln!(
            "raster_bench: rayon pool of {} thread(s)",
            rayon::current_num_threads()
        );
        for rep in 0..a.reps {
            let t0 = Instant::now();
            target.clear();
            target.draw_batch(&items, Coverage::Standard)?;
            let t1 = Instant::now();
            let ds = target.take_stats();
            target.query_aabbs(clip_from_world, &boxes, &opts, None, &mut results)?;
            let t2 = Instant::now();
            let qs = target.take_stats();
            occ.push((t1 - t0).as_secs_f64() * 1e3);
            qry.push((t2 - t1).as_secs_f64() * 1e3);
            if rep == 0 {
                draw_stats = ds;
                query_stats = qs;
            }
        }
        Ok(())
    })?;
    let visible = results.iter().filter(|&&n| n > 0).count();
    // FNV-1a of the depth buffer (row-major bits) and of the query results: equal
    // hashes across builds mean bit-identical output.
    let fnv = |words: &mut dyn Iterator<Item = u32>| {
        words.fold(0xcbf2_9ce4_8422_2325u64, |h, w| {
            w.to_le_bytes()
                .iter()
                .fold(h, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3))
        })
    };
    let depth_hash = fnv(&mut target.depth_rows().into_iter().map(f32::to_bits));
    let query_hash = fnv(&mut results.iter().copied());
    // reps >= 1: the medians exist.
    let (occluder_ms, query_ms) = (median(&occ).unwrap(), median(&qry).unwrap());
    // Minimums too: on a shared machine they show the undisturbed cost.
    let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    let (occluder_min_ms, query_min_ms) = (min(&occ), min(&qry));
    let decided = |s: &raster::RasterStats| {
        let whole = s.tiles_rejected_edges + s.tiles_rejected_hiz + s.tiles_query_accepted_whole;
        whole as f64 / s.tiles_touched.max(1) as f64
    };
    let line = serde_json::json!({
        "scene": a.path.display().to_string(),
        "camera": a.camera,
        "width": width,
        "height": height,
        "threads": a.threads,
        "reps": a.reps,
        "query": name_of(QUERIES, &a.mode),
        "tile": target.tile_pixels(),
        "cull": name_of(CULLS, &a.cull),
        "boxes": boxes.len(),
        "occluder_ms": occluder_ms,
        "query_ms": query_ms,
        "occluder_min_ms": occluder_min_ms,
        "query_min_ms": query_min_ms,
        "visible_boxes": visible,
        "depth_hash": format!("{depth_hash:016x}"),
        "query_hash": format!("{query_hash:016x}"),
        "occluder_triangles": draw_stats.triangles_in,
        "occluder_mtri_per_s": draw_stats.triangles_in as f64 / occluder_ms / 1e3,
        "occluder_triangles_clipped": draw_stats.triangles_clipped,
        "occluder_triangles_culled": draw_stats.triangles_culled,
        "occluder_meshes_rejected_hiz": draw_stats.meshes_rejected_hiz,
        "occluder_tiles_touched": draw_stats.tiles_touched,
        "occluder_tiles_rejected_hiz": draw_stats.tiles_rejected_hiz,
        "occluder_tiles_accepted_whole": draw_stats.tiles_accepted_whole,
        "occluder_pixels_tested": draw_stats.pixels_tested,
        "occluder_pixels_written": draw_stats.pixels_written,
        "occluder_tiles_without_pixel_work": decided(&draw_stats),
        "query_tiles_touched": query_stats.tiles_touched,
        "query_tiles_without_pixel_work": decided(&query_stats),
        "query_pixels_tested": query_stats.pixels_tested,
        "queries_apex": query_stats.queries_apex,
        "query_meshes_rejected_hiz": query_stats.meshes_rejected_hiz,
        "query_triangles": query_stats.triangles_in,
    });
    println!("{line}");
    Ok(())
}
