//! Presets: the options a kind of user starts from, and the options'
//! serialized form, which names a preset and overrides its fields.
//!
//! - [`Preset::Batch`] is [`PipelineOptions::default`]: a CPU mask
//!   (`stencil: bf`) and, in batch jobs, the reference every frame.
//! - [`Preset::GpuHost`] is [`PipelineOptions::gpu_host`]: a renderer that
//!   draws the volumes on its own GPU and wants PSR, PSC and the volumes only.
//!
//! A RON job's `pipeline: (preset: gpu_host, culling: chcpp)` (and the same
//! JSON in Python) starts from the preset and then takes every field it
//! names, in any order; without `preset` it starts from the batch preset, as
//! before presets existed.

use super::options::{
    AutoSpec, ChcppSpec, ClampingSpec, CoverageSpec, CullingSpec, OccludersSpec, PipelineOptions,
    StencilBackend,
};
use super::shadow_options::ClampReceiversSpec;
use raster::StencilBits;
use serde::{Deserialize, Deserializer, Serialize};
use shadowgen::MethodChoice;

/// A named starting point for [`PipelineOptions`] (`preset: gpu_host`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Preset {
    /// [`PipelineOptions::default`]: the CPU mask of a batch job.
    #[default]
    Batch,
    /// [`PipelineOptions::gpu_host`]: no CPU stencil, for a renderer that
    /// draws the volumes itself.
    GpuHost,
}

impl Preset {
    /// Every preset, as RON, JSON, C and the command line name them.
    pub const ALL: [(&'static str, Preset); 2] =
        [("batch", Preset::Batch), ("gpu_host", Preset::GpuHost)];

    /// The preset named `name` (`batch`, `gpu_host`), `None` for another name.
    pub fn from_name(name: &str) -> Option<Preset> {
        Preset::ALL
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, p)| *p)
    }

    /// The preset's options.
    pub fn options(self) -> PipelineOptions {
        match self {
            Preset::Batch => PipelineOptions::default(),
            Preset::GpuHost => PipelineOptions::gpu_host(),
        }
    }
}

impl std::str::FromStr for Preset {
    type Err = String;

    /// `batch` or `gpu_host` (the command lines' `--preset`).
    fn from_str(name: &str) -> Result<Preset, String> {
        Preset::from_name(name).ok_or_else(|| {
            let names: Vec<_> = Preset::ALL.iter().map(|(n, _)| *n).collect();
            format!("unknown preset `{name}`: expected {}", names.join(" or "))
        })
    }
}

impl PipelineOptions {
    /// The options a renderer that draws the shadow volumes on its own GPU
    /// starts from (`docs/host.md`):
    ///
    /// - `stencil: none`: no CPU stencil and no mask; the outputs are PSR,
    ///   PSC and the volumes;
    /// - `reference_every: 0`: no reference in batch runs;
    /// - `culling: auto`: each view culls where its cost model says it pays;
    /// - `scissor: true`: each volume's scissor rectangle, for the host's
    ///   scissor test;
    /// - `occluders: proxy`: the light views draw each solid convex mesh's
    ///   proxy, a few triangles inside it, in place of its mesh;
    /// - `clamping: none`: the host's fill is not this library's to price
    ///   yet, so nothing is spent on segments;
    /// - `culling_resolution: (1920, 1080)`: above 1080p the culling eye
    ///   pass runs coarse (conservative, `docs/host.md`), so its cost stops
    ///   growing with the output; up to 1080p it runs at the viewport,
    ///   where it culls far more.
    ///
    /// Every other field as in [`PipelineOptions::default`]. The exact mask
    /// is what the host's GPU draws from these volumes: culling is
    /// conservative (`coverage: conservative`).
    pub fn gpu_host() -> Self {
        PipelineOptions {
            stencil: StencilBackend::None,
            reference_every: 0,
            culling: CullingSpec::Auto,
            scissor: true,
            occluders: OccludersSpec::Proxy,
            clamping: ClampingSpec::None,
            culling_resolution: Some((1920, 1080)),
            ..PipelineOptions::default()
        }
    }
}

/// Deserializes a field that is present as `Some`, whatever its own type
/// (so that an `Option` field given as `None` is `Some(None)`).
fn present<'de, D: Deserializer<'de>, T: Deserialize<'de>>(d: D) -> Result<Option<T>, D::Error> {
    T::deserialize(d).map(Some)
}

/// Declares [`PipelineSection`], every field of [`PipelineOptions`] as an
/// `Option`, and its merge onto the preset. The merge names every field of
/// `PipelineOptions` without `..`, so a field added there and not here does
/// not compile.
macro_rules! pipeline_section {
    ($( $(#[$attr:meta])* $field:ident: $ty:ty, )*) => {
        /// The serialized form of [`PipelineOptions`]: a preset and the
        /// fields that override it.
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        pub(crate) struct PipelineSection {
            #[serde(default)]
            preset: Preset,
            $(
                $(#[$attr])*
                #[serde(default, deserialize_with = "present")]
                $field: Option<$ty>,
            )*
        }

        impl From<PipelineSection> for PipelineOptions {
            fn from(s: PipelineSection) -> Self {
                let base = s.preset.options();
                PipelineOptions {
                    $( $field: s.$field.unwrap_or(base.$field), )*
                }
            }
        }
    };
}

pipeline_section! {
    method: MethodChoice,
    stencil: StencilBackend,
    scissor: bool,
    depth_bounds: bool,
    #[serde(alias = "stencil_bits")]
    counters: StencilBits,
    tile: u32,
    full_shadow: bool,
    map_size: u32,
    culling_resolution: Option<(u32, u32)>,
    culling: CullingSpec,
    query_threshold: u32,
    coverage: CoverageSpec,
    chcpp: ChcppSpec,
    auto: AutoSpec,
    light_resolution: u32,
    two_sided: bool,
    occluders: OccludersSpec,
    finite_extrusion: bool,
    clamping: ClampingSpec,
    slices: u32,
    clamping_receivers: ClampReceiversSpec,
    clamp_vertex_cost: f64,
    clamp_pixel_cost: f64,
    count_fill: bool,
    threads: u32,
    reference_every: u32,
    reference: crate::reference::ReferenceOptions,
    max_memory: Option<crate::byte_size::ByteSize>,
    instruction_set: Option<raster::InstructionSet>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn json(s: &str) -> PipelineOptions {
        serde_json::from_str(s).unwrap()
    }

    #[test]
    fn a_preset_is_the_base_and_named_fields_override_it() {
        assert_eq!(json("{}"), PipelineOptions::default());
        assert_eq!(json(r#"{"preset": "batch"}"#), PipelineOptions::default());
        let gpu = PipelineOptions::gpu_host();
        assert_eq!(json(r#"{"preset": "gpu_host"}"#), gpu);
        assert_ne!(gpu, PipelineOptions::default());
        // Before or after the preset, a field wins over it.
        for s in [
            r#"{"preset": "gpu_host", "culling": "chcpp", "scissor": false}"#,
            r#"{"culling": "chcpp", "scissor": false, "preset": "gpu_host"}"#,
        ] {
            let o = json(s);
            assert_eq!(o.culling, CullingSpec::Chcpp);
            assert!(!o.scissor);
            assert_eq!(o.stencil, StencilBackend::None);
            assert_eq!(o.reference_every, 0);
        }
        // A field given as its own default still overrides the preset.
        assert_eq!(
            json(r#"{"preset": "gpu_host", "stencil": "bf"}"#).stencil,
            StencilBackend::Bf
        );
        // An `Option` field given as null is set to `None`, not left alone.
        let capped = PipelineOptions {
            instruction_set: Some(raster::InstructionSet::Portable),
            ..PipelineOptions::default()
        };
        let s = serde_json::to_string(&capped).unwrap();
        assert_eq!(json(&s), capped);
        assert_eq!(
            json(r#"{"instruction_set": null}"#).instruction_set,
            None::<raster::InstructionSet>
        );
    }

    #[test]
    fn serialized_options_read_back_equal_and_bad_names_are_errors() {
        for o in Preset::ALL.map(|(_, p)| p.options()) {
            let s = serde_json::to_string(&o).unwrap();
            assert_eq!(json(&s), o);
        }
        let e = serde_json::from_str::<PipelineOptions>(r#"{"preset": "gpu"}"#).unwrap_err();
        assert!(e.to_string().contains("gpu_host"), "{e}");
        let e = serde_json::from_str::<PipelineOptions>(r#"{"stencill": "bf"}"#).unwrap_err();
        assert!(e.to_string().contains("stencill"), "{e}");
        assert_eq!(Preset::from_name("gpu_host"), Some(Preset::GpuHost));
        assert_eq!(Preset::from_name("gpu"), None);
        assert_eq!("batch".parse(), Ok(Preset::Batch));
        let e = "gpu".parse::<Preset>().unwrap_err();
        assert!(e.contains("`gpu`") && e.contains("gpu_host"), "{e}");
    }
}
