//! What a deforming mesh costs a host: a 100 × 100 vertex sheet (10,000
//! vertices, 19,602 triangles) waving over a small city (2 × 2 blocks) under
//! a sun, a point light and a spot, at 640×480, CHC++ and the hierarchical
//! stencil (the defaults).
//!
//! ```text
//! cargo run --release --example deform_cost -- [--frames N] [--strided]
//! ```
//!
//! Runs N frames (default 100, after 10 warm-up frames each) with the sheet
//! still, then N with it deforming every frame, and prints one JSON line of
//! medians over the N frames, in milliseconds:
//! - `call_ms`: the edit call, `Pipeline::update_mesh_positions` (with
//!   `--strided`, `Pipeline::update_mesh_strided` over the host's vertex
//!   and index bytes);
//! - `frame_static_ms`, `frame_deforming_ms`: `Pipeline::frame`;
//! - `deform_ms`: `call_ms` plus `frame_deforming_ms − frame_static_ms`;
//! - `baseline_ms`: the work a deformation cannot avoid, timed on the same
//!   frames: copying the positions, refitting their bounds, and extracting
//!   the sheet's silhouette once per light (`shadowgen::silhouette`);
//! - `ratio`: `deform_ms / baseline_ms` (issue 58's budget is 2).

use glam::{DMat4, DVec3, Vec3};
use scene::procedural::city::{city, CityParams};
use scene::{Aabb, Light, Mesh, ObjectFlags, Scene};
use shadowcull::{FrameInput, Pipeline, PipelineOptions};
use std::time::Instant;
use testkit::median;

/// Vertices per side of the sheet.
const SIDE: u32 = 100;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut frames = 100usize;
    let mut strided = false;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--frames" => {
                frames = it
                    .next()
                    .ok_or_else(|| anyhow::anyhow!("--frames needs a value"))?
                    .parse()?
            }
            "--strided" => strided = true,
            other => anyhow::bail!("deform_cost: unknown argument {other}"),
        }
    }
    let loaded = city(&CityParams {
        blocks_x: 2,
        blocks_z: 2,
        ..Default::default()
    })?;
    let scene = Scene::new(loaded.graph)?;
    let b = scene.bounds();
    let centre = ((b.min + b.max) * 0.5).as_dvec3();
    let mut p = Pipeline::new(scene, PipelineOptions::default())?;
    let lights = [
        Light::Directional {
            direction: DVec3::new(0.4, -0.8, 0.3),
        },
        Light::Point {
            position: centre + DVec3::new(3.0, 25.0, 4.0),
            range: None,
        },
        Light::Spot {
            position: centre + DVec3::new(-6.0, 20.0, 8.0),
            direction: DVec3::new(0.3, -1.0, -0.4),
            apex_angle: 80f64.to_radians(),
            range: None,
        },
    ];
    for l in &lights {
        p.add_light(*l)?;
    }
    let triangles = sheet_triangles();
    let mut positions = sheet(0.0);
    let mesh = p.add_mesh(Mesh::new("sheet", &positions, &triangles)?);
    let place = DMat4::from_translation(centre + DVec3::new(0.0, 8.0, 0.0))
        * DMat4::from_scale(DVec3::splat(12.0));
    let object = p.add_object(mesh, place, ObjectFlags::ALL)?;
    let eye = centre + DVec3::new(0.0, 30.0, 45.0);
    let camera = scene::Camera::look_at(eye, centre, DVec3::Y, 60f64.to_radians(), 4.0 / 3.0, 0.5)?;
    let input = FrameInput::new(640, 480, camera);

    let frame_ms = |p: &mut Pipeline| -> anyhow::Result<f64> {
        let t = Instant::now();
        p.frame(&input)?;
        Ok(t.elapsed().as_secs_f64() * 1e3)
    };
    // Still.
    let mut still = Vec::with_capacity(frames);
    for f in 0..10 + frames {
        let ms = frame_ms(&mut p)?;
        if f >= 10 {
            still.push(ms);
        }
    }
    // Deforming: the host computes the new shape (not timed), hands it over
    // (timed), and runs the frame (timed); the baseline's work on the same
    // shape is timed after the frame.
    let (mut call, mut deforming, mut baseline) = (Vec::new(), Vec::new(), Vec::new());
    let mut copy: Vec<Vec3> = Vec::with_capacity(positions.len());
    let mut silhouette = shadowgen::Silhouette::default();
    for f in 0..10 + frames {
        positions = sheet(f as f32 * 0.15);
        let t = Instant::now();
        if strided {
            p.update_mesh_strided(
                mesh,
                scene::StridedPositions::f32(
                    bytemuck::cast_slice(&positions),
                    0,
                    12,
                    positions.len(),
                ),
                scene::Indices::U32(bytemuck::cast_slice(&triangles)),
            )?;
        } else {
            p.update_mesh_positions(mesh, &positions, &triangles)?;
        }
        let c = t.elapsed().as_secs_f64() * 1e3;
        let ms = frame_ms(&mut p)?;
        let t = Instant::now();
        copy.clear();
        copy.extend_from_slice(&positions);
        let bounds = Aabb::from_points(copy.iter().copied());
        for l in &lights {
            shadowgen::silhouette(p.scene(), object, l, false, &mut silhouette);
        }
        let base = t.elapsed().as_secs_f64() * 1e3;
        std::hint::black_box((bounds, silhouette.edge_count()));
        if f >= 10 {
            call.push(c);
            deforming.push(ms);
            baseline.push(base);
        }
    }
    let m = |v: &[f64]| median(v).unwrap_or(f64::NAN);
    let (call, still, deforming, baseline) = (m(&call), m(&still), m(&deforming), m(&baseline));
    let deform = call + deforming - still;
    println!(
        "{}",
        serde_json::json!({
            "vertices": positions.len(),
            "triangles": triangles.len(),
            "frames": frames,
            "strided": strided,
            "call_ms": call,
            "frame_static_ms": still,
            "frame_deforming_ms": deforming,
            "deform_ms": deform,
            "baseline_ms": baseline,
            "ratio": deform / baseline,
        })
    );
    Ok(())
}

/// The sheet's vertices at time `t`: a unit square in x and z, waving in y.
fn sheet(t: f32) -> Vec<Vec3> {
    let n = SIDE as f32 - 1.0;
    (0..SIDE * SIDE)
        .map(|i| {
            let (x, z) = ((i % SIDE) as f32 / n - 0.5, (i / SIDE) as f32 / n - 0.5);
            let y = 0.04 * (9.0 * x + t).sin() * (7.0 * z - 0.7 * t).cos();
            Vec3::new(x, y, z)
        })
        .collect()
}

/// The sheet's triangles, two a grid cell, facing up.
fn sheet_triangles() -> Vec<[u32; 3]> {
    let mut out = Vec::new();
    for j in 0..SIDE - 1 {
        for i in 0..SIDE - 1 {
            let a = j * SIDE + i;
            let (b, c, d) = (a + 1, a + SIDE, a + SIDE + 1);
            out.push([a, c, b]);
            out.push([b, c, d]);
        }
    }
    out
}
