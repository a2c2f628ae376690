//! Buffer data: the GLB BIN chunk, base64 `data:` URIs and external files
//! (through the caller's `resolve`), loaded when geometry first needs them
//! and cut to the buffer's `byteLength` after checking that the data holds it.

use super::document::{Ctx, Document};
use crate::{Error, Result};
use gltf_json::buffer::Buffer;
use serde_json::Value;
use std::borrow::Cow;
use std::path::Path;

/// Loads a buffer's bytes given its (percent-decoded, relative) URI.
pub(super) type Resolve<'r> = dyn FnMut(&str) -> std::io::Result<Vec<u8>> + 'r;

/// The buffers of one file, each loaded at most once.
pub(super) struct Buffers<'a, 'r> {
    bin: Option<&'a [u8]>,
    is_glb: bool,
    resolve: &'r mut Resolve<'r>,
    cache: Vec<Option<Cow<'a, [u8]>>>,
}

impl<'a, 'r> Buffers<'a, 'r> {
    pub(super) fn new(
        doc: &Document,
        bin: Option<&'a [u8]>,
        is_glb: bool,
        resolve: &'r mut Resolve<'r>,
        ctx: &Ctx<'_>,
    ) -> Result<Self> {
        let n = doc.len("buffers", ctx)?;
        Ok(Buffers {
            bin,
            is_glb,
            resolve,
            cache: vec![None; n],
        })
    }

    /// The bytes of buffer `index`, exactly `byteLength` long.
    ///
    /// # Errors
    /// A dangling index (naming `referrer`), a missing external file
    /// ([`Error::Io`] with `referenced_from` = the glTF file), a malformed or
    /// unsupported URI, or data shorter than `byteLength`.
    pub(super) fn get(
        &mut self,
        doc: &Document,
        index: usize,
        referrer: &str,
        ctx: &Ctx<'_>,
    ) -> Result<&[u8]> {
        if self.cache.get(index).is_some_and(Option::is_none) {
            let data = self.load(doc, index, referrer, ctx)?;
            self.cache[index] = Some(data);
        }
        match self.cache.get(index) {
            Some(Some(data)) => Ok(data),
            _ => Err(ctx.err(
                referrer,
                format!(
                    "refers to buffer {index}, but the file has {} buffers",
                    self.cache.len()
                ),
            )),
        }
    }

    fn load(
        &mut self,
        doc: &Document,
        index: usize,
        referrer: &str,
        ctx: &Ctx<'_>,
    ) -> Result<Cow<'a, [u8]>> {
        let element = format!("buffer {index}");
        let buffer: Buffer = doc.get("buffers", "buffer", index, referrer, ctx)?;
        let length = buffer.byte_length.0;
        let data: Cow<'a, [u8]> = match buffer.uri.as_deref() {
            None => {
                let fallback = buffer
                    .extensions
                    .as_ref()
                    .and_then(|e| e.others.get("EXT_meshopt_compression"))
                    .and_then(|m| m.get("fallback"))
                    .and_then(Value::as_bool)
                    .unwrap_or(false);
                if fallback {
                    return Err(ctx.err(
                        element,
                        "holds no data: it is an EXT_meshopt_compression fallback, and \
                         meshopt-compressed geometry is not supported",
                    ));
                }
                match (index, self.bin) {
                    (0, Some(bin)) => Cow::Borrowed(bin),
                    (0, None) if self.is_glb => {
                        return Err(
                            ctx.err(element, "has no uri, and the GLB file has no BIN chunk")
                        )
                    }
                    _ => {
                        return Err(ctx.err(
                            element,
                            "has no uri (only buffer 0 of a .glb file may omit it)",
                        ))
                    }
                }
            }
            Some(uri) if uri.starts_with("data:") => {
                Cow::Owned(decode_data_uri(uri).map_err(|m| ctx.err(&element, m))?)
            }
            Some(uri) => {
                let relative = relative_path(uri).map_err(|m| ctx.err(&element, m))?;
                let file = ctx.file();
                let data = (self.resolve)(&relative).map_err(|source| Error::Io {
                    path: file.parent().unwrap_or(Path::new("")).join(&relative),
                    referenced_from: Some(file.to_path_buf()),
                    source,
                })?;
                Cow::Owned(data)
            }
        };
        let have = data.len() as u64;
        if have < length {
            return Err(ctx.err(
                element,
                format!("byteLength is {length}, but its data has only {have} bytes"),
            ));
        }
        // `length <= have <= usize::MAX`, so the cast is exact.
        Ok(match data {
            Cow::Borrowed(b) => Cow::Borrowed(&b[..length as usize]),
            Cow::Owned(mut v) => {
                v.truncate(length as usize);
                Cow::Owned(v)
            }
        })
    }
}

/// Decodes `data:[<media type>];base64,<data>`.
fn decode_data_uri(uri: &str) -> std::result::Result<Vec<u8>, String> {
    let Some((header, payload)) = uri.split_once(',') else {
        return Err("data URI has no `,` before its data".into());
    };
    if !header.ends_with(";base64") {
        return Err(format!(
            "data URI `{header},...` is not base64-encoded (only `;base64` data URIs are supported)"
        ));
    }
    decode_base64(payload)
}

/// Standard base64 (RFC 4648 §4), padding optional, ASCII whitespace skipped.
pub(super) fn decode_base64(text: &str) -> std::result::Result<Vec<u8>, String> {
    fn sextet(c: u8) -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    }
    let mut out = Vec::with_capacity(text.len() / 4 * 3 + 3);
    let mut acc = 0u32;
    let mut bits = 0u32;
    let mut padding = 0usize;
    for (i, c) in text.bytes().enumerate() {
        if c.is_ascii_whitespace() {
            continue;
        }
        if c == b'=' {
            padding += 1;
            continue;
        }
        let Some(v) = (if padding == 0 { sextet(c) } else { None }) else {
            return Err(format!(
                "data URI: invalid base64 at character {i} of the data"
            ));
        };
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    if bits >= 6 || padding > 2 {
        return Err("data URI: base64 data has a wrong length".into());
    }
    Ok(out)
}

/// Checks that `uri` is a relative reference and percent-decodes it.
fn relative_path(uri: &str) -> std::result::Result<String, String> {
    let scheme_end = uri
        .find(|c: char| !(c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.')))
        .filter(|&i| uri[i..].starts_with(':'));
    if let Some(i) = scheme_end {
        let scheme = &uri[..i];
        return Err(format!(
            "URI `{uri}` has the scheme `{scheme}:`; only relative references and data: URIs are supported"
        ));
    }
    if uri.starts_with('/') || uri.starts_with('\\') {
        return Err(format!(
            "URI `{uri}` is absolute; only relative references and data: URIs are supported"
        ));
    }
    if uri.is_empty() {
        return Err("URI is empty".into());
    }
    Ok(percent_decode(uri))
}

/// `%XX` → byte; invalid escapes stay as they are, invalid UTF-8 is replaced.
fn percent_decode(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            if let (Some(h), Some(l)) = (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips_known_vectors() {
        assert_eq!(decode_base64("").unwrap(), b"");
        assert_eq!(decode_base64("Zg==").unwrap(), b"f");
        assert_eq!(decode_base64("Zm8=").unwrap(), b"fo");
        assert_eq!(decode_base64("Zm9v").unwrap(), b"foo");
        assert_eq!(decode_base64("Zm9vYg").unwrap(), b"foob");
        assert!(decode_base64("Zm9v!").is_err());
        assert!(decode_base64("Z").is_err());
        assert!(decode_base64("Zg==Zg").is_err());
    }

    #[test]
    fn uris_are_relative_and_percent_decoded() {
        assert_eq!(relative_path("my%20file.bin").unwrap(), "my file.bin");
        assert_eq!(relative_path("a/b%2").unwrap(), "a/b%2");
        assert!(relative_path("http://example.com/x.bin").is_err());
        assert!(relative_path("/etc/x.bin").is_err());
        assert!(relative_path(":").is_err());
        assert_eq!(relative_path("../x.bin").unwrap(), "../x.bin");
    }
}
