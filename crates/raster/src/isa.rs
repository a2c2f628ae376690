//! The instruction sets the rasterizer's kernels are compiled for, and the one
//! this CPU runs. The per-mesh pipeline (`dispatch.rs`) and the stencil's row
//! kernels are built once per level with `#[target_feature]` and chosen at
//! runtime from the [`DepthTarget`](crate::DepthTarget)'s level: the detected
//! one, or a lower cap a host sets ([`DepthTarget::set_instruction_set`](crate::DepthTarget::set_instruction_set))
//! to compare builds or to rule one out. Every build gives bit-identical
//! results; a test checks it.

use std::str::FromStr;

/// An instruction-set level of the rasterizer's kernels, lowest first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "lowercase"))]
pub enum InstructionSet {
    /// The portable build (the baseline of the compilation target).
    Portable,
    /// x86-64 AVX2.
    Avx2,
    /// x86-64 AVX-512 F, VL, BW and DQ (with AVX2).
    Avx512,
}

impl InstructionSet {
    /// The highest level this CPU runs (detected once per process).
    pub fn detected() -> InstructionSet {
        #[cfg(target_arch = "x86_64")]
        {
            static DETECTED: std::sync::OnceLock<InstructionSet> = std::sync::OnceLock::new();
            *DETECTED.get_or_init(|| {
                if std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512vl")
                    && std::arch::is_x86_feature_detected!("avx512bw")
                    && std::arch::is_x86_feature_detected!("avx512dq")
                    && std::arch::is_x86_feature_detected!("avx2")
                {
                    InstructionSet::Avx512
                } else if std::arch::is_x86_feature_detected!("avx2") {
                    InstructionSet::Avx2
                } else {
                    InstructionSet::Portable
                }
            })
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            InstructionSet::Portable
        }
    }

    /// The level that runs when `self` is the cap: `self`, or the detected
    /// level when this CPU lacks `self`.
    pub fn capped(self) -> InstructionSet {
        self.min(InstructionSet::detected())
    }

    /// The cap the environment asks for, for tools that opt in (the
    /// `shadowcull` CLI and the benchmarks; the library never reads it):
    /// `SHADOWCULL_RASTER_SCALAR` set (and not `0`) caps at
    /// [`InstructionSet::Portable`], else `SHADOWCULL_RASTER_AVX2` at
    /// [`InstructionSet::Avx2`]; otherwise `None`.
    pub fn cap_from_env() -> Option<InstructionSet> {
        let set = |name| std::env::var_os(name).is_some_and(|v| !v.is_empty() && v != "0");
        if set("SHADOWCULL_RASTER_SCALAR") {
            Some(InstructionSet::Portable)
        } else if set("SHADOWCULL_RASTER_AVX2") {
            Some(InstructionSet::Avx2)
        } else {
            None
        }
    }

    /// The level's name as [`FromStr`] reads it.
    pub fn name(self) -> &'static str {
        match self {
            InstructionSet::Portable => "portable",
            InstructionSet::Avx2 => "avx2",
            InstructionSet::Avx512 => "avx512",
        }
    }
}

impl Default for InstructionSet {
    /// The detected level.
    fn default() -> Self {
        InstructionSet::detected()
    }
}

impl std::fmt::Display for InstructionSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for InstructionSet {
    type Err = String;

    /// `portable`, `avx2` or `avx512` (any case).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "portable" => Ok(InstructionSet::Portable),
            "avx2" => Ok(InstructionSet::Avx2),
            "avx512" => Ok(InstructionSet::Avx512),
            _ => Err(format!(
                "unknown instruction set `{s}` (expected portable, avx2 or avx512)"
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_caps_never_exceed_the_cpu() {
        for l in [
            InstructionSet::Portable,
            InstructionSet::Avx2,
            InstructionSet::Avx512,
        ] {
            assert_eq!(l.name().parse::<InstructionSet>(), Ok(l));
            assert_eq!(
                l.to_string().to_uppercase().parse::<InstructionSet>(),
                Ok(l)
            );
            assert!(l.capped() <= InstructionSet::detected());
            assert!(l.capped() <= l);
        }
        assert_eq!(InstructionSet::Portable.capped(), InstructionSet::Portable);
        let e = "sse".parse::<InstructionSet>().unwrap_err();
        assert!(e.contains("`sse`") && e.contains("avx512"), "{e}");
    }
}
