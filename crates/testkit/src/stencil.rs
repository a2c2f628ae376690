//! The hierarchical stencil (H) against brute force (BF) on one view.

use glam::Mat4;
use raster::{
    DepthTarget, HierarchicalOptions, HierarchicalStencil, StencilBits, StencilStats,
    StencilTarget, StencilTests, TileSize, VolumeBuffer, VolumeRange,
};
use scene::{Camera, Light, ObjectId, Scene};
use std::cell::OnceCell;

/// What [`hierarchical_matches_brute_force`] saw on one view, to show the
/// check is not vacuous and to look the FS pixels up in a reference.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct HierarchyCheck {
    /// FS-off H draws compared with BF (tiles × counter widths).
    pub draws: u32,
    /// Boundary tiles summed over the FS-off draws.
    pub boundary_tiles: u64,
    /// Fully shadowed tiles summed over the FS-off draws.
    pub shadow_tiles: u64,
    /// Lit tiles summed over the FS-off draws.
    pub lit_tiles: u64,
    /// Fragments of the wide-counter BF draw.
    pub brute_fragments: u64,
    /// Per-pixel fragments H saved against BF, summed over the FS-off draws.
    pub saved_fragments: u64,
    /// Pixels where the FS bit changed the wide-counter mask (each proven to
    /// have a volume with a negative count).
    pub fs_wide_differences: u64,
    /// Pixels where FS with 8-bit counters differs from 8-bit BF (each
    /// proven: wide count a non-zero multiple of 256, or a negative volume count).
    pub fs_eight_differences: u64,
    /// The pixels (row-major indices) where either FS mask differs from BF.
    pub differing: Vec<usize>,
}

/// H against BF on one view, with the same eye depth, volumes and tests
/// (every check returns an error naming the first pixel or counter that fails):
///
/// - FS bit off, for wide and for 8-bit counters and every tile size in
///   `tiles`: the same counter value at every written pixel of `eye`, the same
///   resolved mask, the same triangle count, and no more H per-pixel fragments
///   than BF fragments;
/// - FS on (tile 8), wide: H's resolved mask equals its own per-pixel reading
///   (written and [`HierarchicalStencil::nonzero`]), and every pixel where it
///   differs from BF is shadow in H and has some volume whose own count there
///   is negative;
/// - FS on, 8-bit against 8-bit BF: likewise, every differing pixel is shadow
///   in H with a wide BF count that is a non-zero multiple of 256 (an 8-bit
///   wrap), or a negative volume count.
///
/// # Errors
/// The first failed check, described.
pub fn hierarchical_matches_brute_force(
    eye: &DepthTarget,
    volumes: &[(Mat4, &VolumeRange)],
    buf: &VolumeBuffer,
    tests: StencilTests,
    tiles: &[TileSize],
) -> Result<HierarchyCheck, String> {
    let (w, h) = (eye.width(), eye.height());
    let err = |e: raster::Error| e.to_string();
    let brute = |bits| -> Result<_, String> {
        let mut s = StencilTarget::new(w, h, bits).map_err(err)?;
        let mut st = StencilStats::default();
        s.draw_volumes(eye, volumes, buf, tests, &mut st)
            .map_err(err)?;
        let mut mask = Vec::new();
        s.resolve(eye, &mut mask, &mut StencilStats::default())
            .map_err(err)?;
        Ok((s, st, mask))
    };
    let hier = |tile, bits, full_shadow| -> Result<_, String> {
        let options = HierarchicalOptions {
            tile,
            bits,
            full_shadow,
        };
        let mut s = HierarchicalStencil::new(w, h, options).map_err(err)?;
        let mut st = StencilStats::default();
        s.draw_volumes(eye, volumes, buf, tests, &mut st)
            .map_err(err)?;
        let mut mask = Vec::new();
        s.resolve(eye, &mut mask, &mut StencilStats::default())
            .map_err(err)?;
        Ok((s, st, mask))
    };
    let written = |x: u32, y: u32| eye.depth_at(x, y).is_some();
    let mut out = HierarchyCheck::default();
    let (bw, bw_stats, bw_mask) = brute(StencilBits::Wide)?;
    let (b8, b8_stats, b8_mask) = brute(StencilBits::Eight)?;
    out.brute_fragments = bw_stats.pixels_processed;
    for (bits, bf, bst, bm) in [
        (StencilBits::Wide, &bw, &bw_stats, &bw_mask),
        (StencilBits::Eight, &b8, &b8_stats, &b8_mask),
    ] {
        for &tile in tiles {
            let (hs, st, hm) = hier(tile, bits, false)?;
            for y in 0..h {
                for x in 0..w {
                    if written(x, y) && hs.value(x, y) != bf.value(x, y) {
                        return Err(format!(
                            "{tile:?} {bits:?} FS off: pixel ({x}, {y}) hierarchical {} brute force {}",
                            hs.value(x, y),
                            bf.value(x, y)
                        ));
                    }
                }
            }
            if hm != *bm {
                return Err(format!(
                    "{tile:?} {bits:?} FS off: the resolved masks differ"
                ));
            }
            if st.h_fragments > bst.pixels_processed {
                return Err(format!(
                    "{tile:?} {bits:?} FS off: {} hierarchical fragments > {} brute-force ones",
                    st.h_fragments, bst.pixels_processed
                ));
            }
            if st.triangles != bst.triangles {
                return Err(format!(
                    "{tile:?} {bits:?} FS off: {} triangles, brute force {}",
                    st.triangles, bst.triangles
                ));
            }
            out.draws += 1;
            out.boundary_tiles += st.tiles_boundary;
            out.shadow_tiles += st.tiles_shadow;
            out.lit_tiles += st.tiles_lit;
            out.saved_fragments += bst.pixels_processed - st.h_fragments;
        }
    }
    // FS on: differences need a reason. Every volume's own wide count, drawn
    // only when some pixel needs one.
    let singles = OnceCell::new();
    let negative = |x: u32, y: u32| -> Result<bool, String> {
        if singles.get().is_none() {
            let mut all = Vec::with_capacity(volumes.len());
            for &(m, r) in volumes {
                let mut s = StencilTarget::new(w, h, StencilBits::Wide).map_err(err)?;
                s.draw_volume(eye, m, buf, r, tests, &mut StencilStats::default())
                    .map_err(err)?;
                all.push(s);
            }
            let _ = singles.set(all);
        }
        let singles: &Vec<StencilTarget> = singles.get().expect("just set");
        Ok(singles.iter().any(|s| s.value(x, y) < 0))
    };
    let fs_mask = |hs: &HierarchicalStencil, resolved: &[bool], what: &str| {
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                if resolved[i] != (written(x, y) && hs.nonzero(x, y)) {
                    return Err(format!(
                        "{what}: pixel ({x}, {y}) resolves to {} against its own counters",
                        resolved[i]
                    ));
                }
            }
        }
        Ok(())
    };
    let (hw, _, hw_mask) = hier(TileSize::T8, StencilBits::Wide, true)?;
    fs_mask(&hw, &hw_mask, "FS wide")?;
    for i in (0..hw_mask.len()).filter(|&i| hw_mask[i] != bw_mask[i]) {
        let (x, y) = (i as u32 % w, i as u32 / w);
        if !(hw_mask[i] && negative(x, y)?) {
            return Err(format!(
                "FS wide: pixel ({x}, {y}) differs without a negative volume count"
            ));
        }
        out.fs_wide_differences += 1;
        out.differing.push(i);
    }
    let (h8, _, h8_mask) = hier(TileSize::T8, StencilBits::Eight, true)?;
    fs_mask(&h8, &h8_mask, "FS 8-bit")?;
    for i in (0..h8_mask.len()).filter(|&i| h8_mask[i] != b8_mask[i]) {
        let (x, y) = (i as u32 % w, i as u32 / w);
        let wide = bw.value(x, y);
        let wraps = wide != 0 && wide % 256 == 0;
        if !(h8_mask[i] && (wraps || negative(x, y)?)) {
            return Err(format!(
                "FS 8-bit: pixel ({x}, {y}) differs (wide count {wide}) without a reason"
            ));
        }
        out.fs_eight_differences += 1;
        if !out.differing.contains(&i) {
            out.differing.push(i);
        }
    }
    Ok(out)
}

/// [`hierarchical_matches_brute_force`] on `scene` seen by `cam`: every
/// object casts, with `method` and `two_sided`, against the eye depth `eye`,
/// scissor and depth bounds off.
///
/// # Errors
/// A volume build error or the first failed check, described.
pub fn check_hierarchical(
    scene: &Scene,
    cam: &Camera,
    light: &Light,
    eye: &DepthTarget,
    method: shadowgen::MethodChoice,
    two_sided: bool,
    tiles: &[TileSize],
) -> Result<HierarchyCheck, String> {
    let buf = volumes(scene, cam, light, options(method, two_sided), false)?;
    check_buffer(cam, eye, &buf, tiles)
}

/// [`check_hierarchical`] on continuously clamped volumes (every receiving
/// object a receiver, every gap kept): H's open-edge rule holds on segments
/// too.
///
/// # Errors
/// As [`check_hierarchical`].
pub fn check_hierarchical_clamped(
    scene: &Scene,
    cam: &Camera,
    light: &Light,
    eye: &DepthTarget,
    method: shadowgen::MethodChoice,
    two_sided: bool,
    tiles: &[TileSize],
) -> Result<HierarchyCheck, String> {
    let buf = volumes(scene, cam, light, options(method, two_sided), true)?;
    check_buffer(cam, eye, &buf, tiles)
}

/// The build options of the checks: `method`, `two_sided`, no bounds.
fn options(method: shadowgen::MethodChoice, two_sided: bool) -> shadowgen::BuildOptions {
    shadowgen::BuildOptions {
        method,
        two_sided,
        ..Default::default()
    }
}

/// Every object's volume for `light`, clamped (receivers: every receiving
/// object, no gap model) or not.
fn volumes(
    scene: &Scene,
    cam: &Camera,
    light: &Light,
    options: shadowgen::BuildOptions,
    clamped: bool,
) -> Result<VolumeBuffer, String> {
    let mut buf = VolumeBuffer::new();
    let casters: Vec<ObjectId> = (0..scene.objects().len() as u32)
        .map(ObjectId::from_slot)
        .collect();
    let mut cache = shadowgen::SilhouetteCache::default();
    let err = |e: shadowgen::Error| e.to_string();
    let request = shadowgen::VolumeRequest {
        scene,
        camera: cam,
        light,
        casters: &casters,
        options,
    };
    if clamped {
        let receives: Vec<bool> = scene.objects().iter().map(|o| o.flags.receives).collect();
        let input = shadowgen::ClampInput {
            scene,
            light,
            casters: &casters,
            receives: &receives,
            cost: None,
        };
        let mut plan = shadowgen::ClampPlan::new();
        shadowgen::LightClamp::new()
            .plan(&input, &mut plan)
            .map_err(err)?;
        shadowgen::build_clamped_volumes(&mut buf, &request, &mut cache, &plan).map_err(err)?;
    } else {
        shadowgen::build_volumes(&mut buf, scene, cam, light, &casters, options, &mut cache)
            .map_err(err)?;
    }
    Ok(buf)
}

/// [`hierarchical_matches_brute_force`] on every range of `buf` seen by `cam`.
fn check_buffer(
    cam: &Camera,
    eye: &DepthTarget,
    buf: &VolumeBuffer,
    tiles: &[TileSize],
) -> Result<HierarchyCheck, String> {
    let clip: Vec<Mat4> = buf
        .ranges
        .iter()
        .map(|r| scene::transform::clip_from_local(cam, &r.world_from_local))
        .collect();
    let volumes: Vec<(Mat4, &VolumeRange)> = clip.iter().copied().zip(&buf.ranges).collect();
    hierarchical_matches_brute_force(eye, &volumes, buf, StencilTests::default(), tiles)
}
