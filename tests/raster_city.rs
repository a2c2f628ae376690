//! The raster bench's `visible_boxes` equals a brute-force pixel-centre reference
//! (f64 edge functions with the top-left rule on the rasterizer's own snapped
//! post-clip vertices, the same f32 depth, GREATER writes, GEQUAL queries) on
//! `city_4096` at small resolutions. Skips with a note when `../shared/data` is absent.

use glam::{DMat4, Vec3, Vec4};
use raster::{
    aabb_corners, facing, meets_apex_region, setup_triangle, Coverage, CullMode, DepthTarget,
    DrawItem, QueryMode, QueryOptions, SnappedVertex, TileSize, AABB_TRIANGLES,
};

type Boxes = Vec<(Vec3, Vec3)>;
type Cameras = Vec<(String, scene::LookAt)>;

/// The buildings' boxes (not the ground) and the cameras of a box city.
fn city_boxes(loaded: &scene::load::Loaded) -> (Boxes, Cameras) {
    let g = &loaded.graph;
    let mut boxes = Vec::new();
    for node in g.nodes() {
        if node.name == "ground" {
            continue;
        }
        for m in &node.meshes {
            let b = g.meshes()[m.index()].bounds();
            boxes.push((b.min, b.max));
        }
    }
    (boxes, loaded.cameras.clone())
}

/// The fan triangles of a snapped polygon, oriented, in the rasterizer's order.
fn fan(p: &[SnappedVertex]) -> Vec<[SnappedVertex; 3]> {
    let mut out = Vec::new();
    for i in 1..p.len().saturating_sub(1) {
        let (a, mut b, mut c) = (p[0], p[i], p[i + 1]);
        let area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
        if area == 0 {
            continue;
        }
        if area < 0 {
            std::mem::swap(&mut b, &mut c);
        }
        out.push([a, b, c]);
    }
    out
}

/// Calls `f(x, y, depth)` for every pixel centre the triangle covers (f64 edge
/// functions, top-left rule).
fn brute_force(t: &[SnappedVertex; 3], w: u32, h: u32, mut f: impl FnMut(u32, u32, f32)) {
    let v = t.map(|v| (v.x as f64, v.y as f64, v.z));
    let area = (v[1].0 - v[0].0) * (v[2].1 - v[0].1) - (v[1].1 - v[0].1) * (v[2].0 - v[0].0);
    let inv_area = 1.0 / area;
    let edge = |a: (f64, f64, f64), b: (f64, f64, f64), px: f64, py: f64| {
        let (ea, eb) = (-(b.1 - a.1), b.0 - a.0);
        let e = ea * (px - a.0) + eb * (py - a.1);
        let tl = ea > 0.0 || (ea == 0.0 && eb > 0.0);
        (e, e > 0.0 || (e == 0.0 && tl))
    };
    let xmin = v.iter().map(|p| p.0).fold(f64::MAX, f64::min);
    let xmax = v.iter().map(|p| p.0).fold(f64::MIN, f64::max);
    let ymin = v.iter().map(|p| p.1).fold(f64::MAX, f64::min);
    let ymax = v.iter().map(|p| p.1).fold(f64::MIN, f64::max);
    let x0 = ((xmin / 256.0).floor() as i64 - 1).max(0) as u32;
    let x1 = ((xmax / 256.0).ceil() as i64 + 1).min(w as i64 - 1);
    let y0 = ((ymin / 256.0).floor() as i64 - 1).max(0) as u32;
    let y1 = ((ymax / 256.0).ceil() as i64 + 1).min(h as i64 - 1);
    if x1 < 0 || y1 < 0 {
        return;
    }
    for y in y0..=y1 as u32 {
        for x in x0..=x1 as u32 {
            let (px, py) = (x as f64 * 256.0 + 128.0, y as f64 * 256.0 + 128.0);
            let e0 = edge(v[1], v[2], px, py);
            let e1 = edge(v[2], v[0], px, py);
            let e2 = edge(v[0], v[1], px, py);
            if e0.1 && e1.1 && e2.1 {
                let z = ((e0.0 * v[0].2 + e1.0 * v[1].2 + e2.0 * v[2].2) * inv_area) as f32;
                f(x, y, z);
            }
        }
    }
}

#[test]
fn visible_boxes_match_brute_force_on_city_4096() {
    let Some(city) = testkit::BenchScene::box_city("city_4096") else {
        return;
    };
    let (mut boxes, cameras) = city_boxes(&city.loaded);
    // visible_boxes without culling, per view, to compare with back-face culling.
    let mut unculled = std::collections::HashMap::new();
    for (name, look) in &cameras {
        // 320×240 takes the parallel (binned) path.
        for ((w, h), cull) in [(160u32, 120u32), (256, 200), (320, 240)]
            .into_iter()
            .flat_map(|r| [(r, CullMode::None), (r, CullMode::Back)])
        {
            let cam = look.camera(w as f64 / h as f64).unwrap();
            let eye = cam.position;
            boxes.sort_by(|p, q| {
                let d = |b: &(Vec3, Vec3)| ((b.0 + b.1).as_dvec3() * 0.5 - eye).length_squared();
                d(p).total_cmp(&d(q))
            });
            let m = scene::transform::clip_from_local(&cam, &DMat4::IDENTITY);
            let corners: Vec<[Vec4; 8]> = boxes.iter().map(|&(a, b)| aabb_corners(a, b)).collect();
            // The rasterizer, as the bench runs it.
            let items: Vec<DrawItem> = corners
                .iter()
                .enumerate()
                .map(|(k, c)| DrawItem {
                    clip_from_local: m,
                    positions: c,
                    triangles: &AABB_TRIANGLES,
                    object: k as u32,
                    cull,
                })
                .collect();
            let mut t = DepthTarget::new(w, h, TileSize::T8, false).unwrap();
            t.draw_batch(&items, Coverage::Standard).unwrap();
            let mut res = Vec::new();
            let opts = QueryOptions {
                coverage: Coverage::Standard,
                mode: QueryMode::Any,
            };
            t.query_aabbs(m, &boxes, &opts, None, &mut res).unwrap();
            let visible = res.iter().filter(|&&n| n > 0).count();
            // The brute-force reference (occluders culled by the same facing rule).
            let mut depth = vec![-1.0f32; (w * h) as usize];
            for c in &corners {
                for tri in AABB_TRIANGLES {
                    let clip = tri.map(|i| m * c[i as usize]);
                    if cull.skips(facing(clip)) {
                        continue;
                    }
                    let s = setup_triangle(clip, w, h);
                    for ft in fan(s.polygon()) {
                        brute_force(&ft, w, h, |x, y, z| {
                            let d = &mut depth[(y * w + x) as usize];
                            if z > *d {
                                *d = z;
                            }
                        });
                    }
                }
            }
            let mut expect = 0;
            for (k, c) in corners.iter().enumerate() {
                let (a, b) = boxes[k];
                let mut vis = meets_apex_region(&m, a, b);
                for tri in AABB_TRIANGLES {
                    if vis {
                        break;
                    }
                    let s = setup_triangle(tri.map(|i| m * c[i as usize]), w, h);
                    for ft in fan(s.polygon()) {
                        brute_force(&ft, w, h, |x, y, z| {
                            vis |= z >= depth[(y * w + x) as usize];
                        });
                    }
                }
                expect += usize::from(vis);
            }
            eprintln!("city_4096 {name} {w}x{h} cull {cull:?}: visible_boxes {visible}");
            assert_eq!(visible, expect, "{name} {w}x{h} {cull:?}");
            // Culling the occluders' back faces (the bench's default) finds the
            // same boxes visible as drawing all faces.
            match cull {
                CullMode::None => {
                    unculled.insert((name.clone(), w), visible);
                }
                _ => assert_eq!(Some(&visible), unculled.get(&(name.clone(), w))),
            }
            // Depth buffers agree pixel for pixel.
            let got = t.depth_rows();
            assert_eq!(got, depth, "{name} {w}x{h} {cull:?}");
        }
    }
}
