//! One view through the stencil shadow pipeline, timed per stage.
//!
//! `cargo run --release --example shadow_bench -- SCENE CAMERA WxH [--stencil bf|db|h|hybrid]
//! [--scissor on|off] [--method auto|zpass|zfail|zpplus] [--counters 8|wide] [--tile 4|8|16]
//! [--full-shadow on|off] [--map N] [--culling none|frustum|exact|chc] [--two-sided]
//! [--reference] [--mask OUT.png] [--reps R]`
//! (defaults `--tile 8 --counters 8 --map 2048 --full-shadow on`; `--bits` is another
//! name for `--counters`).
//!
//! SCENE is a box-city file (`../shared/data/bench/*.txt`; CAMERA one of its camera
//! names, its light), `city` (the bundled default job's procedural city; CAMERA
//! `street` or `bird`, the first pose of that path; a point light 1.5 scene
//! heights above the ground, as the default job's first light) or any scene file, with `--light x,y,z` (point light) or
//! `--sun dx,dy,dz` (the direction the light travels) and `--eye x,y,z --target
//! x,y,z` (fovy 60° and near 0.1 unless `--fovy`, `--near`; CAMERA may then be `-`).
//!
//! Each repetition runs the whole frame cold: eye pass, silhouettes (fresh cache),
//! volumes, stencil. Prints one JSON line on stdout with the medians over the
//! repetitions of `eye_ms`, `silhouette_ms`, `volume_ms`, `stencil_ms` and
//! `frame_ms` (their sum), `silhouette_cached_ms` (the silhouette stage once more
//! with a warm cache), the counters of the first repetition (`volume_triangles`,
//! `pixels_processed`, `stencil_updates`, `shadowed_pixels`, `h_fragments`,
//! `tile_tests`, `tiles_lit`, `tiles_shadow`, `tiles_boundary`, `bandwidth_bytes`,
//! `pixel_bytes`, `tile_bytes`, `silhouette_pixels`, `map_ms`, `psr`, `psc`,
//! `queries`, `waits`, `light_ms`, ...) and with
//! `--reference` `mismatch_pixels`, `mismatch_off_boundary`, `ambiguous_pixels`.
//! `--mask` writes the raw stencil result as an 8-bit PNG: 255 where the stencil
//! is non-zero on any surface, 0 elsewhere, row 0 at the top. Logs go to stderr.

use anyhow::{bail, Context};
use glam::DVec3;
use scene::load::Loaded;
use scene::{Light, LookAt, Scene};
use shadowcull::config::{CullingSpec, Method, PipelineOptions, StencilBackend, StencilBitsSpec};
use shadowcull::frame::FrameRunner;
use std::path::PathBuf;

const USAGE: &str =
    "usage: shadow_bench SCENE CAMERA WxH [--stencil bf|db|h|hybrid] [--scissor on|off] \
[--method auto|zpass|zfail|zpplus] [--counters 8|wide] [--tile 4|8|16] [--full-shadow on|off] \
[--map N] [--culling none|frustum|exact|chc] [--two-sided] [--reference] [--mask OUT.png] \
[--reps R] [--light x,y,z | --sun dx,dy,dz] [--eye x,y,z --target x,y,z] [--fovy DEG] [--near D]";

struct Args {
    scene: PathBuf,
    camera: String,
    width: u32,
    height: u32,
    pipeline: PipelineOptions,
    reference: bool,
    mask: Option<PathBuf>,
    reps: usize,
    light: Option<Light>,
    eye: Option<DVec3>,
    target: Option<DVec3>,
    fovy: f64,
    near: f64,
}

fn vec3(s: &str, flag: &str) -> anyhow::Result<DVec3> {
    let v: Vec<f64> = s
        .split(',')
        .map(|c| c.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{flag} must look like x,y,z"))?;
    match v[..] {
        [x, y, z] => Ok(DVec3::new(x, y, z)),
        _ => bail!("{flag} must have three components"),
    }
}

fn parse() -> anyhow::Result<Args> {
    let mut it = std::env::args().skip(1);
    let scene = PathBuf::from(it.next().context(USAGE)?);
    let camera = it.next().context(USAGE)?;
    let res = it.next().context(USAGE)?;
    let (w, h) = res
        .split_once('x')
        .context("resolution must look like 1280x1024")?;
    let mut a = Args {
        scene,
        camera,
        width: w.parse().context("width")?,
        height: h.parse().context("height")?,
        pipeline: PipelineOptions {
            reference_every: 0,
            ..Default::default()
        },
        reference: false,
        mask: None,
        reps: 5,
        light: None,
        eye: None,
        target: None,
        fovy: 60.0,
        near: 0.1,
    };
    while let Some(flag) = it.next() {
        match flag.as_str() {
            "--reference" => {
                a.reference = true;
                continue;
            }
            "--two-sided" => {
                a.pipeline.two_sided = true;
                continue;
            }
            _ => {}
        }
        let v = it.next().with_context(|| format!("{flag} needs a value"))?;
        let p = &mut a.pipeline;
        match flag.as_str() {
            "--stencil" => {
                p.stencil = match v.as_str() {
                    "bf" => StencilBackend::Bf,
                    "db" => StencilBackend::Db,
                    "h" => StencilBackend::H,
                    "hybrid" => StencilBackend::Hybrid,
                    _ => bail!("--stencil must be bf, db, h or hybrid"),
                }
            }
            "--tile" => {
                p.tile = match v.as_str() {
                    "4" => 4,
                    "8" => 8,
                    "16" => 16,
                    _ => bail!("--tile must be 4, 8 or 16"),
                }
            }
            "--map" => {
                p.map_size = v.parse().context("--map")?;
                if !(16..=raster::MAX_TARGET_SIZE).contains(&p.map_size) {
                    bail!("--map must lie in 16..={}", raster::MAX_TARGET_SIZE);
                }
            }
            "--culling" => {
                p.culling = match v.as_str() {
                    "none" => CullingSpec::None,
                    "frustum" => CullingSpec::Frustum,
                    "exact" => CullingSpec::Exact,
                    "chc" => CullingSpec::Chc,
                    _ => bail!("--culling must be none, frustum, exact or chc"),
                }
            }
            "--full-shadow" => {
                p.full_shadow = match v.as_str() {
                    "on" => true,
                    "off" => false,
                    _ => bail!("--full-shadow must be on or off"),
                }
            }
            "--scissor" => {
                p.scissor = match v.as_str() {
                    "on" => true,
                    "off" => false,
                    _ => bail!("--scissor must be on or off"),
                }
            }
            "--method" => {
                p.method = match v.as_str() {
                    "auto" => Method::Auto,
                    "zpass" => Method::Zpass,
                    "zfail" => Method::Zfail,
                    "zpplus" => Method::Zpplus,
                    _ => bail!("--method must be auto, zpass, zfail or zpplus"),
                }
            }
            "--counters" | "--bits" => {
                p.counters = match v.as_str() {
                    "8" => StencilBitsSpec::Eight,
                    "wide" => StencilBitsSpec::Wide,
                    _ => bail!("{flag} must be 8 or wide"),
                }
            }
            "--mask" => a.mask = Some(PathBuf::from(v)),
            "--reps" => a.reps = v.parse::<usize>().context("--reps")?.max(1),
            "--light" => {
                a.light = Some(Light::Point {
                    position: vec3(&v, "--light")?,
                    range: None,
                })
            }
            "--sun" => {
                a.light = Some(Light::Directional {
                    direction: vec3(&v, "--sun")?,
                })
            }
            "--eye" => a.eye = Some(vec3(&v, "--eye")?),
            "--target" => a.target = Some(vec3(&v, "--target")?),
            "--fovy" => a.fovy = v.parse().context("--fovy")?,
            "--near" => a.near = v.parse().context("--near")?,
            _ => bail!("unknown flag {flag}\n{USAGE}"),
        }
    }
    Ok(a)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The view and light: from the flags when given, else the scene's named camera and its light.
fn view(a: &Args, loaded: &Loaded) -> anyhow::Result<(LookAt, Light)> {
    let look = match (a.eye, a.target) {
        (Some(eye), Some(target)) => LookAt {
            eye,
            target,
            up: DVec3::Y,
            fov_y_deg: a.fovy,
            near: a.near,
        },
        (None, None) => {
            loaded
                .cameras
                .iter()
                .find(|(n, _)| *n == a.camera)
                .with_context(|| {
                    format!(
                        "no camera named {:?} in {} (give --eye and --target)",
                        a.camera,
                        a.scene.display()
                    )
                })?
                .1
        }
        _ => bail!("--eye and --target go together"),
    };
    let light = match a.light {
        Some(l) => l,
        None => {
            loaded
                .lights
                .first()
                .with_context(|| {
                    format!(
                        "{} names no light (give --light or --sun)",
                        a.scene.display()
                    )
                })?
                .1
        }
    };
    Ok((look, light))
}

fn main() -> anyhow::Result<()> {
    let a = parse()?;
    let loaded = if a.scene.as_os_str() == "city" {
        let mut l = scene::procedural::city::city(&Default::default())?;
        // The default job's views: the first pose of each camera path.
        for (name, path) in l.paths.clone() {
            if let Some(pose) = path.at(0) {
                l.cameras.push((name, pose));
            }
        }
        if l.lights.is_empty() {
            let b = Scene::new(l.graph.clone())?.bounds();
            let light = shadowcull::config::LightSpec::AboveScene(1.5).resolve(
                &l,
                &b,
                0,
                std::path::Path::new("city"),
            )?;
            l.lights.push(("above".into(), light));
        }
        l
    } else {
        scene::load::load_path(&a.scene)?
    };
    let (look, light) = view(&a, &loaded)?;
    let camera = look.camera(a.width as f64 / a.height as f64)?;
    let scene = Scene::new(loaded.graph.clone())?;
    let res = (a.width, a.height);
    let lights = [light];
    eprintln!(
        "shadow_bench: {} objects, {} triangles, {}x{}, {} reps",
        scene.objects().len(),
        scene.counts().drawn_triangles,
        a.width,
        a.height,
        a.reps
    );
    let mut runner = FrameRunner::new(&scene);
    let (mut eye, mut sil, mut vol, mut st, mut frame) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut first = None;
    for rep in 0..a.reps {
        runner.reset_caches();
        let reference = a.reference && rep == 0;
        let mut out = runner.frame(0, &camera, &lights, res, &a.pipeline, reference)?;
        let lf = out.remove(0);
        let s = &lf.row.shadow;
        eye.push(s.eye_ms);
        sil.push(s.silhouette_ms);
        vol.push(s.volume_ms);
        st.push(s.stencil_ms);
        frame.push(lf.row.frame_ms);
        if rep == 0 {
            first = Some(lf);
        }
    }
    // Once more with the warm silhouette cache of the last repetition.
    let warm = runner.frame(0, &camera, &lights, res, &a.pipeline, false)?;
    let lf = first.context("at least one repetition")?;
    if let Some(path) = &a.mask {
        let bytes: Vec<u8> = lf
            .shadow
            .raw_nonzero
            .iter()
            .map(|&s| if s { 255 } else { 0 })
            .collect();
        shadowcull::mask::write_grey_png(path, a.width, a.height, &bytes)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let row = &lf.row;
    let mut line = serde_json::json!({
        "scene": a.scene.display().to_string(),
        "camera": a.camera,
        "width": a.width,
        "height": a.height,
        "reps": a.reps,
        "stencil": match a.pipeline.stencil {
            StencilBackend::Bf => "bf",
            StencilBackend::Db => "db",
            StencilBackend::H => "h",
            StencilBackend::Hybrid => "hybrid",
        },
        "scissor": a.pipeline.scissor,
        "tile": a.pipeline.tile,
        "counters": if a.pipeline.counters == StencilBitsSpec::Wide { "wide" } else { "8" },
        "full_shadow": a.pipeline.full_shadow,
        "map": a.pipeline.map_size,
        "method": format!("{:?}", a.pipeline.method).to_lowercase(),
        "eye_ms": median(&mut eye),
        "silhouette_ms": median(&mut sil),
        "silhouette_cached_ms": warm[0].row.shadow.silhouette_ms,
        "volume_ms": median(&mut vol),
        "stencil_ms": median(&mut st),
        "frame_ms": median(&mut frame),
        "objects": row.scene.objects,
        "triangles": row.scene.triangles,
        "volume_triangles": row.shadow.volume_triangles,
        "silhouette_edges": row.shadow.silhouette_edges,
        "zpass_casters": row.shadow.zpass_casters,
        "zfail_casters": row.shadow.zfail_casters,
        "zpplus_casters": row.shadow.zpplus_casters,
        "pixels_processed": row.shadow.pixels_processed,
        "stencil_updates": row.shadow.stencil_updates,
        "pixels_touched": row.shadow.pixels_touched,
        "shadowed_pixels": row.shadow.shadowed_pixels,
    });
    // The stencil backends' and the culling's counters (a second object: one
    // `json!` this long exceeds the macro's recursion limit).
    let more = serde_json::json!({
        "h_fragments": row.shadow.h_fragments,
        "tile_tests": row.shadow.tile_tests,
        "tiles_lit": row.shadow.tiles_lit,
        "tiles_shadow": row.shadow.tiles_shadow,
        "tiles_boundary": row.shadow.tiles_boundary,
        "bandwidth_bytes": row.shadow.bandwidth_bytes,
        "pixel_bytes": row.shadow.pixel_bytes,
        "tile_bytes": row.shadow.tile_bytes,
        "silhouette_pixels": row.shadow.silhouette_pixels,
        "map_ms": row.shadow.map_ms,
        "culling": format!("{:?}", a.pipeline.culling).to_lowercase(),
        "psr": row.shadow.psr,
        "psc": row.shadow.psc,
        "queries": row.shadow.queries,
        "waits": row.shadow.waits,
        "light_ms": row.shadow.light_ms,
    });
    if let (Some(m), Some(more)) = (line.as_object_mut(), more.as_object()) {
        m.extend(more.clone());
    }
    if a.reference {
        let m = line.as_object_mut().context("json object")?;
        m.insert("mismatch_pixels".into(), row.check.mismatch_pixels.into());
        m.insert(
            "mismatch_off_boundary".into(),
            row.check.mismatch_off_boundary.into(),
        );
        m.insert("ambiguous_pixels".into(), row.check.ambiguous_pixels.into());
        m.insert("reference_ms".into(), row.reference.reference_ms.into());
    }
    println!("{line}");
    Ok(())
}
