//! `shadowcull._native.Pipeline`: one [`shadowcull::Pipeline`] owned by
//! Python. Ids cross as plain integers: meshes as [`MeshId`]'s, objects as
//! [`ObjectId`]'s (slot and generation, so a stale id is an error, never
//! another object), lights as [`LightId`]'s. A frame's outputs are copied
//! into new numpy arrays, which stay valid after later frames.

use crate::arrays::{self, matrix, matrix_out, vec1, vec2};
use crate::error::{bad, bad_json, scene_to_py, to_py};
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use shadowcull::jobs::config::LightSpec;
use shadowcull::raster::{VolumeBuffer, VolumeMethod};
use shadowcull::scene::load::Loaded;
use shadowcull::scene::{
    self, Camera, ClipDepth, LookAt, Mesh, MeshId, ObjectFlags, ObjectId, Scene,
};
use shadowcull::{FrameInput, HostDepth, LightId, LightOutput, PipelineOptions};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A mask and its ambiguity flags, both `(height, width)`.
type MaskPair<'py> = (
    Bound<'py, numpy::PyArray2<u8>>,
    Bound<'py, numpy::PyArray2<bool>>,
);

/// The shadow-volume culling pipeline (see the Python class `shadowcull.Pipeline`).
#[pyclass(module = "shadowcull._native")]
pub(crate) struct Pipeline {
    inner: shadowcull::Pipeline,
    /// Named cameras, paths and lights of the files loaded so far (no geometry).
    named: Loaded,
    /// Bounds of the objects loaded or framed so far (`AboveScene` lights).
    bounds: scene::Aabb,
}

/// Parses a JSON argument into one of the library's serde types.
fn from_json<'a, T: serde::Deserialize<'a>>(what: &str, text: &'a str) -> PyResult<T> {
    serde_json::from_str(text).map_err(|e| bad_json(what, e))
}

/// The options of keywords (JSON from the Python layer). A refused value is
/// named by its keyword: each keyword is tried alone (with the preset, which
/// the others start from) until one is refused.
fn options_from_json(text: &str) -> PyResult<PipelineOptions> {
    let e = match serde_json::from_str(text) {
        Ok(o) => return Ok(o),
        Err(e) => e,
    };
    if let Ok(serde_json::Value::Object(all)) = serde_json::from_str(text) {
        let preset = all.get("preset");
        for (key, value) in &all {
            let mut one = serde_json::Map::new();
            if let Some(p) = preset.filter(|_| key != "preset") {
                one.insert("preset".into(), p.clone());
            }
            one.insert(key.clone(), value.clone());
            if let Err(e) = serde_json::from_value::<PipelineOptions>(one.into()) {
                return Err(bad(format!(
                    "options: `{key}`: {}",
                    crate::error::in_python_words(&e)
                )));
            }
        }
    }
    Err(bad_json("options", e))
}

fn to_json<T: serde::Serialize>(value: &T) -> PyResult<String> {
    serde_json::to_string(value).map_err(|e| bad(e.to_string()))
}

fn flags(casts: bool, receives: bool, occludes: bool, visible: bool) -> ObjectFlags {
    ObjectFlags {
        casts,
        receives,
        occludes,
        visible,
    }
}

impl Pipeline {
    /// A light from its JSON spec (the RON job's `LightSpec`, externally tagged).
    fn light_of(&self, spec: &str) -> PyResult<scene::Light> {
        let spec: LightSpec = from_json("light", spec)?;
        let bounds = self.bounds.union(&self.inner.scene().bounds());
        spec.resolve(&self.named, &bounds, 0, Path::new("light"))
            .map_err(|e| match e {
                // The job's `file:lights[i]` prefix means nothing here.
                shadowcull::Error::Job { message, .. } => bad(format!("light: {message}")),
                e => to_py(e),
            })
    }

    /// Grows the known bounds by an object of `mesh` at `m`, so that an
    /// `above_scene` light added before the next frame sees it.
    fn grow_bounds(&mut self, mesh: MeshId, m: &glam::DMat4) {
        let Ok(mesh) = self.inner.scene().live_mesh(mesh) else {
            return;
        };
        let local = mesh
            .positions()
            .iter()
            .fold(scene::Aabb::EMPTY, |b, &p| b.union(&scene::Aabb::new(p, p)));
        if local.is_empty() {
            return;
        }
        let corners = (0..8).map(|i| {
            let pick =
                |bit: usize, lo: f32, hi: f32| f64::from(if i >> bit & 1 == 0 { lo } else { hi });
            m.transform_point3(glam::DVec3::new(
                pick(0, local.min.x, local.max.x),
                pick(1, local.min.y, local.max.y),
                pick(2, local.min.z, local.max.z),
            ))
            .as_vec3()
        });
        for c in corners {
            self.bounds = self.bounds.union(&scene::Aabb::new(c, c));
        }
    }

    /// The arrays of one light's output.
    fn light_dict<'py>(py: Python<'py>, l: &LightOutput<'_>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("id", l.id().to_bits())?;
        d.set_item("psc", vec1(py, ids(l.psc())))?;
        let v = l.volumes();
        d.set_item(
            "positions",
            vec2(py, v.positions.concat(), v.positions.len(), 4)?,
        )?;
        d.set_item("indices", vec1(py, v.indices.clone()))?;
        d.set_item("ranges", ranges(py, v)?)?;
        match l.mask() {
            Some(m) => d.set_item(
                "mask",
                vec2(
                    py,
                    m.pixels.iter().map(|&c| c as u8).collect(),
                    m.height as usize,
                    m.width as usize,
                )?,
            )?,
            None => d.set_item("mask", py.None())?,
        }
        d.set_item("views", l.views().len())?;
        d.set_item("stats", to_json(&l.stats().columns())?)?;
        d.set_item("volume_stats", to_json(l.volume_stats())?)?;
        Ok(d)
    }
}

fn ids(v: &[ObjectId]) -> Vec<u64> {
    v.iter().map(|id| id.to_bits()).collect()
}

/// The ranges of a volume buffer, one column per field.
fn ranges<'py>(py: Python<'py>, v: &VolumeBuffer) -> PyResult<Bound<'py, PyDict>> {
    let r = &v.ranges;
    let n = r.len();
    let col = |f: fn(&shadowcull::raster::VolumeRange) -> u32| r.iter().map(f).collect::<Vec<_>>();
    let d = PyDict::new(py);
    d.set_item("object", vec1(py, r.iter().map(|r| r.object).collect()))?;
    d.set_item("segment", vec1(py, col(|r| r.segment)))?;
    let method = |m: VolumeMethod| match m {
        VolumeMethod::ZPass => 0u8,
        VolumeMethod::ZFail => 1,
        VolumeMethod::ZpPlus => 2,
    };
    d.set_item(
        "method",
        vec1(py, r.iter().map(|r| method(r.method)).collect()),
    )?;
    d.set_item("first_vertex", vec1(py, col(|r| r.first_vertex)))?;
    d.set_item("vertex_count", vec1(py, col(|r| r.vertex_count)))?;
    d.set_item("first_index", vec1(py, col(|r| r.first_index)))?;
    d.set_item("index_count", vec1(py, col(|r| r.index_count)))?;
    let pairs = |f: fn(&shadowcull::raster::VolumeRange) -> [u32; 2]| {
        r.iter().flat_map(f).collect::<Vec<_>>()
    };
    d.set_item(
        "light_cap",
        vec2(py, pairs(|r| [r.light_cap.start, r.light_cap.end]), n, 2)?,
    )?;
    d.set_item(
        "dark_cap",
        vec2(py, pairs(|r| [r.dark_cap.start, r.dark_cap.end]), n, 2)?,
    )?;
    d.set_item(
        "scissor",
        vec2(py, r.iter().flat_map(|r| r.scissor).collect(), n, 4)?,
    )?;
    d.set_item(
        "band",
        vec2(py, r.iter().flat_map(|r| r.band).collect(), n, 4)?,
    )?;
    d.set_item(
        "depth_near",
        vec1(py, r.iter().map(|r| r.depth_near).collect()),
    )?;
    d.set_item(
        "depth_far",
        vec1(py, r.iter().map(|r| r.depth_far).collect()),
    )?;
    let m = Array3::from_shape_fn((n, 4, 4), |(i, row, c)| r[i].world_from_local.col(c)[row]);
    d.set_item("world_from_local", m.into_pyarray(py))?;
    // A clamped segment's planes; NaN where there is none.
    for (k, name) in ["near_plane", "far_plane"].into_iter().enumerate() {
        let planes = r.iter().flat_map(|r| r.planes[k].unwrap_or([f64::NAN; 4]));
        d.set_item(name, vec2(py, planes.collect(), n, 4)?)?;
    }
    Ok(d)
}

#[pymethods]
impl Pipeline {
    /// An empty pipeline with `options` (JSON of the RON job's `pipeline` fields).
    #[new]
    fn new(options: &str) -> PyResult<Self> {
        let options = options_from_json(options)?;
        let scene = Scene::new(scene::SceneGraph::new()).map_err(scene_to_py)?;
        Ok(Pipeline {
            inner: shadowcull::Pipeline::new(scene, options).map_err(to_py)?,
            named: Loaded::default(),
            bounds: scene::Aabb::EMPTY,
        })
    }

    /// The options as JSON.
    fn options(&self) -> PyResult<String> {
        to_json(self.inner.options())
    }

    /// Replaces the options (JSON); keeps the scene, lights and histories.
    fn set_options(&mut self, options: &str) -> PyResult<()> {
        let options = options_from_json(options)?;
        self.inner.set_options(options).map_err(to_py)
    }

    /// Adds a mesh from `(n, 3)` positions and `(m, 3)` or `(3m,)` indices.
    #[pyo3(signature = (positions, indices, name="mesh"))]
    fn add_mesh(
        &mut self,
        positions: &Bound<'_, PyAny>,
        indices: &Bound<'_, PyAny>,
        name: &str,
    ) -> PyResult<u64> {
        let p = arrays::positions(positions)?;
        let t = arrays::triangles(indices)?;
        let mesh = Mesh::new(name, &p, &t).map_err(scene_to_py)?;
        Ok(self.inner.add_mesh(mesh).to_bits())
    }

    /// New positions for a mesh of the same topology.
    fn update_mesh_positions(
        &mut self,
        mesh: u64,
        positions: &Bound<'_, PyAny>,
        indices: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        let p = arrays::positions(positions)?;
        let t = arrays::triangles(indices)?;
        self.inner
            .update_mesh_positions(MeshId::from_bits(mesh), &p, &t)
            .map_err(to_py)
    }

    fn remove_mesh(&mut self, mesh: u64) -> PyResult<()> {
        self.inner
            .remove_mesh(MeshId::from_bits(mesh))
            .map_err(to_py)
    }

    /// Adds an object drawing `mesh` with the 4×4 `transform` (numpy layout).
    fn add_object(
        &mut self,
        mesh: u64,
        transform: PyReadonlyArray2<'_, f64>,
        casts: bool,
        receives: bool,
        occludes: bool,
        visible: bool,
    ) -> PyResult<u64> {
        let m = matrix("transform", transform)?;
        let f = flags(casts, receives, occludes, visible);
        let id = self
            .inner
            .add_object(MeshId::from_bits(mesh), m, f)
            .map_err(to_py)?;
        self.grow_bounds(MeshId::from_bits(mesh), &m);
        Ok(id.to_bits())
    }

    fn set_transform(&mut self, object: u64, transform: PyReadonlyArray2<'_, f64>) -> PyResult<()> {
        let m = matrix("transform", transform)?;
        self.inner
            .set_transform(ObjectId::from_bits(object), m)
            .map_err(to_py)
    }

    fn set_flags(
        &mut self,
        object: u64,
        casts: bool,
        receives: bool,
        occludes: bool,
        visible: bool,
    ) -> PyResult<()> {
        let f = flags(casts, receives, occludes, visible);
        self.inner
            .set_flags(ObjectId::from_bits(object), f)
            .map_err(to_py)
    }

    #[pyo3(signature = (object, mesh=None))]
    fn set_occluder(&mut self, object: u64, mesh: Option<u64>) -> PyResult<()> {
        self.inner
            .set_occluder(ObjectId::from_bits(object), mesh.map(MeshId::from_bits))
            .map_err(to_py)
    }

    fn set_mesh(&mut self, object: u64, mesh: u64) -> PyResult<()> {
        self.inner
            .set_mesh(ObjectId::from_bits(object), MeshId::from_bits(mesh))
            .map_err(to_py)
    }

    fn remove_object(&mut self, object: u64) -> PyResult<()> {
        self.inner
            .remove_object(ObjectId::from_bits(object))
            .map_err(to_py)
    }

    /// Adds a light from its JSON spec (the RON job's light variants).
    fn add_light(&mut self, spec: &str) -> PyResult<u64> {
        let light = self.light_of(spec)?;
        Ok(self.inner.add_light(light).map_err(to_py)?.to_bits())
    }

    fn set_light(&mut self, light: u64, spec: &str) -> PyResult<()> {
        let l = self.light_of(spec)?;
        self.inner
            .set_light(LightId::from_bits(light), l)
            .map_err(to_py)
    }

    fn reserve(&mut self, objects: usize, lights: usize) -> PyResult<()> {
        self.inner.reserve(objects, lights).map_err(to_py)
    }

    fn remove_light(&mut self, light: u64) -> PyResult<()> {
        self.inner
            .remove_light(LightId::from_bits(light))
            .map_err(to_py)
    }

    /// A light as JSON (the library's `Light`).
    fn light(&self, light: u64) -> PyResult<String> {
        to_json(&self.inner.light(LightId::from_bits(light)).map_err(to_py)?)
    }

    fn light_ids(&self) -> Vec<u64> {
        self.inner.light_ids().map(|l| l.to_bits()).collect()
    }

    /// Adds every object of a glTF, OBJ or box-city file; returns their ids
    /// and JSON of the file's named cameras, paths, lights and load warnings.
    fn load(&mut self, py: Python<'_>, path: PathBuf) -> PyResult<(Vec<u64>, String)> {
        let (loaded, scene) = py
            .detach(|| {
                let mut loaded = scene::load::load_path(&path)?;
                let graph = std::mem::take(&mut loaded.graph);
                Ok(Scene::new(graph).map(|s| (loaded, s)))
            })
            .and_then(|r| r)
            .map_err(scene_to_py)?;
        self.add_loaded(loaded, scene, &path.display().to_string())
    }

    /// Adds the procedural city of `params` (JSON `CityParams`: the RON
    /// job's `City(...)` fields, each defaulted) with its cameras, paths and
    /// lights, as [`Pipeline::load`] adds a file's.
    fn add_city(&mut self, py: Python<'_>, params: &str) -> PyResult<(Vec<u64>, String)> {
        let params: scene::procedural::city::CityParams = from_json("city", params)?;
        let (loaded, scene) = py
            .detach(|| {
                let mut loaded = scene::procedural::city::city(&params)?;
                let graph = std::mem::take(&mut loaded.graph);
                Ok(Scene::new(graph).map(|s| (loaded, s)))
            })
            .and_then(|r| r)
            .map_err(scene_to_py)?;
        self.add_loaded(loaded, scene, "the procedural city")
    }

    /// The pose (JSON `LookAt`) of a loaded camera path at `frame`, or None
    /// past its end.
    fn path_camera(&self, name: &str, frame: u32) -> PyResult<Option<String>> {
        let Some((_, path)) = self.named.paths.iter().find(|(n, _)| n == name) else {
            let known: Vec<_> = self.named.paths.iter().map(|(n, _)| n.as_str()).collect();
            return Err(bad(format!(
                "path {name:?}: no loaded file names it (known: {known:?})"
            )));
        };
        path.at(frame).map(|p| to_json(&p)).transpose()
    }

    fn set_frame_number(&mut self, frame: u32) {
        self.inner.set_frame_number(frame);
    }

    fn reset_history(&mut self) {
        self.inner.reset_history();
    }

    /// Runs one frame (the GIL released) and returns its outputs as a dict
    /// of arrays: `psr`, `stats` (JSON), `lights` (one dict per light).
    #[pyo3(signature = (width, height, camera=None, view=None, projection=None, clip_depth="negative_one_to_one", host_depth=None, near=None, anamorphic=false))]
    // Each parameter is a Python keyword argument of `frame`: a struct would change the Python API.
    #[allow(clippy::too_many_arguments)]
    fn frame<'py>(
        &mut self,
        py: Python<'py>,
        width: u32,
        height: u32,
        camera: Option<&str>,
        view: Option<PyReadonlyArray2<'_, f64>>,
        projection: Option<PyReadonlyArray2<'_, f64>>,
        clip_depth: &str,
        host_depth: Option<PyReadonlyArray2<'_, f32>>,
        near: Option<f64>,
        anamorphic: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let depth = match clip_depth {
            "negative_one_to_one" => ClipDepth::NegativeOneToOne,
            "zero_to_one" => ClipDepth::ZeroToOne,
            other => {
                return Err(bad(format!(
                    "clip_depth: {other:?} is neither \"negative_one_to_one\" (OpenGL) nor \"zero_to_one\" (Direct3D, Vulkan, Metal)"
                )))
            }
        };
        let camera = match (camera, view, projection) {
            (Some(c), None, None) => {
                let pose: LookAt = from_json("camera", c)?;
                // An empty viewport is the frame's error (naming `viewport`), not the camera's.
                let aspect = if width > 0 && height > 0 {
                    f64::from(width) / f64::from(height)
                } else {
                    1.0
                };
                pose.camera(aspect).map_err(scene_to_py)?
            }
            (None, Some(v), Some(p)) => {
                let (v, p) = (matrix("view", v)?, matrix("projection", p)?);
                match near {
                    Some(n) => Camera::from_view_projection_near(v, p, depth, n),
                    None => Camera::from_view_projection(v, p, depth),
                }
                .map_err(scene_to_py)?
            }
            _ => {
                return Err(bad(
                    "frame: give either camera= or both view= and projection=",
                ))
            }
        };
        let mut input = FrameInput::new(width, height, camera);
        input.anamorphic = anamorphic;
        if let Some(d) = host_depth {
            let a = d.as_array();
            let (h, w) = a.dim();
            input.host_depth = Some(HostDepth {
                camera,
                width: w as u32,
                height: h as u32,
                depth: a.iter().copied().collect(),
            });
        }
        let inner = &mut self.inner;
        py.detach(|| inner.frame(&input).map(|_| ()))
            .map_err(to_py)?;
        let out = self
            .inner
            .last_output()
            .ok_or_else(|| bad("frame: no output"))?;
        self.bounds = self.bounds.union(&self.inner.scene().bounds());
        let d = PyDict::new(py);
        d.set_item("psr", vec1(py, ids(out.psr())))?;
        d.set_item("stats", to_json(out.stats())?)?;
        d.set_item("camera_position", camera.position.to_array().to_vec())?;
        let lights = PyList::empty(py);
        for l in out.lights() {
            lights.append(Self::light_dict(py, &l)?)?;
        }
        d.set_item("lights", lights)?;
        Ok(d)
    }

    /// The exact ray-cast mask of `light` for the last frame (the GIL
    /// released): `(mask, ambiguous)`, both `(height, width)`.
    fn reference_mask<'py>(&mut self, py: Python<'py>, light: u64) -> PyResult<MaskPair<'py>> {
        let inner = &mut self.inner;
        let r = py
            .detach(|| inner.reference_mask(LightId::from_bits(light)))
            .map_err(to_py)?;
        let (w, h) = (r.mask.width as usize, r.mask.height as usize);
        Ok((
            vec2(py, r.mask.pixels.iter().map(|&c| c as u8).collect(), h, w)?,
            vec2(py, r.ambiguous, h, w)?,
        ))
    }

    /// World bounds `(min, max)` of the scene: its objects as of the last
    /// frame, and every file loaded since.
    fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let b = self.bounds.union(&self.inner.scene().bounds());
        (b.min.to_array(), b.max.to_array())
    }

    /// World matrix of an object (numpy layout), for checks and tools.
    /// An object's flags: (casts, receives, occludes, visible).
    fn flags(&self, object: u64) -> PyResult<(bool, bool, bool, bool)> {
        let scene = self.inner.scene();
        let slot = scene
            .live_slot(ObjectId::from_bits(object))
            .map_err(scene_to_py)?;
        let f = scene.objects()[slot as usize].flags;
        Ok((f.casts, f.receives, f.occludes, f.visible))
    }

    /// Live objects.
    fn object_count(&self) -> usize {
        self.inner.scene().counts().objects
    }

    fn transform<'py>(
        &self,
        py: Python<'py>,
        object: u64,
    ) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let scene = self.inner.scene();
        let slot = scene
            .live_slot(ObjectId::from_bits(object))
            .map_err(scene_to_py)?;
        Ok(matrix_out(
            py,
            &scene.objects()[slot as usize].world_from_local,
        ))
    }
}

impl Pipeline {
    /// Adds every object of `scene` (what a loader gave, named `what` in
    /// the metadata) and `loaded`'s cameras, paths and lights: the new
    /// objects' ids and the JSON metadata, with each object's node name.
    fn add_loaded(
        &mut self,
        loaded: Loaded,
        scene: Scene,
        what: &str,
    ) -> PyResult<(Vec<u64>, String)> {
        let mut names = Vec::with_capacity(scene.objects().len());
        let mut meshes: HashMap<MeshId, MeshId> = HashMap::new();
        let mut objects = Vec::with_capacity(scene.objects().len());
        for o in scene.objects().iter().filter(|o| o.alive) {
            let mesh = match meshes.get(&o.mesh) {
                Some(&m) => m,
                None => {
                    let m = self
                        .inner
                        .add_mesh(scene.graph().meshes()[o.mesh.index()].clone());
                    meshes.insert(o.mesh, m);
                    m
                }
            };
            let id = self
                .inner
                .add_object(mesh, o.world_from_local, o.flags)
                .map_err(to_py)?;
            objects.push(id.to_bits());
            names.push(scene.graph().nodes()[o.node.0 as usize].name.clone());
        }
        self.bounds = self.bounds.union(&scene.bounds());
        let meta = serde_json::json!({
            "cameras": loaded.cameras.iter().cloned().collect::<HashMap<_, _>>(),
            "paths": loaded.paths.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>(),
            "lights": loaded.lights.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>(),
            "warnings": scene.warnings(),
            "path": what,
            "names": names,
        });
        self.named.merge(loaded);
        Ok((objects, meta.to_string()))
    }
}
