//! The tile-major layout of a target's pixels, each tile's hierarchical-z
//! bounds [Greene et al. 1993], and bands of tile rows (the unit of parallel
//! drawing): the address arithmetic every pass shares.

/// Depth value of a background (never written) pixel.
pub const BACKGROUND: f32 = -1.0;

/// Tile edge length in pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum TileSize {
    /// 4×4 tiles.
    T4,
    /// 8×8 tiles (the default).
    #[default]
    T8,
    /// 16×16 tiles.
    T16,
}

impl TileSize {
    /// Edge length in pixels.
    pub fn pixels(self) -> u32 {
        1 << self.shift()
    }

    pub(crate) fn shift(self) -> u32 {
        match self {
            TileSize::T4 => 2,
            TileSize::T8 => 3,
            TileSize::T16 => 4,
        }
    }
}

/// Hierarchical-z bounds of one tile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct TileBounds {
    /// Smallest written depth (+∞ when none).
    pub zmin: f32,
    /// Largest written depth ([`BACKGROUND`] when none).
    pub zmax: f32,
    /// In-target pixels still background.
    pub background: u32,
}

impl TileBounds {
    /// Lower bound of every pixel's stored value, background included.
    #[inline]
    pub fn zmin_all(&self) -> f32 {
        if self.background > 0 {
            BACKGROUND
        } else {
            self.zmin
        }
    }
}

/// Address arithmetic of the tile-major layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Layout {
    pub width: u32,
    pub height: u32,
    pub tiles_x: u32,
    pub tiles_y: u32,
    pub shift: u32,
}

impl Layout {
    #[inline(always)]
    pub fn tile_pixels(&self) -> usize {
        1 << (2 * self.shift)
    }

    /// Index of tile `(tx, ty)`.
    #[inline(always)]
    pub fn tile_index(&self, tx: u32, ty: u32) -> usize {
        (ty * self.tiles_x + tx) as usize
    }

    /// Index of pixel `(x, y)` in the tile-major buffers.
    #[inline(always)]
    pub fn pixel_index(&self, x: u32, y: u32) -> usize {
        let t = self.tile_index(x >> self.shift, y >> self.shift);
        let m = (1 << self.shift) - 1;
        (t << (2 * self.shift)) + (((y & m) << self.shift) + (x & m)) as usize
    }

    /// Inclusive in-target pixel range of tile `(tx, ty)`.
    #[inline(always)]
    pub fn tile_rect(&self, tx: u32, ty: u32) -> (u32, u32, u32, u32) {
        let s = 1 << self.shift;
        let x0 = tx * s;
        let y0 = ty * s;
        (
            x0,
            (x0 + s).min(self.width) - 1,
            y0,
            (y0 + s).min(self.height) - 1,
        )
    }

    /// Pixels inside the target in tile `t` (row-major tile index).
    #[inline(always)]
    pub fn tile_area(&self, t: usize) -> u32 {
        let (x0, x1, y0, y1) = self.tile_rect(t as u32 % self.tiles_x, t as u32 / self.tiles_x);
        (x1 - x0 + 1) * (y1 - y0 + 1)
    }
}

/// Bounds of the first `w` pixels of each row of width `T` in `rows`: fixed-width,
/// branch-free loops (plain selects; depths are never NaN) that vectorize.
#[inline(always)]
pub(crate) fn tile_bounds<const T: usize>(rows: &[f32], w: usize) -> TileBounds {
    // A whole-width tile: the same loop with every lane valid (a constant
    // the compiler folds).
    if w == T {
        tile_bounds_of::<T>(rows, T)
    } else {
        tile_bounds_of::<T>(rows, w)
    }
}

#[inline(always)]
fn tile_bounds_of<const T: usize>(rows: &[f32], w: usize) -> TileBounds {
    let mut zmin = [f32::INFINITY; T];
    let mut zmax = [BACKGROUND; T];
    let mut bg = [0u32; T];
    for row in rows.chunks_exact(T) {
        for k in 0..T {
            let d = row[k];
            let valid = k < w;
            let is_bg = d == BACKGROUND;
            bg[k] += u32::from(valid & is_bg);
            let take = valid & !is_bg;
            zmin[k] = if take && d < zmin[k] { d } else { zmin[k] };
            zmax[k] = if take && d > zmax[k] { d } else { zmax[k] };
        }
    }
    TileBounds {
        zmin: zmin.iter().fold(f32::INFINITY, |m, &v| m.min(v)),
        zmax: zmax.iter().fold(BACKGROUND, |m, &v| m.max(v)),
        background: bg.iter().sum(),
    }
}

/// Mutable access to the tile rows `ty0..ty1` of a target (one parallel bin).
pub(crate) struct TileRows<'a> {
    pub layout: Layout,
    pub ty0: u32,
    pub ty1: u32,
    pub depth: &'a mut [f32],
    pub ids: Option<&'a mut [u64]>,
    pub tiles: &'a mut [TileBounds],
}

impl<'a> TileRows<'a> {
    /// Tile rows `ty0..ty1` of a target's whole tile-major buffers.
    pub fn of(
        layout: Layout,
        (ty0, ty1): (u32, u32),
        depth: &'a mut [f32],
        ids: Option<&'a mut [u64]>,
        tiles: &'a mut [TileBounds],
    ) -> Self {
        let px = layout.tile_pixels();
        let (t0, t1) = (
            (ty0 * layout.tiles_x) as usize,
            (ty1 * layout.tiles_x) as usize,
        );
        TileRows {
            layout,
            ty0,
            ty1,
            depth: &mut depth[t0 * px..t1 * px],
            ids: ids.map(|ids| &mut ids[t0 * px..t1 * px]),
            tiles: &mut tiles[t0..t1],
        }
    }

    /// The rows before tile row `ty` and those from it on (`ty` within
    /// the rows).
    #[cfg(feature = "parallel")]
    pub fn split_at(self, ty: u32) -> (TileRows<'a>, TileRows<'a>) {
        debug_assert!((self.ty0..=self.ty1).contains(&ty));
        let n = ((ty - self.ty0) * self.layout.tiles_x) as usize;
        let px = n * self.layout.tile_pixels();
        let (d0, d1) = self.depth.split_at_mut(px);
        let (t0, t1) = self.tiles.split_at_mut(n);
        let (i0, i1) = match self.ids {
            Some(ids) => {
                let (a, b) = ids.split_at_mut(px);
                (Some(a), Some(b))
            }
            None => (None, None),
        };
        let lo = TileRows {
            layout: self.layout,
            ty0: self.ty0,
            ty1: ty,
            depth: d0,
            ids: i0,
            tiles: t0,
        };
        let hi = TileRows {
            layout: self.layout,
            ty0: ty,
            ty1: self.ty1,
            depth: d1,
            ids: i1,
            tiles: t1,
        };
        (lo, hi)
    }
}

impl TileRows<'_> {
    /// Offset of this band's first tile in the whole target.
    #[inline(always)]
    pub fn tile_base(&self) -> usize {
        (self.ty0 * self.layout.tiles_x) as usize
    }

    /// Recomputes the bounds of tile `(tx, ty)` from its pixels.
    pub fn refresh_tile(&mut self, tx: u32, ty: u32) {
        let l = self.layout;
        let t = l.tile_index(tx, ty) - self.tile_base();
        let (x0, x1, y0, y1) = l.tile_rect(tx, ty);
        let base = t * l.tile_pixels();
        let (w, h) = ((x1 - x0 + 1) as usize, (y1 - y0 + 1) as usize);
        let pixels = &self.depth[base..base + (h << l.shift)];
        self.tiles[t] = match l.shift {
            2 => tile_bounds::<4>(pixels, w),
            3 => tile_bounds::<8>(pixels, w),
            _ => tile_bounds::<16>(pixels, w),
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The vectorized tile scan equals the plain definition, for partial
    /// widths, background pixels and every tile size.
    #[test]
    fn tile_bounds_match_a_plain_scan() {
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 40) as f32 / (1u64 << 24) as f32
        };
        for t in [4usize, 8, 16] {
            for _ in 0..200 {
                let w = 1 + (rnd() * t as f32) as usize % t;
                let h = 1 + (rnd() * t as f32) as usize % t;
                let px: Vec<f32> = (0..h * t)
                    .map(|_| if rnd() < 0.3 { BACKGROUND } else { rnd() })
                    .collect();
                let (mut zmin, mut zmax, mut bg) = (f32::INFINITY, BACKGROUND, 0);
                for y in 0..h {
                    for &d in &px[y * t..y * t + w] {
                        if d == BACKGROUND {
                            bg += 1;
                        } else {
                            zmin = zmin.min(d);
                            zmax = zmax.max(d);
                        }
                    }
                }
                let got = match t {
                    4 => tile_bounds::<4>(&px, w),
                    8 => tile_bounds::<8>(&px, w),
                    _ => tile_bounds::<16>(&px, w),
                };
                assert_eq!(
                    got,
                    TileBounds {
                        zmin,
                        zmax,
                        background: bg
                    }
                );
            }
        }
    }
}
