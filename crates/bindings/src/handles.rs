//! The pipeline handles: generation-checked slots in a process-wide table,
//! never raw pointers. A stale or destroyed handle (double destroy included)
//! is `SC_INVALID_ARGUMENT`, never undefined behaviour.
//!
//! Each live pipeline sits behind its own mutex: one thread uses it at a
//! time (a second thread waits), and different pipelines run on different
//! threads at once. Destroying a pipeline another thread is using takes
//! effect when that call returns.

use crate::error::{Failure, Result};
use crate::frame::Outputs;
use shadowcull::Pipeline;
use std::sync::{Arc, Mutex, MutexGuard};

/// A pipeline: 0 is the null handle.
#[allow(non_camel_case_types)]
pub type sc_pipeline = u64;

/// A live pipeline and the buffers its last frame's output points into.
pub(crate) struct Entry {
    pub pipeline: Pipeline,
    pub outputs: Outputs,
    /// The host depth of the last frame that had one, its buffer reused.
    pub host_depth: Option<std::sync::Arc<[f32]>>,
}

struct Slot {
    generation: u32,
    entry: Option<Arc<Mutex<Entry>>>,
}

static TABLE: Mutex<Vec<Slot>> = Mutex::new(Vec::new());

fn table() -> MutexGuard<'static, Vec<Slot>> {
    // The table is only ever left consistent: a poisoned lock is still usable.
    TABLE.lock().unwrap_or_else(|p| p.into_inner())
}

/// `(slot + 1) | generation << 32`: never 0.
fn handle(slot: usize, generation: u32) -> sc_pipeline {
    (slot as u64 + 1) | (u64::from(generation) << 32)
}

/// Registers `entry`; its handle.
pub(crate) fn insert(entry: Entry) -> sc_pipeline {
    let mut t = table();
    let entry = Some(Arc::new(Mutex::new(entry)));
    // A slot whose generation reached the end is retired, never reused.
    match t
        .iter()
        .position(|s| s.entry.is_none() && s.generation != u32::MAX)
    {
        Some(i) => {
            t[i].entry = entry;
            handle(i, t[i].generation)
        }
        None => {
            t.push(Slot {
                generation: 0,
                entry,
            });
            handle(t.len() - 1, 0)
        }
    }
}

fn lookup(h: sc_pipeline) -> Result<(usize, u32)> {
    let (slot, generation) = ((h & 0xffff_ffff) as usize, (h >> 32) as u32);
    if slot == 0 {
        return Err(Failure::invalid("pipeline: the null handle"));
    }
    Ok((slot - 1, generation))
}

/// The live entry of `h`.
pub(crate) fn get(h: sc_pipeline) -> Result<Arc<Mutex<Entry>>> {
    let (slot, generation) = lookup(h)?;
    let t = table();
    match t.get(slot) {
        Some(s) if s.generation == generation => s.entry.clone(),
        _ => None,
    }
    .ok_or_else(|| {
        Failure::invalid(format!(
            "pipeline {h:#x}: unknown, destroyed or stale handle"
        ))
    })
}

/// Runs `f` on the live pipeline `h`, holding its lock.
pub(crate) fn with<T>(h: sc_pipeline, f: impl FnOnce(&mut Entry) -> Result<T>) -> Result<T> {
    let entry = get(h)?;
    let mut e = entry.lock().map_err(|_| Failure {
        status: crate::sc_status::SC_INTERNAL,
        message: format!("pipeline {h:#x}: unusable after an internal error"),
    })?;
    f(&mut e)
}

/// Unregisters `h` (the null handle is a no-op); the pipeline is dropped once
/// no call uses it any more.
pub(crate) fn remove(h: sc_pipeline) -> Result<()> {
    if h == 0 {
        return Ok(());
    }
    let (slot, generation) = lookup(h)?;
    let entry = {
        let mut t = table();
        match t.get_mut(slot) {
            Some(s) if s.generation == generation && s.entry.is_some() => {
                s.generation = s.generation.saturating_add(1);
                s.entry.take()
            }
            _ => None,
        }
    };
    match entry {
        // Dropped outside the table's lock: it joins the pipeline's pool.
        Some(e) => {
            drop(e);
            Ok(())
        }
        None => Err(Failure::invalid(format!(
            "pipeline {h:#x}: unknown, destroyed or stale handle"
        ))),
    }
}
