//! A shared second tier behind the file caches of expensive, content-keyed results — the
//! reachability grids ([`crate::reachability::GridCache`], `reach`), the single-grasp lists
//! ([`crate::grasp::GraspListCache`], `grasps`) and the super-graph roadmaps
//! ([`crate::planning::planners::roadmap_cache::load_or_build`], `roadmaps`) — so that several processes
//! (server replicas sharing one job store) build each entry once instead of once each.
//!
//! A cache with a tier looks in memory, then in its folder, then in the tier (the fetched file
//! is written into the folder and loaded by the cache's usual load path, which checks its keys
//! and refuses a damaged or mismatching file); only then does it build, save the file and
//! publish it. The tier is an optimisation: a tier that fails (or a file that cannot be read or
//! written) only means a build that could have been shared, never an error. The planning core
//! only sees this trait; the server implements it over its job store.

use std::collections::HashMap;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// The `kind` of reachability grid files (`DATA/reach/*.reach`).
pub const REACH: &str = "reach";
/// The `kind` of single-grasp list files (`DATA/grasps/*.grasps.json`).
pub const GRASPS: &str = "grasps";
/// The `kind` of super-graph roadmap files (`DATA/roadmaps/*.roadmap.json`).
pub const ROADMAPS: &str = "roadmaps";

/// A second tier behind a process's file caches (reachability grids, grasp lists, roadmaps):
/// a file missing locally is fetched from it, and a file this process built is published to it,
/// so several processes sharing one tier build each entry once.
pub trait CacheTier: Send + Sync {
    /// The bytes of cache file `name` of cache `kind` (`reach`, `grasps`, `roadmaps`), if some
    /// process published it.
    fn fetch(&self, kind: &str, name: &str) -> Option<Vec<u8>>;

    /// Publishes a cache file this process built (first writer wins; entries are content keyed).
    fn publish(&self, kind: &str, name: &str, bytes: &[u8]);

    /// Publishes a file this process built after the tier's entry under that name was fetched
    /// and refused by the cache's load (damaged, or written in another file format version):
    /// a tier that can overwrite should, so the next process fetches a good entry. The default
    /// is [`CacheTier::publish`], which keeps the refused entry: every process then builds that
    /// entry once and keeps its own file.
    fn replace(&self, kind: &str, name: &str, bytes: &[u8]) {
        self.publish(kind, name, bytes)
    }
}

/// Writes `bytes` to `path` through a temporary file of the same folder and a rename, so a
/// reader (this process or another) never sees part of a file. The temporary name is unique
/// per process and call, so concurrent writers of one path do not mix their bytes.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    static SEQ: AtomicUsize = AtomicUsize::new(0);
    let name = path.file_name().ok_or_else(|| {
        std::io::Error::new(std::io::ErrorKind::InvalidInput, "a path without file name")
    })?;
    let tmp = path.with_file_name(format!(
        ".{}.{}-{}.tmp",
        name.to_string_lossy(),
        std::process::id(),
        SEQ.fetch_add(1, Ordering::Relaxed)
    ));
    let r = std::fs::write(&tmp, bytes).and_then(|_| std::fs::rename(&tmp, path));
    if r.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    r
}

/// Fetches cache file `name` of `kind` from `tier` into `dir/name` (creating `dir`; written
/// atomically, replacing a file already there). True when the tier had it and the file is now
/// there; false without a tier, when the tier has no such entry, or when it cannot be written
/// (logged). The caller then loads the file with its usual checks.
pub fn fetch_into(tier: Option<&dyn CacheTier>, kind: &str, dir: &Path, name: &str) -> bool {
    let Some(tier) = tier else {
        return false;
    };
    let Some(bytes) = tier.fetch(kind, name) else {
        return false;
    };
    let path = dir.join(name);
    match std::fs::create_dir_all(dir).and_then(|_| write_atomic(&path, &bytes)) {
        Ok(()) => true,
        Err(e) => {
            tracing::warn!(kind, file = %path.display(), error = %e,
                "cannot write a cache file fetched from the shared tier");
            false
        }
    }
}

/// Publishes the saved cache file `path` to `tier` under its file name. A file that cannot be
/// read is logged and not published: a cache that cannot be shared is only slower.
pub fn publish_file(tier: Option<&dyn CacheTier>, kind: &str, path: &Path) {
    send_file(tier, kind, path, false)
}

/// [`publish_file`] through [`CacheTier::replace`]: for a file built after the tier's entry of
/// that name was fetched and refused.
pub fn replace_file(tier: Option<&dyn CacheTier>, kind: &str, path: &Path) {
    send_file(tier, kind, path, true)
}

fn send_file(tier: Option<&dyn CacheTier>, kind: &str, path: &Path, replace: bool) {
    let Some(tier) = tier else {
        return;
    };
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
        return;
    };
    match std::fs::read(path) {
        Ok(bytes) if replace => tier.replace(kind, name, &bytes),
        Ok(bytes) => tier.publish(kind, name, &bytes),
        Err(e) => tracing::warn!(kind, file = %path.display(), error = %e,
            "cannot read a built cache file to share it"),
    }
}

/// What [`load_or_fetch`] found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Lookup<T> {
    /// The local file, loaded.
    Local(T),
    /// Not (or not loadable) locally; fetched from the tier into the folder and loaded.
    Fetched(T),
    /// Neither: the caller builds, saves the file and shares it with [`share_built`].
    /// `tier_refused`: the tier had an entry of that name that did not load.
    Missing { tier_refused: bool },
}

/// The lookup the three caches share: `dir/name` loaded with `load` (which checks keys and
/// refuses a damaged or mismatching file by returning `None`); when it is missing or refused,
/// the tier's entry of that name is fetched into `dir` ([`fetch_into`]) and loaded the same way.
/// A fetched entry that does not load is logged and treated as missing.
pub fn load_or_fetch<T>(
    tier: Option<&dyn CacheTier>,
    kind: &str,
    dir: &Path,
    name: &str,
    load: impl Fn(&Path) -> Option<T>,
) -> Lookup<T> {
    let path = dir.join(name);
    if path.exists() {
        if let Some(v) = load(&path) {
            return Lookup::Local(v);
        }
    }
    if !fetch_into(tier, kind, dir, name) {
        return Lookup::Missing {
            tier_refused: false,
        };
    }
    match load(&path) {
        Some(v) => Lookup::Fetched(v),
        None => {
            tracing::warn!(
                kind,
                name,
                "a cache file fetched from the shared tier does not load; building it"
            );
            Lookup::Missing { tier_refused: true }
        }
    }
}

/// Shares the file `path` a cache built and saved after [`Lookup::Missing`]:
/// [`replace_file`] when `tier_refused`, else [`publish_file`].
pub fn share_built(tier: Option<&dyn CacheTier>, kind: &str, path: &Path, tier_refused: bool) {
    send_file(tier, kind, path, tier_refused)
}

/// A [`CacheTier`] in memory with counters: for tests (two caches with different folders and
/// one `MemoryTier` behave like two processes sharing a store) and for sharing between caches
/// of one process. [`CacheTier::publish`] keeps the first entry of a name,
/// [`CacheTier::replace`] overwrites it.
#[derive(Debug, Default)]
pub struct MemoryTier {
    entries: Mutex<HashMap<(String, String), Vec<u8>>>,
    fetches: AtomicUsize,
    misses: AtomicUsize,
    publishes: AtomicUsize,
    replaces: AtomicUsize,
}

impl MemoryTier {
    pub fn new() -> MemoryTier {
        MemoryTier::default()
    }

    /// [`CacheTier::fetch`] calls that returned an entry.
    pub fn fetches(&self) -> usize {
        self.fetches.load(Ordering::Relaxed)
    }

    /// [`CacheTier::fetch`] calls that found none.
    pub fn misses(&self) -> usize {
        self.misses.load(Ordering::Relaxed)
    }

    /// [`CacheTier::publish`] calls (whether or not they stored anything).
    pub fn publishes(&self) -> usize {
        self.publishes.load(Ordering::Relaxed)
    }

    /// [`CacheTier::replace`] calls.
    pub fn replaces(&self) -> usize {
        self.replaces.load(Ordering::Relaxed)
    }

    /// The names of the entries of `kind`, sorted.
    pub fn names(&self, kind: &str) -> Vec<String> {
        let mut v: Vec<String> = self
            .lock()
            .keys()
            .filter(|(k, _)| k == kind)
            .map(|(_, n)| n.clone())
            .collect();
        v.sort();
        v
    }

    /// An entry, without counting a fetch.
    pub fn get(&self, kind: &str, name: &str) -> Option<Vec<u8>> {
        self.lock()
            .get(&(kind.to_string(), name.to_string()))
            .cloned()
    }

    /// Sets an entry, without counting a publish (a test damaging an entry).
    pub fn insert(&self, kind: &str, name: &str, bytes: Vec<u8>) {
        self.lock()
            .insert((kind.to_string(), name.to_string()), bytes);
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<(String, String), Vec<u8>>> {
        self.entries.lock().unwrap_or_else(|p| p.into_inner())
    }
}

impl CacheTier for MemoryTier {
    fn fetch(&self, kind: &str, name: &str) -> Option<Vec<u8>> {
        let v = self.get(kind, name);
        let counter = if v.is_some() {
            &self.fetches
        } else {
            &self.misses
        };
        counter.fetch_add(1, Ordering::Relaxed);
        v
    }

    fn publish(&self, kind: &str, name: &str, bytes: &[u8]) {
        self.publishes.fetch_add(1, Ordering::Relaxed);
        self.lock()
            .entry((kind.to_string(), name.to_string()))
            .or_insert_with(|| bytes.to_vec());
    }

    fn replace(&self, kind: &str, name: &str, bytes: &[u8]) {
        self.replaces.fetch_add(1, Ordering::Relaxed);
        self.insert(kind, name, bytes.to_vec());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!(
            "manyhands-cache-tier-{}-{name}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    /// A tier without an overwrite: `replace` is `publish`.
    struct FirstWriter(MemoryTier);

    impl CacheTier for FirstWriter {
        fn fetch(&self, kind: &str, name: &str) -> Option<Vec<u8>> {
            self.0.fetch(kind, name)
        }
        fn publish(&self, kind: &str, name: &str, bytes: &[u8]) {
            self.0.publish(kind, name, bytes)
        }
    }

    #[test]
    fn fetch_into_writes_the_entry_and_creates_the_folder() {
        let dir = tmp("fetch").join("reach");
        let tier = MemoryTier::new();
        // No tier, no entry: nothing written.
        assert!(!fetch_into(None, REACH, &dir, "a.reach"));
        assert!(!fetch_into(Some(&tier), REACH, &dir, "a.reach"));
        assert_eq!((tier.fetches(), tier.misses()), (0, 1));
        assert!(!dir.exists());
        // Kinds are separate name spaces.
        tier.publish(GRASPS, "a.reach", b"list");
        assert!(!fetch_into(Some(&tier), REACH, &dir, "a.reach"));
        tier.publish(REACH, "a.reach", b"grid");
        assert!(fetch_into(Some(&tier), REACH, &dir, "a.reach"));
        assert_eq!(std::fs::read(dir.join("a.reach")).unwrap(), b"grid");
        assert_eq!((tier.fetches(), tier.misses()), (1, 2));
        // A file already there is replaced; no temporary file is left behind.
        std::fs::write(dir.join("a.reach"), b"old").unwrap();
        assert!(fetch_into(Some(&tier), REACH, &dir, "a.reach"));
        assert_eq!(std::fs::read(dir.join("a.reach")).unwrap(), b"grid");
        let files: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(files, ["a.reach"]);
        // A folder that cannot be created (a file is in the way): false, no panic.
        let blocked = tmp("blocked");
        std::fs::create_dir_all(&blocked).unwrap();
        std::fs::write(blocked.join("file"), b"").unwrap();
        assert!(!fetch_into(
            Some(&tier),
            REACH,
            &blocked.join("file").join("reach"),
            "a.reach"
        ));
        let _ = std::fs::remove_dir_all(tmp("fetch"));
        let _ = std::fs::remove_dir_all(&blocked);
    }

    #[test]
    fn publish_file_shares_a_saved_file_first_writer_wins() {
        let dir = tmp("publish");
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("x.roadmap.json");
        let tier = MemoryTier::new();
        // No tier, or a file that is not there: nothing published.
        publish_file(None, ROADMAPS, &f);
        publish_file(Some(&tier), ROADMAPS, &f);
        assert_eq!(tier.publishes(), 0);
        write_atomic(&f, b"first").unwrap();
        publish_file(Some(&tier), ROADMAPS, &f);
        write_atomic(&f, b"second").unwrap();
        publish_file(Some(&tier), ROADMAPS, &f);
        assert_eq!(tier.publishes(), 2);
        assert_eq!(tier.names(ROADMAPS), ["x.roadmap.json"]);
        assert_eq!(tier.get(ROADMAPS, "x.roadmap.json").unwrap(), b"first");
        // replace overwrites in a MemoryTier...
        replace_file(Some(&tier), ROADMAPS, &f);
        assert_eq!(tier.replaces(), 1);
        assert_eq!(tier.get(ROADMAPS, "x.roadmap.json").unwrap(), b"second");
        // ...and is publish in a tier that does not say otherwise.
        let first = FirstWriter(MemoryTier::new());
        first.publish(ROADMAPS, "x.roadmap.json", b"first");
        replace_file(Some(&first), ROADMAPS, &f);
        assert_eq!(first.0.get(ROADMAPS, "x.roadmap.json").unwrap(), b"first");
        assert_eq!((first.0.publishes(), first.0.replaces()), (2, 0));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn load_or_fetch_prefers_the_folder_then_the_tier_and_reports_a_refused_entry() {
        let dir = tmp("lookup");
        let tier = MemoryTier::new();
        // A "loader" that refuses files not starting with "ok".
        let load = |f: &Path| {
            let b = std::fs::read(f).ok()?;
            b.starts_with(b"ok").then_some(b)
        };
        let missing = Lookup::Missing {
            tier_refused: false,
        };
        assert_eq!(load_or_fetch(None, GRASPS, &dir, "l", load), missing);
        assert_eq!(load_or_fetch(Some(&tier), GRASPS, &dir, "l", load), missing);
        tier.publish(GRASPS, "l", b"ok shared");
        assert_eq!(
            load_or_fetch(Some(&tier), GRASPS, &dir, "l", load),
            Lookup::Fetched(b"ok shared".to_vec())
        );
        // Now local: the tier is not asked again.
        assert_eq!(
            load_or_fetch(Some(&tier), GRASPS, &dir, "l", load),
            Lookup::Local(b"ok shared".to_vec())
        );
        assert_eq!((tier.fetches(), tier.misses()), (1, 1));
        // A local file that does not load is replaced by the tier's entry.
        std::fs::write(dir.join("l"), b"damaged").unwrap();
        assert_eq!(
            load_or_fetch(Some(&tier), GRASPS, &dir, "l", load),
            Lookup::Fetched(b"ok shared".to_vec())
        );
        // A tier entry that does not load: missing, and said so; shared back with replace.
        tier.insert(GRASPS, "m", b"damaged".to_vec());
        assert_eq!(
            load_or_fetch(Some(&tier), GRASPS, &dir, "m", load),
            Lookup::Missing { tier_refused: true }
        );
        std::fs::write(dir.join("m"), b"ok rebuilt").unwrap();
        share_built(Some(&tier), GRASPS, &dir.join("m"), true);
        assert_eq!(tier.get(GRASPS, "m").unwrap(), b"ok rebuilt");
        share_built(Some(&tier), GRASPS, &dir.join("l"), false);
        assert_eq!((tier.publishes(), tier.replaces()), (2, 1));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
