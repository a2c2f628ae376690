//! The scene crate's one error type.

use std::path::PathBuf;

/// Everything that can go wrong while building, loading or updating a scene.
///
/// Every variant names what the user has to look at: the file (and the element
/// or line inside it), the light field, the camera field or the mesh.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read. `path` is the file that failed; when it was
    /// referenced from another file (a glTF `.bin`, an OBJ in a directory),
    /// `referenced_from` names that file. Fix: check the path exists and is readable.
    #[error("{}: cannot read{}: {source}", path.display(), referenced_from.as_ref().map(|r| format!(" (referenced from {})", r.display())).unwrap_or_default())]
    Io {
        /// The file that could not be read.
        path: PathBuf,
        /// The file that referenced it, if any.
        referenced_from: Option<PathBuf>,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A scene file is malformed or uses something the loader cannot represent.
    /// `element` locates the problem: `line 12`, `accessor 3`, `node 5`, `GLB header`.
    #[error("{}: {element}: {message}", file.display())]
    Load {
        /// The file given to the loader.
        file: PathBuf,
        /// Where in the file: a line number or a glTF element and index.
        element: String,
        /// What is wrong.
        message: String,
    },
    /// An object id names no live object: out of range, removed, or stale
    /// (its slot was reused by a newer object). Fix: use the id the latest
    /// `add_object` returned, and stop using it after removing the object.
    #[error("object {id}: {message}")]
    UnknownObject {
        /// The id as given.
        id: crate::ObjectId,
        /// Why it is not a live object.
        message: String,
    },
    /// A mesh id names no live mesh, or a mesh cannot be removed because
    /// objects still instance it. Fix: remove those objects first.
    #[error("mesh {mesh}: {message}")]
    UnknownMesh {
        /// The mesh id.
        mesh: crate::MeshId,
        /// What is wrong.
        message: String,
    },
    /// A light's parameters are invalid (NaN position, zero or NaN direction,
    /// cone of 180° or more, non-positive range).
    #[error("invalid light: field `{field}`: {message}")]
    InvalidLight {
        /// The offending field (`position`, `direction`, `apex_angle`, `range`).
        field: &'static str,
        /// What is wrong with it.
        message: String,
    },
    /// A camera's parameters are invalid (eye equal to target, up parallel to the
    /// view direction, field of view outside (0°, 180°), non-positive near or aspect).
    #[error("invalid camera: field `{field}`: {message}")]
    InvalidCamera {
        /// The offending field.
        field: &'static str,
        /// What is wrong with it.
        message: String,
    },
    /// A mesh's data is invalid (index out of range, non-finite position).
    #[error("mesh `{mesh}`: {message}")]
    InvalidMesh {
        /// The mesh's name.
        mesh: String,
        /// What is wrong with it.
        message: String,
    },
    /// A host object's transform is unusable: an element is not finite, or
    /// it is projective (its bottom row is not (0, 0, 0, 1): meshes are
    /// placed by affine transforms, and a projective one would give masks
    /// that disagree with the reference). `object` names the object: its id,
    /// or the mesh of the object being added.
    #[error("{object}: transform {message}")]
    Transform {
        /// The object: `object 5`, or `the object being added (mesh 2)`.
        object: String,
        /// What is wrong.
        message: String,
    },
    /// The scene graph is malformed: a node cycle, a dangling node or mesh index,
    /// a non-finite or projective transform, or nesting deeper than
    /// [`crate::MAX_NODE_DEPTH`].
    #[error("scene graph: node {node}: {message}")]
    Graph {
        /// Index of the offending node.
        node: u32,
        /// What is wrong.
        message: String,
    },
}

/// Result with the scene crate's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
