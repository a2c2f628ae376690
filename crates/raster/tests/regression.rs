//! Bit-exact regression of whole frames: a procedural box city drawn and queried in
//! every tile size, with and without the id target, serially and in parallel. The
//! expected hashes were computed by the build before the traversal was optimised;
//! any change to depth, ids or query counts changes them.

use crate::perspective;
use glam::{Mat4, Vec3, Vec4};
use raster::*;

/// A deterministic city: a grid of boxes of pseudo-random heights, some straddling
/// the near plane and the guard band, seen from above at an angle.
fn city() -> (Mat4, Vec<(Vec3, Vec3)>) {
    let mut s = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut boxes = Vec::new();
    for i in 0..48 {
        for j in 0..48 {
            let (x, z) = (i as f32 * 4.0 - 96.0, j as f32 * 4.0 - 96.0);
            let (w, d) = (1.0 + 2.5 * rnd(), 1.0 + 2.5 * rnd());
            let h = 1.0 + 30.0 * rnd() * rnd();
            boxes.push((Vec3::new(x, 0.0, z), Vec3::new(x + w, h, z + d)));
        }
    }
    // Right-handed look-at: camera looks down its −z axis.
    let (eye, at) = (Vec3::new(-10.0, 22.0, 60.0), Vec3::new(0.0, 0.0, -20.0));
    let f = (at - eye).normalize();
    let r = f.cross(Vec3::Y).normalize();
    let u = r.cross(f);
    let view = Mat4::from_cols(
        Vec4::new(r.x, u.x, -f.x, 0.0),
        Vec4::new(r.y, u.y, -f.y, 0.0),
        Vec4::new(r.z, u.z, -f.z, 0.0),
        Vec4::new(-r.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
    );
    (perspective(1.1, 4.0 / 3.0, 0.3) * view, boxes)
}

fn fnv(h: u64, w: u64) -> u64 {
    w.to_le_bytes()
        .iter()
        .fold(h, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3))
}

/// Hash of depth, ids and query counts of one frame.
fn frame(tile: TileSize, ids: bool, threads: usize, mode: QueryMode) -> u64 {
    frame_stats(tile, ids, threads, mode).0
}

/// [`frame`] and the draw and query counters.
fn frame_stats(
    tile: TileSize,
    ids: bool,
    threads: usize,
    mode: QueryMode,
) -> (u64, RasterStats, RasterStats) {
    let (w, h) = (320u32, 240u32);
    let (m, boxes) = city();
    let mut order: Vec<usize> = (0..boxes.len()).collect();
    // Roughly front to back, as a renderer would.
    let eye = Vec3::new(-10.0, 22.0, 60.0);
    order.sort_by(|&a, &b| {
        let d = |k: usize| ((boxes[k].0 + boxes[k].1) * 0.5 - eye).length_squared();
        d(a).total_cmp(&d(b))
    });
    let corners: Vec<[Vec4; 8]> = boxes.iter().map(|(a, b)| aabb_corners(*a, *b)).collect();
    let items: Vec<DrawItem> = order
        .iter()
        .map(|&k| DrawItem {
            clip_from_local: m,
            positions: &corners[k],
            triangles: &AABB_TRIANGLES,
            object: k as u32,
            cull: raster::CullMode::None,
        })
        .collect();
    let mut t = DepthTarget::new(w, h, tile, ids).unwrap();
    t.set_threads(threads);
    if threads == 0 {
        // One draw call per mesh.
        for it in &items {
            t.draw(it, Coverage::Standard).unwrap();
        }
    } else {
        t.draw_batch(&items, Coverage::Standard).unwrap();
    }
    let draw_stats = t.take_stats();
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    for y in 0..h {
        for x in 0..w {
            let d = t
                .depth_at(x, y)
                .map_or(u64::MAX, |d| u64::from(d.to_bits()));
            hash = fnv(hash, d);
            if ids {
                let id = t
                    .id_at(x, y)
                    .map_or(u64::MAX, |(o, k)| (u64::from(o) << 32) | u64::from(k));
                hash = fnv(hash, id);
            }
        }
    }
    let mut out = Vec::new();
    let opts = QueryOptions {
        coverage: Coverage::Standard,
        mode,
    };
    t.query_aabbs(m, &boxes, &opts, None, &mut out).unwrap();
    for c in out {
        hash = fnv(hash, u64::from(c));
    }
    (hash, draw_stats, t.take_stats())
}

/// DESIGN.md "Determinism": counters do not depend on the thread count (nor on
/// drawing mesh by mesh instead of in a batch).
#[test]
fn counters_do_not_depend_on_threads() {
    for tile in [TileSize::T4, TileSize::T8, TileSize::T16] {
        for ids in [false, true] {
            let serial = frame_stats(tile, ids, 1, QueryMode::Count);
            assert!(serial.1.tiles_touched > 0 && serial.1.meshes_rejected_hiz > 0);
            for threads in [0, 2, 3, 7] {
                let other = frame_stats(tile, ids, threads, QueryMode::Count);
                assert_eq!(serial, other, "{tile:?} ids {ids} threads {threads}");
            }
        }
    }
}

#[test]
fn frames_are_bit_identical_to_the_reference_build() {
    let mut got = Vec::new();
    for tile in [TileSize::T4, TileSize::T8, TileSize::T16] {
        for ids in [false, true] {
            for mode in [QueryMode::Count, QueryMode::Any] {
                let h1 = frame(tile, ids, 1, mode);
                let h2 = frame(tile, ids, 2, mode);
                assert_eq!(h1, h2, "{tile:?} ids {ids} {mode:?}: threads differ");
                got.push(h1);
            }
        }
    }
    // Depth and ids do not depend on the tile size: the three groups are equal.
    let per_tile = [
        7172258613474262699,
        10355486671323000677,
        1278187018014681288,
        9329135055907040314,
    ];
    let expected: Vec<u64> = per_tile.iter().copied().cycle().take(12).collect();
    assert_eq!(got, expected);
}

/// `clear` (which resets only the tiles written since the last clear) leaves the
/// target as new, and a redrawn frame is identical to the first.
#[test]
fn clear_resets_every_written_tile() {
    let (m, boxes) = city();
    let corners: Vec<[Vec4; 8]> = boxes.iter().map(|(a, b)| aabb_corners(*a, *b)).collect();
    let items: Vec<DrawItem> = corners
        .iter()
        .enumerate()
        .map(|(k, c)| DrawItem {
            clip_from_local: m,
            positions: c,
            triangles: &AABB_TRIANGLES,
            object: k as u32,
            cull: raster::CullMode::None,
        })
        .collect();
    // 317 × 241: partial tiles on the right and bottom edges.
    for tile in [TileSize::T4, TileSize::T8, TileSize::T16] {
        let (w, h) = (317u32, 241u32);
        let fresh = DepthTarget::new(w, h, tile, true).unwrap();
        let mut t = DepthTarget::new(w, h, tile, true).unwrap();
        t.draw_batch(&items, Coverage::Standard).unwrap();
        let first = t.depth_rows();
        assert!(first.iter().any(|&d| d != BACKGROUND));
        t.clear();
        assert_eq!(t.depth_rows(), fresh.depth_rows());
        let (tx, ty) = t.tile_counts();
        for y in 0..ty {
            for x in 0..tx {
                assert_eq!(t.tile_bounds(x, y), None);
                assert_eq!(t.tile_background(x, y), fresh.tile_background(x, y));
            }
        }
        for y in 0..h {
            for x in 0..w {
                assert_eq!(t.id_at(x, y), None);
            }
        }
        t.draw_batch(&items, Coverage::Standard).unwrap();
        assert_eq!(t.depth_rows(), first);
    }
}
