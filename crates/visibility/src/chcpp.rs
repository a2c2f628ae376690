//! CHC++ [Mattausch, Bittner, Wimmer, "CHC++: Coherent hierarchical culling
//! revisited", Eurographics 2008]: CHC (`traverse.rs`) with fewer, cheaper
//! queries and fewer stalls.
//!
//! - **Batches.** Previously invisible nodes met by the front-to-back
//!   traversal are queued and queried [`ChcppOptions::batch`] at a time (and
//!   whenever the traversal has nothing else to do), not one by one.
//! - **Revisits.** A previously visible leaf is rendered at once and assumed
//!   visible; its query is issued only every [`ChcppOptions::revisit`] frames,
//!   with a per-object phase drawn from an RNG seeded by [`ChcppOptions::seed`]
//!   so the queries of a view's visible leaves spread over the frames. These
//!   queries only decide the next frame, so they wait in a queue and fill the
//!   time the traversal would otherwise stall on a result.
//! - **Multiqueries.** Within a batch, nodes that have long been invisible
//!   share one query over the union of their boxes. A node invisible for `t`
//!   frames stays invisible with estimated probability
//!   `p(t) = 0.99 − 0.7·e^(−t)`; nodes are taken in decreasing `p` and grouped
//!   greedily while the group's value `|M| / (1 + (1 − Π p)·|M|)` (nodes
//!   settled per expected query: one query, and on failure one per node)
//!   grows. A group found visible is split: every node gets its own query.
//! - **Tighter volumes.** An inner node is queried with the boxes of its
//!   descendants two levels down when their summed surface area (the
//!   rasterized area, on average over view directions) is below the node's.
//!
//! With threshold 0 it stays conservative: a node is culled only when a query
//! over boxes holding all its geometry passed nowhere against depth that can
//! only come nearer; assumed-visible leaves are drawn. The objects reported
//! may be a superset of CHC's; the depth buffer is the unculled one.

use crate::culler::{in_planes, Pending, Queued, Run, Scratch, ViewCuller};
use crate::hierarchy::{Hierarchy, Node};
use crate::Result;
use scene::{splitmix64, ObjectId};

/// CHC++ parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ChcppOptions {
    /// Previously invisible nodes queried together (the paper's 50); 0 or 1
    /// queries each at once.
    pub batch: u32,
    /// A visible leaf is re-queried every this many frames (the paper's 5);
    /// 0 or 1 queries it every frame.
    pub revisit: u32,
    /// Seed of the per-node revisit phases.
    pub seed: u64,
}

impl Default for ChcppOptions {
    fn default() -> Self {
        ChcppOptions {
            batch: 50,
            revisit: 5,
            seed: 1,
        }
    }
}

impl ChcppOptions {
    /// Whether a previously visible leaf holding `object` is queried in
    /// `frame` (keyed by object, so phases survive a hierarchy rebuild).
    fn revisit_due(&self, object: u32, frame: u32) -> bool {
        if self.revisit <= 1 {
            return true;
        }
        let r = u64::from(self.revisit);
        // One draw per node and seed, so a node's phase does not depend on
        // traversal order.
        let phase = splitmix64(&mut (self.seed ^ (u64::from(object) << 20))) % r;
        (u64::from(frame) + phase).is_multiple_of(r)
    }
}

/// Estimated probability that a node invisible for `t` frames stays invisible.
fn keep_invisible(t: u32) -> f64 {
    0.99 - 0.7 * (-f64::from(t)).exp()
}

fn surface_area(n: &Node) -> f64 {
    let e = (n.max - n.min).as_dvec3().max(glam::DVec3::ZERO);
    2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
}

/// The nodes whose boxes form `node`'s query volume: its descendants two
/// levels down when their boxes have less surface area, else `node` itself.
fn query_volume(h: &Hierarchy, node: u32, out: &mut Vec<u32>) {
    let start = out.len();
    let n = &h.nodes[node as usize];
    if !n.is_leaf() {
        for c in [n.first, n.first + 1] {
            let cn = &h.nodes[c as usize];
            if cn.is_leaf() {
                out.push(c);
            } else {
                out.extend([cn.first, cn.first + 1]);
            }
        }
        let area: f64 = out[start..]
            .iter()
            .map(|&k| surface_area(&h.nodes[k as usize]))
            .sum();
        if area < surface_area(n) {
            return;
        }
        out.truncate(start);
    }
    out.push(node);
}

impl ViewCuller {
    /// CHC++ (see the module doc).
    pub(crate) fn chcpp(
        &mut self,
        run: &mut Run<'_, '_>,
        o: &ChcppOptions,
        s: &mut Scratch,
    ) -> Result<()> {
        let frame = self.frame;
        s.distance.push(Queued { dist: 0.0, node: 0 });
        loop {
            // Results that have arrived.
            while let Some(&(id, _)) = s.pending.front() {
                let Some(samples) = run.backend.poll(id) else {
                    break;
                };
                let (_, p) = s.pending.pop_front().expect("front exists");
                self.chcpp_result(run, s, p, samples)?;
            }
            if let Some(Queued { node, .. }) = s.distance.pop() {
                let n = run.h.nodes[node as usize];
                run.out.stats.nodes_visited += 1;
                let inside = in_planes(&run.view.planes, &n);
                let was_visible = self.leave_invisible(node);
                if !inside {
                    continue;
                }
                if !was_visible {
                    s.batch.push(node);
                    if s.batch.len() >= o.batch.max(1) as usize {
                        self.issue_batch(run, s)?;
                    }
                } else if !n.is_leaf() {
                    // Previously visible inner nodes are opened without a query.
                    run.push_children(&mut s.distance, &n);
                } else {
                    run.render(&n)?;
                    // Assumed visible; queried (later) only when due.
                    self.pull_up(run.h, node);
                    run.out.visible.push(ObjectId::from_slot(n.object));
                    if o.revisit_due(n.object, frame) {
                        s.revisit.push_back(node);
                    }
                }
                continue;
            }
            if !s.batch.is_empty() {
                self.issue_batch(run, s)?;
                continue;
            }
            // Idle until the oldest result arrives: fill the time with a
            // revisit query, whose result only the next frame needs.
            if let Some(node) = s.revisit.pop_front() {
                let n = run.h.nodes[node as usize];
                let id = run.query(&n)?;
                s.pending.push_back((id, Pending::Revisit(node)));
                continue;
            }
            let Some(&(id, _)) = s.pending.front() else {
                return Ok(());
            };
            let samples = run.wait(id);
            let (_, p) = s.pending.pop_front().expect("front exists");
            self.chcpp_result(run, s, p, samples)?;
        }
    }

    /// Queries the nodes of `s.batch` (emptied) in multiquery groups.
    fn issue_batch(&mut self, run: &mut Run<'_, '_>, s: &mut Scratch) -> Result<()> {
        let frame = self.frame;
        s.cand.clear();
        // A node never seen visible has been invisible since the history began.
        let never = self.origin.saturating_sub(1);
        s.cand.extend(s.batch.drain(..).map(|node| {
            let last = self.state[node as usize].last_visible.max(never);
            (
                keep_invisible(frame.saturating_sub(last.saturating_add(1))),
                node,
            )
        }));
        let cand = &mut s.cand;
        cand.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut k = 0;
        while k < cand.len() {
            // Grow a group while nodes settled per expected query grows.
            let (mut prod, mut value, mut end) = (cand[k].0, 1.0, k + 1);
            while end < cand.len() {
                let p = prod * cand[end].0;
                let m = (end + 1 - k) as f64;
                let v = m / (1.0 + (1.0 - p) * m);
                if v <= value {
                    break;
                }
                (prod, value, end) = (p, v, end + 1);
            }
            s.volume.clear();
            for &(_, node) in &cand[k..end] {
                query_volume(run.h, node, &mut s.volume);
            }
            let id = run.query_union(&s.volume)?;
            let pending = if end - k == 1 {
                Pending::Node {
                    node: cand[k].1,
                    was_visible: false,
                }
            } else {
                let start = s.groups.len() as u32;
                s.groups.extend(cand[k..end].iter().map(|c| c.1));
                Pending::Group {
                    start,
                    len: (end - k) as u32,
                }
            };
            s.pending.push_back((id, pending));
            k = end;
        }
        Ok(())
    }

    fn chcpp_result(
        &mut self,
        run: &mut Run<'_, '_>,
        s: &mut Scratch,
        p: Pending,
        samples: u32,
    ) -> Result<()> {
        if !run.visible(samples) {
            if let Pending::Revisit(node) = p {
                // Drawn, but hidden: not visible (nor its ancestors, unless
                // another descendant is).
                self.state[node as usize].visible = false;
                let obj = run.h.nodes[node as usize].object;
                run.out.visible.retain(|o| o.slot() != obj);
            }
            return Ok(());
        }
        match p {
            Pending::Revisit(_) => {}
            Pending::Node { node, was_visible } => {
                self.pull_up(run.h, node);
                let n = run.h.nodes[node as usize];
                if n.is_leaf() {
                    run.out.visible.push(ObjectId::from_slot(n.object));
                }
                if !was_visible {
                    self.traverse(run, &mut s.distance, &n)?;
                }
            }
            Pending::Group { start, len } => {
                // Split: every node of a visible group gets its own query.
                for k in start..start + len {
                    let node = s.groups[k as usize];
                    s.volume.clear();
                    query_volume(run.h, node, &mut s.volume);
                    let id = run.query_union(&s.volume)?;
                    s.pending.push_back((
                        id,
                        Pending::Node {
                            node,
                            was_visible: false,
                        },
                    ));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The phases spread a view's leaves over the revisit interval: every
    /// node is due exactly once per `revisit` frames, and about a fifth of
    /// the nodes in each frame.
    #[test]
    fn revisits_are_due_once_per_interval_and_spread() {
        let o = ChcppOptions::default();
        let nodes = 10_000u32;
        let mut per_frame = [0u32; 5];
        for node in 0..nodes {
            let due: Vec<u32> = (1..=10).filter(|&f| o.revisit_due(node, f)).collect();
            assert_eq!(due.len(), 2, "node {node}: {due:?}");
            assert_eq!(due[1] - due[0], 5);
            per_frame[(due[0] - 1) as usize] += 1;
        }
        for n in per_frame {
            assert!((1700..2300).contains(&n), "{per_frame:?}");
        }
        let other = ChcppOptions { seed: 2, ..o };
        assert!((0..100).any(|k| o.revisit_due(k, 1) != other.revisit_due(k, 1)));
    }

    /// The stay-invisible estimate grows with the frames invisible, from 0.29.
    #[test]
    fn keep_invisible_grows_toward_099() {
        assert!((keep_invisible(0) - 0.29).abs() < 1e-12);
        assert!((1..30).all(|t| keep_invisible(t) > keep_invisible(t - 1)));
        assert!(keep_invisible(40) <= 0.99 && keep_invisible(10) > 0.989);
    }
}
