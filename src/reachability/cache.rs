//! A cache of reachability grids for planners that need them on demand (Bimanual IK-RRT's
//! inverse maps, 002 §III): in memory, then a folder of grid files, else built (in parallel) and
//! saved. Keyed by robot, chain group, kinematics hash and the build parameters, so a changed
//! model or other parameters never reuse a stale grid. With a [`CacheTier`], a grid file missing
//! from the folder is fetched from the tier and a grid built here is published to it.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, OnceLock};

use super::grid::{chain_hash, GridParams, ReachError, ReachabilityGrid};
use super::queries::arm_grid_group;
use crate::cache_tier::{self, CacheTier, Lookup};
use crate::kinematics::randomized::ArmChain;
use crate::kinematics::Chain;
use crate::model::Robot;

/// How grids of the cache are built: voxel size, angle bins, samples, seed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridRecipe {
    pub resolution: f64,
    pub rot_bins: u32,
    pub samples: u64,
    pub seed: u64,
}

impl Default for GridRecipe {
    /// 10 cm, 8 angle bins, 400 000 samples: about 0.5 s per 10-DoF chain on two cores.
    fn default() -> Self {
        GridRecipe {
            resolution: 0.1,
            rot_bins: 8,
            samples: 400_000,
            seed: 1,
        }
    }
}

impl GridRecipe {
    /// Grids of arm chains (shoulder → TCP) for the randomized IK filters (000 §II-D): 5 cm,
    /// 8 angle bins, 1 000 000 samples; about 1 s per 7-DoF arm on two cores.
    pub fn arm() -> GridRecipe {
        GridRecipe {
            resolution: 0.05,
            rot_bins: 8,
            samples: 1_000_000,
            seed: 1,
        }
    }
}

type Key = (String, String, u64, u64, u32, u64, u64);

/// Grids by (robot, group, kinematics, recipe); safe to share between threads.
#[derive(Default)]
pub struct GridCache {
    dir: Option<PathBuf>,
    tier: OnceLock<Arc<dyn CacheTier>>,
    grids: Mutex<HashMap<Key, Arc<ReachabilityGrid>>>,
}

impl std::fmt::Debug for GridCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GridCache")
            .field("dir", &self.dir)
            .field("tier", &self.tier.get().is_some())
            .field("grids", &self.lock().len())
            .finish()
    }
}

impl GridCache {
    /// A cache keeping grid files in `dir` (created on first save), or memory only.
    pub fn new(dir: Option<PathBuf>) -> GridCache {
        GridCache {
            dir,
            tier: OnceLock::new(),
            grids: Mutex::new(HashMap::new()),
        }
    }

    /// This cache with a shared second tier ([`cache_tier`], kind [`cache_tier::REACH`]) behind
    /// its folder; without a folder the tier is not used.
    pub fn with_tier(self, tier: Arc<dyn CacheTier>) -> GridCache {
        self.set_tier(tier);
        self
    }

    /// Sets the tier of a cache already shared; false (and unchanged) when it has one.
    pub fn set_tier(&self, tier: Arc<dyn CacheTier>) -> bool {
        self.tier.set(tier).is_ok()
    }

    /// The grid of an arm chain (shoulder → TCP, [`GridRecipe::arm`]): the randomized IK's
    /// filter (000 §II-D, §III-B). `None` when `robot` has no SRDF group for that chain.
    pub fn arm_grid(
        &self,
        robot: &Arc<Robot>,
        arm: &ArmChain,
    ) -> Result<Option<Arc<ReachabilityGrid>>, ReachError> {
        self.arm_grid_until(robot, arm, &|| false)
    }

    /// [`GridCache::arm_grid`] whose build (if it needs one) ends with [`ReachError::Stopped`]
    /// soon after `stop` returns true.
    pub fn arm_grid_until(
        &self,
        robot: &Arc<Robot>,
        arm: &ArmChain,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Result<Option<Arc<ReachabilityGrid>>, ReachError> {
        match arm_grid_group(robot, arm) {
            Some(group) => self
                .get_until(robot, &group, GridRecipe::arm(), stop)
                .map(Some),
            None => Ok(None),
        }
    }

    /// The grid of `robot`'s chain group `group` built with `recipe`.
    pub fn get(
        &self,
        robot: &Arc<Robot>,
        group: &str,
        recipe: GridRecipe,
    ) -> Result<Arc<ReachabilityGrid>, ReachError> {
        self.get_until(robot, group, recipe, &|| false)
    }

    /// [`GridCache::get`] whose build (if it needs one) ends with [`ReachError::Stopped`] soon
    /// after `stop` returns true; a stopped build is neither cached nor saved.
    pub fn get_until(
        &self,
        robot: &Arc<Robot>,
        group: &str,
        recipe: GridRecipe,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Result<Arc<ReachabilityGrid>, ReachError> {
        let chain = Chain::from_group(robot, group).ok_or_else(|| ReachError::NoChain {
            robot: robot.name.clone(),
            group: group.to_string(),
        })?;
        let hash = chain_hash(robot, &chain);
        let key: Key = (
            robot.name.clone(),
            group.to_string(),
            hash,
            recipe.resolution.to_bits(),
            recipe.rot_bins,
            recipe.samples,
            recipe.seed,
        );
        if let Some(g) = self.lock().get(&key) {
            return Ok(g.clone());
        }
        let params = GridParams::auto(
            robot,
            &chain,
            recipe.resolution,
            recipe.rot_bins,
            recipe.samples,
            recipe.seed,
        )?;
        let name = format!(
            "{}-{}-{:016x}-{}mm-{}-{}-{}.reach",
            robot.name,
            group,
            hash,
            (recipe.resolution * 1000.0).round() as u64,
            recipe.rot_bins,
            recipe.samples,
            recipe.seed
        );
        let tier = self.tier.get().map(|t| &**t as &dyn CacheTier);
        let found = match &self.dir {
            Some(dir) => cache_tier::load_or_fetch(tier, cache_tier::REACH, dir, &name, |f| {
                ReachabilityGrid::load(f, robot, group, Some(&params)).ok()
            }),
            None => Lookup::Missing {
                tier_refused: false,
            },
        };
        let grid = match found {
            Lookup::Local(g) | Lookup::Fetched(g) => g,
            Lookup::Missing { tier_refused } => {
                let g = ReachabilityGrid::build_until(robot, group, &params, &|_| {}, stop)?;
                if let Some(dir) = &self.dir {
                    // A cache that cannot be written (or shared) is only slower next time.
                    let f = dir.join(&name);
                    if std::fs::create_dir_all(dir).is_ok() && g.save(&f).is_ok() {
                        cache_tier::share_built(tier, cache_tier::REACH, &f, tier_refused);
                    }
                }
                g
            }
        };
        let grid = Arc::new(grid);
        self.lock().insert(key, grid.clone());
        Ok(grid)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<Key, Arc<ReachabilityGrid>>> {
        self.grids.lock().unwrap_or_else(|p| p.into_inner())
    }
}
