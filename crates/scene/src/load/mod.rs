//! Scene loaders. Every loader reads the whole file itself, bounds every size
//! by the real byte length, and reports bad input as an [`Error`] naming the
//! file and the element or line — never a panic. Entry points that take bytes
//! exist for fuzzing.
//!
//! The glTF and OBJ loaders sit behind the default cargo features `gltf` and
//! `obj`; the box-city loader is always built.

pub mod box_city;
#[cfg(feature = "gltf")]
pub mod gltf;
#[cfg(feature = "obj")]
pub mod obj;
#[cfg(feature = "obj")]
mod triangulate;

use crate::{CameraPath, Error, Light, LookAt, Result, SceneGraph};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// What a loader returns: the graph plus the named cameras, camera paths and
/// lights the source defines (empty for plain meshes).
#[derive(Clone, Debug, Default)]
pub struct Loaded {
    /// Geometry and hierarchy (with load warnings).
    pub graph: SceneGraph,
    /// Named camera poses.
    pub cameras: Vec<(String, LookAt)>,
    /// Named camera paths.
    pub paths: Vec<(String, CameraPath)>,
    /// Named lights.
    pub lights: Vec<(String, Light)>,
}

impl Loaded {
    /// A source with geometry only.
    pub fn from_graph(graph: SceneGraph) -> Self {
        Loaded {
            graph,
            ..Default::default()
        }
    }

    /// Appends another source (geometry, cameras, paths, lights).
    pub fn merge(&mut self, other: Loaded) {
        self.graph.merge(other.graph);
        self.cameras.extend(other.cameras);
        self.paths.extend(other.paths);
        self.lights.extend(other.lights);
    }
}

/// A mesh (or a cluster of meshes) whose centre lies farther than this many
/// of its radii from its local origin is recentred by the loaders (see
/// [`recentre`]): its f32 vertices then gain at least four bits.
pub const RECENTRE_RATIO: f64 = 16.0;

/// The translation that recentres geometry with f64 bounds `[min, max]`, or
/// `None` when it stays as written.
///
/// Why: files in world coordinates (city.obj holds buildings a few metres
/// wide near (2.6e5, 9.9e6), where an f32 has a spacing of 1) would give
/// meshes whose f32 local vertices lose the geometry, and whose
/// `clip_from_local`, though composed in f64, is applied in f32 to vertices
/// of 1e7. The centre is the midpoint of the bounds; the loader stores
/// `f32(p − centre)`, formed from the file's values in f64, and puts the
/// translation into the node's transform (f64), so world positions are the
/// file's up to the f32 rounding of the *small* local coordinates. Geometry
/// whose centre lies within [`RECENTRE_RATIO`] radii (radius = largest
/// half-extent) of the origin is not moved.
pub fn recentre(min: glam::DVec3, max: glam::DVec3) -> Option<glam::DVec3> {
    if !(min.is_finite() && max.is_finite()) {
        return None;
    }
    let centre = (min + max) * 0.5;
    let radius = ((max - min) * 0.5).max_element();
    (centre.abs().max_element() > RECENTRE_RATIO * radius).then_some(centre)
}

/// The default largest input file the loaders read (4 GiB): generous for
/// scenes, finite for `/dev/zero` or a runaway generator.
pub const DEFAULT_MAX_INPUT_BYTES: u64 = 4 << 30;

static MAX_INPUT_BYTES: AtomicU64 = AtomicU64::new(DEFAULT_MAX_INPUT_BYTES);

/// Sets, for the whole process, the largest file (scene, glTF buffer, job)
/// that [`read_input`] and the loaders read; larger files are an error
/// before anything is allocated. The CLI's `--max-input-size` sets it.
pub fn set_max_input_bytes(bytes: u64) {
    MAX_INPUT_BYTES.store(bytes, Ordering::Relaxed);
}

/// The largest input file read (see [`set_max_input_bytes`]).
pub fn max_input_bytes() -> u64 {
    MAX_INPUT_BYTES.load(Ordering::Relaxed)
}

/// Reads a whole input file: only a regular file (a FIFO would block
/// forever, a device never end), of at most [`max_input_bytes`].
///
/// # Errors
/// The I/O error; `InvalidInput` for anything but a regular file (naming its
/// kind), `FileTooLarge` past the limit (naming both sizes).
pub fn read_input(path: &Path) -> std::io::Result<Vec<u8>> {
    read_capped(path, max_input_bytes())
}

/// [`read_input`] with the limit `cap`.
pub(crate) fn read_capped(path: &Path, cap: u64) -> std::io::Result<Vec<u8>> {
    use std::io::{Error as IoError, ErrorKind, Read};
    // `metadata` follows symbolic links and opens nothing: a FIFO is refused
    // before an `open` that would wait for a writer.
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(IoError::new(
            ErrorKind::InvalidInput,
            format!(
                "not a regular file ({}): refusing to read it",
                file_kind(&meta)
            ),
        ));
    }
    let too_large = |len: u64| {
        IoError::new(
            ErrorKind::FileTooLarge,
            format!(
                "{len} bytes, more than the input size limit of {cap} bytes (raise it: --max-input-size, or scene::load::set_max_input_bytes)"
            ),
        )
    };
    if meta.len() > cap {
        return Err(too_large(meta.len()));
    }
    let mut bytes = Vec::new();
    bytes
        .try_reserve_exact(meta.len() as usize)
        .map_err(|e| IoError::new(ErrorKind::OutOfMemory, e.to_string()))?;
    // The file may grow while it is read: never past the limit.
    std::fs::File::open(path)?
        .take(cap.saturating_add(1))
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > cap {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// What a non-regular file is, for the error.
fn file_kind(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "not a file"
}

/// Reads a whole input file ([`read_input`]), naming it in the error.
pub(crate) fn read_file(path: &Path, referenced_from: Option<&Path>) -> Result<Vec<u8>> {
    read_input(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        referenced_from: referenced_from.map(Path::to_path_buf),
        source,
    })
}

/// Loads any supported file by its extension: `.gltf`/`.glb` (glTF 2.0),
/// `.obj` (or a directory of `.obj` files, in name order), `.txt` with a
/// `citysc 1` header (box city).
///
/// # Errors
/// The loader's error, or [`Error::Load`] for an unknown extension or a
/// format whose cargo feature (`gltf`, `obj`) is disabled.
pub fn load_path(path: &Path) -> Result<Loaded> {
    if path.is_dir() {
        #[cfg(feature = "obj")]
        return obj::load_obj_dir(path).map(Loaded::from_graph);
        #[cfg(not(feature = "obj"))]
        return Err(feature_disabled(path, "a directory of .obj files", "obj"));
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    match ext.as_str() {
        #[cfg(feature = "gltf")]
        "gltf" | "glb" => gltf::load_gltf(path).map(Loaded::from_graph),
        #[cfg(not(feature = "gltf"))]
        "gltf" | "glb" => Err(feature_disabled(path, "glTF", "gltf")),
        #[cfg(feature = "obj")]
        "obj" => obj::load_obj(path).map(Loaded::from_graph),
        #[cfg(not(feature = "obj"))]
        "obj" => Err(feature_disabled(path, "OBJ", "obj")),
        "txt" | "citysc" => box_city::load_box_city(path),
        _ => Err(Error::Load {
            file: PathBuf::from(path),
            element: "file name".into(),
            message: format!(
                "unknown scene format `.{ext}` (expected .gltf, .glb, .obj, a directory of .obj, or a box-city .txt)"
            ),
        }),
    }
}

/// The error for a format whose loader was compiled out.
#[cfg(not(all(feature = "gltf", feature = "obj")))]
fn feature_disabled(path: &Path, format: &str, feature: &str) -> Error {
    Error::Load {
        file: PathBuf::from(path),
        element: "file name".into(),
        message: format!(
            "{format} support is disabled: build shadowcull-scene with the `{feature}` feature"
        ),
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("scene_load_{name}_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// A FIFO, a device (through a symbolic link with a scene's extension)
    /// and a directory are refused at once: the FIFO once blocked forever,
    /// `/dev/zero` grew to 8.4 GB.
    #[cfg(unix)]
    #[test]
    fn only_regular_files_are_read() {
        let d = scratch("special");
        let zero = d.join("zero.obj");
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        let e = super::load_path(&zero).unwrap_err().to_string();
        assert!(
            e.contains("zero.obj") && e.contains("a character device"),
            "{e}"
        );
        let dir = d.join("dir.glb");
        std::fs::create_dir(&dir).unwrap();
        let e = super::read_input(&dir).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput);
        assert!(e.to_string().contains("a directory"), "{e}");
        let fifo = d.join("pipe.obj");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.map(|s| s.success()).unwrap_or(false) {
            let e = super::load_path(&fifo).unwrap_err().to_string();
            assert!(e.contains("pipe.obj") && e.contains("a FIFO"), "{e}");
        } else {
            eprintln!("note: no mkfifo here; the FIFO case is skipped");
        }
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// A file past the limit is refused before it is read, naming both sizes.
    #[test]
    fn files_past_the_size_limit_are_refused() {
        let d = scratch("cap");
        let f = d.join("big.obj");
        std::fs::write(&f, vec![b'#'; 1000]).unwrap();
        assert_eq!(super::read_capped(&f, 1000).unwrap().len(), 1000);
        let e = super::read_capped(&f, 999).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::FileTooLarge);
        assert!(
            e.to_string().contains("1000 bytes") && e.to_string().contains("999"),
            "{e}"
        );
        assert_eq!(super::max_input_bytes(), super::DEFAULT_MAX_INPUT_BYTES);
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// `load_path` on a format whose feature is off names the feature.
    #[cfg(not(all(feature = "gltf", feature = "obj")))]
    fn assert_disabled(file: &str, feature: &str) {
        match super::load_path(std::path::Path::new(file)) {
            Err(crate::Error::Load { message, .. }) => {
                assert!(
                    message.contains(&format!("`{feature}` feature")),
                    "{message}"
                )
            }
            other => panic!("{file}: expected a disabled-feature error, got {other:?}"),
        }
    }

    #[cfg(not(feature = "gltf"))]
    #[test]
    fn gltf_without_its_feature_is_an_error_naming_it() {
        assert_disabled("missing.gltf", "gltf");
        assert_disabled("missing.GLB", "gltf");
    }

    #[cfg(not(feature = "obj"))]
    #[test]
    fn obj_without_its_feature_is_an_error_naming_it() {
        assert_disabled("missing.obj", "obj");
        assert_disabled(env!("CARGO_MANIFEST_DIR"), "obj");
    }
}
