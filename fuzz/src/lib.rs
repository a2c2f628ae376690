//! What the fuzz targets share: reading the fuzzer's bytes as values.

/// The fuzzer's bytes read as values, front to back; zeros past the end, so
/// that every input, however short, is a complete case.
pub struct Bytes<'a>(pub &'a [u8]);

impl Bytes<'_> {
    /// The next byte.
    pub fn u8(&mut self) -> u8 {
        let (b, rest) = self.0.split_first().map_or((0, &[][..]), |(b, r)| (*b, r));
        self.0 = rest;
        b
    }

    /// The next four bytes, little-endian.
    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }

    /// The next two bytes as a fraction in [0, 1].
    pub fn unit(&mut self) -> f64 {
        f64::from(u16::from_le_bytes([self.u8(), self.u8()])) / 65535.0
    }

    /// Any f32 bit pattern (NaN, ±∞, subnormals, huge).
    pub fn any_f32(&mut self) -> f32 {
        f32::from_bits(self.u32())
    }

    /// Any f64 bit pattern.
    pub fn any_f64(&mut self) -> f64 {
        f64::from_bits(u64::from(self.u32()) | (u64::from(self.u32()) << 32))
    }

    /// A small signed value in steps of `step` (−128·step ..= 127·step).
    pub fn small(&mut self, step: f32) -> f32 {
        f32::from(self.u8() as i8) * step
    }
}
