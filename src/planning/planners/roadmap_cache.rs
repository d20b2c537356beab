//! Super graphs on disk (003 §V-A: "computed offline"), like the reachability grids and the
//! grasp lists: a JSON file holding the graph and three SHA-256 keys — of the robot (every
//! joint's kinematics and limits, every link's collision geometry, the SRDF-disabled pairs), of
//! the roadmap world (robot placements and every obstacle's pose and geometry) and of the
//! parameters (Visibility-PRM settings, decomposition groups, base configuration).
//! [`load_super_graph`] refuses a file whose keys differ, naming which, so a changed robot,
//! scene or setting never serves a stale roadmap. [`load_or_build`] with a [`CacheTier`] fetches
//! a roadmap file missing from its folder from the tier and publishes the roadmaps it builds.

use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::cache_tier::{self, CacheTier, Lookup};
use crate::collision::CollisionWorld;
use crate::model::Robot;
use crate::planning::planners::super_graph::{
    build_super_graph, roadmap_world, Decomposition, SuperGraph, SuperGraphParams,
};
use crate::planning::{PlanError, Termination};

/// The `format` tag of a roadmap file.
pub const ROADMAP_FORMAT: &str = "manyhands-super-graph-1";

fn hex(d: impl AsRef<[u8]>) -> String {
    d.as_ref().iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 of a robot's kinematics, collision geometry and disabled pairs. `{:?}` of `f64` is
/// the shortest round-trip text, so equal models give equal keys in every process.
pub fn robot_hash(robot: &Robot) -> String {
    let mut h = Sha256::new();
    h.update(robot.name.as_bytes());
    for j in &robot.joints {
        h.update(format!("{j:?}").as_bytes());
    }
    for l in &robot.links {
        h.update(l.name.as_bytes());
        h.update(format!("{:?}", l.parent_joint).as_bytes());
        for g in &l.collision {
            h.update(format!("{g:?}").as_bytes());
        }
    }
    h.update(format!("{:?}", robot.vars).as_bytes());
    h.update(robot.disabled.iter().map(|&d| d as u8).collect::<Vec<u8>>());
    hex(h.finalize())
}

/// SHA-256 of what a roadmap is checked against: the robots' placements and models, and the
/// roadmap world's fixed bodies ([`roadmap_world`]: obstacles only).
pub fn world_hash(world: &CollisionWorld) -> String {
    let w = roadmap_world(world);
    let mut h = Sha256::new();
    for p in &w.robots {
        h.update(p.name.as_bytes());
        h.update(robot_hash(&p.robot).as_bytes());
        h.update(format!("{:?}{}", p.base, p.offset).as_bytes());
    }
    for s in &w.statics {
        h.update(format!("{}{:?}{:?}", s.name, s.kind, s.pose).as_bytes());
        for g in &s.shapes {
            h.update(format!("{g:?}").as_bytes());
        }
    }
    hex(h.finalize())
}

/// SHA-256 of the build parameters, the decomposition and the base configuration.
pub fn params_hash(dec: &Decomposition, base: &[f64], params: &SuperGraphParams) -> String {
    let s = serde_json::to_string(&(dec, base, params)).unwrap_or_default();
    hex(Sha256::digest(s.as_bytes()))
}

/// Why a roadmap file is not served.
#[derive(Debug, thiserror::Error)]
pub enum RoadmapFileError {
    #[error("{file}: {source}")]
    Io {
        file: String,
        source: std::io::Error,
    },
    #[error("{file} is not a manyhands roadmap: {reason}")]
    Format { file: String, reason: String },
    #[error("{file} was built for another {what} ({found}, expected {expected}): rebuild it")]
    Mismatch {
        file: String,
        what: &'static str,
        found: String,
        expected: String,
    },
    #[error(transparent)]
    Plan(#[from] PlanError),
}

/// The three keys of a roadmap.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct RoadmapKey {
    pub robot: String,
    pub world: String,
    pub params: String,
}

impl RoadmapKey {
    /// The keys of the roadmap of `dec` in `world` built from `base` with `params`.
    pub fn of(
        world: &CollisionWorld,
        dec: &Decomposition,
        base: &[f64],
        params: &SuperGraphParams,
    ) -> Result<RoadmapKey, PlanError> {
        let p = world.robots.get(dec.robot).ok_or_else(|| {
            PlanError::InvalidInput(format!("robot {} is not in the world", dec.robot))
        })?;
        Ok(RoadmapKey {
            robot: robot_hash(&p.robot),
            world: world_hash(world),
            params: params_hash(dec, base, params),
        })
    }

    /// File name `ROBOT-<16 hex of the keys>.roadmap.json`.
    pub fn file_name(&self, robot_name: &str) -> String {
        let k = hex(Sha256::digest(
            format!("{}{}{}", self.robot, self.world, self.params).as_bytes(),
        ));
        format!("{robot_name}-{}.roadmap.json", &k[..16])
    }
}

#[derive(serde::Serialize, serde::Deserialize)]
struct RoadmapFile {
    format: String,
    key: RoadmapKey,
    graph: SuperGraph,
}

/// Writes `graph` with its `key` to `path` (through a temporary file).
pub fn save_super_graph(
    graph: &SuperGraph,
    key: &RoadmapKey,
    path: &Path,
) -> Result<(), RoadmapFileError> {
    let io = |source| RoadmapFileError::Io {
        file: path.display().to_string(),
        source,
    };
    let body = serde_json::to_vec(&RoadmapFile {
        format: ROADMAP_FORMAT.to_string(),
        key: key.clone(),
        graph: graph.clone(),
    })
    .map_err(|e| RoadmapFileError::Format {
        file: path.display().to_string(),
        reason: e.to_string(),
    })?;
    cache_tier::write_atomic(path, &body).map_err(io)
}

/// Reads a roadmap file and refuses it unless its keys are `expected`.
pub fn load_super_graph(
    path: &Path,
    expected: &RoadmapKey,
) -> Result<SuperGraph, RoadmapFileError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| RoadmapFileError::Io {
        file: file.clone(),
        source,
    })?;
    let f: RoadmapFile = serde_json::from_slice(&bytes).map_err(|e| RoadmapFileError::Format {
        file: file.clone(),
        reason: e.to_string(),
    })?;
    if f.format != ROADMAP_FORMAT {
        return Err(RoadmapFileError::Format {
            file,
            reason: format!("format '{}', expected '{ROADMAP_FORMAT}'", f.format),
        });
    }
    for (what, found, want) in [
        ("robot", &f.key.robot, &expected.robot),
        ("scene", &f.key.world, &expected.world),
        ("parameters", &f.key.params, &expected.params),
    ] {
        if found != want {
            return Err(RoadmapFileError::Mismatch {
                file,
                what,
                found: found.chars().take(12).collect(),
                expected: want.chars().take(12).collect(),
            });
        }
    }
    Ok(f.graph)
}

/// Where a roadmap came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RoadmapSource {
    Built,
    /// From the folder (possibly fetched there from the tier).
    Loaded,
}

/// The roadmap of `dec` in `world` from `dir` when a file with the right keys is there, else
/// from `tier` (kind [`cache_tier::ROADMAPS`], fetched into `dir`) when it has one, else built
/// (and saved in `dir` and published to `tier` when `dir` is given; without `dir` the tier is
/// not used). Returns the graph, its file and where it came from. A file that cannot be
/// written or shared is only slower next time.
pub fn load_or_build(
    dir: Option<&Path>,
    tier: Option<&dyn CacheTier>,
    world: &CollisionWorld,
    dec: &Decomposition,
    base: &[f64],
    params: &SuperGraphParams,
    term: &mut Termination,
) -> Result<(SuperGraph, Option<PathBuf>, RoadmapSource), RoadmapFileError> {
    let key = RoadmapKey::of(world, dec, base, params)?;
    let name = key.file_name(&world.robots[dec.robot].robot.name);
    let found = match dir {
        Some(d) => cache_tier::load_or_fetch(tier, cache_tier::ROADMAPS, d, &name, |f| {
            load_super_graph(f, &key).ok()
        }),
        None => Lookup::Missing {
            tier_refused: false,
        },
    };
    let file = dir.map(|d| d.join(&name));
    let tier_refused = match found {
        Lookup::Local(g) | Lookup::Fetched(g) => return Ok((g, file, RoadmapSource::Loaded)),
        Lookup::Missing { tier_refused } => tier_refused,
    };
    let g = build_super_graph(world, dec, base, params, term)?;
    if let (Some(d), Some(f)) = (dir, &file) {
        if std::fs::create_dir_all(d).is_ok() && save_super_graph(&g, &key, f).is_ok() {
            cache_tier::share_built(tier, cache_tier::ROADMAPS, f, tier_refused);
        }
    }
    Ok((g, file, RoadmapSource::Built))
}
