//! Runtime CPU dispatch: the whole per-mesh pipeline (setup, clipping, snapping,
//! traversal) is compiled twice — portable, and for AVX2 (`#[target_feature]`
//! multiversioning: the compiler vectorizes the per-row evaluation 4-wide in f64
//! and inlines `round`) — and chosen once at runtime. Both builds perform the same
//! IEEE operations in the same order (no fused multiply-add is enabled), so their
//! results are bit-identical; a test checks it. Set `SHADOWCULL_RASTER_SCALAR=1`
//! to force the portable build.

use crate::coverage::Coverage;
use crate::depth_target::Band;
use crate::draw::{setup_item, DrawItem};
use crate::hiz::RowSkip;
use crate::setup::Viewport;
use crate::stats::RasterStats;
use crate::traverse::{draw_tri, query_tri, QueryView};
use crate::Result;

#[inline(always)]
fn draw_item_impl(
    vp: &Viewport,
    band: &mut Band,
    item: &DrawItem,
    cov: Coverage,
    skip: &RowSkip,
    st_setup: &mut RasterStats,
    st: &mut RasterStats,
) -> Result<()> {
    setup_item(vp, item, cov, st_setup, |t, pb, id| {
        draw_tri(band, t, pb, cov, id, skip, st);
        false
    })
}

#[inline(always)]
fn query_item_impl(
    vp: &Viewport,
    view: &QueryView,
    item: &DrawItem,
    cov: Coverage,
    any: bool,
    st_setup: &mut RasterStats,
    st: &mut RasterStats,
) -> Result<u64> {
    let mut count = 0u64;
    setup_item(vp, item, cov, st_setup, |t, pb, _| {
        count += query_tri(view, t, pb, cov, any, st);
        any && count > 0
    })?;
    Ok(count)
}

/// Whether the AVX2 builds may run (detected once; `SHADOWCULL_RASTER_SCALAR=1`
/// forces the portable ones).
#[inline]
pub(crate) fn avx2_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        avx2::available()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Sets up and draws every triangle of `item` into the rows of `band`.
pub(crate) fn draw_item(
    vp: &Viewport,
    band: &mut Band,
    item: &DrawItem,
    cov: Coverage,
    skip: &RowSkip,
    st_setup: &mut RasterStats,
    st: &mut RasterStats,
) -> Result<()> {
    #[cfg(target_arch = "x86_64")]
    if avx2::available() {
        // SAFETY: `avx2::draw_item` only requires AVX2, detected at runtime just now.
        return unsafe { avx2::draw_item(vp, band, item, cov, skip, st_setup, st) };
    }
    draw_item_impl(vp, band, item, cov, skip, st_setup, st)
}

/// The portable build of [`draw_item`] (what the tests compare against).
#[cfg(test)]
pub(crate) fn draw_item_scalar(
    vp: &Viewport,
    band: &mut Band,
    item: &DrawItem,
    cov: Coverage,
    skip: &RowSkip,
    st_setup: &mut RasterStats,
    st: &mut RasterStats,
) -> Result<()> {
    draw_item_impl(vp, band, item, cov, skip, st_setup, st)
}

/// Counts the samples of `item` passing the query test (1 at the first with `any`).
pub(crate) fn query_item(
    vp: &Viewport,
    view: &QueryView,
    item: &DrawItem,
    cov: Coverage,
    any: bool,
    st_setup: &mut RasterStats,
    st: &mut RasterStats,
) -> Result<u64> {
    #[cfg(target_arch = "x86_64")]
    if avx2::available() {
        // SAFETY: `avx2::query_item` only requires AVX2, detected at runtime just now.
        return unsafe { avx2::query_item(vp, view, item, cov, any, st_setup, st) };
    }
    query_item_impl(vp, view, item, cov, any, st_setup, st)
}

/// The portable build of [`query_item`].
#[cfg(test)]
pub(crate) fn query_item_scalar(
    vp: &Viewport,
    view: &QueryView,
    item: &DrawItem,
    cov: Coverage,
    any: bool,
    st_setup: &mut RasterStats,
    st: &mut RasterStats,
) -> Result<u64> {
    query_item_impl(vp, view, item, cov, any, st_setup, st)
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;
    use std::sync::atomic::{AtomicU8, Ordering};

    /// 0 unknown, 1 no, 2 yes.
    static AVX2: AtomicU8 = AtomicU8::new(0);

    #[inline]
    pub(super) fn available() -> bool {
        match AVX2.load(Ordering::Relaxed) {
            2 => true,
            1 => false,
            _ => {
                let yes = std::env::var_os("SHADOWCULL_RASTER_SCALAR").is_none()
                    && std::arch::is_x86_feature_detected!("avx2");
                AVX2.store(if yes { 2 } else { 1 }, Ordering::Relaxed);
                yes
            }
        }
    }

    #[target_feature(enable = "avx2")]
    pub(super) fn draw_item(
        vp: &Viewport,
        band: &mut Band,
        item: &DrawItem,
        cov: Coverage,
        skip: &RowSkip,
        st_setup: &mut RasterStats,
        st: &mut RasterStats,
    ) -> Result<()> {
        draw_item_impl(vp, band, item, cov, skip, st_setup, st)
    }

    #[target_feature(enable = "avx2")]
    pub(super) fn query_item(
        vp: &Viewport,
        view: &QueryView,
        item: &DrawItem,
        cov: Coverage,
        any: bool,
        st_setup: &mut RasterStats,
        st: &mut RasterStats,
    ) -> Result<u64> {
        query_item_impl(vp, view, item, cov, any, st_setup, st)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::depth_target::DepthTarget;
    use crate::{DepthPick, TileSize};
    use glam::{Mat4, Vec4};

    fn band(t: &mut DepthTarget) -> Band<'_> {
        Band {
            layout: t.layout,
            ty0: 0,
            ty1: t.layout.tiles_y,
            depth: &mut t.depth,
            ids: t.ids.as_deref_mut(),
            tiles: &mut t.tiles,
        }
    }

    /// The dispatched (AVX2 when available) and portable builds agree bit for bit.
    #[test]
    fn simd_build_equals_scalar_build() {
        for (ids, tile) in [
            (true, TileSize::T8),
            (false, TileSize::T8),
            (false, TileSize::T4),
            (false, TileSize::T16),
        ] {
            let (w, h) = (77u32, 53u32);
            let vp = Viewport::new(w, h);
            let mut a = DepthTarget::new(w, h, tile, ids).unwrap();
            let mut b = DepthTarget::new(w, h, tile, ids).unwrap();
            let mut s = 0x9e3779b97f4a7c15u64;
            let mut rnd = || {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                (s >> 11) as f32 / (1u64 << 53) as f32 * 2.0 - 1.0
            };
            let (mut sa, mut sb) = (RasterStats::default(), RasterStats::default());
            let (mut ta, mut tb) = (RasterStats::default(), RasterStats::default());
            for k in 0..400u32 {
                // Clip-space triangles, some crossing the near plane (z > w).
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
                    triangles: &[[0, 1, 2]],
                    object: k,
                };
                let skip = RowSkip::new();
                draw_item(&vp, &mut band(&mut a), &item, cov, &skip, &mut sa, &mut ta).unwrap();
                draw_item_scalar(&vp, &mut band(&mut b), &item, cov, &skip, &mut sb, &mut tb)
                    .unwrap();
                let view = QueryView {
                    layout: a.layout,
                    depth: &a.depth,
                    tiles: &a.tiles,
                    receivers: None,
                    receiver_tiles: None,
                };
                let qa = query_item(&vp, &view, &item, cov, false, &mut sa, &mut ta).unwrap();
                let qb =
                    query_item_scalar(&vp, &view, &item, cov, false, &mut sb, &mut tb).unwrap();
                assert_eq!(qa, qb);
            }
            assert_eq!(a.depth, b.depth);
            assert_eq!(a.ids, b.ids);
            assert_eq!((sa, ta), (sb, tb));
        }
    }
}
