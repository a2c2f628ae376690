//! Building an obvhs [`Bvh2`] over boxes: the steps of obvhs'
//! `build_bvh2` (PLOC, reinsertion, leaf collapse, reinsertion), without
//! its debug-build validation, and with a traversal stack that fits.
//!
//! Why: boxes that coincide (instances stacked in one place, removed
//! objects, a mesh holding one triangle many times) get equal Morton codes,
//! and PLOC pairs them into a chain as deep as their count. obvhs then
//! leaves `max_depth`, the size of its traversal stacks, at the depth
//! itself, which its debug validation rejects with a panic (found by the
//! `obj` fuzz target: 216 groups, depth 186) and which a traversal can
//! outgrow: its fixed stacks stop growing (missed nodes) and its heap stack
//! panics. Here `max_depth` is the depth plus one, found without recursion.

use obvhs::bvh2::leaf_collapser::collapse;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::bvh2::{Bvh2, DEFAULT_MAX_STACK_DEPTH};
use obvhs::ploc::PlocBuilder;
use obvhs::{aabb::Aabb, BvhBuildParams};

/// A BVH over `boxes` (primitive `i` is `boxes[i]`), built with `params`.
pub fn build_bvh2(boxes: &[Aabb], params: BvhBuildParams) -> Bvh2 {
    if boxes.is_empty() {
        return Bvh2::default();
    }
    let mut bvh = PlocBuilder::with_capacity(boxes.len()).build(
        params.ploc_search_distance,
        boxes,
        (0..boxes.len() as u32).collect(),
        params.sort_precision,
        params.search_depth_threshold,
    );
    let mut reinsertion = ReinsertionOptimizer::default();
    reinsertion.run(&mut bvh, params.reinsertion_batch_ratio, None);
    collapse(
        &mut bvh,
        params.max_prims_per_leaf.clamp(1, 255),
        params.collapse_traversal_cost,
    );
    reinsertion.run(
        &mut bvh,
        params.reinsertion_batch_ratio * params.post_collapse_reinsertion_batch_ratio_multiplier,
        None,
    );
    bvh.max_depth = (depth(&bvh) + 1).max(DEFAULT_MAX_STACK_DEPTH);
    bvh
}

/// The number of nodes on the longest path from the root to a leaf.
pub fn depth(bvh: &Bvh2) -> usize {
    let mut deepest = 0;
    let mut stack = vec![(0usize, 1usize)];
    while let Some((i, d)) = stack.pop() {
        let Some(node) = bvh.nodes.get(i) else {
            continue;
        };
        deepest = deepest.max(d);
        if !node.is_leaf() {
            let first = node.first_index as usize;
            stack.push((first, d + 1));
            stack.push((first + 1, d + 1));
        }
    }
    deepest
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    /// Coinciding boxes chain; the traversal stack still fits (a debug
    /// build, as the tests run, once panicked in obvhs' validation here).
    #[test]
    fn coinciding_boxes_get_a_stack_that_fits() {
        for n in [1, 2, 97, 300, 5000] {
            let boxes = vec![Aabb::new(Vec3A::ZERO, Vec3A::ONE); n];
            let bvh = build_bvh2(&boxes, BvhBuildParams::medium_build());
            let d = depth(&bvh);
            assert!(
                bvh.max_depth > d,
                "{n} boxes: depth {d}, stack {}",
                bvh.max_depth
            );
            let mut seen: Vec<u32> = bvh.primitive_indices.clone();
            seen.sort_unstable();
            assert_eq!(seen, (0..n as u32).collect::<Vec<_>>());
        }
    }
}
