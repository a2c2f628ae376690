//! A host occlusion backend through C callbacks: the host's GPU answers the
//! eye and light passes' occluder draws and occlusion queries. The callback
//! table mirrors `raster::OcclusionBackend` one for one; `begin_view` makes
//! the state of one view for one frame and `end_view` drops it.

use crate::error::Failure;
use crate::frame::sc_light;
use crate::handles;
use crate::handles::sc_pipeline;
use crate::id_handles::light_handle;
use crate::structs::{read, Versioned};
use shadowcull::raster::{
    self, BackendStats, Coverage, CullMode, DepthPick, DrawCommand, OcclusionBackend, QueryCommand,
    QueryId, QueryMode, QueryOptions, ReceiverTarget,
};
use shadowcull::visibility::{BackendFactory, ViewRole};
use std::ffi::c_void;
use std::sync::Arc;

/// The eye pass's view (`sc_view_role.kind`).
pub const SC_VIEW_EYE: u32 = 0;
/// A light view of a light's pass.
pub const SC_VIEW_LIGHT: u32 = 1;

/// Standard coverage: pixel centres (`coverage` of draws and queries).
pub const SC_RASTER_STANDARD: u32 = 0;
/// Outer-conservative: every pixel the primitive touches.
pub const SC_RASTER_OUTER: u32 = 1;
/// Inner-conservative: only pixels the primitive covers whole.
pub const SC_RASTER_INNER: u32 = 2;

/// Conservative coverage takes the nearest depth over pixel ∩ primitive.
pub const SC_PICK_NEAREST: u32 = 0;
/// Conservative coverage takes the farthest depth over pixel ∩ primitive.
pub const SC_PICK_FARTHEST: u32 = 1;

/// Every triangle is drawn (`sc_draw_command.cull`).
pub const SC_CULL_NONE: u32 = 0;
/// Only front-facing (counter-clockwise on screen) triangles are drawn.
pub const SC_CULL_BACK: u32 = 1;
/// Only back-facing (clockwise on screen) triangles are drawn.
pub const SC_CULL_FRONT: u32 = 2;

/// The triangles are drawn one by one (`sc_draw_command.whole`).
pub const SC_WHOLE_NONE: u32 = 0;
/// The triangles bound a convex solid (a convex mesh or an occluder proxy):
/// with `SC_RASTER_INNER` at the farthest depth, a backend may cover every
/// pixel inside their silhouette (the bundled one does), not only those
/// inside one triangle. Drawing them one by one covers less and stays
/// conservative.
pub const SC_WHOLE_CONVEX: u32 = 1;
/// The triangles are a closed mesh whose hidden faces `cull` names: as
/// `SC_WHOLE_CONVEX`, for the union of its front faces.
pub const SC_WHOLE_CLOSED: u32 = 2;

/// A query over one box (`sc_query_command.kind`).
pub const SC_QUERY_BOX: u32 = 0;
/// A query over the union of several boxes (one result).
pub const SC_QUERY_BOXES: u32 = 1;
/// A query over a mesh's triangles.
pub const SC_QUERY_MESH: u32 = 2;

/// Count every passing sample (`sc_query_command.mode`).
pub const SC_QUERY_COUNT: u32 = 0;
/// Any passing sample decides: the host may stop at the first and answer 1.
pub const SC_QUERY_ANY: u32 = 1;

/// Which view a backend serves.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sc_view_role {
    /// `SC_VIEW_EYE` or `SC_VIEW_LIGHT`.
    pub kind: u32,
    /// Viewport width (the eye) or the light view's side, in pixels.
    pub width: u32,
    /// Viewport height (the eye) or the light view's side, in pixels.
    pub height: u32,
    /// The light view's index among its light's views (0 for the eye).
    pub view: u32,
    /// The light (0 for the eye).
    pub light: sc_light,
}

/// An occluder draw: triangles of a mesh, depth-tested (GEQUAL, reversed Z)
/// and written; nothing else.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sc_draw_command {
    /// Local → clip, column-major.
    pub clip_from_local: [f32; 16],
    /// Local positions `[x, y, z, 1]`.
    pub positions: *const [f32; 4],
    /// Number of `positions`.
    pub position_count: usize,
    /// Triangles, three indices into `positions` each.
    pub triangles: *const [u32; 3],
    /// Number of `triangles`.
    pub triangle_count: usize,
    /// The object (its `sc_object` handle minus 1 when it is one).
    pub object: u32,
    /// `SC_RASTER_*`: light views draw occluders `SC_RASTER_INNER` at the
    /// farthest depth; the eye pass draws `SC_RASTER_STANDARD`.
    pub coverage: u32,
    /// `SC_PICK_*` for conservative coverage.
    pub depth_pick: u32,
    /// `SC_CULL_*`: the faces the draw may skip (`glCullFace`). The eye pass
    /// culls the faces of a closed mesh turned away from the eye; a backend
    /// that draws every face instead gets the same masks but for ties of
    /// rounding at silhouette edges, and the bundled backend honours it.
    pub cull: u32,
    /// `SC_WHOLE_*`: whether the triangles may be drawn as one solid
    /// (inner-conservative draws of a coarse eye pass and of light views).
    /// (Added after `cull`: a host that never reads it draws triangle by
    /// triangle, which stays conservative.)
    pub whole: u32,
}

/// An occlusion query: how many samples of its geometry pass GEQUAL against
/// the depth drawn so far (and, with receivers set, lie over a marked pixel
/// at or in front of its receiver depth).
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sc_query_command {
    /// `SC_QUERY_BOX`, `SC_QUERY_BOXES` or `SC_QUERY_MESH`.
    pub kind: u32,
    /// `SC_QUERY_COUNT` or `SC_QUERY_ANY`.
    pub mode: u32,
    /// `SC_RASTER_*`: queries of conservative culling are `SC_RASTER_OUTER`
    /// at the nearest depth.
    pub coverage: u32,
    /// `SC_PICK_*`.
    pub depth_pick: u32,
    /// Local → clip, column-major.
    pub clip_from_local: [f32; 16],
    /// `SC_QUERY_BOX`: the box minimum and maximum.
    pub min: [f32; 3],
    /// See `min`.
    pub max: [f32; 3],
    /// `SC_QUERY_BOXES`: boxes as `[min x, y, z, max x, y, z]`.
    pub boxes: *const [f32; 6],
    /// Number of `boxes`.
    pub box_count: usize,
    /// `SC_QUERY_MESH`: local positions `[x, y, z, 1]`.
    pub positions: *const [f32; 4],
    /// Number of `positions`.
    pub position_count: usize,
    /// `SC_QUERY_MESH`: triangles.
    pub triangles: *const [u32; 3],
    /// Number of `triangles`.
    pub triangle_count: usize,
}

/// The receivers restricting a light view's queries: per pixel (row-major,
/// row 0 at the top) the farthest receiver depth, `+∞` where none.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sc_receivers {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height` depths.
    pub depth: *const f32,
}

/// A host's occlusion backend. Every callback gets `user` and the `view`
/// state `begin_view` returned; statuses are 0 for success (anything else
/// fails the frame with `SC_INVALID_ARGUMENT`).
///
/// What a backend must honour to keep the masks exact: draws and queries in
/// the coverage they carry (a GPU without conservative rasterization must
/// run the pipeline with `SC_COVERAGE_POINT`, whose mismatch is measured);
/// light-view queries restricted to the receivers of `set_receivers`;
/// GEQUAL with reversed Z. Callbacks arrive from the pipeline's pool
/// threads, several views at once, each view on one thread at a time.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct sc_backend_callbacks {
    /// `sizeof(sc_backend_callbacks)`.
    pub struct_size: u32,
    /// Zero.
    pub reserved: u32,
    /// Passed to every callback.
    pub user: *mut c_void,
    /// A view's state for one frame; NULL fails the frame.
    pub begin_view:
        Option<extern "C" fn(user: *mut c_void, role: *const sc_view_role) -> *mut c_void>,
    /// Drops a view's state.
    pub end_view: Option<extern "C" fn(user: *mut c_void, view: *mut c_void)>,
    /// Clears depth to the background (0, reversed Z).
    pub clear: Option<extern "C" fn(user: *mut c_void, view: *mut c_void)>,
    /// Sets (or with NULL removes) the receivers restricting later queries.
    pub set_receivers:
        Option<extern "C" fn(user: *mut c_void, view: *mut c_void, r: *const sc_receivers) -> i32>,
    /// Draws occluders.
    pub draw: Option<
        extern "C" fn(user: *mut c_void, view: *mut c_void, cmd: *const sc_draw_command) -> i32,
    >,
    /// Issues a query; its id goes to `*id` (ids count from 0 per view).
    pub issue_query: Option<
        extern "C" fn(
            user: *mut c_void,
            view: *mut c_void,
            q: *const sc_query_command,
            id: *mut u32,
        ) -> i32,
    >,
    /// 1 with the sample count in `*samples` when query `id`'s result has
    /// arrived, else 0.
    pub poll: Option<
        extern "C" fn(user: *mut c_void, view: *mut c_void, id: u32, samples: *mut u32) -> i32,
    >,
    /// Query `id`'s sample count, waiting for it.
    pub wait: Option<extern "C" fn(user: *mut c_void, view: *mut c_void, id: u32) -> u32>,
    /// Returns when every command has executed.
    pub finish: Option<extern "C" fn(user: *mut c_void, view: *mut c_void)>,
}

impl Versioned for sc_backend_callbacks {
    fn default_value() -> Self {
        sc_backend_callbacks {
            struct_size: std::mem::size_of::<Self>() as u32,
            reserved: 0,
            user: std::ptr::null_mut(),
            begin_view: None,
            end_view: None,
            clear: None,
            set_receivers: None,
            draw: None,
            issue_query: None,
            poll: None,
            wait: None,
            finish: None,
        }
    }
}

/// The callbacks, all present (checked when set).
#[derive(Clone, Copy)]
struct Table(sc_backend_callbacks);

// SAFETY: the header states that callbacks arrive from the pipeline's pool
// threads; a host that sets them promises `user` may be used from them.
unsafe impl Send for Table {}
// SAFETY: as above: shared by the pool threads, read only.
unsafe impl Sync for Table {}

/// One view's backend for one frame.
struct CallbackBackend {
    table: Table,
    view: *mut c_void,
    stats: BackendStats,
    /// Row-major receiver depths and union boxes as the callbacks take them.
    rows: Vec<f32>,
    boxes: Vec<[f32; 6]>,
}

// SAFETY: `view` is the host's state for this view, used by one thread at a
// time (the backend moves to the thread that runs the view); see `Table`.
unsafe impl Send for CallbackBackend {}

fn coverage(c: Coverage) -> (u32, u32) {
    let pick = |p: DepthPick| match p {
        DepthPick::Nearest => SC_PICK_NEAREST,
        DepthPick::Farthest => SC_PICK_FARTHEST,
    };
    match c {
        Coverage::Standard => (SC_RASTER_STANDARD, SC_PICK_NEAREST),
        Coverage::Outer(p) => (SC_RASTER_OUTER, pick(p)),
        Coverage::Inner(p) => (SC_RASTER_INNER, pick(p)),
    }
}

fn host_failed(what: &str, status: i32) -> raster::Error {
    raster::Error::Host {
        message: format!("{what} returned {status}"),
    }
}

impl CallbackBackend {
    fn cb(&self) -> &sc_backend_callbacks {
        &self.table.0
    }

    fn query(&mut self, mut q: sc_query_command, options: QueryOptions) -> raster::Result<QueryId> {
        (q.coverage, q.depth_pick) = coverage(options.coverage);
        q.mode = match options.mode {
            QueryMode::Any | QueryMode::CountUpTo(1) => SC_QUERY_ANY,
            // A host counts every sample; the count is compared the same.
            QueryMode::Count | QueryMode::CountUpTo(_) => SC_QUERY_COUNT,
        };
        self.stats.queries += 1;
        let mut id = 0;
        let f = self.cb().issue_query.expect("checked when set");
        match f(self.cb().user, self.view, &q, &mut id) {
            0 => Ok(QueryId(id)),
            s => Err(host_failed("issue_query", s)),
        }
    }
}

fn query_base(kind: u32, clip_from_local: glam::Mat4) -> sc_query_command {
    sc_query_command {
        kind,
        mode: SC_QUERY_COUNT,
        coverage: SC_RASTER_STANDARD,
        depth_pick: SC_PICK_NEAREST,
        clip_from_local: clip_from_local.to_cols_array(),
        min: [0.0; 3],
        max: [0.0; 3],
        boxes: std::ptr::null(),
        box_count: 0,
        positions: std::ptr::null(),
        position_count: 0,
        triangles: std::ptr::null(),
        triangle_count: 0,
    }
}

impl OcclusionBackend for CallbackBackend {
    fn clear(&mut self) {
        let f = self.cb().clear.expect("checked when set");
        f(self.cb().user, self.view);
    }

    fn set_receivers(&mut self, receivers: Option<Arc<ReceiverTarget>>) -> raster::Result<()> {
        let f = self.cb().set_receivers.expect("checked when set");
        let status = match receivers {
            None => f(self.cb().user, self.view, std::ptr::null()),
            Some(r) => {
                r.rows_into(&mut self.rows);
                let (width, height) = r.size();
                let c = sc_receivers {
                    width,
                    height,
                    depth: self.rows.as_ptr(),
                };
                f(self.cb().user, self.view, &c)
            }
        };
        match status {
            0 => Ok(()),
            s => Err(host_failed("set_receivers", s)),
        }
    }

    fn draw(&mut self, cmd: DrawCommand) -> raster::Result<()> {
        let (cov, pick) = coverage(cmd.coverage);
        let c = sc_draw_command {
            clip_from_local: cmd.clip_from_local.to_cols_array(),
            positions: cmd.positions.as_ptr().cast(),
            position_count: cmd.positions.len(),
            triangles: cmd.triangles.as_ptr(),
            triangle_count: cmd.drawn_triangles().len(),
            object: cmd.object,
            coverage: cov,
            depth_pick: pick,
            cull: match cmd.cull {
                CullMode::None => SC_CULL_NONE,
                CullMode::Back => SC_CULL_BACK,
                CullMode::Front => SC_CULL_FRONT,
            },
            whole: match cmd.whole {
                raster::Whole::No => SC_WHOLE_NONE,
                raster::Whole::Convex => SC_WHOLE_CONVEX,
                raster::Whole::Closed => SC_WHOLE_CLOSED,
            },
        };
        self.stats.draws += 1;
        let f = self.cb().draw.expect("checked when set");
        match f(self.cb().user, self.view, &c) {
            0 => Ok(()),
            s => Err(host_failed("draw", s)),
        }
    }

    fn issue_query(&mut self, q: QueryCommand) -> raster::Result<QueryId> {
        match q {
            QueryCommand::Aabb {
                clip_from_local,
                min,
                max,
                options,
            } => {
                let mut c = query_base(SC_QUERY_BOX, clip_from_local);
                (c.min, c.max) = (min.to_array(), max.to_array());
                self.query(c, options)
            }
            QueryCommand::Aabbs {
                clip_from_local,
                boxes,
                options,
            } => self.issue_box_union(clip_from_local, &boxes, options),
            QueryCommand::Mesh {
                clip_from_local,
                positions,
                triangles,
                options,
            } => {
                let mut c = query_base(SC_QUERY_MESH, clip_from_local);
                c.positions = positions.as_ptr().cast();
                c.position_count = positions.len();
                c.triangles = triangles.as_ptr();
                c.triangle_count = triangles.len();
                self.query(c, options)
            }
        }
    }

    fn issue_box_union(
        &mut self,
        clip_from_local: glam::Mat4,
        boxes: &[(glam::Vec3, glam::Vec3)],
        options: QueryOptions,
    ) -> raster::Result<QueryId> {
        self.boxes.clear();
        self.boxes
            .extend(boxes.iter().map(|(a, b)| [a.x, a.y, a.z, b.x, b.y, b.z]));
        let mut c = query_base(SC_QUERY_BOXES, clip_from_local);
        c.boxes = self.boxes.as_ptr();
        c.box_count = self.boxes.len();
        self.query(c, options)
    }

    fn poll(&mut self, id: QueryId) -> Option<u32> {
        self.stats.polls += 1;
        let f = self.cb().poll.expect("checked when set");
        let mut samples = 0;
        (f(self.cb().user, self.view, id.0, &mut samples) != 0).then_some(samples)
    }

    fn wait(&mut self, id: QueryId) -> u32 {
        self.stats.waits += 1;
        let f = self.cb().wait.expect("checked when set");
        f(self.cb().user, self.view, id.0)
    }

    fn finish(&mut self) {
        let f = self.cb().finish.expect("checked when set");
        f(self.cb().user, self.view);
    }

    fn stats(&self) -> BackendStats {
        self.stats
    }
}

impl Drop for CallbackBackend {
    fn drop(&mut self) {
        let f = self.cb().end_view.expect("checked when set");
        f(self.cb().user, self.view);
    }
}

/// A backend that fails every call: what a `begin_view` returning NULL gets.
struct Failed;

impl OcclusionBackend for Failed {
    fn clear(&mut self) {}
    fn set_receivers(&mut self, _: Option<Arc<ReceiverTarget>>) -> raster::Result<()> {
        Err(host_failed("begin_view", 0))
    }
    fn draw(&mut self, _: DrawCommand) -> raster::Result<()> {
        Err(host_failed("begin_view", 0))
    }
    fn issue_query(&mut self, _: QueryCommand) -> raster::Result<QueryId> {
        Err(host_failed("begin_view", 0))
    }
    fn poll(&mut self, _: QueryId) -> Option<u32> {
        Some(1)
    }
    fn wait(&mut self, _: QueryId) -> u32 {
        1
    }
    fn finish(&mut self) {}
    fn stats(&self) -> BackendStats {
        BackendStats::default()
    }
}

/// Sends the pipeline's occluder draws and occlusion queries (eye pass and
/// every light view) to the host's callbacks; NULL returns to the library's
/// own rasterizer. Every callback must be set.
#[no_mangle]
pub extern "C" fn sc_pipeline_set_backend(
    pipeline: sc_pipeline,
    callbacks: *const sc_backend_callbacks,
) -> crate::sc_status {
    crate::error::guard("sc_pipeline_set_backend", || {
        let factory = if callbacks.is_null() {
            None
        } else {
            let c = read(callbacks, "callbacks")?;
            let missing = [
                ("begin_view", c.begin_view.is_none()),
                ("end_view", c.end_view.is_none()),
                ("clear", c.clear.is_none()),
                ("set_receivers", c.set_receivers.is_none()),
                ("draw", c.draw.is_none()),
                ("issue_query", c.issue_query.is_none()),
                ("poll", c.poll.is_none()),
                ("wait", c.wait.is_none()),
                ("finish", c.finish.is_none()),
            ];
            if let Some((name, _)) = missing.iter().find(|(_, m)| *m) {
                return Err(Failure::invalid(format!("callbacks.{name}: NULL")));
            }
            let table = Table(c);
            let f: Arc<BackendFactory> = Arc::new(move |role: ViewRole| {
                let t = table;
                let r = match role {
                    ViewRole::Eye { width, height } => sc_view_role {
                        kind: SC_VIEW_EYE,
                        width,
                        height,
                        view: 0,
                        light: 0,
                    },
                    ViewRole::LightView { light, view, size } => sc_view_role {
                        kind: SC_VIEW_LIGHT,
                        width: size,
                        height: size,
                        view,
                        light: light_handle(light),
                    },
                };
                let begin = t.0.begin_view.expect("checked when set");
                let view = begin(t.0.user, &r);
                if view.is_null() {
                    return Box::new(Failed) as Box<dyn OcclusionBackend + Send>;
                }
                Box::new(CallbackBackend {
                    table: t,
                    view,
                    stats: BackendStats::default(),
                    rows: Vec::new(),
                    boxes: Vec::new(),
                })
            });
            Some(f)
        };
        handles::with(pipeline, |e| {
            e.pipeline.set_backend_factory(factory);
            Ok(())
        })
    })
}
