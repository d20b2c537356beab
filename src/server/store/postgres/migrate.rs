//! The schema's migrations (`migrations/`), applied at connect under an advisory lock.

#[allow(unused_imports)]
use super::*;

// ---------------------------------------------------------------------------------------------
// Migrations

pub(super) async fn migrate(pool: &Pool) -> StoreResult<()> {
    let mut client = pool.get().await.map_err(pool_err)?;
    let tx = client.transaction().await.map_err(pg_err)?;
    // Replicas starting together wait here for the first one's migrations.
    tx.batch_execute(&format!("SELECT pg_advisory_xact_lock({MIGRATION_LOCK})"))
        .await
        .map_err(pg_err)?;
    tx.batch_execute(
        "CREATE TABLE IF NOT EXISTS manyhands_migrations \
         (version int PRIMARY KEY, applied_ms bigint NOT NULL)",
    )
    .await
    .map_err(pg_err)?;
    let done: Vec<i32> = tx
        .query("SELECT version FROM manyhands_migrations", &[])
        .await
        .map_err(pg_err)?
        .iter()
        .map(|r| col(r, "version"))
        .collect::<StoreResult<_>>()?;
    for (version, sql) in MIGRATIONS {
        if done.contains(version) {
            continue;
        }
        tx.batch_execute(sql)
            .await
            .map_err(|e| StoreError::Other(format!("migration {version}: {e}")))?;
        tx.execute(
            "INSERT INTO manyhands_migrations (version, applied_ms) VALUES ($1, $2)",
            &[version, &to_i64(now_ms())],
        )
        .await
        .map_err(pg_err)?;
    }
    tx.commit().await.map_err(pg_err)
}
