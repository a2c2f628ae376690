//! Accessor reading (glTF 2.0 §3.6): typed, strided views into buffer views,
//! with optional sparse substitution.
//!
//! Nothing is trusted: type and componentType are checked for the role
//! (POSITION: VEC3 float, or integer with `KHR_mesh_quantization`; indices:
//! SCALAR unsigned, not normalized), `byteOffset + byteStride·(count−1) +
//! element size` must lie inside the buffer view and the view inside its
//! buffer, and positions must be finite. `min`/`max` are ignored. Sizes are
//! computed in `u64` with checked arithmetic, and memory is only allocated
//! after the data has been shown to exist.

use super::buffers::Buffers;
use super::document::{check_u32, deserialize, Ctx, Document};
use crate::Result;
use glam::Vec3;
use gltf_json::accessor::{
    Accessor, ComponentType, GenericComponentType, IndexComponentType, Type,
};
use gltf_json::validation::Checked;

/// Most elements an accessor without a bufferView (all zeros, possibly with
/// sparse substitution) may declare: its count is not backed by any bytes.
const MAX_UNBACKED_ELEMENTS: u64 = 1 << 20;

fn size_of(ct: ComponentType) -> usize {
    match ct {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

fn name_of(ct: ComponentType) -> &'static str {
    match ct {
        ComponentType::I8 => "BYTE",
        ComponentType::U8 => "UNSIGNED_BYTE",
        ComponentType::I16 => "SHORT",
        ComponentType::U16 => "UNSIGNED_SHORT",
        ComponentType::U32 => "UNSIGNED_INT",
        ComponentType::F32 => "FLOAT",
    }
}

fn type_name(t: Type) -> &'static str {
    match t {
        Type::Scalar => "SCALAR",
        Type::Vec2 => "VEC2",
        Type::Vec3 => "VEC3",
        Type::Vec4 => "VEC4",
        Type::Mat2 => "MAT2",
        Type::Mat3 => "MAT3",
        Type::Mat4 => "MAT4",
    }
}

/// An accessor's elements copied out tightly packed, sparse values applied.
struct Dense {
    bytes: Vec<u8>,
    ct: ComponentType,
    normalized: bool,
}

/// Reads a POSITION accessor as `f32` vectors (dequantized when
/// `KHR_mesh_quantization` integer types are used).
///
/// # Errors
/// [`crate::Error::Load`] naming the accessor (or `referrer` for a dangling
/// index, or the bufferView/buffer) on a wrong type, componentType or
/// normalization, data out of bounds, or a non-finite position.
pub(super) fn read_positions(
    doc: &Document,
    bufs: &mut Buffers<'_, '_>,
    index: usize,
    referrer: &str,
    ctx: &Ctx<'_>,
) -> Result<Vec<Vec3>> {
    let element = format!("accessor {index}");
    let quantized = doc.quantization();
    let d = read_dense(
        doc,
        bufs,
        index,
        referrer,
        Type::Vec3,
        ctx,
        |ct, normalized| match ct {
            ComponentType::F32 if normalized => {
                Err("normalized is true on a FLOAT accessor".into())
            }
            ComponentType::F32 => Ok(()),
            ComponentType::U32 => Err("POSITION cannot use componentType UNSIGNED_INT".into()),
            _ if quantized => Ok(()),
            other => Err(format!(
                "POSITION uses componentType {}, which needs the KHR_mesh_quantization extension \
                 (not declared in extensionsUsed)",
                name_of(other)
            )),
        },
    )?;
    let size = size_of(d.ct);
    let decode = |b: &[u8]| -> f32 {
        match (d.ct, d.normalized) {
            (ComponentType::F32, _) => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            (ComponentType::I8, false) => f32::from(b[0] as i8),
            (ComponentType::I8, true) => (f32::from(b[0] as i8) / 127.0).max(-1.0),
            (ComponentType::U8, false) => f32::from(b[0]),
            (ComponentType::U8, true) => f32::from(b[0]) / 255.0,
            (ComponentType::I16, false) => f32::from(i16::from_le_bytes([b[0], b[1]])),
            (ComponentType::I16, true) => {
                (f32::from(i16::from_le_bytes([b[0], b[1]])) / 32767.0).max(-1.0)
            }
            (ComponentType::U16, false) => f32::from(u16::from_le_bytes([b[0], b[1]])),
            (ComponentType::U16, true) => f32::from(u16::from_le_bytes([b[0], b[1]])) / 65535.0,
            // Rejected by the check above.
            (ComponentType::U32, _) => f32::NAN,
        }
    };
    let mut out = Vec::with_capacity(d.bytes.len() / (3 * size));
    for (i, e) in d.bytes.chunks_exact(3 * size).enumerate() {
        let p = Vec3::new(
            decode(&e[..size]),
            decode(&e[size..2 * size]),
            decode(&e[2 * size..]),
        );
        if !p.is_finite() {
            return Err(ctx.err(element, format!("position {i} is not finite: {p}")));
        }
        out.push(p);
    }
    Ok(out)
}

/// Reads an index accessor (SCALAR, UNSIGNED_BYTE/SHORT/INT, not normalized).
///
/// # Errors
/// As [`read_positions`]; range checks against the vertex count are the caller's.
pub(super) fn read_indices(
    doc: &Document,
    bufs: &mut Buffers<'_, '_>,
    index: usize,
    referrer: &str,
    ctx: &Ctx<'_>,
) -> Result<Vec<u32>> {
    let d = read_dense(
        doc,
        bufs,
        index,
        referrer,
        Type::Scalar,
        ctx,
        |ct, normalized| match ct {
            _ if normalized => Err("indices must not be normalized".into()),
            ComponentType::U8 | ComponentType::U16 | ComponentType::U32 => Ok(()),
            other => Err(format!(
                "indices must be UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT, not {}",
                name_of(other)
            )),
        },
    )?;
    Ok(decode_unsigned(&d.bytes, d.ct))
}

fn decode_unsigned(bytes: &[u8], ct: ComponentType) -> Vec<u32> {
    match ct {
        ComponentType::U8 => bytes.iter().map(|&b| u32::from(b)).collect(),
        ComponentType::U16 => bytes
            .chunks_exact(2)
            .map(|b| u32::from(u16::from_le_bytes([b[0], b[1]])))
            .collect(),
        _ => bytes
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect(),
    }
}

/// The bytes of bufferView `view` (checked against its buffer) and its stride.
fn view_bytes<'b>(
    doc: &Document,
    bufs: &'b mut Buffers<'_, '_>,
    view: usize,
    referrer: &str,
    ctx: &Ctx<'_>,
) -> Result<(&'b [u8], Option<usize>)> {
    let element = format!("bufferView {view}");
    let raw = doc.raw("bufferViews", "bufferView", view, referrer, ctx)?;
    check_u32(raw, &["buffer"], &element, ctx)?;
    let v: gltf_json::buffer::View = deserialize(raw, &element, ctx)?;
    let buffer = v.buffer.value();
    let data = bufs.get(doc, buffer, &element, ctx)?;
    let offset = v.byte_offset.map_or(0, |o| o.0);
    let length = v.byte_length.0;
    let end = offset.checked_add(length);
    match end {
        Some(end) if end <= data.len() as u64 => {
            // end <= data.len(), so both casts are exact.
            Ok((
                &data[offset as usize..end as usize],
                v.byte_stride.map(|s| s.0),
            ))
        }
        _ => Err(ctx.err(
            element,
            format!(
                "byteOffset {offset} + byteLength {length} exceeds buffer {buffer}'s byteLength {}",
                data.len()
            ),
        )),
    }
}

/// Checks that `count` elements of `size` bytes, `stride` apart, starting at
/// `offset`, fit in `len` bytes; returns the bytes needed.
fn span(offset: u64, stride: u64, count: u64, size: u64) -> Option<u64> {
    if count == 0 {
        return Some(offset);
    }
    offset
        .checked_add(stride.checked_mul(count - 1)?)?
        .checked_add(size)
}

/// Reads accessor `index` (named by `referrer`) as [`Dense`] bytes: its type
/// must be `expected`, and `allowed` judges its componentType and
/// normalization (an error message when the role cannot use them).
fn read_dense(
    doc: &Document,
    bufs: &mut Buffers<'_, '_>,
    index: usize,
    referrer: &str,
    expected: Type,
    ctx: &Ctx<'_>,
    allowed: impl Fn(ComponentType, bool) -> std::result::Result<(), String>,
) -> Result<Dense> {
    // Components per element: 3 for VEC3, 1 for SCALAR, ...
    let components = expected.multiplicity();
    let element = format!("accessor {index}");
    let raw = doc.raw("accessors", "accessor", index, referrer, ctx)?;
    for path in [
        &["bufferView"][..],
        &["componentType"],
        &["sparse", "indices", "bufferView"],
        &["sparse", "indices", "componentType"],
        &["sparse", "values", "bufferView"],
    ] {
        check_u32(raw, path, &element, ctx)?;
    }
    let acc: Accessor = deserialize(raw, &element, ctx)?;
    match acc.type_ {
        Checked::Valid(t) if t == expected => {}
        Checked::Valid(t) => {
            return Err(ctx.err(
                element,
                format!("type is {}, expected {}", type_name(t), type_name(expected)),
            ));
        }
        Checked::Invalid => return Err(ctx.err(element, "type is not a valid accessor type")),
    }
    let ct = match acc.component_type {
        Checked::Valid(GenericComponentType(ct)) => ct,
        Checked::Invalid => {
            return Err(ctx.err(element, "componentType is not a valid component type"))
        }
    };
    allowed(ct, acc.normalized).map_err(|m| ctx.err(&element, m))?;
    let size = size_of(ct) * components;
    let count = acc.count.0;
    let mut bytes = match acc.buffer_view {
        Some(view) => {
            let view = view.value();
            let (data, stride) = view_bytes(doc, bufs, view, &element, ctx)?;
            let stride = stride.unwrap_or(size);
            if stride < size {
                return Err(ctx.err(
                    element,
                    format!("bufferView {view}'s byteStride {stride} is smaller than the element size {size}"),
                ));
            }
            let offset = acc.byte_offset.map_or(0, |o| o.0);
            match span(offset, stride as u64, count, size as u64) {
                Some(need) if need <= data.len() as u64 => {}
                _ => {
                    return Err(ctx.err(
                        element,
                        format!(
                            "{count} elements of {size} bytes, {stride} apart from byteOffset {offset}, \
                             do not fit in bufferView {view}'s {} bytes",
                            data.len()
                        ),
                    ))
                }
            }
            // The span check bounds every slice below, and count·size ≤ data.len().
            let (offset, count) = (offset as usize, count as usize);
            let mut bytes = Vec::with_capacity(count * size);
            for i in 0..count {
                let at = offset + i * stride;
                bytes.extend_from_slice(&data[at..at + size]);
            }
            bytes
        }
        None if acc.sparse.is_none()
            && acc
                .extensions
                .as_ref()
                .is_some_and(|e| !e.others.is_empty()) =>
        {
            return Err(ctx.err(
                element,
                "has no bufferView; its data comes from an unsupported extension",
            ));
        }
        None if count > MAX_UNBACKED_ELEMENTS => {
            return Err(ctx.err(
                element,
                format!("has no bufferView but declares {count} elements (more than {MAX_UNBACKED_ELEMENTS})"),
            ));
        }
        // The specification: without a bufferView the elements are zeros.
        None => vec![0; count as usize * size],
    };
    if let Some(sparse) = &acc.sparse {
        let sparse_count = sparse.count.0;
        if sparse_count > count {
            return Err(ctx.err(
                element,
                format!("sparse.count {sparse_count} exceeds count {count}"),
            ));
        }
        let ict = match sparse.indices.component_type {
            Checked::Valid(IndexComponentType(ict)) => ict,
            Checked::Invalid => {
                return Err(ctx.err(
                    element,
                    "sparse.indices.componentType is not UNSIGNED_BYTE/SHORT/INT",
                ))
            }
        };
        let targets = {
            let view = sparse.indices.buffer_view.value();
            let (data, _) = view_bytes(doc, bufs, view, &element, ctx)?;
            let raw = sparse_slice(
                data,
                sparse.indices.byte_offset.0,
                sparse_count,
                size_of(ict),
            )
            .ok_or_else(|| {
                ctx.err(
                    &element,
                    format!("sparse indices do not fit in bufferView {view}"),
                )
            })?;
            decode_unsigned(raw, ict)
        };
        let view = sparse.values.buffer_view.value();
        let (data, _) = view_bytes(doc, bufs, view, &element, ctx)?;
        let values = sparse_slice(data, sparse.values.byte_offset.0, sparse_count, size)
            .ok_or_else(|| {
                ctx.err(
                    &element,
                    format!("sparse values do not fit in bufferView {view}"),
                )
            })?;
        for (k, (&t, value)) in targets.iter().zip(values.chunks_exact(size)).enumerate() {
            let range = (t as usize)
                .checked_mul(size)
                .and_then(|at| Some(at..at.checked_add(size)?));
            let Some(slot) = range.and_then(|r| bytes.get_mut(r)) else {
                return Err(ctx.err(
                    element,
                    format!("sparse index {k} is {t}, but count is {count}"),
                ));
            };
            slot.copy_from_slice(value);
        }
    }
    Ok(Dense {
        bytes,
        ct,
        normalized: acc.normalized,
    })
}

/// `count` tightly packed elements of `size` bytes at `offset` in `data`.
fn sparse_slice(data: &[u8], offset: u64, count: u64, size: usize) -> Option<&[u8]> {
    let end = span(offset, size as u64, count, size as u64)?;
    if end > data.len() as u64 {
        return None;
    }
    data.get(offset as usize..end as usize)
}
