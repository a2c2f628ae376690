//! One view's culling state across frames ([`ViewCuller`]: per-node
//! visibility and visit frames [Bittner et al. 2004; Steiner §4.3.2]) and the
//! machinery every traversal shares: the front-to-back queue, the per-frame
//! [`Run`] that renders and queries through the backend, and the reused
//! queues. The traversals themselves are in `traverse.rs` (none, frustum,
//! stop-and-wait, CHC) and `chcpp.rs` (CHC++).

use crate::hierarchy::{Hierarchy, Node, NONE};
use crate::view_setup::{ConvexOccluders, MeshData, ViewSetup};
use crate::Result;
use glam::{DVec3, Vec3};
use raster::{DrawCommand, OcclusionBackend, QueryCommand, QueryId};
use scene::{ObjectId, Plane, Scene};
use std::cmp::Ordering;
use std::collections::{BinaryHeap, VecDeque};
use std::time::Instant;

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
    /// Triangles of the objects drawn as occluders (a light view's: their
    /// casting triangles).
    pub triangles_rendered: u64,
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
    pub(crate) next: Option<u32>,
    /// `frame` of the first traversal since the history began (new or
    /// reset): a node never found visible counts as invisible since then.
    pub(crate) origin: u32,
    /// The traversals' queues and lists, kept between frames.
    pub(crate) scratch: Scratch,
    /// Box lists of union queries.
    pub(crate) boxes: Vec<(Vec3, Vec3)>,
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
    pub pending: VecDeque<(QueryId, Pending)>,
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
    pub(crate) fn reserve(&mut self, nodes: usize) {
        self.distance.reserve(nodes);
        self.chc.reserve(nodes);
        self.pending.reserve(3 * nodes);
        self.batch.reserve(nodes);
        self.revisit.reserve(nodes);
        self.cand.reserve(nodes);
        self.volume.reserve(4 * nodes);
        self.groups.reserve(nodes);
    }

    pub(crate) fn clear(&mut self) {
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

/// A CHC++ query in flight (kept in [`Scratch`]).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Pending {
    Node {
        node: u32,
        was_visible: bool,
    },
    /// A multiquery: `len` nodes from `start` in the frame's group list.
    Group {
        start: u32,
        len: u32,
    },
    Revisit(u32),
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

/// The objects a view culls, in the three forms a traversal reads: their
/// hierarchy (what it walks), the scene (flags and bounds) and the meshes in
/// the backends' form (what it draws). All three describe the same objects.
#[derive(Clone, Copy)]
pub struct Objects<'a> {
    /// The object hierarchy.
    pub hierarchy: &'a Hierarchy,
    /// The scene.
    pub scene: &'a Scene,
    /// Meshes in the backends' form.
    pub meshes: &'a MeshData,
}

impl<'a> Objects<'a> {
    /// The objects of `scene`, with their `hierarchy` and `meshes`.
    pub fn new(hierarchy: &'a Hierarchy, scene: &'a Scene, meshes: &'a MeshData) -> Self {
        Objects {
            hierarchy,
            scene,
            meshes,
        }
    }
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
        let id = ObjectId::from_slot(node.object);
        let o = self.scene.object(id);
        if self.view.preloaded || !(self.view.occluder)(&o.flags) {
            self.out.rendered.push(id);
            self.out.stats.objects_rendered += 1;
            return Ok(());
        }
        let drawn = self.view.occluder_mesh(o);
        let mesh = drawn.index();
        let inner = self.view.draw_coverage == raster::Coverage::Inner(raster::DepthPick::Farthest);
        let closed = || match self.scene.graph().meshes()[mesh].solid() {
            Some(_) => raster::Whole::Closed,
            None => raster::Whole::No,
        };
        let (triangles, whole) = match (self.view.triangles, self.view.convex) {
            (Some(f), ConvexOccluders::Own { proxies })
                if inner && self.meshes.convex_draw(drawn, proxies) =>
            {
                (f(id), raster::Whole::Convex)
            }
            (Some(f), _) => (f(id), raster::Whole::No),
            (None, ConvexOccluders::Hulls) if inner => match self.meshes.hull_of(drawn) {
                Some(h) => (h.clone(), raster::Whole::Convex),
                None => (self.meshes.triangles[mesh].clone(), closed()),
            },
            (None, _) => (self.meshes.triangles[mesh].clone(), raster::Whole::No),
        };
        self.out.stats.triangles_rendered += raster::trim_padding(&triangles).len() as u64;
        self.backend.draw(DrawCommand {
            clip_from_local: (self.view.clip_from_local)(&o.world_from_local),
            positions: self.meshes.positions[mesh].clone(),
            triangles,
            object: node.object,
            coverage: self.view.draw_coverage,
            cull: self.view.back_faces.map_or(raster::CullMode::None, |c| {
                crate::eye_cull(c, o, &self.scene.graph().meshes()[mesh])
            }),
            whole,
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
