//! Computes the exact shadow mask of a small scene built in code and writes it
//! as a PNG: the smallest use of the library.
//!
//! `cargo run --example reference_mask -- [OUT.png]`

use glam::{DVec3, Vec3};
use scene::{Camera, Light, Mesh, Scene, SceneGraph, Transform};
use shadowcull::reference::{reference_mask, ReferenceOptions, TriangleBvh};
use std::path::PathBuf;

/// The command line.
#[derive(clap::Parser)]
#[command(
    about = "Computes the exact shadow mask of a small scene built in code and writes it as a PNG"
)]
struct Cli {
    /// Where to write the mask.
    #[arg(value_name = "OUT.png", default_value = "reference_mask.png")]
    out: PathBuf,
}

fn main() -> anyhow::Result<()> {
    let Cli { out } = <Cli as clap::Parser>::parse();
    // A ground quad facing up and a box floating above it.
    let mut graph = SceneGraph::new();
    let ground = Mesh::new(
        "ground",
        &[
            Vec3::new(-10.0, 0.0, -10.0),
            Vec3::new(-10.0, 0.0, 10.0),
            Vec3::new(10.0, 0.0, 10.0),
            Vec3::new(10.0, 0.0, -10.0),
        ],
        &[[0, 1, 2], [0, 2, 3]],
    )?;
    let ground = graph.add_mesh(ground);
    graph.add_instance("ground", ground, Transform::default());
    let cube = graph.add_mesh(scene::procedural::analytic::box_mesh(
        "box",
        Vec3::splat(-0.5),
        Vec3::splat(0.5),
    )?);
    graph.add_instance(
        "box",
        cube,
        Transform::translation(DVec3::new(0.0, 1.5, 0.0)),
    );
    let scene = Scene::new(graph)?;

    let camera = Camera::look_at(
        DVec3::new(0.0, 5.0, 8.0),
        DVec3::ZERO,
        DVec3::Y,
        60f64.to_radians(),
        4.0 / 3.0,
        0.1,
    )?;
    let light = Light::Point {
        position: DVec3::new(2.0, 6.0, 1.0),
        range: None,
    };
    light.validate()?;

    let bvh = TriangleBvh::new(&scene);
    let r = reference_mask(
        &bvh,
        &camera,
        &light,
        320,
        240,
        &ReferenceOptions::default(),
        None,
    );
    r.mask.write_png(&out)?;
    println!("{}: {:?}", out.display(), r.counts);
    Ok(())
}
