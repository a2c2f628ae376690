//! One light's share of a frame: its light pass (PSC) when it culls, its
//! shadow volumes, the stencil and mask, and the modeled costs its `auto`
//! choices learn from.
//!
//! The lights are independent: each owns its light views, silhouette
//! cache, volume buffer and stencil targets. So [`Pipeline`](super::Pipeline)
//! runs every light's share side by side, each a chain from its light pass
//! to its mask: one light's stencil bands fill the cores while another's
//! light pass (one traversal) still runs, where a stage of light passes
//! followed by a stage of stencils left a core idle at each stage's end.
//! The results do not depend on the order or the threads.

use super::auto;
use super::eye::EyePass;
use super::fill_count;
use super::light::{self, Reading};
use super::light_state::LightState;
use super::options::PipelineOptions;
use super::options::{ClampReceiversSpec, ClampingSpec, StencilBackend};
use super::shadow_options::ShadowInput;
use super::shadow_options::{Backend, ShadowOptions};
use super::stencil;
use super::stencil::ShadowFrame;
use super::volume;
use crate::stats::ShadowStats;
use crate::Result;
use scene::{Camera, ObjectId, Scene};
use std::time::Instant;
use visibility::TraversalStats;

/// The eye pass's counters every light's stats repeat.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct EyeCounts {
    /// Wall time of the eye pass and its visible points (ms).
    pub ms: f64,
    /// Potentially shadowed receivers.
    pub psr: u64,
    /// The eye traversal's queries and waits.
    pub queries: u64,
    pub waits: u64,
}

/// What every light's share of one frame reads.
pub(super) struct FrameShared<'a> {
    pub scene: &'a Scene,
    pub camera: &'a Camera,
    pub options: &'a PipelineOptions,
    /// The frame's size in pixels.
    pub viewport: (u32, u32),
    /// The eye pass; `None` when nobody reads it (no culling light, no CPU
    /// stencil, no fill count).
    pub eye: Option<&'a EyePass>,
    pub eye_counts: EyeCounts,
    /// The light passes' input, when some light culls this frame.
    pub pass: Option<light::LightPassInput<'a>>,
    /// Every live casting object: the casters of a light that does not cull.
    pub all_casters: &'a [ObjectId],
    /// Clamping to the PSR's receivers: per object slot, whether it receives.
    pub receives: Option<&'a [bool]>,
    /// The receiver points hold the stencil's stored-depth points too.
    pub stored_points: bool,
    /// `culling: auto` may cull this frame (the lights learn their costs).
    pub auto_culling: bool,
    /// Triangles of every caster (for `culling: auto`'s unculled cost).
    pub all_caster_triangles: u64,
    /// The host brings its own occlusion backends.
    pub host: bool,
}

/// What a light's pass reads for clamping, by its clamping this frame.
///
/// Fragment receivers are read whenever the model is chosen (`count_fill`
/// counts them on unclamped frames), but under `clamping: auto` only by a
/// light that clamps continuously this frame. Discrete clamping reads
/// occupied slices; a sample's slice is its pixel's, whatever its depth,
/// so it needs no stored points.
pub(super) fn reading(clamping: ClampingSpec, o: &PipelineOptions) -> Reading {
    let fragment = o.clamping_receivers == ClampReceiversSpec::Fragment;
    match clamping {
        ClampingSpec::Discrete => Reading::Slices,
        ClampingSpec::Continuous if fragment => Reading::Axes,
        ClampingSpec::None if fragment && o.clamping != ClampingSpec::Auto => Reading::Axes,
        _ => Reading::None,
    }
}

/// Runs light `s`'s share of the frame: its light pass when it culls, then
/// its volumes, stencil and mask, its stats and its `auto` observations.
/// Returns the time spent on `count_fill`'s accounting (ms), which is a
/// measurement, not part of the frame.
///
/// # Errors
/// Light-pass, volume and rasterizer errors.
pub(super) fn run(s: &mut LightState, f: &FrameShared<'_>) -> Result<f64> {
    let FrameShared {
        scene,
        camera,
        options: o,
        eye,
        eye_counts,
        ..
    } = *f;
    let (w, h) = f.viewport;
    // Only the stencil and the fill count read the eye pass here.
    let eye = || {
        eye.ok_or_else(|| crate::Error::Options {
            field: "stencil".into(),
            message: "a frame without an eye pass has no stencil or fill count".into(),
        })
    };
    let auto_culling = f.auto_culling;
    let reading = reading(s.clamping, o);
    // This frame's computation mask is made by its stencil stage (or for
    // `count_fill`), not kept from the last frame.
    s.scratch.shadowable.forget();
    if let (true, Some(input)) = (s.culled, &f.pass) {
        light::light_pass(s.light, (s.id, s.skip_bit), &mut s.culling, reading, input)?;
    }
    let casters: &[ObjectId] = if s.culled {
        s.casters.clear();
        s.casters.reserve(scene.objects().len());
        let casting = (s.culling.result.psc.iter()).filter(|id| scene.object(**id).flags.casts);
        s.casters.extend(casting);
        &s.casters
    } else {
        f.all_casters
    };
    let input = ShadowInput {
        scene,
        camera,
        light: &s.light,
    };
    // `stencil: auto`: this light's stencil this frame.
    let stencil_auto = o.stencil == StencilBackend::Auto;
    let stencil_view = usize::from(s.culled);
    let hierarchical = !stencil_auto || s.stencil_auto[stencil_view].choose(&o.auto);
    let shadow_options = o.shadow_options();
    let light_options = ShadowOptions {
        clamping: o.clamping_options(s.clamping),
        ..if hierarchical {
            shadow_options
        } else {
            auto::db_options(shadow_options)
        }
    };
    // Fragment receivers and slices come from this frame's light pass; a
    // light not culled this frame clamps to every receiving object
    // (discrete: not at all).
    let fragments =
        (s.culled && reading != Reading::None).then(|| volume::Readings::of(&s.culling.result));
    let mut volumes = volume::build_for(
        input,
        casters,
        &light_options,
        (w, h),
        f.receives,
        fragments,
        &mut s.scratch.volume,
    )?;
    if fragments.is_some() && light_options.clamping.is_some() {
        volumes.clamp_ms += s.culling.result.fragment_ms;
    }
    s.volume_stats = volumes;
    // Public ids (slot and generation) in the outputs.
    s.psc.clear();
    s.psc.reserve(scene.objects().len());
    s.psc
        .extend(casters.iter().map(|id| scene.id_of(id.slot())));
    for r in &mut s.scratch.volume.buffer.ranges {
        r.object = scene.id_of(r.object as u32).to_bits();
    }
    // The hybrid's shadow maps: this frame's point-sampled light views,
    // unless no light pass ran or a host's backends drew them (then it
    // renders its own, as for conservative light views, whose depth is no
    // shadow map: see `keep_depth`).
    let hybrid = o.stencil == StencilBackend::Hybrid
        && o.light_pass_options().keep_depth
        && s.culled
        && !f.host;
    let light_views: Vec<_> = match hybrid {
        true => (s.culling.pass.view_depths())
            .filter_map(|(v, t)| Some((v, t?)))
            .collect(),
        false => Vec::new(),
    };
    let shadow = match o.stencil {
        StencilBackend::None => None,
        _ => Some(stencil::stencil_volumes(
            input,
            eye()?,
            &light_options,
            &mut s.scratch,
            volumes,
            s.shadow.take(),
            hybrid.then_some(&light_views[..]),
        )),
    };
    drop(light_views);
    s.shadow = shadow.transpose()?;
    let (light, light_ms) = if s.culled {
        (s.culling.result.stats, s.culling.ms)
    } else {
        (TraversalStats::default(), 0.0)
    };
    let mut fill_ms = 0.0;
    let fill = if o.count_fill {
        let t = Instant::now();
        // Both variants are counted on the pixels the brute-force stencil
        // draws: its computation mask, made here when the frame's stencil
        // made none.
        if !s.scratch.shadowable.fresh() {
            stencil::computation_mask(input, eye()?, light_options.two_sided, &mut s.scratch)?;
        }
        let clamped = fill_count::ClampedVariant {
            options: o.clamp_options(),
            receives: f.receives,
            fragments,
        };
        let drawn = fill_count::Drawn {
            buffer: &s.scratch.volume.buffer,
            stencil: s.shadow.as_ref().map(|f| &f.stencil),
        };
        let on = s.scratch.shadowable.target(&eye()?.target);
        let counts = fill_count::count_fill(
            input,
            on,
            casters,
            &light_options,
            clamped,
            drawn,
            &mut s.scratch.fill,
        )?;
        fill_ms = t.elapsed().as_secs_f64() * 1e3;
        counts
    } else {
        fill_count::FillCounts::default()
    };
    let mut stats = ShadowStats {
        eye_ms: eye_counts.ms,
        volume_triangles: s.scratch.volume.buffer.triangle_count() as u64,
        psr: eye_counts.psr,
        psc: casters.len() as u64,
        queries: eye_counts.queries + light.queries,
        waits: eye_counts.waits + light.waits,
        light_ms,
        volumes,
        light,
        ..Default::default()
    };
    if let Some(f) = &s.shadow {
        add_stencil(&mut stats, f);
        // A brute-force stencil's own count is the fill of what it drew.
        if light_options.backend == Backend::Brute {
            match light_options.clamping {
                Some(_) => stats.bf_fill_clamped = f.stencil.pixels_processed,
                None => stats.bf_fill_unclamped = f.stencil.pixels_processed,
            }
        }
    }
    if o.count_fill {
        stats.bf_fill_unclamped = fill.unclamped;
        stats.bf_fill_clamped = fill.clamped;
    }
    s.stats = stats;
    if let (true, Some(f)) = (stencil_auto, &s.shadow) {
        let pixels = u64::from(w) * u64::from(h);
        let cost = auto::stencil_cost(&o.auto.stencil, hierarchical, &f.stencil, pixels);
        s.stencil_auto[stencil_view].observe(&o.auto, hierarchical, cost, None);
        tracing::debug!(
            target: "shadowcull::auto",
            view = "stencil",
            light = s.id.to_bits(),
            hierarchical,
            cost,
            stencil_ms = f.stencil_ms,
            triangles = f.stencil.triangles,
            tile_tests = f.stencil.tile_tests,
            h_fragments = f.stencil.h_fragments,
            pixels_processed = f.stencil.pixels_processed,
        );
    }
    // The light's modeled costs, for `culling: auto` and `clamping: auto`.
    let costs = (o.clamping == ClampingSpec::Auto || auto_culling).then(|| auto::LightCosts {
        caster_triangles: triangles_of(scene, casters),
        all_caster_triangles: f.all_caster_triangles,
        volume_triangles: s.stats.volume_triangles,
        stencil: s.shadow.as_ref().map(|f| f.stencil).unwrap_or_default(),
        hierarchical: matches!(light_options.backend, Backend::Hierarchical { .. }),
        pass: s.culled.then_some(auto::LightPassWork {
            traversal: light,
            raster: s.culling.result.raster,
            host: f.host,
            eye_pixels: u64::from(w) * u64::from(h),
        }),
    });
    if let (ClampingSpec::Auto, Some(mut costs)) = (o.clamping, costs) {
        observe_clamping(s, o, &mut costs, reading, f.stored_points);
    }
    if let (true, Some(costs)) = (auto_culling, costs) {
        let (cost, unculled) = costs.costs(&o.auto);
        s.auto.observe(&o.auto, s.culled, cost, unculled);
        let st = &s.stats;
        tracing::debug!(
            target: "shadowcull::auto",
            view = "light",
            light = s.id.to_bits(),
            culled = s.culled,
            cost,
            unculled = unculled.unwrap_or(f64::NAN),
            light_ms,
            volumes_ms = st.volumes.silhouette_ms + st.volumes.volume_ms,
            stencil_ms = st.stencil_ms,
            nodes = light.nodes_visited,
            queries = light.queries,
            raster_triangles = s.culling.result.raster.triangles_in,
            raster_tiles = s.culling.result.raster.tiles_touched,
            raster_pixels = s.culling.result.raster.pixels_tested,
            objects = light.objects_rendered,
            caster_triangles = costs.caster_triangles,
            h_fragments = costs.stencil.h_fragments,
            pixels_processed = costs.stencil.pixels_processed,
        );
    }
    Ok(fill_ms)
}

/// `clamping: auto`'s observation of the frame's modeled cost: light pass
/// (its receiver points marked twice with the stored depths), volumes,
/// stencil, and the marked pixels read for clamping.
fn observe_clamping(
    s: &mut LightState,
    o: &PipelineOptions,
    costs: &mut auto::LightCosts,
    reading: Reading,
    stored_points: bool,
) {
    if let Some(p) = &mut costs.pass {
        p.eye_pixels *= 1 + u64::from(stored_points && reading == Reading::Axes);
    }
    let read = match (s.culled, reading) {
        (true, Reading::Axes | Reading::Slices) => {
            s.culling.result.fragments.pixels + s.culling.result.slices.pixels
        }
        _ => 0,
    };
    // Segment triangles at their own price.
    let segments = s.stats.volumes.segment_triangles as f64;
    let cost = costs.costs(&o.auto).0
        + (o.auto.segment_triangle - o.auto.volume_triangle) * segments
        + o.auto.receiver_pixel * read as f64;
    // Clamping costs what its cheapest known mode does: a probe of the
    // dearer one does not count against clamping.
    let clamped = s.clamping != ClampingSpec::None;
    let mut clamp_cost = cost;
    if clamped {
        let discrete = s.clamping == ClampingSpec::Discrete;
        s.clamp_auto[1].observe(&o.auto, discrete, cost, None);
        clamp_cost = s.clamp_auto[1].best().unwrap_or(cost);
    }
    s.clamp_auto[0].observe(&o.auto, clamped, clamp_cost, None);
    tracing::debug!(
        target: "shadowcull::auto",
        view = "clamping",
        light = s.id.to_bits(),
        clamping = ?s.clamping,
        cost,
        read,
        segments = s.stats.volumes.segments,
        pixels_processed = costs.stencil.pixels_processed,
    );
}

/// The stencil stage's share of a light's stats.
fn add_stencil(s: &mut ShadowStats, f: &ShadowFrame) {
    s.stencil_ms = f.stencil_ms;
    s.volume_triangles = f.volume_triangles;
    s.shadowed_pixels = f.mask.counts().shadow;
    s.bandwidth_bytes = f.stencil.bandwidth_bytes();
    s.silhouette_pixels = f.silhouette_pixels;
    s.map_ms = f.map_ms;
    s.stencil = f.stencil;
}

/// The triangles of objects `ids`.
pub(super) fn triangles_of(scene: &Scene, ids: &[ObjectId]) -> u64 {
    let meshes = scene.graph().meshes();
    let objects = scene.objects();
    ids.iter()
        .map(|id| meshes[objects[id.index()].mesh.index()].triangles().len() as u64)
        .sum()
}
