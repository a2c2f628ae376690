//! OBJ text through the loader and into a `Scene`: an error naming the file
//! is fine, a panic or a crash is a finding. (`.mtl` files are not read from
//! memory; their parsing is tobj's and the loader takes only names from them.)

use shadowcull::scene::{load::obj::load_obj_bytes, Scene};
use std::path::Path;

/// One fuzz input through the target (a panic is a finding).
pub fn run(data: &[u8]) {
    if let Ok(graph) = load_obj_bytes(data, Path::new("fuzz.obj")) {
        let _ = Scene::new(graph);
    }
}
