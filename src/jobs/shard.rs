//! Sharded batch jobs: a job's F frames split into N contiguous blocks that
//! run on different machines (`shadowcull run JOB --shard I/N`) and are put
//! back together by [`crate::jobs::merge`].
//!
//! Coherent culling links each frame to the ones before it (CHC/CHC++
//! history, revisit phases), so a shard does two things to behave like its
//! frames of the single run:
//! - frames keep their job numbers ([`crate::Pipeline::set_frame_number`]);
//! - it first runs a few **warm-up** frames before its block (computing no
//!   reference and writing nothing), which rebuild the history the single
//!   run would have. Warm-up never reaches back past a keyframe, where the
//!   single run forgets its history too.
//!
//! What equal means: shadow masks (and every column derived from them)
//! never depend on history, so they are byte-identical to the single run's
//! always. Query counts, PSR, PSC and the volumes drawn do; with keyframes
//! ([`crate::jobs::config::Job::keyframe`]) and shard boundaries on multiples of
//! the keyframe interval they are identical too.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};
use std::ops::Range;
use std::path::Path;

/// Shard `index` of `count` (0-based): `--shard I/N`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// I, from 0.
    pub index: u32,
    /// N, at least 1.
    pub count: u32,
}

impl Shard {
    /// Shard `index` of `count`.
    ///
    /// # Errors
    /// [`Error::Options`] (field `shard`) unless `index < count`.
    pub fn new(index: u32, count: u32) -> Result<Shard> {
        if index >= count {
            return Err(Error::Options {
                field: "shard".into(),
                message: format!(
                    "{index}/{count}: the index counts from 0 and must be below the shard count"
                ),
            });
        }
        Ok(Shard { index, count })
    }

    /// The job frames this shard runs out of `frames`:
    /// `[⌊I·F/N⌋, ⌊(I+1)·F/N⌋)`. The blocks of shards 0..N cover `[0, F)`
    /// exactly once (some are empty when N > F).
    pub fn range(&self, frames: u32) -> Range<u32> {
        let at = |i: u32| (u64::from(i) * u64::from(frames) / u64::from(self.count)) as u32;
        at(self.index)..at(self.index + 1)
    }
}

impl std::str::FromStr for Shard {
    type Err = Error;

    /// `I/N`, as `--shard 3/8` (or an array scheduler's `$TASK_ID/$N`).
    fn from_str(s: &str) -> Result<Shard> {
        let bad = || Error::Options {
            field: "shard".into(),
            message: format!("{s:?}: want I/N, such as 0/4 (I from 0 to N-1)"),
        };
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let i = i.trim().parse().map_err(|_| bad())?;
        let n = n.trim().parse().map_err(|_| bad())?;
        Shard::new(i, n)
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// The first warm-up frame of a block starting at `start`: `warmup` frames
/// before it, but not before the keyframe at or below `start` (the single
/// run forgets its history there, so earlier frames cannot matter).
pub fn warmup_start(start: u32, warmup: u32, keyframe: Option<u32>) -> u32 {
    let floor = keyframe.filter(|&k| k > 0).map_or(0, |k| start - start % k);
    start.saturating_sub(warmup).max(floor)
}

/// `shard.json`: what a shard directory holds, for [`crate::jobs::merge`] to check
/// that shards describe one job and cover it exactly once.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardManifest {
    /// The job file as given on the command line, or `<default>`.
    pub job_path: String,
    /// `fnv1a64:` and 16 hex digits: the FNV-1a hash of the job file's bytes
    /// (of the bundled default job's text for `<default>`).
    pub job_hash: String,
    /// I.
    pub index: u32,
    /// N.
    pub count: u32,
    /// F: the job's frames after any `--frames` cap.
    pub job_frames: u32,
    /// The block `[first, end)` of job frames this shard wrote.
    pub frames: [u32; 2],
    /// W: warm-up frames asked for (`--warmup`, default the job's
    /// `chcpp.revisit`).
    pub warmup: u32,
    /// Warm-up frames run: W, fewer at the job's start or after a keyframe.
    pub warmup_frames: u32,
    /// The keyframe interval in force (`--keyframe` or the job's), if any.
    pub keyframe: Option<u32>,
    /// The `shadowcull` version that ran the shard.
    pub version: String,
    /// Loading or generating the scene (ms).
    pub load_ms: f64,
    /// The warm-up frames (ms).
    pub warmup_ms: f64,
    /// The whole run, start to `shard.json` (ms).
    pub wall_ms: f64,
}

impl ShardManifest {
    /// The manifest of directory `dir`.
    ///
    /// # Errors
    /// [`Error::Shard`] naming `dir` when `shard.json` is missing or unreadable.
    pub fn read(dir: &Path) -> Result<ShardManifest> {
        let path = dir.join("shard.json");
        let text = crate::error::read_text(&path).map_err(|e| Error::Shard {
            path: dir.to_path_buf(),
            message: format!(
                "no readable shard.json ({e}): not the output of `run --shard`, or its run did not finish"
            ),
        })?;
        serde_json::from_str(&text).map_err(|e| Error::Shard {
            path: path.clone(),
            message: format!("not a shard manifest: {e}"),
        })
    }

    /// The job frames written.
    pub fn block(&self) -> Range<u32> {
        self.frames[0]..self.frames[1]
    }
}

/// FNV-1a (64-bit) of `bytes` as `fnv1a64:` and 16 hex digits: a content
/// fingerprint to tell jobs apart, not a cryptographic hash.
pub fn job_hash(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("fnv1a64:{h:016x}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The blocks of 0..N tile [0, F) in order, each ⌊F/N⌋ or ⌈F/N⌉ long.
        #[test]
        fn blocks_tile_the_job(frames in 0u32..5000, count in 1u32..300) {
            let mut next = 0;
            for index in 0..count {
                let r = Shard::new(index, count).unwrap().range(frames);
                prop_assert_eq!(r.start, next);
                prop_assert!(r.len() as u32 >= frames / count);
                prop_assert!(r.len() as u32 <= frames.div_ceil(count));
                next = r.end;
            }
            prop_assert_eq!(next, frames);
        }
    }

    #[test]
    fn shard_syntax() {
        assert_eq!("2/8".parse::<Shard>().unwrap(), Shard::new(2, 8).unwrap());
        assert_eq!(Shard::new(2, 8).unwrap().to_string(), "2/8");
        for bad in ["8/8", "1/0", "3", "-1/4", "a/b", "1/4/2", ""] {
            let e = bad.parse::<Shard>().unwrap_err().to_string();
            assert!(e.starts_with("shard: "), "{bad}: {e}");
        }
        // The extremes of u32 do not overflow.
        let last = Shard::new(u32::MAX - 1, u32::MAX).unwrap();
        assert_eq!(last.range(u32::MAX).end, u32::MAX);
    }

    #[test]
    fn warmup_stops_at_keyframes() {
        assert_eq!(warmup_start(20, 5, None), 15);
        assert_eq!(warmup_start(3, 5, None), 0);
        assert_eq!(
            warmup_start(20, 5, Some(10)),
            20,
            "a keyframe block needs none"
        );
        assert_eq!(warmup_start(23, 5, Some(10)), 20);
        assert_eq!(warmup_start(27, 5, Some(10)), 22);
        assert_eq!(warmup_start(27, 0, Some(10)), 27);
    }

    #[test]
    fn hash_tells_texts_apart() {
        assert_eq!(job_hash(b""), "fnv1a64:cbf29ce484222325");
        assert_ne!(job_hash(b"frames: 40"), job_hash(b"frames: 41"));
    }
}
