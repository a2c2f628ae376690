//! Sweep-and-prune benchmark [Steiner §4.4.1]: per frame, the overlapping
//! pairs of the objects' boxes in a point light's view, by the incremental
//! [`SweepPrune`], by sorting from scratch ([`sweep_pairs`]), by an obvhs BVH
//! query and by testing every pair. Prints one JSON line.
//!
//! ```text
//! cargo run --release --example sap_bench -- 17468 --motion camera --frames 100
//! ```
//!
//! - N = 17468 takes the default procedural city's objects; any other N
//!   generates N boxes on a city-like grid (deterministic).
//! - `--motion camera`: the camera walks the street path (the default city's,
//!   or a line across the generated grid); the set is the objects whose boxes
//!   meet the view frustum, the superset of the potentially visible receivers
//!   that frustum culling gives, so boxes appear and disappear.
//! - `--motion objects`: every frame, 5 % of the boxes (a different 5 % each
//!   frame) step by up to `--step` metres per axis (default 0.25 m: 15 m/s
//!   at 60 frames per second).
//! - `--motion light`: the point light circles above the scene
//!   (`--light-speed` degrees per frame, default 1): every box moves on the
//!   image plane.
//!
//! Every frame checks that the incremental pairs equal the sort's; the first
//! `--check-frames` frames also time the BVH and brute force and check them.

use anyhow::{bail, Context};
use glam::{DMat4, DVec3, Vec3};
use scene::{Aabb, LookAt};
use serde_json::json;
use shadowgen::{sweep_pairs, ImageRect, SweepPrune, DEFAULT_SWAPS_PER_BOX};
use std::time::Instant;
use testkit::cli::one_of;
use testkit::{brute_pairs, bvh_pairs, median, BenchScene};

/// The default city's object count: N that selects it.
const DEFAULT_CITY_OBJECTS: usize = 17_468;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Motion {
    Camera,
    Light,
    Objects,
}

const MOTIONS: &[(&str, Motion)] = &[
    ("camera", Motion::Camera),
    ("light", Motion::Light),
    ("objects", Motion::Objects),
];

#[derive(clap::Parser)]
#[command(about = "Sweep-and-prune against sort, BVH and brute-force pairs (one JSON line)")]
struct Args {
    /// Number of boxes (17468: the default city's objects).
    n: usize,
    /// What moves from frame to frame.
    #[arg(long, value_parser = one_of(MOTIONS), default_value = "camera")]
    motion: Motion,
    /// Frames to run.
    #[arg(long, default_value_t = 100)]
    frames: u32,
    /// Frames (from the first) on which the BVH and brute force run too.
    #[arg(long, default_value_t = 3)]
    check_frames: u32,
    /// The largest step per axis and frame of `--motion objects`, in metres.
    #[arg(long, default_value_t = 0.25)]
    step: f32,
    /// Degrees per frame of `--motion light`.
    #[arg(long, default_value_t = 1.0)]
    light_speed: f64,
    /// The swap budget per box before a frame sorts from scratch.
    #[arg(long, default_value_t = DEFAULT_SWAPS_PER_BOX)]
    swaps_per_box: u32,
}

/// The boxes, the scene's bounds and the camera path of a bench scene.
struct Boxes {
    world: Vec<Aabb>,
    lo: DVec3,
    hi: DVec3,
    path: Vec<LookAt>,
}

fn city_boxes(frames: u32) -> Boxes {
    let city = BenchScene::default_city();
    let world: Vec<Aabb> = city
        .scene
        .objects()
        .iter()
        .map(|o| o.world_bounds)
        .collect();
    let (lo, hi) = bounds(&world);
    let path = city.path("street");
    let path = (0..frames).filter_map(|f| path.at(f)).collect();
    Boxes {
        world,
        lo,
        hi,
        path,
    }
}

/// N buildings on a square grid of 12-unit lots (sizes and heights from
/// `scene::splitmix64`), and a street walk along the grid's middle row.
fn generated_boxes(n: usize, frames: u32) -> Boxes {
    let side = (n as f64).sqrt().ceil() as usize;
    let mut seed = 0x5eed_u64;
    let mut unit = || (scene::splitmix64(&mut seed) >> 11) as f32 / (1u64 << 53) as f32;
    let world: Vec<Aabb> = (0..n)
        .map(|k| {
            let (x, z) = ((k % side) as f32 * 12.0, (k / side) as f32 * 12.0);
            let (w, d, h) = (3.0 + 6.0 * unit(), 3.0 + 6.0 * unit(), 5.0 + 55.0 * unit());
            Aabb {
                min: Vec3::new(x, 0.0, z),
                max: Vec3::new(x + w, h, z + d),
            }
        })
        .collect();
    let (lo, hi) = bounds(&world);
    let street_z = (side / 2) as f64 * 12.0 - 1.5;
    let path = (0..frames)
        .map(|f| {
            let x = lo.x + (hi.x - lo.x) * f64::from(f) / f64::from(frames.max(1));
            LookAt {
                eye: DVec3::new(x, 1.7, street_z),
                target: DVec3::new(x + 10.0, 1.7, street_z),
                up: DVec3::Y,
                fov_y_deg: 60.0,
                near: 0.1,
            }
        })
        .collect();
    Boxes {
        world,
        lo,
        hi,
        path,
    }
}

fn bounds(boxes: &[Aabb]) -> (DVec3, DVec3) {
    boxes.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), b| (lo.min(b.min.as_dvec3()), hi.max(b.max.as_dvec3())),
    )
}

/// A point light `height` above the scene's centre, offset by `angle` on a
/// circle of a quarter of the scene's width, looking at the centre with a
/// field of view that holds the whole scene.
fn light_clip_from_world(lo: DVec3, hi: DVec3, angle: f64) -> anyhow::Result<DMat4> {
    let centre = (lo + hi) * 0.5;
    let radius = (hi - lo).length() * 0.5;
    let r = 0.25 * (hi.x - lo.x);
    let eye = centre + DVec3::new(r * angle.cos(), 2.0 * radius, r * angle.sin());
    let fov = 2.0 * (1.2 * radius / (eye - centre).length()).atan().to_degrees();
    let cam = LookAt {
        eye,
        target: centre,
        up: DVec3::Z,
        fov_y_deg: fov.min(170.0),
        near: 0.1,
    }
    .camera(1.0)
    .context("the light's view")?;
    Ok(cam.clip_from_eye_relative() * DMat4::from_translation(-cam.position))
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn main() -> anyhow::Result<()> {
    let a: Args = clap::Parser::parse();
    if a.n == 0 || a.frames == 0 {
        bail!("N and --frames must be positive");
    }
    let mut boxes = if a.n == DEFAULT_CITY_OBJECTS {
        city_boxes(a.frames)
    } else {
        generated_boxes(a.n, a.frames)
    };
    let n = boxes.world.len();
    let step = a.step;
    let mut sap = SweepPrune::new().budget(a.swaps_per_box);
    let mut seed = 0xb0c5_u64;
    let (mut sap_ms, mut sort_ms, mut bvh_ms, mut brute_ms) = (vec![], vec![], vec![], vec![]);
    let (mut pairs, mut swaps, mut present) = (vec![], vec![], vec![]);
    let mut rebuilt = 0u32;
    let mut rects: Vec<Option<ImageRect>> = vec![None; n];
    let static_light = light_clip_from_world(boxes.lo, boxes.hi, 0.0)?;
    for f in 0..a.frames {
        let clip_from_world = match a.motion {
            Motion::Light => {
                let angle = (a.light_speed * f64::from(f)).to_radians();
                light_clip_from_world(boxes.lo, boxes.hi, angle)?
            }
            _ => static_light,
        };
        if a.motion == Motion::Objects && f > 0 {
            for b in &mut boxes.world {
                if scene::splitmix64(&mut seed).is_multiple_of(20) {
                    let r = scene::splitmix64(&mut seed);
                    let d = |s: u64| ((s & 0xffff) as f32 / 32_768.0 - 1.0) * step;
                    let v = Vec3::new(d(r), d(r >> 16), d(r >> 32));
                    (b.min, b.max) = (b.min + v, b.max + v);
                }
            }
        }
        let frustum = match a.motion {
            Motion::Camera => {
                let look = boxes.path.get(f as usize).or(boxes.path.last());
                let look = look.context("the scene has no street path")?;
                Some(
                    look.camera(4.0 / 3.0)
                        .context("the street camera")?
                        .frustum(),
                )
            }
            _ => None,
        };
        for (r, b) in rects.iter_mut().zip(&boxes.world) {
            let inside = frustum.as_ref().is_none_or(|fr| fr.may_intersect(b));
            *r = inside.then(|| ImageRect::of_box(&clip_from_world, b));
        }
        let t = Instant::now();
        let stats = sap.update(&rects)?;
        sap_ms.push(ms(t));
        let t = Instant::now();
        let sorted = sweep_pairs(&rects);
        sort_ms.push(ms(t));
        let mut incremental: Vec<(u32, u32)> = sap.pairs().collect();
        incremental.sort_unstable();
        if incremental != sorted {
            bail!(
                "frame {f}: sweep-and-prune found {} pairs, the sort {}",
                incremental.len(),
                sorted.len()
            );
        }
        if f < a.check_frames {
            let t = Instant::now();
            let bvh = bvh_pairs(&rects);
            bvh_ms.push(ms(t));
            let t = Instant::now();
            let brute = brute_pairs(&rects);
            brute_ms.push(ms(t));
            if bvh != sorted || brute != sorted {
                bail!(
                    "frame {f}: BVH {} / brute {} / sort {} pairs",
                    bvh.len(),
                    brute.len(),
                    sorted.len()
                );
            }
        }
        pairs.push(stats.pairs);
        swaps.push(stats.swaps);
        present.push(stats.boxes);
        rebuilt += u32::from(stats.rebuilt);
    }
    let med = |v: &[f64]| median(v).unwrap_or(f64::NAN);
    // The first frame inserts every box: report steady frames where there are any.
    let steady = |v: &[f64]| if v.len() > 1 { med(&v[1..]) } else { med(v) };
    let motion = MOTIONS
        .iter()
        .find(|(_, m)| *m == a.motion)
        .map(|(s, _)| *s);
    println!(
        "{}",
        json!({
            "n": n,
            "frames": a.frames,
            "motion": motion,
            "boxes_median": median(&present),
            "pairs_median": median(&pairs),
            "swaps_median": median(&swaps),
            "rebuilt_frames": rebuilt,
            "swaps_per_box": a.swaps_per_box,
            "step": a.step,
            "light_speed": a.light_speed,
            "sap_ms_median": steady(&sap_ms),
            "sap_ms_first": sap_ms.first(),
            "sort_ms_median": med(&sort_ms),
            "bvh_ms_median": med(&bvh_ms),
            "brute_ms_median": med(&brute_ms),
            "check_frames": bvh_ms.len(),
        })
    );
    Ok(())
}
