//! Silhouette extraction with signed edge counters [AW §2.3–2.4, Steiner §4.2, A.2].
//!
//! Every casting (light-facing) triangle adds the direction in which it
//! traverses each of its edges to that edge's counter: `+1` along the edge's
//! stored direction, `−1` against it. An edge then yields `|counter|` side quads
//! oriented by the counter's sign. The counters are the boundary of the chain of
//! casting triangles, so the result is right for closed, open and non-manifold
//! meshes and for mixed winding with no per-case code.
//!
//! Facing is the one rule, [`scene::faces_light`], on the f64 world positions
//! of the one transform path ([`scene::Scene::world_triangle`]); mirrored
//! instances are counted in world winding.

use glam::DMat4;
use scene::{faces_light, Light, ObjectId, Scene};

/// A silhouette edge: directed `from → to` the way the casting triangles
/// traverse it (world winding), used `multiplicity` times.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SilhouetteEdge {
    /// Start vertex (index into the mesh's welded positions).
    pub from: u32,
    /// End vertex.
    pub to: u32,
    /// `|counter|` of the edge, ≥ 1.
    pub multiplicity: u32,
}

/// The silhouette of one caster for one light.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Silhouette {
    /// Edges with a non-zero counter, in mesh edge order.
    pub edges: Vec<SilhouetteEdge>,
    /// The casting triangles (the light cap) as mesh vertex indices, ordered so
    /// that in world space they are counter-clockwise seen from the light.
    pub caps: Vec<[u32; 3]>,
}

impl Silhouette {
    /// Silhouette edges counted with multiplicity.
    pub fn edge_count(&self) -> usize {
        self.edges.iter().map(|e| e.multiplicity as usize).sum()
    }
}

/// Computes the silhouette of object `id` for `light` into `out` (cleared first).
///
/// One-sided (`two_sided = false`): the triangles that face the light cast.
/// Two-sided: every triangle casts, back-facing ones flipped before counting (a
/// triangle with the light exactly in its plane casts in neither mode).
///
/// # Panics
/// If `id` is not an object of `scene`.
pub fn silhouette(
    scene: &Scene,
    id: ObjectId,
    light: &Light,
    two_sided: bool,
    out: &mut Silhouette,
) {
    let mirrored = scene.object(id).mirrored;
    silhouette_with(scene, id, light, two_sided, mirrored, out, &mut Vec::new());
}

/// [`silhouette`] (into `out`, cleared first) with the per-edge counters in
/// `counters` (reused): with `out`'s lists reserved at their bounds (the
/// mesh's triangle and edge counts), a recomputed entry allocates nothing.
fn silhouette_with(
    scene: &Scene,
    id: ObjectId,
    light: &Light,
    two_sided: bool,
    mirrored: bool,
    out: &mut Silhouette,
    counters: &mut Vec<i32>,
) {
    out.edges.clear();
    out.caps.clear();
    let mesh = scene.object_mesh(id);
    out.caps.reserve(mesh.triangles().len());
    out.edges.reserve(mesh.edges().len());
    counters.clear();
    counters.resize(mesh.edges().len(), 0);
    count(scene, id, light, two_sided, mirrored, counters, out);
}

/// The counting of [`silhouette`], with `counters` zeroed, one per mesh edge.
fn count(
    scene: &Scene,
    id: ObjectId,
    light: &Light,
    two_sided: bool,
    mirrored: bool,
    counters: &mut [i32],
    out: &mut Silhouette,
) {
    let mesh = scene.object_mesh(id);
    for (t, (tri, refs)) in mesh
        .triangles()
        .iter()
        .zip(mesh.triangle_edges())
        .enumerate()
    {
        let world = scene.world_triangle(id, t);
        let sign = if faces_light(&world, light) {
            1
        } else if two_sided && faces_light(&[world[0], world[2], world[1]], light) {
            -1
        } else {
            continue;
        };
        // World winding: flipped for mirrored objects, and again for flipped
        // back faces in two-sided mode.
        let flip = (sign < 0) != mirrored;
        let s = if flip { -1 } else { 1 };
        for r in refs {
            counters[r.index()] += s * r.sign();
        }
        out.caps
            .push(if flip { [tri[0], tri[2], tri[1]] } else { *tri });
    }
    for (edge, &c) in mesh.edges().iter().zip(counters.iter()) {
        if c != 0 {
            let [a, b] = edge.v;
            let (from, to) = if c > 0 { (a, b) } else { (b, a) };
            out.edges.push(SilhouetteEdge {
                from,
                to,
                multiplicity: c.unsigned_abs(),
            });
        }
    }
}

/// Bit pattern identifying a light's geometry (its homogeneous position or
/// direction): the cache key part for the light.
fn light_key(light: &Light) -> [u64; 4] {
    light.homogeneous().to_array().map(|v| (v + 0.0).to_bits())
}

struct Entry {
    world_from_local: DMat4,
    two_sided: bool,
    silhouette: Silhouette,
}

/// The entries of one light, indexed by object id.
struct LightEntries {
    key: [u64; 4],
    last_used: u64,
    objects: Vec<Option<Entry>>,
}

/// Silhouettes cached per (object, light) and recomputed only when the
/// object's world transform, the light's position/direction or the two-sided
/// option differs from the one the entry was computed with (exact comparison).
///
/// Per light (identified by the bits of its homogeneous position or direction)
/// a dense table indexed by object id. Tables of lights that moved are left
/// behind; [`SilhouetteCache::next_frame`] and [`SilhouetteCache::evict_unused`]
/// drop them.
#[derive(Default)]
pub struct SilhouetteCache {
    lights: Vec<LightEntries>,
    frame: u64,
    hits: usize,
    misses: usize,
    stale: Vec<(ObjectId, Silhouette)>,
    /// Per entry of `stale` its edge counters, kept between updates.
    counters: Vec<Vec<i32>>,
    pub(crate) scratch: crate::VolumeScratch,
}

impl std::fmt::Debug for SilhouetteCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SilhouetteCache")
            .field("entries", &self.len())
            .field("lights", &self.lights.len())
            .field("frame", &self.frame)
            .finish()
    }
}

impl SilhouetteCache {
    /// An empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// Number of cached silhouettes.
    pub fn len(&self) -> usize {
        self.lights
            .iter()
            .map(|l| l.objects.iter().flatten().count())
            .sum()
    }

    /// True when nothing is cached.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Drops every entry.
    pub fn clear(&mut self) {
        self.lights.clear();
    }

    /// Starts a new frame (lights used from now on count as used in it).
    pub fn next_frame(&mut self) {
        self.frame += 1;
    }

    /// Drops the tables of lights not used in the last `frames` frames (0: not
    /// in this one).
    pub fn evict_unused(&mut self, frames: u64) {
        let oldest = self.frame.saturating_sub(frames);
        self.lights.retain(|l| l.last_used >= oldest);
    }

    /// Lookups answered from the cache and recomputations, since creation.
    pub fn hits_misses(&self) -> (usize, usize) {
        (self.hits, self.misses)
    }

    /// Drops every light's entry of object `id` (its mesh changed, or its
    /// slot now holds another object): the next update recomputes it.
    pub fn invalidate(&mut self, id: ObjectId) {
        for l in &mut self.lights {
            if let Some(e) = l.objects.get_mut(id.0 as usize) {
                *e = None;
            }
        }
    }

    /// Makes sure the silhouettes of `ids` for `light` are current, computing
    /// the missing or stale ones (in parallel with the `parallel` feature).
    ///
    /// # Panics
    /// If an id is not an object of `scene`.
    pub fn update(&mut self, scene: &Scene, light: &Light, two_sided: bool, ids: &[ObjectId]) {
        let key = light_key(light);
        let slot = match self.lights.iter().position(|l| l.key == key) {
            Some(i) => i,
            None => {
                self.lights.push(LightEntries {
                    key,
                    last_used: self.frame,
                    objects: Vec::new(),
                });
                self.lights.len() - 1
            }
        };
        let table = &mut self.lights[slot];
        table.last_used = self.frame;
        if table.objects.len() < scene.objects().len() {
            table.objects.resize_with(scene.objects().len(), || None);
        }
        // Stale entries give their buffers back for reuse.
        let mut work = std::mem::take(&mut self.stale);
        work.clear();
        for &id in ids {
            let w = &scene.object(id).world_from_local;
            let e = &mut table.objects[id.0 as usize];
            let current = e
                .as_ref()
                .is_some_and(|e| e.two_sided == two_sided && same_bits(&e.world_from_local, w));
            if current {
                self.hits += 1;
                continue;
            }
            // Mark the entry current now (a repeated id then counts as a hit)
            // and take its buffers for the recomputation.
            let old = e.replace(Entry {
                world_from_local: *w,
                two_sided,
                silhouette: Silhouette::default(),
            });
            work.push((id, old.map(|o| o.silhouette).unwrap_or_default()));
        }
        self.misses += work.len();
        if self.counters.len() < work.len() {
            self.counters.resize_with(work.len(), Vec::new);
        }
        let compute = |((id, s), c): (&mut (ObjectId, Silhouette), &mut Vec<i32>)| {
            let mirrored = scene.object(*id).mirrored;
            silhouette_with(scene, *id, light, two_sided, mirrored, s, c);
        };
        #[cfg(feature = "parallel")]
        {
            use rayon::prelude::*;
            work.par_iter_mut()
                .zip(self.counters.par_iter_mut())
                .for_each(compute);
        }
        #[cfg(not(feature = "parallel"))]
        work.iter_mut()
            .zip(self.counters.iter_mut())
            .for_each(compute);
        for (id, s) in work.drain(..) {
            if let Some(e) = &mut table.objects[id.0 as usize] {
                e.silhouette = s;
            }
        }
        self.stale = work;
    }

    /// The cached silhouette of `id` for `light`, if present (current or not;
    /// call [`SilhouetteCache::update`] first).
    pub fn get(&self, id: ObjectId, light: &Light) -> Option<&Silhouette> {
        let key = light_key(light);
        self.lights
            .iter()
            .find(|l| l.key == key)?
            .objects
            .get(id.0 as usize)?
            .as_ref()
            .map(|e| &e.silhouette)
    }
}

fn same_bits(a: &DMat4, b: &DMat4) -> bool {
    a.to_cols_array()
        .iter()
        .zip(b.to_cols_array().iter())
        .all(|(x, y)| x.to_bits() == y.to_bits())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DVec3, Vec3};
    use scene::{Mesh, SceneGraph, Transform};

    fn scene_of(mesh: Mesh, t: Transform) -> Scene {
        let mut g = SceneGraph::new();
        let m = g.add_mesh(mesh);
        g.add_instance("o", m, t);
        Scene::new(g).unwrap()
    }

    fn point(p: DVec3) -> Light {
        Light::Point {
            position: p,
            range: None,
        }
    }

    #[test]
    fn open_quad_facing_the_light_gives_its_boundary() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let m = Mesh::new("quad", &p, &[[0, 1, 2], [0, 2, 3]]).unwrap();
        let s = scene_of(m, Transform::default());
        let mut out = Silhouette::default();
        silhouette(
            &s,
            ObjectId(0),
            &point(DVec3::new(0.5, 0.5, 3.0)),
            false,
            &mut out,
        );
        assert_eq!(out.caps.len(), 2);
        assert_eq!(out.edge_count(), 4);
        let mut dir: Vec<(u32, u32)> = out.edges.iter().map(|e| (e.from, e.to)).collect();
        dir.sort_unstable();
        assert_eq!(dir, vec![(0, 1), (1, 2), (2, 3), (3, 0)]);
        // Seen from below: nothing casts one-sided, the reversed loop two-sided.
        let below = point(DVec3::new(0.5, 0.5, -3.0));
        silhouette(&s, ObjectId(0), &below, false, &mut out);
        assert!(out.edges.is_empty() && out.caps.is_empty());
        silhouette(&s, ObjectId(0), &below, true, &mut out);
        let mut dir: Vec<(u32, u32)> = out.edges.iter().map(|e| (e.from, e.to)).collect();
        dir.sort_unstable();
        assert_eq!(dir, vec![(0, 3), (1, 0), (2, 1), (3, 2)]);
    }

    #[test]
    fn non_manifold_fin() {
        // Three triangles on edge (0,1), all facing +z... two do, one is vertical.
        let p = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(0.5, -1.0, 0.0),
            Vec3::new(0.5, 0.0, 1.0),
        ];
        // t0 = (0,1,2) and t1 = (1,0,3)·reversed... t1 = (0,3,1) faces +z too;
        // t2 = (0,1,4) is the fin (normal −y).
        let m = Mesh::new("fin", &p, &[[0, 1, 2], [0, 3, 1], [0, 1, 4]]).unwrap();
        let s = scene_of(m, Transform::default());
        let mut out = Silhouette::default();
        silhouette(
            &s,
            ObjectId(0),
            &point(DVec3::new(0.3, 0.1, 5.0)),
            false,
            &mut out,
        );
        // t0 and t1 cast and cancel on (0,1); the fin faces the light too (light at y > 0?
        // no: the fin's normal is −y and the light has y = 0.1 > 0), so it does not.
        assert_eq!(out.caps.len(), 2);
        assert!(out
            .edges
            .iter()
            .all(|e| (e.from.min(e.to), e.from.max(e.to)) != (0, 1)));
        assert_eq!(out.edge_count(), 4);
        // Light on the fin's front side: (0,1) is traversed by t0 (+), t1 (−), t2 (+).
        silhouette(
            &s,
            ObjectId(0),
            &point(DVec3::new(0.3, -0.1, 5.0)),
            false,
            &mut out,
        );
        assert_eq!(out.caps.len(), 3);
        let e01 = out
            .edges
            .iter()
            .find(|e| (e.from.min(e.to), e.from.max(e.to)) == (0, 1))
            .unwrap();
        assert_eq!((e01.from, e01.to, e01.multiplicity), (0, 1, 1));
    }

    #[test]
    fn mirrored_instance_counts_in_world_winding() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let m = Mesh::new("quad", &p, &[[0, 1, 2], [0, 2, 3]]).unwrap();
        let s = scene_of(
            m,
            Transform::Matrix(DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0))),
        );
        let mut out = Silhouette::default();
        silhouette(
            &s,
            ObjectId(0),
            &point(DVec3::new(-0.5, 0.5, 3.0)),
            false,
            &mut out,
        );
        assert_eq!(out.caps.len(), 2);
        // The cap triangles are CCW seen from the light in world space.
        let o = s.object(ObjectId(0));
        for c in &out.caps {
            let w = c.map(|i| {
                scene::transform::world_point(
                    &o.world_from_local,
                    s.object_mesh(ObjectId(0)).positions()[i as usize],
                )
            });
            assert!((w[1] - w[0]).cross(w[2] - w[0]).z > 0.0);
        }
        let mut dir: Vec<(u32, u32)> = out.edges.iter().map(|e| (e.from, e.to)).collect();
        dir.sort_unstable();
        assert_eq!(dir, vec![(0, 3), (1, 0), (2, 1), (3, 2)]);
    }

    #[test]
    fn cache_recomputes_only_on_change() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let m = Mesh::new("tri", &p, &[[0, 1, 2]]).unwrap();
        let mut s = scene_of(m, Transform::default());
        let l = point(DVec3::new(0.2, 0.2, 2.0));
        let mut c = SilhouetteCache::new();
        c.update(&s, &l, false, &[ObjectId(0)]);
        c.update(&s, &l, false, &[ObjectId(0)]);
        assert_eq!(c.hits_misses(), (1, 1));
        assert_eq!(c.get(ObjectId(0), &l).unwrap().edge_count(), 3);
        s.set_object_transform(
            ObjectId(0),
            DMat4::from_translation(DVec3::new(0.0, 0.0, 5.0)),
        )
        .unwrap();
        c.update(&s, &l, false, &[ObjectId(0)]);
        assert_eq!(c.hits_misses(), (1, 2));
        assert_eq!(c.get(ObjectId(0), &l).unwrap().edge_count(), 0);
        let l2 = point(DVec3::new(0.2, 0.2, 9.0));
        c.update(&s, &l2, false, &[ObjectId(0)]);
        assert_eq!(c.hits_misses(), (1, 3));
        assert_eq!(c.len(), 2);
        c.next_frame();
        c.update(&s, &l2, false, &[ObjectId(0)]);
        c.evict_unused(0);
        assert_eq!(c.len(), 1);
        assert!(c.get(ObjectId(0), &l).is_none());
    }
}
