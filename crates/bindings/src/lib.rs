//! The C ABI of shadowcull: `libshadowcull_c.{so,a}` and
//! `include/shadowcull.h` (generated from this crate by cbindgen; the header
//! is the manual). It wraps `shadowcull::Pipeline` and adds no logic:
//!
//! - handles (`sc_pipeline`, `sc_mesh`, `sc_object`, `sc_light`) are
//!   generation-checked ids, 0 the null handle; a stale or destroyed handle
//!   is `SC_INVALID_ARGUMENT`, double destroy included;
//! - every function returns an `sc_status`; `sc_last_error()` gives the
//!   thread's last message; no panic crosses the boundary;
//! - input structs start with `struct_size` (older and newer hosts work);
//! - a frame's output stays valid until the next frame call or destroy, and
//!   the host frees nothing.
//!
//! Threads: one pipeline is used by one thread at a time (a second caller
//! waits for the first); different pipelines may run on different threads.
//! The pipeline runs its work on its own pool (`threads` > 0, joined on
//! destroy) or on rayon's global pool (`threads` = 0).

// The entry points are called from C: a non-NULL pointer argument is valid
// by the documented contract of the header, as in every C API (NULL is
// checked and refused). Marking them `unsafe` would change nothing for C.
#![allow(clippy::not_unsafe_ptr_arg_deref)]

mod backend;
mod error;
mod frame;
mod handles;
mod id_handles;
mod structs;

pub use backend::*;
pub use error::{sc_last_error, sc_status};
pub use frame::{
    sc_frame_output, sc_frame_stats, sc_light, sc_light_output, sc_light_stats, sc_object,
    sc_volume_range, SC_ZFAIL, SC_ZPASS, SC_ZPPLUS,
};
pub use handles::sc_pipeline;
pub use structs::*;

use error::{guard, Failure, Result};
use glam::DMat4;
use id_handles::{light_handle, light_of, mesh_handle, mesh_of, object_handle, object_of};
use shadowcull::scene::{
    Camera, Indices, Mesh, PositionFormat, Scene, SceneGraph, StridedPositions,
};
use shadowcull::{FrameInput, Pipeline};
use std::ffi::{c_char, CStr};

/// A mesh: 0 is the null handle.
#[allow(non_camel_case_types)]
pub type sc_mesh = u64;

/// The ABI version: bumped when a struct or function changes incompatibly.
pub const SC_ABI_VERSION: u32 = 1;

/// The ABI version this library was built with (`SC_ABI_VERSION`).
#[no_mangle]
pub extern "C" fn sc_version() -> u32 {
    SC_ABI_VERSION
}

/// Writes `value` to `out`, which must not be NULL.
fn put<T>(out: *mut T, name: &str, value: T) -> Result<()> {
    if out.is_null() {
        return Err(Failure::invalid(format!("{name}: NULL")));
    }
    // SAFETY: non-NULL, and by the API's contract a writable `T`.
    unsafe { out.write(value) };
    Ok(())
}

/// A column-major 4×4 from 16 doubles at `m`.
fn matrix(m: *const f64, name: &str) -> Result<DMat4> {
    if m.is_null() {
        return Err(Failure::invalid(format!("{name}: NULL")));
    }
    // SAFETY: non-NULL, and by the API's contract 16 readable doubles.
    let a = unsafe { std::slice::from_raw_parts(m, 16) };
    finite(DMat4::from_cols_slice(a), name)
}

/// `m`, or an error naming it when an element is not finite.
fn finite(m: DMat4, name: &str) -> Result<DMat4> {
    if !m.is_finite() {
        return Err(Failure::invalid(format!("{name}: a non-finite element")));
    }
    Ok(m)
}

/// A column-major 4×4 from 16 floats at `m`.
fn matrix_f32(m: *const f32, name: &str) -> Result<DMat4> {
    if m.is_null() {
        return Err(Failure::invalid(format!("{name}: NULL")));
    }
    // SAFETY: non-NULL, and by the API's contract 16 readable floats.
    let a = unsafe { std::slice::from_raw_parts(m, 16) };
    finite(glam::Mat4::from_cols_slice(a).as_dmat4(), name)
}

/// The mesh a description points to ([`Mesh::from_strided`] over the
/// host's buffers, read in place).
fn mesh_of_desc(d: &sc_mesh_desc) -> Result<Mesh> {
    let (positions, indices) = strided_of_desc(d)?;
    Ok(Mesh::from_strided("mesh", positions, indices)?)
}

/// The host's vertex and index buffers a mesh description points at.
fn strided_of_desc(d: &sc_mesh_desc) -> Result<(StridedPositions<'_>, Indices<'_>)> {
    let format = match d.position_type {
        SC_F32 => PositionFormat::F32x3,
        SC_F64 => PositionFormat::F64x3,
        t => {
            return Err(Failure::invalid(format!(
                "mesh.position_type: {t} is neither SC_F32 nor SC_F64"
            )))
        }
    };
    let (n, stride) = (d.vertex_count as usize, d.position_stride as usize);
    if stride < format.size() {
        return Err(Failure::invalid(format!(
            "mesh.position_stride: {stride} bytes is less than one position ({} bytes)",
            format.size()
        )));
    }
    if n > 0 && d.positions.is_null() {
        return Err(Failure::invalid("mesh.positions: NULL"));
    }
    // The bytes the positions span.
    let span = match n {
        0 => 0,
        n => (n - 1) * stride + format.size(),
    };
    let bytes: &[u8] = match span {
        0 => &[],
        // SAFETY: non-NULL, and by the API's contract `vertex_count`
        // positions `position_stride` bytes apart are readable there.
        _ => unsafe { std::slice::from_raw_parts(d.positions as *const u8, span) },
    };
    let count = d.index_count as usize;
    if count > 0 && d.indices.is_null() {
        return Err(Failure::invalid("mesh.indices: NULL"));
    }
    let indices = match (d.index_type, count) {
        (SC_U16 | SC_U32, 0) => Indices::U32(&[]),
        // SAFETY: non-NULL; the host declared `index_count` indices of this type.
        (SC_U16, _) => {
            Indices::U16(unsafe { std::slice::from_raw_parts(d.indices as *const u16, count) })
        }
        // SAFETY: as above.
        (SC_U32, _) => {
            Indices::U32(unsafe { std::slice::from_raw_parts(d.indices as *const u32, count) })
        }
        (t, _) => {
            return Err(Failure::invalid(format!(
                "mesh.index_type: {t} is neither SC_U16 nor SC_U32"
            )))
        }
    };
    let positions = StridedPositions {
        bytes,
        offset: 0,
        stride,
        count: n,
        format,
    };
    Ok((positions, indices))
}

/// Fills `options` with the defaults (its `struct_size` included): CHC++
/// culling, conservative coverage, no CPU stencil, rayon's global pool.
#[no_mangle]
pub extern "C" fn sc_pipeline_options_default(options: *mut sc_pipeline_options) -> sc_status {
    guard("sc_pipeline_options_default", || {
        put(
            options,
            "options",
            <sc_pipeline_options as Versioned>::default_value(),
        )
    })
}

/// Fills `options` with the options a renderer that draws the shadow volumes
/// on its own GPU starts from (`PipelineOptions::gpu_host`, `docs/host.md`):
/// `culling: auto`, no CPU stencil, conservative coverage, scissor
/// rectangles, occluder proxies (`occluders` `SC_OCCLUDERS_PRESET`), no
/// clamping, `preset` `SC_PRESET_GPU_HOST`.
#[no_mangle]
pub extern "C" fn sc_pipeline_options_gpu_host(options: *mut sc_pipeline_options) -> sc_status {
    guard("sc_pipeline_options_gpu_host", || {
        put(options, "options", sc_pipeline_options::gpu_host())
    })
}

fn create(options: *const sc_pipeline_options, scene: Scene, out: *mut sc_pipeline) -> Result<()> {
    if out.is_null() {
        return Err(Failure::invalid("out: NULL"));
    }
    let o = read(options, "options")?.to_rust()?;
    let pipeline = Pipeline::new(scene, o)?;
    let h = handles::insert(handles::Entry {
        pipeline,
        outputs: Default::default(),
        host_depth: None,
    });
    put(out, "out", h)
}

/// Creates an empty pipeline (add meshes, objects and lights, then call
/// `sc_pipeline_frame`). `options` NULL is not allowed: fill one with
/// `sc_pipeline_options_default`.
#[no_mangle]
pub extern "C" fn sc_pipeline_create(
    options: *const sc_pipeline_options,
    out: *mut sc_pipeline,
) -> sc_status {
    guard("sc_pipeline_create", || {
        create(options, Scene::new(SceneGraph::new())?, out)
    })
}

/// Creates a pipeline holding the scene of a glTF (`.gltf`, `.glb`) or OBJ
/// (`.obj`) file; `SC_IO` when it cannot be read or parsed.
#[no_mangle]
pub extern "C" fn sc_pipeline_create_from_file(
    options: *const sc_pipeline_options,
    path: *const c_char,
    out: *mut sc_pipeline,
) -> sc_status {
    guard("sc_pipeline_create_from_file", || {
        if out.is_null() {
            return Err(Failure::invalid("out: NULL"));
        }
        if path.is_null() {
            return Err(Failure::invalid("path: NULL"));
        }
        // SAFETY: non-NULL, and by the API's contract a NUL-terminated string.
        let path = unsafe { CStr::from_ptr(path) }
            .to_str()
            .map_err(|_| Failure::invalid("path: not UTF-8"))?;
        let path = std::path::Path::new(path);
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let graph = match ext.as_deref() {
            Some("gltf" | "glb") => shadowcull::scene::load::gltf::load_gltf(path)?,
            Some("obj") => shadowcull::scene::load::obj::load_obj(path)?,
            _ => {
                return Err(Failure::invalid(format!(
                    "path {}: not a .gltf, .glb or .obj file",
                    path.display()
                )))
            }
        };
        create(options, Scene::new(graph)?, out)
    })
}

/// Destroys a pipeline and everything it holds (its meshes, objects, lights
/// and outputs); joins its own pool. The null handle is a no-op; a destroyed
/// or stale one is `SC_INVALID_ARGUMENT`.
#[no_mangle]
pub extern "C" fn sc_pipeline_destroy(pipeline: sc_pipeline) -> sc_status {
    guard("sc_pipeline_destroy", || handles::remove(pipeline))
}

/// Adds a mesh (one copy into the library; vertices are welded). Objects
/// instance it with `sc_object_create`.
#[no_mangle]
pub extern "C" fn sc_mesh_create(
    pipeline: sc_pipeline,
    desc: *const sc_mesh_desc,
    out: *mut sc_mesh,
) -> sc_status {
    guard("sc_mesh_create", || {
        if out.is_null() {
            return Err(Failure::invalid("out: NULL"));
        }
        let mesh = mesh_of_desc(&read(desc, "mesh")?)?;
        let id = handles::with(pipeline, |e| Ok(e.pipeline.add_mesh(mesh)))?;
        put(out, "out", mesh_handle(id))
    })
}

/// Replaces a mesh's vertex positions (a deforming mesh): `desc` holds the
/// same triangles as before; a change of topology is `SC_INVALID_ARGUMENT`.
#[no_mangle]
pub extern "C" fn sc_mesh_update_positions(
    pipeline: sc_pipeline,
    mesh: sc_mesh,
    desc: *const sc_mesh_desc,
) -> sc_status {
    guard("sc_mesh_update_positions", || {
        let id = mesh_of(mesh, "mesh")?;
        let desc = read(desc, "mesh")?;
        let (positions, indices) = strided_of_desc(&desc)?;
        handles::with(pipeline, |e| {
            Ok(e.pipeline.update_mesh_strided(id, positions, indices)?)
        })
    })
}

/// Removes a mesh; `SC_INVALID_ARGUMENT` while an object instances it. The
/// null handle is a no-op.
#[no_mangle]
pub extern "C" fn sc_mesh_destroy(pipeline: sc_pipeline, mesh: sc_mesh) -> sc_status {
    guard("sc_mesh_destroy", || {
        if mesh == 0 {
            return handles::get(pipeline).map(|_| ());
        }
        let id = mesh_of(mesh, "mesh")?;
        handles::with(pipeline, |e| Ok(e.pipeline.remove_mesh(id)?))
    })
}

/// Adds an object instancing `mesh` with the column-major world matrix
/// `world_from_local` (16 doubles) and `SC_*` flags (`SC_FLAGS_ALL` for an
/// ordinary object).
#[no_mangle]
pub extern "C" fn sc_object_create(
    pipeline: sc_pipeline,
    mesh: sc_mesh,
    world_from_local: *const f64,
    flags: u32,
    out: *mut sc_object,
) -> sc_status {
    guard("sc_object_create", || {
        object_create(
            pipeline,
            mesh,
            || matrix(world_from_local, "world_from_local"),
            flags,
            out,
        )
    })
}

/// The body of `sc_object_create` and `sc_object_create_f32`.
fn object_create(
    pipeline: sc_pipeline,
    mesh: sc_mesh,
    world_from_local: impl FnOnce() -> Result<DMat4>,
    flags: u32,
    out: *mut sc_object,
) -> Result<()> {
    if out.is_null() {
        return Err(Failure::invalid("out: NULL"));
    }
    let id = mesh_of(mesh, "mesh")?;
    let m = world_from_local()?;
    let f = structs::flags(flags)?;
    let o = handles::with(pipeline, |e| Ok(e.pipeline.add_object(id, m, f)?))?;
    put(out, "out", object_handle(o))
}

/// `sc_object_create` with a matrix of 16 floats.
#[no_mangle]
pub extern "C" fn sc_object_create_f32(
    pipeline: sc_pipeline,
    mesh: sc_mesh,
    world_from_local: *const f32,
    flags: u32,
    out: *mut sc_object,
) -> sc_status {
    guard("sc_object_create_f32", || {
        let m = || matrix_f32(world_from_local, "world_from_local");
        object_create(pipeline, mesh, m, flags, out)
    })
}

/// Moves an object: its new column-major world matrix (16 doubles).
#[no_mangle]
pub extern "C" fn sc_object_set_transform(
    pipeline: sc_pipeline,
    object: sc_object,
    world_from_local: *const f64,
) -> sc_status {
    guard("sc_object_set_transform", || {
        let id = object_of(object, "object")?;
        let m = matrix(world_from_local, "world_from_local")?;
        handles::with(pipeline, |e| Ok(e.pipeline.set_transform(id, m)?))
    })
}

/// `sc_object_set_transform` with a matrix of 16 floats.
#[no_mangle]
pub extern "C" fn sc_object_set_transform_f32(
    pipeline: sc_pipeline,
    object: sc_object,
    world_from_local: *const f32,
) -> sc_status {
    guard("sc_object_set_transform_f32", || {
        let id = object_of(object, "object")?;
        let m = matrix_f32(world_from_local, "world_from_local")?;
        handles::with(pipeline, |e| Ok(e.pipeline.set_transform(id, m)?))
    })
}

/// Sets an object's `SC_*` flags.
#[no_mangle]
pub extern "C" fn sc_object_set_flags(
    pipeline: sc_pipeline,
    object: sc_object,
    flags: u32,
) -> sc_status {
    guard("sc_object_set_flags", || {
        let id = object_of(object, "object")?;
        let f = structs::flags(flags)?;
        handles::with(pipeline, |e| Ok(e.pipeline.set_flags(id, f)?))
    })
}

/// Gives an object the host's own occluder: mesh `occluder`, placed by the
/// object's transform, is drawn in place of its mesh by the light views and
/// a coarse eye pass under `SC_OCCLUDERS_PROXY`. It must hide nothing the
/// object does not (lie inside its solid, or on its surface); its bounds
/// must lie within the object's mesh's. The null handle (0) goes back to the
/// object's own mesh or automatic proxy.
#[no_mangle]
pub extern "C" fn sc_object_set_occluder(
    pipeline: sc_pipeline,
    object: sc_object,
    occluder: sc_mesh,
) -> sc_status {
    guard("sc_object_set_occluder", || {
        let id = object_of(object, "object")?;
        let mesh = match occluder {
            0 => None,
            h => Some(mesh_of(h, "occluder")?),
        };
        handles::with(pipeline, |e| Ok(e.pipeline.set_occluder(id, mesh)?))
    })
}

/// Gives an object another mesh (a level-of-detail change); its handle,
/// flags, transform and occluder stay, and only its cached silhouettes are
/// recomputed.
#[no_mangle]
pub extern "C" fn sc_object_set_mesh(
    pipeline: sc_pipeline,
    object: sc_object,
    mesh: sc_mesh,
) -> sc_status {
    guard("sc_object_set_mesh", || {
        let id = object_of(object, "object")?;
        let mesh = mesh_of(mesh, "mesh")?;
        handles::with(pipeline, |e| Ok(e.pipeline.set_mesh(id, mesh)?))
    })
}

/// Removes an object. The null handle is a no-op; a removed or stale one
/// (double destroy) is `SC_INVALID_ARGUMENT`.
#[no_mangle]
pub extern "C" fn sc_object_destroy(pipeline: sc_pipeline, object: sc_object) -> sc_status {
    guard("sc_object_destroy", || {
        if object == 0 {
            return handles::get(pipeline).map(|_| ());
        }
        let id = object_of(object, "object")?;
        handles::with(pipeline, |e| Ok(e.pipeline.remove_object(id)?))
    })
}

/// Adds a light; each frame's output has one entry per light.
#[no_mangle]
pub extern "C" fn sc_light_create(
    pipeline: sc_pipeline,
    desc: *const sc_light_desc,
    out: *mut sc_light,
) -> sc_status {
    guard("sc_light_create", || {
        if out.is_null() {
            return Err(Failure::invalid("out: NULL"));
        }
        let l = read(desc, "light")?.to_rust()?;
        let id = handles::with(pipeline, |e| Ok(e.pipeline.add_light(l)?))?;
        put(out, "out", light_handle(id))
    })
}

/// Changes a light (its state, such as silhouettes, follows it).
#[no_mangle]
pub extern "C" fn sc_light_set(
    pipeline: sc_pipeline,
    light: sc_light,
    desc: *const sc_light_desc,
) -> sc_status {
    guard("sc_light_set", || {
        let id = light_of(light, "light")?;
        let l = read(desc, "light")?.to_rust()?;
        handles::with(pipeline, |e| Ok(e.pipeline.set_light(id, l)?))
    })
}

/// Makes room for `objects` objects and `lights` lights in all, so that
/// creating up to that many allocates nothing, and objects created into the
/// room refit the culling hierarchy instead of rebuilding it. This call
/// allocates, and the next frame rebuilds the hierarchy once.
#[no_mangle]
pub extern "C" fn sc_pipeline_reserve(
    pipeline: sc_pipeline,
    objects: usize,
    lights: usize,
) -> sc_status {
    guard("sc_pipeline_reserve", || {
        handles::with(pipeline, |e| Ok(e.pipeline.reserve(objects, lights)?))
    })
}

/// Removes a light. The null handle is a no-op.
#[no_mangle]
pub extern "C" fn sc_light_destroy(pipeline: sc_pipeline, light: sc_light) -> sc_status {
    guard("sc_light_destroy", || {
        if light == 0 {
            return handles::get(pipeline).map(|_| ());
        }
        let id = light_of(light, "light")?;
        handles::with(pipeline, |e| Ok(e.pipeline.remove_light(id)?))
    })
}

/// Numbers the next frame `frame` (from 0; a new pipeline's first frame is
/// 0); the frames after it count on. Coherent culling reads these numbers,
/// not how many frames ran, so a batch job split into blocks numbers each
/// block's frames as in the whole job.
#[no_mangle]
pub extern "C" fn sc_pipeline_set_frame_number(pipeline: sc_pipeline, frame: u32) -> sc_status {
    guard("sc_pipeline_set_frame_number", || {
        handles::with(pipeline, |e| {
            e.pipeline.set_frame_number(frame);
            Ok(())
        })
    })
}

/// Forgets all coherent state (culling histories, silhouette caches): the
/// next frame runs as a new pipeline's would. For camera cuts and keyframes.
#[no_mangle]
pub extern "C" fn sc_pipeline_reset_history(pipeline: sc_pipeline) -> sc_status {
    guard("sc_pipeline_reset_history", || {
        handles::with(pipeline, |e| {
            e.pipeline.reset_history();
            Ok(())
        })
    })
}

/// Runs one frame: the edits since the last frame, the eye pass (PSR), per
/// light the light pass (PSC), the shadow volumes and, with a CPU stencil,
/// the mask. `out` (its `struct_size` set) receives pointers that stay valid
/// until the next frame call or destroy of this pipeline, across edits
/// (a destroyed light's volumes are kept until then).
#[no_mangle]
pub extern "C" fn sc_pipeline_frame(
    pipeline: sc_pipeline,
    input: *const sc_frame_input,
    out: *mut sc_frame_output,
) -> sc_status {
    guard("sc_pipeline_frame", || {
        let i = read(input, "input")?;
        if out.is_null() {
            return Err(Failure::invalid("out: NULL"));
        }
        // SAFETY: non-NULL; by the API's contract a writable output whose
        // first field is its `u32` size.
        let size = unsafe { (out as *const u32).read_unaligned() } as usize;
        if size < std::mem::size_of::<sc_frame_output>() {
            return Err(Failure::invalid(format!(
                "out.struct_size: {size}, want sizeof(sc_frame_output) = {}",
                std::mem::size_of::<sc_frame_output>()
            )));
        }
        let view = matrix(i.view.as_ptr(), "input.view")?;
        let projection = matrix(i.projection.as_ptr(), "input.projection")?;
        let camera = match i.near {
            0.0 => Camera::from_view_projection(view, projection, i.depth()?)?,
            n => Camera::from_view_projection_near(view, projection, i.depth()?, n)?,
        };
        let anamorphic = match i.anamorphic {
            0 => false,
            1 => true,
            v => {
                return Err(Failure::invalid(format!(
                    "input.anamorphic: {v}, not 0 or 1"
                )))
            }
        };
        handles::with(pipeline, |e| {
            let mut input = FrameInput::new(i.width, i.height, camera);
            input.anamorphic = anamorphic;
            if !i.host_depth.is_null() {
                let (w, h) = (i.host_depth_width, i.host_depth_height);
                let n = w as usize * h as usize;
                if n == 0 {
                    return Err(Failure::invalid(format!(
                        "input.host_depth: a {w}×{h} buffer"
                    )));
                }
                // SAFETY: non-NULL, and by the API's contract `w × h`
                // readable floats for the duration of the call.
                let src = unsafe { std::slice::from_raw_parts(i.host_depth, n) };
                // The last frame's buffer, when no input holds it any more
                // and it has this size: no allocation a frame.
                let reused = e.host_depth.as_mut().and_then(std::sync::Arc::get_mut);
                match reused.filter(|b| b.len() == n) {
                    Some(b) => b.copy_from_slice(src),
                    None => e.host_depth = Some(src.into()),
                }
                let depth = e.host_depth.clone().expect("set above");
                input.host_depth = Some(shadowcull::HostDepth {
                    camera,
                    width: w,
                    height: h,
                    depth,
                });
            }
            let o = e.pipeline.frame(&input)?;
            // SAFETY: checked non-NULL and at least as large as the struct.
            let c = unsafe { &mut *out };
            e.outputs.fill(&o, c);
            Ok(())
        })
    })
}
