//! glTF 2.0 loader: `.gltf` (with external `.bin` files or base64 `data:`
//! URIs) and `.glb`, read into a [`SceneGraph`].
//!
//! Only what shadow culling needs is read: the default scene's node
//! hierarchy, local transforms (`f64`) and triangle geometry (POSITION and
//! indices). Each glTF mesh *primitive* becomes one scene [`Mesh`](crate::Mesh),
//! so a node whose mesh has k triangle primitives carries k mesh ids and
//! yields k objects; meshes are built once and shared by every node that
//! instances them. Node `i` of the file is `NodeId(i)` of the graph.
//!
//! Why it is written this way: glTF files in the wild are often broken, and
//! the `gltf` wrapper crate panics or misreads on dangling indices, wrong
//! accessor types, float indices, quantized positions and lying GLB headers.
//! So the GLB container is parsed here with every length checked against the
//! real bytes, the JSON goes through `serde_json`/`gltf-json` inside
//! `catch_unwind`, one element at a time when geometry needs it, and every
//! lookup is bounds-checked. Images and materials are never read, so missing
//! textures or appearance-only required extensions never stop geometry from
//! loading. Node hierarchies are walked with explicit stacks, never
//! recursion. Bad input is an [`Error`](crate::Error) naming the file and the element
//! (`accessor 3`, `node 5`, `mesh 2 primitive 1`, `GLB header`, `buffer 0`);
//! anything skipped or repaired is a warning in [`SceneGraph::warnings`].
//!
//! Supported: modes TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN (POINTS and
//! LINES* are skipped with a warning), u8/u16/u32 indices or none, sparse
//! accessors, `KHR_mesh_quantization` (integer positions), and
//! `KHR_node_visibility`. Not supported, and an error when required:
//! `KHR_draco_mesh_compression`, `EXT_meshopt_compression`,
//! `EXT_mesh_gpu_instancing`. Skins and morph targets are ignored (meshes
//! are loaded in their rest pose, with a warning for skins). glTF 1.0 is
//! rejected with a clear error.

mod accessor;
mod buffers;
mod document;
mod glb;
mod hierarchy;
mod primitive;

use crate::{MeshId, Node, NodeId, Result, SceneGraph};
use document::{Ctx, Document};
use std::path::Path;

/// Loads a `.gltf` or `.glb` file; external buffers are read relative to
/// the file's directory.
///
/// # Errors
/// [`Error::Io`](crate::Error::Io) when the file or one of its buffers
/// cannot be read (for a buffer, `path` is the buffer file and
/// `referenced_from` the glTF file); [`Error::Load`](crate::Error::Load)
/// naming the file and element for malformed or unsupported content (see
/// [`load_gltf_slice`]).
pub fn load_gltf(path: &Path) -> Result<SceneGraph> {
    let bytes = super::input::read_file(path, None)?;
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let mut resolve = |uri: &str| super::input::read_input(&dir.join(uri));
    load_gltf_slice(&bytes, path, &mut resolve)
}

/// Loads glTF 2.0 from the bytes of a `.gltf` (JSON) or `.glb` (binary) file.
///
/// `file` names the source in errors and warnings, and decides the format
/// together with the content (a `.glb` name or the `glTF` magic means GLB).
/// `resolve(uri)` returns the bytes of an external buffer, given its
/// percent-decoded relative URI; it is called at most once per buffer, and
/// only for buffers that the default scene's geometry uses.
///
/// # Errors
/// [`Error::Load`](crate::Error::Load) naming `file` and the element on: a
/// malformed GLB container; invalid JSON; glTF 1.0 or another version than
/// 2.x; a required extension that changes geometry and is not supported;
/// dangling indices; node cycles or nesting deeper than
/// [`crate::MAX_NODE_DEPTH`]; non-finite transforms or positions; accessors
/// with the wrong type or component type, or whose data lies outside their
/// buffer view or buffer; indices past the vertex count.
/// [`Error::Io`](crate::Error::Io) when `resolve` fails (with `path` = the
/// buffer file next to `file`, `referenced_from` = `file`).
pub fn load_gltf_slice(
    bytes: &[u8],
    file: &Path,
    resolve: &mut dyn FnMut(&str) -> std::io::Result<Vec<u8>>,
) -> Result<SceneGraph> {
    let mut ctx = Ctx::new(file);
    let glb_name = file
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    let is_glb = glb_name || bytes.starts_with(glb::MAGIC);
    let (json, bin) = if is_glb {
        let glb = glb::parse(bytes, &mut ctx)?;
        (glb.json, glb.bin)
    } else {
        (bytes, None)
    };
    let doc = Document::parse(json, &mut ctx)?;
    let hierarchy = hierarchy::load_hierarchy(&doc, &mut ctx)?;
    let mut bufs = buffers::Buffers::new(&doc, bin, is_glb, resolve, &ctx)?;
    let mut graph = SceneGraph::new();
    let mut built: Vec<Option<Vec<MeshId>>> = vec![None; doc.len("meshes", &ctx)?];
    for (i, node) in hierarchy.nodes.into_iter().enumerate() {
        let meshes = match node.mesh {
            Some(m) => match built.get(m) {
                Some(Some(ids)) => ids.clone(),
                Some(None) => {
                    let referrer = format!("node {i}");
                    let ids =
                        primitive::load_mesh(&doc, &mut bufs, m, &referrer, &mut ctx, &mut graph)?;
                    built[m] = Some(ids.clone());
                    ids
                }
                None => {
                    return Err(ctx.err(format!("node {i}"), format!("mesh {m} does not exist")))
                }
            },
            None => Vec::new(),
        };
        graph.add_node(Node {
            name: node.name,
            transform: node.transform,
            meshes,
            children: node
                .children
                .into_iter()
                .map(|c| NodeId(c as u32))
                .collect(),
        });
    }
    for r in hierarchy.roots {
        graph.push_root(NodeId(r as u32));
    }
    for w in ctx.into_warnings() {
        graph.warn(w);
    }
    Ok(graph)
}
