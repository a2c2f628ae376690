//! Camera paths: a camera pose per frame, for jobs and benches.

use crate::LookAt;
use glam::{DQuat, DVec3};

/// A camera pose as a function of the frame number.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub enum CameraPath {
    /// The same pose every frame.
    Fixed(LookAt),
    /// Moves eye and target by `per_frame` each frame (a dolly).
    Dolly {
        /// Pose at frame 0.
        start: LookAt,
        /// World-space translation per frame.
        per_frame: DVec3,
    },
    /// Rotates eye and target about the vertical (+y) axis through `center`,
    /// `deg_per_frame` degrees per frame (counter-clockwise seen from above).
    Orbit {
        /// Pose at frame 0.
        start: LookAt,
        /// A point on the rotation axis.
        center: DVec3,
        /// Degrees per frame.
        deg_per_frame: f64,
    },
    /// Linear interpolation of eye and target between keyframes `(frame, pose)`,
    /// frames ascending; held constant before the first and after the last.
    Keyframes(Vec<(f64, LookAt)>),
}

impl CameraPath {
    /// The pose at `frame`. An empty keyframe list yields `None`.
    pub fn at(&self, frame: u32) -> Option<LookAt> {
        let f = frame as f64;
        match self {
            CameraPath::Fixed(p) => Some(*p),
            CameraPath::Dolly { start, per_frame } => Some(LookAt {
                eye: start.eye + *per_frame * f,
                target: start.target + *per_frame * f,
                ..*start
            }),
            CameraPath::Orbit {
                start,
                center,
                deg_per_frame,
            } => {
                let q = DQuat::from_rotation_y((deg_per_frame * f).to_radians());
                Some(LookAt {
                    eye: *center + q * (start.eye - *center),
                    target: *center + q * (start.target - *center),
                    ..*start
                })
            }
            CameraPath::Keyframes(keys) => {
                let first = keys.first()?;
                if f <= first.0 {
                    return Some(first.1);
                }
                for w in keys.windows(2) {
                    let (a, b) = (&w[0], &w[1]);
                    if f <= b.0 {
                        let t = if b.0 > a.0 {
                            (f - a.0) / (b.0 - a.0)
                        } else {
                            1.0
                        };
                        return Some(LookAt {
                            eye: a.1.eye.lerp(b.1.eye, t),
                            target: a.1.target.lerp(b.1.target, t),
                            up: a.1.up.lerp(b.1.up, t),
                            fov_y_deg: a.1.fov_y_deg + (b.1.fov_y_deg - a.1.fov_y_deg) * t,
                            near: a.1.near + (b.1.near - a.1.near) * t,
                        });
                    }
                }
                keys.last().map(|k| k.1)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose() -> LookAt {
        LookAt {
            eye: DVec3::new(10.0, 5.0, 0.0),
            target: DVec3::new(0.0, 0.0, 0.0),
            up: DVec3::Y,
            fov_y_deg: 60.0,
            near: 0.5,
        }
    }

    #[test]
    fn orbit_keeps_distance_and_dolly_moves() {
        let o = CameraPath::Orbit {
            start: pose(),
            center: DVec3::ZERO,
            deg_per_frame: 90.0,
        };
        let p = o.at(1).unwrap();
        assert!((p.eye - DVec3::new(0.0, 5.0, -10.0)).length() < 1e-9);
        let d = CameraPath::Dolly {
            start: pose(),
            per_frame: DVec3::NEG_Z,
        };
        assert_eq!(d.at(3).unwrap().eye.z, -3.0);
        assert_eq!(d.at(3).unwrap().target.z, -3.0);
    }

    #[test]
    fn keyframes_interpolate_and_clamp() {
        let mut b = pose();
        b.eye.x = 20.0;
        let k = CameraPath::Keyframes(vec![(0.0, pose()), (10.0, b)]);
        assert_eq!(k.at(5).unwrap().eye.x, 15.0);
        assert_eq!(k.at(50).unwrap().eye.x, 20.0);
        assert!(CameraPath::Keyframes(vec![]).at(0).is_none());
    }
}
