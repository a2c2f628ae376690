//! The flattened scene: objects = (node, mesh) pairs with world transforms,
//! world bounds and an object BVH (obvhs) that is refit, not rebuilt, when
//! objects move.

use crate::ids::next_generation;
use crate::{Aabb, Error, Mesh, MeshId, NodeId, ObjectId, Result, SceneGraph, Topology, Transform};
use glam::{DMat4, DVec3, Vec3, Vec3A};
use obvhs::bvh2::Bvh2;

/// Deepest node nesting accepted when flattening (deeper is an error, not a stack overflow).
pub const MAX_NODE_DEPTH: usize = 4096;

/// Most objects a scene may flatten into (guards against exponential instancing).
pub const MAX_OBJECTS: usize = 1 << 24;

/// What an object takes part in; every flag on by default.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectFlags {
    /// It has shadow volumes and blocks light: it can be a potential shadow
    /// caster, light views draw it as an occluder, the reference's shadow
    /// rays stop at it. Off: light passes through it (no shadow of its own).
    pub casts: bool,
    /// Its surface can be in shadow. Off: its lit side is lit whatever
    /// stands between it and the light.
    pub receives: bool,
    /// The culling passes may use it as an occluder. Off: it is still drawn
    /// (when visible) and still casts, but never hides another object from
    /// a query (a hint for thin or see-through geometry; never changes a mask).
    pub occludes: bool,
    /// The eye sees it: it has pixels. Off: an invisible shadow proxy (with
    /// `casts`) or a disabled object.
    pub visible: bool,
}

impl ObjectFlags {
    /// Every flag on.
    pub const ALL: ObjectFlags = ObjectFlags {
        casts: true,
        receives: true,
        occludes: true,
        visible: true,
    };
}

impl Default for ObjectFlags {
    fn default() -> Self {
        ObjectFlags::ALL
    }
}

/// One drawable instance: a mesh at a node.
#[derive(Clone, Debug)]
pub struct Object {
    /// The node that places it.
    pub node: NodeId,
    /// The mesh it draws.
    pub mesh: MeshId,
    /// Accumulated transform of the node path (f64).
    pub world_from_local: DMat4,
    /// True when `world_from_local` has a negative determinant; triangles are
    /// then reported with flipped winding so world-space facing stays right.
    pub mirrored: bool,
    /// World-space bounds (outward-rounded f32); [`Aabb::EMPTY`] for a removed object.
    pub world_bounds: Aabb,
    /// False once removed ([`Scene::stage_remove_object`]): a removed object
    /// draws the scene's empty mesh, has empty bounds, and no traversal,
    /// pass or reference sees it; its slot may be reused.
    pub alive: bool,
    /// What it takes part in.
    pub flags: ObjectFlags,
    /// The host's occluder for it ([`Scene::set_occluder`]): a mesh drawn in
    /// its place, with its transform, where views draw occluders from
    /// proxies (`occluders: proxy`); `None`: its own mesh or automatic proxy.
    pub occluder: Option<MeshId>,
}

/// A scene ready for culling: the graph, its objects, bounds and object BVH.
#[derive(Clone)]
pub struct Scene {
    graph: SceneGraph,
    objects: Vec<Object>,
    bounds: Aabb,
    bvh: Bvh2,
    /// The BVH's inner nodes, children before parents: the refit's order
    /// (found once per build, so a refit allocates nothing).
    refit_order: Vec<u32>,
    /// Staged edits not yet committed: the BVH needs a rebuild (slots were
    /// added) or a refit (bounds changed).
    pending: Pending,
    /// The mesh removed objects draw (no triangles), added on first removal.
    empty_mesh: Option<MeshId>,
    /// Per mesh slot: its generation, whether it is free, and its version.
    mesh_slots: Vec<MeshSlot>,
    /// Mesh slots freed by [`Scene::stage_remove_mesh`] (each holds an empty
    /// mesh until reused), lowest last.
    free_meshes: Vec<u32>,
    /// Bumped whenever the BVH is rebuilt (its topology changed).
    bvh_version: u64,
    /// Generation per object slot (missing entries are 0).
    generations: Vec<u32>,
    /// Freed object slots, lowest last.
    free_slots: Vec<u32>,
}

/// A mesh slot's bookkeeping.
#[derive(Clone, Copy, Debug, Default)]
struct MeshSlot {
    generation: u32,
    /// Removed: the slot holds an empty mesh and waits for reuse (or is retired).
    free: bool,
    /// Bumped whenever the slot's vertices change (deformation, removal,
    /// reuse), so that copies kept outside the scene know when to refresh.
    version: u64,
}

/// Pushes `slot` on a free list kept lowest last (`pop` reuses the lowest).
fn free_slot(list: &mut Vec<u32>, slot: u32) {
    let at = list.partition_point(|&s| s > slot);
    list.insert(at, slot);
}

/// Staged edits of a [`Scene`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Pending {
    rebuild: bool,
    refit: bool,
}

/// What [`Scene::commit_edits`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Committed {
    /// The object BVH was rebuilt: objects were added in new slots, so its
    /// topology (and [`Scene::bvh_version`]) changed.
    pub rebuilt: bool,
    /// The object BVH was refit: bounds changed, the topology did not.
    pub refit: bool,
}

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("objects", &self.objects.len())
            .field("meshes", &self.graph.meshes().len())
            .field("bounds", &self.bounds)
            .finish()
    }
}

/// Counts over a whole scene, as `shadowcull inspect` prints them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct SceneCounts {
    /// Objects (instances).
    pub objects: usize,
    /// Distinct meshes.
    pub meshes: usize,
    /// Triangles as loaded, summed over all instances: the file's own count,
    /// including the degenerate triangles that meshes drop.
    pub triangles: usize,
    /// Triangles kept and drawn (degenerate ones dropped), summed over all instances.
    pub drawn_triangles: usize,
    /// Welded vertices summed over all instances.
    pub vertices: usize,
    /// Topology counts summed over distinct meshes.
    pub topology: Topology,
}

impl Scene {
    /// Flattens `graph` into objects and builds the object BVH.
    ///
    /// # Errors
    /// [`Error::Graph`] on a node cycle, a dangling node or mesh index, a
    /// non-finite transform, nesting deeper than [`MAX_NODE_DEPTH`], or more
    /// than [`MAX_OBJECTS`] objects.
    pub fn new(graph: SceneGraph) -> Result<Scene> {
        let objects = flatten(&graph)?;
        let meshes = graph.meshes().len();
        let mut scene = Scene {
            graph,
            objects,
            bounds: Aabb::EMPTY,
            bvh: Bvh2::default(),
            refit_order: Vec::new(),
            pending: Pending::default(),
            empty_mesh: None,
            mesh_slots: vec![MeshSlot::default(); meshes],
            free_meshes: Vec::new(),
            bvh_version: 0,
            generations: Vec::new(),
            free_slots: Vec::new(),
        };
        scene.bounds = scene.compute_bounds();
        scene.set_bvh(scene.build_bvh());
        Ok(scene)
    }

    fn compute_bounds(&self) -> Aabb {
        self.objects
            .iter()
            .fold(Aabb::EMPTY, |b, o| b.union(&o.world_bounds))
    }

    fn build_bvh(&self) -> Bvh2 {
        if self.objects.is_empty() {
            return Bvh2::default();
        }
        // Removed objects enter the build as a point at the scene's centre
        // (the builder wants finite boxes); the refit after a rebuild gives
        // their leaves empty bounds.
        let centre = if self.bounds.is_empty() {
            Vec3::ZERO
        } else {
            self.bounds.center().as_vec3()
        };
        let boxes: Vec<obvhs::aabb::Aabb> = self
            .objects
            .iter()
            .map(|o| {
                if o.world_bounds.is_empty() {
                    to_obvhs(&Aabb {
                        min: centre,
                        max: centre,
                    })
                } else {
                    to_obvhs(&o.world_bounds)
                }
            })
            .collect();
        let mut params = obvhs::BvhBuildParams::medium_build();
        // One object per leaf: visibility traverses objects, and refit needs it.
        params.max_prims_per_leaf = 1;
        let mut bvh = crate::bvh_build::build_bvh2(&boxes, params);
        bvh.init_primitives_to_nodes_if_uninit();
        bvh
    }

    /// The graph the scene was built from.
    pub fn graph(&self) -> &SceneGraph {
        &self.graph
    }

    /// All objects, indexed by [`ObjectId`].
    pub fn objects(&self) -> &[Object] {
        &self.objects
    }

    /// One object.
    ///
    /// # Panics
    /// If `id` is out of range (ids come from this scene).
    pub fn object(&self, id: ObjectId) -> &Object {
        &self.objects[id.slot() as usize]
    }

    /// The mesh an object draws.
    pub fn object_mesh(&self, id: ObjectId) -> &Mesh {
        &self.graph.meshes()[self.object(id).mesh.index()]
    }

    /// World bounds of all objects (the scene bounds S of [Steiner §4.3.3]).
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The object BVH: leaf primitive `i` is `ObjectId::from_slot(bvh.primitive_indices[i])`.
    pub fn object_bvh(&self) -> &Bvh2 {
        &self.bvh
    }

    /// Load warnings of the graph.
    pub fn warnings(&self) -> &[String] {
        self.graph.warnings()
    }

    /// Triangle `t` of object `id` in world space (f64, from the one transform
    /// path), counter-clockwise = front even for mirrored objects.
    pub fn world_triangle(&self, id: ObjectId, t: usize) -> [DVec3; 3] {
        let o = self.object(id);
        let mesh = &self.graph.meshes()[o.mesh.index()];
        let [a, b, c] = mesh
            .triangle(t)
            .map(|p| crate::transform::world_point(&o.world_from_local, p));
        if o.mirrored {
            [a, c, b]
        } else {
            [a, b, c]
        }
    }

    /// Counts over the scene.
    pub fn counts(&self) -> SceneCounts {
        let mut c = SceneCounts {
            objects: self.objects.iter().filter(|o| o.alive).count(),
            meshes: self.mesh_slots.iter().filter(|m| !m.free).count()
                - usize::from(self.empty_mesh.is_some()),
            ..Default::default()
        };
        for o in self.objects.iter().filter(|o| o.alive) {
            let m = &self.graph.meshes()[o.mesh.index()];
            c.triangles += m.triangles().len() + m.topology().degenerate_triangles;
            c.drawn_triangles += m.triangles().len();
            c.vertices += m.positions().len();
        }
        for (_, m) in self.graph.meshes().iter().enumerate().filter(|&(i, _)| {
            !self.mesh_slots[i].free && self.empty_mesh.is_none_or(|e| e.index() != i)
        }) {
            let t = m.topology();
            c.topology.boundary_edges += t.boundary_edges;
            c.topology.non_manifold_edges += t.non_manifold_edges;
            c.topology.inconsistent_edges += t.inconsistent_edges;
            c.topology.degenerate_triangles += t.degenerate_triangles;
        }
        c
    }

    /// Sets a node's local transform and updates every affected object's world
    /// transform and bounds; the BVH is refit, not rebuilt.
    ///
    /// # Errors
    /// [`Error::Graph`] when the node does not exist or the transform is not
    /// finite or is projective.
    pub fn set_node_transform(&mut self, node: NodeId, transform: Transform) -> Result<()> {
        check_transform(node, &transform)?;
        if self
            .objects
            .iter()
            .any(|o| o.node.0 == u32::MAX || !o.alive)
        {
            return Err(Error::Graph {
                node: node.0,
                message: "the scene has objects added or removed by id: move them by id".into(),
            });
        }
        self.graph.node_mut(node)?.transform = transform;
        let objects = flatten(&self.graph)?;
        debug_assert_eq!(objects.len(), self.objects.len());
        self.objects = objects;
        self.refit();
        Ok(())
    }

    /// Sets one object's world transform directly (for hosts that animate
    /// objects themselves) and refits the BVH.
    ///
    /// # Errors
    /// [`Error::Transform`] naming the object when the matrix is not finite or
    /// is projective.
    pub fn set_object_transform(&mut self, id: ObjectId, world_from_local: DMat4) -> Result<()> {
        let o = self.objects.get(id.index()).ok_or(Error::Graph {
            node: u32::MAX,
            message: format!("no object {}", id),
        })?;
        check_object_transform(|| format!("object {}", id), &world_from_local)?;
        let mesh_bounds = self.graph.meshes()[o.mesh.index()].bounds();
        check_flattening(|| format!("object {}", id), &mesh_bounds, &world_from_local)?;
        let world = world_bounds(&mesh_bounds, &world_from_local, o.node)?;
        let o = &mut self.objects[id.index()];
        o.world_from_local = world_from_local;
        o.mirrored = world_from_local.determinant() < 0.0;
        o.world_bounds = world;
        self.refit();
        Ok(())
    }

    /// Bumped whenever the object BVH is rebuilt (its topology changed):
    /// per-node state kept outside the scene must then be remapped.
    pub fn bvh_version(&self) -> u64 {
        self.bvh_version
    }

    /// The slot of `id` when it names a live object of this scene (slot in
    /// range, same generation, not removed).
    ///
    /// # Errors
    /// [`Error::UnknownObject`] for an id out of range, of an older
    /// generation, or of a removed object.
    pub fn live_slot(&self, id: ObjectId) -> Result<u32> {
        let slot = id.slot();
        match self.objects.get(slot as usize) {
            Some(o) if o.alive && self.generation(slot) == id.generation() => Ok(slot),
            Some(_) => Err(Error::UnknownObject {
                id,
                message: "removed (a stale id: its slot was freed or reused)".into(),
            }),
            None => Err(Error::UnknownObject {
                id,
                message: format!(
                    "slot {slot} is out of range ({} objects)",
                    self.objects.len()
                ),
            }),
        }
    }

    /// The generation of `slot` (0 for a never-reused slot).
    pub fn generation(&self, slot: u32) -> u32 {
        self.generations.get(slot as usize).copied().unwrap_or(0)
    }

    /// The public id of the object in `slot`: slot and generation.
    pub fn id_of(&self, slot: u32) -> ObjectId {
        ObjectId::new(slot, self.generation(slot))
    }

    /// Adds `mesh` and returns its id; objects may then instance it. It
    /// takes the lowest slot a removed mesh freed (at that slot's next
    /// generation), or a new one.
    pub fn add_mesh(&mut self, mesh: Mesh) -> MeshId {
        match self.free_meshes.pop() {
            Some(slot) => {
                let m = &mut self.mesh_slots[slot as usize];
                m.free = false;
                m.version += 1;
                let id = MeshId::new(slot, m.generation);
                self.graph.replace_mesh(id, mesh);
                id
            }
            None => {
                self.mesh_slots.push(MeshSlot::default());
                self.graph.add_mesh(mesh)
            }
        }
    }

    /// The version of `mesh`'s vertex data: bumped by every replacement
    /// (deformation, removal), so copies kept outside the scene know when to
    /// refresh. 0 for an unknown mesh.
    pub fn mesh_version(&self, mesh: MeshId) -> u64 {
        self.mesh_slots.get(mesh.index()).map_or(0, |m| m.version)
    }

    /// Replaces live `mesh` by `new` (a deformation: the same triangles with
    /// moved vertices) and updates the bounds of every live object drawing
    /// it; returns their slots. Takes effect at [`Scene::commit_edits`].
    ///
    /// # Errors
    /// [`Error::UnknownMesh`] when `mesh` is unknown or removed, or `new` has
    /// another number of triangles or vertices (a topology change: add a new
    /// mesh instead).
    pub fn stage_replace_mesh(&mut self, mesh: MeshId, new: Mesh) -> Result<Vec<u32>> {
        let old = self.live_mesh(mesh)?;
        if old.triangles().len() != new.triangles().len()
            || old.positions().len() != new.positions().len()
        {
            return Err(Error::UnknownMesh {
                mesh,
                message: format!(
                    "the new vertices change the topology ({} triangles and {} welded vertices, \
                     were {} and {}): add a new mesh instead",
                    new.triangles().len(),
                    new.positions().len(),
                    old.triangles().len(),
                    old.positions().len()
                ),
            });
        }
        let bounds = new.bounds();
        for o in self.objects.iter().filter(|o| o.alive && o.mesh == mesh) {
            world_bounds(&bounds, &o.world_from_local, o.node)?;
        }
        self.graph.replace_mesh(mesh, new);
        self.mesh_slots[mesh.index()].version += 1;
        let mut slots = Vec::new();
        for (i, o) in self.objects.iter_mut().enumerate() {
            if o.alive && o.mesh == mesh {
                o.world_bounds = bounds.transformed(&o.world_from_local);
                slots.push(i as u32);
            }
        }
        self.pending.refit = true;
        Ok(slots)
    }

    /// The live mesh `mesh`.
    ///
    /// # Errors
    /// [`Error::UnknownMesh`] when out of range or removed.
    pub fn live_mesh(&self, mesh: MeshId) -> Result<&Mesh> {
        let i = mesh.index();
        match self.graph.meshes().get(i) {
            Some(m)
                if !self.mesh_slots[i].free
                    && self.mesh_slots[i].generation == mesh.generation()
                    && Some(mesh) != self.empty_mesh =>
            {
                Ok(m)
            }
            _ => Err(Error::UnknownMesh {
                mesh,
                message: "out of range or removed".into(),
            }),
        }
    }

    /// Removes `mesh`: its slot holds an empty mesh until [`Scene::add_mesh`]
    /// reuses it at the next generation (the old id stays dead).
    ///
    /// # Errors
    /// [`Error::UnknownMesh`] when out of range, removed, or instanced by a
    /// live object (naming the object).
    pub fn stage_remove_mesh(&mut self, mesh: MeshId) -> Result<()> {
        self.live_mesh(mesh)?;
        if let Some((slot, _)) = self
            .objects
            .iter()
            .enumerate()
            .find(|(_, o)| o.alive && (o.mesh == mesh || o.occluder == Some(mesh)))
        {
            let what = match self.objects[slot].mesh == mesh {
                true => "instanced",
                false => "the occluder",
            };
            return Err(Error::UnknownMesh {
                mesh,
                message: format!("still {what} of object {}", self.id_of(slot as u32)),
            });
        }
        let empty = Mesh::new(
            self.graph.meshes()[mesh.index()].name().to_string(),
            &[],
            &[],
        )?;
        self.graph.replace_mesh(mesh, empty);
        let m = &mut self.mesh_slots[mesh.index()];
        m.free = true;
        m.version += 1;
        if let Some(g) = next_generation(m.generation) {
            m.generation = g;
            free_slot(&mut self.free_meshes, mesh.slot());
        }
        Ok(())
    }

    /// Adds an object drawing `mesh` at `world_from_local`, in the lowest free
    /// slot (whose generation is bumped; a slot whose generation would wrap is
    /// retired instead) or a new one. Takes effect at [`Scene::commit_edits`].
    ///
    /// # Errors
    /// [`Error::UnknownMesh`]; [`Error::Transform`] for a non-finite or projective
    /// matrix; [`Error::Graph`] past
    /// [`MAX_OBJECTS`] slots.
    pub fn stage_add_object(
        &mut self,
        mesh: MeshId,
        world_from_local: DMat4,
        flags: ObjectFlags,
    ) -> Result<ObjectId> {
        let bounds = self.live_mesh(mesh)?.bounds();
        // Host objects belong to no graph node.
        let node = NodeId(u32::MAX);
        let adding = || format!("the object being added (mesh {mesh})");
        check_object_transform(adding, &world_from_local)?;
        check_flattening(adding, &bounds, &world_from_local)?;
        let object = Object {
            node,
            mesh,
            world_from_local,
            mirrored: world_from_local.determinant() < 0.0,
            world_bounds: world_bounds(&bounds, &world_from_local, node)?,
            alive: true,
            flags,
            occluder: None,
        };
        let slot = match self.free_slots.pop() {
            Some(slot) => {
                self.objects[slot as usize] = object;
                self.pending.refit = true;
                slot
            }
            None => {
                if self.objects.len() >= MAX_OBJECTS {
                    return Err(Error::Graph {
                        node: node.0,
                        message: format!("more than {MAX_OBJECTS} objects"),
                    });
                }
                self.objects.push(object);
                self.pending.rebuild = true;
                (self.objects.len() - 1) as u32
            }
        };
        Ok(self.id_of(slot))
    }

    /// Makes room for `objects` objects in all: slots past the current ones
    /// are made free (empty, as removed objects' are), so that
    /// [`Scene::stage_add_object`] takes them up to that count without
    /// growing the object list or rebuilding the BVH (a refit does). The
    /// rebuild for the new slots happens once, at the next
    /// [`Scene::commit_edits`]. Fewer objects than there are slots is a
    /// no-op.
    ///
    /// # Errors
    /// [`Error::Graph`] past [`MAX_OBJECTS`].
    pub fn reserve_objects(&mut self, objects: usize) -> Result<()> {
        if objects > MAX_OBJECTS {
            return Err(Error::Graph {
                node: u32::MAX,
                message: format!("reserve: {objects} objects, more than {MAX_OBJECTS}"),
            });
        }
        let from = self.objects.len();
        if objects <= from {
            return Ok(());
        }
        let empty = self.empty_mesh()?;
        self.objects.reserve_exact(objects - from);
        self.objects.extend((from..objects).map(|_| Object {
            node: NodeId(u32::MAX),
            mesh: empty,
            world_from_local: DMat4::IDENTITY,
            mirrored: false,
            world_bounds: Aabb::EMPTY,
            alive: false,
            flags: ObjectFlags {
                casts: false,
                receives: false,
                occludes: false,
                visible: false,
            },
            occluder: None,
        }));
        self.generations.resize(objects, 0);
        // Lowest last, below the slots freed before (all lower).
        let freed = std::mem::take(&mut self.free_slots);
        self.free_slots.reserve_exact(objects);
        self.free_slots.extend((from as u32..objects as u32).rev());
        self.free_slots.extend(freed);
        self.pending.rebuild = true;
        Ok(())
    }

    /// The empty mesh removed objects and reserved slots draw, made on first use.
    fn empty_mesh(&mut self) -> Result<MeshId> {
        Ok(match self.empty_mesh {
            Some(m) => m,
            None => {
                let m = self.add_mesh(Mesh::new("<removed>", &[], &[])?);
                self.empty_mesh = Some(m);
                m
            }
        })
    }

    /// Moves object `id` to `world_from_local`. Takes effect at [`Scene::commit_edits`].
    ///
    /// # Errors
    /// As [`Scene::live_slot`]; [`Error::Transform`] naming the object for a
    /// non-finite or projective matrix.
    pub fn stage_set_transform(&mut self, id: ObjectId, world_from_local: DMat4) -> Result<()> {
        let slot = self.live_slot(id)? as usize;
        let o = &self.objects[slot];
        check_object_transform(|| format!("object {}", id), &world_from_local)?;
        let bounds = self.graph.meshes()[o.mesh.index()].bounds();
        check_flattening(|| format!("object {}", id), &bounds, &world_from_local)?;
        let world = world_bounds(&bounds, &world_from_local, o.node)?;
        let o = &mut self.objects[slot];
        o.world_from_local = world_from_local;
        o.mirrored = world_from_local.determinant() < 0.0;
        o.world_bounds = world;
        self.pending.refit = true;
        Ok(())
    }

    /// Sets object `id`'s flags (immediately: they change no bounds).
    ///
    /// # Errors
    /// As [`Scene::live_slot`].
    pub fn set_flags(&mut self, id: ObjectId, flags: ObjectFlags) -> Result<()> {
        let slot = self.live_slot(id)?;
        self.objects[slot as usize].flags = flags;
        Ok(())
    }

    /// Sets the host's occluder of object `id` (immediately: it changes no
    /// bounds): `mesh`, with the object's transform, stands in for the
    /// object's own mesh wherever views draw occluders from proxies. The host
    /// promises that it hides nothing the object does not: it lies inside
    /// the object's solid (or on its surface), as an engine's hand-made
    /// low-poly occluder does. `None` goes back to the object's own mesh.
    ///
    /// # Errors
    /// As [`Scene::live_slot`]; [`Error::UnknownMesh`] for an unknown,
    /// removed or empty mesh, or one whose bounds reach outside the bounds
    /// of the object's own mesh (beyond 10⁻⁶ of their diagonal): such an
    /// occluder would hide what its object does not.
    pub fn set_occluder(&mut self, id: ObjectId, mesh: Option<MeshId>) -> Result<()> {
        let slot = self.live_slot(id)? as usize;
        if let Some(m) = mesh {
            let occluder = self.live_mesh(m)?;
            let own = self.graph.meshes()[self.objects[slot].mesh.index()].bounds();
            let b = occluder.bounds();
            if occluder.triangles().is_empty() {
                return Err(Error::UnknownMesh {
                    mesh: m,
                    message: format!("occluder of object {}: has no triangles", id),
                });
            }
            if !occluder_fits(&own, &b) {
                return Err(Error::UnknownMesh {
                    mesh: m,
                    message: format!(
                        "occluder of object {}: its bounds {:?}..{:?} reach outside the \
                         object's mesh's {:?}..{:?}",
                        id, b.min, b.max, own.min, own.max
                    ),
                });
            }
        }
        self.objects[slot].occluder = mesh;
        Ok(())
    }

    /// Gives object `id` another mesh (a level-of-detail change), keeping its
    /// id, flags, transform and occluder. Takes effect at
    /// [`Scene::commit_edits`] (a refit).
    ///
    /// # Errors
    /// As [`Scene::live_slot`] and [`Scene::live_mesh`]; [`Error::Transform`]
    /// when the object's transform flattens the new mesh; [`Error::UnknownMesh`]
    /// when the object's occluder reaches outside the new mesh's bounds
    /// (clear it first with [`Scene::set_occluder`]).
    pub fn stage_set_mesh(&mut self, id: ObjectId, mesh: MeshId) -> Result<()> {
        let slot = self.live_slot(id)? as usize;
        let bounds = self.live_mesh(mesh)?.bounds();
        let o = &self.objects[slot];
        check_flattening(|| format!("object {}", id), &bounds, &o.world_from_local)?;
        let world = world_bounds(&bounds, &o.world_from_local, o.node)?;
        if let Some(occluder) = o.occluder {
            let b = self.graph.meshes()[occluder.index()].bounds();
            if !occluder_fits(&bounds, &b) {
                return Err(Error::UnknownMesh {
                    mesh,
                    message: format!(
                        "the new mesh of object {id}: its occluder (mesh {occluder}) reaches \
                         outside its bounds; clear the occluder first"
                    ),
                });
            }
        }
        let o = &mut self.objects[slot];
        o.mesh = mesh;
        o.world_bounds = world;
        self.pending.refit = true;
        Ok(())
    }

    /// Removes object `id`: it draws the empty mesh and has empty bounds; its
    /// slot is freed for reuse with the next generation (or retired when the
    /// generation would wrap). Takes effect at [`Scene::commit_edits`].
    ///
    /// # Errors
    /// As [`Scene::live_slot`].
    pub fn stage_remove_object(&mut self, id: ObjectId) -> Result<()> {
        let slot = self.live_slot(id)?;
        let empty = self.empty_mesh()?;
        let o = &mut self.objects[slot as usize];
        o.alive = false;
        o.mesh = empty;
        o.occluder = None;
        o.world_bounds = Aabb::EMPTY;
        let generations = &mut self.generations;
        if generations.len() <= slot as usize {
            generations.resize(slot as usize + 1, 0);
        }
        if let Some(g) = next_generation(generations[slot as usize]) {
            generations[slot as usize] = g;
            free_slot(&mut self.free_slots, slot);
        }
        self.pending.refit = true;
        Ok(())
    }

    /// Applies the staged edits: rebuilds the object BVH when objects were
    /// added in new slots (bumping [`Scene::bvh_version`]), else refits it
    /// when bounds changed; recomputes the scene bounds.
    pub fn commit_edits(&mut self) -> Committed {
        let p = std::mem::take(&mut self.pending);
        if p.rebuild {
            self.bounds = self.compute_bounds();
            self.set_bvh(self.build_bvh());
            self.bvh_version += 1;
            self.refit();
        } else if p.refit {
            self.refit();
        }
        Committed {
            rebuilt: p.rebuild,
            refit: p.refit && !p.rebuild,
        }
    }

    /// True while staged edits wait for [`Scene::commit_edits`].
    pub fn has_staged_edits(&self) -> bool {
        self.pending != Pending::default()
    }

    fn refit(&mut self) {
        self.bounds = self.compute_bounds();
        if self.objects.is_empty() {
            return;
        }
        for (prim, o) in self.objects.iter().enumerate() {
            let node = self.bvh.primitives_to_nodes[prim] as usize;
            self.bvh.nodes[node].set_aabb(to_obvhs(&o.world_bounds));
        }
        let nodes = &mut self.bvh.nodes;
        for &i in &self.refit_order {
            let first = nodes[i as usize].first_index as usize;
            let b = nodes[first].aabb().union(nodes[first + 1].aabb());
            nodes[i as usize].set_aabb(b);
        }
    }

    /// Takes `bvh` as the object BVH and finds its refit order.
    fn set_bvh(&mut self, bvh: Bvh2) {
        self.bvh = bvh;
        self.refit_order.clear();
        if self.bvh.nodes.is_empty() {
            return;
        }
        // Pre-order from the root, reversed: every inner node after its children.
        let mut stack = vec![0u32];
        while let Some(i) = stack.pop() {
            let n = &self.bvh.nodes[i as usize];
            if !n.is_leaf() {
                self.refit_order.push(i);
                stack.extend([n.first_index, n.first_index + 1]);
            }
        }
        self.refit_order.reverse();
    }
}

/// Whether an occluder mesh's bounds `occluder` lie inside its object's
/// mesh's bounds `own`, up to 10⁻⁶ of their diagonal (the rounding of
/// meshes that share a surface): an occluder reaching further could hide
/// what its object does not.
fn occluder_fits(own: &Aabb, occluder: &Aabb) -> bool {
    let slack = 1e-6 * (own.max - own.min).length();
    !(occluder.min.cmplt(own.min - slack).any() || occluder.max.cmpgt(own.max + slack).any())
}

/// `bounds` (a mesh's) in world space by `world_from_local`; an error naming
/// `node` when they overflow to a non-finite box (a finite matrix or mesh can
/// still be too large for f32 world bounds).
fn world_bounds(bounds: &Aabb, world_from_local: &DMat4, node: NodeId) -> Result<Aabb> {
    let b = bounds.transformed(world_from_local);
    if b.is_empty() || (b.min.is_finite() && b.max.is_finite()) {
        return Ok(b);
    }
    Err(Error::Graph {
        node: node.0,
        message: "the object's world bounds overflow (its matrix or mesh is too large)".into(),
    })
}

fn to_obvhs(b: &Aabb) -> obvhs::aabb::Aabb {
    obvhs::aabb::Aabb::new(Vec3A::from(b.min), Vec3A::from(b.max))
}

/// What makes transform `t` unusable, if anything: a non-finite element, or
/// a projective matrix (its bottom row not (0, 0, 0, 1), within 10⁻⁹).
/// Every stage places points by the affine part alone
/// (`DMat4::transform_point3`), so a projective transform would be read as
/// another one than the host meant, and the reference with it.
pub(crate) fn transform_fault(t: &Transform) -> Option<String> {
    let finite = match t {
        Transform::Trs {
            translation,
            rotation,
            scale,
        } => translation.is_finite() && rotation.is_finite() && scale.is_finite(),
        Transform::Matrix(m) => m.is_finite(),
    };
    if !finite {
        return Some("is not finite".into());
    }
    let Transform::Matrix(m) = t else {
        return None;
    };
    let row = m.row(3);
    let affine = (row - glam::DVec4::W).abs().max_element() <= 1e-9;
    (!affine).then(|| {
        format!(
            "is projective: its bottom row is ({}, {}, {}, {}), not (0, 0, 0, 1) (meshes are \
             placed by affine transforms)",
            row.x, row.y, row.z, row.w
        )
    })
}

/// Relative thinness below which a placed mesh counts as flattened: its
/// thinnest extent over the size of its coordinates (the distance of its
/// bounds' centre from the origin plus its extents), about 4,500 f64 ulps.
/// Below it the placement rounds a solid into a sheet (a box scaled by 0 in
/// one axis, or by 10⁻²⁰⁰), whose faces coincide, and the masks disagree
/// with the reference (a box scaled by 0 in y lost its whole shadow); at
/// 10⁻⁹ of a unit box they still agree.
const FLAT_RELATIVE: f64 = 1e-12;

/// How much thinner, relative to its coordinates, the transform must make a
/// mesh than it is in its own space to count as flattening it: a mesh that
/// is thin in its own coordinates is the host's shape, not the placement's.
const FLATTENED_BY: f64 = 1e3;

/// The thinnest extent of the box spanned by `axes` (its edge vectors),
/// over the size of its coordinates (`centre`'s distance from the origin
/// plus the edges' lengths); `None` for a box of fewer than two edges or of
/// size 0 (a point).
fn relative_thinness(axes: &[glam::DVec3], centre: glam::DVec3) -> Option<f64> {
    let size: f64 = axes.iter().map(|v| v.length()).sum();
    if size == 0.0 {
        return None;
    }
    let thinnest = match *axes {
        [a, b, c] => {
            let face = [a.cross(b), b.cross(c), c.cross(a)]
                .iter()
                .map(|n| n.length())
                .fold(0.0, f64::max);
            match face {
                0.0 => 0.0,
                f => a.dot(b.cross(c)).abs() / f,
            }
        }
        [a, b] => a.cross(b).length() / a.length().max(b.length()),
        _ => return None,
    };
    Some(thinnest / (size + centre.length()))
}

/// Whether `world_from_local` flattens a mesh with local bounds `bounds`:
/// the world image of its bounds' box (along the axes the mesh extends in)
/// is thinner than [`FLAT_RELATIVE`] of its coordinates' size, and
/// [`FLATTENED_BY`] times thinner so than in the mesh's own space. A
/// transform that collapses the box to a point (scaled by 0) is not
/// flattening: the object has no pixels and casts nothing, consistently.
fn flattening(bounds: &Aabb, world_from_local: &DMat4) -> Option<String> {
    if bounds.is_empty() {
        return None;
    }
    let e = (bounds.max - bounds.min).as_dvec3();
    let centre = bounds.center();
    // The axes the mesh extends in (on the stack: an edit allocates nothing).
    let mut local = [glam::DVec3::ZERO; 3];
    let mut n = 0;
    for v in [
        glam::DVec3::X * e.x,
        glam::DVec3::Y * e.y,
        glam::DVec3::Z * e.z,
    ] {
        if v.length() > 0.0 {
            local[n] = v;
            n += 1;
        }
    }
    let world = local.map(|v| world_from_local.transform_vector3(v));
    let placed = relative_thinness(&world[..n], world_from_local.transform_point3(centre))?;
    let own = relative_thinness(&local[..n], centre)?;
    (placed < FLAT_RELATIVE && placed * FLATTENED_BY < own).then(|| {
        format!(
            "flattens its mesh: its thinnest extent becomes {placed:e} of its coordinates' \
             size ({own:e} in its own space), which rounding turns into a sheet whose shadow \
             is wrong (scale an object by 0 in every axis, or switch it off with its flags, \
             to hide it)"
        )
    })
}

/// [`transform_fault`] as an error naming graph node `node`.
fn check_transform(node: NodeId, t: &Transform) -> Result<()> {
    match transform_fault(t) {
        None => Ok(()),
        Some(message) => Err(Error::Graph {
            node: node.0,
            message: format!("transform {message}"),
        }),
    }
}

/// [`flattening`] as an error naming the object.
fn check_flattening(object: impl FnOnce() -> String, bounds: &Aabb, m: &DMat4) -> Result<()> {
    match flattening(bounds, m) {
        None => Ok(()),
        Some(message) => Err(Error::Transform {
            object: object(),
            message,
        }),
    }
}

/// [`transform_fault`] of a host object's matrix, as an error naming the
/// object (`object()`: its id, or the mesh of the one being added).
fn check_object_transform(object: impl FnOnce() -> String, m: &DMat4) -> Result<()> {
    match transform_fault(&Transform::Matrix(*m)) {
        None => Ok(()),
        Some(message) => Err(Error::Transform {
            object: object(),
            message,
        }),
    }
}

/// Walks the graph with an explicit stack (no recursion), detecting cycles and
/// limiting depth, and emits one object per (node, mesh) in depth-first order.
fn flatten(graph: &SceneGraph) -> Result<Vec<Object>> {
    let nodes = graph.nodes();
    let n_meshes = graph.meshes().len();
    let mut on_path = vec![false; nodes.len()];
    let mut path: Vec<NodeId> = Vec::new();
    let mut objects = Vec::new();
    // (node, depth, parent's world transform)
    let mut stack: Vec<(NodeId, usize, DMat4)> = graph
        .roots()
        .iter()
        .rev()
        .map(|&r| (r, 0, DMat4::IDENTITY))
        .collect();
    while let Some((id, depth, parent)) = stack.pop() {
        while path.len() > depth {
            let left = path.pop().expect("path is longer than depth");
            on_path[left.0 as usize] = false;
        }
        let node = nodes.get(id.0 as usize).ok_or(Error::Graph {
            node: id.0,
            message: format!("referenced, but the graph has only {} nodes", nodes.len()),
        })?;
        if on_path[id.0 as usize] {
            return Err(Error::Graph {
                node: id.0,
                message: "node cycle: the node is its own ancestor".into(),
            });
        }
        if depth >= MAX_NODE_DEPTH {
            return Err(Error::Graph {
                node: id.0,
                message: format!("nodes nested deeper than {MAX_NODE_DEPTH} levels"),
            });
        }
        check_transform(id, &node.transform)?;
        on_path[id.0 as usize] = true;
        path.push(id);
        let world = parent * node.transform.matrix();
        for &m in &node.meshes {
            let mesh = graph.meshes().get(m.index()).ok_or(Error::Graph {
                node: id.0,
                message: format!(
                    "mesh {} referenced, but there are only {n_meshes}",
                    m.slot()
                ),
            })?;
            if let Some(message) = flattening(&mesh.bounds(), &world) {
                return Err(Error::Graph {
                    node: id.0,
                    message: format!("transform {message}"),
                });
            }
            if objects.len() >= MAX_OBJECTS {
                return Err(Error::Graph {
                    node: id.0,
                    message: format!("more than {MAX_OBJECTS} objects"),
                });
            }
            objects.push(Object {
                node: id,
                mesh: m,
                world_from_local: world,
                mirrored: world.determinant() < 0.0,
                world_bounds: mesh.bounds().transformed(&world),
                alive: true,
                flags: ObjectFlags::ALL,
                occluder: None,
            });
        }
        for &c in node.children.iter().rev() {
            stack.push((c, depth + 1, world));
        }
    }
    Ok(objects)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{faces_light, Light, Node};
    use glam::Vec3;

    fn tri_mesh() -> Mesh {
        Mesh::new("tri", &[Vec3::ZERO, Vec3::X, Vec3::NEG_Z], &[[0, 1, 2]]).unwrap()
    }

    /// Found by the `obj` fuzz target: objects whose bounds coincide chain
    /// the object BVH as deep as their count, and obvhs' debug validation
    /// panicked on the depth (`bvh_build`). Tests run with debug assertions.
    #[test]
    fn coinciding_instances_build_a_scene() {
        let mut g = SceneGraph::new();
        let m = g.add_mesh(tri_mesh());
        for k in 0..300 {
            g.add_instance(&format!("o{k}"), m, Transform::default());
        }
        let s = Scene::new(g).unwrap();
        let bvh = s.object_bvh();
        assert!(bvh.max_depth > crate::bvh_build::depth(bvh));
        assert_eq!(bvh.primitive_indices.len(), 300);
    }

    #[test]
    fn instancing_and_hierarchy_accumulate() {
        let mut g = SceneGraph::new();
        let m = g.add_mesh(tri_mesh());
        let child = g.add_node(Node {
            name: "c".into(),
            transform: Transform::translation(DVec3::new(0.0, 1.0, 0.0)),
            meshes: vec![m],
            children: vec![],
        });
        g.add_root(Node {
            name: "p".into(),
            transform: Transform::translation(DVec3::new(10.0, 0.0, 0.0)),
            meshes: vec![m],
            children: vec![child],
        });
        let s = Scene::new(g).unwrap();
        assert_eq!(s.objects().len(), 2);
        assert_eq!(s.counts().triangles, 2);
        assert_eq!(s.counts().meshes, 1);
        assert_eq!(
            s.object(ObjectId::from_slot(1)).world_bounds.min,
            Vec3::new(10.0, 1.0, -1.0)
        );
        assert_eq!(s.bounds().max, Vec3::new(11.0, 1.0, 0.0));
    }

    #[test]
    fn cycles_are_errors_not_hangs() {
        let mut g = SceneGraph::new();
        let a = g.add_root(Node::default());
        let b = g.add_node(Node {
            children: vec![a],
            ..Node::default()
        });
        g.node_mut(a).unwrap().children.push(b);
        let e = Scene::new(g).unwrap_err();
        assert!(e.to_string().contains("cycle"), "{e}");
    }

    #[test]
    fn deep_chains_are_errors_not_overflows() {
        let mut g = SceneGraph::new();
        let mut prev = g.add_root(Node::default());
        for _ in 0..200_000 {
            let n = g.add_node(Node::default());
            g.node_mut(prev).unwrap().children.push(n);
            prev = n;
        }
        assert!(Scene::new(g).is_err());
    }

    #[test]
    fn mirrored_instances_keep_world_facing() {
        let mut g = SceneGraph::new();
        let m = g.add_mesh(tri_mesh()); // CCW seen from +y
        g.add_instance(
            "mirror",
            m,
            Transform::Matrix(DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0))),
        );
        let s = Scene::new(g).unwrap();
        assert!(s.object(ObjectId::from_slot(0)).mirrored);
        let above = Light::Point {
            position: DVec3::new(-0.2, 3.0, -0.2),
            range: None,
        };
        // The mirror image of an upward-facing triangle still faces up.
        assert!(faces_light(
            &s.world_triangle(ObjectId::from_slot(0), 0),
            &above
        ));
    }

    #[test]
    fn moving_objects_refits_bounds_and_bvh() {
        let mut g = SceneGraph::new();
        let m = g.add_mesh(tri_mesh());
        let n0 = g.add_instance("a", m, Transform::default());
        g.add_instance("b", m, Transform::translation(DVec3::new(5.0, 0.0, 0.0)));
        let mut s = Scene::new(g).unwrap();
        s.set_node_transform(n0, Transform::translation(DVec3::new(0.0, 100.0, 0.0)))
            .unwrap();
        assert_eq!(s.bounds().max.y, 100.0);
        let root = s.object_bvh().nodes[0];
        assert_eq!(root.aabb().max.y, 100.0);
        s.set_object_transform(
            ObjectId::from_slot(1),
            DMat4::from_translation(DVec3::new(0.0, -7.0, 0.0)),
        )
        .unwrap();
        assert_eq!(s.object_bvh().nodes[0].aabb().min.y, -7.0);
        assert!(s
            .set_node_transform(n0, Transform::translation(DVec3::NAN))
            .is_err());
    }

    /// A finite matrix whose world bounds overflow f32 is refused (the BVH
    /// builder needs finite boxes), on add and on move; the scene stays as it was.
    #[test]
    fn overflowing_world_bounds_are_refused() {
        let cube = crate::procedural::analytic::box_mesh("cube", Vec3::ZERO, Vec3::ONE).unwrap();
        let mut s = Scene::new(SceneGraph::new()).unwrap();
        let m = s.add_mesh(cube);
        let huge = DMat4::from_scale(DVec3::splat(1e300));
        let e = s.stage_add_object(m, huge, ObjectFlags::ALL).unwrap_err();
        assert!(e.to_string().contains("overflow"), "{e}");
        let a = s
            .stage_add_object(m, DMat4::IDENTITY, ObjectFlags::ALL)
            .unwrap();
        assert!(s.stage_set_transform(a, huge).is_err());
        s.commit_edits();
        assert_eq!(
            s.object(ObjectId::from_slot(a.slot())).world_from_local,
            DMat4::IDENTITY
        );
        assert!(s.bounds().max.is_finite());
    }

    /// Host edits by id: stale ids are errors, slots are reused with the next
    /// generation (and retired before it wraps), the BVH is rebuilt only when
    /// slots are added, and removed objects vanish from counts and bounds.
    #[test]
    fn object_edits_by_id() {
        let cube = crate::procedural::analytic::box_mesh("cube", Vec3::ZERO, Vec3::ONE).unwrap();
        let mut s = Scene::new(SceneGraph::new()).unwrap();
        let m = s.add_mesh(cube);
        let at = |x: f64| DMat4::from_translation(DVec3::new(x, 0.0, 0.0));
        let a = s.stage_add_object(m, at(0.0), ObjectFlags::ALL).unwrap();
        let b = s.stage_add_object(m, at(5.0), ObjectFlags::ALL).unwrap();
        assert_eq!((a, b), (ObjectId::new(0, 0), ObjectId::new(1, 0)));
        assert!(s.has_staged_edits());
        let v = s.bvh_version();
        assert!(s.commit_edits().rebuilt);
        assert!(s.bvh_version() > v && !s.has_staged_edits());
        assert_eq!(s.counts().objects, 2);
        assert_eq!(s.bounds().max.x, 6.0);
        // Moving refits; removing empties the bounds and frees the slot.
        s.stage_set_transform(b, at(9.0)).unwrap();
        assert_eq!(
            s.commit_edits(),
            Committed {
                rebuilt: false,
                refit: true
            }
        );
        assert_eq!(s.bounds().max.x, 10.0);
        s.stage_remove_object(b).unwrap();
        s.commit_edits();
        assert_eq!(s.bounds().max.x, 1.0);
        assert_eq!(s.counts().objects, 1);
        assert!(s.object(b).world_bounds.is_empty() && s.object_mesh(b).triangles().is_empty());
        assert!(matches!(s.live_slot(b), Err(Error::UnknownObject { .. })));
        assert!(s.stage_set_transform(b, at(1.0)).is_err());
        assert!(s.stage_remove_object(b).is_err(), "double remove");
        // The freed slot comes back with the next generation; the old id stays stale.
        let c = s.stage_add_object(m, at(2.0), ObjectFlags::ALL).unwrap();
        assert_eq!((c.slot(), c.generation()), (1, 1));
        assert!(!s.commit_edits().rebuilt, "a reused slot refits");
        assert!(s.live_slot(b).is_err() && s.live_slot(c).is_ok());
        assert!(s.live_slot(ObjectId::new(7, 0)).is_err(), "out of range");
        // Churn reuses the one slot, each time at the next generation.
        let mut id = c;
        for _ in 0..300 {
            s.stage_remove_object(id).unwrap();
            id = s.stage_add_object(m, at(2.0), ObjectFlags::ALL).unwrap();
        }
        assert_eq!((id.slot(), id.generation()), (1, 301));
        assert_eq!(s.objects().len(), 2, "no slot added");
        // A slot whose generation would wrap is retired, never reused.
        s.generations[1] = u32::MAX - 1;
        let old = s.id_of(1);
        s.stage_remove_object(old).unwrap();
        id = s.stage_add_object(m, at(2.0), ObjectFlags::ALL).unwrap();
        assert_eq!(id.slot(), 1, "generation u32::MAX is still used");
        s.stage_remove_object(id).unwrap();
        id = s.stage_add_object(m, at(2.0), ObjectFlags::ALL).unwrap();
        assert_eq!(id.slot(), 2, "slot 1 retired after generation u32::MAX");
        assert!(s.live_slot(old).is_err());
        s.commit_edits();
        assert_eq!(s.counts().objects, 2);
        // A mesh cannot go while instanced; afterwards its id is dead.
        assert!(matches!(
            s.stage_remove_mesh(m),
            Err(Error::UnknownMesh { .. })
        ));
        s.stage_remove_object(a).unwrap();
        s.stage_remove_object(id).unwrap();
        s.stage_remove_mesh(m).unwrap();
        assert!(s.stage_add_object(m, at(0.0), ObjectFlags::ALL).is_err());
        assert!(s.stage_remove_mesh(m).is_err());
        s.commit_edits();
        assert_eq!(s.counts().objects, 0);
        assert!(s.bounds().is_empty());
        // The next mesh takes the freed mesh slot at the next generation, and
        // the old id stays dead.
        let meshes = s.graph().meshes().len();
        let version = s.mesh_version(m);
        let m2 =
            s.add_mesh(crate::procedural::analytic::box_mesh("c2", Vec3::ZERO, Vec3::ONE).unwrap());
        assert_eq!((m2.slot(), m2.generation()), (m.slot(), m.generation() + 1));
        assert_eq!(s.graph().meshes().len(), meshes, "no mesh slot added");
        assert!(s.mesh_version(m2) > version, "copies see the new mesh");
        assert!(s.live_mesh(m).is_err() && s.live_mesh(m2).is_ok());
        assert!(s.stage_add_object(m, at(0.0), ObjectFlags::ALL).is_err());
        assert_eq!(s.counts().meshes, 1);
        assert!(s
            .stage_add_object(
                m2,
                DMat4::from_cols_array(&[f64::NAN; 16]),
                ObjectFlags::ALL
            )
            .is_err());
    }

    /// A projective matrix (bottom row not (0, 0, 0, 1)) is refused on every
    /// path, naming the object or the node; a bottom row within 10⁻⁹ of it
    /// is taken.
    #[test]
    fn projective_transforms_are_refused() {
        use crate::procedural::analytic::box_mesh;
        let mut projective = DMat4::IDENTITY;
        projective.x_axis.w = 0.05;
        let cube = box_mesh("cube", Vec3::ZERO, Vec3::ONE).unwrap();
        let mut s = Scene::new(SceneGraph::new()).unwrap();
        let m = s.add_mesh(cube.clone());
        let e = s
            .stage_add_object(m, projective, ObjectFlags::ALL)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the object being added (mesh 0): transform is projective"),
            "{e}"
        );
        assert!(e.contains("(0.05, 0, 0, 1)"), "{e}");
        let a = s
            .stage_add_object(m, DMat4::IDENTITY, ObjectFlags::ALL)
            .unwrap();
        let e = s
            .stage_set_transform(a, projective)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("object 0: transform is projective"), "{e}");
        let mut nearly = DMat4::IDENTITY;
        nearly.w_axis.w = 1.0 + 1e-12;
        s.stage_set_transform(a, nearly).unwrap();
        let mut g = SceneGraph::new();
        let mesh = g.add_mesh(cube);
        g.add_instance("tilted", mesh, Transform::Matrix(projective));
        let e = Scene::new(g).expect_err("refused").to_string();
        assert!(e.contains("node 0: transform is projective"), "{e}");
    }

    /// A host's occluder must fit the object's mesh's bounds; a mesh used as
    /// one cannot be removed; removing the object (and so reusing its slot)
    /// forgets it.
    #[test]
    fn host_occluders_fit_their_objects() {
        use crate::procedural::analytic::box_mesh;
        let mut s = Scene::new(SceneGraph::new()).unwrap();
        let cube = s.add_mesh(box_mesh("cube", Vec3::ZERO, Vec3::ONE).unwrap());
        let inner = s.add_mesh(box_mesh("inner", Vec3::splat(0.2), Vec3::splat(0.8)).unwrap());
        let outer = s.add_mesh(box_mesh("outer", Vec3::splat(0.2), Vec3::splat(1.1)).unwrap());
        let empty = s.add_mesh(Mesh::new("empty", &[], &[]).unwrap());
        let a = s
            .stage_add_object(cube, DMat4::IDENTITY, ObjectFlags::ALL)
            .unwrap();
        s.set_occluder(a, Some(inner)).unwrap();
        assert_eq!(s.object(a).occluder, Some(inner));
        let e = s.set_occluder(a, Some(outer)).unwrap_err().to_string();
        assert!(
            e.contains("occluder of object 0") && e.contains("reach outside"),
            "{e}"
        );
        let e = s.set_occluder(a, Some(empty)).unwrap_err().to_string();
        assert!(e.contains("no triangles"), "{e}");
        assert!(s.set_occluder(a, Some(MeshId::from_slot(99))).is_err());
        assert_eq!(s.object(a).occluder, Some(inner), "refusals change nothing");
        let e = s.stage_remove_mesh(inner).unwrap_err().to_string();
        assert!(e.contains("the occluder of object 0"), "{e}");
        s.stage_remove_object(a).unwrap();
        assert!(s.set_occluder(a, None).is_err(), "a stale id");
        let b = s
            .stage_add_object(cube, DMat4::IDENTITY, ObjectFlags::ALL)
            .unwrap();
        assert_eq!((b.slot(), s.object(b).occluder), (a.slot(), None));
        s.stage_remove_mesh(inner).unwrap();
    }
}
