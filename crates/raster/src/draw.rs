//! Drawing occluders into a [`DepthTarget`]: transform, setup, fan, traversal;
//! batches are binned into bands of tile rows and rasterized in parallel
//! (rayon), each band processing its triangles in submission order, so the
//! output is identical to the single-threaded path.

use crate::clip::MAX_CLIPPED_VERTICES;
use crate::coverage::{pixel_bounds, Coverage};
use crate::depth_target::{Band, DepthTarget, Layout};
use crate::dispatch::{draw_mesh, project_items};
use crate::edge::Tri;
use crate::hiz::{hidden, Projected, RowSkip};
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
    // Small meshes (boxes) and the rest get a copy each, the other's path compiled
    // out (a leaner loop spills less).
    if cache.is_some() {
        setup_item_as::<true>(vp, item, cov, cull, cache, st, f)
    } else {
        setup_item_as::<false>(vp, item, cov, cull, None, st, f)
    }
}

/// [`setup_item`]; `CACHED`: `cache` is `Some`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn setup_item_as<const CACHED: bool>(
    vp: &Viewport,
    item: &DrawItem,
    cov: Coverage,
    cull: CullMode,
    cache: Option<&VertexCache>,
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

/// Tile-row cuts `[0, …, tiles_y]` of about `bands` parallel bands of similar
/// estimated work: each mesh costs its screen rectangle's width in tiles plus a
/// fixed setup share in every tile row it reaches (all rows when its bounds are
/// unknown). Evenly sized bands left one thread with nearly all the work when the
/// meshes crowd a few rows (a street view's horizon).
#[cfg(feature = "parallel")]
fn band_rows(projected: &[Projected], l: &Layout, bands: usize) -> Vec<u32> {
    const SETUP_TILES: u64 = 4;
    let rows = l.tiles_y as usize;
    if rows == 0 {
        return vec![0, 0];
    }
    // Difference array of the per-row work.
    let mut diff = vec![0i64; rows + 1];
    for p in projected {
        let (r0, r1, w) = match p {
            Projected::Offscreen => continue,
            Projected::Unknown => (0, rows - 1, u64::from(l.tiles_x)),
            Projected::Bounds(b) => (
                (b.y0 >> l.shift) as usize,
                (b.y1 >> l.shift) as usize,
                u64::from((b.x1 >> l.shift) - (b.x0 >> l.shift) + 1),
            ),
        };
        let w = (w + SETUP_TILES) as i64;
        diff[r0] += w;
        diff[r1 + 1] -= w;
    }
    // Prefix sums of the per-row work; every row costs something (clearing,
    // bounds), so empty rows still split.
    let mut prefix = Vec::with_capacity(rows + 1);
    prefix.push(0u64);
    let mut run = 0i64;
    for d in &diff[..rows] {
        run += d;
        prefix.push(prefix[prefix.len() - 1] + run as u64 + 1);
    }
    let total = prefix[rows];
    let bands = bands.clamp(1, rows) as u64;
    // Cut k goes to the row boundary whose prefix is nearest k/bands of the total,
    // so a heavy row gets cuts on both sides.
    let mut cuts = vec![0u32];
    for k in 1..bands {
        let target = total * k / bands;
        let r = prefix.partition_point(|&p| p < target);
        let r = if r > 0 && target - prefix[r - 1] < prefix.get(r).map_or(u64::MAX, |p| p - target)
        {
            r - 1
        } else {
            r
        };
        if r > cuts[cuts.len() - 1] as usize && r < rows {
            cuts.push(r as u32);
        }
    }
    cuts.push(l.tiles_y);
    cuts
}

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
        // (Indices were checked by `draw_batch`.)
        // Screen bounds of every item (in parallel, order kept).
        let mut projected = vec![Projected::Offscreen; items.len()];
        projected
            .par_chunks_mut(256)
            .zip(items.par_chunks(256))
            .for_each(|(out, its)| project_items(&vp, its, out));
        // Bands of tile rows, several per thread, of similar estimated work; each
        // band sets up and draws, in submission order, the items whose bounds reach
        // it.
        let cuts = band_rows(&projected, &l, threads * 4);
        let tile_px = l.tile_pixels();
        let mut parts = Vec::with_capacity(cuts.len());
        let (mut depth, mut tiles) = (&mut self.depth[..], &mut self.tiles[..]);
        let mut ids = self.ids.as_deref_mut();
        for w in cuts.windows(2) {
            let n = ((w[1] - w[0]) * l.tiles_x) as usize;
            let (d, dr) = std::mem::take(&mut depth).split_at_mut(n * tile_px);
            let (t, tr) = std::mem::take(&mut tiles).split_at_mut(n);
            let i = match ids.take() {
                Some(all) => {
                    let (i, ir) = all.split_at_mut(n * tile_px);
                    ids = Some(ir);
                    Some(i)
                }
                None => None,
            };
            (depth, tiles) = (dr, tr);
            parts.push((w[0], w[1], d, t, i));
        }
        // Per band: traversal counters and, per item set up there, its setup counters
        // (triangles clipped, culled); the first band that set an item up reports them.
        type BandOut = (RasterStats, Vec<(u32, u32, u32)>);
        let outs: Vec<BandOut> = parts
            .into_par_iter()
            .map(|(ty0, ty1, depth, tiles, ids)| {
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
                        // Outside the band, or hidden in every row of it here (what
                        // `draw_mesh` would find first, without its call and setup).
                        if (sb.y1 >> l.shift) < ty0
                            || (sb.y0 >> l.shift) >= ty1
                            || hidden(&l, band.tiles, ty0, ty1, sb)
                        {
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

#[cfg(all(test, feature = "parallel"))]
mod tests {
    use super::*;
    use crate::hiz::ScreenBounds;

    fn layout(tiles_y: u32) -> Layout {
        Layout {
            width: 800,
            height: tiles_y * 8,
            tiles_x: 100,
            tiles_y,
            shift: 3,
        }
    }

    fn rect(y0: u32, y1: u32) -> Projected {
        Projected::Bounds(ScreenBounds {
            x0: 0,
            x1: 15,
            y0,
            y1,
            zmax: 0.5,
        })
    }

    fn check(cuts: &[u32], l: &Layout, bands: usize) {
        assert_eq!(cuts.first(), Some(&0));
        assert_eq!(cuts.last(), Some(&l.tiles_y));
        assert!(cuts.windows(2).all(|w| w[0] < w[1]), "{cuts:?}");
        assert!(cuts.len() <= bands + 1, "{cuts:?}");
    }

    #[test]
    fn bands_split_where_the_meshes_crowd() {
        let l = layout(100);
        // Nothing to draw: even split of the uniform row cost.
        let cuts = band_rows(&[], &l, 4);
        check(&cuts, &l, 4);
        assert_eq!(cuts, vec![0, 25, 50, 75, 100]);
        // A horizon: thousands of small meshes in tile rows 50 and 51, one tall one.
        let mut p = vec![rect(400, 415); 4000];
        p.push(rect(0, 799));
        p.push(Projected::Offscreen);
        let cuts = band_rows(&p, &l, 8);
        check(&cuts, &l, 8);
        // Each crowded row gets a band of its own; the light rows around them make
        // one band each.
        assert_eq!(cuts, vec![0, 50, 51, 52, 100]);
        // Unknown bounds cost every row; a single row makes one band.
        let one = layout(1);
        let cuts = band_rows(&[Projected::Unknown], &one, 8);
        assert_eq!(cuts, vec![0, 1]);
    }
}
