//! # shadowcull-scene
//!
//! Scene graph, meshes and their topology, loaders (glTF 2.0, OBJ, the box-city
//! benchmark format, procedural cities), the object BVH, and the geometry types
//! every other shadowcull crate shares (`Aabb`, `Plane`, `Frustum`, `Camera`,
//! `Light`), plus the one transform path and the one facing rule.
//!
//! Cargo features, both default: `gltf` — the glTF loader `load::gltf` (gltf-json, serde_json);
//! `obj` — the OBJ loader `load::obj` (tobj, spade). Box city and procedural scenes are always built.
//!
//! # Conventions
//! - Right-handed world, +y up, column vectors; glam `f32` for vertex data,
//!   `f64` for transforms, camera and light positions, planes and facing.
//! - Triangles are counter-clockwise seen from the front; mirrored instances
//!   are reported with flipped winding ([`Scene::world_triangle`]).
//! - Projection: reversed Z with an infinite far plane — depth 1 at the near
//!   plane, 0 at infinity ([`Camera::projection`]).
//! - Planes: inside is the positive side.
//! - `clip_from_local` is composed in f64 in eye-relative form and rounded to
//!   f32 once ([`transform::clip_from_local`]).
//! - A triangle faces a light when the light is strictly on its front side
//!   ([`faces_light`]).
#![forbid(unsafe_code)]

mod aabb;
pub mod bvh_build;
mod camera;
mod camera_path;
mod error;
mod facing;
mod frustum;
mod graph;
mod host_camera;
mod ids;
pub mod load;
mod loaded;
mod mesh;
mod occluder_proxy;
mod plane;
pub mod procedural;
mod scene;
mod splitmix;
mod strided;
pub mod transform;

pub use aabb::Aabb;
pub use camera::{Camera, LookAt, Rays};
pub use camera_path::CameraPath;
pub use error::{Error, Result};
pub use facing::faces_light;
pub use frustum::Frustum;
pub use graph::{Node, NodeId, SceneGraph, Transform};
pub use host_camera::{ClipDepth, HostBasis};
pub use ids::{LightId, MeshId, ObjectId};
pub use light::Light;
pub use mesh::{Edge, EdgeRef, Mesh, Solid, Topology};
pub use occluder_proxy::{is_convex_solid, occluder_proxy, PROXY_VERTICES};
pub use plane::Plane;
pub use scene::{Committed, Object, ObjectFlags, Scene, SceneCounts, MAX_NODE_DEPTH, MAX_OBJECTS};
pub use splitmix::splitmix64;
pub use strided::{Indices, PositionFormat, StridedPositions};

mod light;
