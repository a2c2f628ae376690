//! The culled eye pass (PSR) in the frame runner: along a camera path, the
//! masks and raw stencil with occlusion culling equal those without, frame by
//! frame and light by light, while far fewer objects are drawn; CHC issues
//! fewer queries than stop-and-wait.

use scene::procedural::city::{city, CityParams};
use scene::{Light, Scene};
use shadowcull::config::{CullingSpec, PipelineOptions, StencilBackend};
use shadowcull::frame::FrameRunner;

#[test]
fn culled_eye_pass_keeps_every_mask_along_the_street_path() {
    let loaded = city(&CityParams {
        blocks_x: 6,
        blocks_z: 6,
        ..Default::default()
    })
    .unwrap();
    let path = loaded
        .paths
        .iter()
        .find(|(n, _)| n == "street")
        .unwrap()
        .1
        .clone();
    let scene = Scene::new(loaded.graph).unwrap();
    let b = scene.bounds();
    let c = b.center();
    let lights = [
        Light::Point {
            position: glam::DVec3::new(c.x, f64::from(b.max.y) * 1.5, c.z),
            range: None,
        },
        Light::Directional {
            direction: glam::DVec3::new(0.4, -0.8, 0.3),
        },
    ];
    let res = (160, 120);
    let base = PipelineOptions {
        stencil: StencilBackend::H,
        reference_every: 0,
        ..Default::default()
    };
    let mut runners: Vec<(CullingSpec, FrameRunner)> =
        [CullingSpec::None, CullingSpec::Exact, CullingSpec::Chc]
            .into_iter()
            .map(|c| (c, FrameRunner::new(&scene)))
            .collect();
    let (mut psr, mut queries) = ([0u64; 3], [0u64; 3]);
    for f in 0..20 {
        let cam = path
            .at(f)
            .unwrap()
            .camera(f64::from(res.0) / f64::from(res.1))
            .unwrap();
        let mut outs = Vec::new();
        for (k, (culling, runner)) in runners.iter_mut().enumerate() {
            let opts = PipelineOptions {
                culling: *culling,
                ..base
            };
            let out = runner.frame(f, &cam, &lights, res, &opts, false).unwrap();
            psr[k] += out[0].row.shadow.psr;
            queries[k] += out[0].row.shadow.queries;
            outs.push(out);
        }
        for k in 1..3 {
            for (li, (a, b)) in outs[0].iter().zip(&outs[k]).enumerate() {
                assert!(
                    a.shadow.mask == b.shadow.mask && a.shadow.raw_nonzero == b.shadow.raw_nonzero,
                    "frame {f} light {li}: {:?} changed the mask",
                    runners[k].0
                );
            }
        }
    }
    println!("psr none/exact/chc {psr:?}, queries {queries:?}");
    assert!(psr[2] * 4 < psr[0], "{psr:?}");
    assert!(queries[2] < queries[1], "{queries:?}");
}
