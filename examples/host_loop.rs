//! An engine-style loop around [`shadowcull::Pipeline`]: the host owns its
//! vertex and index arrays and its object matrices (about 500 objects of
//! three meshes on a ground plane), uploads them once, and every frame of a
//! camera path hands the pipeline the camera and two lights (a point light
//! and a sun), then reads the potentially shadowed receivers (PSR), per light
//! the potential shadow casters (PSC) and the shadow volumes it would draw.
//!
//! The library glue is the one marked block (begin and end comments). The
//! rest is the host's own world and the checks: every K-th frame the culled
//! pipeline's mask against the ray-cast reference, and every frame against
//! an unculled pipeline on the same frames (conservative culling must not
//! change a pixel).
//!
//! ```sh
//! cargo run --release --example host_loop -- [--frames N] [--reference-every K] [--size WxH]
//! ```
//! prints one JSON line last: `frames`, `objects`, `psr_median`,
//! `psc_median` (summed over lights), `frame_ms_median` (wall time of
//! `Pipeline::frame`, all lights), `mismatch_pixels`,
//! `mismatch_off_boundary`, `culled_vs_unculled_differing_pixels`, …

use glam::{DMat4, DQuat, DVec3};
use shadowcull::mask::compare;
use shadowcull::raster::VolumeMethod;
use shadowcull::scene::{Camera, Light};
use std::sync::Arc;

/// A mesh as a host keeps it: flat positions and a triangle index list.
struct HostMesh {
    positions: Vec<[f32; 3]>,
    indices: Vec<u32>,
}

/// An object as a host keeps it: which mesh, and its world matrix.
struct HostObject {
    mesh: usize,
    world: DMat4,
}

/// What the host took from one frame.
#[derive(Default)]
struct Drawn {
    psr: usize,
    psc: usize,
    volume_triangles: usize,
    non_zpass_ranges: usize,
    frame_ms: f64,
}

// glue:begin
use shadowcull::scene::{Mesh, MeshId, Scene, SceneGraph, Transform};
use shadowcull::{CullingSpec, FrameInput, Pipeline, PipelineOptions, StencilBackend};

/// Uploads the host's arrays once: a scene mesh per host mesh, an instance per object.
fn upload(meshes: &[HostMesh], objects: &[HostObject]) -> shadowcull::Result<Arc<Scene>> {
    let mut graph = SceneGraph::new();
    for m in meshes {
        let positions: Vec<glam::Vec3> = m.positions.iter().map(|&p| p.into()).collect();
        let tris: Vec<[u32; 3]> = m.indices.chunks(3).map(|t| [t[0], t[1], t[2]]).collect();
        graph.add_mesh(Mesh::new("mesh", &positions, &tris)?);
    }
    for o in objects {
        let transform = Transform::Matrix(o.world);
        graph.add_instance("object", MeshId(o.mesh as u32), transform);
    }
    Ok(Arc::new(Scene::new(graph)?))
}

/// Conservative CHC++ from the eye and the lights, volumes for the PSC only. A
/// GPU host chooses `StencilBackend::None`; the CPU stencil is on here so the
/// example can check its masks.
fn pipeline(scene: Arc<Scene>, culling: CullingSpec) -> shadowcull::Result<Pipeline> {
    let stencil = StencilBackend::H;
    Pipeline::new(
        scene,
        PipelineOptions {
            culling,
            stencil,
            ..Default::default()
        },
    )
}

/// One frame: the call, then what a renderer reads to draw its shadows.
fn host_frame(p: &mut Pipeline, input: &FrameInput) -> shadowcull::Result<Drawn> {
    let out = p.frame(input)?;
    let (psr, frame_ms) = (out.psr().len(), out.stats().frame_ms);
    let mut d = Drawn {
        psr,
        frame_ms,
        ..Default::default()
    };
    for light in out.lights() {
        d.psc += light.psc().len();
        let v = light.volumes();
        for r in &v.ranges {
            // Bind r.world_from_local, set the stencil ops of r.method, the
            // scissor and depth bounds, then draw these indices.
            let _triangles = &v.indices[r.indices()];
            d.volume_triangles += r.triangle_count();
            d.non_zpass_ranges += usize::from(r.method != VolumeMethod::ZPass);
        }
    }
    Ok(d)
}
// glue:end

/// Unit cube, 8 corners and 12 outward triangles.
fn cube() -> HostMesh {
    let positions = (0..8)
        .map(|i| {
            [
                (i & 1) as f32 - 0.5,
                ((i >> 1) & 1) as f32,
                ((i >> 2) & 1) as f32 - 0.5,
            ]
        })
        .collect();
    let faces = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    HostMesh {
        positions,
        indices: quads(&faces),
    }
}

/// A square frustum: the cube with its top face narrowed to 60 %.
fn tower() -> HostMesh {
    let mut m = cube();
    for p in m.positions.iter_mut().filter(|p| p[1] == 1.0) {
        p[0] *= 0.6;
        p[2] *= 0.6;
    }
    m
}

/// The ground: one large quad facing up.
fn ground(half: f32) -> HostMesh {
    HostMesh {
        positions: vec![
            [-half, 0.0, -half],
            [-half, 0.0, half],
            [half, 0.0, half],
            [half, 0.0, -half],
        ],
        indices: vec![0, 1, 2, 0, 2, 3],
    }
}

/// Two triangles per quad `[a, b, c, d]` (counter-clockwise seen from outside).
fn quads(faces: &[[u32; 4]]) -> Vec<u32> {
    faces
        .iter()
        .flat_map(|&[a, b, c, d]| [a, b, c, a, c, d])
        .collect()
}

/// A 22 × 23 grid of cubes and towers with pseudo-random sizes and turns
/// (506 objects) plus the ground; streets run along x between the rows.
fn world() -> (Vec<HostMesh>, Vec<HostObject>) {
    let meshes = vec![ground(120.0), cube(), tower()];
    let mut objects = vec![HostObject {
        mesh: 0,
        world: DMat4::IDENTITY,
    }];
    let mut seed = 0x2545_f491_u32;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        f64::from(seed) / f64::from(u32::MAX)
    };
    for i in 0..22 {
        for j in 0..23 {
            let (x, z) = ((i as f64 - 10.5) * 9.0, (j as f64 - 11.0) * 8.0);
            let (w, d, h) = (2.0 + 3.0 * rnd(), 2.0 + 3.0 * rnd(), 2.0 + 14.0 * rnd());
            objects.push(HostObject {
                mesh: 1 + usize::from(rnd() < 0.3),
                world: DMat4::from_scale_rotation_translation(
                    DVec3::new(w, h, d),
                    DQuat::from_rotation_y(rnd() * 0.8),
                    DVec3::new(x, 0.0, z),
                ),
            });
        }
    }
    (meshes, objects)
}

/// The camera of frame `f` of `n`: down a street, rising at the end.
fn camera(f: u32, n: u32, (w, h): (u32, u32)) -> anyhow::Result<Camera> {
    let t = f64::from(f) / f64::from(n.max(2) - 1);
    let eye = DVec3::new(-95.0 + 170.0 * t, 2.0 + 25.0 * t * t, 4.0);
    let target = eye + DVec3::new(1.0, -0.15 - 0.4 * t * t, 0.25 * (6.0 * t).sin());
    Ok(Camera::look_at(
        eye,
        target,
        DVec3::Y,
        60f64.to_radians(),
        f64::from(w) / f64::from(h),
        0.1,
    )?)
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

fn main() -> anyhow::Result<()> {
    let (mut frames, mut every, mut size) = (60u32, 10u32, (320u32, 240u32));
    let args: Vec<String> = std::env::args().skip(1).collect();
    for pair in args.chunks(2) {
        let value = pair.get(1).map(String::as_str).unwrap_or("");
        match pair[0].as_str() {
            "--frames" => frames = value.parse()?,
            "--reference-every" => every = value.parse()?,
            "--size" => {
                let (w, h) = value.split_once('x').ok_or_else(|| anyhow::anyhow!("--size WxH"))?;
                size = (w.parse()?, h.parse()?);
            }
            other => anyhow::bail!("unknown flag {other}; usage: host_loop [--frames N] [--reference-every K] [--size WxH]"),
        }
    }
    let lights = [
        Light::Point {
            position: DVec3::new(15.0, 70.0, -10.0),
            range: None,
        },
        Light::Directional {
            direction: DVec3::new(-0.45, -1.0, -0.3),
        },
    ];
    let (meshes, objects) = world();
    let scene = upload(&meshes, &objects)?;
    let mut culled = pipeline(scene.clone(), CullingSpec::Chcpp)?;
    let mut unculled = pipeline(scene.clone(), CullingSpec::None)?;
    let (mut psr, mut psc, mut ms) = (Vec::new(), Vec::new(), Vec::new());
    let (mut mismatch, mut off_boundary, mut ambiguous, mut compared, mut differing) =
        (0u64, 0u64, 0u64, 0u64, 0u64);
    let (mut volume_triangles, mut zfail_ranges, mut checked) = (0usize, 0usize, 0u32);
    for f in 0..frames {
        let cam = camera(f, frames, size)?;
        let input = FrameInput {
            width: size.0,
            height: size.1,
            camera: cam,
            lights: &lights,
        };
        let d = host_frame(&mut culled, &input)?;
        psr.push(d.psr as f64);
        psc.push(d.psc as f64);
        ms.push(d.frame_ms);
        volume_triangles += d.volume_triangles;
        zfail_ranges += d.non_zpass_ranges;
        let masks: Vec<_> = {
            let out = culled.last_output().expect("a frame ran");
            out.lights().map(|l| l.mask().cloned()).collect()
        };
        // The same frame without culling: conservative culling changes no pixel.
        let plain = unculled.frame(&input)?;
        for (m, p) in masks.iter().zip(plain.lights()) {
            let (m, p) = (m.as_ref().expect("mask"), p.mask().expect("mask"));
            differing += m
                .pixels
                .iter()
                .zip(&p.pixels)
                .filter(|(a, b)| a != b)
                .count() as u64;
        }
        if every > 0 && f % every == 0 {
            checked += 1;
            for (li, m) in masks.iter().enumerate() {
                let r = culled.reference_mask(li)?;
                let c = compare(&r.mask, &r.ambiguous, m.as_ref().expect("mask"));
                mismatch += c.mismatches;
                off_boundary += c.mismatches - c.mismatches_on_boundary;
                ambiguous += c.ambiguous;
                compared += c.compared;
            }
        }
    }
    let line = serde_json::json!({
        "frames": frames,
        "objects": scene.objects().len(),
        "width": size.0,
        "height": size.1,
        "lights": lights.len(),
        "psr_median": median(&mut psr),
        "psc_median": median(&mut psc),
        "frame_ms_median": median(&mut ms),
        "volume_triangles_total": volume_triangles,
        "non_zpass_ranges_total": zfail_ranges,
        "reference_frames": checked,
        "mismatch_pixels": mismatch,
        "mismatch_off_boundary": off_boundary,
        "ambiguous_pixels": ambiguous,
        "compared_pixels": compared,
        "culled_vs_unculled_differing_pixels": differing,
    });
    println!("{line}");
    Ok(())
}
