//! Differential fuzzing of sharded jobs against the single run (the
//! contract of `shadowcull::jobs::shard`, which `scripts/shard_check.sh` checks
//! on the default job): a small scene from the fuzzer's bytes (the
//! `pipeline` target's boxes and light), a camera moving along a line for
//! 2 to 12 frames, CHC or CHC++ culling, keyframes or none, 1 to 4 shards
//! and 0 to 7 warm-up frames. Each shard runs in its own `FrameRunner`, as
//! on its own machine: its warm-up frames (`shard::warmup_start`), then its
//! block. Checked:
//! - every frame's mask equals the single run's;
//! - where keyframes put the shard's first frame on one (or it is frame 0),
//!   every column but the times (queries, PSR, PSC, volumes, pixels)
//!   equals the single run's too.

use crate::{box_scene, point, Bytes};
use glam::DVec3;
use shadowcull::jobs::frame::FrameRunner;
use shadowcull::jobs::shard::{warmup_start, Shard};
use shadowcull::mask::Mask;
use shadowcull::scene::Camera;
use shadowcull::stats::{Cell, Columns};
use shadowcull::{CullingSpec, PipelineOptions, StencilBackend};
use std::ops::Range;
use std::sync::Arc;

const W: u32 = 40;
const H: u32 = 30;

/// The columns that are not times.
fn counters(c: &Columns) -> Vec<(&'static str, Cell)> {
    c.iter()
        .filter(|(_, cell)| !matches!(cell, Cell::Ms(_)))
        .cloned()
        .collect()
}

/// One fuzz input through the target (a panic is a finding).
pub fn run(data: &[u8]) {
    let mut b = Bytes(data);
    let Some((scene, light)) = box_scene(&mut b) else {
        return;
    };
    let frames = 2 + u32::from(b.u8() % 11);
    let eye = point(&mut b, 14.0) + DVec3::Y * 4.0;
    let step = point(&mut b, 1.5);
    let target = point(&mut b, 4.0);
    let aspect = f64::from(W) / f64::from(H);
    let Ok(cameras) = (0..frames)
        .map(|f| {
            Camera::look_at(
                eye + step * f64::from(f),
                target,
                DVec3::Y,
                1.0,
                aspect,
                0.05,
            )
        })
        .collect::<Result<Vec<_>, _>>()
    else {
        return;
    };
    let culling = [CullingSpec::Chc, CullingSpec::Chcpp][usize::from(b.u8() % 2)];
    let keyframe = match b.u8() % 3 {
        0 => None,
        k => Some(u32::from(k) + 1),
    };
    let count = 1 + u32::from(b.u8() % 4);
    let warmup = u32::from(b.u8() % 8);
    let options = PipelineOptions {
        culling,
        stencil: StencilBackend::H,
        light_resolution: 64,
        reference_every: 0,
        ..Default::default()
    };
    let scene = Arc::new(scene);
    let lights = [light];
    // Frames `block` after warm-up frames `warm`, in a fresh runner.
    let run = |warm: Range<u32>, block: Range<u32>| -> Vec<(Mask, Columns)> {
        let mut runner = FrameRunner::new(scene.clone());
        runner.set_keyframe(keyframe);
        let mut frame = |f: u32| {
            let camera = &cameras[f as usize];
            let mut out = runner
                .frame(f, camera, &lights, (W, H), &options, false)
                .expect("a frame");
            out.pop().expect("one light")
        };
        for f in warm {
            frame(f);
        }
        block
            .map(|f| {
                let lf = frame(f);
                (lf.mask().clone(), lf.row.columns())
            })
            .collect()
    };
    let single = run(0..0, 0..frames);
    for index in 0..count {
        let shard = Shard::new(index, count).expect("index below count");
        let block = shard.range(frames);
        let warm = warmup_start(block.start, warmup, keyframe)..block.start;
        let aligned = block.start == 0 || keyframe.is_some_and(|k| block.start.is_multiple_of(k));
        let got = run(warm, block.clone());
        for (f, (g, s)) in block.zip(
            got.iter()
                .zip(&single[shard.range(frames).start as usize..]),
        ) {
            assert!(
                g.0 == s.0,
                "shard {index}/{count}: frame {f}'s mask differs"
            );
            if aligned {
                assert_eq!(
                    counters(&g.1),
                    counters(&s.1),
                    "shard {index}/{count} (keyframe {keyframe:?}): frame {f}'s counters differ"
                );
            }
        }
    }
}
