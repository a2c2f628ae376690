//! The engine bench scene: a scene built in code the way an engine client
//! builds one from its own arrays (`shadow_bench engine`; issue 56's
//! budgets and the auto and host-API issues read it).
//!
//! - About 1,500 objects of mixed sizes and about 100k triangles, instanced
//!   from six meshes: a ground slab, 80 buildings (boxes), 60 statues (UV
//!   spheres of 960 triangles), 40 rocks (224), 300 pillars (cylinders of
//!   96), 1,000 crates and 24 vehicles (boxes).
//! - Three lights: a sun, a point light that circles the centre every frame
//!   and a spot light looking down the main street.
//! - Every frame the vehicles drive, two objects are added (debris) and,
//!   from frame 30 on, the two added 30 frames before are removed.
//! - Its camera path `engine` walks down the main street at eye height, then
//!   climbs to look over the roofs, over 90 frames (held after).
//!
//! Everything is a pure function of the frame number and the seed, so a
//! host loop, a test and the bench see the same frames.

use glam::{DMat4, DVec3, Vec3};
use scene::procedural::analytic::{box_corners, box_triangles};
use scene::{CameraPath, Light, LookAt, Mesh, MeshId, SceneGraph, Transform};

/// The frame size the engine scene is measured at.
pub const ENGINE_SIZE: (u32, u32) = (1280, 720);

/// Frames after which an added object is removed again.
pub const DEBRIS_LIFETIME: u32 = 30;

/// Objects added every frame.
pub const DEBRIS_PER_FRAME: u32 = 2;

/// Half the side of the square the scene covers, in metres.
const HALF: f64 = 130.0;

/// The engine scene's meshes, as [`EngineScene::graph`] numbers them.
#[derive(Clone, Copy, Debug)]
pub struct EngineMeshes {
    /// The unit cube `[0, 1]³` (buildings, crates, vehicles, debris: scaled).
    pub cube: MeshId,
    /// A UV sphere of radius 1 with 960 triangles.
    pub statue: MeshId,
    /// A UV sphere of radius 1 with 224 triangles.
    pub rock: MeshId,
    /// A closed cylinder of radius 1 and height 1 with 96 triangles.
    pub pillar: MeshId,
}

/// One object the scene has from the start: its mesh and where it stands.
#[derive(Clone, Copy, Debug)]
pub struct Placement {
    /// Its mesh.
    pub mesh: MeshId,
    /// Its world matrix at frame 0.
    pub world_from_local: DMat4,
}

/// What changes before frame `f` (applied between frame `f − 1` and `f`).
#[derive(Clone, Debug, Default)]
pub struct FrameEdits {
    /// Initial objects (by index into [`EngineScene::objects`]) that move,
    /// with their new world matrices.
    pub moves: Vec<(usize, DMat4)>,
    /// Objects added: a handle (numbered from 0 over the whole run, in the
    /// order they are added), the mesh and the world matrix.
    pub adds: Vec<(u32, MeshId, DMat4)>,
    /// Handles of earlier [`FrameEdits::adds`] removed.
    pub removes: Vec<u32>,
}

/// The engine scene at frame 0 and its per-frame changes.
#[derive(Clone, Debug)]
pub struct EngineScene {
    /// Every mesh, and one instance per initial object, in
    /// [`EngineScene::objects`]' order (so object `i` of the flattened
    /// scene is `objects[i]`).
    pub graph: SceneGraph,
    /// Its meshes.
    pub meshes: EngineMeshes,
    /// The initial objects.
    pub objects: Vec<Placement>,
    /// The vehicles: indices into `objects`, with the lane each drives.
    vehicles: Vec<(usize, Lane)>,
}

/// A vehicle's lane: it drives back and forth along `axis` through `origin`.
#[derive(Clone, Copy, Debug)]
struct Lane {
    origin: DVec3,
    axis: DVec3,
    phase: f64,
    size: DVec3,
}

/// A small deterministic generator (splitmix64) for the layout.
struct Rng(u64);

impl Rng {
    /// Uniform in `[lo, hi)`.
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        let u = (scene::splitmix64(&mut self.0) >> 11) as f64 / (1u64 << 53) as f64;
        lo + (hi - lo) * u
    }
}

/// A UV sphere of radius 1: `rings` latitude bands of `segments` quads, the
/// poles fans: `2·segments·(rings − 1)` triangles, closed and outward-wound.
fn uv_sphere(name: &str, segments: u32, rings: u32) -> Mesh {
    let mut positions = vec![Vec3::Y];
    for r in 1..rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            positions.push(Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                -theta.sin() * phi.sin(),
            ));
        }
    }
    positions.push(-Vec3::Y);
    let bottom = positions.len() as u32 - 1;
    let at = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
    let mut triangles = Vec::new();
    for s in 0..segments {
        triangles.push([0, at(1, s), at(1, s + 1)]);
        triangles.push([bottom, at(rings - 1, s + 1), at(rings - 1, s)]);
    }
    for r in 1..rings - 1 {
        for s in 0..segments {
            let (a, b) = (at(r, s), at(r, s + 1));
            let (c, d) = (at(r + 1, s), at(r + 1, s + 1));
            triangles.push([a, c, d]);
            triangles.push([a, d, b]);
        }
    }
    Mesh::new(name, &positions, &triangles).expect("a valid sphere")
}

/// A closed cylinder of radius 1 from y = 0 to y = 1: `segments` side
/// quads and two capping fans, `4·segments` triangles, outward-wound.
fn cylinder(name: &str, segments: u32) -> Mesh {
    let mut positions = vec![Vec3::ZERO, Vec3::Y];
    for y in [0.0, 1.0] {
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            positions.push(Vec3::new(phi.cos(), y, -phi.sin()));
        }
    }
    let low = |s: u32| 2 + s % segments;
    let high = |s: u32| 2 + segments + s % segments;
    let mut triangles = Vec::new();
    for s in 0..segments {
        triangles.push([0, low(s + 1), low(s)]);
        triangles.push([1, high(s), high(s + 1)]);
        triangles.push([low(s), low(s + 1), high(s + 1)]);
        triangles.push([low(s), high(s + 1), high(s)]);
    }
    Mesh::new(name, &positions, &triangles).expect("a valid cylinder")
}

/// The unit cube `[0, 1]³`.
fn cube() -> Mesh {
    let corners = box_corners(Vec3::ZERO, Vec3::ONE);
    Mesh::new("cube", &corners, &box_triangles()).expect("a valid cube")
}

/// The world matrix of a box of `size` whose floor centre is at `base`.
fn box_at(base: DVec3, size: DVec3) -> DMat4 {
    DMat4::from_translation(base - DVec3::new(size.x, 0.0, size.z) * 0.5) * DMat4::from_scale(size)
}

/// The world matrix of a mesh scaled by `scale` at `position`, turned `yaw`.
fn placed(position: DVec3, yaw: f64, scale: DVec3) -> DMat4 {
    DMat4::from_translation(position) * DMat4::from_rotation_y(yaw) * DMat4::from_scale(scale)
}

/// Side of a city block, street included, in metres.
const CELL: f64 = 20.0;

/// Whether a block is a street crossing: the main street (along x, the
/// camera's) and the cross street (along z) leave theirs free.
fn is_street(i: i32, j: i32) -> bool {
    i == 0 || j == 0
}

impl EngineScene {
    /// The scene with layout seed `seed` (the bench uses 1).
    pub fn new(seed: u64) -> EngineScene {
        let mut rng = Rng(seed);
        let mut graph = SceneGraph::new();
        let meshes = EngineMeshes {
            cube: graph.add_mesh(cube()),
            statue: graph.add_mesh(uv_sphere("statue", 32, 16)),
            rock: graph.add_mesh(uv_sphere("rock", 16, 8)),
            pillar: graph.add_mesh(cylinder("pillar", 24)),
        };
        let mut objects = Vec::new();
        let mut vehicles = Vec::new();
        let mut put = |mesh, m| {
            objects.push(Placement {
                mesh,
                world_from_local: m,
            })
        };
        // The ground: a slab under everything.
        put(
            meshes.cube,
            box_at(
                DVec3::new(0.0, -1.0, 0.0),
                DVec3::new(2.0 * HALF, 1.0, 2.0 * HALF),
            ),
        );
        // Buildings: one per block of an 11 × 11 grid but the streets' and
        // every fifth diagonal's (squares), each leaving a street of at
        // least 4 m around it.
        let blocks = (HALF / CELL) as i32 - 1;
        for i in -blocks..=blocks {
            for j in -blocks..=blocks {
                if is_street(i, j) || (i + j).rem_euclid(5) == 0 {
                    continue;
                }
                let (w, d) = (rng.range(6.0, 16.0), rng.range(6.0, 16.0));
                let h = rng.range(5.0, 40.0);
                let centre = DVec3::new(i as f64 * CELL, 0.0, j as f64 * CELL);
                put(meshes.cube, box_at(centre, DVec3::new(w, h, d)));
            }
        }
        // Props along the streets: a random block, then a point on its
        // street margin (the outer 2 m of the block).
        let street_point = |rng: &mut Rng| {
            let i = rng.range(-blocks as f64, blocks as f64 + 1.0).floor();
            let j = rng.range(-blocks as f64, blocks as f64 + 1.0).floor();
            let (u, v) = (rng.range(-0.5, 0.5), rng.range(8.0, 10.0));
            let side = rng.range(0.0, 4.0) as u32;
            let (x, z) = match side {
                0 => (u * CELL, v),
                1 => (u * CELL, -v),
                2 => (v, u * CELL),
                _ => (-v, u * CELL),
            };
            DVec3::new(i * CELL + x, 0.0, j * CELL + z)
        };
        for _ in 0..60 {
            let p = street_point(&mut rng);
            let r = rng.range(0.6, 1.4);
            put(
                meshes.statue,
                placed(p + DVec3::Y * r, 0.0, DVec3::splat(r)),
            );
        }
        for _ in 0..40 {
            let p = street_point(&mut rng);
            let s = DVec3::new(
                rng.range(0.8, 2.0),
                rng.range(0.5, 1.2),
                rng.range(0.8, 2.0),
            );
            put(meshes.rock, placed(p, rng.range(0.0, 6.3), s));
        }
        for _ in 0..300 {
            let p = street_point(&mut rng);
            let (r, h) = (rng.range(0.15, 0.4), rng.range(2.0, 6.0));
            put(meshes.pillar, placed(p, 0.0, DVec3::new(r, h, r)));
        }
        for _ in 0..1000 {
            let p = street_point(&mut rng);
            let s = DVec3::splat(rng.range(0.4, 1.2));
            put(
                meshes.cube,
                placed(p, rng.range(0.0, 6.3), s)
                    * DMat4::from_translation(DVec3::splat(-0.5) + DVec3::Y * 0.5),
            );
        }
        // Vehicles: 12 on the main street, 12 on the cross street.
        for k in 0..24 {
            let along_x = k < 12;
            let offset = if k % 2 == 0 { 2.5 } else { -2.5 };
            let (origin, axis) = if along_x {
                (DVec3::new(0.0, 0.0, offset), DVec3::X)
            } else {
                (DVec3::new(offset, 0.0, 0.0), DVec3::Z)
            };
            let size = DVec3::new(4.0, 1.6, 1.9);
            let lane = Lane {
                origin,
                axis,
                phase: k as f64 * 0.7,
                size,
            };
            let index = objects.len();
            objects.push(Placement {
                mesh: meshes.cube,
                world_from_local: lane.at(0),
            });
            vehicles.push((index, lane));
        }
        for (k, o) in objects.iter().enumerate() {
            graph.add_instance(
                &format!("object{k}"),
                o.mesh,
                Transform::Matrix(o.world_from_local),
            );
        }
        EngineScene {
            graph,
            meshes,
            objects,
            vehicles,
        }
    }

    /// The three lights at frame `f`: the sun, the circling point light and
    /// the spot, in that order.
    pub fn lights(&self, f: u32) -> [Light; 3] {
        let a = (f as f64 * 2.0).to_radians();
        [
            Light::Directional {
                direction: DVec3::new(0.45, -1.0, 0.3),
            },
            Light::Point {
                position: DVec3::new(50.0 * a.cos(), 25.0, 50.0 * a.sin()),
                range: Some(120.0),
            },
            Light::Spot {
                position: DVec3::new(-70.0, 30.0, 0.0),
                direction: DVec3::new(1.0, -0.6, 0.05),
                apex_angle: 0.9,
                range: Some(200.0),
            },
        ]
    }

    /// The camera path `engine`: down the main street at eye height, then
    /// up over the roofs (frames 0–90, held after).
    pub fn path() -> CameraPath {
        let pose = |eye: DVec3, target: DVec3| LookAt {
            eye,
            target,
            up: DVec3::Y,
            fov_y_deg: 60.0,
            near: 0.1,
        };
        CameraPath::Keyframes(vec![
            (
                0.0,
                pose(DVec3::new(-110.0, 1.8, 1.0), DVec3::new(-80.0, 1.8, 1.0)),
            ),
            (
                40.0,
                pose(DVec3::new(-10.0, 1.8, 1.0), DVec3::new(20.0, 2.5, 6.0)),
            ),
            (
                60.0,
                pose(DVec3::new(20.0, 12.0, 10.0), DVec3::new(60.0, 0.0, 40.0)),
            ),
            (
                90.0,
                pose(DVec3::new(60.0, 45.0, 60.0), DVec3::new(0.0, 0.0, 0.0)),
            ),
        ])
    }

    /// What changes before frame `f` (nothing before frame 0).
    pub fn edits(&self, f: u32) -> FrameEdits {
        if f == 0 {
            return FrameEdits::default();
        }
        let moves = (self.vehicles.iter())
            .map(|(i, lane)| (*i, lane.at(f)))
            .collect();
        let mut rng = Rng(0x5eed ^ u64::from(f));
        let adds = (0..DEBRIS_PER_FRAME)
            .map(|k| {
                let handle = (f - 1) * DEBRIS_PER_FRAME + k;
                let p = DVec3::new(
                    rng.range(-HALF, HALF),
                    rng.range(0.0, 3.0),
                    rng.range(-8.0, 8.0),
                );
                let s = DVec3::splat(rng.range(0.3, 0.9));
                (handle, self.meshes.cube, placed(p, rng.range(0.0, 6.3), s))
            })
            .collect();
        let removes = match f.checked_sub(DEBRIS_LIFETIME) {
            Some(g) if g >= 1 => ((g - 1) * DEBRIS_PER_FRAME..g * DEBRIS_PER_FRAME).collect(),
            _ => Vec::new(),
        };
        FrameEdits {
            moves,
            adds,
            removes,
        }
    }
}

impl Lane {
    /// The vehicle's world matrix at frame `f`: back and forth over ±100 m.
    fn at(&self, f: u32) -> DMat4 {
        let t = f as f64 * 0.04 + self.phase;
        let p = self.origin + self.axis * (100.0 * t.sin());
        let yaw = if self.axis == DVec3::X {
            0.0
        } else {
            std::f64::consts::FRAC_PI_2
        };
        DMat4::from_translation(p) * DMat4::from_rotation_y(yaw) * box_at(DVec3::ZERO, self.size)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_engine_scene_has_its_size_and_its_edits_balance() {
        let e = EngineScene::new(1);
        let s = scene::Scene::new(e.graph.clone()).unwrap();
        let c = s.counts();
        assert!((1_400..=1_600).contains(&c.objects), "{c:?}");
        assert!((90_000..=115_000).contains(&c.triangles), "{c:?}");
        assert_eq!(c.objects, e.objects.len());
        for m in [
            e.meshes.cube,
            e.meshes.statue,
            e.meshes.rock,
            e.meshes.pillar,
        ] {
            let mesh = &s.graph().meshes()[m.index()];
            assert!(mesh.solid().is_some(), "{} is closed", mesh.name());
        }
        let (mut alive, mut seen) = (std::collections::BTreeSet::new(), 0);
        for f in 0..=80 {
            let ed = e.edits(f);
            assert_eq!(ed.moves.len(), if f == 0 { 0 } else { 24 });
            for (h, _, m) in &ed.adds {
                assert!(m.is_finite());
                assert!(alive.insert(*h), "handle {h} added once");
                seen += 1;
            }
            for h in &ed.removes {
                assert!(alive.remove(h), "handle {h} removed after it was added");
            }
        }
        assert_eq!(seen, 80 * DEBRIS_PER_FRAME);
        assert_eq!(alive.len() as u32, DEBRIS_LIFETIME * DEBRIS_PER_FRAME);
        let light = e.lights(5);
        assert_ne!(light[1], e.lights(6)[1], "the point light moves");
        for l in light {
            l.validate().unwrap();
        }
        assert!(EngineScene::path().at(60).is_some());
    }
}
