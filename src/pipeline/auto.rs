//! `culling: auto` and `stencil: auto`: per view and per frame, one of two
//! modes, whichever a cost model of earlier frames' counters finds cheaper.
//!
//! `culling: auto`, for each view — the eye pass, and each light's light
//! pass — chooses whether to cull (CHC++) or to draw everything.
//! Culling pays when it removes more work than its traversal costs: on a
//! street view it removes nearly every object; on a bird view, where most
//! objects are visible and cast visible shadows, its queries cost more than
//! they save; in a scene of a few large objects there is nothing to remove
//! [Steiner §2.5.1, §5].
//!
//! `stencil: auto`, for each light, chooses the hierarchical stencil (`h`)
//! or the brute-force one with the depth-bounds test and scissor rectangles
//! (`db`). `h` pays where volumes cover large screen areas of few boundary
//! tiles (its whole-tile updates); `db` where many small or distant volumes
//! make `h` test many tiles and rasterize most of them per pixel anyway,
//! while the depth bounds and scissors reject most of their fragments
//! [Aila04 §5, EK].
//!
//! `clamping: auto`, for each light, chooses between no clamping,
//! continuous and discrete clamping [Steiner §4.4]: two such choices in a
//! row, clamping or not (first mode: clamping), and on clamped frames
//! discrete or continuous (first mode: discrete). A frame's cost is the
//! light's whole modeled cost ([`LightCosts`]: light pass, volumes,
//! stencil), its receiver points counted twice where fragment receivers
//! mark the stored depths too, plus `receiver_pixel` per marked pixel read
//! for clamping. Segments cost volume triangles and save stencil
//! fragments; the reading costs its pixels.
//!
//! The decision reads counters of earlier frames and the cost constants of
//! [`AutoSpec`], never a timer, so a run's choices — and so its counters —
//! are a function of its inputs: repeated runs choose alike, and so do
//! shards that reset at the same keyframes. Masks never depend on it.
//!
//! The rule, per view (for the stencil, per light; its first mode is `h`,
//! its second `db`, and neither needs a warm frame):
//! 1. Each mode has a modeled cost: a weighted sum of the counters of the
//!    stage it changes ([`eye_cost`], [`LightCosts`], [`stencil_cost`]);
//!    the bundled eye's culled traversal runs as two halves side by side
//!    and costs its slower half ([`split_eye_cost`]). A culled frame measures the culled cost; an unculled frame the unculled
//!    one. A light's culled frame also estimates its unculled cost: the
//!    volumes of every caster, scaled from those of the potential casters by
//!    caster triangles. The estimate is kept only when it differs from the
//!    culled cost by more than the factor `margin`; a close call is measured
//!    by a probe instead, as the eye's always is.
//! 2. The view runs the mode with the lower known cost, culling on a tie.
//!    Only a warm culled frame (one after a culled frame) measures the
//!    culled cost: the first culled frame after a gap has no history and
//!    queries far more.
//! 3. A kept cost goes stale: once the other mode's cost is `period` frames
//!    old it is probed — run for one frame, two for culling (cold, then
//!    warm). The period starts at `probe` frames and doubles, up to eight
//!    times `probe`, each time a probe confirms the choice; it starts over
//!    when a probe reverses it.
//! 4. After [`super::Pipeline::reset_history`] (and in a new pipeline) a
//!    view starts with its first mode (culling: cold, then warm), then
//!    measures the second.
//! 5. A scene with fewer than `min_objects` objects never culls.

use super::options::{AutoSpec, StencilCosts};
use super::shadow_options::{Backend, ShadowOptions};
use raster::{RasterStats, StencilStats};
use visibility::TraversalStats;

/// A modeled cost and the frame (counted from the view's last reset) it
/// was measured or estimated in.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Cost {
    value: f64,
    at: u32,
}

/// One view's choice state across frames, between a first mode (culling;
/// the stencil's `h`) and a second (no culling; `db`).
#[derive(Clone, Debug, Default)]
pub(crate) struct AutoView {
    /// The first mode's cost (`culled`) and the second's.
    culled: Option<Cost>,
    unculled: Option<Cost>,
    /// Consecutive first-mode frames up to the last one.
    culled_run: u32,
    /// First-mode frames in a row before one measures its cost: 2 for
    /// culling (its first frame after a gap has no history), 1 for a choice
    /// without state.
    warm: u32,
    /// Frames observed since the last reset.
    frames: u32,
    /// Frames after which the mode not chosen is probed (0: `probe`).
    period: u32,
    /// While a probe runs: the mode preferred before it (true: culling).
    probing: Option<bool>,
}

impl AutoView {
    /// A view choosing whether to cull.
    pub fn culling() -> Self {
        AutoView {
            warm: 2,
            ..AutoView::default()
        }
    }

    /// A light choosing its stencil (true: `h`).
    pub fn stencil() -> Self {
        AutoView {
            warm: 1,
            ..AutoView::default()
        }
    }

    /// Forgets everything (a keyframe, new options).
    pub fn reset(&mut self) {
        *self = AutoView {
            warm: self.warm,
            ..AutoView::default()
        };
    }

    /// Whether this frame runs the first mode (culls).
    pub fn choose(&mut self, spec: &AutoSpec) -> bool {
        if self.period == 0 {
            self.period = spec.probe.max(1);
        }
        if let Some(preferred) = self.probing {
            // A culling probe lasts until its warm frame.
            return !preferred;
        }
        let (Some(c), Some(u)) = (self.culled, self.unculled) else {
            return match self.culled {
                None => true,
                // Culled cost known, unculled not (the eye): measure it.
                Some(_) => {
                    self.probing = Some(true);
                    false
                }
            };
        };
        let preferred = c.value <= u.value;
        let other = if preferred { u.at } else { c.at };
        if self.frames.saturating_sub(other) >= self.period {
            self.probing = Some(preferred);
            return !preferred;
        }
        preferred
    }

    /// The lower of the two modes' known costs; `None` before any.
    pub fn best(&self) -> Option<f64> {
        match (self.culled, self.unculled) {
            (Some(a), Some(b)) => Some(a.value.min(b.value)),
            (a, b) => a.or(b).map(|c| c.value),
        }
    }

    /// Records the frame just run: whether it culled, its modeled cost, and
    /// (a light's culled frame) the estimated unculled cost.
    pub fn observe(&mut self, spec: &AutoSpec, culled: bool, cost: f64, unculled: Option<f64>) {
        let at = self.frames;
        if culled {
            self.culled_run += 1;
            if self.culled_run >= self.warm.max(1) {
                self.culled = Some(Cost { value: cost, at });
            }
            // An estimate close to the culled cost is not trusted: the
            // unculled mode is then measured by a probe.
            let margin = spec.margin.max(1.0);
            let sure = |e: f64| e >= cost * margin || e * margin <= cost;
            if let Some(value) = unculled.filter(|e| sure(*e)) {
                self.unculled = Some(Cost { value, at });
            }
        } else {
            self.culled_run = 0;
            self.unculled = Some(Cost { value: cost, at });
        }
        if let Some(before) = self.probing {
            let done = if before {
                !culled
            } else {
                culled && self.culled_run >= self.warm.max(1)
            };
            if done {
                self.probing = None;
                let after = match (self.culled, self.unculled) {
                    (Some(c), Some(u)) => c.value <= u.value,
                    _ => before,
                };
                let base = spec.probe.max(1);
                self.period = if after == before {
                    (self.period.max(base) * 2).min(base.saturating_mul(8))
                } else {
                    base
                };
            }
        }
        self.frames = self.frames.saturating_add(1);
    }
}

/// The eye pass's modeled cost from the eye target's raster counters and
/// the traversal's: culled, the traversal's draws and query boxes one at a
/// time, its nodes, and the queries a host backend answered; unculled, one
/// parallel batch of every object.
pub(crate) fn eye_cost(
    spec: &AutoSpec,
    culled: bool,
    raster: &RasterStats,
    traversal: &TraversalStats,
    host_queries: bool,
) -> f64 {
    let (tri, tile, px) = (
        raster.triangles_in as f64,
        raster.tiles_touched as f64,
        raster.pixels_tested as f64,
    );
    if !culled {
        return spec.batch_triangle * tri + spec.batch_tile * tile + spec.batch_pixel * px;
    }
    let queries = if host_queries { traversal.queries } else { 0 };
    spec.eye_triangle * tri
        + spec.eye_tile * tile
        + spec.eye_pixel * px
        + spec.eye_node * traversal.nodes_visited as f64
        + spec.query * queries as f64
}

/// The culled eye's modeled cost when its traversal ran split
/// (`eye.rs`): the two halves run side by side, so the frame waits for the
/// slower one, not for their sum. `halves` holds each half's traversal and
/// raster counters (the bundled backend: no host queries). Modeling the sum
/// overstated the culled eye about twofold against the unculled batch,
/// which runs on every thread too: on city_16384 `street` `auto` drew every
/// object (16–20 ms a frame against 6–9 for `chcpp`).
pub(crate) fn split_eye_cost(spec: &AutoSpec, halves: &[(TraversalStats, RasterStats); 2]) -> f64 {
    (halves.iter())
        .map(|(traversal, raster)| eye_cost(spec, true, raster, traversal, false))
        .fold(0.0, f64::max)
}

/// A culled light's light pass: its traversal's and its views' raster
/// counters, and the eye pixels whose receiver points it marks.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct LightPassWork {
    pub traversal: TraversalStats,
    pub raster: RasterStats,
    /// Its views ran on a host backend (queries counted, raster not).
    pub host: bool,
    pub eye_pixels: u64,
}

/// What a light's costs are modeled from.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct LightCosts {
    /// Triangles of the casters whose volumes the frame built.
    pub caster_triangles: u64,
    /// Triangles of every casting object.
    pub all_caster_triangles: u64,
    /// The volumes' triangles.
    pub volume_triangles: u64,
    /// The stencil's counters.
    pub stencil: StencilStats,
    /// Hierarchical stencil (fragments are `h_fragments`), else brute force
    /// (`pixels_processed`).
    pub hierarchical: bool,
    /// Culled: the light pass.
    pub pass: Option<LightPassWork>,
}

impl LightCosts {
    /// The volumes' and the stencil's modeled cost.
    fn volumes(&self, spec: &AutoSpec) -> f64 {
        let fragments = if self.hierarchical {
            spec.h_fragment * self.stencil.h_fragments as f64
        } else {
            spec.bf_fragment * self.stencil.pixels_processed as f64
                + spec.fill_tile * self.stencil.tiles_scanned as f64
        };
        spec.caster_triangle * self.caster_triangles as f64
            + spec.volume_triangle * self.volume_triangles as f64
            + spec.stencil_tile * self.stencil.tile_tests as f64
            + fragments
    }

    /// The modeled cost of the frame's mode, and for a culled frame the
    /// estimated cost of drawing every caster's volume: the volumes' cost
    /// per caster triangle of the potential casters (`caster_triangle` when
    /// there were none) times every caster's triangles.
    pub fn costs(&self, spec: &AutoSpec) -> (f64, Option<f64>) {
        let volumes = self.volumes(spec);
        let Some(p) = self.pass else {
            return (volumes, None);
        };
        let (t, r) = (&p.traversal, &p.raster);
        let queries = if p.host { t.queries } else { 0 };
        let pass = spec.light_triangle * r.triangles_in as f64
            + spec.light_tile * r.tiles_touched as f64
            + spec.light_pixel * r.pixels_tested as f64
            + spec.light_node * t.nodes_visited as f64
            + spec.query * queries as f64
            + spec.receiver_pixel * p.eye_pixels as f64;
        let per_triangle = if self.caster_triangles > 0 {
            volumes / self.caster_triangles as f64
        } else {
            spec.caster_triangle + spec.volume_triangle
        };
        (
            pass + volumes,
            Some(per_triangle * self.all_caster_triangles as f64),
        )
    }
}

/// `stencil: auto`'s `db`: brute force with the per-volume depth-bounds
/// test and scissor rectangles, from the options of its `h`.
pub(crate) fn db_options(h: ShadowOptions) -> ShadowOptions {
    ShadowOptions {
        backend: Backend::Brute,
        depth_bounds: true,
        scissor: true,
        ..h
    }
}

/// The stencil stage's modeled cost for one light: `h` from its tile tests
/// and boundary-tile fragments, `db` from its fragments processed, both
/// also per volume triangle and per eye pixel.
pub(crate) fn stencil_cost(
    costs: &StencilCosts,
    hierarchical: bool,
    stencil: &StencilStats,
    eye_pixels: u64,
) -> f64 {
    let (px, tri) = (eye_pixels as f64, stencil.triangles as f64);
    if hierarchical {
        costs.h_pixel * px
            + costs.h_triangle * tri
            + costs.h_tile * stencil.tile_tests as f64
            + costs.h_fragment * stencil.h_fragments as f64
    } else {
        costs.db_pixel * px
            + costs.db_triangle * tri
            + costs.db_fragment * stencil.pixels_processed as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs `frames` frames of a view whose culled frames cost `culled(run)`
    /// (run: consecutive culled frames, 1 = cold) and unculled frames
    /// `unculled`, with no estimate; returns the modes chosen.
    fn run(
        frames: u32,
        culled: impl Fn(u32) -> f64,
        unculled: f64,
        estimate: Option<f64>,
    ) -> Vec<bool> {
        let spec = AutoSpec::default();
        let mut v = AutoView::culling();
        let mut run = 0;
        (0..frames)
            .map(|_| {
                let c = v.choose(&spec);
                run = if c { run + 1 } else { 0 };
                let cost = if c { culled(run) } else { unculled };
                v.observe(&spec, c, cost, estimate.filter(|_| c));
                c
            })
            .collect()
    }

    /// `clamping: auto`'s first state sees a clamped frame at the cost of
    /// the cheaper clamped mode (`best`), so a probe of the dearer one does
    /// not turn clamping off.
    #[test]
    fn best_is_the_cheaper_known_mode() {
        let spec = AutoSpec::default();
        let mut v = AutoView::stencil();
        assert_eq!(v.best(), None);
        v.observe(&spec, true, 29.0, None);
        assert_eq!(v.best(), Some(29.0));
        v.observe(&spec, false, 31.0, None);
        assert_eq!(v.best(), Some(29.0));
        v.observe(&spec, true, 33.0, None);
        assert_eq!(v.best(), Some(31.0));
    }

    #[test]
    fn a_view_starts_culling_cold_then_warm_then_measures_the_other_mode() {
        let modes = run(4, |_| 1.0, 10.0, None);
        assert_eq!(modes, [true, true, false, true]);
    }

    #[test]
    fn the_cheaper_mode_wins_and_the_other_is_probed_less_and_less_often() {
        // Culling costs 3 warm (9 cold), drawing everything 2.
        let modes = run(200, |r| if r == 1 { 9.0 } else { 3.0 }, 2.0, None);
        let culled: Vec<usize> = (0..modes.len()).filter(|&i| modes[i]).collect();
        // Frames 0, 1 (start), then probes of two frames, each starting
        // once the culled cost is 8, 16, 32, 64, 64 frames old.
        assert_eq!(&culled[..2], &[0, 1]);
        let starts: Vec<usize> = culled
            .iter()
            .copied()
            .filter(|&i| i > 1 && !modes[i - 1])
            .collect();
        assert_eq!(starts[..5], [9, 26, 59, 124, 189], "{starts:?}");
        // Culling ran on few frames.
        assert!(culled.len() < 20, "{}", culled.len());
    }

    #[test]
    fn a_light_estimate_keeps_culling_without_probing_the_unculled_mode() {
        // Culled 1, estimated unculled 50: never draws everything.
        let modes = run(100, |_| 1.0, 1e9, Some(50.0));
        assert!(modes.iter().all(|&c| c));
        // An estimate within the margin (2) is measured instead: the third
        // frame probes the unculled mode, which costs 1.5 and wins.
        let modes = run(12, |_| 1.0, 1.5, Some(1.5));
        assert_eq!(modes[..4], [true, true, false, true]);
        let modes = run(12, |_| 1.0, 0.5, Some(1.5));
        assert_eq!(modes[..4], [true, true, false, false]);
    }

    #[test]
    fn a_reversing_probe_switches_and_restarts_the_period() {
        let spec = AutoSpec::default();
        let mut v = AutoView::culling();
        // Culled warm cost 5, unculled 10: culling preferred.
        assert!(v.choose(&spec));
        v.observe(&spec, true, 5.0, None);
        assert!(v.choose(&spec));
        v.observe(&spec, true, 5.0, None);
        assert!(!v.choose(&spec));
        v.observe(&spec, false, 10.0, None);
        // The probe confirmed culling: the period doubles.
        assert_eq!(v.period, 16);
        // Culling gets expensive: its warm frame switches the view.
        let mut culled = 0;
        while v.choose(&spec) {
            v.observe(&spec, true, 50.0, None);
            culled += 1;
        }
        assert_eq!(culled, 2);
        v.observe(&spec, false, 10.0, None);
        // Unculled until the culled cost is 16 frames old, then a
        // two-frame probe finds culling cheap again.
        let mut unculled = 1;
        while !v.choose(&spec) {
            v.observe(&spec, false, 10.0, None);
            unculled += 1;
        }
        assert_eq!(unculled, 15);
        v.observe(&spec, true, 5.0, None);
        assert!(v.choose(&spec));
        v.observe(&spec, true, 5.0, None);
        assert_eq!(v.period, 8);
        assert!(v.choose(&spec));
    }

    #[test]
    fn the_stencil_cost_reads_each_backends_own_counters() {
        let c = StencilCosts::default();
        let s = StencilStats {
            triangles: 10,
            tile_tests: 20,
            h_fragments: 30,
            pixels_processed: 40,
            ..Default::default()
        };
        let h = c.h_pixel * 100.0 + c.h_triangle * 10.0 + c.h_tile * 20.0 + c.h_fragment * 30.0;
        assert_eq!(stencil_cost(&c, true, &s, 100), h);
        let db = c.db_pixel * 100.0 + c.db_triangle * 10.0 + c.db_fragment * 40.0;
        assert_eq!(stencil_cost(&c, false, &s, 100), db);
        // `db` is brute force with depth bounds and scissors, the rest kept.
        let h = ShadowOptions {
            backend: Backend::Hierarchical {
                tile: raster::TileSize::T8,
                full_shadow: true,
            },
            two_sided: true,
            ..Default::default()
        };
        let db = db_options(h);
        assert_eq!(db.backend, Backend::Brute);
        assert!(db.depth_bounds && db.scissor && db.two_sided);
    }

    #[test]
    fn a_stencil_view_measures_its_first_mode_at_once() {
        let spec = AutoSpec::default();
        let mut v = AutoView::stencil();
        assert!(v.choose(&spec));
        v.observe(&spec, true, 5.0, None);
        // No warm frame: `db` is probed at the second frame, and loses.
        assert!(!v.choose(&spec));
        v.observe(&spec, false, 9.0, None);
        assert!(v.choose(&spec));
        v.reset();
        assert!(v.choose(&spec));
        v.observe(&spec, true, 5.0, None);
        assert!(!v.choose(&spec), "a reset keeps the warm-up count");
    }

    #[test]
    fn light_costs_estimate_every_caster_from_the_potential_ones() {
        let spec = AutoSpec::default();
        let mut c = LightCosts {
            caster_triangles: 100,
            all_caster_triangles: 1000,
            hierarchical: true,
            pass: Some(LightPassWork::default()),
            ..Default::default()
        };
        c.stencil.h_fragments = 300;
        c.stencil.pixels_processed = 7;
        let (culled, unculled) = c.costs(&spec);
        let volumes = spec.caster_triangle * 100.0 + spec.h_fragment * 300.0;
        assert_eq!(culled, volumes);
        assert_eq!(unculled, Some(volumes * 10.0));
        let none = LightCosts { pass: None, ..c };
        assert_eq!(none.costs(&spec), (volumes, None));
        // No potential caster: every caster at the per-triangle cost.
        let empty = LightCosts {
            caster_triangles: 0,
            stencil: StencilStats::default(),
            ..c
        };
        let per_triangle = spec.caster_triangle + spec.volume_triangle;
        assert_eq!(empty.costs(&spec).1, Some(per_triangle * 1000.0));
    }

    /// The split eye costs its slower half: less than the whole traversal's
    /// counters modeled as one, as much as either half alone.
    #[test]
    fn the_split_eye_costs_its_slower_half() {
        let spec = AutoSpec::default();
        let half = |nodes: u64, triangles: u64, pixels: u64| {
            let t = TraversalStats {
                nodes_visited: nodes,
                queries: 3,
                ..Default::default()
            };
            let r = RasterStats {
                triangles_in: triangles,
                tiles_touched: triangles / 2,
                pixels_tested: pixels,
                ..Default::default()
            };
            (t, r)
        };
        let halves = [half(40, 900, 30_000), half(60, 1200, 20_000)];
        let each = halves.map(|(t, r)| eye_cost(&spec, true, &r, &t, false));
        // Both halves' counters summed, as the joined traversal reports them.
        let (t, r) = half(100, 2100, 50_000);
        let t = TraversalStats { queries: 6, ..t };
        let whole = eye_cost(&spec, true, &r, &t, false);
        let split = split_eye_cost(&spec, &halves);
        assert_eq!(split, each[0].max(each[1]));
        assert!(each[0] != each[1] && split < whole, "{each:?} {whole}");
    }
}
