//! Uploaded robots, meshes and scenes shared by the replicas of a shared job store (PostgreSQL).
//!
//! An upload through any replica is validated there, kept in its catalog (and its data
//! directory, as a local copy) and written to the store, which announces it; every other
//! replica hears the notice and loads the same upload into its catalog (validated again, with
//! its own built-in models). A replica that starts loads every upload from the store, and one
//! asked for a robot or scene it does not know yet (a request that raced the notice) reads the
//! store before it answers 404. With the embedded store the data directory is the record, as
//! it always was.
//!
//! The expensive caches (reachability grids, grasp lists, super-graph roadmaps; all content
//! keyed files) go through [`StoreTier`]: a replica that lacks one fetches it from the store
//! before building, and one that built it publishes it, so a cluster builds each once.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use super::api::RobotUpload;
use super::error::{ApiError, ApiResult};
use super::jobs::store_error;
use super::store::{JobStore, Notice, Resource};
use super::AppState;
use crate::model::SceneJson;

/// The shared store as the second tier of the file caches (see [`crate::cache_tier`]). Its
/// calls come from planner and pool threads; each runs on a short-lived thread of its own, so
/// it is safe from any thread (a cache miss costs far more than that thread).
pub struct StoreTier {
    pub store: Arc<dyn JobStore>,
    pub rt: tokio::runtime::Handle,
}

impl StoreTier {
    fn run<T: Send>(&self, f: impl std::future::Future<Output = T> + Send) -> Option<T> {
        std::thread::scope(|s| {
            std::thread::Builder::new()
                .name("manyhands-cache".into())
                .spawn_scoped(s, || self.rt.block_on(f))
                .ok()?
                .join()
                .ok()
        })
    }
}

impl crate::cache_tier::CacheTier for StoreTier {
    fn fetch(&self, kind: &str, name: &str) -> Option<Vec<u8>> {
        match self.run(self.store.get_blob(kind, name))? {
            Ok(b) => {
                if b.is_some() {
                    tracing::info!(kind, name, "cache entry fetched from the shared store");
                }
                b
            }
            Err(e) => {
                tracing::warn!(kind, name, error = %e, "cannot read the shared cache");
                None
            }
        }
    }

    fn publish(&self, kind: &str, name: &str, bytes: &[u8]) {
        match self.run(self.store.put_blob(kind, name, bytes)) {
            Some(Ok(())) => {
                tracing::info!(kind, name, bytes = bytes.len(), "cache entry shared")
            }
            Some(Err(e)) => tracing::warn!(kind, name, error = %e, "cannot share a cache entry"),
            None => {}
        }
    }
}

/// Kinds of shared resources, in the order they load (scenes name robots and meshes).
pub const KINDS: [&str; 3] = ["robot", "mesh", "scene"];

/// What this replica has applied: (kind, name) → the upload's time.
#[derive(Default)]
pub struct Applied(Mutex<HashMap<(String, String), u64>>);

impl Applied {
    fn get(&self, kind: &str, name: &str) -> Option<u64> {
        self.0
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .get(&(kind.to_string(), name.to_string()))
            .copied()
    }

    fn set(&self, kind: &str, name: &str, ms: Option<u64>) {
        let mut m = self.0.lock().unwrap_or_else(|p| p.into_inner());
        let k = (kind.to_string(), name.to_string());
        match ms {
            Some(ms) => {
                m.insert(k, ms);
            }
            None => {
                m.remove(&k);
            }
        }
    }
}

fn shared(st: &AppState) -> Option<&Arc<dyn JobStore>> {
    let s = st.jobs.store();
    (s.backend() != "embedded").then_some(s)
}

/// Writes an accepted upload to the shared store (no-op with the embedded store).
pub async fn publish(st: &AppState, kind: &str, name: &str, body: Vec<u8>) -> ApiResult<()> {
    let Some(store) = shared(st) else {
        return Ok(());
    };
    let r = Resource {
        kind: kind.to_string(),
        name: name.to_string(),
        body,
        updated_ms: super::jobs::now_ms(),
    };
    store.put_resource(&r).await.map_err(store_error)?;
    st.applied.set(kind, name, Some(r.updated_ms));
    Ok(())
}

/// Removes a deleted upload from the shared store (no-op with the embedded store).
pub async fn unpublish(st: &AppState, kind: &str, name: &str) -> ApiResult<()> {
    let Some(store) = shared(st) else {
        return Ok(());
    };
    store
        .delete_resource(kind, name)
        .await
        .map_err(store_error)?;
    st.applied.set(kind, name, None);
    Ok(())
}

/// Loads one upload from the store into this replica's catalog (or removes it when the store
/// no longer has it). Already applied versions are skipped.
async fn apply(st: &Arc<AppState>, kind: &str, name: &str, r: Option<Resource>) -> ApiResult<()> {
    match r {
        Some(r) => {
            if st.applied.get(kind, name) == Some(r.updated_ms) {
                return Ok(());
            }
            let st2 = st.clone();
            let n = name.to_string();
            let body = r.body.clone();
            match kind {
                "robot" => {
                    let up: RobotUpload = serde_json::from_slice(&body)
                        .map_err(|e| ApiError::internal(format!("stored robot '{n}': {e}")))?;
                    st.pool
                        .run_heavy(move || {
                            st2.catalog.put_robot(
                                &n,
                                &up.urdf,
                                up.srdf.as_deref(),
                                up.joint_limits.as_deref(),
                            )
                        })
                        .await?;
                }
                "mesh" => {
                    st.pool
                        .run_heavy(move || st2.catalog.put_mesh(&n, &body).map(|_| ()))
                        .await?;
                }
                _ => {
                    let json: SceneJson = serde_json::from_slice(&body)
                        .map_err(|e| ApiError::internal(format!("stored scene '{n}': {e}")))?;
                    st.pool
                        .run_heavy(move || st2.catalog.put_scene(&n, json))
                        .await?;
                }
            }
            st.applied.set(kind, name, Some(r.updated_ms));
            tracing::info!(kind, name, "upload loaded from the shared store");
        }
        None => {
            if st.applied.get(kind, name).is_none() {
                return Ok(());
            }
            let st2 = st.clone();
            let n = name.to_string();
            let k = kind.to_string();
            let _ = st
                .pool
                .run(move || match k.as_str() {
                    "robot" => st2.catalog.delete_robot(&n),
                    "mesh" => st2.catalog.delete_mesh(&n),
                    _ => st2.catalog.delete_scene(&n),
                })
                .await;
            st.applied.set(kind, name, None);
            tracing::info!(
                kind,
                name,
                "upload removed (deleted through another replica)"
            );
        }
    }
    Ok(())
}

/// Loads every upload of the shared store that this replica has not applied yet.
pub async fn sync_all(st: &Arc<AppState>) -> ApiResult<()> {
    let Some(store) = shared(st).cloned() else {
        return Ok(());
    };
    for kind in KINDS {
        let list = store.list_resources(kind).await.map_err(store_error)?;
        for r in list {
            let name = r.name.clone();
            if let Err(e) = apply(st, kind, &name, Some(r)).await {
                tracing::warn!(kind, name = %name, error = %e.message, "cannot load a shared upload");
            }
        }
    }
    Ok(())
}

/// Follows the store's notices of uploads and deletions made through other replicas.
pub fn spawn_listener(st: &Arc<AppState>) -> Option<tokio::task::JoinHandle<()>> {
    let store = shared(st)?.clone();
    let weak = Arc::downgrade(st);
    let mut rx = store.subscribe();
    Some(tokio::spawn(async move {
        loop {
            let n = match rx.recv().await {
                Ok(n) => n,
                Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => Notice::Resync,
                Err(_) => return,
            };
            let Some(st) = weak.upgrade() else { return };
            match n {
                Notice::Resource { kind, name } => {
                    let r = match store.get_resource(&kind, &name).await {
                        Ok(r) => r,
                        Err(e) => {
                            tracing::warn!(kind, name, error = %e, "cannot read a shared upload");
                            continue;
                        }
                    };
                    if let Err(e) = apply(&st, &kind, &name, r).await {
                        tracing::warn!(kind, name, error = %e.message, "cannot load a shared upload");
                    }
                }
                Notice::Resync => {
                    if let Err(e) = sync_all(&st).await {
                        tracing::warn!(error = %e.message, "cannot resync shared uploads");
                    }
                }
                _ => {}
            }
        }
    }))
}
