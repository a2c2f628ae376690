//! Drives the C ABI's entry points with arbitrary struct contents and handle
//! values: any status is fine, `SC_INTERNAL` (a caught panic) and a crash
//! are findings. Pointers stay valid (the contract every C caller keeps); the
//! counts they come with and everything else are arbitrary.

use shadowcull_c::*;

/// Reads the fuzzer's bytes as values.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        let (b, rest) = self.0.split_first().map_or((0, &[][..]), |(b, r)| (*b, r));
        self.0 = rest;
        b
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }
    fn u64(&mut self) -> u64 {
        u64::from(self.u32()) | (u64::from(self.u32()) << 32)
    }
    fn f64(&mut self) -> f64 {
        // Mostly small values, sometimes any bit pattern (NaN, ∞, huge).
        match self.u8() % 4 {
            0 => f64::from_bits(self.u64()),
            _ => f64::from(self.u8() as i8) * 0.25,
        }
    }
    fn handle(&mut self, known: &[u64]) -> u64 {
        match self.u8() % 4 {
            0 => self.u64(),
            _ if known.is_empty() => 0,
            _ => known[self.u8() as usize % known.len()],
        }
    }
}

fn check(s: sc_status) {
    assert_ne!(s, sc_status::SC_INTERNAL, "a caught panic");
}

/// One fuzz input through the target (a panic is a finding).
pub fn run(data: &[u8]) {
    let mut b = Bytes(data);
    let (mut pipelines, mut meshes, mut objects, mut lights) = (vec![], vec![], vec![], vec![]);
    let mut opts = std::mem::MaybeUninit::<sc_pipeline_options>::uninit();
    check(sc_pipeline_options_default(opts.as_mut_ptr()));
    // SAFETY: filled by the call above.
    let base = unsafe { opts.assume_init() };
    for _ in 0..64 {
        if b.0.is_empty() {
            break;
        }
        match b.u8() % 14 {
            0 => {
                let mut o = base;
                let size = if b.u8() % 4 == 0 {
                    b.u32() % 64
                } else {
                    o.struct_size
                };
                o.struct_size = size;
                o.culling = b.u32() % 6;
                o.stencil = b.u32() % 4;
                o.coverage = b.u32() % 3;
                o.query_threshold = b.u32() % 4;
                o.light_resolution = b.u32() % 130;
                o.threads = 0;
                o.two_sided = b.u32() % 2;
                // The struct in a buffer of its declared size (the contract):
                // past ours, zeros or fuzz bytes.
                let ours = std::mem::size_of::<sc_pipeline_options>();
                let mut buf = vec![0u64; (size as usize).max(ours).div_ceil(8)];
                let extra = b.u8() % 2 == 1;
                // SAFETY: `buf` holds at least `ours` bytes, 8-aligned.
                unsafe {
                    std::ptr::copy_nonoverlapping(
                        &o as *const _ as *const u8,
                        buf.as_mut_ptr().cast(),
                        ours,
                    );
                    let bytes = std::slice::from_raw_parts_mut(
                        buf.as_mut_ptr().cast::<u8>(),
                        buf.len() * 8,
                    );
                    for x in bytes[ours..].iter_mut() {
                        *x = if extra { b.u8() } else { 0 };
                    }
                }
                let mut h = 0;
                check(sc_pipeline_create(buf.as_ptr().cast(), &mut h));
                if h != 0 {
                    pipelines.push(h);
                }
            }
            1 => {
                let p = b.handle(&pipelines);
                let n = (b.u8() % 12) as usize;
                let pos: Vec<f64> = (0..3 * n + 3).map(|_| b.f64()).collect();
                let idx: Vec<u32> = (0..(b.u8() % 13) as usize).map(|_| b.u32() % 14).collect();
                let d = sc_mesh_desc {
                    struct_size: std::mem::size_of::<sc_mesh_desc>() as u32,
                    position_type: SC_F64,
                    position_stride: 24,
                    vertex_count: n as u32,
                    positions: pos.as_ptr().cast(),
                    index_type: SC_U32,
                    index_count: idx.len() as u32,
                    indices: idx.as_ptr().cast(),
                };
                let mut m = 0;
                check(sc_mesh_create(p, &d, &mut m));
                if m != 0 {
                    meshes.push(m);
                }
            }
            2 => {
                let (p, m) = (b.handle(&pipelines), b.handle(&meshes));
                let mat: Vec<f64> = (0..16).map(|_| b.f64()).collect();
                let mut o = 0;
                check(sc_object_create(p, m, mat.as_ptr(), b.u32() % 17, &mut o));
                if o != 0 {
                    objects.push(o);
                }
            }
            3 => {
                let (p, o) = (b.handle(&pipelines), b.handle(&objects));
                let mat: Vec<f64> = (0..16).map(|_| b.f64()).collect();
                check(sc_object_set_transform(p, o, mat.as_ptr()));
            }
            4 => {
                let (p, o) = (b.handle(&pipelines), b.handle(&objects));
                check(sc_object_destroy(p, o));
            }
            5 => {
                let p = b.handle(&pipelines);
                let d = sc_light_desc {
                    struct_size: std::mem::size_of::<sc_light_desc>() as u32,
                    kind: b.u32() % 4,
                    position: [b.f64(), b.f64(), b.f64()],
                    direction: [b.f64(), b.f64(), b.f64()],
                    apex_angle: b.f64(),
                    range: b.f64(),
                };
                let mut l = 0;
                check(sc_light_create(p, &d, &mut l));
                if l != 0 {
                    lights.push(l);
                }
            }
            6 => {
                let (p, l) = (b.handle(&pipelines), b.handle(&lights));
                check(sc_light_destroy(p, l));
            }
            7 | 8 => {
                let p = b.handle(&pipelines);
                let mut i = sc_frame_input {
                    struct_size: std::mem::size_of::<sc_frame_input>() as u32,
                    width: b.u32() % 48,
                    height: b.u32() % 48,
                    clip_depth: b.u32() % 3,
                    view: [0.0; 16],
                    projection: [0.0; 16],
                    host_depth: std::ptr::null(),
                    host_depth_width: 0,
                    host_depth_height: 0,
                    near: 0.0,
                    anamorphic: b.u32() % 3,
                };
                for v in i.view.iter_mut().chain(i.projection.iter_mut()) {
                    *v = b.f64();
                }
                if b.u8() % 2 == 0 {
                    // A plausible camera: identity view, a GL perspective.
                    i.view = [
                        1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., -1., -8., 1.,
                    ];
                    i.projection = [
                        1., 0., 0., 0., 0., 1., 0., 0., 0., 0., -1.002, -1., 0., 0., -0.2002, 0.,
                    ];
                }
                // Now and then a host depth of any size and values.
                let depth: Vec<f32> = match b.u8() % 4 {
                    0 => {
                        i.host_depth_width = b.u32() % 48;
                        i.host_depth_height = b.u32() % 48;
                        let n = (i.host_depth_width * i.host_depth_height) as usize;
                        (0..n).map(|_| b.f64() as f32).collect()
                    }
                    _ => Vec::new(),
                };
                if !depth.is_empty() {
                    i.host_depth = depth.as_ptr();
                }
                // SAFETY: plain data; zero is a valid value of every field.
                let mut out: sc_frame_output = unsafe { std::mem::zeroed() };
                out.struct_size = std::mem::size_of::<sc_frame_output>() as u32;
                check(sc_pipeline_frame(p, &i, &mut out));
            }
            9 => {
                let (p, m) = (b.handle(&pipelines), b.handle(&meshes));
                check(sc_mesh_destroy(p, m));
            }
            10 => {
                let (p, o) = (b.handle(&pipelines), b.handle(&objects));
                match b.u32() % 24 {
                    f @ 0..20 => check(sc_object_set_flags(p, o, f)),
                    _ => check(sc_object_set_occluder(p, o, b.handle(&meshes))),
                }
            }
            11 => {
                let p = b.handle(&pipelines);
                check(sc_pipeline_set_frame_number(p, b.u32()));
            }
            12 => {
                let p = b.handle(&pipelines);
                check(sc_pipeline_reset_history(p));
            }
            _ => {
                let p = b.handle(&pipelines);
                check(sc_pipeline_destroy(p));
            }
        }
    }
    for p in pipelines {
        check(sc_pipeline_destroy(p));
    }
}
