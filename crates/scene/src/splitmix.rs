//! SplitMix64 (Steele, Lea, Flood 2014): the workspace's one small
//! deterministic generator. The procedural city draws its blocks from it, and
//! CHC++ its per-node revisit phases; both need the same numbers on every
//! machine and from every thread count, which a seeded Weyl sequence gives.

/// One step of SplitMix64: advances the Weyl sequence `state` and returns its
/// mixed value. `splitmix64(&mut seed)` on a copy is a good 64-bit hash of `seed`.
pub fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_reference_sequence() {
        // The published test vector: the first outputs for seed 1234567.
        let mut s = 1234567;
        let got: Vec<u64> = (0..3).map(|_| splitmix64(&mut s)).collect();
        assert_eq!(
            got,
            [
                6457827717110365317,
                3203168211198807973,
                9817491932198370423
            ]
        );
    }
}
