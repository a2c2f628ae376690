//! Occlusion queries with GPU semantics: count the samples of some geometry that
//! pass GEQUAL against the current depth, without writing it [GL
//! `SAMPLES_PASSED` / `ANY_SAMPLES_PASSED`; Steiner §2.5].
//!
//! An AABB query first tests the box against the view's apex region — in clip
//! space `{z ≥ w, |x| ≤ w, |y| ≤ w}`: for a perspective view conv(centre of
//! projection, near rectangle), for an orthographic one the half-infinite prism
//! over the near rectangle toward the light — widened by [`APEX_EPS`]; a box
//! meeting it is [`VISIBLE`] without rasterizing. Every other box has its 12
//! triangles (all faces, no culling) clipped and rasterized as usual.

use crate::depth_target::DepthTarget;
use crate::dispatch::{query_box, query_mesh};
use crate::item::DrawItem;
use crate::prefetch;
use crate::query_options::{QueryOptions, VISIBLE};
use crate::receiver_target::ReceiverTarget;
use crate::stats::RasterStats;
use crate::tile_walk::QueryView;
use crate::{Error, Result};
use glam::{Mat4, Vec3};

fn check_receivers(t: &DepthTarget, r: Option<&ReceiverTarget>) -> Result<()> {
    match r {
        Some(r) if r.size() != (t.width(), t.height()) || r.depth.len() != t.depth.len() => {
            Err(Error::SizeMismatch {
                expected: (t.width(), t.height()),
                got: r.size(),
            })
        }
        _ => Ok(()),
    }
}

impl DepthTarget {
    pub(crate) fn query_view<'a>(&'a self, receivers: Option<&'a ReceiverTarget>) -> QueryView<'a> {
        QueryView {
            vp: &self.vp,
            layout: self.layout,
            depth: &self.depth,
            tiles: &self.tiles,
            receivers: receivers.map(|r| r.depth.as_slice()),
            receiver_tiles: receivers.map(|r| r.tile_min.as_slice()),
        }
    }

    /// Prefetches the depth tiles under a box queried soon.
    #[inline(always)]
    fn prefetch_box(&self, m: &Mat4, b: Option<&(Vec3, Vec3)>) {
        if let Some(&(lo, hi)) = b {
            let ends = (lo.extend(1.0), hi.extend(1.0));
            prefetch::span(m, ends, &self.layout, &self.depth, &self.tiles);
        }
    }

    pub(crate) fn query_item(
        &self,
        item: &DrawItem,
        opts: &QueryOptions,
        receivers: Option<&ReceiverTarget>,
        st: &mut RasterStats,
    ) -> Result<u32> {
        let view = self.query_view(receivers);
        let mut st2 = RasterStats::default();
        let (cov, limit) = (opts.coverage, opts.mode.limit());
        let count = query_mesh(self.isa, &view, item, cov, limit, st, &mut st2)?;
        st.add(&st2);
        st.queries += 1;
        Ok(count.min(u64::from(VISIBLE - 1)) as u32)
    }

    /// Counts the samples of a mesh passing GEQUAL against the current depth (no
    /// writes, no face culling), restricted to marked receiver pixels at or nearer
    /// than the receiver depth when `receivers` is given.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a bad triangle index, [`Error::SizeMismatch`]
    /// when `receivers` belongs to another size.
    pub fn query(
        &mut self,
        item: &DrawItem,
        opts: &QueryOptions,
        receivers: Option<&ReceiverTarget>,
    ) -> Result<u32> {
        check_receivers(self, receivers)?;
        let mut st = RasterStats::default();
        let r = self.query_item(item, opts, receivers, &mut st);
        self.stats.add(&st);
        r
    }

    /// Queries the box `(min, max)` in local space: [`VISIBLE`] when it meets the apex
    /// region, else the count (or any-samples flag) of its 12 triangles.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] when `receivers` belongs to another size.
    pub fn query_aabb(
        &mut self,
        clip_from_local: Mat4,
        min: Vec3,
        max: Vec3,
        opts: &QueryOptions,
        receivers: Option<&ReceiverTarget>,
    ) -> Result<u32> {
        check_receivers(self, receivers)?;
        let mut st = RasterStats::default();
        let r = self.query_aabb_inner(clip_from_local, min, max, opts, receivers, &mut st);
        self.stats.add(&st);
        r
    }

    pub(crate) fn query_aabb_inner(
        &self,
        clip_from_local: Mat4,
        min: Vec3,
        max: Vec3,
        opts: &QueryOptions,
        receivers: Option<&ReceiverTarget>,
        st: &mut RasterStats,
    ) -> Result<u32> {
        let view = self.query_view(receivers);
        let (cov, limit) = (opts.coverage, opts.mode.limit());
        let bounds = (min, max);
        Ok(query_box(
            self.isa,
            &view,
            &clip_from_local,
            bounds,
            cov,
            limit,
            st,
        ))
    }

    /// One query over the union of several boxes (a CHC++ multiquery, or a node's
    /// tighter volume from its children's boxes) [Mattausch et al. 2008]: the
    /// sum of the boxes' counts, saturating below [`VISIBLE`]; [`VISIBLE`] when
    /// any box meets the apex region. With [`Any`](crate::QueryMode::Any) or
    /// [`CountUpTo`](crate::QueryMode::CountUpTo) it stops once the sum
    /// reaches the mode's limit and answers the limit (a sum of counts each
    /// taken up to the limit reaches it exactly when the full sum does).
    /// Zero exactly when [`DepthTarget::query_aabb`] is zero for every box.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] when `receivers` belongs to another size.
    pub fn query_aabb_union(
        &mut self,
        clip_from_local: Mat4,
        boxes: &[(Vec3, Vec3)],
        opts: &QueryOptions,
        receivers: Option<&ReceiverTarget>,
    ) -> Result<u32> {
        check_receivers(self, receivers)?;
        let mut st = RasterStats::default();
        let mut total = 0u32;
        for &(a, b) in boxes {
            let n = self.query_aabb_inner(clip_from_local, a, b, opts, receivers, &mut st)?;
            if n == VISIBLE {
                total = VISIBLE;
                break;
            }
            total = total.saturating_add(n).min(VISIBLE - 1);
            if u64::from(total) >= opts.mode.limit() {
                total = opts.mode.limit() as u32;
                break;
            }
        }
        self.stats.add(&st);
        Ok(total)
    }

    /// Queries many boxes against the current depth, in parallel when threads allow;
    /// results in input order, identical to one-by-one [`DepthTarget::query_aabb`].
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] when `receivers` belongs to another size.
    pub fn query_aabbs(
        &mut self,
        clip_from_local: Mat4,
        boxes: &[(Vec3, Vec3)],
        opts: &QueryOptions,
        receivers: Option<&ReceiverTarget>,
        out: &mut Vec<u32>,
    ) -> Result<()> {
        check_receivers(self, receivers)?;
        out.clear();
        #[cfg(feature = "parallel")]
        {
            let threads = if self.threads == 0 {
                rayon::current_num_threads()
            } else {
                self.threads
            };
            if threads > 1 && boxes.len() > 64 {
                use rayon::prelude::*;
                let this = &*self;
                let chunk = boxes.len().div_ceil(threads * 8).max(1);
                let parts: Vec<(Vec<u32>, RasterStats)> = boxes
                    .par_chunks(chunk)
                    .map(|bs| {
                        let mut st = RasterStats::default();
                        let mut v = Vec::with_capacity(bs.len());
                        this.query_run(clip_from_local, bs, opts, receivers, &mut st, &mut v)
                            .expect("receivers were checked");
                        (v, st)
                    })
                    .collect();
                for (v, st) in parts {
                    out.extend(v);
                    self.stats.add(&st);
                }
                return Ok(());
            }
        }
        let mut st = RasterStats::default();
        let r = self.query_run(clip_from_local, boxes, opts, receivers, &mut st, out);
        self.stats.add(&st);
        r
    }

    /// Queries `boxes` in order into `out`, prefetching the depth tiles a few
    /// boxes ahead while recent queries read depth (when hierarchical z rejects
    /// nearly every box, as in a street view, they read none and prefetches would
    /// only cost).
    fn query_run(
        &self,
        clip_from_local: Mat4,
        boxes: &[(Vec3, Vec3)],
        opts: &QueryOptions,
        receivers: Option<&ReceiverTarget>,
        st: &mut RasterStats,
        out: &mut Vec<u32>,
    ) -> Result<()> {
        // Bit k: the query k boxes back read depth (tiles or a probed pixel).
        let mut recent = u32::MAX;
        for (k, &(a, b)) in boxes.iter().enumerate() {
            if (recent & 0xff).count_ones() >= 2 {
                self.prefetch_box(&clip_from_local, boxes.get(k + prefetch::AHEAD));
            }
            let read = st.tiles_touched + st.pixels_tested;
            out.push(self.query_aabb_inner(clip_from_local, a, b, opts, receivers, st)?);
            recent = recent << 1 | u32::from(st.tiles_touched + st.pixels_tested > read);
        }
        Ok(())
    }
}
