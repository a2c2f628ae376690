//! The input structs the host fills, and how they are read: every one starts
//! with `struct_size`, so a host built against an older, smaller version
//! keeps working (the missing fields take their defaults), and a newer,
//! larger one is accepted when its extra bytes are zero.

use crate::error::{Failure, Result};
use shadowcull::scene::{ClipDepth, Light, ObjectFlags};
use shadowcull::{
    ClampReceiversSpec, ClampingSpec, CoverageSpec, CullingSpec, OccludersSpec, PipelineOptions,
    Preset, StencilBackend,
};
use std::ffi::c_void;

/// The object takes part in shadow casting (its volumes are built).
pub const SC_CASTS: u32 = 1;
/// The object's visible surface can be shadowed.
pub const SC_RECEIVES: u32 = 2;
/// The object hides what lies behind it in the culling passes.
pub const SC_OCCLUDES: u32 = 4;
/// The eye sees the object (it is drawn and can be in the PSR).
pub const SC_VISIBLE: u32 = 8;
/// Every flag: an ordinary object.
pub const SC_FLAGS_ALL: u32 = 15;

/// Culling of the eye and light passes (`sc_pipeline_options.culling`).
pub const SC_CULLING_NONE: u32 = 0;
/// View-frustum culling only.
pub const SC_CULLING_FRUSTUM: u32 = 1;
/// Stop-and-wait hierarchical occlusion culling.
pub const SC_CULLING_EXACT: u32 = 2;
/// Coherent hierarchical culling.
pub const SC_CULLING_CHC: u32 = 3;
/// CHC++ (the default).
pub const SC_CULLING_CHCPP: u32 = 4;
/// Per view and frame, CHC++ or no culling, as a cost model of the last
/// frames' counters chooses (`culling: auto`; its cost constants are the
/// defaults).
pub const SC_CULLING_AUTO: u32 = 5;

/// CPU stencil (`sc_pipeline_options.stencil`): none; no mask, for a host
/// that draws the volumes itself (the default).
pub const SC_STENCIL_NONE: u32 = 0;
/// Brute-force stencil.
pub const SC_STENCIL_BF: u32 = 1;
/// Hierarchical stencil.
pub const SC_STENCIL_H: u32 = 2;
/// Brute-force stencil with the per-volume depth-bounds test.
pub const SC_STENCIL_DB: u32 = 3;
/// Per light and frame, the hierarchical stencil or the depth-bounds one
/// with scissor rectangles, as a cost model of the last frames' counters
/// chooses (`stencil: auto`; its cost constants are the defaults).
pub const SC_STENCIL_AUTO: u32 = 4;

/// Conservative coverage: the culled mask equals the unculled one (default).
pub const SC_COVERAGE_CONSERVATIVE: u32 = 0;
/// Pixel-centre sampling: faster, aggressive (its mismatch is measured).
pub const SC_COVERAGE_POINT: u32 = 1;

/// No clamping (`sc_pipeline_options.clamping`, the default): volumes
/// extrude to infinity.
pub const SC_CLAMPING_NONE: u32 = 0;
/// Continuous clamping: each caster's volume cut into segments over the
/// depths its receivers occupy; `sc_volume_range.segment` numbers them.
pub const SC_CLAMPING_CONTINUOUS: u32 = 1;

/// Discrete clamping [Steiner §4.4.2]: each caster's volume drawn only in
/// the strips of the image (`sc_pipeline_options.slices` of them, cut by
/// planes through the eye) where the light pass finds a receiver in its
/// shadow. Exact with `SC_COVERAGE_CONSERVATIVE`, aggressive with
/// `SC_COVERAGE_POINT`. A caster cut by the plane through eye, light and
/// strip direction, or not wholly in front of the eye, stays unclamped, as
/// does every caster of a light the frame does not cull.
pub const SC_CLAMPING_DISCRETE: u32 = 2;
/// Per light and frame none, continuous or discrete clamping, whichever a
/// cost model of earlier frames' counters finds cheaper (deterministic).
pub const SC_CLAMPING_AUTO: u32 = 3;

/// Every receiving object is a receiver for clamping (the default).
pub const SC_CLAMP_RECEIVERS_ALL: u32 = 0;
/// The eye pass's potentially visible receivers (with culling).
pub const SC_CLAMP_RECEIVERS_PSR: u32 = 1;
/// Fragment receivers: the eye's visible surface read in the light views
/// (with culling; a light the frame does not cull clamps as with `ALL`).
pub const SC_CLAMP_RECEIVERS_FRAGMENT: u32 = 2;

/// `float` elements.
pub const SC_F32: u32 = 0;
/// `double` elements.
pub const SC_F64: u32 = 1;
/// `uint16_t` indices.
pub const SC_U16: u32 = 2;
/// `uint32_t` indices.
pub const SC_U32: u32 = 3;

/// Point light (`sc_light_desc.kind`).
pub const SC_LIGHT_POINT: u32 = 0;
/// Spot light.
pub const SC_LIGHT_SPOT: u32 = 1;
/// Directional light.
pub const SC_LIGHT_DIRECTIONAL: u32 = 2;

/// `sc_pipeline_options.preset`: the batch defaults (a CPU mask in batch
/// jobs) for the fields the struct lacks.
pub const SC_PRESET_BATCH: u32 = 0;
/// `sc_pipeline_options.preset`: a renderer that draws the volumes on its own
/// GPU (`sc_pipeline_options_gpu_host`).
pub const SC_PRESET_GPU_HOST: u32 = 1;

/// `sc_pipeline_options.occluders`: the preset's (`SC_PRESET_GPU_HOST`:
/// proxies; `SC_PRESET_BATCH`: meshes).
pub const SC_OCCLUDERS_PRESET: u32 = 0;
/// `sc_pipeline_options.occluders`: the light views draw every object's mesh.
pub const SC_OCCLUDERS_MESH: u32 = 1;
/// `sc_pipeline_options.occluders`: the light views draw each solid convex
/// mesh's proxy (the hull of 16 of its vertices, inside it) in its place.
pub const SC_OCCLUDERS_PROXY: u32 = 2;

/// OpenGL clip depth, `[-w, w]` (`sc_frame_input.clip_depth`).
pub const SC_CLIP_DEPTH_NEGATIVE_ONE_TO_ONE: u32 = 0;
/// Direct3D, Vulkan, Metal, WebGPU clip depth, `[0, w]`.
pub const SC_CLIP_DEPTH_ZERO_TO_ONE: u32 = 1;

/// Pipeline options. Fill with `sc_pipeline_options_default`, then change
/// fields.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sc_pipeline_options {
    /// `sizeof(sc_pipeline_options)`.
    pub struct_size: u32,
    /// `SC_CULLING_*`.
    pub culling: u32,
    /// `SC_STENCIL_*`.
    pub stencil: u32,
    /// `SC_COVERAGE_*`.
    pub coverage: u32,
    /// A node counts as visible above this many samples (0: conservative).
    pub query_threshold: u32,
    /// Side of every light view or cube face, in pixels.
    pub light_resolution: u32,
    /// Worker threads of the pipeline's own pool, joined on destroy; 0 uses
    /// rayon's global pool (its threads live until the process exits).
    pub threads: u32,
    /// Non-zero: every triangle casts, back faces flipped.
    pub two_sided: u32,
    /// The most memory a frame may need, by the library's estimate, in
    /// bytes; a larger estimate fails the frame (`SC_INVALID_ARGUMENT`
    /// naming `max_memory`) before anything is allocated. 0: three quarters
    /// of the machine's memory. (Added in version 0.1 of this struct's
    /// 40-byte layout; a 32-byte struct from an older host means 0.)
    pub max_memory: u64,
    /// `SC_CLAMPING_*`: shadow-volume clamping [Steiner §4.4]. (Added with
    /// the 64-byte layout, as the three fields after it; an older host's
    /// struct means none.)
    pub clamping: u32,
    /// `SC_CLAMP_RECEIVERS_*`: the receivers clamping fits volumes to.
    pub clamping_receivers: u32,
    /// Clamping's cost per volume vertex (v); 0: the library's default.
    pub clamp_vertex_cost: f64,
    /// Clamping's cost per stencil pixel (r); 0: the library's default.
    pub clamp_pixel_cost: f64,
    /// Non-zero: count each light's brute-force fill without and with
    /// clamping (`sc_light_stats.bf_fill_unclamped`, `bf_fill_clamped`) on
    /// any stencil; a measurement left out of every time. (Added with the
    /// 72-byte layout; an older host's struct means 0.)
    pub count_fill: u32,
    /// Discrete clamping's number of slices, 1 to 64; 0: the library's
    /// default (10). (Added in the 72-byte layout's last field, which was
    /// reserved as zero: an older host means the default.)
    pub slices: u32,
    /// `SC_PRESET_*`: the options every field this struct lacks takes
    /// (`SC_PRESET_GPU_HOST`: `PipelineOptions::gpu_host`'s). The fields it
    /// has always win. (Added with the 80-byte layout, as `scissor`; an
    /// older host's struct means `SC_PRESET_BATCH` and no scissor.)
    pub preset: u32,
    /// Non-zero: compute each volume's scissor rectangle
    /// (`sc_volume_range.scissor`), for the host's scissor test.
    pub scissor: u32,
    /// `SC_OCCLUDERS_*`: what the light views draw as occluders. (Added
    /// with the 88-byte layout, as the reserved field after it; an older
    /// host's struct means `SC_OCCLUDERS_PRESET`.)
    pub occluders: u32,
    /// The culling eye pass's size (`PipelineOptions::culling_resolution`):
    /// the largest size within `culling_width × culling_height` with the
    /// viewport's aspect, never above the viewport; both 0: the preset's.
    /// (Added with the 96-byte layout, in the 88-byte layout's reserved
    /// field and the one after it; an older host's struct means the
    /// preset's.)
    pub culling_width: u32,
    /// See `culling_width`.
    pub culling_height: u32,
    /// Reserved, zero.
    pub reserved: u32,
}

/// A mesh in the host's memory: positions `vertex_count` times, `stride`
/// bytes apart, as three `float`s or `double`s; triangles as
/// `index_count` (a multiple of 3) `uint16_t` or `uint32_t` indices.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sc_mesh_desc {
    /// `sizeof(sc_mesh_desc)`.
    pub struct_size: u32,
    /// `SC_F32` or `SC_F64`.
    pub position_type: u32,
    /// Bytes from one position to the next (at least 3 elements).
    pub position_stride: u32,
    /// Number of vertices.
    pub vertex_count: u32,
    /// The first position's first element.
    pub positions: *const c_void,
    /// `SC_U16` or `SC_U32`.
    pub index_type: u32,
    /// Number of indices, three per triangle.
    pub index_count: u32,
    /// The indices.
    pub indices: *const c_void,
}

/// A light.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sc_light_desc {
    /// `sizeof(sc_light_desc)`.
    pub struct_size: u32,
    /// `SC_LIGHT_*`.
    pub kind: u32,
    /// Position (point and spot lights), world space.
    pub position: [f64; 3],
    /// Direction the light travels (spot and directional lights).
    pub direction: [f64; 3],
    /// Full cone angle of a spot light, radians, in (0, π).
    pub apex_angle: f64,
    /// Range of a point or spot light; 0 for none.
    pub range: f64,
}

/// One frame's input: the viewport and the host's view and projection
/// matrices (column-major, perspective; any near plane, finite or infinite
/// far plane, off-centre or jittered).
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sc_frame_input {
    /// `sizeof(sc_frame_input)`.
    pub struct_size: u32,
    /// Viewport width in pixels.
    pub width: u32,
    /// Viewport height in pixels.
    pub height: u32,
    /// `SC_CLIP_DEPTH_*` of `projection`.
    pub clip_depth: u32,
    /// World → view, column-major.
    pub view: [f64; 16],
    /// View → clip, column-major.
    pub projection: [f64; 16],
    /// The host's own depth of this frame, or NULL: `host_depth_width ×
    /// host_depth_height` floats, row-major, row 0 at the top, reversed Z
    /// (`near / view distance`, 1 at the near plane, 0 where nothing was
    /// drawn), per pixel of the culling size the farthest depth over the
    /// output pixels whose centres it holds (see `docs/host.md`, "The host's
    /// own depth"). Copied during the call.
    pub host_depth: *const f32,
    /// Width of `host_depth`: the frame's culling size.
    pub host_depth_width: u32,
    /// Height of `host_depth`.
    pub host_depth_height: u32,
    /// The near plane the host built `projection` with, or 0: when given,
    /// a projection whose near plane under `clip_depth` differs from it by
    /// more than 1e-6 relative is `SC_INVALID_ARGUMENT` (a wrong clip-depth
    /// convention, which the matrix alone cannot show).
    pub near: f64,
    /// 1 when the viewport's pixels are not square; else 0, and a
    /// `width / height` more than 1 % from the projection's aspect is
    /// `SC_INVALID_ARGUMENT` (a projection made for another viewport size).
    pub anamorphic: u32,
}

/// Structs read by [`read`]: a default for the fields an older host leaves out.
pub(crate) trait Versioned: Copy {
    /// The struct with every field at its default (`struct_size` set).
    fn default_value() -> Self;
    /// Bytes up to and including the first field after `struct_size`: the
    /// smallest size accepted.
    const MIN_SIZE: usize = 8;
}

/// Reads the struct `p` points to, named `name` in messages, by its
/// `struct_size`: fields beyond an older host's size take their defaults;
/// a larger size is accepted when every extra byte is zero.
pub(crate) fn read<T: Versioned>(p: *const T, name: &str) -> Result<T> {
    if p.is_null() {
        return Err(Failure::invalid(format!("{name}: NULL")));
    }
    // SAFETY: `p` is non-NULL and, by the API's contract, points to a
    // readable struct whose first field is its `u32` size; read unaligned.
    let size = unsafe { (p as *const u32).read_unaligned() } as usize;
    let ours = std::mem::size_of::<T>();
    if size < T::MIN_SIZE {
        return Err(Failure::invalid(format!(
            "{name}.struct_size: {size} is smaller than any version ({} bytes at least)",
            T::MIN_SIZE
        )));
    }
    if size > ours {
        // SAFETY: the host declared `size` readable bytes at `p`.
        let extra = unsafe { std::slice::from_raw_parts((p as *const u8).add(ours), size - ours) };
        if extra.iter().any(|&b| b != 0) {
            return Err(Failure::invalid(format!(
                "{name}.struct_size: {size} bytes with non-zero fields past this library's {ours}"
            )));
        }
    }
    let mut out = T::default_value();
    let n = size.min(ours);
    // SAFETY: `n` bytes are readable at `p` (declared by the host) and
    // writable in `out` (n ≤ its size); the structs are plain data, repr(C).
    unsafe {
        std::ptr::copy_nonoverlapping(p as *const u8, &mut out as *mut T as *mut u8, n);
    }
    Ok(out)
}

impl Versioned for sc_pipeline_options {
    fn default_value() -> Self {
        sc_pipeline_options {
            struct_size: std::mem::size_of::<Self>() as u32,
            culling: SC_CULLING_CHCPP,
            stencil: SC_STENCIL_NONE,
            coverage: SC_COVERAGE_CONSERVATIVE,
            query_threshold: 0,
            light_resolution: PipelineOptions::default().light_resolution,
            threads: 0,
            two_sided: 0,
            max_memory: 0,
            clamping: SC_CLAMPING_NONE,
            clamping_receivers: SC_CLAMP_RECEIVERS_ALL,
            clamp_vertex_cost: 0.0,
            clamp_pixel_cost: 0.0,
            count_fill: 0,
            slices: 0,
            preset: SC_PRESET_BATCH,
            scissor: 0,
            occluders: SC_OCCLUDERS_PRESET,
            culling_width: 0,
            culling_height: 0,
            reserved: 0,
        }
    }
}

impl sc_pipeline_options {
    /// `sc_pipeline_options_gpu_host`'s fill: the struct's form of
    /// [`PipelineOptions::gpu_host`].
    pub(crate) fn gpu_host() -> Self {
        let o = PipelineOptions::gpu_host();
        sc_pipeline_options {
            culling: SC_CULLING_AUTO,
            stencil: SC_STENCIL_NONE,
            light_resolution: o.light_resolution,
            clamping: SC_CLAMPING_NONE,
            preset: SC_PRESET_GPU_HOST,
            scissor: u32::from(o.scissor),
            ..<Self as Versioned>::default_value()
        }
    }
}

impl Versioned for sc_mesh_desc {
    fn default_value() -> Self {
        sc_mesh_desc {
            struct_size: std::mem::size_of::<Self>() as u32,
            position_type: SC_F32,
            position_stride: 12,
            vertex_count: 0,
            positions: std::ptr::null(),
            index_type: SC_U32,
            index_count: 0,
            indices: std::ptr::null(),
        }
    }
}

impl Versioned for sc_light_desc {
    fn default_value() -> Self {
        sc_light_desc {
            struct_size: std::mem::size_of::<Self>() as u32,
            kind: SC_LIGHT_POINT,
            position: [0.0; 3],
            direction: [0.0, -1.0, 0.0],
            apex_angle: 1.0,
            range: 0.0,
        }
    }
}

impl Versioned for sc_frame_input {
    fn default_value() -> Self {
        sc_frame_input {
            struct_size: std::mem::size_of::<Self>() as u32,
            width: 0,
            height: 0,
            clip_depth: SC_CLIP_DEPTH_NEGATIVE_ONE_TO_ONE,
            view: [0.0; 16],
            projection: [0.0; 16],
            host_depth: std::ptr::null(),
            host_depth_width: 0,
            host_depth_height: 0,
            near: 0.0,
            anamorphic: 0,
        }
    }
}

impl sc_pipeline_options {
    /// The facade's options.
    pub(crate) fn to_rust(self) -> Result<PipelineOptions> {
        if self.reserved != 0 {
            return Err(Failure::invalid(format!(
                "options.reserved: {} must be 0",
                self.reserved
            )));
        }
        let base = match self.preset {
            SC_PRESET_BATCH => Preset::Batch,
            SC_PRESET_GPU_HOST => Preset::GpuHost,
            v => {
                return Err(Failure::invalid(format!(
                    "options.preset: {v} is no SC_PRESET_*"
                )))
            }
        }
        .options();
        let culling = match self.culling {
            SC_CULLING_NONE => CullingSpec::None,
            SC_CULLING_FRUSTUM => CullingSpec::Frustum,
            SC_CULLING_EXACT => CullingSpec::Exact,
            SC_CULLING_CHC => CullingSpec::Chc,
            SC_CULLING_CHCPP => CullingSpec::Chcpp,
            SC_CULLING_AUTO => CullingSpec::Auto,
            v => {
                return Err(Failure::invalid(format!(
                    "options.culling: {v} is no SC_CULLING_*"
                )))
            }
        };
        let stencil = match self.stencil {
            SC_STENCIL_NONE => StencilBackend::None,
            SC_STENCIL_BF => StencilBackend::Bf,
            SC_STENCIL_H => StencilBackend::H,
            SC_STENCIL_DB => StencilBackend::Db,
            SC_STENCIL_AUTO => StencilBackend::Auto,
            v => {
                return Err(Failure::invalid(format!(
                    "options.stencil: {v} is no SC_STENCIL_*"
                )))
            }
        };
        let coverage = match self.coverage {
            SC_COVERAGE_CONSERVATIVE => CoverageSpec::Conservative,
            SC_COVERAGE_POINT => CoverageSpec::Point,
            v => {
                return Err(Failure::invalid(format!(
                    "options.coverage: {v} is no SC_COVERAGE_*"
                )))
            }
        };
        let clamping = match self.clamping {
            SC_CLAMPING_NONE => ClampingSpec::None,
            SC_CLAMPING_CONTINUOUS => ClampingSpec::Continuous,
            SC_CLAMPING_DISCRETE => ClampingSpec::Discrete,
            SC_CLAMPING_AUTO => ClampingSpec::Auto,
            v => {
                return Err(Failure::invalid(format!(
                    "options.clamping: {v} is no SC_CLAMPING_*"
                )))
            }
        };
        let clamping_receivers = match self.clamping_receivers {
            SC_CLAMP_RECEIVERS_ALL => ClampReceiversSpec::All,
            SC_CLAMP_RECEIVERS_PSR => ClampReceiversSpec::Psr,
            SC_CLAMP_RECEIVERS_FRAGMENT => ClampReceiversSpec::Fragment,
            v => {
                return Err(Failure::invalid(format!(
                    "options.clamping_receivers: {v} is no SC_CLAMP_RECEIVERS_*"
                )))
            }
        };
        let cost = |v: f64, name: &str, default: f64| {
            if v == 0.0 {
                Ok(default)
            } else if v.is_finite() && v > 0.0 {
                Ok(v)
            } else {
                Err(Failure::invalid(format!(
                    "options.{name}: {v} is not a positive finite cost (0 for the default)"
                )))
            }
        };
        Ok(PipelineOptions {
            culling,
            stencil,
            coverage,
            clamping,
            clamping_receivers,
            clamp_vertex_cost: cost(
                self.clamp_vertex_cost,
                "clamp_vertex_cost",
                base.clamp_vertex_cost,
            )?,
            clamp_pixel_cost: cost(
                self.clamp_pixel_cost,
                "clamp_pixel_cost",
                base.clamp_pixel_cost,
            )?,
            query_threshold: self.query_threshold,
            light_resolution: self.light_resolution,
            threads: self.threads,
            two_sided: self.two_sided != 0,
            count_fill: self.count_fill != 0,
            slices: match self.slices {
                0 => base.slices,
                n => n,
            },
            max_memory: (self.max_memory > 0)
                .then_some(shadowcull::byte_size::ByteSize(self.max_memory)),
            scissor: self.scissor != 0,
            occluders: match self.occluders {
                SC_OCCLUDERS_PRESET => base.occluders,
                SC_OCCLUDERS_MESH => OccludersSpec::Mesh,
                SC_OCCLUDERS_PROXY => OccludersSpec::Proxy,
                v => {
                    return Err(Failure::invalid(format!(
                        "options.occluders: {v} is no SC_OCCLUDERS_*"
                    )))
                }
            },
            culling_resolution: match (self.culling_width, self.culling_height) {
                (0, 0) => base.culling_resolution,
                (w, h) if w > 0 && h > 0 => Some((w, h)),
                (w, h) => {
                    return Err(Failure::invalid(format!(
                        "options.culling_width × culling_height: {w}×{h} needs both \
                         sides, or neither (0 × 0: the preset's)"
                    )))
                }
            },
            ..base
        })
    }
}

impl sc_light_desc {
    /// The light (validated by the pipeline).
    pub(crate) fn to_rust(self) -> Result<Light> {
        let v = |a: [f64; 3]| glam::DVec3::from_array(a);
        let range = (self.range != 0.0).then_some(self.range);
        Ok(match self.kind {
            SC_LIGHT_POINT => Light::Point {
                position: v(self.position),
                range,
            },
            SC_LIGHT_SPOT => Light::Spot {
                position: v(self.position),
                direction: v(self.direction),
                apex_angle: self.apex_angle,
                range,
            },
            SC_LIGHT_DIRECTIONAL => Light::Directional {
                direction: v(self.direction),
            },
            k => {
                return Err(Failure::invalid(format!(
                    "light.kind: {k} is no SC_LIGHT_*"
                )))
            }
        })
    }
}

impl sc_frame_input {
    /// The clip-depth convention.
    pub(crate) fn depth(&self) -> Result<ClipDepth> {
        match self.clip_depth {
            SC_CLIP_DEPTH_NEGATIVE_ONE_TO_ONE => Ok(ClipDepth::NegativeOneToOne),
            SC_CLIP_DEPTH_ZERO_TO_ONE => Ok(ClipDepth::ZeroToOne),
            v => Err(Failure::invalid(format!(
                "input.clip_depth: {v} is no SC_CLIP_DEPTH_*"
            ))),
        }
    }
}

/// The flags of `SC_*` bits.
pub(crate) fn flags(bits: u32) -> Result<ObjectFlags> {
    if bits & !SC_FLAGS_ALL != 0 {
        return Err(Failure::invalid(format!(
            "flags: {bits:#x} has bits beyond SC_FLAGS_ALL"
        )));
    }
    Ok(ObjectFlags {
        casts: bits & SC_CASTS != 0,
        receives: bits & SC_RECEIVES != 0,
        occludes: bits & SC_OCCLUDES != 0,
        visible: bits & SC_VISIBLE != 0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The C presets are the Rust ones, and the struct's own fields win.
    #[test]
    fn the_c_presets_are_the_rust_presets() {
        let batch = <sc_pipeline_options as Versioned>::default_value();
        let rust = PipelineOptions {
            culling: CullingSpec::Chcpp,
            stencil: StencilBackend::None,
            ..PipelineOptions::default()
        };
        assert_eq!(batch.to_rust().unwrap(), rust);
        let gpu = sc_pipeline_options::gpu_host();
        assert_eq!(gpu.to_rust().unwrap(), PipelineOptions::gpu_host());
        let chcpp = sc_pipeline_options {
            culling: SC_CULLING_CHCPP,
            scissor: 0,
            ..gpu
        };
        let o = chcpp.to_rust().unwrap();
        assert_eq!((o.culling, o.scissor), (CullingSpec::Chcpp, false));
        assert_eq!(o.reference_every, 0, "the preset's, which the struct lacks");
        let bad = sc_pipeline_options { preset: 2, ..gpu };
        assert!(bad.to_rust().is_err());
        // Occluders: the preset's unless named.
        assert_eq!(gpu.to_rust().unwrap().occluders, OccludersSpec::Proxy);
        assert_eq!(batch.to_rust().unwrap().occluders, OccludersSpec::Mesh);
        let meshes = sc_pipeline_options {
            occluders: SC_OCCLUDERS_MESH,
            ..gpu
        };
        assert_eq!(meshes.to_rust().unwrap().occluders, OccludersSpec::Mesh);
        let proxies = sc_pipeline_options {
            occluders: SC_OCCLUDERS_PROXY,
            ..batch
        };
        assert_eq!(proxies.to_rust().unwrap().occluders, OccludersSpec::Proxy);
        // The culling resolution: the preset's unless both sides are named.
        assert_eq!(
            gpu.to_rust().unwrap().culling_resolution,
            Some((1920, 1080))
        );
        assert_eq!(batch.to_rust().unwrap().culling_resolution, None);
        let coarse = sc_pipeline_options {
            culling_width: 320,
            culling_height: 180,
            ..batch
        };
        assert_eq!(
            coarse.to_rust().unwrap().culling_resolution,
            Some((320, 180))
        );
        for bad in [
            sc_pipeline_options {
                occluders: 3,
                ..gpu
            },
            sc_pipeline_options { reserved: 1, ..gpu },
            sc_pipeline_options {
                culling_width: 320,
                ..gpu
            },
        ] {
            assert!(bad.to_rust().is_err());
        }
    }
}
