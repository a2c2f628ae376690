//! The library's errors as Python exceptions: `OSError` for files (a missing
//! or unreadable scene, job or output directory, a busy output directory),
//! `MemoryError` when a buffer cannot be allocated, `ValueError` for
//! everything a caller got wrong; the message is the
//! library's own, which names the file, object or field.

use pyo3::exceptions::{PyMemoryError, PyOSError, PyValueError};
use pyo3::PyErr;
use shadowcull::scene;

/// Converts a library error.
pub(crate) fn to_py(e: shadowcull::Error) -> PyErr {
    let message = e.to_string();
    match e {
        shadowcull::Error::Io { .. }
        | shadowcull::Error::OutputBusy { .. }
        | shadowcull::Error::Scene(scene::Error::Io { .. }) => PyOSError::new_err(message),
        shadowcull::Error::OutOfMemory { .. }
        | shadowcull::Error::Raster(shadowcull::raster::Error::OutOfMemory { .. }) => {
            PyMemoryError::new_err(message)
        }
        _ => PyValueError::new_err(message),
    }
}

/// Converts a scene error (mesh building, loading).
pub(crate) fn scene_to_py(e: scene::Error) -> PyErr {
    to_py(shadowcull::Error::Scene(e))
}

/// A `ValueError` naming what was wrong with an argument.
pub(crate) fn bad(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// A JSON argument the Python layer built from keywords that the library's
/// serde types reject (an unknown option, a wrong type): a `ValueError`
/// starting with `what`.
pub(crate) fn bad_json(what: &str, e: serde_json::Error) -> PyErr {
    // serde_json appends where in the text it stopped; the caller wrote
    // keywords, not text, so only the message is shown.
    let message = e.to_string();
    let message = match message.rfind(" at line ") {
        Some(i) => &message[..i],
        None => &message,
    };
    bad(format!("{what}: {message}"))
}
