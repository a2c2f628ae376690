//! glTF bytes (GLB, or JSON with its buffers) through the loader and into a
//! `Scene`: an error naming the file is fine, a panic or a crash is a
//! finding. Bytes after the first `\0\xff\0` separator are the content of
//! every external buffer the document references (none: a missing file).

use shadowcull::scene::{load::gltf::load_gltf_slice, Scene};
use std::path::Path;

const SEPARATOR: &[u8] = b"\0\xff\0";

/// One fuzz input through the target (a panic is a finding).
pub fn run(data: &[u8]) {
    let (doc, buffer) = match data.windows(SEPARATOR.len()).position(|w| w == SEPARATOR) {
        Some(k) => (&data[..k], Some(&data[k + SEPARATOR.len()..])),
        None => (data, None),
    };
    let mut resolve = |_: &str| match buffer {
        Some(b) => Ok(b.to_vec()),
        None => Err(std::io::Error::from(std::io::ErrorKind::NotFound)),
    };
    if let Ok(graph) = load_gltf_slice(doc, Path::new("fuzz.gltf"), &mut resolve) {
        let _ = Scene::new(graph);
    }
}
