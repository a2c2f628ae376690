//! The stencil stage [Aila04 §3–4, EK]: one light's shadow volumes drawn
//! into a brute-force, hierarchical or hybrid stencil on the eye depth
//! buffer, and the raw stencil plus the primitive ids assembled into the
//! four-class mask ([`crate::mask::assemble`]).

use super::eye::EyePass;
use super::shadow_options::ShadowInput;
pub use super::shadow_options::{Backend, ShadowOptions};
use super::shadowable::ShadowableScratch;
use super::volume::{build_for, VolumeScratch};
use crate::mask::{apply_stencil, classify_runs, Mask, MaskInput, PixelClass, TriangleFacts, View};
use crate::Result;
use raster::{HierarchicalOptions, HierarchicalStencil, StencilStats, StencilTarget, TileClass};
use scene::{Camera, Light, ObjectId, Scene};
use shadowgen::VolumeStats;

/// The tile classification of a hierarchical frame ([Aila04 Fig. 1]).
#[derive(Clone, Debug, PartialEq)]
pub struct TileImage {
    /// Tile side in pixels.
    pub tile: u32,
    /// Tiles across and down.
    pub tiles_x: u32,
    /// Tiles down.
    pub tiles_y: u32,
    /// Row-major classes.
    pub classes: Vec<TileClass>,
}

impl TileImage {
    /// RGB pixels of a `width × height` image: every pixel takes its tile's
    /// colour — lit white, shadow dark blue, boundary orange, background black.
    pub fn rgb(&self, width: u32, height: u32) -> Vec<u8> {
        let mut out = Vec::with_capacity((width * height * 3) as usize);
        for y in 0..height {
            for x in 0..width {
                let c = self.classes[((y / self.tile) * self.tiles_x + x / self.tile) as usize];
                out.extend_from_slice(match c {
                    TileClass::Background => &[0, 0, 0],
                    TileClass::Lit => &[235, 235, 235],
                    TileClass::Shadow => &[40, 60, 140],
                    TileClass::Boundary => &[245, 150, 40],
                });
            }
        }
        out
    }
}

/// The shadow stage's output for one light.
#[derive(Clone, Debug)]
pub struct ShadowFrame {
    /// The four-class mask.
    pub mask: Mask,
    /// Volume construction counters.
    pub volumes: VolumeStats,
    /// Volume triangles drawn.
    pub volume_triangles: u64,
    /// Stencil counters.
    pub stencil: StencilStats,
    /// Per pixel (row-major, row 0 at the top): the raw stencil is non-zero.
    /// The brute-force and hierarchical stencils draw only at the pixels
    /// whose class they decide (receivers the light reaches, the
    /// computation mask of `shadowable.rs`); it is false at every other.
    pub raw_nonzero: Vec<bool>,
    /// Wall time of the stencil stage: clearing, every volume drawn (for the
    /// hierarchical backend its tile bounds, both stages), the resolve, mask
    /// assembly (ms).
    pub stencil_ms: f64,
    /// The hierarchical backend's tile classification.
    pub tiles: Option<TileImage>,
    /// Hybrid: pixels left to the volumes (the shadow map's silhouette pixels).
    pub silhouette_pixels: u64,
    /// Hybrid: shadow-map rendering (its own maps only) and classification
    /// (ms), inside `stencil_ms`.
    pub map_ms: f64,
}

/// Scratch kept across frames: the volume stage's (silhouette cache, volume
/// buffer, clamping state) and the stencil targets.
#[derive(Default)]
pub struct ShadowScratch {
    pub(crate) volume: VolumeScratch,
    /// Fill accounting's (`count_fill`) other variant and stencil.
    pub(crate) fill: super::fill_count::FillScratch,
    /// The stencil targets (each light of a pipeline has its own: the
    /// lights are stenciled side by side).
    pub(crate) targets: StencilTargets,
    /// Per volume range its clip matrix, and the (matrix, range) list the
    /// stencil draws (kept empty between frames).
    clip: Vec<glam::Mat4>,
    ranges: Vec<(glam::Mat4, &'static raster::VolumeRange)>,
    /// The mask assembly's run buffers, one per band of rows.
    runs: Vec<crate::surface::RunRows<TriangleFacts>>,
    /// The classes of [`computation_mask`] (which no stencil reads).
    classes: Option<Mask>,
    /// The computation mask and the masked eye depth the brute-force and
    /// hierarchical stencils draw on.
    pub(crate) shadowable: ShadowableScratch,
}

/// The stencil stage's targets, cleared for every frame.
#[derive(Default)]
pub(crate) struct StencilTargets {
    stencil: Option<StencilTarget>,
    hierarchical: Option<HierarchicalStencil>,
}

impl std::fmt::Debug for ShadowScratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ShadowScratch")
            .field("volume_ranges", &self.volume.buffer.ranges.len())
            .finish_non_exhaustive()
    }
}

/// Builds every object's shadow volume for `light`, stencils them on the eye
/// depth buffer and assembles the mask.
///
/// # Errors
/// Invalid light ([`crate::Error::Shadowgen`]) or rasterizer errors.
pub fn shadow_mask(
    scene: &Scene,
    camera: &Camera,
    light: &Light,
    eye: &EyePass,
    options: &ShadowOptions,
    scratch: &mut ShadowScratch,
) -> Result<ShadowFrame> {
    let casters: Vec<ObjectId> = (0..scene.objects().len() as u32)
        .map(ObjectId::from_slot)
        .collect();
    shadow_mask_for(scene, camera, light, eye, options, scratch, &casters)
}

/// [`shadow_mask`] with shadow volumes for `casters` only (the potential
/// shadow casters of the light pass).
///
/// # Errors
/// As [`shadow_mask`]; also a caster id outside the scene.
pub fn shadow_mask_for(
    scene: &Scene,
    camera: &Camera,
    light: &Light,
    eye: &EyePass,
    options: &ShadowOptions,
    scratch: &mut ShadowScratch,
    casters: &[ObjectId],
) -> Result<ShadowFrame> {
    let viewport = (eye.target.width(), eye.target.height());
    let input = ShadowInput {
        scene,
        camera,
        light,
    };
    let volumes = build_for(
        input,
        casters,
        options,
        viewport,
        None,
        None,
        &mut scratch.volume,
    )?;
    stencil_volumes(input, eye, options, scratch, volumes, None, None)
}

/// The stencil stage alone: draws the volumes already in `scratch` (built by
/// [`super::volume::build_for`], whose counters `volumes` are) with
/// `options.backend` and assembles the mask; `previous` (the last frame's
/// output) lends its buffers. The hybrid reads its shadow maps from
/// `light_views` (this frame's light views with their kept depth,
/// [`crate::hybrid::classify_with_views`]) when given, else renders its own
/// ([`crate::hybrid::classify`]).
///
/// # Errors
/// Rasterizer errors; for the hybrid, an invalid light.
pub(crate) fn stencil_volumes(
    input: ShadowInput<'_>,
    eye: &EyePass,
    options: &ShadowOptions,
    scratch: &mut ShadowScratch,
    volumes: VolumeStats,
    previous: Option<ShadowFrame>,
    light_views: Option<&[(&visibility::LightView, &raster::DepthTarget)]>,
) -> Result<ShadowFrame> {
    let ShadowInput {
        scene,
        camera,
        light,
    } = input;
    let (w, h) = (eye.target.width(), eye.target.height());
    let t = std::time::Instant::now();
    scratch.shadowable.forget();
    let mut stats = StencilStats::default();
    let tests = raster::StencilTests {
        scissor: options.scissor,
        depth_bounds: options.depth_bounds,
    };
    // As long as the volume buffer's range list (no growth of their own).
    let n = scratch.volume.buffer.ranges.capacity();
    scratch.clip.clear();
    scratch.clip.reserve(n);
    scratch.clip.extend(
        scratch
            .volume
            .buffer
            .ranges
            .iter()
            .map(|r| scene::transform::clip_from_local(camera, &r.world_from_local)),
    );
    let mut ranges: Vec<(glam::Mat4, &raster::VolumeRange)> =
        recycle(std::mem::take(&mut scratch.ranges));
    ranges.reserve(n);
    ranges.extend(
        scratch
            .clip
            .iter()
            .copied()
            .zip(&scratch.volume.buffer.ranges),
    );
    let (mut mask, mut raw_nonzero, mut tiles) = match previous {
        Some(p) => (p.mask, p.raw_nonzero, p.tiles),
        None => (Mask::filled(0, 0, PixelClass::Background), Vec::new(), None),
    };
    // The classes the stencil does not decide, and the pixels it does.
    let mask_in = MaskInput {
        scene,
        view: View {
            camera,
            width: w,
            height: h,
        },
        light,
        surface: eye.surface(),
        two_sided: options.two_sided,
    };
    let left = classify_runs(
        mask_in,
        &mut mask,
        &mut scratch.shadowable.decides,
        &mut scratch.runs,
    );
    let (mut silhouette_pixels, mut map_ms) = (0, 0.0);
    match options.backend {
        Backend::Brute => {
            tiles = None;
            let mut stencil = match scratch.targets.stencil.take() {
                Some(mut s) if (s.width(), s.height(), s.bits()) == (w, h, options.bits) => {
                    s.clear();
                    s
                }
                _ => StencilTarget::new(w, h, options.bits)?,
            };
            scratch.shadowable.mask(&eye.target, left)?;
            let on = scratch.shadowable.target(&eye.target);
            stencil.draw_volumes(on, &ranges, &scratch.volume.buffer, tests, &mut stats)?;
            stencil.resolve(on, &mut raw_nonzero, &mut stats)?;
            scratch.targets.stencil = Some(stencil);
        }
        Backend::Hierarchical { tile, full_shadow } => {
            let want = HierarchicalOptions {
                tile,
                bits: options.bits,
                full_shadow,
            };
            let mut stencil = match scratch.targets.hierarchical.take() {
                Some(mut s) if (s.width(), s.height(), s.options()) == (w, h, want) => {
                    s.clear();
                    s
                }
                _ => HierarchicalStencil::new(w, h, want)?,
            };
            scratch.shadowable.mask(&eye.target, left)?;
            let on = scratch.shadowable.target(&eye.target);
            stencil.draw_volumes(on, &ranges, &scratch.volume.buffer, tests, &mut stats)?;
            stencil.resolve(on, &mut raw_nonzero, &mut stats)?;
            let (tiles_x, tiles_y) = stencil.tile_counts();
            let mut classes = tiles.take().map(|t| t.classes).unwrap_or_default();
            stencil.tile_classes_into(&mut classes);
            tiles = Some(TileImage {
                tile: tile.pixels(),
                tiles_x,
                tiles_y,
                classes,
            });
            scratch.targets.hierarchical = Some(stencil);
        }
        Backend::Hybrid { map_size } => {
            tiles = None;
            let class = match light_views {
                Some(views) => crate::hybrid::classify_with_views(
                    scene,
                    camera,
                    light,
                    eye.surface(),
                    (w, h),
                    views,
                    options.two_sided,
                )?,
                None => crate::hybrid::classify(
                    scene,
                    camera,
                    light,
                    eye.surface(),
                    (w, h),
                    map_size,
                    options.two_sided,
                )?,
            };
            // The computation mask: volumes see only the silhouette pixels'
            // depth, and the fill skips every tile without one (its depth
            // box is empty), as a GPU's hierarchical z rejects them
            // [ChanDurand04]. Brute force with each volume's scissor
            // rectangle and depth bounds: on the sparse mask it tests
            // 1.5-2x faster than the hierarchical stencil (city bird).
            let mut masked = eye.target.clone();
            masked.keep_only(&class.silhouette)?;
            let mut stencil = match scratch.targets.stencil.take() {
                Some(mut s) if (s.width(), s.height(), s.bits()) == (w, h, options.bits) => {
                    s.clear();
                    s
                }
                _ => StencilTarget::new(w, h, options.bits)?,
            };
            let tests = raster::StencilTests {
                scissor: true,
                depth_bounds: true,
            };
            stencil.draw_volumes(&masked, &ranges, &scratch.volume.buffer, tests, &mut stats)?;
            stencil.resolve(&masked, &mut raw_nonzero, &mut stats)?;
            scratch.targets.stencil = Some(stencil);
            for (i, r) in raw_nonzero.iter_mut().enumerate() {
                if !class.silhouette[i] {
                    *r = class.shadowed[i];
                }
            }
            silhouette_pixels = class.silhouette_pixels;
            map_ms = class.map_ms;
        }
    }
    scratch.ranges = recycle(ranges);
    let volume_triangles = stats.triangles;
    apply_stencil(&mut mask, &scratch.shadowable.decides, |i| raw_nonzero[i]);
    Ok(ShadowFrame {
        mask,
        volumes,
        volume_triangles,
        stencil: stats,
        raw_nonzero,
        stencil_ms: t.elapsed().as_secs_f64() * 1e3,
        tiles,
        silhouette_pixels,
        map_ms,
    })
}

/// The computation mask of `input.light` on `eye` when the frame's stencil
/// stage made none (no stencil, or the hybrid's): what `count_fill` counts
/// brute-force pixels on, as the brute-force stencil would draw them.
///
/// # Errors
/// Rasterizer errors.
pub(crate) fn computation_mask(
    input: ShadowInput<'_>,
    eye: &EyePass,
    two_sided: bool,
    scratch: &mut ShadowScratch,
) -> Result<()> {
    let (w, h) = (eye.target.width(), eye.target.height());
    let mask_in = MaskInput {
        scene: input.scene,
        view: View {
            camera: input.camera,
            width: w,
            height: h,
        },
        light: input.light,
        surface: eye.surface(),
        two_sided,
    };
    let classes = scratch
        .classes
        .get_or_insert_with(|| Mask::filled(0, 0, PixelClass::Background));
    let left = classify_runs(
        mask_in,
        classes,
        &mut scratch.shadowable.decides,
        &mut scratch.runs,
    );
    scratch.shadowable.mask(&eye.target, left)
}

/// An empty vector of `U` in `v`'s allocation: for element types of one
/// layout (references differing only in lifetime) the standard library's
/// in-place collection keeps the buffer, so a list of references into one
/// frame's data keeps its capacity for the next.
fn recycle<T, U>(mut v: Vec<T>) -> Vec<U> {
    v.clear();
    v.into_iter().map(|_| unreachable!("empty")).collect()
}
