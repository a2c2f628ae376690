//! The hybrid's shadow maps taken from the light pass's own light views
//! [ChanDurand04 abstract; Steiner §4.3.3]: the views are fitted to the
//! intersection body B, which holds every visible receiver point, and after
//! the pass their depth holds the casting triangles of every object the
//! traversal found visible. Those are all the casters that can shadow a
//! visible receiver: an object the traversal culled covers no receiver
//! pixel in front of its receiver, or only pixels where drawn casters cover
//! it from the light, and these shadow the receiver there themselves. So no
//! map is rendered for the hybrid: it reads the views ([`ViewMaps`]).
//!
//! # Reading a view as a map
//! A view is any world → clip matrix (off-centre windows, cube faces,
//! orthographic), with reversed depth: greater is nearer the light
//! (`visibility::light_view`'s conventions). The classification is
//! [`super::classify_point`]'s, in the view's own depth units:
//! - the point's 2×2 texel footprint must lie in the view (for a cube, in
//!   the face of the dominant axis of `p − l`, whose receivers were surely
//!   marked and so whose rows around the point were drawn), else the point
//!   is a silhouette point;
//! - the receiver plane is taken to clip space (`M⁻ᵀ · plane`), where it is
//!   a plane again, so its depth at a texel centre is
//!   `z = −(P.x·nx + P.y·ny + P.w) / P.z` — the receiver-plane depth of
//!   the module docs, exact, per texel, without a ray;
//! - a texel is shadowed when its stored depth is greater (nearer) than the
//!   plane's by more than the bias: [`DEPTH_BIAS_REL`] of the depth
//!   (perspective: depth ∝ 1 / distance, so a relative bias is one in
//!   distance) or of the whole range (orthographic), plus
//!   [`SLOPE_BIAS_TEXELS`] of the plane's largest depth step between
//!   footprint texels;
//! - where a footprint texel's plane depth differs from the point's by more
//!   than `GRAZING_TEXELS` texel footprints (relative to the depth for
//!   perspective views, whose depth steps scale with it) the light grazes
//!   the receiver: silhouette.
//!
//! The pipeline reads point-sampled light views only (`coverage: point`):
//! their casters are sampled at texel centres, an ordinary shadow map.
//! Conservative views draw each triangle inner-conservative, so a texel
//! holds a caster only where one triangle covers all of it: the texels
//! along a box's roof diagonal, along the fold between roof and wall, and
//! most of the thin strip a wall seen steeply from the light projects to
//! stay empty, holes inside its shadow that a 2×2 footprint (or a 4×4 one)
//! reads as lit. On city street with the point light that gave 6,475
//! pixels off the shadow boundaries, against 158 with point-sampled views.

use super::bias::{DEPTH_BIAS_REL, GRAZING_TEXELS, SLOPE_BIAS_TEXELS};
use super::cube_face::dominant_face;
use crate::Result;
use glam::{DMat4, DVec3, DVec4};
use raster::DepthTarget;
use scene::Light;
use visibility::{LightView, LightViewKind};

/// One light view's depth read as a shadow map.
struct ViewMap<'a> {
    clip_from_world: DMat4,
    /// `clip_from_world⁻ᵀ`: world planes to clip planes.
    plane_to_clip: DMat4,
    target: &'a DepthTarget,
    /// Side in texels.
    n: f64,
    perspective: bool,
    /// Largest depth step from the point to a footprint texel's plane depth
    /// before the receiver counts as grazing (relative to the point's depth
    /// for perspective views).
    graze: f64,
}

/// What a view says about a point.
enum Lookup {
    /// The footprint is not (wholly) in the view: ask another.
    Outside,
    /// The view decides: `Some(shadowed)`, or `None` for silhouette.
    Inside(Option<bool>),
}

impl<'a> ViewMap<'a> {
    fn new(view: &LightView, target: &'a DepthTarget) -> Result<Self> {
        let r = view.resolution;
        if (target.width(), target.height()) != (r, r) {
            return Err(raster::Error::MaskLength {
                expected: r as usize * r as usize,
                got: target.width() as usize * target.height() as usize,
                width: r,
                height: r,
            }
            .into());
        }
        let m = view.clip_from_world;
        let n = f64::from(r);
        // A texel's side per unit distance (perspective) or in world units
        // (orthographic): 2 / (n · the window's scale).
        let scale = m
            .row(0)
            .truncate()
            .length()
            .min(m.row(1).truncate().length());
        let texel = 2.0 / (n * scale);
        let perspective = view.kind != LightViewKind::Ortho;
        let graze = if perspective {
            GRAZING_TEXELS * texel
        } else {
            // Depth per world unit along the light.
            GRAZING_TEXELS * texel * m.row(2).truncate().length()
        };
        Ok(ViewMap {
            clip_from_world: m,
            plane_to_clip: m.inverse().transpose(),
            target,
            n,
            perspective,
            graze,
        })
    }

    /// Depth of the clip-space plane `pc` at texel centre `(i, j)`.
    fn plane_depth(&self, pc: DVec4, i: u32, j: u32) -> f64 {
        let nx = 2.0 * (f64::from(i) + 0.5) / self.n - 1.0;
        let ny = 1.0 - 2.0 * (f64::from(j) + 0.5) / self.n;
        -(pc.x * nx + pc.y * ny + pc.w) / pc.z
    }

    fn lookup(&self, p: DVec3, plane: DVec4) -> Lookup {
        let c = self.clip_from_world * p.extend(1.0);
        // In the frustum beyond the near plane (NaN fails every test).
        let inside = c.w > 0.0 && c.x.abs() <= c.w && c.y.abs() <= c.w && c.z >= 0.0 && c.z <= c.w;
        if !inside {
            return Lookup::Outside;
        }
        let u = (c.x / c.w + 1.0) * 0.5 * self.n;
        let v = (1.0 - c.y / c.w) * 0.5 * self.n;
        let (i0, j0) = ((u - 0.5).floor(), (v - 0.5).floor());
        if !(i0 >= 0.0 && j0 >= 0.0 && i0 + 1.0 < self.n && j0 + 1.0 < self.n) {
            return Lookup::Outside;
        }
        let (i0, j0) = (i0 as u32, j0 as u32);
        let pc = self.plane_to_clip * plane;
        let zp = c.z / c.w;
        let limit = if self.perspective {
            self.graze * zp
        } else {
            self.graze
        };
        let mut z = [0.0f64; 4];
        for (k, zk) in z.iter_mut().enumerate() {
            let d = self.plane_depth(pc, i0 + (k as u32 & 1), j0 + (k as u32 >> 1));
            // A plane along the rays, behind the light, or grazed.
            let ahead = d > 0.0 || !self.perspective;
            if !(d.is_finite() && ahead) || (d - zp).abs() > limit {
                return Lookup::Inside(None);
            }
            *zk = d;
        }
        let slope = [(0, 1), (2, 3), (0, 2), (1, 3)]
            .iter()
            .map(|&(a, b)| (z[a] - z[b]).abs())
            .fold(0.0f64, f64::max);
        let mut answer = None;
        for (k, &zk) in z.iter().enumerate() {
            let scale = if self.perspective { zk } else { 1.0 };
            let bias = DEPTH_BIAS_REL * scale + SLOPE_BIAS_TEXELS * slope;
            let s = self
                .target
                .depth_at(i0 + (k as u32 & 1), j0 + (k as u32 >> 1))
                .is_some_and(|zm| f64::from(zm) > zk + bias);
            match answer {
                None => answer = Some(s),
                Some(prev) if prev != s => return Lookup::Inside(None),
                _ => {}
            }
        }
        Lookup::Inside(answer)
    }
}

/// The light views of one light's pass, read as its shadow maps.
pub(super) struct ViewMaps<'a> {
    maps: Vec<ViewMap<'a>>,
    /// Per cube face (+X, −X, +Y, −Y, +Z, −Z), its index in `maps`.
    faces: [Option<usize>; 6],
    /// The light's position (cube faces).
    light: DVec3,
}

impl<'a> ViewMaps<'a> {
    /// The maps of `views` (each with its kept depth) of `light`.
    ///
    /// # Errors
    /// [`crate::Error::Raster`] for a target that is not its view's size.
    pub(super) fn new(views: &[(&LightView, &'a DepthTarget)], light: &Light) -> Result<Self> {
        let mut faces = [None; 6];
        for (k, (v, _)) in views.iter().enumerate() {
            if let LightViewKind::CubeFace(f) = v.kind {
                faces[usize::from(f).min(5)] = Some(k);
            }
        }
        Ok(ViewMaps {
            maps: views
                .iter()
                .map(|&(v, t)| ViewMap::new(v, t))
                .collect::<Result<_>>()?,
            faces,
            light: light.position().unwrap_or(DVec3::ZERO),
        })
    }

    /// The maps' answer for surface point `p` on the plane through `a` with
    /// normal `nrm`: `Some(shadowed)` when the footprint's four texels agree,
    /// `None` for a silhouette point (disagreement, grazing, or in no view).
    pub(super) fn classify(&self, p: DVec3, a: DVec3, nrm: DVec3) -> Option<bool> {
        let plane = nrm.extend(-nrm.dot(a));
        let map = if self.faces.iter().any(Option::is_some) {
            // Only the dominant axis's face: its receivers were surely
            // marked, so its rows around the point were drawn (a neighbour
            // face's need not be).
            self.faces[dominant_face(p - self.light)]
        } else {
            // One view (perspective or orthographic).
            (self.maps.len() == 1).then_some(0)
        };
        match map.map(|k| self.maps[k].lookup(p, plane)) {
            Some(Lookup::Inside(answer)) => answer,
            _ => None,
        }
    }
}
