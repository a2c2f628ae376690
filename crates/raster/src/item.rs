//! What is drawn or queried: a [`DrawItem`] (a mesh with its
//! `clip_from_local` and ids), the box mesh of AABB queries, and the per-item
//! setup that clips, snaps and fans each triangle for the tile walk.

use crate::clip::MAX_CLIPPED_VERTICES;
use crate::coverage::{pixel_bounds, Coverage, Rect};
use crate::depth_target::CullMode;
use crate::edge::Tri;
use crate::setup::{
    setup_into, Facing, MeshVertices, Setup, SnappedVertex, VertexCache, VertexStage, Viewport,
};
use crate::stats::RasterStats;
use crate::{Error, Result};
use glam::{Mat4, Vec3, Vec4};

/// Triangles of an axis-aligned box in the box-city order (README of the bench
/// data): corner `c = (x?1:0) | (y?2:0) | (z?4:0)`, faces −X, +X, −Y, +Y, −Z, +Z
/// as CCW quads seen from outside, each split into (a, b, c), (a, c, d).
pub const AABB_TRIANGLES: [[u32; 3]; 12] = [
    [0, 4, 6],
    [0, 6, 2],
    [1, 3, 7],
    [1, 7, 5],
    [0, 1, 5],
    [0, 5, 4],
    [2, 6, 7],
    [2, 7, 3],
    [0, 2, 3],
    [0, 3, 1],
    [4, 5, 7],
    [4, 7, 6],
];

/// The eight corners of the box `(min, max)` as points (w = 1), indexed as in
/// [`AABB_TRIANGLES`].
pub fn aabb_corners(min: Vec3, max: Vec3) -> [Vec4; 8] {
    std::array::from_fn(|c| {
        Vec4::new(
            if c & 1 != 0 { max.x } else { min.x },
            if c & 2 != 0 { max.y } else { min.y },
            if c & 4 != 0 { max.z } else { min.z },
            1.0,
        )
    })
}

/// One mesh to draw: local positions (w = 0 for points at infinity), triangles,
/// the `clip_from_local` matrix and the object id written to the id target.
#[derive(Clone, Copy, Debug)]
pub struct DrawItem<'a> {
    /// `clip_from_local` (reversed Z, see the crate conventions).
    pub clip_from_local: Mat4,
    /// Local-space positions.
    pub positions: &'a [Vec4],
    /// Vertex indices of each triangle; triangle `k` gets id `(object, k)`.
    pub triangles: &'a [[u32; 3]],
    /// Object id.
    pub object: u32,
    /// Which triangles the draw skips by facing (queries never cull).
    pub cull: CullMode,
}

/// Clip-space vertices of triangle `k` of `item`.
#[inline(always)]
pub(crate) fn clip_vertices(item: &DrawItem, k: usize) -> Result<[Vec4; 3]> {
    let t = item.triangles[k];
    let mut out = [Vec4::ZERO; 3];
    for (o, &i) in out.iter_mut().zip(&t) {
        let p = item
            .positions
            .get(i as usize)
            .ok_or(Error::IndexOutOfRange {
                triangle: k,
                index: i,
                len: item.positions.len(),
            })?;
        *o = item.clip_from_local * *p;
    }
    Ok(out)
}

pub(crate) fn check_indices(item: &DrawItem) -> Result<()> {
    for (k, t) in item.triangles.iter().enumerate() {
        for &i in t {
            if i as usize >= item.positions.len() {
                return Err(Error::IndexOutOfRange {
                    triangle: k,
                    index: i,
                    len: item.positions.len(),
                });
            }
        }
    }
    Ok(())
}

/// What [`setup_item`] feeds its fan triangles to: a trait with an
/// `#[inline(always)]` method rather than a closure, so that the traversal is
/// inlined into (and compiled with the target features of) the dispatched
/// per-mesh function — a closure this large is outlined and built for the
/// baseline CPU.
pub(crate) trait TriSink {
    /// Takes fan triangle `t` with pixel bounds `pb` and id `id`; true to stop
    /// (a query whose count reached its limit).
    fn tri(&mut self, t: &Tri, pb: Rect, id: u64) -> bool;
}

/// Where [`setup_item`] takes a mesh's vertex stage from.
#[derive(Clone, Copy)]
pub(crate) enum Vertices<'a> {
    /// Computed per triangle (three vertices each).
    PerTriangle,
    /// A small mesh's (a box's) cache: [`VertexCache::transform_into`], then
    /// [`VertexCache::snap`].
    Small(&'a VertexCache),
    /// A larger mesh's, filled by [`MeshVertices::fill`].
    Mesh(&'a MeshVertices),
}

/// Sets up every triangle of `item`, feeding each fan triangle that can cover a
/// pixel of the target, with its pixel bounds and id, to `f`. `vertices` says
/// where the vertex stage comes from: the values are the same either way.
#[inline(always)]
pub(crate) fn setup_item(
    vp: &Viewport,
    item: &DrawItem,
    cov: Coverage,
    cull: CullMode,
    vertices: Vertices,
    st: &mut RasterStats,
    f: &mut impl TriSink,
) -> Result<()> {
    // Each source gets its own copy, the others' paths compiled out (a leaner
    // loop spills less).
    match vertices {
        Vertices::PerTriangle => {
            setup_item_as::<VertexCache, false>(vp, item, cov, cull, None, st, f)
        }
        Vertices::Small(c) => setup_item_as::<_, true>(vp, item, cov, cull, Some(c), st, f),
        Vertices::Mesh(c) => setup_item_as::<_, true>(vp, item, cov, cull, Some(c), st, f),
    }
}

/// [`setup_item`]; `CACHED`: `cache` is `Some`.
#[inline(always)]
fn setup_item_as<C: VertexStage, const CACHED: bool>(
    vp: &Viewport,
    item: &DrawItem,
    cov: Coverage,
    cull: CullMode,
    cache: Option<&C>,
    st: &mut RasterStats,
    f: &mut impl TriSink,
) -> Result<()> {
    let cache = if CACHED { cache } else { None };
    let mut s = Setup {
        facing: None,
        clipped: false,
        vertices: [SnappedVertex::default(); MAX_CLIPPED_VERTICES],
        len: 0,
    };
    // Cached meshes come with each vertex transformed, clip-tested and snapped
    // once; a box's front-facing triangles go first: the result does not depend
    // on the order within a draw (GREATER keeps the maximum; ties go to the
    // smaller id), but back faces drawn after the front ones mostly fail early.
    let passes = if cache.is_some() && C::FRONT_FIRST {
        2
    } else {
        1
    };
    // Facing of the first triangles, from the first pass (computed once).
    const KEEP: usize = 16;
    let mut facings = [None; KEEP];
    for pass in 0..passes {
        for (k, &t) in item.triangles.iter().enumerate() {
            match cache {
                Some(c) => {
                    if let Some(&i) = t.iter().find(|&&i| i as usize >= item.positions.len()) {
                        return Err(Error::IndexOutOfRange {
                            triangle: k,
                            index: i,
                            len: item.positions.len(),
                        });
                    }
                    let facing = match facings.get_mut(k) {
                        _ if passes == 1 => c.facing(t),
                        Some(f) if pass == 1 => *f,
                        Some(f) => {
                            *f = c.facing(t);
                            *f
                        }
                        None => c.facing(t),
                    };
                    let front = facing == Some(Facing::Front);
                    if passes == 2 && front != (pass == 0) {
                        continue;
                    }
                    if cull.skips(facing) {
                        st.triangles_in += 1;
                        st.triangles_culled += 1;
                        continue;
                    }
                    c.setup(t, facing, vp, &mut s);
                }
                None => {
                    setup_into(clip_vertices(item, k)?, vp, &mut s);
                    if cull.skips(s.facing) {
                        st.triangles_in += 1;
                        st.triangles_culled += 1;
                        continue;
                    }
                }
            }
            st.triangles_in += 1;
            if s.clipped {
                st.triangles_clipped += 1;
            }
            let id = (u64::from(item.object) << 32) | k as u64;
            let mut any = false;
            let mut stop = false;
            let poly = s.polygon();
            for i in 1..poly.len().saturating_sub(1) {
                let Some(t) = Tri::new(poly[0], poly[i], poly[i + 1]) else {
                    continue;
                };
                if let Some(pb) = pixel_bounds(&t, cov, vp.width, vp.height) {
                    any = true;
                    if f.tri(&t, pb, id) {
                        stop = true;
                        break;
                    }
                }
            }
            if !any {
                st.triangles_culled += 1;
            }
            if stop {
                return Ok(());
            }
        }
    }
    Ok(())
}
