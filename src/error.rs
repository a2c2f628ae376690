//! The facade's error type.

use std::path::PathBuf;

/// Errors of jobs, runs, pipelines and outputs.
///
/// The scene's constructors re-exported here (`Mesh::new`, `Scene::new`,
/// `Camera::from_view_projection*`, `Camera::look_at`) return
/// [`scene::Result`]; a scene error converts into [`Error::Scene`], so one
/// `?` takes both in a function returning [`crate::Result`]:
///
/// ```
/// use shadowcull::glam::{DMat4, Vec3};
/// use shadowcull::scene::{Mesh, ObjectFlags, ObjectId, Scene, SceneGraph};
/// use shadowcull::{Pipeline, PipelineOptions};
///
/// fn upload(p: &mut Pipeline, pos: &[Vec3], tris: &[[u32; 3]]) -> shadowcull::Result<ObjectId> {
///     let mesh = p.add_mesh(Mesh::new("crate", pos, tris)?); // scene::Error → Error::Scene
///     p.add_object(mesh, DMat4::IDENTITY, ObjectFlags::ALL) // shadowcull::Error
/// }
///
/// let mut p = Pipeline::new(Scene::new(SceneGraph::new())?, PipelineOptions::default())?;
/// let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
/// upload(&mut p, &tri, &[[0, 1, 2]])?;
/// let bad = upload(&mut p, &tri, &[[0, 1, 7]]).unwrap_err();
/// assert!(matches!(bad, shadowcull::Error::Scene(_)), "{bad}");
/// # Ok::<(), shadowcull::Error>(())
/// ```
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Loading or building the scene failed (names the file and element).
    #[error(transparent)]
    Scene(#[from] scene::Error),
    /// The rasterizer rejected its input (a bug in the caller, or an oversized target).
    #[error("rasterizer: {0}")]
    Raster(#[from] raster::Error),
    /// Culling failed (a bad light or view names its field).
    #[error("visibility: {0}")]
    Visibility(#[from] visibility::Error),
    /// Shadow-volume construction failed (an invalid light or caster id).
    #[error("shadow volumes: {0}")]
    Shadowgen(#[from] shadowgen::Error),
    /// The job file could not be parsed or holds a bad value. `location` is
    /// `line:column` when the parser knows it. Fix: edit the named field.
    #[error("{}:{location}: {message}", file.display())]
    Job {
        /// The job file.
        file: PathBuf,
        /// `line:column`, or the field path for semantic errors.
        location: String,
        /// What is wrong.
        message: String,
    },
    /// A [`crate::PipelineOptions`] field or a [`crate::FrameInput`] value is
    /// out of range (a viewport size, an invalid light). Fix: change the named
    /// field.
    #[error("{field}: {message}")]
    Options {
        /// The field (`tile`, `viewport`, `lights[1]`).
        field: String,
        /// What is wrong.
        message: String,
    },
    /// A shard of a batch job cannot be run or merged: a bad `--shard`, a
    /// missing, overlapping or foreign shard directory. `path` names the
    /// directory (or the job file); the message says what to rerun or drop.
    #[error("{}: {message}", path.display())]
    Shard {
        /// The shard directory (or job file).
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Another `shadowcull` run, merge or comparison holds the output
    /// directory's lock. Fix: wait for it, or write somewhere else.
    #[error(
        "{}: another shadowcull run is writing to this directory (it holds {}); wait for it to finish or choose another --out",
        dir.display(),
        lock.display()
    )]
    OutputBusy {
        /// The output directory.
        dir: PathBuf,
        /// The lock file the other run holds.
        lock: PathBuf,
    },
    /// A buffer sized by the viewport or the scene could not be allocated.
    /// Fix: a smaller resolution or scene, or lower `max_memory` so that the
    /// run is refused up front.
    #[error("out of memory: {what} need {bytes} bytes")]
    OutOfMemory {
        /// The buffer.
        what: String,
        /// The allocation that failed.
        bytes: u64,
    },
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
}

/// Result with the facade's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

#[cfg(feature = "jobs")]
pub(crate) fn io_err(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |source| Error::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Reads a text file the run did not write itself: a regular file within the
/// input size limit ([`scene::load::read_input`]), UTF-8.
#[cfg(feature = "jobs")]
pub(crate) fn read_text(path: &std::path::Path) -> std::io::Result<String> {
    let bytes = scene::load::read_input(path)?;
    String::from_utf8(bytes).map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e))
}
