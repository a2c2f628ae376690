//! `shadowcull compare`: the job's pipeline variants on the same frames, each
//! measured on both sides of the speed/accuracy trade — median time per stage
//! and pixels processed, against mismatches with the ray-cast reference.
//!
//! Writes `compare.csv` (one row per variant) and `compare.svg` (time against
//! off-boundary mismatch per variant, with the Pareto front; see
//! `trade_plot.rs`). The reference of a frame and light is computed once
//! and shared by every variant with the same reference options; each variant
//! starts with no history (culling, silhouette caches) at frame 0, so no
//! variant inherits another's work.

use crate::jobs::config::{load_scene_for_job, resolve_lights};
use crate::jobs::config::{Job, NamedPipeline};
use crate::jobs::frame::FrameRunner;
use crate::jobs::run::{atomic, frame_camera};
use crate::jobs::trade_plot::{pareto_front, TradePoint};
use crate::pipeline::{
    ClampReceiversSpec, ClampingSpec, CoverageSpec, CullingSpec, PipelineOptions, StencilBackend,
};
use crate::stats::{cells, from_cells, leaves, median, Cell, FrameRow};
use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// How to run a comparison.
#[derive(Clone, Debug)]
pub struct CompareOptions {
    /// Output directory (created if missing).
    pub out_dir: PathBuf,
    /// Stop after this many frames.
    pub max_frames: Option<u32>,
}

/// One variant's row of `compare.csv`: its fields are the columns, in
/// order. Besides `name`, `rows` and the options (`culling` … `chcpp`), each
/// is the `stats.csv` column of the same name over the variant's rows: a
/// time (`*_ms`) their median, a counter their sum.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct VariantRow {
    /// Variant name.
    pub name: String,
    /// Frame-and-light rows measured.
    pub rows: u64,
    /// Median eye-pass time (ms).
    pub eye_ms: f64,
    /// Median silhouette time (ms).
    pub silhouette_ms: f64,
    /// Median volume-construction time (ms).
    pub volume_ms: f64,
    /// Median stencil-stage time (ms).
    pub stencil_ms: f64,
    /// Median pipeline time per frame and light (ms).
    pub frame_ms: f64,
    /// Shadow-volume triangles, summed over the rows.
    pub volume_triangles: u64,
    /// Per-pixel stencil operations, summed over the rows.
    pub pixels_processed: u64,
    /// Shadowed pixels of the pipeline's masks, summed.
    pub shadowed_pixels: u64,
    /// Mismatches against the reference, summed.
    pub mismatch_pixels: u64,
    /// Mismatches off a reference shadow boundary, summed.
    pub mismatch_off_boundary: u64,
    /// Ambiguous pixels (excluded), summed.
    pub ambiguous_pixels: u64,
    /// Pixels compared, summed.
    pub compared_pixels: u64,
    /// Hierarchical stencil: fragments inside boundary tiles, summed.
    pub h_fragments: u64,
    /// Hierarchical stencil: stage-1 tile visits, summed.
    pub tile_tests: u64,
    /// Hierarchical stencil: boundary tiles over all volumes, summed.
    pub tiles_boundary: u64,
    /// Modeled bandwidth (per-pixel plus per-tile bytes), summed.
    pub bandwidth_bytes: u64,
    /// Hybrid: pixels left to the volumes, summed.
    pub silhouette_pixels: u64,
    /// Culling traversal (`none`, `frustum`, `exact`, `chc`, `chcpp`, `auto`).
    pub culling: String,
    /// Culling's sampling (`conservative` or the aggressive `point`).
    pub coverage: String,
    /// Query threshold (0: conservative).
    pub query_threshold: u32,
    /// Light-view side in pixels.
    pub light_resolution: u32,
    /// CHC++ parameters `batch/revisit/seed` (empty for other traversals).
    pub chcpp: String,
    /// Median light-pass time (ms).
    pub light_ms: f64,
    /// Potentially shadowed receivers (eye pass), summed over the rows.
    pub psr: u64,
    /// Potential shadow casters, summed over the rows.
    pub psc: u64,
    /// Occlusion queries (eye and light passes), summed.
    pub queries: u64,
    /// Waits for query results, summed.
    pub waits: u64,
    /// Shadow-volume clamping (`none`, `continuous`).
    pub clamping: String,
    /// Clamping's receivers (`all`, `psr`, `fragment`).
    pub clamping_receivers: String,
    /// Median clamping time (ms).
    pub clamp_ms: f64,
    /// Clamping's overlapping pairs, summed.
    pub sap_pairs: u64,
    /// Clamping's endpoint swaps, summed.
    pub sap_swaps: u64,
    /// Segments of clamped casters, summed.
    pub segments: u64,
    /// Triangles of those segments, summed.
    pub segment_triangles: u64,
    /// Brute-force pixels processed by the volumes without clamping, summed
    /// (counted for the clamping variants and by `bf`/`db` themselves).
    pub bf_fill_unclamped: u64,
    /// The same with clamping's segments, summed.
    pub bf_fill_clamped: u64,
    /// 1 when the variant is on the comparison's Pareto front of `frame_ms`
    /// against `mismatch_off_boundary` (no other variant is at least as fast
    /// and as close, and better in one), else 0.
    pub pareto: u64,
}

/// A serde enum's lowercase name (`chcpp`, `point`).
fn spec_name<T: Serialize>(v: &T) -> String {
    ron::to_string(v).unwrap_or_default().to_lowercase()
}

impl VariantRow {
    fn from_rows(name: &str, p: &PipelineOptions, rows: &[FrameRow]) -> Self {
        let table: Vec<Vec<Cell>> = rows.iter().map(FrameRow::cells).collect();
        let chcpp = if matches!(p.culling, CullingSpec::Chcpp | CullingSpec::Auto) {
            format!("{}/{}/{}", p.chcpp.batch, p.chcpp.revisit, p.chcpp.seed)
        } else {
            String::new()
        };
        let cells = leaves(&VariantRow::default())
            .into_iter()
            .map(|(column, kind)| match column.as_str() {
                "name" => Cell::Text(name.to_string()),
                "rows" => Cell::Count(rows.len() as u64),
                "culling" => Cell::Text(spec_name(&p.culling)),
                "coverage" => Cell::Text(spec_name(&p.coverage)),
                "query_threshold" => Cell::Count(p.query_threshold.into()),
                "light_resolution" => Cell::Count(p.light_resolution.into()),
                "chcpp" => Cell::Text(chcpp.clone()),
                "clamping" => Cell::Text(spec_name(&p.clamping)),
                "clamping_receivers" => Cell::Text(spec_name(&p.clamping_receivers)),
                // Set over the whole table, by `mark_front`.
                "pareto" => Cell::Count(0),
                stat => {
                    let k = FrameRow::column(stat)
                        .unwrap_or_else(|| panic!("`{stat}` is not a stats.csv column"));
                    let column = table.iter().map(|r| &r[k]);
                    match kind {
                        Cell::Ms(_) => Cell::Ms(median(&column.map(Cell::ms).collect::<Vec<_>>())),
                        _ => Cell::Count(column.map(Cell::count).sum()),
                    }
                }
            });
        from_cells(cells).expect("a cell per column of its kind")
    }
}

/// `compare.csv`: a header of [`VariantRow`]'s fields, then one record per
/// variant.
fn write_csv(rows: &[VariantRow]) -> std::io::Result<Vec<u8>> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(leaves(&VariantRow::default()).iter().map(|(name, _)| name))?;
    for r in rows {
        w.write_record(cells(r).iter().map(Cell::text))?;
    }
    w.into_inner().map_err(|e| e.into_error())
}

/// The variants a job compares: its `pipelines`, or when empty brute force,
/// depth bounds, scissor with depth bounds, the hierarchical stencil with
/// tiles 4, 8 and 16, the shadow-map hybrid, and the hierarchical stencil
/// with CHC, CHC++, point-sampled (aggressive) CHC++, point-sampled CHC++
/// in 256² light views (`h_chcpp_point_lr256`, a trade point), CHC++ with a
/// query threshold of 16 samples (`h_chcpp_t16`, a trade point), the hybrid
/// reading point-sampled CHC++ light views of 1024² and 512²
/// (`hybrid_chcpp_point`, `hybrid_chcpp_point_lr512`, trade points),
/// `scissor_db` with `auto` culling in point-sampled 512² light views
/// (`scissor_db_auto_point_lr512`, a trade point) and `auto` culling,
/// `auto` culling with `auto` stencil (`auto`), and brute
/// force with continuous clamping (receivers `all`, `psr`, and `fragment`
/// with CHC++; each counts the fill without and with clamping,
/// `count_fill`), each otherwise like `pipeline`.
pub fn variants(job: &Job) -> Vec<NamedPipeline> {
    if !job.pipelines.is_empty() {
        return job.pipelines.clone();
    }
    let base = job.pipeline;
    let with = |name: &str, stencil, scissor, tile| NamedPipeline {
        name: name.into(),
        pipeline: PipelineOptions {
            stencil,
            scissor,
            tile,
            ..base
        },
    };
    let culled_at = |name: &str, culling, coverage, light_resolution| NamedPipeline {
        name: name.into(),
        pipeline: PipelineOptions {
            stencil: StencilBackend::H,
            tile: 8,
            culling,
            coverage,
            light_resolution,
            ..base
        },
    };
    let culled =
        |name: &str, culling, coverage| culled_at(name, culling, coverage, base.light_resolution);
    let clamped = |name: &str, clamping_receivers| NamedPipeline {
        name: name.into(),
        pipeline: PipelineOptions {
            stencil: StencilBackend::Bf,
            clamping: ClampingSpec::Continuous,
            clamping_receivers,
            count_fill: true,
            ..base
        },
    };
    vec![
        with("bf", StencilBackend::Bf, false, 8),
        with("db", StencilBackend::Db, false, 8),
        with("scissor_db", StencilBackend::Db, true, 8),
        with("h_tile4", StencilBackend::H, false, 4),
        with("h", StencilBackend::H, false, 8),
        with("h_tile16", StencilBackend::H, false, 16),
        with("hybrid", StencilBackend::Hybrid, false, 8),
        culled("h_chc", CullingSpec::Chc, CoverageSpec::Conservative),
        culled("h_chcpp", CullingSpec::Chcpp, CoverageSpec::Conservative),
        culled("h_chcpp_point", CullingSpec::Chcpp, CoverageSpec::Point),
        // A trade point: point sampling in 256² light views (aggressive).
        culled_at(
            "h_chcpp_point_lr256",
            CullingSpec::Chcpp,
            CoverageSpec::Point,
            256,
        ),
        // A trade point: a node needs more than 16 samples to be visible
        // (aggressive; each query counts only up to 17). Default job's
        // street path, point light: PSC 196 -> 123, stencil 9.0 -> 6.5 ms,
        // 15 mismatched pixels over 8 frames, none off a boundary.
        NamedPipeline {
            name: "h_chcpp_t16".into(),
            pipeline: PipelineOptions {
                query_threshold: 16,
                ..culled("", CullingSpec::Chcpp, CoverageSpec::Conservative).pipeline
            },
        },
        // Trade points: the hybrid's maps are the light views.
        NamedPipeline {
            name: "hybrid_chcpp_point".into(),
            pipeline: PipelineOptions {
                stencil: StencilBackend::Hybrid,
                ..culled("", CullingSpec::Chcpp, CoverageSpec::Point).pipeline
            },
        },
        NamedPipeline {
            name: "hybrid_chcpp_point_lr512".into(),
            pipeline: PipelineOptions {
                stencil: StencilBackend::Hybrid,
                ..culled_at("", CullingSpec::Chcpp, CoverageSpec::Point, 512).pipeline
            },
        },
        // The trade point that buys most on bird views: brute force with
        // depth bounds and scissor, `auto` culling, point-sampled 512²
        // light views (city bird, point light: 1.55x the fastest exact).
        NamedPipeline {
            name: "scissor_db_auto_point_lr512".into(),
            pipeline: PipelineOptions {
                stencil: StencilBackend::Db,
                scissor: true,
                ..culled_at("", CullingSpec::Auto, CoverageSpec::Point, 512).pipeline
            },
        },
        culled("h_auto", CullingSpec::Auto, CoverageSpec::Conservative),
        NamedPipeline {
            name: "auto".into(),
            pipeline: PipelineOptions {
                stencil: StencilBackend::Auto,
                culling: CullingSpec::Auto,
                coverage: CoverageSpec::Conservative,
                ..base
            },
        },
        clamped("bf_clamp", ClampReceiversSpec::All),
        clamped("bf_clamp_psr", ClampReceiversSpec::Psr),
        // Fragment receivers come from the light pass: culled.
        NamedPipeline {
            name: "bf_clamp_fragment".into(),
            pipeline: PipelineOptions {
                culling: CullingSpec::Chcpp,
                ..clamped("", ClampReceiversSpec::Fragment).pipeline
            },
        },
        // Discrete clamping [Steiner §4.4.2], 10 slices: exact with
        // conservative light views, aggressive with point-sampled ones.
        NamedPipeline {
            name: "bf_clamp_discrete".into(),
            pipeline: PipelineOptions {
                culling: CullingSpec::Chcpp,
                clamping: ClampingSpec::Discrete,
                ..clamped("", ClampReceiversSpec::All).pipeline
            },
        },
        NamedPipeline {
            name: "bf_clamp_auto".into(),
            pipeline: PipelineOptions {
                culling: CullingSpec::Chcpp,
                clamping: ClampingSpec::Auto,
                ..clamped("", ClampReceiversSpec::Fragment).pipeline
            },
        },
        NamedPipeline {
            name: "bf_clamp_discrete_point".into(),
            pipeline: PipelineOptions {
                culling: CullingSpec::Chcpp,
                coverage: CoverageSpec::Point,
                clamping: ClampingSpec::Discrete,
                ..clamped("", ClampReceiversSpec::All).pipeline
            },
        },
    ]
}

/// Runs every variant of `job` (from `job_file`; the bundled default when
/// `None`) on the same frames, with the reference on every frame, and writes
/// `compare.csv` and `compare.svg` into `options.out_dir`.
///
/// # Errors
/// Scene, job, pipeline and I/O errors.
pub fn compare_job(
    job: &Job,
    job_file: Option<&Path>,
    options: &CompareOptions,
) -> Result<Vec<VariantRow>> {
    let file = job_file.unwrap_or(Path::new("<default job>"));
    // One writer per directory, before any work.
    crate::jobs::run::check_max_frames(options.max_frames)?;
    let _lock = crate::jobs::out_dir::OutputLock::acquire(&options.out_dir)?;
    let capped = job
        .frame_count()
        .min(options.max_frames.unwrap_or(u32::MAX));
    let count = variants(job).len() as u32;
    let named = job.lights.len().max(1) as u32;
    crate::jobs::run::check_job_memory(job, capped, count, named, None)?;
    let (loaded, scene, path) = load_scene_for_job(job, job_file)?;
    let lights = resolve_lights(job, &loaded, &scene.bounds(), file)?;
    crate::jobs::run::check_job_memory(
        job,
        capped,
        count,
        lights.len() as u32,
        Some(&scene.counts()),
    )?;
    let frames = job
        .frame_count()
        .min(options.max_frames.unwrap_or(u32::MAX));
    let res = job.resolution;
    let mut runner = FrameRunner::new(scene);
    runner.cache_references(true);
    // Every variant starts cold at frame 0, and forgets at the job's keyframes.
    runner.set_keyframe(job.keyframe);
    let mut table = Vec::new();
    for v in variants(job) {
        let mut rows = Vec::new();
        for frame in 0..frames {
            let camera = frame_camera(&path, frame, res, file)?;
            let out = runner
                .frame(frame, &camera, &lights, res, &v.pipeline, true)
                .map_err(|e| Error::Job {
                    file: file.to_path_buf(),
                    location: format!("pipelines ({})", v.name),
                    message: e.to_string(),
                })?;
            rows.extend(out.into_iter().map(|lf| lf.row));
        }
        let row = VariantRow::from_rows(&v.name, &v.pipeline, &rows);
        tracing::info!(target: "shadowcull::compare", variant = %row.name, frame_ms = row.frame_ms,
            pixels_processed = row.pixels_processed, mismatch_pixels = row.mismatch_pixels);
        table.push(row);
    }
    mark_front(&mut table);
    let out = &options.out_dir;
    let csv_path = out.join("compare.csv");
    atomic(&csv_path, |tmp| std::fs::write(tmp, write_csv(&table)?))?;
    let svg_path = out.join("compare.svg");
    atomic(&svg_path, |tmp| {
        plot(&table, tmp).map_err(|e| std::io::Error::other(e.to_string()))
    })?;
    Ok(table)
}

/// Sets every row's `pareto` column from the table's front of `frame_ms`
/// against `mismatch_off_boundary` ([`crate::jobs::trade_plot::pareto_front`]).
fn mark_front(table: &mut [VariantRow]) {
    let points: Vec<(f64, u64)> = table
        .iter()
        .map(|r| (r.frame_ms, r.mismatch_off_boundary))
        .collect();
    for (row, on) in table.iter_mut().zip(pareto_front(&points)) {
        row.pareto = on.into();
    }
}

/// `compare.svg`: [`crate::jobs::trade_plot`]'s plot of the table.
fn plot(rows: &[VariantRow], path: &Path) -> std::result::Result<(), Box<dyn std::error::Error>> {
    let points: Vec<TradePoint> = rows
        .iter()
        .map(|r| TradePoint {
            name: r.name.clone(),
            ms: r.frame_ms,
            mismatch: r.mismatch_off_boundary,
            front: r.pareto != 0,
        })
        .collect();
    crate::jobs::trade_plot::plot(&points, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_aggregates_medians_and_sums() {
        let mut rows = vec![FrameRow::default(); 3];
        for (i, r) in rows.iter_mut().enumerate() {
            r.frame_ms = [5.0, 1.0, 3.0][i];
            r.shadow.stencil.pixels_processed = 10 * (i as u64 + 1);
            r.shadow.volumes.silhouette_ms = [0.5, 0.25, 2.0][i];
            r.check.mismatch_pixels = i as u64;
        }
        let unculled = PipelineOptions {
            culling: CullingSpec::None,
            ..Default::default()
        };
        let v = VariantRow::from_rows("a,b", &unculled, &rows);
        assert_eq!(v.frame_ms, 3.0);
        assert_eq!(v.silhouette_ms, 0.5);
        assert_eq!(v.pixels_processed, 60);
        assert_eq!(v.mismatch_pixels, 3);
        assert_eq!(v.rows, 3);
        assert_eq!((v.culling.as_str(), v.chcpp.as_str()), ("none", ""));
        let text = String::from_utf8(write_csv(&[v]).unwrap()).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert!(
            lines[1].starts_with("\"a,b\",3,0.000,0.500,"),
            "{}",
            lines[1]
        );
        assert_eq!(
            lines[1].matches(',').count() - 1,
            lines[0].matches(',').count()
        );
    }

    /// `compare.csv`'s header is a contract: exactly these columns, in this
    /// order (new columns go at the end).
    #[test]
    fn compare_csv_header_is_the_contract() {
        let text = String::from_utf8(write_csv(&[]).unwrap()).unwrap();
        assert_eq!(
            text,
            "name,rows,eye_ms,silhouette_ms,volume_ms,stencil_ms,frame_ms,volume_triangles,\
             pixels_processed,shadowed_pixels,mismatch_pixels,mismatch_off_boundary,\
             ambiguous_pixels,compared_pixels,h_fragments,tile_tests,tiles_boundary,\
             bandwidth_bytes,silhouette_pixels,culling,coverage,query_threshold,\
             light_resolution,chcpp,light_ms,psr,psc,queries,waits,clamping,\
             clamping_receivers,clamp_ms,sap_pairs,sap_swaps,segments,segment_triangles,\
             bf_fill_unclamped,bf_fill_clamped,pareto\n"
        );
    }
}
