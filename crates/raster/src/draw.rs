//! Drawing occluders into a [`DepthTarget`]: transform, setup, fan, traversal;
//! batches are binned into bands of tile rows and rasterized in parallel
//! (rayon), each band processing its triangles in submission order, so the
//! output is identical to the single-threaded path.

use crate::clip::MAX_CLIPPED_VERTICES;
use crate::coverage::{pixel_bounds, Coverage};
use crate::depth_target::{Band, DepthTarget};
use crate::dispatch::draw_mesh;
use crate::edge::Tri;
use crate::hiz::{project, Projected, RowSkip};
use crate::setup::SnappedVertex;
use crate::setup::{setup_into, Facing, Setup, VertexCache, Viewport};
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

fn check_indices(item: &DrawItem) -> Result<()> {
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
    /// (an any-samples query that passed).
    fn tri(&mut self, t: &Tri, pb: (i64, i64, i64, i64), id: u64) -> bool;
}

/// Which triangles a draw skips by their [`Facing`] (GL's `glCullFace`); set with
/// [`DepthTarget::set_cull`]. Queries never cull.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum CullMode {
    /// Every triangle is drawn.
    #[default]
    None,
    /// Only [`Facing::Front`] triangles are drawn (back-facing and edge-on ones
    /// are counted as culled). For closed meshes seen from outside this drops
    /// only surfaces hidden behind their own front faces; a mesh the eye is in,
    /// or one the near plane cuts, occludes less (never more) than with
    /// [`CullMode::None`], so occlusion culling stays conservative.
    Back,
}

/// Sets up every triangle of `item`, feeding each fan triangle that can cover a
/// pixel of the target, with its pixel bounds and id, to `f`. `cache` holds the
/// vertex stage of a small mesh ([`VertexCache::transform_into`], then
/// [`VertexCache::snap`]; `None` for large ones).
#[inline(always)]
pub(crate) fn setup_item(
    vp: &Viewport,
    item: &DrawItem,
    cov: Coverage,
    cull: CullMode,
    cache: Option<&VertexCache>,
    st: &mut RasterStats,
    f: &mut impl TriSink,
) -> Result<()> {
    let mut s = Setup {
        facing: None,
        clipped: false,
        vertices: [SnappedVertex::default(); MAX_CLIPPED_VERTICES],
        len: 0,
    };
    // Small meshes (boxes) come with each vertex transformed, clip-tested and
    // snapped once; their front-facing triangles go first: the result does not
    // depend on the order within a draw (GREATER keeps the maximum; ties go to the
    // smaller id), but back faces drawn after the front ones mostly fail early.
    let passes = if cache.is_some() { 2 } else { 1 };
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
                        Some(f) if pass == 1 => *f,
                        Some(f) => {
                            *f = c.facing(t);
                            *f
                        }
                        None => c.facing(t),
                    };
                    if (facing == Some(Facing::Front)) != (pass == 0) {
                        continue;
                    }
                    if pass == 1 && cull == CullMode::Back {
                        st.triangles_in += 1;
                        st.triangles_culled += 1;
                        continue;
                    }
                    c.setup(t, facing, vp, &mut s);
                }
                None => {
                    setup_into(clip_vertices(item, k)?, vp, &mut s);
                    if cull == CullMode::Back && s.facing != Some(Facing::Front) {
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

/// Smallest target (pixels) for which batches are binned and run in parallel.
const PARALLEL_MIN_PIXELS: u64 = 256 * 256;

impl DepthTarget {
    /// Draws the triangles of one mesh with the GREATER depth test (ties to the
    /// smaller id when the id target is enabled), skipping those the cull mode
    /// ([`DepthTarget::set_cull`]) names.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] when a triangle names a missing vertex (triangles
    /// before it are drawn).
    pub fn draw(&mut self, item: &DrawItem, cov: Coverage) -> Result<()> {
        self.draw_one(item, cov, false)
    }

    /// [`DepthTarget::draw`]; `checked`: the indices are known to be in range.
    fn draw_one(&mut self, item: &DrawItem, cov: Coverage, checked: bool) -> Result<()> {
        let vp = self.vp;
        let l = self.layout;
        let (ty0, ty1) = self.draw_rows.unwrap_or((0, l.tiles_y));
        let mut st = RasterStats::default();
        let mut drawn = false;
        let mut r = Ok(());
        if ty0 < ty1 {
            let px = l.tile_pixels();
            let (t0, t1) = ((ty0 * l.tiles_x) as usize, (ty1 * l.tiles_x) as usize);
            let mut band = Band {
                layout: l,
                ty0,
                ty1,
                depth: &mut self.depth[t0 * px..t1 * px],
                ids: self
                    .ids
                    .as_deref_mut()
                    .map(|ids| &mut ids[t0 * px..t1 * px]),
                tiles: &mut self.tiles[t0..t1],
            };
            let mut st2 = RasterStats::default();
            match draw_mesh(
                &vp,
                &mut band,
                item,
                cov,
                self.cull,
                &mut self.skip,
                None,
                &mut st,
                &mut st2,
            ) {
                Ok(d) => drawn = d,
                Err(e) => {
                    drawn = true;
                    r = Err(e);
                }
            }
            st.add(&st2);
        }
        if !drawn {
            if !checked {
                check_indices(item)?;
            }
            let n = item.triangles.len() as u64;
            st.triangles_in += n;
            st.triangles_culled += n;
            st.meshes_rejected_hiz += 1;
        }
        self.stats.add(&st);
        r
    }

    /// Draws the 12 triangles of the box `(min, max)` ([`AABB_TRIANGLES`]) as `object`.
    pub fn draw_aabb(
        &mut self,
        clip_from_local: Mat4,
        min: Vec3,
        max: Vec3,
        object: u32,
        cov: Coverage,
    ) {
        let corners = aabb_corners(min, max);
        let item = DrawItem {
            clip_from_local,
            positions: &corners,
            triangles: &AABB_TRIANGLES,
            object,
        };
        self.draw(&item, cov).expect("box indices are in range");
    }

    /// Draws many meshes in order; the result equals drawing them one by one with
    /// [`DepthTarget::draw`]. Large targets are split into bands of tile rows that are
    /// rasterized in parallel (see [`DepthTarget::set_threads`]).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] as [`DepthTarget::draw`]; then nothing is drawn.
    pub fn draw_batch(&mut self, items: &[DrawItem], cov: Coverage) -> Result<()> {
        let threads = self.effective_threads();
        let pixels = u64::from(self.width()) * u64::from(self.height());
        for it in items {
            check_indices(it)?;
        }
        if threads <= 1 || pixels < PARALLEL_MIN_PIXELS {
            for it in items {
                self.draw_one(it, cov, true)?;
            }
            return Ok(());
        }
        self.draw_batch_parallel(items, cov, threads)
    }

    fn effective_threads(&self) -> usize {
        #[cfg(feature = "parallel")]
        {
            if self.threads == 0 {
                rayon::current_num_threads()
            } else {
                self.threads
            }
        }
        #[cfg(not(feature = "parallel"))]
        {
            1
        }
    }

    #[cfg(not(feature = "parallel"))]
    fn draw_batch_parallel(
        &mut self,
        items: &[DrawItem],
        cov: Coverage,
        _threads: usize,
    ) -> Result<()> {
        for it in items {
            self.draw(it, cov)?;
        }
        Ok(())
    }

    #[cfg(feature = "parallel")]
    fn draw_batch_parallel(
        &mut self,
        items: &[DrawItem],
        cov: Coverage,
        threads: usize,
    ) -> Result<()> {
        use rayon::prelude::*;
        let vp = self.vp;
        let l = self.layout;
        let cull = self.cull;
        for it in items {
            check_indices(it)?;
        }
        // Screen bounds of every item (in parallel, order kept).
        let projected: Vec<Projected> = items
            .par_iter()
            .map(|it| project(&it.clip_from_local, it.positions, vp.width, vp.height))
            .collect();
        // Bands of tile rows, several per thread for balance; each band sets up and
        // draws, in submission order, the items whose bounds reach it.
        let bands = (threads * 4).min(l.tiles_y as usize).max(1) as u32;
        let rows_per = l.tiles_y.div_ceil(bands);
        let tile_px = l.tile_pixels();
        let band_tiles = (rows_per * l.tiles_x) as usize;
        let ids_chunks: Vec<Option<&mut [u64]>> = match self.ids.as_deref_mut() {
            Some(ids) => ids.chunks_mut(band_tiles * tile_px).map(Some).collect(),
            None => (0..l.tiles_y.div_ceil(rows_per)).map(|_| None).collect(),
        };
        // Per band: traversal counters and, per item set up there, its setup counters
        // (triangles clipped, culled); the first band that set an item up reports them.
        type BandOut = (RasterStats, Vec<(u32, u32, u32)>);
        let outs: Vec<BandOut> = self
            .depth
            .par_chunks_mut(band_tiles * tile_px)
            .zip(self.tiles.par_chunks_mut(band_tiles))
            .zip(ids_chunks.into_par_iter())
            .enumerate()
            .map(|(b, ((depth, tiles), ids))| {
                let ty0 = b as u32 * rows_per;
                let ty1 = (ty0 + rows_per).min(l.tiles_y);
                let mut band = Band {
                    layout: l,
                    ty0,
                    ty1,
                    depth,
                    ids,
                    tiles,
                };
                let mut st = RasterStats::default();
                let mut setups = Vec::new();
                let mut skip = RowSkip::new();
                for (k, (it, p)) in items.iter().zip(&projected).enumerate() {
                    if let Projected::Bounds(sb) = p {
                        if (sb.y1 >> l.shift) < ty0 || (sb.y0 >> l.shift) >= ty1 {
                            continue;
                        }
                    }
                    let mut sst = RasterStats::default();
                    // Indices were checked above.
                    let drawn = draw_mesh(
                        &vp,
                        &mut band,
                        it,
                        cov,
                        cull,
                        &mut skip,
                        Some(p),
                        &mut sst,
                        &mut st,
                    );
                    if !matches!(drawn, Ok(true)) {
                        continue;
                    }
                    setups.push((
                        k as u32,
                        sst.triangles_clipped as u32,
                        sst.triangles_culled as u32,
                    ));
                }
                (st, setups)
            })
            .collect();
        let mut seen = vec![false; items.len()];
        for (st, setups) in &outs {
            self.stats.add(st);
            for &(k, clipped, culled) in setups {
                if !std::mem::replace(&mut seen[k as usize], true) {
                    self.stats.triangles_clipped += u64::from(clipped);
                    self.stats.triangles_culled += u64::from(culled);
                }
            }
        }
        // Items no band set up: off screen or hidden wherever they reach.
        for (it, seen) in items.iter().zip(&seen) {
            if !seen {
                self.stats.triangles_culled += it.triangles.len() as u64;
                self.stats.meshes_rejected_hiz += 1;
            }
        }
        self.stats.triangles_in += items
            .iter()
            .map(|it| it.triangles.len() as u64)
            .sum::<u64>();
        Ok(())
    }
}
