//! Placeholder until the PostgreSQL backend lands (replaced by the real module).
use std::time::Duration;

use super::{StoreError, StoreResult};

#[derive(Debug, Clone)]
pub struct PgOptions {
    pub pool_size: usize,
    pub connect_timeout: Duration,
}

impl Default for PgOptions {
    fn default() -> PgOptions {
        PgOptions {
            pool_size: 8,
            connect_timeout: Duration::from_secs(5),
        }
    }
}

pub struct PgStore;

impl PgStore {
    pub async fn connect(_url: &str, _opts: PgOptions) -> StoreResult<super::embedded::EmbeddedStore> {
        Err(StoreError::Other("not yet".into()))
    }
}
