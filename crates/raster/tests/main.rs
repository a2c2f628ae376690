//! The rasterizer's integration tests: one test binary (`cargo test -p
//! shadowcull-raster --test main`), one module per area.

mod raster;
mod regression;
mod stencil;

use glam::{Mat4, Vec4};

/// Reversed-Z infinite perspective as in the scene crate: clip = (x·f/a, y·f, near, −z).
pub fn perspective(fov_y: f32, aspect: f32, near: f32) -> Mat4 {
    let f = 1.0 / (0.5 * fov_y).tan();
    Mat4::from_cols(
        Vec4::new(f / aspect, 0.0, 0.0, 0.0),
        Vec4::new(0.0, f, 0.0, 0.0),
        Vec4::new(0.0, 0.0, 0.0, -1.0),
        Vec4::new(0.0, 0.0, near, 0.0),
    )
}
