//! `shadowcull merge OUT SHARD_DIR...`: the shards of one job put back
//! together as the single run's output directory ([`crate::jobs::shard`]).
//!
//! Checks first, then writes:
//! - every directory holds a `shard.json`, all for one job: the same job
//!   hash, frame count F, shard count N, keyframe interval and tool version
//!   (else the directory is foreign);
//! - shards 0..N each appear once, with the block their index gives, so the
//!   blocks cover `[0, F)` exactly once (else a shard is missing or two
//!   overlap);
//! - every `stats.csv` has the same header, and its rows lie in its block.
//!
//! Then `stats.csv` is the shards' rows concatenated in frame order (records
//! copied as written), `frames/` holds each shard's images of its block, and
//! `summary.json` is recomputed. Its rule per key:
//! - `job`, `scene`, `bounds`, `warnings`, `resolution`, `lights`: the first
//!   shard's, which every shard must share;
//! - `frames`: the sum (F);
//! - `totals`, `shadow_totals`, `check_totals`: sums over the merged rows;
//! - `mean_reference_ms`, `mean_frame_ms`, `frame_ms_median`,
//!   `frame_ms_mean`: recomputed from the merged rows, as a single run
//!   computes them ([`RowSummary::of`]);
//! - `load_ms`, `bvh_ms`: the maximum over shards (each shard loads the scene
//!   and builds the reference's BVH once; the slowest one bounds the job);
//! - `peak_rss_bytes`, `memory_estimate_bytes`: the maximum over shards
//!   (each is its own process, admitted with its own block's rows);
//! - `shards` (only in a merged summary): each shard's directory and
//!   `shard.json`, with its load, warm-up and wall times.

use crate::error::io_err;
use crate::jobs::run::{write_json, RowSummary};
use crate::jobs::shard::ShardManifest;
use crate::stats::FrameRow;
use crate::{Error, Result};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// One shard directory, read and checked.
struct ShardDir {
    dir: PathBuf,
    manifest: ShardManifest,
    summary: Value,
    /// `stats.csv` records after the header, as written.
    records: Vec<csv::StringRecord>,
    rows: Vec<FrameRow>,
}

/// What a merge wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MergeReport {
    /// Shards merged (N).
    pub shards: u32,
    /// Job frames covered (F).
    pub frames: u32,
    /// `stats.csv` rows written.
    pub rows: usize,
    /// Images copied into `frames/`.
    pub images: usize,
}

/// Merges the shard directories `dirs` of one job into `out` (created if
/// missing; it must not be one of `dirs`).
///
/// # Errors
/// [`Error::Shard`] naming the directory for a missing, overlapping or
/// foreign shard, or one whose files disagree with its `shard.json`;
/// I/O errors.
pub fn merge_shards(out: &Path, dirs: &[PathBuf]) -> Result<MergeReport> {
    let shard_err = |dir: &Path, message: String| Error::Shard {
        path: dir.to_path_buf(),
        message,
    };
    if dirs.is_empty() {
        return Err(shard_err(out, "no shard directories to merge".into()));
    }
    let out_real = std::fs::canonicalize(out).ok();
    let mut shards = Vec::with_capacity(dirs.len());
    for dir in dirs {
        if out_real.is_some() && std::fs::canonicalize(dir).ok() == out_real {
            return Err(shard_err(
                out,
                "the output directory is one of the shards; merge into a new directory".into(),
            ));
        }
        shards.push(read_shard(dir)?);
    }

    // One job.
    let first = &shards[0].manifest;
    for s in &shards[1..] {
        let m = &s.manifest;
        let fields = [
            ("job_hash", m.job_hash != first.job_hash),
            ("job_frames", m.job_frames != first.job_frames),
            ("count", m.count != first.count),
            ("keyframe", m.keyframe != first.keyframe),
            ("version", m.version != first.version),
        ];
        if let Some((field, _)) = fields.iter().find(|f| f.1) {
            return Err(shard_err(
                &s.dir,
                format!(
                    "a shard of another job: its shard.json `{field}` differs from {}'s ({} {} of F = {} frames, N = {}, keyframe {:?}, version {})",
                    shards[0].dir.display(),
                    first.job_path,
                    first.job_hash,
                    first.job_frames,
                    first.count,
                    first.keyframe,
                    first.version
                ),
            ));
        }
        for key in ["scene", "bounds", "warnings", "resolution", "lights"] {
            if s.summary.get(key) != shards[0].summary.get(key) {
                return Err(shard_err(
                    &s.dir,
                    format!(
                        "summary.json `{key}` differs from {}'s: the shards did not run the same scene",
                        shards[0].dir.display()
                    ),
                ));
            }
        }
    }
    let (count, frames) = (first.count, first.job_frames);

    // Each shard once, each with its own block: [0, F) covered exactly once.
    shards.sort_by_key(|s| s.manifest.index);
    for pair in shards.windows(2) {
        if pair[0].manifest.index == pair[1].manifest.index {
            let m = &pair[1].manifest;
            return Err(shard_err(
                &pair[1].dir,
                format!(
                    "overlaps {}: both hold shard {}/{count} (frames {}..{})",
                    pair[0].dir.display(),
                    m.index,
                    m.frames[0],
                    m.frames[1]
                ),
            ));
        }
    }
    for s in &shards {
        let m = &s.manifest;
        let shard = crate::jobs::shard::Shard::new(m.index, count)
            .map_err(|e| shard_err(&s.dir, format!("shard.json: {e}")))?;
        let range = shard.range(frames);
        if m.block() != range {
            return Err(shard_err(
                &s.dir,
                format!(
                    "shard.json says frames {}..{}, but shard {shard} of {frames} frames is {}..{}",
                    m.frames[0], m.frames[1], range.start, range.end
                ),
            ));
        }
    }
    // Indices are distinct and below N: N of them cover every block.
    if let Some(want) = (0..count).find(|&i| shards.iter().all(|s| s.manifest.index != i)) {
        let shard = crate::jobs::shard::Shard::new(want, count)?;
        let range = shard.range(frames);
        return Err(shard_err(
            out,
            format!(
                "shard {shard} is missing: frames {}..{} of {frames} are not covered (run it with --shard {shard})",
                range.start, range.end
            ),
        ));
    }

    // Write: stats.csv, frames/, summary.json (into a locked directory,
    // emptied of an earlier run's or merge's outputs).
    let _lock = crate::jobs::out_dir::claim_for_run(out)?;
    let rows: Vec<FrameRow> = shards.iter().flat_map(|s| s.rows.iter().copied()).collect();
    crate::jobs::run::atomic(&out.join("stats.csv"), |tmp| {
        let mut csv = csv::Writer::from_writer(Vec::new());
        FrameRow::write_csv_header(&mut csv)?;
        for record in shards.iter().flat_map(|s| &s.records) {
            csv.write_record(record)?;
        }
        std::fs::write(tmp, csv.into_inner().map_err(|e| e.into_error())?)
    })?;
    let mut images = 0;
    for s in &shards {
        images += copy_images(&s.dir, out, &s.manifest)?;
    }
    let mut summary = shards[0].summary.clone();
    let derived = serde_json::to_value(RowSummary::of(frames, &rows))
        .map_err(|e| shard_err(out, format!("summary: {e}")))?;
    if let (Value::Object(summary), Value::Object(derived)) = (&mut summary, derived) {
        summary.extend(derived);
        let max = |key: &str| {
            shards
                .iter()
                .filter_map(|s| s.summary.get(key).and_then(Value::as_f64))
                .fold(0.0, f64::max)
        };
        summary.insert("load_ms".into(), max("load_ms").into());
        summary.insert("bvh_ms".into(), max("bvh_ms").into());
        summary.insert(
            "memory_estimate_bytes".into(),
            (max("memory_estimate_bytes") as u64).into(),
        );
        if shards
            .iter()
            .any(|s| s.summary.get("peak_rss_bytes").is_some())
        {
            summary.insert(
                "peak_rss_bytes".into(),
                (max("peak_rss_bytes") as u64).into(),
            );
        }
        let list = shards
            .iter()
            .map(|s| {
                let mut m = serde_json::to_value(&s.manifest).unwrap_or(Value::Null);
                if let Value::Object(m) = &mut m {
                    m.insert("dir".into(), s.dir.display().to_string().into());
                }
                m
            })
            .collect();
        summary.insert("shards".into(), Value::Array(list));
    }
    write_json(&out.join("summary.json"), &summary)?;
    Ok(MergeReport {
        shards: count,
        frames,
        rows: rows.len(),
        images,
    })
}

/// Reads `dir`'s `shard.json`, `summary.json` and `stats.csv`, checking the
/// rows against the manifest.
fn read_shard(dir: &Path) -> Result<ShardDir> {
    let bad = |message: String| Error::Shard {
        path: dir.to_path_buf(),
        message,
    };
    let manifest = ShardManifest::read(dir)?;
    let sp = dir.join("summary.json");
    let summary: Value = serde_json::from_str(&crate::error::read_text(&sp).map_err(io_err(&sp))?)
        .map_err(|e| bad(format!("summary.json: {e}")))?;
    let cp = dir.join("stats.csv");
    let text = crate::error::read_text(&cp).map_err(io_err(&cp))?;
    // Flexible: a record of another length is named by `FrameRow::from_csv`.
    let mut csv = csv::ReaderBuilder::new()
        .flexible(true)
        .from_reader(text.as_bytes());
    let header = csv.headers().map_err(|e| bad(format!("stats.csv: {e}")))?;
    if !header.iter().eq(FrameRow::COLUMNS.iter().copied()) {
        return Err(bad(
            "stats.csv has other columns than this version writes".into()
        ));
    }
    let block = manifest.block();
    let (mut records, mut rows) = (Vec::new(), Vec::new());
    for record in csv.records() {
        let record = record.map_err(|e| bad(format!("stats.csv: {e}")))?;
        let line = record.position().map_or(0, csv::Position::line);
        let row =
            FrameRow::from_csv(&record).map_err(|e| bad(format!("stats.csv line {line}: {e}")))?;
        if !block.contains(&row.frame) {
            return Err(bad(format!(
                "stats.csv line {line}: frame {} is outside the shard's frames {}..{}",
                row.frame, block.start, block.end
            )));
        }
        records.push(record);
        rows.push(row);
    }
    Ok(ShardDir {
        dir: dir.to_path_buf(),
        manifest,
        summary,
        records,
        rows,
    })
}

/// Copies the images of `dir/frames` whose frame (the number before the
/// first `_`) lies in the shard's block into `out/frames`; returns how many.
/// Files of other frames (an earlier run's leftovers) are not the shard's.
fn copy_images(dir: &Path, out: &Path, m: &ShardManifest) -> Result<usize> {
    let from = dir.join("frames");
    let Ok(entries) = std::fs::read_dir(&from) else {
        return Ok(0);
    };
    let to = out.join("frames");
    std::fs::create_dir_all(&to).map_err(io_err(&to))?;
    let mut n = 0;
    for entry in entries {
        let entry = entry.map_err(io_err(&from))?;
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let frame = name.split('_').next().and_then(|f| f.parse::<u32>().ok());
        if !name.ends_with(".png") || !frame.is_some_and(|f| m.block().contains(&f)) {
            continue;
        }
        // Only regular files: a FIFO named like an image would block the copy.
        if !entry.file_type().is_ok_and(|t| t.is_file()) {
            return Err(Error::Shard {
                path: entry.path(),
                message: "not a regular file: a shard's images are files `run` wrote".into(),
            });
        }
        let target = to.join(name);
        std::fs::copy(entry.path(), &target).map_err(io_err(&target))?;
        n += 1;
    }
    Ok(n)
}
