//! Per-frame statistics: one row per frame and light, written to `stats.csv`,
//! emitted as one `tracing` event, and summed into `summary.json`.
//!
//! One source: the structs below, grouped by stage and nesting the crates'
//! own counters ([`shadowgen::VolumeStats`], [`raster::StencilStats`],
//! [`visibility::TraversalStats`]). Everything else is derived from their
//! one flattening (the serialized leaves, in order): the `stats.csv` record
//! and the tracing event ([`FrameRow::COLUMNS`]), the totals (`add`), the
//! flat JSON of [`ShadowStats::columns`], and `compare.csv`. Times are
//! `*_ms`.

mod flat;

#[cfg(feature = "jobs")]
pub(crate) use flat::{cells, from_cells, leaves};
pub use flat::{Cell, Columns};
use raster::StencilStats;
use serde::{Deserialize, Serialize};
use shadowgen::VolumeStats;
use std::sync::OnceLock;
use visibility::TraversalStats;

/// Scene-update counters of a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SceneStats {
    /// Time to update transforms and refit (ms).
    pub update_ms: f64,
    /// Objects in the scene.
    pub objects: u64,
    /// Triangles drawn (all instances; degenerate triangles dropped at load).
    pub triangles: u64,
}

/// Reference counters of a frame and light.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ReferenceStats {
    /// Time of the ray-cast reference (ms), 0 when skipped.
    pub reference_ms: f64,
    /// Lit pixels.
    pub lit: u64,
    /// Shadowed pixels.
    pub shadow: u64,
    /// Unlit pixels.
    pub unlit: u64,
    /// Background pixels.
    pub background: u64,
    /// Ambiguous (lit or shadow) pixels.
    pub ambiguous: u64,
}

/// The shadow pipeline's counters of a frame and light: its own, and each
/// stage's counters as the stage's crate reports them.
///
/// Growth rule: fields are only added (new counters), never renamed or
/// removed within a major version; construct it with `..Default::default()`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct ShadowStats {
    /// Eye pass: depth and primitive ids (ms) — with culling, the culled eye
    /// pass and the visible surface points the light pass marks. Measured
    /// once per frame; every light's row of the frame repeats it.
    pub eye_ms: f64,
    /// The whole stencil stage: clear, every volume, mask assembly (ms).
    pub stencil_ms: f64,
    /// Shadow-volume triangles drawn.
    pub volume_triangles: u64,
    /// Pixels the pipeline's mask classes shadow.
    pub shadowed_pixels: u64,
    /// Modeled buffer traffic in bytes: [`StencilStats::bandwidth_bytes`].
    pub bandwidth_bytes: u64,
    /// Hybrid: eye pixels the shadow map leaves to the volumes.
    pub silhouette_pixels: u64,
    /// Hybrid: shadow map rendering and classification (ms), part of `stencil_ms`.
    pub map_ms: f64,
    /// Objects the eye pass drew: the potentially shadowed receivers (all
    /// objects without culling).
    pub psr: u64,
    /// Objects whose shadow volumes were built: the potential shadow casters
    /// of the light pass (all objects without culling).
    pub psc: u64,
    /// Occlusion queries of the eye and light passes.
    pub queries: u64,
    /// Waits for query results in the eye and light passes.
    pub waits: u64,
    /// The light pass: receiver marking and culling in the light views (ms).
    pub light_ms: f64,
    /// Silhouettes and volume construction: silhouette and volume times,
    /// silhouette edges (with multiplicity), casters per method, cache use.
    pub volumes: VolumeStats,
    /// The stencil stage's counters (zero with `stencil: none`): per-pixel
    /// stencil operations (after the scissor and, with `stencil: db`, the
    /// depth-bounds test), stencil updates, pixels touched, the
    /// hierarchical stencil's fragments and tiles, modeled traffic.
    pub stencil: StencilStats,
    /// The light pass's traversal in this light's views (zero without
    /// culling).
    pub light: TraversalStats,
    /// Brute-force pixels processed (under the frame's scissor and
    /// depth-bounds tests) that this light's volumes cost without clamping:
    /// the frame's own count when it draws unclamped volumes with `bf` or
    /// `db`, else counted with [`crate::PipelineOptions::count_fill`]; 0 when
    /// not measured.
    pub bf_fill_unclamped: u64,
    /// The same with continuous clamping's segments [Steiner §4.4]: the
    /// frame's own count when it draws clamped volumes with `bf` or `db`,
    /// else counted with `count_fill`; 0 when not measured.
    pub bf_fill_clamped: u64,
}

/// The pipeline's mask against the reference's, on frames that run it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CheckStats {
    /// Pixels lit or shadow in both masks, not ambiguous, that differ.
    pub mismatch_pixels: u64,
    /// Mismatches without a differently classified 4-neighbour in the reference.
    pub mismatch_off_boundary: u64,
    /// Pixels the reference calls ambiguous (excluded from the comparison).
    pub ambiguous_pixels: u64,
    /// Pixels compared (lit or shadow in both, not ambiguous).
    pub compared_pixels: u64,
}

/// Everything measured for one frame and one light.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameRow {
    /// Frame number, from 0.
    pub frame: u32,
    /// Light index in the job.
    pub light: u32,
    /// Scene update.
    pub scene: SceneStats,
    /// The reference.
    pub reference: ReferenceStats,
    /// The shadow pipeline.
    pub shadow: ShadowStats,
    /// The pipeline against the reference.
    pub check: CheckStats,
    /// The pipeline's time for this light: eye pass + silhouettes + volumes +
    /// stencil (ms); scene load, the reference and image output excluded.
    pub frame_ms: f64,
    /// Wall time of the whole [`crate::Pipeline::frame`] call of this frame,
    /// all lights together (ms; [`FrameStats::frame_ms`]); repeated on each
    /// light's row of the frame.
    pub pipeline_frame_ms: f64,
}

/// Frame-level counters of one [`crate::Pipeline::frame`] call; the
/// per-light counters are each light's [`ShadowStats`].
///
/// Growth rule: fields are only added (new counters), never renamed or
/// removed within a major version.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
#[non_exhaustive]
pub struct FrameStats {
    /// The frame's number ([`crate::Pipeline::set_frame_number`]).
    pub frame: u32,
    /// Wall time of the whole `frame` call, every light included (ms).
    pub frame_ms: f64,
    /// The eye pass, with culling its traversal and the receiver points (ms).
    pub eye_ms: f64,
    /// Objects in the scene.
    pub objects: u64,
    /// Triangles of all objects.
    pub triangles: u64,
    /// Objects the eye pass drew (the PSR; all objects without culling).
    pub psr: u64,
    /// Occlusion queries of the eye pass.
    pub eye_queries: u64,
    /// Waits for eye-pass query results.
    pub eye_waits: u64,
    /// Lights of the frame.
    pub lights: u32,
}

impl ReferenceStats {
    /// Adds `other`'s counters and time to `self`.
    pub fn add(&mut self, other: &Self) {
        flat::add(self, other);
    }
}

impl ShadowStats {
    /// Adds `other`'s counters and times to `self`, nested ones included.
    pub fn add(&mut self, other: &Self) {
        flat::add(self, other);
    }

    /// This light's columns of `stats.csv`, in order: the flat shape of
    /// `summary.json`'s `shadow_totals` and of the Python `light_stats`.
    pub fn columns(&self) -> Columns {
        let row = FrameRow {
            shadow: *self,
            ..Default::default()
        };
        let s = schema();
        let cells = row.cells();
        Columns(
            FrameRow::COLUMNS
                .iter()
                .zip(cells)
                .zip(&s.paths)
                .filter(|(_, path)| path.starts_with("shadow."))
                .map(|((&name, cell), _)| (name, cell))
                .collect(),
        )
    }
}

impl CheckStats {
    /// Adds `other`'s counters to `self`.
    pub fn add(&mut self, other: &Self) {
        flat::add(self, other);
    }
}

impl FrameRow {
    /// The columns of `stats.csv` in order: its header, a contract that
    /// checks read (columns are only appended). Each column is a leaf of
    /// the flattened row: the field of that name — the outermost one when a
    /// crate's counters nested deeper have one of the same name — or the
    /// crate counter [`RENAMED`] gives that name.
    pub const COLUMNS: &'static [&'static str] = &[
        "frame",
        "light",
        "update_ms",
        "objects",
        "triangles",
        "reference_ms",
        "lit",
        "shadow",
        "unlit",
        "background",
        "ambiguous",
        "eye_ms",
        "silhouette_ms",
        "volume_ms",
        "stencil_ms",
        "volume_triangles",
        "silhouette_edges",
        "zpass_casters",
        "zfail_casters",
        "zpplus_casters",
        "pixels_processed",
        "stencil_updates",
        "pixels_touched",
        "shadowed_pixels",
        "h_fragments",
        "tile_tests",
        "tiles_lit",
        "tiles_shadow",
        "tiles_boundary",
        "pixel_bytes",
        "tile_bytes",
        "bandwidth_bytes",
        "silhouette_pixels",
        "map_ms",
        "psr",
        "psc",
        "queries",
        "waits",
        "light_ms",
        "mismatch_pixels",
        "mismatch_off_boundary",
        "ambiguous_pixels",
        "compared_pixels",
        "frame_ms",
        "pipeline_frame_ms",
        "clamp_ms",
        "sap_pairs",
        "sap_swaps",
        "segments",
        "segment_triangles",
        "bf_fill_unclamped",
        "bf_fill_clamped",
        "tiles_scanned",
    ];

    /// The columns a sharded run reproduces byte for byte, whatever its
    /// warm-up: those derived from the masks (conservative culling makes a
    /// mask independent of the coherent history a shard starts without).
    /// `scripts/shard_check.sh` checks them; README.md lists them.
    pub const MASK_COLUMNS: &'static [&'static str] = &[
        "lit",
        "shadow",
        "unlit",
        "background",
        "ambiguous",
        "shadowed_pixels",
        "mismatch_pixels",
        "mismatch_off_boundary",
        "ambiguous_pixels",
        "compared_pixels",
    ];

    /// The columns that depend on coherent history (culling state, caches),
    /// so that a shard's may differ from a single run's: every column but
    /// the frame's and scene's identity (`frame`, `light`, `objects`,
    /// `triangles`), the times (`*_ms`) and [`FrameRow::MASK_COLUMNS`].
    pub fn history_columns() -> impl Iterator<Item = &'static str> {
        let identity = ["frame", "light", "objects", "triangles"];
        Self::COLUMNS.iter().copied().filter(move |c| {
            !identity.contains(c) && !c.ends_with("_ms") && !Self::MASK_COLUMNS.contains(c)
        })
    }

    /// The row's cells in [`FrameRow::COLUMNS`] order.
    pub fn cells(&self) -> Vec<Cell> {
        let mut leaves = flat::cells(self);
        schema()
            .leaf
            .iter()
            .map(|&i| std::mem::replace(&mut leaves[i], Cell::Count(0)))
            .collect()
    }

    /// The row as named cells in [`FrameRow::COLUMNS`] order.
    pub fn columns(&self) -> Columns {
        Columns(Self::COLUMNS.iter().copied().zip(self.cells()).collect())
    }

    /// The index in [`FrameRow::COLUMNS`] of column `name`.
    pub fn column(name: &str) -> Option<usize> {
        Self::COLUMNS.iter().position(|c| *c == name)
    }

    /// Emits the row as one `tracing` event (target `shadowcull::frame`,
    /// level INFO) whose fields are the columns.
    pub fn emit(&self) {
        let enabled = tracing::Level::INFO <= tracing::level_filters::STATIC_MAX_LEVEL
            && tracing::Level::INFO <= tracing::level_filters::LevelFilter::current()
            && {
                let interest = ROW_CALLSITE.interest();
                !interest.is_never()
                    && (interest.is_always()
                        || tracing::dispatcher::get_default(|d| d.enabled(&ROW_EVENT)))
            };
        if !enabled {
            return;
        }
        let cells = self.cells();
        let values: Vec<Option<&dyn tracing::Value>> = cells
            .iter()
            .map(|c| {
                Some(match c {
                    Cell::Count(n) => n as &dyn tracing::Value,
                    Cell::Ms(ms) => ms as &dyn tracing::Value,
                    Cell::Text(s) => s as &dyn tracing::Value,
                })
            })
            .collect();
        // What `tracing::info!` expands to, with the columns as its fields.
        let values = ROW_EVENT.fields().value_set_all(&values);
        tracing_core::Event::dispatch(&ROW_EVENT, &values);
    }
}

/// The crates' counters whose `stats.csv` column has another name than
/// their field: (path in [`FrameRow`], column).
pub const RENAMED: &[(&str, &str)] = &[
    ("shadow.volumes.zpass", "zpass_casters"),
    ("shadow.volumes.zfail", "zfail_casters"),
    ("shadow.volumes.zpplus", "zpplus_casters"),
];

/// Where [`FrameRow::COLUMNS`] are among the row's leaves.
struct Schema {
    /// Per column, the index of its leaf.
    leaf: Vec<usize>,
    /// Per column, its leaf's path (`shadow.stencil.pixels_processed`).
    paths: Vec<String>,
}

fn schema() -> &'static Schema {
    static SCHEMA: OnceLock<Schema> = OnceLock::new();
    SCHEMA.get_or_init(|| {
        let paths: Vec<String> = flat::leaves(&FrameRow::default())
            .into_iter()
            .map(|(path, _)| path)
            .collect();
        let leaf: Vec<usize> = FrameRow::COLUMNS
            .iter()
            .map(|c| leaf_of(&paths, c).unwrap_or_else(|e| panic!("stats.csv column `{c}`: {e}")))
            .collect();
        Schema {
            paths: leaf.iter().map(|&i| paths[i].clone()).collect(),
            leaf,
        }
    })
}

/// The index among the leaf `paths` of column `column`'s leaf.
fn leaf_of(paths: &[String], column: &str) -> Result<usize, String> {
    if let Some((path, _)) = RENAMED.iter().find(|(_, c)| *c == column) {
        return paths
            .iter()
            .position(|p| p == path)
            .ok_or_else(|| format!("no leaf `{path}`"));
    }
    let depth = |p: &str| p.matches('.').count();
    let named: Vec<usize> = (0..paths.len())
        .filter(|&i| paths[i].rsplit('.').next() == Some(column))
        .collect();
    let outermost = named.iter().map(|&i| depth(&paths[i])).min();
    let found: Vec<usize> = named
        .into_iter()
        .filter(|&i| Some(depth(&paths[i])) == outermost)
        .collect();
    match found[..] {
        [i] => Ok(i),
        [] => Err("no field of that name".into()),
        _ => Err(format!(
            "several fields of that name: {}",
            found
                .iter()
                .map(|&i| paths[i].as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// The callsite of [`FrameRow::emit`]'s event, whose fields are the columns.
static ROW_CALLSITE: tracing_core::callsite::DefaultCallsite =
    tracing_core::callsite::DefaultCallsite::new(&ROW_EVENT);

static ROW_EVENT: tracing::Metadata<'static> = tracing::Metadata::new(
    concat!("event ", file!(), ":", line!()),
    "shadowcull::frame",
    tracing::Level::INFO,
    Some(file!()),
    Some(line!()),
    Some(module_path!()),
    tracing_core::field::FieldSet::new(
        FrameRow::COLUMNS,
        tracing_core::identify_callsite!(&ROW_CALLSITE),
    ),
    tracing_core::metadata::Kind::EVENT,
);

/// `stats.csv` through the `csv` crate.
#[cfg(feature = "jobs")]
impl FrameRow {
    /// Writes the header record of `stats.csv`.
    ///
    /// # Errors
    /// The writer's.
    pub fn write_csv_header<W: std::io::Write>(w: &mut csv::Writer<W>) -> csv::Result<()> {
        w.write_record(Self::COLUMNS)
    }

    /// Writes the row as one record of `stats.csv` (times with three
    /// decimals).
    ///
    /// # Errors
    /// The writer's.
    pub fn write_csv<W: std::io::Write>(&self, w: &mut csv::Writer<W>) -> csv::Result<()> {
        w.write_record(self.cells().iter().map(Cell::text))
    }

    /// Parses a record of [`FrameRow::COLUMNS`] (as [`FrameRow::write_csv`]
    /// writes it; times keep their three decimals).
    ///
    /// # Errors
    /// The column that is missing or not a number.
    pub fn from_csv(record: &csv::StringRecord) -> std::result::Result<FrameRow, String> {
        let s = schema();
        if record.len() > Self::COLUMNS.len() {
            return Err(format!("more than the {} columns", Self::COLUMNS.len()));
        }
        // Every leaf of its kind; those of no column stay 0.
        let mut leaves = flat::cells(&FrameRow::default());
        for (k, column) in Self::COLUMNS.iter().enumerate() {
            let text = record
                .get(k)
                .ok_or_else(|| format!("no `{column}` column"))?;
            let leaf = &mut leaves[s.leaf[k]];
            *leaf = leaf
                .parse_like(text)
                .ok_or_else(|| format!("`{column}`: {text:?} is not a value of the column"))?;
        }
        flat::from_cells(leaves).map_err(|e| e.to_string())
    }
}

/// The median of `values` (the upper one of an even count; 0 when empty).
pub fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};
    use tracing::field::{Field, Visit};
    use tracing_subscriber::layer::{Context, SubscriberExt};

    struct Capture(Arc<Mutex<Vec<(String, String)>>>);
    struct Names<'a>(&'a mut Vec<(String, String)>);
    impl Visit for Names<'_> {
        fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
            self.0
                .push((field.name().to_string(), format!("{value:?}")));
        }
    }
    impl<S: tracing::Subscriber> tracing_subscriber::Layer<S> for Capture {
        fn on_event(&self, e: &tracing::Event<'_>, _: Context<'_, S>) {
            assert_eq!(e.metadata().target(), "shadowcull::frame");
            assert_eq!(*e.metadata().level(), tracing::Level::INFO);
            let mut v = self.0.lock().unwrap();
            e.record(&mut Names(&mut v));
        }
    }

    /// `stats.csv`'s header is a contract that checks read: exactly these
    /// columns, in this order (new columns go at the end).
    #[test]
    fn stats_csv_header_is_the_contract() {
        assert_eq!(
            FrameRow::COLUMNS.join(","),
            "frame,light,update_ms,objects,triangles,reference_ms,lit,shadow,unlit,\
             background,ambiguous,eye_ms,silhouette_ms,volume_ms,stencil_ms,\
             volume_triangles,silhouette_edges,zpass_casters,zfail_casters,\
             zpplus_casters,pixels_processed,stencil_updates,pixels_touched,\
             shadowed_pixels,h_fragments,tile_tests,tiles_lit,tiles_shadow,\
             tiles_boundary,pixel_bytes,tile_bytes,bandwidth_bytes,silhouette_pixels,\
             map_ms,psr,psc,queries,waits,light_ms,mismatch_pixels,\
             mismatch_off_boundary,ambiguous_pixels,compared_pixels,frame_ms,\
             pipeline_frame_ms,clamp_ms,sap_pairs,sap_swaps,segments,segment_triangles,\
             bf_fill_unclamped,bf_fill_clamped,tiles_scanned"
        );
    }

    /// Every column has its leaf, and a leaf without a column is one of
    /// these: a field added to a statistics struct is a column (appended to
    /// [`FrameRow::COLUMNS`]) or added here, never forgotten.
    #[test]
    fn every_leaf_is_a_column_or_left_out_on_purpose() {
        let s = schema();
        let columns: Vec<(&str, &str)> = FrameRow::COLUMNS
            .iter()
            .zip(&s.paths)
            .map(|(c, p)| (*c, p.as_str()))
            .collect();
        assert!(columns.contains(&("triangles", "scene.triangles")));
        assert!(columns.contains(&("volume_triangles", "shadow.volume_triangles")));
        assert!(columns.contains(&("queries", "shadow.queries")));
        assert!(columns.contains(&("zpass_casters", "shadow.volumes.zpass")));
        assert!(columns.contains(&("silhouette_ms", "shadow.volumes.silhouette_ms")));
        assert!(columns.contains(&("pixels_processed", "shadow.stencil.pixels_processed")));
        let left_out: Vec<String> = flat::leaves(&FrameRow::default())
            .into_iter()
            .map(|(path, _)| path)
            .filter(|p| !s.paths.contains(p))
            .collect();
        assert_eq!(
            left_out,
            [
                "shadow.volumes.casters",
                "shadow.volumes.cache_hits",
                "shadow.volumes.cache_misses",
                "shadow.volumes.cap_source_triangles",
                "shadow.volumes.volume_triangles",
                "shadow.volumes.finite_volumes",
                "shadow.volumes.clamped_casters",
                "shadow.stencil.triangles",
                "shadow.light.nodes_visited",
                "shadow.light.queries",
                "shadow.light.waits",
                "shadow.light.wait_ms",
                "shadow.light.objects_rendered",
                "shadow.light.triangles_rendered",
                "shadow.light.objects_visible",
            ]
        );
    }

    /// `summary.json`'s `shadow_totals` and the Python `light_stats` keep
    /// their flat keys.
    #[test]
    fn shadow_columns_are_the_flat_keys() {
        let mut s = ShadowStats::default();
        s.volumes.zfail = 4;
        s.stencil.tile_bytes = 9;
        s.map_ms = 0.5;
        let c = s.columns();
        let names: Vec<&str> = c.iter().map(|(n, _)| *n).collect();
        assert_eq!(
            names,
            [
                "eye_ms",
                "silhouette_ms",
                "volume_ms",
                "stencil_ms",
                "volume_triangles",
                "silhouette_edges",
                "zpass_casters",
                "zfail_casters",
                "zpplus_casters",
                "pixels_processed",
                "stencil_updates",
                "pixels_touched",
                "shadowed_pixels",
                "h_fragments",
                "tile_tests",
                "tiles_lit",
                "tiles_shadow",
                "tiles_boundary",
                "pixel_bytes",
                "tile_bytes",
                "bandwidth_bytes",
                "silhouette_pixels",
                "map_ms",
                "psr",
                "psc",
                "queries",
                "waits",
                "light_ms",
                "clamp_ms",
                "sap_pairs",
                "sap_swaps",
                "segments",
                "segment_triangles",
                "bf_fill_unclamped",
                "bf_fill_clamped",
                "tiles_scanned",
            ]
        );
        assert_eq!(c.get("zfail_casters"), Some(&Cell::Count(4)));
        assert_eq!(c.get("tile_bytes"), Some(&Cell::Count(9)));
        assert_eq!(c.get("map_ms"), Some(&Cell::Ms(0.5)));
    }

    #[test]
    fn tracing_event_fields_are_the_csv_columns() {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let sub = tracing_subscriber::registry().with(Capture(seen.clone()));
        let row = FrameRow {
            frame: 7,
            shadow: ShadowStats {
                volumes: VolumeStats {
                    zpplus: 3,
                    ..Default::default()
                },
                ..Default::default()
            },
            frame_ms: 1.5,
            ..Default::default()
        };
        tracing::subscriber::with_default(sub, || row.emit());
        let seen = seen.lock().unwrap();
        let names: Vec<&str> = seen.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, FrameRow::COLUMNS);
        assert!(seen.contains(&("frame".into(), "7".into())));
        assert!(seen.contains(&("zpplus_casters".into(), "3".into())));
        assert!(seen.contains(&("frame_ms".into(), "1.5".into())));
    }

    #[test]
    fn totals_add_every_field() {
        let mut a = ShadowStats {
            stencil_ms: 1.5,
            ..Default::default()
        };
        a.stencil.pixels_processed = 5;
        let mut b = ShadowStats {
            stencil_ms: 2.0,
            shadowed_pixels: 3,
            ..Default::default()
        };
        b.stencil.pixels_processed = 7;
        b.volumes.zpass = 2;
        b.light.wait_ms = 0.25;
        a.add(&b);
        assert_eq!((a.stencil.pixels_processed, a.shadowed_pixels), (12, 3));
        assert_eq!((a.stencil_ms, a.light.wait_ms), (3.5, 0.25));
        assert_eq!(a.volumes.zpass, 2);
        let mut c = CheckStats::default();
        c.add(&CheckStats {
            mismatch_pixels: 2,
            compared_pixels: 9,
            ..Default::default()
        });
        assert_eq!((c.mismatch_pixels, c.compared_pixels), (2, 9));
    }

    #[cfg(feature = "jobs")]
    #[test]
    fn rows_go_through_csv_and_back() {
        let mut s = FrameRow {
            frame: 3,
            light: 1,
            ..Default::default()
        };
        s.reference.shadow = 42;
        s.reference.reference_ms = 1.23456;
        s.shadow.volumes.zfail = 5;
        let mut w = csv::Writer::from_writer(Vec::new());
        FrameRow::write_csv_header(&mut w).unwrap();
        s.write_csv(&mut w).unwrap();
        let text = String::from_utf8(w.into_inner().unwrap()).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], FrameRow::COLUMNS.join(","));
        let pairs: Vec<(&str, &str)> = lines[0].split(',').zip(lines[1].split(',')).collect();
        assert_eq!(pairs.len(), FrameRow::COLUMNS.len());
        assert!(pairs.contains(&("frame", "3")));
        assert!(pairs.contains(&("shadow", "42")));
        assert!(pairs.contains(&("reference_ms", "1.235")));
        assert!(pairs.contains(&("zfail_casters", "5")));
        // Back from CSV: counters exactly, times to three decimals.
        let record = |line: &str| csv::StringRecord::from(line.split(',').collect::<Vec<_>>());
        let back = FrameRow::from_csv(&record(lines[1])).unwrap();
        assert_eq!((back.frame, back.light, back.reference.shadow), (3, 1, 42));
        assert_eq!(
            (back.reference.reference_ms, back.shadow.volumes.zfail),
            (1.235, 5)
        );
        let mut again = csv::Writer::from_writer(Vec::new());
        back.write_csv(&mut again).unwrap();
        assert_eq!(
            again.into_inner().unwrap(),
            format!("{}\n", lines[1]).into_bytes()
        );
        assert!(FrameRow::from_csv(&record("3,1"))
            .unwrap_err()
            .contains("update_ms"));
        assert!(FrameRow::from_csv(&record(&format!("{},9", lines[1]))).is_err());
        let bad = lines[1].replacen(",42,", ",x,", 1);
        assert!(FrameRow::from_csv(&record(&bad))
            .unwrap_err()
            .contains("`shadow`"));
    }
}
