//! The stencil pipeline (raster eye pass, shadowgen volumes, brute-force
//! stencil, mask assembly) against the ray-cast reference fed with the same
//! primitive ids: every compared pixel agrees except ambiguous ones and at
//! most 0.01% of the image more, each on a reference shadow boundary.

use crate::common::{boxes_on_ground, overview_camera};
use glam::{DMat4, DVec3};
use rayon::prelude::*;
use scene::load::Loaded;
use scene::{Camera, CameraPath, Light, Scene, Transform};
use shadowcull::jobs::config::{load_scene_for_job, Job};
use shadowcull::mask::{compare, Mask};
use shadowcull::pipeline::{
    eye_pass, shadow_mask, EyePass, MeshCache, ShadowOptions, ShadowScratch,
};
use shadowcull::reference::{reference_mask, ReferenceOptions, TriangleBvh};
use shadowgen::MethodChoice;
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

/// Runs pipeline and reference on one view; returns (mismatches, off-boundary, compared).
fn check(
    scene: &Scene,
    camera: &Camera,
    light: &Light,
    method: MethodChoice,
    two_sided: bool,
) -> (u64, u64, u64) {
    let (w, h) = (160u32, 120u32);
    let meshes = MeshCache::new(scene);
    let eye = eye_pass(scene, &meshes, camera, w, h).unwrap();
    let opts = ShadowOptions {
        method,
        two_sided,
        ..Default::default()
    };
    let frame = shadow_mask(
        scene,
        camera,
        light,
        &eye,
        &opts,
        &mut ShadowScratch::default(),
    )
    .unwrap();
    let bvh = TriangleBvh::new(scene);
    let ropts = ReferenceOptions {
        two_sided,
        ..Default::default()
    };
    let r = reference_mask(&bvh, camera, light, w, h, &ropts, Some(eye.surface()));
    assert_eq!(frame.mask.counts().background, r.counts.classes.background);
    let c = compare(&r.mask, &r.ambiguous, &frame.mask);
    let off = c.mismatches - c.mismatches_on_boundary;
    (c.mismatches, off, c.compared)
}

fn lights() -> Vec<Light> {
    vec![
        Light::Point {
            position: DVec3::new(-4.0, 8.0, 3.0),
            range: None,
        },
        Light::Directional {
            direction: DVec3::new(0.4, -1.0, -0.3),
        },
        Light::Spot {
            position: DVec3::new(3.0, 7.0, -2.0),
            direction: DVec3::new(-0.4, -1.0, 0.3),
            apex_angle: 70f64.to_radians(),
            range: None,
        },
    ]
}

fn assert_exact(what: &str, (mism, off, compared): (u64, u64, u64)) {
    let allowed = (160 * 120) / 10_000; // 0.01% of the image
    println!("{what}: {mism} mismatches ({off} off boundary) of {compared} compared");
    assert!(compared > 1000, "{what}: too few compared pixels");
    assert_eq!(
        off, 0,
        "{what}: mismatches off the reference shadow boundary"
    );
    assert!(mism <= allowed, "{what}: {mism} mismatches > {allowed}");
}

#[test]
fn stencil_mask_matches_the_reference_for_every_method() {
    let s = boxes_on_ground(Transform::default());
    let cam = overview_camera();
    for (li, light) in lights().iter().enumerate() {
        for method in [MethodChoice::Auto, MethodChoice::ZFail] {
            assert_exact(
                &format!("light {li} {method:?}"),
                check(&s, &cam, light, method, false),
            );
        }
        assert_exact(
            &format!("light {li} two-sided"),
            check(&s, &cam, light, MethodChoice::Auto, true),
        );
    }
}

#[test]
fn scissor_and_depth_bounds_leave_the_raw_stencil_unchanged() {
    // shadowgen's own per-volume bounds: the raw stencil (≠ 0) with scissor, depth
    // bounds or both equals brute force without them, bit for bit, with less
    // per-pixel work; every light type, the eye outside and inside a volume.
    let s = boxes_on_ground(Transform::default());
    let (w, h) = (160u32, 120u32);
    let meshes = MeshCache::new(&s);
    let cams = [
        (DVec3::new(2.0, 9.0, 12.0), DVec3::ZERO),
        (DVec3::new(0.0, 1.2, 3.0), DVec3::new(0.0, 0.5, 8.0)),
        (DVec3::new(-6.0, 0.4, -5.0), DVec3::new(1.0, 1.0, 1.0)),
    ];
    let mut lights = lights();
    lights.push(Light::Point {
        position: DVec3::new(0.0, 9.0, -4.0),
        range: None,
    });
    let mut saved = 0;
    for (eye_pos, target) in cams {
        let cam = Camera::look_at(
            eye_pos,
            target,
            DVec3::Y,
            60f64.to_radians(),
            4.0 / 3.0,
            0.05,
        )
        .unwrap();
        let eye = eye_pass(&s, &meshes, &cam, w, h).unwrap();
        for light in &lights {
            for method in [
                MethodChoice::Auto,
                MethodChoice::ZFail,
                MethodChoice::ZpPlus,
            ] {
                let run = |scissor, depth_bounds| {
                    let opts = ShadowOptions {
                        method,
                        scissor,
                        depth_bounds,
                        bits: raster::StencilBits::Wide,
                        ..Default::default()
                    };
                    shadow_mask(&s, &cam, light, &eye, &opts, &mut ShadowScratch::default())
                        .unwrap()
                };
                let bf = run(false, false);
                for (sc, db) in [(true, false), (false, true), (true, true)] {
                    let t = run(sc, db);
                    assert_eq!(
                        t.raw_nonzero, bf.raw_nonzero,
                        "{eye_pos} {light:?} {method:?} scissor {sc} db {db}"
                    );
                    assert!(t.stencil.pixels_processed <= bf.stencil.pixels_processed);
                    saved += bf.stencil.pixels_processed - t.stencil.pixels_processed;
                }
            }
        }
    }
    assert!(saved > 100_000, "the bounds save work: {saved}");
}

#[test]
fn finite_extrusion_gives_the_infinite_volumes_mask_within_range() {
    // A ranged point light whose range covers the visible scene: finitely
    // extruded (closed) volumes must give the infinite volumes' mask, for every
    // method, and match the reference.
    let s = boxes_on_ground(Transform::default());
    let cam = overview_camera();
    let (w, h) = (160u32, 120u32);
    let meshes = MeshCache::new(&s);
    let eye = eye_pass(&s, &meshes, &cam, w, h).unwrap();
    let bvh = TriangleBvh::new(&s);
    for position in [DVec3::new(-3.0, 8.0, 2.0), DVec3::new(1.0, 4.0, 1.5)] {
        let light = Light::Point {
            position,
            range: Some(40.0),
        };
        let r = reference_mask(
            &bvh,
            &cam,
            &light,
            w,
            h,
            &ReferenceOptions::default(),
            Some(eye.surface()),
        );
        for method in [
            MethodChoice::Auto,
            MethodChoice::ZFail,
            MethodChoice::ZpPlus,
        ] {
            let run = |finite_extrusion| {
                let opts = ShadowOptions {
                    method,
                    finite_extrusion,
                    ..Default::default()
                };
                shadow_mask(&s, &cam, &light, &eye, &opts, &mut ShadowScratch::default()).unwrap()
            };
            let (inf, fin) = (run(false), run(true));
            assert!(
                fin.volumes.finite_volumes > 0,
                "{method:?}: finite volumes built"
            );
            assert_eq!(inf.volumes.finite_volumes, 0);
            assert_eq!(
                fin.mask, inf.mask,
                "{position} {method:?}: finite and infinite volumes differ"
            );
            assert!(fin.mask.counts().shadow > 100, "shadows visible");
            let c = compare(&r.mask, &r.ambiguous, &fin.mask);
            assert_exact(
                &format!("{position} {method:?} finite"),
                (
                    c.mismatches,
                    c.mismatches - c.mismatches_on_boundary,
                    c.compared,
                ),
            );
        }
    }
}

#[test]
fn camera_inside_a_shadow_volume_is_exact_with_auto() {
    // The eye stands in the tower's shadow: zpass would fail, Auto must not.
    let s = boxes_on_ground(Transform::default());
    let light = Light::Point {
        position: DVec3::new(0.0, 9.0, -4.0),
        range: None,
    };
    let cam = Camera::look_at(
        DVec3::new(0.0, 1.2, 3.0),
        DVec3::new(0.0, 0.5, 8.0),
        DVec3::Y,
        60f64.to_radians(),
        4.0 / 3.0,
        0.05,
    )
    .unwrap();
    assert_exact(
        "eye in shadow, Auto",
        check(&s, &cam, &light, MethodChoice::Auto, false),
    );
    assert_exact(
        "eye in shadow, zfail",
        check(&s, &cam, &light, MethodChoice::ZFail, false),
    );
}

#[test]
fn far_from_the_origin_and_scaled() {
    for (offset, scale) in [
        (DVec3::new(1e5, 0.0, 1e5), 1.0),
        (DVec3::new(1e6, 0.0, -1e6), 1.0),
        (DVec3::ZERO, 1e-3),
        (DVec3::ZERO, 1e3),
    ] {
        let root = Transform::Matrix(
            DMat4::from_translation(offset) * DMat4::from_scale(DVec3::splat(scale)),
        );
        let s = boxes_on_ground(root);
        let at = |p: DVec3| offset + p * scale;
        let cam = Camera::look_at(
            at(DVec3::new(2.0, 9.0, 12.0)),
            at(DVec3::ZERO),
            DVec3::Y,
            50f64.to_radians(),
            4.0 / 3.0,
            0.05 * scale,
        )
        .unwrap();
        let light = Light::Point {
            position: at(DVec3::new(-4.0, 8.0, 3.0)),
            range: None,
        };
        assert_exact(
            &format!("offset {offset} scale {scale}"),
            check(&s, &cam, &light, MethodChoice::Auto, false),
        );
    }
}

// ------------------------------------------------------------ shared jobs

/// One shared job (`data/jobs/shared_*.ron`), loaded once per test binary for
/// the three shared-job tests: its scene, camera path and lights, its mesh
/// cache, every frame's camera and eye pass, and the reference's BVH. All of
/// it is built up front: a lazy cell filled from inside a parallel view could
/// deadlock the thread pool.
struct SharedJob {
    file: PathBuf,
    /// The job file's name.
    name: String,
    job: Job,
    loaded: Loaded,
    scene: Arc<Scene>,
    path: CameraPath,
    /// The job's lights, resolved.
    lights: Vec<Light>,
    /// Per frame: its camera at the job's resolution and the eye pass.
    eyes: Vec<(Camera, EyePass)>,
    bvh: TriangleBvh,
}

impl SharedJob {
    fn load(file: PathBuf) -> Self {
        let job = Job::from_file(&file).unwrap();
        let (w, h) = job.resolution;
        let (loaded, scene, path) = load_scene_for_job(&job, Some(&file)).unwrap();
        let bounds = scene.bounds();
        let lights = (job.lights.iter().enumerate())
            .map(|(li, spec)| spec.resolve(&loaded, &bounds, li, &file).unwrap())
            .collect();
        let meshes = MeshCache::new(&scene);
        let eyes = (0..job.frame_count())
            .map(|frame| {
                let cam = (path.at(frame).unwrap())
                    .camera(f64::from(w) / f64::from(h))
                    .unwrap();
                let eye = eye_pass(&scene, &meshes, &cam, w, h).unwrap();
                (cam, eye)
            })
            .collect();
        SharedJob {
            name: file.file_name().unwrap().to_string_lossy().to_string(),
            bvh: TriangleBvh::new(&scene),
            file,
            job,
            loaded,
            scene: Arc::new(scene),
            path,
            lights,
            eyes,
        }
    }

    /// The job's image size.
    fn size(&self) -> (u32, u32) {
        self.job.resolution
    }

    /// Frame `frame`'s camera and eye pass at the job's resolution.
    fn eye(&self, frame: u32) -> &(Camera, EyePass) {
        &self.eyes[frame as usize]
    }

    fn bvh(&self) -> &TriangleBvh {
        &self.bvh
    }

    /// Its views: every (frame, light index).
    fn views(&self) -> impl Iterator<Item = (u32, usize)> + '_ {
        (0..self.job.frame_count()).flat_map(move |f| (0..self.lights.len()).map(move |l| (f, l)))
    }
}

/// Every shared job, loaded in parallel on first use; none (with a note) when
/// `../shared/data` is absent.
fn shared_jobs() -> &'static [SharedJob] {
    static JOBS: OnceLock<Vec<SharedJob>> = OnceLock::new();
    JOBS.get_or_init(|| {
        (testkit::shared_jobs("").into_par_iter())
            .map(SharedJob::load)
            .collect()
    })
}

/// Every view (job, frame, light index) of every shared job, in order.
fn shared_views() -> Vec<(&'static SharedJob, u32, usize)> {
    (shared_jobs().iter())
        .flat_map(|j| j.views().map(move |(f, l)| (j, f, l)))
        .collect()
}

/// A sparse diagonal of [`shared_views`] for the default run, whose full
/// matrices are `.ci/run`'s `test-heavy` step: `per_job` views of every
/// shared job, spread over its frames and lights from `phase` on, each with
/// one variant of [`H_VARIANTS`] turning with the view's position so that
/// every variant appears. Tests pass different phases to see different views.
fn sparse_views(per_job: usize, phase: usize) -> Vec<HViewSpec> {
    let mut out = Vec::new();
    for (ji, j) in shared_jobs().iter().enumerate() {
        let views: Vec<(u32, usize)> = j.views().collect();
        let n = per_job.min(views.len());
        for i in 0..n {
            let (frame, li) = views[(phase + ji + i * views.len() / n) % views.len()];
            let variant = H_VARIANTS[(phase + ji * per_job + i) % H_VARIANTS.len()];
            out.push((j, frame, li, vec![variant]));
        }
    }
    out
}

/// Issue 4's exactness check on shared-job views at the job's resolution
/// (320×240), with its criterion unchanged: no mismatch off a reference
/// shadow boundary and at most 0.01% of the image on one, for each view's
/// variants (one- or two-sided; Auto, forced zfail or forced zp+, whose
/// masks must also equal Auto's on every pixel, so Auto's is checked too).
/// The views run in parallel; prints a line per mask. Returns the variants
/// checked.
fn check_reference_views(views: Vec<HViewSpec>) -> u64 {
    // Per view: its printed lines, the variants checked and its failures.
    let per_view: Vec<(Vec<String>, u64, Vec<String>)> = (views.into_par_iter())
        .map(|(j, frame, li, variants)| {
            let (mut lines, mut checked, mut failures) = (Vec::new(), 0, Vec::new());
            // The job's own image: the bound is 0.01% of its pixels.
            let (w, h) = j.size();
            let (cam, eye) = j.eye(frame);
            let light = &j.lights[li];
            let mut scratch = ShadowScratch::default();
            for two_sided in [false, true] {
                let methods: Vec<MethodChoice> = (variants.iter())
                    .filter(|v| v.0 == two_sided)
                    .map(|v| v.1)
                    .collect();
                if methods.is_empty() {
                    continue;
                }
                let ropts = ReferenceOptions {
                    two_sided,
                    ..Default::default()
                };
                let r = reference_mask(j.bvh(), cam, light, w, h, &ropts, Some(eye.surface()));
                // Auto first: every method's mask must equal it.
                let mut auto_mask = None;
                for method in [
                    MethodChoice::Auto,
                    MethodChoice::ZFail,
                    MethodChoice::ZpPlus,
                ] {
                    if method != MethodChoice::Auto && !methods.contains(&method) {
                        continue;
                    }
                    let opts = ShadowOptions {
                        method,
                        two_sided,
                        ..Default::default()
                    };
                    let out = shadow_mask(&j.scene, cam, light, eye, &opts, &mut scratch).unwrap();
                    let c = compare(&r.mask, &r.ambiguous, &out.mask);
                    let off = c.mismatches - c.mismatches_on_boundary;
                    // Methods against each other: the same mask on every pixel.
                    let differ = auto_mask.as_ref().map_or(0, |m: &Mask| {
                        m.pixels
                            .iter()
                            .zip(&out.mask.pixels)
                            .filter(|(a, b)| a != b)
                            .count()
                    });
                    if auto_mask.is_none() {
                        auto_mask = Some(out.mask.clone());
                    }
                    checked += u64::from(methods.contains(&method));
                    let what = format!(
                        "{} camera {frame} light {li} {method:?}{}",
                        j.name,
                        if two_sided { " two-sided" } else { "" }
                    );
                    lines.push(format!(
                        "{what}: {} mismatches ({off} off boundary), {} ambiguous, of {}; {differ} px differ from Auto",
                        c.mismatches, c.ambiguous, c.compared
                    ));
                    if off > 0 || c.mismatches > u64::from(w * h) / 10_000 || differ > 0 {
                        failures.push(format!(
                            "{what}: {} mismatches, {off} off boundary, {differ} px differ from Auto",
                            c.mismatches
                        ));
                    }
                }
            }
            (lines, checked, failures)
        })
        .collect();
    let (mut checked, mut failures) = (0, Vec::new());
    for (lines, n, f) in per_view {
        lines.iter().for_each(|l| println!("{l}"));
        checked += n;
        failures.extend(f);
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    checked
}

/// Issue 4's exactness matrix in full ([`check_reference_views`]): every view
/// of every shared job in all six variants. `cargo test --test main --
/// --ignored --nocapture shared_jobs_match` prints the table.
///
/// All 64 views pass in all six variants, and the methods agree on every
/// pixel of every view. On the way here: the stencil counts every snapped fan
/// piece by its own snapped orientation (rocker-arm, engine), OBJ geometry far
/// from the origin is recentred (city.obj), and the reference's ambiguity covers
/// 1/256-pixel vertex snapping, the eye buffer's measured depth error and the
/// boundary of the visible triangle's own shadow prism (bunny, camera 1, light
/// 3, pixel (135, 85): the sun at n·l = 4·10⁻⁵ to the surface, where the
/// surface's own volume side passes 0.3·δ behind it; `cargo run --release
/// --example stencil_diagnose -- pixel bunny 1 3 135 85` prints such a pixel's
/// analysis, `-- mismatches` every mismatched pixel's).
///
/// About 50 CPU-seconds in the test profile: `.ci/run`'s `test-heavy` step;
/// the default run checks a diagonal,
/// [`shared_jobs_match_the_reference_on_a_diagonal`].
#[test]
#[ignore = "the full reference matrix: .ci/run's test-heavy step"]
fn shared_jobs_match_the_reference() {
    let views: Vec<_> = (shared_views().into_iter())
        .map(|(j, frame, li)| (j, frame, li, H_VARIANTS.to_vec()))
        .collect();
    let n = views.len() as u64;
    assert_eq!(check_reference_views(views), 6 * n);
}

/// A diagonal of [`shared_jobs_match_the_reference`] with the same checks:
/// two views of every shared job ([`sparse_views`]).
#[test]
fn shared_jobs_match_the_reference_on_a_diagonal() {
    let views = sparse_views(2, 0);
    let n = views.len() as u64;
    assert_eq!(check_reference_views(views), n);
    assert!(n == 0 || n >= 16, "{n} views");
}

/// The variants of the hierarchical-stencil matrix: (two-sided, method).
const H_VARIANTS: [(bool, MethodChoice); 6] = [
    (false, MethodChoice::Auto),
    (false, MethodChoice::ZFail),
    (false, MethodChoice::ZpPlus),
    (true, MethodChoice::Auto),
    (true, MethodChoice::ZFail),
    (true, MethodChoice::ZpPlus),
];

/// A view of the hierarchical-stencil matrix (job, frame, light index) and
/// its variants.
type HViewSpec = (&'static SharedJob, u32, usize, Vec<(bool, MethodChoice)>);

/// What the hierarchical-stencil matrix saw on one view.
#[derive(Default)]
struct HView {
    variants: u64,
    boundary: u64,
    fs_changed: u64,
    failures: Vec<String>,
}

/// Issue 5's check on shared-job views, the views in parallel: for each view
/// (job, frame, light index) and each of its variants (two-sided, method), the
/// hierarchical stencil equals brute force ([`testkit::check_hierarchical`]:
/// tile 8, and tiles 4 and 16 too on Auto one-sided); every pixel its FS bit
/// changes is ambiguous in the reference, and at most 0.01% of the image.
/// Prints per-job totals; returns the variants checked and the boundary tiles
/// seen, or panics with every failure.
fn check_hierarchical_views(views: Vec<HViewSpec>) -> (u64, u64) {
    use raster::TileSize;
    let per_view: Vec<(&SharedJob, HView)> = (views.into_par_iter())
        .map(|(j, frame, li, variants)| {
            let mut out = HView::default();
            let (w, h) = j.size();
            let (cam, eye) = j.eye(frame);
            let light = &j.lights[li];
            for (two_sided, method) in variants {
                let tiles: &[TileSize] = if method == MethodChoice::Auto && !two_sided {
                    &[TileSize::T4, TileSize::T8, TileSize::T16]
                } else {
                    &[TileSize::T8]
                };
                let what = format!(
                    "{} camera {frame} light {li} {method:?}{}",
                    j.name,
                    if two_sided { " two-sided" } else { "" }
                );
                out.variants += 1;
                let c = match testkit::check_hierarchical(
                    &j.scene,
                    cam,
                    light,
                    &eye.target,
                    method,
                    two_sided,
                    tiles,
                ) {
                    Ok(c) => c,
                    Err(e) => {
                        out.failures.push(format!("{what}: {e}"));
                        continue;
                    }
                };
                out.boundary += c.boundary_tiles;
                out.fs_changed += c.differing.len() as u64;
                if c.differing.len() as u64 > u64::from(w * h) / 10_000 {
                    out.failures
                        .push(format!("{what}: FS changed {} pixels", c.differing.len()));
                }
                if !c.differing.is_empty() {
                    let ropts = ReferenceOptions {
                        two_sided,
                        ..Default::default()
                    };
                    let r = reference_mask(j.bvh(), cam, light, w, h, &ropts, Some(eye.surface()));
                    for &i in &c.differing {
                        if !r.ambiguous[i] {
                            out.failures.push(format!(
                                "{what}: FS changed pixel {i}, not ambiguous in the reference"
                            ));
                        }
                    }
                }
            }
            (j, out)
        })
        .collect();
    let mut failures = Vec::new();
    let (mut views, mut boundary, mut fs_changed) = (0u64, 0u64, 0u64);
    for (k, (j, v)) in per_view.iter().enumerate() {
        views += v.variants;
        boundary += v.boundary;
        fs_changed += v.fs_changed;
        failures.extend(v.failures.iter().cloned());
        if per_view
            .get(k + 1)
            .is_none_or(|(next, _)| next.file != j.file)
        {
            println!("{}: done", j.name);
        }
    }
    println!(
        "{views} views, {boundary} boundary tiles (FS off), {fs_changed} pixels changed by FS"
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    (views, boundary)
}

/// Issue 5's exactness matrix, in full: on every view of every shared job, for
/// Auto, forced zfail and forced zp+, one- and two-sided, the hierarchical
/// stencil (tile 8) equals brute force value for value with wide and with
/// 8-bit counters and the FS bit off; with it on, every pixel that changes is
/// explained (a volume's negative count, or an 8-bit wrap) and ambiguous in
/// the reference, and at most 0.01% of the image. Tiles 4 and 16 run on Auto,
/// one-sided ([`testkit::hierarchical_matches_brute_force`] has the details).
/// Prints per-job totals with `--nocapture`.
///
/// About 140 CPU-seconds in the test profile: `.ci/run`'s `test-heavy` step;
/// the default run checks a diagonal of it,
/// [`hierarchical_stencil_matches_brute_force_on_a_diagonal`].
#[test]
#[ignore = "the full hierarchical-stencil matrix: .ci/run's test-heavy step"]
fn hierarchical_stencil_matches_brute_force_on_shared_jobs() {
    let views: Vec<_> = (shared_views().into_iter())
        .map(|(j, frame, li)| (j, frame, li, H_VARIANTS.to_vec()))
        .collect();
    if views.is_empty() {
        return;
    }
    let (views, boundary) = check_hierarchical_views(views);
    assert!(
        views >= 384 && boundary > 10_000,
        "{views} views, {boundary} boundary tiles"
    );
}

/// A diagonal of Issue 5's matrix
/// ([`hierarchical_stencil_matches_brute_force_on_shared_jobs`], which
/// `.ci/run` runs in full) with the same checks: two views of every shared
/// job, each in one variant (one- or two-sided, Auto, zfail or zp+; all six
/// appear), [`sparse_views`].
#[test]
fn hierarchical_stencil_matches_brute_force_on_a_diagonal() {
    let views = sparse_views(2, 1);
    let n = views.len() as u64;
    let (checked, boundary) = check_hierarchical_views(views);
    assert_eq!(checked, n);
    if n > 0 {
        assert!(
            n >= 16 && boundary > BOUNDARY_TILES_ON_A_DIAGONAL,
            "{n} views, {boundary} boundary tiles"
        );
    }
}

/// Boundary tiles the hierarchical diagonal meets at least (it met 0 when it
/// did not run, so the check cannot pass empty).
const BOUNDARY_TILES_ON_A_DIAGONAL: u64 = 10_000;

/// A run of [`check_culling_runs`]: a shared job, one- or two-sided, its
/// first `frames` frames, and which clamping runners join it (0 fragment
/// receivers, 1 discrete).
type CullingRun = (&'static SharedJob, bool, u32, &'static [usize]);

/// What [`check_culling_runs`] counted: casters without and with culling;
/// per clamping kind (fragment, discrete), its segments and the casters
/// (without culling) of the runs it joined.
#[derive(Default)]
struct CullingTotals {
    casters: u64,
    culled: u64,
    segments: [u64; 2],
    clamp_casters: [u64; 2],
}

/// Issue 6's conservative culling on shared-job runs (Auto): the culled eye
/// pass (PSR, CHC) and the light pass (PSC, 128² light views) leave every
/// mask pixel as it is without culling. Each run goes through its frames in
/// order on its own runners (CHC's temporal coherence); the runs go in
/// parallel.
///
/// Clamping runners join where a run asks: continuous clamping to fragment
/// receivers, discrete clamping (10 slices); each keeps every pixel but ones
/// the reference calls ambiguous (a segment's new vertices snap on their
/// own), of which at most 0.01% of the image may differ from the reference's
/// class. Panics with every failure.
fn check_culling_runs(runs: Vec<CullingRun>) -> CullingTotals {
    use shadowcull::jobs::config::resolve_lights;
    use shadowcull::jobs::frame::FrameRunner;
    use shadowcull::pipeline::{
        ClampReceiversSpec, ClampingSpec, CullingSpec, PipelineOptions, StencilBackend,
    };
    // Per run: its counts and failures.
    let per_run: Vec<(CullingTotals, Vec<String>)> = (runs.into_par_iter())
        .map(|(j, two_sided, frames, kinds)| {
            let (mut casters, mut culled, mut failures) = (0u64, 0u64, Vec::new());
            let mut segments = [0u64; 2];
            let (w, h) = j.size();
            let lights =
                resolve_lights(&j.job, &j.loaded, &j.scene.bounds(), &j.file).unwrap();
            let base = PipelineOptions {
                stencil: StencilBackend::H,
                two_sided,
                reference_every: 0,
                light_resolution: 128,
                ..Default::default()
            };
            let culled_opts = PipelineOptions {
                culling: CullingSpec::Chc,
                ..base
            };
            let fragment_opts = PipelineOptions {
                clamping: ClampingSpec::Continuous,
                clamping_receivers: ClampReceiversSpec::Fragment,
                ..culled_opts
            };
            let discrete_opts = PipelineOptions {
                clamping: ClampingSpec::Discrete,
                slices: 10,
                ..culled_opts
            };
            let (mut plain, mut cull) = (
                FrameRunner::new(j.scene.clone()),
                FrameRunner::new(j.scene.clone()),
            );
            let every = [(fragment_opts, "fragment"), (discrete_opts, "discrete")];
            let mut clamps: Vec<_> = (kinds.iter())
                .map(|&k| (FrameRunner::new(j.scene.clone()), every[k].0, every[k].1))
                .collect();
            for frame in 0..frames.min(j.job.frame_count()) {
                let cam = (j.path.at(frame).unwrap())
                    .camera(f64::from(w) / f64::from(h))
                    .unwrap();
                let a = plain
                    .frame(frame, &cam, &lights, (w, h), &base, false)
                    .unwrap();
                let b = cull
                    .frame(frame, &cam, &lights, (w, h), &culled_opts, false)
                    .unwrap();
                for (clamp, opts, label) in &mut clamps {
                    let c = clamp.frame(frame, &cam, &lights, (w, h), opts, false).unwrap();
                    for (li, (x, z)) in a.iter().zip(&c).enumerate() {
                        let s = z.row.shadow.volumes.segments as u64;
                        segments[usize::from(*label == "discrete")] += s;
                        let (p, q) = (&x.mask().pixels, &z.mask().pixels);
                        let differ: Vec<usize> =
                            (0..p.len()).filter(|&i| p[i] != q[i]).collect();
                        if differ.is_empty() {
                            continue;
                        }
                        let ropts = ReferenceOptions {
                            two_sided,
                            ..Default::default()
                        };
                        let eye = &j.eye(frame).1;
                        let r = reference_mask(j.bvh(), &cam, &lights[li], w, h, &ropts, Some(eye.surface()));
                        let clear = differ.iter().filter(|&&i| !r.ambiguous[i]).count();
                        let astray = differ.iter().filter(|&&i| q[i] != r.mask.pixels[i]).count();
                        if clear > 0 || astray as u64 > u64::from(w * h) / 10_000 {
                            failures.push(format!(
                                "{} camera {frame} light {li} two_sided {two_sided}, {label} clamping: {} pixels differ, {clear} not ambiguous, {astray} not the reference's",
                                j.name,
                                differ.len()
                            ));
                        }
                    }
                }
                for (li, (x, y)) in a.iter().zip(&b).enumerate() {
                    casters += x.row.shadow.psc;
                    culled += y.row.shadow.psc;
                    let differ = x
                        .mask()
                        .pixels
                        .iter()
                        .zip(&y.mask().pixels)
                        .filter(|(p, q)| p != q)
                        .count();
                    if differ > 0 {
                        failures.push(format!(
                            "{} camera {frame} light {li} two_sided {two_sided}: {differ} pixels differ",
                            j.name
                        ));
                    }
                }
            }
            let mut t = CullingTotals {
                casters,
                culled,
                ..CullingTotals::default()
            };
            for &k in kinds {
                t.segments[k] = segments[k];
                t.clamp_casters[k] = casters;
            }
            (t, failures)
        })
        .collect();
    let mut t = CullingTotals::default();
    let mut failures = Vec::new();
    for (r, f) in per_run {
        t.casters += r.casters;
        t.culled += r.culled;
        for k in 0..2 {
            t.segments[k] += r.segments[k];
            t.clamp_casters[k] += r.clamp_casters[k];
        }
        failures.extend(f);
    }
    let [fragment, discrete] = t.segments;
    println!(
        "casters without culling {}, with {}; {fragment} fragment segments, {discrete} discrete segments",
        t.casters, t.culled
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    t
}

/// The culling and clamping counts of a check that ran: culling culled, and
/// each clamping kind cut volumes (fragment segments more than a quarter of
/// its runs' casters, discrete more than an eighth).
fn assert_culled_and_clamped(t: &CullingTotals) {
    let [fragment, discrete] = t.segments;
    let [fragment_casters, discrete_casters] = t.clamp_casters;
    assert!(t.culled < t.casters, "{} of {}", t.culled, t.casters);
    assert!(
        fragment > fragment_casters / 4,
        "{fragment} fragment segments"
    );
    assert!(
        discrete > discrete_casters / 8,
        "{discrete} discrete segments"
    );
}

/// [`check_culling_runs`] in full: every shared job one- and two-sided over
/// all its frames, with both clamping kinds (`.ci/run`'s `test-heavy`
/// step; the default run checks [`culling_keeps_the_mask_on_a_diagonal_of_the_shared_jobs`]).
#[test]
#[ignore = "the full culling matrix: .ci/run's test-heavy step"]
fn culling_keeps_every_shared_job_mask() {
    let runs: Vec<CullingRun> = (shared_jobs().iter())
        .flat_map(|j| {
            [
                (j, false, u32::MAX, &[0, 1][..]),
                (j, true, u32::MAX, &[0, 1][..]),
            ]
        })
        .collect();
    let t = check_culling_runs(runs);
    if !shared_jobs().is_empty() {
        assert_culled_and_clamped(&t);
    }
}

/// A diagonal of [`culling_keeps_every_shared_job_mask`] with the same
/// checks: every shared job once over its first four frames, one- or
/// two-sided and with one clamping kind in turn (every combination appears).
#[test]
fn culling_keeps_the_mask_on_a_diagonal_of_the_shared_jobs() {
    const KINDS: [&[usize]; 2] = [&[0], &[1]];
    let runs: Vec<CullingRun> = (shared_jobs().iter().enumerate())
        .map(|(k, j)| (j, k % 2 == 1, 4, KINDS[k / 2 % 2]))
        .collect();
    let t = check_culling_runs(runs);
    if !shared_jobs().is_empty() {
        assert_culled_and_clamped(&t);
    }
}

/// Continuous clamping on the shared views: for each (view, variant), the
/// mask with clamping (receivers `all`, gaps merged by the default cost
/// model, and every gap kept) equals the unclamped mask on every pixel, and
/// the views clamp something. Returns (variants, segments).
fn check_clamping(views: Vec<HViewSpec>) -> (u64, u64) {
    use shadowcull::pipeline::{ClampOptions, ClampReceiversSpec};
    let per_view: Vec<(u64, u64, Vec<String>)> = (views.into_par_iter())
        .map(|(j, frame, li, variants)| {
            let (cam, eye) = j.eye(frame);
            let light = &j.lights[li];
            let mut scratch = ShadowScratch::default();
            let (mut checked, mut segments, mut failures) = (0, 0, Vec::new());
            for (two_sided, method) in variants {
                let base = ShadowOptions {
                    method,
                    two_sided,
                    ..Default::default()
                };
                let plain = shadow_mask(&j.scene, cam, light, eye, &base, &mut scratch).unwrap();
                for (vertex_cost, pixel_cost) in [(40.0, 1.0), (0.0, 1.0)] {
                    let opts = ShadowOptions {
                        clamping: Some(ClampOptions {
                            receivers: ClampReceiversSpec::All,
                            vertex_cost,
                            pixel_cost,
                            slices: None,
                        }),
                        ..base
                    };
                    let clamped =
                        shadow_mask(&j.scene, cam, light, eye, &opts, &mut scratch).unwrap();
                    checked += 1;
                    segments += clamped.volumes.segments as u64;
                    let differ: Vec<usize> = (plain.mask.pixels.iter().zip(&clamped.mask.pixels))
                        .enumerate()
                        .filter(|(_, (a, b))| a != b)
                        .map(|(i, _)| i)
                        .collect();
                    if differ.is_empty() {
                        continue;
                    }
                    // A segment's new vertices snap on their own: a pixel
                    // centre within snapping distance of a shadow boundary
                    // may flip. Such a pixel is ambiguous in the reference.
                    let (w, h) = j.size();
                    let ropts = ReferenceOptions {
                        two_sided,
                        ..Default::default()
                    };
                    let r = reference_mask(j.bvh(), cam, light, w, h, &ropts, Some(eye.surface()));
                    let clear: Vec<&usize> = differ.iter().filter(|&&i| !r.ambiguous[i]).collect();
                    let what = format!(
                        "{} camera {frame} light {li} {method:?}{} v={vertex_cost}",
                        j.name,
                        if two_sided { " two-sided" } else { "" }
                    );
                    println!(
                        "{what}: {} pixels differ, {} not ambiguous",
                        differ.len(),
                        clear.len()
                    );
                    if !clear.is_empty() || differ.len() as u64 > u64::from(w * h) / 10_000 {
                        failures.push(format!(
                            "{what}: {} pixels differ, {} not ambiguous in the reference ({:?})",
                            differ.len(),
                            clear.len(),
                            &clear[..clear.len().min(5)]
                        ));
                    }
                }
            }
            (checked, segments, failures)
        })
        .collect();
    let failures: Vec<String> = per_view.iter().flat_map(|v| v.2.clone()).collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    per_view.iter().fold((0, 0), |(c, s), v| (c + v.0, s + v.1))
}

/// Continuous clamping never changes the mask: two views of every shared
/// job, each in one variant (one- or two-sided, Auto, zfail or zp+),
/// [`sparse_views`]; `.ci/run` runs every variant of every view
/// ([`clamping_keeps_every_shared_job_mask_in_every_variant`]).
#[test]
fn clamping_keeps_the_mask_on_a_diagonal_of_the_shared_views() {
    let views = sparse_views(2, 2);
    let n = views.len() as u64;
    let (checked, segments) = check_clamping(views);
    assert_eq!(checked, 2 * n);
    if n > 0 {
        assert!(
            segments > checked,
            "{segments} segments over {checked} masks"
        );
    }
}

/// [`clamping_keeps_the_mask_on_a_diagonal_of_the_shared_views`] in every
/// variant of every view (`.ci/run`'s `test-heavy` step).
#[test]
#[ignore = "the full clamping matrix: .ci/run's test-heavy step"]
fn clamping_keeps_every_shared_job_mask_in_every_variant() {
    let views: Vec<_> = (shared_views().into_iter())
        .map(|(j, frame, li)| (j, frame, li, H_VARIANTS.to_vec()))
        .collect();
    let (checked, segments) = check_clamping(views);
    println!("{checked} masks, {segments} segments");
}
