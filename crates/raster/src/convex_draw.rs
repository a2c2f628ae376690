//! Convex occluders drawn whole: the union of a convex solid's triangles,
//! inner-conservative at the farthest depth, without the cracks that
//! drawing each triangle inner-conservative leaves along every shared edge
//! (a pixel the edge crosses lies wholly inside neither triangle, though
//! wholly inside their union). Those cracks let a coarse view see through
//! every building along its triangles' diagonals and box edges.
//!
//! In front of the near plane the projective map keeps the solid convex
//! (pixel x, pixel y, reversed-Z depth z/w). There its image covers exactly
//! the convex hull of its projected vertices, and its front surface is the
//! image's upper envelope: at every point of the hull, the least of the
//! planes of its upper faces (those with the image's interior below them,
//! at smaller depth). A plane's image is a plane, so the farthest depth of
//! the front surface over a pixel square inside the hull is, per upper
//! face, its plane's least value over the square's corners, least over the
//! faces. A pixel is covered when its closed square lies inside the hull,
//! shrunk by a margin; its depth is rounded outward and widened by the
//! evaluation error and by how far snapping the vertices could move it, as
//! [`crate::DepthPick::Farthest`] is.

use crate::depth_plane::DepthPlane;
use crate::depth_target::DepthTarget;
use crate::item::DrawItem;
use crate::layout::TileRows;
use crate::whole_draw::{snap_slack, to_f32_below, ConvexScratch, HULL_MARGIN_PX};
use glam::DVec2;

impl DepthTarget {
    /// Draws the mesh of `item`, which must bound a convex solid (its
    /// triangles' vertices in convex position, its faces the hull's), as one
    /// occluder: every pixel whose closed square lies inside its silhouette,
    /// at a depth no nearer than its front surface over the square, with the
    /// GREATER test (ties to the smaller id). The id written is
    /// `(object, 0)`. `item.cull` is ignored: the front faces are found from
    /// the geometry. Returns `false`, drawing nothing, when some vertex is
    /// not strictly in front of the near plane (or not finite): the caller
    /// draws the triangles instead.
    pub fn draw_convex(&mut self, item: &DrawItem) -> bool {
        let mut s = std::mem::take(&mut self.convex);
        let drawn = self.draw_convex_with(item, &mut s);
        self.convex = s;
        drawn
    }

    fn draw_convex_with(&mut self, item: &DrawItem, s: &mut ConvexScratch) -> bool {
        let (w, h) = (f64::from(self.width()), f64::from(self.height()));
        s.points.clear();
        let m = item.clip_from_local;
        for t in item.triangles {
            for &i in t {
                let Some(p) = item.positions.get(i as usize) else {
                    return false;
                };
                // The f32 product, as setup transforms.
                let c = (m * *p).as_dvec4();
                if !(c.w > 0.0 && c.z < c.w && c.is_finite()) {
                    return false;
                }
                let iw = 1.0 / c.w;
                s.points.push((
                    (c.x * iw + 1.0) * 0.5 * w,
                    (1.0 - c.y * iw) * 0.5 * h,
                    c.z * iw,
                ));
            }
        }
        self.stats.triangles_in += item.triangles.len() as u64;
        if s.points.len() < 3 {
            return true;
        }
        hull_2d(&s.points, &mut s.sorted, &mut s.hull);
        if s.hull.len() < 3 {
            return true;
        }
        // An interior point of the image: the mean of the projected
        // vertices, each face's plane above it or not.
        let n = s.points.len() as f64;
        let mid = s.points.iter().fold((0.0, 0.0, 0.0), |a, p| {
            (a.0 + p.0 / n, a.1 + p.1 / n, a.2 + p.2 / n)
        });
        s.planes.clear();
        for tri in s.points.chunks_exact(3) {
            // Edge-on (or degenerate) in the image: no upper face.
            let Some(p) = DepthPlane::through(tri[0], tri[1], tri[2], 1e-9) else {
                continue;
            };
            if p.at(mid.0, mid.1) > mid.2 {
                s.planes.push(p);
            }
        }
        if s.planes.is_empty() {
            return true;
        }
        let l = self.layout;
        let (ty0, ty1) = self.draw_rows.unwrap_or((0, l.tiles_y));
        // No depth it writes is nearer than its nearest vertex.
        let znear = crate::coverage::f32_up(s.points.iter().fold(0.0f64, |z, p| z.max(p.2)));
        let (ylo, yhi) = s
            .hull
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
                (a.0.min(p.y), a.1.max(p.y))
            });
        let s_px = f64::from(1u32 << l.shift);
        let r0 = ylo.ceil().max(f64::from(ty0) * s_px);
        let r1 = (yhi.floor() - 1.0)
            .min(h - 1.0)
            .min(f64::from(ty1) * s_px - 1.0);
        s.tiles.clear();
        // A row of `tiles_x` bits (no more than the room: `tiles_x ≤ tiles`).
        s.seen.clear();
        s.seen.resize((l.tiles_x as usize).div_ceil(64), 0);
        let mut seen_row = u32::MAX;
        let mut written = 0u64;
        let id = u64::from(item.object) << 32;
        let tile_px = 1u32 << l.shift;
        if r0 <= r1 {
            for r in r0 as u32..=r1 as u32 {
                let Some((x0, x1)) = inner_span(&s.hull, f64::from(r), w) else {
                    continue;
                };
                if r >> l.shift != seen_row {
                    seen_row = r >> l.shift;
                    s.seen.fill(0);
                }
                // Per plane, its least over each square of the row is
                // affine in x: a·x + base.
                let yf = f64::from(r);
                s.row.clear();
                s.row.extend(s.planes.iter().map(|p| {
                    // The least over [0, 1] × [r, r + 1], minus the slack:
                    // over [x, x + 1] it is a·x more.
                    let base = p.least((0.0, 1.0), (yf, yf + 1.0)) - snap_slack(p.a, p.b);
                    (p.a, base)
                }));
                let mut x = x0;
                while x <= x1 {
                    // One tile's part of the span at a time.
                    let end = (x | (tile_px - 1)).min(x1);
                    let t = l.tile_index(x >> l.shift, r >> l.shift);
                    // Hidden tiles (`set_hidden_part`, `set_draw_tiles`)
                    // hold bounds nearer than any depth, and a tile whose
                    // every pixel is nearer than the solid's nearest vertex
                    // keeps them all: nothing is drawn there.
                    let b = self.tiles[t];
                    if b.zmax == f32::INFINITY || (b.background == 0 && b.zmin > znear) {
                        x = end + 1;
                        continue;
                    }
                    let base = l.pixel_index(x, r);
                    // Per pixel the least over the planes (plane by plane,
                    // a loop the compiler vectorizes), then widened and
                    // rounded down to f32.
                    let n = (end - x + 1) as usize;
                    let zs = &mut s.span[..n];
                    zs.fill(f64::INFINITY);
                    for &(a, b) in &s.row {
                        for (k, z) in zs.iter_mut().enumerate() {
                            *z = z.min(a * f64::from(x + k as u32) + b);
                        }
                    }
                    let mut wrote = false;
                    for (k, &z) in zs.iter().enumerate() {
                        let z = to_f32_below(z);
                        if z > 0.0 && self.write_bound(base + k, z, id) {
                            wrote = true;
                            written += 1;
                        }
                    }
                    let (word, bit) = ((x >> l.shift) as usize / 64, (x >> l.shift) % 64);
                    if wrote && s.seen[word] & 1 << bit == 0 {
                        s.seen[word] |= 1 << bit;
                        s.tiles.push(t as u32);
                    }
                    x = end + 1;
                }
            }
        }
        self.stats.pixels_written += written;
        self.refresh_tiles(&mut s.tiles);
        true
    }

    /// Writes depth `z` and id `id` at pixel `i` (tile-major) when it wins
    /// the GREATER test (ties to the smaller id); returns whether it did.
    /// The tile bounds are left to [`DepthTarget::refresh_tiles`].
    #[inline(always)]
    pub(crate) fn write_bound(&mut self, i: usize, z: f32, id: u64) -> bool {
        let d = self.depth[i];
        let wins = z > d || (z == d && self.ids.as_ref().is_some_and(|ids| id < ids[i]));
        if wins {
            self.depth[i] = z;
            if let Some(ids) = &mut self.ids {
                ids[i] = id;
            }
        }
        wins
    }

    /// Recomputes the bounds of the tiles `tiles` names (row-major tile
    /// indices, any order, repeats allowed; sorted in place).
    pub(crate) fn refresh_tiles(&mut self, tiles: &mut Vec<u32>) {
        if tiles.is_empty() {
            return;
        }
        tiles.sort_unstable();
        tiles.dedup();
        let l = self.layout;
        let mut rows = TileRows::of(
            l,
            (0, l.tiles_y),
            &mut self.depth,
            self.ids.as_deref_mut(),
            &mut self.tiles,
        );
        for &t in tiles.iter() {
            rows.refresh_tile(t % l.tiles_x, t / l.tiles_x);
        }
    }
}

/// The convex hull of `points`' pixel coordinates into `hull`,
/// counter-clockwise on screen with y down (Andrew's monotone chain;
/// collinear points dropped).
fn hull_2d(points: &[(f64, f64, f64)], p: &mut Vec<DVec2>, hull: &mut Vec<DVec2>) {
    hull.clear();
    p.clear();
    p.extend(points.iter().map(|q| DVec2::new(q.0, q.1)));
    p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    p.dedup();
    if p.len() < 3 {
        hull.extend(p.iter());
        return;
    }
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let chain = |q: DVec2, start: usize, hull: &mut Vec<DVec2>| {
        while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0
        {
            hull.pop();
        }
        hull.push(q);
    };
    // Lower chain left to right, upper chain back; each drops its last
    // point (the other's first).
    for &q in p.iter() {
        chain(q, 0, hull);
    }
    hull.pop();
    let start = hull.len();
    for &q in p.iter().rev() {
        chain(q, start, hull);
    }
    hull.pop();
}

/// The pixels `x0..=x1` of row `r` whose closed squares lie inside the
/// convex polygon `hull` (counter-clockwise, y down) shrunk by
/// [`HULL_MARGIN_PX`], cut to `0..width`; `None` when none does.
fn inner_span(hull: &[DVec2], r: f64, width: f64) -> Option<(u32, u32)> {
    let (mut lo, mut hi) = (0.0f64, width);
    for (i, &a) in hull.iter().enumerate() {
        let b = hull[(i + 1) % hull.len()];
        // Inside: the left of a → b, cross(b − a, p − a) ≥ margin·|b − a|.
        let e = b - a;
        let len = e.length();
        // cross(e, p − a) = e.x·(p.y − a.y) − e.y·(p.x − a.x) ≥ m.
        let m = HULL_MARGIN_PX * len;
        for y in [r, r + 1.0] {
            let k = e.x * (y - a.y) - m;
            // −e.y·(p.x − a.x) ≥ −k.
            if e.y == 0.0 {
                if k < 0.0 {
                    return None;
                }
            } else if e.y < 0.0 {
                // p.x ≥ a.x − k / (−e.y)… (−e.y > 0): p.x − a.x ≥ −k/(−e.y).
                lo = lo.max(a.x + k / e.y);
            } else {
                hi = hi.min(a.x + k / e.y);
            }
        }
    }
    // Squares [x, x + 1] inside [lo, hi].
    let (x0, x1) = (lo.ceil(), hi.floor() - 1.0);
    (x0 <= x1).then_some((x0 as u32, x1 as u32))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Coverage, CullMode, DepthPick, TileSize};
    use glam::{Mat4, Vec4};

    /// A cube's 12 triangles, outward, over its 8 corners (±1).
    fn cube() -> (Vec<Vec4>, Vec<[u32; 3]>) {
        let c = crate::aabb_corners(glam::Vec3::splat(-1.0), glam::Vec3::ONE);
        (c.to_vec(), crate::AABB_TRIANGLES.to_vec())
    }

    fn perspective() -> Mat4 {
        Mat4::from_cols(
            Vec4::new(1.2, 0.0, 0.0, 0.0),
            Vec4::new(0.0, 1.6, 0.0, 0.0),
            Vec4::new(0.0, 0.0, 0.0, -1.0),
            Vec4::new(0.0, 0.0, 0.1, 0.0),
        )
    }

    /// A rotated cube in front of the eye: the convex draw covers every
    /// pixel its triangles drawn one by one inner-conservative cover, more
    /// (the cracks along their shared edges), no pixel outside the
    /// triangles' outer coverage, and everywhere no nearer than the
    /// standard coverage's depth at the pixel centre.
    #[test]
    fn a_cube_is_drawn_without_cracks_and_no_nearer() {
        let (p, t) = cube();
        for (k, angle) in [0.3f32, 1.1, 2.0].into_iter().enumerate() {
            let model = Mat4::from_translation(glam::Vec3::new(0.2 * k as f32, -0.3, -6.0))
                * Mat4::from_rotation_y(angle)
                * Mat4::from_rotation_x(0.5 * angle);
            let item = DrawItem {
                clip_from_local: perspective() * model,
                positions: &p,
                triangles: &t,
                object: 3,
                cull: CullMode::None,
            };
            let target = |cov: Option<Coverage>| {
                let mut d = DepthTarget::new(64, 48, TileSize::T8, true).unwrap();
                match cov {
                    Some(c) => d.draw(&item, c).unwrap(),
                    None => assert!(d.draw_convex(&item)),
                }
                d
            };
            let (convex, inner) = (
                target(None),
                target(Some(Coverage::Inner(DepthPick::Farthest))),
            );
            let outer = target(Some(Coverage::Outer(DepthPick::Nearest)));
            let standard = target(Some(Coverage::Standard));
            let (mut gained, mut covered, mut lost) = (0, 0, 0);
            for y in 0..48 {
                for x in 0..64 {
                    let c = convex.depth_at(x, y);
                    // (Only a square within the hull's margin of the
                    // silhouette, which inner coverage of the snapped
                    // triangles may still take, is left.)
                    lost += usize::from(inner.depth_at(x, y).is_some() && c.is_none());
                    let Some(z) = c else { continue };
                    covered += 1;
                    gained += usize::from(inner.depth_at(x, y).is_none());
                    assert!(
                        outer.depth_at(x, y).is_some(),
                        "({x}, {y}) outside the cube"
                    );
                    let s = standard
                        .depth_at(x, y)
                        .expect("inside: the centre is covered");
                    assert!(z <= s, "({x}, {y}): {z} nearer than {s}");
                    assert_eq!(convex.id_at(x, y), Some((3, 0)));
                }
            }
            assert!(
                covered > 100 && gained > 10,
                "{covered} covered, {gained} gained"
            );
            assert!(
                lost * 10 < gained,
                "{lost} inner-covered pixels not covered"
            );
            // The tile bounds follow the pixels.
            for (tx, ty) in (0..8).flat_map(|tx| (0..6).map(move |ty| (tx, ty))) {
                let depths: Vec<f32> = (0..64)
                    .flat_map(|x| (0..48).map(move |y| (x, y)))
                    .filter(|&(x, y)| x / 8 == tx && y / 8 == ty)
                    .filter_map(|(x, y)| convex.depth_at(x, y))
                    .collect();
                let want = (!depths.is_empty()).then(|| {
                    let lo = depths.iter().copied().fold(f32::INFINITY, f32::min);
                    (lo, depths.iter().copied().fold(0.0, f32::max))
                });
                assert_eq!(convex.tile_bounds(tx, ty), want, "tile ({tx}, {ty})");
            }
        }
    }

    /// A solid covering the whole target lists each tile it writes once, so
    /// the room a target is made with holds it (a steady frame's convex
    /// draws allocate nothing whichever target a light view gets), and
    /// every tile's bounds are refreshed.
    #[test]
    fn a_solid_over_the_whole_target_stays_within_the_room() {
        let (p, t) = cube();
        let item = DrawItem {
            clip_from_local: perspective()
                * Mat4::from_translation(glam::Vec3::new(0.0, 0.0, -1.5)),
            positions: &p,
            triangles: &t,
            object: 1,
            cull: CullMode::None,
        };
        let mut d = DepthTarget::new(64, 64, TileSize::T8, false).unwrap();
        let room = d.convex.tiles.capacity();
        assert_eq!(room, 64);
        assert!(d.draw_convex(&item));
        assert_eq!(d.convex.tiles.capacity(), room);
        assert_eq!(d.convex.tiles.len(), 64, "every tile once");
        for (tx, ty) in (0..8).flat_map(|tx| (0..8).map(move |ty| (tx, ty))) {
            assert!(d.tile_bounds(tx, ty).is_some(), "tile ({tx}, {ty})");
        }
    }

    /// A cube reaching behind the near plane is left to the triangles.
    #[test]
    fn a_cube_through_the_near_plane_is_refused() {
        let (p, t) = cube();
        let item = DrawItem {
            clip_from_local: perspective()
                * Mat4::from_translation(glam::Vec3::new(0.0, 0.0, -0.5)),
            positions: &p,
            triangles: &t,
            object: 0,
            cull: CullMode::None,
        };
        let mut d = DepthTarget::new(16, 16, TileSize::T8, false).unwrap();
        assert!(!d.draw_convex(&item));
        assert_eq!(d.depth_at(8, 8), None);
    }
}
