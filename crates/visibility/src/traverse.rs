//! Hierarchical visibility traversals over an [`OcclusionBackend`]
//! [Steiner §2.5.1]: no culling, view-frustum culling, exact stop-and-wait
//! occlusion culling, and coherent hierarchical culling (CHC) [Bittner,
//! Wimmer, Piringer, Purgathofer 2004; Steiner Listing 2.1].
//!
//! Every traversal renders the objects it finds visible into the backend's
//! depth target, front to back, and reports them. Occlusion queries test a
//! node's box against the depth rendered so far (GEQUAL, the backend's
//! semantics): with threshold 0 a box with no passing sample holds only
//! geometry behind the current depth, which can only come nearer, so every
//! culled object is hidden in the final image — the rendered set's depth
//! buffer is the unculled one. A threshold above 0 is aggressive.
//!
//! CHC keeps per node, across frames, whether it was visible and when it was
//! last visited. Previously visible inner nodes are opened without a query;
//! previously visible leaves are rendered at once and queried without waiting
//! for the result; previously invisible nodes (the termination nodes) are
//! queried and their results handled as they arrive, interleaved with the
//! front-to-back traversal; a visible result pulls visibility up to the root.
//! CHC++ (batched and multi-queries, revisits) is in `chcpp.rs`.

use crate::chcpp::ChcppOptions;
use crate::culler::{in_planes, CullResult, NodeState, Objects, Queued, Run, Scratch, ViewCuller};
use crate::view_setup::ViewSetup;
use crate::Result;
use raster::OcclusionBackend;
use scene::ObjectId;

/// Which traversal a view runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Culling {
    /// Render every object.
    #[default]
    None,
    /// Render every object whose box may meet the view's planes.
    Frustum,
    /// Query every node in the frustum front to back and wait for each
    /// result before going on (stop-and-wait).
    Exact,
    /// Coherent hierarchical culling [Bittner et al. 2004].
    Chc,
    /// CHC++ [Mattausch, Bittner, Wimmer 2008]: CHC with batched queries of
    /// previously invisible nodes, multiqueries, tighter query volumes, and
    /// visible leaves re-queried only every few frames.
    ChcPlusPlus(ChcppOptions),
}

impl Culling {
    /// True for the coherent traversals, which report as visible only what
    /// their queries (or CHC++'s revisit rule) confirmed.
    fn coherent(self) -> bool {
        matches!(self, Culling::Chc | Culling::ChcPlusPlus(_))
    }
}

impl ViewCuller {
    /// Runs one frame of `culling` for `view`: clears the backend's target,
    /// renders the visible objects front to back, and reports them. Per-node
    /// state carries over to the next call (CHC's coherence).
    ///
    /// # Errors
    /// Backend errors (a bad mesh index).
    pub fn cull(
        &mut self,
        objects: Objects<'_>,
        view: &ViewSetup<'_>,
        culling: Culling,
        backend: &mut dyn OcclusionBackend,
    ) -> Result<CullResult> {
        let mut out = CullResult::default();
        self.cull_into(objects, view, culling, backend, &mut out)?;
        Ok(out)
    }

    /// [`ViewCuller::cull`] into `out` (cleared first), whose lists are
    /// reused: with the culler's own queues kept too, a steady frame
    /// allocates nothing.
    ///
    /// # Errors
    /// As [`ViewCuller::cull`].
    pub fn cull_into(
        &mut self,
        objects: Objects<'_>,
        view: &ViewSetup<'_>,
        culling: Culling,
        backend: &mut dyn OcclusionBackend,
        out: &mut CullResult,
    ) -> Result<()> {
        let Objects {
            hierarchy: h,
            scene,
            meshes,
        } = objects;
        self.frame = match self.next.take() {
            Some(f) => f.saturating_add(1),
            None => self.frame.saturating_add(1),
        };
        if self.state.len() != h.len() {
            // Keeps the allocation across resets.
            self.state.clear();
            self.state.resize(h.len(), NodeState::default());
            self.origin = self.frame;
        }
        if !view.preloaded {
            backend.clear();
        }
        out.clear();
        let mut s = std::mem::take(&mut self.scratch);
        let mut boxes = std::mem::take(&mut self.boxes);
        s.clear();
        s.reserve(h.len());
        // A union query holds at most four boxes per node of its group.
        boxes.reserve(4 * h.len());
        out.rendered.reserve(h.len());
        out.visible.reserve(h.len());
        let mut run = Run {
            h,
            scene,
            meshes,
            view,
            backend,
            out,
            boxes: &mut boxes,
        };
        let r = if h.is_empty() {
            Ok(())
        } else {
            match culling {
                Culling::None | Culling::Frustum => {
                    self.plain(&mut run, culling == Culling::Frustum, &mut s)
                }
                Culling::Exact => self.stop_and_wait(&mut run, &mut s),
                Culling::Chc => self.chc(&mut run, &mut s),
                Culling::ChcPlusPlus(o) => self.chcpp(&mut run, &o, &mut s),
            }
        };
        let Run { backend, out, .. } = run;
        self.scratch = s;
        if r.is_ok() {
            backend.finish();
            if !culling.coherent() {
                out.visible.clone_from(&out.rendered);
            }
            out.stats.objects_visible = out.visible.len() as u64;
        }
        self.boxes = boxes;
        r
    }

    /// No occlusion queries: every leaf (inside the planes with `frustum`).
    fn plain(&mut self, run: &mut Run<'_, '_>, frustum: bool, s: &mut Scratch) -> Result<()> {
        let q = &mut s.distance;
        q.push(Queued { dist: 0.0, node: 0 });
        while let Some(Queued { node, .. }) = q.pop() {
            let n = run.h.nodes[node as usize];
            run.out.stats.nodes_visited += 1;
            if frustum && !in_planes(&run.view.planes, &n) {
                continue;
            }
            self.state[node as usize] = NodeState {
                visible: true,
                visited: self.frame,
                last_visible: self.frame,
            };
            if n.is_leaf() {
                run.render(&n)?;
            } else {
                run.push_children(q, &n);
            }
        }
        Ok(())
    }

    /// Query, wait, descend: the exact hierarchical occlusion traversal.
    fn stop_and_wait(&mut self, run: &mut Run<'_, '_>, s: &mut Scratch) -> Result<()> {
        let q = &mut s.distance;
        q.push(Queued { dist: 0.0, node: 0 });
        while let Some(Queued { node, .. }) = q.pop() {
            let n = run.h.nodes[node as usize];
            run.out.stats.nodes_visited += 1;
            if !in_planes(&run.view.planes, &n) {
                continue;
            }
            let id = run.query(&n)?;
            let samples = run.wait(id);
            let visible = run.visible(samples);
            let s = &mut self.state[node as usize];
            s.visible = visible;
            s.visited = self.frame;
            if visible {
                s.last_visible = self.frame;
            }
            if visible {
                if n.is_leaf() {
                    run.render(&n)?;
                } else {
                    run.push_children(q, &n);
                }
            }
        }
        Ok(())
    }

    /// Coherent hierarchical culling [Steiner Listing 2.1].
    fn chc(&mut self, run: &mut Run<'_, '_>, s: &mut Scratch) -> Result<()> {
        let distance = &mut s.distance;
        // (node, query, was visible): results handled in issue order.
        let queries = &mut s.chc;
        distance.push(Queued { dist: 0.0, node: 0 });
        while !distance.is_empty() || !queries.is_empty() {
            // Results that have arrived (or all of them once there is nothing
            // else to do).
            while let Some(&(node, id, was_visible)) = queries.front() {
                let samples = if distance.is_empty() {
                    run.wait(id)
                } else {
                    match run.backend.poll(id) {
                        Some(s) => s,
                        None => break,
                    }
                };
                queries.pop_front();
                if run.visible(samples) {
                    self.pull_up(run.h, node);
                    let n = &run.h.nodes[node as usize];
                    if n.is_leaf() {
                        run.out.visible.push(ObjectId::from_slot(n.object));
                    }
                    if !was_visible {
                        let n = run.h.nodes[node as usize];
                        self.traverse(run, distance, &n)?;
                    }
                }
            }
            let Some(Queued { node, .. }) = distance.pop() else {
                continue;
            };
            let n = run.h.nodes[node as usize];
            run.out.stats.nodes_visited += 1;
            if !in_planes(&run.view.planes, &n) {
                // Outside the view: invisible, not queried.
                self.leave_invisible(node);
                continue;
            }
            let was_visible = self.leave_invisible(node);
            // Previously visible inner nodes are opened without a query.
            let opened = was_visible && !n.is_leaf();
            if !opened {
                let id = run.query(&n)?;
                queries.push_back((node, id, was_visible));
            }
            if was_visible {
                self.traverse(run, distance, &n)?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hierarchy::{Hierarchy, Node, NONE};
    use crate::view_setup::MeshData;
    use glam::DMat4;
    use raster::{DepthTarget, SyncBackend, TileSize};
    use scene::procedural::city::{city, CityParams};
    use scene::Scene;

    /// `h` renumbered breadth-first with every node's children swapped: the
    /// same tree over the same objects, as a rebuild might number it.
    fn renumbered(h: &Hierarchy) -> Hierarchy {
        let mut order = vec![0u32];
        let mut new_of = vec![NONE; h.len()];
        new_of[0] = 0;
        let mut k = 0;
        while k < order.len() {
            let n = h.nodes[order[k] as usize];
            if !n.is_leaf() {
                for c in [n.first + 1, n.first] {
                    new_of[c as usize] = order.len() as u32;
                    order.push(c);
                }
            }
            k += 1;
        }
        let mut nodes: Vec<Node> = order.iter().map(|&o| h.nodes[o as usize]).collect();
        for n in &mut nodes {
            if !n.is_leaf() {
                // The swapped pair: the old second child now comes first.
                n.first = new_of[n.first as usize + 1];
            }
            if n.parent != NONE {
                n.parent = new_of[n.parent as usize];
            }
        }
        Hierarchy { nodes }
    }

    /// A 4×4-block procedural city and its `street` camera path.
    fn street_city() -> (Scene, scene::CameraPath) {
        let loaded = city(&CityParams {
            blocks_x: 4,
            blocks_z: 4,
            ..Default::default()
        })
        .unwrap();
        let path = loaded.paths.iter().find(|(n, _)| n == "street").unwrap();
        let path = path.1.clone();
        (Scene::new(loaded.graph).unwrap(), path)
    }

    /// After a rebuild, remapped CHC state gives the next frame the same
    /// visible set and the same queries as if nothing had been rebuilt; a
    /// fresh state pays for the lost coherence.
    #[test]
    fn remapped_state_survives_a_rebuild() {
        let (scene, path) = street_city();
        let meshes = MeshData::from_scene(&scene);
        let h1 = Hierarchy::from_scene(&scene);
        let h2 = renumbered(&h1);
        assert_eq!(h2.len(), h1.len());
        let frame = |culler: &mut ViewCuller, h: &Hierarchy, f: u32, culling: Culling| {
            let cam = path.at(f).unwrap().camera(4.0 / 3.0).unwrap();
            let clip = |w: &DMat4| scene::transform::clip_from_local(&cam, w);
            let view = ViewSetup::eye(&cam, &clip, 0);
            let mut b = SyncBackend::new(DepthTarget::new(160, 120, TileSize::T8, true).unwrap());
            let mut r = culler
                .cull(Objects::new(h, &scene, &meshes), &view, culling, &mut b)
                .unwrap();
            r.visible.sort_unstable();
            r
        };
        for culling in [Culling::Chc, Culling::ChcPlusPlus(ChcppOptions::default())] {
            let (mut kept, mut remapped) = (ViewCuller::new(), ViewCuller::new());
            for f in 0..6 {
                frame(&mut kept, &h1, f, culling);
                frame(&mut remapped, &h1, f, culling);
            }
            remapped.remap(&h1, &h2);
            // Leaves keep their object's state exactly; an inner node is
            // visible only where the kept state has it visible (the kept
            // state may also hold an inner node whose own query passed while
            // none of its children's did).
            let live =
                |c: &ViewCuller, i: usize| c.state[i].visible && c.state[i].visited == c.frame;
            let old_of: std::collections::HashMap<u32, usize> = h1
                .nodes
                .iter()
                .enumerate()
                .filter(|(_, n)| n.is_leaf())
                .map(|(i, n)| (n.object, i))
                .collect();
            let mut live_leaves = 0;
            for (i, n) in h2.nodes.iter().enumerate() {
                if n.is_leaf() {
                    let o = old_of[&n.object];
                    assert_eq!(live(&remapped, i), live(&kept, o));
                    assert_eq!(remapped.state[i].last_visible, kept.state[o].last_visible);
                    live_leaves += usize::from(live(&remapped, i));
                }
            }
            assert!(live_leaves > 10, "{live_leaves}");
            // The next frame finds the same visible objects; a fresh state
            // pays for the lost coherence with more queries.
            let a = frame(&mut kept, &h1, 6, culling);
            let b = frame(&mut remapped, &h2, 6, culling);
            let mut fresh = ViewCuller::new();
            fresh.set_frame(6);
            let c = frame(&mut fresh, &h2, 6, culling);
            assert_eq!(a.visible, b.visible, "{culling:?}");
            println!(
                "{culling:?}: queries kept {}, remapped {}, fresh {}",
                a.stats.queries, b.stats.queries, c.stats.queries
            );
            assert!(
                c.stats.queries > b.stats.queries * 3 / 2,
                "{culling:?}: fresh {} vs remapped {}",
                c.stats.queries,
                b.stats.queries
            );
        }
    }

    /// Coherence reads job frame numbers, not calls: a cold start at frame
    /// 100 behaves like one at frame 0 (the revisit period 5 divides 100, and
    /// never-visible nodes count from the start of the history), while a
    /// cold start at frame 101 queries other leaves on revisit (and so
    /// reports another superset of the visible objects).
    #[test]
    fn frame_numbers_not_calls_decide() {
        let (scene, path) = street_city();
        let cam = path.at(3).unwrap().camera(4.0 / 3.0).unwrap();
        let meshes = MeshData::from_scene(&scene);
        let h = Hierarchy::from_scene(&scene);
        let clip = |w: &DMat4| scene::transform::clip_from_local(&cam, w);
        let view = ViewSetup::eye(&cam, &clip, 0);
        let culling = Culling::ChcPlusPlus(ChcppOptions::default());
        // Per frame: queries issued and the visible objects.
        let run = |first: Option<u32>| {
            let mut culler = ViewCuller::new();
            if let Some(f) = first {
                culler.set_frame(f);
            }
            (0..12)
                .map(|_| {
                    let mut b =
                        SyncBackend::new(DepthTarget::new(160, 120, TileSize::T8, true).unwrap());
                    let mut r = culler
                        .cull(Objects::new(&h, &scene, &meshes), &view, culling, &mut b)
                        .unwrap();
                    r.visible.sort_unstable();
                    (r.stats.queries, r.visible)
                })
                .collect::<Vec<_>>()
        };
        let at0 = run(None);
        assert_eq!(run(Some(0)), at0);
        assert_eq!(run(Some(100)), at0);
        let at101 = run(Some(101));
        let queries = |r: &[(u64, Vec<ObjectId>)]| r.iter().map(|x| x.0).collect::<Vec<_>>();
        assert_ne!(
            queries(&at101),
            queries(&at0),
            "revisit phases follow the frame number"
        );
    }

    /// Frame numbers up to `u32::MAX` (a host may pass any): CHC and CHC++
    /// run on through the last number and past it (it saturates), with the
    /// visible set of a cold start. The fuzzer found the overflow of
    /// `visited + 1` at `u32::MAX`.
    #[test]
    fn frame_numbers_at_the_top_of_the_range() {
        let (scene, path) = street_city();
        let cam = path.at(3).unwrap().camera(4.0 / 3.0).unwrap();
        let meshes = MeshData::from_scene(&scene);
        let h = Hierarchy::from_scene(&scene);
        let clip = |w: &DMat4| scene::transform::clip_from_local(&cam, w);
        let view = ViewSetup::eye(&cam, &clip, 0);
        let visible = |culler: &mut ViewCuller, culling: Culling| {
            let mut b = SyncBackend::new(DepthTarget::new(160, 120, TileSize::T8, true).unwrap());
            let mut r = culler
                .cull(Objects::new(&h, &scene, &meshes), &view, culling, &mut b)
                .unwrap();
            r.visible.sort_unstable();
            r.visible
        };
        // What stop-and-wait culling finds visible: every coherent frame holds it.
        let exact = visible(&mut ViewCuller::new(), Culling::Exact);
        for culling in [Culling::Chc, Culling::ChcPlusPlus(ChcppOptions::default())] {
            let mut culler = ViewCuller::new();
            culler.set_frame(u32::MAX - 2);
            for _ in 0..5 {
                let v = visible(&mut culler, culling);
                assert!(
                    exact.iter().all(|o| v.contains(o)),
                    "{culling:?}: lost a visible object"
                );
            }
        }
    }
}
