//! Status codes, the thread's last error message, and the guard every entry
//! point runs its body in: no panic crosses the C boundary.

use std::cell::RefCell;
use std::ffi::{c_char, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

/// What a call did. Every function of the library returns one.
#[allow(non_camel_case_types)]
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum sc_status {
    /// Success.
    SC_OK = 0,
    /// A NULL pointer, a bad `struct_size`, an unknown, destroyed or stale
    /// handle, or a value out of range; `sc_last_error()` names it.
    SC_INVALID_ARGUMENT = 1,
    /// An allocation failed.
    SC_OUT_OF_MEMORY = 2,
    /// A file could not be read or parsed.
    SC_IO = 3,
    /// A bug in the library (a caught panic); the message says where.
    SC_INTERNAL = 4,
}

/// A failed call: its status and message.
#[derive(Debug)]
pub(crate) struct Failure {
    pub status: sc_status,
    pub message: String,
}

impl Failure {
    /// An `SC_INVALID_ARGUMENT` failure naming the argument or field.
    pub fn invalid(message: impl Into<String>) -> Self {
        Failure {
            status: sc_status::SC_INVALID_ARGUMENT,
            message: message.into(),
        }
    }
}

impl From<shadowcull::Error> for Failure {
    fn from(e: shadowcull::Error) -> Self {
        use shadowcull::scene::Error as SceneError;
        let status = match &e {
            shadowcull::Error::Io { .. }
            | shadowcull::Error::Scene(SceneError::Io { .. } | SceneError::Load { .. }) => {
                sc_status::SC_IO
            }
            shadowcull::Error::OutOfMemory { .. }
            | shadowcull::Error::Raster(shadowcull::raster::Error::OutOfMemory { .. }) => {
                sc_status::SC_OUT_OF_MEMORY
            }
            _ => sc_status::SC_INVALID_ARGUMENT,
        };
        Failure {
            status,
            message: e.to_string(),
        }
    }
}

impl From<shadowcull::scene::Error> for Failure {
    fn from(e: shadowcull::scene::Error) -> Self {
        Failure::from(shadowcull::Error::from(e))
    }
}

/// The result type of the entry points' bodies.
pub(crate) type Result<T> = std::result::Result<T, Failure>;

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

/// Runs `body`, records a failure's message for `sc_last_error`, and maps a
/// panic to `SC_INTERNAL`: what every `extern "C"` function returns.
pub(crate) fn guard(name: &str, body: impl FnOnce() -> Result<()>) -> sc_status {
    let failure = match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => {
            set_last_error("");
            return sc_status::SC_OK;
        }
        Ok(Err(f)) => f,
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Failure {
                status: sc_status::SC_INTERNAL,
                message: format!("internal error: {what}"),
            }
        }
    };
    set_last_error(&format!("{name}: {}", failure.message));
    failure.status
}

fn set_last_error(message: &str) {
    // Interior NULs cannot occur in our messages; were one to, it is cut there.
    let text = message.split('\0').next().unwrap_or_default();
    let c = CString::new(text).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = c);
}

/// The message of the last failed call on this thread ("" after a success),
/// naming the function and the argument or field. The string stays valid
/// until the next call on this thread.
#[no_mangle]
pub extern "C" fn sc_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}
