//! The memory a run will need, estimated before anything big is allocated,
//! and the limit it must fit: [`PipelineOptions::max_memory`], by default
//! three quarters of the machine's memory.
//!
//! Why: a 16384×16384 job with the reference grew past 13.6 GB and aborted
//! when one 3 GiB allocation failed; a city of 10⁶ objects ran out of memory
//! while it was still being generated; `frames: 1000000000` keeps a billion
//! rows for the summary. Each is refused up front instead, naming the fields
//! that drive the estimate.
//!
//! The model is linear in what it counts, with coefficients measured on
//! the procedural city (peak RSS of `shadowcull run` at 400×300 to
//! 3200×2400, light views of 512² to 4096², with and without the reference;
//! the notes of the hostile-input issue give the runs) and rounded up, so it
//! overestimates by 15–30 %: it is a guard against runs that cannot fit, not
//! a prediction.

use crate::{Error, PipelineOptions, Result, StencilBackend};
use std::sync::OnceLock;

/// Process, code, thread pools and small tables.
const BASE: u64 = 64 << 20;
/// Per scene triangle: meshes, welded topology, silhouette caches, hierarchy.
const PER_TRIANGLE: u64 = 100;
/// Per object: transform, bounds, per-view culling state.
const PER_OBJECT: u64 = 512;
/// Per viewport pixel: eye depth and primitive ids, the surface points
/// (measured), and the culled eye traversal's second target for its right
/// half (12 bytes, added after).
const PER_PIXEL: u64 = 52;
/// Per viewport pixel and light: stencil counters, the mask, tiles, and the
/// stencil's computation mask (a masked copy of the eye depth, 4 bytes, and
/// its flags, 1 byte).
const PER_PIXEL_LIGHT: u64 = 30;
/// Per viewport pixel of the reference: classes, primitives, cosines, rays.
const PER_PIXEL_REFERENCE: u64 = 48;
/// Per scene triangle of the reference's world-space triangle BVH.
const PER_TRIANGLE_REFERENCE: u64 = 360;
/// Per light-view texel and light: depth, ids, receiver depths, the spare
/// receiver target a crowded view's marking splits into, and each thread's
/// quarter-size targets for a crowded view culled as quadrants (4 bytes).
const PER_LIGHT_TEXEL: u64 = 36;
/// Per viewport pixel and light of `count_fill`'s scratch stencil.
const PER_PIXEL_LIGHT_FILL: u64 = 2;
/// Per hybrid shadow-map texel and light.
const PER_MAP_TEXEL: u64 = 8;
/// Per light-view texel, view and light the hybrid keeps with point-sampled
/// light views (each view's depth after the light pass: 4 bytes and its
/// tiles' bounds).
const PER_KEPT_VIEW_TEXEL: u64 = 5;
/// Most light views a light has (the six cube faces).
const MAX_VIEWS: u64 = 6;

/// What a run holds, for [`estimate`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Workload {
    /// Viewport width in pixels.
    pub width: u32,
    /// Viewport height in pixels.
    pub height: u32,
    /// Lights per frame.
    pub lights: u32,
    /// Scene triangles (drawn instances).
    pub triangles: u64,
    /// Scene objects.
    pub objects: u64,
    /// Frame-and-light rows a batch job keeps for its summary (0 for a host).
    pub rows: u64,
}

/// An estimate: the total and its parts, each named by the field that drives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// Bytes in all.
    pub total: u64,
    /// `(field, bytes)`, largest first; parts that do not apply are 0.
    /// (An array: a frame checks its estimate without allocating.)
    pub parts: [(&'static str, u64); 6],
}

/// Estimates the memory of running `options` on `w`.
pub fn estimate(options: &PipelineOptions, w: &Workload) -> MemoryEstimate {
    let pixels = u64::from(w.width) * u64::from(w.height);
    let lights = u64::from(w.lights);
    let texels = u64::from(options.light_resolution).pow(2);
    let m = |a: u64, b: u64| a.saturating_mul(b);
    let reference = if options.reference_every > 0 {
        m(pixels, PER_PIXEL_REFERENCE).saturating_add(m(w.triangles, PER_TRIANGLE_REFERENCE))
    } else {
        0
    };
    let map = if options.stencil == StencilBackend::Hybrid {
        m(m(lights, u64::from(options.map_size).pow(2)), PER_MAP_TEXEL)
    } else {
        0
    };
    let mut parts = [
        (
            "resolution",
            m(
                pixels,
                PER_PIXEL
                    + m(
                        lights,
                        PER_PIXEL_LIGHT + u64::from(options.count_fill) * PER_PIXEL_LIGHT_FILL,
                    ),
            ),
        ),
        (
            "scene",
            BASE.saturating_add(m(w.triangles, PER_TRIANGLE))
                .saturating_add(m(w.objects, PER_OBJECT)),
        ),
        (
            "light_resolution",
            m(
                m(lights, texels),
                PER_LIGHT_TEXEL
                    + u64::from(options.light_pass_options().keep_depth)
                        * MAX_VIEWS
                        * PER_KEPT_VIEW_TEXEL,
            ),
        ),
        (
            "frames",
            m(w.rows, std::mem::size_of::<crate::stats::FrameRow>() as u64),
        ),
        ("reference_every", reference),
        ("map_size", map),
    ];
    parts.sort_unstable_by_key(|p| std::cmp::Reverse(p.1));
    MemoryEstimate {
        total: parts.iter().fold(0u64, |t, p| t.saturating_add(p.1)),
        parts,
    }
}

impl MemoryEstimate {
    /// Checks the estimate against `limit` bytes.
    ///
    /// # Errors
    /// [`Error::Options`] on field `max_memory`, naming the estimate, the
    /// limit and the fields that make up most of the estimate, largest first.
    pub fn check(&self, limit: u64) -> Result<()> {
        if self.total <= limit {
            return Ok(());
        }
        let mut named = Vec::new();
        let mut covered = 0u64;
        for &(field, bytes) in &self.parts {
            if covered >= self.total / 10 * 9 || bytes == 0 {
                break;
            }
            covered = covered.saturating_add(bytes);
            named.push(format!("`{field}` {}", human(bytes)));
        }
        Err(Error::Options {
            field: "max_memory".into(),
            message: format!(
                "this run needs about {} of memory, more than the limit of {} ({}); lower those fields, or raise `max_memory` (CLI: --max-memory)",
                human(self.total),
                human(limit),
                named.join(", ")
            ),
        })
    }
}

/// The limit of `options`: [`PipelineOptions::max_memory`], else three
/// quarters of the machine's memory ([`machine_memory`]), else none.
pub fn limit(options: &PipelineOptions) -> u64 {
    options
        .max_memory
        .map(|b| b.0)
        .or_else(|| machine_memory().map(|m| m / 4 * 3))
        .unwrap_or(u64::MAX)
}

/// The machine's physical memory in bytes (`MemTotal` of `/proc/meminfo`),
/// read once; `None` where it cannot be read.
pub fn machine_memory() -> Option<u64> {
    static TOTAL: OnceLock<Option<u64>> = OnceLock::new();
    *TOTAL.get_or_init(|| {
        let text = std::fs::read_to_string("/proc/meminfo").ok()?;
        let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
        let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        kib.checked_mul(1024)
    })
}

/// The process's peak resident set in bytes so far (`VmHWM` of
/// `/proc/self/status`); `None` where it cannot be read (not Linux).
pub fn peak_rss_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = text.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// Bytes for people, in the binary units `--max-memory` takes: `12.7 GiB`.
fn human(bytes: u64) -> String {
    let b = bytes as f64;
    match bytes {
        0..=0xF_FFFF => format!("{:.0} KiB", b / 1024.0),
        0x10_0000..=0x3FFF_FFFF => format!("{:.0} MiB", b / 1048576.0),
        _ => format!("{:.1} GiB", b / 1073741824.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::byte_size::ByteSize;

    fn city_at(width: u32, height: u32) -> Workload {
        Workload {
            width,
            height,
            lights: 2,
            triangles: 1_055_684,
            objects: 17_468,
            rows: 0,
        }
    }

    /// The model covers what was measured (peak RSS, the default city, two
    /// lights, reference on) with a margin of at most 1.5×.
    #[test]
    fn the_model_covers_the_measured_runs() {
        let o = PipelineOptions::default();
        for ((w, h), measured_kib) in [((400, 300), 481_416u64), ((3200, 2400), 1_407_632)] {
            let e = estimate(&o, &city_at(w, h)).total;
            let measured = measured_kib * 1024;
            assert!(
                e >= measured && e <= measured / 2 * 3,
                "{w}×{h}: {e} vs {measured}"
            );
        }
    }

    /// The probe's cases are refused on a 24 GiB machine's default limit,
    /// each naming the field that drives it.
    #[test]
    fn the_probes_runaway_jobs_name_their_field() {
        let limit = 18 << 30;
        let o = PipelineOptions::default();
        let e = estimate(&o, &city_at(16384, 16384))
            .check(limit)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("max_memory: ") && e.contains("`resolution`"),
            "{e}"
        );
        assert!(e.contains("`reference_every`"), "{e}");
        let rows = Workload {
            rows: 2_000_000_000,
            ..city_at(800, 600)
        };
        let e = estimate(&o, &rows).check(limit).unwrap_err().to_string();
        assert!(e.contains("`frames`") && !e.contains("`resolution`"), "{e}");
        let huge = Workload {
            triangles: 1_300_000_000_000,
            objects: 10_400_000,
            ..city_at(800, 600)
        };
        let e = estimate(&o, &huge).check(limit).unwrap_err().to_string();
        assert!(e.contains("`scene`"), "{e}");
        // The default job fits easily.
        estimate(
            &o,
            &Workload {
                rows: 80,
                ..city_at(800, 600)
            },
        )
        .check(limit)
        .unwrap();
    }

    #[test]
    fn the_limit_is_the_option_or_a_share_of_the_machine() {
        let o = PipelineOptions {
            max_memory: Some(ByteSize(1 << 30)),
            ..Default::default()
        };
        assert_eq!(limit(&o), 1 << 30);
        let machine = limit(&PipelineOptions::default());
        match machine_memory() {
            Some(m) => assert_eq!(machine, m / 4 * 3),
            None => assert_eq!(machine, u64::MAX),
        }
    }
}
