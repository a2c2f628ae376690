//! The eye's visible surface ([`EyeSurface`]: per pixel the visible
//! primitive and the rasterized depth), and where a pixel's eye ray meets
//! its visible triangle's plane: the one function the light pass's receiver
//! points, the mask classes, the hybrid's classification and the reference
//! all use, so they agree on every pixel (DESIGN.md "Visible surface").

use glam::DVec3;
use scene::ObjectId;

/// A triangle id: the object and the triangle index in its mesh.
pub type PrimitiveId = (ObjectId, u32);

/// The eye pass's visible surface, when a rasterizer produced one: per pixel
/// (row 0 at the top) the primitive id of the visible triangle, `None` for
/// background, and the rasterized depth when known. The surface point is
/// rebuilt in f64 by intersecting the pixel's eye ray with that triangle's
/// plane. It reads an eye pass's tile-major target in place
/// ([`crate::pipeline::EyePass::surface`]) or row-major buffers
/// ([`EyeSurface::from_rows`]).
#[derive(Clone, Copy, Debug)]
pub struct EyeSurface<'a> {
    source: Source<'a>,
}

#[derive(Clone, Copy, Debug)]
enum Source<'a> {
    Rows {
        width: u32,
        primitive: &'a [Option<PrimitiveId>],
        depth: Option<&'a [f32]>,
    },
    /// A depth target with primitive ids.
    Target(&'a raster::DepthTarget),
}

impl<'a> EyeSurface<'a> {
    /// Row-major buffers `width` pixels wide: the primitive ids and, when
    /// known, the rasterized depth (reversed Z) of the same pixels: the
    /// ambiguity window along the eye ray is widened to twice the distance
    /// between the exact surface point and the rasterized one, since every
    /// stencil decision at the pixel is made against the rasterized depth.
    pub fn from_rows(
        width: u32,
        primitive: &'a [Option<PrimitiveId>],
        depth: Option<&'a [f32]>,
    ) -> Self {
        EyeSurface {
            source: Source::Rows {
                width,
                primitive,
                depth,
            },
        }
    }

    /// The surface of a depth target drawn with primitive ids.
    pub(crate) fn from_target(target: &'a raster::DepthTarget) -> Self {
        EyeSurface {
            source: Source::Target(target),
        }
    }

    /// Whether the surface is `width × height` pixels (its depth too, when
    /// known).
    pub fn fits(&self, width: u32, height: u32) -> bool {
        let n = width as usize * height as usize;
        match self.source {
            Source::Rows {
                width: w,
                primitive,
                depth,
            } => w == width && primitive.len() == n && depth.is_none_or(|d| d.len() == n),
            Source::Target(t) => (t.width(), t.height()) == (width, height),
        }
    }

    /// The number of pixels.
    pub fn len(&self) -> usize {
        match self.source {
            Source::Rows { primitive, .. } => primitive.len(),
            Source::Target(t) => t.width() as usize * t.height() as usize,
        }
    }

    /// Whether the surface has no pixel.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether the rasterized depth is known.
    pub fn has_depth(&self) -> bool {
        match self.source {
            Source::Rows { depth, .. } => depth.is_some(),
            Source::Target(_) => true,
        }
    }

    /// The visible primitive at pixel `(x, y)`.
    ///
    /// # Panics
    /// When `(x, y)` lies outside the surface.
    pub fn primitive(&self, x: u32, y: u32) -> Option<PrimitiveId> {
        match self.source {
            Source::Rows {
                width, primitive, ..
            } => {
                assert!(x < width, "pixel ({x}, {y}) outside the surface");
                primitive[y as usize * width as usize + x as usize]
            }
            Source::Target(t) => t.id_at(x, y).map(|(o, k)| (ObjectId::from_slot(o), k)),
        }
    }

    /// The rasterized depth at pixel `(x, y)` (reversed Z,
    /// [`raster::BACKGROUND`] where nothing was drawn), when known.
    ///
    /// # Panics
    /// When `(x, y)` lies outside the surface.
    pub fn depth(&self, x: u32, y: u32) -> Option<f32> {
        match self.source {
            Source::Rows { width, depth, .. } => {
                assert!(x < width, "pixel ({x}, {y}) outside the surface");
                depth.map(|d| d[y as usize * width as usize + x as usize])
            }
            Source::Target(t) => Some(t.depth_at(x, y).unwrap_or(raster::BACKGROUND)),
        }
    }

    /// Calls `f(x0, x1, primitive)` for every run of pixels `x0..x1` of row
    /// `y` that show one primitive (or none), left to right: what consumers
    /// that decide once per visible triangle read.
    ///
    /// # Panics
    /// When `y` lies outside the surface.
    #[inline]
    pub(crate) fn for_each_run_in_row(
        &self,
        y: u32,
        mut f: impl FnMut(u32, u32, Option<PrimitiveId>),
    ) {
        if let Source::Target(t) = self.source {
            t.for_each_id_run_in_row(y, |x0, x1, id| {
                f(x0, x1, id.map(|(o, k)| (ObjectId::from_slot(o), k)));
            });
            return;
        }
        let mut run: Option<(u32, Option<PrimitiveId>)> = None;
        let mut end = 0;
        self.for_each_in_row(y, |x, p| {
            match run {
                Some((x0, q)) if q != p => {
                    f(x0, x, q);
                    run = Some((x, p));
                }
                None => run = Some((x, p)),
                _ => {}
            }
            end = x + 1;
        });
        if let Some((x0, q)) = run {
            f(x0, end, q);
        }
    }

    /// Calls `f(y, x0, x1, primitive, data)` for every run of pixels
    /// `x0..x1` of rows `rows` (top to bottom) that show one primitive,
    /// skipping pixels that show none, with `data(primitive)`, the per-triangle
    /// work of a consumer. A run that overlaps a run of the row above
    /// showing the same primitive takes that run's `data` instead of calling
    /// `data` again: a triangle a few pixels wide spans several rows, and its
    /// world triangle, plane and facing are found once, not once per row.
    /// `data` must depend on the primitive alone.
    ///
    /// # Panics
    /// When `rows` reaches outside the surface.
    pub(crate) fn for_each_run_in_rows<T: Copy>(
        &self,
        rows: std::ops::Range<u32>,
        scratch: &mut RunRows<T>,
        mut data: impl FnMut(PrimitiveId) -> T,
        mut f: impl FnMut(u32, u32, u32, PrimitiveId, T),
    ) {
        let RunRows { above, here } = scratch;
        above.clear();
        for y in rows {
            here.clear();
            let mut k = 0;
            self.for_each_run_in_row(y, |x0, x1, p| {
                let Some(p) = p else { return };
                // The runs above that end after x0, from the first; those that
                // start before x1 overlap.
                while k < above.len() && above[k].1 <= x0 {
                    k += 1;
                }
                let reuse = above[k..]
                    .iter()
                    .take_while(|r| r.0 < x1)
                    .find(|r| r.2 == p)
                    .map(|r| r.3);
                let d = reuse.unwrap_or_else(|| data(p));
                here.push((x0, x1, p, d));
                f(y, x0, x1, p, d);
            });
            std::mem::swap(above, here);
        }
    }

    /// Calls `f(x, primitive)` for every pixel of row `y`, left to right:
    /// the bulk form of [`EyeSurface::primitive`].
    ///
    /// # Panics
    /// When `y` lies outside the surface.
    #[inline]
    pub fn for_each_in_row(&self, y: u32, mut f: impl FnMut(u32, Option<PrimitiveId>)) {
        match self.source {
            Source::Rows {
                width, primitive, ..
            } => {
                let row = &primitive[y as usize * width as usize..][..width as usize];
                for (x, p) in row.iter().enumerate() {
                    f(x as u32, *p);
                }
            }
            Source::Target(t) => t.for_each_in_row(y, |x, _, id| {
                f(x, id.map(|(o, k)| (ObjectId::from_slot(o), k)));
            }),
        }
    }
}

/// A world triangle's plane seen from a ray origin (the eye), in
/// origin-relative form so that a scene far from the world origin keeps its
/// precision: the ray `origin + t·dir` meets the plane at
/// `t = offset / normal·dir`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RayPlane {
    /// The unnormalized plane normal `(b − a) × (c − a)`.
    pub normal: DVec3,
    /// `normal · (a − origin)`.
    offset: f64,
}

impl RayPlane {
    /// The plane of `tri` (world, f64) for rays from `origin`.
    pub fn new(tri: &[DVec3; 3], origin: DVec3) -> Self {
        let normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
        RayPlane {
            normal,
            offset: normal.dot(tri[0] - origin),
        }
    }

    /// The ray parameter at which `origin + t·dir` meets the plane, `None`
    /// when the ray is parallel to it (or the triangle is degenerate).
    pub fn hit(&self, dir: DVec3) -> Option<f64> {
        let den = self.normal.dot(dir);
        (den != 0.0).then(|| self.offset / den)
    }

    /// The point where the ray meets the plane; the origin itself when the
    /// ray is parallel (the mask assembly's and the light pass's rule).
    pub fn point_or_origin(&self, origin: DVec3, dir: DVec3) -> DVec3 {
        origin + dir * self.hit(dir).unwrap_or(0.0)
    }
}

/// The runs of the last two rows of [`EyeSurface::for_each_run_in_rows`]
/// (reused from call to call): `(x0, x1, primitive, data)`.
#[derive(Debug)]
pub(crate) struct RunRows<T> {
    above: Vec<(u32, u32, PrimitiveId, T)>,
    here: Vec<(u32, u32, PrimitiveId, T)>,
}

impl<T> Default for RunRows<T> {
    fn default() -> Self {
        RunRows {
            above: Vec::new(),
            here: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_the_plane_and_reports_parallel_rays() {
        let tri = [
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 1.0),
        ];
        let o = DVec3::new(0.3, 5.0, 0.2);
        let p = RayPlane::new(&tri, o);
        let d = DVec3::new(0.1, -2.0, 0.05);
        let t = p.hit(d).unwrap();
        assert!(((o + d * t).y - 1.0).abs() < 1e-12);
        assert_eq!(p.hit(DVec3::X), None);
        assert_eq!(p.point_or_origin(o, DVec3::X), o);
    }

    /// The runs of rows `rows` by the definition: maximal runs of one
    /// primitive, pixels showing none skipped.
    fn naive_runs(w: u32, ids: &[Option<PrimitiveId>]) -> Vec<(u32, u32, u32, PrimitiveId)> {
        let mut out = Vec::new();
        for (y, row) in ids.chunks(w as usize).enumerate() {
            let mut x = 0;
            while x < row.len() {
                let end = x + row[x..].iter().take_while(|p| **p == row[x]).count();
                if let Some(p) = row[x] {
                    out.push((y as u32, x as u32, end as u32, p));
                }
                x = end;
            }
        }
        out
    }

    proptest::proptest! {
        /// The runs are the maximal runs of one primitive, each with its
        /// primitive's data; a triangle that continues from the row above
        /// keeps its data without another call.
        #[test]
        fn runs_of_rows_carry_their_primitives_data(
            w in 1u32..12,
            cells in proptest::collection::vec(proptest::option::weighted(0.8, 0u32..4), 1..120),
        ) {
            let h = (cells.len() as u32).div_ceil(w);
            let mut ids: Vec<Option<PrimitiveId>> =
                cells.iter().map(|c| c.map(|k| (ObjectId::from_slot(k % 2), k))).collect();
            ids.resize((w * h) as usize, None);
            let surface = EyeSurface::from_rows(w, &ids, None);
            let mut calls = 0;
            let mut got = Vec::new();
            let mut scratch = RunRows::default();
            surface.for_each_run_in_rows(
                0..h,
                &mut scratch,
                |p: PrimitiveId| {
                    calls += 1;
                    p.1 * 10 + p.0 .slot()
                },
                |y, x0, x1, p, d| got.push((y, x0, x1, p, d)),
            );
            let want = naive_runs(w, &ids);
            proptest::prop_assert_eq!(got.len(), want.len());
            for (g, n) in got.iter().zip(&want) {
                proptest::prop_assert_eq!((g.0, g.1, g.2, g.3), *n);
                proptest::prop_assert_eq!(g.4, g.3 .1 * 10 + g.3 .0 .slot());
            }
            // Calls: one per run that overlaps no run of the same primitive above.
            let fresh = want
                .iter()
                .filter(|r| {
                    !want.iter().any(|a| {
                        a.0 + 1 == r.0 && a.3 == r.3 && a.1 < r.2 && r.1 < a.2
                    })
                })
                .count();
            proptest::prop_assert_eq!(calls, fresh);
        }
    }
}
