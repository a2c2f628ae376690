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
use crate::hierarchy::{Hierarchy, Node, NONE};
use crate::Result;
use glam::{DMat4, DVec3, Mat4, Vec3, Vec4};
use raster::{Coverage, DrawCommand, OcclusionBackend, QueryCommand, QueryId, QueryOptions};
use scene::{ObjectId, Plane, Scene};
use std::cmp::Ordering;
use std::collections::{BinaryHeap, VecDeque};
use std::sync::Arc;
use std::time::Instant;

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

/// How draws, queries and receiver marks sample pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Sampling {
    /// Conservative: box queries outer-conservative at the nearest depth;
    /// light-view occluders inner-conservative at the farthest depth;
    /// receivers widened by [`raster::RECEIVER_EPS_PX`] and pushed away from
    /// the light. The culled mask equals the unculled one.
    #[default]
    Conservative,
    /// Aggressive: everything at pixel centres (standard coverage), receivers
    /// unwidened and unpushed, as a GPU implementation would sample. Can cull
    /// a caster whose shadow falls between samples: measured, not exact.
    Point,
}

/// Per-mesh vertex data in the backend's form (`w = 1`, shared with draw commands).
#[derive(Clone, Debug)]
pub struct MeshData {
    positions: Vec<Arc<[Vec4]>>,
    triangles: Vec<Arc<[[u32; 3]]>>,
    /// The scene's mesh version each copy was made from.
    versions: Vec<u64>,
}

impl MeshData {
    /// Converts every mesh of `scene`.
    pub fn from_scene(scene: &Scene) -> Self {
        let mut data = MeshData {
            positions: Vec::new(),
            triangles: Vec::new(),
            versions: Vec::new(),
        };
        data.sync(scene);
        data
    }

    /// The triangles of mesh `mesh` (shared).
    pub(crate) fn triangles_of(&self, mesh: scene::MeshId) -> Arc<[[u32; 3]]> {
        self.triangles[mesh.0 as usize].clone()
    }

    /// Catches up with meshes added to `scene` since, and with meshes whose
    /// vertices changed ([`Scene::mesh_version`]; a removed mesh keeps its
    /// slot, empty).
    pub fn sync(&mut self, scene: &Scene) {
        let meshes = scene.graph().meshes();
        self.positions.truncate(meshes.len());
        self.triangles.truncate(meshes.len());
        self.versions.truncate(meshes.len());
        for (i, m) in meshes.iter().enumerate() {
            let version = scene.mesh_version(scene::MeshId(i as u32));
            if self.versions.get(i) == Some(&version) {
                continue;
            }
            let p: Arc<[Vec4]> = m.positions().iter().map(|p| p.extend(1.0)).collect();
            let t: Arc<[[u32; 3]]> = m.triangles().into();
            if i < self.positions.len() {
                self.positions[i] = p;
                self.triangles[i] = t;
                self.versions[i] = version;
            } else {
                self.positions.push(p);
                self.triangles.push(t);
                self.versions.push(version);
            }
        }
    }
}

/// One view: how objects and boxes reach its clip space, its culling planes,
/// and the coverage of its draws and queries.
pub struct ViewSetup<'a> {
    /// `clip_from_local` for an object's `world_from_local` (the one transform path).
    pub clip_from_local: &'a dyn Fn(&DMat4) -> Mat4,
    /// Boxes are sent relative to this point (f64 subtraction, rounded
    /// outward), with [`ViewSetup::clip_from_origin`].
    pub origin: DVec3,
    /// `clip_from_local` of the translation to `origin`.
    pub clip_from_origin: Mat4,
    /// The view's planes (inside positive), for frustum culling.
    pub planes: [Plane; 5],
    /// Where front-to-back distances are measured from (the centre of projection).
    pub apex: DVec3,
    /// Coverage of occluder draws.
    pub draw_coverage: Coverage,
    /// Coverage and mode of box queries.
    pub query: QueryOptions,
    /// A node is visible when more than this many samples pass (0: conservative).
    pub threshold: u32,
    /// The triangles an object draws as an occluder, when not all of its
    /// mesh's (a light view draws only the triangles that cast).
    pub triangles: Option<&'a dyn Fn(ObjectId) -> Arc<[[u32; 3]]>>,
    /// Which objects the view draws as occluders when it renders them (the
    /// others are reported rendered but draw nothing): the eye draws visible
    /// occluders ([`ViewSetup::eye_occluder`]), a light view casting ones.
    pub occluder: fn(&scene::ObjectFlags) -> bool,
}

impl<'a> ViewSetup<'a> {
    /// The eye view of `camera`: boxes eye-relative, the frustum's planes,
    /// standard-coverage draws, outer-conservative box queries at the nearest
    /// depth (any-samples when `threshold` is 0, counts otherwise).
    /// `clip_from_local` is the eye pass's transform path
    /// (`scene::transform::clip_from_local` with `camera`).
    pub fn eye(
        camera: &scene::Camera,
        clip_from_local: &'a dyn Fn(&DMat4) -> Mat4,
        threshold: u32,
    ) -> Self {
        Self::eye_sampled(camera, clip_from_local, threshold, Sampling::Conservative)
    }

    /// [`ViewSetup::eye`] with box queries sampled as `sampling` says.
    pub fn eye_sampled(
        camera: &scene::Camera,
        clip_from_local: &'a dyn Fn(&DMat4) -> Mat4,
        threshold: u32,
        sampling: Sampling,
    ) -> Self {
        ViewSetup {
            clip_from_local,
            origin: camera.position,
            clip_from_origin: scene::transform::clip_from_local(
                camera,
                &DMat4::from_translation(camera.position),
            ),
            planes: camera.frustum().planes,
            apex: camera.position,
            draw_coverage: Coverage::Standard,
            query: QueryOptions {
                coverage: sampling.query_coverage(),
                // With threshold 0 one passing sample decides: stop there.
                mode: if threshold == 0 {
                    raster::QueryMode::Any
                } else {
                    raster::QueryMode::Count
                },
            },
            threshold,
            triangles: None,
            occluder: Self::eye_occluder,
        }
    }

    /// The eye's occluders: visible objects that may occlude.
    pub fn eye_occluder(f: &scene::ObjectFlags) -> bool {
        f.visible && f.occludes
    }

    /// A light view's occluders: casting objects that may occlude.
    pub fn light_occluder(f: &scene::ObjectFlags) -> bool {
        f.casts && f.occludes
    }
}

impl Sampling {
    /// Coverage of box queries.
    pub(crate) fn query_coverage(self) -> Coverage {
        match self {
            Sampling::Conservative => Coverage::Outer(raster::DepthPick::Nearest),
            Sampling::Point => Coverage::Standard,
        }
    }
}

/// Counters of one traversal.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct TraversalStats {
    /// Nodes taken from the traversal queue.
    pub nodes_visited: u64,
    /// Occlusion queries issued.
    pub queries: u64,
    /// Waits for a query result.
    pub waits: u64,
    /// Time spent waiting (ms).
    pub wait_ms: f64,
    /// Objects drawn.
    pub objects_rendered: u64,
    /// Objects found visible (drawn and, where queried, confirmed).
    pub objects_visible: u64,
}

/// The objects a traversal found, and its counters.
#[derive(Clone, Debug, Default)]
pub struct CullResult {
    /// Objects drawn into the view, in drawing order.
    pub rendered: Vec<ObjectId>,
    /// Objects whose own query found them visible (for traversals without
    /// queries: every object drawn). CHC draws previously visible objects
    /// before their query returns; those whose query then fails are drawn but
    /// not visible.
    pub visible: Vec<ObjectId>,
    /// Counters.
    pub stats: TraversalStats,
}

impl CullResult {
    /// Empties the lists (keeping their buffers) and zeroes the counters.
    pub fn clear(&mut self) {
        self.rendered.clear();
        self.visible.clear();
        self.stats = TraversalStats::default();
    }
}

/// Per-node state a view keeps across frames.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct NodeState {
    pub visible: bool,
    /// Frame of the last visit (frames count from 1; 0: never).
    pub visited: u32,
    /// Last frame the node was found visible (0: never).
    pub last_visible: u32,
}

/// One view's persistent culling state [Steiner §4.3.2: the eye and every
/// light view own their instance].
#[derive(Clone, Debug, Default)]
pub struct ViewCuller {
    pub(crate) state: Vec<NodeState>,
    /// The last traversal's frame, counted from 1 (0: none yet): the job
    /// frame number plus one. Node states record it; CHC++'s revisit phases
    /// and multiquery grouping read it.
    pub(crate) frame: u32,
    /// The job frame number of the next traversal, when the caller set it.
    next: Option<u32>,
    /// `frame` of the first traversal since the history began (new or
    /// reset): a node never found visible counts as invisible since then.
    pub(crate) origin: u32,
    /// The traversals' queues and lists, kept between frames.
    scratch: Scratch,
    /// Box lists of union queries.
    boxes: Vec<(Vec3, Vec3)>,
}

/// The queues and lists of a traversal, reused from frame to frame (cleared,
/// not reallocated): a steady frame allocates nothing.
#[derive(Clone, Debug, Default)]
pub(crate) struct Scratch {
    /// Front-to-back queue.
    pub distance: BinaryHeap<Queued>,
    /// CHC: (node, query, was visible), handled in issue order.
    pub chc: VecDeque<(u32, QueryId, bool)>,
    /// CHC++: queries in issue order.
    pub pending: VecDeque<(QueryId, crate::chcpp::Pending)>,
    /// CHC++: previously invisible nodes waiting for a batch.
    pub batch: Vec<u32>,
    /// CHC++: rendered visible leaves due for their revisit query.
    pub revisit: VecDeque<u32>,
    /// CHC++: a batch's nodes with their keep-invisible probability.
    pub cand: Vec<(f64, u32)>,
    /// CHC++: the node list of one query volume.
    pub volume: Vec<u32>,
    /// CHC++: the nodes of every multiquery group issued this frame.
    pub groups: Vec<u32>,
}

impl Scratch {
    /// Reserves every list at its bound for a hierarchy of `nodes` nodes (a
    /// node is queued, batched and grouped at most once per frame; queried
    /// at most twice, plus a revisit), so no frame grows them.
    fn reserve(&mut self, nodes: usize) {
        self.distance.reserve(nodes);
        self.chc.reserve(nodes);
        self.pending.reserve(3 * nodes);
        self.batch.reserve(nodes);
        self.revisit.reserve(nodes);
        self.cand.reserve(nodes);
        self.volume.reserve(4 * nodes);
        self.groups.reserve(nodes);
    }

    fn clear(&mut self) {
        self.distance.clear();
        self.chc.clear();
        self.pending.clear();
        self.batch.clear();
        self.revisit.clear();
        self.cand.clear();
        self.volume.clear();
        self.groups.clear();
    }
}

/// A node in the front-to-back queue: nearer first, then lower index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Queued {
    pub dist: f64,
    pub node: u32,
}

impl Eq for Queued {}

impl Ord for Queued {
    fn cmp(&self, o: &Self) -> Ordering {
        o.dist
            .total_cmp(&self.dist)
            .then_with(|| o.node.cmp(&self.node))
    }
}

impl PartialOrd for Queued {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

/// Squared distance from `p` to the box.
fn box_distance2(n: &Node, p: DVec3) -> f64 {
    let (lo, hi) = (n.min.as_dvec3(), n.max.as_dvec3());
    let d = (lo - p).max(p - hi).max(DVec3::ZERO);
    d.length_squared()
}

/// Conservative box-vs-planes test: false only when the box lies wholly
/// outside one plane.
pub(crate) fn in_planes(planes: &[Plane], n: &Node) -> bool {
    let (lo, hi) = (n.min.as_dvec3(), n.max.as_dvec3());
    planes.iter().all(|pl| {
        let m = pl.normal;
        let far = DVec3::new(
            if m.x >= 0.0 { hi.x } else { lo.x },
            if m.y >= 0.0 { hi.y } else { lo.y },
            if m.z >= 0.0 { hi.z } else { lo.z },
        );
        pl.signed_distance(far) >= 0.0
    })
}

/// `v` rounded to f32 toward −∞ (`up` false) or +∞.
fn round_f32(v: f64, up: bool) -> f32 {
    let r = v as f32;
    match (up, f64::from(r).partial_cmp(&v)) {
        (true, Some(Ordering::Less)) => r.next_up(),
        (false, Some(Ordering::Greater)) => r.next_down(),
        _ => r,
    }
}

/// `n`'s box relative to `o`, rounded outward to f32.
fn local_box(n: &Node, o: DVec3) -> (Vec3, Vec3) {
    let (lo, hi) = (n.min.as_dvec3() - o, n.max.as_dvec3() - o);
    (
        Vec3::new(
            round_f32(lo.x, false),
            round_f32(lo.y, false),
            round_f32(lo.z, false),
        ),
        Vec3::new(
            round_f32(hi.x, true),
            round_f32(hi.y, true),
            round_f32(hi.z, true),
        ),
    )
}

/// The traversal of one frame: the view, the backend, what was rendered.
pub(crate) struct Run<'a, 'b> {
    pub h: &'a Hierarchy,
    pub scene: &'a Scene,
    pub meshes: &'a MeshData,
    pub view: &'a ViewSetup<'b>,
    pub backend: &'a mut dyn OcclusionBackend,
    pub out: &'a mut CullResult,
    /// The boxes of a union query.
    pub boxes: &'a mut Vec<(Vec3, Vec3)>,
}

impl Run<'_, '_> {
    pub fn render(&mut self, node: &Node) -> Result<()> {
        let id = ObjectId(node.object);
        let o = self.scene.object(id);
        if !(self.view.occluder)(&o.flags) {
            self.out.rendered.push(id);
            self.out.stats.objects_rendered += 1;
            return Ok(());
        }
        let mesh = o.mesh.0 as usize;
        let triangles = match self.view.triangles {
            Some(f) => f(id),
            None => self.meshes.triangles[mesh].clone(),
        };
        self.backend.draw(DrawCommand {
            clip_from_local: (self.view.clip_from_local)(&o.world_from_local),
            positions: self.meshes.positions[mesh].clone(),
            triangles,
            object: node.object,
            coverage: self.view.draw_coverage,
        })?;
        self.out.rendered.push(id);
        self.out.stats.objects_rendered += 1;
        Ok(())
    }

    pub fn query(&mut self, node: &Node) -> Result<QueryId> {
        let (min, max) = local_box(node, self.view.origin);
        self.out.stats.queries += 1;
        Ok(self.backend.issue_query(QueryCommand::Aabb {
            clip_from_local: self.view.clip_from_origin,
            min,
            max,
            options: self.view.query,
        })?)
    }

    /// One query over the union of the boxes of `nodes` (a multiquery, or a
    /// node's tighter volume).
    pub fn query_union(&mut self, nodes: &[u32]) -> Result<QueryId> {
        if let [one] = nodes {
            let n = self.h.nodes[*one as usize];
            return self.query(&n);
        }
        let o = self.view.origin;
        self.boxes.clear();
        self.boxes.extend(
            nodes
                .iter()
                .map(|&k| local_box(&self.h.nodes[k as usize], o)),
        );
        self.out.stats.queries += 1;
        Ok(self
            .backend
            .issue_box_union(self.view.clip_from_origin, self.boxes, self.view.query)?)
    }

    pub fn wait(&mut self, id: QueryId) -> u32 {
        let t = Instant::now();
        let r = self.backend.wait(id);
        self.out.stats.waits += 1;
        self.out.stats.wait_ms += t.elapsed().as_secs_f64() * 1e3;
        r
    }

    pub fn visible(&self, samples: u32) -> bool {
        samples > self.view.threshold
    }

    pub fn push_children(&self, q: &mut BinaryHeap<Queued>, n: &Node) {
        for c in [n.first, n.first + 1] {
            let child = &self.h.nodes[c as usize];
            q.push(Queued {
                dist: box_distance2(child, self.view.apex),
                node: c,
            });
        }
    }
}

impl ViewCuller {
    /// A view with no history (every node previously invisible).
    pub fn new() -> Self {
        ViewCuller::default()
    }

    /// Forgets all history: every node is previously invisible again. The
    /// frame numbering goes on.
    pub fn reset(&mut self) {
        self.state.clear();
    }

    /// Makes the next traversal job frame `frame` (from 0); later traversals
    /// count on from it unless set again. Coherence reads frame numbers, not
    /// calls: a node's state carries into a traversal only from the frame
    /// just before it, and CHC++'s revisit phases are a function of the
    /// frame number. So frame `k` of a run gives what frame `k` of any other
    /// run gives from the same history, whatever ran before (a sharded batch
    /// job's frames, a host skipping frames). Without a call, the first
    /// traversal is frame 0.
    pub fn set_frame(&mut self, frame: u32) {
        self.next = Some(frame);
    }

    /// Carries the per-node state from `old` over to `new`, a rebuilt
    /// hierarchy over the same objects (after objects moved too far for a
    /// refit): a leaf takes the state of the old leaf holding its object; an
    /// inner node is visible when one of its children is, and was last
    /// visible when its latest child was. Objects new to `new` start with no
    /// history. (A refit keeps node indices and needs no remapping.)
    pub fn remap(&mut self, old: &Hierarchy, new: &Hierarchy) {
        if self.state.len() != old.len() || new.is_empty() {
            self.state.clear();
            return;
        }
        let mut by_object = std::collections::HashMap::new();
        for (i, n) in old.nodes.iter().enumerate() {
            if n.is_leaf() {
                by_object.insert(n.object, self.state[i]);
            }
        }
        let mut state = vec![NodeState::default(); new.len()];
        // Post-order: children before their parent.
        let mut stack = vec![(0u32, false)];
        while let Some((i, done)) = stack.pop() {
            let n = &new.nodes[i as usize];
            if n.is_leaf() {
                state[i as usize] = by_object.get(&n.object).copied().unwrap_or_default();
            } else if !done {
                stack.extend([(i, true), (n.first, false), (n.first + 1, false)]);
            } else {
                let (a, b) = (state[n.first as usize], state[n.first as usize + 1]);
                let live = |s: NodeState| s.visible && s.visited == self.frame;
                state[i as usize] = NodeState {
                    visible: live(a) || live(b),
                    visited: a.visited.max(b.visited),
                    last_visible: a.last_visible.max(b.last_visible),
                };
            }
        }
        self.state = state;
    }

    /// Runs one frame of `culling` for `view`: clears the backend's target,
    /// renders the visible objects front to back, and reports them. Per-node
    /// state carries over to the next call (CHC's coherence).
    ///
    /// # Errors
    /// Backend errors (a bad mesh index).
    pub fn cull(
        &mut self,
        h: &Hierarchy,
        scene: &Scene,
        meshes: &MeshData,
        view: &ViewSetup<'_>,
        culling: Culling,
        backend: &mut dyn OcclusionBackend,
    ) -> Result<CullResult> {
        let mut out = CullResult::default();
        self.cull_into(h, scene, meshes, view, culling, backend, &mut out)?;
        Ok(out)
    }

    /// [`ViewCuller::cull`] into `out` (cleared first), whose lists are
    /// reused: with the culler's own queues kept too, a steady frame
    /// allocates nothing.
    ///
    /// # Errors
    /// As [`ViewCuller::cull`].
    #[allow(clippy::too_many_arguments)]
    pub fn cull_into(
        &mut self,
        h: &Hierarchy,
        scene: &Scene,
        meshes: &MeshData,
        view: &ViewSetup<'_>,
        culling: Culling,
        backend: &mut dyn OcclusionBackend,
        out: &mut CullResult,
    ) -> Result<()> {
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
        backend.clear();
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
                        run.out.visible.push(ObjectId(n.object));
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

    /// Marks `node` visited and (until a result says otherwise) invisible in
    /// this frame; returns whether it was visible in the previous frame.
    pub(crate) fn leave_invisible(&mut self, node: u32) -> bool {
        let s = &mut self.state[node as usize];
        // Checked: a host may number frames up to u32::MAX.
        let was_visible = s.visible && s.visited.checked_add(1) == Some(self.frame);
        s.visible = false;
        s.visited = self.frame;
        was_visible
    }

    /// CHC's TraverseNode: render a leaf, queue an inner node's children.
    pub(crate) fn traverse(
        &mut self,
        run: &mut Run<'_, '_>,
        distance: &mut BinaryHeap<Queued>,
        n: &Node,
    ) -> Result<()> {
        if n.is_leaf() {
            run.render(n)
        } else {
            run.push_children(distance, n);
            Ok(())
        }
    }

    /// Marks `node` and its ancestors visible, stopping at the first that already is.
    pub(crate) fn pull_up(&mut self, h: &Hierarchy, mut node: u32) {
        while node != NONE && !self.state[node as usize].visible {
            self.state[node as usize].visible = true;
            self.state[node as usize].last_visible = self.frame;
            node = h.nodes[node as usize].parent;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use raster::{DepthTarget, SyncBackend, TileSize};
    use scene::procedural::city::{city, CityParams};

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
                .cull(h, &scene, &meshes, &view, culling, &mut b)
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
                        .cull(&h, &scene, &meshes, &view, culling, &mut b)
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
                .cull(&h, &scene, &meshes, &view, culling, &mut b)
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
