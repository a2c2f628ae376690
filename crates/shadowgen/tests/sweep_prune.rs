//! Sweep-and-prune against its baselines: brute-force pairs, the sort from
//! scratch and an obvhs BVH query give the same pair set every frame, with
//! boxes that move, appear and disappear, and with every swap budget (so both
//! the incremental path and the rebuild are checked).

use proptest::prelude::*;
use shadowgen::{sweep_pairs, ImageRect, SweepPrune};
use testkit::{brute_pairs, bvh_pairs};

/// A box on a half-unit grid, so that boxes often touch and share endpoints.
fn grid_rect() -> impl Strategy<Value = ImageRect> {
    (-8i32..8, -8i32..8, 0i32..6, 0i32..6).prop_map(|(x, y, w, h)| ImageRect {
        min: [x as f32 * 0.5, y as f32 * 0.5],
        max: [(x + w) as f32 * 0.5, (y + h) as f32 * 0.5],
    })
}

/// Per box and frame: stay, step by up to one unit, jump anywhere, or toggle
/// presence.
#[derive(Clone, Debug)]
enum Change {
    Stay,
    Step(i32, i32),
    Jump(ImageRect),
    Toggle,
}

fn change() -> impl Strategy<Value = Change> {
    prop_oneof![
        3 => Just(Change::Stay),
        4 => (-2i32..=2, -2i32..=2).prop_map(|(x, y)| Change::Step(x, y)),
        1 => grid_rect().prop_map(Change::Jump),
        1 => Just(Change::Toggle),
    ]
}

fn apply(frame: &mut [Option<ImageRect>], spare: &mut [ImageRect], changes: &[Change]) {
    for ((slot, spare), c) in frame.iter_mut().zip(spare).zip(changes) {
        match (c, slot.as_mut()) {
            (Change::Step(dx, dy), Some(r)) => {
                for (k, d) in [*dx, *dy].into_iter().enumerate() {
                    r.min[k] += d as f32 * 0.5;
                    r.max[k] += d as f32 * 0.5;
                }
            }
            (Change::Jump(j), Some(r)) => *r = *j,
            (Change::Toggle, Some(r)) => {
                *spare = *r;
                *slot = None;
            }
            (Change::Toggle, None) => *slot = Some(*spare),
            _ => {}
        }
    }
}

proptest! {
    #![proptest_config(testkit::proptest_config(64))]

    #[test]
    fn sweep_and_prune_pairs_equal_the_baselines(
        start in prop::collection::vec(prop::option::weighted(0.8, grid_rect()), 0..40),
        frames in prop::collection::vec(prop::collection::vec(change(), 40), 1..12),
    ) {
        let mut states = [0, 1, 8, u32::MAX].map(|b| SweepPrune::new().budget(b));
        let mut frame = start.clone();
        let mut spare: Vec<ImageRect> = frame
            .iter()
            .map(|r| r.unwrap_or(ImageRect { min: [0.0; 2], max: [1.0; 2] }))
            .collect();
        for (f, changes) in std::iter::once(&Vec::new()).chain(&frames).enumerate() {
            apply(&mut frame, &mut spare, changes);
            let brute = brute_pairs(&frame);
            prop_assert_eq!(&sweep_pairs(&frame), &brute, "sort from scratch, frame {}", f);
            prop_assert_eq!(&bvh_pairs(&frame), &brute, "BVH, frame {}", f);
            for s in &mut states {
                let stats = s.update(&frame).unwrap();
                let mut pairs: Vec<_> = s.pairs().collect();
                pairs.sort_unstable();
                prop_assert_eq!(&pairs, &brute, "incremental, frame {}, stats {:?}", f, stats);
                prop_assert_eq!(stats.pairs, brute.len() as u64);
                prop_assert_eq!(stats.boxes as usize, frame.iter().flatten().count());
                for &(a, b) in &brute {
                    prop_assert!(s.neighbours(a).contains(&b) && s.neighbours(b).contains(&a));
                }
            }
        }
    }
}

/// Shrinking the set (a shorter slice) removes the boxes past its end, and
/// `clear` forgets everything.
#[test]
fn a_shorter_set_removes_the_tail_and_clear_forgets() {
    let r = |x: f32| {
        Some(ImageRect {
            min: [x, 0.0],
            max: [x + 1.0, 1.0],
        })
    };
    let mut s = SweepPrune::new();
    s.update(&[r(0.0), r(0.5), r(0.9)]).unwrap();
    assert_eq!(s.pair_count(), 3);
    let st = s.update(&[r(0.0)]).unwrap();
    assert_eq!((st.removed, st.boxes, st.pairs), (2, 1, 0));
    s.clear();
    let st = s.update(&[r(0.0), r(0.5)]).unwrap();
    assert_eq!((st.inserted, st.pairs), (2, 1));
}
