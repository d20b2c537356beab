//! The job store: the single source of truth for jobs, their events and results, the queue
//! the planner threads claim from, uploaded robots and scenes, and the expensive caches.
//!
//! Two backends implement [`JobStore`]: [`embedded::EmbeddedStore`] (redb, one file under the
//! data directory; the default, one process) and [`postgres::PgStore`] (PostgreSQL, shared by
//! any number of replicas). The runner, the routes and the event streams talk only to the
//! trait; memory holds only what running jobs need (their stop flags and fences), never a
//! finished result.
//!
//! The queue follows the PostgreSQL job queues (River, Oban, graphile-worker): a job is a row;
//! a replica claims the next queued one (priority, then age) and takes a lease
//! (owner, attempt, deadline) that it renews; every write of a running job is conditional on
//! its [`Fence`] (owner and attempt), so a replica that stalled past its lease and wakes up
//! cannot overwrite what the job's new owner wrote, and a job reaches exactly one final state.
//! A lease that runs out is reaped by any replica: the job is queued again when its request
//! allowed another attempt (`max_attempts`), else recorded `interrupted`.

pub mod embedded;
pub mod postgres;

use std::time::Duration;

use serde::{Deserialize, Serialize};
use serde_json::value::RawValue;
use serde_json::Value;
use tokio::sync::broadcast;

use super::api::{Job, JobState, JobSummary};
use manyhands_api::ErrorDetail;

/// The job store could not be opened, read or written.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The store cannot be reached now (database down, connection lost): retry later.
    #[error("job store unavailable: {0}")]
    Unavailable(String),
    /// Anything else (corrupt record, failed migration, I/O).
    #[error("job store: {0}")]
    Other(String),
}

impl StoreError {
    pub fn other(e: impl std::fmt::Display) -> StoreError {
        StoreError::Other(e.to_string())
    }
    pub fn unavailable(e: impl std::fmt::Display) -> StoreError {
        StoreError::Unavailable(e.to_string())
    }
}

pub type StoreResult<T> = Result<T, StoreError>;

/// A job as the store keeps it: its record without the result, the result as the exact JSON
/// text the planner produced (never parsed again: served byte for byte), and the queue's
/// bookkeeping.
#[derive(Debug, Clone)]
pub struct StoredJob {
    /// `result` is always `None` here; see [`StoredJob::result`].
    pub job: Job,
    pub result: Option<Box<RawValue>>,
    pub meta: JobMeta,
}

/// The queue's bookkeeping of a job.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct JobMeta {
    /// Higher runs first; equal priorities run oldest first.
    pub priority: i32,
    /// Attempts allowed (≥ 1): a job whose lease runs out is queued again while
    /// `attempt < max_attempts`.
    pub max_attempts: u32,
    /// Attempts started so far (0 while first queued).
    pub attempt: u32,
    /// The replica that holds the job's lease (running jobs only).
    pub owner: Option<String>,
    /// Unix ms at which the lease runs out (running jobs only).
    pub lease_until_ms: Option<u64>,
    /// A cancel was asked for while the job ran.
    pub cancel_requested: bool,
    /// Sequence number of the job's last event.
    pub last_seq: u64,
}

/// The owner and attempt that a running job's writes must still hold.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fence {
    pub id: String,
    pub owner: String,
    pub attempt: u32,
}

/// A job handed to a planner thread by [`JobStore::claim`]: its record (state `running`) and
/// the fence its writes carry.
#[derive(Debug, Clone)]
pub struct Claimed {
    pub job: Job,
    pub fence: Fence,
    pub meta: JobMeta,
}

/// A new job for [`JobStore::enqueue`] (state `queued`).
#[derive(Debug, Clone)]
pub struct NewJob {
    pub job: Job,
    pub priority: i32,
    pub max_attempts: u32,
}

/// The answer of [`JobStore::enqueue`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Enqueued {
    Accepted,
    /// The cluster-wide queue already holds this many queued jobs (≥ its bound).
    QueueFull {
        depth: usize,
    },
}

/// How a job ends.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub state: JobState,
    /// The result's JSON text (succeeded jobs).
    pub result: Option<Box<RawValue>>,
    pub error: Option<ErrorDetail>,
    /// Last statistics, kept as the job's `progress` when given.
    pub progress: Option<Value>,
    pub finished_ms: u64,
}

/// The answer of [`JobStore::renew`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Renewal {
    /// The lease is extended; `cancel` when a cancel was asked for meanwhile.
    Held { cancel: bool },
    /// The fence no longer holds (the job is final, re-queued or owned by another attempt):
    /// stop and write nothing more.
    Lost,
}

/// The answer of [`JobStore::cancel`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CancelResult {
    /// The job was queued and is now `cancelled`.
    CancelledQueued,
    /// The job is running on `owner`; the cancel is recorded and announced.
    Requested { owner: String },
    /// The job was already final.
    AlreadyFinal,
}

/// One event of a job, as the store records it (`GET /v1/plans/{id}/events` replays them;
/// `Last-Event-ID` is `seq`). `name`: `state` (data: the job record, without result),
/// `progress` (data: `{id, state, progress}`) or `end` (data empty: the stream sends the final
/// job as stored).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EventRec {
    pub seq: u64,
    pub name: String,
    pub data: String,
}

/// What a replica hears about changes, from its own writes and (PostgreSQL) every other
/// replica's, through LISTEN/NOTIFY.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "t", rename_all = "snake_case")]
pub enum Notice {
    /// A job has a new event (or state).
    Job { id: String },
    /// A cancel was asked for a job running on `owner`.
    Cancel { id: String, owner: String },
    /// A job was queued (or re-queued): idle planner threads should try to claim.
    Queued,
    /// An uploaded robot or scene changed (`kind`: `robot` or `scene`).
    Resource { kind: String, name: String },
    /// Notices may have been missed (the listening connection was lost and is back): every
    /// waiter re-reads what it waits for.
    Resync,
}

/// `GET /v1/plans` paging and filters.
#[derive(Debug, Clone, Default)]
pub struct ListQuery {
    pub limit: usize,
    /// Resume after this job (newest first: created time descending, then id descending).
    pub after: Option<Cursor>,
    pub state: Option<JobState>,
    pub kind: Option<String>,
}

/// Position in the list order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Cursor {
    pub created_ms: u64,
    pub id: String,
}

impl Cursor {
    /// The opaque text form: `<created_ms>.<id>`.
    pub fn encode(&self) -> String {
        format!("{}.{}", self.created_ms, self.id)
    }

    pub fn decode(s: &str) -> Option<Cursor> {
        let (ms, id) = s.split_once('.')?;
        let created_ms = ms.parse().ok()?;
        (!id.is_empty() && id.len() <= 64 && id.bytes().all(|b| b.is_ascii_alphanumeric())).then(
            || Cursor {
                created_ms,
                id: id.to_string(),
            },
        )
    }
}

/// One page of the list.
#[derive(Debug, Clone, Default)]
pub struct Page {
    pub jobs: Vec<JobSummary>,
    /// Where the next page starts; `None` on the last page.
    pub next: Option<Cursor>,
}

/// What [`JobStore::expire`] removes: finished jobs older than `retention`, then the oldest
/// finished jobs while the stored results exceed `max_result_bytes`.
#[derive(Debug, Clone, Copy)]
pub struct RetentionPolicy {
    pub retention: Duration,
    pub max_result_bytes: u64,
}

/// What [`JobStore::expire`] removed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Expired {
    pub by_age: usize,
    pub by_size: usize,
    pub bytes: u64,
}

/// Counts for the gauges.
#[derive(Debug, Clone, Default)]
pub struct Counts {
    pub by_state: std::collections::BTreeMap<&'static str, usize>,
    pub result_bytes: u64,
}

/// What [`JobStore::reap`] did with jobs whose lease ran out.
#[derive(Debug, Clone, Default)]
pub struct Reaped {
    pub requeued: Vec<String>,
    pub interrupted: Vec<String>,
}

/// An uploaded robot or scene, shared by every replica.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Resource {
    /// `robot` or `scene`.
    pub kind: String,
    pub name: String,
    /// The upload's body as the client sent it (JSON).
    pub body: Vec<u8>,
    pub updated_ms: u64,
}

/// The job store. Every method may block on I/O: the async runtime awaits them; planner
/// threads run them as tasks on the runtime and wait for the answer.
#[async_trait::async_trait]
pub trait JobStore: Send + Sync + 'static {
    /// `embedded` or `postgres`.
    fn backend(&self) -> &'static str;

    /// Notices of changes (this replica's and, for a shared store, every replica's).
    fn subscribe(&self) -> broadcast::Receiver<Notice>;

    /// Is the store reachable now?
    async fn ping(&self) -> StoreResult<()>;

    /// Records a queued job, unless the queue (cluster-wide) already holds `max_queue`.
    /// Committed before it returns (and before the client is answered).
    async fn enqueue(&self, job: &NewJob, max_queue: usize) -> StoreResult<Enqueued>;

    /// Claims the next queued job (highest priority, then oldest) for `owner`: state
    /// `running`, attempt + 1, a lease of `lease`, a `state` event.
    async fn claim(&self, owner: &str, lease: Duration) -> StoreResult<Option<Claimed>>;

    /// Extends a running job's lease.
    async fn renew(&self, fence: &Fence, lease: Duration) -> StoreResult<Renewal>;

    /// Records a running job's progress (its `progress` and a `progress` event). `false`: the
    /// fence no longer holds.
    async fn progress(&self, fence: &Fence, progress: &Value) -> StoreResult<bool>;

    /// Makes a job final, with an `end` event. With a fence, only while the fence holds; without
    /// one (cancel, shutdown of a queued job), only while the job is not final. `false`: nothing
    /// was written.
    async fn finish(&self, id: &str, fence: Option<&Fence>, outcome: &Outcome)
        -> StoreResult<bool>;

    /// Asks for a cancel: a queued job is cancelled at once; a running one is flagged and its
    /// owner told. `None`: no such job.
    async fn cancel(&self, id: &str, now_ms: u64) -> StoreResult<Option<CancelResult>>;

    async fn get(&self, id: &str) -> StoreResult<Option<StoredJob>>;

    async fn list(&self, q: &ListQuery) -> StoreResult<Page>;

    /// The job's events with `seq > after`, oldest first, at most `limit`.
    async fn events_after(&self, id: &str, after: u64, limit: usize) -> StoreResult<Vec<EventRec>>;

    /// Gives a running job back to the queue (its replica is shutting down): state `queued`,
    /// no owner, a `state` event, and one more attempt allowed (the one given back does not count
    /// against `max_attempts`; attempt numbers only grow, so fences stay unique). Only while the
    /// fence holds and no cancel was asked for (`false`: nothing written).
    async fn release(&self, fence: &Fence) -> StoreResult<bool>;

    /// Running jobs whose lease ran out before `now_ms` (every running job with `all`, for an
    /// embedded store opened after a crash): queued again while attempts remain, else
    /// `interrupted`.
    async fn reap(&self, now_ms: u64, all: bool) -> StoreResult<Reaped>;

    /// Removes old finished jobs (and their events and results).
    async fn expire(&self, policy: &RetentionPolicy, now_ms: u64) -> StoreResult<Expired>;

    async fn counts(&self) -> StoreResult<Counts>;

    /// Jobs queued now (cluster-wide).
    async fn queue_depth(&self) -> StoreResult<usize>;

    /// Stores (inserts or replaces) an uploaded robot or scene and announces it.
    async fn put_resource(&self, r: &Resource) -> StoreResult<()>;

    /// Deletes one; `false` if there was none.
    async fn delete_resource(&self, kind: &str, name: &str) -> StoreResult<bool>;

    async fn get_resource(&self, kind: &str, name: &str) -> StoreResult<Option<Resource>>;

    /// Every uploaded resource of `kind`.
    async fn list_resources(&self, kind: &str) -> StoreResult<Vec<Resource>>;

    /// A content-keyed cache entry (reachability grid, roadmap, grasp list) shared by the
    /// replicas; `None` when no replica has built it yet.
    async fn get_blob(&self, kind: &str, key: &str) -> StoreResult<Option<Vec<u8>>>;

    /// Stores a cache entry (first writer wins: entries are content keyed, so equal).
    async fn put_blob(&self, kind: &str, key: &str, bytes: &[u8]) -> StoreResult<()>;

    /// Closes the store (the embedded file is released for the next process); later calls
    /// fail with [`StoreError::Unavailable`].
    async fn close(&self) {}
}

/// Returns what the calling thread freed to the OS now. A planner builds its result in memory
/// (tens of megabytes for a long, finely sampled trajectory) and the store reads and writes it
/// whole; mimalloc (the server's allocator) keeps freed pages on the thread that freed them
/// until it allocates again, so idle threads would hold the peak of the last large jobs. Called
/// by planner threads after each job and by the embedded store's threads after moving a large
/// result. A no-op under another allocator.
pub fn release_freed_memory() {
    // SAFETY: mi_collect takes no pointers; it only returns this thread's free pages.
    unsafe { libmimalloc_sys::mi_collect(true) };
}

/// Results at least this large (bytes) make the threads that moved them release memory.
pub const LARGE_RESULT: usize = 1 << 20;

/// The record with its result spliced back in: the JSON a `GET` answers, built without
/// parsing the result again.
pub fn job_json(s: &StoredJob) -> String {
    // `Job` with the result as raw JSON (same field order and attributes as `Job`).
    #[derive(Serialize)]
    struct JobHead<'a> {
        id: &'a str,
        kind: &'a str,
        state: JobState,
        created_ms: u64,
        started_ms: Option<u64>,
        finished_ms: Option<u64>,
        time_limit: f64,
        request: &'a Value,
        progress: &'a Option<Value>,
        result: Option<&'a RawValue>,
        error: &'a Option<ErrorDetail>,
        #[serde(skip_serializing_if = "<[String]>::is_empty")]
        warnings: &'a [String],
        #[serde(skip_serializing_if = "Option::is_none")]
        attempt: Option<u32>,
        #[serde(skip_serializing_if = "Option::is_none")]
        max_attempts: Option<u32>,
        #[serde(skip_serializing_if = "Option::is_none")]
        priority: Option<i32>,
        #[serde(skip_serializing_if = "Option::is_none")]
        replica: Option<&'a str>,
    }
    let j = &s.job;
    let head = JobHead {
        id: &j.id,
        kind: &j.kind,
        state: j.state,
        created_ms: j.created_ms,
        started_ms: j.started_ms,
        finished_ms: j.finished_ms,
        time_limit: j.time_limit,
        request: &j.request,
        progress: &j.progress,
        result: s.result.as_deref(),
        error: &j.error,
        warnings: &j.warnings,
        attempt: j.attempt,
        max_attempts: j.max_attempts,
        priority: j.priority,
        replica: j.replica.as_deref(),
    };
    // One allocation of the final size: a large result is then one block the allocator returns
    // to the OS when the answer is sent, not a series of doubled buffers left behind.
    let size = s.result.as_deref().map_or(0, |r| r.get().len())
        + serde_json::to_string(&j.request).map_or(0, |r| r.len())
        + 4096;
    let mut out = Vec::with_capacity(size);
    if serde_json::to_writer(&mut out, &head).is_err() {
        return "{}".into();
    }
    String::from_utf8(out).unwrap_or_else(|_| "{}".into())
}
