//! Rows of the PostgreSQL store: error mapping, conversions between the store's types and
//! columns, and the writes every job change makes inside its transaction (events, notices).

#[allow(unused_imports)]
use super::*;

/// Connection trouble (lost, refused, the server shutting down or not accepting connections
/// yet) is `Unavailable`; SQL errors and undecodable values are `Other`.
pub(super) fn pg_err(e: tokio_postgres::Error) -> StoreError {
    let source = std::error::Error::source(&e);
    // The driver's own text names the step ("error serializing parameter 0"); its source
    // says what went wrong.
    let text = match source {
        Some(s) if e.as_db_error().is_none() => format!("{e}: {s}"),
        _ => e.to_string(),
    };
    if let Some(db) = e.as_db_error() {
        let code = db.code().code();
        // 08: connection exception; 57P: operator intervention (shutdown, crash, starting up);
        // 53300: too many connections.
        return if code.starts_with("08") || code.starts_with("57P") || code == "53300" {
            StoreError::Unavailable(text)
        } else {
            StoreError::Other(text)
        };
    }
    let io = source.is_some_and(|s| s.is::<std::io::Error>());
    if e.is_closed() || io {
        StoreError::Unavailable(text)
    } else {
        StoreError::Other(text)
    }
}

pub(super) fn pool_err(e: PoolError) -> StoreError {
    match e {
        PoolError::Backend(e) => pg_err(e),
        PoolError::NoRuntimeSpecified => StoreError::other(e),
        e => StoreError::unavailable(e),
    }
}

pub(super) fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| u64::try_from(d.as_millis()).unwrap_or(u64::MAX))
        .unwrap_or(0)
}

/// Unsigned values are stored in signed columns (saturating: a time past year 292 million
/// reads back as the largest one).
pub(super) fn to_i64(v: u64) -> i64 {
    i64::try_from(v).unwrap_or(i64::MAX)
}

pub(super) fn to_u64(v: i64) -> u64 {
    u64::try_from(v).unwrap_or(0)
}

pub(super) fn to_i32(v: u32) -> i32 {
    i32::try_from(v).unwrap_or(i32::MAX)
}

pub(super) fn to_u32(v: i32) -> u32 {
    u32::try_from(v).unwrap_or(0)
}

pub(super) fn parse_state(s: &str) -> StoreResult<JobState> {
    JobState::ALL
        .into_iter()
        .find(|st| st.name() == s)
        .ok_or_else(|| StoreError::Other(format!("unknown job state {s:?}")))
}

pub(super) fn error_json(code: &str, message: &str) -> StoreResult<String> {
    serde_json::to_string(&ErrorDetail {
        code: code.into(),
        message: message.into(),
        field: None,
    })
    .map_err(StoreError::other)
}

pub(super) fn cutoff(policy: &RetentionPolicy, now_ms: u64) -> u64 {
    let keep = u64::try_from(policy.retention.as_millis()).unwrap_or(u64::MAX);
    now_ms.saturating_sub(keep)
}

// ---------------------------------------------------------------------------------------------
// Rows

/// The columns a job's record is read from (everything but the result).
macro_rules! job_cols {
    () => {
        "id, kind, state, priority, created_ms, started_ms, finished_ms, time_limit, request, \
         progress, error, warnings, max_attempts, attempt, owner, \
         (extract(epoch FROM lease_until) * 1000)::bigint AS lease_ms, cancel_requested, last_seq"
    };
}
pub(super) use job_cols;

pub(super) fn col<'a, T: tokio_postgres::types::FromSql<'a>>(
    row: &'a Row,
    name: &str,
) -> StoreResult<T> {
    row.try_get(name)
        .map_err(|e| StoreError::Other(format!("column {name}: {e}")))
}

pub(super) fn json_col<T: serde::de::DeserializeOwned>(
    row: &Row,
    name: &str,
) -> StoreResult<Option<T>> {
    col::<Option<&str>>(row, name)?
        .map(|s| serde_json::from_str(s).map_err(|e| StoreError::Other(format!("{name}: {e}"))))
        .transpose()
}

/// A row of [`job_cols!`] as the job's record (without result) and its bookkeeping.
pub(super) fn job_of_row(row: &Row) -> StoreResult<(Job, JobMeta)> {
    let owner: Option<String> = col(row, "owner")?;
    let meta = JobMeta {
        priority: col(row, "priority")?,
        max_attempts: to_u32(col(row, "max_attempts")?),
        attempt: to_u32(col(row, "attempt")?),
        owner: owner.clone(),
        lease_until_ms: col::<Option<i64>>(row, "lease_ms")?.map(to_u64),
        cancel_requested: col(row, "cancel_requested")?,
        last_seq: to_u64(col(row, "last_seq")?),
    };
    let job = Job {
        id: col(row, "id")?,
        kind: col(row, "kind")?,
        state: parse_state(col(row, "state")?)?,
        created_ms: to_u64(col(row, "created_ms")?),
        started_ms: col::<Option<i64>>(row, "started_ms")?.map(to_u64),
        finished_ms: col::<Option<i64>>(row, "finished_ms")?.map(to_u64),
        time_limit: col(row, "time_limit")?,
        request: json_col(row, "request")?.unwrap_or(Value::Null),
        progress: json_col(row, "progress")?,
        result: None,
        error: json_col(row, "error")?,
        warnings: json_col(row, "warnings")?.unwrap_or_default(),
        attempt: Some(meta.attempt),
        max_attempts: Some(meta.max_attempts),
        priority: Some(meta.priority),
        replica: owner,
    };
    Ok((job, meta))
}

// ---------------------------------------------------------------------------------------------
// Writes inside a transaction

pub(super) async fn append_event(
    tx: &Transaction<'_>,
    id: &str,
    seq: i64,
    name: &str,
    data: &str,
) -> StoreResult<()> {
    let st = tx
        .prepare_cached("INSERT INTO events (job_id, seq, name, data) VALUES ($1, $2, $3, $4)")
        .await
        .map_err(pg_err)?;
    tx.execute(&st, &[&id, &seq, &name, &data])
        .await
        .map_err(pg_err)?;
    Ok(())
}

/// A `state` event carrying the job's record as it is now.
pub(super) async fn state_event(
    tx: &Transaction<'_>,
    job: &Job,
    meta: &JobMeta,
) -> StoreResult<()> {
    let data = serde_json::to_string(job).map_err(StoreError::other)?;
    append_event(tx, &job.id, to_i64(meta.last_seq), "state", &data).await
}

/// Sends the notices at commit.
pub(super) async fn notify(tx: &Transaction<'_>, notices: &[Notice]) -> StoreResult<()> {
    let payloads = notices
        .iter()
        .map(serde_json::to_string)
        .collect::<Result<Vec<String>, _>>()
        .map_err(StoreError::other)?;
    let st = tx
        .prepare_cached("SELECT pg_notify($1, n) FROM unnest($2::text[]) AS n")
        .await
        .map_err(pg_err)?;
    tx.execute(&st, &[&CHANNEL, &payloads])
        .await
        .map_err(pg_err)?;
    Ok(())
}

pub(super) fn job_notice(id: &str) -> Notice {
    Notice::Job { id: id.to_string() }
}
