//! Mesh input in the host's own layout: positions read from a byte buffer at
//! an offset and a stride (an interleaved vertex buffer, a glTF accessor,
//! meshoptimizer's `vertex_positions`/`vertex_positions_stride`), indices as
//! `u16` or `u32`. The host hands its buffers over as they are; the mesh
//! keeps its own welded copy ([`Mesh::new`]), so nothing is borrowed past
//! the call.

use crate::{Error, Mesh, Result};
use glam::Vec3;

/// The components of one position in a [`StridedPositions`] buffer, in the
/// machine's byte order (glTF's little-endian on every platform shadowcull
/// builds for).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PositionFormat {
    /// Three `f32`: glTF's `VEC3`/`FLOAT`, 12 bytes.
    F32x3,
    /// Three `f64`, narrowed to `f32` as the mesh keeps them; 24 bytes.
    F64x3,
}

impl PositionFormat {
    /// Bytes of one position.
    pub const fn size(self) -> usize {
        match self {
            PositionFormat::F32x3 => 12,
            PositionFormat::F64x3 => 24,
        }
    }
}

/// `count` positions in `bytes`, the first at `offset`, each `stride` bytes
/// after the one before (at least [`PositionFormat::size`]); no alignment
/// is required.
#[derive(Clone, Copy, Debug)]
pub struct StridedPositions<'a> {
    /// The vertex buffer.
    pub bytes: &'a [u8],
    /// Byte offset of the first position.
    pub offset: usize,
    /// Bytes from one position to the next.
    pub stride: usize,
    /// Number of vertices.
    pub count: usize,
    /// The components' type.
    pub format: PositionFormat,
}

impl<'a> StridedPositions<'a> {
    /// `count` tightly packed or interleaved `f32 × 3` positions.
    pub fn f32(bytes: &'a [u8], offset: usize, stride: usize, count: usize) -> Self {
        StridedPositions {
            bytes,
            offset,
            stride,
            count,
            format: PositionFormat::F32x3,
        }
    }

    /// The positions, checked to lie inside the buffer.
    fn read(&self, mesh: &str) -> Result<Vec<Vec3>> {
        let size = self.format.size();
        let bad = |message: String| Error::InvalidMesh {
            mesh: mesh.to_string(),
            message,
        };
        if self.stride < size {
            return Err(bad(format!(
                "position stride {} is less than one position ({size} bytes)",
                self.stride
            )));
        }
        if self.count == 0 {
            return Ok(Vec::new());
        }
        let end = (self.count - 1)
            .checked_mul(self.stride)
            .and_then(|last| last.checked_add(self.offset))
            .and_then(|last| last.checked_add(size));
        if end.is_none_or(|end| end > self.bytes.len()) {
            return Err(bad(format!(
                "{} positions at offset {} and stride {} reach past the {}-byte buffer",
                self.count,
                self.offset,
                self.stride,
                self.bytes.len()
            )));
        }
        let at = |i: usize| &self.bytes[self.offset + i * self.stride..][..size];
        Ok((0..self.count)
            .map(|i| {
                let p = at(i);
                match self.format {
                    PositionFormat::F32x3 => {
                        let c = |k: usize| {
                            f32::from_ne_bytes(p[4 * k..4 * k + 4].try_into().unwrap_or_default())
                        };
                        Vec3::new(c(0), c(1), c(2))
                    }
                    PositionFormat::F64x3 => {
                        let c = |k: usize| {
                            f64::from_ne_bytes(p[8 * k..8 * k + 8].try_into().unwrap_or_default())
                                as f32
                        };
                        Vec3::new(c(0), c(1), c(2))
                    }
                }
            })
            .collect())
    }
}

/// A triangle list's indices, three per triangle.
#[derive(Clone, Copy, Debug)]
pub enum Indices<'a> {
    /// 16-bit indices.
    U16(&'a [u16]),
    /// 32-bit indices.
    U32(&'a [u32]),
}

impl Indices<'_> {
    /// Number of indices.
    pub fn len(&self) -> usize {
        match self {
            Indices::U16(i) => i.len(),
            Indices::U32(i) => i.len(),
        }
    }

    /// No indices.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The triangles, three indices each.
    fn triangles(&self, mesh: &str) -> Result<Vec<[u32; 3]>> {
        if !self.len().is_multiple_of(3) {
            return Err(Error::InvalidMesh {
                mesh: mesh.to_string(),
                message: format!("{} indices are not a multiple of 3", self.len()),
            });
        }
        Ok(match self {
            Indices::U16(i) => i
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]].map(u32::from))
                .collect(),
            Indices::U32(i) => i.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        })
    }
}

impl Mesh {
    /// Builds a mesh from the host's buffers as they are: `positions` read
    /// at their offset and stride, `indices` of either width. The same mesh
    /// as [`Mesh::new`] on the positions and triangles they hold.
    ///
    /// # Errors
    /// [`Error::InvalidMesh`] naming `name`: a stride shorter than a
    /// position, positions reaching past the buffer, an index count that is
    /// not a multiple of 3, and [`Mesh::new`]'s errors (an index out of
    /// range, a position that is not finite).
    pub fn from_strided(
        name: impl Into<String>,
        positions: StridedPositions<'_>,
        indices: Indices<'_>,
    ) -> Result<Mesh> {
        let name = name.into();
        let p = positions.read(&name)?;
        let t = indices.triangles(&name)?;
        Mesh::new(name, &p, &t)
    }

    /// This mesh deformed to the host's strided vertices: exactly
    /// `Mesh::from_strided(self.name(), positions, indices)`, built as
    /// [`Mesh::deformed`] builds (the edge table kept when the topology is).
    ///
    /// # Errors
    /// As [`Mesh::from_strided`].
    pub fn deformed_strided(
        &self,
        positions: StridedPositions<'_>,
        indices: Indices<'_>,
    ) -> Result<Mesh> {
        let p = positions.read(self.name())?;
        let t = indices.triangles(self.name())?;
        self.deformed(&p, &t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An interleaved buffer: per vertex a 4-byte tag, the position, a
    /// normal (ignored), after a 6-byte header.
    fn interleaved(positions: &[[f32; 3]]) -> Vec<u8> {
        let mut b = vec![0xAB; 6];
        for p in positions {
            b.extend_from_slice(&7u32.to_ne_bytes());
            for c in p {
                b.extend_from_slice(&c.to_ne_bytes());
            }
            b.extend_from_slice(&[0; 12]);
        }
        b
    }

    const QUAD: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];

    #[test]
    fn interleaved_positions_and_either_index_width_give_the_plain_mesh() {
        let bytes = interleaved(&QUAD);
        let plain =
            Mesh::new("quad", &QUAD.map(Vec3::from_array), &[[0, 1, 2], [0, 2, 3]]).unwrap();
        let strided = |i| Mesh::from_strided("quad", StridedPositions::f32(&bytes, 10, 28, 4), i);
        let a = strided(Indices::U16(&[0, 1, 2, 0, 2, 3])).unwrap();
        let b = strided(Indices::U32(&[0, 1, 2, 0, 2, 3])).unwrap();
        for m in [&a, &b] {
            assert_eq!(m.positions(), plain.positions());
            assert_eq!(m.triangles(), plain.triangles());
        }
        // f64 positions, packed.
        let wide: Vec<u8> = QUAD
            .iter()
            .flatten()
            .flat_map(|&c| f64::from(c).to_ne_bytes())
            .collect();
        let positions = StridedPositions {
            format: PositionFormat::F64x3,
            ..StridedPositions::f32(&wide, 0, 24, 4)
        };
        let c = Mesh::from_strided("quad", positions, Indices::U16(&[0, 1, 2, 0, 2, 3])).unwrap();
        assert_eq!(c.positions(), plain.positions());
    }

    #[test]
    fn bad_buffers_are_errors_naming_the_mesh() {
        let bytes = interleaved(&QUAD);
        let tri = Indices::U32(&[0, 1, 2]);
        let err = |p, i| match Mesh::from_strided("crate", p, i) {
            Err(Error::InvalidMesh { mesh, message }) => {
                assert_eq!(mesh, "crate");
                message
            }
            other => panic!("an InvalidMesh error, got {other:?}"),
        };
        let m = err(StridedPositions::f32(&bytes, 10, 8, 4), tri);
        assert!(m.contains("stride 8"), "{m}");
        // One byte short, and an overflowing count.
        let m = err(
            StridedPositions::f32(&bytes[..bytes.len() - 13], 10, 28, 4),
            tri,
        );
        assert!(m.contains("reach past"), "{m}");
        let m = err(StridedPositions::f32(&bytes, 10, 28, usize::MAX), tri);
        assert!(m.contains("reach past"), "{m}");
        let m = err(
            StridedPositions::f32(&bytes, 10, 28, 4),
            Indices::U16(&[0, 1]),
        );
        assert!(m.contains("multiple of 3"), "{m}");
        let m = err(
            StridedPositions::f32(&bytes, 10, 28, 4),
            Indices::U16(&[0, 1, 4]),
        );
        assert!(m.contains("vertex 4"), "{m}");
        // The exact length fits.
        let exact = &bytes[..bytes.len() - 12];
        assert!(Mesh::from_strided("crate", StridedPositions::f32(exact, 10, 28, 4), tri).is_ok());
    }
}
