//! The job store contract: what every [`JobStore`] backend must do, written once against the
//! trait. [`contract`] takes a fresh, empty store and exercises every method and the fencing
//! rules; `tests/store_contract.rs` runs it on each backend.
//!
//! Each part leaves no job queued or running, except the last (paging), which leaves 200
//! queued jobs of kind `paging`.
#![allow(dead_code)]

use std::collections::BTreeSet;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use manyhands::server::api::{Job, JobState};
use manyhands::server::store::{
    job_json, CancelResult, Claimed, Cursor, Enqueued, Expired, Fence, JobStore, ListQuery, NewJob,
    Notice, Outcome, Renewal, Resource, RetentionPolicy,
};
use manyhands_api::ErrorDetail;
use serde_json::value::RawValue;
use serde_json::{json, Value};
use tokio::sync::broadcast;

/// How long a notice may take to arrive (PostgreSQL: through LISTEN, after the commit).
pub const NOTICE_WAIT: Duration = Duration::from_secs(5);

const LONG: Duration = Duration::from_secs(60);

pub fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_millis() as u64)
        .unwrap_or(0)
}

/// A queued job's record as the routes build it.
pub fn job(id: &str, kind: &str, created_ms: u64) -> Job {
    Job {
        id: id.into(),
        kind: kind.into(),
        state: JobState::Queued,
        created_ms,
        started_ms: None,
        finished_ms: None,
        time_limit: 12.5,
        request: json!({"kind": kind, "scene": "kitchen", "robots": [{"name": "armar"}], "x": 0.1}),
        progress: None,
        result: None,
        error: None,
        warnings: vec!["time_limit capped to 12.5 s".into()],
        attempt: None,
        max_attempts: None,
        priority: None,
        replica: None,
    }
}

pub fn new_job(id: &str, kind: &str, created_ms: u64, priority: i32, max_attempts: u32) -> NewJob {
    NewJob {
        job: job(id, kind, created_ms),
        priority,
        max_attempts,
    }
}

fn raw(text: &str) -> Box<RawValue> {
    RawValue::from_string(text.to_string()).expect("valid JSON")
}

fn outcome(state: JobState, finished_ms: u64) -> Outcome {
    Outcome {
        state,
        result: None,
        error: None,
        progress: None,
        finished_ms,
    }
}

fn succeeded(result: &str, finished_ms: u64) -> Outcome {
    Outcome {
        result: Some(raw(result)),
        ..outcome(JobState::Succeeded, finished_ms)
    }
}

fn error(code: &str, message: &str) -> ErrorDetail {
    ErrorDetail {
        code: code.into(),
        message: message.into(),
        field: None,
    }
}

/// Waits for `want`, skipping other notices; `false` after `within`.
pub async fn wait_notice(
    rx: &mut broadcast::Receiver<Notice>,
    want: &Notice,
    within: Duration,
) -> bool {
    let deadline = tokio::time::Instant::now() + within;
    loop {
        match tokio::time::timeout_at(deadline, rx.recv()).await {
            Err(_) | Ok(Err(broadcast::error::RecvError::Closed)) => return false,
            Ok(Ok(n)) if &n == want => return true,
            Ok(_) => {}
        }
    }
}

/// Waits until every one of `want` came, in any order (backends may send a write's notices in
/// any order).
pub async fn wait_all(
    rx: &mut broadcast::Receiver<Notice>,
    want: &[Notice],
    within: Duration,
) -> bool {
    let deadline = tokio::time::Instant::now() + within;
    let mut missing: Vec<&Notice> = want.iter().collect();
    while !missing.is_empty() {
        match tokio::time::timeout_at(deadline, rx.recv()).await {
            Err(_) | Ok(Err(broadcast::error::RecvError::Closed)) => return false,
            Ok(Ok(n)) => missing.retain(|w| **w != n),
            Ok(_) => {}
        }
    }
    true
}

fn job_notice(id: &str) -> Notice {
    Notice::Job { id: id.into() }
}

async fn enqueue(store: &dyn JobStore, j: NewJob) {
    let id = j.job.id.clone();
    assert_eq!(
        store.enqueue(&j, 100_000).await.expect("enqueue"),
        Enqueued::Accepted,
        "enqueue {id}"
    );
}

async fn claim(store: &dyn JobStore, owner: &str, lease: Duration) -> Claimed {
    store
        .claim(owner, lease)
        .await
        .expect("claim")
        .expect("a queued job to claim")
}

async fn get(store: &dyn JobStore, id: &str) -> manyhands::server::store::StoredJob {
    store
        .get(id)
        .await
        .expect("get")
        .unwrap_or_else(|| panic!("job {id} exists"))
}

async fn event_names(store: &dyn JobStore, id: &str) -> Vec<String> {
    store
        .events_after(id, 0, 1000)
        .await
        .expect("events")
        .into_iter()
        .map(|e| e.name)
        .collect()
}

/// Nothing queued or running: each part of the contract starts and ends so.
async fn assert_idle(store: &dyn JobStore, part: &str) {
    let c = store.counts().await.expect("counts");
    assert_eq!(
        c.by_state.get("queued"),
        Some(&0),
        "{part}: queued jobs left"
    );
    assert_eq!(
        c.by_state.get("running"),
        Some(&0),
        "{part}: running jobs left"
    );
    assert_eq!(store.queue_depth().await.expect("depth"), 0, "{part}");
}

/// Runs every part of the contract on a fresh, empty store, printing each part's time.
pub async fn contract(store: Arc<dyn JobStore>) {
    let s = &*store;
    let total = Instant::now();
    let mut t = Instant::now();
    let mut lap = |part: &str| {
        println!(
            "contract {} {part}: {:.3} s",
            s.backend(),
            t.elapsed().as_secs_f64()
        );
        t = Instant::now();
    };
    empty_store(s).await;
    lap("empty store");
    enqueue_and_bound(s).await;
    lap("enqueue and the queue bound");
    claim_order(s).await;
    lap("claim order");
    concurrent_claims(store.clone()).await;
    lap("concurrent claims");
    renew_and_cancel_flag(s).await;
    lap("renew");
    stale_fence(s).await;
    lap("stale fence");
    reap_to_final(s).await;
    lap("reap to final");
    finish_once(s).await;
    lap("finish once");
    release_at_shutdown(s).await;
    lap("release");
    cancel_cases(s).await;
    lap("cancel");
    events_and_notices(s).await;
    lap("events and notices");
    results_byte_for_byte(s).await;
    lap("results byte for byte");
    resources_and_blobs(s).await;
    lap("resources and blobs");
    expire(s).await;
    lap("expire");
    counts_match_the_list(s).await;
    lap("counts");
    paging(s).await;
    lap("paging");
    println!(
        "contract {}: {:.2} s in all",
        s.backend(),
        total.elapsed().as_secs_f64()
    );
}

async fn empty_store(s: &dyn JobStore) {
    assert!(!s.backend().is_empty());
    s.ping().await.expect("ping");
    let c = s.counts().await.expect("counts");
    assert_eq!(c.by_state.len(), 6, "every state counted: {:?}", c.by_state);
    for st in JobState::ALL {
        assert_eq!(c.by_state.get(st.name()), Some(&0), "{}", st.name());
    }
    assert_eq!(c.result_bytes, 0);
    assert_eq!(s.queue_depth().await.expect("depth"), 0);
    assert!(s.get("nosuch").await.expect("get").is_none());
    assert_eq!(s.cancel("nosuch", now_ms()).await.expect("cancel"), None);
    assert!(s
        .events_after("nosuch", 0, 10)
        .await
        .expect("events")
        .is_empty());
    assert!(s.claim("r1", LONG).await.expect("claim").is_none());
    let p = s
        .list(&ListQuery {
            limit: 10,
            ..ListQuery::default()
        })
        .await
        .expect("list");
    assert!(p.jobs.is_empty() && p.next.is_none());
}

async fn enqueue_and_bound(s: &dyn JobStore) {
    let now = now_ms();
    for (i, id) in ["enqa", "enqb", "enqc"].into_iter().enumerate() {
        let r = s
            .enqueue(&new_job(id, "joint_space", now + i as u64, 0, 1), 3)
            .await
            .expect("enqueue");
        assert_eq!(r, Enqueued::Accepted, "{id}");
    }
    let full = s
        .enqueue(&new_job("enqd", "joint_space", now, 0, 1), 3)
        .await
        .expect("enqueue");
    assert_eq!(full, Enqueued::QueueFull { depth: 3 });
    assert!(
        s.get("enqd").await.expect("get").is_none(),
        "a refused job is not written"
    );
    assert_eq!(s.queue_depth().await.expect("depth"), 3);

    let stored = get(s, "enqa").await;
    let expected = job("enqa", "joint_space", now);
    let j = &stored.job;
    assert_eq!(j.state, JobState::Queued);
    assert_eq!((j.id.as_str(), j.kind.as_str()), ("enqa", "joint_space"));
    assert_eq!(j.created_ms, now);
    assert_eq!((j.started_ms, j.finished_ms), (None, None));
    assert_eq!(j.time_limit, expected.time_limit);
    assert_eq!(j.request, expected.request);
    assert_eq!(j.warnings, expected.warnings);
    assert_eq!((j.progress.as_ref(), j.result.as_ref()), (None, None));
    assert_eq!(j.error, None);
    assert_eq!(j.attempt, Some(0));
    assert_eq!(j.max_attempts, Some(1));
    assert_eq!(j.priority, Some(0));
    assert_eq!(j.replica, None);
    assert!(stored.result.is_none());
    let m = &stored.meta;
    assert_eq!((m.priority, m.max_attempts, m.attempt), (0, 1, 0));
    assert_eq!((m.owner.as_deref(), m.lease_until_ms), (None, None));
    assert!(!m.cancel_requested);
    assert_eq!(m.last_seq, 1);
    let ev = s.events_after("enqa", 0, 10).await.expect("events");
    assert_eq!(ev.len(), 1);
    assert_eq!((ev[0].seq, ev[0].name.as_str()), (1, "state"));
    let recorded: Job = serde_json::from_str(&ev[0].data).expect("a state event holds a Job");
    assert_eq!(&recorded, j);

    // The bound counts queued jobs only.
    for id in ["enqa", "enqb", "enqc"] {
        assert_eq!(
            s.cancel(id, now_ms()).await.expect("cancel"),
            Some(CancelResult::CancelledQueued)
        );
    }
    let again = s
        .enqueue(&new_job("enqd", "joint_space", now, 0, 1), 1)
        .await
        .expect("enqueue");
    assert_eq!(again, Enqueued::Accepted);
    assert_eq!(
        s.enqueue(&new_job("enqe", "joint_space", now, 0, 1), 1)
            .await
            .expect("enqueue"),
        Enqueued::QueueFull { depth: 1 }
    );
    assert_eq!(
        s.cancel("enqd", now_ms()).await.expect("cancel"),
        Some(CancelResult::CancelledQueued)
    );
    assert_idle(s, "enqueue").await;
}

async fn claim_order(s: &dyn JobStore) {
    let t = now_ms();
    // (id, priority, created): highest priority first, then oldest, then smallest id.
    let jobs = [
        ("orda", 0, t + 10),
        ("ordb", 5, t + 20),
        ("ordc", 0, t + 5),
        ("ordd", 5, t + 20),
        ("orde", -1, t),
        ("ordf", 5, t + 30),
    ];
    for (id, prio, created) in jobs {
        enqueue(s, new_job(id, "reach", created, prio, 1)).await;
    }
    let before = now_ms();
    let mut order = Vec::new();
    while let Some(c) = s.claim("r1", LONG).await.expect("claim") {
        assert_eq!(c.job.state, JobState::Running);
        assert_eq!(c.fence.id, c.job.id);
        assert_eq!((c.fence.owner.as_str(), c.fence.attempt), ("r1", 1));
        assert_eq!(c.job.attempt, Some(1));
        assert_eq!(c.job.replica.as_deref(), Some("r1"));
        assert!(c.job.started_ms.is_some_and(|ms| ms + 5_000 >= before));
        assert!(c.job.result.is_none());
        assert_eq!((c.meta.attempt, c.meta.owner.as_deref()), (1, Some("r1")));
        assert_eq!(c.meta.last_seq, 2);
        // The database's clock sets the deadline: allow some skew.
        let lease = c.meta.lease_until_ms.expect("a lease");
        assert!(
            lease + 30_000 > before + 60_000 && lease < now_ms() + 90_000,
            "lease {lease} vs now {before}"
        );
        order.push(c);
    }
    let ids: Vec<&str> = order.iter().map(|c| c.job.id.as_str()).collect();
    assert_eq!(ids, ["ordb", "ordd", "ordf", "ordc", "orda", "orde"]);
    let stored = get(s, "ordb").await;
    assert_eq!(stored.job.state, JobState::Running);
    assert_eq!(stored.meta.owner.as_deref(), Some("r1"));
    assert_eq!(event_names(s, "ordb").await, ["state", "state"]);
    for c in &order {
        let ok = s
            .finish(&c.job.id, Some(&c.fence), &succeeded("{}", now_ms()))
            .await
            .expect("finish");
        assert!(ok, "finish {}", c.job.id);
    }
    assert_idle(s, "claim order").await;
}

async fn concurrent_claims(store: Arc<dyn JobStore>) {
    let t = now_ms();
    for i in 0..50 {
        enqueue(&*store, new_job(&format!("cc{i:02}"), "reach", t + i, 0, 1)).await;
    }
    let mut tasks = Vec::new();
    for k in 0..8 {
        let store = store.clone();
        tasks.push(tokio::spawn(async move {
            let owner = format!("w{k}");
            let mut got = Vec::new();
            while let Some(c) = store.claim(&owner, LONG).await.expect("claim") {
                got.push(c.fence);
            }
            got
        }));
    }
    let mut fences: Vec<Fence> = Vec::new();
    for task in tasks {
        fences.extend(task.await.expect("claimer"));
    }
    let ids: BTreeSet<&str> = fences.iter().map(|f| f.id.as_str()).collect();
    assert_eq!(fences.len(), 50, "every job claimed once");
    assert_eq!(ids.len(), 50, "no job claimed twice");
    assert_eq!(store.queue_depth().await.expect("depth"), 0);
    for f in &fences {
        let stored = get(&*store, &f.id).await;
        assert_eq!(stored.meta.owner.as_ref(), Some(&f.owner));
        let ok = store
            .finish(&f.id, Some(f), &succeeded("[]", now_ms()))
            .await
            .expect("finish");
        assert!(ok);
    }
    assert_idle(&*store, "concurrent claims").await;
}

async fn renew_and_cancel_flag(s: &dyn JobStore) {
    enqueue(s, new_job("rnw1", "reach", now_ms(), 0, 1)).await;
    let c = claim(s, "r1", LONG).await;
    let f = c.fence.clone();
    assert_eq!(
        s.renew(&f, LONG).await.expect("renew"),
        Renewal::Held { cancel: false }
    );
    assert!(get(s, "rnw1").await.meta.lease_until_ms.is_some());
    let other_owner = Fence {
        owner: "r2".into(),
        ..f.clone()
    };
    let other_attempt = Fence {
        attempt: 2,
        ..f.clone()
    };
    let other_job = Fence {
        id: "nosuch".into(),
        ..f.clone()
    };
    for stale in [&other_owner, &other_attempt, &other_job] {
        assert_eq!(s.renew(stale, LONG).await.expect("renew"), Renewal::Lost);
    }
    assert_eq!(
        s.cancel("rnw1", now_ms()).await.expect("cancel"),
        Some(CancelResult::Requested { owner: "r1".into() })
    );
    let stored = get(s, "rnw1").await;
    assert_eq!(stored.job.state, JobState::Running);
    assert!(stored.meta.cancel_requested);
    assert_eq!(
        s.renew(&f, LONG).await.expect("renew"),
        Renewal::Held { cancel: true }
    );
    let cancelled = Outcome {
        error: Some(error("cancelled", "cancelled while running")),
        ..outcome(JobState::Cancelled, now_ms())
    };
    assert!(s
        .finish("rnw1", Some(&f), &cancelled)
        .await
        .expect("finish"));
    assert_eq!(s.renew(&f, LONG).await.expect("renew"), Renewal::Lost);
    let stored = get(s, "rnw1").await;
    assert_eq!(stored.job.state, JobState::Cancelled);
    assert_eq!(stored.meta.lease_until_ms, None);
    assert_eq!(
        stored.job.replica.as_deref(),
        Some("r1"),
        "the owner stays on record"
    );
    assert_idle(s, "renew").await;
}

/// Lets a lease of zero run out on any clock.
async fn past_lease() {
    tokio::time::sleep(Duration::from_millis(20)).await;
}

async fn stale_fence(s: &dyn JobStore) {
    enqueue(s, new_job("stale1", "reach", now_ms(), 0, 2)).await;
    let first = claim(s, "r1", Duration::ZERO).await;
    assert_eq!(first.fence.attempt, 1);
    // A lease that has not run out is not reaped.
    enqueue(s, new_job("stale2", "reach", now_ms(), -5, 1)).await;
    let live = claim(s, "r3", LONG).await;
    assert_eq!(live.job.id, "stale2");
    past_lease().await;
    let reaped = s.reap(now_ms(), false).await.expect("reap");
    assert_eq!(reaped.requeued, ["stale1"]);
    assert!(reaped.interrupted.is_empty());
    let q = get(s, "stale1").await;
    assert_eq!(q.job.state, JobState::Queued);
    assert_eq!(
        (q.meta.owner.as_deref(), q.meta.lease_until_ms),
        (None, None)
    );
    assert_eq!(q.meta.attempt, 1);
    assert!(!q.meta.cancel_requested);
    assert_eq!(q.job.replica, None);
    let ev = s.events_after("stale1", 0, 100).await.expect("events");
    let last = ev.last().expect("events");
    assert_eq!((last.seq, last.name.as_str()), (3, "state"));
    let recorded: Job = serde_json::from_str(&last.data).expect("job");
    assert_eq!(recorded.state, JobState::Queued);
    assert_eq!(s.queue_depth().await.expect("depth"), 1);

    let f1 = first.fence.clone();
    assert!(!s.progress(&f1, &json!({"n": 1})).await.expect("progress"));
    assert_eq!(s.renew(&f1, LONG).await.expect("renew"), Renewal::Lost);

    let second = claim(s, "r2", LONG).await;
    assert_eq!(second.job.id, "stale1");
    assert_eq!(second.fence.attempt, 2);
    assert_eq!(second.job.attempt, Some(2));
    let f2 = second.fence.clone();
    // The first owner wakes up: none of its writes land.
    assert!(!s.progress(&f1, &json!({"n": 2})).await.expect("progress"));
    assert_eq!(s.renew(&f1, LONG).await.expect("renew"), Renewal::Lost);
    let stale_result = succeeded(r#"{"by":"r1"}"#, now_ms());
    assert!(!s
        .finish("stale1", Some(&f1), &stale_result)
        .await
        .expect("finish"));
    assert!(s.progress(&f2, &json!({"n": 3})).await.expect("progress"));
    assert!(s
        .finish("stale1", Some(&f2), &succeeded(r#"{"by":"r2"}"#, now_ms()))
        .await
        .expect("finish"));
    let done = get(s, "stale1").await;
    assert_eq!(done.job.state, JobState::Succeeded);
    assert_eq!(done.job.replica.as_deref(), Some("r2"));
    assert_eq!(done.job.attempt, Some(2));
    assert_eq!(done.job.progress, Some(json!({"n": 3})));
    assert_eq!(
        done.result.as_deref().map(RawValue::get),
        Some(r#"{"by":"r2"}"#)
    );
    assert_eq!(
        event_names(s, "stale1").await,
        ["state", "state", "state", "state", "progress", "end"]
    );
    assert!(!s
        .finish("stale1", Some(&f2), &stale_result)
        .await
        .expect("finish"));
    assert!(!s
        .finish("stale1", None, &stale_result)
        .await
        .expect("finish"));
    assert!(s
        .finish("stale2", Some(&live.fence), &succeeded("1", now_ms()))
        .await
        .expect("finish"));
    assert_idle(s, "stale fence").await;
}

async fn reap_to_final(s: &dyn JobStore) {
    // No attempt left: interrupted.
    enqueue(s, new_job("reapi", "reach", now_ms(), 0, 1)).await;
    let c = claim(s, "r1", Duration::ZERO).await;
    past_lease().await;
    let at = now_ms();
    let reaped = s.reap(at, false).await.expect("reap");
    assert_eq!(reaped.interrupted, ["reapi"]);
    assert!(reaped.requeued.is_empty());
    let j = get(s, "reapi").await;
    assert_eq!(j.job.state, JobState::Interrupted);
    assert_eq!(j.job.finished_ms, Some(at));
    assert_eq!(
        j.job.error.as_ref().map(|e| e.code.as_str()),
        Some("interrupted")
    );
    assert_eq!(j.meta.lease_until_ms, None);
    assert_eq!(
        event_names(s, "reapi").await.last().map(String::as_str),
        Some("end")
    );
    assert!(!s
        .finish("reapi", Some(&c.fence), &succeeded("1", now_ms()))
        .await
        .expect("finish"));

    // A cancel was asked for: cancelled, not run again (listed with the interrupted ones).
    enqueue(s, new_job("reapc", "reach", now_ms(), 0, 3)).await;
    claim(s, "r1", Duration::ZERO).await;
    assert_eq!(
        s.cancel("reapc", now_ms()).await.expect("cancel"),
        Some(CancelResult::Requested { owner: "r1".into() })
    );
    past_lease().await;
    let reaped = s.reap(now_ms(), false).await.expect("reap");
    assert_eq!(reaped.interrupted, ["reapc"]);
    assert!(reaped.requeued.is_empty());
    let j = get(s, "reapc").await;
    assert_eq!(j.job.state, JobState::Cancelled);
    assert_eq!(
        j.job.error.as_ref().map(|e| e.code.as_str()),
        Some("cancelled")
    );

    // `all`: every running job, whatever its lease.
    enqueue(s, new_job("reapall", "reach", now_ms(), 0, 2)).await;
    claim(s, "r1", LONG).await;
    let none = s.reap(now_ms(), false).await.expect("reap");
    assert!(none.requeued.is_empty() && none.interrupted.is_empty());
    let all = s.reap(now_ms(), true).await.expect("reap");
    assert_eq!(all.requeued, ["reapall"]);
    assert_eq!(
        s.cancel("reapall", now_ms()).await.expect("cancel"),
        Some(CancelResult::CancelledQueued)
    );
    assert_idle(s, "reap").await;
}

/// A replica shutting down gives its running job back: queued again with one more attempt
/// allowed, a new claim gets a new attempt number (the old fence stays dead); never a cancelled
/// one, never with a stale fence.
async fn release_at_shutdown(s: &dyn JobStore) {
    enqueue(s, new_job("rel1", "reach", now_ms(), 0, 1)).await;
    let c1 = claim(s, "leaving", LONG).await;
    assert_eq!(c1.job.id, "rel1");
    assert!(s.release(&c1.fence).await.expect("release"));
    let j = get(s, "rel1").await;
    assert_eq!(j.job.state, JobState::Queued);
    assert_eq!(j.meta.owner, None);
    assert_eq!(j.meta.max_attempts, 2);
    assert!(!s.release(&c1.fence).await.expect("release twice"));
    let c2 = claim(s, "staying", LONG).await;
    assert_eq!(c2.job.id, "rel1");
    assert_eq!(c2.fence.attempt, 2);
    assert!(!s
        .progress(&c1.fence, &serde_json::json!({"old": true}))
        .await
        .expect("progress"));
    // A job asked to cancel is not given back.
    assert!(matches!(
        s.cancel("rel1", now_ms()).await.expect("cancel"),
        Some(CancelResult::Requested { .. })
    ));
    assert!(!s.release(&c2.fence).await.expect("release"));
    assert!(s
        .finish(
            "rel1",
            Some(&c2.fence),
            &outcome(JobState::Cancelled, now_ms())
        )
        .await
        .expect("finish"));
    let names = event_names(s, "rel1").await;
    assert_eq!(
        names,
        ["state", "state", "state", "state", "end"],
        "{names:?}"
    );
}

async fn finish_once(s: &dyn JobStore) {
    // Without a fence: a queued job (shutdown) ends once.
    enqueue(s, new_job("fin1", "reach", now_ms(), 0, 1)).await;
    let shutdown = Outcome {
        error: Some(error("interrupted", "the server stopped")),
        ..outcome(JobState::Interrupted, now_ms())
    };
    assert!(s.finish("fin1", None, &shutdown).await.expect("finish"));
    assert!(!s.finish("fin1", None, &shutdown).await.expect("finish"));
    let j = get(s, "fin1").await;
    assert_eq!(j.job.state, JobState::Interrupted);
    assert_eq!(j.job.error, shutdown.error);
    assert_eq!(event_names(s, "fin1").await, ["state", "end"]);
    assert!(!s.finish("nosuch", None, &shutdown).await.expect("finish"));

    // Without a fence on a running job; the fence then no longer holds.
    enqueue(s, new_job("fin2", "reach", now_ms(), 0, 1)).await;
    let c = claim(s, "r1", LONG).await;
    assert!(s
        .finish("fin2", None, &outcome(JobState::Cancelled, now_ms()))
        .await
        .expect("finish"));
    assert!(!s
        .finish("fin2", Some(&c.fence), &succeeded("1", now_ms()))
        .await
        .expect("finish"));
    assert_eq!(get(s, "fin2").await.job.state, JobState::Cancelled);

    // A fence is for its own job only.
    enqueue(s, new_job("fin3", "reach", now_ms(), 0, 1)).await;
    enqueue(s, new_job("fin4", "reach", now_ms() + 1, 0, 1)).await;
    let c3 = claim(s, "r1", LONG).await;
    let c4 = claim(s, "r1", LONG).await;
    assert_eq!((c3.job.id.as_str(), c4.job.id.as_str()), ("fin3", "fin4"));
    assert!(!s
        .finish("fin4", Some(&c3.fence), &succeeded("1", now_ms()))
        .await
        .expect("finish"));
    // The last progress stays unless the outcome brings its own.
    assert!(s
        .progress(&c3.fence, &json!({"it": 5}))
        .await
        .expect("progress"));
    assert!(s
        .progress(&c4.fence, &json!({"it": 1}))
        .await
        .expect("progress"));
    let failed = Outcome {
        error: Some(error("no_path", "no path found")),
        ..outcome(JobState::Failed, now_ms())
    };
    assert!(s
        .finish("fin3", Some(&c3.fence), &failed)
        .await
        .expect("finish"));
    let with_stats = Outcome {
        progress: Some(json!({"it": 9})),
        ..succeeded("[1]", now_ms())
    };
    assert!(s
        .finish("fin4", Some(&c4.fence), &with_stats)
        .await
        .expect("finish"));
    let j3 = get(s, "fin3").await;
    assert_eq!(j3.job.state, JobState::Failed);
    assert_eq!(j3.job.progress, Some(json!({"it": 5})));
    assert_eq!(j3.job.error, failed.error);
    assert!(j3.result.is_none());
    assert_eq!(get(s, "fin4").await.job.progress, Some(json!({"it": 9})));
    assert_idle(s, "finish").await;
}

async fn cancel_cases(s: &dyn JobStore) {
    enqueue(s, new_job("can1", "reach", now_ms(), 0, 1)).await;
    let at = now_ms();
    assert_eq!(
        s.cancel("can1", at).await.expect("cancel"),
        Some(CancelResult::CancelledQueued)
    );
    let j = get(s, "can1").await;
    assert_eq!(j.job.state, JobState::Cancelled);
    assert_eq!(j.job.finished_ms, Some(at));
    assert_eq!(
        j.job.error,
        Some(error("cancelled", "cancelled while queued"))
    );
    assert_eq!(event_names(s, "can1").await, ["state", "end"]);
    assert_eq!(j.meta.last_seq, 2);
    let end = s.events_after("can1", 1, 10).await.expect("events");
    assert_eq!(end.len(), 1);
    assert_eq!(end[0].data, "");
    assert_eq!(
        s.cancel("can1", now_ms()).await.expect("cancel"),
        Some(CancelResult::AlreadyFinal)
    );

    enqueue(s, new_job("can2", "reach", now_ms(), 0, 1)).await;
    let c = claim(s, "r7", LONG).await;
    for _ in 0..2 {
        assert_eq!(
            s.cancel("can2", now_ms()).await.expect("cancel"),
            Some(CancelResult::Requested { owner: "r7".into() })
        );
    }
    assert_eq!(get(s, "can2").await.job.state, JobState::Running);
    assert!(s
        .finish(
            "can2",
            Some(&c.fence),
            &outcome(JobState::Cancelled, now_ms())
        )
        .await
        .expect("finish"));
    assert_eq!(
        s.cancel("can2", now_ms()).await.expect("cancel"),
        Some(CancelResult::AlreadyFinal)
    );
    assert_eq!(s.cancel("nosuch", now_ms()).await.expect("cancel"), None);
    assert_idle(s, "cancel").await;
}

async fn events_and_notices(s: &dyn JobStore) {
    let mut rx = s.subscribe();
    enqueue(s, new_job("evt1", "reach", now_ms(), 0, 1)).await;
    let enqueued = [Notice::Queued, job_notice("evt1")];
    assert!(wait_all(&mut rx, &enqueued, NOTICE_WAIT).await, "enqueue");
    let c = claim(s, "r1", LONG).await;
    assert!(
        wait_notice(&mut rx, &job_notice("evt1"), NOTICE_WAIT).await,
        "claim"
    );
    for i in 1..=3 {
        assert!(s
            .progress(&c.fence, &json!({"iterations": i}))
            .await
            .expect("progress"));
        assert!(
            wait_notice(&mut rx, &job_notice("evt1"), NOTICE_WAIT).await,
            "progress {i}"
        );
    }
    assert_eq!(
        s.cancel("evt1", now_ms()).await.expect("cancel"),
        Some(CancelResult::Requested { owner: "r1".into() })
    );
    let cancel = Notice::Cancel {
        id: "evt1".into(),
        owner: "r1".into(),
    };
    let cancelled = [cancel, job_notice("evt1")];
    assert!(wait_all(&mut rx, &cancelled, NOTICE_WAIT).await, "Cancel");
    assert!(s
        .finish(
            "evt1",
            Some(&c.fence),
            &outcome(JobState::Cancelled, now_ms())
        )
        .await
        .expect("finish"));
    assert!(
        wait_notice(&mut rx, &job_notice("evt1"), NOTICE_WAIT).await,
        "finish"
    );

    let ev = s.events_after("evt1", 0, 100).await.expect("events");
    let seqs: Vec<u64> = ev.iter().map(|e| e.seq).collect();
    assert_eq!(seqs, [1, 2, 3, 4, 5, 6]);
    let names: Vec<&str> = ev.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(
        names,
        ["state", "state", "progress", "progress", "progress", "end"]
    );
    let queued: Job = serde_json::from_str(&ev[0].data).expect("job");
    let running: Job = serde_json::from_str(&ev[1].data).expect("job");
    assert_eq!(
        (queued.state, running.state),
        (JobState::Queued, JobState::Running)
    );
    assert_eq!(running.replica.as_deref(), Some("r1"));
    assert!(running.result.is_none());
    for (i, e) in ev[2..5].iter().enumerate() {
        let v: Value = serde_json::from_str(&e.data).expect("progress data");
        assert_eq!(
            v,
            json!({"id": "evt1", "state": "running", "progress": {"iterations": i + 1}})
        );
    }
    assert_eq!(ev[5].data, "");
    assert_eq!(get(s, "evt1").await.meta.last_seq, 6);

    // Paging through the events.
    let mut after = 0;
    let mut pages = Vec::new();
    loop {
        let page = s.events_after("evt1", after, 2).await.expect("events");
        if page.is_empty() {
            break;
        }
        after = page.last().map_or(after, |e| e.seq);
        pages.push(page.iter().map(|e| e.seq).collect::<Vec<_>>());
    }
    assert_eq!(pages, [vec![1, 2], vec![3, 4], vec![5, 6]]);
    let tail: Vec<u64> = s
        .events_after("evt1", 3, 100)
        .await
        .expect("events")
        .iter()
        .map(|e| e.seq)
        .collect();
    assert_eq!(tail, [4, 5, 6]);
    assert!(s
        .events_after("evt1", 6, 100)
        .await
        .expect("events")
        .is_empty());
    assert_idle(s, "events").await;
}

/// About 2 MB of JSON floats.
fn big_result() -> String {
    let mut text = String::from("{\"path\":[");
    let mut i = 0u64;
    while text.len() < 2_000_000 {
        if i > 0 {
            text.push(',');
        }
        let x = (i as f64) * 0.1 + 1.0 / 3.0;
        text.push_str(&format!("[{x},{},{}]", -x * 1e-7, x * 7.0e12));
        i += 1;
    }
    text.push_str("],\"stats\":{\"z\":1,\"a\":2}}");
    text
}

async fn results_byte_for_byte(s: &dyn JobStore) {
    let sum = 0.1f64 + 0.2;
    // Unsorted and nested keys, a float that is not 0.3, exponents, escapes and spaces: a
    // parsed-and-printed copy (or jsonb) would differ.
    let text = format!(
        r#"{{"z": {sum}, "a": {{"y": [1, 2.5e-8, {{"b": null, "a": "x"}}], "x": 0.1}}, "e": 1E+2, "u": "\u00e9\n", "big": 12345678901234567890}}"#
    );
    let big = big_result();
    let before = s.counts().await.expect("counts").result_bytes;
    for (id, result) in [("res1", &text), ("res2", &big)] {
        enqueue(s, new_job(id, "joint_space", now_ms(), 0, 1)).await;
        let c = claim(s, "r1", LONG).await;
        assert!(s
            .finish(id, Some(&c.fence), &succeeded(result, now_ms()))
            .await
            .expect("finish"));
        let stored = get(s, id).await;
        assert!(
            stored.job.result.is_none(),
            "the record never holds the result"
        );
        assert_eq!(stored.job.state, JobState::Succeeded);
        let back = stored
            .result
            .as_deref()
            .map(RawValue::get)
            .expect("a result");
        assert!(
            back == result.as_str(),
            "{id}: the result changed on the way"
        );
        assert!(job_json(&stored).contains(result.as_str()));
    }
    let after = s.counts().await.expect("counts").result_bytes;
    assert_eq!(after - before, (text.len() + big.len()) as u64);
    assert_idle(s, "results").await;
}

async fn resources_and_blobs(s: &dyn JobStore) {
    let mut rx = s.subscribe();
    assert!(s
        .get_resource("robot", "arm1")
        .await
        .expect("get")
        .is_none());
    let arm = Resource {
        kind: "robot".into(),
        name: "arm1".into(),
        body: br#"{"urdf": "<robot name='arm1'/>", "b": 1}"#.to_vec(),
        updated_ms: 1_000,
    };
    s.put_resource(&arm).await.expect("put");
    let notice = Notice::Resource {
        kind: "robot".into(),
        name: "arm1".into(),
    };
    assert!(
        wait_notice(&mut rx, &notice, NOTICE_WAIT).await,
        "put notice"
    );
    assert_eq!(
        s.get_resource("robot", "arm1").await.expect("get"),
        Some(arm.clone())
    );
    let arm2 = Resource {
        body: br#"{"urdf": "<robot name='arm1' v='2'/>"}"#.to_vec(),
        updated_ms: 2_000,
        ..arm.clone()
    };
    s.put_resource(&arm2).await.expect("replace");
    assert!(
        wait_notice(&mut rx, &notice, NOTICE_WAIT).await,
        "replace notice"
    );
    assert_eq!(
        s.get_resource("robot", "arm1").await.expect("get"),
        Some(arm2.clone())
    );
    let arm0 = Resource {
        name: "arm0".into(),
        ..arm.clone()
    };
    let kitchen = Resource {
        kind: "scene".into(),
        name: "arm1".into(),
        body: b"{}".to_vec(),
        updated_ms: 3_000,
    };
    s.put_resource(&arm0).await.expect("put");
    s.put_resource(&kitchen).await.expect("put");
    let mut robots = s.list_resources("robot").await.expect("list");
    robots.sort_by(|a, b| a.name.cmp(&b.name));
    assert_eq!(robots, [arm0, arm2]);
    assert_eq!(
        s.list_resources("scene").await.expect("list"),
        std::slice::from_ref(&kitchen)
    );
    assert!(s.list_resources("gripper").await.expect("list").is_empty());
    assert!(s.delete_resource("robot", "arm1").await.expect("delete"));
    assert!(
        wait_notice(&mut rx, &notice, NOTICE_WAIT).await,
        "delete notice"
    );
    assert!(!s.delete_resource("robot", "arm1").await.expect("delete"));
    assert!(s
        .get_resource("robot", "arm1")
        .await
        .expect("get")
        .is_none());
    assert_eq!(
        s.get_resource("scene", "arm1").await.expect("get"),
        Some(kitchen)
    );

    assert!(s.get_blob("grid", "k1").await.expect("blob").is_none());
    let bytes: Vec<u8> = (0..1_000_000u32).map(|i| (i % 251) as u8).collect();
    s.put_blob("grid", "k1", &bytes).await.expect("put blob");
    assert_eq!(
        s.get_blob("grid", "k1").await.expect("blob"),
        Some(bytes.clone())
    );
    s.put_blob("grid", "k1", &[9, 9])
        .await
        .expect("put blob again");
    assert_eq!(
        s.get_blob("grid", "k1").await.expect("blob"),
        Some(bytes),
        "the first writer wins"
    );
    assert!(s.get_blob("roadmap", "k1").await.expect("blob").is_none());
    s.put_blob("roadmap", "k1", &[])
        .await
        .expect("put empty blob");
    assert_eq!(
        s.get_blob("roadmap", "k1").await.expect("blob"),
        Some(Vec::new())
    );
}

/// Runs a job to `succeeded` with a result of exactly `bytes` bytes, finished at `finished_ms`.
async fn finished_with(s: &dyn JobStore, id: &str, bytes: usize, finished_ms: u64) {
    enqueue(s, new_job(id, "reach", finished_ms, 0, 1)).await;
    let c = claim(s, "r1", LONG).await;
    let text = format!("\"{}\"", "x".repeat(bytes - 2));
    assert!(s
        .finish(id, Some(&c.fence), &succeeded(&text, finished_ms))
        .await
        .expect("finish"));
}

async fn expire(s: &dyn JobStore) {
    let now = now_ms();
    let hour = 3_600_000;
    // Every other finished job dates from this test run (the last minutes).
    for i in 0..3 {
        finished_with(s, &format!("expold{i}"), 100, now - 3 * hour + i).await;
    }
    for i in 0..4 {
        finished_with(s, &format!("exps{i}"), 1_000, now - hour / 2 + i * 1_000).await;
    }
    // Never final, never expired, however old.
    enqueue(s, new_job("expq", "reach", now - 10 * hour, 0, 1)).await;
    let total = s.counts().await.expect("counts").result_bytes;
    let policy = RetentionPolicy {
        retention: Duration::from_secs(3600),
        // After the three old ones go: the two oldest of `exps` must go too.
        max_result_bytes: total - 300 - 1_500,
    };
    let gone = s.expire(&policy, now).await.expect("expire");
    assert_eq!(
        gone,
        Expired {
            by_age: 3,
            by_size: 2,
            bytes: 300 + 2_000
        }
    );
    for id in ["expold0", "expold1", "expold2", "exps0", "exps1"] {
        assert!(s.get(id).await.expect("get").is_none(), "{id} expired");
        assert!(
            s.events_after(id, 0, 10).await.expect("events").is_empty(),
            "{id}"
        );
    }
    for id in ["exps2", "exps3", "expq", "res2", "evt1"] {
        assert!(s.get(id).await.expect("get").is_some(), "{id} kept");
    }
    assert_eq!(
        s.counts().await.expect("counts").result_bytes,
        total - 2_300
    );
    assert_eq!(
        s.expire(&policy, now).await.expect("expire"),
        Expired::default()
    );
    assert_eq!(
        s.cancel("expq", now_ms()).await.expect("cancel"),
        Some(CancelResult::CancelledQueued)
    );
    assert_idle(s, "expire").await;
}

async fn all_pages(
    s: &dyn JobStore,
    base: ListQuery,
) -> Vec<Vec<manyhands::server::api::JobSummary>> {
    let mut pages = Vec::new();
    let mut q = base;
    loop {
        let page = s.list(&q).await.expect("list");
        pages.push(page.jobs);
        match page.next {
            Some(next) => {
                let decoded = Cursor::decode(&next.encode()).expect("a cursor decodes");
                assert_eq!(decoded, next);
                q.after = Some(decoded);
            }
            None => break,
        }
        assert!(pages.len() < 1_000, "paging does not end");
    }
    pages
}

async fn counts_match_the_list(s: &dyn JobStore) {
    let c = s.counts().await.expect("counts");
    let pages = all_pages(
        s,
        ListQuery {
            limit: 7,
            ..ListQuery::default()
        },
    )
    .await;
    let all: Vec<_> = pages.into_iter().flatten().collect();
    let ids: BTreeSet<&str> = all.iter().map(|j| j.id.as_str()).collect();
    assert_eq!(ids.len(), all.len(), "no job listed twice");
    assert_eq!(all.len(), c.by_state.values().sum::<usize>());
    assert!(all
        .windows(2)
        .all(|w| (w[0].created_ms, &w[0].id) > (w[1].created_ms, &w[1].id)));
    for st in JobState::ALL {
        let n = all.iter().filter(|j| j.state == st).count();
        assert_eq!(c.by_state.get(st.name()), Some(&n), "{}", st.name());
    }
    let mut bytes = 0u64;
    for j in &all {
        let stored = get(s, &j.id).await;
        assert_eq!(
            (stored.job.kind.as_str(), stored.job.state),
            (j.kind.as_str(), j.state)
        );
        bytes += stored.result.map_or(0, |r| r.get().len() as u64);
    }
    assert_eq!(c.result_bytes, bytes);
}

async fn paging(s: &dyn JobStore) {
    let base = now_ms() + 1_000_000;
    let n = 250u64;
    // Four jobs per millisecond: page boundaries fall inside ties (broken by id).
    for i in 0..n {
        enqueue(
            s,
            new_job(&format!("pg{i:03}"), "paging", base + i / 4, 0, 1),
        )
        .await;
    }
    let mut expected: Vec<(u64, String)> = (0..n)
        .map(|i| (base + i / 4, format!("pg{i:03}")))
        .collect();
    expected.sort();
    expected.reverse();
    let q = ListQuery {
        limit: 100,
        kind: Some("paging".into()),
        ..ListQuery::default()
    };
    let pages = all_pages(s, q.clone()).await;
    let sizes: Vec<usize> = pages.iter().map(Vec::len).collect();
    assert_eq!(sizes, [100, 100, 50]);
    let got: Vec<(u64, String)> = pages
        .iter()
        .flatten()
        .map(|j| (j.created_ms, j.id.clone()))
        .collect();
    assert_eq!(got, expected, "newest first, each once");
    assert!(pages
        .iter()
        .flatten()
        .all(|j| j.kind == "paging" && j.state == JobState::Queued));

    // A page boundary inside a tie resumes right after the cursor.
    let one = s
        .list(&ListQuery {
            limit: 1,
            ..q.clone()
        })
        .await
        .expect("list");
    assert_eq!(one.jobs.len(), 1);
    assert_eq!(
        one.next,
        Some(Cursor {
            created_ms: expected[0].0,
            id: expected[0].1.clone()
        })
    );

    for i in (0..n).step_by(5) {
        assert_eq!(
            s.cancel(&format!("pg{i:03}"), now_ms())
                .await
                .expect("cancel"),
            Some(CancelResult::CancelledQueued)
        );
    }
    let cancelled = all_pages(
        s,
        ListQuery {
            state: Some(JobState::Cancelled),
            ..q.clone()
        },
    )
    .await;
    assert_eq!(cancelled.len(), 1);
    assert_eq!(cancelled[0].len(), 50);
    assert!(cancelled[0].iter().all(|j| j.state == JobState::Cancelled));
    let want: Vec<&str> = expected
        .iter()
        .filter(|(_, id)| id[2..].parse::<u64>().is_ok_and(|i| i % 5 == 0))
        .map(|(_, id)| id.as_str())
        .collect();
    let got: Vec<&str> = cancelled[0].iter().map(|j| j.id.as_str()).collect();
    assert_eq!(got, want);
    let queued = all_pages(
        s,
        ListQuery {
            state: Some(JobState::Queued),
            ..q.clone()
        },
    )
    .await;
    let sizes: Vec<usize> = queued.iter().map(Vec::len).collect();
    assert_eq!(sizes, [100, 100]);
    // The state filter alone spans every kind.
    let every_cancelled = all_pages(
        s,
        ListQuery {
            limit: 100,
            state: Some(JobState::Cancelled),
            ..ListQuery::default()
        },
    )
    .await;
    let every: Vec<_> = every_cancelled.into_iter().flatten().collect();
    assert!(every.iter().all(|j| j.state == JobState::Cancelled));
    assert!(
        every.len() > 50,
        "other kinds' cancelled jobs are listed too"
    );
    assert_eq!(
        s.counts().await.expect("counts").by_state.get("cancelled"),
        Some(&every.len())
    );
    // No such kind.
    let none = s
        .list(&ListQuery {
            limit: 10,
            kind: Some("nosuch".into()),
            ..ListQuery::default()
        })
        .await
        .expect("list");
    assert!(none.jobs.is_empty() && none.next.is_none());
}
