//! What a view is to a traversal: how objects and boxes reach its clip space
//! ([`ViewSetup`]), how it samples ([`Sampling`]), and the meshes in the
//! backend's form ([`MeshData`]).

use glam::{DMat4, DVec3, Mat4, Vec4};
use raster::{Coverage, QueryOptions};
use scene::{ObjectId, Plane, Scene};
use std::sync::Arc;

/// How draws, queries and receiver marks sample pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Sampling {
    /// Conservative: box queries outer-conservative at the nearest depth;
    /// light-view occluders inner-conservative at the farthest depth;
    /// receivers widened by [`raster::RECEIVER_EPS_PX`] and pushed away from
    /// the light. The culled mask equals the unculled one.
    #[default]
    Conservative,
    /// Aggressive: everything at pixel centres (standard coverage), receivers
    /// unwidened and unpushed, as a GPU implementation would sample. Can cull
    /// a caster whose shadow falls between samples: measured, not exact.
    Point,
}

/// Per-mesh vertex data in the backend's form (`w = 1`, shared with draw commands).
#[derive(Clone, Debug)]
pub struct MeshData {
    pub(crate) positions: Vec<Arc<[Vec4]>>,
    pub(crate) triangles: Vec<Arc<[[u32; 3]]>>,
    /// Per mesh its occluder proxy ([`scene::occluder_proxy`]: triangles
    /// over the mesh's own vertices), `None` where the mesh is its own.
    pub(crate) proxies: Vec<Option<Arc<[[u32; 3]]>>>,
    /// Per mesh: it bounds a convex solid ([`scene::is_convex_solid`]).
    pub(crate) convex: Vec<bool>,
    /// The scene's mesh version each copy was made from.
    versions: Vec<u64>,
}

impl MeshData {
    /// Converts every mesh of `scene`.
    pub fn from_scene(scene: &Scene) -> Self {
        let mut data = MeshData {
            positions: Vec::new(),
            triangles: Vec::new(),
            proxies: Vec::new(),
            convex: Vec::new(),
            versions: Vec::new(),
        };
        data.sync(scene);
        data
    }

    /// The triangles of mesh `mesh` (shared).
    pub(crate) fn triangles_of(&self, mesh: scene::MeshId) -> Arc<[[u32; 3]]> {
        self.triangles[mesh.index()].clone()
    }

    /// The triangles of a convex solid inside mesh `mesh`, drawn whole
    /// ([`raster::DrawCommand::whole`]): its proxy, or its own when the
    /// mesh is convex; `None` for other meshes.
    pub(crate) fn hull_of(&self, mesh: scene::MeshId) -> Option<&Arc<[[u32; 3]]>> {
        let i = mesh.index();
        self.proxy_of(mesh)
            .or_else(|| self.convex.get(i).copied()?.then(|| &self.triangles[i]))
    }

    /// Whether the occluder triangles a view draws of mesh `mesh` bound a
    /// convex solid: the mesh is convex, or (`proxies`) they are its proxy's.
    pub(crate) fn convex_draw(&self, mesh: scene::MeshId, proxies: bool) -> bool {
        let i = mesh.index();
        self.convex.get(i).copied().unwrap_or(false) || (proxies && self.proxy_of(mesh).is_some())
    }

    /// The occluder proxy of mesh `mesh`, `None` when the mesh is its own.
    pub(crate) fn proxy_of(&self, mesh: scene::MeshId) -> Option<&Arc<[[u32; 3]]>> {
        self.proxies.get(mesh.index())?.as_ref()
    }

    /// Triangles an occluder draw of every mesh with an object holds:
    /// `(full meshes, with host occluders or proxies where they have one)`, per object of
    /// `scene` (what `occluders: proxy` saves a view that draws them all).
    pub fn occluder_triangles(&self, scene: &Scene) -> (u64, u64) {
        let (mut full, mut proxied) = (0u64, 0u64);
        for o in scene.objects() {
            full += self.triangles[o.mesh.index()].len() as u64;
            let m = drawn_mesh(o, true);
            let n = self.triangles[m.index()].len() as u64;
            proxied += self.proxy_of(m).map_or(n, |p| p.len() as u64);
        }
        (full, proxied)
    }

    /// Catches up with meshes added to `scene` since, and with meshes whose
    /// vertices changed ([`Scene::mesh_version`]; a removed mesh keeps its
    /// slot, empty).
    pub fn sync(&mut self, scene: &Scene) {
        let meshes = scene.graph().meshes();
        self.positions.truncate(meshes.len());
        self.triangles.truncate(meshes.len());
        self.proxies.truncate(meshes.len());
        self.convex.truncate(meshes.len());
        self.versions.truncate(meshes.len());
        for (i, m) in meshes.iter().enumerate() {
            let version = scene.mesh_version(scene::MeshId::from_slot(i as u32));
            if self.versions.get(i) == Some(&version) {
                continue;
            }
            let p: Arc<[Vec4]> = m.positions().iter().map(|p| p.extend(1.0)).collect();
            let t: Arc<[[u32; 3]]> = m.triangles().into();
            let proxy = scene::occluder_proxy(m).map(Arc::from);
            let convex = scene::is_convex_solid(m);
            if i < self.positions.len() {
                self.positions[i] = p;
                self.triangles[i] = t;
                self.proxies[i] = proxy;
                self.convex[i] = convex;
                self.versions[i] = version;
            } else {
                self.positions.push(p);
                self.triangles.push(t);
                self.proxies.push(proxy);
                self.convex.push(convex);
                self.versions.push(version);
            }
        }
    }
}

/// The mesh object `o` draws as an occluder: its host-given occluder when
/// `host` (views that draw proxies), else its own.
pub(crate) fn drawn_mesh(o: &scene::Object, host: bool) -> scene::MeshId {
    match (host, o.occluder) {
        (true, Some(m)) => m,
        _ => o.mesh,
    }
}

/// One view: how objects and boxes reach its clip space, its culling planes,
/// and the coverage of its draws and queries.
pub struct ViewSetup<'a> {
    /// `clip_from_local` for an object's `world_from_local` (the one transform path).
    pub clip_from_local: &'a dyn Fn(&DMat4) -> Mat4,
    /// Boxes are sent relative to this point (f64 subtraction, rounded
    /// outward), with [`ViewSetup::clip_from_origin`].
    pub origin: DVec3,
    /// `clip_from_local` of the translation to `origin`.
    pub clip_from_origin: Mat4,
    /// The view's planes (inside positive), for frustum culling.
    pub planes: [Plane; 5],
    /// Where front-to-back distances are measured from (the centre of projection).
    pub apex: DVec3,
    /// Coverage of occluder draws.
    pub draw_coverage: Coverage,
    /// Coverage and mode of box queries.
    pub query: QueryOptions,
    /// A node is visible when more than this many samples pass (0: conservative).
    pub threshold: u32,
    /// The triangles an object draws as an occluder, when not all of its
    /// mesh's (a light view draws only the triangles that cast).
    pub triangles: Option<&'a dyn Fn(ObjectId) -> Arc<[[u32; 3]]>>,
    /// Which objects the view draws as occluders when it renders them (the
    /// others are reported rendered but draw nothing): the eye draws visible
    /// occluders ([`ViewSetup::eye_occluder`]), a light view casting ones.
    pub occluder: fn(&scene::ObjectFlags) -> bool,
    /// The eye whose hidden faces occluder draws skip ([`crate::eye_cull`]);
    /// `None` (light views): draws keep every face.
    pub back_faces: Option<&'a scene::Camera>,
    /// Which occluders are drawn whole as convex solids, with
    /// inner-conservative coverage at the farthest depth
    /// ([`raster::DrawCommand::whole`]).
    pub convex: ConvexOccluders,
    /// Objects with a host-given occluder ([`scene::Object::occluder`])
    /// draw it in place of their mesh (`occluders: proxy`).
    pub host_occluders: bool,
    /// The backend already holds the view's depth (a host's own depth
    /// buffer of this frame): the traversal neither clears nor draws into
    /// it, and rendered objects are only listed; its queries decide.
    pub preloaded: bool,
}

/// Which occluders a view draws whole as convex solids
/// ([`ViewSetup::convex`]): drawn triangle by triangle, inner-conservative
/// coverage leaves a crack along every edge two triangles share, through
/// which a view sees what the solid hides.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ConvexOccluders {
    /// None: every occluder is drawn triangle by triangle.
    #[default]
    Off,
    /// Each occluder with a convex solid inside it draws that solid's
    /// triangles instead of its mesh's (its proxy, or its own mesh when
    /// convex), and other closed meshes are drawn whole as closed meshes
    /// (the eye at a coarse culling resolution).
    Hulls,
    /// The view's own triangles ([`ViewSetup::triangles`]), drawn whole
    /// where they are a convex mesh's or, with `proxies`, its proxy's.
    Own {
        /// The triangles are proxies where a mesh has one.
        proxies: bool,
    },
}

impl<'a> ViewSetup<'a> {
    /// The eye view of `camera`: boxes eye-relative, the frustum's planes,
    /// standard-coverage draws, outer-conservative box queries at the nearest
    /// depth (any-samples when `threshold` is 0, counts otherwise).
    /// `clip_from_local` is the eye pass's transform path
    /// (`scene::transform::clip_from_local` with `camera`).
    pub fn eye(
        camera: &'a scene::Camera,
        clip_from_local: &'a dyn Fn(&DMat4) -> Mat4,
        threshold: u32,
    ) -> Self {
        Self::eye_sampled(camera, clip_from_local, threshold, Sampling::Conservative)
    }

    /// [`ViewSetup::eye`] with box queries sampled as `sampling` says.
    pub fn eye_sampled(
        camera: &'a scene::Camera,
        clip_from_local: &'a dyn Fn(&DMat4) -> Mat4,
        threshold: u32,
        sampling: Sampling,
    ) -> Self {
        ViewSetup {
            clip_from_local,
            origin: camera.position,
            clip_from_origin: scene::transform::clip_from_local(
                camera,
                &DMat4::from_translation(camera.position),
            ),
            planes: camera.frustum().planes,
            apex: camera.position,
            draw_coverage: Coverage::Standard,
            query: QueryOptions {
                coverage: sampling.query_coverage(),
                // A view asks whether more than `threshold` samples pass: the
                // count stops there (at the first sample for 0).
                mode: raster::QueryMode::more_than(threshold),
            },
            threshold,
            triangles: None,
            occluder: Self::eye_occluder,
            back_faces: Some(camera),
            convex: ConvexOccluders::Off,
            host_occluders: false,
            preloaded: false,
        }
    }

    /// The mesh object `o` draws as an occluder in this view: its host-given
    /// occluder when the view takes them, else its own.
    pub(crate) fn occluder_mesh(&self, o: &scene::Object) -> scene::MeshId {
        drawn_mesh(o, self.host_occluders)
    }

    /// The eye's occluders: visible objects that may occlude.
    pub fn eye_occluder(f: &scene::ObjectFlags) -> bool {
        f.visible && f.occludes
    }

    /// A light view's occluders: casting objects that may occlude.
    pub fn light_occluder(f: &scene::ObjectFlags) -> bool {
        f.casts && f.occludes
    }
}

impl Sampling {
    /// Coverage of box queries.
    pub(crate) fn query_coverage(self) -> Coverage {
        match self {
            Sampling::Conservative => Coverage::Outer(raster::DepthPick::Nearest),
            Sampling::Point => Coverage::Standard,
        }
    }
}
