//! An engine-style loop around [`shadowcull::Pipeline`]: the host owns its
//! vertex and index arrays and its object matrices (about 500 objects of
//! three meshes on a ground plane), uploads them once, and every frame of a
//! camera path hands the pipeline the camera and two lights (a point light
//! and a sun), then reads the potentially shadowed receivers (PSR), per light
//! the potential shadow casters (PSC) and the shadow volumes it would draw.
//!
//! The library glue is the one marked block (begin and end comments). The
//! rest is the host's own world and the checks: every K-th frame the culled
//! pipeline's mask against the ray-cast reference, and every frame against
//! an unculled pipeline on the same frames (conservative culling must not
//! change a pixel).
//!
//! ```sh
//! cargo run --release --example host_loop -- [--frames N] [--reference-every K] [--size WxH] [--there-and-back on|off] [--write-masks DIR | --gpu-host] [--moving-light]
//! ```
//! prints one JSON line last: `frames`, `objects`, `psr_median`,
//! `psc_median` (summed over lights), `frame_ms_median` (wall time of
//! `Pipeline::frame`, all lights), `mismatch_pixels`,
//! `mismatch_off_boundary`, `culled_vs_unculled_differing_pixels`,
//! `allocations_per_frame_max` (the worst frame of the way back, where only
//! one object moves), `steady_frames` and `steady_allocations` (with
//! `--moving-light`: the steps after the first 20 and their allocations,
//! frames and `set_light` calls), …

use glam::{DMat4, DQuat, DVec3, DVec4};
use shadowcull::mask::compare;
use shadowcull::raster::VolumeMethod;
use shadowcull::scene::{Camera, Light};
use shadowcull::{CullingSpec, StencilBackend};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use testkit::cli::parse_size;
use testkit::median;

/// The host's thread pool, shared with its pipelines.
type Pool = Arc<rayon::ThreadPool>;

/// A mesh as a host keeps it: flat positions and a triangle index list.
struct HostMesh {
    positions: Vec<[f32; 3]>,
    indices: Vec<u32>,
}

/// An object as a host keeps it: which mesh, its world matrix, and what it
/// takes part in.
struct HostObject {
    mesh: usize,
    world: DMat4,
    flags: ObjectFlags,
}

/// Everything the host owns: meshes, objects and lights.
struct HostWorld {
    meshes: Vec<HostMesh>,
    objects: Vec<HostObject>,
    lights: Vec<Light>,
}

/// A pipeline with the ids of the host's meshes and objects (in host order;
/// objects the host adds later are appended).
struct Uploaded {
    pipeline: Pipeline,
    meshes: Vec<MeshId>,
    objects: Vec<ObjectId>,
}

impl Uploaded {
    fn new(pipeline: Pipeline) -> Self {
        Uploaded {
            pipeline,
            meshes: Vec::new(),
            objects: Vec::new(),
        }
    }
}

/// A scene edit the host makes between frames (indices into its own lists).
enum HostEdit {
    /// Object `i` moves to a new world matrix.
    Move(usize, DMat4),
    /// Object `i` is removed.
    Remove(usize),
    /// A new object of mesh `m` appears.
    Add(usize, DMat4, ObjectFlags),
}

/// What the host took from one frame.
#[derive(Default)]
struct Drawn {
    psr: usize,
    psc: usize,
    volume_triangles: usize,
    non_zpass_ranges: usize,
    frame_ms: f64,
}

impl Drawn {
    fn new(psr: usize, frame_ms: f64) -> Self {
        Drawn {
            psr,
            frame_ms,
            ..Default::default()
        }
    }
}

// glue:begin
use shadowcull::scene::{ClipDepth, Indices, Mesh, MeshId, ObjectFlags, ObjectId};
use shadowcull::scene::{Scene, SceneGraph, StridedPositions as Strided};
use shadowcull::{FrameInput, Pipeline, PipelineOptions};

/// A pipeline on the host's thread pool holding its meshes, objects and lights, with their ids.
/// A GPU host's options: `PipelineOptions::gpu_host()` (here, to check the masks: a CPU stencil).
fn upload(w: &HostWorld, options: PipelineOptions, pool: &Pool) -> shadowcull::Result<Uploaded> {
    let mut u = Uploaded::new(Pipeline::new(Scene::new(SceneGraph::new())?, options)?);
    u.pipeline.set_thread_pool(Some(pool.clone()))?;
    // Room for the proxy added later: it takes a reserved slot, no hierarchy rebuild.
    u.pipeline.reserve(w.objects.len() + 1, w.lights.len())?;
    for m in &w.meshes {
        // The host's buffers as they are: f32 × 3 positions 12 bytes apart, u32 indices.
        let at = Strided::f32(bytemuck::cast_slice(&m.positions), 0, 12, m.positions.len());
        let mesh = Mesh::from_strided("mesh", at, Indices::U32(&m.indices))?;
        u.meshes.push(u.pipeline.add_mesh(mesh));
    }
    for o in &w.objects {
        let id = u.pipeline.add_object(u.meshes[o.mesh], o.world, o.flags)?;
        u.objects.push(id);
    }
    for l in &w.lights {
        u.pipeline.add_light(*l)?;
    }
    Ok(u)
}

/// The host's scene edits of one frame, by the ids the upload returned.
fn edit(u: &mut Uploaded, e: &HostEdit) -> shadowcull::Result<()> {
    match *e {
        HostEdit::Move(i, m) => u.pipeline.set_transform(u.objects[i], m)?,
        HostEdit::Remove(i) => u.pipeline.remove_object(u.objects[i])?,
        HostEdit::Add(mesh, m, f) => u.objects.push(u.pipeline.add_object(u.meshes[mesh], m, f)?),
    }
    Ok(())
}

/// A frame from the host's view and projection; what a renderer reads to draw shadows.
fn host_frame(
    p: &mut Pipeline,
    size: (u32, u32),
    [view, proj]: [DMat4; 2],
) -> shadowcull::Result<Drawn> {
    let camera = Camera::from_view_projection_near(view, proj, ClipDepth::NegativeOneToOne, NEAR)?;
    let out = p.frame(&FrameInput::new(size.0, size.1, camera))?;
    let mut d = Drawn::new(out.psr().len(), out.stats().frame_ms);
    for light in out.lights() {
        d.psc += light.psc().len();
        let v = light.volumes();
        for r in &v.ranges {
            // Bind r.world_from_local, set r.method's stencil ops, scissor and depth bounds:
            let _triangles = &v.indices[r.indices()];
            d.volume_triangles += r.triangle_count();
            d.non_zpass_ranges += usize::from(r.method != VolumeMethod::ZPass);
        }
    }
    Ok(d)
}
// glue:end

/// Unit cube, 8 corners and 12 outward triangles.
fn cube() -> HostMesh {
    let positions = (0..8)
        .map(|i| {
            [
                (i & 1) as f32 - 0.5,
                ((i >> 1) & 1) as f32,
                ((i >> 2) & 1) as f32 - 0.5,
            ]
        })
        .collect();
    let faces = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    HostMesh {
        positions,
        indices: quads(&faces),
    }
}

/// A square frustum: the cube with its top face narrowed to 60 %.
fn tower() -> HostMesh {
    let mut m = cube();
    for p in m.positions.iter_mut().filter(|p| p[1] == 1.0) {
        p[0] *= 0.6;
        p[2] *= 0.6;
    }
    m
}

/// The ground: one large quad facing up.
fn ground(half: f32) -> HostMesh {
    HostMesh {
        positions: vec![
            [-half, 0.0, -half],
            [-half, 0.0, half],
            [half, 0.0, half],
            [half, 0.0, -half],
        ],
        indices: vec![0, 1, 2, 0, 2, 3],
    }
}

/// Two triangles per quad `[a, b, c, d]` (counter-clockwise seen from outside).
fn quads(faces: &[[u32; 4]]) -> Vec<u32> {
    faces
        .iter()
        .flat_map(|&[a, b, c, d]| [a, b, c, a, c, d])
        .collect()
}

/// A 22 × 23 grid of cubes and towers with pseudo-random sizes and turns
/// (506 objects) plus the ground, streets along x between the rows; a point
/// light and a sun.
fn world() -> HostWorld {
    let meshes = vec![ground(120.0), cube(), tower()];
    let mut objects = vec![HostObject {
        mesh: 0,
        world: DMat4::IDENTITY,
        flags: ObjectFlags::ALL,
    }];
    let mut seed = 0x2545_f491_u32;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        f64::from(seed) / f64::from(u32::MAX)
    };
    for i in 0..22 {
        for j in 0..23 {
            let (x, z) = ((i as f64 - 10.5) * 9.0, (j as f64 - 11.0) * 8.0);
            let (w, d, h) = (2.0 + 3.0 * rnd(), 2.0 + 3.0 * rnd(), 2.0 + 14.0 * rnd());
            objects.push(HostObject {
                mesh: 1 + usize::from(rnd() < 0.3),
                world: DMat4::from_scale_rotation_translation(
                    DVec3::new(w, h, d),
                    DQuat::from_rotation_y(rnd() * 0.8),
                    DVec3::new(x, 0.0, z),
                ),
                // Every 25th object shows no shadows on itself.
                flags: ObjectFlags {
                    receives: objects.len() % 25 != 0,
                    ..ObjectFlags::ALL
                },
            });
        }
    }
    let lights = vec![
        Light::Point {
            position: DVec3::new(15.0, 70.0, -10.0),
            range: None,
        },
        Light::Directional {
            direction: DVec3::new(-0.45, -1.0, -0.3),
        },
    ];
    HostWorld {
        meshes,
        objects,
        lights,
    }
}

/// Frame `f`'s edits: object 1 circles its lot (at angle `a`); early on the
/// object beside the street is removed and an invisible tower (a shadow
/// proxy) appears.
fn edits(f: u32, a: f64, world: &HostWorld) -> Vec<HostEdit> {
    let base = world.objects[1].world;
    let mut e = vec![HostEdit::Move(
        1,
        DMat4::from_translation(DVec3::new(3.0 * a.cos(), 0.0, 3.0 * a.sin())) * base,
    )];
    // Early, so that the path back (which replays moves only) sees the
    // scene the path forward saw.
    if f == 1 {
        e.push(HostEdit::Remove(12));
    }
    if f == 2 {
        let m = DMat4::from_scale_rotation_translation(
            DVec3::new(3.0, 12.0, 3.0),
            DQuat::IDENTITY,
            DVec3::new(-10.0, 0.0, 8.5),
        );
        // An invisible shadow proxy: it casts, nobody sees it.
        let proxy = ObjectFlags {
            visible: false,
            ..ObjectFlags::ALL
        };
        e.push(HostEdit::Add(2, m, proxy));
    }
    e
}

/// The host's near plane distance.
const NEAR: f64 = 0.1;

/// The host's view and projection of frame `f` of `n`: down a street,
/// rising at the end; OpenGL-style, with a far plane and a TAA jitter.
fn host_matrices(f: u32, n: u32, (w, h): (u32, u32)) -> (DMat4, DMat4) {
    let t = f64::from(f) / f64::from(n.max(2) - 1);
    let eye = DVec3::new(-95.0 + 170.0 * t, 2.0 + 25.0 * t * t, 4.0);
    let dir = DVec3::new(1.0, -0.15 - 0.4 * t * t, 0.25 * (6.0 * t).sin()).normalize();
    let side = dir.cross(DVec3::Y).normalize();
    let up = side.cross(dir);
    let view = DMat4::from_cols(
        DVec4::new(side.x, up.x, -dir.x, 0.0),
        DVec4::new(side.y, up.y, -dir.y, 0.0),
        DVec4::new(side.z, up.z, -dir.z, 0.0),
        DVec4::new(-side.dot(eye), -up.dot(eye), dir.dot(eye), 1.0),
    );
    let (near, far, fy) = (NEAR, 2000.0, 1.0 / 30f64.to_radians().tan());
    // Halton (2, 3) jitter in pixels, as a TAA renderer shifts its projection.
    let halton = |mut i: u32, b: u32| {
        let (mut r, mut f) = (0.0, 1.0);
        while i > 0 {
            f /= f64::from(b);
            r += f * f64::from(i % b);
            i /= b;
        }
        r - 0.5
    };
    let (jx, jy) = (
        2.0 * halton(f + 1, 2) / f64::from(w),
        2.0 * halton(f + 1, 3) / f64::from(h),
    );
    let projection = DMat4::from_cols(
        DVec4::new(fy * f64::from(h) / f64::from(w), 0.0, 0.0, 0.0),
        DVec4::new(0.0, fy, 0.0, 0.0),
        DVec4::new(jx, jy, -(far + near) / (far - near), -1.0),
        DVec4::new(0.0, 0.0, -2.0 * far * near / (far - near), 0.0),
    );
    (view, projection)
}

/// Counts heap allocations while [`COUNTING`] is set: the allocations made
/// inside `Pipeline::frame` calls (the pool's threads included: they only
/// work inside a call).
struct CountingAllocator;

static COUNTING: AtomicBool = AtomicBool::new(false);
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);
static BYTES: AtomicU64 = AtomicU64::new(0);
static FREED: AtomicU64 = AtomicU64::new(0);

// SAFETY: forwards every call to the system allocator unchanged; the counters
// are atomics and allocate nothing.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
            BYTES.fetch_add(layout.size() as u64, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if COUNTING.load(Ordering::Relaxed) {
            FREED.fetch_add(layout.size() as u64, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.load(Ordering::Relaxed) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
            BYTES.fetch_add(new_size as u64, Ordering::Relaxed);
            FREED.fetch_add(layout.size() as u64, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract, passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// Runs `f` with the allocation counters on: `(allocations, bytes allocated,
/// bytes freed)` during the call.
fn counted<T>(f: impl FnOnce() -> T) -> (T, [u64; 3]) {
    for c in [&ALLOCATIONS, &BYTES, &FREED] {
        c.store(0, Ordering::SeqCst);
    }
    COUNTING.store(true, Ordering::SeqCst);
    let r = f();
    COUNTING.store(false, Ordering::SeqCst);
    let counts = [&ALLOCATIONS, &BYTES, &FREED].map(|c| c.load(Ordering::SeqCst));
    (r, counts)
}

/// `on` or `off`.
fn parse_on_off(s: &str) -> Result<bool, String> {
    match s {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(format!("{s:?} is neither on nor off")),
    }
}

/// The command line.
#[derive(clap::Parser)]
#[command(
    about = "An engine-style loop around shadowcull::Pipeline, checked against the reference"
)]
struct Cli {
    /// Frames of the camera path.
    #[arg(long, default_value_t = 60)]
    frames: u32,
    /// Compare with the ray-cast reference every K-th frame.
    #[arg(long = "reference-every", value_name = "K", default_value_t = 10)]
    every: u32,
    /// Viewport, WxH.
    #[arg(long, value_parser = parse_size, default_value = "320x240")]
    size: (u32, u32),
    /// Run the path forward and back again (on|off).
    #[arg(long = "there-and-back", value_parser = parse_on_off, default_value = "on", action = clap::ArgAction::Set)]
    there_and_back: bool,
    /// Write each frame's masks and volumes here (as examples/c/host.c does).
    #[arg(long = "write-masks", value_name = "DIR", conflicts_with = "gpu_host")]
    write_masks: Option<std::path::PathBuf>,
    /// Run `PipelineOptions::gpu_host()` (no CPU stencil) and check its
    /// volumes on the reference frames as a GPU would draw them
    /// (`Pipeline::check_gpu`: the same JSON keys, without the unculled
    /// pipeline's frames).
    #[arg(long = "gpu-host")]
    gpu_host: bool,
    /// Orbit the point light (period 20 frames, `set_light` every frame),
    /// with the camera swinging along the path's first frames and object 1
    /// circling in the same period, and count the allocations of every
    /// step after the first 20 (frame and edit calls): `steady_frames`,
    /// `steady_allocations`.
    #[arg(long = "moving-light")]
    moving_light: bool,
}

/// The moving light's period in frames, and the steps before counting.
const LIGHT_PERIOD: u32 = 20;

/// The point light at step `k` of its orbit (period [`LIGHT_PERIOD`]).
fn orbiting(world: &HostWorld, k: u32) -> Light {
    let a = std::f64::consts::TAU * f64::from(k % LIGHT_PERIOD) / f64::from(LIGHT_PERIOD);
    match world.lights[0] {
        Light::Point { position, range } => Light::Point {
            position: position + DVec3::new(25.0 * a.cos(), 0.0, 25.0 * a.sin()),
            range,
        },
        other => other,
    }
}

fn main() -> anyhow::Result<()> {
    let Cli {
        frames,
        every,
        size,
        there_and_back,
        write_masks,
        gpu_host,
        moving_light,
    } = <Cli as clap::Parser>::parse();
    let world = world();
    // The host's job system: frames run on its threads (rayon allocates a
    // queue block every 63 jobs injected from outside a pool).
    let pool = Pool::new(rayon::ThreadPoolBuilder::new().build()?);
    let args = Args {
        frames,
        every,
        size,
        there_and_back,
        write_masks,
        gpu_host,
        moving_light,
    };
    pool.clone().install(|| run(&world, &pool, &args))
}

/// The loop: uploads, then frames along the path with the checks.
/// The command line.
struct Args {
    frames: u32,
    every: u32,
    size: (u32, u32),
    there_and_back: bool,
    /// Each frame's masks as binary PGM (P5, one byte per pixel, DESIGN's
    /// class values), `frame_KKK_light_L.pgm`: what `examples/c/host.c` writes.
    write_masks: Option<std::path::PathBuf>,
    /// The `gpu_host` preset, checked by `Pipeline::check_gpu`.
    gpu_host: bool,
    /// The point light orbits; steps after the first 20 are counted.
    moving_light: bool,
}

/// Writes frame `k`'s id lists and volume buffers as little-endian binary
/// files, as `examples/c/host.c` does: `frame_KKK_psr.bin` (u32 slots),
/// per light `frame_KKK_light_L_psc.bin` (u32) and `_volumes.bin` (the
/// positions as f32 × 4, the u32 indices, then per range its object's slot,
/// method, first index and index count as u32).
fn write_outputs(
    dir: &std::path::Path,
    k: u32,
    out: &shadowcull::FrameOutput<'_>,
) -> std::io::Result<()> {
    let ids = |ids: &[ObjectId]| -> Vec<u8> {
        ids.iter().flat_map(|id| id.slot().to_le_bytes()).collect()
    };
    std::fs::write(dir.join(format!("frame_{k:03}_psr.bin")), ids(out.psr()))?;
    for (l, light) in out.lights().enumerate() {
        let name = |what: &str| dir.join(format!("frame_{k:03}_light_{l}_{what}.bin"));
        std::fs::write(name("psc"), ids(light.psc()))?;
        let v = light.volumes();
        let mut b: Vec<u8> = v
            .positions
            .iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        b.extend(v.indices.iter().flat_map(|i| i.to_le_bytes()));
        for r in &v.ranges {
            // The object's slot: the low half of its id bits.
            for x in [
                r.object as u32,
                r.method as u32,
                r.first_index,
                r.index_count,
            ] {
                b.extend(x.to_le_bytes());
            }
        }
        std::fs::write(name("volumes"), b)?;
    }
    Ok(())
}

/// Writes `mask` as a binary PGM with maxval 3 (the class values).
fn write_pgm(path: &std::path::Path, mask: &shadowcull::mask::Mask) -> std::io::Result<()> {
    let mut bytes = format!("P5\n{} {}\n3\n", mask.width, mask.height).into_bytes();
    bytes.extend(mask.pixels.iter().map(|&p| p as u8));
    std::fs::write(path, bytes)
}

fn run(world: &HostWorld, pool: &Pool, args: &Args) -> anyhow::Result<()> {
    let Args {
        frames,
        every,
        size,
        there_and_back,
        ..
    } = *args;
    // The CPU-mask mode checks a culled `h` pipeline against an unculled
    // one and the reference; `--gpu-host` runs the preset a GPU host starts
    // from and checks its volumes as a GPU would draw them
    // (`Pipeline::check_gpu`, on the reference frames).
    let cpu = |culling| PipelineOptions {
        culling,
        stencil: StencilBackend::H,
        ..Default::default()
    };
    let options = match args.gpu_host {
        true => PipelineOptions::gpu_host(),
        false => cpu(CullingSpec::Chcpp),
    };
    let mut culled = upload(world, options, pool)?;
    let mut unculled = upload(world, cpu(CullingSpec::None), pool)?;
    let (mut psr, mut psc, mut ms) = (Vec::new(), Vec::new(), Vec::new());
    let (mut mismatch, mut off_boundary, mut ambiguous, mut compared, mut differing) =
        (0u64, 0u64, 0u64, 0u64, 0u64);
    let (mut volume_triangles, mut zfail_ranges, mut checked) = (0usize, 0usize, 0u32);
    // Forward along the path (edits included), then back (the moving object only).
    let steps = if there_and_back { 2 * frames } else { frames };
    let (mut allocations_max, mut bytes_max, mut warmup_bytes) = (0u64, 0u64, 0i64);
    let (mut steady_frames, mut steady_allocations) = (0u32, 0u64);
    let point = culled
        .pipeline
        .light_ids()
        .next()
        .expect("the host adds two lights");
    for k in 0..steps {
        let backward = k >= frames;
        let f = if backward { 2 * frames - 1 - k } else { k };
        // With the moving light, everything moves with its period: the
        // camera swings along the path's first frames and back, object 1
        // circles once; so every step after the first period repeats one.
        let (at, angle) = match args.moving_light {
            true => {
                let phase = k % LIGHT_PERIOD;
                let a = std::f64::consts::TAU * f64::from(phase) / f64::from(LIGHT_PERIOD);
                (phase.min(LIGHT_PERIOD - phase), a)
            }
            false => (f, f64::from(f) * 0.2),
        };
        let edits: Vec<HostEdit> = edits(f, angle, world)
            .into_iter()
            .filter(|e| !backward || matches!(e, HostEdit::Move(..)))
            .collect();
        let light = orbiting(world, k);
        for e in &edits {
            edit(&mut unculled, e)?;
        }
        if args.moving_light {
            unculled.pipeline.set_light(point, light)?;
        }
        // The culled pipeline's edit calls and frame, counted apart.
        let (r, [edit_allocations, ..]) = counted(|| -> shadowcull::Result<()> {
            for e in &edits {
                edit(&mut culled, e)?;
            }
            if args.moving_light {
                culled.pipeline.set_light(point, light)?;
            }
            Ok(())
        });
        r?;
        let (view, projection) = host_matrices(at, frames, size);
        let (d, [allocations, bytes, freed]) =
            counted(|| host_frame(&mut culled.pipeline, size, [view, projection]));
        let d = d?;
        if args.moving_light && k >= LIGHT_PERIOD {
            steady_frames += 1;
            steady_allocations += edit_allocations + allocations;
        }
        if backward {
            allocations_max = allocations_max.max(allocations);
            bytes_max = bytes_max.max(bytes);
        } else {
            warmup_bytes += bytes as i64 - freed as i64;
        }
        psr.push(d.psr as f64);
        psc.push(d.psc as f64);
        ms.push(d.frame_ms);
        volume_triangles += d.volume_triangles;
        zfail_ranges += d.non_zpass_ranges;
        let masks: Vec<_> = {
            let out = culled.pipeline.last_output().expect("a frame ran");
            out.lights().map(|l| (l.id(), l.mask().cloned())).collect()
        };
        let reference_frame = every > 0 && k % every == 0;
        if args.gpu_host {
            if reference_frame {
                checked += 1;
                for (id, _) in &masks {
                    let c = culled.pipeline.check_gpu(*id)?;
                    mismatch += c.mismatch_pixels;
                    off_boundary += c.mismatch_off_boundary;
                    differing += c.culled_vs_unculled_differing_pixels;
                }
            }
            continue;
        }
        if let Some(dir) = &args.write_masks {
            for (l, (_, m)) in masks.iter().enumerate() {
                let path = dir.join(format!("frame_{k:03}_light_{l}.pgm"));
                write_pgm(&path, m.as_ref().expect("mask"))?;
            }
            let out = culled.pipeline.last_output().expect("a frame ran");
            write_outputs(dir, k, &out)?;
        }
        // The same frame without culling: conservative culling changes no pixel.
        host_frame(&mut unculled.pipeline, size, [view, projection])?;
        let plain = unculled.pipeline.last_output().expect("a frame ran");
        for ((_, m), p) in masks.iter().zip(plain.lights()) {
            let (m, p) = (m.as_ref().expect("mask"), p.mask().expect("mask"));
            differing += m
                .pixels
                .iter()
                .zip(&p.pixels)
                .filter(|(a, b)| a != b)
                .count() as u64;
        }
        if reference_frame {
            checked += 1;
            for (id, m) in &masks {
                let r = culled.pipeline.reference_mask(*id)?;
                let c = compare(&r.mask, &r.ambiguous, m.as_ref().expect("mask"));
                mismatch += c.mismatches;
                off_boundary += c.mismatches - c.mismatches_on_boundary;
                ambiguous += c.ambiguous;
                compared += c.compared;
            }
        }
    }
    let line = serde_json::json!({
        "frames": steps,
        "objects": culled.pipeline.scene().counts().objects,
        "moving_objects": 1,
        "there_and_back": there_and_back,
        "allocations_per_frame_max": allocations_max,
        "bytes_allocated_per_frame_max": bytes_max,
        "warmup_bytes": warmup_bytes,
        "width": size.0,
        "height": size.1,
        "lights": world.lights.len(),
        "gpu_host": args.gpu_host,
        "moving_light": args.moving_light,
        "steady_frames": steady_frames,
        "steady_allocations": steady_allocations,
        "psr_median": median(&psr).unwrap_or(0.0),
        "psc_median": median(&psc).unwrap_or(0.0),
        "frame_ms_median": median(&ms).unwrap_or(0.0),
        "volume_triangles_total": volume_triangles,
        "non_zpass_ranges_total": zfail_ranges,
        "reference_frames": checked,
        "mismatch_pixels": mismatch,
        "mismatch_off_boundary": off_boundary,
        "ambiguous_pixels": ambiguous,
        "compared_pixels": compared,
        "culled_vs_unculled_differing_pixels": differing,
    });
    println!("{line}");
    Ok(())
}
