//! RON job files: which scene, views, lights, outputs and pipeline options a
//! batch run uses.
//!
//! The schema grows without breaking old jobs: `version: 1`, and every field
//! but `scene` has a default. Unknown fields and bad values are errors with
//! line and column (or the field's path).

use crate::{Error, Result};
use glam::DVec3;
use scene::load::Loaded;
use scene::procedural::city::CityParams;
use scene::{CameraPath, Light, LookAt};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// The job schema version this build reads.
pub const JOB_VERSION: u32 = 1;

/// A batch job.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Job {
    /// Schema version; must be [`JOB_VERSION`].
    #[serde(default = "default_version")]
    pub version: u32,
    /// The scene to load or generate.
    pub scene: SceneSpec,
    /// An optional ground quad added under the scene.
    #[serde(default)]
    pub ground: Option<Ground>,
    /// Viewport `(width, height)` in pixels; default 800×600.
    #[serde(default = "default_resolution")]
    pub resolution: (u32, u32),
    /// The view(s): a camera or camera path.
    #[serde(default)]
    pub camera: CameraSpec,
    /// Number of frames; default: the camera's sequence length, else 1.
    #[serde(default)]
    pub frames: Option<u32>,
    /// Lights; each frame is computed once per light. Default: the scene's
    /// named lights, else one point light above the scene.
    #[serde(default)]
    pub lights: Vec<LightSpec>,
    /// Which files to write.
    #[serde(default)]
    pub outputs: Outputs,
    /// Pipeline options.
    #[serde(default)]
    pub pipeline: PipelineOptions,
    /// Variants `shadowcull compare` runs on the same frames (empty: brute
    /// force, depth bounds, and scissor with depth bounds, each otherwise
    /// like `pipeline`).
    #[serde(default)]
    pub pipelines: Vec<NamedPipeline>,
}

fn default_version() -> u32 {
    JOB_VERSION
}

fn default_resolution() -> (u32, u32) {
    (800, 600)
}

/// Where the scene comes from. Relative paths are relative to the job file.
#[derive(Clone, Debug, PartialEq, Deserialize)]
pub enum SceneSpec {
    /// A glTF 2.0 file (`.gltf` or `.glb`).
    Gltf(PathBuf),
    /// An OBJ file, or a directory of OBJ files loaded in name order.
    Obj(PathBuf),
    /// A box-city benchmark file (`citysc 1`).
    BoxCity(PathBuf),
    /// The procedural city with parameters (`City(())` for the defaults).
    City(CityParams),
    /// Several scenes combined into one.
    Group(Vec<SceneSpec>),
}

/// A ground quad: a square of side `size` centred under the scene bounds, at height `y`, facing up.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ground {
    /// Edge length.
    pub size: f32,
    /// Height of the quad.
    pub y: f32,
}

/// The view of each frame.
#[derive(Clone, Debug, PartialEq, Deserialize, Default)]
pub enum CameraSpec {
    /// A fixed pose.
    Fixed(LookAt),
    /// One pose per frame, in order (frame i uses pose i).
    Sequence(Vec<LookAt>),
    /// A camera the scene names (box city: `street`, `bird`).
    Named(String),
    /// A camera path the scene names (`street`, `bird`).
    Path(String),
    /// Keyframes `(frame, pose)`, linearly interpolated.
    Keyframes(Vec<(f64, LookAt)>),
    /// Default: the scene's `street` path if it has one, else a view of the
    /// whole scene bounds from the side.
    #[default]
    Auto,
}

/// A light of the job.
#[derive(Clone, Debug, PartialEq, Deserialize)]
pub enum LightSpec {
    /// Point light; `range` limits it.
    Point {
        /// Position.
        position: DVec3,
        /// Optional range.
        #[serde(default)]
        range: Option<f64>,
    },
    /// Spot light; `apex_deg` is the full cone angle in degrees.
    Spot {
        /// Position.
        position: DVec3,
        /// Axis direction.
        direction: DVec3,
        /// Full apex angle in degrees, (0, 180).
        apex_deg: f64,
        /// Optional range.
        #[serde(default)]
        range: Option<f64>,
    },
    /// Directional light travelling along `direction`.
    Directional(DVec3),
    /// The sun at `elevation_deg` above the horizon and `azimuth_deg`
    /// counter-clockwise from +x seen from above (toward −z).
    Sun {
        /// Elevation in degrees.
        elevation_deg: f64,
        /// Azimuth in degrees.
        azimuth_deg: f64,
    },
    /// A point light above the centre of the scene bounds at
    /// `min.y + factor · height` (height = bounds' y extent).
    AboveScene(f64),
    /// A light the scene names (box city: `light`).
    Named(String),
}

/// Files a run writes besides `stats.csv` and `summary.json`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Outputs {
    /// `frames/<frame>_<light>_mask.png`: the four-class reference mask.
    pub masks: bool,
    /// `frames/<frame>_<light>_shaded.png`: a shaded image of the frame.
    pub shaded: bool,
    /// `frames/<frame>_<light>_tiles.png`: the hierarchical stencil's tile
    /// classification (lit white, shadow blue, boundary orange, background
    /// black; [Aila04 Fig. 1]); only with `pipeline.stencil: h`.
    pub tile_image: bool,
    /// Write images only for every n-th frame (1 = all).
    pub image_every: u32,
}

impl Default for Outputs {
    fn default() -> Self {
        Outputs {
            masks: false,
            shaded: false,
            tile_image: false,
            image_every: 1,
        }
    }
}

/// Shadow-volume method per caster, as the job spells it (`method: auto`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// zpass where it is safe, else zfail ([`shadowgen::MethodChoice::Auto`]).
    #[default]
    Auto,
    /// zpass everywhere (wrong where a volume meets the near rectangle).
    Zpass,
    /// zfail everywhere.
    Zfail,
    /// zp+ everywhere.
    Zpplus,
}

impl Method {
    /// The shadowgen choice.
    pub fn choice(self) -> shadowgen::MethodChoice {
        match self {
            Method::Auto => shadowgen::MethodChoice::Auto,
            Method::Zpass => shadowgen::MethodChoice::ZPass,
            Method::Zfail => shadowgen::MethodChoice::ZFail,
            Method::Zpplus => shadowgen::MethodChoice::ZpPlus,
        }
    }
}

/// Stencil backend (`stencil: bf`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum StencilBackend {
    /// Brute force: every volume fragment on a non-background pixel.
    #[default]
    Bf,
    /// Brute force with the per-volume depth-bounds test [EK "Computing Depth Bounds"].
    Db,
    /// Hierarchical shadow volumes \[Aila04\] (`tile`, `full_shadow`).
    H,
    /// Shadow map plus volumes at its silhouette pixels \[ChanDurand04\] (`map_size`).
    Hybrid,
}

/// Occlusion culling (`culling: chc`) of the eye pass (PSR) and of the light
/// views (PSC: shadow volumes only for potential casters) [Steiner §2.5.1, §4.3].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CullingSpec {
    /// Draw every object.
    #[default]
    None,
    /// View-frustum culling.
    Frustum,
    /// Stop-and-wait hierarchical occlusion culling.
    Exact,
    /// Coherent hierarchical culling.
    Chc,
    /// CHC++: batched queries, multiqueries, revisits (`chcpp`).
    Chcpp,
}

/// How culling samples pixels (`coverage: conservative`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CoverageSpec {
    /// Conservative queries, occluders and receivers: the mask equals the
    /// unculled one.
    #[default]
    Conservative,
    /// Pixel-centre sampling (aggressive; its mismatch is measured).
    Point,
}

impl CoverageSpec {
    /// The traversals' sampling.
    pub fn sampling(self) -> visibility::Sampling {
        match self {
            CoverageSpec::Conservative => visibility::Sampling::Conservative,
            CoverageSpec::Point => visibility::Sampling::Point,
        }
    }
}

/// CHC++ parameters (`chcpp: (batch: 50, revisit: 5, seed: 1)`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct ChcppSpec {
    /// Previously invisible nodes queried together.
    pub batch: u32,
    /// A visible leaf is re-queried every this many frames.
    pub revisit: u32,
    /// Seed of the revisit phases.
    pub seed: u64,
}

impl Default for ChcppSpec {
    fn default() -> Self {
        let o = visibility::ChcppOptions::default();
        ChcppSpec {
            batch: o.batch,
            revisit: o.revisit,
            seed: o.seed,
        }
    }
}

/// Stencil counter width (`counters: bits8`; `stencil_bits: eight` is the older spelling).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum StencilBitsSpec {
    /// 8-bit wrapping counters, as a GPU.
    #[default]
    #[serde(rename = "bits8", alias = "eight")]
    Eight,
    /// Wide counters (shows where 8 bits alias).
    Wide,
}

/// Pipeline options: how shadows are computed and how often the reference checks them.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PipelineOptions {
    /// Volume method per caster.
    pub method: Method,
    /// Stencil backend.
    pub stencil: StencilBackend,
    /// Per-volume scissor rectangles.
    pub scissor: bool,
    /// Per-volume depth-bounds test for any backend (`stencil: db` is `bf` with it).
    pub depth_bounds: bool,
    /// Stencil counter width (`bits8` or `wide`).
    #[serde(alias = "stencil_bits")]
    pub counters: StencilBitsSpec,
    /// Tile size of the hierarchical stencil: 4, 8 or 16.
    pub tile: u32,
    /// The hierarchical stencil's full-shadow bit [Aila04 §4.3.2].
    pub full_shadow: bool,
    /// Shadow-map size of the hybrid (texels per side).
    pub map_size: u32,
    /// Occlusion culling of the eye pass (the objects it draws are the
    /// potentially shadowed receivers, PSR) and of the light pass (shadow
    /// volumes only for the potential shadow casters, PSC).
    pub culling: CullingSpec,
    /// A node counts as visible above this many samples (0: conservative).
    pub query_threshold: u32,
    /// How culling samples pixels (`conservative` or the aggressive `point`).
    pub coverage: CoverageSpec,
    /// CHC++ parameters (with `culling: chcpp`).
    pub chcpp: ChcppSpec,
    /// Side of every light view (or cube face) of the light pass, in pixels.
    pub light_resolution: u32,
    /// Every triangle casts (back-facing ones flipped); the reference uses the same rule.
    pub two_sided: bool,
    /// Lights with a range extrude their shadow volumes finitely (always closed).
    pub finite_extrusion: bool,
    /// Compute the reference mask every n-th frame (0 = never).
    pub reference_every: u32,
    /// The reference's options (depth-error bound; its `two_sided` must equal
    /// the pipeline's or be left out).
    pub reference: crate::reference::ReferenceOptions,
}

impl Default for PipelineOptions {
    fn default() -> Self {
        PipelineOptions {
            method: Method::Auto,
            stencil: StencilBackend::Bf,
            scissor: false,
            depth_bounds: false,
            counters: StencilBitsSpec::Eight,
            tile: 8,
            full_shadow: true,
            map_size: 2048,
            culling: CullingSpec::None,
            query_threshold: 0,
            coverage: CoverageSpec::Conservative,
            chcpp: ChcppSpec::default(),
            light_resolution: 1024,
            two_sided: false,
            finite_extrusion: false,
            reference_every: 1,
            reference: Default::default(),
        }
    }
}

impl PipelineOptions {
    /// The culling traversal.
    pub fn culling(&self) -> visibility::Culling {
        match self.culling {
            CullingSpec::None => visibility::Culling::None,
            CullingSpec::Frustum => visibility::Culling::Frustum,
            CullingSpec::Exact => visibility::Culling::Exact,
            CullingSpec::Chc => visibility::Culling::Chc,
            CullingSpec::Chcpp => visibility::Culling::ChcPlusPlus(visibility::ChcppOptions {
                batch: self.chcpp.batch,
                revisit: self.chcpp.revisit,
                seed: self.chcpp.seed,
            }),
        }
    }

    /// The shadow stage's options.
    pub fn shadow_options(&self) -> crate::pipeline::ShadowOptions {
        crate::pipeline::ShadowOptions {
            method: self.method.choice(),
            two_sided: self.two_sided,
            backend: match self.stencil {
                StencilBackend::Bf | StencilBackend::Db => crate::pipeline::Backend::Brute,
                StencilBackend::H => crate::pipeline::Backend::Hierarchical {
                    tile: match self.tile {
                        4 => raster::TileSize::T4,
                        16 => raster::TileSize::T16,
                        _ => raster::TileSize::T8,
                    },
                    full_shadow: self.full_shadow,
                },
                StencilBackend::Hybrid => crate::pipeline::Backend::Hybrid {
                    map_size: self.map_size,
                },
            },
            bits: match self.counters {
                StencilBitsSpec::Eight => raster::StencilBits::Eight,
                StencilBitsSpec::Wide => raster::StencilBits::Wide,
            },
            scissor: self.scissor,
            depth_bounds: self.depth_bounds || self.stencil == StencilBackend::Db,
            finite_extrusion: self.finite_extrusion,
        }
    }

    /// The reference's options, with the pipeline's two-sided rule.
    pub fn reference_options(&self) -> crate::reference::ReferenceOptions {
        crate::reference::ReferenceOptions {
            two_sided: self.two_sided,
            ..self.reference
        }
    }
}

/// One variant of `shadowcull compare`: a name and its pipeline options.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NamedPipeline {
    /// Row name in `compare.csv` and label in `compare.svg`.
    pub name: String,
    /// The options (defaults as in the job's `pipeline`).
    #[serde(default)]
    pub pipeline: PipelineOptions,
}

impl Job {
    /// Parses a job from RON text; `file` names it in errors.
    ///
    /// # Errors
    /// [`Error::Job`] with line and column for syntax errors, unknown fields
    /// and bad values.
    pub fn from_ron(text: &str, file: &Path) -> Result<Job> {
        let job: Job = ron::Options::default()
            .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
            .from_str(text)
            .map_err(|e| Error::Job {
                file: file.to_path_buf(),
                location: format!("{}:{}", e.position.line, e.position.col),
                message: e.code.to_string(),
            })?;
        job.validate(file)?;
        Ok(job)
    }

    /// Reads and parses a job file.
    ///
    /// # Errors
    /// [`Error::Io`] or [`Error::Job`].
    pub fn from_file(path: &Path) -> Result<Job> {
        let text = std::fs::read_to_string(path).map_err(crate::error::io_err(path))?;
        Job::from_ron(&text, path)
    }

    fn validate(&self, file: &Path) -> Result<()> {
        let bad = |field: &str, message: String| Error::Job {
            file: file.to_path_buf(),
            location: field.to_string(),
            message,
        };
        if self.version != JOB_VERSION {
            return Err(bad(
                "version",
                format!(
                    "unsupported job version {} (this build reads {JOB_VERSION})",
                    self.version
                ),
            ));
        }
        let (w, h) = self.resolution;
        if w == 0 || h == 0 || w > 16384 || h > 16384 {
            return Err(bad(
                "resolution",
                format!("{w}×{h} must be between 1×1 and 16384×16384"),
            ));
        }
        if let Some(g) = self.ground {
            if g.size <= 0.0 || !g.size.is_finite() || !g.y.is_finite() {
                return Err(bad(
                    "ground",
                    "size must be positive and finite, y finite".into(),
                ));
            }
        }
        if self.frames == Some(0) {
            return Err(bad("frames", "must be at least 1".into()));
        }
        if self.outputs.image_every == 0 {
            return Err(bad("outputs.image_every", "must be at least 1".into()));
        }
        let variants = std::iter::once(("pipeline".to_string(), &self.pipeline)).chain(
            self.pipelines
                .iter()
                .enumerate()
                .map(|(i, p)| (format!("pipelines[{i}].pipeline"), &p.pipeline)),
        );
        for (at, p) in variants {
            if !(p.reference.depth_error >= 0.0 && p.reference.depth_error < 1e-2) {
                return Err(bad(
                    &format!("{at}.reference.depth_error"),
                    "must lie in [0, 0.01)".into(),
                ));
            }
            if ![4, 8, 16].contains(&p.tile) {
                return Err(bad(
                    &format!("{at}.tile"),
                    format!("{} is not 4, 8 or 16", p.tile),
                ));
            }
            if p.chcpp.batch == 0 || p.chcpp.revisit == 0 {
                return Err(bad(
                    &format!("{at}.chcpp"),
                    format!(
                        "batch ({}) and revisit ({}) must be at least 1",
                        p.chcpp.batch, p.chcpp.revisit
                    ),
                ));
            }
            if !(8..=raster::MAX_TARGET_SIZE).contains(&p.light_resolution) {
                return Err(bad(
                    &format!("{at}.light_resolution"),
                    format!(
                        "{} is not in 8..={}",
                        p.light_resolution,
                        raster::MAX_TARGET_SIZE
                    ),
                ));
            }
            if !(16..=raster::MAX_TARGET_SIZE).contains(&p.map_size) {
                return Err(bad(
                    &format!("{at}.map_size"),
                    format!("{} is not in 16..={}", p.map_size, raster::MAX_TARGET_SIZE),
                ));
            }
            if p.reference.two_sided && !p.two_sided {
                return Err(bad(
                    &format!("{at}.reference.two_sided"),
                    format!(
                        "set {at}.two_sided instead: the pipeline and its reference use one rule"
                    ),
                ));
            }
        }
        let mut names = std::collections::HashSet::new();
        for (i, p) in self.pipelines.iter().enumerate() {
            if p.name.is_empty() || !names.insert(p.name.as_str()) {
                return Err(bad(
                    &format!("pipelines[{i}].name"),
                    format!("{:?} must be non-empty and unique", p.name),
                ));
            }
        }
        for (i, l) in self.lights.iter().enumerate() {
            if let Ok(Some(light)) = l.to_light_static() {
                light
                    .validate()
                    .map_err(|e| bad(&format!("lights[{i}]"), e.to_string()))?;
            }
        }
        Ok(())
    }

    /// The number of frames the job asks for.
    pub fn frame_count(&self) -> u32 {
        self.frames.unwrap_or(match &self.camera {
            CameraSpec::Sequence(v) => v.len().max(1) as u32,
            _ => 1,
        })
    }
}

impl LightSpec {
    /// The light, when it does not depend on the scene.
    fn to_light_static(&self) -> std::result::Result<Option<Light>, ()> {
        Ok(Some(match *self {
            LightSpec::Point { position, range } => Light::Point { position, range },
            LightSpec::Spot {
                position,
                direction,
                apex_deg,
                range,
            } => Light::Spot {
                position,
                direction,
                apex_angle: apex_deg.to_radians(),
                range,
            },
            LightSpec::Directional(direction) => Light::Directional { direction },
            LightSpec::Sun {
                elevation_deg,
                azimuth_deg,
            } => {
                let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
                let toward_sun = DVec3::new(e.cos() * a.cos(), e.sin(), -e.cos() * a.sin());
                Light::Directional {
                    direction: -toward_sun,
                }
            }
            LightSpec::AboveScene(_) | LightSpec::Named(_) => return Ok(None),
        }))
    }

    /// Resolves the light against the loaded scene.
    ///
    /// # Errors
    /// [`Error::Job`] naming `lights[index]` for an unknown name or an invalid light.
    pub fn resolve(
        &self,
        loaded: &Loaded,
        bounds: &scene::Aabb,
        index: usize,
        file: &Path,
    ) -> Result<Light> {
        let bad = |message: String| Error::Job {
            file: file.to_path_buf(),
            location: format!("lights[{index}]"),
            message,
        };
        let light = match self {
            LightSpec::AboveScene(factor) => {
                if bounds.is_empty() {
                    return Err(bad("the scene is empty; AboveScene needs bounds".into()));
                }
                let c = bounds.center();
                let h = (bounds.max.y - bounds.min.y) as f64;
                Light::Point {
                    position: DVec3::new(c.x, bounds.min.y as f64 + factor * h, c.z),
                    range: None,
                }
            }
            LightSpec::Named(name) => loaded
                .lights
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, l)| *l)
                .ok_or_else(|| bad(format!("the scene has no light named `{name}`")))?,
            other => other
                .to_light_static()
                .ok()
                .flatten()
                .ok_or_else(|| bad("unresolvable light".into()))?,
        };
        light.validate().map_err(|e| bad(e.to_string()))?;
        Ok(light)
    }
}

/// The camera path of a job, resolved against the loaded scene.
///
/// # Errors
/// [`Error::Job`] naming `camera` for an unknown name.
pub fn resolve_camera(
    spec: &CameraSpec,
    loaded: &Loaded,
    bounds: &scene::Aabb,
    file: &Path,
) -> Result<CameraPath> {
    let bad = |message: String| Error::Job {
        file: file.to_path_buf(),
        location: "camera".into(),
        message,
    };
    Ok(match spec {
        CameraSpec::Fixed(p) => CameraPath::Fixed(*p),
        CameraSpec::Sequence(v) => {
            if v.is_empty() {
                return Err(bad("Sequence needs at least one pose".into()));
            }
            CameraPath::Keyframes(v.iter().enumerate().map(|(i, p)| (i as f64, *p)).collect())
        }
        CameraSpec::Keyframes(k) => {
            if k.is_empty()
                || k.windows(2)
                    .any(|w| w[0].0.partial_cmp(&w[1].0) != Some(std::cmp::Ordering::Less))
            {
                return Err(bad(
                    "Keyframes need at least one key, frames strictly ascending".into(),
                ));
            }
            CameraPath::Keyframes(k.clone())
        }
        CameraSpec::Named(name) => loaded
            .cameras
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, c)| CameraPath::Fixed(*c))
            .ok_or_else(|| bad(format!("the scene has no camera named `{name}`")))?,
        CameraSpec::Path(name) => loaded
            .paths
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, p)| p.clone())
            .ok_or_else(|| bad(format!("the scene has no camera path named `{name}`")))?,
        CameraSpec::Auto => match loaded.paths.iter().find(|(n, _)| n == "street") {
            Some((_, p)) => p.clone(),
            None => {
                if bounds.is_empty() {
                    return Err(bad("the scene is empty; give a camera".into()));
                }
                CameraPath::Fixed(fit_side_view(bounds))
            }
        },
    })
}

/// A side view of `bounds`: 60° vertical fov, looking at the centre from +z
/// at 1.2× the distance at which the bounding sphere fills the view, eye at a
/// quarter of the bounds' height; near plane at 1/1000 of the distance.
pub fn fit_side_view(bounds: &scene::Aabb) -> LookAt {
    let c = bounds.center();
    let r = (bounds.size().as_dvec3().length() * 0.5).max(1e-6);
    let d = 1.2 * r / 30f64.to_radians().sin();
    let eye_y = bounds.min.y as f64 + 0.25 * bounds.size().y as f64;
    LookAt {
        eye: DVec3::new(c.x, eye_y, c.z + d),
        target: c,
        up: DVec3::Y,
        fov_y_deg: 60.0,
        near: d / 1000.0,
    }
}

/// Loads or generates the scene of `spec`; relative paths resolve against `base`.
///
/// # Errors
/// The loader's error.
pub fn load_scene(spec: &SceneSpec, base: &Path) -> Result<Loaded> {
    let abs = |p: &PathBuf| {
        if p.is_absolute() {
            p.clone()
        } else {
            base.join(p)
        }
    };
    Ok(match spec {
        SceneSpec::Gltf(p) => Loaded::from_graph(scene::load::gltf::load_gltf(&abs(p))?),
        SceneSpec::Obj(p) => {
            let p = abs(p);
            if p.is_dir() {
                Loaded::from_graph(scene::load::obj::load_obj_dir(&p)?)
            } else {
                Loaded::from_graph(scene::load::obj::load_obj(&p)?)
            }
        }
        SceneSpec::BoxCity(p) => scene::load::box_city::load_box_city(&abs(p))?,
        SceneSpec::City(params) => scene::procedural::city::city(params)?,
        SceneSpec::Group(specs) => {
            let mut all = Loaded::default();
            for s in specs {
                all.merge(load_scene(s, base)?);
            }
            all
        }
    })
}

/// The bundled default job: the procedural city's `street` path at 800×600,
/// a point light 1.5× the city height above its centre and a sun at 35°
/// elevation, azimuth 30° from +x; conservative CHC++ culling (PSR, PSC) and
/// the hierarchical stencil; masks and shaded images written.
pub fn default_job() -> Job {
    Job {
        version: JOB_VERSION,
        scene: SceneSpec::City(CityParams::default()),
        ground: None,
        resolution: (800, 600),
        camera: CameraSpec::Path("street".into()),
        frames: Some(8),
        lights: vec![
            LightSpec::AboveScene(1.5),
            LightSpec::Sun {
                elevation_deg: 35.0,
                azimuth_deg: 30.0,
            },
        ],
        outputs: Outputs {
            masks: true,
            shaded: true,
            tile_image: true,
            image_every: 1,
        },
        pipeline: PipelineOptions {
            stencil: StencilBackend::H,
            culling: CullingSpec::Chcpp,
            ..PipelineOptions::default()
        },
        pipelines: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<Job> {
        Job::from_ron(s, Path::new("test.ron"))
    }

    #[test]
    fn minimal_job_gets_defaults() {
        let j = parse("(scene: Obj(\"a.obj\"))").unwrap();
        assert_eq!(j.version, 1);
        assert_eq!(j.resolution, (800, 600));
        assert_eq!(j.camera, CameraSpec::Auto);
        assert_eq!(j.pipeline.reference_every, 1);
        assert_eq!(j.frame_count(), 1);
    }

    /// The culling fields as the issue spells them, and bad values naming
    /// their field.
    #[test]
    fn culling_fields_parse_and_bad_values_name_their_field() {
        let j = parse(
            r#"(version: 1, scene: City(()), pipeline: (culling: chcpp, coverage: conservative,
                light_resolution: 1024, query_threshold: 0,
                chcpp: (batch: 50, revisit: 5, seed: 1)))"#,
        )
        .unwrap();
        let p = &j.pipeline;
        assert_eq!(
            (p.culling, p.coverage),
            (CullingSpec::Chcpp, CoverageSpec::Conservative)
        );
        assert_eq!(
            p.culling(),
            visibility::Culling::ChcPlusPlus(visibility::ChcppOptions::default())
        );
        let j = parse(
            r#"(version: 1, scene: City(()), pipeline: (coverage: point, chcpp: (seed: 9)))"#,
        )
        .unwrap();
        assert_eq!(j.pipeline.coverage, CoverageSpec::Point);
        assert_eq!((j.pipeline.chcpp.batch, j.pipeline.chcpp.seed), (50, 9));
        for (text, field) in [
            ("chcpp: (batch: 0)", "pipeline.chcpp"),
            ("light_resolution: 4", "pipeline.light_resolution"),
        ] {
            let e = parse(&format!(
                "(version: 1, scene: City(()), pipeline: ({text}))"
            ))
            .unwrap_err()
            .to_string();
            assert!(e.contains(field), "{e}");
        }
        for text in ["culling: chcp", "coverage: exact", "chcpp: (batches: 5)"] {
            let e = parse(&format!(
                "(version: 1, scene: City(()), pipeline: ({text}))"
            ));
            assert!(e.is_err(), "{text}");
        }
    }

    #[test]
    fn full_job_parses() {
        let j = parse(
            r#"(
                version: 1,
                scene: Group([Obj("a.obj"), City((seed: 7))]),
                ground: Some((size: 100.0, y: 0.0)),
                resolution: (320, 240),
                camera: Sequence([
                    (eye: (0.0, 1.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 60.0, near: 0.1),
                    (eye: (5.0, 5.0, 5.0), target: (0.0, 0.0, 0.0), up: (0.0, 1.0, 0.0), fov_y_deg: 60.0, near: 0.1),
                ]),
                lights: [
                    Point(position: (0.0, 10.0, 0.0)),
                    Spot(position: (0.0, 10.0, 0.0), direction: (0.0, -1.0, 0.0), apex_deg: 60.0, range: Some(50.0)),
                    Directional((0.3, -1.0, 0.2)),
                    Sun(elevation_deg: 35.0, azimuth_deg: 30.0),
                    AboveScene(1.5),
                    Named("light"),
                ],
                outputs: (masks: true, shaded: false),
                pipeline: (method: zfail, stencil: db, scissor: true, two_sided: true, reference_every: 2),
                pipelines: [(name: "bf"), (name: "zp+", pipeline: (method: zpplus, stencil_bits: wide))],
            )"#,
        )
        .unwrap();
        assert_eq!(j.frame_count(), 2);
        assert_eq!(j.lights.len(), 6);
        assert_eq!(j.pipeline.method, Method::Zfail);
        assert_eq!(j.pipeline.stencil, StencilBackend::Db);
        assert!(j.pipeline.scissor);
        assert!(j.pipeline.reference_options().two_sided);
        let o = j.pipeline.shadow_options();
        assert!(o.two_sided && o.depth_bounds && o.scissor);
        assert_eq!(j.pipelines.len(), 2);
        assert_eq!(j.pipelines[0].pipeline, PipelineOptions::default());
        assert_eq!(
            j.pipelines[1].pipeline.method.choice(),
            shadowgen::MethodChoice::ZpPlus
        );
    }

    #[test]
    fn errors_name_line_and_column_or_field() {
        let e = parse("(\n  scene: Obj(\"a.obj\"),\n  colour: 3,\n)")
            .unwrap_err()
            .to_string();
        assert!(e.contains("test.ron:3:"), "{e}");
        assert!(e.contains("colour"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), resolution: (0, 10))")
            .unwrap_err()
            .to_string();
        assert!(e.contains("resolution"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), version: 2)")
            .unwrap_err()
            .to_string();
        assert!(e.contains("version"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), lights: [Spot(position: (0.0,1.0,0.0), direction: (0.0,0.0,0.0), apex_deg: 30.0)])")
            .unwrap_err()
            .to_string();
        assert!(e.contains("lights[0]") && e.contains("direction"), "{e}");
        let e = parse("(resolution: (10, 10))").unwrap_err().to_string();
        assert!(e.contains("scene"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), pipeline: (stencil: hier))")
            .unwrap_err()
            .to_string();
        assert!(e.contains("hier"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), pipeline: (stencil: h, tile: 12))")
            .unwrap_err()
            .to_string();
        assert!(e.contains("pipeline.tile") && e.contains("12"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), pipeline: (stencil: hybrid, map_size: 5))")
            .unwrap_err()
            .to_string();
        assert!(e.contains("pipeline.map_size"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), pipeline: (counters: bits16))")
            .unwrap_err()
            .to_string();
        assert!(e.contains("bits16"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), pipeline: (reference: (two_sided: true)))")
            .unwrap_err()
            .to_string();
        assert!(e.contains("pipeline.reference.two_sided"), "{e}");
        let e = parse("(scene: Obj(\"a.obj\"), pipelines: [(name: \"a\"), (name: \"a\")])")
            .unwrap_err()
            .to_string();
        assert!(e.contains("pipelines[1].name"), "{e}");
    }

    #[test]
    fn sun_direction_points_down_from_its_azimuth() {
        let l = LightSpec::Sun {
            elevation_deg: 35.0,
            azimuth_deg: 30.0,
        }
        .to_light_static()
        .unwrap()
        .unwrap();
        let Light::Directional { direction } = l else {
            panic!("sun is directional")
        };
        assert!(direction.y < 0.0);
        let toward = -direction;
        assert!((toward.y - 35f64.to_radians().sin()).abs() < 1e-12);
        assert!(toward.x > 0.0 && toward.z < 0.0);
    }
}
