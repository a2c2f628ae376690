//! Culling in the frame runner: the culled eye pass (PSR) and the light pass
//! (PSC, shadow volumes only for potential casters). Along a camera path, the
//! masks with conservative culling equal those without, frame by frame and
//! light by light, while far fewer objects are drawn and cast; CHC issues
//! fewer queries than stop-and-wait.

use shadowcull::jobs::frame::FrameRunner;
use shadowcull::pipeline::{CullingSpec, PipelineOptions, StencilBackend};

#[test]
fn culled_eye_pass_keeps_every_mask_along_the_street_path() {
    let (scene, path) = crate::common::street_city();
    let lights = crate::common::city_lights(&scene);
    let res = (160, 120);
    let base = PipelineOptions {
        stencil: StencilBackend::H,
        reference_every: 0,
        ..Default::default()
    };
    // Light views of 256² and, for CHC once more, 64²: in conservative mode
    // the light-view resolution changes only the speed, never the mask.
    let mut runners: Vec<((CullingSpec, u32), FrameRunner)> = [
        (CullingSpec::None, 256),
        (CullingSpec::Exact, 256),
        (CullingSpec::Chc, 256),
        (CullingSpec::Chc, 64),
        (CullingSpec::Chcpp, 256),
    ]
    .into_iter()
    .map(|c| (c, FrameRunner::new(scene.clone())))
    .collect();
    let (mut psr, mut psc, mut queries) = ([0u64; 5], [0u64; 10], [0u64; 5]);
    for f in 0..20 {
        let cam = path
            .at(f)
            .unwrap()
            .camera(f64::from(res.0) / f64::from(res.1))
            .unwrap();
        let mut outs = Vec::new();
        for (k, ((culling, light_resolution), runner)) in runners.iter_mut().enumerate() {
            let opts = PipelineOptions {
                culling: *culling,
                light_resolution: *light_resolution,
                ..base
            };
            let out = runner.frame(f, &cam, &lights, res, &opts, false).unwrap();
            psr[k] += out[0].row.shadow.psr;
            psc[2 * k] += out[0].row.shadow.psc;
            psc[2 * k + 1] += out[1].row.shadow.psc;
            queries[k] += out[0].row.shadow.queries;
            outs.push(out);
        }
        for k in 1..5 {
            for (li, (a, b)) in outs[0].iter().zip(&outs[k]).enumerate() {
                let differ = a
                    .mask()
                    .pixels
                    .iter()
                    .zip(&b.mask().pixels)
                    .filter(|(p, q)| p != q)
                    .count();
                assert_eq!(
                    differ, 0,
                    "frame {f} light {li}: {:?} changed the mask",
                    runners[k].0
                );
            }
        }
    }
    println!(
        "psr none/exact/chc/chc-64/chcpp {psr:?}, psc (per light) {psc:?}, queries {queries:?}"
    );
    assert!(psr[2] * 4 < psr[0], "{psr:?}");
    assert!(psc[4] < psc[0] && psc[5] < psc[1], "{psc:?}");
    assert!(queries[2] < queries[1], "{queries:?}");
    assert!(
        queries[4] < queries[2],
        "CHC++ issues fewer queries: {queries:?}"
    );
}
