//! The intersection body and the light views on arbitrary view frusta,
//! scene bounds and lights. Checked, as the visibility tests state them, on
//! inputs in their domain (a scene within ±100, a camera near it, a light
//! anywhere around it): B ⊆ S; B is empty exactly when V ∩ S is; every
//! vertex of V ∩ S lies in B; a directional light gets one view, a
//! positional light at most six, any light but a spot at least one for a
//! non-empty B; the views cover every vertex of B (a spot's only where its
//! cone reaches; the light's own position, a vertex of B when the light is
//! in S, is lit by definition and not checked). Half the inputs take any bit pattern instead (NaN, ∞,
//! 1e300, a zero direction): those must not panic.

use crate::Bytes;
use glam::DVec3;
use shadowcull::scene::{Aabb, Camera, Light};
use shadowcull::visibility::{fit_light_views, intersection_body, Polyhedron};

/// Values in their test domain, or (wild inputs) sometimes any bit pattern.
struct Values<'a> {
    b: Bytes<'a>,
    wild: bool,
}

impl Values<'_> {
    /// In `[lo, hi]`, or (wild inputs, one in four) any f64 bit pattern.
    fn f64(&mut self, lo: f64, hi: f64) -> f64 {
        if self.wild && self.b.u8().is_multiple_of(4) {
            return self.b.any_f64();
        }
        lo + (hi - lo) * self.b.unit()
    }
    fn vec3(&mut self, lo: f64, hi: f64) -> DVec3 {
        DVec3::new(self.f64(lo, hi), self.f64(lo, hi), self.f64(lo, hi))
    }
    fn u8(&mut self) -> u8 {
        self.b.u8()
    }
}

/// One fuzz input through the target (a panic is a finding).
pub fn run(data: &[u8]) {
    let wild = data.first().is_some_and(|b| b % 2 == 1);
    let mut b = Values {
        b: Bytes(data.get(1..).unwrap_or(&[])),
        wild,
    };
    let lo = b.vec3(-100.0, 100.0);
    let size = b.vec3(0.0, 100.0);
    let hi = lo + size;
    let s = Aabb {
        min: lo.min(hi).as_vec3(),
        max: lo.max(hi).as_vec3(),
    };
    let c = s.center();
    let eye = c + b.vec3(-150.0, 150.0);
    let target = c + b.vec3(-50.0, 50.0);
    let fovy = b.f64(0.05, 3.0);
    let aspect = b.f64(0.25, 4.0);
    let near = b.f64(1e-3, 2.0);
    let Ok(cam) = Camera::look_at(eye, target, DVec3::Y, fovy, aspect, near) else {
        return;
    };
    let light = match b.u8() % 3 {
        0 => Light::Directional {
            direction: b.vec3(-1.0, 1.0),
        },
        1 => Light::Point {
            position: c + b.vec3(-300.0, 300.0),
            range: None,
        },
        _ => Light::Spot {
            position: c + b.vec3(-300.0, 300.0),
            direction: b.vec3(-1.0, 1.0),
            apex_angle: b.f64(0.01, 3.1),
            range: None,
        },
    };
    let resolution = 1 + u32::from(b.u8());
    let frustum = cam.frustum();
    let body = intersection_body(&frustum, &light, &s);
    let views = fit_light_views(&body, &light, resolution);
    if wild || light.validate().is_err() {
        return;
    }
    let far = light.position().map_or(0.0, |l| (l - c).length());
    let tol = 1e-12 * (s.size().as_dvec3().length() + far + c.length() + 1.0);
    let p = Polyhedron::from_frustum(&frustum, &s);
    assert_eq!(
        body.is_empty(),
        p.is_empty(),
        "B empty but not V ∩ S, or the reverse"
    );
    let (slo, shi) = (s.min.as_dvec3() - tol, s.max.as_dvec3() + tol);
    for v in body.vertices() {
        assert!(
            v.cmpge(slo).all() && v.cmple(shi).all(),
            "B's vertex {v} outside S"
        );
    }
    for v in p.vertices() {
        assert!(body.contains(*v, tol), "V ∩ S's vertex {v} outside B");
    }
    if body.is_empty() {
        assert!(views.is_empty());
        return;
    }
    let spot = matches!(light, Light::Spot { .. });
    match light {
        Light::Directional { .. } => assert_eq!(views.len(), 1),
        _ => assert!(views.len() <= 6 && (spot || !views.is_empty())),
    }
    // The light's own position (a vertex of B when the light is in S) has
    // no direction to be seen in: lit by definition, and not checked.
    let at_light = |v: DVec3| {
        light
            .position()
            .is_some_and(|l| (v - l).length() <= 1e-9 * (1.0 + l.length()))
    };
    for v in body.vertices() {
        if (spot && !light.reaches(*v)) || at_light(*v) {
            continue;
        }
        assert!(
            views.iter().any(|view| view.covers(*v, 1e-9)),
            "B's vertex {v} not covered by {views:?} (light {light:?}, S {s:?}, clip {:?})",
            views
                .iter()
                .map(|w| w.clip_from_world * v.extend(1.0))
                .collect::<Vec<_>>()
        );
    }
}
