//! Shadow masks: the four pixel classes of DESIGN.md "Masks", the unlit rule
//! every producer of masks shares, comparison against the reference, and PNG
//! output.

use crate::surface::{EyeSurface, PrimitiveId, RayPlane, RunRows};
use glam::DVec3;
use scene::{faces_light, Camera, Light, Scene};
#[cfg(feature = "images")]
use std::io::Write;
#[cfg(feature = "images")]
use std::path::Path;

/// What one pixel shows with respect to one light.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[repr(u8)]
pub enum PixelClass {
    /// The visible surface receives light.
    Lit = 0,
    /// The visible surface would receive light but something casts a shadow on it.
    Shadow = 1,
    /// The visible side of the surface gets no light from this light at all
    /// (faces away, eye and light on opposite sides, outside cone or range).
    Unlit = 2,
    /// No surface.
    Background = 3,
}

impl PixelClass {
    /// Grey level in the mask PNG: 0 lit, 255 shadow, 128 unlit, 64 background.
    pub fn grey(self) -> u8 {
        match self {
            PixelClass::Lit => 0,
            PixelClass::Shadow => 255,
            PixelClass::Unlit => 128,
            PixelClass::Background => 64,
        }
    }

    /// True for the classes that comparisons count (lit and shadow).
    pub fn is_compared(self) -> bool {
        matches!(self, PixelClass::Lit | PixelClass::Shadow)
    }
}

/// True when the visible side of the surface triangle `tri` (world space,
/// counter-clockwise front) at `point`, seen from `eye`, gets no light from
/// `light`: the triangle does not face the light, or eye and light lie on
/// opposite sides of its plane, or `point` is outside the light's cone or
/// range. With `two_sided`, only the last two tests apply.
///
/// The reference and the stencil mask assembly both call this, with the same
/// inputs, so the unlit class never differs between them.
pub fn is_unlit(
    tri: &[DVec3; 3],
    eye: DVec3,
    light: &Light,
    point: DVec3,
    two_sided: bool,
) -> bool {
    !light.reaches(point) || unlit_by_facing(tri, eye, light, two_sided)
}

/// The part of [`is_unlit`] that does not depend on the surface point: the
/// triangle's facing to the light and the eye.
pub(crate) fn unlit_by_facing(
    tri: &[DVec3; 3],
    eye: DVec3,
    light: &Light,
    two_sided: bool,
) -> bool {
    if two_sided {
        let [a, b, c] = *tri;
        let n = (b - a).cross(c - a);
        let eye_side = n.dot(eye - a);
        let light_side = match light.position() {
            Some(l) => n.dot(l - a),
            None => n.dot(light.toward_light(a)),
        };
        // Light in the plane, or eye and light on opposite sides: unlit.
        light_side == 0.0 || eye_side * light_side < 0.0
    } else {
        if !faces_light(tri, light) {
            return true;
        }
        let [a, b, c] = *tri;
        let n = (b - a).cross(c - a);
        // The light is on the front side; the eye must be too.
        n.dot(eye - a) <= 0.0
    }
}

/// The view a mask is assembled for: the camera and the image it renders,
/// `width × height` pixels, row 0 at the top, pixel centres at +0.5.
#[derive(Clone, Copy, Debug)]
pub struct View<'a> {
    /// The eye.
    pub camera: &'a Camera,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

/// Assembles the four-class mask from the raw stencil and the eye pass's
/// visible surface's primitive ids (DESIGN.md "Masks") for `view`: background where no
/// primitive; unlit where [`is_unlit`] says so for the visible triangle (world
/// space, from [`Scene::world_triangle`]) at the pixel's surface point (the
/// pixel-centre eye ray meeting that triangle's plane, in f64); otherwise
/// shadow where `shadowed(pixel)` (stencil ≠ 0) and the object receives shadows
/// ([`scene::ObjectFlags::receives`]), else lit. `two_sided`: every triangle
/// casts, as in [`is_unlit`].
///
/// # Panics
/// If `surface` is not `view.width × view.height` or names an object or
/// triangle not in `scene`.
pub fn assemble(
    scene: &Scene,
    view: View<'_>,
    light: &Light,
    surface: EyeSurface<'_>,
    shadowed: impl Fn(usize) -> bool + Sync,
    two_sided: bool,
) -> Mask {
    let mut mask = Mask::filled(0, 0, PixelClass::Background);
    assemble_into(scene, view, light, surface, shadowed, two_sided, &mut mask);
    mask
}

/// [`assemble`] into `mask`, whose pixel buffer is reused (the per-band run
/// buffers are made per call; the pipeline keeps its own).
///
/// # Panics
/// As [`assemble`].
pub fn assemble_into(
    scene: &Scene,
    view: View<'_>,
    light: &Light,
    surface: EyeSurface<'_>,
    shadowed: impl Fn(usize) -> bool + Sync,
    two_sided: bool,
    mask: &mut Mask,
) {
    let (mut decides, mut runs) = (Vec::new(), Vec::new());
    let mask_in = MaskInput {
        scene,
        view,
        light,
        surface,
        two_sided,
    };
    classify_runs(mask_in, mask, &mut decides, &mut runs);
    apply_stencil(mask, &decides, shadowed);
}

/// What [`classify_runs`] reads.
pub(crate) struct MaskInput<'a> {
    pub scene: &'a Scene,
    pub view: View<'a>,
    pub light: &'a Light,
    pub surface: EyeSurface<'a>,
    pub two_sided: bool,
}

/// One visible triangle's part of the mask rule, found once per run, or
/// taken from the run of the same triangle in the row above.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TriangleFacts {
    /// Unlit by its facing (or the eye and light on opposite sides).
    unlit: bool,
    /// Its object receives shadows.
    receives: bool,
    /// Its plane seen from the eye, where the light's reach depends on the
    /// surface point (spot and ranged point lights).
    plane: Option<RayPlane>,
}

/// Rows per band of [`classify_runs`]' parallel work.
const MASK_BAND_ROWS: usize = 16;

/// The mask's classes that do not depend on the stencil, before it runs:
/// background, unlit ([`is_unlit`]), and lit for every other pixel, with
/// `decides[pixel]` (row-major) set where the stencil decides between lit
/// and shadow: the pixel's object receives shadows and the light reaches
/// its surface. Returns whether some non-background pixel is left to its
/// class (the stencil can skip it: the computation mask of
/// [`crate::pipeline::stencil`]).
///
/// The rule is found once per visible triangle (per run of its pixels),
/// and per pixel only where the light's reach depends on the point (spot
/// and ranged point lights).
pub(crate) fn classify_runs(
    input: MaskInput<'_>,
    mask: &mut Mask,
    decides: &mut Vec<bool>,
    runs: &mut Vec<RunRows<TriangleFacts>>,
) -> bool {
    let MaskInput {
        scene,
        view,
        light,
        surface,
        two_sided,
    } = input;
    let View {
        camera,
        width,
        height,
    } = view;
    assert!(surface.fits(width, height), "primitive ids size");
    (mask.width, mask.height) = (width, height);
    let n = width as usize * height as usize;
    mask.pixels.clear();
    mask.pixels.resize(n, PixelClass::Background);
    decides.clear();
    decides.resize(n, false);
    let rays = camera.rays(width, height);
    // Only spot lights and ranged point lights depend on the surface point.
    let everywhere = matches!(
        light,
        Light::Point { range: None, .. } | Light::Directional { .. }
    );
    let e = camera.position;
    let w = width as usize;
    let facts = |id: PrimitiveId| {
        let tri = scene.world_triangle(id.0, id.1 as usize);
        TriangleFacts {
            unlit: unlit_by_facing(&tri, e, light, two_sided),
            receives: scene.object(id.0).flags.receives,
            plane: (!everywhere).then(|| RayPlane::new(&tri, e)),
        }
    };
    // Per band: its rows' classes and stencil pixels; whether it left a
    // visible pixel to its class.
    let band = |b: usize,
                (out, dec): (&mut [PixelClass], &mut [bool]),
                runs: &mut RunRows<TriangleFacts>| {
        let y0 = b * MASK_BAND_ROWS;
        let rows = y0 as u32..(y0 + out.len() / w) as u32;
        let mut left = false;
        surface.for_each_run_in_rows(rows, runs, facts, |y, x0, x1, _, f| {
            let (y, x0, x1) = (y as usize, x0 as usize, x1 as usize);
            let at = (y - y0) * w;
            let (out, dec) = (&mut out[at + x0..at + x1], &mut dec[at + x0..at + x1]);
            if f.unlit {
                out.fill(PixelClass::Unlit);
                left = true;
                return;
            }
            let Some(plane) = f.plane else {
                out.fill(PixelClass::Lit);
                dec.fill(f.receives);
                left |= !f.receives;
                return;
            };
            // The light's reach depends on the point: per pixel.
            for (k, (px, d)) in out.iter_mut().zip(dec.iter_mut()).enumerate() {
                let x = x0 + k;
                let dir = rays.direction(x as f64 + 0.5, y as f64 + 0.5);
                let reached = light.reaches(plane.point_or_origin(e, dir));
                *px = if reached {
                    PixelClass::Lit
                } else {
                    PixelClass::Unlit
                };
                *d = reached && f.receives;
                left |= !*d;
            }
        });
        left
    };
    use rayon::prelude::*;
    let rows = (w * MASK_BAND_ROWS).max(1);
    runs.resize_with((height as usize).div_ceil(MASK_BAND_ROWS), Default::default);
    mask.pixels
        .par_chunks_mut(rows)
        .zip(decides.par_chunks_mut(rows))
        .zip(runs.par_iter_mut())
        .enumerate()
        .map(|(b, (parts, runs))| band(b, parts, runs))
        .reduce(|| false, |a, b| a | b)
}

/// The stencil's share of the mask: every pixel it decides
/// ([`classify_runs`]) is shadow where `shadowed(pixel)` (stencil ≠ 0).
pub(crate) fn apply_stencil(
    mask: &mut Mask,
    decides: &[bool],
    shadowed: impl Fn(usize) -> bool + Sync,
) {
    use rayon::prelude::*;
    const CHUNK: usize = 1 << 14;
    mask.pixels
        .par_chunks_mut(CHUNK)
        .zip(decides.par_chunks(CHUNK))
        .enumerate()
        .for_each(|(c, (out, dec))| {
            for (k, (px, &d)) in out.iter_mut().zip(dec).enumerate() {
                if d && shadowed(c * CHUNK + k) {
                    *px = PixelClass::Shadow;
                }
            }
        });
}

/// A per-pixel classification, row 0 at the top.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mask {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height` classes, row-major from the top row.
    pub pixels: Vec<PixelClass>,
}

/// Counts of pixels per class.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ClassCounts {
    /// Lit pixels.
    pub lit: u64,
    /// Shadowed pixels.
    pub shadow: u64,
    /// Unlit pixels.
    pub unlit: u64,
    /// Background pixels.
    pub background: u64,
}

impl Mask {
    /// A mask of one class.
    pub fn filled(width: u32, height: u32, class: PixelClass) -> Self {
        Mask {
            width,
            height,
            pixels: vec![class; width as usize * height as usize],
        }
    }

    /// The class at `(x, y)`.
    pub fn get(&self, x: u32, y: u32) -> PixelClass {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// Pixels per class.
    pub fn counts(&self) -> ClassCounts {
        let mut c = ClassCounts::default();
        for p in &self.pixels {
            match p {
                PixelClass::Lit => c.lit += 1,
                PixelClass::Shadow => c.shadow += 1,
                PixelClass::Unlit => c.unlit += 1,
                PixelClass::Background => c.background += 1,
            }
        }
        c
    }

    /// True when a 4-neighbour of `(x, y)` has a different class.
    pub fn is_boundary(&self, x: u32, y: u32) -> bool {
        let c = self.get(x, y);
        let (w, h) = (self.width as i64, self.height as i64);
        [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)]
            .iter()
            .any(|(dx, dy)| {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                nx >= 0 && ny >= 0 && nx < w && ny < h && self.get(nx as u32, ny as u32) != c
            })
    }

    #[cfg(feature = "images")]
    /// Writes the mask as an 8-bit greyscale PNG (0 lit, 255 shadow, 128 unlit,
    /// 64 background; row 0 at the top).
    ///
    /// # Errors
    /// I/O or encoding errors.
    pub fn write_png(&self, path: &Path) -> std::io::Result<()> {
        let grey: Vec<u8> = self.pixels.iter().map(|p| p.grey()).collect();
        write_png(
            path,
            self.width,
            self.height,
            png::ColorType::Grayscale,
            &grey,
        )
    }
}

/// The result of comparing a mask with the reference over lit/shadow pixels.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Comparison {
    /// Pixels compared: the reference says lit or shadow, and the pixel is not ambiguous.
    pub compared: u64,
    /// Compared pixels where the mask differs from the reference.
    pub mismatches: u64,
    /// Mismatches on a reference shadow boundary (a 4-neighbour classified differently).
    pub mismatches_on_boundary: u64,
    /// Lit/shadow reference pixels left out because they are ambiguous.
    pub ambiguous: u64,
    /// The mismatched pixels `(x, y, on_boundary)`, row-major order.
    pub mismatch_pixels: Vec<(u32, u32, bool)>,
}

/// Compares `mask` with `reference` over the reference's lit and shadow pixels,
/// skipping those flagged in `ambiguous` (same size, row-major).
///
/// # Panics
/// If the sizes differ (both come from the same job).
pub fn compare(reference: &Mask, ambiguous: &[bool], mask: &Mask) -> Comparison {
    assert_eq!(
        (reference.width, reference.height),
        (mask.width, mask.height),
        "mask sizes differ"
    );
    assert_eq!(
        ambiguous.len(),
        reference.pixels.len(),
        "ambiguity flags size differs"
    );
    let mut out = Comparison::default();
    for y in 0..reference.height {
        for x in 0..reference.width {
            let i = y as usize * reference.width as usize + x as usize;
            let r = reference.pixels[i];
            if !r.is_compared() {
                continue;
            }
            if ambiguous[i] {
                out.ambiguous += 1;
                continue;
            }
            out.compared += 1;
            if mask.pixels[i] != r {
                let b = reference.is_boundary(x, y);
                out.mismatches += 1;
                out.mismatches_on_boundary += b as u64;
                out.mismatch_pixels.push((x, y, b));
            }
        }
    }
    out
}

#[cfg(feature = "images")]
/// Writes an 8-bit greyscale image (`width × height` bytes, row 0 at the top) as a PNG file.
///
/// # Errors
/// I/O and encoder errors; a pixel count other than `width × height`.
pub fn write_grey_png(path: &Path, width: u32, height: u32, grey: &[u8]) -> std::io::Result<()> {
    write_png(path, width, height, png::ColorType::Grayscale, grey)
}

#[cfg(feature = "images")]
/// Writes 8-bit pixels as a PNG file.
pub(crate) fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    color: png::ColorType,
    data: &[u8],
) -> std::io::Result<()> {
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, width, height);
        enc.set_color(color);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().map_err(std::io::Error::other)?;
        w.write_image_data(data).map_err(std::io::Error::other)?;
    }
    let mut f = std::fs::File::create(path)?;
    f.write_all(&bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compare_counts_mismatches_and_boundaries() {
        let mut r = Mask::filled(4, 1, PixelClass::Lit);
        r.pixels[2] = PixelClass::Shadow;
        r.pixels[3] = PixelClass::Background;
        let mut m = r.clone();
        m.pixels[0] = PixelClass::Shadow; // interior mismatch
        m.pixels[1] = PixelClass::Shadow; // next to the reference boundary
        m.pixels[3] = PixelClass::Lit; // background is never compared
        let c = compare(&r, &[false; 4], &m);
        assert_eq!(c.compared, 3);
        assert_eq!(c.mismatches, 2);
        assert_eq!(c.mismatches_on_boundary, 1);
        let c = compare(&r, &[true, false, false, false], &m);
        assert_eq!((c.compared, c.mismatches, c.ambiguous), (2, 1, 1));
    }

    #[test]
    fn unlit_rule() {
        let up = [DVec3::ZERO, DVec3::new(0.0, 0.0, -1.0), DVec3::X]; // normal... check
        let n = (up[1] - up[0]).cross(up[2] - up[0]);
        let (tri, eye_above) = if n.y > 0.0 {
            (up, DVec3::Y)
        } else {
            ([up[0], up[2], up[1]], DVec3::Y)
        };
        let light = Light::Point {
            position: DVec3::new(0.1, 4.0, -0.1),
            range: None,
        };
        let p = DVec3::new(0.2, 0.0, -0.2);
        assert!(!is_unlit(&tri, eye_above, &light, p, false));
        assert!(is_unlit(&tri, -eye_above, &light, p, false), "eye below");
        let below = Light::Point {
            position: DVec3::new(0.1, -4.0, -0.1),
            range: None,
        };
        assert!(is_unlit(&tri, eye_above, &below, p, false));
        // Two-sided: the back side is lit when eye and light are both below.
        assert!(!is_unlit(&tri, -eye_above, &below, p, true));
        assert!(is_unlit(&tri, eye_above, &below, p, true));
        let short = Light::Point {
            position: DVec3::new(0.1, 4.0, -0.1),
            range: Some(1.0),
        };
        assert!(is_unlit(&tri, eye_above, &short, p, false));
    }
}
