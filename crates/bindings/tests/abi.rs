//! The C ABI through its `extern "C"` functions: the output equals the Rust
//! `Pipeline`'s bit for bit, misuse gives the right status and message and
//! never a crash, versioned structs read as documented, and two pipelines
//! run on two threads.

use glam::{DMat4, DVec3};
use shadowcull::scene::{Camera, ClipDepth, Light, Mesh, ObjectFlags, Scene, SceneGraph};
use shadowcull::{CullingSpec, FrameInput, Pipeline, PipelineOptions, StencilBackend};
use shadowcull_c::*;
use std::ffi::CStr;

const W: u32 = 160;
const H: u32 = 120;

fn last_error() -> String {
    // SAFETY: the library returns a valid NUL-terminated string.
    unsafe { CStr::from_ptr(sc_last_error()) }
        .to_string_lossy()
        .into_owned()
}

fn ok(s: sc_status) {
    assert_eq!(s, sc_status::SC_OK, "{}", last_error());
}

/// A unit cube, corners at 0 and 1, as a host keeps it (f32, u16).
fn cube() -> (Vec<[f32; 3]>, Vec<u16>) {
    let p = (0..8)
        .map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32])
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let idx = quads
        .iter()
        .flat_map(|q| [q[0], q[1], q[2], q[0], q[2], q[3]])
        .collect();
    (p, idx)
}

/// Object `k` of the scene: boxes on a grid over a ground slab.
fn placement(k: usize) -> DMat4 {
    if k == 0 {
        return DMat4::from_scale_rotation_translation(
            DVec3::new(40.0, 0.5, 40.0),
            glam::DQuat::IDENTITY,
            DVec3::new(-20.0, -0.5, -20.0),
        );
    }
    let (i, j) = ((k - 1) % 6, (k - 1) / 6);
    DMat4::from_scale_rotation_translation(
        DVec3::new(1.5, 1.0 + (k % 4) as f64, 1.5),
        glam::DQuat::IDENTITY,
        DVec3::new(-15.0 + 5.0 * i as f64, 0.0, -15.0 + 5.0 * j as f64),
    )
}

const OBJECTS: usize = 37;

fn lights() -> [Light; 2] {
    [
        Light::Point {
            position: DVec3::new(2.0, 14.0, 3.0),
            range: None,
        },
        Light::Directional {
            direction: DVec3::new(0.4, -0.8, 0.3),
        },
    ]
}

fn light_desc(l: &Light) -> sc_light_desc {
    let mut d = sc_light_desc {
        struct_size: std::mem::size_of::<sc_light_desc>() as u32,
        kind: SC_LIGHT_POINT,
        position: [0.0; 3],
        direction: [0.0; 3],
        apex_angle: 1.0,
        range: 0.0,
    };
    match *l {
        Light::Point { position, .. } => d.position = position.to_array(),
        Light::Directional { direction } => {
            d.kind = SC_LIGHT_DIRECTIONAL;
            d.direction = direction.to_array();
        }
        Light::Spot { .. } => unreachable!("not used"),
    }
    d
}

/// The view and projection (GL) of frame `f`: circling the grid.
fn matrices(f: u32) -> (DMat4, DMat4) {
    let a = f64::from(f) * 0.15;
    let eye = DVec3::new(25.0 * a.cos(), 9.0, 25.0 * a.sin());
    // Right-handed look-at: rows r, u, -f.
    let f = (DVec3::new(0.0, 1.0, 0.0) - eye).normalize();
    let r = f.cross(DVec3::Y).normalize();
    let u = r.cross(f);
    let view = DMat4::from_cols(
        glam::DVec4::new(r.x, u.x, -f.x, 0.0),
        glam::DVec4::new(r.y, u.y, -f.y, 0.0),
        glam::DVec4::new(r.z, u.z, -f.z, 0.0),
        glam::DVec4::new(-r.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
    );
    // OpenGL perspective, 60° vertical, near 0.1, far 200.
    let (near, far) = (0.1, 200.0);
    let t = 1.0 / (30f64.to_radians()).tan();
    let aspect = f64::from(W) / f64::from(H);
    let proj = DMat4::from_cols(
        glam::DVec4::new(t / aspect, 0.0, 0.0, 0.0),
        glam::DVec4::new(0.0, t, 0.0, 0.0),
        glam::DVec4::new(0.0, 0.0, -(far + near) / (far - near), -1.0),
        glam::DVec4::new(0.0, 0.0, -2.0 * far * near / (far - near), 0.0),
    );
    (view, proj)
}

fn c_options() -> sc_pipeline_options {
    let mut o = std::mem::MaybeUninit::<sc_pipeline_options>::uninit();
    ok(sc_pipeline_options_default(o.as_mut_ptr()));
    // SAFETY: filled by the call above.
    let mut o = unsafe { o.assume_init() };
    o.stencil = SC_STENCIL_H;
    o.light_resolution = 256;
    o
}

/// The description of the cube `pos`, `idx` (f32 positions, u16 indices).
fn cube_desc(pos: &[[f32; 3]], idx: &[u16]) -> sc_mesh_desc {
    sc_mesh_desc {
        struct_size: std::mem::size_of::<sc_mesh_desc>() as u32,
        position_type: SC_F32,
        position_stride: 12,
        vertex_count: pos.len() as u32,
        positions: pos.as_ptr().cast(),
        index_type: SC_U16,
        index_count: idx.len() as u32,
        indices: idx.as_ptr().cast(),
    }
}

/// The scene through the C ABI: (pipeline, objects, lights).
fn c_pipeline() -> (sc_pipeline, Vec<sc_object>, Vec<sc_light>) {
    let mut p = 0;
    ok(sc_pipeline_create(&c_options(), &mut p));
    let (pos, idx) = cube();
    let desc = cube_desc(&pos, &idx);
    let mut mesh = 0;
    ok(sc_mesh_create(p, &desc, &mut mesh));
    let objects = (0..OBJECTS)
        .map(|k| {
            let mut o = 0;
            let m = placement(k).to_cols_array();
            ok(sc_object_create(p, mesh, m.as_ptr(), SC_FLAGS_ALL, &mut o));
            o
        })
        .collect();
    let lights = lights()
        .iter()
        .map(|l| {
            let mut h = 0;
            ok(sc_light_create(p, &light_desc(l), &mut h));
            h
        })
        .collect();
    (p, objects, lights)
}

fn rust_pipeline() -> Pipeline {
    let options = PipelineOptions {
        culling: CullingSpec::Chcpp,
        stencil: StencilBackend::H,
        light_resolution: 256,
        ..Default::default()
    };
    let mut p = Pipeline::new(Scene::new(SceneGraph::new()).unwrap(), options).unwrap();
    let (pos, idx) = cube();
    let positions: Vec<glam::Vec3> = pos.iter().map(|&q| q.into()).collect();
    let tris: Vec<[u32; 3]> = idx
        .chunks(3)
        .map(|t| [u32::from(t[0]), u32::from(t[1]), u32::from(t[2])])
        .collect();
    let mesh = p.add_mesh(Mesh::new("mesh", &positions, &tris).unwrap());
    for k in 0..OBJECTS {
        p.add_object(mesh, placement(k), ObjectFlags::ALL).unwrap();
    }
    for l in lights() {
        p.add_light(l).unwrap();
    }
    p
}

fn input(f: u32) -> sc_frame_input {
    let (view, proj) = matrices(f);
    sc_frame_input {
        struct_size: std::mem::size_of::<sc_frame_input>() as u32,
        width: W,
        height: H,
        clip_depth: SC_CLIP_DEPTH_NEGATIVE_ONE_TO_ONE,
        view: view.to_cols_array(),
        projection: proj.to_cols_array(),
        host_depth: std::ptr::null(),
        host_depth_width: 0,
        host_depth_height: 0,
        near: 0.0,
        anamorphic: 0,
    }
}

fn empty_output() -> sc_frame_output {
    // SAFETY: plain data: zeroed pointers and counts are valid values.
    let mut o: sc_frame_output = unsafe { std::mem::zeroed() };
    o.struct_size = std::mem::size_of::<sc_frame_output>() as u32;
    o
}

/// A slice from a pointer and count of the library's output.
/// The C handle of a thing of `kind` (1 object, 2 mesh, 3 light) at
/// `slot` and `generation`: the layout `id_handles.rs` documents.
fn handle(kind: u64, slot: u32, generation: u32) -> u64 {
    (u64::from(slot) | kind << 28 | u64::from(generation) << 32) + 1
}

fn object_handle(id: shadowcull::scene::ObjectId) -> u64 {
    handle(1, id.slot(), id.generation())
}

fn slice<'a, T>(p: *const T, n: usize) -> &'a [T] {
    if n == 0 {
        return &[];
    }
    // SAFETY: the library's output: `n` elements at `p`, valid until the
    // next frame call.
    unsafe { std::slice::from_raw_parts(p, n) }
}

/// Frames of the C pipeline equal the Rust pipeline's bit for bit: PSR, per
/// light PSC, the volume buffer (positions, indices, ranges) and the mask,
/// with an object moved, one removed and one added along the way.
#[test]
fn output_equals_the_rust_pipeline() {
    let (p, objects, _) = c_pipeline();
    let mut r = rust_pipeline();
    let ids: Vec<_> = (0..OBJECTS as u32)
        .map(shadowcull::scene::ObjectId::from_slot)
        .collect();
    let mut out = empty_output();
    let mut masks_with_shadow = 0;
    for f in 0..8 {
        let moved =
            placement(5) * DMat4::from_translation(DVec3::new(0.3 * f64::from(f), 0.0, 0.0));
        ok(sc_object_set_transform(
            p,
            objects[5],
            moved.to_cols_array().as_ptr(),
        ));
        r.set_transform(ids[5], moved).unwrap();
        if f == 3 {
            ok(sc_object_destroy(p, objects[7]));
            r.remove_object(ids[7]).unwrap();
        }
        // A jump in frame numbers, then a keyframe.
        if f == 5 {
            ok(sc_pipeline_set_frame_number(p, 40));
            r.set_frame_number(40);
        }
        if f == 6 {
            ok(sc_pipeline_reset_history(p));
            r.reset_history();
        }
        ok(sc_pipeline_frame(p, &input(f), &mut out));
        let (view, proj) = matrices(f);
        let cam = Camera::from_view_projection(view, proj, ClipDepth::NegativeOneToOne).unwrap();
        let o = r.frame(&FrameInput::new(W, H, cam)).unwrap();
        let number = if f < 5 { f } else { f + 35 };
        assert_eq!((out.stats.frame, o.stats().frame), (number, number));
        assert_eq!(out.stats.eye_queries, o.stats().eye_queries, "frame {f}");
        let psr: Vec<u64> = o.psr().iter().map(|&id| object_handle(id)).collect();
        assert_eq!(slice(out.psr, out.psr_count), &psr[..], "frame {f}: PSR");
        let lights = slice(out.lights, out.light_count);
        assert_eq!(lights.len(), o.light_count());
        for (c, l) in lights.iter().zip(o.lights()) {
            let id = l.id();
            assert_eq!(c.light, handle(3, id.slot(), id.generation()));
            assert_eq!(c.stats.queries, l.stats().queries, "frame {f}: queries");
            let psc: Vec<u64> = l.psc().iter().map(|&id| object_handle(id)).collect();
            assert_eq!(slice(c.psc, c.psc_count), &psc[..], "frame {f}: PSC");
            let v = l.volumes();
            assert_eq!(slice(c.positions, c.position_count), &v.positions[..]);
            assert_eq!(slice(c.indices, c.index_count), &v.indices[..]);
            let ranges = slice(c.ranges, c.range_count);
            assert_eq!(ranges.len(), v.ranges.len());
            for (a, b) in ranges.iter().zip(&v.ranges) {
                let id = shadowcull::scene::ObjectId::from_bits(b.object);
                assert_eq!(a.object, object_handle(id));
                assert_eq!(
                    (a.first_index, a.index_count),
                    (b.first_index, b.index_count)
                );
                assert_eq!(a.world_from_local, b.world_from_local.to_cols_array());
                assert_eq!(a.scissor, b.scissor);
                assert_eq!(a.band, b.band);
            }
            let mask = l.mask().expect("h stencil draws a mask");
            let bytes: Vec<u8> = mask.pixels.iter().map(|&p| p as u8).collect();
            assert_eq!(
                slice(c.mask, (W * H) as usize),
                &bytes[..],
                "frame {f}: mask"
            );
            masks_with_shadow += usize::from(bytes.contains(&1));
        }
    }
    assert!(masks_with_shadow > 0, "the scene casts shadows");
    ok(sc_pipeline_destroy(p));
}

/// A frame's output stays valid until the next frame call, edits between
/// included: a renderer draws frame N's volumes while it edits for N + 1.
/// Destroying the lights and an object and making another light keep the
/// output's pointers on what the frame wrote.
#[test]
fn the_output_outlives_edits_until_the_next_frame() {
    let (p, objects, handles) = c_pipeline();
    let mut out = empty_output();
    ok(sc_pipeline_frame(p, &input(0), &mut out));
    type Copied = (Vec<[f32; 4]>, Vec<u32>, Vec<u8>);
    let copy = |out: &sc_frame_output| -> Vec<Copied> {
        slice(out.lights, out.light_count)
            .iter()
            .map(|c| {
                (
                    slice(c.positions, c.position_count).to_vec(),
                    slice(c.indices, c.index_count).to_vec(),
                    slice(c.mask, (W * H) as usize).to_vec(),
                )
            })
            .collect()
    };
    let before = copy(&out);
    assert!(
        before.iter().any(|(_, i, _)| !i.is_empty()),
        "volumes drawn"
    );
    for &l in &handles {
        ok(sc_light_destroy(p, l));
    }
    ok(sc_object_destroy(p, objects[2]));
    let mut again = 0;
    ok(sc_light_create(p, &light_desc(&lights()[0]), &mut again));
    assert_eq!(
        copy(&out),
        before,
        "the output changed before the next frame"
    );
    ok(sc_pipeline_frame(p, &input(1), &mut out));
    assert_eq!(out.light_count, 1);
    ok(sc_pipeline_destroy(p));
}

/// The host's own depth through `sc_frame_input.host_depth`: a depth with
/// nothing drawn hides nothing (every visible object in the PSR), a wall
/// at the near plane hides everything (an empty PSR, once CHC++ has queried
/// each object again); one of another size
/// than the culling size is refused, naming the field.
#[test]
fn a_host_depth_decides_the_psr() {
    use sc_status::*;
    let (p, _, _) = c_pipeline();
    let mut out = empty_output();
    ok(sc_pipeline_frame(p, &input(0), &mut out));
    let culled = out.psr_count;
    assert!(culled > 0);
    let frame = |depth: &[f32], w: u32, h: u32, out: &mut sc_frame_output| {
        let mut i = input(0);
        (i.host_depth, i.host_depth_width, i.host_depth_height) = (depth.as_ptr(), w, h);
        sc_pipeline_frame(p, &i, out)
    };
    let n = (W * H) as usize;
    ok(frame(&vec![0.0; n], W, H, &mut out));
    assert!(out.psr_count >= culled, "{} < {culled}", out.psr_count);
    // (CHC++ queries what was visible again within a few frames.)
    let wall = vec![1.0; n];
    let counts: Vec<usize> = (0..12)
        .map(|_| {
            ok(frame(&wall, W, H, &mut out));
            out.psr_count
        })
        .collect();
    assert_eq!(
        counts.last(),
        Some(&0),
        "a wall at the near plane hides all: {counts:?}"
    );
    let small = vec![0.0; n / 4];
    assert_eq!(frame(&small, W / 2, H / 2, &mut out), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("host_depth"), "{}", last_error());
    ok(sc_pipeline_destroy(p));
}

/// `sc_object_set_occluder`: a mesh inside the object's is taken (and
/// framed), one reaching outside it is refused with a message naming the
/// object, the null handle goes back to the object's own mesh.
#[test]
fn a_host_occluder_is_set_refused_and_cleared() {
    use sc_status::*;
    let (p, objects, _) = c_pipeline();
    let (pos, idx) = cube();
    let scaled =
        |s: f32, o: f32| -> Vec<[f32; 3]> { pos.iter().map(|v| v.map(|c| c * s + o)).collect() };
    let mesh = |positions: &[[f32; 3]]| {
        let mut m = 0;
        ok(sc_mesh_create(p, &cube_desc(positions, &idx), &mut m));
        m
    };
    let inner = mesh(&scaled(0.5, 0.25));
    let outer = mesh(&scaled(2.0, -0.5));
    ok(sc_object_set_occluder(p, objects[0], inner));
    let mut out = empty_output();
    ok(sc_pipeline_frame(p, &input(0), &mut out));
    assert_eq!(
        sc_object_set_occluder(p, objects[1], outer),
        SC_INVALID_ARGUMENT
    );
    let e = last_error();
    assert!(
        e.contains("occluder of object") && e.contains("reach outside"),
        "{e}"
    );
    assert_eq!(
        sc_object_set_occluder(p, objects[1], u64::MAX),
        SC_INVALID_ARGUMENT
    );
    assert!(last_error().contains("occluder"), "{}", last_error());
    ok(sc_object_set_occluder(p, objects[0], 0));
    ok(sc_pipeline_frame(p, &input(1), &mut out));
    ok(sc_pipeline_destroy(p));
}

#[test]
fn misuse_gives_statuses_and_messages() {
    use sc_status::*;
    let mut h = 0;
    // NULL arguments.
    assert_eq!(
        sc_pipeline_options_default(std::ptr::null_mut()),
        SC_INVALID_ARGUMENT
    );
    assert!(last_error().contains("options"), "{}", last_error());
    assert_eq!(
        sc_pipeline_create(std::ptr::null(), &mut h),
        SC_INVALID_ARGUMENT
    );
    assert!(last_error().contains("options: NULL"), "{}", last_error());
    assert_eq!(
        sc_pipeline_create(&c_options(), std::ptr::null_mut()),
        SC_INVALID_ARGUMENT
    );
    // A wrong struct_size.
    let mut o = c_options();
    o.struct_size = 3;
    assert_eq!(sc_pipeline_create(&o, &mut h), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("struct_size"), "{}", last_error());

    let (p, objects, lights) = c_pipeline();
    // The cube mesh c_pipeline made first.
    let cube_mesh = handle(2, 0, 0);
    let (pos, idx) = cube();
    let mut desc = sc_mesh_desc {
        position_stride: 0,
        ..cube_desc(&pos, &idx)
    };
    let mut mesh = 0;
    // Stride 0.
    assert_eq!(sc_mesh_create(p, &desc, &mut mesh), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("position_stride"), "{}", last_error());
    // An index out of range.
    desc.position_stride = 12;
    let bad: Vec<u16> = idx.iter().map(|&i| if i == 7 { 8 } else { i }).collect();
    desc.indices = bad.as_ptr().cast();
    assert_eq!(sc_mesh_create(p, &desc, &mut mesh), SC_INVALID_ARGUMENT);
    assert!(!last_error().is_empty());
    // NULL positions, a bad index type.
    desc.indices = idx.as_ptr().cast();
    desc.positions = std::ptr::null();
    assert_eq!(sc_mesh_create(p, &desc, &mut mesh), SC_INVALID_ARGUMENT);
    desc.positions = pos.as_ptr().cast();
    desc.index_type = 9;
    assert_eq!(sc_mesh_create(p, &desc, &mut mesh), SC_INVALID_ARGUMENT);
    // NaN matrices.
    let mut nan = DMat4::IDENTITY.to_cols_array();
    nan[5] = f64::NAN;
    assert_eq!(
        sc_object_set_transform(p, objects[1], nan.as_ptr()),
        SC_INVALID_ARGUMENT
    );
    assert!(
        last_error().contains("world_from_local"),
        "{}",
        last_error()
    );
    assert_eq!(
        sc_object_set_transform(p, objects[1], std::ptr::null()),
        SC_INVALID_ARGUMENT
    );
    // A projective matrix (bottom row not (0, 0, 0, 1)), named.
    let mut projective = DMat4::IDENTITY.to_cols_array();
    projective[3] = 0.05;
    assert_eq!(
        sc_object_set_transform(p, objects[1], projective.as_ptr()),
        SC_INVALID_ARGUMENT
    );
    let e = last_error();
    assert!(e.contains("object") && e.contains("projective"), "{e}");
    let mut i = input(0);
    i.view[0] = f64::NAN;
    let mut out = empty_output();
    assert_eq!(sc_pipeline_frame(p, &i, &mut out), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("input.view"), "{}", last_error());
    // A 0×0 viewport.
    let mut i = input(0);
    (i.width, i.height) = (0, 0);
    assert_eq!(sc_pipeline_frame(p, &i, &mut out), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("viewport"), "{}", last_error());
    // A viewport of another aspect than the projection's: refused unless
    // its pixels are declared not square.
    let mut i = input(0);
    i.width += W / 10;
    assert_eq!(sc_pipeline_frame(p, &i, &mut out), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("aspect"), "{}", last_error());
    i.anamorphic = 1;
    ok(sc_pipeline_frame(p, &i, &mut out));
    i.anamorphic = 2;
    assert_eq!(sc_pipeline_frame(p, &i, &mut out), SC_INVALID_ARGUMENT);
    assert!(
        last_error().contains("input.anamorphic"),
        "{}",
        last_error()
    );
    // The host's near plane: right under OpenGL depth, refused under
    // zero-to-one (the matrix is OpenGL's).
    let mut i = input(0);
    i.near = 0.1;
    ok(sc_pipeline_frame(p, &i, &mut out));
    i.clip_depth = SC_CLIP_DEPTH_ZERO_TO_ONE;
    assert_eq!(sc_pipeline_frame(p, &i, &mut out), SC_INVALID_ARGUMENT);
    assert!(
        last_error().contains("is NegativeOneToOne, not ZeroToOne"),
        "{}",
        last_error()
    );
    // An output without its size.
    let mut small = empty_output();
    small.struct_size = 8;
    assert_eq!(
        sc_pipeline_frame(p, &input(0), &mut small),
        SC_INVALID_ARGUMENT
    );
    assert_eq!(
        sc_pipeline_frame(p, &input(0), std::ptr::null_mut()),
        SC_INVALID_ARGUMENT
    );
    // Stale handles after destroy; double destroy; the null handle.
    ok(sc_object_destroy(p, objects[2]));
    assert_eq!(sc_object_destroy(p, objects[2]), SC_INVALID_ARGUMENT);
    assert_eq!(
        sc_object_set_flags(p, objects[2], SC_FLAGS_ALL),
        SC_INVALID_ARGUMENT
    );
    ok(sc_object_destroy(p, 0));
    assert_eq!(sc_object_set_flags(p, objects[3], 99), SC_INVALID_ARGUMENT);
    ok(sc_light_destroy(p, lights[0]));
    assert_eq!(sc_light_destroy(p, lights[0]), SC_INVALID_ARGUMENT);
    assert_eq!(
        sc_light_set(p, lights[0], &light_desc(&lights_0())),
        SC_INVALID_ARGUMENT
    );
    // The freed slots are reused under new handles; the old ones stay stale.
    let (mut object, mut light) = (0, 0);
    let m = DMat4::IDENTITY.to_cols_array();
    ok(sc_object_create(
        p,
        cube_mesh,
        m.as_ptr(),
        SC_FLAGS_ALL,
        &mut object,
    ));
    ok(sc_light_create(p, &light_desc(&lights_0()), &mut light));
    assert!(object != objects[2] && light != lights[0]);
    // A LOD change takes a mesh's handle, and refuses any other kind.
    ok(sc_object_set_mesh(p, object, cube_mesh));
    assert_eq!(sc_object_set_mesh(p, object, light), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("not a mesh's"), "{}", last_error());
    assert_eq!(
        sc_object_set_mesh(p, objects[2], cube_mesh),
        SC_INVALID_ARGUMENT
    );
    assert_eq!(
        object & 0xffff_ffff,
        objects[2] & 0xffff_ffff,
        "the slot is reused"
    );
    assert_eq!(
        light & 0xffff_ffff,
        lights[0] & 0xffff_ffff,
        "the slot is reused"
    );
    assert_eq!(
        sc_object_set_flags(p, objects[2], SC_FLAGS_ALL),
        SC_INVALID_ARGUMENT
    );
    assert!(last_error().contains("stale"), "{}", last_error());
    assert_eq!(sc_light_destroy(p, lights[0]), SC_INVALID_ARGUMENT);
    ok(sc_object_set_flags(p, object, SC_FLAGS_ALL));
    ok(sc_object_destroy(p, object));
    ok(sc_light_destroy(p, light));
    // NULL for the remaining pointer arguments.
    let m = DMat4::IDENTITY.to_cols_array();
    let nul = std::ptr::null_mut();
    let mut x = 0;
    for (what, status) in [
        (
            "sc_mesh_create out",
            sc_mesh_create(p, &cube_desc(&pos, &idx), nul),
        ),
        (
            "sc_mesh_update_positions",
            sc_mesh_update_positions(p, cube_mesh, std::ptr::null()),
        ),
        (
            "sc_object_create out",
            sc_object_create(p, cube_mesh, m.as_ptr(), SC_FLAGS_ALL, nul),
        ),
        (
            "sc_object_create_f32",
            sc_object_create_f32(p, cube_mesh, std::ptr::null(), SC_FLAGS_ALL, &mut x),
        ),
        (
            "sc_object_set_transform_f32",
            sc_object_set_transform_f32(p, objects[3], std::ptr::null()),
        ),
        (
            "sc_light_create desc",
            sc_light_create(p, std::ptr::null(), &mut x),
        ),
        (
            "sc_light_create out",
            sc_light_create(p, &light_desc(&lights_0()), nul),
        ),
        ("sc_light_set", sc_light_set(p, lights[1], std::ptr::null())),
        (
            "sc_pipeline_create_from_file path",
            sc_pipeline_create_from_file(&c_options(), std::ptr::null(), &mut x),
        ),
        (
            "sc_pipeline_create_from_file out",
            sc_pipeline_create_from_file(&c_options(), c"a.obj".as_ptr(), nul),
        ),
    ] {
        assert_eq!(status, SC_INVALID_ARGUMENT, "{what}: {}", last_error());
        assert!(last_error().contains("NULL"), "{what}: {}", last_error());
    }
    // A mesh in use cannot go; an unknown one is stale.
    assert_eq!(sc_mesh_destroy(p, cube_mesh), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("instanced"), "{}", last_error());
    assert_eq!(sc_mesh_destroy(p, 77), SC_INVALID_ARGUMENT);
    // A handle of another kind names nothing: an object's handle given for
    // a mesh, a mesh's for an object, a light's for an object.
    assert_eq!(sc_mesh_destroy(p, objects[3]), SC_INVALID_ARGUMENT);
    assert!(
        last_error().contains("is an object's handle, not a mesh's"),
        "{}",
        last_error()
    );
    assert_eq!(sc_object_destroy(p, cube_mesh), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("a mesh's handle"), "{}", last_error());
    assert_eq!(sc_object_destroy(p, lights[1]), SC_INVALID_ARGUMENT);
    ok(sc_object_set_flags(p, objects[3], SC_FLAGS_ALL));
    ok(sc_pipeline_frame(p, &input(0), &mut out));
    ok(sc_pipeline_destroy(p));
    assert_eq!(sc_pipeline_destroy(p), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("stale"), "{}", last_error());
    assert_eq!(
        sc_pipeline_frame(p, &input(0), &mut out),
        SC_INVALID_ARGUMENT
    );
    assert_eq!(sc_object_destroy(p, objects[1]), SC_INVALID_ARGUMENT);
    assert_eq!(sc_pipeline_set_frame_number(p, 3), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("stale"), "{}", last_error());
    assert_eq!(sc_pipeline_reset_history(p), SC_INVALID_ARGUMENT);
    assert_eq!(sc_pipeline_reset_history(0), SC_INVALID_ARGUMENT);
    ok(sc_pipeline_destroy(0));
    // A frame before any object exists.
    let mut q = 0;
    ok(sc_pipeline_create(&c_options(), &mut q));
    ok(sc_pipeline_frame(q, &input(0), &mut out));
    assert_eq!((out.psr_count, out.light_count), (0, 0));
    ok(sc_pipeline_destroy(q));
    // A file that is not there, and one that is no scene.
    let path = c"/nonexistent/scene.gltf";
    assert_eq!(
        sc_pipeline_create_from_file(&c_options(), path.as_ptr(), &mut q),
        SC_IO
    );
    assert!(last_error().contains("scene.gltf"), "{}", last_error());
    assert_eq!(
        sc_pipeline_create_from_file(&c_options(), c"x.txt".as_ptr(), &mut q),
        SC_INVALID_ARGUMENT
    );
}

fn lights_0() -> Light {
    lights()[0]
}

/// `struct_size` smaller than ours takes defaults for the rest; larger is
/// accepted when the extra bytes are zero and refused otherwise.
#[test]
fn versioned_structs() {
    use sc_status::*;
    #[repr(C)]
    struct Bigger {
        options: sc_pipeline_options,
        extra: u64,
    }
    let mut big = Bigger {
        options: c_options(),
        extra: 0,
    };
    big.options.struct_size = std::mem::size_of::<Bigger>() as u32;
    let mut h = 0;
    ok(sc_pipeline_create(&big.options, &mut h));
    ok(sc_pipeline_destroy(h));
    big.extra = 1;
    assert_eq!(
        sc_pipeline_create(&big.options, &mut h),
        SC_INVALID_ARGUMENT
    );
    assert!(last_error().contains("non-zero"), "{}", last_error());
    // An older host knew only `struct_size` and `culling`: the rest defaults.
    let mut old = c_options();
    old.struct_size = 8;
    old.culling = SC_CULLING_NONE;
    old.stencil = 77; // past the old size: ignored
    ok(sc_pipeline_create(&old, &mut h));
    ok(sc_pipeline_destroy(h));
    // `culling: auto` is a culling value; past it, none is.
    let mut auto = c_options();
    auto.culling = SC_CULLING_AUTO;
    ok(sc_pipeline_create(&auto, &mut h));
    ok(sc_pipeline_destroy(h));
    auto.culling = SC_CULLING_AUTO + 1;
    assert_eq!(sc_pipeline_create(&auto, &mut h), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("options.culling"), "{}", last_error());
    // So are the depth-bounds and `auto` stencils; past them, none is.
    let mut stencil = c_options();
    for v in [SC_STENCIL_DB, SC_STENCIL_AUTO] {
        stencil.stencil = v;
        ok(sc_pipeline_create(&stencil, &mut h));
        ok(sc_pipeline_destroy(h));
    }
    stencil.stencil = SC_STENCIL_AUTO + 1;
    assert_eq!(sc_pipeline_create(&stencil, &mut h), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("options.stencil"), "{}", last_error());
    assert_eq!(sc_version(), SC_ABI_VERSION);
}

/// `sc_pipeline_options_gpu_host` fills a struct a pipeline takes; NULL and
/// an unknown preset are errors naming the argument or field; a 72-byte
/// struct from before `preset` and `scissor` means the batch preset.
#[test]
fn the_gpu_host_preset_fills_options_a_pipeline_takes() {
    use sc_status::*;
    assert_eq!(
        sc_pipeline_options_gpu_host(std::ptr::null_mut()),
        SC_INVALID_ARGUMENT
    );
    assert!(last_error().contains("options"), "{}", last_error());
    let mut o = std::mem::MaybeUninit::<sc_pipeline_options>::uninit();
    ok(sc_pipeline_options_gpu_host(o.as_mut_ptr()));
    // SAFETY: filled by the call above.
    let mut o = unsafe { o.assume_init() };
    assert_eq!(
        o.struct_size as usize,
        std::mem::size_of::<sc_pipeline_options>()
    );
    assert_eq!(
        (o.preset, o.stencil, o.culling),
        (SC_PRESET_GPU_HOST, SC_STENCIL_NONE, SC_CULLING_AUTO)
    );
    assert_ne!(o.scissor, 0);
    let mut h = 0;
    ok(sc_pipeline_create(&o, &mut h));
    ok(sc_pipeline_destroy(h));
    let mut old = o;
    old.struct_size = 72;
    old.preset = 99; // past the old size: ignored
    ok(sc_pipeline_create(&old, &mut h));
    ok(sc_pipeline_destroy(h));
    o.preset = SC_PRESET_GPU_HOST + 1;
    assert_eq!(sc_pipeline_create(&o, &mut h), SC_INVALID_ARGUMENT);
    assert!(last_error().contains("options.preset"), "{}", last_error());
}

/// `max_memory` (the 40-byte options): a frame whose memory estimate
/// exceeds it fails before allocating, naming the field; a 32-byte struct
/// from before the field means the machine's default.
#[test]
fn max_memory_refuses_a_frame_that_cannot_fit() {
    use sc_status::*;
    let mut o = c_options();
    o.max_memory = 1 << 20;
    let mut p = 0;
    ok(sc_pipeline_create(&o, &mut p));
    let (pos, idx) = cube();
    let mut mesh = 0;
    ok(sc_mesh_create(p, &cube_desc(&pos, &idx), &mut mesh));
    let mut obj = 0;
    let m = placement(0).to_cols_array();
    ok(sc_object_create(
        p,
        mesh,
        m.as_ptr(),
        SC_FLAGS_ALL,
        &mut obj,
    ));
    let mut out = empty_output();
    assert_eq!(
        sc_pipeline_frame(p, &input(0), &mut out),
        SC_INVALID_ARGUMENT
    );
    assert!(last_error().contains("max_memory"), "{}", last_error());
    ok(sc_pipeline_destroy(p));
    let mut old = c_options();
    old.struct_size = 32;
    old.max_memory = 1; // past the old size: ignored
    ok(sc_pipeline_create(&old, &mut p));
    ok(sc_mesh_create(p, &cube_desc(&pos, &idx), &mut mesh));
    ok(sc_object_create(
        p,
        mesh,
        m.as_ptr(),
        SC_FLAGS_ALL,
        &mut obj,
    ));
    ok(sc_pipeline_frame(p, &input(0), &mut out));
    ok(sc_pipeline_destroy(p));
}

/// Two pipelines on two threads at once give what each gives alone.
#[test]
fn two_pipelines_on_two_threads() {
    let run = || {
        let (p, _, _) = c_pipeline();
        let mut out = empty_output();
        let mut sums = Vec::new();
        for f in 0..4 {
            ok(sc_pipeline_frame(p, &input(f), &mut out));
            let lights = slice(out.lights, out.light_count);
            sums.push((
                out.psr_count,
                lights.iter().map(|l| l.index_count).sum::<usize>(),
                lights
                    .iter()
                    .map(|l| {
                        slice(l.mask, (W * H) as usize)
                            .iter()
                            .map(|&b| u64::from(b))
                            .sum::<u64>()
                    })
                    .sum::<u64>(),
            ));
        }
        ok(sc_pipeline_destroy(p));
        sums
    };
    let alone = run();
    let (a, b) = std::thread::scope(|s| {
        let a = s.spawn(run);
        let b = s.spawn(run);
        (a.join().unwrap(), b.join().unwrap())
    });
    assert_eq!(a, alone);
    assert_eq!(b, alone);
}

/// The host backend through the C callbacks, each forwarding to the
/// library's own software backend (`raster::SyncBackend`): the output equals
/// the pipeline's without it, frame by frame (PSR, PSC, volumes, masks).
mod forwarding {
    use super::*;
    use shadowcull::raster::{
        Coverage, CullMode, DepthPick, DepthTarget, DrawCommand, OcclusionBackend, QueryCommand,
        QueryId, QueryMode, QueryOptions, ReceiverTarget, SyncBackend, TileSize,
    };
    use std::ffi::c_void;
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::sync::Arc;

    /// Views begun and ended, over every pipeline of the test.
    static BEGUN: AtomicU64 = AtomicU64::new(0);
    static ENDED: AtomicU64 = AtomicU64::new(0);

    struct View(SyncBackend);

    fn view<'a>(v: *mut c_void) -> &'a mut SyncBackend {
        // SAFETY: `v` is the `View` `begin_view` boxed, used by one thread.
        unsafe { &mut (*(v as *mut View)).0 }
    }

    fn coverage(c: u32, pick: u32) -> Coverage {
        let p = if pick == SC_PICK_FARTHEST {
            DepthPick::Farthest
        } else {
            DepthPick::Nearest
        };
        match c {
            SC_RASTER_OUTER => Coverage::Outer(p),
            SC_RASTER_INNER => Coverage::Inner(p),
            _ => Coverage::Standard,
        }
    }

    extern "C" fn begin_view(_: *mut c_void, role: *const sc_view_role) -> *mut c_void {
        // SAFETY: the library passes a valid role.
        let r = unsafe { &*role };
        BEGUN.fetch_add(1, Ordering::SeqCst);
        let t = DepthTarget::new(r.width, r.height, TileSize::T8, false).unwrap();
        Box::into_raw(Box::new(View(SyncBackend::new(t)))).cast()
    }

    extern "C" fn end_view(_: *mut c_void, v: *mut c_void) {
        ENDED.fetch_add(1, Ordering::SeqCst);
        // SAFETY: boxed by `begin_view`, ended once.
        drop(unsafe { Box::from_raw(v as *mut View) });
    }

    extern "C" fn clear(_: *mut c_void, v: *mut c_void) {
        view(v).clear();
    }

    extern "C" fn set_receivers(_: *mut c_void, v: *mut c_void, r: *const sc_receivers) -> i32 {
        let b = view(v);
        let receivers = if r.is_null() {
            None
        } else {
            // SAFETY: the library passes width × height depths.
            let r = unsafe { &*r };
            let rows = slice(r.depth, (r.width * r.height) as usize);
            Some(Arc::new(
                ReceiverTarget::from_rows(b.target(), rows).unwrap(),
            ))
        };
        i32::from(b.set_receivers(receivers).is_err())
    }

    fn positions(p: *const [f32; 4], n: usize) -> Arc<[glam::Vec4]> {
        slice(p, n)
            .iter()
            .map(|&a| glam::Vec4::from_array(a))
            .collect()
    }

    extern "C" fn draw(_: *mut c_void, v: *mut c_void, cmd: *const sc_draw_command) -> i32 {
        // SAFETY: the library passes a valid command.
        let c = unsafe { &*cmd };
        let d = DrawCommand {
            clip_from_local: glam::Mat4::from_cols_array(&c.clip_from_local),
            positions: positions(c.positions, c.position_count),
            triangles: slice(c.triangles, c.triangle_count).into(),
            object: c.object,
            coverage: coverage(c.coverage, c.depth_pick),
            cull: match c.cull {
                SC_CULL_BACK => CullMode::Back,
                SC_CULL_FRONT => CullMode::Front,
                _ => CullMode::None,
            },
            whole: match c.whole {
                SC_WHOLE_CONVEX => shadowcull::raster::Whole::Convex,
                SC_WHOLE_CLOSED => shadowcull::raster::Whole::Closed,
                _ => shadowcull::raster::Whole::No,
            },
        };
        i32::from(view(v).draw(d).is_err())
    }

    extern "C" fn issue_query(
        _: *mut c_void,
        v: *mut c_void,
        q: *const sc_query_command,
        id: *mut u32,
    ) -> i32 {
        // SAFETY: the library passes a valid command and id slot.
        let (q, id) = unsafe { (&*q, &mut *id) };
        let options = QueryOptions {
            coverage: coverage(q.coverage, q.depth_pick),
            mode: if q.mode == SC_QUERY_ANY {
                QueryMode::Any
            } else {
                QueryMode::Count
            },
        };
        let m = glam::Mat4::from_cols_array(&q.clip_from_local);
        let cmd = match q.kind {
            SC_QUERY_BOX => QueryCommand::Aabb {
                clip_from_local: m,
                min: q.min.into(),
                max: q.max.into(),
                options,
            },
            SC_QUERY_BOXES => QueryCommand::Aabbs {
                clip_from_local: m,
                boxes: slice(q.boxes, q.box_count)
                    .iter()
                    .map(|b| {
                        (
                            glam::Vec3::new(b[0], b[1], b[2]),
                            glam::Vec3::new(b[3], b[4], b[5]),
                        )
                    })
                    .collect(),
                options,
            },
            _ => QueryCommand::Mesh {
                clip_from_local: m,
                positions: positions(q.positions, q.position_count),
                triangles: slice(q.triangles, q.triangle_count).into(),
                options,
            },
        };
        match view(v).issue_query(cmd) {
            Ok(QueryId(i)) => {
                *id = i;
                0
            }
            Err(_) => 1,
        }
    }

    extern "C" fn poll(_: *mut c_void, v: *mut c_void, id: u32, samples: *mut u32) -> i32 {
        match view(v).poll(QueryId(id)) {
            Some(n) => {
                // SAFETY: the library passes a writable slot.
                unsafe { *samples = n };
                1
            }
            None => 0,
        }
    }

    extern "C" fn wait(_: *mut c_void, v: *mut c_void, id: u32) -> u32 {
        view(v).wait(QueryId(id))
    }

    extern "C" fn finish(_: *mut c_void, v: *mut c_void) {
        view(v).finish();
    }

    fn callbacks() -> sc_backend_callbacks {
        sc_backend_callbacks {
            struct_size: std::mem::size_of::<sc_backend_callbacks>() as u32,
            reserved: 0,
            user: std::ptr::null_mut(),
            begin_view: Some(begin_view),
            end_view: Some(end_view),
            clear: Some(clear),
            set_receivers: Some(set_receivers),
            draw: Some(draw),
            issue_query: Some(issue_query),
            poll: Some(poll),
            wait: Some(wait),
            finish: Some(finish),
        }
    }

    /// Per frame: PSR, per light (PSC, indices, mask).
    type Frame = (Vec<u64>, Vec<(Vec<u64>, Vec<u32>, Vec<u8>)>);

    fn frames(p: sc_pipeline) -> Vec<Frame> {
        let mut out = empty_output();
        (0..6)
            .map(|f| {
                ok(sc_pipeline_frame(p, &input(f), &mut out));
                let lights = slice(out.lights, out.light_count)
                    .iter()
                    .map(|l| {
                        (
                            slice(l.psc, l.psc_count).to_vec(),
                            slice(l.indices, l.index_count).to_vec(),
                            slice(l.mask, (W * H) as usize).to_vec(),
                        )
                    })
                    .collect();
                (slice(out.psr, out.psr_count).to_vec(), lights)
            })
            .collect()
    }

    #[test]
    fn host_callbacks_give_the_bundled_output() {
        let (plain, _, _) = c_pipeline();
        let (hosted, _, _) = c_pipeline();
        ok(sc_pipeline_set_backend(hosted, &callbacks()));
        let (a, b) = (frames(plain), frames(hosted));
        assert!(
            BEGUN.load(Ordering::SeqCst) >= 6 * 3,
            "eye and light views went to the host"
        );
        assert_eq!(a, b);
        // Back to the bundled rasterizer; a missing callback is refused.
        ok(sc_pipeline_set_backend(hosted, std::ptr::null()));
        let mut c = callbacks();
        c.wait = None;
        assert_eq!(
            sc_pipeline_set_backend(hosted, &c),
            sc_status::SC_INVALID_ARGUMENT
        );
        assert!(last_error().contains("callbacks.wait"), "{}", last_error());
        ok(sc_pipeline_destroy(plain));
        ok(sc_pipeline_destroy(hosted));
        assert_eq!(BEGUN.load(Ordering::SeqCst), ENDED.load(Ordering::SeqCst));
    }
}

/// Clamping through the C options (the 64-byte layout): segments come with
/// their far planes and numbers, the counters say so, the mask equals the
/// unclamped pipeline's but where the reference would call a pixel
/// ambiguous (checked in the facade's tests; here: at most 0.01% of it); a
/// bad value names its field, and a 40-byte struct means no clamping. Fill
/// accounting through `count_fill`.
#[test]
fn clamping_through_the_options() {
    use sc_status::*;
    let run = |o: &sc_pipeline_options| {
        let mut p = 0;
        ok(sc_pipeline_create(o, &mut p));
        let (pos, idx) = cube();
        let mut mesh = 0;
        ok(sc_mesh_create(p, &cube_desc(&pos, &idx), &mut mesh));
        for k in 0..OBJECTS {
            let (mut obj, m) = (0, placement(k).to_cols_array());
            ok(sc_object_create(
                p,
                mesh,
                m.as_ptr(),
                SC_FLAGS_ALL,
                &mut obj,
            ));
        }
        for l in lights() {
            let mut h = 0;
            ok(sc_light_create(p, &light_desc(&l), &mut h));
        }
        let mut out = empty_output();
        ok(sc_pipeline_frame(p, &input(2), &mut out));
        let lights = slice(out.lights, out.light_count);
        let per_light: Vec<(Vec<u8>, Vec<sc_volume_range>, sc_light_stats)> = lights
            .iter()
            .map(|l| {
                (
                    slice(l.mask, (W * H) as usize).to_vec(),
                    slice(l.ranges, l.range_count).to_vec(),
                    l.stats,
                )
            })
            .collect();
        ok(sc_pipeline_destroy(p));
        per_light
    };
    let plain = run(&c_options());
    let mut o = c_options();
    o.clamping = SC_CLAMPING_CONTINUOUS;
    o.clamping_receivers = SC_CLAMP_RECEIVERS_PSR;
    let clamped = run(&o);
    let mut fragment = o;
    fragment.clamping_receivers = SC_CLAMP_RECEIVERS_FRAGMENT;
    let clamped_fragment = run(&fragment);
    let mut discrete = c_options();
    discrete.clamping = SC_CLAMPING_DISCRETE;
    discrete.slices = 12;
    let clamped_discrete = run(&discrete);
    let mut automatic = discrete;
    automatic.clamping = SC_CLAMPING_AUTO;
    let clamped_auto = run(&automatic);
    let mut segments = 0;
    let all = (clamped.iter().chain(&clamped_fragment))
        .chain(&clamped_discrete)
        .chain(&clamped_auto);
    for ((pm, pr, _), (cm, cr, cs)) in plain.iter().cycle().zip(all) {
        assert!(pr.iter().all(|r| r.segment == 0 && r.far_plane == [0.0; 4]));
        segments += cs.segments;
        // Discrete clamping leaves a caster unclamped where the light's
        // plane cuts it: one range without planes.
        let clamped = |r: &&sc_volume_range| r.segment > 0 || r.far_plane != [0.0; 4];
        // With fragment receivers a segment comes once per band of its
        // caster: consecutive ranges that share its geometry.
        let mut cr: Vec<_> = cr.iter().filter(clamped).collect();
        assert!(cr
            .iter()
            .all(|r| r.band[0] < r.band[2] && r.band[1] < r.band[3]));
        cr.dedup_by_key(|r| r.first_index);
        assert_eq!(cs.segments as usize, cr.len());
        for (k, r) in cr.iter().enumerate() {
            // Only a caster's last segment may extrude to infinity
            // (discrete clamping, beyond a plane its rays never reach).
            let last = cr.get(k + 1).is_none_or(|n| n.segment == 0);
            assert!(
                r.far_plane != [0.0; 4] || (last && r.segment > 0),
                "a segment has its far plane"
            );
            assert_eq!(r.near_plane == [0.0; 4], r.segment == 0);
        }
        let differ = pm.iter().zip(cm).filter(|(a, b)| a != b).count();
        assert!(differ as u32 <= W * H / 10_000, "{differ} pixels differ");
    }
    assert!(segments > 0, "the cubes are clamped");
    // Fragment receivers draw the volumes in bands.
    let full = [0, 0, u32::MAX, u32::MAX];
    let banded = clamped_fragment.iter().flat_map(|(_, r, _)| r);
    assert!(banded.filter(|r| r.band != full).count() > 0, "no band");
    assert!(
        clamped_discrete.iter().any(|(_, _, s)| s.segments > 0),
        "discrete clamping cuts the cubes"
    );
    // Bad clamping fields are refused, naming the field.
    type Spoil = fn(&mut sc_pipeline_options);
    let bad_fields: [(&str, Spoil); 5] = [
        ("options.clamping_receivers", |o| o.clamping_receivers = 7),
        ("options.clamping", |o| o.clamping = 9),
        ("options.clamping", |o| o.clamping = 4),
        ("slices", |o| o.slices = 65),
        ("clamp_pixel_cost", |o| o.clamp_pixel_cost = -1.0),
    ];
    for (field, spoil) in bad_fields {
        let mut bad = c_options();
        spoil(&mut bad);
        let mut p = 0;
        assert_eq!(sc_pipeline_create(&bad, &mut p), SC_INVALID_ARGUMENT);
        assert!(last_error().contains(field), "{}", last_error());
    }
    let mut old = o;
    old.struct_size = 40;
    let before = run(&old);
    assert!(before
        .iter()
        .all(|(_, r, s)| s.segments == 0 && r.iter().all(|r| r.segment == 0)));

    // Fill accounting (the 72-byte layout): off, an `h` frame counts
    // nothing; on, it changes no mask, and the unclamped and clamped fills
    // are the same whichever variant the frame draws and whichever stencil
    // draws it (the brute-force stencil's own count is one of them).
    assert!(plain
        .iter()
        .all(|(_, _, s)| (s.bf_fill_unclamped, s.bf_fill_clamped) == (0, 0)));
    let mut f = c_options();
    f.count_fill = 1;
    let plain_counted = run(&f);
    f.clamping = SC_CLAMPING_CONTINUOUS;
    f.clamping_receivers = SC_CLAMP_RECEIVERS_PSR;
    let clamped_counted = run(&f);
    let mut b = f;
    b.stencil = SC_STENCIL_BF;
    let bf_clamped = run(&b);
    let fills = |v: &[(Vec<u8>, Vec<sc_volume_range>, sc_light_stats)]| -> Vec<(u64, u64)> {
        v.iter()
            .map(|(_, _, s)| (s.bf_fill_unclamped, s.bf_fill_clamped))
            .collect()
    };
    for (a, b) in plain.iter().zip(&plain_counted) {
        assert_eq!(a.0, b.0, "count_fill changes no mask");
    }
    let counted = fills(&plain_counted);
    assert!(counted.iter().all(|&(u, c)| u > 0 && c > 0), "{counted:?}");
    assert_eq!(fills(&clamped_counted), counted);
    assert_eq!(fills(&bf_clamped), counted);
    let mut old = f;
    old.struct_size = 64;
    assert!(run(&old)
        .iter()
        .all(|(_, _, s)| (s.bf_fill_unclamped, s.bf_fill_clamped) == (0, 0)));
}
