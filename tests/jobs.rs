//! The job files in `data/jobs/`: they parse, and the shared-scene test views
//! show their scenes with shadows the reference can compute.

use shadowcull::jobs::config::prepare_scene;
use shadowcull::jobs::config::{default_job, resolve_camera, Job};
use shadowcull::reference::{reference_mask, TriangleBvh};
use std::path::{Path, PathBuf};

fn jobs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/jobs")
}

fn job_files() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(jobs_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .collect();
    v.sort();
    v
}

#[test]
fn every_job_file_parses() {
    let files = job_files();
    assert!(
        files.len() >= 9,
        "default + 8 shared jobs, found {}",
        files.len()
    );
    for f in files {
        Job::from_file(&f).unwrap_or_else(|e| panic!("{e}"));
    }
}

/// The single-object job of `culling: auto`'s cases: one object of at
/// least 100k triangles, over at least 30 frames.
#[test]
fn the_merged_city_job_is_one_object_of_100k_triangles() {
    let f = jobs_dir().join("merged_city.ron");
    let job = Job::from_file(&f).unwrap();
    let (_, scene) = prepare_scene(&job, f.parent().unwrap()).unwrap();
    let c = scene.counts();
    assert_eq!(c.objects, 1, "{c:?}");
    assert!(c.triangles >= 100_000, "{c:?}");
    assert!(job.frames.is_some_and(|n| n >= 30));
}

#[test]
fn default_job_file_matches_the_built_in_default() {
    let j = Job::from_file(&jobs_dir().join("default_city.ron")).unwrap();
    assert_eq!(j, default_job());
}

/// `default_city_gpu_host.ron` is the default job as a GPU host runs it:
/// the `gpu_host` preset and no images.
#[test]
fn the_gpu_host_job_is_the_default_job_with_the_preset_and_no_outputs() {
    let j = Job::from_file(&jobs_dir().join("default_city_gpu_host.ron")).unwrap();
    let want = Job {
        outputs: Default::default(),
        pipeline: shadowcull::PipelineOptions::gpu_host(),
        ..default_job()
    };
    assert_eq!(j, want);
    assert_eq!(j.resolution, (800, 600));
    assert_eq!(j.lights.len(), 2);
}

#[test]
fn shared_scene_views_show_their_scenes_and_shadows() {
    if testkit::shared_data().is_none() {
        return;
    }
    let (w, h) = (96u32, 72u32);
    for f in job_files().into_iter().filter(|f| {
        f.file_name()
            .unwrap()
            .to_str()
            .unwrap()
            .starts_with("shared_")
    }) {
        let job = Job::from_file(&f).unwrap();
        let (loaded, scene) = prepare_scene(&job, f.parent().unwrap())
            .unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        let bounds = scene.bounds();
        let path = resolve_camera(&job.camera, &loaded, &bounds, &f).unwrap();
        let bvh = TriangleBvh::new(&scene);
        assert_eq!(job.frame_count(), 2, "{}: two cameras", f.display());
        assert_eq!(job.lights.len(), 4, "{}: four lights", f.display());
        for frame in 0..2 {
            let cam = path.at(frame).unwrap().camera(w as f64 / h as f64).unwrap();
            let mut shadow_seen = false;
            for (i, l) in job.lights.iter().enumerate() {
                let light = l.resolve(&loaded, &bounds, i, &f).unwrap();
                let r = reference_mask(&bvh, &cam, &light, w, h, &job.pipeline.reference, None);
                let c = r.counts.classes;
                assert_eq!(c.lit + c.shadow + c.unlit + c.background, (w * h) as u64);
                // At least 2% of the view shows the scene (city.obj's buildings are
                // scattered thinly over their bounds; every other scene fills far more).
                assert!(
                    c.background < (w * h) as u64 * 49 / 50,
                    "{} frame {frame}: the view misses the scene: {c:?}",
                    f.display()
                );
                // At most 5% of the compared pixels (one pixel allowed when a
                // view shows fewer than 20 lit or shadowed pixels).
                assert!(
                    r.counts.ambiguous * 20 <= (c.lit + c.shadow).max(20),
                    "{} frame {frame} light {i}: too many ambiguous pixels: {:?}",
                    f.display(),
                    r.counts
                );
                shadow_seen |= c.shadow > 0;
            }
            assert!(
                shadow_seen,
                "{} frame {frame}: no light casts a visible shadow",
                f.display()
            );
        }
    }
}

/// The batch modules' paths from before they moved under `jobs` still name
/// the same items (kept for one minor version), and the new ones resolve.
#[test]
fn the_batch_modules_resolve_at_their_old_and_new_paths() {
    use std::any::TypeId;
    assert_eq!(
        TypeId::of::<shadowcull::frame::FrameRunner>(),
        TypeId::of::<shadowcull::jobs::frame::FrameRunner>()
    );
    assert_eq!(
        TypeId::of::<shadowcull::config::LightSpec>(),
        TypeId::of::<shadowcull::jobs::config::LightSpec>()
    );
    assert_eq!(
        TypeId::of::<shadowcull::shard::Shard>(),
        TypeId::of::<shadowcull::jobs::shard::Shard>()
    );
    assert_eq!(
        shadowcull::run::run_job as *const (),
        shadowcull::jobs::run::run_job as *const ()
    );
    assert_eq!(
        shadowcull::compare::compare_job as *const (),
        shadowcull::jobs::compare::compare_job as *const ()
    );
    assert_eq!(
        shadowcull::merge::merge_shards as *const (),
        shadowcull::jobs::merge::merge_shards as *const ()
    );
}

/// The backticked names between `<!-- name -->` and `<!-- /name -->` in `text`.
fn listed(text: &str, name: &str) -> Vec<String> {
    let open = format!("<!-- {name} -->");
    let start = text.find(&open).unwrap_or_else(|| panic!("no {open}")) + open.len();
    let end = start + text[start..].find(&format!("<!-- /{name} -->")).unwrap();
    text[start..end]
        .split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect()
}

/// The README's lists of the columns a sharded run keeps and of those that
/// depend on history, and `scripts/shard_check.sh`'s checked columns, are
/// the code's (`FrameRow::MASK_COLUMNS`, `FrameRow::history_columns`).
#[test]
fn the_shard_column_lists_are_the_codes() {
    use shadowcull::stats::FrameRow;
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    assert_eq!(listed(&readme, "mask-columns"), FrameRow::MASK_COLUMNS);
    let history: Vec<&str> = FrameRow::history_columns().collect();
    assert_eq!(listed(&readme, "history-columns"), history);
    assert!(history.contains(&"silhouette_edges") && history.contains(&"h_fragments"));
    let script = std::fs::read_to_string(root.join("scripts/shard_check.sh")).unwrap();
    let start = script.find("mask_cols=(").unwrap() + "mask_cols=(".len();
    let end = start + script[start..].find(')').unwrap();
    let checked: Vec<&str> = script[start..end].split_whitespace().collect();
    assert_eq!(checked, FrameRow::MASK_COLUMNS);
}
