//! Procedural scenes: the seeded city generator that stands in for the city of
//! [Steiner ch. 5] ([`city()`]), and small analytic test scenes whose shadows
//! are known exactly ([`analytic`]).

pub mod analytic;
pub mod city;
mod city_meshes;

pub use analytic::{
    box_mesh, box_over_plane, ground_with_boxes, horizontal_quad, open_quad, stacked_occluders,
};
pub use city::{city, city_bounds, city_height, CityParams};
