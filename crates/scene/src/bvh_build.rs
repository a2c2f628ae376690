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

/// Turns a BVH built over clusters of consecutive primitives (cluster `c`
/// holds primitives `starts[c]..starts[c + 1]`; `starts` ends with the
/// primitive count) into the same tree over the primitives: each leaf holds
/// its clusters' primitives. Its boxes stay valid when each cluster's box
/// held its primitives'.
///
/// Why: the build's scratch and the tree scale with the clusters, not the
/// primitives (PLOC over a million triangles takes about 150 bytes each
/// while it builds; the reference builds over clusters of four).
///
/// # Panics
/// If a leaf names a cluster `starts` does not hold.
pub fn expand_clusters(bvh: &mut Bvh2, starts: &[u32]) {
    let clusters = std::mem::take(&mut bvh.primitive_indices);
    let total = starts.last().copied().unwrap_or(0) as usize;
    let mut primitives = Vec::with_capacity(total);
    for node in bvh.nodes.iter_mut().filter(|n| n.is_leaf()) {
        let first = primitives.len();
        let range = node.first_index as usize..(node.first_index + node.prim_count) as usize;
        for &c in &clusters[range] {
            primitives.extend(starts[c as usize]..starts[c as usize + 1]);
        }
        node.first_index = first as u32;
        node.prim_count = (primitives.len() - first) as u32;
    }
    bvh.primitive_indices = primitives;
    // A map from clusters to nodes would now name the wrong primitives.
    bvh.primitives_to_nodes.clear();
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

    /// Clusters expand to their primitives: each primitive in exactly one
    /// leaf, inside that leaf's box.
    #[test]
    fn clusters_expand_to_their_primitives() {
        // Unit boxes along a line, in clusters of 1 to 4.
        let n = 1000u32;
        let prim = |i: u32| {
            let x = (i as f32 * 0.37).sin() * 50.0 + i as f32 * 0.1;
            Aabb::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x + 1.0, 1.0, 1.0))
        };
        let mut starts = vec![0u32];
        while *starts.last().unwrap() < n {
            let next = starts.last().unwrap() + 1 + starts.len() as u32 % 4;
            starts.push(next.min(n));
        }
        let boxes: Vec<Aabb> = starts
            .windows(2)
            .map(|w| (w[0]..w[1]).fold(Aabb::empty(), |b, i| b.union(&prim(i))))
            .collect();
        let mut bvh = build_bvh2(&boxes, BvhBuildParams::fast_build());
        expand_clusters(&mut bvh, &starts);
        let mut seen = vec![0u32; n as usize];
        for node in bvh.nodes.iter().filter(|n| n.is_leaf()) {
            let leaf = *node.aabb();
            for p in node.first_index..node.first_index + node.prim_count {
                let i = bvh.primitive_indices[p as usize];
                seen[i as usize] += 1;
                let b = prim(i);
                assert!(leaf.min.cmple(b.min).all() && leaf.max.cmpge(b.max).all());
            }
        }
        assert!(seen.iter().all(|&k| k == 1), "{seen:?}");
        assert_eq!(bvh.primitive_indices.len(), n as usize);
    }
}
