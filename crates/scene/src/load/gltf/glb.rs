//! The GLB container (glTF 2.0 §4.4): a 12-byte header (magic `glTF`,
//! version 2, total length), a JSON chunk, then an optional BIN chunk.
//!
//! Every declared length is checked against the real byte length before it
//! is used, and nothing is allocated from a declared size: the chunks are
//! sub-slices of the input.

use super::document::Ctx;
use crate::Result;

/// The 4-byte magic at the start of every GLB file.
pub(super) const MAGIC: &[u8; 4] = b"glTF";
const HEADER: usize = 12;
const CHUNK_HEADER: usize = 8;
const JSON_CHUNK: u32 = 0x4E4F_534A;
const BIN_CHUNK: u32 = 0x004E_4942;

/// The chunks of a GLB file, borrowed from its bytes.
pub(super) struct Glb<'a> {
    /// The JSON chunk.
    pub json: &'a [u8],
    /// The BIN chunk, if present (the data of buffer 0 when it has no `uri`).
    pub bin: Option<&'a [u8]>,
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Splits a GLB file into its JSON and BIN chunks.
///
/// # Errors
/// [`crate::Error::Load`] with element `GLB header` or `GLB chunk k` when the
/// file is shorter than its header, has a wrong magic or version, declares a
/// length beyond the real bytes, has a truncated chunk, or lacks a JSON chunk.
pub(super) fn parse<'a>(bytes: &'a [u8], ctx: &mut Ctx<'_>) -> Result<Glb<'a>> {
    const H: &str = "GLB header";
    if bytes.len() < HEADER {
        return Err(ctx.err(
            H,
            format!(
                "the file has {} bytes, fewer than the 12-byte GLB header",
                bytes.len()
            ),
        ));
    }
    if !bytes.starts_with(MAGIC) {
        return Err(ctx.err(H, "the file does not start with the magic `glTF`"));
    }
    let version = u32_at(bytes, 4).unwrap_or_default();
    match version {
        2 => {}
        1 => {
            return Err(ctx.err(
                H,
                "binary glTF 1.0 (GLB version 1) is not supported (only glTF 2.0)",
            ))
        }
        v => return Err(ctx.err(H, format!("GLB version {v} is not supported (expected 2)"))),
    }
    let declared = u32_at(bytes, 8).unwrap_or_default() as usize;
    if declared < HEADER {
        return Err(ctx.err(
            H,
            format!("declared length {declared} is smaller than the 12-byte header"),
        ));
    }
    if declared > bytes.len() {
        return Err(ctx.err(
            H,
            format!(
                "declared length {declared} exceeds the file's {} bytes (truncated file?)",
                bytes.len()
            ),
        ));
    }
    if declared < bytes.len() {
        ctx.warn(
            H,
            format!(
                "{} bytes after the declared length {declared} are ignored",
                bytes.len() - declared
            ),
        );
    }
    let total = &bytes[..declared];
    let mut json = None;
    let mut bin = None;
    let mut at = HEADER;
    let mut k = 0usize;
    while at < total.len() {
        let element = format!("GLB chunk {k}");
        let rest = total.len() - at;
        if rest < CHUNK_HEADER {
            return Err(ctx.err(
                element,
                format!("only {rest} bytes left, fewer than an 8-byte chunk header"),
            ));
        }
        let len = u32_at(total, at).unwrap_or_default() as usize;
        let kind = u32_at(total, at + 4).unwrap_or_default();
        let start = at + CHUNK_HEADER;
        if len > total.len() - start {
            return Err(ctx.err(
                element,
                format!(
                    "declared length {len} exceeds the {} bytes left in the file",
                    total.len() - start
                ),
            ));
        }
        let data = &total[start..start + len];
        match (k, kind) {
            (0, JSON_CHUNK) => json = Some(data),
            (0, other) => {
                return Err(ctx.err(
                    element,
                    format!(
                        "the first chunk must be JSON (type 0x4E4F534A), found type 0x{other:08X}"
                    ),
                ))
            }
            (1, BIN_CHUNK) => bin = Some(data),
            (_, JSON_CHUNK) => ctx.warn(&element, "a second JSON chunk is ignored"),
            (_, BIN_CHUNK) => ctx.warn(
                &element,
                "a BIN chunk that is not the second chunk is ignored",
            ),
            // Unknown chunk types are skipped, as the specification asks.
            _ => {}
        }
        at = start + len;
        k += 1;
    }
    let json = json.ok_or_else(|| ctx.err(H, "the file has no JSON chunk"))?;
    Ok(Glb { json, bin })
}
