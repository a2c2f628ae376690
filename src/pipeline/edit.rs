//! The living scene: meshes, objects and lights added, moved and removed by
//! id between frames, and what the pipeline does so that nothing it keeps
//! goes stale — the hierarchy refit or rebuilt (per-node CHC state remapped
//! [`visibility::ViewCuller::remap`]), the silhouette caches invalidated for
//! exactly the objects that changed, the mesh copies and the reference's BVH
//! brought up to date. Edits are staged on the scene and applied once at the
//! start of the next [`Pipeline::frame`].

use super::{live_slots, LightId, LightSlot, LightState, Pipeline};
use crate::{Error, Result};
use glam::DMat4;
use scene::{Light, Mesh, MeshId, ObjectFlags, ObjectId, Scene};
use std::sync::Arc;

impl Pipeline {
    /// The scene for editing: shared scenes are copied on first edit.
    fn scene_mut(&mut self) -> &mut Scene {
        Arc::make_mut(&mut self.scene)
    }

    /// Makes room for `objects` objects and `lights` lights in all, so that
    /// adding up to that many later allocates nothing in
    /// [`Pipeline::add_object`] and [`Pipeline::add_light`], and an object
    /// added into a reserved slot refits the object hierarchy instead of
    /// rebuilding it (an object added past every slot rebuilds it, and
    /// remaps every view's culling history). `reserve` itself allocates,
    /// and the next frame rebuilds the hierarchy once over the new slots;
    /// the frames after objects or lights are added allocate for their new
    /// work as any first frames do (`docs/host.md`, "Allocations"). Counts
    /// at or below what is there already change nothing.
    ///
    /// # Errors
    /// [`Error::Scene`] past [`scene::MAX_OBJECTS`] objects; [`Error::Options`]
    /// past 2^32 − 1 lights.
    pub fn reserve(&mut self, objects: usize, lights: usize) -> Result<()> {
        if lights > u32::MAX as usize {
            return Err(Error::Options {
                field: "reserve".into(),
                message: format!("{lights} lights, more than {}", u32::MAX),
            });
        }
        if objects > self.scene.objects().len() {
            self.scene_mut().reserve_objects(objects)?;
            self.edited = true;
        }
        for list in [&mut self.all_visible, &mut self.all_casters, &mut self.psr] {
            list.reserve(objects.saturating_sub(list.len()));
        }
        self.lights
            .reserve(lights.saturating_sub(self.lights.len()));
        self.retired
            .reserve(lights.saturating_sub(self.retired.len()));
        Ok(())
    }

    /// Adds a mesh that objects can then instance ([`Pipeline::add_object`]).
    pub fn add_mesh(&mut self, mesh: Mesh) -> MeshId {
        self.edited = true;
        self.scene_mut().add_mesh(mesh)
    }

    /// Removes a mesh no object instances any more; its id is dead afterwards.
    ///
    /// # Errors
    /// [`Error::Scene`] naming the mesh when it is unknown, removed, or still
    /// instanced (naming an object that uses it).
    pub fn remove_mesh(&mut self, mesh: MeshId) -> Result<()> {
        self.scene_mut().stage_remove_mesh(mesh)?;
        self.edited = true;
        Ok(())
    }

    /// Deforms `mesh`: `positions` are its new vertices, `triangles` the index
    /// buffer it was built from (same topology; the mesh is rebuilt and
    /// welded as [`Mesh::new`] does). Every object drawing it takes the new
    /// shape from the next frame on; only their silhouettes are recomputed.
    ///
    /// # Errors
    /// [`Error::Scene`] for an unknown or removed mesh, an index out of range,
    /// a non-finite vertex, or a change of topology (naming the mesh).
    pub fn update_mesh_positions(
        &mut self,
        mesh: MeshId,
        positions: &[glam::Vec3],
        triangles: &[[u32; 3]],
    ) -> Result<()> {
        let shape = self.scene.live_mesh(mesh)?.deformed(positions, triangles)?;
        self.update_mesh(mesh, shape)
    }

    /// Deforms `mesh` to the host's own vertex buffer, read as
    /// [`Mesh::from_strided`] reads it (`indices` the index buffer it was
    /// built from), as [`Pipeline::update_mesh_positions`] does.
    ///
    /// # Errors
    /// As [`Pipeline::update_mesh_positions`], and [`Mesh::from_strided`]'s
    /// errors for the buffers.
    pub fn update_mesh_strided(
        &mut self,
        mesh: MeshId,
        positions: scene::StridedPositions<'_>,
        indices: scene::Indices<'_>,
    ) -> Result<()> {
        let shape = self
            .scene
            .live_mesh(mesh)?
            .deformed_strided(positions, indices)?;
        self.update_mesh(mesh, shape)
    }

    /// Deforms `mesh` to `shape`, a mesh of the same topology (built with
    /// [`Mesh::new`] or, from the host's own vertex buffer,
    /// [`Mesh::from_strided`]), as [`Pipeline::update_mesh_positions`] does.
    ///
    /// # Errors
    /// [`Error::Scene`] for an unknown or removed mesh or a change of
    /// topology (naming the mesh).
    pub fn update_mesh(&mut self, mesh: MeshId, shape: Mesh) -> Result<()> {
        let slots = self.scene_mut().stage_replace_mesh(mesh, shape)?;
        for slot in slots {
            self.invalidate_silhouettes(ObjectId::from_slot(slot));
        }
        Ok(())
    }

    /// Adds an object drawing `mesh` with `world_from_local` (f64, column
    /// vectors, finite) and `flags` ([`ObjectFlags::ALL`] for an ordinary
    /// object). It takes part from the next frame on; its id stays
    /// valid until [`Pipeline::remove_object`].
    ///
    /// # Errors
    /// [`Error::Scene`] for an unknown mesh, a non-finite or projective
    /// matrix (bottom row not (0, 0, 0, 1), naming the object), or past
    /// [`scene::MAX_OBJECTS`] objects.
    pub fn add_object(
        &mut self,
        mesh: MeshId,
        world_from_local: DMat4,
        flags: ObjectFlags,
    ) -> Result<ObjectId> {
        let id = self
            .scene_mut()
            .stage_add_object(mesh, world_from_local, flags)?;
        // A reused slot must not keep the old object's silhouettes.
        self.invalidate_silhouettes(id);
        Ok(id)
    }

    /// Sets what object `id` takes part in ([`ObjectFlags`]: casts, receives,
    /// occludes, visible) from the next frame on.
    ///
    /// # Errors
    /// [`Error::Scene`] for an unknown, removed or stale id.
    pub fn set_flags(&mut self, id: ObjectId, flags: ObjectFlags) -> Result<()> {
        self.scene_mut().set_flags(id, flags)?;
        self.edited = true;
        Ok(())
    }

    /// Gives object `id` the host's own occluder from the next frame on:
    /// `occluder` (a mesh added with [`Pipeline::add_mesh`], placed by the
    /// object's transform) is what the light views and a coarse eye pass
    /// draw for it in place of its mesh, under `occluders: proxy`
    /// ([`crate::OccludersSpec::Proxy`]); `None` goes back to its own mesh
    /// or automatic proxy. Engines author such occluders low-poly and inside
    /// the visible mesh; the host promises the occluder hides nothing the
    /// object does not hide, from any eye or light (it lies inside the
    /// object's solid, or on its surface). An occluder that breaks the
    /// promise makes culling drop casters and receivers that are visible:
    /// [`Pipeline::check_gpu`] finds it (shadow_bench `--check-gpu`).
    ///
    /// # Errors
    /// [`Error::Scene`] for an unknown, removed or stale object id; an
    /// unknown, removed or empty mesh; or an occluder whose bounds reach
    /// outside the bounds of the object's own mesh (naming both).
    pub fn set_occluder(&mut self, id: ObjectId, occluder: Option<MeshId>) -> Result<()> {
        self.scene_mut().set_occluder(id, occluder)?;
        self.edited = true;
        Ok(())
    }

    /// Moves object `id` to `world_from_local` from the next frame on (its
    /// cached silhouettes are recomputed: the cache compares transforms).
    ///
    /// # Errors
    /// [`Error::Scene`] for an unknown, removed or stale id, or a non-finite
    /// or projective matrix (naming the object).
    pub fn set_transform(&mut self, id: ObjectId, world_from_local: DMat4) -> Result<()> {
        self.scene_mut().stage_set_transform(id, world_from_local)?;
        Ok(())
    }

    /// Gives object `id` the mesh `mesh` from the next frame on (a LOD
    /// change): its id, flags, transform and occluder stay. The hierarchy is
    /// refit; only this object's cached silhouettes and casting lists are
    /// dropped.
    ///
    /// # Errors
    /// [`Error::Scene`] for an unknown, removed or stale object or mesh id, a
    /// transform that flattens the new mesh, or an occluder reaching outside
    /// the new mesh's bounds (naming the object).
    pub fn set_mesh(&mut self, id: ObjectId, mesh: MeshId) -> Result<()> {
        self.scene_mut().stage_set_mesh(id, mesh)?;
        self.invalidate_silhouettes(id);
        Ok(())
    }

    /// Removes object `id` from the next frame on; the id is stale afterwards
    /// (an error everywhere, never another object).
    ///
    /// # Errors
    /// [`Error::Scene`] for an unknown, removed or stale id.
    pub fn remove_object(&mut self, id: ObjectId) -> Result<()> {
        self.scene_mut().stage_remove_object(id)?;
        self.invalidate_silhouettes(id);
        Ok(())
    }

    /// Adds a light; every frame computes its PSC, volumes and mask.
    ///
    /// # Errors
    /// [`Error::Options`] naming `light` and its bad field.
    pub fn add_light(&mut self, light: Light) -> Result<LightId> {
        check_light(&light)?;
        let slot = match self
            .lights
            .iter()
            .position(|s| s.state.is_none() && s.generation < u32::MAX)
        {
            Some(i) => {
                self.lights[i].generation += 1;
                i
            }
            None => {
                self.lights.push(LightSlot::default());
                self.lights.len() - 1
            }
        };
        let id = LightId::new(slot as u32, self.lights[slot].generation);
        self.lights[slot].state = Some(LightState::new(light, id));
        self.output_current = false;
        Ok(id)
    }

    /// Changes light `id` (position, direction, cone, range). Its state —
    /// light views, culling history, silhouette cache — stays with the id.
    ///
    /// # Errors
    /// [`Error::Options`] for an unknown or stale id, or an invalid light.
    pub fn set_light(&mut self, id: LightId, light: Light) -> Result<()> {
        check_light(&light)?;
        self.light_state_mut(id)?.light = light;
        self.output_current = false;
        Ok(())
    }

    /// Removes light `id` and its state; the id is stale afterwards.
    ///
    /// # Errors
    /// [`Error::Options`] for an unknown or stale id.
    pub fn remove_light(&mut self, id: LightId) -> Result<()> {
        self.light_state_mut(id)?;
        // Kept until the next frame: the last output's buffers stay valid.
        self.retired.extend(self.lights[id.index()].state.take());
        self.output_current = false;
        Ok(())
    }

    /// Light `id`.
    ///
    /// # Errors
    /// [`Error::Options`] for an unknown or stale id.
    pub fn light(&self, id: LightId) -> Result<Light> {
        Ok(self.light_state(id)?.light)
    }

    /// The ids of the pipeline's lights, in slot order.
    pub fn light_ids(&self) -> impl Iterator<Item = LightId> + '_ {
        self.live_lights().map(|s| s.id)
    }

    pub(super) fn live_lights(&self) -> impl Iterator<Item = &LightState> + '_ {
        self.lights.iter().filter_map(|s| s.state.as_ref())
    }

    pub(super) fn light_state(&self, id: LightId) -> Result<&LightState> {
        match self.lights.get(id.index()) {
            Some(LightSlot {
                generation,
                state: Some(s),
            }) if *generation == id.generation() => Ok(s),
            _ => Err(unknown_light(id)),
        }
    }

    fn light_state_mut(&mut self, id: LightId) -> Result<&mut LightState> {
        match self.lights.get_mut(id.index()) {
            Some(LightSlot {
                generation,
                state: Some(s),
            }) if *generation == id.generation() => Ok(s),
            _ => Err(unknown_light(id)),
        }
    }

    /// Drops every light's cached silhouette of the object in `id`'s slot.
    fn invalidate_silhouettes(&mut self, id: ObjectId) {
        for s in self.lights.iter_mut().filter_map(|s| s.state.as_mut()) {
            s.scratch
                .volume
                .cache
                .invalidate(ObjectId::from_slot(id.slot()));
        }
    }

    /// Applies the staged scene edits (called at the start of a frame):
    /// commits them on the scene, then brings the mesh copies, the hierarchy
    /// (refit, or rebuilt with every view's CHC state remapped), the live
    /// object list, the counts and the reference's BVH up to date.
    pub(super) fn apply_edits(&mut self) {
        if !self.scene.has_staged_edits() && !self.edited {
            return;
        }
        let committed = self.scene_mut().commit_edits();
        let scene = &self.scene;
        self.meshes.sync(scene);
        if let Some(culling) = &mut self.culling {
            culling.sync_meshes(scene);
            if committed.rebuilt {
                let old = culling.rebuild(scene);
                for s in self.lights.iter_mut().filter_map(|s| s.state.as_mut()) {
                    s.culling.pass.remap(&old, culling.hierarchy());
                }
            } else if committed.refit {
                culling.refit(scene);
            }
        }
        self.edited = false;
        live_slots(scene, |f| f.visible, &mut self.all_visible);
        live_slots(scene, |f| f.casts, &mut self.all_casters);
        self.counts = scene.counts();
        self.bvh = None;
    }
}

fn check_light(light: &Light) -> Result<()> {
    light.validate().map_err(|e| Error::Options {
        field: "light".into(),
        message: e.to_string(),
    })
}

fn unknown_light(id: LightId) -> Error {
    Error::Options {
        field: "light".into(),
        message: format!("light {id} is unknown, removed or stale"),
    }
}
