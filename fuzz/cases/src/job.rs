//! RON job text through parsing, validation and resolution, without running
//! frames: lights, camera and frame count resolved against a small
//! procedural city (the job's own scene is not loaded: a fuzzed path or a
//! huge city would measure the disk or the allocator, not the job code), and
//! the memory estimate checked. An error naming the file and field is fine,
//! a panic or a crash is a finding.

use shadowcull::jobs::config::{resolve_camera, resolve_lights, Job};
use shadowcull::scene::{load::Loaded, procedural::CityParams, Scene};
use std::path::Path;
use std::sync::OnceLock;

fn city() -> &'static (Loaded, shadowcull::scene::Aabb) {
    static CITY: OnceLock<(Loaded, shadowcull::scene::Aabb)> = OnceLock::new();
    CITY.get_or_init(|| {
        let loaded = shadowcull::scene::procedural::city(&CityParams {
            blocks_x: 2,
            blocks_z: 2,
            ..Default::default()
        })
        .unwrap();
        let bounds = Scene::new(loaded.graph.clone()).unwrap().bounds();
        (loaded, bounds)
    })
}

/// One fuzz input through the target (a panic is a finding).
pub fn run(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let file = Path::new("fuzz.ron");
    let Ok(job) = Job::from_ron(text, file) else {
        return;
    };
    let (loaded, bounds) = city();
    let _ = resolve_lights(&job, loaded, bounds, file);
    if let Ok(path) = resolve_camera(&job.camera, loaded, bounds, file) {
        let aspect = f64::from(job.resolution.0.max(1)) / f64::from(job.resolution.1.max(1));
        for f in [0, 1, job.frame_count().saturating_sub(1)] {
            if let Some(pose) = path.at(f) {
                let _ = pose.camera(aspect);
            }
        }
    }
    let workload = shadowcull::memory::Workload {
        width: job.resolution.0,
        height: job.resolution.1,
        lights: job.lights.len().max(1) as u32,
        rows: u64::from(job.frame_count()),
        ..Default::default()
    };
    let estimate = shadowcull::memory::estimate(&job.pipeline, &workload);
    let _ = estimate.check(shadowcull::memory::limit(&job.pipeline));
}
