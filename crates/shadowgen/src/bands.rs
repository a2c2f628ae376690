//! Receiver bands: a caster's volume drawn only in the eye slices its
//! receivers occupy [Steiner §4.4.2, with the slicing planes of
//! `slicing.rs`].
//!
//! # Why the mask does not change
//! The slicing planes pass through the eye, so each is seen edge-on: it
//! projects onto a pixel edge line, a row or column boundary of the image
//! ([`EyeSlices`]). An eye ray through a pixel centre therefore lies in one
//! slice, and a caster's volume changes the stencil count of that pixel
//! only if the surface point lies in the caster's shadow. The light pass
//! reads, per caster, a conservative set of the slices holding visible
//! surface points in its shadow (`visibility`'s `slice_occupancy.rs`). A
//! pixel outside those slices gets no count from the caster, whether its
//! volume is drawn there or not; inside them, drawing the whole volume (or
//! its clamped segments) gives the right count.
//!
//! So each of the caster's ranges is drawn once per run of occupied slices,
//! with [`VolumeRange::band`] the run's rows (or columns): the geometry
//! stays as it is (closed, any counting method), and pixels outside every
//! band are skipped. Band edges are pixel edges, half a pixel from any
//! centre. Unlike discrete clamping, the cut costs no geometry, only a draw
//! per band, so the bands use the finest count, [`BAND_SLICES`].
//!
//! Segmented volumes cut along the light's depth ([`crate::ClampPlan`]) and
//! bands cut across the screen. Together they bound a shadow volume both
//! along and across the light rays: on the default city's street view, the
//! bands take continuous clamping's BF fill from 8.8 M to 5.2 M pixels.

use crate::EyeSlices;
use raster::{VolumeBuffer, VolumeRange};
use scene::ObjectId;

/// Slices of the bands (the most `visibility`'s slice occupancy reads).
pub const BAND_SLICES: u32 = 64;

/// Splits the ranges `out.ranges[first..]` that `keep` selects into one
/// range per band of their caster: `bands(caster)` gives its occupied
/// slices as intervals of `slices`' base orientation (pixel edges,
/// ascending, disjoint). A caster without bands keeps its ranges whole.
/// The geometry is shared: the new ranges name the same vertices and
/// indices. `scratch` is reused.
pub fn split_into_bands<'b>(
    out: &mut VolumeBuffer,
    first: usize,
    slices: &EyeSlices,
    bands: impl Fn(ObjectId) -> Option<&'b [[f64; 2]]>,
    keep: impl Fn(&VolumeRange) -> bool,
    scratch: &mut Vec<VolumeRange>,
) {
    scratch.clear();
    scratch.extend(out.ranges.drain(first..));
    for r in scratch.drain(..) {
        let runs = match bands(ObjectId::from_bits(r.object)) {
            Some(runs) if keep(&r) => runs,
            _ => {
                out.ranges.push(r);
                continue;
            }
        };
        for &run in runs {
            if let Some(band) = band_rect(slices, run, &r.band) {
                out.ranges.push(VolumeRange { band, ..r.clone() });
            }
        }
    }
}

/// The pixel rectangle of the slices `[lo, hi]` (base orientation) inside
/// `within`; `None` when empty.
fn band_rect(slices: &EyeSlices, [lo, hi]: [f64; 2], within: &[u32; 4]) -> Option<[u32; 4]> {
    // Edges are whole pixels; rounding outward keeps any stray fraction
    // conservative.
    let lo = lo.floor().clamp(0.0, f64::from(slices.extent())) as u32;
    let hi = hi.ceil().clamp(0.0, f64::from(slices.extent())) as u32;
    let [x0, y0, x1, y1] = *within;
    let r = if slices.rows() {
        [x0, y0.max(lo), x1, y1.min(hi)]
    } else {
        [x0.max(lo), y0, x1.min(hi), y1]
    };
    (r[0] < r[2] && r[1] < r[3]).then_some(r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat4, DVec3};
    use raster::VolumeMethod;
    use scene::{Camera, Light};

    fn range(object: u64) -> VolumeRange {
        VolumeRange {
            object,
            segment: 0,
            world_from_local: DMat4::IDENTITY,
            method: VolumeMethod::ZFail,
            first_vertex: 0,
            vertex_count: 0,
            first_index: 0,
            index_count: 0,
            light_cap: 0..0,
            dark_cap: 0..0,
            depth_near: 1.0,
            depth_far: 0.0,
            scissor: VolumeRange::FULL_SCISSOR,
            band: VolumeRange::FULL_SCISSOR,
            planes: [None, None],
        }
    }

    fn pencil(light: Light) -> EyeSlices {
        let eye = DVec3::new(0.0, 0.0, 10.0);
        let camera = Camera::look_at(eye, DVec3::ZERO, DVec3::Y, 1.0, 1.25, 0.1).expect("a camera");
        EyeSlices::new(&camera, (100, 80), &light, BAND_SLICES).expect("a pencil")
    }

    /// Each caster's ranges become one per run, with the run's rows (or
    /// columns); a caster without bands and a range `keep` refuses stay
    /// whole, and ranges before `first` are untouched.
    #[test]
    fn ranges_split_per_run() {
        // A light far above the eye: the line through its image is a row.
        let rows = pencil(Light::Point {
            position: DVec3::new(0.0, 1000.0, 0.0),
            range: None,
        });
        assert!(rows.rows());
        let mut buf = VolumeBuffer::new();
        buf.ranges.extend([range(9), range(1), range(2), range(3)]);
        buf.ranges[1].segment = 1;
        let runs: [[f64; 2]; 2] = [[0.0, 10.0], [30.0, 45.0]];
        let mut scratch = Vec::new();
        split_into_bands(
            &mut buf,
            1,
            &rows,
            |id| (id.slot() != 2).then_some(&runs[..]),
            |r| r.object != 3,
            &mut scratch,
        );
        let got: Vec<(u64, u32, [u32; 4])> = buf
            .ranges
            .iter()
            .map(|r| (r.object, r.segment, r.band))
            .collect();
        let full = VolumeRange::FULL_SCISSOR;
        assert_eq!(
            got,
            vec![
                (9, 0, full),
                (1, 1, [0, 0, u32::MAX, 10]),
                (1, 1, [0, 30, u32::MAX, 45]),
                (2, 0, full),
                (3, 0, full),
            ]
        );
        // Columns: a light far to the side.
        let cols = pencil(Light::Point {
            position: DVec3::new(1000.0, 0.0, 0.0),
            range: None,
        });
        assert!(!cols.rows());
        assert_eq!(
            band_rect(&cols, [20.0, 35.5], &full),
            Some([20, 0, 36, u32::MAX])
        );
        // An empty run, or one outside the range's band, draws nothing.
        assert_eq!(band_rect(&cols, [20.0, 20.0], &full), None);
        assert_eq!(band_rect(&cols, [20.0, 30.0], &[40, 0, 60, 10]), None);
    }
}
