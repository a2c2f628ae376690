//! Box-city text through the parser and into a `Scene`, with its cameras and
//! paths evaluated: an error naming the file and line is fine, a panic or a
//! crash is a finding.

use shadowcull::scene::{load::box_city::load_box_city_str, Scene};
use std::path::Path;

/// One fuzz input through the target (a panic is a finding).
pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(loaded) = load_box_city_str(text, Path::new("fuzz.txt")) {
        for (_, path) in &loaded.paths {
            for f in 0..3 {
                if let Some(pose) = path.at(f) {
                    let _ = pose.camera(4.0 / 3.0);
                }
            }
        }
        for (_, look) in &loaded.cameras {
            let _ = look.camera(4.0 / 3.0);
        }
        let _ = Scene::new(loaded.graph);
    }
}
