//! Runtime CPU dispatch: the whole per-mesh pipeline (vertex stage, screen
//! bounds and hierarchical-z skip, setup, clipping, snapping, traversal) is
//! compiled three times — portable, AVX2 and AVX-512 (`#[target_feature]`
//! multiversioning: the compiler vectorizes the per-row evaluation 4- or 8-wide
//! in f64, the per-vertex stage across vertices, and inlines `round`) — and
//! chosen once at runtime. Every build performs the same IEEE operations in the
//! same order (no fused multiply-add is enabled), so their results are
//! bit-identical; a test checks it. The level is the target's
//! ([`crate::InstructionSet`]): the detected one unless the host caps it.
//!
//! AVX-512 pays on its own (measured on city_16384 `bird` 1920×1080, one thread:
//! occluders 57 → 46 ms, identical output): an 8-pixel tile row is one register
//! of f64 lanes instead of two.

use crate::coverage::{Coverage, Rect};
use crate::depth_target::CullMode;
use crate::edge::Tri;
use crate::hiz::{hidden, project, project_lanes, project_wide, Projected, RowSkip};
use crate::isa::InstructionSet;
use crate::item::{setup_item, DrawItem, TriSink, Vertices};
use crate::layout::TileRows;
use crate::query_options::{meets_apex_region, APEX_EPS, VISIBLE};
use crate::setup::{widen, MeshVertices, VertexCache, Viewport, CACHE_VERTICES};
use crate::stats::RasterStats;
use crate::tile_walk::{draw_tri, probe_passes, query_tri, QueryView};
use crate::Result;
use glam::{Mat4, Vec3};

/// The screen bounds of `item`; a small mesh's vertex stage is left in `cache`
/// (filled in place: moving it costs a copy per mesh).
#[inline(always)]
fn screen_bounds(vp: &Viewport, item: &DrawItem, cache: &mut VertexCache) -> Projected {
    if item.positions.len() <= CACHE_VERTICES {
        cache.transform_into(&item.clip_from_local, item.positions);
        let (lanes, n) = cache.lanes();
        project_lanes(lanes, n, vp.width, vp.height)
    } else {
        project(&item.clip_from_local, item.positions, vp.width, vp.height)
    }
}

/// Defines `name(isa, args)`, running the body compiled for `isa` (capped at
/// [`InstructionSet::detected`], so any level is safe to ask for); the body is
/// compiled once per level. (The `multiversion` crate was evaluated instead:
/// its dispatch picks the best detected level by itself and cannot run a level
/// the caller chooses, which the cap and the bit-for-bit test need.)
///
/// The functions take at most six arguments besides `isa` (clippy's limit is
/// seven): what belongs together travels as one struct ([`BandTarget`],
/// a query's viewport comes with its [`QueryView`]).
macro_rules! multiversioned {
    ($(
        $(#[$m:meta])*
        fn $name:ident ($($a:ident : $t:ty),* $(,)?) -> $r:ty $body:block
    )*) => {$(
        $(#[$m])*
        pub(crate) fn $name(isa: InstructionSet, $($a: $t),*) -> $r {
            #[inline(always)]
            fn imp($($a: $t),*) -> $r $body
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                fn avx2($($a: $t),*) -> $r {
                    imp($($a),*)
                }
                #[target_feature(enable = "avx512f,avx512vl,avx512bw,avx512dq,avx2")]
                fn avx512($($a: $t),*) -> $r {
                    imp($($a),*)
                }
                match isa.capped() {
                    // SAFETY: `capped` is at most the detected level: this CPU has
                    // AVX-512 F/VL/BW/DQ and AVX2.
                    InstructionSet::Avx512 => return unsafe { avx512($($a),*) },
                    // SAFETY: as above, this CPU has AVX2.
                    InstructionSet::Avx2 => return unsafe { avx2($($a),*) },
                    InstructionSet::Portable => {}
                }
            }
            #[cfg(not(target_arch = "x86_64"))]
            let _ = isa;
            imp($($a),*)
        }
    )*};
}

/// Where [`draw_mesh`] draws: a band of tile rows with the band's own
/// hierarchical-z row skip (scratch, recomputed per mesh) and traversal
/// counters. A parallel draw has one per band.
pub(crate) struct BandTarget<'a, 'b> {
    /// The band's tile rows.
    pub rows: &'a mut TileRows<'b>,
    /// The band's rows a mesh's bounds show hidden.
    pub skip: &'a mut RowSkip,
    /// Traversal counters (tiles and pixels) of the band.
    pub st: &'a mut RasterStats,
}

thread_local! {
    /// The vertex stage of a mesh larger than a box (scratch, recomputed per
    /// mesh), one per thread: a draw holds it only inside [`draw_mesh`],
    /// which calls into no thread pool, so it is never held twice. Kept
    /// per target and band, every light view, quadrant and band kept room
    /// for the largest mesh it ever drew (42 bytes a vertex: 190 MB for a
    /// 75k-vertex scan drawn into three lights' views); per thread, the
    /// pool's threads hold it once each.
    static MESH_VERTICES: std::cell::RefCell<MeshVertices> =
        std::cell::RefCell::new(MeshVertices::with_room());
}

multiversioned! {
    /// Draws one mesh into the rows of `target`: vertex stage, screen bounds
    /// (`projected`, or computed here), hierarchical-z skip of its hidden tile rows
    /// (false: skipped whole, nothing counted), then setup and traversal. Setup
    /// counters (triangles in, clipped, culled) go to `st_setup`, apart from the
    /// band's traversal counters: a parallel draw reports each item's setup once.
    fn draw_mesh(
        vp: &Viewport,
        target: BandTarget,
        item: &DrawItem,
        cov: Coverage,
        projected: Option<&Projected>,
        st_setup: &mut RasterStats,
    ) -> Result<bool> {
        let BandTarget {
            rows: band,
            skip,
            st,
        } = target;
        // The cache is filled in place (moving it costs a copy per mesh).
        let small = item.positions.len() <= CACHE_VERTICES;
        let mut cache = VertexCache::empty();
        let transformed = projected.is_none() && small;
        let p = match projected {
            Some(p) => *p,
            None => screen_bounds(vp, item, &mut cache),
        };
        let l = band.layout;
        match p {
            Projected::Offscreen => return Ok(false),
            Projected::Bounds(b) => {
                if (b.y1 >> l.shift) < band.ty0
                    || (b.y0 >> l.shift) >= band.ty1
                    || skip.compute(&l, band.tiles, band.ty0, band.ty1, &b)
                {
                    return Ok(false);
                }
            }
            Projected::Unknown => skip.reset(),
        }
        let mut sink = Draw {
            band,
            cov,
            skip,
            st,
        };
        let mut set_up = |vertices: Vertices<'_>| {
            setup_item(vp, item, cov, item.cull, vertices, st_setup, &mut sink)
        };
        if small {
            if !transformed {
                cache.transform_into(&item.clip_from_local, item.positions);
            }
            cache.snap(vp);
            set_up(Vertices::Small(&cache))?;
        } else if MeshVertices::pays(item.positions.len(), item.triangles.len()) {
            MESH_VERTICES.with(|v| match v.try_borrow_mut() {
                Ok(mut verts) => {
                    verts.fill(&item.clip_from_local, item.positions, vp);
                    set_up(Vertices::Mesh(&verts))
                }
                // (Held by a draw further up this thread's stack, which
                // none is: the same values per triangle.)
                Err(_) => set_up(Vertices::PerTriangle),
            })?;
        } else {
            set_up(Vertices::PerTriangle)?;
        }
        Ok(true)
    }

    /// The screen bounds of each of `items` into `out` (same length), as
    /// [`draw_mesh`] computes them.
    #[cfg(feature = "parallel")]
    fn project_items(
        vp: &Viewport,
        items: &[DrawItem],
        out: &mut [Projected],
    ) -> () {
        let mut cache = VertexCache::empty();
        for (it, o) in items.iter().zip(out) {
            *o = screen_bounds(vp, it, &mut cache);
        }
    }

    /// Counts the samples of `item` passing the query test, up to `limit`
    /// ([`QueryMode::limit`](crate::QueryMode::limit); 1: any samples). Setup
    /// counters go to `st_setup`, traversal counters to `st`.
    fn query_mesh(
        view: &QueryView,
        item: &DrawItem,
        cov: Coverage,
        limit: u64,
        st_setup: &mut RasterStats,
        st: &mut RasterStats,
    ) -> Result<u64> {
        let vp = view.vp;
        let small = item.positions.len() <= CACHE_VERTICES;
        let mut cache = VertexCache::empty();
        if small {
            cache.transform_into(&item.clip_from_local, item.positions);
            cache.snap(vp);
        }
        let mut sink = Query::new(view, cov, limit, st);
        setup_item(
            vp,
            item,
            cov,
            CullMode::None,
            if small { Vertices::Small(&cache) } else { Vertices::PerTriangle },
            st_setup,
            &mut sink,
        )?;
        Ok(sink.finish())
    }

    /// The query of the box `(min, max)`: [`VISIBLE`] when it meets the apex
    /// region, 0 when hierarchical z hides its screen rectangle, else the count of
    /// its 12 triangles up to `limit` (at most `VISIBLE − 1`). Counts the
    /// query in `st`.
    fn query_box(
        view: &QueryView,
        clip_from_local: &Mat4,
        bounds: (Vec3, Vec3),
        cov: Coverage,
        limit: u64,
        st: &mut RasterStats,
    ) -> u32 {
        let vp = view.vp;
        let (min, max) = bounds;
        use crate::item::{AABB_TRIANGLES, aabb_corners};
        st.queries += 1;
        let mut cache = VertexCache::empty();
        cache.transform_box(clip_from_local, min, max);
        let (lanes, _) = cache.lanes();
        let wide = widen(lanes);
        let [x, y, z, w] = &wide;
        // Most boxes lie wholly outside one plane of the apex region (beyond the
        // near plane, or behind the eye and beside the view), with twice the
        // widening of the exact test to spare (the f32 corners differ from its f64
        // ones by ~2⁻²⁴ of the scale): [`meets_apex_region`] would reject them at
        // its first test. (Plain selects and `&`, so the eight corners vectorize.)
        let mut scale = 0f64;
        let [cx, cy, cz, cw] = lanes;
        for k in 0..8 {
            let s = f64::from(cx[k].abs() + cy[k].abs() + cz[k].abs() + cw[k].abs());
            scale = if s > scale { s } else { scale };
        }
        let delta = 2.0 * APEX_EPS * scale;
        // All corners strictly outside: near plane z ≥ w, then w ± x ≥ 0, w ± y ≥ 0.
        let mut out = [true; 5];
        for k in 0..8 {
            out[0] &= z[k] - w[k] + delta < 0.0;
            out[1] &= w[k] - x[k] + delta < 0.0;
            out[2] &= w[k] + x[k] + delta < 0.0;
            out[3] &= w[k] - y[k] + delta < 0.0;
            out[4] &= w[k] + y[k] + delta < 0.0;
        }
        let outside = out[0] | out[1] | out[2] | out[3] | out[4];
        if !outside && meets_apex_region(clip_from_local, min, max) {
            st.queries_apex += 1;
            return VISIBLE;
        }
        let n = AABB_TRIANGLES.len() as u64;
        let skip = match project_wide(&wide, 8, vp.width, vp.height) {
            Projected::Unknown => false,
            Projected::Offscreen => true,
            Projected::Bounds(b) => hidden(&view.layout, view.tiles, 0, view.layout.tiles_y, &b),
        };
        if skip {
            st.triangles_in += n;
            st.triangles_culled += n;
            st.meshes_rejected_hiz += 1;
            return 0;
        }
        cache.snap(vp);
        let corners = aabb_corners(min, max);
        let item = DrawItem {
            clip_from_local: *clip_from_local,
            positions: &corners,
            triangles: &AABB_TRIANGLES,
            object: 0,
            cull: crate::CullMode::None,
        };
        let mut st2 = RasterStats::default();
        let mut sink = Query::new(view, cov, limit, &mut st2);
        // Box indices are in range.
        let _ = setup_item(vp, &item, cov, CullMode::None, Vertices::Small(&cache), st, &mut sink);
        let count = sink.finish();
        st.add(&st2);
        count.min(u64::from(VISIBLE - 1)) as u32
    }
}

/// [`setup_item`]'s consumer for draws.
struct Draw<'a, 'b> {
    band: &'a mut TileRows<'b>,
    cov: Coverage,
    skip: &'a RowSkip,
    st: &'a mut RasterStats,
}

impl TriSink for Draw<'_, '_> {
    #[inline(always)]
    fn tri(&mut self, t: &Tri, pb: Rect, id: u64) -> bool {
        draw_tri(self.band, t, pb, self.cov, id, self.skip, self.st);
        false
    }
}

/// [`setup_item`]'s consumer for queries.
struct Query<'a, 'b> {
    view: &'a QueryView<'b>,
    cov: Coverage,
    /// The count the query stops at (1: any samples).
    limit: u64,
    st: &'a mut RasterStats,
    count: u64,
    /// Any-samples queries first probe every triangle's centroid pixel
    /// ([`probe_passes`]) and traverse the triangles kept here only when no probe
    /// passed: most visible boxes then need no tile loop at all.
    pending: [Option<(Tri, Rect)>; PENDING],
    deferred: usize,
}

/// Triangles an any-samples query defers (a box's twelve; more are traversed at
/// once).
const PENDING: usize = 12;

impl<'a, 'b> Query<'a, 'b> {
    #[inline(always)]
    fn new(view: &'a QueryView<'b>, cov: Coverage, limit: u64, st: &'a mut RasterStats) -> Self {
        Query {
            view,
            cov,
            limit: limit.max(1),
            st,
            count: 0,
            pending: [None; PENDING],
            deferred: 0,
        }
    }

    /// Traverses the deferred triangles (until one passes); the count, up
    /// to the limit.
    #[inline(always)]
    fn finish(mut self) -> u64 {
        for (t, pb) in self.pending[..self.deferred].iter().flatten() {
            if self.count > 0 {
                break;
            }
            self.count += query_tri(self.view, t, *pb, self.cov, 1, self.st);
        }
        self.count.min(self.limit)
    }
}

impl TriSink for Query<'_, '_> {
    #[inline(always)]
    fn tri(&mut self, t: &Tri, pb: Rect, _id: u64) -> bool {
        if self.limit == 1 && self.cov == Coverage::Standard {
            if probe_passes(self.view, t, pb, self.st) {
                self.count = 1;
                return true;
            }
            if let Some(slot) = self.pending.get_mut(self.deferred) {
                *slot = Some((*t, pb));
                self.deferred += 1;
                return false;
            }
        }
        // `setup_item` stops at the first `true`: the count is below the limit.
        let left = self.limit - self.count;
        self.count += query_tri(self.view, t, pb, self.cov, left, self.st);
        self.count >= self.limit
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::depth_target::tests::signed_unit;
    use crate::depth_target::DepthTarget;
    use crate::{DepthPick, TileSize};
    use glam::{Mat4, Vec4};

    fn band(t: &mut DepthTarget) -> TileRows<'_> {
        TileRows {
            layout: t.layout,
            ty0: 0,
            ty1: t.layout.tiles_y,
            depth: &mut t.depth,
            ids: t.ids.as_deref_mut(),
            tiles: &mut t.tiles,
        }
    }

    /// Every build this CPU runs (AVX-512, AVX2) agrees bit for bit with the
    /// portable build: depth, ids, counters, mesh and box query counts.
    #[test]
    fn simd_builds_equal_scalar_build() {
        let levels: Vec<InstructionSet> = [InstructionSet::Avx2, InstructionSet::Avx512]
            .into_iter()
            .filter(|&l| l <= InstructionSet::detected())
            .collect();
        if levels.is_empty() {
            eprintln!("note: no SIMD build runs on this CPU; nothing to compare");
        }
        for level in levels {
            for (ids, tile, cull) in [
                (true, TileSize::T8, CullMode::None),
                (false, TileSize::T8, CullMode::None),
                (false, TileSize::T8, CullMode::Back),
                (false, TileSize::T4, CullMode::None),
                (false, TileSize::T16, CullMode::Back),
                (true, TileSize::T8, CullMode::Front),
            ] {
                compare(level, ids, tile, cull);
            }
        }
    }

    /// A welded mesh larger than a box, drawn with its vertex stage done once
    /// per vertex ([`MeshVertices`]) in every build this CPU runs, gives the
    /// depth, ids and counters of the portable per-triangle setup (the same
    /// mesh with unused vertices appended, so that [`MeshVertices::pays`] is
    /// false): grids in perspective, some crossing the near plane, the sides
    /// of the view or lying behind the eye.
    #[test]
    fn mesh_vertex_stage_draws_as_per_triangle_setup() {
        let (w, h) = (91u32, 67u32);
        let vp = Viewport::new(w, h);
        let mut rnd = signed_unit(0x2545_f491_4f6c_dd1d);
        // A right-handed perspective (reversed Z, near 0.1) looking down −z.
        let proj = Mat4::from_cols(
            Vec4::new(1.2, 0.0, 0.0, 0.0),
            Vec4::new(0.0, 1.6, 0.0, 0.0),
            Vec4::new(0.0, 0.0, 0.0, -1.0),
            Vec4::new(0.0, 0.0, 0.1, 0.0),
        );
        let n = 6u32;
        let mut triangles = Vec::new();
        for i in 0..n - 1 {
            for j in 0..n - 1 {
                let a = i * n + j;
                triangles.push([a, a + 1, a + n + 1]);
                triangles.push([a, a + n + 1, a + n]);
            }
        }
        let mut drawn = 0;
        for k in 0..300u32 {
            let (cull, cov) = match k % 5 {
                0 => (CullMode::Back, Coverage::Standard),
                4 => (CullMode::Front, Coverage::Standard),
                1 => (CullMode::None, Coverage::Outer(DepthPick::Nearest)),
                2 => (CullMode::None, Coverage::Inner(DepthPick::Farthest)),
                _ => (CullMode::None, Coverage::Standard),
            };
            // A wavy grid: centre anywhere from behind the eye to far ahead.
            let c = glam::Vec3::new(2.0 * rnd(), 2.0 * rnd(), -2.5 + 2.7 * rnd());
            let (du, dv) = (
                glam::Vec3::new(rnd(), rnd(), rnd()),
                glam::Vec3::new(rnd(), rnd(), rnd()),
            );
            let mut positions: Vec<Vec4> = (0..n * n)
                .map(|q| {
                    let (u, v) = (
                        (q % n) as f32 / (n - 1) as f32 - 0.5,
                        (q / n) as f32 / (n - 1) as f32 - 0.5,
                    );
                    (c + u * du + v * dv + 0.1 * rnd() * glam::Vec3::Z).extend(1.0)
                })
                .collect();
            let item = DrawItem {
                clip_from_local: proj,
                positions: &positions.clone(),
                triangles: &triangles,
                object: k,
                cull,
            };
            assert!(MeshVertices::pays(item.positions.len(), triangles.len()));
            // Copies of vertex 0: the mesh's screen bounds stay the same.
            positions.resize(3 * triangles.len() + 1, positions[0]);
            let padded = DrawItem {
                positions: &positions,
                ..item
            };
            assert!(!MeshVertices::pays(padded.positions.len(), triangles.len()));
            // The per-triangle setup (portable), then the per-vertex stage in
            // every build this CPU runs.
            let runs = std::iter::once((InstructionSet::Portable, &padded)).chain(
                [
                    InstructionSet::Portable,
                    InstructionSet::Avx2,
                    InstructionSet::Avx512,
                ]
                .into_iter()
                .filter(|&l| l <= InstructionSet::detected())
                .map(|l| (l, &item)),
            );
            let mut out = Vec::new();
            for (level, it) in runs {
                let mut t = DepthTarget::new(w, h, TileSize::T8, true).unwrap();
                let (mut st, mut st_setup) = (RasterStats::default(), RasterStats::default());
                let target = BandTarget {
                    rows: &mut band(&mut t),
                    skip: &mut RowSkip::new(),
                    st: &mut st,
                };
                let d = draw_mesh(level, &vp, target, it, cov, None, &mut st_setup);
                out.push((d.unwrap(), t.depth, t.ids, st, st_setup));
            }
            for o in &out[1..] {
                assert!(
                    *o == out[0],
                    "grid {k}: {:?} / {:?}",
                    (out[0].0, out[0].3, out[0].4),
                    (o.0, o.3, o.4)
                );
            }
            drawn += usize::from(out[0].3.pixels_written > 0);
        }
        assert!(drawn > 100, "only {drawn} grids cover a pixel");
    }

    fn compare(level: InstructionSet, ids: bool, tile: TileSize, cull: CullMode) {
        use InstructionSet::Portable;
        let (w, h) = (77u32, 53u32);
        let vp = Viewport::new(w, h);
        let mut a = DepthTarget::new(w, h, tile, ids).unwrap();
        let mut b = DepthTarget::new(w, h, tile, ids).unwrap();
        let mut rnd = signed_unit(0x9e37_79b9_7f4a_7c15);
        let (mut sa, mut sb) = (RasterStats::default(), RasterStats::default());
        let (mut ta, mut tb) = (RasterStats::default(), RasterStats::default());
        for k in 0..400u32 {
            // Clip-space triangles, some crossing the near plane (z > w), and a box.
            let v: Vec<Vec4> = (0..3)
                .map(|_| {
                    let wv = 0.2 + 3.0 * rnd().abs();
                    Vec4::new(rnd() * 1.5 * wv, rnd() * 1.5 * wv, 0.5, wv)
                })
                .collect();
            let cov = match k % 5 {
                0 => Coverage::Outer(DepthPick::Nearest),
                1 => Coverage::Inner(DepthPick::Farthest),
                _ => Coverage::Standard,
            };
            let item = DrawItem {
                clip_from_local: Mat4::IDENTITY,
                positions: &v,
                triangles: &[[0, 1, 2], [0, 2, 1]],
                object: k,
                cull,
            };
            let lo = Vec3::new(rnd(), rnd(), -3.0 + rnd());
            let hi = lo + Vec3::new(0.1 + rnd().abs(), 0.1 + rnd().abs(), 0.5 * rnd().abs());
            // A right-handed perspective (reversed Z, near 0.1) looking down −z.
            let m = Mat4::from_cols(
                Vec4::new(1.2, 0.0, 0.0, 0.0),
                Vec4::new(0.0, 1.6, 0.0, 0.0),
                Vec4::new(0.0, 0.0, 0.0, -1.0),
                Vec4::new(0.0, 0.0, 0.1, 0.0),
            );
            let corners = crate::item::aabb_corners(lo, hi);
            let boxed = DrawItem {
                clip_from_local: m,
                positions: &corners,
                triangles: &crate::item::AABB_TRIANGLES,
                object: 1000 + k,
                cull,
            };
            for it in [&item, &boxed] {
                let (mut ra, mut rb) = (RowSkip::new(), RowSkip::new());
                let target_a = BandTarget {
                    rows: &mut band(&mut a),
                    skip: &mut ra,
                    st: &mut ta,
                };
                let da = draw_mesh(level, &vp, target_a, it, cov, None, &mut sa).unwrap();
                let target_b = BandTarget {
                    rows: &mut band(&mut b),
                    skip: &mut rb,
                    st: &mut tb,
                };
                let db = draw_mesh(Portable, &vp, target_b, it, cov, None, &mut sb).unwrap();
                assert_eq!(da, db);
            }
            let view = a.query_view(None);
            for limit in [u64::MAX, 1, 7] {
                let qa = query_mesh(level, &view, &item, cov, limit, &mut sa, &mut ta);
                let qb = query_mesh(Portable, &view, &item, cov, limit, &mut sb, &mut tb);
                assert_eq!(qa.unwrap(), qb.unwrap());
                let ba = query_box(level, &view, &m, (lo, hi), cov, limit, &mut sa);
                let bb = query_box(Portable, &view, &m, (lo, hi), cov, limit, &mut sb);
                assert_eq!(ba, bb);
            }
        }
        assert_eq!(a.depth, b.depth, "{level:?}");
        assert_eq!(a.ids, b.ids, "{level:?}");
        assert_eq!((sa, ta), (sb, tb), "{level:?}");
        assert!(sa.pixels_written + ta.pixels_written > 0);
    }
}
