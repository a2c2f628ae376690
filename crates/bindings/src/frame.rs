//! `sc_pipeline_frame`'s output: the C view of `FrameOutput`. Ids, ranges
//! and masks are copied into buffers the pipeline's entry keeps (reused from
//! frame to frame); volume positions and indices point into the pipeline's
//! own volume buffers. Everything stays valid until the next frame call or
//! the pipeline's destroy; the host frees nothing.

use crate::id_handles::{light_handle, object_handle};
use shadowcull::mask::PixelClass;
use shadowcull::raster::{VolumeMethod, VolumeRange};
use shadowcull::scene::ObjectId;
use shadowcull::FrameOutput;

/// An object: 0 is the null handle.
#[allow(non_camel_case_types)]
pub type sc_object = u64;

/// A light: 0 is the null handle.
#[allow(non_camel_case_types)]
pub type sc_light = u64;

/// zpass volume (no caps; `sc_volume_range.method`).
pub const SC_ZPASS: u32 = 0;
/// zfail volume (light and dark caps).
pub const SC_ZFAIL: u32 = 1;
/// zp+ volume (near-plane cap).
pub const SC_ZPPLUS: u32 = 2;

/// One caster's shadow volume in the light's volume buffer.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sc_volume_range {
    /// The caster.
    pub object: sc_object,
    /// Segment of the caster's volume (0 until clamping splits volumes).
    pub segment: u32,
    /// `SC_ZPASS`, `SC_ZFAIL` or `SC_ZPPLUS`: the stencil operations to use.
    pub method: u32,
    /// First vertex of the range in `positions`.
    pub first_vertex: u32,
    /// Vertices of the range.
    pub vertex_count: u32,
    /// First index of the range in `indices`.
    pub first_index: u32,
    /// Indices of the range (three per triangle).
    pub index_count: u32,
    /// Index range `[begin, end)` of the light cap.
    pub light_cap: [u32; 2],
    /// Index range `[begin, end)` of the dark cap.
    pub dark_cap: [u32; 2],
    /// Scissor rectangle `[x0, y0, x1, y1)` in pixels, row 0 at the top.
    pub scissor: [u32; 4],
    /// Depth bounds (reversed Z): fragments outside `[depth_far, depth_near]`
    /// cannot change the stencil.
    pub depth_near: f32,
    /// See `depth_near`.
    pub depth_far: f32,
    /// Local → world of the positions, column-major.
    pub world_from_local: [f64; 16],
    /// A clamped volume's segment planes in world space, `(a, b, c, d)`
    /// with `a·x + b·y + c·z + d = 0` and `(a, b, c)` a unit normal towards
    /// greater light depth: the near plane (all zero for segment 0, which
    /// starts at the caster) and the far plane (all zero for an unclamped
    /// volume). The segment's geometry already lies between them; a host may
    /// use them as clip planes or ignore them.
    pub near_plane: [f32; 4],
    /// See `near_plane`.
    pub far_plane: [f32; 4],
    /// Band `[x0, y0, x1, y1)` in pixels, row 0 at the top: the only pixels
    /// the range may be drawn at. Unlike `scissor` it is not optional: a
    /// caster's volume drawn once per band of the eye slices its receivers
    /// occupy (several ranges sharing one geometry) counts right only
    /// inside each band. `{0, 0, UINT32_MAX, UINT32_MAX}` when unbanded.
    pub band: [u32; 4],
}

/// One light's counters of a frame.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct sc_light_stats {
    /// Light pass (PSC) wall time, ms.
    pub light_ms: f64,
    /// Silhouettes, ms.
    pub silhouette_ms: f64,
    /// Volume construction, ms.
    pub volume_ms: f64,
    /// CPU stencil and mask, ms (0 without a stencil).
    pub stencil_ms: f64,
    /// Volume triangles.
    pub volume_triangles: u64,
    /// Silhouette edges.
    pub silhouette_edges: u64,
    /// Casters by method.
    pub zpass_casters: u64,
    /// See `zpass_casters`.
    pub zfail_casters: u64,
    /// See `zpass_casters`.
    pub zpplus_casters: u64,
    /// Occlusion queries of the eye and this light's passes.
    pub queries: u64,
    /// Waits for query results.
    pub waits: u64,
    /// Continuous clamping (sweeps and intervals), ms.
    pub clamp_ms: f64,
    /// Overlapping pairs of clamping's sweeps.
    pub sap_pairs: u64,
    /// Endpoint swaps of clamping's sweeps.
    pub sap_swaps: u64,
    /// Segments of the clamped casters.
    pub segments: u64,
    /// Triangles of those segments.
    pub segment_triangles: u64,
    /// Brute-force pixels processed by the light's volumes without
    /// clamping: a `bf` frame's own count, or counted with
    /// `sc_pipeline_options.count_fill`; 0 when not measured.
    pub bf_fill_unclamped: u64,
    /// The same with clamping's segments.
    pub bf_fill_clamped: u64,
    /// Zero; room for fields to come.
    pub reserved: [u64; 1],
}

/// One light's output.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sc_light_output {
    /// The light.
    pub light: sc_light,
    /// Potential shadow casters, ascending.
    pub psc: *const sc_object,
    /// Number of `psc`.
    pub psc_count: usize,
    /// Volume vertices `[x, y, z, w]` in each range's local space (`w = 0`
    /// at infinity).
    pub positions: *const [f32; 4],
    /// Number of `positions`.
    pub position_count: usize,
    /// Volume triangles, three absolute indices into `positions` each.
    pub indices: *const u32,
    /// Number of `indices`.
    pub index_count: usize,
    /// One range per caster.
    pub ranges: *const sc_volume_range,
    /// Number of `ranges`.
    pub range_count: usize,
    /// With a CPU stencil: one byte per pixel, row 0 at the top, 0 lit,
    /// 1 shadow, 2 unlit, 3 background; else NULL.
    pub mask: *const u8,
    /// Counters.
    pub stats: sc_light_stats,
}

/// Frame-level counters.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub struct sc_frame_stats {
    /// Wall time of the frame call, ms.
    pub frame_ms: f64,
    /// Eye pass, ms.
    pub eye_ms: f64,
    /// Objects in the scene.
    pub objects: u64,
    /// Triangles drawn by the eye pass.
    pub triangles: u64,
    /// Potentially shadowed receivers.
    pub psr: u64,
    /// Eye-pass queries.
    pub eye_queries: u64,
    /// Eye-pass waits.
    pub eye_waits: u64,
    /// Lights.
    pub lights: u32,
    /// The frame's number (`sc_pipeline_set_frame_number`).
    pub frame: u32,
    /// Zero; room for fields to come.
    pub reserved: [u64; 8],
}

/// A frame's output. Set `struct_size`; the library fills the rest.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sc_frame_output {
    /// `sizeof(sc_frame_output)`, set by the caller.
    pub struct_size: u32,
    /// Zero.
    pub reserved0: u32,
    /// Potentially shadowed receivers, ascending.
    pub psr: *const sc_object,
    /// Number of `psr`.
    pub psr_count: usize,
    /// One output per light, in the order the lights were created.
    pub lights: *const sc_light_output,
    /// Number of `lights`.
    pub light_count: usize,
    /// Counters.
    pub stats: sc_frame_stats,
}

/// The buffers an entry keeps for its last output.
#[derive(Default)]
pub(crate) struct Outputs {
    psr: Vec<sc_object>,
    psc: Vec<Vec<sc_object>>,
    ranges: Vec<Vec<sc_volume_range>>,
    masks: Vec<Vec<u8>>,
    lights: Vec<sc_light_output>,
}

// SAFETY: the raw pointers in `lights` point into buffers of the same entry
// (or of its pipeline) and are only read by the host, under the entry's
// documented lifetime; the entry moves between threads only behind its mutex.
unsafe impl Send for Outputs {}

fn range_of(r: &VolumeRange) -> sc_volume_range {
    sc_volume_range {
        object: object_handle(ObjectId::from_bits(r.object)),
        segment: r.segment,
        method: match r.method {
            VolumeMethod::ZPass => SC_ZPASS,
            VolumeMethod::ZFail => SC_ZFAIL,
            VolumeMethod::ZpPlus => SC_ZPPLUS,
        },
        first_vertex: r.first_vertex,
        vertex_count: r.vertex_count,
        first_index: r.first_index,
        index_count: r.index_count,
        light_cap: [r.light_cap.start, r.light_cap.end],
        dark_cap: [r.dark_cap.start, r.dark_cap.end],
        scissor: r.scissor,
        depth_near: r.depth_near,
        depth_far: r.depth_far,
        world_from_local: r.world_from_local.to_cols_array(),
        near_plane: plane_of(r.planes[0]),
        far_plane: plane_of(r.planes[1]),
        band: r.band,
    }
}

/// A segment plane as the C struct holds it: zeros for none.
fn plane_of(p: Option<[f64; 4]>) -> [f32; 4] {
    p.map_or([0.0; 4], |p| p.map(|v| v as f32))
}

impl Outputs {
    /// Copies `out` into the buffers and fills `c` with pointers to them.
    pub(crate) fn fill(&mut self, out: &FrameOutput<'_>, c: &mut sc_frame_output) {
        self.psr.clear();
        self.psr
            .extend(out.psr().iter().map(|&id| object_handle(id)));
        let n = out.light_count();
        self.psc.resize_with(n.max(self.psc.len()), Vec::new);
        self.ranges.resize_with(n.max(self.ranges.len()), Vec::new);
        self.masks.resize_with(n.max(self.masks.len()), Vec::new);
        self.lights.clear();
        for (k, l) in out.lights().enumerate() {
            let psc = &mut self.psc[k];
            psc.clear();
            psc.extend(l.psc().iter().map(|&id| object_handle(id)));
            let v = l.volumes();
            let ranges = &mut self.ranges[k];
            ranges.clear();
            ranges.extend(v.ranges.iter().map(range_of));
            let mask = l.mask().map(|m| {
                let bytes = &mut self.masks[k];
                bytes.clear();
                bytes.extend(m.pixels.iter().map(|&p| class_byte(p)));
                bytes.as_ptr()
            });
            let s = l.stats();
            self.lights.push(sc_light_output {
                light: light_handle(l.id()),
                psc: psc.as_ptr(),
                psc_count: psc.len(),
                positions: v.positions.as_ptr(),
                position_count: v.positions.len(),
                indices: v.indices.as_ptr(),
                index_count: v.indices.len(),
                ranges: ranges.as_ptr(),
                range_count: ranges.len(),
                mask: mask.unwrap_or(std::ptr::null()),
                stats: sc_light_stats {
                    light_ms: s.light_ms,
                    silhouette_ms: s.volumes.silhouette_ms,
                    volume_ms: s.volumes.volume_ms,
                    stencil_ms: s.stencil_ms,
                    volume_triangles: s.volume_triangles,
                    silhouette_edges: s.volumes.silhouette_edges as u64,
                    zpass_casters: s.volumes.zpass as u64,
                    zfail_casters: s.volumes.zfail as u64,
                    zpplus_casters: s.volumes.zpplus as u64,
                    queries: s.queries,
                    waits: s.waits,
                    clamp_ms: s.volumes.clamp_ms,
                    sap_pairs: s.volumes.sap_pairs as u64,
                    sap_swaps: s.volumes.sap_swaps as u64,
                    segments: s.volumes.segments as u64,
                    segment_triangles: s.volumes.segment_triangles as u64,
                    bf_fill_unclamped: s.bf_fill_unclamped,
                    bf_fill_clamped: s.bf_fill_clamped,
                    reserved: [0; 1],
                },
            });
        }
        let s = out.stats();
        *c = sc_frame_output {
            struct_size: c.struct_size,
            reserved0: 0,
            psr: self.psr.as_ptr(),
            psr_count: self.psr.len(),
            lights: self.lights.as_ptr(),
            light_count: self.lights.len(),
            stats: sc_frame_stats {
                frame_ms: s.frame_ms,
                eye_ms: s.eye_ms,
                objects: s.objects,
                triangles: s.triangles,
                psr: s.psr,
                eye_queries: s.eye_queries,
                eye_waits: s.eye_waits,
                lights: s.lights,
                frame: s.frame,
                reserved: [0; 8],
            },
        };
    }
}

/// DESIGN.md's class value of a mask pixel.
fn class_byte(p: PixelClass) -> u8 {
    p as u8
}
