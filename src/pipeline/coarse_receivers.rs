//! The light pass's receivers from a coarse eye pass (a culling resolution
//! below the output's) [Steiner §4.3.1]: pieces of surface, not points.
//!
//! The coarse pass draws its occluders inner-conservative at their farthest
//! depth, so its depth `Z_occ` at a coarse pixel is a bound no eye sample of
//! the pixel is hidden behind: a receiver point visible at an output pixel
//! centre in it lies on a potentially shadowed receiver's triangle that
//! touches the pixel, no farther than `Z_occ`. This producer draws every
//! receiving triangle of the PSR over the coarse pixels (outer coverage, at
//! a nearest-depth bound: the slice's nearest, and the triangle's plane at
//! the pixel's nearest corner), keeps per coarse row the runs of pixels
//! where that bound is not behind `Z_occ`, and sends each run's piece of
//! the triangle, clipped to the run's frustum (and the near plane), as a
//! receiver polygon ([`visibility::ReceiverPolygons`]): the light pass
//! marks each polygon whole, so every output pixel's receiver point inside
//! it is marked, at a depth no nearer, whatever the output resolution.

use super::eye::SkipLights;
use crate::mask::unlit_by_facing;
use glam::{DVec3, DVec4};
use raster::{CullMode, DepthTarget};
use rayon::prelude::*;
use scene::{Camera, ObjectId, Scene};

/// Receiving objects per part of the parallel work.
const PART_OBJECTS: usize = 32;

/// Widening of a run's frustum, in coarse pixels: covers the rounding of
/// its planes, so that output pixel centres on a coarse pixel's edge stay
/// inside.
const RUN_SLACK_PX: f64 = 1.0 / 1024.0;

/// Relative widening of the nearest-depth bound before it is compared with
/// the coarse depth: covers the rasterizer's depth error and rounding
/// ([`raster::DEPTH_ERROR`] is 2⁻²³) many times over.
const DEPTH_SLACK: f64 = 1.0 / 65536.0;

/// A vertex of a clipped triangle: eye-relative world point and clip point.
#[derive(Clone, Copy)]
struct Vertex {
    v: DVec3,
    c: DVec4,
}

/// The receiving objects of `psr` (slots) as receiver polygons, in
/// `parts` (their buffers reused), from the coarse pass `coarse` of
/// `camera`; `skips` gives each polygon the lights that may leave it out.
pub(crate) fn coarse_receivers_into(
    scene: &Scene,
    camera: &Camera,
    (coarse, rows, bounds): (&DepthTarget, &mut Vec<f32>, &mut Vec<(f32, f32)>),
    psr: &[ObjectId],
    skips: SkipLights<'_>,
    parts: &mut Vec<visibility::ReceiverPoints>,
) {
    let chunks = psr.len().div_ceil(PART_OBJECTS).max(1);
    parts.resize_with(chunks, Default::default);
    parts.truncate(chunks);
    coarse.depth_rows_into(rows);
    segment_bounds(rows, coarse.width() as usize, bounds);
    let grid = Grid::new(camera, coarse, (rows, bounds));
    parts.par_iter_mut().enumerate().for_each(|(k, part)| {
        part.points.clear();
        part.joined.clear();
        part.skip.clear();
        part.polygons.clear();
        let ids = psr.iter().skip(k * PART_OBJECTS).take(PART_OBJECTS);
        for &id in ids {
            object_polygons(scene, camera, &grid, id, skips, part);
        }
    });
}

/// Pixels per segment of a row whose depth bounds the producer keeps.
const SEGMENT: u32 = 8;

/// Per row of `rows` (`w` wide), per segment of [`SEGMENT`] pixels, the
/// least and greatest depth, into `bounds`.
fn segment_bounds(rows: &[f32], w: usize, bounds: &mut Vec<(f32, f32)>) {
    bounds.clear();
    for row in rows.chunks_exact(w) {
        bounds.extend(row.chunks(SEGMENT as usize).map(|s| {
            s.iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &z| {
                    (lo.min(z), hi.max(z))
                })
        }));
    }
}

/// The coarse pass as the producer reads it.
struct Grid<'a> {
    /// Its depths, row-major ([`raster::BACKGROUND`], −1, where nothing
    /// covers a pixel: no bound).
    rows: &'a [f32],
    /// Per row, per segment of [`SEGMENT`] pixels: the least and greatest
    /// depth there.
    bounds: &'a [(f32, f32)],
    /// Segments per row.
    segments: usize,
    w: f64,
    h: f64,
    clip: glam::DMat4,
}

impl<'a> Grid<'a> {
    fn new(
        camera: &Camera,
        target: &DepthTarget,
        (rows, bounds): (&'a [f32], &'a [(f32, f32)]),
    ) -> Self {
        Grid {
            rows,
            bounds,
            segments: target.width().div_ceil(SEGMENT) as usize,
            w: f64::from(target.width()),
            h: f64::from(target.height()),
            clip: camera.clip_from_eye_relative(),
        }
    }

    /// Pixel coordinates (row 0 at the top) and depth of clip point `c`.
    fn project(&self, c: DVec4) -> (f64, f64, f64) {
        let iw = 1.0 / c.w;
        (
            (c.x * iw + 1.0) * 0.5 * self.w,
            (1.0 - c.y * iw) * 0.5 * self.h,
            c.z * iw,
        )
    }
}

/// Appends object `id`'s receiver polygons to `part`.
fn object_polygons(
    scene: &Scene,
    camera: &Camera,
    grid: &Grid<'_>,
    id: ObjectId,
    skips: SkipLights<'_>,
    part: &mut visibility::ReceiverPoints,
) {
    let o = scene.object(id);
    if !(o.flags.visible && o.flags.receives) {
        return;
    }
    let mesh = scene.object_mesh(id);
    let cull = visibility::eye_cull(camera, o, mesh);
    let e = camera.position;
    for t in 0..mesh.triangles().len() {
        let tri = scene.world_triangle(id, t);
        let v = tri.map(|p| p - e);
        let c = v.map(|v| grid.clip * v.extend(1.0));
        // The eye pass skips the faces its culling names; one nearly edge-on
        // (which rounding could turn) is kept.
        if cull != CullMode::None && clearly_skipped(cull, &c, o.mirrored) {
            continue;
        }
        let mut skip = 0u32;
        for (k, light) in skips.lights.iter().enumerate() {
            if unlit_by_facing(&tri, e, light, skips.two_sided) {
                skip |= 1 << k;
            }
        }
        triangle_polygons(
            grid,
            [0, 1, 2].map(|i| Vertex { v: v[i], c: c[i] }),
            |poly| {
                part.polygons.push(poly.iter().map(|p| e + p.v), skip);
            },
        );
    }
}

/// Whether `cull` skips the triangle of clip points `c` (in the mesh's own
/// winding: `mirrored` objects' world triangles come reversed) with room to
/// spare: its facing determinant is beyond 10⁻⁹ of its terms' size.
fn clearly_skipped(cull: CullMode, c: &[DVec4; 3], mirrored: bool) -> bool {
    let det = |c: &[DVec4; 3]| {
        let terms = [
            c[0].x * (c[1].y * c[2].w - c[2].y * c[1].w),
            -c[1].x * (c[0].y * c[2].w - c[2].y * c[0].w),
            c[2].x * (c[0].y * c[1].w - c[1].y * c[0].w),
        ];
        let scale: f64 = (c.iter())
            .map(|p| p.x.abs() * (p.y.abs() + p.w.abs()))
            .sum::<f64>()
            * 2.0;
        (terms.iter().sum::<f64>(), scale)
    };
    let (d, scale) = det(c);
    let d = if mirrored { -d } else { d };
    if d.abs() <= 1e-9 * scale {
        return false;
    }
    let facing = if d > 0.0 {
        raster::Facing::Front
    } else {
        raster::Facing::Back
    };
    cull.skips(Some(facing))
}

/// A convex polygon of at most [`Poly::MAX`] vertices, on the stack: a
/// triangle clipped by the near plane and a run's four planes.
#[derive(Clone, Copy)]
struct Poly {
    v: [Vertex; Poly::MAX],
    n: usize,
}

impl Poly {
    /// A triangle (4), then four planes (one vertex each): 8, with room.
    const MAX: usize = 10;

    fn new() -> Self {
        Poly {
            v: [Vertex {
                v: DVec3::ZERO,
                c: DVec4::ZERO,
            }; Poly::MAX],
            n: 0,
        }
    }

    fn vertices(&self) -> &[Vertex] {
        &self.v[..self.n]
    }

    fn push(&mut self, v: Vertex) {
        // (Convex input keeps within MAX; a rounding-made extra is dropped
        // only past it, which planes through one polygon never reach.)
        if self.n < Poly::MAX {
            self.v[self.n] = v;
            self.n += 1;
        }
    }
}

/// Clips polygon `p` (into `out`) to `f(c) ≥ 0`, a linear function of the
/// clip point: the vertices interpolate their world points with it.
fn clip_polygon(p: &Poly, f: impl Fn(DVec4) -> f64, out: &mut Poly) {
    out.n = 0;
    let v = p.vertices();
    for (i, a) in v.iter().enumerate() {
        let b = v[(i + 1) % v.len()];
        let (fa, fb) = (f(a.c), f(b.c));
        if fa >= 0.0 {
            out.push(*a);
        }
        if (fa >= 0.0) != (fb >= 0.0) {
            let t = fa / (fa - fb);
            out.push(Vertex {
                v: a.v + (b.v - a.v) * t,
                c: a.c + (b.c - a.c) * t,
            });
        }
    }
}

/// Calls `emit` with the receiver polygons of one triangle: per coarse row
/// it touches, each run of pixels where it may be visible, as the
/// triangle's part within the run's frustum.
fn triangle_polygons(grid: &Grid<'_>, tri: [Vertex; 3], mut emit: impl FnMut(&[Vertex])) {
    // In front of the near plane (reversed Z: z ≤ w).
    let mut t = Poly::new();
    tri.into_iter().for_each(|v| t.push(v));
    let mut q = Poly::new();
    clip_polygon(&t, |c| c.w - c.z, &mut q);
    if q.n < 3 {
        return;
    }
    let mut s = [(0.0, 0.0, 0.0); Poly::MAX];
    for (s, p) in s.iter_mut().zip(q.vertices()) {
        *s = grid.project(p.c);
    }
    let s = &s[..q.n];
    if s.iter()
        .any(|p| !(p.0.is_finite() && p.1.is_finite() && p.2.is_finite()))
    {
        return;
    }
    let (ylo, yhi) = s
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.1), b.max(p.1))
        });
    let r0 = (ylo - 1.0).ceil().max(0.0);
    let r1 = yhi.floor().min(grid.h - 1.0);
    if r0 > r1 {
        return;
    }
    let plane = depth_plane(s);
    let (mut a, mut b) = (Poly::new(), Poly::new());
    let ndc_x = |px: f64| 2.0 * px / grid.w - 1.0;
    let ndc_y = |py: f64| 1.0 - 2.0 * py / grid.h;
    // Emits the triangle within rows `ra..=rb` and columns `start..=end`,
    // the frustum widened by the slack.
    let mut piece = |(ra, rb): (u32, u32), (start, end): (u32, u32)| {
        let (yt, yb) = (
            ndc_y(f64::from(ra) - RUN_SLACK_PX),
            ndc_y(f64::from(rb) + 1.0 + RUN_SLACK_PX),
        );
        clip_polygon(&q, |c| c.y - yb * c.w, &mut a);
        clip_polygon(&a, |c| yt * c.w - c.y, &mut b);
        let (xl, xr) = (
            ndc_x(f64::from(start) - RUN_SLACK_PX),
            ndc_x(f64::from(end) + 1.0 + RUN_SLACK_PX),
        );
        clip_polygon(&b, |c| c.x - xl * c.w, &mut a);
        clip_polygon(&a, |c| xr * c.w - c.x, &mut b);
        if b.n > 0 {
            emit(b.vertices());
        }
    };
    // Rows where the triangle may be visible over all of its slice (cut to
    // the view), not yet emitted: one piece for all of them, within their
    // columns.
    let mut full: Option<((u32, u32), (u32, u32))> = None;
    let mut runs: [(u32, u32); 8] = [(0, 0); 8];
    for r in r0 as u32..=r1 as u32 {
        // The slice's x extent and nearest depth.
        let Some(((xlo, xhi), (_, znear))) =
            raster::band_extent(s, (f64::from(r), f64::from(r) + 1.0))
        else {
            continue;
        };
        let c0 = (xlo - 1.0).ceil().max(0.0);
        let c1 = xhi.floor().min(grid.w - 1.0);
        if c0.is_nan() || c1.is_nan() || c0 > c1 {
            continue;
        }
        let (c0, c1) = (c0 as u32, c1 as u32);
        let row = &grid.rows[r as usize * grid.w as usize..][..grid.w as usize];
        // The nearest-depth bound over pixel x, widened by the slack: the
        // slice's, and the plane's at the square's nearest corner.
        let bound = |x: u32| {
            let mut z = znear;
            if let Some((p, err)) = plane {
                let (xf, yf) = (f64::from(x), f64::from(r));
                z = z.min(p.greatest((xf, xf + 1.0), (yf, yf + 1.0)) + err);
            }
            z + DEPTH_SLACK * z.abs()
        };
        let visible = |x: u32| bound(x) >= f64::from(row[x as usize]);
        let (mut n, mut open): (usize, Option<u32>) = (0, None);
        let mut close = |open: &mut Option<u32>, end: u32, n: &mut usize| {
            if let Some(start) = open.take() {
                if *n == runs.len() {
                    // More runs than kept: the rest as one (a superset).
                    runs[*n - 1].1 = end;
                } else {
                    runs[*n] = (start, end);
                    *n += 1;
                }
            }
        };
        let mut x = c0;
        while x <= c1 {
            let k = (r as usize * grid.segments) + (x / SEGMENT) as usize;
            let end = (x | (SEGMENT - 1)).min(c1);
            let (lo, hi) = grid.bounds[k];
            // The bound is monotone along the row (the plane is affine),
            // so its ends bound it over the segment.
            let (ba, bb) = (bound(x), bound(end));
            if ba.min(bb) >= f64::from(hi) {
                open.get_or_insert(x);
            } else if ba.max(bb) < f64::from(lo) {
                close(&mut open, x.saturating_sub(1), &mut n);
            } else {
                for px in x..=end {
                    if visible(px) {
                        open.get_or_insert(px);
                    } else {
                        close(&mut open, px.saturating_sub(1), &mut n);
                    }
                }
            }
            x = end + 1;
        }
        close(&mut open, c1, &mut n);
        if n == 1 && runs[0] == (c0, c1) {
            full = Some(match full {
                Some(((ra, _), (x0, x1))) => ((ra, r), (x0.min(c0), x1.max(c1))),
                None => ((r, r), (c0, c1)),
            });
            continue;
        }
        if let Some((rows, cols)) = full.take() {
            piece(rows, cols);
        }
        for &(start, end) in &runs[..n] {
            piece((r, r), (start, end));
        }
    }
    if let Some((rows, cols)) = full {
        piece(rows, cols);
    }
}

/// The depth plane of a projected planar polygon and its error bound:
/// [`raster::DepthPlane::fit`]'s, and the rasterizer's snapping of
/// vertices (1/256 pixel at its own resolution, finer than this one's)
/// moving the plane by its slope.
fn depth_plane(s: &[(f64, f64, f64)]) -> Option<(raster::DepthPlane, f64)> {
    let (p, err) = raster::DepthPlane::fit(s)?;
    Some((p, err + (p.a.abs() + p.b.abs()) / 256.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every output pixel centre of a coarse pixel where a triangle may be
    /// visible lies in one of its polygons, and none where the coarse depth
    /// hides it: a triangle covering the view at distance 5, with a nearer
    /// occluder over the left half of coarse rows 2 and 3.
    #[test]
    fn polygons_hold_the_visible_centres_and_not_the_hidden_ones() {
        let camera = Camera::look_at(
            DVec3::new(0.3, -0.2, 5.0),
            DVec3::new(0.1, 0.4, 0.0),
            DVec3::Y,
            1.0,
            4.0 / 3.0,
            0.1,
        )
        .unwrap();
        let target = DepthTarget::new(8, 6, raster::TileSize::T8, false).unwrap();
        let e = camera.position;
        let world = [
            DVec3::new(-100.0, -100.0, 0.0),
            DVec3::new(100.0, -100.0, 0.0),
            DVec3::new(0.0, 100.0, 0.0),
        ];
        let hidden = |cx: u32, cy: u32| cx < 4 && (2..4).contains(&cy);
        for occluded in [false, true] {
            let mut rows = vec![raster::BACKGROUND; 48];
            for (k, z) in rows.iter_mut().enumerate() {
                if occluded && hidden(k as u32 % 8, k as u32 / 8) {
                    *z = 0.9;
                }
            }
            let mut bounds = Vec::new();
            segment_bounds(&rows, 8, &mut bounds);
            let grid = Grid::new(&camera, &target, (&rows, &bounds));
            let tri = world.map(|p| Vertex {
                v: p - e,
                c: grid.clip * (p - e).extend(1.0),
            });
            let mut polys = Vec::new();
            triangle_polygons(&grid, tri, |p| {
                polys.push(p.iter().map(|v| e + v.v).collect::<Vec<_>>())
            });
            // Unoccluded, all rows are whole: one polygon. Occluded: rows
            // 0–1 whole, rows 2 and 3 their right halves, rows 4–5 whole.
            assert_eq!(polys.len(), if occluded { 4 } else { 1 }, "{occluded}");
            // Inside a convex polygon of the plane z = 0 (either winding).
            let inside = |poly: &[DVec3], q: DVec3| {
                let sides: Vec<f64> = (0..poly.len())
                    .map(|i| {
                        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
                        (b.x - a.x) * (q.y - a.y) - (b.y - a.y) * (q.x - a.x)
                    })
                    .collect();
                sides.iter().all(|s| *s >= -1e-9) || sides.iter().all(|s| *s <= 1e-9)
            };
            let rays = camera.rays(800, 600);
            for y in (0..600).step_by(7).chain([599]) {
                for x in (0..800).step_by(9).chain([799]) {
                    let d = rays.direction(x as f64 + 0.5, y as f64 + 0.5);
                    let hit = e + d * (-e.z / d.z);
                    let held = polys.iter().any(|p| inside(p, hit));
                    let visible = !(occluded && hidden(x / 100, y / 100));
                    assert_eq!(held, visible, "{occluded}: pixel ({x}, {y}) at {hit}");
                }
            }
        }
    }
}
