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

mod input;
mod recentre;

pub use crate::loaded::Loaded;
pub use input::{max_input_bytes, read_input, set_max_input_bytes, DEFAULT_MAX_INPUT_BYTES};
pub use recentre::{recentre, RECENTRE_RATIO};

use crate::{Error, Result};
use std::path::{Path, PathBuf};

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
    use testkit::scratch_dir as scratch;

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
    }

    /// A file past the limit is refused before it is read, naming both sizes.
    #[test]
    fn files_past_the_size_limit_are_refused() {
        let d = scratch("cap");
        let f = d.join("big.obj");
        std::fs::write(&f, vec![b'#'; 1000]).unwrap();
        assert_eq!(super::input::read_capped(&f, 1000).unwrap().len(), 1000);
        let e = super::input::read_capped(&f, 999).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::FileTooLarge);
        assert!(
            e.to_string().contains("1000 bytes") && e.to_string().contains("999"),
            "{e}"
        );
        assert_eq!(super::max_input_bytes(), super::DEFAULT_MAX_INPUT_BYTES);
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
