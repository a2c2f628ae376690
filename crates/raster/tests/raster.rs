//! Integration tests of the rasterizer against brute-force f64 references on the
//! rasterizer's own snapped post-clip vertices (DESIGN.md "Tests").

use crate::perspective;
use glam::{Mat4, Vec3, Vec4};
use proptest::prelude::*;
use raster::*;
use std::sync::Arc;

/// One fan triangle of a snapped polygon, as the f64 reference sees it.
struct RefTri {
    v: [(f64, f64, f64); 3],
    area: f64,
}

fn ref_tris(s: &Setup) -> Vec<RefTri> {
    let p = s.polygon();
    let mut out = Vec::new();
    for i in 1..p.len().saturating_sub(1) {
        let f = |q: &SnappedVertex| (q.x as f64, q.y as f64, q.z);
        let (a, mut b, mut c) = (f(&p[0]), f(&p[i]), f(&p[i + 1]));
        let mut area = (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
        if area == 0.0 {
            continue;
        }
        if area < 0.0 {
            std::mem::swap(&mut b, &mut c);
            area = -area;
        }
        out.push(RefTri { v: [a, b, c], area });
    }
    out
}

impl RefTri {
    /// Edge values (opposite each vertex) at the fixed-point point `(px, py)`.
    fn edges(&self, px: f64, py: f64) -> [(f64, bool); 3] {
        let e = |a: (f64, f64, f64), b: (f64, f64, f64)| {
            let (ea, eb) = (-(b.1 - a.1), b.0 - a.0);
            (
                ea * (px - a.0) + eb * (py - a.1),
                ea > 0.0 || (ea == 0.0 && eb > 0.0),
            )
        };
        [
            e(self.v[1], self.v[2]),
            e(self.v[2], self.v[0]),
            e(self.v[0], self.v[1]),
        ]
    }

    /// Standard coverage of pixel (x, y) with the top-left rule.
    fn covers(&self, x: u32, y: u32) -> bool {
        let (px, py) = (x as f64 * 256.0 + 128.0, y as f64 * 256.0 + 128.0);
        self.edges(px, py)
            .iter()
            .all(|&(e, tl)| e > 0.0 || (e == 0.0 && tl))
    }

    /// Plane depth at pixel (x, y).
    fn depth(&self, x: u32, y: u32) -> f64 {
        let (px, py) = (x as f64 * 256.0 + 128.0, y as f64 * 256.0 + 128.0);
        let e = self.edges(px, py);
        (0..3).map(|i| e[i].0 / self.area * self.v[i].2).sum()
    }

    /// The rasterizer's f32 depth formula (for exact query counts).
    fn depth_f32(&self, x: u32, y: u32) -> f32 {
        let (px, py) = (x as f64 * 256.0 + 128.0, y as f64 * 256.0 + 128.0);
        let e = self.edges(px, py);
        ((e[0].0 * self.v[0].2 + e[1].0 * self.v[1].2 + e[2].0 * self.v[2].2) * (1.0 / self.area))
            as f32
    }

    fn inside_closed(&self, px: f64, py: f64) -> bool {
        self.edges(px, py).iter().all(|&(e, _)| e >= 0.0)
    }

    /// The closed pixel square meets the closed triangle (separating axes).
    fn outer(&self, x: u32, y: u32) -> bool {
        let (x0, y0) = (x as f64 * 256.0, y as f64 * 256.0);
        let (x1, y1) = (x0 + 256.0, y0 + 256.0);
        let xs = self.v.map(|v| v.0);
        let ys = self.v.map(|v| v.1);
        if xs.iter().cloned().fold(f64::MIN, f64::max) < x0
            || xs.iter().cloned().fold(f64::MAX, f64::min) > x1
            || ys.iter().cloned().fold(f64::MIN, f64::max) < y0
            || ys.iter().cloned().fold(f64::MAX, f64::min) > y1
        {
            return false;
        }
        let corners = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)];
        (0..3).all(|i| {
            corners
                .iter()
                .any(|&(cx, cy)| self.edges(cx, cy)[i].0 >= 0.0)
        })
    }

    fn inner(&self, x: u32, y: u32) -> bool {
        let (x0, y0) = (x as f64 * 256.0, y as f64 * 256.0);
        [(0.0, 0.0), (256.0, 0.0), (0.0, 256.0), (256.0, 256.0)]
            .iter()
            .all(|&(dx, dy)| self.inside_closed(x0 + dx, y0 + dy))
    }
}

fn tile_strategy() -> impl Strategy<Value = TileSize> {
    prop_oneof![Just(TileSize::T4), Just(TileSize::T8), Just(TileSize::T16)]
}

/// A view-space vertex: a point (w = 1) or, sometimes, a direction (w = 0); at
/// `scale` 1e5 the triangles are huge.
fn vertex(scale: f32) -> impl Strategy<Value = Vec4> {
    (
        -scale..scale,
        -scale..scale,
        -scale..scale * 0.3,
        prop_oneof![5 => Just(1.0f32), 1 => Just(0.0f32)],
    )
        .prop_map(|(x, y, z, w)| Vec4::new(x, y, z, w))
}

fn triangle() -> impl Strategy<Value = [Vec4; 3]> {
    prop_oneof![
        [vertex(10.0), vertex(10.0), vertex(10.0)],
        [vertex(1e5), vertex(1e5), vertex(1e5)],
        // A direction perpendicular to the view: clip w = 0.
        (vertex(10.0), vertex(10.0), -1.0f32..1.0, -1.0f32..1.0).prop_map(|(a, b, x, y)| [
            a,
            b,
            Vec4::new(x, y, 0.0, 0.0)
        ]),
    ]
}

fn draw_one(t: &mut DepthTarget, m: Mat4, tri: [Vec4; 3], object: u32, cov: Coverage) {
    let item = DrawItem {
        clip_from_local: m,
        positions: &tri,
        triangles: &[[0, 1, 2]],
        object,
        cull: raster::CullMode::None,
    };
    t.draw(&item, cov).unwrap();
}

proptest! {
    #![proptest_config(testkit::proptest_config(300))]

    /// Coverage equals the f64 reference on the snapped post-clip vertices, and depth
    /// lies within DEPTH_ERROR of the plane through them.
    #[test]
    fn coverage_and_depth_match_reference(
        tri in triangle(),
        (w, h) in prop_oneof![Just((37u32, 23u32)), Just((64, 64)), Just((50, 70))],
        tile in tile_strategy(),
        near in prop_oneof![Just(0.1f32), Just(1.0)],
        ids in any::<bool>(),
    ) {
        let m = perspective(1.0, w as f32 / h as f32, near);
        let clip = tri.map(|p| m * p);
        let s = setup_triangle(clip, w, h);
        let refs = ref_tris(&s);
        // With and without the id target (two traversal paths).
        let mut t = DepthTarget::new(w, h, tile, ids).unwrap();
        draw_one(&mut t, m, tri, 7, Coverage::Standard);
        for y in 0..h {
            for x in 0..w {
                let hits: Vec<&RefTri> = refs.iter().filter(|r| r.covers(x, y)).collect();
                prop_assert!(hits.len() <= 1, "fan overlap at ({x}, {y})");
                let got = t.depth_at(x, y);
                prop_assert_eq!(got.is_some(), hits.len() == 1, "pixel ({}, {})", x, y);
                if let (Some(z), Some(r)) = (got, hits.first()) {
                    let zr = r.depth(x, y);
                    prop_assert!(((z as f64) - zr).abs() <= DEPTH_ERROR * zr * (1.0 + 1e-9),
                        "depth {} vs {} at ({}, {})", z, zr, x, y);
                    prop_assert_eq!(t.id_at(x, y), ids.then_some((7, 0)));
                }
            }
        }
        // Hierarchical z contains the pixel depths of every tile.
        check_hiz(&t)?;
    }

    /// Outer and inner conservative coverage against their definitions (per fan triangle).
    #[test]
    fn conservative_coverage_matches_definitions(
        tri in [vertex(10.0), vertex(10.0), vertex(10.0)],
        tile in tile_strategy(),
        pick in prop_oneof![Just(DepthPick::Nearest), Just(DepthPick::Farthest)],
        outer in any::<bool>(),
    ) {
        let (w, h) = (40u32, 30u32);
        let m = perspective(1.0, w as f32 / h as f32, 0.5);
        let clip = tri.map(|p| m * p);
        let s = setup_triangle(clip, w, h);
        let refs = ref_tris(&s);
        let cov = if outer { Coverage::Outer(pick) } else { Coverage::Inner(pick) };
        let mut t = DepthTarget::new(w, h, tile, false).unwrap();
        draw_one(&mut t, m, tri, 0, cov);
        for y in 0..h {
            for x in 0..w {
                let hits: Vec<&RefTri> = refs
                    .iter()
                    .filter(|r| if outer { r.outer(x, y) } else { r.inner(x, y) })
                    .collect();
                let got = t.depth_at(x, y);
                prop_assert_eq!(got.is_some(), !hits.is_empty(), "pixel ({}, {})", x, y);
                let Some(z) = got else { continue };
                // The bound holds for every point of pixel ∩ triangle we can name: for
                // Nearest over every fan triangle hit (GREATER keeps the largest bound),
                // for Farthest over at least one (the one whose bound won).
                let ok: Vec<bool> = hits.iter().map(|r| {
                    let mut pts = vec![];
                    for (dx, dy) in [(0.0, 0.0), (256.0, 0.0), (0.0, 256.0), (256.0, 256.0), (128.0, 128.0)] {
                        let (px, py) = (x as f64 * 256.0 + dx, y as f64 * 256.0 + dy);
                        if r.inside_closed(px, py) {
                            pts.push((px, py));
                        }
                    }
                    for v in r.v {
                        if v.0 >= x as f64 * 256.0 && v.0 <= x as f64 * 256.0 + 256.0
                            && v.1 >= y as f64 * 256.0 && v.1 <= y as f64 * 256.0 + 256.0 {
                            pts.push((v.0, v.1));
                        }
                    }
                    pts.iter().all(|&(px, py)| {
                        let e = r.edges(px, py);
                        let zp: f64 = (0..3).map(|i| e[i].0 / r.area * r.v[i].2).sum();
                        match pick {
                            DepthPick::Nearest => z as f64 >= zp * (1.0 - 1e-12),
                            DepthPick::Farthest => z as f64 <= zp * (1.0 + 1e-12),
                        }
                    })
                }).collect();
                match pick {
                    DepthPick::Nearest => prop_assert!(ok.iter().all(|&b| b), "pixel ({}, {})", x, y),
                    DepthPick::Farthest => prop_assert!(ok.iter().any(|&b| b), "pixel ({}, {})", x, y),
                }
            }
        }
        check_hiz(&t)?;
    }

    /// The primitive-id winner and depth do not depend on draw order.
    #[test]
    fn id_winner_is_order_independent(
        tris in prop::collection::vec([vertex(10.0), vertex(10.0), vertex(10.0)], 2..8),
        seed in any::<u64>(),
    ) {
        let (w, h) = (48u32, 32u32);
        let m = perspective(1.0, 1.5, 0.5);
        // Each triangle twice under two ids: exact depth ties.
        let mut list: Vec<(u32, [Vec4; 3])> = Vec::new();
        for (i, t) in tris.iter().enumerate() {
            list.push((2 * i as u32 + 5, *t));
            list.push((2 * i as u32 + 4, *t));
        }
        let mut a = DepthTarget::new(w, h, TileSize::T8, true).unwrap();
        for (id, t) in &list {
            draw_one(&mut a, m, *t, *id, Coverage::Standard);
        }
        // Shuffle deterministically from the seed.
        let mut s = seed | 1;
        for i in (1..list.len()).rev() {
            s ^= s << 13; s ^= s >> 7; s ^= s << 17;
            list.swap(i, (s % (i as u64 + 1)) as usize);
        }
        let mut b = DepthTarget::new(w, h, TileSize::T8, true).unwrap();
        for (id, t) in &list {
            draw_one(&mut b, m, *t, *id, Coverage::Standard);
        }
        for y in 0..h {
            for x in 0..w {
                prop_assert_eq!(a.depth_at(x, y), b.depth_at(x, y));
                prop_assert_eq!(a.id_at(x, y), b.id_at(x, y));
                if let Some((o, _)) = a.id_at(x, y) {
                    prop_assert!(o % 2 == 0, "the smaller id of a tie wins");
                }
            }
        }
        // Incrementally maintained tile bounds stay exact enough to contain every pixel.
        check_hiz(&a)?;
        check_hiz(&b)?;
    }

    /// A perturbed triangulated grid covers every pixel exactly once (or, when it
    /// crosses the near plane, at most once and exactly the reference union).
    #[test]
    fn grid_is_watertight(
        jitter in prop::collection::vec((-0.24f32..0.24, -0.24f32..0.24), 81),
        tilt in prop_oneof![Just(0.0f32), -0.8f32..0.8],
        flip in any::<bool>(),
    ) {
        let (w, h) = (61u32, 47u32);
        let near = 1.0;
        let m = perspective(1.2, w as f32 / h as f32, near);
        let n = 9usize;
        // Plane z = −3 + tilt·y in view space, spanning far beyond the view.
        let pts: Vec<Vec4> = (0..n * n)
            .map(|k| {
                let (i, j) = ((k % n) as f32, (k / n) as f32);
                let (dx, dy) = jitter[k];
                let (x, y) = (-12.0 + 3.0 * (i + dx), -12.0 + 3.0 * (j + dy));
                Vec4::new(x, y, -3.0 + tilt * y, 1.0)
            })
            .collect();
        let mut tris = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = (j * n + i) as u32;
                let (b, c, d) = (a + 1, a + n as u32, a + n as u32 + 1);
                if flip { tris.push([a, b, d]); tris.push([a, d, c]); }
                else { tris.push([a, b, c]); tris.push([b, d, c]); }
            }
        }
        check_watertight(w, h, m, &pts, &tris, tilt == 0.0)?;
    }

    /// A planar triangle fan around a hub inside its convex rim is covered at most once
    /// per pixel and exactly as the reference, also when the plane crosses the near plane.
    #[test]
    fn fan_is_watertight(
        hub in (-1.0f32..1.0, -1.0f32..1.0),
        n in 3usize..24,
        r in 0.3f32..3.0,
        tilt in prop_oneof![Just(0.0f32), 0.0f32..1.5],
    ) {
        let (w, h) = (64u32, 64u32);
        let m = perspective(1.0, 1.0, 0.5);
        // The plane z = −1.5 + tilt·x crosses the near plane z = −0.5 when tilt·r > 1.
        let on_plane = |x: f32, y: f32| Vec4::new(x, y, -1.5 + tilt * x, 1.0);
        // Inside the rim: its inscribed radius is r·cos(π/n) ≥ r/2.
        let mut pts = vec![on_plane(hub.0 * r * 0.35, hub.1 * r * 0.35)];
        for k in 0..n {
            let a = k as f32 * std::f32::consts::TAU / n as f32;
            pts.push(on_plane(r * a.cos(), r * a.sin()));
        }
        let tris: Vec<[u32; 3]> = (0..n).map(|k| [0, 1 + k as u32, 1 + ((k + 1) % n) as u32]).collect();
        check_watertight(w, h, m, &pts, &tris, false)?;
    }

    /// Query counts equal a brute-force count against the same depth buffer.
    #[test]
    fn query_counts_match_brute_force(
        occluders in prop::collection::vec([vertex(10.0), vertex(10.0), vertex(10.0)], 0..6),
        q in [vertex(10.0), vertex(10.0), vertex(10.0)],
        tile in tile_strategy(),
    ) {
        let (w, h) = (40u32, 36u32);
        let m = perspective(1.0, w as f32 / h as f32, 0.5);
        let mut t = DepthTarget::new(w, h, tile, false).unwrap();
        for (i, o) in occluders.iter().enumerate() {
            draw_one(&mut t, m, *o, i as u32, Coverage::Standard);
        }
        let item = DrawItem { clip_from_local: m, positions: &q, triangles: &[[0, 1, 2]], object: 0, cull: raster::CullMode::None  };
        let count = t.query(&item, &QueryOptions::default(), None).unwrap();
        let any = t.query(&item, &QueryOptions { mode: QueryMode::Any, ..Default::default() }, None).unwrap();
        let refs = ref_tris(&setup_triangle(q.map(|p| m * p), w, h));
        let mut expect = 0u32;
        for y in 0..h {
            for x in 0..w {
                for r in &refs {
                    if r.covers(x, y) {
                        let stored = t.depth_at(x, y).unwrap_or(BACKGROUND);
                        if r.depth_f32(x, y) >= stored {
                            expect += 1;
                        }
                    }
                }
            }
        }
        prop_assert_eq!(count, expect);
        prop_assert_eq!(any, u32::from(expect > 0));
        // A count up to n stops there: min(count, n).
        for n in [1, 2, 5, 40] {
            let up_to = QueryOptions { mode: QueryMode::CountUpTo(n), ..Default::default() };
            prop_assert_eq!(t.query(&item, &up_to, None).unwrap(), expect.min(n));
        }
    }

    /// Draws restricted to tile rows write exactly the unrestricted depth,
    /// ids and tile bounds in those rows, and nothing elsewhere.
    #[test]
    fn row_restricted_draws_match_inside_and_skip_outside(
        tris in prop::collection::vec([vertex(10.0), vertex(10.0), vertex(10.0)], 1..6),
        r0 in 0u32..6,
        len in 0u32..6,
        cov_k in 0usize..3,
    ) {
        let (w, h) = (40u32, 44u32);
        let m = perspective(1.0, w as f32 / h as f32, 0.5);
        let cov = [
            Coverage::Standard,
            Coverage::Inner(DepthPick::Farthest),
            Coverage::Outer(DepthPick::Nearest),
        ][cov_k];
        let mut full = DepthTarget::new(w, h, TileSize::T8, true).unwrap();
        let mut part = DepthTarget::new(w, h, TileSize::T8, true).unwrap();
        let rows = (r0, r0 + len);
        part.set_draw_rows(Some(rows));
        for (i, t) in tris.iter().enumerate() {
            draw_one(&mut full, m, *t, i as u32, cov);
            draw_one(&mut part, m, *t, i as u32, cov);
        }
        for y in 0..h {
            let inside = (rows.0..rows.1).contains(&(y / 8));
            for x in 0..w {
                if inside {
                    prop_assert_eq!(part.depth_at(x, y), full.depth_at(x, y));
                    prop_assert_eq!(part.id_at(x, y), full.id_at(x, y));
                } else {
                    prop_assert_eq!(part.depth_at(x, y), None);
                }
            }
        }
        for ty in 0..h.div_ceil(8) {
            for tx in 0..w.div_ceil(8) {
                if (rows.0..rows.1).contains(&ty) {
                    prop_assert_eq!(part.tile_bounds(tx, ty), full.tile_bounds(tx, ty));
                }
            }
        }
    }

    /// A receiver segment marks every pixel its points mark (each point's
    /// footprint at half the segment's, leaving room for the f32 rounding of
    /// points computed one by one), at a farthest depth no nearer and a
    /// nearest depth no farther (up to that rounding); segments reaching
    /// behind the eye or off the target too.
    #[test]
    fn receiver_segments_cover_their_points(
        a in (-12.0f64..12.0, -12.0f64..12.0, -20.0f64..3.0),
        b in (-12.0f64..12.0, -12.0f64..12.0, -20.0f64..3.0),
    ) {
        let (w, h) = (64u32, 48u32);
        let m = perspective(1.0, w as f32 / h as f32, 0.5);
        let t = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
        let (a, b) = (glam::DVec3::new(a.0, a.1, a.2), glam::DVec3::new(b.0, b.1, b.2));
        let points: Vec<Vec4> = (0..=64)
            .map(|k| (a + (b - a) * (k as f64 / 64.0)).as_vec3().extend(1.0))
            .collect();
        let eps = RECEIVER_EPS_PX;
        let mut by_points = ReceiverTarget::for_target(&t);
        by_points.set_track_nearest(true);
        by_points.mark_points_within(m, &points, eps / 2.0);
        let mut by_segment = ReceiverTarget::for_target(&t);
        by_segment.set_track_nearest(true);
        by_segment.mark_segments_within(
            m,
            [(a.as_vec3().extend(1.0), b.as_vec3().extend(1.0))],
            eps,
        );
        for y in 0..h {
            for x in 0..w {
                if let Some(dp) = by_points.at(x, y) {
                    let ds = by_segment.at(x, y);
                    prop_assert!(
                        ds.is_some_and(|ds| ds <= dp + 1e-6),
                        "pixel ({}, {}): point depth {} segment {:?}", x, y, dp, ds
                    );
                    let (np, ns) = (by_points.nearest_at(x, y), by_segment.nearest_at(x, y));
                    prop_assert!(
                        np.zip(ns).is_some_and(|(np, ns)| ns >= np - 1e-6 && ns >= ds.unwrap_or(0.0)),
                        "pixel ({}, {}): nearest point depth {:?} segment {:?}", x, y, np, ns
                    );
                }
            }
        }
    }

    /// A union query of several boxes is the sum of their single queries
    /// (VISIBLE when one is); with any-samples it is 0 exactly when every
    /// box's query is, and counted up to n it is the sum up to n (n or
    /// VISIBLE when one box is VISIBLE).
    #[test]
    fn aabb_union_query_sums_its_boxes(
        occluders in prop::collection::vec([vertex(10.0), vertex(10.0), vertex(10.0)], 0..4),
        boxes in prop::collection::vec(
            ((-6.0f32..6.0, -6.0f32..6.0, -12.0f32..2.0), (0.1f32..3.0, 0.1f32..3.0, 0.1f32..3.0)),
            1..5,
        ),
    ) {
        let (w, h) = (40u32, 30u32);
        let m = perspective(1.0, w as f32 / h as f32, 0.5);
        let mut t = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
        for (i, o) in occluders.iter().enumerate() {
            draw_one(&mut t, m, *o, i as u32, Coverage::Standard);
        }
        let boxes: Vec<(Vec3, Vec3)> = boxes
            .iter()
            .map(|(c, e)| {
                let (c, e) = (Vec3::new(c.0, c.1, c.2), Vec3::new(e.0, e.1, e.2));
                (c - e, c + e)
            })
            .collect();
        let count = QueryOptions { mode: QueryMode::Count, ..Default::default() };
        let any = QueryOptions { mode: QueryMode::Any, ..Default::default() };
        let single: Vec<u32> = boxes
            .iter()
            .map(|&(a, b)| t.query_aabb(m, a, b, &count, None).unwrap())
            .collect();
        let expect = if single.contains(&VISIBLE) {
            VISIBLE
        } else {
            single.iter().fold(0u32, |s, &n| s.saturating_add(n)).min(VISIBLE - 1)
        };
        prop_assert_eq!(t.query_aabb_union(m, &boxes, &count, None).unwrap(), expect);
        let got_any = t.query_aabb_union(m, &boxes, &any, None).unwrap();
        prop_assert_eq!(got_any == 0, expect == 0);
        for n in [1, 3, 50] {
            let up_to = QueryOptions { mode: QueryMode::CountUpTo(n), ..Default::default() };
            // It may stop at n before a box that meets the apex region.
            let got = t.query_aabb_union(m, &boxes, &up_to, None).unwrap();
            if expect == VISIBLE {
                prop_assert!(got == VISIBLE || got == n, "{} of VISIBLE", got);
            } else {
                prop_assert_eq!(got, expect.min(n));
            }
            for &(a, b) in &boxes {
                let full = t.query_aabb(m, a, b, &count, None).unwrap();
                let capped = if full == VISIBLE { VISIBLE } else { full.min(n) };
                prop_assert_eq!(t.query_aabb(m, a, b, &up_to, None).unwrap(), capped);
            }
        }
    }

    /// AABB queries: the count equals the brute force over its 12 triangles, unless
    /// the box meets the apex region (then VISIBLE).
    #[test]
    fn aabb_query_counts_all_faces(
        occluders in prop::collection::vec([vertex(10.0), vertex(10.0), vertex(10.0)], 0..4),
        c in (-6.0f32..6.0, -6.0f32..6.0, -12.0f32..2.0),
        e in (0.1f32..3.0, 0.1f32..3.0, 0.1f32..3.0),
    ) {
        let (w, h) = (40u32, 30u32);
        let m = perspective(1.0, w as f32 / h as f32, 0.5);
        let mut t = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
        for (i, o) in occluders.iter().enumerate() {
            draw_one(&mut t, m, *o, i as u32, Coverage::Standard);
        }
        let (min, max) = (Vec3::new(c.0, c.1, c.2) - Vec3::from(e), Vec3::new(c.0, c.1, c.2) + Vec3::from(e));
        let got = t.query_aabb(m, min, max, &QueryOptions::default(), None).unwrap();
        let corners = aabb_corners(min, max);
        let mut expect = 0u32;
        for tri in AABB_TRIANGLES {
            let refs = ref_tris(&setup_triangle(tri.map(|i| m * corners[i as usize]), w, h));
            for y in 0..h {
                for x in 0..w {
                    for r in &refs {
                        if r.covers(x, y) && r.depth_f32(x, y) >= t.depth_at(x, y).unwrap_or(BACKGROUND) {
                            expect += 1;
                        }
                    }
                }
            }
        }
        if got == VISIBLE {
            // Only boxes reaching within the near distance of the eye's pyramid.
            prop_assert!(min.z < -0.0 + 0.5 * 1.01 || max.z > -0.5 * 1.01);
        } else {
            prop_assert_eq!(got, expect);
        }
    }
}

fn check_hiz(t: &DepthTarget) -> std::result::Result<(), TestCaseError> {
    let (tx, ty) = t.tile_counts();
    let s = t.tile_pixels();
    for j in 0..ty {
        for i in 0..tx {
            let b = t.tile_bounds(i, j);
            let mut bg = 0;
            for y in j * s..((j + 1) * s).min(t.height()) {
                for x in i * s..((i + 1) * s).min(t.width()) {
                    match (t.depth_at(x, y), b) {
                        (None, _) => bg += 1,
                        (Some(z), Some((lo, hi))) => prop_assert!(lo <= z && z <= hi),
                        (Some(_), None) => prop_assert!(false, "tile ({i}, {j}) lost a pixel"),
                    }
                }
            }
            prop_assert_eq!(bg, t.tile_background(i, j));
        }
    }
    Ok(())
}

/// Draws each triangle alone and counts coverage per pixel: never more than once, the
/// union equal to the reference, and (if `full`) every pixel exactly once.
fn check_watertight(
    w: u32,
    h: u32,
    m: Mat4,
    pts: &[Vec4],
    tris: &[[u32; 3]],
    full: bool,
) -> std::result::Result<(), TestCaseError> {
    let mut count = vec![0u32; (w * h) as usize];
    let mut refc = vec![0u32; (w * h) as usize];
    let mut t = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
    for tri in tris {
        t.clear();
        let v = tri.map(|i| pts[i as usize]);
        draw_one(&mut t, m, v, 0, Coverage::Standard);
        let refs = ref_tris(&setup_triangle(v.map(|p| m * p), w, h));
        for y in 0..h {
            for x in 0..w {
                if t.depth_at(x, y).is_some() {
                    count[(y * w + x) as usize] += 1;
                }
                if refs.iter().any(|r| r.covers(x, y)) {
                    refc[(y * w + x) as usize] += 1;
                }
            }
        }
    }
    prop_assert_eq!(&count, &refc);
    for (k, &c) in count.iter().enumerate() {
        prop_assert!(c <= 1, "pixel {} covered {} times", k, c);
        if full {
            prop_assert_eq!(c, 1, "pixel {} missed", k);
        }
    }
    Ok(())
}

#[test]
fn fan_rim_interior_is_covered_exactly_once() {
    // A convex fan entirely in front of the camera: every pixel centre strictly inside
    // the rim polygon is covered exactly once.
    let (w, h) = (64u32, 64u32);
    let m = perspective(1.0, 1.0, 0.5);
    let n = 17;
    let mut pts = vec![Vec4::new(0.1, -0.05, -2.0, 1.0)];
    for k in 0..n {
        let a = k as f32 * std::f32::consts::TAU / n as f32 + 0.1;
        pts.push(Vec4::new(
            0.8 * a.cos(),
            0.8 * a.sin(),
            -2.0 - 0.3 * a.sin(),
            1.0,
        ));
    }
    let mut count = vec![0u32; (w * h) as usize];
    let mut t = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
    for k in 0..n {
        t.clear();
        let v = [pts[0], pts[1 + k], pts[1 + (k + 1) % n]];
        draw_one(&mut t, m, v, 0, Coverage::Standard);
        for y in 0..h {
            for x in 0..w {
                count[(y * w + x) as usize] += u32::from(t.depth_at(x, y).is_some());
            }
        }
    }
    // Rim polygon in pixels.
    let rim: Vec<(f64, f64)> = pts[1..]
        .iter()
        .map(|p| {
            let c = m * *p;
            (
                (c.x / c.w + 1.0) as f64 * 0.5 * w as f64,
                (1.0 - c.y / c.w) as f64 * 0.5 * h as f64,
            )
        })
        .collect();
    let mut inside_pixels = 0;
    for y in 0..h {
        for x in 0..w {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let inside = (0..n).all(|k| {
                let (a, b) = (rim[k], rim[(k + 1) % n]);
                // Strictly inside with a margin of the snapping error.
                let e = (b.0 - a.0) * (py - a.1) - (b.1 - a.1) * (px - a.0);
                let len = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
                e / len < -0.01
            });
            if inside {
                inside_pixels += 1;
                assert_eq!(count[(y * w + x) as usize], 1, "pixel ({x}, {y})");
            } else {
                assert!(count[(y * w + x) as usize] <= 1);
            }
        }
    }
    assert!(inside_pixels > 100);
}

/// `n` boxes scattered in front of the eye, `spread` high.
fn scattered_boxes(n: usize, spread: f32) -> Vec<(Vec3, Vec3)> {
    (0..n)
        .map(|k| {
            let f = k as f32;
            let c = Vec3::new(
                (f * 1.37).sin() * 8.0,
                (f * 0.71).cos() * spread,
                -6.0 - (f * 0.53).sin().abs() * 20.0,
            );
            (c - Vec3::splat(0.7), c + Vec3::splat(0.9))
        })
        .collect()
}

/// The boxes' corners, and draw items of them (object ids in order).
fn box_items<'a>(m: Mat4, corners: &'a [[Vec4; 8]]) -> Vec<DrawItem<'a>> {
    corners
        .iter()
        .enumerate()
        .map(|(k, c)| DrawItem {
            clip_from_local: m,
            positions: c,
            triangles: &AABB_TRIANGLES,
            object: k as u32,
            cull: raster::CullMode::None,
        })
        .collect()
}

#[test]
fn parallel_batch_equals_serial() {
    let (w, h) = (300u32, 260u32);
    let m = perspective(1.0, w as f32 / h as f32, 0.5);
    let boxes = scattered_boxes(200, 5.0);
    let corners: Vec<[Vec4; 8]> = boxes.iter().map(|(a, b)| aabb_corners(*a, *b)).collect();
    let items = box_items(m, &corners);
    let mut a = DepthTarget::new(w, h, TileSize::T8, true).unwrap();
    a.set_threads(1);
    a.draw_batch(&items, Coverage::Standard).unwrap();
    let mut b = DepthTarget::new(w, h, TileSize::T8, true).unwrap();
    b.set_threads(3);
    b.draw_batch(&items, Coverage::Standard).unwrap();
    assert_eq!(a.depth_rows(), b.depth_rows());
    for y in 0..h {
        for x in 0..w {
            assert_eq!(a.id_at(x, y), b.id_at(x, y));
        }
    }
    check_hiz(&a).unwrap();
    check_hiz(&b).unwrap();
    let (sa, sb) = (a.stats(), b.stats());
    assert_eq!(
        (sa.triangles_in, sa.pixels_written),
        (sb.triangles_in, sb.pixels_written)
    );
    let opts = QueryOptions::default();
    let (mut qa, mut qb) = (Vec::new(), Vec::new());
    a.query_aabbs(m, &boxes, &opts, None, &mut qa).unwrap();
    b.query_aabbs(m, &boxes, &opts, None, &mut qb).unwrap();
    assert_eq!(qa, qb);
    assert!(qa.contains(&0) && qa.iter().any(|&c| c > 0));
}

/// A parallel batch into a row window draws what the full batch draws
/// there, and nothing elsewhere.
#[test]
fn parallel_batch_keeps_to_the_row_window() {
    let (w, h) = (320u32, 256u32);
    let m = perspective(1.0, w as f32 / h as f32, 0.5);
    let corners: Vec<[Vec4; 8]> = scattered_boxes(150, 6.0)
        .iter()
        .map(|(a, b)| aabb_corners(*a, *b))
        .collect();
    let items = box_items(m, &corners);
    let mut full = DepthTarget::new(w, h, TileSize::T8, true).unwrap();
    full.set_threads(3);
    full.draw_batch(&items, Coverage::Standard).unwrap();
    for rows in [(5, 17), (0, 3), (30, 32), (12, 12)] {
        let mut part = DepthTarget::new(w, h, TileSize::T8, true).unwrap();
        part.set_threads(3);
        part.set_draw_rows(Some(rows));
        part.draw_batch(&items, Coverage::Standard).unwrap();
        check_hiz(&part).unwrap();
        for y in 0..h {
            let inside = (rows.0..rows.1).contains(&(y / 8));
            for x in 0..w {
                let want = if inside { full.depth_at(x, y) } else { None };
                assert_eq!(part.depth_at(x, y), want, "({x}, {y}), rows {rows:?}");
                let want = if inside { full.id_at(x, y) } else { None };
                assert_eq!(part.id_at(x, y), want, "({x}, {y}), rows {rows:?}");
            }
        }
    }
    assert!(full.depth_rows()[..w as usize * 40]
        .iter()
        .any(|&d| d != BACKGROUND));
}

#[test]
fn box_behind_wall_is_hidden_and_box_around_eye_is_visible() {
    let (w, h) = (64u32, 48u32);
    let m = perspective(1.0, w as f32 / h as f32, 0.5);
    let mut t = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
    // A wall at z = −5 far wider than the view.
    t.draw_aabb(
        m,
        Vec3::new(-100.0, -100.0, -5.1),
        Vec3::new(100.0, 100.0, -5.0),
        0,
        Coverage::Standard,
    );
    let o = QueryOptions::default();
    assert_eq!(
        t.query_aabb(
            m,
            Vec3::new(-1.0, -1.0, -9.0),
            Vec3::new(1.0, 1.0, -7.0),
            &o,
            None
        )
        .unwrap(),
        0
    );
    // The wall's own box tests visible against a buffer holding it (GEQUAL).
    assert!(
        t.query_aabb(
            m,
            Vec3::new(-100.0, -100.0, -5.1),
            Vec3::new(100.0, 100.0, -5.0),
            &o,
            None
        )
        .unwrap()
            > 0
    );
    // Boxes containing the eye, cut by the near rectangle, or tiny inside the apex pyramid.
    for (a, b) in [
        (Vec3::splat(-1.0), Vec3::splat(1.0)),
        (Vec3::new(-0.1, -0.1, -0.6), Vec3::new(0.1, 0.1, -0.4)),
        (Vec3::new(-0.01, -0.01, -0.3), Vec3::new(0.01, 0.01, -0.29)),
        (Vec3::splat(-1000.0), Vec3::splat(1000.0)),
    ] {
        assert_eq!(t.query_aabb(m, a, b, &o, None).unwrap(), VISIBLE, "{a} {b}");
    }
    // Wholly behind the near plane, outside the apex pyramid: 0.
    assert_eq!(
        t.query_aabb(
            m,
            Vec3::new(5.0, 5.0, 1.0),
            Vec3::new(6.0, 6.0, 2.0),
            &o,
            None
        )
        .unwrap(),
        0
    );
    // Outside the frustum: 0.
    assert_eq!(
        t.query_aabb(
            m,
            Vec3::new(50.0, 0.0, -3.0),
            Vec3::new(51.0, 1.0, -2.0),
            &o,
            None
        )
        .unwrap(),
        0
    );
}

#[test]
fn orthographic_apex_prism_reaches_toward_the_light() {
    // Orthographic reversed Z: depth = 1 at z_view = −1, 0 at z_view = −101; w = 1.
    let m = Mat4::from_cols(
        Vec4::new(0.1, 0.0, 0.0, 0.0),
        Vec4::new(0.0, 0.1, 0.0, 0.0),
        Vec4::new(0.0, 0.0, 0.01, 0.0),
        Vec4::new(0.0, 0.0, 1.01, 1.0),
    );
    // Far behind the near plane toward the light but over the near rectangle: visible.
    assert!(meets_apex_region(
        &m,
        Vec3::new(-1.0, -1.0, 50.0),
        Vec3::new(1.0, 1.0, 60.0)
    ));
    // Beside the prism: not.
    assert!(!meets_apex_region(
        &m,
        Vec3::new(20.0, -1.0, 50.0),
        Vec3::new(21.0, 1.0, 60.0)
    ));
    // In the view volume: not.
    assert!(!meets_apex_region(
        &m,
        Vec3::new(-1.0, -1.0, -50.0),
        Vec3::new(1.0, 1.0, -40.0)
    ));
}

#[test]
fn receivers_restrict_query_counts() {
    let (w, h) = (32u32, 32u32);
    let m = perspective(1.0, 1.0, 0.5);
    let mut t = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
    let mut r = ReceiverTarget::for_target(&t);
    // Receivers on a plane at z = −4 over the left half of the view.
    let f = 1.0 / 0.5f32.tan();
    let mut pts = Vec::new();
    for y in 0..h {
        for x in 0..w / 2 {
            let nx = (x as f32 + 0.5) / w as f32 * 2.0 - 1.0;
            let ny = 1.0 - (y as f32 + 0.5) / h as f32 * 2.0;
            pts.push(Vec4::new(nx * 4.0 / f, ny * 4.0 / f, -4.0, 1.0));
        }
    }
    r.mark_points(m, &pts);
    let quad = |z: f32| {
        [
            Vec4::new(-9.0, -9.0, z, 1.0),
            Vec4::new(9.0, -9.0, z, 1.0),
            Vec4::new(9.0, 9.0, z, 1.0),
            Vec4::new(-9.0, 9.0, z, 1.0),
        ]
    };
    let tris = [[0, 1, 2], [0, 2, 3]];
    let o = QueryOptions::default();
    let q = quad(-3.0);
    let item = DrawItem {
        clip_from_local: m,
        positions: &q,
        triangles: &tris,
        object: 0,
        cull: raster::CullMode::None,
    };
    // In front of the receivers: counts exactly the marked half.
    assert_eq!(t.query(&item, &o, Some(&r)).unwrap(), w * h / 2);
    assert_eq!(t.query(&item, &o, None).unwrap(), w * h);
    // Any-samples: the lower-right triangle's centroid lies over the unmarked
    // half, so its probe fails and traversal finds the marked pixels left of it.
    let any = QueryOptions {
        mode: QueryMode::Any,
        ..Default::default()
    };
    let lower_right = DrawItem {
        triangles: &tris[..1],
        ..item
    };
    let before = t.stats().pixels_tested;
    assert_eq!(t.query(&lower_right, &any, Some(&r)).unwrap(), 1);
    assert!(t.stats().pixels_tested > before + 1, "traversal ran");
    assert_eq!(t.query(&item, &any, Some(&r)).unwrap(), 1);
    // Behind the receivers: nothing.
    let q = quad(-5.0);
    let item = DrawItem {
        clip_from_local: m,
        positions: &q,
        triangles: &tris,
        object: 0,
        cull: raster::CullMode::None,
    };
    assert_eq!(t.query(&item, &o, Some(&r)).unwrap(), 0);
    assert_eq!(t.query(&item, &any, Some(&r)).unwrap(), 0);
    let _ = &mut t;
}

fn backend_script(b: &mut dyn OcclusionBackend) -> Vec<u32> {
    let m = perspective(1.0, 4.0 / 3.0, 0.5);
    let mut ids = Vec::new();
    let mut out = Vec::new();
    b.clear();
    for k in 0..40 {
        let f = k as f32;
        let c = Vec3::new(
            (f * 1.37).sin() * 4.0,
            (f * 0.71).cos() * 3.0,
            -4.0 - (f * 0.53).sin().abs() * 20.0,
        );
        let (min, max) = (c - Vec3::splat(0.5), c + Vec3::splat(0.6));
        ids.push(
            b.issue_query(QueryCommand::Aabb {
                clip_from_local: m,
                min,
                max,
                options: QueryOptions::default(),
            })
            .unwrap(),
        );
        let corners: Arc<[Vec4]> = aabb_corners(min, max).to_vec().into();
        b.draw(DrawCommand {
            clip_from_local: m,
            positions: corners,
            triangles: AABB_TRIANGLES.to_vec().into(),
            object: k,
            coverage: Coverage::Standard,
            cull: CullMode::None,
            whole: raster::Whole::No,
        })
        .unwrap();
        if k % 7 == 3 {
            out.push(b.wait(ids[k as usize / 2]));
        }
    }
    for id in ids {
        out.push(b.wait(id));
    }
    b.finish();
    out
}

#[test]
fn backends_give_identical_counts() {
    let t = || DepthTarget::new(80, 60, TileSize::T8, true).unwrap();
    let a = backend_script(&mut SyncBackend::new(t()));
    let b = backend_script(&mut SimulatedBackend::new(t(), Latency::Commands(3)));
    let c = backend_script(&mut ThreadedBackend::new(t()));
    assert_eq!(a, b);
    assert_eq!(a, c);
    assert!(a.iter().any(|&n| n > 0));
}

/// Runs of draws (1 to 9, some conservative among standard ones, some of
/// those convex and drawn whole, in every cull mode) between
/// queries, on a target large enough for parallel batches: the bundled
/// backends hold draws and draw each run as one batch before the next
/// query; their counts and final depth and ids equal the threaded backend's,
/// which draws each at once.
#[test]
fn held_draws_equal_immediate_draws() {
    fn script(b: &mut (impl OcclusionBackend + ReadTarget)) -> (Vec<u32>, Vec<f32>, Vec<u64>) {
        let m = perspective(1.0, 4.0 / 3.0, 0.5);
        let boxes: Vec<(Vec3, Vec3)> = (0..90)
            .map(|k| {
                let f = k as f32;
                let c = Vec3::new(
                    (f * 1.37).sin() * 5.0,
                    (f * 0.71).cos() * 3.5,
                    -3.0 - (f * 0.53).sin().abs() * 25.0,
                );
                (c - Vec3::splat(0.7), c + Vec3::splat(0.9))
            })
            .collect();
        let count = QueryOptions {
            mode: QueryMode::Count,
            ..Default::default()
        };
        let mut out = Vec::new();
        b.clear();
        let mut k = 0;
        let mut run = 1;
        while k < boxes.len() {
            for (j, &(min, max)) in boxes.iter().enumerate().skip(k).take(run) {
                b.draw(DrawCommand {
                    clip_from_local: m,
                    positions: aabb_corners(min, max).to_vec().into(),
                    triangles: AABB_TRIANGLES.to_vec().into(),
                    object: j as u32,
                    coverage: match j % 5 {
                        2 => Coverage::Outer(DepthPick::Nearest),
                        4 => Coverage::Inner(DepthPick::Farthest),
                        _ => Coverage::Standard,
                    },
                    cull: [CullMode::None, CullMode::Back, CullMode::Front][j % 3],
                    // Boxes are convex and closed: some of the inner ones
                    // drawn whole.
                    whole: [
                        raster::Whole::No,
                        raster::Whole::Convex,
                        raster::Whole::Closed,
                    ][j % 3],
                })
                .unwrap();
            }
            k += run;
            run = run % 9 + 1;
            let ids: Vec<QueryId> = boxes
                .iter()
                .map(|&(min, max)| {
                    b.issue_query(QueryCommand::Aabb {
                        clip_from_local: m,
                        min,
                        max,
                        options: count,
                    })
                    .unwrap()
                })
                .collect();
            out.extend(ids.into_iter().map(|id| b.wait(id)));
        }
        b.finish();
        let (mut depth, mut ids) = (Vec::new(), Vec::new());
        b.read_target(&mut |t| {
            depth = t.depth_rows();
            for y in 0..t.height() {
                for x in 0..t.width() {
                    ids.push(
                        t.id_at(x, y)
                            .map_or(u64::MAX, |(o, k)| u64::from(o) << 32 | u64::from(k)),
                    );
                }
            }
        });
        (out, depth, ids)
    }
    let t = || DepthTarget::new(320, 256, TileSize::T8, true).unwrap();
    let want = script(&mut ThreadedBackend::new(t()));
    assert_eq!(script(&mut SyncBackend::new(t())), want);
    assert_eq!(
        script(&mut SimulatedBackend::new(t(), Latency::Commands(2))),
        want
    );
    // Later runs' queries see earlier runs' depth: some counts shrink.
    assert!(want.0.iter().any(|&n| n > 0));
    assert!(want
        .0
        .chunks(90)
        .zip(want.0.chunks(90).skip(1))
        .any(|(a, b)| a != b));
}

#[test]
fn simulated_latency_reveals_results_k_commands_later() {
    let m = perspective(1.0, 1.0, 0.5);
    let mut b = SimulatedBackend::new(
        DepthTarget::new(16, 16, TileSize::T8, false).unwrap(),
        Latency::Commands(2),
    );
    let q = || QueryCommand::Aabb {
        clip_from_local: m,
        min: Vec3::new(-1.0, -1.0, -5.0),
        max: Vec3::ONE.with_z(-4.0),
        options: QueryOptions::default(),
    };
    let id0 = b.issue_query(q()).unwrap();
    assert_eq!(b.poll(id0), None);
    let id1 = b.issue_query(q()).unwrap();
    assert_eq!(b.poll(id0), None);
    b.clear();
    let n = b.poll(id0).expect("two commands later");
    assert!(n > 0);
    assert_eq!(b.poll(id1), None);
    assert_eq!(b.wait(id1), n);
    assert_eq!(b.stats().waits_blocked, 1);
}

#[test]
fn threaded_backend_holds_results_until_the_gate_opens() {
    let m = perspective(1.0, 1.0, 0.5);
    let (mut b, gate) =
        ThreadedBackend::with_gate(DepthTarget::new(16, 16, TileSize::T8, false).unwrap());
    let q = |z: f32| QueryCommand::Aabb {
        clip_from_local: m,
        min: Vec3::new(-1.0, -1.0, z - 1.0),
        max: Vec3::ONE.with_z(z),
        options: QueryOptions::default(),
    };
    let ids: Vec<QueryId> = (0..5)
        .map(|k| b.issue_query(q(-4.0 - k as f32)).unwrap())
        .collect();
    for &id in &ids {
        assert_eq!(b.poll(id), None, "the worker is held");
    }
    gate.open();
    // Results arrive in order: once the last is there, all are.
    let last = b.wait(ids[4]);
    assert!(last > 0);
    for &id in &ids {
        assert!(b.poll(id).is_some());
    }
    let s = b.stats();
    assert_eq!((s.queries, s.waits), (5, 1));
}

/// Back-face culling: a closed box seen from outside leaves the depth of its
/// front faces (the same buffer as drawing all faces here); seen from inside it
/// draws nothing, so it hides nothing (culling stays conservative); a lone
/// back-facing triangle is counted as culled, and drawn by the other modes;
/// front culling draws a mirrored instance as back culling draws the original.
#[test]
fn back_face_culling_keeps_front_faces_and_never_hides_more() {
    let (w, h) = (64u32, 48u32);
    let m = perspective(1.0, w as f32 / h as f32, 0.5);
    let boxes = [
        (Vec3::new(-1.0, -0.7, -6.0), Vec3::new(0.8, 0.9, -4.0)),
        (Vec3::new(-3.0, -2.0, -9.0), Vec3::new(-1.5, 1.5, -7.5)),
        (Vec3::new(0.5, -3.0, -12.0), Vec3::new(4.0, -1.0, -8.0)),
    ];
    let draw = |cull: CullMode, boxes: &[(Vec3, Vec3)]| {
        let mut t = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
        for (k, &(a, b)) in boxes.iter().enumerate() {
            let corners = aabb_corners(a, b);
            let item = DrawItem {
                clip_from_local: m,
                positions: &corners,
                triangles: &AABB_TRIANGLES,
                object: k as u32,
                cull,
            };
            t.draw(&item, Coverage::Standard).unwrap();
        }
        t
    };
    let (mut all, mut front) = (draw(CullMode::None, &boxes), draw(CullMode::Back, &boxes));
    assert_eq!(all.depth_rows(), front.depth_rows());
    let (sa, sf) = (all.take_stats(), front.take_stats());
    assert_eq!(sa.triangles_in, sf.triangles_in);
    assert!(
        sf.triangles_culled >= sa.triangles_culled + 3 * 6 - 3,
        "{sf:?}"
    );
    assert!(sf.pixels_tested < sa.pixels_tested);
    // The eye inside a box: every face is a back face.
    let around = [(Vec3::splat(-2.0), Vec3::splat(2.0))];
    let (inside_all, inside_front) = (draw(CullMode::None, &around), draw(CullMode::Back, &around));
    assert!(inside_all.depth_rows().iter().all(|&d| d > 0.0));
    assert!(inside_front.depth_rows().iter().all(|&d| d == BACKGROUND));
    // One clockwise (back-facing) triangle.
    let mut t = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
    let cw = [
        Vec4::new(-0.5, -0.5, 0.5, 1.0),
        Vec4::new(0.0, 0.5, 0.5, 1.0),
        Vec4::new(0.5, -0.5, 0.5, 1.0),
    ];
    let item = DrawItem {
        clip_from_local: Mat4::IDENTITY,
        positions: &cw,
        triangles: &[[0, 1, 2]],
        object: 0,
        cull: CullMode::Back,
    };
    t.draw(&item, Coverage::Standard).unwrap();
    let s = t.take_stats();
    assert_eq!(
        (s.triangles_in, s.triangles_culled, s.pixels_written),
        (1, 1, 0)
    );
    for cull in [CullMode::None, CullMode::Front] {
        t.draw(&DrawItem { cull, ..item }, Coverage::Standard)
            .unwrap();
        assert!(t.take_stats().pixels_written > 0);
        t.clear();
    }
    // Front culling of a mirrored instance (a transform of negative
    // determinant) draws what back culling draws of the boxes themselves.
    let mirror = Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0));
    let mut mirrored = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
    for (k, &(a, b)) in boxes.iter().enumerate() {
        // The box in local space, outward; the mirror turns its faces.
        let corners = aabb_corners(Vec3::new(-b.x, a.y, a.z), Vec3::new(-a.x, b.y, b.z));
        let item = DrawItem {
            clip_from_local: m * mirror,
            positions: &corners,
            triangles: &AABB_TRIANGLES,
            object: k as u32,
            cull: CullMode::Front,
        };
        mirrored.draw(&item, Coverage::Standard).unwrap();
    }
    assert_eq!(mirrored.depth_rows(), front.depth_rows());
    assert_eq!(mirrored.take_stats().triangles_culled, sf.triangles_culled);
}
