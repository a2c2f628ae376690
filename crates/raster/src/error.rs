//! The crate's one error type.

/// Errors of the rasterizer's public API.
#[derive(Debug, thiserror::Error, Clone, PartialEq, Eq)]
pub enum Error {
    /// A target was created with a zero or too large size. Use a width and
    /// height in `1..=`[`crate::MAX_TARGET_SIZE`].
    #[error("invalid target size {width}x{height}: each side must lie in 1..={max}")]
    InvalidSize {
        /// Requested width in pixels.
        width: u32,
        /// Requested height in pixels.
        height: u32,
        /// The largest allowed side.
        max: u32,
    },
    /// A triangle index names a vertex past the end of the position slice.
    /// Fix the index buffer or pass the matching positions.
    #[error("triangle {triangle} names vertex {index}, but only {len} positions were given")]
    IndexOutOfRange {
        /// Triangle number within the draw or query.
        triangle: usize,
        /// The offending vertex index.
        index: u32,
        /// Number of positions passed.
        len: usize,
    },
    /// A receiver target does not have the size of the depth target it is used with.
    #[error("receiver target is {got:?}, depth target is {expected:?}")]
    SizeMismatch {
        /// (width, height) of the depth target.
        expected: (u32, u32),
        /// (width, height) of the receiver target.
        got: (u32, u32),
    },
    /// A per-pixel mask does not have one entry per pixel of the target.
    /// Pass `width × height` entries, row-major, row 0 at the top.
    #[error("per-pixel mask has {got} entries, the {width}x{height} target needs {expected}")]
    MaskLength {
        /// `width × height` of the target.
        expected: usize,
        /// Entries passed.
        got: usize,
        /// Target width.
        width: u32,
        /// Target height.
        height: u32,
    },
    /// A host's occlusion backend reported a failure.
    #[error("host backend: {message}")]
    Host {
        /// What failed.
        message: String,
    },
    /// A target's buffer could not be allocated. Use a smaller target, or
    /// free memory.
    #[error("out of memory: {what} of {width}x{height} needs {bytes} bytes")]
    OutOfMemory {
        /// The buffer (`depth`, `primitive ids`).
        what: &'static str,
        /// Target width.
        width: u32,
        /// Target height.
        height: u32,
        /// The allocation that failed.
        bytes: u64,
    },
}

/// A vector of `n` copies of `value`, or [`Error::OutOfMemory`] when the
/// allocation fails (instead of aborting the process): targets are sized by
/// the user's viewport.
pub(crate) fn try_filled<T: Clone>(
    n: usize,
    value: T,
    what: &'static str,
    (width, height): (u32, u32),
) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| Error::OutOfMemory {
        what,
        width,
        height,
        bytes: (n as u64).saturating_mul(std::mem::size_of::<T>() as u64),
    })?;
    v.resize(n, value);
    Ok(v)
}

/// Result with the crate's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

#[cfg(test)]
mod tests {
    use super::*;

    /// An allocation that cannot succeed is an error naming the buffer and
    /// its size, not an abort.
    #[test]
    fn a_failed_allocation_is_an_error() {
        let e = try_filled(usize::MAX / 4, 0u64, "depth", (16384, 16384)).unwrap_err();
        assert!(
            matches!(
                e,
                Error::OutOfMemory {
                    what: "depth",
                    width: 16384,
                    ..
                }
            ),
            "{e}"
        );
        assert!(
            e.to_string()
                .starts_with("out of memory: depth of 16384x16384"),
            "{e}"
        );
        assert_eq!(try_filled(3, 7u8, "depth", (1, 3)).unwrap(), [7, 7, 7]);
    }
}
