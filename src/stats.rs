//! Per-frame statistics: one row per frame and light, written to `stats.csv`,
//! emitted as one `tracing` event, and summed into `summary.json`.
//!
//! Column names are the leaf field names; the benchmark examples' JSON uses
//! the same names. Times are `*_ms`.

use serde::Serialize;

/// Scene-update counters of a frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SceneStats {
    /// Time to update transforms and refit (ms).
    pub update_ms: f64,
    /// Objects in the scene.
    pub objects: u64,
    /// Triangles drawn (all instances; degenerate triangles dropped at load).
    pub triangles: u64,
}

/// Reference counters of a frame and light.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
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

/// The shadow pipeline's counters of a frame and light.
///
/// Growth rule: fields are only added (new counters), never renamed or
/// removed within a major version; construct it with `..Default::default()`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
#[non_exhaustive]
pub struct ShadowStats {
    /// Eye pass: depth and primitive ids (ms) — with culling, the culled eye
    /// pass and the visible surface points the light pass marks. Measured
    /// once per frame; every light's row of the frame repeats it.
    pub eye_ms: f64,
    /// Silhouette extraction, cache lookups included (ms).
    pub silhouette_ms: f64,
    /// Method choice and volume construction (ms).
    pub volume_ms: f64,
    /// The whole stencil stage: clear, every volume, mask assembly (ms).
    pub stencil_ms: f64,
    /// Shadow-volume triangles drawn.
    pub volume_triangles: u64,
    /// Silhouette edges, with multiplicity.
    pub silhouette_edges: u64,
    /// Casters drawn with zpass.
    pub zpass_casters: u64,
    /// Casters drawn with zfail.
    pub zfail_casters: u64,
    /// Casters drawn with zp+.
    pub zpplus_casters: u64,
    /// Per-pixel stencil operations (after the scissor and, with `stencil: db`,
    /// the depth-bounds test).
    pub pixels_processed: u64,
    /// Stencil values changed.
    pub stencil_updates: u64,
    /// Distinct pixels whose stencil value was changed at least once.
    pub pixels_touched: u64,
    /// Pixels the pipeline's mask classes shadow.
    pub shadowed_pixels: u64,
    /// Hierarchical stencil: volume fragments rasterized inside boundary tiles.
    pub h_fragments: u64,
    /// Hierarchical stencil: stage-1 (piece, tile) visits.
    pub tile_tests: u64,
    /// Hierarchical stencil: tiles classified lit, summed over volumes.
    pub tiles_lit: u64,
    /// Hierarchical stencil: tiles classified wholly in shadow, summed over volumes.
    pub tiles_shadow: u64,
    /// Hierarchical stencil: boundary tiles, summed over volumes.
    pub tiles_boundary: u64,
    /// Modeled per-pixel buffer traffic in bytes ([`raster::StencilStats::pixel_bytes`]).
    pub pixel_bytes: u64,
    /// Modeled per-tile buffer traffic in bytes ([`raster::StencilStats::tile_bytes`]).
    pub tile_bytes: u64,
    /// `pixel_bytes + tile_bytes`.
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
}

/// The pipeline's mask against the reference's, on frames that run it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
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
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
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

/// `add` for summing rows into run totals, over the named fields.
macro_rules! summable {
    ($t:ty { $($f:ident),* $(,)? }) => {
        impl $t {
            /// Adds `other`'s counters (and times) to `self`.
            pub fn add(&mut self, other: &Self) {
                $(self.$f += other.$f;)*
            }
        }
    };
}

summable!(ReferenceStats {
    reference_ms,
    lit,
    shadow,
    unlit,
    background,
    ambiguous
});
summable!(ShadowStats {
    eye_ms,
    silhouette_ms,
    volume_ms,
    stencil_ms,
    volume_triangles,
    silhouette_edges,
    zpass_casters,
    zfail_casters,
    zpplus_casters,
    pixels_processed,
    stencil_updates,
    pixels_touched,
    shadowed_pixels,
    h_fragments,
    tile_tests,
    tiles_lit,
    tiles_shadow,
    tiles_boundary,
    pixel_bytes,
    tile_bytes,
    bandwidth_bytes,
    silhouette_pixels,
    map_ms,
    psr,
    psc,
    queries,
    waits,
    light_ms,
});
summable!(CheckStats {
    mismatch_pixels,
    mismatch_off_boundary,
    ambiguous_pixels,
    compared_pixels,
});

/// Defines the flattened row once, so the CSV header, the CSV values and
/// the tracing event can never disagree.
macro_rules! stats_row {
    ($( $name:ident : $($path:ident).+ ),* $(,)?) => {
        impl FrameRow {
            /// Column names of the flattened row, in order.
            pub const COLUMNS: &'static [&'static str] = &[$(stringify!($name)),*];

            /// The flattened row's values, formatted for CSV, in [`FrameRow::COLUMNS`] order.
            pub fn values(&self) -> Vec<String> {
                vec![$(format_value(&self.$($path).+)),*]
            }

            /// Emits the row as one `tracing` event (target `shadowcull::frame`,
            /// level INFO) whose fields are the columns.
            pub fn emit(&self) {
                tracing::info!(target: "shadowcull::frame", $($name = self.$($path).+),*);
            }

            /// Parses a CSV line of [`FrameRow::COLUMNS`] (as [`FrameRow::csv_row`]
            /// writes it; times keep their three decimals).
            ///
            /// # Errors
            /// The column that is missing or not a number.
            pub fn from_csv(line: &str) -> std::result::Result<FrameRow, String> {
                let mut row = FrameRow::default();
                let mut fields = line.split(',');
                $(
                    let text = fields
                        .next()
                        .ok_or_else(|| format!("no `{}` column", stringify!($name)))?;
                    row.$($path).+ = CsvValue::parse(text).ok_or_else(|| {
                        format!("`{}`: {text:?} is not a value of the column", stringify!($name))
                    })?;
                )*
                if fields.next().is_some() {
                    return Err(format!("more than the {} columns", Self::COLUMNS.len()));
                }
                Ok(row)
            }
        }
    };
}

stats_row! {
    frame: frame,
    light: light,
    update_ms: scene.update_ms,
    objects: scene.objects,
    triangles: scene.triangles,
    reference_ms: reference.reference_ms,
    lit: reference.lit,
    shadow: reference.shadow,
    unlit: reference.unlit,
    background: reference.background,
    ambiguous: reference.ambiguous,
    eye_ms: shadow.eye_ms,
    silhouette_ms: shadow.silhouette_ms,
    volume_ms: shadow.volume_ms,
    stencil_ms: shadow.stencil_ms,
    volume_triangles: shadow.volume_triangles,
    silhouette_edges: shadow.silhouette_edges,
    zpass_casters: shadow.zpass_casters,
    zfail_casters: shadow.zfail_casters,
    zpplus_casters: shadow.zpplus_casters,
    pixels_processed: shadow.pixels_processed,
    stencil_updates: shadow.stencil_updates,
    pixels_touched: shadow.pixels_touched,
    shadowed_pixels: shadow.shadowed_pixels,
    h_fragments: shadow.h_fragments,
    tile_tests: shadow.tile_tests,
    tiles_lit: shadow.tiles_lit,
    tiles_shadow: shadow.tiles_shadow,
    tiles_boundary: shadow.tiles_boundary,
    pixel_bytes: shadow.pixel_bytes,
    tile_bytes: shadow.tile_bytes,
    bandwidth_bytes: shadow.bandwidth_bytes,
    silhouette_pixels: shadow.silhouette_pixels,
    map_ms: shadow.map_ms,
    psr: shadow.psr,
    psc: shadow.psc,
    queries: shadow.queries,
    waits: shadow.waits,
    light_ms: shadow.light_ms,
    mismatch_pixels: check.mismatch_pixels,
    mismatch_off_boundary: check.mismatch_off_boundary,
    ambiguous_pixels: check.ambiguous_pixels,
    compared_pixels: check.compared_pixels,
    frame_ms: frame_ms,
    pipeline_frame_ms: pipeline_frame_ms,
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

trait CsvValue: Sized {
    fn csv(&self) -> String;
    fn parse(text: &str) -> Option<Self>;
}
impl CsvValue for f64 {
    fn csv(&self) -> String {
        format!("{self:.3}")
    }
    fn parse(text: &str) -> Option<Self> {
        text.parse().ok()
    }
}
impl CsvValue for u64 {
    fn csv(&self) -> String {
        self.to_string()
    }
    fn parse(text: &str) -> Option<Self> {
        text.parse().ok()
    }
}
impl CsvValue for u32 {
    fn csv(&self) -> String {
        self.to_string()
    }
    fn parse(text: &str) -> Option<Self> {
        text.parse().ok()
    }
}
fn format_value<T: CsvValue>(v: &T) -> String {
    v.csv()
}

impl FrameRow {
    /// The CSV header line (no newline).
    pub fn csv_header() -> String {
        Self::COLUMNS.join(",")
    }

    /// The CSV line of this row (no newline).
    pub fn csv_row(&self) -> String {
        self.values().join(",")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};
    use tracing::field::{Field, Visit};
    use tracing_subscriber::layer::{Context, SubscriberExt};

    struct Capture(Arc<Mutex<Vec<String>>>);
    struct Names<'a>(&'a mut Vec<String>);
    impl Visit for Names<'_> {
        fn record_debug(&mut self, field: &Field, _: &dyn std::fmt::Debug) {
            self.0.push(field.name().to_string());
        }
    }
    impl<S: tracing::Subscriber> tracing_subscriber::Layer<S> for Capture {
        fn on_event(&self, e: &tracing::Event<'_>, _: Context<'_, S>) {
            let mut v = self.0.lock().unwrap();
            e.record(&mut Names(&mut v));
        }
    }

    #[test]
    fn tracing_event_fields_are_the_csv_columns() {
        let names = Arc::new(Mutex::new(Vec::new()));
        let sub = tracing_subscriber::registry().with(Capture(names.clone()));
        tracing::subscriber::with_default(sub, || FrameRow::default().emit());
        assert_eq!(*names.lock().unwrap(), FrameRow::COLUMNS);
    }

    #[test]
    fn totals_add_every_field() {
        let mut a = ShadowStats {
            pixels_processed: 5,
            stencil_ms: 1.5,
            ..Default::default()
        };
        let b = ShadowStats {
            pixels_processed: 7,
            stencil_ms: 2.0,
            shadowed_pixels: 3,
            ..Default::default()
        };
        a.add(&b);
        assert_eq!((a.pixels_processed, a.shadowed_pixels), (12, 3));
        assert_eq!(a.stencil_ms, 3.5);
        let mut c = CheckStats::default();
        c.add(&CheckStats {
            mismatch_pixels: 2,
            compared_pixels: 9,
            ..Default::default()
        });
        assert_eq!((c.mismatch_pixels, c.compared_pixels), (2, 9));
    }

    #[test]
    fn row_matches_header() {
        let mut s = FrameRow {
            frame: 3,
            light: 1,
            ..Default::default()
        };
        s.reference.shadow = 42;
        s.reference.reference_ms = 1.23456;
        let cols = FrameRow::csv_header();
        let row = s.csv_row();
        assert_eq!(cols.split(',').count(), row.split(',').count());
        let pairs: Vec<(&str, &str)> = cols.split(',').zip(row.split(',')).collect();
        assert!(pairs.contains(&("frame", "3")));
        assert!(pairs.contains(&("shadow", "42")));
        assert!(pairs.contains(&("reference_ms", "1.235")));
        // Back from CSV: counters exactly, times to three decimals.
        let back = FrameRow::from_csv(&row).unwrap();
        assert_eq!(back.csv_row(), row);
        assert_eq!((back.frame, back.light, back.reference.shadow), (3, 1, 42));
        assert!(FrameRow::from_csv("3,1").unwrap_err().contains("update_ms"));
        assert!(FrameRow::from_csv(&format!("{row},9")).is_err());
        let bad = row.replacen(",42,", ",x,", 1);
        assert!(FrameRow::from_csv(&bad).unwrap_err().contains("`shadow`"));
    }
}
