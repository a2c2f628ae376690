//! The depth plane of a projected planar polygon: reversed-Z depth z/w is
//! affine in pixel coordinates over a plane's image (the projective map
//! takes planes to planes), `z = a·x + b·y + c`. Conservative bounds over
//! a pixel square then come from its corners: the least at the corner the
//! slopes point away from, the greatest at the other.

/// `z = a·x + b·y + c` over pixel coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthPlane {
    /// Slope along x (per pixel).
    pub a: f64,
    /// Slope along y (per pixel, rows down).
    pub b: f64,
    /// Depth at the pixel origin.
    pub c: f64,
}

impl DepthPlane {
    /// The plane through three projected points `(x, y, z)`, `None` when
    /// their triangle is too thin for the fit to be trusted: twice its
    /// area at most `thin` times the square of its extent (the sum of its
    /// two edges' coordinate spans from the first point).
    pub fn through(
        p0: (f64, f64, f64),
        p1: (f64, f64, f64),
        p2: (f64, f64, f64),
        thin: f64,
    ) -> Option<DepthPlane> {
        let det = (p1.0 - p0.0) * (p2.1 - p0.1) - (p2.0 - p0.0) * (p1.1 - p0.1);
        let extent =
            (p1.0 - p0.0).abs() + (p1.1 - p0.1).abs() + (p2.0 - p0.0).abs() + (p2.1 - p0.1).abs();
        if det.is_nan() || det.abs() <= thin * extent * extent || det.abs() <= 1e-12 {
            return None;
        }
        let a = ((p1.2 - p0.2) * (p2.1 - p0.1) - (p2.2 - p0.2) * (p1.1 - p0.1)) / det;
        let b = ((p1.0 - p0.0) * (p2.2 - p0.2) - (p2.0 - p0.0) * (p1.2 - p0.2)) / det;
        let c = p0.2 - a * p0.0 - b * p0.1;
        (a.is_finite() && b.is_finite() && c.is_finite()).then_some(DepthPlane { a, b, c })
    }

    /// The plane of a convex planar polygon, through the widest triangle of
    /// its fan from the first vertex, with a bound on its evaluation error
    /// near the polygon: the fit's rounding relative to its terms, and
    /// 10⁻⁶ of the largest depth for vertices off one plane by rounding
    /// (f32 clip points). `None` when too thin (see [`DepthPlane::through`]
    /// with `thin` 10⁻⁶).
    pub fn fit(v: &[(f64, f64, f64)]) -> Option<(DepthPlane, f64)> {
        if v.len() < 3 {
            return None;
        }
        let p0 = v[0];
        let twice_area = |i: usize| {
            let (p1, p2) = (v[i], v[i + 1]);
            ((p1.0 - p0.0) * (p2.1 - p0.1) - (p2.0 - p0.0) * (p1.1 - p0.1)).abs()
        };
        let i = (1..v.len() - 1).max_by(|&i, &j| twice_area(i).total_cmp(&twice_area(j)))?;
        let plane = DepthPlane::through(p0, v[i], v[i + 1], 1e-6)?;
        let extent = v
            .iter()
            .map(|p| (p.0 - p0.0).abs() + (p.1 - p0.1).abs())
            .fold(0.0, f64::max);
        let zmax = v.iter().map(|p| p.2.abs()).fold(0.0, f64::max);
        let span = extent + p0.0.abs() + p0.1.abs();
        let err = 1e-9 * (zmax + (plane.a.abs() + plane.b.abs()) * span) + 1e-6 * zmax;
        Some((plane, err))
    }

    /// The depth at `(x, y)`.
    #[inline(always)]
    pub fn at(&self, x: f64, y: f64) -> f64 {
        self.a * x + self.b * y + self.c
    }

    /// The least over the square `[x0, x1] × [y0, y1]` (at its corner the
    /// slopes point away from).
    #[inline(always)]
    pub fn least(&self, (x0, x1): (f64, f64), (y0, y1): (f64, f64)) -> f64 {
        let x = if self.a > 0.0 { x0 } else { x1 };
        let y = if self.b > 0.0 { y0 } else { y1 };
        self.at(x, y)
    }

    /// The greatest over the square `[x0, x1] × [y0, y1]`.
    #[inline(always)]
    pub fn greatest(&self, (x0, x1): (f64, f64), (y0, y1): (f64, f64)) -> f64 {
        let x = if self.a > 0.0 { x1 } else { x0 };
        let y = if self.b > 0.0 { y1 } else { y0 };
        self.at(x, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fit reproduces the plane at the vertices; the square's bounds
    /// are its corners' extremes; thin triangles give no plane.
    #[test]
    fn planes_fit_their_points_and_bound_squares() {
        let z = |x: f64, y: f64| 0.3 * x - 0.2 * y + 0.7;
        let p = |x: f64, y: f64| (x, y, z(x, y));
        let plane = DepthPlane::through(p(0.0, 0.0), p(4.0, 1.0), p(1.0, 5.0), 1e-9).unwrap();
        for (x, y) in [(0.0, 0.0), (4.0, 1.0), (1.0, 5.0), (2.5, -3.0)] {
            assert!((plane.at(x, y) - z(x, y)).abs() < 1e-12);
        }
        let corners = [(2.0, 3.0), (3.0, 3.0), (2.0, 4.0), (3.0, 4.0)].map(|(x, y)| z(x, y));
        let lo = corners.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = corners.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert!((plane.least((2.0, 3.0), (3.0, 4.0)) - lo).abs() < 1e-12);
        assert!((plane.greatest((2.0, 3.0), (3.0, 4.0)) - hi).abs() < 1e-12);
        assert_eq!(
            DepthPlane::through(p(0.0, 0.0), p(4.0, 1.0), p(8.0, 2.0), 1e-9),
            None
        );
        let (fit, err) =
            DepthPlane::fit(&[p(0.0, 0.0), p(0.1, 0.0), p(4.0, 4.0), p(0.0, 4.0)]).unwrap();
        assert!((fit.at(1.0, 1.0) - z(1.0, 1.0)).abs() <= err.max(1e-12));
    }
}
