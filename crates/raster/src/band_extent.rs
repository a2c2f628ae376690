//! A convex polygon's part within a band of rows: in pixel coordinates,
//! the part of a convex polygon between two horizontal lines is convex,
//! and its vertices are those of its edges clipped to the band, so its x
//! extent and (z being affine along each projected edge) its depth range
//! are theirs.

/// The parameters `t0 ≤ t1` of the part of the segment from y `pa` to
/// `pb` within the band `[b0, b1]`, `None` when it misses it.
#[inline(always)]
pub(crate) fn band_clip(pa: f64, pb: f64, (b0, b1): (f64, f64)) -> Option<(f64, f64)> {
    let dy = pb - pa;
    if dy == 0.0 {
        return (pa >= b0 && pa <= b1).then_some((0.0, 1.0));
    }
    let (ta, tb) = ((b0 - pa) / dy, (b1 - pa) / dy);
    let (t0, t1) = (ta.min(tb).max(0.0), ta.max(tb).min(1.0));
    (t0 <= t1).then_some((t0, t1))
}

/// The x extent and the depth range `((x_lo, x_hi), (z_lo, z_hi))` of the
/// part of the convex polygon `v` (pixel coordinates and depth, in order
/// around it) within the rows `band = (y0, y1)`; `None` when it misses the
/// band.
#[inline]
pub fn band_extent(v: &[(f64, f64, f64)], band: (f64, f64)) -> Option<((f64, f64), (f64, f64))> {
    let (mut x, mut z) = (
        (f64::INFINITY, f64::NEG_INFINITY),
        (f64::INFINITY, f64::NEG_INFINITY),
    );
    for (i, p) in v.iter().enumerate() {
        let q = v[(i + 1) % v.len()];
        let Some((t0, t1)) = band_clip(p.1, q.1, band) else {
            continue;
        };
        for t in [t0, t1] {
            let (px, pz) = (p.0 + (q.0 - p.0) * t, p.2 + (q.2 - p.2) * t);
            x = (x.0.min(px), x.1.max(px));
            z = (z.0.min(pz), z.1.max(pz));
        }
    }
    (x.0 <= x.1).then_some((x, z))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square's band: its x extent, and the depths of its part there.
    #[test]
    fn a_band_of_a_square_is_its_slice() {
        // Depth = x / 10 + y / 100 over the square [0, 4]².
        let p = |x: f64, y: f64| (x, y, x / 10.0 + y / 100.0);
        let sq = [p(0.0, 0.0), p(4.0, 0.0), p(4.0, 4.0), p(0.0, 4.0)];
        let ((x0, x1), (z0, z1)) = band_extent(&sq, (1.0, 2.0)).unwrap();
        assert_eq!((x0, x1), (0.0, 4.0));
        assert!(
            (z0 - 0.01).abs() < 1e-12 && (z1 - 0.42).abs() < 1e-12,
            "{z0} {z1}"
        );
        assert_eq!(band_extent(&sq, (5.0, 6.0)), None);
        // A triangle's apex band is narrow.
        let tri = [p(0.0, 0.0), p(4.0, 0.0), p(2.0, 4.0)];
        let ((x0, x1), _) = band_extent(&tri, (3.0, 4.0)).unwrap();
        assert!(
            (x0 - 1.5).abs() < 1e-12 && (x1 - 2.5).abs() < 1e-12,
            "{x0} {x1}"
        );
    }
}
