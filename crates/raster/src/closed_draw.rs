//! Closed occluders drawn whole: a closed mesh (convex or not), as the
//! union of its front faces, inner-conservative at the farthest depth,
//! without the cracks per-triangle inner coverage leaves along shared
//! edges (see `convex_draw.rs`).
//!
//! Seen from outside (every vertex in front of the near plane), a closed
//! mesh's silhouette is bounded by its silhouette edges, those between a
//! face turned toward the eye and one turned away. A pixel square that a
//! front face meets and that no silhouette edge meets lies wholly inside
//! the silhouette: it holds a point of it, and its boundary nowhere. There
//! the visible surface is made of the front faces meeting the square, so
//! it is no nearer than the least of their farthest depths over it (each
//! bounded as [`crate::DepthPick::Farthest`] bounds it: the plane's least
//! over the square's corners, and the least over the face's part in the
//! pixel's row). Edges met by other than two faces count as silhouette.

use crate::band_extent::{band_clip, band_extent};
use crate::depth_plane::DepthPlane;
use crate::depth_target::DepthTarget;
use crate::item::DrawItem;
use crate::setup::facing_f64;
use crate::whole_draw::{snap_slack, to_f32_below, ClosedScratch, HULL_MARGIN_PX};

/// Widening of a silhouette edge's footprint, in pixels: as a convex
/// draw's hull margin (rounding, and snapping at this resolution or a
/// finer one).
const EDGE_MARGIN_PX: f64 = HULL_MARGIN_PX;

impl DepthTarget {
    /// Draws the closed mesh of `item` as one occluder: every pixel whose
    /// closed square lies inside its silhouette, at a depth no nearer than
    /// its visible surface over the square (GREATER test, ties to the
    /// smaller id; the id written is `(object, 0)`). Its front faces are the
    /// ones `item.cull` keeps, which must be [`crate::CullMode::Back`] or
    /// [`crate::CullMode::Front`] (the eye's culling of a closed mesh seen
    /// from outside). Returns `false`, drawing nothing, for
    /// [`crate::CullMode::None`], or when some vertex is not strictly in
    /// front of the near plane (or not finite): the caller draws the
    /// triangles instead.
    pub fn draw_closed(&mut self, item: &DrawItem) -> bool {
        if item.cull == crate::CullMode::None {
            return false;
        }
        let mut s = std::mem::take(&mut self.closed);
        let drawn = self.draw_closed_with(item, &mut s);
        self.closed = s;
        drawn
    }

    fn draw_closed_with(&mut self, item: &DrawItem, s: &mut ClosedScratch) -> bool {
        let (w, h) = (f64::from(self.width()), f64::from(self.height()));
        let m = item.clip_from_local;
        s.points.clear();
        s.clip.clear();
        let (mut xlo, mut xhi, mut ylo, mut yhi) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for p in item.positions {
            let c = (m * *p).as_dvec4();
            if !(c.w > 0.0 && c.z < c.w && c.is_finite()) {
                // A vertex no triangle uses does not matter, but telling
                // them apart costs a pass: refuse.
                return false;
            }
            let iw = 1.0 / c.w;
            let q = (
                (c.x * iw + 1.0) * 0.5 * w,
                (1.0 - c.y * iw) * 0.5 * h,
                c.z * iw,
            );
            (xlo, xhi, ylo, yhi) = (xlo.min(q.0), xhi.max(q.0), ylo.min(q.1), yhi.max(q.1));
            s.points.push(q);
            s.clip.push(c);
        }
        self.stats.triangles_in += item.triangles.len() as u64;
        // The bounding rectangle of pixels, inclusive, cut to the target and
        // to the drawn rows.
        let l = self.layout;
        let (ty0, ty1) = self.draw_rows.unwrap_or((0, l.tiles_y));
        let tile = f64::from(1u32 << l.shift);
        let bx0 = (xlo - 1.0).ceil().max(0.0);
        let bx1 = xhi.floor().min(w - 1.0);
        let by0 = (ylo - 1.0).ceil().max(f64::from(ty0) * tile);
        let by1 = yhi.floor().min(h - 1.0).min(f64::from(ty1) * tile - 1.0);
        if bx0.is_nan() || bx1.is_nan() || by0.is_nan() || by1.is_nan() || bx0 > bx1 || by0 > by1 {
            return true;
        }
        let (bx0, by0) = (bx0 as u32, by0 as u32);
        let (bw, bh) = (bx1 as u32 - bx0 + 1, by1 as u32 - by0 + 1);
        let cells = bw as usize * bh as usize;
        s.depth.clear();
        s.depth.resize(cells, f64::INFINITY);
        s.edge.clear();
        s.edge.resize(cells, false);
        s.edges.clear();
        s.order.clear();
        let bits = |p: &glam::Vec4| [p.x, p.y, p.z].map(|v| (v + 0.0).to_bits());
        s.order.extend(
            item.positions
                .iter()
                .enumerate()
                .map(|(i, p)| (bits(p), i as u32)),
        );
        s.order.sort_unstable();
        s.weld.clear();
        s.weld.resize(item.positions.len(), 0);
        let mut first = 0;
        for k in 0..s.order.len() {
            if s.order[k].0 != s.order[first].0 {
                first = k;
            }
            s.weld[s.order[k].1 as usize] = s.order[first].1;
        }
        let rect = Rect {
            x0: bx0,
            y0: by0,
            w: bw,
            h: bh,
        };
        for t in item.triangles {
            if t.iter().any(|&i| i as usize >= s.points.len()) {
                return false;
            }
            let front = !item.cull.skips(facing_f64(t.map(|i| s.clip[i as usize])));
            for k in 0..3 {
                let (a, b) = (s.weld[t[k] as usize], s.weld[t[(k + 1) % 3] as usize]);
                s.edges.push((a.min(b), a.max(b), front));
            }
            if front {
                let tri = t.map(|i| s.points[i as usize]);
                front_face(&tri, &rect, &mut s.depth);
            }
        }
        // Silhouette edges: one front face of two, or not two faces.
        s.edges.sort_unstable();
        let mut i = 0;
        while i < s.edges.len() {
            let (a, b, _) = s.edges[i];
            let mut j = i;
            let mut fronts = 0;
            while j < s.edges.len() && (s.edges[j].0, s.edges[j].1) == (a, b) {
                fronts += usize::from(s.edges[j].2);
                j += 1;
            }
            if j - i != 2 || fronts == 1 {
                let (p, q) = (s.points[a as usize], s.points[b as usize]);
                mark_segment((p.0, p.1), (q.0, q.1), &rect, &mut s.edge);
            }
            i = j;
        }
        let mut written = 0u64;
        // No depth it writes is nearer than its nearest vertex.
        let znear = crate::coverage::f32_up(s.points.iter().fold(0.0f64, |z, p| z.max(p.2)));
        let id = u64::from(item.object) << 32;
        let mut touched = std::mem::take(&mut s.touched);
        touched.clear();
        for y in 0..bh {
            for x in 0..bw {
                let k = (y * bw + x) as usize;
                let z = s.depth[k];
                if s.edge[k] || z == f64::INFINITY {
                    continue;
                }
                let (px, py) = (bx0 + x, by0 + y);
                let t = l.tile_index(px >> l.shift, py >> l.shift);
                let b = self.tiles[t];
                if b.zmax == f32::INFINITY || (b.background == 0 && b.zmin > znear) {
                    continue;
                }
                let z = to_f32_below(z);
                if z.is_nan() || z <= 0.0 {
                    continue;
                }
                if self.write_bound(l.pixel_index(px, py), z, id) {
                    touched.push(t as u32);
                    written += 1;
                }
            }
        }
        self.stats.pixels_written += written;
        self.refresh_tiles(&mut touched);
        s.touched = touched;
        true
    }
}

/// The pixels `x0..x0 + w`, `y0..y0 + h` of the target a draw's buffers
/// cover.
struct Rect {
    x0: u32,
    y0: u32,
    w: u32,
    h: u32,
}

/// Takes, into `depth` (the rectangle's pixels), the least of its value and
/// the front face `tri`'s farthest bound over every pixel square the face
/// meets.
fn front_face(tri: &[(f64, f64, f64); 3], r: &Rect, depth: &mut [f64]) {
    let [p0, p1, p2] = *tri;
    // The depth plane where well conditioned (the slices bound it otherwise).
    let plane = DepthPlane::through(p0, p1, p2, 1e-9);
    // Snapping moves the face by up to its slope times the margin; an
    // edge-on face (no plane) moves by its depth range over its width, at
    // most its whole range.
    let slack = match plane {
        Some(p) => snap_slack(p.a, p.b),
        None => (p0.2.max(p1.2).max(p2.2) - p0.2.min(p1.2).min(p2.2)).abs(),
    };
    let ylo = p0.1.min(p1.1).min(p2.1);
    let yhi = p0.1.max(p1.1).max(p2.1);
    let (ry0, ry1) = (f64::from(r.y0), f64::from(r.y0 + r.h - 1));
    let y0 = (ylo - 1.0).ceil().max(ry0);
    let y1 = yhi.floor().min(ry1);
    if y0 > y1 {
        return;
    }
    for y in y0 as u32..=y1 as u32 {
        let Some(((xa, xb), (zf, _))) = band_extent(tri, (f64::from(y), f64::from(y) + 1.0)) else {
            continue;
        };
        let x0 = (xa - 1.0).ceil().max(f64::from(r.x0));
        let x1 = xb.floor().min(f64::from(r.x0 + r.w - 1));
        if x0.is_nan() || x1.is_nan() || x0 > x1 {
            continue;
        }
        for x in x0 as u32..=x1 as u32 {
            let mut z = zf;
            if let Some(p) = plane {
                let xf = f64::from(x);
                z = z.max(p.least((xf, xf + 1.0), (f64::from(y), f64::from(y) + 1.0)));
            }
            let k = ((y - r.y0) * r.w + (x - r.x0)) as usize;
            depth[k] = depth[k].min(z - slack);
        }
    }
}

/// Flags, in `edge` (the rectangle's pixels), every pixel whose closed
/// square, widened by [`EDGE_MARGIN_PX`], the segment `p q` meets.
fn mark_segment(p: (f64, f64), q: (f64, f64), r: &Rect, edge: &mut [bool]) {
    let e = EDGE_MARGIN_PX;
    let (ylo, yhi) = (p.1.min(q.1), p.1.max(q.1));
    let y0 = (ylo - e - 1.0).ceil().max(f64::from(r.y0));
    let y1 = (yhi + e).floor().min(f64::from(r.y0 + r.h - 1));
    if y0 > y1 {
        return;
    }
    for y in y0 as u32..=y1 as u32 {
        let Some((t0, t1)) = band_clip(p.1, q.1, (f64::from(y) - e, f64::from(y) + 1.0 + e)) else {
            continue;
        };
        let (xa, xb) = (p.0 + (q.0 - p.0) * t0, p.0 + (q.0 - p.0) * t1);
        let x0 = (xa.min(xb) - e - 1.0).ceil().max(f64::from(r.x0));
        let x1 = (xa.max(xb) + e).floor().min(f64::from(r.x0 + r.w - 1));
        if x0.is_nan() || x1.is_nan() || x0 > x1 {
            continue;
        }
        for x in x0 as u32..=x1 as u32 {
            edge[((y - r.y0) * r.w + (x - r.x0)) as usize] = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Coverage, CullMode, DepthPick, TileSize};
    use glam::{Mat4, Vec3, Vec4};

    /// Two boxes stacked as one closed, non-convex mesh (a tier on a wider
    /// base, joined by a ring): an L-shaped silhouette from the side.
    fn tiered() -> (Vec<Vec4>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        let mut t = Vec::new();
        let mut quad = |q: [Vec3; 4]| {
            let b = p.len() as u32;
            p.extend(q.map(|v| v.extend(1.0)));
            t.push([b, b + 1, b + 2]);
            t.push([b, b + 2, b + 3]);
        };
        // Base [-2, 2] × [0, 1] × [-2, 2]; tier [-1, 1] × [1, 3] × [-1, 1].
        let boxes = [(2.0, 0.0, 1.0), (1.0, 1.0, 3.0)];
        for (k, &(r, y0, y1)) in boxes.iter().enumerate() {
            let c = |x: f32, y: f32, z: f32| Vec3::new(x * r, y, z * r);
            // Sides, outward (counter-clockwise from outside).
            quad([
                c(-1.0, y0, 1.0),
                c(1.0, y0, 1.0),
                c(1.0, y1, 1.0),
                c(-1.0, y1, 1.0),
            ]);
            quad([
                c(1.0, y0, -1.0),
                c(-1.0, y0, -1.0),
                c(-1.0, y1, -1.0),
                c(1.0, y1, -1.0),
            ]);
            quad([
                c(1.0, y0, 1.0),
                c(1.0, y0, -1.0),
                c(1.0, y1, -1.0),
                c(1.0, y1, 1.0),
            ]);
            quad([
                c(-1.0, y0, -1.0),
                c(-1.0, y0, 1.0),
                c(-1.0, y1, 1.0),
                c(-1.0, y1, -1.0),
            ]);
            if k == 0 {
                quad([
                    c(-1.0, y0, -1.0),
                    c(1.0, y0, -1.0),
                    c(1.0, y0, 1.0),
                    c(-1.0, y0, 1.0),
                ]);
            }
        }
        // The ring between the base's top and the tier's bottom, and the
        // tier's top.
        let (o, i) = (2.0f32, 1.0f32);
        let ring = [(-1.0, 1.0), (1.0, 1.0), (1.0, -1.0), (-1.0, -1.0)];
        for e in 0..4 {
            let (a, b) = (ring[e], ring[(e + 1) % 4]);
            quad([
                Vec3::new(a.0 * o, 1.0, a.1 * o),
                Vec3::new(b.0 * o, 1.0, b.1 * o),
                Vec3::new(b.0 * i, 1.0, b.1 * i),
                Vec3::new(a.0 * i, 1.0, a.1 * i),
            ]);
        }
        quad([
            Vec3::new(-1.0, 3.0, 1.0),
            Vec3::new(1.0, 3.0, 1.0),
            Vec3::new(1.0, 3.0, -1.0),
            Vec3::new(-1.0, 3.0, -1.0),
        ]);
        (p, t)
    }

    /// The tiered mesh seen from above and the side, drawn whole: it covers
    /// every pixel its triangles inner-conservative cover and more (the
    /// cracks), only pixels its triangles' outer coverage reaches, and no
    /// nearer than the standard coverage's depth at the pixel centre.
    #[test]
    fn a_tiered_mesh_is_drawn_without_cracks_and_no_nearer() {
        let (p, t) = tiered();
        let proj = Mat4::from_cols(
            Vec4::new(1.2, 0.0, 0.0, 0.0),
            Vec4::new(0.0, 1.6, 0.0, 0.0),
            Vec4::new(0.0, 0.0, 0.0, -1.0),
            Vec4::new(0.0, 0.0, 0.1, 0.0),
        );
        for (k, (angle, tilt)) in [(0.3f32, 0.4f32), (1.1, 0.9), (2.0, 0.2)]
            .into_iter()
            .enumerate()
        {
            let model = Mat4::from_translation(Vec3::new(0.3 * k as f32, -1.0, -9.0))
                * Mat4::from_rotation_x(tilt)
                * Mat4::from_rotation_y(angle);
            let m = proj * model;
            // The cull mode that keeps the faces turned toward the eye.
            let cull = [CullMode::Back, CullMode::Front]
                .into_iter()
                .max_by_key(|c| {
                    let mut n = 0;
                    let mut d = DepthTarget::new(64, 48, TileSize::T8, false).unwrap();
                    let item = DrawItem {
                        clip_from_local: m,
                        positions: &p,
                        triangles: &t,
                        object: 0,
                        cull: *c,
                    };
                    d.draw(&item, Coverage::Standard).unwrap();
                    for y in 0..48 {
                        for x in 0..64 {
                            n += usize::from(d.depth_at(x, y).is_some());
                        }
                    }
                    n
                })
                .unwrap();
            let item = DrawItem {
                clip_from_local: m,
                positions: &p,
                triangles: &t,
                object: 5,
                cull,
            };
            let target = |cov: Option<Coverage>| {
                let mut d = DepthTarget::new(64, 48, TileSize::T8, true).unwrap();
                match cov {
                    Some(c) => d
                        .draw(
                            &DrawItem {
                                cull: CullMode::None,
                                ..item
                            },
                            c,
                        )
                        .unwrap(),
                    None => assert!(d.draw_closed(&item)),
                }
                d
            };
            let closed = target(None);
            let inner = target(Some(Coverage::Inner(DepthPick::Farthest)));
            let outer = target(Some(Coverage::Outer(DepthPick::Nearest)));
            let standard = target(Some(Coverage::Standard));
            let (mut covered, mut gained) = (0, 0);
            for y in 0..48 {
                for x in 0..64 {
                    let Some(z) = closed.depth_at(x, y) else {
                        continue;
                    };
                    covered += 1;
                    gained += usize::from(inner.depth_at(x, y).is_none());
                    assert!(
                        outer.depth_at(x, y).is_some(),
                        "({x}, {y}) outside the mesh"
                    );
                    let s = standard
                        .depth_at(x, y)
                        .expect("inside: the centre is covered");
                    assert!(z <= s, "({x}, {y}): {z} nearer than {s}");
                }
            }
            assert!(
                covered > 100 && gained > 10,
                "{covered} covered, {gained} gained"
            );
        }
        // Culling nothing, the faces are unknown: refused.
        let mut d = DepthTarget::new(16, 16, TileSize::T8, false).unwrap();
        let item = DrawItem {
            clip_from_local: proj * Mat4::from_translation(Vec3::new(0.0, 0.0, -9.0)),
            positions: &p,
            triangles: &t,
            object: 0,
            cull: CullMode::None,
        };
        assert!(!d.draw_closed(&item));
    }
}
