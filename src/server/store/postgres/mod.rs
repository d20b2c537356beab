//! The PostgreSQL job store, shared by any number of replicas.
//!
//! A job is a row of `jobs`; its events are rows of `events` (`seq` 1, 2, … per job, the job's
//! `last_seq` counts them); JSON is kept as text (never `jsonb`), so a result is served byte for
//! byte as the planner wrote it. The schema is in `migrations/` (embedded here), applied at
//! [`PgStore::connect`] under an advisory lock so that replicas starting together do not race.
//!
//! The queue is the usual PostgreSQL job queue: a claim takes the next queued row with
//! `FOR UPDATE SKIP LOCKED`, so concurrent claimers (threads or replicas) never get the same
//! job; a running job's writes are conditional on its owner and attempt (its fence). Lease
//! deadlines are on the database's clock (`now()`), so the replicas' clocks need not agree.
//!
//! Every write that changes a job sends `pg_notify('manyhands', <Notice JSON>)` in its own
//! transaction (delivered at commit). One connection per store LISTENs and forwards the
//! notices to [`JobStore::subscribe`]rs; when it is lost it reconnects (backoff 100 ms → 1 s)
//! and then sends [`Notice::Resync`], since notices may have been missed meanwhile.
//!
//! What the trait leaves open, decided here:
//! - `reap`: a running job whose lease ran out after a cancel was asked for becomes `cancelled`
//!   (not queued again) and is listed in [`Reaped::interrupted`] with the interrupted ones: that
//!   list holds every job the reap made final. An interrupted job keeps its owner on record.
//! - `enqueue` records the job as queued whatever its record says (no start, end, progress or
//!   error), with `max_attempts` at least 1.
//! - `finish` with a state that is not final is an error; with a fence of another job, `false`.
//! - `list` with `limit` 0 answers as with 1 (a page always makes progress).
//! - `delete_resource` announces only a deletion that happened.
//! - `expire`: among jobs finished in the same millisecond, the larger id counts as the newer.

use std::pin::Pin;
use std::str::FromStr;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use deadpool_postgres::{
    Manager, ManagerConfig, Pool, PoolError, RecyclingMethod, Runtime, Transaction,
};
use futures_util::{Stream, StreamExt};
use serde_json::value::RawValue;
use serde_json::Value;
use tokio::sync::broadcast;
use tokio::task::JoinHandle;
use tokio_postgres::types::ToSql;
use tokio_postgres::{AsyncMessage, NoTls, Row};

use super::{
    CancelResult, Claimed, Counts, Cursor, Enqueued, EventRec, Expired, Fence, JobMeta, JobStore,
    ListQuery, NewJob, Notice, Outcome, Page, Reaped, Renewal, Resource, RetentionPolicy,
    StoreError, StoreResult, StoredJob,
};
use crate::server::api::{Job, JobState, JobSummary};
use manyhands_api::ErrorDetail;

mod listen;
mod migrate;
mod rows;

use listen::*;
use migrate::*;
use rows::*;

/// The schema, in order; each runs once per database.
const MIGRATIONS: &[(i32, &str)] = &[(1, include_str!("../../../../migrations/0001_jobs.sql"))];

/// The LISTEN/NOTIFY channel.
const CHANNEL: &str = "manyhands";

/// Advisory lock keys ("mh" + a purpose): schema migrations, and the queue's bound check.
const MIGRATION_LOCK: i64 = 0x6d68_0000_0000_0001;
const QUEUE_LOCK: i64 = 0x6d68_0000_0000_0002;

/// Capacity of the notice broadcast (a subscriber that lags behind more than this misses
/// notices and is told so by `RecvError::Lagged`).
const NOTICE_CAPACITY: usize = 1024;

/// Connection pool settings.
#[derive(Debug, Clone)]
pub struct PgOptions {
    /// Connections kept open at most.
    pub pool_size: usize,
    /// Time to open a connection (unless the URL sets `connect_timeout`), and the longest a
    /// call waits for a free connection or for checking an idle one: with the database down, a
    /// call fails with [`StoreError::Unavailable`] after about this long instead of hanging.
    pub connect_timeout: Duration,
}

impl Default for PgOptions {
    fn default() -> Self {
        PgOptions {
            pool_size: 16,
            connect_timeout: Duration::from_secs(2),
        }
    }
}

/// A result larger than this (bytes) passed through a connection retires it: the driver keeps
/// its read and write buffers at their largest size, so a pooled connection that carried an
/// 18 MB result would hold that much memory for as long as it lives.
const LARGE_BYTES: i64 = 1 << 20;

/// Closes a pooled connection instead of returning it to the pool (its buffers go with it).
fn retire(client: deadpool_postgres::Client) {
    drop(deadpool_postgres::Object::take(client));
}

/// The job store in a PostgreSQL database.
pub struct PgStore {
    pool: Pool,
    notices: broadcast::Sender<Notice>,
    listener: JoinHandle<()>,
}

impl Drop for PgStore {
    fn drop(&mut self) {
        self.listener.abort();
    }
}

impl PgStore {
    /// Connects to the database at `url` (`postgres://user@host:port/db`, or the key=value
    /// form), applies the migrations it lacks and starts listening for notices.
    pub async fn connect(url: &str, opts: PgOptions) -> StoreResult<PgStore> {
        let cfg = pg_config(url, &opts)?;
        let manager = Manager::from_config(
            cfg.clone(),
            NoTls,
            ManagerConfig {
                // A connection is checked before reuse: those left over from before a database
                // restart are dropped and replaced.
                recycling_method: RecyclingMethod::Verified,
            },
        );
        let wait = Some(opts.connect_timeout);
        let pool = Pool::builder(manager)
            .max_size(opts.pool_size.max(1))
            .runtime(Runtime::Tokio1)
            .wait_timeout(wait)
            .create_timeout(wait)
            .recycle_timeout(wait)
            .build()
            .map_err(StoreError::other)?;
        migrate(&pool).await?;
        let listener = listen(&cfg).await.map_err(StoreError::Unavailable)?;
        let (notices, _) = broadcast::channel(NOTICE_CAPACITY);
        let listener = tokio::spawn(run_listener(cfg, notices.clone(), listener));
        Ok(PgStore {
            pool,
            notices,
            listener,
        })
    }

    async fn client(&self) -> StoreResult<deadpool_postgres::Client> {
        self.pool.get().await.map_err(pool_err)
    }
}

/// The URL parsed, with this store's defaults where it sets none.
fn pg_config(url: &str, opts: &PgOptions) -> StoreResult<tokio_postgres::Config> {
    let mut cfg = tokio_postgres::Config::from_str(url)
        .map_err(|e| StoreError::Other(format!("database URL: {e}")))?;
    if cfg.get_connect_timeout().is_none() {
        cfg.connect_timeout(opts.connect_timeout);
    }
    if cfg.get_application_name().is_none() {
        cfg.application_name("manyhands");
    }
    // A silently dropped connection (no FIN: host gone, network cut) is noticed in minutes,
    // not hours.
    cfg.keepalives_idle(Duration::from_secs(30));
    Ok(cfg)
}
// ---------------------------------------------------------------------------------------------
// The trait

const FINAL_STATES: &str = "('succeeded', 'failed', 'cancelled', 'interrupted')";

#[async_trait::async_trait]
impl JobStore for PgStore {
    fn backend(&self) -> &'static str {
        "postgres"
    }

    async fn close(&self) {
        self.listener.abort();
        self.pool.close();
    }

    fn subscribe(&self) -> broadcast::Receiver<Notice> {
        self.notices.subscribe()
    }

    async fn ping(&self) -> StoreResult<()> {
        let client = self.client().await?;
        client.simple_query("SELECT 1").await.map_err(pg_err)?;
        Ok(())
    }

    async fn enqueue(&self, new: &NewJob, max_queue: usize) -> StoreResult<Enqueued> {
        let job = &new.job;
        let request = serde_json::to_string(&job.request).map_err(StoreError::other)?;
        let warnings = serde_json::to_string(&job.warnings).map_err(StoreError::other)?;
        let mut client = self.client().await?;
        let tx = client.transaction().await.map_err(pg_err)?;
        // One enqueue at a time checks the bound, so concurrent ones cannot overshoot it.
        tx.batch_execute(&format!("SELECT pg_advisory_xact_lock({QUEUE_LOCK})"))
            .await
            .map_err(pg_err)?;
        let st = tx
            .prepare_cached("SELECT count(*) FROM jobs WHERE state = 'queued'")
            .await
            .map_err(pg_err)?;
        let depth = to_u64(col(
            &tx.query_one(&st, &[]).await.map_err(pg_err)?,
            "count",
        )?);
        let depth = usize::try_from(depth).unwrap_or(usize::MAX);
        if depth >= max_queue {
            tx.rollback().await.map_err(pg_err)?;
            return Ok(Enqueued::QueueFull { depth });
        }
        let st = tx
            .prepare_cached(concat!(
                "INSERT INTO jobs (id, kind, state, priority, created_ms, time_limit, request, \
                 warnings, max_attempts, attempt, cancel_requested, last_seq, result_bytes) \
                 VALUES ($1, $2, 'queued', $3, $4, $5, $6, $7, $8, 0, false, 1, 0) RETURNING ",
                job_cols!()
            ))
            .await
            .map_err(pg_err)?;
        let row = tx
            .query_one(
                &st,
                &[
                    &job.id,
                    &job.kind,
                    &new.priority,
                    &to_i64(job.created_ms),
                    &job.time_limit,
                    &request,
                    &warnings,
                    &to_i32(new.max_attempts.max(1)),
                ],
            )
            .await
            .map_err(pg_err)?;
        let (job, meta) = job_of_row(&row)?;
        state_event(&tx, &job, &meta).await?;
        notify(&tx, &[Notice::Queued, job_notice(&job.id)]).await?;
        tx.commit().await.map_err(pg_err)?;
        Ok(Enqueued::Accepted)
    }

    async fn claim(&self, owner: &str, lease: Duration) -> StoreResult<Option<Claimed>> {
        let mut client = self.client().await?;
        let tx = client.transaction().await.map_err(pg_err)?;
        let st = tx
            .prepare_cached(concat!(
                "UPDATE jobs SET state = 'running', attempt = attempt + 1, owner = $1, \
                 lease_until = now() + make_interval(secs => $2), started_ms = $3, \
                 cancel_requested = false, last_seq = last_seq + 1 \
                 WHERE state = 'queued' AND id = (SELECT id FROM jobs WHERE state = 'queued' \
                 ORDER BY priority DESC, created_ms, id FOR UPDATE SKIP LOCKED LIMIT 1) \
                 RETURNING ",
                job_cols!()
            ))
            .await
            .map_err(pg_err)?;
        let row = tx
            .query_opt(&st, &[&owner, &lease.as_secs_f64(), &to_i64(now_ms())])
            .await
            .map_err(pg_err)?;
        let Some(row) = row else {
            tx.rollback().await.map_err(pg_err)?;
            return Ok(None);
        };
        let (job, meta) = job_of_row(&row)?;
        state_event(&tx, &job, &meta).await?;
        notify(&tx, &[job_notice(&job.id)]).await?;
        tx.commit().await.map_err(pg_err)?;
        let fence = Fence {
            id: job.id.clone(),
            owner: owner.to_string(),
            attempt: meta.attempt,
        };
        Ok(Some(Claimed { job, fence, meta }))
    }

    async fn renew(&self, fence: &Fence, lease: Duration) -> StoreResult<Renewal> {
        let client = self.client().await?;
        let st = client
            .prepare_cached(
                "UPDATE jobs SET lease_until = now() + make_interval(secs => $4) \
                 WHERE id = $1 AND state = 'running' AND owner = $2 AND attempt = $3 \
                 RETURNING cancel_requested",
            )
            .await
            .map_err(pg_err)?;
        let row = client
            .query_opt(
                &st,
                &[
                    &fence.id,
                    &fence.owner,
                    &to_i32(fence.attempt),
                    &lease.as_secs_f64(),
                ],
            )
            .await
            .map_err(pg_err)?;
        Ok(match row {
            Some(row) => Renewal::Held {
                cancel: col(&row, "cancel_requested")?,
            },
            None => Renewal::Lost,
        })
    }

    async fn progress(&self, fence: &Fence, progress: &Value) -> StoreResult<bool> {
        let text = progress.to_string();
        let mut client = self.client().await?;
        let tx = client.transaction().await.map_err(pg_err)?;
        let st = tx
            .prepare_cached(
                "UPDATE jobs SET progress = $4, last_seq = last_seq + 1 \
                 WHERE id = $1 AND state = 'running' AND owner = $2 AND attempt = $3 \
                 RETURNING last_seq",
            )
            .await
            .map_err(pg_err)?;
        let row = tx
            .query_opt(
                &st,
                &[&fence.id, &fence.owner, &to_i32(fence.attempt), &text],
            )
            .await
            .map_err(pg_err)?;
        let Some(row) = row else {
            tx.rollback().await.map_err(pg_err)?;
            return Ok(false);
        };
        let seq: i64 = col(&row, "last_seq")?;
        let data = serde_json::json!({"id": fence.id, "state": "running", "progress": progress});
        append_event(&tx, &fence.id, seq, "progress", &data.to_string()).await?;
        notify(&tx, &[job_notice(&fence.id)]).await?;
        tx.commit().await.map_err(pg_err)?;
        Ok(true)
    }

    async fn finish(
        &self,
        id: &str,
        fence: Option<&Fence>,
        outcome: &Outcome,
    ) -> StoreResult<bool> {
        if !outcome.state.is_final() {
            return Err(StoreError::Other(format!(
                "finish with the non-final state {}",
                outcome.state.name()
            )));
        }
        let result = outcome.result.as_deref().map(RawValue::get);
        let result_bytes = result.map_or(0, |r| to_i64(r.len() as u64));
        let error = outcome
            .error
            .as_ref()
            .map(serde_json::to_string)
            .transpose()
            .map_err(StoreError::other)?;
        if fence.is_some_and(|f| f.id != id) {
            return Ok(false);
        }
        let progress = outcome.progress.as_ref().map(Value::to_string);
        let finished = to_i64(outcome.finished_ms);
        let state = outcome.state.name();
        let mut client = self.client().await?;
        let tx = client.transaction().await.map_err(pg_err)?;
        const SET: &str = "UPDATE jobs SET state = $2, finished_ms = $3, result = $4, \
                           result_bytes = $5, error = $6, progress = COALESCE($7, progress), \
                           lease_until = NULL, last_seq = last_seq + 1 WHERE id = $1 AND ";
        let row = match fence {
            Some(f) => {
                let sql = format!(
                    "{SET}state = 'running' AND owner = $8 AND attempt = $9 RETURNING last_seq"
                );
                let st = tx.prepare_cached(&sql).await.map_err(pg_err)?;
                let attempt = to_i32(f.attempt);
                tx.query_opt(
                    &st,
                    &[
                        &id,
                        &state,
                        &finished,
                        &result,
                        &result_bytes,
                        &error,
                        &progress,
                        &f.owner,
                        &attempt,
                    ],
                )
                .await
            }
            None => {
                let sql = format!("{SET}state IN ('queued', 'running') RETURNING last_seq");
                let st = tx.prepare_cached(&sql).await.map_err(pg_err)?;
                tx.query_opt(
                    &st,
                    &[
                        &id,
                        &state,
                        &finished,
                        &result,
                        &result_bytes,
                        &error,
                        &progress,
                    ],
                )
                .await
            }
        }
        .map_err(pg_err)?;
        let Some(row) = row else {
            tx.rollback().await.map_err(pg_err)?;
            return Ok(false);
        };
        append_event(&tx, id, col(&row, "last_seq")?, "end", "").await?;
        notify(&tx, &[job_notice(id)]).await?;
        tx.commit().await.map_err(pg_err)?;
        if result_bytes > LARGE_BYTES {
            retire(client);
        }
        Ok(true)
    }

    async fn cancel(&self, id: &str, now_ms: u64) -> StoreResult<Option<CancelResult>> {
        let mut client = self.client().await?;
        let tx = client.transaction().await.map_err(pg_err)?;
        let st = tx
            .prepare_cached("SELECT state, owner FROM jobs WHERE id = $1 FOR UPDATE")
            .await
            .map_err(pg_err)?;
        let Some(row) = tx.query_opt(&st, &[&id]).await.map_err(pg_err)? else {
            tx.rollback().await.map_err(pg_err)?;
            return Ok(None);
        };
        let answer = match parse_state(col(&row, "state")?)? {
            JobState::Queued => {
                let error = error_json("cancelled", "cancelled while queued")?;
                let st = tx
                    .prepare_cached(
                        "UPDATE jobs SET state = 'cancelled', finished_ms = $2, error = $3, \
                         lease_until = NULL, last_seq = last_seq + 1 WHERE id = $1 \
                         RETURNING last_seq",
                    )
                    .await
                    .map_err(pg_err)?;
                let row = tx
                    .query_one(&st, &[&id, &to_i64(now_ms), &error])
                    .await
                    .map_err(pg_err)?;
                append_event(&tx, id, col(&row, "last_seq")?, "end", "").await?;
                notify(&tx, &[job_notice(id)]).await?;
                CancelResult::CancelledQueued
            }
            JobState::Running => {
                let owner: String = col::<Option<String>>(&row, "owner")?.unwrap_or_default();
                let st = tx
                    .prepare_cached("UPDATE jobs SET cancel_requested = true WHERE id = $1")
                    .await
                    .map_err(pg_err)?;
                tx.execute(&st, &[&id]).await.map_err(pg_err)?;
                let cancel = Notice::Cancel {
                    id: id.to_string(),
                    owner: owner.clone(),
                };
                notify(&tx, &[cancel, job_notice(id)]).await?;
                CancelResult::Requested { owner }
            }
            _ => CancelResult::AlreadyFinal,
        };
        tx.commit().await.map_err(pg_err)?;
        Ok(Some(answer))
    }

    async fn get(&self, id: &str) -> StoreResult<Option<StoredJob>> {
        let client = self.client().await?;
        let st = client
            .prepare_cached(concat!(
                "SELECT ",
                job_cols!(),
                ", result FROM jobs WHERE id = $1"
            ))
            .await
            .map_err(pg_err)?;
        let Some(row) = client.query_opt(&st, &[&id]).await.map_err(pg_err)? else {
            return Ok(None);
        };
        let (job, meta) = job_of_row(&row)?;
        let result = col::<Option<String>>(&row, "result")?
            .map(|text| {
                RawValue::from_string(text).map_err(|e| StoreError::Other(format!("result: {e}")))
            })
            .transpose()?;
        drop(row);
        if result
            .as_ref()
            .is_some_and(|r| r.get().len() as i64 > LARGE_BYTES)
        {
            retire(client);
        }
        Ok(Some(StoredJob { job, result, meta }))
    }

    async fn list(&self, q: &ListQuery) -> StoreResult<Page> {
        let limit = q.limit.max(1);
        let after_ms = q.after.as_ref().map(|c| to_i64(c.created_ms));
        let after_id = q.after.as_ref().map(|c| c.id.as_str());
        let state = q.state.map(JobState::name);
        let fetch = to_i64(limit as u64).saturating_add(1);
        let mut sql = String::from("SELECT id, kind, state, created_ms FROM jobs");
        let mut params: Vec<&(dyn ToSql + Sync)> = Vec::new();
        let mut conds = Vec::new();
        if let (Some(ms), Some(id)) = (&after_ms, &after_id) {
            params.push(ms);
            params.push(id);
            conds.push(format!(
                "(created_ms, id) < (${}, ${})",
                params.len() - 1,
                params.len()
            ));
        }
        if let Some(state) = &state {
            params.push(state);
            conds.push(format!("state = ${}", params.len()));
        }
        if let Some(kind) = &q.kind {
            params.push(kind);
            conds.push(format!("kind = ${}", params.len()));
        }
        if !conds.is_empty() {
            sql.push_str(" WHERE ");
            sql.push_str(&conds.join(" AND "));
        }
        params.push(&fetch);
        sql.push_str(&format!(
            " ORDER BY created_ms DESC, id DESC LIMIT ${}",
            params.len()
        ));
        let client = self.client().await?;
        let st = client.prepare_cached(&sql).await.map_err(pg_err)?;
        let rows = client.query(&st, &params).await.map_err(pg_err)?;
        let more = rows.len() > limit;
        let jobs = rows
            .iter()
            .take(limit)
            .map(|r| {
                Ok(JobSummary {
                    id: col(r, "id")?,
                    kind: col(r, "kind")?,
                    state: parse_state(col(r, "state")?)?,
                    created_ms: to_u64(col(r, "created_ms")?),
                })
            })
            .collect::<StoreResult<Vec<_>>>()?;
        let next = if more {
            jobs.last().map(|j| Cursor {
                created_ms: j.created_ms,
                id: j.id.clone(),
            })
        } else {
            None
        };
        Ok(Page { jobs, next })
    }

    async fn events_after(&self, id: &str, after: u64, limit: usize) -> StoreResult<Vec<EventRec>> {
        let client = self.client().await?;
        let st = client
            .prepare_cached(
                "SELECT seq, name, data FROM events WHERE job_id = $1 AND seq > $2 \
                 ORDER BY seq LIMIT $3",
            )
            .await
            .map_err(pg_err)?;
        let limit = to_i64(limit as u64);
        client
            .query(&st, &[&id, &to_i64(after), &limit])
            .await
            .map_err(pg_err)?
            .iter()
            .map(|r| {
                Ok(EventRec {
                    seq: to_u64(col(r, "seq")?),
                    name: col(r, "name")?,
                    data: col(r, "data")?,
                })
            })
            .collect()
    }

    async fn release(&self, fence: &Fence) -> StoreResult<bool> {
        let mut client = self.client().await?;
        let tx = client.transaction().await.map_err(pg_err)?;
        let st = tx
            .prepare_cached(concat!(
                "UPDATE jobs SET state = 'queued', owner = NULL, lease_until = NULL, \
                 max_attempts = max_attempts + 1, last_seq = last_seq + 1 \
                 WHERE id = $1 AND state = 'running' AND owner = $2 AND attempt = $3 \
                 AND NOT cancel_requested RETURNING ",
                job_cols!()
            ))
            .await
            .map_err(pg_err)?;
        let row = tx
            .query_opt(&st, &[&fence.id, &fence.owner, &to_i32(fence.attempt)])
            .await
            .map_err(pg_err)?;
        let Some(row) = row else {
            tx.rollback().await.map_err(pg_err)?;
            return Ok(false);
        };
        let (job, meta) = job_of_row(&row)?;
        state_event(&tx, &job, &meta).await?;
        notify(&tx, &[Notice::Queued, job_notice(&fence.id)]).await?;
        tx.commit().await.map_err(pg_err)?;
        Ok(true)
    }

    async fn reap(&self, now_ms: u64, all: bool) -> StoreResult<Reaped> {
        let mut client = self.client().await?;
        let tx = client.transaction().await.map_err(pg_err)?;
        let sql = if all {
            "SELECT id, attempt, max_attempts, cancel_requested FROM jobs \
             WHERE state = 'running' ORDER BY id FOR UPDATE SKIP LOCKED"
        } else {
            "SELECT id, attempt, max_attempts, cancel_requested FROM jobs \
             WHERE state = 'running' AND (lease_until IS NULL OR lease_until < now()) \
             ORDER BY id FOR UPDATE SKIP LOCKED"
        };
        let st = tx.prepare_cached(sql).await.map_err(pg_err)?;
        let rows = tx.query(&st, &[]).await.map_err(pg_err)?;
        let mut reaped = Reaped::default();
        for row in &rows {
            let id: String = col(row, "id")?;
            let attempt: i32 = col(row, "attempt")?;
            let max_attempts: i32 = col(row, "max_attempts")?;
            let cancel: bool = col(row, "cancel_requested")?;
            if !cancel && attempt < max_attempts {
                let st = tx
                    .prepare_cached(concat!(
                        "UPDATE jobs SET state = 'queued', owner = NULL, lease_until = NULL, \
                         cancel_requested = false, last_seq = last_seq + 1 WHERE id = $1 \
                         RETURNING ",
                        job_cols!()
                    ))
                    .await
                    .map_err(pg_err)?;
                let row = tx.query_one(&st, &[&id]).await.map_err(pg_err)?;
                let (job, meta) = job_of_row(&row)?;
                state_event(&tx, &job, &meta).await?;
                notify(&tx, &[Notice::Queued, job_notice(&id)]).await?;
                reaped.requeued.push(id);
            } else {
                let (state, error) = if cancel {
                    (
                        "cancelled",
                        error_json("cancelled", "cancelled while running")?,
                    )
                } else {
                    (
                        "interrupted",
                        error_json(
                            "interrupted",
                            "the replica running the job stopped or stalled past its lease",
                        )?,
                    )
                };
                let st = tx
                    .prepare_cached(
                        "UPDATE jobs SET state = $2, finished_ms = $3, error = $4, \
                         lease_until = NULL, last_seq = last_seq + 1 WHERE id = $1 \
                         RETURNING last_seq",
                    )
                    .await
                    .map_err(pg_err)?;
                let row = tx
                    .query_one(&st, &[&id, &state, &to_i64(now_ms), &error])
                    .await
                    .map_err(pg_err)?;
                append_event(&tx, &id, col(&row, "last_seq")?, "end", "").await?;
                notify(&tx, &[job_notice(&id)]).await?;
                reaped.interrupted.push(id);
            }
        }
        tx.commit().await.map_err(pg_err)?;
        Ok(reaped)
    }

    async fn expire(&self, policy: &RetentionPolicy, now_ms: u64) -> StoreResult<Expired> {
        let mut client = self.client().await?;
        let tx = client.transaction().await.map_err(pg_err)?;
        let by_age = format!(
            "WITH gone AS (DELETE FROM jobs WHERE state IN {FINAL_STATES} AND finished_ms < $1 \
             RETURNING result_bytes) \
             SELECT count(*) AS n, COALESCE(sum(result_bytes), 0)::bigint AS bytes FROM gone"
        );
        // The newest finished jobs are kept while their results fit; the rest (the oldest)
        // go. Ties in finished time: the larger id counts as the newer.
        let by_size = format!(
            "WITH ranked AS (SELECT id, sum(result_bytes) OVER (ORDER BY finished_ms DESC, \
             id DESC ROWS UNBOUNDED PRECEDING) AS total FROM jobs WHERE state IN {FINAL_STATES}), \
             gone AS (DELETE FROM jobs j USING ranked r WHERE j.id = r.id AND r.total > $1::bigint \
             RETURNING j.result_bytes) \
             SELECT count(*) AS n, COALESCE(sum(result_bytes), 0)::bigint AS bytes FROM gone"
        );
        let mut out = Expired::default();
        let st = tx.prepare_cached(&by_age).await.map_err(pg_err)?;
        let row = tx
            .query_one(&st, &[&to_i64(cutoff(policy, now_ms))])
            .await
            .map_err(pg_err)?;
        out.by_age = usize::try_from(col::<i64>(&row, "n")?).unwrap_or(0);
        out.bytes = to_u64(col(&row, "bytes")?);
        let st = tx.prepare_cached(&by_size).await.map_err(pg_err)?;
        let row = tx
            .query_one(&st, &[&to_i64(policy.max_result_bytes)])
            .await
            .map_err(pg_err)?;
        out.by_size = usize::try_from(col::<i64>(&row, "n")?).unwrap_or(0);
        out.bytes = out.bytes.saturating_add(to_u64(col(&row, "bytes")?));
        tx.commit().await.map_err(pg_err)?;
        Ok(out)
    }

    async fn counts(&self) -> StoreResult<Counts> {
        let client = self.client().await?;
        let st = client
            .prepare_cached(
                "SELECT state, count(*) AS n, COALESCE(sum(result_bytes), 0)::bigint AS bytes \
                 FROM jobs GROUP BY state",
            )
            .await
            .map_err(pg_err)?;
        let rows = client.query(&st, &[]).await.map_err(pg_err)?;
        let mut counts = Counts::default();
        for s in JobState::ALL {
            counts.by_state.insert(s.name(), 0);
        }
        for row in &rows {
            let state = parse_state(col(row, "state")?)?;
            let n = usize::try_from(col::<i64>(row, "n")?).unwrap_or(0);
            counts.by_state.insert(state.name(), n);
            counts.result_bytes = counts
                .result_bytes
                .saturating_add(to_u64(col(row, "bytes")?));
        }
        Ok(counts)
    }

    async fn queue_depth(&self) -> StoreResult<usize> {
        let client = self.client().await?;
        let st = client
            .prepare_cached("SELECT count(*) AS n FROM jobs WHERE state = 'queued'")
            .await
            .map_err(pg_err)?;
        let row = client.query_one(&st, &[]).await.map_err(pg_err)?;
        Ok(usize::try_from(col::<i64>(&row, "n")?).unwrap_or(0))
    }

    async fn put_resource(&self, r: &Resource) -> StoreResult<()> {
        let mut client = self.client().await?;
        let tx = client.transaction().await.map_err(pg_err)?;
        let st = tx
            .prepare_cached(
                "INSERT INTO resources (kind, name, body, updated_ms) VALUES ($1, $2, $3, $4) \
                 ON CONFLICT (kind, name) DO UPDATE \
                 SET body = excluded.body, updated_ms = excluded.updated_ms",
            )
            .await
            .map_err(pg_err)?;
        tx.execute(&st, &[&r.kind, &r.name, &r.body, &to_i64(r.updated_ms)])
            .await
            .map_err(pg_err)?;
        let notice = Notice::Resource {
            kind: r.kind.clone(),
            name: r.name.clone(),
        };
        notify(&tx, &[notice]).await?;
        tx.commit().await.map_err(pg_err)
    }

    async fn delete_resource(&self, kind: &str, name: &str) -> StoreResult<bool> {
        let mut client = self.client().await?;
        let tx = client.transaction().await.map_err(pg_err)?;
        let st = tx
            .prepare_cached("DELETE FROM resources WHERE kind = $1 AND name = $2")
            .await
            .map_err(pg_err)?;
        let n = tx.execute(&st, &[&kind, &name]).await.map_err(pg_err)?;
        if n == 0 {
            tx.rollback().await.map_err(pg_err)?;
            return Ok(false);
        }
        let notice = Notice::Resource {
            kind: kind.to_string(),
            name: name.to_string(),
        };
        notify(&tx, &[notice]).await?;
        tx.commit().await.map_err(pg_err)?;
        Ok(true)
    }

    async fn get_resource(&self, kind: &str, name: &str) -> StoreResult<Option<Resource>> {
        let client = self.client().await?;
        let st = client
            .prepare_cached(
                "SELECT kind, name, body, updated_ms FROM resources \
                 WHERE kind = $1 AND name = $2",
            )
            .await
            .map_err(pg_err)?;
        client
            .query_opt(&st, &[&kind, &name])
            .await
            .map_err(pg_err)?
            .as_ref()
            .map(resource_of_row)
            .transpose()
    }

    async fn list_resources(&self, kind: &str) -> StoreResult<Vec<Resource>> {
        let client = self.client().await?;
        let st = client
            .prepare_cached(
                "SELECT kind, name, body, updated_ms FROM resources WHERE kind = $1 \
                 ORDER BY name",
            )
            .await
            .map_err(pg_err)?;
        client
            .query(&st, &[&kind])
            .await
            .map_err(pg_err)?
            .iter()
            .map(resource_of_row)
            .collect()
    }

    async fn get_blob(&self, kind: &str, key: &str) -> StoreResult<Option<Vec<u8>>> {
        let client = self.client().await?;
        let st = client
            .prepare_cached("SELECT bytes FROM blobs WHERE kind = $1 AND key = $2")
            .await
            .map_err(pg_err)?;
        client
            .query_opt(&st, &[&kind, &key])
            .await
            .map_err(pg_err)?
            .map(|r| col(&r, "bytes"))
            .transpose()
    }

    async fn put_blob(&self, kind: &str, key: &str, bytes: &[u8]) -> StoreResult<()> {
        let client = self.client().await?;
        let st = client
            .prepare_cached(
                "INSERT INTO blobs (kind, key, bytes, created_ms) VALUES ($1, $2, $3, $4) \
                 ON CONFLICT (kind, key) DO NOTHING",
            )
            .await
            .map_err(pg_err)?;
        client
            .execute(&st, &[&kind, &key, &bytes, &to_i64(now_ms())])
            .await
            .map_err(pg_err)?;
        Ok(())
    }
}

fn resource_of_row(row: &Row) -> StoreResult<Resource> {
    Ok(Resource {
        kind: col(row, "kind")?,
        name: col(row, "name")?,
        body: col(row, "body")?,
        updated_ms: to_u64(col(row, "updated_ms")?),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn state_names_parse_back() {
        for s in JobState::ALL {
            assert_eq!(parse_state(s.name()).ok(), Some(s));
        }
        assert!(parse_state("paused").is_err());
    }

    #[test]
    fn unsigned_values_saturate() {
        assert_eq!(to_i64(u64::MAX), i64::MAX);
        assert_eq!(to_i64(42), 42);
        assert_eq!(to_u64(-1), 0);
        assert_eq!(to_i32(u32::MAX), i32::MAX);
        assert_eq!(to_u32(-5), 0);
    }

    #[test]
    fn retention_cutoff_never_underflows() {
        let p = RetentionPolicy {
            retention: Duration::from_secs(3600),
            max_result_bytes: 0,
        };
        assert_eq!(cutoff(&p, 10_000_000), 10_000_000 - 3_600_000);
        assert_eq!(cutoff(&p, 5), 0);
        let forever = RetentionPolicy {
            retention: Duration::MAX,
            max_result_bytes: 0,
        };
        assert_eq!(cutoff(&forever, 10_000_000), 0);
    }

    #[test]
    fn notices_fit_a_notify_payload() {
        // pg_notify takes at most 8000 bytes; the longest notice carries two ids of ≤ 64.
        let id = "a".repeat(64);
        let n = Notice::Cancel {
            id: id.clone(),
            owner: id,
        };
        let text = serde_json::to_string(&n).unwrap_or_default();
        assert!(text.len() < 8000 && !text.is_empty());
        assert_eq!(serde_json::from_str::<Notice>(&text).ok(), Some(n));
        let resync = serde_json::to_string(&Notice::Resync).unwrap_or_default();
        assert_eq!(resync, r#"{"t":"resync"}"#);
    }

    #[test]
    fn url_gets_the_store_defaults() {
        let opts = PgOptions::default();
        let cfg = pg_config("postgres://manyhands@127.0.0.1:5432/manyhands", &opts);
        let cfg = cfg.ok();
        assert_eq!(
            cfg.as_ref().and_then(|c| c.get_connect_timeout().copied()),
            Some(opts.connect_timeout)
        );
        assert_eq!(
            cfg.as_ref().and_then(|c| c.get_application_name()),
            Some("manyhands")
        );
        let own = pg_config(
            "postgres://u@h/db?connect_timeout=7&application_name=x",
            &opts,
        )
        .ok();
        assert_eq!(
            own.as_ref().and_then(|c| c.get_connect_timeout().copied()),
            Some(Duration::from_secs(7))
        );
        assert!(matches!(
            pg_config("postgres://u@h:notaport/db", &opts),
            Err(StoreError::Other(_))
        ));
    }

    #[test]
    fn cancel_errors_are_error_details() {
        let text = error_json("cancelled", "cancelled while queued").unwrap_or_default();
        assert_eq!(
            text,
            r#"{"code":"cancelled","message":"cancelled while queued","field":null}"#
        );
    }
}
