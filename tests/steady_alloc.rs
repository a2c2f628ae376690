//! A steady frame allocates nothing: in each case below, a motion of
//! period P = 20 frames runs twice, then five more periods are counted
//! (100 frames), and the counted `Pipeline::frame` calls and edit calls
//! (`set_light`, `set_transform`) make 0 heap allocations.
//!
//! Its own test binary without the test harness (`harness = false`): its
//! counting global allocator sees every allocation of the process while a
//! frame runs, so nothing else may run beside it.
//!
//! The scene is the procedural city (4 × 4 blocks). The camera swings along
//! the first frames of its `street` path and back; a point light low over
//! the street (it needs one perspective view or several cube faces
//! depending on the camera), a sun and a spot light shine. The pipeline
//! (CHC++, hierarchical stencil, unless the case says otherwise) runs on its
//! own two-thread pool (`threads: 2`), every frame called through
//! `Pipeline::install`, as a host's job system would call it. The cases:
//! static lights; a moving point light, sun and spot (`set_light` every
//! frame); a moving object (`set_transform`); `culling: none`;
//! `clamping: continuous`; `stencil: none`. Printed per case: the counted
//! allocations and bytes and the worst warm-up frame. Set
//! `STEADY_ALLOC_TRACE=1` to print where a counted allocation came from.
//!
//! Called from outside the pool (`frame` from the main thread), rayon's
//! injector allocates a queue block now and then: the last case counts
//! those apart and prints them without failing.
//!
//! `Pipeline::reserve`: after `reserve(objects + 16, lights + 2)` and one
//! frame, adding 16 objects and two lights allocates nothing in the calls,
//! and the frame after them refits the object hierarchy instead of
//! rebuilding it (the scene's BVH version stays).
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
use shadowcull::{
    ClampingSpec, CullingSpec, FrameInput, Pipeline, PipelineOptions, StencilBackend,
};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

struct Counting;

static ON: AtomicBool = AtomicBool::new(false);
/// Print a backtrace of each counted allocation (`STEADY_ALLOC_TRACE`).
static TRACE: AtomicBool = AtomicBool::new(false);
static TRACED: AtomicU64 = AtomicU64::new(0);
/// The counted (steady) frames run: only their allocations are traced.
static STEADY: AtomicBool = AtomicBool::new(false);

thread_local! {
    /// Inside the tracer: its own allocations are not traced.
    static TRACING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Prints where a counted allocation of `size` bytes came from.
fn trace(size: usize) {
    if !TRACE.load(Ordering::Relaxed)
        || !STEADY.load(Ordering::Relaxed)
        || TRACING.with(|t| t.replace(true))
    {
        return;
    }
    // The first few per case are enough to find the site.
    if TRACED.fetch_add(1, Ordering::Relaxed) >= 400 {
        TRACING.with(|t| t.set(false));
        return;
    }
    let was = ON.swap(false, Ordering::SeqCst);
    eprintln!(
        "steady_alloc: allocation of {size} bytes at\n{}",
        std::backtrace::Backtrace::force_capture()
    );
    ON.store(was, Ordering::SeqCst);
    TRACING.with(|t| t.set(false));
}
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
            trace(layout.size());
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
            trace(new_size);
        }
        // SAFETY: the caller's contract, passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The motion's period in frames, the periods run before counting, and the
/// periods counted.
const PERIOD: u32 = 20;
const WARM_PERIODS: u32 = 2;
const COUNTED_PERIODS: u32 = 5;
const W: u32 = 320;
const H: u32 = 240;

fn main() {
    if let Err(e) = steady().and_then(|()| churn()).and_then(|()| reserved()) {
        eprintln!("steady_alloc: FAILED: {e}");
        std::process::exit(1);
    }
    println!("steady_alloc: ok");
}

/// What moves every frame, besides the camera.
#[derive(Clone, Copy, PartialEq)]
enum Moving {
    Nothing,
    PointLight,
    Sun,
    Spot,
    Object,
}

struct Case {
    name: &'static str,
    moving: Moving,
    options: PipelineOptions,
    /// Frames called through `Pipeline::install` (else from this thread).
    installed: bool,
    /// Asserted to make no allocation (else reported only).
    asserted: bool,
}

/// Counts the allocations of `f` (and where they came from, with tracing on).
fn counted<R>(f: impl FnOnce() -> R) -> (R, [u64; 2]) {
    ALLOCATIONS.store(0, Ordering::SeqCst);
    BYTES.store(0, Ordering::SeqCst);
    ON.store(true, Ordering::SeqCst);
    let r = f();
    ON.store(false, Ordering::SeqCst);
    let n = [
        ALLOCATIONS.load(Ordering::SeqCst),
        BYTES.load(Ordering::SeqCst),
    ];
    (r, n)
}

fn steady() -> Result<(), String> {
    TRACE.store(
        std::env::var_os("STEADY_ALLOC_TRACE").is_some(),
        Ordering::SeqCst,
    );
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
    let scene = Arc::new(Scene::new(loaded.graph).map_err(|e| e.to_string())?);
    let base = PipelineOptions {
        culling: CullingSpec::Chcpp,
        stencil: StencilBackend::H,
        light_resolution: 512,
        threads: 2,
        ..Default::default()
    };
    let case = |name, moving, options| Case {
        name,
        moving,
        options,
        installed: true,
        asserted: true,
    };
    let cases = [
        case("static lights", Moving::Nothing, base),
        case("moving point light", Moving::PointLight, base),
        case("moving sun", Moving::Sun, base),
        case("moving spot", Moving::Spot, base),
        case("moving object", Moving::Object, base),
        case(
            "culling: none",
            Moving::Object,
            PipelineOptions {
                culling: CullingSpec::None,
                ..base
            },
        ),
        case(
            "clamping: continuous",
            Moving::Object,
            PipelineOptions {
                clamping: ClampingSpec::Continuous,
                ..base
            },
        ),
        case(
            "stencil: none",
            Moving::PointLight,
            PipelineOptions {
                stencil: StencilBackend::None,
                ..base
            },
        ),
        Case {
            name: "called from outside the pool",
            moving: Moving::Object,
            options: base,
            installed: false,
            asserted: false,
        },
    ];
    let mut failed = Vec::new();
    for c in &cases {
        TRACED.store(0, Ordering::SeqCst);
        let [warm, [a, bytes]] = run_case(&scene, &path, c)?;
        println!(
            "steady_alloc: {}: {} counted frames, {a} allocations ({bytes} bytes); worst warm-up \
             frame {} allocations",
            c.name,
            PERIOD * COUNTED_PERIODS,
            warm[0]
        );
        if a != 0 && c.asserted {
            failed.push(format!("{}: {a} allocations ({bytes} bytes)", c.name));
        }
    }
    if !failed.is_empty() {
        return Err(format!("steady frames allocated: {}", failed.join("; ")));
    }
    Ok(())
}

/// Runs one case; returns the worst warm-up frame's and the counted frames'
/// allocations and bytes.
fn run_case(
    scene: &Arc<Scene>,
    path: &scene::CameraPath,
    c: &Case,
) -> Result<[[u64; 2]; 2], String> {
    let e = |e: shadowcull::Error| e.to_string();
    let b = scene.bounds();
    let start = path.at(0).ok_or("empty path")?;
    let ahead = start.eye + (start.target - start.eye).normalize() * 20.0;
    let mut p = Pipeline::new(scene.clone(), c.options).map_err(e)?;
    let point = |a: f64| Light::Point {
        position: DVec3::new(ahead.x + 4.0 * a.cos(), 6.0, ahead.z + 4.0 * a.sin()),
        range: None,
    };
    let sun = |a: f64| Light::Directional {
        direction: DVec3::new(0.4 * a.cos(), -0.8, 0.4 * a.sin()),
    };
    let spot = |a: f64| Light::Spot {
        position: DVec3::new(ahead.x + 3.0, f64::from(b.max.y) * 1.2, ahead.z - 2.0),
        direction: DVec3::new(0.3 * a.cos(), -1.0, 0.3 * a.sin()),
        apex_angle: 100f64.to_radians(),
        range: None,
    };
    let ids = [
        p.add_light(point(0.0)).map_err(e)?,
        p.add_light(sun(0.0)).map_err(e)?,
        p.add_light(spot(0.0)).map_err(e)?,
    ];
    let cube = scene::procedural::analytic::box_mesh("box", Vec3::splat(-0.5), Vec3::splat(0.5))
        .map_err(|e| e.to_string())?;
    let mesh = p.add_mesh(cube);
    let moving = p
        .add_object(mesh, DMat4::IDENTITY, ObjectFlags::ALL)
        .map_err(e)?;
    let mut warm = [0u64; 2];
    let mut total = [0u64; 2];
    for f in 0..PERIOD * (WARM_PERIODS + COUNTED_PERIODS) {
        let phase = f % PERIOD;
        let a = std::f64::consts::TAU * f64::from(phase) / f64::from(PERIOD);
        // The camera swings along the path's first frames and back.
        let k = phase.min(PERIOD - phase);
        let pose = path.at(k).ok_or("path frame")?;
        let camera = pose
            .camera(f64::from(W) / f64::from(H))
            .map_err(|e| e.to_string())?;
        let input = FrameInput::new(W, H, camera);
        let place = DMat4::from_translation(ahead + DVec3::new(2.0 * a.cos(), 1.0, 2.0 * a.sin()))
            * DMat4::from_scale(DVec3::new(1.0, 2.0, 1.0));
        let step = |p: &mut Pipeline| -> Result<(), String> {
            match c.moving {
                Moving::Nothing => Ok(()),
                Moving::PointLight => p.set_light(ids[0], point(a)),
                Moving::Sun => p.set_light(ids[1], sun(a)),
                Moving::Spot => p.set_light(ids[2], spot(a)),
                Moving::Object => p.set_transform(moving, place),
            }
            .map_err(e)?;
            p.frame(&input).map(|_| ()).map_err(e)
        };
        STEADY.store(f >= PERIOD * WARM_PERIODS, Ordering::SeqCst);
        let (r, n) = match c.installed {
            true => p.install(|p| counted(|| step(p))),
            false => counted(|| step(&mut p)),
        };
        r?;
        if f < PERIOD * WARM_PERIODS {
            warm = [warm[0].max(n[0]), warm[1].max(n[1])];
        } else {
            total = [total[0] + n[0], total[1] + n[1]];
        }
    }
    Ok([warm, total])
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

/// A small city (2 × 2 blocks) on one thread with a sun, its centre, and a
/// 64 × 48 view of it from above.
fn small_city() -> Result<(Pipeline, DVec3, FrameInput), String> {
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
    let mut p = Pipeline::new(scene, options).map_err(|e| e.to_string())?;
    p.add_light(Light::Directional {
        direction: DVec3::new(0.4, -0.8, 0.3),
    })
    .map_err(|e| e.to_string())?;
    let eye = centre + DVec3::new(0.0, 30.0, 60.0);
    let camera = scene::Camera::look_at(eye, centre, DVec3::Y, 60f64.to_radians(), 4.0 / 3.0, 0.5)
        .map_err(|e| e.to_string())?;
    Ok((p, centre, FrameInput::new(64, 48, camera)))
}

fn churn() -> Result<(), String> {
    let e = |e: shadowcull::Error| e.to_string();
    let (mut p, centre, input) = small_city()?;
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

/// Objects and lights added into room made by `Pipeline::reserve`.
fn reserved() -> Result<(), String> {
    const ADDED: usize = 16;
    let e = |e: shadowcull::Error| e.to_string();
    let (mut p, centre, input) = small_city()?;
    let objects = p.scene().counts().objects;
    p.reserve(objects + ADDED, 3).map_err(e)?;
    let cube = scene::procedural::analytic::box_mesh("added", Vec3::ZERO, Vec3::splat(0.7))
        .map_err(|e| e.to_string())?;
    let mesh = p.add_mesh(cube);
    p.frame(&input).map_err(e)?;
    let version = p.scene().bvh_version();
    let (r, [allocations, bytes]) = counted(|| -> shadowcull::Result<()> {
        for k in 0..ADDED {
            let at = centre + DVec3::new(2.0 * k as f64 - 16.0, 0.0, 4.0);
            p.add_object(mesh, DMat4::from_translation(at), ObjectFlags::ALL)?;
        }
        for k in 0..2 {
            p.add_light(Light::Point {
                position: centre + DVec3::new(5.0 * f64::from(k), 8.0, 0.0),
                range: None,
            })?;
        }
        Ok(())
    });
    r.map_err(e)?;
    p.frame(&input).map_err(e)?;
    let out = p.last_output().ok_or("a frame ran")?;
    println!(
        "steady_alloc: reserve: {ADDED} objects and 2 lights added: {allocations} allocations \
         ({bytes} bytes); {} objects, {} lights framed",
        out.stats().objects,
        out.light_count()
    );
    if allocations > 0 {
        return Err(format!(
            "adding into reserved room allocated {allocations} times ({bytes} bytes)"
        ));
    }
    if out.stats().objects != (objects + ADDED) as u64 || out.light_count() != 3 {
        return Err("the added objects or lights are missing".into());
    }
    if p.scene().bvh_version() != version {
        return Err("objects added into reserved slots rebuilt the hierarchy".into());
    }
    Ok(())
}
