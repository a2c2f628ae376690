//! The stencil pass's innermost step: for a run of up to 8 contiguous pixels of
//! one tile row, which fragments lie on a written surface inside the depth
//! window (`inside`) and which of those update the stencil (`update`: strictly
//! nearer than the surface for zpass, not strictly nearer for zfail).
//!
//! Two builds with identical results: portable scalar, and AVX2 (4 pixels per
//! step). Both evaluate the same IEEE operations in the same order — edge
//! values `E_i = e_i + step_i·k` (exact integers below 2⁵³), depth
//! `((E_0·z_0 + E_1·z_1) + E_2·z_2)·inv` in f64 without fused multiply-add,
//! rounded to f32 to nearest — so the depth of every fragment is bit-identical
//! to the eye pass's and between the builds. A unit test checks the builds agree.

use crate::layout::BACKGROUND;

/// Inputs of one run: edge values at its first pixel and their per-pixel
/// steps, the plane's vertex depths and 1/area, the depth window, the rule.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RunPlane {
    pub e: [f64; 3],
    pub step: [f64; 3],
    pub z: [f64; 3],
    pub inv: f64,
    pub dlo: f32,
    pub dhi: f32,
    pub zfail: bool,
}

/// Bit masks (bit k for pixel k of `depth`, at most 8 pixels): `(inside, update)`,
/// with the AVX2 kernel when `avx2` (only true when the CPU has AVX2).
#[inline(always)]
pub(crate) fn run_masks(avx2: bool, p: &RunPlane, depth: &[f32]) -> (u32, u32) {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2::run_masks` only requires AVX2; callers pass `avx2` only
        // when the target's level (at most the detected one) has it.
        return unsafe { avx2::run_masks(p, depth) };
    }
    run_masks_scalar(p, depth)
}

/// The portable build of [`run_masks`].
#[inline(always)]
pub(crate) fn run_masks_scalar(p: &RunPlane, depth: &[f32]) -> (u32, u32) {
    let (mut inside, mut update) = (0u32, 0u32);
    for (k, &d) in depth.iter().enumerate() {
        let kk = k as f64;
        let e = [0, 1, 2].map(|i| p.e[i] + p.step[i] * kk);
        let zp = ((e[0] * p.z[0] + e[1] * p.z[1] + e[2] * p.z[2]) * p.inv) as f32;
        let ins = (d != BACKGROUND) & (d >= p.dlo) & (d <= p.dhi);
        // Strict reversed-Z test: pass iff strictly nearer.
        let upd = ins & ((zp > d) ^ p.zfail);
        inside |= u32::from(ins) << k;
        update |= u32::from(upd) << k;
    }
    (inside, update)
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{RunPlane, BACKGROUND};
    use std::arch::x86_64::*;

    /// [`super::run_masks`] four pixels at a time.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) fn run_masks(p: &RunPlane, depth: &[f32]) -> (u32, u32) {
        let n = depth.len().min(8);
        let (mut inside, mut update) = (0u32, 0u32);
        let bg = _mm_set1_ps(BACKGROUND);
        let dlo = _mm_set1_ps(p.dlo);
        let dhi = _mm_set1_ps(p.dhi);
        let flip = if p.zfail { 0xF } else { 0 };
        let e = p.e.map(|v| _mm256_set1_pd(v));
        let step = p.step.map(|v| _mm256_set1_pd(v));
        let z = p.z.map(|v| _mm256_set1_pd(v));
        let inv = _mm256_set1_pd(p.inv);
        let mut base = 0;
        while base < n {
            let m = (n - base).min(4);
            let d = if m == 4 {
                let q = &depth[base..base + 4];
                // SAFETY: `q` holds 4 contiguous f32; unaligned loads are allowed.
                unsafe { _mm_loadu_ps(q.as_ptr()) }
            } else {
                let at = |i: usize| if i < m { depth[base + i] } else { 0.0 };
                _mm_set_ps(at(3), at(2), at(1), at(0))
            };
            let k = _mm256_set_pd(
                (base + 3) as f64,
                (base + 2) as f64,
                (base + 1) as f64,
                base as f64,
            );
            let ev = [0, 1, 2].map(|i| _mm256_add_pd(e[i], _mm256_mul_pd(step[i], k)));
            let s01 = _mm256_add_pd(_mm256_mul_pd(ev[0], z[0]), _mm256_mul_pd(ev[1], z[1]));
            let s = _mm256_add_pd(s01, _mm256_mul_pd(ev[2], z[2]));
            let zp = _mm256_cvtpd_ps(_mm256_mul_pd(s, inv));
            // `!=` is true on unordered operands, `>=`/`<=`/`>` false: as in Rust.
            let ins = _mm_and_ps(
                _mm_cmp_ps::<_CMP_NEQ_UQ>(d, bg),
                _mm_and_ps(
                    _mm_cmp_ps::<_CMP_GE_OQ>(d, dlo),
                    _mm_cmp_ps::<_CMP_LE_OQ>(d, dhi),
                ),
            );
            let pass = _mm_cmp_ps::<_CMP_GT_OQ>(zp, d);
            let valid = (1u32 << m) - 1;
            let ins_bits = _mm_movemask_ps(ins) as u32 & valid;
            let upd_bits = ins_bits & ((_mm_movemask_ps(pass) as u32 ^ flip) & valid);
            inside |= ins_bits << base;
            update |= upd_bits << base;
            base += 4;
        }
        (inside, update)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn builds_agree(
            e in prop::array::uniform3(-1e12f64..1e12),
            step in prop::array::uniform3(-1e6f64..1e6),
            z in prop::array::uniform3(0.0f64..1.0),
            area in 1.0f64..1e12,
            d in prop::collection::vec(prop_oneof![Just(BACKGROUND), 0.0f32..1.0], 1..=8),
            win in (0.0f32..0.5, 0.5f32..1.0),
            zfail in any::<bool>(),
        ) {
            let p = RunPlane {
                e: e.map(f64::round),
                step: step.map(|s| s.round() * 256.0),
                z,
                inv: 1.0 / area,
                dlo: win.0,
                dhi: win.1,
                zfail,
            };
            let avx2 = crate::InstructionSet::detected() >= crate::InstructionSet::Avx2;
            prop_assert_eq!(run_masks(avx2, &p, &d), run_masks_scalar(&p, &d));
        }
    }
}
