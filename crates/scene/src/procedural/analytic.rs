//! Analytic test scenes: a few boxes and quads whose shadows can be worked out
//! by hand, so reference tests can compare masks against exact answers, plus
//! the two mesh builders every generated scene uses — the closed box
//! ([`box_mesh`], in the box-city corner and face order) and the single-sided
//! horizontal quad ([`horizontal_quad`]).
//!
//! Every scene states its exact geometry in its doc comment. All coordinates
//! are small multiples of 0.25, exact in f32, so a test can compare positions
//! bit for bit. Objects come out in the order the builder documents (the scene
//! graph's roots in order, flattened by [`crate::Scene::new`]).

use crate::loaded::Loaded;
use crate::{Error, Light, LookAt, Mesh, Result, SceneGraph, Transform};
use glam::{DVec3, Vec3};
use std::path::PathBuf;

/// The `file` that parameter errors of these builders name.
pub const ANALYTIC_FILE: &str = "<analytic scene>";

/// The eight corners of an axis-aligned box by index
/// `c = (x?1:0) | (y?2:0) | (z?4:0)` (0 = min, 1 = max), as in the box-city
/// format (`../shared/data/bench/README.md`).
pub fn box_corners(min: Vec3, max: Vec3) -> [Vec3; 8] {
    crate::Aabb { min, max }.corners()
}

/// The six faces of a box as corner-index quads, counter-clockwise seen from
/// outside, in the order −X, +X, −Y, +Y, −Z, +Z (the box-city format's order).
/// Quad `(a, b, c, d)` becomes triangles `(a, b, c)`, `(a, c, d)`.
pub const BOX_FACES: [[u32; 4]; 6] = [
    [0, 4, 6, 2],
    [1, 3, 7, 5],
    [0, 1, 5, 4],
    [2, 6, 7, 3],
    [0, 2, 3, 1],
    [4, 5, 7, 6],
];

/// The twelve triangles of a box over the corners of [`box_corners`]: the
/// faces of [`BOX_FACES`] in order, each quad `(a, b, c, d)` split into
/// `(a, b, c)`, `(a, c, d)`.
pub fn box_triangles() -> [[u32; 3]; 12] {
    std::array::from_fn(|t| {
        let [a, b, c, d] = BOX_FACES[t / 2];
        if t % 2 == 0 {
            [a, b, c]
        } else {
            [a, c, d]
        }
    })
}

/// A closed axis-aligned box mesh: 8 vertices, 12 triangles, 18 edges,
/// counter-clockwise seen from outside.
///
/// Triangle `t` is triangle `t` of [`box_triangles`] (faces −X, +X, −Y, +Y,
/// −Z, +Z, two triangles each), with exactly the positions `min`/`max` given
/// (no arithmetic on them). The mesh's vertex *indices* are its welded,
/// first-use order (see [`Mesh::new`]), not the corner indices.
///
/// # Errors
/// [`Error::InvalidMesh`] naming `name` when a coordinate is not finite or
/// `min` is not strictly below `max` on every axis (a flat box would lose
/// triangles and no longer be closed).
pub fn box_mesh(name: impl Into<String>, min: Vec3, max: Vec3) -> Result<Mesh> {
    let name = name.into();
    if !min.is_finite() || !max.is_finite() {
        return Err(Error::InvalidMesh {
            mesh: name,
            message: format!("box corners {min} and {max} must be finite"),
        });
    }
    for (axis, lo, hi) in [
        ("x", min.x, max.x),
        ("y", min.y, max.y),
        ("z", min.z, max.z),
    ] {
        if lo >= hi {
            return Err(Error::InvalidMesh {
                mesh: name,
                message: format!("box min {axis} = {lo} must be below max {axis} = {hi}"),
            });
        }
    }
    Mesh::new(name, &box_corners(min, max), &box_triangles())
}

/// A single-sided horizontal quad (2 triangles, an open mesh with 4 boundary
/// edges) covering `x[0]..x[1]` × `z[0]..z[1]` at height `y`.
///
/// Its front is +y (counter-clockwise seen from above) when `facing_up`, else
/// −y. Triangles: with corners `p00 = (x0, y, z0)`, `p01 = (x0, y, z1)`,
/// `p11 = (x1, y, z1)`, `p10 = (x1, y, z0)`, facing up gives
/// `(p00, p01, p11)`, `(p00, p11, p10)`; facing down `(p00, p10, p11)`,
/// `(p00, p11, p01)`.
///
/// # Errors
/// [`Error::InvalidMesh`] naming `name` when a coordinate is not finite or a
/// range is empty (`x[0] >= x[1]` or `z[0] >= z[1]`).
pub fn horizontal_quad(
    name: impl Into<String>,
    x: [f32; 2],
    z: [f32; 2],
    y: f32,
    facing_up: bool,
) -> Result<Mesh> {
    let name = name.into();
    if !(x.iter().chain(&z).all(|v| v.is_finite()) && y.is_finite()) {
        return Err(Error::InvalidMesh {
            mesh: name,
            message: "quad coordinates must be finite".into(),
        });
    }
    if x[0] >= x[1] || z[0] >= z[1] {
        return Err(Error::InvalidMesh {
            mesh: name,
            message: format!(
                "quad ranges x {}..{} and z {}..{} must not be empty",
                x[0], x[1], z[0], z[1]
            ),
        });
    }
    let p = [
        Vec3::new(x[0], y, z[0]),
        Vec3::new(x[0], y, z[1]),
        Vec3::new(x[1], y, z[1]),
        Vec3::new(x[1], y, z[0]),
    ];
    let tris = if facing_up {
        [[0, 1, 2], [0, 2, 3]]
    } else {
        [[0, 3, 2], [0, 2, 1]]
    };
    Mesh::new(name, &p, &tris)
}

fn param_err(field: &str, message: String) -> Error {
    Error::Load {
        file: PathBuf::from(ANALYTIC_FILE),
        element: field.into(),
        message,
    }
}

/// A ground quad with boxes on or above it, geometry only.
///
/// Objects `0..boxes.len()` are the boxes (`(min, max)` each, [`box_mesh`],
/// named `box {i}`, identity transform); the last object is the ground: the
/// up-facing [`horizontal_quad`] `[−h, h] × {0} × [−h, h]` with
/// `h = ground_half_size`. No cameras, paths or lights.
///
/// # Errors
/// [`Error::Load`] with file [`ANALYTIC_FILE`] and element `ground_half_size`
/// when it is not positive and finite; [`Error::InvalidMesh`] naming `box {i}`
/// for an invalid box.
pub fn ground_with_boxes(ground_half_size: f32, boxes: &[(Vec3, Vec3)]) -> Result<Loaded> {
    if !(ground_half_size > 0.0 && ground_half_size.is_finite()) {
        return Err(param_err(
            "ground_half_size",
            format!("must be positive and finite, got {ground_half_size}"),
        ));
    }
    let mut graph = SceneGraph::new();
    for (i, &(min, max)) in boxes.iter().enumerate() {
        let name = format!("box {i}");
        let mesh = graph.add_mesh(box_mesh(name.clone(), min, max)?);
        graph.add_instance(&name, mesh, Transform::default());
    }
    let h = ground_half_size;
    let ground = graph.add_mesh(horizontal_quad("ground", [-h, h], [-h, h], 0.0, true)?);
    graph.add_instance("ground", ground, Transform::default());
    Ok(Loaded::from_graph(graph))
}

/// A unit box hovering 1 above a large ground plane, lit from straight above.
///
/// Exact geometry:
/// - object 0: the box `[−0.5, 0.5] × [1, 2] × [−0.5, 0.5]` (closed, 12 triangles);
/// - object 1: the ground `[−50, 50] × {0} × [−50, 50]`, facing up (2 triangles);
/// - light `light`: a point light at `(0, 10, 0)`, unlimited range;
/// - camera `view`: eye `(0, 6, 6)`, target `(0, 0, 0)`, up +y, 60°, near 0.1.
///
/// Seen from the light only the box's top face faces it (its sides are
/// edge-on), so its silhouette is the top face's outline at y = 2 and the
/// exact shadow on the ground is the square `|x| ≤ 0.625, |z| ≤ 0.625`
/// (0.5 · 10 / (10 − 2)); the box's bottom face is in its own shadow.
///
/// # Errors
/// None in practice; the `Result` is that of the mesh builders.
pub fn box_over_plane() -> Result<Loaded> {
    let mut loaded = ground_with_boxes(
        50.0,
        &[(Vec3::new(-0.5, 1.0, -0.5), Vec3::new(0.5, 2.0, 0.5))],
    )?;
    loaded.lights.push((
        "light".into(),
        Light::Point {
            position: DVec3::new(0.0, 10.0, 0.0),
            range: None,
        },
    ));
    loaded.cameras.push((
        "view".into(),
        LookAt {
            eye: DVec3::new(0.0, 6.0, 6.0),
            target: DVec3::ZERO,
            up: DVec3::Y,
            fov_y_deg: 60.0,
            near: 0.1,
        },
    ));
    Ok(loaded)
}

/// The largest `n` [`stacked_occluders`] accepts.
pub const MAX_STACKED: u32 = 4096;

/// `n` identical slabs stacked above a ground, lit from straight above: the
/// top slab hides all the others from the light, so every slab but the top one
/// is a caster whose shadow is redundant (shadow-caster culling should drop it).
///
/// Exact geometry:
/// - objects `0..n`: slab `i` is the box `[−1, 1] × [1 + i, 1.25 + i] × [−1, 1]`
///   (closed, 12 triangles), bottom to top;
/// - object `n`: the ground `[−g, g] × {0} × [−g, g]` with `g = 2 (n + 10)`, facing up;
/// - light `light`: a point light at `(0, L, 0)` with `L = n + 10`, unlimited range;
/// - camera `view`: eye `(0, L, 2 L)`, target `(0, 0, 0)`, up +y, 60°, near 0.1.
///
/// For `n ≥ 1` the exact shadow on the ground is the square
/// `|x|, |z| ≤ L / (L − t)` with `t = n + 0.25` the top slab's top (its top face
/// outline is the silhouette); `n = 0` is the bare ground.
///
/// # Errors
/// [`Error::Load`] with file [`ANALYTIC_FILE`] and element `n` when
/// `n > MAX_STACKED`.
pub fn stacked_occluders(n: u32) -> Result<Loaded> {
    if n > MAX_STACKED {
        return Err(param_err(
            "n",
            format!("at most {MAX_STACKED} slabs, got {n}"),
        ));
    }
    let slabs: Vec<(Vec3, Vec3)> = (0..n)
        .map(|i| {
            let y = 1.0 + i as f32;
            (Vec3::new(-1.0, y, -1.0), Vec3::new(1.0, y + 0.25, 1.0))
        })
        .collect();
    let l = f64::from(n) + 10.0;
    let mut loaded = ground_with_boxes(2.0 * l as f32, &slabs)?;
    loaded.lights.push((
        "light".into(),
        Light::Point {
            position: DVec3::new(0.0, l, 0.0),
            range: None,
        },
    ));
    loaded.cameras.push((
        "view".into(),
        LookAt {
            eye: DVec3::new(0.0, l, 2.0 * l),
            target: DVec3::ZERO,
            up: DVec3::Y,
            fov_y_deg: 60.0,
            near: 0.1,
        },
    ));
    Ok(loaded)
}

/// One single-sided quad, the smallest open mesh: object 0 is
/// `[−1, 1] × {0} × [−1, 1]` ([`horizontal_quad`], 2 triangles, 4 boundary
/// edges), front side +y when `facing_up`, else −y. Geometry only.
///
/// # Errors
/// None in practice; the `Result` is that of the mesh builder.
pub fn open_quad(facing_up: bool) -> Result<Loaded> {
    let mut graph = SceneGraph::new();
    let mesh = graph.add_mesh(horizontal_quad(
        "quad",
        [-1.0, 1.0],
        [-1.0, 1.0],
        0.0,
        facing_up,
    )?);
    graph.add_instance("quad", mesh, Transform::default());
    Ok(Loaded::from_graph(graph))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Scene, Topology};

    fn normal(m: &Mesh, t: usize) -> Vec3 {
        let [a, b, c] = m.triangle(t);
        (b - a).cross(c - a)
    }

    fn signed_volume(m: &Mesh) -> f64 {
        (0..m.triangles().len())
            .map(|t| {
                let [a, b, c] = m.triangle(t).map(|p| p.as_dvec3());
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn box_mesh_is_closed_and_outward() {
        let (min, max) = (Vec3::new(-1.0, 0.25, 2.0), Vec3::new(3.5, 4.0, 2.75));
        let m = box_mesh("b", min, max).unwrap();
        assert_eq!(m.triangles().len(), 12);
        assert_eq!(m.positions().len(), 8);
        assert_eq!(m.edges().len(), 18);
        assert_eq!(m.topology(), Topology::default());
        let centre = (min + max) * 0.5;
        for t in 0..12 {
            let [a, b, c] = m.triangle(t);
            let centroid = (a + b + c) / 3.0;
            assert!(
                normal(&m, t).dot(centroid - centre) > 0.0,
                "triangle {t} faces inward"
            );
        }
        assert!((signed_volume(&m) - 4.5 * 3.75 * 0.75).abs() < 1e-9);
        assert_eq!(m.bounds().min, min);
        assert_eq!(m.bounds().max, max);
    }

    #[test]
    fn box_mesh_follows_the_box_city_order() {
        let (min, max) = (Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0));
        let corners = box_corners(min, max);
        let m = box_mesh("b", min, max).unwrap();
        let faces_normals = [
            Vec3::NEG_X,
            Vec3::X,
            Vec3::NEG_Y,
            Vec3::Y,
            Vec3::NEG_Z,
            Vec3::Z,
        ];
        for (t, tri) in box_triangles().iter().enumerate() {
            assert_eq!(m.triangle(t), tri.map(|c| corners[c as usize]));
            assert!(normal(&m, t).normalize().dot(faces_normals[t / 2]) > 0.999);
        }
        // −X face, first triangle: corners 0, 4, 6.
        assert_eq!(box_triangles()[0], [0, 4, 6]);
        assert_eq!(box_triangles()[11], [4, 7, 6]);
    }

    #[test]
    fn box_mesh_rejects_bad_corners() {
        let flat = box_mesh("flat", Vec3::ZERO, Vec3::new(1.0, 0.0, 1.0));
        assert!(matches!(flat, Err(Error::InvalidMesh { ref mesh, .. }) if mesh == "flat"));
        assert!(box_mesh("inv", Vec3::ONE, Vec3::ZERO).is_err());
        assert!(box_mesh("nan", Vec3::new(f32::NAN, 0.0, 0.0), Vec3::ONE).is_err());
        assert!(box_mesh("inf", Vec3::ZERO, Vec3::splat(f32::INFINITY)).is_err());
    }

    #[test]
    fn quads_face_the_requested_side_and_are_open() {
        for up in [true, false] {
            let q = horizontal_quad("q", [-1.0, 2.0], [0.0, 3.0], 0.5, up).unwrap();
            assert_eq!(q.triangles().len(), 2);
            assert_eq!(q.topology().boundary_edges, 4);
            assert_eq!(q.topology().inconsistent_edges, 0);
            for t in 0..2 {
                assert_eq!(normal(&q, t).y > 0.0, up);
                assert_eq!(normal(&q, t).x, 0.0);
                assert_eq!(normal(&q, t).z, 0.0);
            }
        }
        assert!(horizontal_quad("q", [1.0, 1.0], [0.0, 1.0], 0.0, true).is_err());
        assert!(horizontal_quad("q", [0.0, 1.0], [0.0, 1.0], f32::NAN, true).is_err());
    }

    #[test]
    fn scenes_have_the_documented_counts() {
        let s = Scene::new(box_over_plane().unwrap().graph).unwrap();
        let c = s.counts();
        assert_eq!((c.objects, c.triangles), (2, 14));
        assert_eq!(
            s.object_mesh(crate::ObjectId::from_slot(0)).bounds().min,
            Vec3::new(-0.5, 1.0, -0.5)
        );
        assert_eq!(s.bounds().max, Vec3::new(50.0, 2.0, 50.0));

        for n in [0, 1, 5] {
            let l = stacked_occluders(n).unwrap();
            assert_eq!(l.lights.len(), 1);
            let s = Scene::new(l.graph).unwrap();
            assert_eq!(s.counts().objects, n as usize + 1);
            assert_eq!(s.counts().triangles, 12 * n as usize + 2);
            assert_eq!(s.counts().topology.boundary_edges, 4);
        }
        assert!(matches!(
            stacked_occluders(MAX_STACKED + 1),
            Err(Error::Load { ref element, .. }) if element == "n"
        ));

        let q = Scene::new(open_quad(false).unwrap().graph).unwrap();
        assert_eq!((q.counts().objects, q.counts().triangles), (1, 2));
        assert!(ground_with_boxes(0.0, &[]).is_err());
        assert!(matches!(
            ground_with_boxes(1.0, &[(Vec3::ONE, Vec3::ZERO)]),
            Err(Error::InvalidMesh { ref mesh, .. }) if mesh == "box 0"
        ));
    }
}
