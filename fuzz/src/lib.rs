//! What the fuzz targets share: reading the fuzzer's bytes as values.

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
