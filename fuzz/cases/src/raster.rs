//! The rasterizer on arbitrary triangles: clip-space vertices from the
//! fuzzer's bytes (mostly small values; sometimes any bit pattern: w ≤ 0,
//! NaN, ∞, huge and tiny values), out-of-range indices among them, every
//! coverage mode, cull mode and tile size, on a small target. Checked, as the
//! raster tests state them:
//! - no panic; an index past the vertices is an error, not a crash;
//! - every written depth is finite and within [0, 1] (reversed Z);
//! - the hierarchical z contains every pixel depth of its tile, and counts
//!   its background pixels;
//! - depth and primitive ids do not depend on draw order;
//! - the portable kernels give the same depth, ids and counters as the
//!   detected SIMD level (differential).

use crate::Bytes;
use glam::{Mat4, Vec4};
use shadowcull::raster::{
    Coverage, CullMode, DepthPick, DepthTarget, DrawItem, InstructionSet, TileSize,
};

/// Mostly small values; one in eight any bit pattern, one in eight large.
fn coordinate(b: &mut Bytes) -> f32 {
    match b.u8() % 8 {
        0 => b.any_f32(),
        1 => b.small(1e3),
        _ => b.small(1.0 / 16.0),
    }
}

/// Asserts that `b` holds `a`'s depth and ids.
fn same_image(a: &DepthTarget, b: &DepthTarget, what: &str) {
    assert_eq!(a.depth_rows(), b.depth_rows(), "{what} changed depth");
    for y in 0..a.height() {
        for x in 0..a.width() {
            assert_eq!(
                a.id_at(x, y),
                b.id_at(x, y),
                "{what} changed the id at ({x}, {y})"
            );
        }
    }
}

/// Draws `tris` one item each, in `order`, into a fresh target.
fn draw(
    (w, h, tile): (u32, u32, TileSize),
    (cov, cull, isa): (Coverage, CullMode, InstructionSet),
    positions: &[Vec4],
    tris: &[[u32; 3]],
    order: impl Iterator<Item = usize>,
) -> DepthTarget {
    let mut t = DepthTarget::new(w, h, tile, true).expect("a small target");
    t.set_instruction_set(isa);
    for k in order {
        let item = DrawItem {
            clip_from_local: Mat4::IDENTITY,
            positions,
            triangles: std::slice::from_ref(&tris[k]),
            object: k as u32,
            cull,
        };
        let bad = tris[k].iter().any(|&i| i as usize >= positions.len());
        assert_eq!(
            t.draw(&item, cov).is_err(),
            bad,
            "triangle {k}: {:?}",
            tris[k]
        );
    }
    t
}

/// One fuzz input through the target (a panic is a finding).
pub fn run(data: &[u8]) {
    let mut b = Bytes(data);
    let w = 1 + u32::from(b.u8() % 64);
    let h = 1 + u32::from(b.u8() % 64);
    let tile = [TileSize::T4, TileSize::T8, TileSize::T16][usize::from(b.u8() % 3)];
    let pick = |b: &mut Bytes| {
        if b.u8().is_multiple_of(2) {
            DepthPick::Nearest
        } else {
            DepthPick::Farthest
        }
    };
    let cov = match b.u8() % 3 {
        0 => Coverage::Standard,
        1 => Coverage::Outer(pick(&mut b)),
        _ => Coverage::Inner(pick(&mut b)),
    };
    let cull = [CullMode::None, CullMode::Back, CullMode::Front][usize::from(b.u8() % 3)];
    let n = 1 + usize::from(b.u8() % 12);
    let positions: Vec<Vec4> = (0..n)
        .map(|_| {
            Vec4::new(
                coordinate(&mut b),
                coordinate(&mut b),
                coordinate(&mut b),
                coordinate(&mut b),
            )
        })
        .collect();
    let count = 1 + usize::from(b.u8() % 8);
    let tris: Vec<[u32; 3]> = (0..count)
        .map(|_| {
            [0; 3].map(|_| match b.u8() {
                255 => b.u32(),
                k => u32::from(k) % n as u32,
            })
        })
        .collect();
    let frame = (w, h, tile);
    let detected = InstructionSet::detected();
    let a = draw(frame, (cov, cull, detected), &positions, &tris, 0..count);
    for y in 0..h {
        for x in 0..w {
            if let Some(z) = a.depth_at(x, y) {
                assert!(
                    z.is_finite() && (0.0..=1.0).contains(&z),
                    "depth {z} at ({x}, {y})"
                );
            }
        }
    }
    let (tx, ty) = a.tile_counts();
    let s = a.tile_pixels();
    for j in 0..ty {
        for i in 0..tx {
            let bounds = a.tile_bounds(i, j);
            let mut background = 0;
            for y in j * s..((j + 1) * s).min(h) {
                for x in i * s..((i + 1) * s).min(w) {
                    match (a.depth_at(x, y), bounds) {
                        (None, _) => background += 1,
                        (Some(z), Some((lo, hi))) => assert!(lo <= z && z <= hi),
                        (Some(_), None) => panic!("tile ({i}, {j}) lost a pixel"),
                    }
                }
            }
            assert_eq!(background, a.tile_background(i, j));
        }
    }
    let reversed = draw(
        frame,
        (cov, cull, detected),
        &positions,
        &tris,
        (0..count).rev(),
    );
    same_image(&a, &reversed, "the reversed draw order");
    if detected != InstructionSet::Portable {
        let p = draw(
            frame,
            (cov, cull, InstructionSet::Portable),
            &positions,
            &tris,
            0..count,
        );
        same_image(&a, &p, "the portable kernels");
        assert_eq!(a.stats(), p.stats());
    }
}
