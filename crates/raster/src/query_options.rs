//! What a query asks and what it answers: [`QueryMode`], [`QueryOptions`], the
//! [`VISIBLE`] answer, and the apex-region test that gives it without
//! rasterizing (a box meeting the view's apex region `{z ≥ w, |x| ≤ w, |y| ≤ w}`,
//! widened by [`APEX_EPS`]).

use crate::coverage::Coverage;
use crate::item::aabb_corners;
use glam::{DMat4, DVec4, Mat4, Vec3};

/// Query result meaning "visible without counting" (apex region).
pub const VISIBLE: u32 = u32::MAX;

/// Relative widening of the apex-region planes, scaled by the box's clip-space
/// magnitude `max(|x| + |y| + |z| + |w|)` over its corners: covers the f32
/// rounding of `clip_from_local` (2⁻²⁴ per entry) with a wide margin.
pub const APEX_EPS: f64 = 1.0 / 65536.0;

/// What a query returns.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum QueryMode {
    /// The number of passing samples (GL `SAMPLES_PASSED`), saturating below [`VISIBLE`].
    #[default]
    Count,
    /// 1 at the first passing sample, else 0 (GL `ANY_SAMPLES_PASSED`).
    Any,
    /// The number of passing samples, counted only up to `n`: `min(count, n)`
    /// (`n` at least 1; 0 counts as 1). A culler asking whether more than `t`
    /// samples pass needs no more than `t + 1`, and the count stops there
    /// as [`QueryMode::Any`] stops at the first. Hosts may count them all.
    CountUpTo(u32),
}

impl QueryMode {
    /// The mode of a query asked whether more than `threshold` samples pass:
    /// [`QueryMode::Any`] for 0, else the count up to `threshold + 1`.
    pub fn more_than(threshold: u32) -> Self {
        match threshold {
            0 => QueryMode::Any,
            t => QueryMode::CountUpTo(t.saturating_add(1)),
        }
    }

    /// The count at which a query may stop: `u64::MAX` for [`QueryMode::Count`],
    /// 1 for [`QueryMode::Any`].
    pub fn limit(self) -> u64 {
        match self {
            QueryMode::Count => u64::MAX,
            QueryMode::Any => 1,
            QueryMode::CountUpTo(n) => u64::from(n.max(1)),
        }
    }
}

/// Options of a query.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct QueryOptions {
    /// Coverage of the query geometry (outer-conservative at nearest depth for casters).
    pub coverage: Coverage,
    /// Count or any-samples.
    pub mode: QueryMode,
}

/// Whether the box `(min, max)` meets the apex region `{z ≥ w, |x| ≤ w, |y| ≤ w}`
/// of `clip_from_local`, widened by [`APEX_EPS`].
pub fn meets_apex_region(clip_from_local: &Mat4, min: Vec3, max: Vec3) -> bool {
    let m: DMat4 = clip_from_local.as_dmat4();
    let corners = aabb_corners(min, max).map(|p| m * p.as_dvec4());
    let scale = corners
        .iter()
        .map(|c| c.x.abs() + c.y.abs() + c.z.abs() + c.w.abs())
        .fold(0.0, f64::max);
    let delta = APEX_EPS * scale;
    let planes = [
        DVec4::new(0.0, 0.0, 1.0, -1.0),
        DVec4::new(-1.0, 0.0, 0.0, 1.0),
        DVec4::new(1.0, 0.0, 0.0, 1.0),
        DVec4::new(0.0, -1.0, 0.0, 1.0),
        DVec4::new(0.0, 1.0, 0.0, 1.0),
    ];
    // Quick reject: all corners strictly outside one (widened) plane.
    for p in &planes {
        if corners.iter().all(|c| p.dot(*c) + delta < 0.0) {
            return false;
        }
    }
    const FACES: [[usize; 4]; 6] = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    for f in FACES {
        // A quad clipped by five planes has at most 9 vertices.
        let mut poly = [DVec4::ZERO; 12];
        let mut next = [DVec4::ZERO; 12];
        let mut n = 4;
        for (k, &i) in f.iter().enumerate() {
            poly[k] = corners[i];
        }
        for p in &planes {
            let mut m = 0;
            for i in 0..n {
                let a = poly[i];
                let b = poly[(i + 1) % n];
                let da = p.dot(a) + delta;
                let db = p.dot(b) + delta;
                if da >= 0.0 {
                    next[m] = a;
                    m += 1;
                }
                if (da >= 0.0) != (db >= 0.0) {
                    next[m] = a + (b - a) * (da / (da - db));
                    m += 1;
                }
            }
            poly[..m].copy_from_slice(&next[..m]);
            n = m;
            if n == 0 {
                break;
            }
        }
        if n > 0 {
            return true;
        }
    }
    // The region may lie inside the box without meeting a face: test the
    // near-rectangle centre (clip (0, 0, 1, 1)), a point of the region.
    if m.determinant() != 0.0 {
        let q = m.inverse() * DVec4::new(0.0, 0.0, 1.0, 1.0);
        if q.w != 0.0 {
            let p = q.truncate() / q.w;
            let (lo, hi) = (min.as_dvec3(), max.as_dvec3());
            let pad = (hi - lo).abs().max_element() * APEX_EPS;
            if p.cmpge(lo - pad).all() && p.cmple(hi + pad).all() {
                return true;
            }
        }
    }
    false
}
