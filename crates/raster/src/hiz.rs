//! Whole-mesh hierarchical-z culling [Greene et al. 1993]: a mesh whose vertices
//! all lie in front of the near plane covers only pixels inside the bounding
//! rectangle of their projections, at depths no nearer than the nearest vertex
//! (depth along a triangle is a convex combination of its vertex depths). When
//! every tile under that rectangle already holds only strictly nearer depths, no
//! sample of the mesh can pass GREATER or GEQUAL, so it is skipped without setup.

use crate::coverage::f32_up;
use crate::layout::{Layout, TileBounds};
use crate::setup::{transform_lanes, widen, Lanes, Wide, CACHE_VERTICES};
use glam::{Mat4, Vec4};

/// Pixel margin added around the projected rectangle: covers snapping (1/512 px),
/// outer-conservative coverage (1 px) and rounding, with room to spare.
const MARGIN_PX: f64 = 2.0;

/// Screen rectangle (inclusive pixel range, clamped) and nearest depth of a mesh.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ScreenBounds {
    pub x0: u32,
    pub x1: u32,
    pub y0: u32,
    pub y1: u32,
    /// At least as near as every depth the mesh can produce.
    pub zmax: f32,
}

/// Outcome of projecting a mesh's vertices.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Projected {
    /// Some vertex is not strictly in front of the near plane: no shortcut.
    Unknown,
    /// The mesh cannot cover any pixel of the target.
    Offscreen,
    /// Bounds of what it can cover.
    Bounds(ScreenBounds),
}

/// Projects `positions` with `clip_from_local` exactly as setup does (f32 product,
/// f64 division).
#[inline(always)]
pub(crate) fn project(m: &Mat4, positions: &[Vec4], width: u32, height: u32) -> Projected {
    let mut acc = Acc::new(width, height);
    for chunk in positions.chunks(LANES) {
        // Short chunks repeat their first vertex, which changes no bound, outcode or
        // flag.
        let n = chunk.len();
        acc.add(&widen(&transform_lanes(m, |k| {
            chunk[if k < n { k } else { 0 }]
        })));
    }
    acc.finish(positions.len(), width, height)
}

/// [`project`] of the `count` clip-space vertices of `lanes` (lanes from `count`
/// on repeat a vertex).
#[inline(always)]
pub(crate) fn project_lanes(lanes: &Lanes, count: usize, width: u32, height: u32) -> Projected {
    project_wide(&widen(lanes), count, width, height)
}

/// [`project_lanes`] of lanes already widened to f64 ([`widen`]).
#[inline(always)]
pub(crate) fn project_wide(wide: &Wide, count: usize, width: u32, height: u32) -> Projected {
    let mut acc = Acc::new(width, height);
    acc.add(wide);
    acc.finish(count, width, height)
}

/// Vertices processed together, lane by lane (vectorized by the compiler).
const LANES: usize = CACHE_VERTICES;

/// Running bounds of projected vertices.
struct Acc {
    /// Side-plane factors, pushed out by the margin.
    gx: f64,
    gy: f64,
    xmin: f64,
    xmax: f64,
    ymin: f64,
    ymax: f64,
    zmax: f64,
    unknown: bool,
    /// Bit k set: every vertex so far is strictly outside frustum plane k.
    all_out: u32,
}

impl Acc {
    #[inline(always)]
    fn new(width: u32, height: u32) -> Self {
        Acc {
            gx: 1.0 + 2.0 * MARGIN_PX / width as f64,
            gy: 1.0 + 2.0 * MARGIN_PX / height as f64,
            xmin: f64::INFINITY,
            xmax: f64::NEG_INFINITY,
            ymin: f64::INFINITY,
            ymax: f64::NEG_INFINITY,
            zmax: 0.0,
            unknown: false,
            all_out: 0x3f,
        }
    }

    /// Adds eight clip-space vertices. Side planes are pushed out by the margin,
    /// so that snapping and outer-conservative coverage at the viewport border
    /// cannot matter.
    #[inline(always)]
    fn add(&mut self, clip: &Wide) {
        let (gx, gy) = (self.gx, self.gy);
        let [x, y, z, w] = clip;
        // Per lane, with non-short-circuit operators and plain selects (a NaN never
        // wins, like `f64::min`), so the compiler vectorizes across vertices.
        let mut out = [0u32; LANES];
        let mut unknown = [false; LANES];
        let (mut xmin, mut xmax) = ([f64::INFINITY; LANES], [f64::NEG_INFINITY; LANES]);
        let (mut ymin, mut ymax) = ([f64::INFINITY; LANES], [f64::NEG_INFINITY; LANES]);
        let mut zmax = [0f64; LANES];
        for k in 0..LANES {
            let (x, y, z, w) = (x[k], y[k], z[k], w[k]);
            out[k] = u32::from(w - z < 0.0)
                | u32::from(z < 0.0) << 1
                | u32::from(gx * w + x < 0.0) << 2
                | u32::from(gx * w - x < 0.0) << 3
                | u32::from(gy * w + y < 0.0) << 4
                | u32::from(gy * w - y < 0.0) << 5;
            // Strictly inside near and far planes, w clearly positive; otherwise the
            // bounds are not used.
            unknown[k] = w.is_nan() | (w <= 0.0) | (z > w * (1.0 - 1e-6)) | (z < 0.0);
            // One division; the product differs from x / w by at most an ulp
            // (covered by the margins).
            let iw = 1.0 / w;
            let (sx, sy, sz) = (x * iw, y * iw, z * iw);
            xmin[k] = if sx < xmin[k] { sx } else { xmin[k] };
            xmax[k] = if sx > xmax[k] { sx } else { xmax[k] };
            ymin[k] = if sy < ymin[k] { sy } else { ymin[k] };
            ymax[k] = if sy > ymax[k] { sy } else { ymax[k] };
            zmax[k] = if sz > zmax[k] { sz } else { zmax[k] };
        }
        for k in 0..LANES {
            self.all_out &= out[k];
            self.unknown |= unknown[k];
            self.xmin = if xmin[k] < self.xmin {
                xmin[k]
            } else {
                self.xmin
            };
            self.xmax = if xmax[k] > self.xmax {
                xmax[k]
            } else {
                self.xmax
            };
            self.ymin = if ymin[k] < self.ymin {
                ymin[k]
            } else {
                self.ymin
            };
            self.ymax = if ymax[k] > self.ymax {
                ymax[k]
            } else {
                self.ymax
            };
            self.zmax = if zmax[k] > self.zmax {
                zmax[k]
            } else {
                self.zmax
            };
        }
    }

    #[inline(always)]
    fn finish(&self, count: usize, width: u32, height: u32) -> Projected {
        // All vertices outside one frustum plane: so is their convex hull
        // (homogeneous clipping would remove every triangle).
        if count == 0 || self.all_out != 0 {
            return Projected::Offscreen;
        }
        if self.unknown {
            return Projected::Unknown;
        }
        let (w, h) = (width as f64, height as f64);
        let px0 = ((self.xmin + 1.0) * 0.5 * w - MARGIN_PX).floor();
        let px1 = ((self.xmax + 1.0) * 0.5 * w + MARGIN_PX).floor();
        let py0 = ((1.0 - self.ymax) * 0.5 * h - MARGIN_PX).floor();
        let py1 = ((1.0 - self.ymin) * 0.5 * h + MARGIN_PX).floor();
        if !(px0.is_finite() && px1.is_finite() && py0.is_finite() && py1.is_finite()) {
            return Projected::Unknown;
        }
        if px1 < 0.0 || py1 < 0.0 || px0 > w - 1.0 || py0 > h - 1.0 {
            return Projected::Offscreen;
        }
        Projected::Bounds(ScreenBounds {
            x0: px0.max(0.0) as u32,
            x1: px1.min(w - 1.0) as u32,
            y0: py0.max(0.0) as u32,
            y1: py1.min(h - 1.0) as u32,
            // (1e-12 ≫ the few f64 ulps by which setup's z / w can differ.)
            zmax: f32_up(self.zmax * (1.0 + 1e-12)),
        })
    }
}

/// Whether every tile of the tile rows `ty0..ty1` under `b` holds only depths
/// strictly nearer than `b.zmax` (background counts as farthest). `tiles` holds the
/// bounds of those rows, starting at row `ty0`.
#[inline(always)]
pub(crate) fn hidden(
    l: &Layout,
    tiles: &[TileBounds],
    ty0: u32,
    ty1: u32,
    b: &ScreenBounds,
) -> bool {
    let (tx0, tx1, r0, r1) = row_span(l, ty0, ty1, b);
    (r0..r1 + 1).all(|ty| row_hidden(l, tiles, ty0, ty, tx0, tx1, b.zmax))
}

/// The tile columns `tx0..=tx1` and rows `r0..=r1` under `b`, rows limited to
/// `ty0..ty1` (empty when `r1 < r0`).
#[inline(always)]
fn row_span(l: &Layout, ty0: u32, ty1: u32, b: &ScreenBounds) -> (u32, u32, u32, u32) {
    let s = l.shift;
    let (r0, r1) = ((b.y0 >> s).max(ty0), (b.y1 >> s).min(ty1.saturating_sub(1)));
    (b.x0 >> s, b.x1 >> s, r0, r1)
}

/// Whether every tile `tx0..=tx1` of tile row `ty` (bounds in `tiles`, which
/// start at row `ty0`) holds only depths strictly nearer than `zmax`.
#[inline(always)]
fn row_hidden(
    l: &Layout,
    tiles: &[TileBounds],
    ty0: u32,
    ty: u32,
    tx0: u32,
    tx1: u32,
    zmax: f32,
) -> bool {
    let row = ((ty - ty0) * l.tiles_x) as usize;
    tiles[row + tx0 as usize..=row + tx1 as usize]
        .iter()
        .all(|t| zmax < t.zmin_all())
}

/// Most tile rows a target can have (16384 pixels in 4-pixel tiles).
const MAX_TILE_ROWS: usize = 4096;

/// The tile rows of one mesh's screen rectangle that are hidden when the mesh
/// starts (every tile under the rectangle in that row strictly nearer than the
/// mesh's nearest depth); traversal of the mesh's triangles skips them.
///
/// A row's state when a mesh starts depends only on the meshes drawn before it
/// into that row, in submission order, so the rows skipped — and the tiles
/// counted — are the same for the serial path and for any split into bands.
#[derive(Clone, Debug)]
pub(crate) struct RowSkip {
    /// First and last tile row of the rectangle (`r1 < r0`: no rows skipped).
    r0: u32,
    r1: u32,
    bits: [u64; MAX_TILE_ROWS / 64],
}

impl RowSkip {
    /// Skips nothing.
    pub fn new() -> Self {
        RowSkip {
            r0: 1,
            r1: 0,
            bits: [0; MAX_TILE_ROWS / 64],
        }
    }

    /// Skips nothing (for meshes without screen bounds).
    #[inline]
    pub fn reset(&mut self) {
        self.r0 = 1;
        self.r1 = 0;
    }

    /// Marks the hidden rows of `b` among tile rows `ty0..ty1` (whose bounds `tiles`
    /// holds, starting at row `ty0`); true when every such row is hidden (the mesh
    /// can be skipped in these rows).
    #[inline(always)]
    pub fn compute(
        &mut self,
        l: &Layout,
        tiles: &[TileBounds],
        ty0: u32,
        ty1: u32,
        b: &ScreenBounds,
    ) -> bool {
        let (tx0, tx1, r0, r1) = row_span(l, ty0, ty1, b);
        self.r0 = r0;
        self.r1 = r1;
        let mut all = true;
        if r1 < r0 {
            return true;
        }
        let words = ((r1 - r0) / 64 + 1) as usize;
        if words == 1 {
            self.bits[0] = 0;
        } else {
            self.bits[..words].fill(0);
        }
        for ty in r0..r1 + 1 {
            let hid = row_hidden(l, tiles, ty0, ty, tx0, tx1, b.zmax);
            all &= hid;
            let k = (ty - r0) as usize;
            self.bits[k / 64] |= u64::from(hid) << (k % 64);
        }
        all
    }

    /// Whether tile row `ty` is skipped.
    #[inline(always)]
    pub fn hides(&self, ty: u32) -> bool {
        if ty < self.r0 || ty > self.r1 {
            return false;
        }
        let k = (ty - self.r0) as usize;
        self.bits[k / 64] >> (k % 64) & 1 != 0
    }
}
