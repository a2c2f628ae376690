//! A job resolved against its scene: the scene loaded (or generated) and
//! flattened, its camera path and its lights.

use super::schema::{CameraSpec, Job, LightSpec, SceneSpec};
use crate::{Error, Result};
use glam::{DVec3, Vec3};
use scene::load::Loaded;
use scene::{CameraPath, Light, LookAt, Mesh, Scene, SceneGraph, Transform};
use std::path::{Path, PathBuf};

impl LightSpec {
    /// The light, when it does not depend on the scene.
    pub(super) fn to_light_static(&self) -> std::result::Result<Option<Light>, ()> {
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
    #[allow(unused)]
    let disabled = |p: &PathBuf, feature: &str| Error::Job {
        file: abs(p),
        location: "scene".into(),
        message: format!("this build has no `{feature}` loader (cargo feature `{feature}`)"),
    };
    Ok(match spec {
        #[cfg(feature = "gltf")]
        SceneSpec::Gltf(p) => Loaded::from_graph(scene::load::gltf::load_gltf(&abs(p))?),
        #[cfg(not(feature = "gltf"))]
        SceneSpec::Gltf(p) => return Err(disabled(p, "gltf")),
        #[cfg(not(feature = "obj"))]
        SceneSpec::Obj(p) => return Err(disabled(p, "obj")),
        #[cfg(feature = "obj")]
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
        SceneSpec::Merged(inner) => {
            let mut loaded = load_scene(inner, base)?;
            loaded.graph = merged_graph(std::mem::take(&mut loaded.graph))?;
            loaded
        }
    })
}

/// `graph`'s objects baked into one mesh at the identity transform:
/// vertices in world space (f32), mirrored objects' triangles rewound so
/// that world-space facing is kept. The warnings carry over.
///
/// # Errors
/// A graph that does not flatten, or more vertices than 32-bit indices hold.
fn merged_graph(graph: SceneGraph) -> Result<SceneGraph> {
    let scene = Scene::new(graph)?;
    let meshes = scene.graph().meshes();
    let (mut positions, mut triangles) = (Vec::new(), Vec::new());
    for o in scene.objects() {
        let mesh = &meshes[o.mesh.index()];
        let first = u32::try_from(positions.len())
            .ok()
            .filter(|f| f.checked_add(mesh.positions().len() as u32).is_some())
            .ok_or_else(|| Error::Options {
                field: "scene".into(),
                message: "Merged: more vertices than 32-bit indices hold".into(),
            })?;
        let m = o.world_from_local;
        positions.extend(
            mesh.positions()
                .iter()
                .map(|p| m.transform_point3(p.as_dvec3()).as_vec3()),
        );
        triangles.extend(mesh.triangles().iter().map(|t| {
            let [a, b, c] = t.map(|i| i + first);
            if o.mirrored {
                [a, c, b]
            } else {
                [a, b, c]
            }
        }));
    }
    let mut merged = SceneGraph::new();
    for w in scene.warnings() {
        merged.warn(w.clone());
    }
    let mesh = merged.add_mesh(Mesh::new("merged", &positions, &triangles)?);
    merged.add_instance("merged", mesh, Transform::default());
    Ok(merged)
}

/// Loads the job's scene (with its optional ground quad) and flattens it.
/// The graph moves into the [`Scene`] (read it there, [`Scene::graph`]):
/// the returned [`Loaded`] keeps the cameras, paths and lights, with an
/// empty graph, so the job holds its geometry once.
///
/// # Errors
/// Loader and graph errors, naming the file.
pub fn prepare_scene(job: &Job, base: &Path) -> Result<(Loaded, Scene)> {
    let mut loaded = load_scene(&job.scene, base)?;
    if let Some(g) = job.ground {
        // Bounds before the ground, to centre it under the scene.
        let probe = Scene::new(loaded.graph.clone())?;
        let c = if probe.bounds().is_empty() {
            DVec3::ZERO
        } else {
            probe.bounds().center()
        };
        let h = g.size * 0.5;
        let quad = Mesh::new(
            "ground",
            &[
                Vec3::new(-h, 0.0, -h),
                Vec3::new(-h, 0.0, h),
                Vec3::new(h, 0.0, h),
                Vec3::new(h, 0.0, -h),
            ],
            &[[0, 1, 2], [0, 2, 3]],
        )?;
        let m = loaded.graph.add_mesh(quad);
        loaded.graph.add_instance(
            "ground",
            m,
            Transform::translation(DVec3::new(c.x, g.y as f64, c.z)),
        );
    }
    let scene = Scene::new(std::mem::take(&mut loaded.graph))?;
    Ok((loaded, scene))
}

/// Loads `job`'s scene (paths relative to `job_file`'s directory) and
/// resolves its camera path.
///
/// # Errors
/// Loader, graph and camera errors, naming the file or job field.
pub fn load_scene_for_job(
    job: &Job,
    job_file: Option<&Path>,
) -> Result<(Loaded, Scene, scene::CameraPath)> {
    let base = job_file.and_then(Path::parent).unwrap_or(Path::new("."));
    let file = job_file.unwrap_or(Path::new("<default job>"));
    let (loaded, scene) = prepare_scene(job, base)?;
    if scene.counts().triangles == 0 {
        // Say so here, not later as an empty camera or light: `/dev/null`
        // or `/etc/passwd` as an OBJ load fine and hold nothing.
        let said = scene
            .warnings()
            .first()
            .map(|w| format!("; the loader said: {w}"))
            .unwrap_or_default();
        return Err(Error::Job {
            file: file.to_path_buf(),
            location: "scene".into(),
            message: format!(
                "{} holds no geometry (no triangles): check the path and the format{said}",
                describe_scene(&job.scene)
            ),
        });
    }
    let path = resolve_camera(&job.camera, &loaded, &scene.bounds(), file)?;
    Ok((loaded, scene, path))
}

/// The scene's sources as a job names them.
fn describe_scene(spec: &SceneSpec) -> String {
    match spec {
        SceneSpec::Gltf(p) | SceneSpec::Obj(p) | SceneSpec::BoxCity(p) => p.display().to_string(),
        SceneSpec::City(_) => "the procedural city".into(),
        SceneSpec::Group(v) if v.is_empty() => "an empty Group([])".into(),
        SceneSpec::Group(v) => v.iter().map(describe_scene).collect::<Vec<_>>().join(" + "),
        SceneSpec::Merged(inner) => format!("{} (merged)", describe_scene(inner)),
    }
}

/// The job's lights: its `lights`, else the scene's named lights, else one
/// point light above the scene.
///
/// # Errors
/// A light that fails validation or names a missing scene light.
pub fn resolve_lights(
    job: &Job,
    loaded: &Loaded,
    bounds: &scene::Aabb,
    file: &Path,
) -> Result<Vec<Light>> {
    if !job.lights.is_empty() {
        return job
            .lights
            .iter()
            .enumerate()
            .map(|(i, l)| l.resolve(loaded, bounds, i, file))
            .collect();
    }
    if loaded.lights.is_empty() {
        Ok(vec![
            LightSpec::AboveScene(1.5).resolve(loaded, bounds, 0, file)?
        ])
    } else {
        Ok(loaded.lights.iter().map(|(_, l)| *l).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
