//! Lights: point (optional range), spot (full apex angle < 180°), directional.

use crate::{Error, Result};
use glam::DVec3;

/// A light source. Directions are world space; positions are f64.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Light {
    /// Omnidirectional point light; `range` (> 0) limits what it reaches.
    Point {
        /// World position.
        position: DVec3,
        /// Maximum distance lit, `None` for unlimited.
        range: Option<f64>,
    },
    /// Spot light with a circular cone around `direction`.
    Spot {
        /// World position (the cone's apex).
        position: DVec3,
        /// Axis of the cone, the direction the light shines (need not be unit).
        direction: DVec3,
        /// Full apex angle of the cone in radians, in (0, π).
        apex_angle: f64,
        /// Maximum distance lit, `None` for unlimited.
        range: Option<f64>,
    },
    /// Light from infinitely far away, e.g. the sun.
    Directional {
        /// The direction the light travels: from the sun toward the scene (need not be unit).
        direction: DVec3,
    },
}

fn light_err(field: &'static str, message: &str) -> Error {
    Error::InvalidLight {
        field,
        message: message.to_string(),
    }
}

fn check_dir(d: DVec3) -> Result<()> {
    if !d.is_finite() || d.length_squared() == 0.0 || !d.length_squared().is_finite() {
        return Err(light_err("direction", "must be finite and non-zero"));
    }
    Ok(())
}

fn check_range(range: Option<f64>) -> Result<()> {
    match range {
        Some(r) if !(r > 0.0 && r.is_finite()) => {
            Err(light_err("range", "must be positive and finite"))
        }
        _ => Ok(()),
    }
}

impl Light {
    /// Checks every field.
    ///
    /// # Errors
    /// [`Error::InvalidLight`] naming the field: non-finite position, zero or
    /// non-finite direction, apex angle outside (0°, 180°), non-positive range.
    pub fn validate(&self) -> Result<()> {
        match *self {
            Light::Point { position, range } => {
                if !position.is_finite() {
                    return Err(light_err("position", "must be finite"));
                }
                check_range(range)
            }
            Light::Spot {
                position,
                direction,
                apex_angle,
                range,
            } => {
                if !position.is_finite() {
                    return Err(light_err("position", "must be finite"));
                }
                check_dir(direction)?;
                if !(apex_angle > 0.0 && apex_angle < std::f64::consts::PI) {
                    return Err(light_err(
                        "apex_angle",
                        "full cone angle must lie strictly between 0° and 180°",
                    ));
                }
                check_range(range)
            }
            Light::Directional { direction } => check_dir(direction),
        }
    }

    /// The light's position, `None` for a directional light.
    pub fn position(&self) -> Option<DVec3> {
        match *self {
            Light::Point { position, .. } | Light::Spot { position, .. } => Some(position),
            Light::Directional { .. } => None,
        }
    }

    /// The homogeneous light position: `(p, 1)` for positional lights,
    /// `(−direction, 0)` (toward the light) for directional ones.
    pub fn homogeneous(&self) -> glam::DVec4 {
        match *self {
            Light::Point { position, .. } | Light::Spot { position, .. } => position.extend(1.0),
            Light::Directional { direction } => (-direction).extend(0.0),
        }
    }

    /// Unnormalised direction from `p` toward the light.
    pub fn toward_light(&self, p: DVec3) -> DVec3 {
        match *self {
            Light::Point { position, .. } | Light::Spot { position, .. } => position - p,
            Light::Directional { direction } => -direction,
        }
    }

    /// True when `p` is within the light's cone and range (always for a
    /// directional light, and for unlimited point lights). The cone and range
    /// test shared by the reference and the mask classes (DESIGN.md "Masks").
    pub fn reaches(&self, p: DVec3) -> bool {
        match *self {
            Light::Point { position, range } => match range {
                Some(r) => (p - position).length_squared() <= r * r,
                None => true,
            },
            Light::Spot {
                position,
                direction,
                apex_angle,
                range,
            } => {
                let v = p - position;
                let len2 = v.length_squared();
                if let Some(r) = range {
                    if len2 > r * r {
                        return false;
                    }
                }
                if len2 == 0.0 {
                    return false;
                }
                let cos = v.dot(direction) / (len2.sqrt() * direction.length());
                cos >= (0.5 * apex_angle).cos()
            }
            Light::Directional { .. } => true,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invalid_lights_are_errors() {
        let nan = Light::Point {
            position: DVec3::new(f64::NAN, 0.0, 0.0),
            range: None,
        };
        assert!(matches!(
            nan.validate(),
            Err(Error::InvalidLight {
                field: "position",
                ..
            })
        ));
        let zero = Light::Directional {
            direction: DVec3::ZERO,
        };
        assert!(matches!(
            zero.validate(),
            Err(Error::InvalidLight {
                field: "direction",
                ..
            })
        ));
        let wide = Light::Spot {
            position: DVec3::ZERO,
            direction: DVec3::NEG_Y,
            apex_angle: std::f64::consts::PI,
            range: None,
        };
        assert!(matches!(
            wide.validate(),
            Err(Error::InvalidLight {
                field: "apex_angle",
                ..
            })
        ));
        let r = Light::Point {
            position: DVec3::ZERO,
            range: Some(0.0),
        };
        assert!(matches!(
            r.validate(),
            Err(Error::InvalidLight { field: "range", .. })
        ));
    }

    #[test]
    fn spot_cone_and_range() {
        let s = Light::Spot {
            position: DVec3::ZERO,
            direction: DVec3::NEG_Y * 3.0,
            apex_angle: 90f64.to_radians(),
            range: Some(10.0),
        };
        assert!(s.validate().is_ok());
        assert!(s.reaches(DVec3::new(0.9, -1.0, 0.0)));
        assert!(!s.reaches(DVec3::new(1.1, -1.0, 0.0)));
        assert!(!s.reaches(DVec3::new(0.0, -10.5, 0.0)));
        assert!(!s.reaches(DVec3::new(0.0, 1.0, 0.0)));
    }
}
