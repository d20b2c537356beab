//! Single-grasp lists on disk (003 §IV-A: "computed offline"): a JSON file holding the list and
//! three SHA-256 keys — of the hand (every hand joint's kinematics and limits, the chains from
//! the palm to the fingertips, the collision geometry of the hand's links and the finger order),
//! of the object (its geometry: vertex coordinates bit for bit, triangles, poses) and of the
//! parameters. [`load_grasp_list`] refuses a file whose keys differ from the hand, object and
//! parameters it is asked for, naming which, so a changed robot model, mesh or setting never
//! serves a stale list. [`GraspListCache`] keeps lists in memory and in a folder, and with a
//! [`CacheTier`] fetches a list file missing from the folder from the tier and publishes the
//! lists it builds to it.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};

use sha2::{Digest, Sha256};

use super::hand::Hand;
use super::list::{build_grasp_list, GraspList, GraspListError, GraspListParams, GraspObject};
use crate::cache_tier::{self, CacheTier, Lookup};
use crate::geometry::Shape;

/// The `format` tag of a list file.
pub const LIST_FORMAT: &str = "manyhands-grasp-list-1";

fn hex(d: impl AsRef<[u8]>) -> String {
    d.as_ref().iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 of the hand's kinematics and geometry (module docs).
pub fn hand_hash(hand: &Hand) -> String {
    let r = &hand.robot;
    let mut h = Sha256::new();
    h.update(r.links[hand.palm].name.as_bytes());
    for &v in &hand.vars {
        h.update(r.var_name(v).as_bytes());
        h.update(format!("{:?}", r.var_limits(v)).as_bytes());
    }
    for f in &hand.fingers {
        h.update(f.group.as_bytes());
        let path = r.link_path(hand.palm, f.tip_link).unwrap_or_default();
        for &l in &path {
            if let Some(j) = r.links[l].parent_joint {
                h.update(format!("{:?}", r.joints[j]).as_bytes());
            }
        }
    }
    // Sorted: a HashMap's order differs between processes.
    let mut links: Vec<usize> = hand.shapes.keys().copied().collect();
    links.sort_unstable();
    for &l in &links {
        h.update(r.links[l].name.as_bytes());
        for g in &r.links[l].collision {
            h.update(format!("{:?}", g.origin).as_bytes());
            hash_shape(&mut h, &g.shape);
        }
        for &b in &links {
            h.update([r.is_disabled(l, b) as u8]);
        }
    }
    hex(h.finalize())
}

fn hash_shape(h: &mut Sha256, s: &Shape) {
    match s {
        Shape::Mesh(m) => {
            h.update(b"mesh");
            for v in &m.vertices {
                for c in [v.x, v.y, v.z] {
                    h.update(c.to_bits().to_le_bytes());
                }
            }
            for t in &m.triangles {
                for i in t {
                    h.update(i.to_le_bytes());
                }
            }
        }
        other => h.update(format!("{other:?}").as_bytes()),
    }
}

/// SHA-256 of the object's geometry (module docs).
pub fn object_hash(object: &GraspObject) -> String {
    let mut h = Sha256::new();
    for g in &object.geometry {
        h.update(format!("{:?}", g.origin).as_bytes());
        hash_shape(&mut h, &g.shape);
    }
    hex(h.finalize())
}

/// SHA-256 of the parameters' JSON.
pub fn params_hash(params: &GraspListParams) -> String {
    let s = serde_json::to_string(params).unwrap_or_default();
    hex(Sha256::digest(s.as_bytes()))
}

/// Why a list file is not served.
#[derive(Debug, thiserror::Error)]
pub enum ListFileError {
    #[error("{file}: {source}")]
    Io {
        file: String,
        source: std::io::Error,
    },
    #[error("{file} is not a manyhands grasp list: {reason}")]
    Format { file: String, reason: String },
    #[error("{file} was built for another {what} ({found}, expected {expected}): rebuild it")]
    Mismatch {
        file: String,
        what: &'static str,
        found: String,
        expected: String,
    },
}

#[derive(serde::Serialize, serde::Deserialize)]
struct ListFile {
    format: String,
    list: GraspList,
}

/// Writes `list` to `path` (through a temporary file, so a reader never sees half a list).
pub fn save_grasp_list(list: &GraspList, path: &Path) -> Result<(), ListFileError> {
    let io = |source| ListFileError::Io {
        file: path.display().to_string(),
        source,
    };
    let body = serde_json::to_vec(&ListFile {
        format: LIST_FORMAT.to_string(),
        list: list.clone(),
    })
    .map_err(|e| ListFileError::Format {
        file: path.display().to_string(),
        reason: e.to_string(),
    })?;
    cache_tier::write_atomic(path, &body).map_err(io)
}

/// Reads a list file without checking it against a hand or object.
pub fn read_grasp_list(path: &Path) -> Result<GraspList, ListFileError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| ListFileError::Io {
        file: file.clone(),
        source,
    })?;
    let f: ListFile = serde_json::from_slice(&bytes).map_err(|e| ListFileError::Format {
        file: file.clone(),
        reason: e.to_string(),
    })?;
    if f.format != LIST_FORMAT {
        return Err(ListFileError::Format {
            file,
            reason: format!("format '{}', expected '{LIST_FORMAT}'", f.format),
        });
    }
    Ok(f.list)
}

/// Reads a list file and refuses it unless it was built for `hand`, `object` and `params`.
pub fn load_grasp_list(
    path: &Path,
    hand: &Hand,
    object: &GraspObject,
    params: &GraspListParams,
) -> Result<GraspList, ListFileError> {
    let list = read_grasp_list(path)?;
    let file = path.display().to_string();
    let checks = [
        ("hand", &list.hand_hash, hand_hash(hand)),
        ("object", &list.object_hash, object_hash(object)),
        ("parameters", &list.params_hash, params_hash(params)),
    ];
    for (what, found, expected) in checks {
        if *found != expected {
            return Err(ListFileError::Mismatch {
                file,
                what,
                found: found.chars().take(12).collect(),
                expected: expected.chars().take(12).collect(),
            });
        }
    }
    if list.params != *params {
        return Err(ListFileError::Mismatch {
            file,
            what: "parameters",
            found: serde_json::to_string(&list.params).unwrap_or_default(),
            expected: serde_json::to_string(params).unwrap_or_default(),
        });
    }
    Ok(list)
}

/// The file name of a list: `ROBOT-HAND-OBJECT-<12 hex of the three keys>.grasps.json`.
pub fn list_file_name(hand: &Hand, object: &GraspObject, params: &GraspListParams) -> String {
    let key = hex(Sha256::digest(
        format!(
            "{}{}{}",
            hand_hash(hand),
            object_hash(object),
            params_hash(params)
        )
        .as_bytes(),
    ));
    let clean = |s: &str| -> String {
        s.chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '_' {
                    c
                } else {
                    '_'
                }
            })
            .collect()
    };
    format!(
        "{}-{}-{}-{}.grasps.json",
        clean(&hand.robot.name),
        clean(&hand.group),
        clean(&object.name),
        &key[..12]
    )
}

/// Lists in memory, then in a folder, then in the tier (if set), else built, saved and
/// published; keyed by the three hashes.
#[derive(Default)]
pub struct GraspListCache {
    dir: Option<PathBuf>,
    tier: OnceLock<Arc<dyn CacheTier>>,
    lists: Mutex<HashMap<String, Arc<GraspList>>>,
}

impl std::fmt::Debug for GraspListCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GraspListCache")
            .field("dir", &self.dir)
            .field("tier", &self.tier.get().is_some())
            .field("lists", &self.lock().len())
            .finish()
    }
}

impl GraspListCache {
    pub fn new(dir: Option<PathBuf>) -> GraspListCache {
        GraspListCache {
            dir,
            tier: OnceLock::new(),
            lists: Mutex::new(HashMap::new()),
        }
    }

    /// This cache with a shared second tier ([`cache_tier`], kind [`cache_tier::GRASPS`])
    /// behind its folder; without a folder the tier is not used.
    pub fn with_tier(self, tier: Arc<dyn CacheTier>) -> GraspListCache {
        self.set_tier(tier);
        self
    }

    /// Sets the tier of a cache already shared; false (and unchanged) when it has one.
    pub fn set_tier(&self, tier: Arc<dyn CacheTier>) -> bool {
        self.tier.set(tier).is_ok()
    }

    fn tier(&self) -> Option<&dyn CacheTier> {
        self.tier.get().map(|t| &**t as &dyn CacheTier)
    }

    /// The cached list, if built before (memory, folder or tier); never builds.
    pub fn find(
        &self,
        hand: &Hand,
        object: &GraspObject,
        params: &GraspListParams,
    ) -> Option<Arc<GraspList>> {
        self.lookup(hand, object, params).ok()
    }

    /// The list from memory, the folder or the tier; else (`Err`) whether the tier's entry was
    /// refused.
    fn lookup(
        &self,
        hand: &Hand,
        object: &GraspObject,
        params: &GraspListParams,
    ) -> Result<Arc<GraspList>, bool> {
        let name = list_file_name(hand, object, params);
        if let Some(l) = self.lock().get(&name) {
            return Ok(l.clone());
        }
        let Some(dir) = &self.dir else {
            return Err(false);
        };
        let found = cache_tier::load_or_fetch(self.tier(), cache_tier::GRASPS, dir, &name, |f| {
            load_grasp_list(f, hand, object, params).ok()
        });
        match found {
            Lookup::Local(l) | Lookup::Fetched(l) => {
                let list = Arc::new(l);
                self.lock().insert(name, list.clone());
                Ok(list)
            }
            Lookup::Missing { tier_refused } => Err(tier_refused),
        }
    }

    /// The list, built (and saved, and published) if not cached; the second value is true
    /// when it was built.
    pub fn get_or_build(
        &self,
        hand: &Hand,
        object: &GraspObject,
        params: &GraspListParams,
        progress: &(dyn Fn(usize, usize) + Sync),
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Result<(Arc<GraspList>, bool), GraspListError> {
        let tier_refused = match self.lookup(hand, object, params) {
            Ok(l) => return Ok((l, false)),
            Err(refused) => refused,
        };
        let list = Arc::new(build_grasp_list(hand, object, params, progress, stop)?);
        let name = list_file_name(hand, object, params);
        if let Some(dir) = &self.dir {
            // A cache that cannot be written (or shared) is only slower next time.
            let f = dir.join(&name);
            if std::fs::create_dir_all(dir).is_ok() && save_grasp_list(&list, &f).is_ok() {
                cache_tier::share_built(self.tier(), cache_tier::GRASPS, &f, tier_refused);
            }
        }
        self.lock().insert(name, list.clone());
        Ok((list, true))
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<String, Arc<GraspList>>> {
        self.lists.lock().unwrap_or_else(|p| p.into_inner())
    }
}
