//! The hybrid's comparison bias and grazing limit, shared by its own maps
//! and the light views read as maps (see the module docs of `hybrid`).

/// Footprint reach, in texels: a texel ray meeting the receiver plane farther
/// than this from the surface point marks a grazing receiver, left to the
/// volumes (see `classify_point`). A receiver facing the light meets its
/// four rays within √2 texels; 4 admits planes up to about 70° from the
/// light. Measured on city_16384 `street` at 1280×1024 with a 1024² cube: a
/// wall lit at 85° was classified shadowed on 4,374 pixels without this rule.
pub(crate) const GRAZING_TEXELS: f64 = 4.0;

/// Depth-relative part of the comparison bias (see [`crate::hybrid`]).
pub const DEPTH_BIAS_REL: f64 = 1.0 / 65536.0;

/// Slope part of the comparison bias, in texels of receiver-plane slope.
pub const SLOPE_BIAS_TEXELS: f64 = 1.0 / 64.0;
