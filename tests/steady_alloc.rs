//! A steady frame allocates nothing: every `Pipeline::frame` call of the
//! last backward pass of a there-and-back path makes 0 heap allocations.
//!
//! Its own test binary without the test harness (`harness = false`): its
//! counting global allocator sees every allocation of the process while a
//! frame runs, so nothing else may run beside it.
//!
//! The scene is the procedural city (4 × 4 blocks) down its `street` path,
//! with a point light low over the street (it needs one perspective view or
//! several cube faces depending on the camera), a sun and a spot light, and a
//! box that circles on the street (moved every frame, as a host moves an
//! object). The culled pipeline (CHC++, hierarchical stencil) runs on its
//! own two-thread pool, called from one of the pool's threads as a host's job
//! system calls it (called from any other thread, rayon's injector allocates
//! a queue block about every 63 frames).
//!
//! The path runs forward then back twice. The first round visits every state
//! of the path in both directions (the frames' lists grow to what they hold,
//! with headroom); the second round's backward pass is counted. Printed: the
//! allocations and bytes of every round's worst frame.
//!
//! Then churn: a host streaming meshes, objects and lights in and out of a
//! level keeps a bounded heap. Each of 400,000 cycles removes the oldest of
//! a few streamed meshes (with its object) and light and adds new ones, with
//! a frame every 1,000 cycles; the live heap (bytes allocated less bytes
//! freed) after the last frame is within 1 MiB of its value after the first
//! 1,000 cycles. Slots are reused (their generations guard stale ids, which
//! the test also checks), so nothing grows per cycle.

use glam::{DMat4, DVec3, Vec3};
use scene::procedural::city::{city, CityParams};
use scene::{Light, ObjectFlags, Scene};
use shadowcull::{CullingSpec, FrameInput, Pipeline, PipelineOptions, StencilBackend};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

struct Counting;

static ON: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);
static BYTES: AtomicU64 = AtomicU64::new(0);
/// Bytes allocated and freed over the whole run (counted always).
static ALLOCATED: AtomicU64 = AtomicU64::new(0);
static FREED: AtomicU64 = AtomicU64::new(0);

// SAFETY: forwards every call to the system allocator unchanged; the counters
// are atomics and allocate nothing.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATED.fetch_add(layout.size() as u64, Ordering::Relaxed);
        if ON.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
            BYTES.fetch_add(layout.size() as u64, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        FREED.fetch_add(layout.size() as u64, Ordering::Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATED.fetch_add(new_size as u64, Ordering::Relaxed);
        FREED.fetch_add(layout.size() as u64, Ordering::Relaxed);
        if ON.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
            BYTES.fetch_add(new_size as u64, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract, passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Frames along the path, each way.
const FRAMES: u32 = 24;
const W: u32 = 320;
const H: u32 = 240;

fn main() {
    if let Err(e) = steady().and_then(|()| churn()) {
        eprintln!("steady_alloc: FAILED: {e}");
        std::process::exit(1);
    }
    println!("steady_alloc: ok");
}

fn steady() -> Result<(), String> {
    let loaded = city(&CityParams {
        blocks_x: 4,
        blocks_z: 4,
        ..Default::default()
    })
    .map_err(|e| e.to_string())?;
    let path = loaded
        .paths
        .iter()
        .find(|(n, _)| n == "street")
        .ok_or("no street path")?
        .1
        .clone();
    let scene = Scene::new(loaded.graph).map_err(|e| e.to_string())?;
    let (b, start) = (scene.bounds(), path.at(0).ok_or("empty path")?);
    let options = PipelineOptions {
        culling: CullingSpec::Chcpp,
        stencil: StencilBackend::H,
        light_resolution: 512,
        ..Default::default()
    };
    let mut p = Pipeline::new(scene.clone(), options).map_err(|e| e.to_string())?;
    let ahead = start.eye + (start.target - start.eye).normalize() * 20.0;
    let point = p
        .add_light(Light::Point {
            position: DVec3::new(ahead.x, 6.0, ahead.z),
            range: None,
        })
        .map_err(|e| e.to_string())?;
    for l in [
        Light::Directional {
            direction: DVec3::new(0.4, -0.8, 0.3),
        },
        Light::Spot {
            position: DVec3::new(ahead.x + 3.0, f64::from(b.max.y) * 1.2, ahead.z - 2.0),
            direction: DVec3::new(-0.1, -1.0, 0.1),
            apex_angle: 100f64.to_radians(),
            range: None,
        },
    ] {
        p.add_light(l).map_err(|e| e.to_string())?;
    }
    let cube = scene::procedural::analytic::box_mesh("box", Vec3::splat(-0.5), Vec3::splat(0.5))
        .map_err(|e| e.to_string())?;
    let mesh = p.add_mesh(cube);
    let moving = p
        .add_object(mesh, DMat4::IDENTITY, ObjectFlags::ALL)
        .map_err(|e| e.to_string())?;
    let place = |f: u32| {
        let a = f64::from(f) * 0.3;
        let c = ahead + DVec3::new(2.0 * a.cos(), 1.0, 2.0 * a.sin());
        DMat4::from_translation(c) * DMat4::from_scale(DVec3::new(1.0, 2.0, 1.0))
    };
    let pool = Arc::new(
        rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .map_err(|e| e.to_string())?,
    );
    p.set_thread_pool(Some(pool.clone()))
        .map_err(|e| e.to_string())?;

    // Per pass (forward, back, forward, back): the worst frame's allocations
    // and bytes; and the point light's view counts seen.
    let mut worst = [[0u64; 2]; 4];
    let mut views = Vec::new();
    pool.install(|| -> Result<(), String> {
        for (pass, w) in worst.iter_mut().enumerate() {
            for k in 0..FRAMES {
                let f = if pass % 2 == 0 { k } else { FRAMES - 1 - k };
                p.set_transform(moving, place(f))
                    .map_err(|e| e.to_string())?;
                let pose = path.at(f).ok_or("path frame")?;
                let camera = pose
                    .camera(f64::from(W) / f64::from(H))
                    .map_err(|e| e.to_string())?;
                let input = FrameInput::new(W, H, camera);
                ALLOCATIONS.store(0, Ordering::SeqCst);
                BYTES.store(0, Ordering::SeqCst);
                ON.store(true, Ordering::SeqCst);
                let r = p
                    .frame(&input)
                    .map(|out| out.light(point).map_or(0, |l| l.views().len()));
                ON.store(false, Ordering::SeqCst);
                let n = r.map_err(|e| e.to_string())?;
                views.push(n);
                let (a, bytes) = (
                    ALLOCATIONS.load(Ordering::SeqCst),
                    BYTES.load(Ordering::SeqCst),
                );
                w[0] = w[0].max(a);
                w[1] = w[1].max(bytes);
            }
        }
        Ok(())
    })?;
    for (name, [a, bytes]) in ["forward", "back", "forward again", "back again"]
        .iter()
        .zip(worst)
    {
        println!("steady_alloc: {name}: worst frame {a} allocations, {bytes} bytes");
    }
    views.sort_unstable();
    views.dedup();
    println!("steady_alloc: point light view counts {views:?}");
    if views.len() < 2 {
        return Err(format!(
            "the point light's view count never changed ({views:?}): the path misses the case"
        ));
    }
    let [a, bytes] = worst[3];
    if a != 0 {
        return Err(format!(
            "a steady frame made {a} allocations ({bytes} bytes); want 0"
        ));
    }
    Ok(())
}

/// The live heap: bytes allocated less bytes freed.
fn live_bytes() -> i64 {
    ALLOCATED.load(Ordering::SeqCst) as i64 - FREED.load(Ordering::SeqCst) as i64
}

/// Churn cycles, a frame every `CHURN_FRAME_EVERY` of them.
const CHURN_CYCLES: u32 = 400_000;
const CHURN_FRAME_EVERY: u32 = 1_000;
/// Streamed meshes (each with one object) and lights alive at a time.
const STREAMED: usize = 4;

fn churn() -> Result<(), String> {
    let e = |e: shadowcull::Error| e.to_string();
    let loaded = city(&CityParams {
        blocks_x: 2,
        blocks_z: 2,
        ..Default::default()
    })
    .map_err(|e| e.to_string())?;
    let scene = Scene::new(loaded.graph).map_err(|e| e.to_string())?;
    let b = scene.bounds();
    let centre = ((b.min + b.max) * 0.5).as_dvec3();
    let options = PipelineOptions {
        threads: 1,
        light_resolution: 128,
        ..Default::default()
    };
    let mut p = Pipeline::new(scene, options).map_err(e)?;
    p.add_light(Light::Directional {
        direction: DVec3::new(0.4, -0.8, 0.3),
    })
    .map_err(e)?;
    let eye = centre + DVec3::new(0.0, 30.0, 60.0);
    let camera = scene::Camera::look_at(eye, centre, DVec3::Y, 60f64.to_radians(), 4.0 / 3.0, 0.5)
        .map_err(|e| e.to_string())?;
    let input = FrameInput::new(64, 48, camera);
    let mut streamed = std::collections::VecDeque::new();
    let mut lights = std::collections::VecDeque::new();
    let mut stale = None;
    let mut after_first = 0;
    for i in 0..CHURN_CYCLES {
        let a = f64::from(i) * 0.01;
        let at = centre + DVec3::new(10.0 * a.cos(), 2.0, 10.0 * a.sin());
        let size = 0.5 + 0.25 * (i % 3) as f32;
        let cube = scene::procedural::analytic::box_mesh("streamed", Vec3::ZERO, Vec3::splat(size))
            .map_err(|e| e.to_string())?;
        let mesh = p.add_mesh(cube);
        let object = p
            .add_object(mesh, DMat4::from_translation(at), ObjectFlags::ALL)
            .map_err(e)?;
        streamed.push_back((mesh, object));
        let light = p
            .add_light(Light::Point {
                position: at + DVec3::new(0.0, 5.0, 0.0),
                range: None,
            })
            .map_err(e)?;
        lights.push_back(light);
        if streamed.len() > STREAMED {
            let (mesh, object) = streamed.pop_front().ok_or("empty ring")?;
            p.remove_object(object).map_err(e)?;
            p.remove_mesh(mesh).map_err(e)?;
            let light = lights.pop_front().ok_or("empty ring")?;
            p.remove_light(light).map_err(e)?;
            if stale.is_none() {
                stale = Some((mesh, object, light));
            }
        }
        if (i + 1) % CHURN_FRAME_EVERY == 0 {
            p.frame(&input).map_err(e)?;
            if i + 1 == CHURN_FRAME_EVERY {
                after_first = live_bytes();
            }
            if (i + 1) % (CHURN_CYCLES / 8) == 0 {
                println!(
                    "steady_alloc: churn: after {} cycles: live heap grown by {} bytes",
                    i + 1,
                    live_bytes() - after_first
                );
            }
        }
    }
    // The first removed ids stay dead although their slots were reused
    // hundreds of thousands of times.
    let (mesh, object, light) = stale.ok_or("nothing was removed")?;
    if p.set_transform(object, DMat4::IDENTITY).is_ok()
        || p.light(light).is_ok()
        || p.remove_mesh(mesh).is_ok()
    {
        return Err("a stale id named a live mesh, object or light".into());
    }
    let grown = live_bytes() - after_first;
    println!(
        "steady_alloc: churn: {CHURN_CYCLES} cycles, live heap {} bytes after the first \
         {CHURN_FRAME_EVERY}, grown by {grown} bytes ({:.1} bytes a cycle)",
        after_first,
        grown as f64 / f64::from(CHURN_CYCLES - CHURN_FRAME_EVERY)
    );
    if grown > 1 << 20 {
        return Err(format!(
            "churn grew the live heap by {grown} bytes (more than 1 MiB) over {CHURN_CYCLES} cycles"
        ));
    }
    Ok(())
}
