//! The occlusion backend: the seam CHC talks to (DESIGN.md "Seams"). Draws and
//! queries are commands executed in submission order; a query's result arrives
//! later, as from a GPU [Bittner et al. 2004, "Coherent hierarchical culling"].
//!
//! Three implementations give identical counts for the same command stream:
//! [`SyncBackend`] (results at once), [`SimulatedBackend`] (a result becomes
//! visible [`Latency::Commands`]`(k)` commands after its query — deterministic)
//! and [`ThreadedBackend`] (a worker thread executes the commands in order; a
//! [`Gate`] can hold it for tests).

use crate::coverage::Coverage;
use crate::depth_target::{CullMode, DepthTarget};
use crate::item::DrawItem;
use crate::query_options::QueryOptions;
use crate::receiver_target::ReceiverTarget;
use crate::{Error, Result};
use glam::{Mat4, Vec3, Vec4};
use std::sync::mpsc;
use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;

/// Names an issued query; ids count up from 0 per backend.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct QueryId(pub u32);

/// An occluder draw: owned mesh data, so it can travel to a worker thread.
#[derive(Clone, Debug)]
pub struct DrawCommand {
    /// `clip_from_local`.
    pub clip_from_local: Mat4,
    /// Local positions (w = 0 for points at infinity).
    pub positions: Arc<[Vec4]>,
    /// Triangles (vertex indices).
    pub triangles: Arc<[[u32; 3]]>,
    /// Object id written with the depth.
    pub object: u32,
    /// Coverage mode.
    pub coverage: Coverage,
    /// Which triangles the draw skips by facing (`glCullFace`).
    pub cull: CullMode,
    /// Whether the triangles are drawn as one solid
    /// ([`Whole`]): with [`Coverage::Inner`] at the farthest depth, the
    /// bundled backends then cover the pixels inside its silhouette rather
    /// than those inside one triangle. A host may draw the triangles
    /// inner-conservative, which covers less and stays conservative.
    pub whole: Whole,
}

/// How a draw's triangles make one occluder ([`DrawCommand::whole`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Whole {
    /// Triangle by triangle.
    #[default]
    No,
    /// They bound a convex solid (a convex mesh, or an occluder proxy):
    /// [`DepthTarget::draw_convex`].
    Convex,
    /// They are a closed mesh, `cull` naming its hidden faces:
    /// [`DepthTarget::draw_closed`].
    Closed,
}

/// `triangles` less their trailing run of padding: triangles whose three
/// indices are equal, which cover nothing. A list the library refills in
/// place (a moving light's casting triangles) keeps its length and pads
/// the tail this way; drawing it trimmed skips the padding's setup.
pub fn trim_padding(triangles: &[[u32; 3]]) -> &[[u32; 3]] {
    let pad = |t: &&[u32; 3]| t[0] == t[1] && t[1] == t[2];
    let n = triangles.len() - triangles.iter().rev().take_while(pad).count();
    &triangles[..n]
}

impl DrawCommand {
    /// The triangles to draw: [`DrawCommand::triangles`] less any trailing
    /// padding ([`trim_padding`]).
    pub fn drawn_triangles(&self) -> &[[u32; 3]] {
        trim_padding(&self.triangles)
    }

    /// Draws this command whole on `target` when it asks to and can be
    /// ([`DrawCommand::whole`] at inner-conservative, farthest coverage);
    /// returns whether it did.
    fn draw_whole(&self, target: &mut DepthTarget) -> bool {
        if self.coverage != Coverage::Inner(crate::DepthPick::Farthest) {
            return false;
        }
        let item = DrawItem {
            clip_from_local: self.clip_from_local,
            positions: &self.positions,
            triangles: self.drawn_triangles(),
            object: self.object,
            cull: self.cull,
        };
        match self.whole {
            Whole::No => false,
            Whole::Convex => target.draw_convex(&item),
            Whole::Closed => target.draw_closed(&item),
        }
    }
}

/// An occlusion query.
#[derive(Clone, Debug)]
pub enum QueryCommand {
    /// The box `(min, max)` in local space (apex test, then all 12 faces).
    Aabb {
        /// `clip_from_local`.
        clip_from_local: Mat4,
        /// Box minimum.
        min: Vec3,
        /// Box maximum.
        max: Vec3,
        /// Coverage and mode.
        options: QueryOptions,
    },
    /// The union of several local-space boxes `(min, max)`: one query whose
    /// result is [`DepthTarget::query_aabb_union`]'s (CHC++ multiqueries and
    /// tighter node volumes).
    Aabbs {
        /// `clip_from_local`.
        clip_from_local: Mat4,
        /// The boxes.
        boxes: Arc<[(Vec3, Vec3)]>,
        /// Coverage and mode.
        options: QueryOptions,
    },
    /// Triangles of a mesh.
    Mesh {
        /// `clip_from_local`.
        clip_from_local: Mat4,
        /// Local positions.
        positions: Arc<[Vec4]>,
        /// Triangles (vertex indices).
        triangles: Arc<[[u32; 3]]>,
        /// Coverage and mode.
        options: QueryOptions,
    },
}

/// Counters of a backend.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct BackendStats {
    /// Draw commands submitted.
    pub draws: u64,
    /// Queries issued.
    pub queries: u64,
    /// Polls made.
    pub polls: u64,
    /// Waits made.
    pub waits: u64,
    /// Waits that found the result not yet available.
    pub waits_blocked: u64,
    /// Wall time spent blocked in waits and finishes, nanoseconds.
    pub wait_ns: u64,
}

/// When a simulated query result becomes visible.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Latency {
    /// `k` commands (draws, queries, clears) after the query itself was submitted.
    Commands(u32),
}

/// The asynchronous occlusion interface CHC talks to (one real seam: a GPU host
/// implements it over its own queries).
pub trait OcclusionBackend {
    /// Clears depth (and ids) to background.
    fn clear(&mut self);
    /// Sets (or removes) the receiver target restricting later queries.
    ///
    /// # Errors
    /// [`Error::SizeMismatch`] when its size differs from the depth target.
    fn set_receivers(&mut self, receivers: Option<Arc<ReceiverTarget>>) -> Result<()>;
    /// Submits an occluder draw.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a bad triangle index (checked at submission).
    fn draw(&mut self, cmd: DrawCommand) -> Result<()>;
    /// Submits a query; its result arrives later.
    ///
    /// # Errors
    /// [`Error::IndexOutOfRange`] for a bad triangle index (checked at submission).
    fn issue_query(&mut self, q: QueryCommand) -> Result<QueryId>;
    /// Submits a query over the union of the local-space boxes `boxes`
    /// (as [`QueryCommand::Aabbs`]). The default copies them into one; the
    /// bundled backends run it from the borrowed slice, so CHC++'s
    /// multiqueries allocate nothing.
    ///
    /// # Errors
    /// As [`OcclusionBackend::issue_query`].
    fn issue_box_union(
        &mut self,
        clip_from_local: Mat4,
        boxes: &[(Vec3, Vec3)],
        options: QueryOptions,
    ) -> Result<QueryId> {
        self.issue_query(QueryCommand::Aabbs {
            clip_from_local,
            boxes: boxes.into(),
            options,
        })
    }
    /// The result if it has arrived.
    fn poll(&mut self, id: QueryId) -> Option<u32>;
    /// The result, blocking until it arrives.
    ///
    /// # Panics
    /// When `id` was not issued by this backend.
    fn wait(&mut self, id: QueryId) -> u32;
    /// Blocks until every submitted command has executed.
    fn finish(&mut self);
    /// Counters so far.
    fn stats(&self) -> BackendStats;
}

/// A backend whose depth target can be read: the bundled ones. A host's
/// GPU backend implements [`OcclusionBackend`] alone.
pub trait ReadTarget {
    /// Calls `f` with the depth target after [`OcclusionBackend::finish`].
    fn read_target(&mut self, f: &mut dyn FnMut(&DepthTarget));
}

/// Checks a query's mesh indices (box queries need no check).
fn check_query(q: &QueryCommand) -> Result<()> {
    if let QueryCommand::Mesh {
        positions,
        triangles,
        ..
    } = q
    {
        check_indices(positions, triangles)?;
    }
    Ok(())
}

fn check_indices(positions: &[Vec4], triangles: &[[u32; 3]]) -> Result<()> {
    for (k, t) in triangles.iter().enumerate() {
        for &i in t {
            if i as usize >= positions.len() {
                return Err(Error::IndexOutOfRange {
                    triangle: k,
                    index: i,
                    len: positions.len(),
                });
            }
        }
    }
    Ok(())
}

fn check_receiver_size(t: &DepthTarget, r: &Option<Arc<ReceiverTarget>>) -> Result<()> {
    match r {
        Some(r) if r.size() != (t.width(), t.height()) || r.depth.len() != t.depth.len() => {
            Err(Error::SizeMismatch {
                expected: (t.width(), t.height()),
                got: r.size(),
            })
        }
        _ => Ok(()),
    }
}

/// A command as executed.
enum Command {
    Clear,
    Receivers(Option<Arc<ReceiverTarget>>),
    Draw(DrawCommand),
    Query(QueryId, QueryCommand),
    Fence,
}

/// Executes one command on `target`; returns a query's result.
fn execute(
    target: &mut DepthTarget,
    receivers: &mut Option<Arc<ReceiverTarget>>,
    cmd: Command,
) -> Option<(QueryId, u32)> {
    match cmd {
        Command::Clear => target.clear(),
        Command::Receivers(r) => *receivers = r,
        Command::Draw(d) => {
            let item = DrawItem {
                clip_from_local: d.clip_from_local,
                positions: &d.positions,
                triangles: d.drawn_triangles(),
                object: d.object,
                cull: d.cull,
            };
            if !d.draw_whole(target) {
                target
                    .draw(&item, d.coverage)
                    .expect("indices checked at submission");
            }
        }
        Command::Query(id, q) => {
            let r = receivers.as_deref();
            let n = match q {
                QueryCommand::Aabb {
                    clip_from_local,
                    min,
                    max,
                    options,
                } => target.query_aabb(clip_from_local, min, max, &options, r),
                QueryCommand::Aabbs {
                    clip_from_local,
                    boxes,
                    options,
                } => target.query_aabb_union(clip_from_local, &boxes, &options, r),
                QueryCommand::Mesh {
                    clip_from_local,
                    positions,
                    triangles,
                    options,
                } => {
                    let item = DrawItem {
                        clip_from_local,
                        positions: &positions,
                        triangles: &triangles,
                        object: 0,
                        cull: crate::CullMode::None,
                    };
                    target.query(&item, &options, r)
                }
            };
            return Some((id, n.expect("checked at submission")));
        }
        Command::Fence => {}
    }
    None
}

/// An empty vector of `U` in `v`'s allocation: for element types of one
/// layout (here draw items differing only in lifetime) the standard
/// library's in-place collection keeps the buffer.
fn recycle<T, U>(mut v: Vec<T>) -> Vec<U> {
    v.clear();
    v.into_iter().map(|_| unreachable!("empty")).collect()
}

/// The query-result list and the held-draw lists of a bundled backend,
/// kept between frames ([`SyncBackend::into_parts`],
/// [`SyncBackend::reusing`]) so that a steady frame allocates nothing.
#[derive(Debug, Default)]
pub struct QueryBuffers {
    results: Vec<(u32, u64)>,
    pending: Vec<DrawCommand>,
    items: Vec<DrawItem<'static>>,
    /// The batches' buffers ([`DepthTarget::draw_batch`]), lent to the
    /// target while the backend holds it: they grow with this view's
    /// batches, whichever target set the view draws into.
    batch: crate::batch_scratch::BatchScratch,
}

/// Deterministic backend: executes at once, reveals a result `k` commands later.
///
/// Draws are held until the next command that reads or changes the target
/// otherwise (a query, a clear, new receivers, a read of the target) and
/// then drawn as one batch ([`DepthTarget::draw_batch`]: bands of tile rows
/// in parallel). Depth, ids and query results are those of drawing each at
/// once: the depth test's winner does not depend on the order.
#[derive(Debug)]
pub struct SimulatedBackend {
    target: DepthTarget,
    /// Draws submitted since the last command of another kind.
    pending: Vec<DrawCommand>,
    /// The held draws' item list, empty between flushes (its buffer kept).
    items: Vec<DrawItem<'static>>,
    receivers: Option<Arc<ReceiverTarget>>,
    latency: Latency,
    /// Per query: (result, command count when it becomes visible).
    results: Vec<(u32, u64)>,
    commands: u64,
    stats: BackendStats,
}

impl SimulatedBackend {
    /// A backend drawing into `target` with the given latency.
    pub fn new(target: DepthTarget, latency: Latency) -> Self {
        SimulatedBackend::new_empty(target, latency)
    }

    /// The depth target, with every draw submitted so far.
    pub fn target(&mut self) -> &DepthTarget {
        self.flush();
        &self.target
    }

    /// The depth target, giving up the backend.
    pub fn into_target(mut self) -> DepthTarget {
        self.flush();
        self.target
    }

    /// A backend drawing into `target`, with the result list of an earlier
    /// one (emptied): as [`SimulatedBackend::new`], without its allocations.
    pub fn reusing(target: DepthTarget, latency: Latency, buffers: QueryBuffers) -> Self {
        let QueryBuffers {
            mut results,
            mut pending,
            items,
            batch,
        } = buffers;
        results.clear();
        pending.clear();
        let mut target = target;
        target.batch = batch;
        SimulatedBackend {
            results,
            pending,
            items,
            ..SimulatedBackend::new_empty(target, latency)
        }
    }

    fn new_empty(target: DepthTarget, latency: Latency) -> Self {
        SimulatedBackend {
            target,
            pending: Vec::new(),
            items: Vec::new(),
            receivers: None,
            latency,
            results: Vec::new(),
            commands: 0,
            stats: BackendStats::default(),
        }
    }

    /// The depth target and the result list, giving up the backend.
    pub fn into_parts(mut self) -> (DepthTarget, QueryBuffers) {
        self.flush();
        let buffers = QueryBuffers {
            results: self.results,
            pending: self.pending,
            items: self.items,
            batch: std::mem::take(&mut self.target.batch),
        };
        (self.target, buffers)
    }

    /// Records a query result `n` as [`SimulatedBackend::run`] does.
    fn push_result(&mut self, id: QueryId, n: u32) {
        let Latency::Commands(k) = self.latency;
        debug_assert_eq!(id.0 as usize, self.results.len());
        self.results.push((n, self.commands + u64::from(k)));
    }

    fn run(&mut self, cmd: Command) {
        self.commands += 1;
        if let Command::Draw(d) = cmd {
            self.pending.push(d);
            return;
        }
        self.flush();
        if let Some((id, n)) = execute(&mut self.target, &mut self.receivers, cmd) {
            self.push_result(id, n);
        }
    }

    /// Draws the held draws: convex ones whole, the others each run of one
    /// coverage as one batch (draws commute: nearest depth, then smallest
    /// id, wins).
    fn flush(&mut self) {
        let mut items = recycle(std::mem::take(&mut self.items));
        let target = &mut self.target;
        self.pending.retain(|d| !d.draw_whole(target));
        let mut rest = &self.pending[..];
        while let Some(first) = rest.first() {
            let n = rest
                .iter()
                .position(|d| d.coverage != first.coverage)
                .unwrap_or(rest.len());
            let (run, tail) = rest.split_at(n);
            items.clear();
            items.extend(run.iter().map(|d| DrawItem {
                clip_from_local: d.clip_from_local,
                positions: &d.positions,
                triangles: d.drawn_triangles(),
                object: d.object,
                cull: d.cull,
            }));
            self.target
                .draw_batch(&items, first.coverage)
                .expect("indices checked at submission");
            rest = tail;
        }
        self.items = recycle(items);
        self.pending.clear();
    }
}

impl OcclusionBackend for SimulatedBackend {
    fn clear(&mut self) {
        self.run(Command::Clear);
    }

    fn set_receivers(&mut self, receivers: Option<Arc<ReceiverTarget>>) -> Result<()> {
        check_receiver_size(&self.target, &receivers)?;
        self.run(Command::Receivers(receivers));
        Ok(())
    }

    fn draw(&mut self, cmd: DrawCommand) -> Result<()> {
        check_indices(&cmd.positions, &cmd.triangles)?;
        self.stats.draws += 1;
        self.run(Command::Draw(cmd));
        Ok(())
    }

    fn issue_query(&mut self, q: QueryCommand) -> Result<QueryId> {
        check_query(&q)?;
        self.stats.queries += 1;
        let id = QueryId(self.results.len() as u32);
        self.run(Command::Query(id, q));
        Ok(id)
    }

    fn issue_box_union(
        &mut self,
        clip_from_local: Mat4,
        boxes: &[(Vec3, Vec3)],
        options: QueryOptions,
    ) -> Result<QueryId> {
        // As `issue_query(QueryCommand::Aabbs { .. })`, from the borrowed boxes.
        self.flush();
        self.stats.queries += 1;
        let id = QueryId(self.results.len() as u32);
        self.commands += 1;
        let n = self.target.query_aabb_union(
            clip_from_local,
            boxes,
            &options,
            self.receivers.as_deref(),
        )?;
        self.push_result(id, n);
        Ok(id)
    }

    fn poll(&mut self, id: QueryId) -> Option<u32> {
        self.stats.polls += 1;
        let (n, at) = self.results[id.0 as usize];
        (self.commands >= at).then_some(n)
    }

    fn wait(&mut self, id: QueryId) -> u32 {
        self.stats.waits += 1;
        let (n, at) = self.results[id.0 as usize];
        if self.commands < at {
            self.stats.waits_blocked += 1;
        }
        n
    }

    fn finish(&mut self) {}

    fn stats(&self) -> BackendStats {
        self.stats
    }
}

impl ReadTarget for SimulatedBackend {
    fn read_target(&mut self, f: &mut dyn FnMut(&DepthTarget)) {
        f(self.target())
    }
}

/// Synchronous backend: every result is available as soon as its query returns.
#[derive(Debug)]
pub struct SyncBackend(SimulatedBackend);

impl SyncBackend {
    /// A backend drawing into `target`.
    pub fn new(target: DepthTarget) -> Self {
        SyncBackend(SimulatedBackend::new(target, Latency::Commands(0)))
    }

    /// The depth target, with every draw submitted so far.
    pub fn target(&mut self) -> &DepthTarget {
        self.0.target()
    }

    /// The depth target, giving up the backend (the caller keeps the image).
    pub fn into_target(self) -> DepthTarget {
        self.0.into_target()
    }

    /// A backend drawing into `target` with the result list of an earlier one
    /// ([`SyncBackend::into_parts`]): [`SyncBackend::new`] without its
    /// allocations.
    pub fn reusing(target: DepthTarget, buffers: QueryBuffers) -> Self {
        SyncBackend(SimulatedBackend::reusing(
            target,
            Latency::Commands(0),
            buffers,
        ))
    }

    /// The depth target and the result list, giving up the backend.
    pub fn into_parts(self) -> (DepthTarget, QueryBuffers) {
        self.0.into_parts()
    }
}

impl OcclusionBackend for SyncBackend {
    fn clear(&mut self) {
        self.0.clear()
    }
    fn set_receivers(&mut self, receivers: Option<Arc<ReceiverTarget>>) -> Result<()> {
        self.0.set_receivers(receivers)
    }
    fn draw(&mut self, cmd: DrawCommand) -> Result<()> {
        self.0.draw(cmd)
    }
    fn issue_query(&mut self, q: QueryCommand) -> Result<QueryId> {
        self.0.issue_query(q)
    }
    fn issue_box_union(
        &mut self,
        clip_from_local: Mat4,
        boxes: &[(Vec3, Vec3)],
        options: QueryOptions,
    ) -> Result<QueryId> {
        self.0.issue_box_union(clip_from_local, boxes, options)
    }
    fn poll(&mut self, id: QueryId) -> Option<u32> {
        self.0.poll(id)
    }
    fn wait(&mut self, id: QueryId) -> u32 {
        self.0.wait(id)
    }
    fn finish(&mut self) {}
    fn stats(&self) -> BackendStats {
        self.0.stats()
    }
}

impl ReadTarget for SyncBackend {
    fn read_target(&mut self, f: &mut dyn FnMut(&DepthTarget)) {
        self.0.read_target(f)
    }
}

/// Holds a [`ThreadedBackend`]'s worker before each command until opened.
#[derive(Clone, Debug)]
pub struct Gate(Arc<(Mutex<bool>, Condvar)>);

impl Gate {
    fn new(open: bool) -> Self {
        Gate(Arc::new((Mutex::new(open), Condvar::new())))
    }

    /// Lets the worker run (for good).
    pub fn open(&self) {
        *self.0 .0.lock().expect("gate lock") = true;
        self.0 .1.notify_all();
    }

    fn pass(&self) {
        let mut g = self.0 .0.lock().expect("gate lock");
        while !*g {
            g = self.0 .1.wait(g).expect("gate lock");
        }
    }
}

#[derive(Debug, Default)]
struct Progress {
    results: Vec<Option<u32>>,
    done: u64,
}

#[derive(Debug)]
struct Shared {
    target: Mutex<DepthTarget>,
    progress: Mutex<Progress>,
    arrived: Condvar,
}

/// A worker thread executes the commands in submission order; results arrive later.
#[derive(Debug)]
pub struct ThreadedBackend {
    shared: Arc<Shared>,
    tx: Option<mpsc::Sender<Command>>,
    worker: Option<std::thread::JoinHandle<()>>,
    gate: Gate,
    submitted: u64,
    queries: u32,
    size: (u32, u32, usize),
    stats: BackendStats,
}

impl ThreadedBackend {
    /// A backend whose worker draws into `target`.
    pub fn new(target: DepthTarget) -> Self {
        Self::start(target, Gate::new(true))
    }

    /// A backend whose worker waits for the returned [`Gate`] to open before executing
    /// anything (deterministic tests of asynchrony).
    pub fn with_gate(target: DepthTarget) -> (Self, Gate) {
        let gate = Gate::new(false);
        (Self::start(target, gate.clone()), gate)
    }

    fn start(target: DepthTarget, gate: Gate) -> Self {
        let size = (target.width(), target.height(), target.depth.len());
        let shared = Arc::new(Shared {
            target: Mutex::new(target),
            progress: Mutex::new(Progress::default()),
            arrived: Condvar::new(),
        });
        let (tx, rx) = mpsc::channel::<Command>();
        let (s, g) = (shared.clone(), gate.clone());
        let worker = std::thread::spawn(move || {
            let mut receivers = None;
            while let Ok(cmd) = rx.recv() {
                g.pass();
                let r = {
                    let mut t = s.target.lock().expect("target lock");
                    execute(&mut t, &mut receivers, cmd)
                };
                let mut p = s.progress.lock().expect("progress lock");
                if let Some((id, n)) = r {
                    p.results[id.0 as usize] = Some(n);
                }
                p.done += 1;
                drop(p);
                s.arrived.notify_all();
            }
        });
        ThreadedBackend {
            shared,
            tx: Some(tx),
            worker: Some(worker),
            gate,
            submitted: 0,
            queries: 0,
            size,
            stats: BackendStats::default(),
        }
    }

    fn send(&mut self, cmd: Command) {
        self.submitted += 1;
        self.tx
            .as_ref()
            .expect("worker running")
            .send(cmd)
            .expect("worker alive");
    }

    /// Blocks until `done(progress)` holds; returns whether it had to block.
    fn block_until(&mut self, done: impl Fn(&Progress) -> bool) -> bool {
        let mut p = self.shared.progress.lock().expect("progress lock");
        if done(&p) {
            return false;
        }
        let t0 = Instant::now();
        while !done(&p) {
            p = self.shared.arrived.wait(p).expect("progress lock");
        }
        self.stats.wait_ns += t0.elapsed().as_nanos() as u64;
        true
    }
}

impl OcclusionBackend for ThreadedBackend {
    fn clear(&mut self) {
        self.send(Command::Clear);
    }

    fn set_receivers(&mut self, receivers: Option<Arc<ReceiverTarget>>) -> Result<()> {
        if let Some(r) = &receivers {
            if r.size() != (self.size.0, self.size.1) || r.depth.len() != self.size.2 {
                return Err(Error::SizeMismatch {
                    expected: (self.size.0, self.size.1),
                    got: r.size(),
                });
            }
        }
        self.send(Command::Receivers(receivers));
        Ok(())
    }

    fn draw(&mut self, cmd: DrawCommand) -> Result<()> {
        check_indices(&cmd.positions, &cmd.triangles)?;
        self.stats.draws += 1;
        self.send(Command::Draw(cmd));
        Ok(())
    }

    fn issue_query(&mut self, q: QueryCommand) -> Result<QueryId> {
        check_query(&q)?;
        self.stats.queries += 1;
        let id = QueryId(self.queries);
        self.queries += 1;
        self.shared
            .progress
            .lock()
            .expect("progress lock")
            .results
            .push(None);
        self.send(Command::Query(id, q));
        Ok(id)
    }

    fn poll(&mut self, id: QueryId) -> Option<u32> {
        self.stats.polls += 1;
        self.shared.progress.lock().expect("progress lock").results[id.0 as usize]
    }

    fn wait(&mut self, id: QueryId) -> u32 {
        self.stats.waits += 1;
        assert!(id.0 < self.queries, "query {id:?} was not issued");
        if self.block_until(|p| p.results[id.0 as usize].is_some()) {
            self.stats.waits_blocked += 1;
        }
        self.shared.progress.lock().expect("progress lock").results[id.0 as usize].expect("arrived")
    }

    fn finish(&mut self) {
        self.send(Command::Fence);
        let n = self.submitted;
        self.block_until(|p| p.done >= n);
    }

    fn stats(&self) -> BackendStats {
        self.stats
    }
}

impl ReadTarget for ThreadedBackend {
    fn read_target(&mut self, f: &mut dyn FnMut(&DepthTarget)) {
        self.finish();
        f(&self.shared.target.lock().expect("target lock"))
    }
}

impl Drop for ThreadedBackend {
    fn drop(&mut self) {
        self.gate.open();
        self.tx = None;
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
    }
}
