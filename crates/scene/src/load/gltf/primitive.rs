//! Mesh primitives → scene meshes: one [`Mesh`] per triangle primitive.
//!
//! TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN are assembled into triangle
//! lists (strips alternate their winding so every triangle keeps the first
//! one's orientation, glTF 2.0 §3.7.2.1); POINTS and LINES* are skipped with a
//! warning. Indices are checked against the vertex count here, so a bad index
//! is reported with the file and the primitive.

use super::accessor::{read_indices, read_positions};
use super::buffers::Buffers;
use super::document::{check_u32, deserialize, Ctx, Document};
use crate::{Mesh, MeshId, Result, SceneGraph};
use gltf_json::mesh::{Mode, Semantic};
use gltf_json::validation::Checked;
use serde_json::Value;

/// Builds the scene meshes of glTF mesh `index` (one per triangle primitive;
/// skipped primitives produce none) and adds them to `graph`.
///
/// # Errors
/// [`crate::Error::Load`] naming the mesh, primitive, accessor, bufferView or
/// buffer; [`crate::Error::Io`] when an external buffer cannot be read.
pub(super) fn load_mesh(
    doc: &Document,
    bufs: &mut Buffers<'_, '_>,
    index: usize,
    referrer: &str,
    ctx: &mut Ctx<'_>,
    graph: &mut SceneGraph,
) -> Result<Vec<MeshId>> {
    let element = format!("mesh {index}");
    let raw = doc.raw("meshes", "mesh", index, referrer, ctx)?;
    let raw_prims = raw.get("primitives").and_then(Value::as_array);
    for (p, prim) in raw_prims.into_iter().flatten().enumerate() {
        let element = format!("mesh {index} primitive {p}");
        for path in [&["indices"][..], &["attributes", "POSITION"], &["mode"]] {
            check_u32(prim, path, &element, ctx)?;
        }
    }
    let mesh: gltf_json::Mesh = deserialize(raw, &element, ctx)?;
    let base = mesh.name.clone().unwrap_or(element);
    let several = mesh.primitives.len() > 1;
    let mut ids = Vec::new();
    for (p, prim) in mesh.primitives.iter().enumerate() {
        let element = format!("mesh {index} primitive {p}");
        let mode = match prim.mode {
            Checked::Valid(m @ (Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan)) => m,
            Checked::Valid(other) => {
                let name = match other {
                    Mode::Points => "POINTS",
                    Mode::Lines => "LINES",
                    Mode::LineLoop => "LINE_LOOP",
                    _ => "LINE_STRIP",
                };
                ctx.warn(
                    &element,
                    format!("mode {name} is not a triangle mode; skipped"),
                );
                continue;
            }
            Checked::Invalid => return Err(ctx.err(element, "mode is not a valid primitive mode")),
        };
        let Some(position) = prim.attributes.get(&Checked::Valid(Semantic::Positions)) else {
            ctx.warn(&element, "has no POSITION attribute; skipped");
            continue;
        };
        let position = position.value();
        let draco = prim
            .extensions
            .as_ref()
            .is_some_and(|e| e.others.contains_key("KHR_draco_mesh_compression"));
        if draco {
            let acc = doc.raw("accessors", "accessor", position, &element, ctx)?;
            if acc.get("bufferView").is_none() && acc.get("sparse").is_none() {
                return Err(ctx.err(
                    element,
                    "is compressed with KHR_draco_mesh_compression and has no uncompressed \
                     fallback; Draco is not supported",
                ));
            }
        }
        let positions = read_positions(doc, bufs, position, &element, ctx)?;
        let n = positions.len();
        if u32::try_from(n).is_err() {
            return Err(ctx.err(
                element,
                format!("{n} vertices are more than a u32 index can address"),
            ));
        }
        let indices = match prim.indices {
            Some(i) => {
                let i = i.value();
                let indices = read_indices(doc, bufs, i, &element, ctx)?;
                if let Some((k, v)) = indices.iter().enumerate().find(|(_, &v)| v as usize >= n) {
                    return Err(ctx.err(
                        element,
                        format!(
                            "index {k} of accessor {i} is {v}, but POSITION accessor {position} has only {n} vertices"
                        ),
                    ));
                }
                Some(indices)
            }
            None => None,
        };
        let count = indices.as_ref().map_or(n, Vec::len);
        if mode == Mode::Triangles && count % 3 != 0 {
            ctx.warn(
                &element,
                format!(
                    "{count} vertices are not a multiple of 3; the last {} are ignored",
                    count % 3
                ),
            );
        }
        let at = |k: usize| indices.as_ref().map_or(k as u32, |ix| ix[k]);
        let triangles = assemble(mode, count, at);
        let name = if several {
            format!("{base} primitive {p}")
        } else {
            base.clone()
        };
        let mesh = Mesh::new(name, &positions, &triangles)
            .map_err(|e| ctx.err(&element, e.to_string()))?;
        if mesh.triangles().is_empty() {
            ctx.warn(
                &element,
                format!(
                    "has no non-degenerate triangles ({} given); skipped",
                    triangles.len()
                ),
            );
            continue;
        }
        ids.push(graph.add_mesh(mesh));
    }
    Ok(ids)
}

/// Triangle list of `count` vertices in `mode`; `at(k)` is the k-th vertex index.
fn assemble(mode: Mode, count: usize, at: impl Fn(usize) -> u32) -> Vec<[u32; 3]> {
    match mode {
        Mode::TriangleStrip => (0..count.saturating_sub(2))
            .map(|i| {
                if i % 2 == 0 {
                    [at(i), at(i + 1), at(i + 2)]
                } else {
                    [at(i), at(i + 2), at(i + 1)]
                }
            })
            .collect(),
        Mode::TriangleFan => (0..count.saturating_sub(2))
            .map(|i| [at(0), at(i + 1), at(i + 2)])
            .collect(),
        _ => (0..count / 3)
            .map(|t| [at(3 * t), at(3 * t + 1), at(3 * t + 2)])
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_keep_the_first_triangles_orientation() {
        // Even vertices along the bottom, odd ones along the top.
        let p = |k: u32| [(k / 2) as f32 + 0.5 * (k % 2) as f32, (k % 2) as f32];
        let area = |[a, b, c]: [u32; 3]| {
            let (a, b, c) = (p(a), p(b), p(c));
            (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        };
        let t = assemble(Mode::TriangleStrip, 7, |k| k as u32);
        assert_eq!(
            t,
            vec![[0, 1, 2], [1, 3, 2], [2, 3, 4], [3, 5, 4], [4, 5, 6]]
        );
        let first = area(t[0]).signum();
        assert!(t.iter().all(|&tri| area(tri).signum() == first));
    }

    #[test]
    fn fans_share_the_first_vertex() {
        let t = assemble(Mode::TriangleFan, 5, |k| k as u32);
        assert_eq!(t, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
        assert!(assemble(Mode::TriangleFan, 2, |k| k as u32).is_empty());
    }

    #[test]
    fn triangle_lists_drop_an_incomplete_tail() {
        assert_eq!(assemble(Mode::Triangles, 7, |k| k as u32).len(), 2);
    }
}
