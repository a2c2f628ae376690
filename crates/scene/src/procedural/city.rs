//! Procedural city: a seeded, deterministic stand-in for the city scene of
//! [Steiner ch. 5] (Fig. 4.1: "17,420 individual geometric objects, some of
//! which are instantiated for multiple use … 1,033,002 triangles"), the
//! *complex* scene the thesis is about — a flat, very wide scene graph of
//! many small objects, not a few big ones.
//!
//! # Layout
//! The city is centred on the origin, +y up, metres. A grid of
//! `blocks_x × blocks_z` cells of side `pitch = block_size + street_width`;
//! each cell holds a square block with half a street on every side, so the
//! streets run along the cell borders (the central street along x = 0 when
//! `blocks_x` is even). Per cell, in object order:
//! 1. one ground tile covering the whole cell (an up-facing quad at y = 0,
//!    world coordinates; the tiles meet edge to edge and are the only open
//!    meshes);
//! 2. buildings: the block minus a `sidewalk` ring is cut into
//!    `lots_per_side²` lots, each holding a building with probability
//!    `building_density`; footprints and heights are multiples of 0.25 m
//!    (exact in f32), at least 0.25 m inside the lot, taller towards the city
//!    centre. Most are boxes (12 triangles); some carry a roof structure
//!    (28), a hip roof (14) or are stepped towers of 2–3 tiers (28/44). Every
//!    building is one closed, consistently wound mesh (tiers joined by a
//!    ring, not overlapping boxes), local to its footprint corner and placed
//!    by a translation;
//! 3. trees along the sidewalk: instances (random heading, scale 0.8–1.2) of
//!    one shared mesh — an octagonal trunk and a faceted ellipsoid crown,
//!    316 triangles at the default resolution, most of the triangle budget;
//! 4. lamp posts at the kerb: instances of one shared 44-triangle mesh, the
//!    arm pointing over the street.
//!
//! # Defaults and Steiner ch. 5
//! The defaults (see [`CityParams::default`]) give 20 × 20 blocks of 84 m
//! with 16 m streets (a 2 km square), 36 lots per block at 85 % density
//! (≈ 12,200 buildings), 6 trees and 6 lamp posts per block and 400 ground
//! tiles: ≈ 17,400 objects and ≈ 1.05 M triangles, matching the thesis's
//! 17,420 objects and 1,033,002 triangles, with the same character — many
//! small objects and instanced street furniture (the thesis names trees and
//! traffic lights). The thesis gives no street plan, so the plan here is a
//! regular grid.
//!
//! # Cameras, paths, lights
//! `street`: eye at 1.7 m in the street along x = −W/2 + ⌊blocks_x/2⌋·pitch,
//! starting a quarter street width inside the city's +z edge, looking and
//! walking toward −z at 1 m per frame ([`CameraPath::Dolly`]). `bird`: looking
//! down 35° at the city centre from a horizontal distance of 0.75 × the larger
//! city side, orbiting the vertical axis through the centre at 1° per frame
//! ([`CameraPath::Orbit`]). Cameras `street` and `bird` are the paths' frame-0
//! poses. Lights: `light`, a point light high above the city, off centre, and
//! `sun`, a directional light.
//!
//! Determinism: every block draws from its own generator, seeded from
//! `(seed, block x, block z)` with splitmix64, so the same parameters give
//! the same scene bit for bit on every platform.

use super::analytic::horizontal_quad;
use super::city_meshes::{
    building_mesh, lamp_mesh, tree_mesh, Tier, CROWN_RY, CROWN_Y, LAMP_HEIGHT,
};
use crate::loaded::Loaded;
use crate::{
    splitmix64, CameraPath, Error, Light, LookAt, MeshId, Result, SceneGraph, Transform,
    MAX_OBJECTS,
};
use glam::{DQuat, DVec3};
use std::f64::consts::TAU;
use std::path::PathBuf;

/// The `file` that parameter errors name.
pub const CITY_FILE: &str = "<procedural city>";

/// Eye height of the `street` camera, metres.
pub const STREET_EYE_HEIGHT: f64 = 1.7;
/// How far the `street` camera moves per frame (toward −z), metres.
pub const STREET_METRES_PER_FRAME: f64 = 1.0;
/// How far the `bird` camera looks down, degrees below the horizon.
pub const BIRD_PITCH_DEG: f64 = 35.0;
/// How far the `bird` camera turns per frame, degrees.
pub const BIRD_DEGREES_PER_FRAME: f64 = 1.0;

/// Largest per-instance tree scale (the smallest is 0.8).
const TREE_SCALE_MAX: f64 = 1.2;
/// Distance of lamp posts from the block edge, metres.
const LAMP_INSET: f64 = 0.6;
/// Triangles of a block's ground tile.
const TILE_TRIANGLES_MAX: u64 = 2;
/// The most triangles a building has: three tiers of sides and rings and a
/// roof (checked against generated cities in the tests).
const BUILDING_TRIANGLES_MAX: u64 = 64;

/// Parameters of [`city`]. Lengths in metres; every field has a default, so a
/// RON/JSON job may name only what it changes (unknown fields are an error).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CityParams {
    /// Seed of the generator; the same seed gives the same city. Default 1.
    pub seed: u64,
    /// Blocks along x, 1..=1024. Default 20.
    pub blocks_x: u32,
    /// Blocks along z, 1..=1024. Default 20.
    pub blocks_z: u32,
    /// Side of a square block (buildings and sidewalk), > 0. Default 84.
    pub block_size: f64,
    /// Width of the streets between blocks, > 0. Default 16.
    pub street_width: f64,
    /// Ring along the block edge kept free of buildings (trees and lamps stand
    /// in it), ≥ 0 and < block_size / 2. Default 5.
    pub sidewalk: f64,
    /// Lots per block side, 1..=64; a lot must be at least 2 m wide. Default 6.
    pub lots_per_side: u32,
    /// Probability that a lot holds a building, in \[0, 1\]. Default 0.85.
    pub building_density: f64,
    /// Smallest footprint side as a fraction of the lot side, in (0, 1]. Default 0.55.
    pub footprint_min: f64,
    /// Largest footprint side as a fraction of the lot side, in
    /// \[footprint_min, 1\]. Default 0.95.
    pub footprint_max: f64,
    /// Lowest building, ≥ 1 m. Default 6.
    pub height_min: f64,
    /// Highest building including roof structures, ≥ height_min, ≤ 10 km. Default 80.
    pub height_max: f64,
    /// Fraction of buildings built as stepped towers (2–3 tiers). Default 0.06.
    pub tower_fraction: f64,
    /// Fraction with a box-shaped roof structure (a lift housing). Default 0.12.
    pub roof_structure_fraction: f64,
    /// Fraction with a hip roof. The three fractions sum to at most 1. Default 0.12.
    pub hip_roof_fraction: f64,
    /// Trees per block, ≤ 1000. Default 6.
    pub trees_per_block: u32,
    /// Lamp posts per block, ≤ 1000. Default 6.
    pub lamps_per_block: u32,
    /// Segments around a tree crown, 3..=256. Default 16.
    pub tree_segments: u32,
    /// Rings from pole to pole of a tree crown, 2..=256; a tree has
    /// `2·segments·(rings − 1) + 28` triangles. Default 10 (316 triangles).
    pub tree_rings: u32,
}

impl Default for CityParams {
    /// Steiner's city in size: ≈ 17,400 objects, ≈ 1.05 M triangles (see the module doc).
    fn default() -> Self {
        CityParams {
            seed: 1,
            blocks_x: 20,
            blocks_z: 20,
            block_size: 84.0,
            street_width: 16.0,
            sidewalk: 5.0,
            lots_per_side: 6,
            building_density: 0.85,
            footprint_min: 0.55,
            footprint_max: 0.95,
            height_min: 6.0,
            height_max: 80.0,
            tower_fraction: 0.06,
            roof_structure_fraction: 0.12,
            hip_roof_fraction: 0.12,
            trees_per_block: 6,
            lamps_per_block: 6,
            tree_segments: 16,
            tree_rings: 10,
        }
    }
}

fn bad(field: &str, message: impl Into<String>) -> Error {
    Error::Load {
        file: PathBuf::from(CITY_FILE),
        element: field.into(),
        message: message.into(),
    }
}

fn check_range(field: &str, v: f64, lo: f64, hi: f64, lo_open: bool) -> Result<()> {
    let ok = v.is_finite() && (if lo_open { v > lo } else { v >= lo }) && v <= hi;
    if ok {
        Ok(())
    } else {
        let open = if lo_open { "(" } else { "[" };
        Err(bad(
            field,
            format!("must lie in {open}{lo}, {hi}], got {v}"),
        ))
    }
}

fn check_count(field: &str, v: u32, lo: u32, hi: u32) -> Result<()> {
    if (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(bad(field, format!("must lie in {lo}..={hi}, got {v}")))
    }
}

impl CityParams {
    /// Checks every field against the ranges documented on it.
    ///
    /// # Errors
    /// [`Error::Load`] with file [`CITY_FILE`] and the field's name as element.
    pub fn validate(&self) -> Result<()> {
        check_count("blocks_x", self.blocks_x, 1, 1024)?;
        check_count("blocks_z", self.blocks_z, 1, 1024)?;
        check_range("block_size", self.block_size, 0.0, 10_000.0, true)?;
        check_range("street_width", self.street_width, 0.0, 10_000.0, true)?;
        check_range("sidewalk", self.sidewalk, 0.0, 10_000.0, false)?;
        if 2.0 * self.sidewalk >= self.block_size {
            return Err(bad("sidewalk", "must be less than half the block size"));
        }
        check_count("lots_per_side", self.lots_per_side, 1, 64)?;
        if self.lot_side() < 2.0 {
            return Err(bad(
                "lots_per_side",
                format!(
                    "lots would be {} m wide; at least 2 m needed",
                    self.lot_side()
                ),
            ));
        }
        check_range("building_density", self.building_density, 0.0, 1.0, false)?;
        check_range("footprint_min", self.footprint_min, 0.0, 1.0, true)?;
        check_range(
            "footprint_max",
            self.footprint_max,
            self.footprint_min,
            1.0,
            false,
        )?;
        check_range("height_min", self.height_min, 1.0, 10_000.0, false)?;
        check_range(
            "height_max",
            self.height_max,
            self.height_min,
            10_000.0,
            false,
        )?;
        check_range("tower_fraction", self.tower_fraction, 0.0, 1.0, false)?;
        check_range(
            "roof_structure_fraction",
            self.roof_structure_fraction,
            0.0,
            1.0,
            false,
        )?;
        check_range("hip_roof_fraction", self.hip_roof_fraction, 0.0, 1.0, false)?;
        if self.tower_fraction + self.roof_structure_fraction + self.hip_roof_fraction > 1.0 {
            return Err(bad(
                "hip_roof_fraction",
                "tower, roof-structure and hip-roof fractions must sum to at most 1",
            ));
        }
        check_count("trees_per_block", self.trees_per_block, 0, 1000)?;
        check_count("lamps_per_block", self.lamps_per_block, 0, 1000)?;
        check_count("tree_segments", self.tree_segments, 3, 256)?;
        check_count("tree_rings", self.tree_rings, 2, 256)?;
        let per_block = u64::from(self.lots_per_side).pow(2)
            + u64::from(self.trees_per_block)
            + u64::from(self.lamps_per_block)
            + 1;
        let blocks = u64::from(self.blocks_x) * u64::from(self.blocks_z);
        if blocks * per_block > MAX_OBJECTS as u64 {
            return Err(bad(
                "blocks_x",
                format!(
                    "up to {} objects, more than the {MAX_OBJECTS} a scene can hold",
                    blocks * per_block
                ),
            ));
        }
        Ok(())
    }

    /// Upper bounds `(objects, triangles)` of the city these parameters
    /// generate, computed without generating it (so that a run can refuse a
    /// city that would not fit in memory): per block the ground tile, a
    /// building on every lot with the most triangles a building shape has
    /// (three tiers and a roof), every tree and every lamp post.
    ///
    /// # Errors
    /// As [`CityParams::validate`], and a tree shape that cannot be built.
    pub fn bounds(&self) -> Result<(u64, u64)> {
        self.validate()?;
        let tree = tree_mesh(self.tree_segments, self.tree_rings)?
            .triangles()
            .len() as u64;
        let lamp = lamp_mesh()?.triangles().len() as u64;
        let lots = u64::from(self.lots_per_side).pow(2);
        let trees = u64::from(self.trees_per_block);
        let lamps = u64::from(self.lamps_per_block);
        let blocks = u64::from(self.blocks_x) * u64::from(self.blocks_z);
        let objects = blocks * (1 + lots + trees + lamps);
        let per_block =
            TILE_TRIANGLES_MAX + lots * BUILDING_TRIANGLES_MAX + trees * tree + lamps * lamp;
        Ok((objects, blocks.saturating_mul(per_block)))
    }

    fn pitch(&self) -> f64 {
        self.block_size + self.street_width
    }

    fn lot_side(&self) -> f64 {
        (self.block_size - 2.0 * self.sidewalk) / f64::from(self.lots_per_side)
    }

    /// City extent along x and z (ground tiles included).
    fn size(&self) -> (f64, f64) {
        (
            f64::from(self.blocks_x) * self.pitch(),
            f64::from(self.blocks_z) * self.pitch(),
        )
    }
}

/// The height no object of the city exceeds, metres: the larger of
/// `height_max` (buildings, roof structures included, never exceed it) and
/// the tallest tree (8 m × 1.2) or lamp post (6 m).
pub fn city_height(params: &CityParams) -> f64 {
    let tree = f64::from(CROWN_Y + CROWN_RY) * TREE_SCALE_MAX;
    params.height_max.max(tree).max(f64::from(LAMP_HEIGHT))
}

/// A box `(min, max)` holding every object of the city:
/// `[−W/2, W/2] × [0, city_height] × [−D/2, D/2]` with `W`, `D` the city's
/// extent along x and z (`blocks · (block_size + street_width)`). The ground
/// tiles span it exactly in x and z.
pub fn city_bounds(params: &CityParams) -> (DVec3, DVec3) {
    let (w, d) = params.size();
    (
        DVec3::new(-0.5 * w, 0.0, -0.5 * d),
        DVec3::new(0.5 * w, city_height(params), 0.5 * d),
    )
}

/// Generates the city (see the module doc): objects per cell in the order
/// ground tile, buildings, trees, lamp posts, cells in rows of increasing z,
/// x fastest; cameras and paths `street` and `bird`; lights `light` and `sun`.
///
/// # Errors
/// [`Error::Load`] with file [`CITY_FILE`] and the offending field's name
/// when a parameter is out of range ([`CityParams::validate`]).
pub fn city(params: &CityParams) -> Result<Loaded> {
    params.validate()?;
    let mut graph = SceneGraph::new();
    let tree = graph.add_mesh(tree_mesh(params.tree_segments, params.tree_rings)?);
    let lamp = graph.add_mesh(lamp_mesh()?);
    for bz in 0..params.blocks_z {
        for bx in 0..params.blocks_x {
            add_block(&mut graph, params, bx, bz, tree, lamp)?;
        }
    }
    let (street, bird) = poses(params);
    let (w, d) = params.size();
    let ext = w.max(d);
    Ok(Loaded {
        graph,
        cameras: vec![("street".into(), street), ("bird".into(), bird)],
        paths: vec![
            (
                "street".into(),
                CameraPath::Dolly {
                    start: street,
                    per_frame: DVec3::new(0.0, 0.0, -STREET_METRES_PER_FRAME),
                },
            ),
            (
                "bird".into(),
                CameraPath::Orbit {
                    start: bird,
                    center: DVec3::ZERO,
                    deg_per_frame: BIRD_DEGREES_PER_FRAME,
                },
            ),
        ],
        lights: vec![
            (
                "light".into(),
                Light::Point {
                    position: DVec3::new(0.21 * w + 0.37, 0.4 * ext + 0.37, 0.17 * d + 0.37),
                    range: None,
                },
            ),
            (
                "sun".into(),
                Light::Directional {
                    direction: DVec3::new(-0.4, -1.0, -0.3),
                },
            ),
        ],
    })
}

/// Frame-0 poses of the `street` and `bird` cameras.
fn poses(params: &CityParams) -> (LookAt, LookAt) {
    let (w, d) = params.size();
    let x = -0.5 * w + f64::from(params.blocks_x / 2) * params.pitch();
    let z = 0.5 * d - 0.25 * params.street_width;
    let eye = DVec3::new(x, STREET_EYE_HEIGHT, z);
    let street = LookAt {
        eye,
        target: eye - DVec3::new(0.0, 0.0, 100.0),
        up: DVec3::Y,
        fov_y_deg: 60.0,
        near: 0.5,
    };
    let dist = 0.75 * w.max(d);
    let eye = DVec3::new(0.0, dist * BIRD_PITCH_DEG.to_radians().tan(), dist);
    let bird = LookAt {
        eye,
        target: DVec3::ZERO,
        up: DVec3::Y,
        fov_y_deg: 60.0,
        near: (eye.length() / 400.0).min(5.0),
    };
    (street, bird)
}

/// A tiny deterministic generator (splitmix64), one per block.
struct Rng(u64);

impl Rng {
    fn for_block(seed: u64, bx: u32, bz: u32) -> Rng {
        let mut s = seed;
        let block = (u64::from(bx) << 32 | u64::from(bz)).wrapping_mul(0xD1B5_4A32_D192_ED03);
        Rng(splitmix64(&mut s) ^ block)
    }

    fn next_u64(&mut self) -> u64 {
        splitmix64(&mut self.0)
    }

    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Uniform integer in 0..n (0 when n ≤ 0).
    fn below(&mut self, n: i32) -> i32 {
        if n <= 0 {
            return 0;
        }
        (((self.next_u64() >> 32) * n as u64) >> 32) as i32
    }
}

/// A point on the rectangle `[x0 + a, x1 − a] × [z0 + a, z1 − a]` at arc length
/// `s` (wrapping), walking +x along the −z side first, and the side's outward
/// normal.
fn on_ring(x0: f64, z0: f64, size: f64, a: f64, s: f64) -> (DVec3, DVec3) {
    let l = size - 2.0 * a;
    if l <= 0.0 {
        return (
            DVec3::new(x0 + 0.5 * size, 0.0, z0 + 0.5 * size),
            DVec3::NEG_Z,
        );
    }
    let s = s.rem_euclid(4.0 * l);
    let side = ((s / l) as u32).min(3);
    let t = s - f64::from(side) * l;
    let (lo_x, lo_z, hi_x, hi_z) = (x0 + a, z0 + a, x0 + size - a, z0 + size - a);
    match side {
        0 => (DVec3::new(lo_x + t, 0.0, lo_z), DVec3::NEG_Z),
        1 => (DVec3::new(hi_x, 0.0, lo_z + t), DVec3::X),
        2 => (DVec3::new(hi_x - t, 0.0, hi_z), DVec3::Z),
        _ => (DVec3::new(lo_x, 0.0, hi_z - t), DVec3::NEG_X),
    }
}

/// Adds cell `(bx, bz)`: ground tile, buildings, trees, lamp posts.
fn add_block(
    graph: &mut SceneGraph,
    p: &CityParams,
    bx: u32,
    bz: u32,
    tree: MeshId,
    lamp: MeshId,
) -> Result<()> {
    let mut rng = Rng::for_block(p.seed, bx, bz);
    let (w, d) = p.size();
    let pitch = p.pitch();
    let cell_x = -0.5 * w + f64::from(bx) * pitch;
    let cell_z = -0.5 * d + f64::from(bz) * pitch;
    let cell_x1 = -0.5 * w + f64::from(bx + 1) * pitch;
    let cell_z1 = -0.5 * d + f64::from(bz + 1) * pitch;
    let tile_name = format!("ground {bx},{bz}");
    let tile = horizontal_quad(
        tile_name.clone(),
        [cell_x as f32, cell_x1 as f32],
        [cell_z as f32, cell_z1 as f32],
        0.0,
        true,
    )?;
    let tile = graph.add_mesh(tile);
    graph.add_instance(&tile_name, tile, Transform::default());

    let (x0, z0) = (cell_x + 0.5 * p.street_width, cell_z + 0.5 * p.street_width);
    // Closeness to the centre: 0 at the centre, 1 at the city's corners.
    let centre = DVec3::new(x0 + 0.5 * p.block_size, 0.0, z0 + 0.5 * p.block_size);
    let r = (centre.length() / (0.5 * w.hypot(d))).min(1.0);
    let exponent = 1.5 + 3.0 * r;
    let lot = p.lot_side();
    // Usable lot width in quarter metres, keeping 0.25 m free on each side.
    let avail = (lot * 4.0).floor() as i32 - 2;
    let mut k = 0;
    for j in 0..p.lots_per_side {
        for i in 0..p.lots_per_side {
            if rng.unit() >= p.building_density {
                continue;
            }
            let side = |rng: &mut Rng| {
                let size =
                    (f64::from(avail) * rng.range(p.footprint_min, p.footprint_max)).round() as i32;
                let size = size.clamp(2, avail);
                (size, rng.below(avail - size + 1))
            };
            let (sx, ox) = side(&mut rng);
            let (sz, oz) = side(&mut rng);
            let h = p.height_min + (p.height_max - p.height_min) * rng.unit().powf(exponent);
            let h_lo = (p.height_min * 4.0).ceil() as i32;
            let h_hi = (p.height_max * 4.0).floor() as i32;
            let h = ((h * 4.0).round() as i32).clamp(h_lo, h_hi.max(h_lo));
            let (tiers, apex) = building_shape(&mut rng, p, sx, sz, h);
            let name = format!("building {bx},{bz},{k}");
            let mesh = graph.add_mesh(building_mesh(name.clone(), &tiers, apex)?);
            let lot_x = x0 + p.sidewalk + f64::from(i) * lot;
            let lot_z = z0 + p.sidewalk + f64::from(j) * lot;
            let at = DVec3::new(
                lot_x + 0.25 * f64::from(1 + ox),
                0.0,
                lot_z + 0.25 * f64::from(1 + oz),
            );
            graph.add_instance(&name, mesh, Transform::translation(at));
            k += 1;
        }
    }

    let ring = 4.0 * (p.block_size - p.sidewalk);
    for t in 0..p.trees_per_block {
        let s = (f64::from(t) + 0.5 + rng.range(-0.25, 0.25)) * ring / f64::from(p.trees_per_block);
        let (at, _) = on_ring(x0, z0, p.block_size, 0.5 * p.sidewalk, s);
        let transform = Transform::Trs {
            translation: at,
            rotation: DQuat::from_rotation_y(rng.range(0.0, TAU)),
            scale: DVec3::splat(rng.range(0.8, TREE_SCALE_MAX)),
        };
        graph.add_instance(&format!("tree {bx},{bz},{t}"), tree, transform);
    }
    let ring = 4.0 * (p.block_size - 2.0 * LAMP_INSET);
    for t in 0..p.lamps_per_block {
        let s = (f64::from(t) + rng.range(0.0, 0.1)) * ring / f64::from(p.lamps_per_block);
        let (at, out) = on_ring(x0, z0, p.block_size, LAMP_INSET, s);
        // The arm (local +x) points out over the street: R_y(θ)·x = (cos θ, 0, −sin θ).
        let transform = Transform::Trs {
            translation: at,
            rotation: DQuat::from_rotation_y((-out.z).atan2(out.x)),
            scale: DVec3::ONE,
        };
        graph.add_instance(&format!("lamp {bx},{bz},{t}"), lamp, transform);
    }
    Ok(())
}

/// Picks a building's shape: tiers (quarter metres, local to the footprint
/// corner) and an optional hip-roof apex height. `sx`, `sz` footprint, `h`
/// total height, all in quarter metres; nothing rises above `h`.
fn building_shape(
    rng: &mut Rng,
    p: &CityParams,
    sx: i32,
    sz: i32,
    h: i32,
) -> (Vec<Tier>, Option<i32>) {
    let base = Tier {
        x: [0, sx],
        z: [0, sz],
        top: h,
    };
    let v = rng.unit();
    let towers = p.tower_fraction;
    let structures = towers + p.roof_structure_fraction;
    let hips = structures + p.hip_roof_fraction;
    if v < towers && sx >= 16 && sz >= 16 && h >= 24 {
        let n = 2 + rng.below(2);
        let cuts: Vec<f64> = if n == 2 {
            vec![rng.range(0.45, 0.7)]
        } else {
            vec![rng.range(0.3, 0.45), rng.range(0.55, 0.75)]
        };
        let mut tiers = vec![base];
        let mut prev_top = 0;
        for (k, c) in cuts.iter().enumerate() {
            let top = ((f64::from(h) * c).round() as i32)
                .clamp(prev_top + 1, h - (cuts.len() - k) as i32);
            tiers[k].top = top;
            prev_top = top;
            let last = tiers[k];
            let inset = |lo: i32, hi: i32, rng: &mut Rng| {
                let wid = hi - lo;
                let a = ((f64::from(wid) * rng.range(0.08, 0.2)).round() as i32).max(1);
                let b = ((f64::from(wid) * rng.range(0.08, 0.2)).round() as i32).max(1);
                [lo + a, hi - b]
            };
            let x = inset(last.x[0], last.x[1], rng);
            let z = inset(last.z[0], last.z[1], rng);
            if x[1] - x[0] < 4 || z[1] - z[0] < 4 {
                tiers[k].top = h;
                break;
            }
            tiers.push(Tier { x, z, top: h });
        }
        (tiers, None)
    } else if v < structures && sx >= 12 && sz >= 12 && h >= 20 {
        let hh = 8 + rng.below(9);
        let span = |s: i32, rng: &mut Rng| {
            let len = ((f64::from(s) * rng.range(0.25, 0.5)).round() as i32).clamp(4, s - 2);
            let lo = 1 + rng.below(s - len - 1);
            [lo, lo + len]
        };
        let x = span(sx, rng);
        let z = span(sz, rng);
        let main = Tier {
            top: h - hh,
            ..base
        };
        (vec![main, Tier { x, z, top: h }], None)
    } else if v < hips && h >= 12 {
        let rh = ((f64::from(sx.min(sz)) * rng.range(0.2, 0.4)).round() as i32).clamp(1, h - 4);
        (
            vec![Tier {
                top: h - rh,
                ..base
            }],
            Some(h),
        )
    } else {
        (vec![base], None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::procedural::city_meshes::tests::assert_closed;
    use glam::Vec3;

    #[test]
    fn rng_is_deterministic_and_spread() {
        let mut a = Rng::for_block(7, 3, 4);
        let mut b = Rng::for_block(7, 3, 4);
        let mut c = Rng::for_block(7, 4, 3);
        let xs: Vec<u64> = (0..8).map(|_| a.next_u64()).collect();
        assert_eq!(xs, (0..8).map(|_| b.next_u64()).collect::<Vec<_>>());
        assert_ne!(xs, (0..8).map(|_| c.next_u64()).collect::<Vec<_>>());
        let mean = (0..10_000).map(|_| a.unit()).sum::<f64>() / 10_000.0;
        assert!((mean - 0.5).abs() < 0.02, "mean {mean}");
        assert!((0..1000).all(|_| (0..5).contains(&a.below(5))));
        assert_eq!(a.below(0), 0);
    }

    #[test]
    fn generated_building_shapes_are_closed() {
        // Random shapes from the generator itself.
        let p = CityParams::default();
        let mut rng = Rng::for_block(3, 0, 0);
        let mut counts = std::collections::BTreeMap::new();
        for _ in 0..2000 {
            let (sx, sz, h) = (2 + rng.below(45), 2 + rng.below(45), 24 + rng.below(300));
            let (tiers, apex) = building_shape(&mut rng, &p, sx, sz, h);
            let m = building_mesh("b".into(), &tiers, apex).unwrap();
            assert_closed(&m);
            assert!(m.bounds().max.y <= h as f32 * 0.25);
            assert_eq!(m.bounds().min, Vec3::ZERO);
            *counts.entry(m.triangles().len()).or_insert(0) += 1;
        }
        for n in [12, 14, 28, 44] {
            assert!(
                counts.contains_key(&n),
                "no building with {n} triangles: {counts:?}"
            );
        }
    }

    #[test]
    fn bad_params_name_the_field() {
        let with = |f: fn(&mut CityParams)| {
            let mut p = CityParams::default();
            f(&mut p);
            p
        };
        let cases = [
            ("blocks_x", with(|p| p.blocks_x = 0)),
            ("block_size", with(|p| p.block_size = f64::NAN)),
            ("street_width", with(|p| p.street_width = 0.0)),
            ("sidewalk", with(|p| p.sidewalk = 42.0)),
            ("lots_per_side", with(|p| p.lots_per_side = 60)),
            ("building_density", with(|p| p.building_density = 1.5)),
            ("footprint_max", with(|p| p.footprint_max = 0.5)),
            ("height_max", with(|p| p.height_max = 2.0)),
            ("hip_roof_fraction", with(|p| p.hip_roof_fraction = 0.9)),
            ("tree_rings", with(|p| p.tree_rings = 1)),
            (
                "blocks_x",
                with(|p| {
                    p.blocks_x = 1024;
                    p.blocks_z = 1024;
                }),
            ),
        ];
        for (field, p) in cases {
            match city(&p) {
                Err(Error::Load { file, element, .. }) => {
                    assert_eq!(file, PathBuf::from(CITY_FILE));
                    assert_eq!(element, field);
                }
                other => panic!("{field}: expected a parameter error, got {other:?}"),
            }
        }
    }

    #[test]
    fn params_deserialize_with_defaults_and_reject_unknown_fields() {
        let p: CityParams = serde_json::from_str(r#"{"seed": 9, "blocks_x": 3}"#).unwrap();
        assert_eq!(
            p,
            CityParams {
                seed: 9,
                blocks_x: 3,
                ..Default::default()
            }
        );
        assert!(serde_json::from_str::<CityParams>(r#"{"blocks": 3}"#).is_err());
    }

    /// [`CityParams::bounds`] holds for generated cities whatever the shape mix.
    #[test]
    fn bounds_cover_generated_cities() {
        for (tower, structure, hip) in [
            (0.0, 0.0, 0.0),
            (1.0, 0.0, 0.0),
            (0.0, 1.0, 0.0),
            (0.0, 0.0, 1.0),
            (0.3, 0.3, 0.3),
        ] {
            let p = CityParams {
                blocks_x: 3,
                blocks_z: 2,
                building_density: 1.0,
                tower_fraction: tower,
                roof_structure_fraction: structure,
                hip_roof_fraction: hip,
                ..CityParams::default()
            };
            let (objects, triangles) = p.bounds().unwrap();
            let scene = crate::Scene::new(city(&p).unwrap().graph).unwrap();
            let c = scene.counts();
            assert!(
                c.objects as u64 <= objects && c.triangles as u64 <= triangles,
                "{c:?} vs {objects}, {triangles}"
            );
            for o in scene.objects() {
                let name = scene.graph().meshes()[o.mesh.index()].name().to_string();
                if name.starts_with("building") {
                    let t = scene.graph().meshes()[o.mesh.index()].triangles().len() as u64;
                    assert!(t <= BUILDING_TRIANGLES_MAX, "{name}: {t}");
                }
            }
        }
        // A city like the probe's (10.4 M objects, about 1.3e12 triangles) is
        // bounded without being generated.
        let huge = CityParams {
            blocks_x: 1024,
            blocks_z: 512,
            lots_per_side: 4,
            trees_per_block: 8,
            tree_segments: 256,
            tree_rings: 256,
            ..CityParams::default()
        };
        let (objects, triangles) = huge.bounds().unwrap();
        assert!(
            objects > 10_000_000 && triangles > 100_000_000_000,
            "{objects}, {triangles}"
        );
    }

    #[test]
    fn small_city_is_deterministic() {
        let p = CityParams {
            blocks_x: 2,
            blocks_z: 3,
            ..Default::default()
        };
        let a = city(&p).unwrap();
        let b = city(&p).unwrap();
        assert_eq!(a.graph.nodes().len(), b.graph.nodes().len());
        for (m, n) in a.graph.meshes().iter().zip(b.graph.meshes()) {
            assert_eq!(m.positions(), n.positions());
        }
        for (m, n) in a.graph.nodes().iter().zip(b.graph.nodes()) {
            assert_eq!(m.transform, n.transform);
        }
        assert_eq!(a.paths, b.paths);
    }
}
