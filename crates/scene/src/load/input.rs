//! Reading input files: regular files only, at most a process-wide size
//! limit, with errors naming the file.

use crate::{Error, Result};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// The default largest input file the loaders read (4 GiB): generous for
/// scenes, finite for `/dev/zero` or a runaway generator.
pub const DEFAULT_MAX_INPUT_BYTES: u64 = 4 << 30;

static MAX_INPUT_BYTES: AtomicU64 = AtomicU64::new(DEFAULT_MAX_INPUT_BYTES);

/// Sets, for the whole process, the largest file (scene, glTF buffer, job)
/// that [`read_input`] and the loaders read; larger files are an error
/// before anything is allocated. The CLI's `--max-input-size` sets it.
pub fn set_max_input_bytes(bytes: u64) {
    MAX_INPUT_BYTES.store(bytes, Ordering::Relaxed);
}

/// The largest input file read (see [`set_max_input_bytes`]).
pub fn max_input_bytes() -> u64 {
    MAX_INPUT_BYTES.load(Ordering::Relaxed)
}

/// Reads a whole input file: only a regular file (a FIFO would block
/// forever, a device never end), of at most [`max_input_bytes`].
///
/// # Errors
/// The I/O error; `InvalidInput` for anything but a regular file (naming its
/// kind), `FileTooLarge` past the limit (naming both sizes).
pub fn read_input(path: &Path) -> std::io::Result<Vec<u8>> {
    read_capped(path, max_input_bytes())
}

/// [`read_input`] with the limit `cap`.
pub(crate) fn read_capped(path: &Path, cap: u64) -> std::io::Result<Vec<u8>> {
    use std::io::{Error as IoError, ErrorKind, Read};
    // `metadata` follows symbolic links and opens nothing: a FIFO is refused
    // before an `open` that would wait for a writer.
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(IoError::new(
            ErrorKind::InvalidInput,
            format!(
                "not a regular file ({}): refusing to read it",
                file_kind(&meta)
            ),
        ));
    }
    let too_large = |len: u64| {
        IoError::new(
            ErrorKind::FileTooLarge,
            format!(
                "{len} bytes, more than the input size limit of {cap} bytes (raise it: --max-input-size, or scene::load::set_max_input_bytes)"
            ),
        )
    };
    if meta.len() > cap {
        return Err(too_large(meta.len()));
    }
    let mut bytes = Vec::new();
    bytes
        .try_reserve_exact(meta.len() as usize)
        .map_err(|e| IoError::new(ErrorKind::OutOfMemory, e.to_string()))?;
    // The file may grow while it is read: never past the limit.
    std::fs::File::open(path)?
        .take(cap.saturating_add(1))
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > cap {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// What a non-regular file is, for the error.
fn file_kind(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "not a file"
}

/// Reads a whole input file ([`read_input`]), naming it in the error.
pub(crate) fn read_file(path: &Path, referenced_from: Option<&Path>) -> Result<Vec<u8>> {
    read_input(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        referenced_from: referenced_from.map(Path::to_path_buf),
        source,
    })
}
