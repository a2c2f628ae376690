//! Meshes and their topology, prepared once per mesh: welded positions,
//! triangle list, and the edge table with the signed-counter layout of
//! [AW §2.4] that silhouette extraction uses.

use crate::{Aabb, Error, Result};
use glam::{DVec3, Vec3};
use std::collections::HashMap;

/// The build's tables: keys are vertex bits and indices, hashed with
/// foldhash (SipHash took about half of rebuilding a deformed 20k-triangle
/// mesh).
type Table<K, V> = HashMap<K, V, foldhash::fast::RandomState>;

/// A reference from a triangle to one of its edges, with the direction the
/// triangle traverses it: `+1` when the triangle runs from the edge's `v[0]`
/// to `v[1]`, `−1` when it runs the other way. Silhouette extraction [AW §2.4]
/// adds this sign to the edge's counter for every light-facing triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EdgeRef(u32);

impl EdgeRef {
    const REVERSED: u32 = 1 << 31;

    fn new(edge: u32, reversed: bool) -> Self {
        EdgeRef(edge | if reversed { Self::REVERSED } else { 0 })
    }

    /// Index into [`Mesh::edges`].
    pub fn index(self) -> usize {
        (self.0 & !Self::REVERSED) as usize
    }

    /// `+1` if the triangle traverses the edge from `v[0]` to `v[1]`, else `−1`.
    pub fn sign(self) -> i32 {
        if self.0 & Self::REVERSED != 0 {
            -1
        } else {
            1
        }
    }
}

/// An undirected edge between two welded vertices, `v[0] < v[1]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Edge {
    /// Vertex indices, smaller first.
    pub v: [u32; 2],
    /// Number of triangles that use the edge.
    pub triangles: u32,
    /// Sum of the traversal signs over those triangles (0 for a consistently
    /// wound manifold edge).
    pub winding_sum: i32,
}

/// Topology counts of a mesh, reported by `shadowcull inspect`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Topology {
    /// Edges used by exactly one triangle (holes, open borders).
    pub boundary_edges: usize,
    /// Edges used by more than two triangles.
    pub non_manifold_edges: usize,
    /// Edges used by two or more triangles, at least two of which traverse
    /// the edge in the same direction (inconsistent orientation).
    pub inconsistent_edges: usize,
    /// Triangles dropped because two of their welded vertices coincide or
    /// their three vertices are collinear (zero area).
    pub degenerate_triangles: usize,
}

/// Which side of a closed mesh's triangles faces its outside
/// ([`Mesh::solid`]): seen from outside the mesh's bounds, the first surface a
/// ray meets is one of those sides, so a rasterizer may skip the other
/// (back-face culling).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Solid {
    /// Every piece encloses positive volume: front faces (counter-clockwise)
    /// face out.
    Outward,
    /// Every piece encloses negative volume: back faces face out (an
    /// inside-out mesh).
    Inward,
}

/// A triangle mesh with welded vertices and an edge table.
///
/// Built once per mesh and shared by every instance. Winding: counter-clockwise
/// seen from the front. Vertices at bit-identical positions (with −0 equal to
/// +0) are welded into one, so edges are shared across unwelded polygon soups.
#[derive(Clone, Debug)]
pub struct Mesh {
    name: String,
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    edges: Vec<Edge>,
    triangle_edges: Vec<[EdgeRef; 3]>,
    topology: Topology,
    bounds: Aabb,
    solid: Option<Solid>,
}

fn weld_key(p: Vec3) -> [u32; 3] {
    // +0.0 turns −0 into +0: the two weld together.
    [
        (p.x + 0.0).to_bits(),
        (p.y + 0.0).to_bits(),
        (p.z + 0.0).to_bits(),
    ]
}

impl Mesh {
    /// Builds a mesh from raw positions and triangles (indices into `positions`).
    ///
    /// Positions are welded, degenerate triangles dropped and counted, and the
    /// edge table built.
    ///
    /// # Errors
    /// [`Error::InvalidMesh`] naming `name` when an index is out of range or a
    /// position used by a triangle is not finite.
    pub fn new(
        name: impl Into<String>,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
    ) -> Result<Mesh> {
        let name = name.into();
        let (welded, tris, degenerate) = weld(&name, positions, triangles)?;
        let (edges, triangle_edges) = build_edges(&tris);
        let topology = Topology {
            degenerate_triangles: degenerate,
            ..edge_topology(&edges, &triangle_edges)
        };
        Ok(Mesh::finish(
            name,
            welded,
            tris,
            (edges, triangle_edges),
            topology,
        ))
    }

    /// This mesh deformed: exactly `Mesh::new(self.name(), positions,
    /// triangles)`, built faster when the new positions weld the triangles
    /// as this mesh's were welded (a deformation that keeps the topology):
    /// the edge table is then this mesh's, not rebuilt (it depends on the
    /// welded triangles alone).
    ///
    /// # Errors
    /// As [`Mesh::new`].
    pub fn deformed(&self, positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<Mesh> {
        let (welded, tris, degenerate) = weld(&self.name, positions, triangles)?;
        let (edges, topology) = if tris == self.triangles {
            (
                (self.edges.clone(), self.triangle_edges.clone()),
                self.topology,
            )
        } else {
            let (edges, triangle_edges) = build_edges(&tris);
            let t = edge_topology(&edges, &triangle_edges);
            ((edges, triangle_edges), t)
        };
        let topology = Topology {
            degenerate_triangles: degenerate,
            ..topology
        };
        Ok(Mesh::finish(
            self.name.clone(),
            welded,
            tris,
            edges,
            topology,
        ))
    }

    /// A mesh from its welded parts: its bounds and, when closed, which
    /// side faces out.
    fn finish(
        name: String,
        positions: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        (edges, triangle_edges): (Vec<Edge>, Vec<[EdgeRef; 3]>),
        topology: Topology,
    ) -> Mesh {
        let bounds = Aabb::from_points(positions.iter().copied());
        let closed = Topology {
            degenerate_triangles: 0,
            ..topology
        } == Topology::default();
        let solid = closed
            .then(|| solid(&positions, &triangles, &triangle_edges, edges.len(), bounds))
            .flatten();
        Mesh {
            name,
            positions,
            triangles,
            edges,
            triangle_edges,
            topology,
            bounds,
            solid,
        }
    }

    /// The mesh's name (from the file, or given in code).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Welded vertex positions in local space.
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Triangles (indices into [`Mesh::positions`]), counter-clockwise = front.
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The undirected edges.
    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }

    /// Per triangle, its edges `(v0,v1), (v1,v2), (v2,v0)` with traversal signs.
    pub fn triangle_edges(&self) -> &[[EdgeRef; 3]] {
        &self.triangle_edges
    }

    /// Topology counts.
    pub fn topology(&self) -> Topology {
        self.topology
    }

    /// Which faces face out, when the mesh is closed (no boundary,
    /// non-manifold or inconsistently wound edge) and each of its pieces
    /// (triangles joined by edges) encloses volume of the same sign; `None`
    /// otherwise, and for pieces of (next to) no volume.
    ///
    /// Seen from a point outside the mesh's bounds, the winding number is 0,
    /// and with every piece of one sign it is never of the other anywhere:
    /// a ray's first crossing of the surface enters (for [`Solid::Outward`]),
    /// through a front face. Pieces may overlap; a single piece whose surface
    /// crosses itself into a region of the other sign is not detected.
    pub fn solid(&self) -> Option<Solid> {
        self.solid
    }

    /// Local-space bounds.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The three local positions of triangle `t`.
    pub fn triangle(&self, t: usize) -> [Vec3; 3] {
        self.triangles[t].map(|i| self.positions[i as usize])
    }
}

/// [`Mesh::solid`] of a closed mesh: its pieces by union-find over shared
/// edges, and each piece's signed volume (the divergence theorem, relative
/// to the bounds' centre for precision); `None` when pieces differ in sign or
/// one is flat (below `1e-9` of the cube of the bounds' diagonal).
fn solid(
    positions: &[Vec3],
    tris: &[[u32; 3]],
    triangle_edges: &[[EdgeRef; 3]],
    edges: usize,
    bounds: Aabb,
) -> Option<Solid> {
    fn root(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            let up = parent[parent[i as usize] as usize];
            parent[i as usize] = up;
            i = up;
        }
        i
    }
    let mut parent: Vec<u32> = (0..tris.len() as u32).collect();
    let mut first = vec![u32::MAX; edges];
    for (t, te) in triangle_edges.iter().enumerate() {
        for r in te {
            let f = &mut first[r.index()];
            if *f == u32::MAX {
                *f = t as u32;
            } else {
                let (a, b) = (root(&mut parent, *f), root(&mut parent, t as u32));
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    let centre = bounds.center();
    let mut volume = vec![0f64; tris.len()];
    for (t, tri) in tris.iter().enumerate() {
        let [a, b, c] = tri.map(|i| positions[i as usize].as_dvec3() - centre);
        let r = root(&mut parent, t as u32) as usize;
        volume[r] += a.dot(b.cross(c)) / 6.0;
    }
    let flat = 1e-9 * (bounds.max - bounds.min).as_dvec3().length().powi(3);
    let mut sign = None;
    for (t, &v) in volume.iter().enumerate() {
        if parent[t] != t as u32 {
            continue;
        }
        let s = match v {
            v if v > flat => Solid::Outward,
            v if v < -flat => Solid::Inward,
            _ => return None,
        };
        if *sign.get_or_insert(s) != s {
            return None;
        }
    }
    sign
}

/// [`Mesh::new`]'s first step: checks the indices and positions, welds the
/// vertices the triangles use (bit-identical positions, −0 = +0, in
/// first-use order), and drops degenerate triangles (two welded vertices
/// equal, or zero area) and the vertices only they used. Returns the
/// welded positions, the kept triangles and how many were dropped.
fn weld(
    name: &str,
    positions: &[Vec3],
    triangles: &[[u32; 3]],
) -> Result<(Vec<Vec3>, Vec<[u32; 3]>, usize)> {
    let n = positions.len();
    for (t, tri) in triangles.iter().enumerate() {
        for &i in tri {
            if i as usize >= n {
                return Err(Error::InvalidMesh {
                    mesh: name.to_string(),
                    message: format!(
                        "triangle {t} uses vertex {i}, but there are only {n} vertices"
                    ),
                });
            }
            if !positions[i as usize].is_finite() {
                return Err(Error::InvalidMesh {
                    mesh: name.to_string(),
                    message: format!("vertex {i} (used by triangle {t}) is not finite"),
                });
            }
        }
    }
    // Weld only the vertices that triangles use, in first-use order.
    let mut remap = vec![u32::MAX; n];
    let mut lookup: Table<[u32; 3], u32> = Table::with_capacity_and_hasher(n, Default::default());
    let mut welded: Vec<Vec3> = Vec::new();
    let mut tris = Vec::with_capacity(triangles.len());
    let mut degenerate = 0;
    for tri in triangles {
        let w = tri.map(|i| {
            let slot = &mut remap[i as usize];
            if *slot == u32::MAX {
                let p = positions[i as usize];
                *slot = *lookup.entry(weld_key(p)).or_insert_with(|| {
                    welded.push(p + Vec3::ZERO);
                    (welded.len() - 1) as u32
                });
            }
            *slot
        });
        if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] {
            degenerate += 1;
            continue;
        }
        let [a, b, c] = w.map(|i| welded[i as usize].as_dvec3());
        if (b - a).cross(c - a) == DVec3::ZERO {
            degenerate += 1;
            continue;
        }
        tris.push(w);
    }
    // Drop vertices that only degenerate triangles used.
    let mut used = vec![u32::MAX; welded.len()];
    let mut compact = Vec::with_capacity(welded.len());
    for t in &mut tris {
        for i in t.iter_mut() {
            if used[*i as usize] == u32::MAX {
                used[*i as usize] = compact.len() as u32;
                compact.push(welded[*i as usize]);
            }
            *i = used[*i as usize];
        }
    }
    Ok((compact, tris, degenerate))
}

/// The edge counts of [`Topology`] (boundary, non-manifold, inconsistently
/// wound; no degenerate triangles) of an edge table.
fn edge_topology(edges: &[Edge], triangle_edges: &[[EdgeRef; 3]]) -> Topology {
    let mut topology = Topology::default();
    let mut forward = vec![0u32; edges.len()];
    for te in triangle_edges {
        for r in te {
            if r.sign() > 0 {
                forward[r.index()] += 1;
            }
        }
    }
    for (e, edge) in edges.iter().enumerate() {
        let backward = edge.triangles - forward[e];
        match edge.triangles {
            1 => topology.boundary_edges += 1,
            2 => {}
            _ => topology.non_manifold_edges += 1,
        }
        if edge.triangles >= 2 && (forward[e] >= 2 || backward >= 2) {
            topology.inconsistent_edges += 1;
        }
    }
    topology
}

fn build_edges(tris: &[[u32; 3]]) -> (Vec<Edge>, Vec<[EdgeRef; 3]>) {
    let mut index: Table<u64, u32> =
        Table::with_capacity_and_hasher(tris.len() * 3 / 2, Default::default());
    let mut edges: Vec<Edge> = Vec::with_capacity(tris.len() * 3 / 2);
    let triangle_edges = tris
        .iter()
        .map(|t| {
            std::array::from_fn(|k| {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let (lo, hi, reversed) = if a < b { (a, b, false) } else { (b, a, true) };
                let e = *index
                    .entry(u64::from(lo) << 32 | u64::from(hi))
                    .or_insert_with(|| {
                        edges.push(Edge {
                            v: [lo, hi],
                            triangles: 0,
                            winding_sum: 0,
                        });
                        (edges.len() - 1) as u32
                    });
                let r = EdgeRef::new(e, reversed);
                let edge = &mut edges[e as usize];
                edge.triangles += 1;
                edge.winding_sum += r.sign();
                r
            })
        })
        .collect();
    (edges, triangle_edges)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unit cube as 12 CCW-outward triangles with 24 unwelded corners (like the
    /// Cornell boxes), so welding must find the 8 real vertices.
    fn soup_cube() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        use crate::procedural::analytic::{box_corners, BOX_FACES};
        let c = box_corners(Vec3::ZERO, Vec3::ONE);
        let mut pos = Vec::new();
        let mut tris = Vec::new();
        for f in BOX_FACES {
            let base = pos.len() as u32;
            pos.extend(f.iter().map(|&i| c[i as usize]));
            tris.push([base, base + 1, base + 2]);
            tris.push([base, base + 2, base + 3]);
        }
        (pos, tris)
    }

    /// Every field of two meshes (a `Mesh` has no `PartialEq`: its float
    /// positions compare bit for bit here).
    fn assert_same(a: &Mesh, b: &Mesh) {
        assert_eq!(a.name(), b.name());
        let bits = |m: &Mesh| {
            m.positions()
                .iter()
                .map(|p| weld_key(*p))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(a), bits(b));
        assert_eq!(a.triangles(), b.triangles());
        assert_eq!(a.edges(), b.edges());
        assert_eq!(a.triangle_edges(), b.triangle_edges());
        assert_eq!(a.topology(), b.topology());
        assert_eq!(a.bounds(), b.bounds());
        assert_eq!(a.solid(), b.solid());
    }

    /// `deformed` is `new` on the new positions, whether the deformation
    /// keeps the welded triangles (the edge table is reused), welds two
    /// vertices into one (a triangle degenerates), or turns the mesh inside
    /// out (the solid side is found again).
    #[test]
    fn a_deformed_mesh_is_the_mesh_built_anew() {
        let (p, t) = soup_cube();
        let cube = Mesh::new("cube", &p, &t).unwrap();
        let stretched: Vec<Vec3> = p.iter().map(|v| *v * Vec3::new(2.0, 1.0, 0.5)).collect();
        let flipped: Vec<Vec3> = p.iter().map(|v| *v * Vec3::new(-1.0, 1.0, 1.0)).collect();
        // Every corner at x = 1 moved onto x = 0: the cube flattens, its
        // eight side triangles degenerate.
        let flat: Vec<Vec3> = p
            .iter()
            .map(|v| {
                if v.x == 1.0 {
                    Vec3::new(0.0, v.y, v.z)
                } else {
                    *v
                }
            })
            .collect();
        for (what, q) in [
            ("stretched", &stretched),
            ("flipped", &flipped),
            ("flat", &flat),
        ] {
            let d = cube.deformed(q, &t).unwrap();
            assert_same(&d, &Mesh::new("cube", q, &t).unwrap());
            assert_eq!(d.solid().is_some(), what != "flat", "{what}");
        }
        assert_eq!(
            cube.deformed(&flipped, &t).unwrap().solid(),
            Some(Solid::Inward)
        );
        assert_eq!(cube.deformed(&flat, &t).unwrap().triangles().len(), 4);
        // Bad input is refused as `new` refuses it.
        let mut nan = p.clone();
        nan[0].x = f32::NAN;
        assert_eq!(
            cube.deformed(&nan, &t).unwrap_err().to_string(),
            Mesh::new("cube", &nan, &t).unwrap_err().to_string()
        );
    }

    #[test]
    fn welded_cube_is_closed_and_consistent() {
        let (p, t) = soup_cube();
        let m = Mesh::new("cube", &p, &t).unwrap();
        assert_eq!(m.positions().len(), 8);
        assert_eq!(m.triangles().len(), 12);
        assert_eq!(m.edges().len(), 18);
        assert_eq!(m.topology(), Topology::default());
        for e in m.edges() {
            assert_eq!(e.triangles, 2);
            assert_eq!(e.winding_sum, 0);
        }
    }

    /// `soup_cube` moved by `d` and scaled by `s`, its indices after `base`.
    fn cube_at(d: Vec3, s: f32, base: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let (p, t) = soup_cube();
        let p = p.into_iter().map(|p| p * s + d).collect();
        (p, t.into_iter().map(|t| t.map(|i| i + base)).collect())
    }

    /// Closed meshes whose pieces all enclose volume of one sign are solid
    /// with that sign; a flipped piece of another sign, an open, inconsistent
    /// or flat mesh are not.
    #[test]
    fn solid_needs_closed_pieces_of_one_sign() {
        let flip = |t: Vec<[u32; 3]>| t.into_iter().map(|[a, b, c]| [a, c, b]).collect();
        let join = |a: (Vec<Vec3>, Vec<[u32; 3]>), b: (Vec<Vec3>, Vec<[u32; 3]>)| {
            ([a.0, b.0].concat(), [a.1, b.1].concat())
        };
        let solid = |(p, t): (Vec<Vec3>, Vec<[u32; 3]>)| Mesh::new("m", &p, &t).unwrap().solid();
        let far = Vec3::new(1e4, -3e3, 2e4);
        assert_eq!(solid(cube_at(Vec3::ZERO, 1.0, 0)), Some(Solid::Outward));
        assert_eq!(solid(cube_at(far, 0.5, 0)), Some(Solid::Outward));
        let (p, t) = cube_at(far, 7.0, 0);
        assert_eq!(solid((p, flip(t))), Some(Solid::Inward));
        // Two pieces, overlapping or apart: solid while their signs agree.
        let two = |d: Vec3, flipped: bool| {
            let b = cube_at(d, 2.0, 24);
            let b = if flipped { (b.0, flip(b.1)) } else { b };
            solid(join(cube_at(Vec3::ZERO, 1.0, 0), b))
        };
        assert_eq!(two(Vec3::splat(0.5), false), Some(Solid::Outward));
        assert_eq!(two(Vec3::splat(5.0), false), Some(Solid::Outward));
        // A hollow shell (an inner piece wound inward) and a flipped piece
        // apart: mixed signs.
        assert_eq!(two(Vec3::splat(-0.5), true), None);
        assert_eq!(two(Vec3::splat(5.0), true), None);
        // Open (one face missing), inconsistent (one triangle flipped).
        let (p, t) = soup_cube();
        assert_eq!(solid((p.clone(), t[2..].to_vec())), None);
        let mut bad = t.clone();
        bad[0].swap(1, 2);
        assert_eq!(solid((p.clone(), bad)), None);
        // A closed double-sided sheet encloses nothing.
        let sheet: Vec<[u32; 3]> = vec![[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]];
        let quad = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        assert_eq!(
            Mesh::new("sheet", &quad, &sheet).unwrap().topology(),
            Topology::default()
        );
        assert_eq!(solid((quad, sheet)), None);
    }

    #[test]
    fn flipped_face_counts_inconsistent_edges() {
        let (p, mut t) = soup_cube();
        t[0].swap(1, 2);
        let m = Mesh::new("cube", &p, &t).unwrap();
        assert_eq!(m.topology().inconsistent_edges, 3);
    }

    #[test]
    fn negative_zero_welds_and_degenerates_are_dropped() {
        let p = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(-0.0, 0.0, -0.0),
            Vec3::new(2.0, 0.0, 0.0),
        ];
        // Triangle 1 repeats the origin (as −0), triangle 2 is collinear.
        let m = Mesh::new("t", &p, &[[0, 1, 2], [3, 0, 2], [0, 1, 4]]).unwrap();
        assert_eq!(m.positions().len(), 3);
        assert_eq!(m.triangles().len(), 1);
        assert_eq!(m.topology().degenerate_triangles, 2);
        assert_eq!(m.topology().boundary_edges, 3);
    }

    #[test]
    fn non_manifold_fin() {
        // Three triangles sharing edge (0,1).
        let p = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            Vec3::new(0.5, -1.0, 0.0),
        ];
        let m = Mesh::new("fin", &p, &[[0, 1, 2], [1, 0, 3], [0, 1, 4]]).unwrap();
        assert_eq!(m.topology().non_manifold_edges, 1);
        assert_eq!(m.topology().inconsistent_edges, 1);
        let e = m.edges().iter().find(|e| e.v == [0, 1]).unwrap();
        assert_eq!(e.triangles, 3);
        assert_eq!(e.winding_sum, 1);
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(Mesh::new("m", &[Vec3::ZERO], &[[0, 0, 1]]).is_err());
        let nan = [Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 0.0, 0.0)];
        let err = Mesh::new("m", &nan, &[[0, 1, 2]]).unwrap_err();
        assert!(err.to_string().contains("mesh `m`"));
    }
}
