//! Laws of the built volumes on the shared scenes (`../shared/data`; skipped
//! with a note when absent): every buffer is consistent, every closed-volume
//! range (zfail, zp+) is a closed surface for any mesh (finitely extruded
//! ones included), and the silhouettes
//! balance at every vertex.

use glam::DVec3;
use raster::{VolumeBuffer, VolumeMethod};
use scene::{Light, ObjectId, Scene};
use shadowgen::{build_volumes, BuildOptions, MethodChoice, SilhouetteCache};
use std::collections::HashMap;

fn closed(buf: &VolumeBuffer, r: &raster::VolumeRange) -> bool {
    let mut m: HashMap<(u32, u32), i32> = HashMap::new();
    for t in r.indices().step_by(3) {
        for k in 0..3 {
            let (a, b) = (buf.indices[t + k], buf.indices[t + (k + 1) % 3]);
            if a < b {
                *m.entry((a, b)).or_insert(0) += 1;
            } else if b < a {
                *m.entry((b, a)).or_insert(0) -= 1;
            }
        }
    }
    m.values().all(|&v| v == 0)
}

fn check_scene(name: &str, scene: &Scene, lights: &[Light]) {
    let b = scene.bounds();
    let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
    let c = (lo + hi) * 0.5;
    let r = (hi - lo).length() * 0.5;
    let camera = scene::Camera::look_at(
        c + DVec3::new(0.3, 0.4, 1.0) * r,
        c,
        DVec3::Y,
        1.0,
        1.0,
        r * 1e-3,
    )
    .unwrap();
    let ids: Vec<ObjectId> = (0..scene.objects().len() as u32)
        .map(ObjectId::from_slot)
        .collect();
    let mut cache = SilhouetteCache::new();
    let mut buf = VolumeBuffer::new();
    for (i, l) in lights.iter().enumerate() {
        for method in [MethodChoice::Auto, MethodChoice::ZFail] {
            for two_sided in [false, true] {
                let opts = BuildOptions {
                    method,
                    two_sided,
                    viewport: Some((64, 48)),
                    // A no-op for lights without a range.
                    finite_extrusion: true,
                };
                let st =
                    build_volumes(&mut buf, scene, &camera, l, &ids, opts, &mut cache).unwrap();
                buf.check().unwrap();
                for r in &buf.ranges {
                    if r.method != VolumeMethod::ZPass {
                        assert!(
                            closed(&buf, r),
                            "{name}: light {i} object {} not closed",
                            r.object
                        );
                    }
                }
                eprintln!(
                    "{name} light {i} {method:?} two_sided={two_sided}: {} edges, {} triangles, zpass {} zfail {}, finite {}, sil {:.2} ms, vol {:.2} ms",
                    st.silhouette_edges, st.volume_triangles, st.zpass, st.zfail, st.finite_volumes, st.silhouette_ms, st.volume_ms
                );
            }
        }
    }
}

#[test]
fn shared_meshes_and_city_build_closed_volumes() {
    let Some(root) = testkit::shared_data() else {
        return;
    };
    let city = scene::load::load_path(&root.join("bench/city_4096.txt")).unwrap();
    let mut lights: Vec<Light> = city.lights.iter().map(|(_, l)| *l).collect();
    lights.push(Light::Directional {
        direction: DVec3::new(0.3, -1.0, 0.2),
    });
    check_scene("city_4096", &Scene::new(city.graph).unwrap(), &lights);
    for mesh in ["suzanne.obj", "cow.obj", "fandisk.obj"] {
        let loaded = scene::load::load_path(&root.join("meshes").join(mesh)).unwrap();
        let scene = Scene::new(loaded.graph).unwrap();
        let b = scene.bounds();
        let c = (b.min.as_dvec3() + b.max.as_dvec3()) * 0.5;
        let r = (b.max.as_dvec3() - b.min.as_dvec3()).length();
        let lights = [
            Light::Point {
                position: c + DVec3::new(0.2, 1.0, 0.3) * r,
                range: None,
            },
            Light::Point {
                position: c,
                range: None,
            },
            // Finitely extruded (BuildOptions::finite_extrusion).
            Light::Point {
                position: c + DVec3::new(-0.3, 0.8, 0.5) * r,
                range: Some(1.5 * r),
            },
            Light::Directional {
                direction: DVec3::new(-0.4, -1.0, 0.1),
            },
        ];
        check_scene(mesh, &scene, &lights);
    }
}
