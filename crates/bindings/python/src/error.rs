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
    bad(format!("{what}: {}", in_python_words(&e)))
}

/// A serde_json error in the words of the Python caller, who wrote keywords
/// and values, not JSON text: no position in the text, Python's names for
/// the values (`None`, `True`, a list, a dict) and plain words for the
/// Rust types it expected (an integer ≥ 0, a number). Unknown fields and
/// variants keep their lists of what is allowed.
pub(crate) fn in_python_words(e: &serde_json::Error) -> String {
    let message = e.to_string();
    // serde_json appends where in the text it stopped.
    let mut m = match message.rfind(" at line ") {
        Some(i) => message[..i].to_string(),
        None => message,
    };
    for (from, to) in [
        ("invalid type: null", "got None"),
        ("invalid type: boolean `true`", "got True"),
        ("invalid type: boolean `false`", "got False"),
        ("invalid type: sequence", "got a list"),
        ("invalid type: map", "got a dict"),
        ("invalid type: string", "got the string"),
        ("invalid type: integer", "got the integer"),
        ("invalid type: floating point", "got the number"),
        ("invalid value: integer", "got"),
        ("invalid value: floating point", "got"),
        ("invalid length", "got the length"),
        ("expected u8", "expected an integer from 0 to 255"),
        ("expected u16", "expected an integer from 0 to 65535"),
        ("expected u32", "expected an integer from 0 to 4294967295"),
        ("expected u64", "expected an integer ≥ 0"),
        ("expected usize", "expected an integer ≥ 0"),
        ("expected i32", "expected an integer"),
        ("expected f32", "expected a number"),
        ("expected f64", "expected a number"),
        ("expected a boolean", "expected True or False"),
        ("unknown field", "no such keyword"),
        ("unknown variant", "no such choice"),
    ] {
        m = m.replace(from, to);
    }
    // `got `-1``: the value as Python shows it, without serde's quotes.
    if let Some(i) = m.find("got `") {
        let start = i + "got ".len();
        if let Some(len) = m[start + 1..].find('`') {
            let value = m[start + 1..start + 1 + len].to_string();
            m.replace_range(start..start + len + 2, &value);
        }
    }
    m
}
