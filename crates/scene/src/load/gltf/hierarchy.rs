//! The node hierarchy of the default scene: reference checks, one parent per
//! node, cycle detection, root selection and local transforms — all with
//! loops over explicit stacks, never recursion, so a hostile file can neither
//! hang the loader nor overflow its stack.

use super::document::{deserialize, Ctx, Document};
use crate::{Result, Transform, MAX_NODE_DEPTH};
use glam::{DMat4, DQuat, DVec3};
use serde::Deserialize;
use serde_json::{Map, Value};

/// A node as the file states it (transforms read as `f64`).
#[derive(Deserialize)]
struct RawNode {
    name: Option<String>,
    children: Option<Vec<u32>>,
    mesh: Option<u32>,
    matrix: Option<[f64; 16]>,
    translation: Option<[f64; 3]>,
    rotation: Option<[f64; 4]>,
    scale: Option<[f64; 3]>,
    skin: Option<Value>,
    extensions: Option<Map<String, Value>>,
}

#[derive(Deserialize)]
struct RawScene {
    nodes: Option<Vec<u32>>,
}

/// A node ready for the scene graph.
pub(super) struct HNode {
    /// Name from the file (may be empty).
    pub name: String,
    /// Local transform (identity for nodes outside the scene whose transform is invalid).
    pub transform: Transform,
    /// The glTF mesh drawn here, if the node is in the scene and visible.
    pub mesh: Option<usize>,
    /// Children, after dropping links to nodes that already have a parent.
    pub children: Vec<usize>,
}

/// Nodes (indexed as in the file) and the roots of the default scene.
pub(super) struct Hierarchy {
    /// All nodes of the file, in file order.
    pub nodes: Vec<HNode>,
    /// Root nodes of the default scene.
    pub roots: Vec<usize>,
}

/// Reads and checks the node hierarchy and picks the default scene's roots.
///
/// # Errors
/// [`crate::Error::Load`] naming the node or scene: a dangling child, mesh or
/// scene node, a node cycle, nesting deeper than [`MAX_NODE_DEPTH`], or a
/// non-finite transform of a node in the scene.
pub(super) fn load_hierarchy(doc: &Document, ctx: &mut Ctx<'_>) -> Result<Hierarchy> {
    let n = doc.len("nodes", ctx)?;
    let n_meshes = doc.len("meshes", ctx)?;
    let mut raw = Vec::with_capacity(n);
    for i in 0..n {
        let element = format!("node {i}");
        let node: RawNode =
            deserialize(doc.raw("nodes", "node", i, &element, ctx)?, &element, ctx)?;
        for &c in node.children.iter().flatten() {
            if c as usize >= n {
                return Err(ctx.err(
                    element,
                    format!("child {c} does not exist (the file has {n} nodes)"),
                ));
            }
        }
        if let Some(m) = node.mesh {
            if m as usize >= n_meshes {
                return Err(ctx.err(
                    element,
                    format!("mesh {m} does not exist (the file has {n_meshes} meshes)"),
                ));
            }
        }
        raw.push(node);
    }

    // One parent per node: later links to an already parented node are dropped.
    let mut parent: Vec<Option<usize>> = vec![None; n];
    let mut children: Vec<Vec<usize>> = Vec::with_capacity(n);
    for (i, node) in raw.iter().enumerate() {
        let mut kept = Vec::new();
        for &c in node.children.iter().flatten() {
            let c = c as usize;
            match parent[c] {
                None => {
                    parent[c] = Some(i);
                    kept.push(c);
                }
                Some(p) => ctx.warn(
                    format!("node {i}"),
                    format!("node {c} is already a child of node {p} (a node may have only one parent); this link is ignored"),
                ),
            }
        }
        children.push(kept);
    }
    check_cycles(&parent, ctx)?;

    let roots = pick_roots(doc, &parent, ctx)?;

    // Walk the scene: reachability and depth, with an explicit stack.
    let hidden: Vec<bool> = raw.iter().map(is_hidden).collect();
    let mut in_scene = vec![false; n];
    let mut stack: Vec<(usize, usize)> = roots.iter().map(|&r| (r, 0)).collect();
    while let Some((i, depth)) = stack.pop() {
        if depth >= MAX_NODE_DEPTH {
            return Err(ctx.err(
                format!("node {i}"),
                format!("nodes are nested deeper than {MAX_NODE_DEPTH} levels"),
            ));
        }
        if in_scene[i] || hidden[i] {
            continue;
        }
        in_scene[i] = true;
        stack.extend(children[i].iter().map(|&c| (c, depth + 1)));
    }

    let skinned = (0..n)
        .filter(|&i| in_scene[i] && raw[i].skin.is_some() && raw[i].mesh.is_some())
        .count();
    if skinned > 0 {
        ctx.warn(
            "skins",
            format!("{skinned} skinned mesh nodes are loaded unskinned (bind pose at the node)"),
        );
    }

    let mut nodes = Vec::with_capacity(n);
    for (i, (node, children)) in raw.into_iter().zip(children).enumerate() {
        let transform = if in_scene[i] {
            local_transform(&node, i, ctx)?
        } else {
            // Outside the scene nothing draws it; a bad transform is not an error there.
            let mut quiet = Ctx::new(ctx.file());
            local_transform(&node, i, &mut quiet).unwrap_or_default()
        };
        let visible = in_scene[i] && !hidden[i];
        nodes.push(HNode {
            name: node.name.unwrap_or_default(),
            transform,
            mesh: node.mesh.map(|m| m as usize).filter(|_| visible),
            children: if hidden[i] { Vec::new() } else { children },
        });
    }
    Ok(Hierarchy { nodes, roots })
}

/// `KHR_node_visibility`: `visible: false` hides a node and its subtree.
fn is_hidden(node: &RawNode) -> bool {
    node.extensions
        .as_ref()
        .and_then(|e| e.get("KHR_node_visibility"))
        .and_then(|v| v.get("visible"))
        .and_then(Value::as_bool)
        == Some(false)
}

/// With at most one parent per node, a cycle is a loop of parent links.
/// Each node is walked at most once (state 1 = on the current walk, 2 = done).
fn check_cycles(parent: &[Option<usize>], ctx: &Ctx<'_>) -> Result<()> {
    let mut state = vec![0u8; parent.len()];
    let mut walk = Vec::new();
    for start in 0..parent.len() {
        walk.clear();
        let mut i = Some(start);
        while let Some(j) = i {
            match state[j] {
                2 => break,
                1 => {
                    // j is its own ancestor: report the loop from parent to child.
                    let from = walk.iter().position(|&w| w == j).unwrap_or(0);
                    let mut cycle: Vec<usize> = walk[from..].to_vec();
                    cycle.reverse();
                    cycle.push(cycle[0]);
                    let shown: Vec<String> =
                        cycle.iter().take(9).map(|c| format!("node {c}")).collect();
                    let more = if cycle.len() > 9 { " → ..." } else { "" };
                    return Err(ctx.err(
                        format!("node {j}"),
                        format!(
                            "node cycle: {}{more} (a node is its own ancestor)",
                            shown.join(" → ")
                        ),
                    ));
                }
                _ => {
                    state[j] = 1;
                    walk.push(j);
                    i = parent[j];
                }
            }
        }
        for &w in &walk {
            state[w] = 2;
        }
    }
    Ok(())
}

/// The default scene's roots: `scene`, else scene 0, else every node without
/// a parent (with a warning).
fn pick_roots(doc: &Document, parent: &[Option<usize>], ctx: &mut Ctx<'_>) -> Result<Vec<usize>> {
    let n = parent.len();
    let n_scenes = doc.len("scenes", ctx)?;
    let declared: Option<u32> = match doc.field("scene") {
        None | Some(Value::Null) => None,
        Some(v) => Some(deserialize(v, "scene", ctx)?),
    };
    let chosen = match declared {
        Some(s) if (s as usize) < n_scenes => Some(s as usize),
        Some(s) => {
            let fallback = if n_scenes > 0 {
                "scene 0 is used"
            } else {
                "all root nodes are used"
            };
            if n > 0 {
                ctx.warn("scene", format!("default scene {s} does not exist (the file has {n_scenes} scenes); {fallback}"));
            }
            (n_scenes > 0).then_some(0)
        }
        None => (n_scenes > 0).then_some(0),
    };
    let Some(s) = chosen else {
        let roots: Vec<usize> = (0..n).filter(|&i| parent[i].is_none()).collect();
        if n > 0 {
            ctx.warn(
                "scenes",
                format!(
                    "the file has no scenes; all {} root nodes are shown",
                    roots.len()
                ),
            );
        }
        return Ok(roots);
    };
    let element = format!("scene {s}");
    let scene: RawScene = doc.get("scenes", "scene", s, "scene", ctx)?;
    let listed = scene.nodes.unwrap_or_default();
    let mut is_root = vec![false; n];
    let mut roots = Vec::with_capacity(listed.len());
    for &r in &listed {
        let r = r as usize;
        if r >= n {
            return Err(ctx.err(
                element,
                format!("node {r} does not exist (the file has {n} nodes)"),
            ));
        }
        if is_root[r] {
            ctx.warn(&element, format!("lists node {r} twice; drawn once"));
            continue;
        }
        is_root[r] = true;
        roots.push(r);
    }
    // A listed node must be a root; if an ancestor is listed too it is drawn
    // under it only, otherwise it is drawn as a root without its parents.
    let mut under_root: Vec<Option<bool>> = vec![None; n];
    let mut path = Vec::new();
    let mut kept = Vec::with_capacity(roots.len());
    for &r in &roots {
        let Some(p) = parent[r] else {
            kept.push(r);
            continue;
        };
        // Is some ancestor of r listed? Memoized walk up the (acyclic) parent links.
        path.clear();
        let mut i = Some(p);
        let mut answer = false;
        while let Some(j) = i {
            if let Some(known) = under_root[j] {
                answer = known;
                break;
            }
            if is_root[j] {
                answer = true;
                break;
            }
            path.push(j);
            i = parent[j];
        }
        for &j in &path {
            under_root[j] = Some(answer);
        }
        if answer {
            ctx.warn(&element, format!("lists node {r}, which is also drawn as a descendant of another listed node; drawn once"));
        } else {
            ctx.warn(&element, format!("lists node {r}, which has parent {p}; drawn as a root without its parents' transforms"));
            kept.push(r);
        }
    }
    Ok(kept)
}

/// The node's local transform: its matrix, or translation · rotation · scale.
fn local_transform(node: &RawNode, i: usize, ctx: &mut Ctx<'_>) -> Result<Transform> {
    let element = format!("node {i}");
    let has_trs = node.translation.is_some() || node.rotation.is_some() || node.scale.is_some();
    if let Some(m) = node.matrix {
        let m = DMat4::from_cols_array(&m);
        if let Some(fault) = crate::scene::transform_fault(&Transform::Matrix(m)) {
            return Err(ctx.err(element, format!("matrix {fault}")));
        }
        if !has_trs {
            return Ok(Transform::Matrix(m));
        }
        if m != DMat4::IDENTITY {
            ctx.warn(
                &element,
                "has both matrix and translation/rotation/scale; the matrix is used",
            );
            return Ok(Transform::Matrix(m));
        }
    }
    let translation = DVec3::from_array(node.translation.unwrap_or([0.0; 3]));
    let scale = DVec3::from_array(node.scale.unwrap_or([1.0; 3]));
    let [x, y, z, w] = node.rotation.unwrap_or([0.0, 0.0, 0.0, 1.0]);
    let rotation = DQuat::from_xyzw(x, y, z, w);
    if !translation.is_finite() || !scale.is_finite() || !rotation.is_finite() {
        return Err(ctx.err(element, "translation, rotation or scale is not finite"));
    }
    let length = rotation.length();
    if !(length > 1e-12 && length.is_finite()) {
        return Err(ctx.err(
            element,
            format!("rotation {:?} is not a unit quaternion", [x, y, z, w]),
        ));
    }
    if (length - 1.0).abs() > 1e-3 {
        ctx.warn(
            &element,
            format!("rotation has length {length}, not 1; normalized"),
        );
    }
    let rotation = if length == 1.0 {
        rotation
    } else {
        rotation / length
    };
    Ok(Transform::Trs {
        translation,
        rotation,
        scale,
    })
}
