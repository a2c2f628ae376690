//! 8-bit stencil wrap end to end: 256 nested shadow volumes over one ground
//! region make a count of exactly 256, which an 8-bit wrapping stencil reads
//! as 0 (lit) and wide counters as 256 (shadow); every count 1..255 is shadow
//! in both, and the count 0 lit in both.

use crate::common::scene_of;
use glam::DVec3;
use scene::procedural::analytic;
use scene::{Camera, Light, Mesh, Scene, Transform};
use shadowcull::mask::{compare, Mask, PixelClass};
use shadowcull::pipeline::{eye_pass, shadow_mask, MeshCache, ShadowOptions, ShadowScratch};
use shadowcull::reference::{reference_mask, ReferenceOptions, TriangleBvh};

/// Number of stacked quads: one more would push the centre to 257 (= 1).
const QUADS: usize = 256;
/// Height of the point light above the ground's centre.
const LIGHT_Y: f64 = 50.0;
/// The camera's height: below the lowest quad, looking straight down.
const EYE_Y: f64 = 0.5;
const SIZE: u32 = 64;

/// A quad's ground footprint: the square `|x − cx|, |z − cz| < half`.
struct Footprint {
    cx: f64,
    cz: f64,
    half: f64,
}

impl Footprint {
    /// Chebyshev distance of ground point `(x, z)` from the centre.
    fn radius(&self, x: f64, z: f64) -> f64 {
        (x - self.cx).abs().max((z - self.cz).abs())
    }
}

/// The ground, then `QUADS` up-facing horizontal quads at heights
/// `1 + 0.02·k`, sized and placed so that quad `k` shadows a square of
/// half-size falling evenly from 0.45 to 0.12 whose centre wanders within
/// 0.02 of the origin: every footprint distinct, all of them overlapping
/// around the origin (count 256), and many different counts elsewhere.
/// Returns the scene and the footprints (from the quads' own f32 coordinates).
fn stack() -> (Scene, Vec<Footprint>) {
    let mut meshes: Vec<Mesh> =
        vec![analytic::horizontal_quad("ground", [-2.0, 2.0], [-2.0, 2.0], 0.0, true).unwrap()];
    let mut footprints = Vec::with_capacity(QUADS);
    for k in 0..QUADS {
        let y = (1.0 + 0.02 * k as f64) as f32;
        let half = 0.45 - 0.33 * k as f64 / (QUADS - 1) as f64;
        let (cx, cz) = (0.02 * (1.7 * k as f64).sin(), 0.02 * (2.3 * k as f64).cos());
        // Ground footprint → quad at height y: scaled by (L − y) / L toward the light's foot.
        let to_quad = (LIGHT_Y - y as f64) / LIGHT_Y;
        let x = [
            ((cx - half) * to_quad) as f32,
            ((cx + half) * to_quad) as f32,
        ];
        let z = [
            ((cz - half) * to_quad) as f32,
            ((cz + half) * to_quad) as f32,
        ];
        meshes.push(analytic::horizontal_quad(format!("quad {k}"), x, z, y, true).unwrap());
        // Back to the ground from the f32 coordinates.
        let g = |a: f32| a as f64 / to_quad;
        footprints.push(Footprint {
            cx: 0.5 * (g(x[0]) + g(x[1])),
            cz: 0.5 * (g(z[0]) + g(z[1])),
            half: 0.5 * (g(x[1]) - g(x[0])),
        });
        assert!((0.5 * (g(z[1]) - g(z[0])) - footprints[k].half).abs() < 1e-6);
    }
    (scene_of(meshes, Transform::default()), footprints)
}

fn light() -> Light {
    Light::Point {
        position: DVec3::new(0.0, LIGHT_Y, 0.0),
        range: None,
    }
}

fn camera() -> Camera {
    Camera::look_at(
        DVec3::new(0.0, EYE_Y, 0.0),
        DVec3::ZERO,
        DVec3::Z,
        90f64.to_radians(),
        1.0,
        0.05,
    )
    .unwrap()
}

fn mask(
    scene: &Scene,
    camera: &Camera,
    eye: &shadowcull::pipeline::EyePass,
    bits: raster::StencilBits,
) -> Mask {
    let opts = ShadowOptions {
        bits,
        ..Default::default()
    };
    shadow_mask(
        scene,
        camera,
        &light(),
        eye,
        &opts,
        &mut ShadowScratch::default(),
    )
    .unwrap()
    .mask
}

#[test]
fn a_count_of_256_wraps_to_lit_in_8_bits_and_stays_shadow_wide() {
    let (scene, footprints) = stack();
    let cam = camera();
    let meshes = MeshCache::new(&scene);
    let eye = eye_pass(&scene, &meshes, &cam, SIZE, SIZE).unwrap();
    let eight = mask(&scene, &cam, &eye, raster::StencilBits::Eight);
    let wide = mask(&scene, &cam, &eye, raster::StencilBits::Wide);

    // Per pixel, the exact count of footprints holding the ground point;
    // pixels within 2e-4 of a footprint edge (a pixel is 1.6e-2 wide) are
    // left out.
    let mut seen = [0usize; QUADS + 1];
    for y in 0..SIZE {
        for x in 0..SIZE {
            let d = cam.ray_direction(x as f64 + 0.5, y as f64 + 0.5, SIZE, SIZE);
            let p = cam.position + d * (EYE_Y / -d.y);
            assert!(
                eye.primitive(x, y).is_some(),
                "pixel ({x}, {y}) sees the ground"
            );
            assert_eq!(
                eye.primitive(x, y).unwrap().0.slot(),
                0,
                "only the ground is visible"
            );
            if footprints
                .iter()
                .any(|f| (f.radius(p.x, p.z) - f.half).abs() < 2e-4)
            {
                continue;
            }
            let count = footprints
                .iter()
                .filter(|f| f.radius(p.x, p.z) < f.half)
                .count();
            seen[count] += 1;
            let (e, w) = (eight.get(x, y), wide.get(x, y));
            match count {
                0 => assert!(
                    e == PixelClass::Lit && w == PixelClass::Lit,
                    "({x}, {y}) count 0: {e:?} {w:?}"
                ),
                QUADS => {
                    assert_eq!(e, PixelClass::Lit, "({x}, {y}): 256 wraps to 0 in 8 bits");
                    assert_eq!(
                        w,
                        PixelClass::Shadow,
                        "({x}, {y}): 256 is shadow in wide counters"
                    );
                }
                _ => assert!(
                    e == PixelClass::Shadow && w == PixelClass::Shadow,
                    "({x}, {y}) count {count}: {e:?} {w:?}"
                ),
            }
        }
    }
    let between = seen[1..QUADS].iter().filter(|&&n| n > 0).count();
    println!(
        "pixels: {} at 0, {} at 1..255 ({between} distinct counts), {} at 256",
        seen[0],
        seen[1..QUADS].iter().sum::<usize>(),
        seen[QUADS]
    );
    assert!(seen[QUADS] >= 100, "too few pixels with a count of 256");
    assert!(
        seen[0] >= 50 && between >= 100,
        "too few pixels with other counts"
    );

    // The reference (shadow where anything blocks) agrees with the wide
    // counters everywhere but on its own ambiguous or boundary pixels, and
    // the 8-bit mask differs from it only where it wrapped a shadow to lit.
    let r = reference_mask(
        &TriangleBvh::new(&scene),
        &cam,
        &light(),
        SIZE,
        SIZE,
        &ReferenceOptions::default(),
        Some(eye.surface()),
    );
    let c = compare(&r.mask, &r.ambiguous, &wide);
    assert_eq!(
        c.mismatches - c.mismatches_on_boundary,
        0,
        "wide vs reference: {c:?}"
    );
    let c8 = compare(&r.mask, &r.ambiguous, &eight);
    println!(
        "reference: wide {} mismatches ({} on boundary), 8-bit {}",
        c.mismatches, c.mismatches_on_boundary, c8.mismatches
    );
    assert!(
        c8.mismatches >= seen[QUADS] as u64,
        "8-bit vs reference: {c8:?}"
    );
    for &(x, y, _) in &c8.mismatch_pixels {
        assert_eq!(
            (eight.get(x, y), wide.get(x, y)),
            (PixelClass::Lit, PixelClass::Shadow),
            "8-bit differs from the reference at ({x}, {y}) other than by wrapping"
        );
    }
}
