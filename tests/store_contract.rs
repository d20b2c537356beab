//! The job store contract (tests/job_store) on each backend, and what only the PostgreSQL
//! backend has to survive: replicas migrating the same database at once, and a database
//! restart. PostgreSQL runs from a throwaway cluster (tests/pg); without PostgreSQL installed
//! those tests print a SKIPPED line.

mod job_store;
mod pg;
#[path = "common/tmp.rs"]
mod tmp;

use std::sync::Arc;
use std::time::{Duration, Instant};

use manyhands::server::api::JobState;
use manyhands::server::store::embedded::EmbeddedStore;
use manyhands::server::store::postgres::{PgOptions, PgStore};
use manyhands::server::store::{JobStore, Notice, StoreError};

use job_store::{new_job, now_ms, wait_notice, NOTICE_WAIT};
use pg::PgCluster;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn embedded_store_meets_the_contract() {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let dir = tmp::run_root().join(format!("manyhands-contract-{}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let store = EmbeddedStore::open(&dir.join("jobs.redb")).expect("open");
    job_store::contract(Arc::new(store)).await;
    let _ = std::fs::remove_dir_all(dir);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_store_meets_the_contract() {
    let Some(cluster) = PgCluster::start("postgres_store_meets_the_contract") else {
        return;
    };
    let store = PgStore::connect(&cluster.url(), PgOptions::default())
        .await
        .expect("connect");
    job_store::contract(Arc::new(store)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_replicas_starting_together_migrate_once() {
    let Some(cluster) = PgCluster::start("postgres_replicas_starting_together_migrate_once") else {
        return;
    };
    let url = cluster.url();
    let (a, b) = tokio::join!(
        PgStore::connect(&url, PgOptions::default()),
        PgStore::connect(&url, PgOptions::default())
    );
    let (a, b) = (a.expect("replica a"), b.expect("replica b"));
    // Once more on a migrated database: nothing to do.
    let c = PgStore::connect(&url, PgOptions::default())
        .await
        .expect("replica c");
    let (client, conn) = tokio_postgres::connect(&url, tokio_postgres::NoTls)
        .await
        .expect("connect");
    let driver = tokio::spawn(conn);
    let versions = client
        .query(
            "SELECT version FROM manyhands_migrations ORDER BY version",
            &[],
        )
        .await
        .expect("migrations table");
    let versions: Vec<i32> = versions.iter().map(|r| r.get(0)).collect();
    assert_eq!(versions, [1]);
    drop(client);
    let _ = driver.await;

    // One database: what a replica writes, the others read and hear about.
    let mut heard = b.subscribe();
    a.enqueue(&new_job("shared1", "reach", now_ms(), 0, 1), 10)
        .await
        .expect("enqueue");
    assert!(wait_notice(&mut heard, &Notice::Queued, NOTICE_WAIT).await);
    let claimed = c
        .claim("c", Duration::from_secs(60))
        .await
        .expect("claim")
        .expect("the job a queued");
    assert_eq!(claimed.job.id, "shared1");
    let seen = b.get("shared1").await.expect("get").expect("job");
    assert_eq!(seen.job.state, JobState::Running);
    assert_eq!(seen.job.replica.as_deref(), Some("c"));
}

/// Polls `f` until it succeeds, for at most `within`.
async fn until_ok<T, F, Fut>(within: Duration, mut f: F) -> Result<T, StoreError>
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = Result<T, StoreError>>,
{
    let deadline = Instant::now() + within;
    loop {
        match f().await {
            Ok(v) => return Ok(v),
            Err(e) if Instant::now() > deadline => return Err(e),
            Err(_) => tokio::time::sleep(Duration::from_millis(100)).await,
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_restart_is_survived() {
    let Some(cluster) = PgCluster::start("postgres_restart_is_survived") else {
        return;
    };
    let store = PgStore::connect(&cluster.url(), PgOptions::default())
        .await
        .expect("connect");
    store
        .enqueue(&new_job("before1", "reach", now_ms(), 0, 1), 10)
        .await
        .expect("enqueue");
    store
        .enqueue(&new_job("before2", "reach", now_ms() + 1, 0, 1), 10)
        .await
        .expect("enqueue");
    let c = store
        .claim("r1", Duration::from_secs(60))
        .await
        .expect("claim")
        .expect("a job");
    assert_eq!(c.job.id, "before1");
    let result = r#"{"b": 0.30000000000000004, "a": [1e-7]}"#;
    let outcome = manyhands::server::store::Outcome {
        state: JobState::Succeeded,
        result: Some(serde_json::value::RawValue::from_string(result.to_string()).expect("json")),
        error: None,
        progress: None,
        finished_ms: now_ms(),
    };
    assert!(store
        .finish("before1", Some(&c.fence), &outcome)
        .await
        .expect("finish"));
    let mut rx = store.subscribe();

    tokio::task::block_in_place(|| cluster.stop());
    // The database is down: calls fail at once, as unavailable, instead of hanging.
    for call in 0..3 {
        let t = Instant::now();
        let r = store.queue_depth().await;
        let took = t.elapsed();
        assert!(
            matches!(r, Err(StoreError::Unavailable(_))),
            "call {call} with the database down: {r:?}"
        );
        assert!(took < Duration::from_secs(3), "call {call} took {took:?}");
    }
    let t = Instant::now();
    let r = store
        .enqueue(&new_job("during", "reach", now_ms(), 0, 1), 10)
        .await;
    assert!(matches!(r, Err(StoreError::Unavailable(_))), "{r:?}");
    assert!(t.elapsed() < Duration::from_secs(3));
    assert!(matches!(
        store.ping().await,
        Err(StoreError::Unavailable(_))
    ));

    tokio::task::block_in_place(|| cluster.start_again());
    let t = Instant::now();
    until_ok(Duration::from_secs(10), || store.ping())
        .await
        .expect("the store is back");
    println!(
        "calls succeed {:.2} s after the restart",
        t.elapsed().as_secs_f64()
    );
    assert!(
        wait_notice(&mut rx, &Notice::Resync, Duration::from_secs(10)).await,
        "Resync after the notice connection is back"
    );
    println!(
        "Resync {:.2} s after the restart",
        t.elapsed().as_secs_f64()
    );

    // Live notices again, and nothing lost.
    assert_eq!(store.queue_depth().await.expect("depth"), 1);
    let c2 = store
        .claim("r2", Duration::from_secs(60))
        .await
        .expect("claim")
        .expect("a job");
    assert_eq!(c2.job.id, "before2");
    assert!(store
        .progress(&c2.fence, &serde_json::json!({"n": 1}))
        .await
        .expect("progress"));
    let notice = Notice::Job {
        id: "before2".into(),
    };
    assert!(
        wait_notice(&mut rx, &notice, NOTICE_WAIT).await,
        "live notices again"
    );
    let kept = store.get("before1").await.expect("get").expect("job");
    assert_eq!(kept.job.state, JobState::Succeeded);
    assert_eq!(kept.result.as_deref().map(|r| r.get()), Some(result));
    assert!(store.get("during").await.expect("get").is_none());
    let events = store.events_after("before1", 0, 10).await.expect("events");
    assert_eq!(events.len(), 3);
}
