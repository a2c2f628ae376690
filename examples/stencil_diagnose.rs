//! Diagnostics of the shared-job exactness matrix (`shared_jobs_match_the_reference`
//! in `tests/stencil_exact.rs`): what the stencil pipeline and the ray-cast
//! reference see at a mismatched pixel. Prints only; needs the shared corpus
//! (`../shared/data`), and says so when it is absent.
//!
//! - `cargo run --release --example stencil_diagnose -- mismatches [--job SUBSTRING]`:
//!   every mismatched pixel of the matrix (Auto, one-sided) on the shared jobs
//!   whose file name contains SUBSTRING (all by default);
//! - `cargo run --release --example stencil_diagnose -- pixel JOB CAMERA LIGHT X Y [--all]`:
//!   one pixel in depth, e.g. `pixel bunny 1 3 135 85` (`--all` also lists
//!   the volume triangles with a stencil value and an f64 crossing).

use clap::{Parser, Subcommand};
use glam::DVec3;
use shadowcull::mask::compare;
use shadowcull::pipeline::{eye_pass, shadow_mask, MeshCache, ShadowOptions, ShadowScratch};
use shadowcull::reference::{reference_mask, ReferenceOptions, TriangleBvh};
use shadowgen::MethodChoice;

/// Diagnostics of the shared-job exactness matrix.
#[derive(Parser)]
struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Every mismatched pixel of the matrix (Auto, one-sided): classes, depths,
    /// the volumes and casters at the pixel, and how far the class is from flipping.
    Mismatches {
        /// Only the shared jobs whose file name contains this.
        #[arg(long, default_value = "")]
        job: String,
    },
    /// One pixel in depth: the casters between it and the light, and every
    /// volume triangle that counts there or that the eye ray crosses.
    Pixel {
        /// The first shared job whose file name contains this.
        job: String,
        /// The camera: a frame of the job's path.
        camera: u32,
        /// The light: an index into the job's lights.
        light: usize,
        /// Pixel column.
        x: u32,
        /// Pixel row (0 at the top).
        y: u32,
        /// Also list the counting volume triangles the eye ray does not cross in f64.
        #[arg(long)]
        all: bool,
    },
}

fn main() {
    let args = Args::parse();
    if testkit::shared_data().is_none() {
        return;
    }
    match args.command {
        Command::Mismatches { job } => mismatches(&job),
        Command::Pixel {
            job,
            camera,
            light,
            x,
            y,
            all,
        } => one_pixel(&job, camera, light, (x, y), all),
    }
}

/// Diagnoses every mismatched pixel of the shared-job matrix (the jobs whose
/// file name contains `pick`): reference and pipeline
/// classes, surface depth (exact and eye-buffer), δ, the volumes whose stencil
/// contribution is non-zero at the pixel, the casters the shadow ray hits or
/// nearly misses (margin = signed distance of the ray's plane hit to the
/// nearest edge, in units of the triangle's size), and how far the point must
/// move along the eye ray (in δ) or across the screen (in pixels) for the
/// reference's class to flip.
fn mismatches(pick: &str) {
    use scene::{faces_light, ObjectId};
    use shadowcull::jobs::config::load_scene_for_job;
    use shadowcull::jobs::config::Job;
    for f in testkit::shared_jobs(pick) {
        let job = Job::from_file(&f).unwrap();
        let (w, h) = job.resolution;
        let (loaded, scene, path) = load_scene_for_job(&job, Some(&f)).unwrap();
        let bounds = scene.bounds();
        let meshes = MeshCache::new(&scene);
        let bvh = TriangleBvh::new(&scene);
        let mut scratch = ShadowScratch::default();
        // All world triangles (f64), for brute-force rays.
        let mut tris: Vec<(ObjectId, u32, [DVec3; 3])> = Vec::new();
        for o in 0..scene.objects().len() {
            let id = ObjectId::from_slot(o as u32);
            for t in 0..scene.object_mesh(id).triangles().len() {
                tris.push((id, t as u32, scene.world_triangle(id, t)));
            }
        }
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        for frame in 0..job.frame_count() {
            let cam = path.at(frame).unwrap().camera(w as f64 / h as f64).unwrap();
            let eye = eye_pass(&scene, &meshes, &cam, w, h).unwrap();
            for (li, spec) in job.lights.iter().enumerate() {
                let light = spec.resolve(&loaded, &bounds, li, &f).unwrap();
                let out = shadow_mask(
                    &scene,
                    &cam,
                    &light,
                    &eye,
                    &ShadowOptions::default(),
                    &mut scratch,
                )
                .unwrap();
                let r = reference_mask(
                    &bvh,
                    &cam,
                    &light,
                    w,
                    h,
                    &ReferenceOptions::default(),
                    Some(eye.surface()),
                );
                let c = compare(&r.mask, &r.ambiguous, &out.mask);
                if c.mismatch_pixels.is_empty() {
                    continue;
                }
                // Other methods, for comparison.
                let other = |method| {
                    shadow_mask(
                        &scene,
                        &cam,
                        &light,
                        &eye,
                        &ShadowOptions {
                            method,
                            ..Default::default()
                        },
                        &mut ShadowScratch::default(),
                    )
                    .unwrap()
                    .mask
                };
                let zpass = other(MethodChoice::ZPass);
                let zfail = other(MethodChoice::ZFail);
                // Volumes, for per-volume stencil values.
                let mut vb = raster::VolumeBuffer::default();
                shadowgen::build_volumes(
                    &mut vb,
                    &scene,
                    &cam,
                    &light,
                    &(0..scene.objects().len() as u32)
                        .map(ObjectId::from_slot)
                        .collect::<Vec<_>>(),
                    shadowgen::BuildOptions {
                        method: MethodChoice::Auto,
                        two_sided: false,
                        viewport: None,
                        finite_extrusion: false,
                    },
                    &mut shadowgen::SilhouetteCache::default(),
                )
                .unwrap();
                for &(x, y, on_boundary) in &c.mismatch_pixels {
                    let i = (y * w + x) as usize;
                    let (obj, tri) = eye.primitive(x, y).unwrap();
                    let surf = scene.world_triangle(obj, tri as usize);
                    let dir = cam.ray_direction(x as f64 + 0.5, y as f64 + 0.5, w, h);
                    let fwd = cam.forward();
                    let plane_t = |d: DVec3| {
                        let n = (surf[1] - surf[0]).cross(surf[2] - surf[0]);
                        n.dot(surf[0] - cam.position) / n.dot(d)
                    };
                    let t = plane_t(dir);
                    let p = cam.position + dir * t;
                    let vd = (p - cam.position).dot(fwd);
                    let delta = (4.0 * shadowcull::reference::DEFAULT_DEPTH_ERROR * vd)
                        .max(vd / (1u64 << 20) as f64);
                    let exact_depth = cam.near / vd;
                    let buf_depth = eye.target.depth_at(x, y).unwrap() as f64;
                    println!(
                        "== {name} camera {frame} light {li} pixel ({x},{y}) boundary={on_boundary}: ref {:?} pipe {:?} zpass {:?} zfail {:?} raw_nonzero {}",
                        r.mask.pixels[i], out.mask.pixels[i], zpass.pixels[i], zfail.pixels[i], out.raw_nonzero[i]
                    );
                    println!(
                        "   surface {obj:?} tri {tri} {surf:?}; p {p}; view depth {vd:.6e}; delta {delta:.3e}; depth exact {exact_depth:.9e} buffer {buf_depth:.9e} (rel err {:.2e}, in delta {:.2})",
                        (buf_depth - exact_depth) / exact_depth,
                        ((exact_depth / buf_depth - 1.0) * vd) / delta
                    );
                    // Per-volume stencil values at the pixel.
                    let mut vals = Vec::new();
                    for range in &vb.ranges {
                        let mut st =
                            raster::StencilTarget::new(w, h, raster::StencilBits::Wide).unwrap();
                        st.draw_volume(
                            &eye.target,
                            scene::transform::clip_from_local(&cam, &range.world_from_local),
                            &vb,
                            range,
                            raster::StencilTests::default(),
                            &mut raster::StencilStats::default(),
                        )
                        .unwrap();
                        let v = st.value(x, y);
                        if v != 0 {
                            vals.push((range.object, range.method, v));
                        }
                    }
                    println!("   volumes with non-zero stencil at the pixel: {vals:?}");
                    // Brute-force shadow ray with blockers and near misses.
                    let classify = |q: DVec3, verbose: bool| -> bool {
                        let (ldir, tmax) = match light.position() {
                            Some(l) => ((l - q).normalize(), (l - q).length()),
                            None => (light.toward_light(q).normalize(), f64::INFINITY),
                        };
                        let n = (surf[1] - surf[0]).cross(surf[2] - surf[0]);
                        let behind = n.dot(q - surf[0]) * n.dot(cam.position - surf[0]).signum();
                        let mut tmin = delta;
                        if behind < 0.0 && n.dot(ldir) != 0.0 {
                            let tp = n.dot(surf[0] - q) / n.dot(ldir);
                            if tp > 0.0 {
                                tmin = tp + delta;
                            }
                        }
                        let mut blocked = false;
                        for (o, k, tri3) in &tris {
                            if (*o, *k) == (obj, tri) || !faces_light(tri3, &light) {
                                continue;
                            }
                            let e1 = tri3[1] - tri3[0];
                            let e2 = tri3[2] - tri3[0];
                            let nn = e1.cross(e2);
                            let den = nn.dot(ldir);
                            if den == 0.0 {
                                continue;
                            }
                            let th = nn.dot(tri3[0] - q) / den;
                            if !(th > tmin && th < tmax) {
                                continue;
                            }
                            let hp = q + ldir * th;
                            // Signed distance to each edge inside the plane (positive inside).
                            let nu = nn.normalize();
                            let mut margin = f64::INFINITY;
                            for e in 0..3 {
                                let a = tri3[e];
                                let b = tri3[(e + 1) % 3];
                                let inward = nu.cross(b - a).normalize();
                                margin = margin.min((hp - a).dot(inward));
                            }
                            let size = e1.length().max(e2.length());
                            if margin >= 0.0 {
                                blocked = true;
                            }
                            if verbose && margin > -1e-3 * size {
                                println!(
                                    "   caster {o:?} tri {k}: t {th:.6e}, margin {margin:.3e} ({:.2e} of size), blocks {}",
                                    margin / size,
                                    margin >= 0.0
                                );
                            }
                        }
                        blocked
                    };
                    let base = classify(p, true);
                    let mut along = None;
                    for s in 0..24 {
                        let m = (1u64 << s) as f64 * delta;
                        if classify(p - dir * m, false) != base
                            || classify(p + dir * m, false) != base
                        {
                            along = Some(1u64 << s);
                            break;
                        }
                    }
                    let mut across = None;
                    'outer: for s in (0..30).rev() {
                        let o = 0.5f64.powi(s);
                        for (dx, dy) in [(o, 0.0), (-o, 0.0), (0.0, o), (0.0, -o)] {
                            let d2 =
                                cam.ray_direction(x as f64 + 0.5 + dx, y as f64 + 0.5 + dy, w, h);
                            let q = cam.position + d2 * plane_t(d2);
                            if classify(q, false) != base {
                                across = Some(o);
                                break 'outer;
                            }
                        }
                    }
                    println!(
                        "   brute-force shadow: {base}; class flips along the eye ray at {along:?} delta, across the screen at {across:?} px"
                    );
                }
            }
        }
    }
}

/// One pixel in depth: `pixel` of `camera` (a frame of the job's path) and light
/// `li` of the first shared job whose file name contains `pick`.
/// Prints, per object, how many of its light-facing triangles lie between the
/// eye (and the near-plane corners) and the light; then every volume triangle
/// whose own stencil value at the pixel is non-zero next to every one the eye
/// ray crosses in f64 (extruded vertices placed 1e4 view depths away).
fn one_pixel(pick: &str, frame: u32, li: usize, (x, y): (u32, u32), all: bool) {
    use scene::{faces_light, ObjectId};
    use shadowcull::jobs::config::load_scene_for_job;
    use shadowcull::jobs::config::Job;
    let f = testkit::shared_jobs(pick)
        .into_iter()
        .next()
        .expect("a shared job matching the pick");
    let job = Job::from_file(&f).unwrap();
    let (w, h) = job.resolution;
    let (loaded, scene, path) = load_scene_for_job(&job, Some(&f)).unwrap();
    let bounds = scene.bounds();
    let meshes = MeshCache::new(&scene);
    let cam = path.at(frame).unwrap().camera(w as f64 / h as f64).unwrap();
    let eye = eye_pass(&scene, &meshes, &cam, w, h).unwrap();
    let light = job.lights[li].resolve(&loaded, &bounds, li, &f).unwrap();
    println!("light {light:?}; eye {}", cam.position);
    // Light-facing triangles between a point and the light, per object.
    let count_between = |q: DVec3| {
        let (ldir, tmax) = match light.position() {
            Some(l) => ((l - q).normalize(), (l - q).length()),
            None => (light.toward_light(q).normalize(), f64::INFINITY),
        };
        let mut per: std::collections::BTreeMap<u32, Vec<u32>> = Default::default();
        for o in 0..scene.objects().len() {
            let id = ObjectId::from_slot(o as u32);
            for t in 0..scene.object_mesh(id).triangles().len() {
                let tri = scene.world_triangle(id, t);
                if !faces_light(&tri, &light) {
                    continue;
                }
                let e1 = tri[1] - tri[0];
                let e2 = tri[2] - tri[0];
                let pv = ldir.cross(e2);
                let det = e1.dot(pv);
                if det == 0.0 {
                    continue;
                }
                let s = q - tri[0];
                let u = s.dot(pv) / det;
                let qq = s.cross(e1);
                let v = ldir.dot(qq) / det;
                let th = e2.dot(qq) / det;
                if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && th > 0.0 && th < tmax {
                    per.entry(o as u32).or_default().push(t as u32);
                }
            }
        }
        per
    };
    println!("eye between-count: {:?}", count_between(cam.position));
    let inv = (cam.clip_from_eye_relative()).inverse();
    for (cx, cy) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
        let e = inv * glam::DVec4::new(cx, cy, 1.0, 1.0);
        let q = cam.position + e.truncate() / e.w;
        println!("near corner ({cx},{cy}) {q}: {:?}", count_between(q));
    }
    let (obj, tri) = eye.primitive(x, y).unwrap();
    let surf = scene.world_triangle(obj, tri as usize);
    let dir = cam.ray_direction(x as f64 + 0.5, y as f64 + 0.5, w, h);
    let n = (surf[1] - surf[0]).cross(surf[2] - surf[0]);
    let t = n.dot(surf[0] - cam.position) / n.dot(dir);
    let p = cam.position + dir * t;
    println!(
        "pixel surface {obj:?} tri {tri}, p {p}, eye-ray t {t}; p between-count {:?}",
        count_between(p)
    );
    for method in [MethodChoice::Auto, MethodChoice::ZPass, MethodChoice::ZFail] {
        let mut vb = raster::VolumeBuffer::default();
        shadowgen::build_volumes(
            &mut vb,
            &scene,
            &cam,
            &light,
            &(0..scene.objects().len() as u32)
                .map(ObjectId::from_slot)
                .collect::<Vec<_>>(),
            shadowgen::BuildOptions {
                method,
                two_sided: false,
                viewport: None,
                finite_extrusion: false,
            },
            &mut shadowgen::SilhouetteCache::default(),
        )
        .unwrap();
        println!("-- method {method:?}");
        let far = 1e4 * t;
        for range in &vb.ranges {
            let clip = scene::transform::clip_from_local(&cam, &range.world_from_local);
            let mut lines = Vec::new();
            let mut total = 0;
            let mut exact_total = 0;
            for k in 0..range.index_count / 3 {
                let mut one = range.clone();
                one.first_index = range.first_index + 3 * k;
                one.index_count = 3;
                let mut st = raster::StencilTarget::new(w, h, raster::StencilBits::Wide).unwrap();
                st.draw_volume(
                    &eye.target,
                    clip,
                    &vb,
                    &one,
                    raster::StencilTests::default(),
                    &mut raster::StencilStats::default(),
                )
                .unwrap();
                let v = st.value(x, y);
                // f64 crossing of the eye ray with this volume triangle.
                let f0 = one.first_index as usize;
                let idx: [u32; 3] = [vb.indices[f0], vb.indices[f0 + 1], vb.indices[f0 + 2]];
                let hv: Vec<glam::DVec4> = idx
                    .iter()
                    .map(|&j| {
                        let q = vb.positions[j as usize];
                        range.world_from_local
                            * glam::DVec4::new(q[0] as f64, q[1] as f64, q[2] as f64, q[3] as f64)
                    })
                    .collect();
                let fin: Vec<DVec3> = hv
                    .iter()
                    .map(|q| {
                        if q.w != 0.0 {
                            q.truncate() / q.w
                        } else {
                            // An extruded vertex: far along its direction from
                            // the triangle's finite vertices.
                            let base = hv
                                .iter()
                                .find(|r| r.w != 0.0)
                                .map(|r| r.truncate() / r.w)
                                .unwrap_or(cam.position);
                            base + q.truncate().normalize() * far
                        }
                    })
                    .collect();
                let e1 = fin[1] - fin[0];
                let e2 = fin[2] - fin[0];
                let pv = dir.cross(e2);
                let det = e1.dot(pv);
                let mut crossing = None;
                if det != 0.0 {
                    let s = cam.position - fin[0];
                    let u = s.dot(pv) / det;
                    let qq = s.cross(e1);
                    let vv = dir.dot(qq) / det;
                    let th = e2.dot(qq) / det;
                    let margin = u.min(vv).min(1.0 - u - vv);
                    if margin > -1e-4 && th > 0.0 {
                        crossing = Some((th, margin, det.signum()));
                    }
                    if v != 0 && (crossing.is_none() || all) {
                        println!(
                            "      (tri {k} of object {}: u {u:.3e} v {vv:.3e} th {th:.6e}; homogeneous world {hv:?})",
                            range.object
                        );
                    }
                }
                let crosses_counted = crossing.is_some_and(|(th, m, _)| {
                    m >= 0.0
                        && match range.method {
                            raster::VolumeMethod::ZFail => th > t,
                            _ => th < t,
                        }
                });
                if crosses_counted {
                    exact_total += 1;
                }
                total += v;
                if v != 0 || crossing.is_some_and(|c| c.1 > -2e-5) {
                    let lv = idx.map(|j| glam::Vec4::from_array(vb.positions[j as usize]));
                    let su =
                        raster::setup_triangle([clip * lv[0], clip * lv[1], clip * lv[2]], w, h);
                    // Snapped signed area (screen y down): negative = Front.
                    let poly = su.polygon();
                    let mut area2 = 0i128;
                    for a in 0..poly.len() {
                        let (p0, p1) = (poly[a], poly[(a + 1) % poly.len()]);
                        area2 += p0.x as i128 * p1.y as i128 - p1.x as i128 * p0.y as i128;
                    }
                    let snapped_front = area2 < 0;
                    let flipped = match su.facing {
                        Some(raster::Facing::Front) => !snapped_front && area2 != 0,
                        Some(raster::Facing::Back) => snapped_front,
                        None => false,
                    };
                    lines.push(format!(
                        "        {}tri {k} indices {idx:?}; snapped area*2 {area2} (1/256 px units); snapped {:?} clipped {} facing {:?}",
                        if flipped { "FLIPPED BY SNAPPING: " } else { "" },
                        su.polygon()
                            .iter()
                            .map(|q| (q.x as f64 / 256.0, q.y as f64 / 256.0))
                            .collect::<Vec<_>>(),
                        su.clipped,
                        su.facing
                    ));
                }
                if v != 0 || crossing.is_some() {
                    lines.push(format!(
                        "      tri {k}: raster {v}, f64 crossing {crossing:?} (eye-ray t of surface {t:.9e}) w {:?}",
                        hv.iter().map(|q| q.w).collect::<Vec<_>>()
                    ));
                }
            }
            if !lines.is_empty() {
                println!(
                    "   object {} {:?}: raster sum {total}, f64 counted crossings (unsigned) {exact_total}",
                    range.object, range.method
                );
                for l in lines {
                    println!("{l}");
                }
            }
        }
    }
}
