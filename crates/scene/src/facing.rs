//! The one facing rule (DESIGN.md "Facing").

use crate::Light;
use glam::DVec3;

/// True when the triangle `(a, b, c)` (world space, f64, counter-clockwise =
/// front) faces `light`: the light lies strictly on the positive side of the
/// triangle's plane, the side `(b − a) × (c − a)` points to. A light exactly in
/// the plane means *not* facing; a degenerate triangle faces nothing.
///
/// Silhouettes, caps, light-view occluders, the reference and the mask classes
/// all call this with the same world positions (from
/// [`crate::transform::world_point`], winding already flipped for mirrored
/// objects by [`crate::Scene::world_triangle`]).
///
/// The sign is exact for finite inputs: the determinant
/// `det[b − a, c − a, v]` (`v` = light − a, or the direction toward a
/// directional light) is evaluated in f64 with a forward error bound
/// [Shewchuk's `orient3d` filter], and only when the bound cannot decide
/// (the light within rounding of the plane, or an overflow) again in exact
/// integer arithmetic. So a triangle and its rotations always agree, a
/// triangle and its reverse never both face the light, and the answer is
/// the true side even where floating point cancels catastrophically (found
/// by the `volumes` fuzz target: a triangle with one vertex 10³⁶ out and
/// two near the origin, whose f64 normal taken at the far vertex lost its
/// largest component, so the shadow volume was built inside out).
/// Non-finite inputs face nothing.
pub fn faces_light(tri: &[DVec3; 3], light: &Light) -> bool {
    let [a, b, c] = *tri;
    let v = match *light {
        Light::Point { position, .. } | Light::Spot { position, .. } => Toward::Point(position),
        Light::Directional { direction } => Toward::Direction(-direction),
    };
    orientation(a, b, c, v) > 0
}

/// Where the light is: a finite point, or a direction toward it.
#[derive(Clone, Copy)]
enum Toward {
    Point(DVec3),
    Direction(DVec3),
}

/// The exact sign (−1, 0, 1) of `det[b − a, c − a, v]`, `v` = `p − a` for
/// `Toward::Point(p)` and `d` for `Toward::Direction(d)`; 0 for non-finite
/// inputs.
fn orientation(a: DVec3, b: DVec3, c: DVec3, toward: Toward) -> i32 {
    let (x, y, v) = match toward {
        Toward::Point(p) => (b - a, c - a, p - a),
        Toward::Direction(d) => (b - a, c - a, d),
    };
    let d = x.cross(y).dot(v);
    // The permanent: the determinant's terms with absolute values. Rounding
    // (of the differences, products and sums) moves the f64 determinant by
    // less than (7 + 56ε)·ε·permanent [Shewchuk, o3derrboundA]; 8ε is safe.
    // The absolute term covers products that underflowed.
    let (x, y, v) = (x.abs(), y.abs(), v.abs());
    let permanent = x.x * (y.y * v.z + y.z * v.y)
        + x.y * (y.x * v.z + y.z * v.x)
        + x.z * (y.x * v.y + y.y * v.x);
    let bound = 8.0 * f64::EPSILON / 2.0 * permanent + 1e-300;
    if d.is_finite() && bound.is_finite() && d.abs() > bound {
        return if d > 0.0 { 1 } else { -1 };
    }
    exact::orientation(a, b, c, toward)
}

/// The fallback: the same determinant in exact integer arithmetic. Every
/// finite f64 is an integer multiple of a power of two, so the inputs,
/// scaled by the smallest such power among them, are integers; their
/// differences and the determinant's products are exact in a fixed
/// 1,024-bit two's-complement integer on the stack ([`Wide`]) whenever the
/// inputs span at most `MAX_SPREAD` (330) binary orders of magnitude, which
/// allocates nothing (a steady frame calls this wherever a light is
/// exactly in a face's plane: a sun along an axis and axis-aligned boxes).
/// Wider spreads (a vertex 10⁹⁹ times farther out than another) take big
/// integers, which allocate.
mod exact {
    use super::Toward;
    use glam::DVec3;

    const LIMBS: usize = 16;
    /// The widest exponent spread (from the smallest nonzero input's unit in
    /// the last place to the largest one's top bit) that [`Wide`] holds:
    /// scaled inputs then have at most spread + 1 bits, their differences
    /// one more, and the determinant (six products of three, summed) at
    /// most 3 · (spread + 2) + 3 ≤ 64 · LIMBS − 1 bits.
    pub(super) const MAX_SPREAD: i32 = 330;

    /// `x` as `mantissa · 2^exponent` (every finite f64 is one; 0 is (0, _)).
    fn split(x: f64) -> (u64, i32) {
        let bits = x.to_bits();
        let field = ((bits >> 52) & 0x7ff) as i32;
        let fraction = bits & ((1 << 52) - 1);
        // Subnormals: fraction · 2⁻¹⁰⁷⁴; normals: (2⁵² + fraction) · 2^(e − 1075).
        match field {
            0 => (fraction, -1074),
            _ => (fraction | (1 << 52), field - 1075),
        }
    }

    /// A two's-complement integer of 64 · LIMBS bits, limbs little-endian.
    #[derive(Clone, Copy)]
    struct Wide([u64; LIMBS]);

    impl Wide {
        /// `±mantissa · 2^shift` (`shift` below 64 · (LIMBS − 1)).
        fn new(x: f64, lowest: i32) -> Wide {
            let (m, e) = split(x);
            let mut w = Wide([0; LIMBS]);
            if m != 0 {
                let shift = (e - lowest) as u32;
                let (limb, bit) = ((shift / 64) as usize, shift % 64);
                w.0[limb] = m << bit;
                if bit > 0 {
                    w.0[limb + 1] = m >> (64 - bit);
                }
            }
            if x.is_sign_negative() {
                w.neg()
            } else {
                w
            }
        }

        fn neg(self) -> Wide {
            let mut r = [0; LIMBS];
            let mut carry = true;
            for (r, &x) in r.iter_mut().zip(&self.0) {
                let (v, c) = (!x).overflowing_add(u64::from(carry));
                *r = v;
                carry = c;
            }
            Wide(r)
        }

        fn add(self, o: Wide) -> Wide {
            let mut r = [0; LIMBS];
            let mut carry = false;
            for ((r, &x), &y) in r.iter_mut().zip(&self.0).zip(&o.0) {
                let (v, c1) = x.overflowing_add(y);
                let (v, c2) = v.overflowing_add(u64::from(carry));
                *r = v;
                carry = c1 || c2;
            }
            Wide(r)
        }

        fn sub(self, o: Wide) -> Wide {
            self.add(o.neg())
        }

        fn negative(&self) -> bool {
            self.0[LIMBS - 1] >> 63 == 1
        }

        fn abs(self) -> Wide {
            if self.negative() {
                self.neg()
            } else {
                self
            }
        }

        /// The product (the caller's bound keeps it within 64 · LIMBS − 1 bits).
        fn mul(self, o: Wide) -> Wide {
            let negative = self.negative() != o.negative();
            let (a, b) = (self.abs().0, o.abs().0);
            let used = |x: &[u64; LIMBS]| LIMBS - x.iter().rev().take_while(|&&l| l == 0).count();
            let (na, nb) = (used(&a), used(&b));
            let mut r = [0u64; LIMBS];
            for (i, &x) in a.iter().enumerate().take(na) {
                let mut carry = 0u128;
                for j in 0..nb.min(LIMBS - i) {
                    let t = u128::from(r[i + j]) + u128::from(x) * u128::from(b[j]) + carry;
                    r[i + j] = t as u64;
                    carry = t >> 64;
                }
                if i + nb < LIMBS {
                    r[i + nb] = carry as u64;
                }
            }
            if negative {
                Wide(r).neg()
            } else {
                Wide(r)
            }
        }

        fn sign(&self) -> i32 {
            if self.negative() {
                -1
            } else if self.0.iter().all(|&l| l == 0) {
                0
            } else {
                1
            }
        }
    }

    /// The exponent range (lowest, highest) of the nonzero coordinates.
    fn exponents(points: &[DVec3]) -> Option<(i32, i32)> {
        let mut range: Option<(i32, i32)> = None;
        for (m, e) in points.iter().flat_map(|p| p.to_array()).map(split) {
            if m != 0 {
                let top = e + 63 - m.leading_zeros() as i32;
                range = Some(match range {
                    Some((lo, hi)) => (lo.min(e), hi.max(top)),
                    None => (e, top),
                });
            }
        }
        range
    }

    /// `det[x, y, v]` of exact integer vectors.
    fn det<T: Copy>(
        x: [T; 3],
        y: [T; 3],
        v: [T; 3],
        mul: impl Fn(T, T) -> T,
        add: impl Fn(T, T) -> T,
        sub: impl Fn(T, T) -> T,
    ) -> T {
        let minor = |i: usize, j: usize| sub(mul(y[i], v[j]), mul(y[j], v[i]));
        add(
            add(mul(x[0], minor(1, 2)), mul(x[1], minor(2, 0))),
            mul(x[2], minor(0, 1)),
        )
    }

    pub(super) fn orientation(a: DVec3, b: DVec3, c: DVec3, toward: Toward) -> i32 {
        let light = match toward {
            Toward::Point(p) | Toward::Direction(p) => p,
        };
        if ![a, b, c, light].iter().all(|p| p.is_finite()) {
            return 0;
        }
        // The points share one scale; a direction takes its own (the
        // determinant is linear in it, so a positive scale keeps the sign).
        let (shared, own): (&[DVec3], Option<DVec3>) = match toward {
            Toward::Point(p) => (&[a, b, c, p], None),
            Toward::Direction(d) => (&[a, b, c], Some(d)),
        };
        let spread = |r: Option<(i32, i32)>| r.map_or(0, |(lo, hi)| hi - lo);
        let (points, direction) = (exponents(shared), own.and_then(|d| exponents(&[d])));
        if spread(points).max(spread(direction)) <= MAX_SPREAD {
            let lowest = |r: Option<(i32, i32)>| r.map_or(0, |(lo, _)| lo);
            let wide = |p: DVec3, lo: i32| [p.x, p.y, p.z].map(|x| Wide::new(x, lo));
            let at = |p: DVec3| wide(p, lowest(points));
            let diff = |p: [Wide; 3], q: [Wide; 3]| [0, 1, 2].map(|i| p[i].sub(q[i]));
            let wa = at(a);
            let v = match toward {
                Toward::Point(p) => diff(at(p), wa),
                Toward::Direction(d) => wide(d, lowest(direction)),
            };
            let d = det(
                diff(at(b), wa),
                diff(at(c), wa),
                v,
                Wide::mul,
                Wide::add,
                Wide::sub,
            );
            return d.sign();
        }
        big::orientation(a, b, c, toward)
    }

    /// Beyond [`MAX_SPREAD`]: big integers.
    mod big {
        use super::super::Toward;
        use glam::DVec3;
        use num_bigint::BigInt;

        /// `x` as an integer multiple of 2⁻¹⁰⁷⁴.
        fn scaled(x: f64) -> BigInt {
            let (m, e) = super::split(x);
            let m = BigInt::from(m) << (e + 1074);
            if x.is_sign_negative() {
                -m
            } else {
                m
            }
        }

        fn vector(p: DVec3) -> [BigInt; 3] {
            [scaled(p.x), scaled(p.y), scaled(p.z)]
        }

        fn sub(p: &[BigInt; 3], q: &[BigInt; 3]) -> [BigInt; 3] {
            [&p[0] - &q[0], &p[1] - &q[1], &p[2] - &q[2]]
        }

        pub(in super::super) fn orientation(a: DVec3, b: DVec3, c: DVec3, toward: Toward) -> i32 {
            let [a, b, c] = [a, b, c].map(vector);
            let (x, y) = (sub(&b, &a), sub(&c, &a));
            let v = match toward {
                Toward::Point(p) => sub(&vector(p), &a),
                Toward::Direction(d) => vector(d),
            };
            let d = &x[0] * (&y[1] * &v[2] - &y[2] * &v[1])
                + &x[1] * (&y[2] * &v[0] - &y[0] * &v[2])
                + &x[2] * (&y[0] * &v[1] - &y[1] * &v[0]);
            match d.sign() {
                num_bigint::Sign::Plus => 1,
                num_bigint::Sign::Minus => -1,
                num_bigint::Sign::NoSign => 0,
            }
        }
    }

    #[cfg(test)]
    pub(super) use big::orientation as big_orientation;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn facing_sign_and_in_plane() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::Z * -1.0]; // normal +y
        let above = Light::Point {
            position: DVec3::new(0.2, 5.0, -0.2),
            range: None,
        };
        let below = Light::Point {
            position: DVec3::new(0.2, -5.0, -0.2),
            range: None,
        };
        let inplane = Light::Point {
            position: DVec3::new(7.0, 0.0, 3.0),
            range: None,
        };
        assert!(faces_light(&t, &above));
        assert!(!faces_light(&t, &below));
        assert!(!faces_light(&t, &inplane));
        let sun = Light::Directional {
            direction: DVec3::new(0.3, -1.0, 0.0),
        };
        assert!(faces_light(&t, &sun));
        let grazing = Light::Directional {
            direction: DVec3::X,
        };
        assert!(!faces_light(&t, &grazing));
    }

    /// Found by the `volumes` fuzz target: a vertex 10³⁸ times farther out
    /// than the others, a light nearly in the plane. Listed from its second
    /// vertex, the triangle used to face the light while listed from its
    /// first it did not, so a mesh holding both cast it once each way.
    #[test]
    fn rotations_agree_where_rounding_decides() {
        let t = [
            DVec3::new(-0.0003125, 0.0103125, 0.0),
            DVec3::new(-1.0800166385859862e-21, -0.0009375, -0.0015625),
            DVec3::new(-2.5646812848878285e36, -5.629624272932864e34, 0.01375),
        ];
        let l = Light::Point {
            position: DVec3::new(
                0.01317708094911116,
                -0.02354222934309911,
                -0.03934325169756619,
            ),
            range: None,
        };
        let f = faces_light(&t, &l);
        assert_eq!(faces_light(&[t[1], t[2], t[0]], &l), f);
        assert_eq!(faces_light(&[t[2], t[0], t[1]], &l), f);
        assert!(!(f && faces_light(&[t[0], t[2], t[1]], &l)));
    }

    /// Found by the `volumes` fuzz target: one vertex 10³³ out, two near
    /// the origin, the sun along −(1, 1, 1). Taken at the far vertex (the
    /// lexicographically smallest, as the rule once did), the f64 normal
    /// loses its largest component and the triangle seems to face the other
    /// way; its shadow volume was built inside out.
    #[test]
    fn a_far_vertex_does_not_flip_the_facing() {
        let p = DVec3::new(0.001375, 3.125e-5, 0.0);
        let q = DVec3::new(
            9.196021172131612e-44,
            -3.711097520999097e-30,
            -0.00028125000000000003,
        );
        let r = DVec3::new(-7.969793658065675e28, 0.0, 1.3057709929374802e33);
        let sun = Light::Directional {
            direction: DVec3::splat(-1.0),
        };
        // The true normal of (p, q, r), taken at p, where nothing cancels:
        // (q − p) × (r − p) · (1, 1, 1) > 0.
        assert!((q - p).cross(r - p).dot(DVec3::ONE) > 0.0);
        for t in [[p, q, r], [q, r, p], [r, p, q]] {
            assert!(faces_light(&t, &sun));
            assert!(!faces_light(&[t[0], t[2], t[1]], &sun));
        }
    }

    /// A light in the plane faces nothing, however far out the vertices.
    #[test]
    fn a_light_exactly_in_the_plane_faces_nothing() {
        let t = [
            DVec3::new(-3.0e30, 0.0, 7.0),
            DVec3::new(0.25, 0.0, -1e-20),
            DVec3::new(5.0, 0.0, 2.0e33),
        ];
        for position in [DVec3::new(1e-300, 0.0, 4.0), DVec3::new(-2.0e40, 0.0, 3.0)] {
            let l = Light::Point {
                position,
                range: None,
            };
            assert!(!faces_light(&t, &l));
            assert!(!faces_light(&[t[0], t[2], t[1]], &l));
        }
        let grazing = Light::Directional {
            direction: DVec3::new(1.0, 0.0, -1e-30),
        };
        assert!(!faces_light(&t, &grazing));
        assert!(!faces_light(&[t[0], t[2], t[1]], &grazing));
    }

    proptest::proptest! {
        /// Any triangle (coordinates over 80 orders of magnitude) and light:
        /// its rotations agree, and it and its reverse never both face.
        #[test]
        fn rotations_agree_and_reverses_exclude(
            v in proptest::array::uniform3(proptest::array::uniform3(-1.0f64..1.0)),
            e in proptest::array::uniform3(-40i32..40),
            p in proptest::array::uniform3(-1.0f64..1.0),
            sun in proptest::bool::ANY,
        ) {
            let t = [0, 1, 2].map(|k| DVec3::from(v[k]) * 10f64.powi(e[k]));
            let l = if sun {
                Light::Directional { direction: DVec3::from(p) }
            } else {
                Light::Point { position: DVec3::from(p), range: None }
            };
            let f = faces_light(&t, &l);
            proptest::prop_assert_eq!(faces_light(&[t[1], t[2], t[0]], &l), f);
            proptest::prop_assert_eq!(faces_light(&[t[2], t[0], t[1]], &l), f);
            for r in [[t[0], t[2], t[1]], [t[2], t[1], t[0]], [t[1], t[0], t[2]]] {
                proptest::prop_assert!(!(f && faces_light(&r, &l)));
            }
        }

        /// The f64 filter never decides against the exact determinant, with
        /// lights within rounding of the plane (where it must defer) and
        /// vertices over 80 orders of magnitude.
        #[test]
        fn the_filter_agrees_with_the_exact_sign(
            v in proptest::array::uniform3(proptest::array::uniform3(-1.0f64..1.0)),
            e in proptest::array::uniform3(-40i32..40),
            st in proptest::array::uniform2(-2.0f64..2.0),
            off in -40i32..2,
            sun in proptest::bool::ANY,
        ) {
            let [a, b, c] = [0, 1, 2].map(|k| DVec3::from(v[k]) * 10f64.powi(e[k]));
            let n = (b - a).cross(c - a);
            let in_plane = a + (b - a) * st[0] + (c - a) * st[1];
            let toward = if sun {
                Toward::Direction((b - a) * st[0] + (c - a) * st[1] + n * 10f64.powi(off))
            } else {
                Toward::Point(in_plane + n * 10f64.powi(off))
            };
            proptest::prop_assert_eq!(
                orientation(a, b, c, toward),
                exact::orientation(a, b, c, toward)
            );
        }

        /// The fixed-width exact sign equals the big-integer one, for
        /// lights within rounding of the plane, exactly in it (integer
        /// grids, axis-aligned suns), and spreads up to the fixed width's.
        #[test]
        fn the_fixed_width_sign_equals_the_big_integer_sign(
            v in proptest::array::uniform3(proptest::array::uniform3(-1.0f64..1.0)),
            e in proptest::array::uniform3(-30i32..30),
            st in proptest::array::uniform2(-2.0f64..2.0),
            off in -330i32..2,
            grid in proptest::bool::ANY,
            sun in proptest::bool::ANY,
        ) {
            let snap = |p: DVec3| if grid { (p * 8.0).round() } else { p };
            let [a, b, c] = [0, 1, 2].map(|k| snap(DVec3::from(v[k]) * 10f64.powi(e[k])));
            let n = (b - a).cross(c - a);
            let off = if grid { 0.0 } else { 2f64.powi(off) };
            let toward = if sun {
                Toward::Direction(snap((b - a) * st[0] + (c - a) * st[1]) + n * off)
            } else {
                Toward::Point(snap(a + (b - a) * st[0] + (c - a) * st[1]) + n * off)
            };
            proptest::prop_assert_eq!(
                exact::orientation(a, b, c, toward),
                exact::big_orientation(a, b, c, toward)
            );
        }
    }
}
