//! RON batch jobs: the schema ([`Job`] and its parts), its validation (every
//! bad value named by file and field, or line and column), and its
//! resolution into a flattened scene, a camera path and lights. The job's
//! `pipeline` section is the runtime [`PipelineOptions`] itself.

mod resolve;
mod schema;
mod validate;

pub use crate::pipeline::PipelineOptions;
pub use resolve::{
    fit_side_view, load_scene, load_scene_for_job, prepare_scene, resolve_camera, resolve_lights,
};
pub use schema::{
    default_job, CameraSpec, Ground, Job, LightSpec, NamedPipeline, Outputs, SceneSpec, JOB_VERSION,
};
