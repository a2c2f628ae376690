//! Errors of the visibility crate.

/// What can go wrong.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The rasterizer refused a command.
    #[error(transparent)]
    Raster(#[from] raster::Error),
    /// A light or view that cannot be used (names the field).
    #[error("{field}: {why}")]
    Invalid {
        /// The offending field.
        field: &'static str,
        /// Why.
        why: String,
    },
}

/// Result with [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
