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
            Source::Target(t) => t.id_at(x, y).map(|(o, k)| (ObjectId(o), k)),
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

    /// Calls `f(x, primitive)` for every pixel of row `y`, left to right:
    /// the bulk form of [`EyeSurface::primitive`].
    ///
    /// # Panics
    /// When `y` lies outside the surface.
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
                f(x, id.map(|(o, k)| (ObjectId(o), k)));
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
}
