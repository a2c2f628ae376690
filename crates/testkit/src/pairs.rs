//! Baselines of [`shadowgen::SweepPrune`]: the overlapping pairs of a set of
//! image-plane rectangles by testing every pair, and by an obvhs BVH query.
//! Both return `(a, b)` with `a < b`, sorted.

use obvhs::aabb::Aabb;
use shadowgen::ImageRect;

/// Every pair tested: O(n²).
pub fn brute_pairs(rects: &[Option<ImageRect>]) -> Vec<(u32, u32)> {
    let present: Vec<(u32, ImageRect)> = (rects.iter().enumerate())
        .filter_map(|(id, r)| r.map(|r| (id as u32, r.sanitized())))
        .collect();
    let mut out = Vec::new();
    for (i, (a, ra)) in present.iter().enumerate() {
        for (b, rb) in &present[i + 1..] {
            if ra.overlaps(rb) {
                out.push((*a, *b));
            }
        }
    }
    out
}

/// A BVH over the rectangles (obvhs, one box per leaf) queried with each one.
/// Infinite bounds are cut to ±1e30 (obvhs sorts by centroid), so the
/// rectangles must lie inside that range to match the other methods.
pub fn bvh_pairs(rects: &[Option<ImageRect>]) -> Vec<(u32, u32)> {
    let (ids, boxes): (Vec<u32>, Vec<Aabb>) = (rects.iter().enumerate())
        .filter_map(|(id, r)| r.map(|r| (id as u32, to_aabb(&r.sanitized()))))
        .unzip();
    if boxes.is_empty() {
        return Vec::new();
    }
    let mut params = obvhs::BvhBuildParams::fast_build();
    params.max_prims_per_leaf = 1;
    let bvh = obvhs::bvh2::builder::build_bvh2(&boxes, params, &mut Default::default());
    let mut out = Vec::new();
    for (k, b) in boxes.iter().enumerate() {
        bvh.aabb_traverse(*b, |bvh, node| {
            let node = &bvh.nodes[node as usize];
            let first = node.first_index as usize;
            for &p in &bvh.primitive_indices[first..first + node.prim_count as usize] {
                if (p as usize) > k && boxes[p as usize].intersect_aabb(b) {
                    out.push((ids[k], ids[p as usize]));
                }
            }
            true
        });
    }
    out.sort_unstable();
    out
}

fn to_aabb(r: &ImageRect) -> Aabb {
    let c = |v: f32| v.clamp(-1e30, 1e30);
    Aabb::new(
        glam::Vec3A::new(c(r.min[0]), c(r.min[1]), 0.0),
        glam::Vec3A::new(c(r.max[0]), c(r.max[1]), 0.0),
    )
}
