//! Persistence of job records (redb, one file `jobs.redb` under the data directory). Records are
//! JSON values keyed by job id; written at every state change.

use std::path::Path;

use redb::{Database, ReadableDatabase, ReadableTable, TableDefinition};

use crate::server::api::Job;

const JOBS: TableDefinition<&str, &[u8]> = TableDefinition::new("jobs");

use super::StoreError;

fn err(e: impl std::fmt::Display) -> StoreError {
    StoreError::other(e)
}

/// Job records on disk.
pub struct Store {
    db: Database,
}

impl Store {
    /// Opens (or creates) the store file.
    pub fn open(path: &Path) -> Result<Store, StoreError> {
        let db =
            Database::create(path).map_err(|e| StoreError::Other(format!("{}: {e}", path.display())))?;
        let txn = db.begin_write().map_err(err)?;
        txn.open_table(JOBS).map_err(err)?;
        txn.commit().map_err(err)?;
        Ok(Store { db })
    }

    /// Writes (inserts or replaces) job records in one transaction.
    pub fn put_all(&self, jobs: &[&Job]) -> Result<(), StoreError> {
        let txn = self.db.begin_write().map_err(err)?;
        {
            let mut t = txn.open_table(JOBS).map_err(err)?;
            for job in jobs {
                let bytes = serde_json::to_vec(job).map_err(err)?;
                t.insert(job.id.as_str(), bytes.as_slice()).map_err(err)?;
            }
        }
        txn.commit().map_err(err)
    }

    pub fn put(&self, job: &Job) -> Result<(), StoreError> {
        self.put_all(&[job])
    }

    /// Deletes records.
    pub fn remove(&self, ids: &[String]) -> Result<(), StoreError> {
        let txn = self.db.begin_write().map_err(err)?;
        {
            let mut t = txn.open_table(JOBS).map_err(err)?;
            for id in ids {
                t.remove(id.as_str()).map_err(err)?;
            }
        }
        txn.commit().map_err(err)
    }

    /// Every record; undecodable ones are skipped with a warning.
    pub fn load_all(&self) -> Result<Vec<Job>, StoreError> {
        let txn = self.db.begin_read().map_err(err)?;
        let t = txn.open_table(JOBS).map_err(err)?;
        let mut out = Vec::new();
        for item in t.iter().map_err(err)? {
            let (k, v) = item.map_err(err)?;
            match serde_json::from_slice::<Job>(v.value()) {
                Ok(j) => out.push(j),
                Err(e) => {
                    tracing::warn!(id = k.value(), error = %e, "skipping undecodable job record")
                }
            }
        }
        Ok(out)
    }
}
