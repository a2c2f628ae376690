//! The fuzz targets' code, one module per target, each a `run(&[u8])` that
//! panics on a finding. Two builds call it:
//! - `fuzz/fuzz_targets/*.rs`: cargo-fuzz's libFuzzer binaries (nightly,
//!   coverage-guided, AddressSanitizer), one line each around `run`;
//! - `fuzz_replay` (this crate's binary, any toolchain): replays the
//!   committed inputs of every target (`fuzz/regressions/TARGET` and
//!   `fuzz/corpus-min/TARGET`) or the files it is given; `cargo test` runs
//!   it over all of them (`tests/replay.rs`).
//!
//! `fuzz/HOURS.md` has the campaigns and findings, `scripts/fuzz_campaign.sh`
//! runs one.
//!
//! Below: reading the fuzzer's bytes as values, and the small box scenes the
//! differential targets share.

pub mod box_city;
pub mod c_abi;
pub mod gltf;
pub mod job;
pub mod light_views;
pub mod obj;
pub mod pipeline;
pub mod raster;
pub mod shards;
pub mod volumes;

/// A fuzz target: its name (as `fuzz/fuzz_targets` and
/// `scripts/fuzz_campaign.sh` name it) and its code.
pub struct Target {
    /// The target's name.
    pub name: &'static str,
    /// One input through the target; a panic is a finding.
    pub run: fn(&[u8]),
}

/// Every target.
pub const TARGETS: [Target; 10] = [
    Target {
        name: "gltf",
        run: gltf::run,
    },
    Target {
        name: "obj",
        run: obj::run,
    },
    Target {
        name: "box_city",
        run: box_city::run,
    },
    Target {
        name: "job",
        run: job::run,
    },
    Target {
        name: "raster",
        run: raster::run,
    },
    Target {
        name: "volumes",
        run: volumes::run,
    },
    Target {
        name: "light_views",
        run: light_views::run,
    },
    Target {
        name: "pipeline",
        run: pipeline::run,
    },
    Target {
        name: "shards",
        run: shards::run,
    },
    Target {
        name: "c_abi",
        run: c_abi::run,
    },
];

/// The fuzzer's bytes read as values, front to back; zeros past the end, so
/// that every input, however short, is a complete case.
pub struct Bytes<'a>(pub &'a [u8]);

impl Bytes<'_> {
    /// The next byte.
    pub fn u8(&mut self) -> u8 {
        let (b, rest) = self.0.split_first().map_or((0, &[][..]), |(b, r)| (*b, r));
        self.0 = rest;
        b
    }

    /// The next four bytes, little-endian.
    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }

    /// The next two bytes as a fraction in [0, 1].
    pub fn unit(&mut self) -> f64 {
        f64::from(u16::from_le_bytes([self.u8(), self.u8()])) / 65535.0
    }

    /// Any f32 bit pattern (NaN, ±∞, subnormals, huge).
    pub fn any_f32(&mut self) -> f32 {
        f32::from_bits(self.u32())
    }

    /// Any f64 bit pattern.
    pub fn any_f64(&mut self) -> f64 {
        f64::from_bits(u64::from(self.u32()) | (u64::from(self.u32()) << 32))
    }

    /// A small signed value in steps of `step` (−128·step ..= 127·step).
    pub fn small(&mut self, step: f32) -> f32 {
        f32::from(self.u8() as i8) * step
    }
}

use glam::{DMat4, DQuat, DVec3, Vec3};
use shadowcull::scene::{Light, Mesh, Scene, SceneGraph, Transform};

/// The unit box [0, 1]³.
fn unit_box() -> Mesh {
    let p: Vec<Vec3> = (0..8)
        .map(|c| Vec3::new((c & 1) as f32, ((c >> 1) & 1) as f32, ((c >> 2) & 1) as f32))
        .collect();
    let tris = shadowcull::raster::AABB_TRIANGLES;
    Mesh::new("box", &p, &tris).expect("a unit box")
}

/// A point of the cube [−scale, scale]³.
pub fn point(b: &mut Bytes, scale: f64) -> DVec3 {
    (DVec3::new(b.unit(), b.unit(), b.unit()) * 2.0 - 1.0) * scale
}

/// A small scene and a light from the bytes: a 20 × 20 ground slab and up
/// to six boxes of any size and turn above it; a sun, point or spot light
/// above them. `None` when the bytes make an invalid light.
pub fn box_scene(b: &mut Bytes) -> Option<(Scene, Light)> {
    let mut g = SceneGraph::new();
    let cube = g.add_mesh(unit_box());
    let ground = DMat4::from_scale_rotation_translation(
        DVec3::new(20.0, 0.01, 20.0),
        DQuat::IDENTITY,
        DVec3::new(-10.0, -0.01, -10.0),
    );
    g.add_instance("ground", cube, Transform::Matrix(ground));
    for k in 0..b.u8() % 7 {
        let size = DVec3::new(b.unit(), b.unit(), b.unit()) * 3.0 + 0.05;
        let at = point(b, 6.0) + DVec3::Y * 6.0;
        let turn = DQuat::from_rotation_y(b.unit() * std::f64::consts::TAU);
        let m = DMat4::from_scale_rotation_translation(size, turn, at);
        g.add_instance(&format!("box{k}"), cube, Transform::Matrix(m));
    }
    let scene = Scene::new(g).ok()?;
    let light = match b.u8() % 3 {
        0 => Light::Directional {
            direction: point(b, 1.0) - DVec3::Y,
        },
        1 => Light::Point {
            position: point(b, 12.0) + DVec3::Y * 8.0,
            range: None,
        },
        _ => Light::Spot {
            position: point(b, 12.0) + DVec3::Y * 8.0,
            direction: point(b, 1.0) - DVec3::Y,
            apex_angle: 0.2 + 2.5 * b.unit(),
            range: None,
        },
    };
    light.validate().ok()?;
    Some((scene, light))
}
