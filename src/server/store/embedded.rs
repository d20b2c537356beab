//! The embedded job store: one redb file (`jobs.redb` under the data directory), one process.
//! The default: `manyhands serve` needs nothing else.
//!
//! Tables: `job_heads` (the record without its result, with the queue's bookkeeping),
//! `job_results` (the result's JSON text, read only by a `GET` of that job), `job_events`
//! (`(id, seq)`), and the indexes the queue, paging, the reaper and retention walk:
//! `job_queue` (`(-priority, created, id)` of queued jobs), `job_order` (`(created, id)` →
//! state and kind), `job_running` (id → lease deadline), `job_finished` (`(finished, id)` →
//! result bytes). Every job change is one write transaction, committed durably before the
//! method returns; progress events are committed without a sync of their own (a crash may lose
//! the last progress, never a state). Notices go to this process's subscribers after commit.

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use redb::{
    Database, Durability, ReadableDatabase, ReadableTable, ReadableTableMetadata, Table,
    TableDefinition, WriteTransaction,
};
use serde::{Deserialize, Serialize};
use serde_json::value::RawValue;
use serde_json::{json, Value};
use tokio::sync::broadcast;

use super::{
    CancelResult, Claimed, Counts, Cursor, Enqueued, EventRec, Expired, Fence, JobMeta, JobStore,
    ListQuery, NewJob, Notice, Outcome, Page, Reaped, Renewal, Resource, RetentionPolicy,
    StoreError, StoreResult, StoredJob,
};
use crate::server::api::{Job, JobState, JobSummary};
use manyhands_api::ErrorDetail;

/// The record of the previous layout (whole jobs, results inside), migrated at open.
const OLD_JOBS: TableDefinition<&str, &[u8]> = TableDefinition::new("jobs");
const HEADS: TableDefinition<&str, &[u8]> = TableDefinition::new("job_heads");
const RESULTS: TableDefinition<&str, &[u8]> = TableDefinition::new("job_results");
const EVENTS: TableDefinition<(&str, u64), &[u8]> = TableDefinition::new("job_events");
const QUEUE: TableDefinition<(i64, u64, &str), ()> = TableDefinition::new("job_queue");
const ORDER: TableDefinition<(u64, &str), &str> = TableDefinition::new("job_order");
const RUNNING: TableDefinition<&str, u64> = TableDefinition::new("job_running");
const FINISHED: TableDefinition<(u64, &str), u64> = TableDefinition::new("job_finished");
const RESOURCES: TableDefinition<(&str, &str), &[u8]> = TableDefinition::new("resources");
const BLOBS: TableDefinition<(&str, &str), &[u8]> = TableDefinition::new("blobs");

/// redb's page cache.
const CACHE_BYTES: usize = 16 << 20;

fn err(e: impl std::fmt::Display) -> StoreError {
    StoreError::other(e)
}

fn now_ms() -> u64 {
    crate::server::jobs::now_ms()
}

/// A job's stored head: the record without its result, and the bookkeeping.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Head {
    job: Job,
    meta: JobMeta,
    #[serde(default)]
    result_bytes: u64,
}

impl Head {
    /// The record as served: the bookkeeping's fields filled in.
    fn record(&self) -> Job {
        let mut j = self.job.clone();
        j.result = None;
        j.attempt = Some(self.meta.attempt);
        j.max_attempts = Some(self.meta.max_attempts);
        j.priority = Some(self.meta.priority);
        j.replica = self.meta.owner.clone();
        j
    }
}

fn order_value(state: JobState, kind: &str) -> String {
    format!("{}\t{kind}", state.name())
}

fn state_of(name: &str) -> Option<JobState> {
    JobState::ALL.into_iter().find(|s| s.name() == name)
}

fn encode_event(name: &str, data: &str) -> Vec<u8> {
    let mut v = Vec::with_capacity(name.len() + 1 + data.len());
    v.extend_from_slice(name.as_bytes());
    v.push(b'\n');
    v.extend_from_slice(data.as_bytes());
    v
}

fn decode_event(seq: u64, b: &[u8]) -> EventRec {
    let s = String::from_utf8_lossy(b);
    let (name, data) = s.split_once('\n').unwrap_or((&s, ""));
    EventRec {
        seq,
        name: name.to_string(),
        data: data.to_string(),
    }
}

struct Inner {
    db: Database,
    tx: broadcast::Sender<Notice>,
}

/// The embedded (redb) backend of [`JobStore`].
pub struct EmbeddedStore {
    /// `None` once closed.
    inner: std::sync::RwLock<Option<Arc<Inner>>>,
    tx: broadcast::Sender<Notice>,
}

/// The tables one job change touches.
struct Tables<'t> {
    heads: Table<'t, &'static str, &'static [u8]>,
    events: Table<'t, (&'static str, u64), &'static [u8]>,
    queue: Table<'t, (i64, u64, &'static str), ()>,
    order: Table<'t, (u64, &'static str), &'static str>,
    running: Table<'t, &'static str, u64>,
    finished: Table<'t, (u64, &'static str), u64>,
    results: Table<'t, &'static str, &'static [u8]>,
}

impl<'t> Tables<'t> {
    fn open(txn: &'t WriteTransaction) -> StoreResult<Tables<'t>> {
        Ok(Tables {
            heads: txn.open_table(HEADS).map_err(err)?,
            events: txn.open_table(EVENTS).map_err(err)?,
            queue: txn.open_table(QUEUE).map_err(err)?,
            order: txn.open_table(ORDER).map_err(err)?,
            running: txn.open_table(RUNNING).map_err(err)?,
            finished: txn.open_table(FINISHED).map_err(err)?,
            results: txn.open_table(RESULTS).map_err(err)?,
        })
    }

    fn head(&self, id: &str) -> StoreResult<Option<Head>> {
        match self.heads.get(id).map_err(err)? {
            Some(v) => serde_json::from_slice(v.value()).map(Some).map_err(err),
            None => Ok(None),
        }
    }

    fn put_head(&mut self, h: &Head) -> StoreResult<()> {
        let b = serde_json::to_vec(h).map_err(err)?;
        self.heads
            .insert(h.job.id.as_str(), b.as_slice())
            .map_err(err)?;
        self.order
            .insert(
                (h.job.created_ms, h.job.id.as_str()),
                order_value(h.job.state, &h.job.kind).as_str(),
            )
            .map_err(err)?;
        Ok(())
    }

    /// Appends an event (seq = last_seq + 1) to `h` (the caller stores `h` afterwards).
    fn event(&mut self, h: &mut Head, name: &str, data: &str) -> StoreResult<()> {
        h.meta.last_seq += 1;
        self.events
            .insert(
                (h.job.id.as_str(), h.meta.last_seq),
                encode_event(name, data).as_slice(),
            )
            .map_err(err)?;
        Ok(())
    }

    fn state_event(&mut self, h: &mut Head) -> StoreResult<()> {
        h.meta.last_seq += 1;
        let data = serde_json::to_string(&h.record()).map_err(err)?;
        self.events
            .insert(
                (h.job.id.as_str(), h.meta.last_seq),
                encode_event("state", &data).as_slice(),
            )
            .map_err(err)?;
        Ok(())
    }

    fn queue_key(h: &Head) -> (i64, u64, &str) {
        (
            -(h.meta.priority as i64),
            h.job.created_ms,
            h.job.id.as_str(),
        )
    }

    /// Makes `h` final with `outcome` (indexes, result, `end` event) and stores it.
    fn make_final(&mut self, h: &mut Head, outcome: &Outcome) -> StoreResult<()> {
        let was = h.job.state;
        if was == JobState::Queued {
            self.queue.remove(Self::queue_key(h)).map_err(err)?;
        }
        if was == JobState::Running {
            self.running.remove(h.job.id.as_str()).map_err(err)?;
        }
        h.job.state = outcome.state;
        h.job.finished_ms = Some(outcome.finished_ms);
        h.job.error = outcome.error.clone();
        if let Some(p) = &outcome.progress {
            h.job.progress = Some(p.clone());
        }
        h.meta.lease_until_ms = None;
        h.result_bytes = 0;
        if let Some(r) = &outcome.result {
            let text = r.get();
            self.results
                .insert(h.job.id.as_str(), text.as_bytes())
                .map_err(err)?;
            h.result_bytes = text.len() as u64;
        }
        self.finished
            .insert((outcome.finished_ms, h.job.id.as_str()), h.result_bytes)
            .map_err(err)?;
        self.event(h, "end", "")?;
        self.put_head(h)
    }

    /// Removes a final job and everything of it; its result bytes.
    fn remove(&mut self, id: &str) -> StoreResult<u64> {
        let Some(h) = self.head(id)? else {
            return Ok(0);
        };
        self.heads.remove(id).map_err(err)?;
        self.results.remove(id).map_err(err)?;
        self.order.remove((h.job.created_ms, id)).map_err(err)?;
        if let Some(f) = h.job.finished_ms {
            self.finished.remove((f, id)).map_err(err)?;
        }
        for seq in 1..=h.meta.last_seq {
            self.events.remove((id, seq)).map_err(err)?;
        }
        Ok(h.result_bytes)
    }
}

fn fence_holds(h: &Head, f: &Fence) -> bool {
    h.job.state == JobState::Running
        && h.meta.owner.as_deref() == Some(f.owner.as_str())
        && h.meta.attempt == f.attempt
}

impl EmbeddedStore {
    /// Opens (or creates) the store file; migrates records of the previous layout.
    pub fn open(path: &Path) -> StoreResult<EmbeddedStore> {
        // A small page cache: results are read once per GET and streamed out, so caching them
        // would only hold memory (redb's default cache is 1 GiB).
        let db = Database::builder()
            .set_cache_size(CACHE_BYTES)
            .create(path)
            .map_err(|e| StoreError::Other(format!("{}: {e}", path.display())))?;
        let txn = db.begin_write().map_err(err)?;
        {
            let mut t = Tables::open(&txn)?;
            txn.open_table(RESOURCES).map_err(err)?;
            txn.open_table(BLOBS).map_err(err)?;
            // The previous layout kept whole jobs (results inside) in one table.
            let old: Vec<Job> = match txn.open_table(OLD_JOBS) {
                Ok(o) => {
                    let mut v = Vec::new();
                    for item in o.iter().map_err(err)? {
                        let (k, val) = item.map_err(err)?;
                        match serde_json::from_slice::<Job>(val.value()) {
                            Ok(j) => v.push(j),
                            Err(e) => tracing::warn!(id = k.value(), error = %e,
                                "skipping undecodable job record"),
                        }
                    }
                    v
                }
                Err(e) => return Err(err(e)),
            };
            let migrated = old.len();
            for mut job in old {
                let result = job.result.take();
                let mut h = Head {
                    job,
                    meta: JobMeta {
                        max_attempts: 1,
                        attempt: 1,
                        ..JobMeta::default()
                    },
                    result_bytes: 0,
                };
                if h.job.state == JobState::Queued {
                    h.meta.attempt = 0;
                    t.queue.insert(Tables::queue_key(&h), ()).map_err(err)?;
                } else if h.job.state == JobState::Running {
                    t.running.insert(h.job.id.as_str(), 0).map_err(err)?;
                }
                if let Some(r) = result {
                    let text = serde_json::to_string(&r).map_err(err)?;
                    t.results
                        .insert(h.job.id.as_str(), text.as_bytes())
                        .map_err(err)?;
                    h.result_bytes = text.len() as u64;
                }
                if h.job.state.is_final() {
                    let f = h.job.finished_ms.unwrap_or(h.job.created_ms);
                    t.finished
                        .insert((f, h.job.id.as_str()), h.result_bytes)
                        .map_err(err)?;
                }
                t.state_event(&mut h)?;
                if h.job.state.is_final() {
                    t.event(&mut h, "end", "")?;
                }
                t.put_head(&h)?;
            }
            drop(t);
            if migrated > 0 {
                txn.delete_table(OLD_JOBS).map_err(err)?;
                tracing::info!(count = migrated, "job records migrated to the paged layout");
            } else {
                let _ = txn.delete_table(OLD_JOBS);
            }
        }
        txn.commit().map_err(err)?;
        let (tx, _) = broadcast::channel(1024);
        Ok(EmbeddedStore {
            inner: std::sync::RwLock::new(Some(Arc::new(Inner { db, tx: tx.clone() }))),
            tx,
        })
    }

    /// Runs `f` on a blocking thread with the database.
    async fn blocking<T: Send + 'static>(
        &self,
        f: impl FnOnce(&Inner) -> StoreResult<T> + Send + 'static,
    ) -> StoreResult<T> {
        let inner = self
            .inner
            .read()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
            .ok_or_else(|| StoreError::unavailable("the job store is closed"))?;
        match tokio::runtime::Handle::try_current() {
            Ok(_) => tokio::task::spawn_blocking(move || f(&inner))
                .await
                .map_err(|e| StoreError::Other(format!("store task: {e}")))?,
            Err(_) => f(&inner),
        }
    }
}

impl Inner {
    fn notify(&self, n: Notice) {
        let _ = self.tx.send(n);
    }

    fn write<T>(
        &self,
        durable: bool,
        f: impl FnOnce(&mut Tables<'_>) -> StoreResult<T>,
    ) -> StoreResult<T> {
        let mut txn = self.db.begin_write().map_err(err)?;
        if !durable {
            txn.set_durability(Durability::None).map_err(err)?;
        }
        let out = {
            let mut t = Tables::open(&txn)?;
            f(&mut t)?
        };
        txn.commit().map_err(err)?;
        Ok(out)
    }
}

#[async_trait::async_trait]
impl JobStore for EmbeddedStore {
    fn backend(&self) -> &'static str {
        "embedded"
    }

    fn subscribe(&self) -> broadcast::Receiver<Notice> {
        self.tx.subscribe()
    }

    async fn close(&self) {
        // Operations in flight hold their own reference; the file is released with the last.
        let inner = self.inner.write().unwrap_or_else(|p| p.into_inner()).take();
        if let Some(mut held) = inner {
            // Wait (briefly) for operations in flight, so the file is free when this returns.
            for _ in 0..200 {
                match Arc::try_unwrap(held) {
                    Ok(i) => {
                        drop(i);
                        return;
                    }
                    Err(a) => {
                        held = a;
                        tokio::time::sleep(Duration::from_millis(5)).await;
                    }
                }
            }
        }
    }

    async fn ping(&self) -> StoreResult<()> {
        Ok(())
    }

    async fn enqueue(&self, job: &NewJob, max_queue: usize) -> StoreResult<Enqueued> {
        let job = job.clone();
        self.blocking(move |db| {
            let id = job.job.id.clone();
            let r = db.write(true, |t| {
                let depth = t.queue.len().map_err(err)? as usize;
                if depth >= max_queue {
                    return Ok(Enqueued::QueueFull { depth });
                }
                let mut h = Head {
                    job: Job {
                        state: JobState::Queued,
                        result: None,
                        ..job.job
                    },
                    meta: JobMeta {
                        priority: job.priority,
                        max_attempts: job.max_attempts.max(1),
                        ..JobMeta::default()
                    },
                    result_bytes: 0,
                };
                t.queue.insert(Tables::queue_key(&h), ()).map_err(err)?;
                t.state_event(&mut h)?;
                t.put_head(&h)?;
                Ok(Enqueued::Accepted)
            })?;
            if r == Enqueued::Accepted {
                db.notify(Notice::Queued);
                db.notify(Notice::Job { id });
            }
            Ok(r)
        })
        .await
    }

    async fn claim(&self, owner: &str, lease: Duration) -> StoreResult<Option<Claimed>> {
        let owner = owner.to_string();
        self.blocking(move |db| {
            // Idle threads try often: an empty queue is seen without a (synced) write commit.
            {
                let txn = db.db.begin_read().map_err(err)?;
                if txn
                    .open_table(QUEUE)
                    .map_err(err)?
                    .is_empty()
                    .map_err(err)?
                {
                    return Ok(None);
                }
            }
            let c = db.write(true, |t| {
                let first = t.queue.first().map_err(err)?.map(|(k, _)| {
                    let (p, c, id) = k.value();
                    (p, c, id.to_string())
                });
                let Some((p, c, id)) = first else {
                    return Ok(None);
                };
                t.queue.remove((p, c, id.as_str())).map_err(err)?;
                let Some(mut h) = t.head(&id)? else {
                    return Ok(None);
                };
                let now = now_ms();
                h.job.state = JobState::Running;
                h.job.started_ms = Some(now);
                h.meta.attempt += 1;
                h.meta.owner = Some(owner.clone());
                h.meta.cancel_requested = false;
                let until = now + lease.as_millis() as u64;
                h.meta.lease_until_ms = Some(until);
                t.running.insert(id.as_str(), until).map_err(err)?;
                t.state_event(&mut h)?;
                t.put_head(&h)?;
                Ok(Some(Claimed {
                    job: h.record(),
                    fence: Fence {
                        id: id.clone(),
                        owner: owner.clone(),
                        attempt: h.meta.attempt,
                    },
                    meta: h.meta.clone(),
                }))
            })?;
            if let Some(c) = &c {
                db.notify(Notice::Job {
                    id: c.fence.id.clone(),
                });
            }
            Ok(c)
        })
        .await
    }

    async fn renew(&self, fence: &Fence, lease: Duration) -> StoreResult<Renewal> {
        let fence = fence.clone();
        self.blocking(move |db| {
            db.write(false, |t| {
                let Some(mut h) = t.head(&fence.id)? else {
                    return Ok(Renewal::Lost);
                };
                if !fence_holds(&h, &fence) {
                    return Ok(Renewal::Lost);
                }
                let until = now_ms() + lease.as_millis() as u64;
                h.meta.lease_until_ms = Some(until);
                t.running.insert(fence.id.as_str(), until).map_err(err)?;
                t.put_head(&h)?;
                Ok(Renewal::Held {
                    cancel: h.meta.cancel_requested,
                })
            })
        })
        .await
    }

    async fn progress(&self, fence: &Fence, progress: &Value) -> StoreResult<bool> {
        let fence = fence.clone();
        let progress = progress.clone();
        self.blocking(move |db| {
            let ok = db.write(false, |t| {
                let Some(mut h) = t.head(&fence.id)? else {
                    return Ok(false);
                };
                if !fence_holds(&h, &fence) {
                    return Ok(false);
                }
                let data = serde_json::to_string(
                    &json!({"id": fence.id, "state": h.job.state, "progress": progress}),
                )
                .map_err(err)?;
                h.job.progress = Some(progress);
                t.event(&mut h, "progress", &data)?;
                t.put_head(&h)?;
                Ok(true)
            })?;
            if ok {
                db.notify(Notice::Job {
                    id: fence.id.clone(),
                });
            }
            Ok(ok)
        })
        .await
    }

    async fn finish(
        &self,
        id: &str,
        fence: Option<&Fence>,
        outcome: &Outcome,
    ) -> StoreResult<bool> {
        let id = id.to_string();
        let fence = fence.cloned();
        let outcome = outcome.clone();
        self.blocking(move |db| {
            let ok = db.write(true, |t| {
                let Some(mut h) = t.head(&id)? else {
                    return Ok(false);
                };
                let may = match &fence {
                    Some(f) => f.id == id && fence_holds(&h, f),
                    None => !h.job.state.is_final(),
                };
                if !may {
                    return Ok(false);
                }
                t.make_final(&mut h, &outcome)?;
                Ok(true)
            })?;
            if outcome
                .result
                .as_ref()
                .is_some_and(|r| r.get().len() >= super::LARGE_RESULT)
            {
                super::release_freed_memory();
            }
            if ok {
                db.notify(Notice::Job { id });
            }
            Ok(ok)
        })
        .await
    }

    async fn cancel(&self, id: &str, now: u64) -> StoreResult<Option<CancelResult>> {
        let id = id.to_string();
        self.blocking(move |db| {
            let r = db.write(true, |t| {
                let Some(mut h) = t.head(&id)? else {
                    return Ok(None);
                };
                match h.job.state {
                    JobState::Queued => {
                        t.make_final(
                            &mut h,
                            &Outcome {
                                state: JobState::Cancelled,
                                result: None,
                                error: Some(ErrorDetail {
                                    code: "cancelled".into(),
                                    message: "cancelled while queued".into(),
                                    field: None,
                                }),
                                progress: None,
                                finished_ms: now,
                            },
                        )?;
                        Ok(Some(CancelResult::CancelledQueued))
                    }
                    JobState::Running => {
                        h.meta.cancel_requested = true;
                        let owner = h.meta.owner.clone().unwrap_or_default();
                        t.put_head(&h)?;
                        Ok(Some(CancelResult::Requested { owner }))
                    }
                    _ => Ok(Some(CancelResult::AlreadyFinal)),
                }
            })?;
            match &r {
                Some(CancelResult::CancelledQueued) => db.notify(Notice::Job { id }),
                Some(CancelResult::Requested { owner }) => {
                    db.notify(Notice::Cancel {
                        id: id.clone(),
                        owner: owner.clone(),
                    });
                    db.notify(Notice::Job { id });
                }
                _ => {}
            }
            Ok(r)
        })
        .await
    }

    async fn get(&self, id: &str) -> StoreResult<Option<StoredJob>> {
        let id = id.to_string();
        self.blocking(move |db| {
            let txn = db.db.begin_read().map_err(err)?;
            let heads = txn.open_table(HEADS).map_err(err)?;
            let Some(v) = heads.get(id.as_str()).map_err(err)? else {
                return Ok(None);
            };
            let h: Head = serde_json::from_slice(v.value()).map_err(err)?;
            let result = if h.job.state == JobState::Succeeded || h.result_bytes > 0 {
                let results = txn.open_table(RESULTS).map_err(err)?;
                match results.get(id.as_str()).map_err(err)? {
                    Some(r) => {
                        let text = String::from_utf8(r.value().to_vec()).map_err(err)?;
                        Some(RawValue::from_string(text).map_err(err)?)
                    }
                    None => None,
                }
            } else {
                None
            };
            if h.result_bytes as usize >= super::LARGE_RESULT {
                drop((heads, txn));
                super::release_freed_memory();
            }
            Ok(Some(StoredJob {
                job: h.record(),
                result,
                meta: h.meta,
            }))
        })
        .await
    }

    async fn list(&self, q: &ListQuery) -> StoreResult<Page> {
        let q = q.clone();
        self.blocking(move |db| {
            let txn = db.db.begin_read().map_err(err)?;
            let order = txn.open_table(ORDER).map_err(err)?;
            let range = match &q.after {
                Some(c) => order.range(..(c.created_ms, c.id.as_str())).map_err(err)?,
                None => order.range::<(u64, &str)>(..).map_err(err)?,
            };
            let mut page = Page::default();
            let limit = q.limit.max(1);
            for item in range.rev() {
                let (k, v) = item.map_err(err)?;
                let (created_ms, id) = k.value();
                let value = v.value();
                let (state, kind) = value.split_once('\t').unwrap_or((value, ""));
                let Some(state) = state_of(state) else {
                    continue;
                };
                if q.state.is_some_and(|s| s != state)
                    || q.kind.as_deref().is_some_and(|k| k != kind)
                {
                    continue;
                }
                if page.jobs.len() == limit {
                    let last = &page.jobs[limit - 1];
                    page.next = Some(Cursor {
                        created_ms: last.created_ms,
                        id: last.id.clone(),
                    });
                    break;
                }
                page.jobs.push(JobSummary {
                    id: id.to_string(),
                    kind: kind.to_string(),
                    state,
                    created_ms,
                });
            }
            Ok(page)
        })
        .await
    }

    async fn events_after(&self, id: &str, after: u64, limit: usize) -> StoreResult<Vec<EventRec>> {
        let id = id.to_string();
        self.blocking(move |db| {
            let txn = db.db.begin_read().map_err(err)?;
            let events = txn.open_table(EVENTS).map_err(err)?;
            let mut out = Vec::new();
            for item in events
                .range((id.as_str(), after.saturating_add(1))..=(id.as_str(), u64::MAX))
                .map_err(err)?
            {
                let (k, v) = item.map_err(err)?;
                out.push(decode_event(k.value().1, v.value()));
                if out.len() >= limit {
                    break;
                }
            }
            Ok(out)
        })
        .await
    }

    async fn release(&self, fence: &Fence) -> StoreResult<bool> {
        let fence = fence.clone();
        self.blocking(move |db| {
            let ok = db.write(true, |t| {
                let Some(mut h) = t.head(&fence.id)? else {
                    return Ok(false);
                };
                if !fence_holds(&h, &fence) || h.meta.cancel_requested {
                    return Ok(false);
                }
                t.running.remove(fence.id.as_str()).map_err(err)?;
                h.job.state = JobState::Queued;
                h.meta.owner = None;
                h.meta.lease_until_ms = None;
                h.meta.max_attempts += 1;
                t.queue.insert(Tables::queue_key(&h), ()).map_err(err)?;
                t.state_event(&mut h)?;
                t.put_head(&h)?;
                Ok(true)
            })?;
            if ok {
                db.notify(Notice::Queued);
                db.notify(Notice::Job { id: fence.id });
            }
            Ok(ok)
        })
        .await
    }

    async fn reap(&self, now: u64, all: bool) -> StoreResult<Reaped> {
        self.blocking(move |db| {
            let r = db.write(true, |t| {
                let mut due = Vec::new();
                for item in t.running.iter().map_err(err)? {
                    let (k, v) = item.map_err(err)?;
                    if all || v.value() < now {
                        due.push(k.value().to_string());
                    }
                }
                let mut r = Reaped::default();
                for id in due {
                    t.running.remove(id.as_str()).map_err(err)?;
                    let Some(mut h) = t.head(&id)? else { continue };
                    if h.job.state != JobState::Running {
                        continue;
                    }
                    if h.meta.cancel_requested {
                        t.make_final(&mut h, &cancelled_running(now))?;
                        r.interrupted.push(id);
                    } else if h.meta.attempt < h.meta.max_attempts {
                        h.job.state = JobState::Queued;
                        h.meta.owner = None;
                        h.meta.lease_until_ms = None;
                        t.queue.insert(Tables::queue_key(&h), ()).map_err(err)?;
                        t.state_event(&mut h)?;
                        t.put_head(&h)?;
                        r.requeued.push(id);
                    } else {
                        t.make_final(&mut h, &lease_lost(now))?;
                        r.interrupted.push(id);
                    }
                }
                Ok(r)
            })?;
            if !r.requeued.is_empty() {
                db.notify(Notice::Queued);
            }
            for id in r.requeued.iter().chain(&r.interrupted) {
                db.notify(Notice::Job { id: id.clone() });
            }
            Ok(r)
        })
        .await
    }

    async fn expire(&self, policy: &RetentionPolicy, now: u64) -> StoreResult<Expired> {
        let policy = *policy;
        self.blocking(move |db| {
            db.write(true, |t| {
                let cutoff = now.saturating_sub(policy.retention.as_millis() as u64);
                let mut finished: Vec<(u64, String, u64)> = Vec::new();
                for item in t.finished.iter().map_err(err)? {
                    let (k, v) = item.map_err(err)?;
                    let (f, id) = k.value();
                    finished.push((f, id.to_string(), v.value()));
                }
                let mut out = Expired::default();
                let mut total: u64 = finished.iter().map(|f| f.2).sum();
                // Oldest first: past the age cut-off, every later one is kept unless the
                // results still exceed the cap.
                for (f, id, bytes) in &finished {
                    let by_age = *f < cutoff;
                    if !by_age && total <= policy.max_result_bytes {
                        break;
                    }
                    t.remove(id)?;
                    total -= bytes;
                    out.bytes += bytes;
                    if by_age {
                        out.by_age += 1;
                    } else {
                        out.by_size += 1;
                    }
                }
                Ok(out)
            })
        })
        .await
    }

    async fn counts(&self) -> StoreResult<Counts> {
        self.blocking(|db| {
            let txn = db.db.begin_read().map_err(err)?;
            let order = txn.open_table(ORDER).map_err(err)?;
            let finished = txn.open_table(FINISHED).map_err(err)?;
            let mut c = Counts {
                by_state: JobState::ALL.iter().map(|s| (s.name(), 0)).collect(),
                result_bytes: 0,
            };
            for item in order.iter().map_err(err)? {
                let (_, v) = item.map_err(err)?;
                let value = v.value();
                let state = value.split('\t').next().unwrap_or("");
                if let Some(s) = state_of(state) {
                    *c.by_state.entry(s.name()).or_insert(0) += 1;
                }
            }
            for item in finished.iter().map_err(err)? {
                let (_, v) = item.map_err(err)?;
                c.result_bytes += v.value();
            }
            Ok(c)
        })
        .await
    }

    async fn queue_depth(&self) -> StoreResult<usize> {
        self.blocking(|db| {
            let txn = db.db.begin_read().map_err(err)?;
            let q = txn.open_table(QUEUE).map_err(err)?;
            Ok(q.len().map_err(err)? as usize)
        })
        .await
    }

    async fn put_resource(&self, r: &Resource) -> StoreResult<()> {
        let r = r.clone();
        self.blocking(move |db| {
            let txn = db.db.begin_write().map_err(err)?;
            {
                let mut t = txn.open_table(RESOURCES).map_err(err)?;
                let mut v = r.updated_ms.to_le_bytes().to_vec();
                v.extend_from_slice(&r.body);
                t.insert((r.kind.as_str(), r.name.as_str()), v.as_slice())
                    .map_err(err)?;
            }
            txn.commit().map_err(err)?;
            db.notify(Notice::Resource {
                kind: r.kind,
                name: r.name,
            });
            Ok(())
        })
        .await
    }

    async fn delete_resource(&self, kind: &str, name: &str) -> StoreResult<bool> {
        let (kind, name) = (kind.to_string(), name.to_string());
        self.blocking(move |db| {
            let txn = db.db.begin_write().map_err(err)?;
            let had = {
                let mut t = txn.open_table(RESOURCES).map_err(err)?;
                let had = t
                    .remove((kind.as_str(), name.as_str()))
                    .map_err(err)?
                    .is_some();
                had
            };
            txn.commit().map_err(err)?;
            if had {
                db.notify(Notice::Resource { kind, name });
            }
            Ok(had)
        })
        .await
    }

    async fn get_resource(&self, kind: &str, name: &str) -> StoreResult<Option<Resource>> {
        let (kind, name) = (kind.to_string(), name.to_string());
        self.blocking(move |db| {
            let txn = db.db.begin_read().map_err(err)?;
            let t = txn.open_table(RESOURCES).map_err(err)?;
            let v = t.get((kind.as_str(), name.as_str())).map_err(err)?;
            Ok(v.map(|v| decode_resource(&kind, &name, v.value())))
        })
        .await
    }

    async fn list_resources(&self, kind: &str) -> StoreResult<Vec<Resource>> {
        let kind = kind.to_string();
        self.blocking(move |db| {
            let txn = db.db.begin_read().map_err(err)?;
            let t = txn.open_table(RESOURCES).map_err(err)?;
            let mut out = Vec::new();
            for item in t.range((kind.as_str(), "")..).map_err(err)? {
                let (k, v) = item.map_err(err)?;
                let (k_kind, name) = k.value();
                if k_kind != kind {
                    break;
                }
                out.push(decode_resource(&kind, name, v.value()));
            }
            Ok(out)
        })
        .await
    }

    async fn get_blob(&self, kind: &str, key: &str) -> StoreResult<Option<Vec<u8>>> {
        let (kind, key) = (kind.to_string(), key.to_string());
        self.blocking(move |db| {
            let txn = db.db.begin_read().map_err(err)?;
            let t = txn.open_table(BLOBS).map_err(err)?;
            let v = t.get((kind.as_str(), key.as_str())).map_err(err)?;
            Ok(v.map(|v| v.value().to_vec()))
        })
        .await
    }

    async fn put_blob(&self, kind: &str, key: &str, bytes: &[u8]) -> StoreResult<()> {
        let (kind, key, bytes) = (kind.to_string(), key.to_string(), bytes.to_vec());
        self.blocking(move |db| {
            let txn = db.db.begin_write().map_err(err)?;
            {
                let mut t = txn.open_table(BLOBS).map_err(err)?;
                if t.get((kind.as_str(), key.as_str())).map_err(err)?.is_none() {
                    t.insert((kind.as_str(), key.as_str()), bytes.as_slice())
                        .map_err(err)?;
                }
            }
            txn.commit().map_err(err)
        })
        .await
    }
}

fn decode_resource(kind: &str, name: &str, v: &[u8]) -> Resource {
    let (ms, body) = v.split_at(8.min(v.len()));
    let mut b = [0u8; 8];
    b[..ms.len()].copy_from_slice(ms);
    Resource {
        kind: kind.to_string(),
        name: name.to_string(),
        body: body.to_vec(),
        updated_ms: u64::from_le_bytes(b),
    }
}

/// The outcome of a running job whose lease ran out with no attempt left.
pub fn lease_lost(now: u64) -> Outcome {
    Outcome {
        state: JobState::Interrupted,
        result: None,
        error: Some(ErrorDetail {
            code: "interrupted".into(),
            message: "the replica running the job stopped or stalled past its lease".into(),
            field: None,
        }),
        progress: None,
        finished_ms: now,
    }
}

/// The outcome of a running job that was asked to cancel and whose lease ran out.
pub fn cancelled_running(now: u64) -> Outcome {
    Outcome {
        state: JobState::Cancelled,
        result: None,
        error: Some(ErrorDetail {
            code: "cancelled".into(),
            message: "cancelled while running".into(),
            field: None,
        }),
        progress: None,
        finished_ms: now,
    }
}
