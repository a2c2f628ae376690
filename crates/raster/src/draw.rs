//! Drawing occluders into a [`DepthTarget`]: transform, setup, fan, traversal;
//! batches are binned into bands of tile rows and rasterized in parallel
//! (rayon), each band processing its triangles in submission order, so the
//! output is identical to the single-threaded path.

#[cfg(feature = "parallel")]
use crate::batch_scratch::{BandOut, BatchScratch};
use crate::coverage::Coverage;
use crate::depth_target::DepthTarget;
#[cfg(feature = "parallel")]
use crate::dispatch::project_items;
use crate::dispatch::{draw_mesh, BandTarget};
#[cfg(feature = "parallel")]
use crate::hiz::{hidden, Projected, RowSkip};
use crate::item::{aabb_corners, check_indices, DrawItem, AABB_TRIANGLES};
#[cfg(feature = "parallel")]
use crate::layout::Layout;
use crate::layout::TileRows;
use crate::stats::RasterStats;
use crate::Result;
use glam::{Mat4, Vec3};

/// Smallest target (pixels) for which batches are binned and run in parallel.
const PARALLEL_MIN_PIXELS: u64 = 256 * 256;

/// Tile-row cuts `[0, …, tiles_y]` of about `bands` parallel bands of similar
/// estimated work: each mesh costs its screen rectangle's width in tiles plus a
/// fixed setup share in every tile row it reaches (all rows when its bounds are
/// unknown). Evenly sized bands left one thread with nearly all the work when the
/// meshes crowd a few rows (a street view's horizon).
#[cfg(feature = "parallel")]
fn band_rows(projected: &[Projected], l: &Layout, bands: usize, scratch: &mut BatchScratch) {
    const SETUP_TILES: u64 = 4;
    let BatchScratch {
        cuts, diff, prefix, ..
    } = scratch;
    cuts.clear();
    let rows = l.tiles_y as usize;
    if rows == 0 {
        cuts.extend([0, 0]);
        return;
    }
    // Difference array of the per-row work.
    diff.clear();
    diff.resize(rows + 1, 0);
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
    prefix.clear();
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
    cuts.push(0);
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
}

/// Runs `f` on the bands of `rows` cut at `cuts` (its first and last are
/// the rows' ends), each with its own output, splitting in halves with
/// `rayon::join` (no allocation, unlike collecting the bands).
#[cfg(feature = "parallel")]
fn for_each_band<F>(rows: TileRows<'_>, cuts: &[u32], outs: &mut [BandOut], f: &F)
where
    F: Fn(TileRows<'_>, &mut BandOut) + Sync,
{
    if cuts.len() <= 2 {
        if let Some(out) = outs.first_mut() {
            f(rows, out);
        }
        return;
    }
    let mid = cuts.len() / 2;
    let (lo, hi) = rows.split_at(cuts[mid]);
    let (olo, ohi) = outs.split_at_mut(mid);
    rayon::join(
        || for_each_band(lo, &cuts[..=mid], olo, f),
        || for_each_band(hi, &cuts[mid..], ohi, f),
    );
}

impl DepthTarget {
    /// Draws the triangles of one mesh with the GREATER depth test (ties to the
    /// smaller id when the id target is enabled), skipping those the item's
    /// cull mode ([`DrawItem::cull`]) names.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`](crate::Error::IndexOutOfRange) when a triangle names a missing vertex (triangles
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
            let mut band = TileRows::of(
                l,
                (ty0, ty1),
                &mut self.depth,
                self.ids.as_deref_mut(),
                &mut self.tiles,
            );
            let mut st2 = RasterStats::default();
            let target = BandTarget {
                rows: &mut band,
                skip: &mut self.skip,
                st: &mut st2,
            };
            match draw_mesh(self.isa, &vp, target, item, cov, None, &mut st) {
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
            cull: crate::CullMode::None,
        };
        self.draw(&item, cov).expect("box indices are in range");
    }

    /// Draws many meshes in order; the result equals drawing them one by one with
    /// [`DepthTarget::draw`]. Large targets are split into bands of tile rows that are
    /// rasterized in parallel (see [`DepthTarget::set_threads`]).
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`](crate::Error::IndexOutOfRange) as [`DepthTarget::draw`]; then nothing is drawn.
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
        let isa = self.isa;
        // (Indices were checked by `draw_batch`.)
        let mut scratch = std::mem::take(&mut self.batch);
        // Screen bounds of every item (in parallel, order kept).
        scratch.projected.clear();
        scratch.projected.resize(items.len(), Projected::Offscreen);
        scratch
            .projected
            .par_chunks_mut(256)
            .zip(items.par_chunks(256))
            .for_each(|(out, its)| project_items(isa, &vp, its, out));
        // Bands of tile rows, two per thread, of similar estimated work; each
        // band sets up and draws, in submission order, the items whose bounds reach
        // it. (Every band re-tests and sets up the items it shares with another:
        // four per thread measured slower on city_16384 street, 2 threads, 1080p,
        // occluders 2.4–3.3 against 2.9–4.2 ms in three interleaved rounds.)
        let projected = std::mem::take(&mut scratch.projected);
        band_rows(&projected, &l, threads * 2, &mut scratch);
        // Only the row window is drawn (`set_draw_rows`), as `draw` does:
        // the bands are cut to it.
        let (wy0, wy1) = self.draw_rows.unwrap_or((0, l.tiles_y));
        let cuts = &mut scratch.cuts;
        for c in cuts.iter_mut() {
            *c = (*c).clamp(wy0, wy1);
        }
        cuts.dedup();
        let bands = cuts.len().saturating_sub(1);
        // (Never shortened: each band's setup list keeps its buffer.)
        if scratch.bands.len() < bands {
            scratch.bands.resize_with(bands, Default::default);
        }
        if let (Some(&ty0), Some(&ty1), true) = (cuts.first(), cuts.last(), bands > 0) {
            let rows = TileRows::of(
                l,
                (ty0, ty1),
                &mut self.depth,
                self.ids.as_deref_mut(),
                &mut self.tiles,
            );
            let band = |mut band: TileRows<'_>, out: &mut BandOut| {
                let (ty0, ty1) = (band.ty0, band.ty1);
                let (st, setups) = out;
                *st = RasterStats::default();
                setups.clear();
                // Room for every item: which band draws how many changes
                // from batch to batch, and a steady frame allocates nothing.
                setups.reserve(items.len());
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
                    let target = BandTarget {
                        rows: &mut band,
                        skip: &mut skip,
                        st,
                    };
                    // Indices were checked above.
                    let drawn = draw_mesh(isa, &vp, target, it, cov, Some(p), &mut sst);
                    if !matches!(drawn, Ok(true)) {
                        continue;
                    }
                    setups.push((
                        k as u32,
                        sst.triangles_clipped as u32,
                        sst.triangles_culled as u32,
                    ));
                }
            };
            for_each_band(rows, &scratch.cuts, &mut scratch.bands[..bands], &band);
        }
        scratch.projected = projected;
        let seen = &mut scratch.seen;
        seen.clear();
        seen.resize(items.len(), false);
        for (st, setups) in &scratch.bands[..bands] {
            self.stats.add(st);
            for &(k, clipped, culled) in setups {
                if !std::mem::replace(&mut seen[k as usize], true) {
                    self.stats.triangles_clipped += u64::from(clipped);
                    self.stats.triangles_culled += u64::from(culled);
                }
            }
        }
        // Items no band set up: off screen or hidden wherever they reach.
        for (it, &seen) in items.iter().zip(&scratch.seen) {
            if !seen {
                self.stats.triangles_culled += it.triangles.len() as u64;
                self.stats.meshes_rejected_hiz += 1;
            }
        }
        self.stats.triangles_in += items
            .iter()
            .map(|it| it.triangles.len() as u64)
            .sum::<u64>();
        self.batch = scratch;
        Ok(())
    }
}

#[cfg(all(test, feature = "parallel"))]
mod tests {
    use super::*;
    use crate::hiz::ScreenBounds;

    /// [`band_rows`]' cuts.
    fn cuts_of(projected: &[Projected], l: &Layout, bands: usize) -> Vec<u32> {
        let mut scratch = BatchScratch::default();
        band_rows(projected, l, bands, &mut scratch);
        scratch.cuts
    }

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
        let cuts = cuts_of(&[], &l, 4);
        check(&cuts, &l, 4);
        assert_eq!(cuts, vec![0, 25, 50, 75, 100]);
        // A horizon: thousands of small meshes in tile rows 50 and 51, one tall one.
        let mut p = vec![rect(400, 415); 4000];
        p.push(rect(0, 799));
        p.push(Projected::Offscreen);
        let cuts = cuts_of(&p, &l, 8);
        check(&cuts, &l, 8);
        // Each crowded row gets a band of its own; the light rows around them make
        // one band each.
        assert_eq!(cuts, vec![0, 50, 51, 52, 100]);
        // Unknown bounds cost every row; a single row makes one band.
        let one = layout(1);
        let cuts = cuts_of(&[Projected::Unknown], &one, 8);
        assert_eq!(cuts, vec![0, 1]);
    }
}
