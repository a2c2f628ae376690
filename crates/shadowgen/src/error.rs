//! The crate's one error type.

/// Errors of shadow-volume construction.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The light failed validation (NaN position, zero or NaN direction, spot
    /// cone ≥ 180°, bad range). Fix the named field of the light.
    #[error("invalid light: {0}")]
    Light(#[from] scene::Error),
    /// A caster id does not name an object of the scene. Pass ids from this scene.
    #[error("caster {id} is not an object of the scene ({objects} objects)")]
    UnknownObject {
        /// The offending id.
        id: u32,
        /// Number of objects in the scene.
        objects: usize,
    },
    /// The volume buffer would need more than `u32::MAX` vertices or indices.
    /// Build fewer casters per buffer.
    #[error("volume buffer overflow: more than u32::MAX vertices or indices")]
    BufferOverflow,
    /// A sweep-and-prune update named more boxes than its keys can hold
    /// (ids up to `MAX_BOX_ID`, 2³¹ − 1). Split the set over several states.
    #[error("sweep-and-prune over {boxes} boxes: ids past 2^31 - 1 do not fit its keys")]
    TooManyBoxes {
        /// The number of boxes passed.
        boxes: usize,
    },
}

/// Result with the crate's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
