//! Silhouettes cached per (object, light) across frames [Steiner §4.2: static
//! caster–light pairs keep their silhouette], with the reusable scratch of
//! volume construction, so a steady frame recomputes and allocates nothing.

use crate::segments::SegmentScratch;
use crate::silhouette::{silhouette_with, Silhouette};
use crate::volume::VolumeScratch;
use glam::DMat4;
use scene::{Light, ObjectId, Scene};

/// Bit pattern identifying a light's geometry (its homogeneous position or
/// direction): the cache key part for the light.
fn light_key(light: &Light) -> [u64; 4] {
    light.homogeneous().to_array().map(|v| (v + 0.0).to_bits())
}

struct Entry {
    world_from_local: DMat4,
    two_sided: bool,
    /// Computed for its table's current light (false after the table was
    /// handed to another light position).
    valid: bool,
    silhouette: Silhouette,
}

/// Light positions kept at once per cache (one cache per pipeline light):
/// a light moving between a few positions keeps all of theirs; a light
/// moving on hands its least recently used table, entries and buffers
/// included, to the new position, so memory stays bounded and the
/// recomputation allocates nothing.
const LIGHT_TABLES: usize = 4;

/// The entries of one light, indexed by object id (boxed: most objects of a
/// large scene never cast for a given view, and an empty slot then costs 8
/// bytes, not an entry's 180).
struct LightEntries {
    key: [u64; 4],
    last_used: u64,
    /// [`SilhouetteCache::update`]'s count when it last used the table.
    used: u64,
    objects: Vec<Option<Box<Entry>>>,
}

/// Silhouettes cached per (object, light) and recomputed only when the
/// object's world transform, the light's position/direction or the two-sided
/// option differs from the one the entry was computed with (exact comparison).
///
/// Per light (identified by the bits of its homogeneous position or direction)
/// a dense table indexed by object id, at most four of them: a new position
/// takes over the least recently used table (its entries recomputed in
/// place). [`SilhouetteCache::evict_unused`] drops tables not used lately.
#[derive(Default)]
pub struct SilhouetteCache {
    lights: Vec<LightEntries>,
    frame: u64,
    /// Updates so far (the tables' recency).
    uses: u64,
    hits: usize,
    misses: usize,
    stale: Vec<(ObjectId, Silhouette)>,
    /// Per entry of `stale` its edge counters, kept between updates.
    counters: Vec<Vec<i32>>,
    pub(crate) scratch: VolumeScratch,
    pub(crate) segment_scratch: SegmentScratch,
    /// The parallel volume build's shares (`build.rs`).
    pub(crate) build_parts: Vec<crate::volume::BuildPart>,
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
            .map(|l| l.objects.iter().flatten().filter(|e| e.valid).count())
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
            if let Some(e) = l.objects.get_mut(id.index()) {
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
        self.uses += 1;
        let slot = match self.lights.iter().position(|l| l.key == key) {
            Some(i) => i,
            None if self.lights.len() >= LIGHT_TABLES => {
                let (i, _) = (self.lights.iter().enumerate())
                    .min_by_key(|(_, l)| l.used)
                    .expect("LIGHT_TABLES > 0");
                let table = &mut self.lights[i];
                table.key = key;
                for e in table.objects.iter_mut().flatten() {
                    e.valid = false;
                }
                i
            }
            None => {
                self.lights.push(LightEntries {
                    key,
                    last_used: self.frame,
                    used: self.uses,
                    objects: Vec::new(),
                });
                self.lights.len() - 1
            }
        };
        let table = &mut self.lights[slot];
        table.last_used = self.frame;
        table.used = self.uses;
        if table.objects.len() < scene.objects().len() {
            table.objects.resize_with(scene.objects().len(), || None);
        }
        // Stale entries give their buffers back for reuse.
        let mut work = std::mem::take(&mut self.stale);
        work.clear();
        for &id in ids {
            let w = &scene.object(id).world_from_local;
            let e = &mut table.objects[id.index()];
            let current = e.as_ref().is_some_and(|e| {
                e.valid && e.two_sided == two_sided && same_bits(&e.world_from_local, w)
            });
            if current {
                self.hits += 1;
                continue;
            }
            // Mark the entry current now (a repeated id then counts as a hit)
            // and take its buffers for the recomputation (a stale entry is
            // rewritten in place).
            let old = match e {
                Some(e) => {
                    e.world_from_local = *w;
                    e.two_sided = two_sided;
                    e.valid = true;
                    std::mem::take(&mut e.silhouette)
                }
                None => {
                    *e = Some(Box::new(Entry {
                        world_from_local: *w,
                        two_sided,
                        valid: true,
                        silhouette: Silhouette::default(),
                    }));
                    Silhouette::default()
                }
            };
            work.push((id, old));
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
            if let Some(e) = &mut table.objects[id.index()] {
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
            .get(id.index())?
            .as_ref()
            .filter(|e| e.valid)
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
    fn cache_recomputes_only_on_change() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let m = Mesh::new("tri", &p, &[[0, 1, 2]]).unwrap();
        let mut s = scene_of(m, Transform::default());
        let l = point(DVec3::new(0.2, 0.2, 2.0));
        let mut c = SilhouetteCache::new();
        c.update(&s, &l, false, &[ObjectId::from_slot(0)]);
        c.update(&s, &l, false, &[ObjectId::from_slot(0)]);
        assert_eq!(c.hits_misses(), (1, 1));
        assert_eq!(c.get(ObjectId::from_slot(0), &l).unwrap().edge_count(), 3);
        s.set_object_transform(
            ObjectId::from_slot(0),
            DMat4::from_translation(DVec3::new(0.0, 0.0, 5.0)),
        )
        .unwrap();
        c.update(&s, &l, false, &[ObjectId::from_slot(0)]);
        assert_eq!(c.hits_misses(), (1, 2));
        assert_eq!(c.get(ObjectId::from_slot(0), &l).unwrap().edge_count(), 0);
        let l2 = point(DVec3::new(0.2, 0.2, 9.0));
        c.update(&s, &l2, false, &[ObjectId::from_slot(0)]);
        assert_eq!(c.hits_misses(), (1, 3));
        assert_eq!(c.len(), 2);
        c.next_frame();
        c.update(&s, &l2, false, &[ObjectId::from_slot(0)]);
        c.evict_unused(0);
        assert_eq!(c.len(), 1);
        assert!(c.get(ObjectId::from_slot(0), &l).is_none());
    }

    /// A light moving on keeps at most [`LIGHT_TABLES`] tables: each new
    /// position takes over the least recently used one, whose entries are
    /// recomputed (never read as another position's), and positions seen
    /// lately stay cached.
    #[test]
    fn a_moving_light_keeps_a_bounded_cache() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let m = Mesh::new("tri", &p, &[[0, 1, 2]]).unwrap();
        let s = scene_of(m, Transform::default());
        let id = ObjectId::from_slot(0);
        // In front of the triangle (it casts: 3 edges) or behind (it does not).
        let at = |k: u32| {
            point(DVec3::new(
                0.2,
                0.2,
                if k.is_multiple_of(2) { 2.0 } else { -2.0 } + f64::from(k) * 1e-3,
            ))
        };
        let mut c = SilhouetteCache::new();
        for k in 0..40 {
            c.update(&s, &at(k), false, &[id]);
            let want = if k.is_multiple_of(2) { 3 } else { 0 };
            assert_eq!(
                c.get(id, &at(k)).unwrap().edge_count(),
                want,
                "position {k}"
            );
            assert!(c.lights.len() <= LIGHT_TABLES);
        }
        assert_eq!(c.len(), LIGHT_TABLES);
        assert!(
            c.get(id, &at(0)).is_none(),
            "a position handed over is gone"
        );
        let misses = c.hits_misses().1;
        c.update(&s, &at(39), false, &[id]);
        c.update(&s, &at(36), false, &[id]);
        assert_eq!(c.hits_misses().1, misses, "recent positions stay cached");
    }
}
