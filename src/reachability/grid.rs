//! The 6-D reachability grid of paper 000 §II-B (Vahrenkamp et al. 2009, after Zacharias et al.
//! and Diankov et al.): voxels over the TCP pose (x, y, z, roll, pitch, yaw) in the chain-base
//! frame, each holding how often sampled joint configurations put the TCP into it.
//!
//! The grid is filled "by randomly sampling the joint values while using the forward kinematics to
//! determine the pose of the end effector and thus the corresponding 6D voxel" (000 §II-B); only
//! self-collision-free samples count. Entries saturate at 255 (as in Simox, the paper's toolbox);
//! the probability of a cell is its entry divided by the largest entry.
//!
//! Building is parallel (rayon) and deterministic: the sample count is split into a fixed number of
//! chunks, chunk `i` draws from `ChaCha8Rng::seed_from_u64(seed)` on stream `i`, and the counts
//! are summed, so the result does not depend on the number of threads.

use std::f64::consts::PI;
use std::io::Read;
use std::path::Path;
use std::sync::Arc;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use thiserror::Error;

use crate::collision::{CollisionChecker, CollisionWorld, FastChecker};
use crate::geometry::{atan2, Pose};
use crate::kinematics::randomized::ReachabilityMap;
use crate::kinematics::Chain;
use crate::model::Robot;

/// Version of the binary file format written by [`ReachabilityGrid::save`].
pub const FORMAT_VERSION: u32 = 1;
const MAGIC: &[u8; 8] = b"MHREACH\0";
/// Number of independently seeded chunks the samples are split into.
const CHUNKS: u64 = 256;

/// Why a grid cannot be built, saved or loaded.
#[derive(Debug, Error)]
pub enum ReachError {
    #[error("robot '{robot}' has no group '{group}' that is a chain")]
    NoChain { robot: String, group: String },
    #[error("invalid reachability parameters: {0}")]
    InvalidParams(String),
    #[error("reachability file {file}: {reason}")]
    Io { file: String, reason: String },
    #[error("{file} is not a manyhands reachability file (bad magic bytes)")]
    BadMagic { file: String },
    #[error("reachability file {file} has format version {found}; this build reads version {expected}: rebuild it with `manyhands reach build`")]
    Version {
        file: String,
        found: u32,
        expected: u32,
    },
    #[error("reachability file {file} was built for {what} '{found}', not '{expected}'")]
    Mismatch {
        file: String,
        what: &'static str,
        found: String,
        expected: String,
    },
    #[error("reachability file {file} was built for other kinematics of chain {chain} (hash {found:016x}, the model now has {expected:016x}): rebuild it")]
    KinematicsChanged {
        file: String,
        chain: String,
        found: u64,
        expected: u64,
    },
    #[error("reachability file {file} was built with other parameters: {diff}")]
    ParamsMismatch { file: String, diff: String },
    #[error("reachability file {file} is truncated or corrupt: {reason}")]
    Corrupt { file: String, reason: String },
    #[error("the reachability grid build was stopped on request")]
    Stopped,
}

/// Resolution and extents of a grid, and how it was sampled.
#[derive(Debug, Clone, PartialEq)]
pub struct GridParams {
    /// Edge length (m) of a voxel in x, y and z.
    pub resolution: f64,
    /// Number of bins of each angle: roll and yaw over [−π, π), pitch over [−π/2, π/2].
    pub rot_bins: u32,
    /// Lower corner of the position extents (chain-base frame, m).
    pub min: [f64; 3],
    /// Upper corner of the position extents (chain-base frame, m).
    pub max: [f64; 3],
    /// Joint configurations sampled.
    pub samples: u64,
    pub seed: u64,
}

impl GridParams {
    /// Parameters whose position extents cover the chain's workspace: the bounding box of 20 000
    /// seeded FK samples (collisions ignored) grown by 10 % of its size plus one voxel, snapped to
    /// the resolution.
    pub fn auto(
        robot: &Robot,
        chain: &Chain,
        resolution: f64,
        rot_bins: u32,
        samples: u64,
        seed: u64,
    ) -> Result<GridParams, ReachError> {
        if !(resolution.is_finite() && resolution > 1e-4) {
            return Err(ReachError::InvalidParams(format!(
                "resolution {resolution} m must be a number > 0.0001"
            )));
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_b0b5);
        let mut q = robot
            .named_config("home")
            .unwrap_or_else(|| robot.zero_config());
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for _ in 0..20_000 {
            robot.sample_vars(&chain.vars, &mut q, &mut rng);
            let t = chain.tip_pose(robot, &q).translation.vector;
            for k in 0..3 {
                lo[k] = lo[k].min(t[k]);
                hi[k] = hi[k].max(t[k]);
            }
        }
        let mut min = [0.0; 3];
        let mut max = [0.0; 3];
        for k in 0..3 {
            let grow = 0.1 * (hi[k] - lo[k]) + resolution;
            min[k] = ((lo[k] - grow) / resolution).floor() * resolution;
            max[k] = ((hi[k] + grow) / resolution).ceil() * resolution;
        }
        let p = GridParams {
            resolution,
            rot_bins,
            min,
            max,
            samples,
            seed,
        };
        p.validate()?;
        Ok(p)
    }

    /// Cells along x, y, z.
    pub fn dims(&self) -> [usize; 3] {
        std::array::from_fn(|k| {
            (((self.max[k] - self.min[k]) / self.resolution).round() as usize).max(1)
        })
    }

    /// Total number of cells.
    pub fn cells(&self) -> usize {
        let d = self.dims();
        let r = self.rot_bins as usize;
        d[0] * d[1] * d[2] * r * r * r
    }

    fn validate(&self) -> Result<(), ReachError> {
        let bad = |m: String| Err(ReachError::InvalidParams(m));
        if !(self.resolution.is_finite() && self.resolution > 1e-4) {
            return bad(format!("resolution {} m must be > 0.0001", self.resolution));
        }
        if self.rot_bins == 0 || self.rot_bins > 64 {
            return bad(format!("rot_bins {} must be in 1..=64", self.rot_bins));
        }
        for k in 0..3 {
            if !(self.min[k].is_finite() && self.max[k].is_finite() && self.max[k] > self.min[k]) {
                return bad(format!("extent {k}: [{}, {}]", self.min[k], self.max[k]));
            }
        }
        let cells =
            self.dims().iter().map(|&d| d as f64).product::<f64>() * (self.rot_bins as f64).powi(3);
        if cells > 2.0e9 {
            return bad(format!(
                "{cells:.3e} cells (more than 2e9): coarser resolution or fewer rotation bins"
            ));
        }
        Ok(())
    }

    /// Human-readable list of the fields that differ from `o` (empty when equal).
    pub fn diff(&self, o: &GridParams) -> String {
        let mut d = Vec::new();
        if self.resolution != o.resolution {
            d.push(format!("resolution {} ≠ {}", self.resolution, o.resolution));
        }
        if self.rot_bins != o.rot_bins {
            d.push(format!("rot_bins {} ≠ {}", self.rot_bins, o.rot_bins));
        }
        if self.min != o.min || self.max != o.max {
            d.push(format!(
                "extents {:?}–{:?} ≠ {:?}–{:?}",
                self.min, self.max, o.min, o.max
            ));
        }
        if self.samples != o.samples {
            d.push(format!("samples {} ≠ {}", self.samples, o.samples));
        }
        if self.seed != o.seed {
            d.push(format!("seed {} ≠ {}", self.seed, o.seed));
        }
        d.join(", ")
    }
}

/// Counts of a build.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BuildStats {
    /// Configurations sampled.
    pub samples: u64,
    /// Of these, free of self-collision.
    pub free: u64,
    /// Free samples whose TCP fell outside the extents.
    pub outside: u64,
    /// Cells with a non-zero entry.
    pub filled: u64,
}

/// A 6-D reachability grid of one chain of one robot (see the module documentation).
#[derive(Debug, Clone)]
pub struct ReachabilityGrid {
    robot: String,
    group: String,
    base_link: String,
    tip_link: String,
    hash: u64,
    params: GridParams,
    dims: [usize; 3],
    stats: BuildStats,
    max_entry: u8,
    inv_max: f64,
    bins: CellBins,
    data: Vec<u8>,
    /// One bit per cell, set where the entry is > 0 (an eighth of the entries' size). Most cells
    /// are empty (3.7 % are filled in ARMAR's arm grids), so most lookups end in this bitmap,
    /// which stays in cache, instead of missing on the entries.
    occupied: Vec<u64>,
    /// One bit per position voxel, set where any of its orientation cells is filled: a lookup
    /// whose position falls in an empty voxel (most of them) skips the orientation binning.
    positions: Vec<u64>,
}

/// What a lookup needs to bin a pose without divisions or inverse trigonometry: the inner
/// edges of the angle bins as sines and cosines, so roll, pitch and yaw are binned by
/// comparisons instead of `atan2` / `asin` (a bin is the number of edges at or below the
/// angle), and the inverse of the position resolution.
#[derive(Debug, Clone)]
struct CellBins {
    /// sin of the pitch edges −π/2 + k·π/b (ascending): sin is increasing on [−π/2, π/2].
    pitch_sin: Vec<f64>,
    /// Roll / yaw edges −π + k·2π/b in (−π, 0): their cosines (cos is increasing there).
    neg_cos: Vec<f64>,
    /// Roll / yaw edges in [0, π): their cosines (cos is decreasing there).
    pos_cos: Vec<f64>,
    /// 1 / position resolution: a lookup multiplies instead of dividing.
    inv_resolution: f64,
}

impl CellBins {
    fn new(bins: u32, resolution: f64) -> CellBins {
        let b = bins as f64;
        let edges = (1..bins).map(|k| -PI + k as f64 * 2.0 * PI / b);
        CellBins {
            pitch_sin: (1..bins)
                .map(|k| (-0.5 * PI + k as f64 * PI / b).sin())
                .collect(),
            neg_cos: edges.clone().filter(|&e| e < 0.0).map(f64::cos).collect(),
            pos_cos: edges.filter(|&e| e >= 0.0).map(f64::cos).collect(),
            inv_resolution: 1.0 / resolution,
        }
    }

    /// Bin of `atan2(y, x)` over [−π, π) (y = ±0 with x < 0 counts as π).
    #[inline]
    fn full_turn(&self, y: f64, x: f64) -> usize {
        // cos = x / h compared as x against edge · h (no division); h = 0 is angle 0.
        let h = (x * x + y * y).sqrt();
        let (x, h) = if h > 0.0 { (x, h) } else { (1.0, 1.0) };
        if y >= 0.0 {
            self.neg_cos.len() + self.pos_cos.iter().filter(|&&e| x <= e * h).count()
        } else {
            self.neg_cos.iter().filter(|&&e| x >= e * h).count()
        }
    }

    /// Bin of the pitch whose sine is `s`, over [−π/2, π/2).
    #[inline]
    fn pitch(&self, s: f64) -> usize {
        self.pitch_sin.iter().filter(|&&e| s >= e).count()
    }
}

/// FNV-1a, 64 bit.
fn fnv(bytes: &[u8], mut h: u64) -> u64 {
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x100_0000_01b3);
    }
    h
}
const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// Hash of a chain's kinematics: joint names, kinds, origins, axes, limits and mimic data of every
/// joint from base to tip (`{:?}` text of each joint, deterministic for f64), plus the link names.
pub fn chain_hash(robot: &Robot, chain: &Chain) -> u64 {
    let mut h = fnv(robot.links[chain.base_link].name.as_bytes(), FNV_OFFSET);
    h = fnv(robot.links[chain.tip_link].name.as_bytes(), h);
    for &j in &chain.joints {
        h = fnv(format!("{:?}", robot.joints[j]).as_bytes(), h);
    }
    h
}

impl ReachabilityGrid {
    /// Builds the grid of SRDF chain group `group` (000 §II-B): `params.samples` configurations of
    /// the chain's variables (all others at the `home` state), self-collision-free ones (fast
    /// checker on a world holding only the robot) counted in the voxel of their TCP pose.
    /// `progress` is called with the number of samples finished so far (from worker threads).
    pub fn build(
        robot: &Arc<Robot>,
        group: &str,
        params: &GridParams,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<ReachabilityGrid, ReachError> {
        Self::build_until(robot, group, params, progress, &|| false)
    }

    /// [`ReachabilityGrid::build`] that polls `stop` every 256 samples on every worker and ends
    /// with [`ReachError::Stopped`] soon after it returns true (a job's cancel).
    pub fn build_until(
        robot: &Arc<Robot>,
        group: &str,
        params: &GridParams,
        progress: &(dyn Fn(u64) + Sync),
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Result<ReachabilityGrid, ReachError> {
        params.validate()?;
        let chain = Chain::from_group(robot, group).ok_or_else(|| ReachError::NoChain {
            robot: robot.name.clone(),
            group: group.to_string(),
        })?;
        let mut grid = ReachabilityGrid {
            robot: robot.name.clone(),
            group: group.to_string(),
            base_link: robot.links[chain.base_link].name.clone(),
            tip_link: robot.links[chain.tip_link].name.clone(),
            hash: chain_hash(robot, &chain),
            params: params.clone(),
            dims: params.dims(),
            stats: BuildStats::default(),
            max_entry: 0,
            inv_max: 0.0,
            bins: CellBins::new(params.rot_bins, params.resolution),
            data: vec![0; params.cells()],
            occupied: Vec::new(),
            positions: Vec::new(),
        };
        let world = CollisionWorld::single(robot.clone(), Pose::identity());
        let checker = FastChecker::new(&world);
        let home = robot
            .named_config("home")
            .unwrap_or_else(|| robot.zero_config());
        let done = std::sync::atomic::AtomicU64::new(0);
        let total = params.samples;
        // Chunks in batches so the index lists stay small.
        let mut counts = vec![0u32; 0];
        let mut sparse: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
        let dense = grid.data.len() <= 400_000_000;
        if dense {
            counts = vec![0u32; grid.data.len()];
        }
        let chunk_len = |c: u64| total / CHUNKS + u64::from(c < total % CHUNKS);
        let batch = 16u64;
        let mut c0 = 0;
        while c0 < CHUNKS {
            let c1 = (c0 + batch).min(CHUNKS);
            let results: Vec<(Vec<u32>, u64, u64)> = (c0..c1)
                .into_par_iter()
                .map(|c| {
                    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
                    rng.set_stream(c);
                    let mut checker = checker.clone();
                    let mut q = home.clone();
                    let n = chunk_len(c);
                    let mut hits = Vec::with_capacity(n as usize);
                    let (mut free, mut outside) = (0u64, 0u64);
                    for i in 0..n {
                        if i % 256 == 0 && stop() {
                            break;
                        }
                        robot.sample_vars(&chain.vars, &mut q, &mut rng);
                        if checker.is_free(&q) {
                            free += 1;
                            let tip = chain.tip_pose(robot, &q);
                            match grid.cell_of(&tip) {
                                Some(cell) => hits.push(cell as u32),
                                None => outside += 1,
                            }
                        }
                        if i % 4096 == 4095 {
                            progress(
                                done.fetch_add(4096, std::sync::atomic::Ordering::Relaxed) + 4096,
                            );
                        }
                    }
                    progress(
                        done.fetch_add(n % 4096, std::sync::atomic::Ordering::Relaxed) + n % 4096,
                    );
                    (hits, free, outside)
                })
                .collect();
            for (hits, free, outside) in results {
                grid.stats.free += free;
                grid.stats.outside += outside;
                for h in hits {
                    if dense {
                        counts[h as usize] += 1;
                    } else {
                        *sparse.entry(h).or_insert(0) += 1;
                    }
                }
            }
            c0 = c1;
            if stop() {
                return Err(ReachError::Stopped);
            }
        }
        grid.stats.samples = total;
        let mut put = |cell: usize, n: u32| {
            grid.data[cell] = n.min(255) as u8;
        };
        if dense {
            for (cell, &n) in counts.iter().enumerate() {
                if n > 0 {
                    put(cell, n);
                }
            }
        } else {
            for (&cell, &n) in &sparse {
                put(cell as usize, n);
            }
        }
        grid.finish();
        Ok(grid)
    }

    fn finish(&mut self) {
        self.max_entry = self.data.iter().copied().max().unwrap_or(0);
        self.inv_max = if self.max_entry > 0 {
            1.0 / self.max_entry as f64
        } else {
            0.0
        };
        self.occupied = self
            .data
            .chunks(64)
            .map(|c| {
                c.iter()
                    .enumerate()
                    .fold(0u64, |m, (i, &v)| m | (((v > 0) as u64) << i))
            })
            .collect();
        self.stats.filled = self.occupied.iter().map(|w| w.count_ones() as u64).sum();
        let per = (self.params.rot_bins as usize).pow(3);
        let voxels = self.dims[0] * self.dims[1] * self.dims[2];
        let mut positions = vec![0u64; voxels.div_ceil(64)];
        for v in 0..voxels {
            if self.any_occupied(v * per, (v + 1) * per) {
                positions[v >> 6] |= 1 << (v & 63);
            }
        }
        self.positions = positions;
    }

    /// Entry of a flat cell index (0 for `usize::MAX`, the "outside" marker); the bitmap
    /// answers for empty cells.
    #[inline]
    fn entry_at(&self, cell: usize) -> u8 {
        match self.occupied.get(cell >> 6) {
            Some(&w) if (w >> (cell & 63)) & 1 != 0 => self.data[cell],
            _ => 0,
        }
    }

    /// Centres (chain-base frame) of the position voxels with at least one filled orientation
    /// cell. Every pose with a non-zero entry lies in the cube of one of them (side: the
    /// resolution).
    pub fn filled_positions(&self) -> Vec<nalgebra::Vector3<f64>> {
        let [nx, ny, nz] = self.dims;
        let mut out = Vec::new();
        for ix in 0..nx {
            for iy in 0..ny {
                for iz in 0..nz {
                    if self.voxel_filled(&[ix, iy, iz]) {
                        out.push(nalgebra::Vector3::new(
                            self.cell_centre(0, ix),
                            self.cell_centre(1, iy),
                            self.cell_centre(2, iz),
                        ));
                    }
                }
            }
        }
        out
    }

    /// Whether any cell in `start..end` is filled (bitmap words at a time).
    fn any_occupied(&self, start: usize, end: usize) -> bool {
        let mut i = start;
        while i < end {
            let w = self.occupied.get(i >> 6).copied().unwrap_or(0);
            let lo = i & 63;
            let hi = (end - (i - lo)).min(64);
            let mask = if hi - lo == 64 {
                u64::MAX
            } else {
                ((1u64 << (hi - lo)) - 1) << lo
            };
            if w & mask != 0 {
                return true;
            }
            i += hi - lo;
        }
        false
    }

    /// Robot name the grid was built for.
    pub fn robot(&self) -> &str {
        &self.robot
    }
    /// SRDF group of the chain.
    pub fn group(&self) -> &str {
        &self.group
    }
    /// Chain base link (the frame of the grid).
    pub fn base_link(&self) -> &str {
        &self.base_link
    }
    /// Chain tip link (the TCP).
    pub fn tip_link(&self) -> &str {
        &self.tip_link
    }
    /// Kinematics hash of the chain ([`chain_hash`]).
    pub fn hash(&self) -> u64 {
        self.hash
    }
    pub fn params(&self) -> &GridParams {
        &self.params
    }
    /// Cells along x, y, z.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }
    pub fn stats(&self) -> &BuildStats {
        &self.stats
    }
    /// Largest entry (the entry of probability 1).
    pub fn max_entry(&self) -> u8 {
        self.max_entry
    }
    /// Raw entries, index `((((ix·ny + iy)·nz + iz)·b + ir)·b + ip)·b + iw`.
    pub fn data(&self) -> &[u8] {
        &self.data
    }

    /// Bin of an angle over `[lo, lo + span)`, clamped.
    #[inline]
    fn angle_bin(&self, a: f64, lo: f64, span: f64) -> usize {
        let b = self.params.rot_bins as usize;
        let x = (a - lo) / span * b as f64;
        // Truncation is floor for x > 0; x ≤ 0 and NaN go to bin 0.
        if x > 0.0 {
            (x as usize).min(b - 1)
        } else {
            0
        }
    }

    /// The 6-D cell indices (ix, iy, iz, iroll, ipitch, iyaw) of a pose in the chain-base frame;
    /// `None` outside the position extents.
    #[inline]
    pub fn cell_coords(&self, pose: &Pose) -> Option<[usize; 6]> {
        let mut c = [0usize; 6];
        c[..3].copy_from_slice(&self.voxel_of(&pose.translation.vector)?);
        self.bin_rotation(&pose.rotation, &mut c);
        Some(c)
    }

    /// Position voxel indices of a point (chain-base frame); `None` outside the extents.
    #[inline]
    fn voxel_of(&self, t: &nalgebra::Vector3<f64>) -> Option<[usize; 3]> {
        let mut c = [0usize; 3];
        for k in 0..3 {
            let f = (t[k] - self.params.min[k]) * self.bins.inv_resolution;
            if f.is_nan() || f < 0.0 || f >= self.dims[k] as f64 {
                return None;
            }
            c[k] = f as usize;
        }
        Some(c)
    }

    /// Whether any orientation cell of a position voxel is filled.
    #[inline]
    fn voxel_filled(&self, c: &[usize; 3]) -> bool {
        let v = (c[0] * self.dims[1] + c[1]) * self.dims[2] + c[2];
        (self.positions[v >> 6] >> (v & 63)) & 1 != 0
    }

    /// Raw entry of a pose given as its position and rotation: empty position voxels answer
    /// before the rotation is composed or binned.
    #[inline]
    fn entry_parts(
        &self,
        t: &nalgebra::Vector3<f64>,
        rotation: impl FnOnce() -> nalgebra::UnitQuaternion<f64>,
    ) -> u8 {
        let Some(v) = self.voxel_of(t) else {
            return 0;
        };
        if !self.voxel_filled(&v) {
            return 0;
        }
        let mut c = [v[0], v[1], v[2], 0, 0, 0];
        self.bin_rotation(&rotation(), &mut c);
        self.entry_at(self.index(&c))
    }

    /// Roll, pitch and yaw bins of a rotation into `c[3..6]`.
    #[inline]
    fn bin_rotation(&self, rotation: &nalgebra::UnitQuaternion<f64>, c: &mut [usize; 6]) {
        // URDF roll-pitch-yaw (as nalgebra's `euler_angles`), from the needed entries of the
        // rotation matrix only, binned by comparisons (see `CellBins`).
        let q = rotation.quaternion();
        let (w, x, y, z) = (q.w, q.i, q.j, q.k);
        let r20 = 2.0 * (x * z - w * y);
        if r20.abs() < 1.0 {
            let (r21, r22) = (2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y));
            let (r10, r00) = (2.0 * (x * y + w * z), 1.0 - 2.0 * (y * y + z * z));
            c[3] = self.bins.full_turn(r21, r22);
            c[4] = self.bins.pitch(-r20);
            c[5] = self.bins.full_turn(r10, r00);
        } else {
            let (r01, r02) = (2.0 * (x * y - w * z), 2.0 * (x * z + w * y));
            let (roll, pitch) = if r20 <= -1.0 {
                (atan2(r01, r02), 0.5 * PI)
            } else {
                (-atan2(-r01, -r02), -0.5 * PI)
            };
            c[3] = self.angle_bin(roll, -PI, 2.0 * PI);
            c[4] = self.angle_bin(pitch, -0.5 * PI, PI);
            c[5] = self.angle_bin(0.0, -PI, 2.0 * PI);
        }
    }

    /// Flat index of cell coordinates.
    #[inline]
    pub fn index(&self, c: &[usize; 6]) -> usize {
        let b = self.params.rot_bins as usize;
        ((((c[0] * self.dims[1] + c[1]) * self.dims[2] + c[2]) * b + c[3]) * b + c[4]) * b + c[5]
    }

    /// The orientation part of the flat cell index of a rotation (chain-base frame): a pose's
    /// cell is its position voxel's index · rot_bins³ plus this ([`Self::index`]). Lets callers
    /// that look up many positions with one rotation bin it once
    /// ([`Self::probability_with_rotation`]).
    pub fn rotation_offset(&self, rotation: &nalgebra::UnitQuaternion<f64>) -> usize {
        let mut c = [0usize; 6];
        self.bin_rotation(rotation, &mut c);
        let b = self.params.rot_bins as usize;
        (c[3] * b + c[4]) * b + c[5]
    }

    /// [`Self::probability`] of the pose with position `t` and the rotation whose
    /// [`Self::rotation_offset`] is `rotation_offset`: the same value, without binning the
    /// rotation again.
    #[inline]
    pub fn probability_with_rotation(
        &self,
        t: &nalgebra::Vector3<f64>,
        rotation_offset: usize,
    ) -> f64 {
        let Some(v) = self.voxel_of(t) else {
            return 0.0;
        };
        if !self.voxel_filled(&v) {
            return 0.0;
        }
        let b = self.params.rot_bins as usize;
        let voxel = (v[0] * self.dims[1] + v[1]) * self.dims[2] + v[2];
        self.entry_at(voxel * b * b * b + rotation_offset) as f64 * self.inv_max
    }

    /// Flat cell index of a pose (chain-base frame).
    #[inline]
    pub fn cell_of(&self, pose: &Pose) -> Option<usize> {
        self.cell_coords(pose).map(|c| self.index(&c))
    }

    /// Raw entry at a pose (0 outside).
    #[inline]
    pub fn entry(&self, pose: &Pose) -> u8 {
        self.entry_parts(&pose.translation.vector, || pose.rotation)
    }

    /// Probability that an IK query for `pose` (TCP in the chain-base frame) succeeds: entry of
    /// its voxel divided by the largest entry (000 §II-B); 0 outside the extents.
    #[inline]
    pub fn probability(&self, pose: &Pose) -> f64 {
        self.entry(pose) as f64 * self.inv_max
    }

    /// Probability of a cell given by coordinates (0 if out of range).
    pub fn probability_at(&self, c: &[usize; 6]) -> f64 {
        let b = self.params.rot_bins as usize;
        if (0..3).any(|k| c[k] >= self.dims[k]) || (3..6).any(|k| c[k] >= b) {
            return 0.0;
        }
        self.data[self.index(c)] as f64 * self.inv_max
    }

    /// Centre of cell coordinate `i` along dimension `k` (position in m, angles in rad).
    pub fn cell_centre(&self, k: usize, i: usize) -> f64 {
        let b = self.params.rot_bins as f64;
        match k {
            0..=2 => self.params.min[k] + (i as f64 + 0.5) * self.params.resolution,
            4 => -0.5 * PI + (i as f64 + 0.5) * PI / b,
            _ => -PI + (i as f64 + 0.5) * 2.0 * PI / b,
        }
    }

    /// Writes the grid: magic, format version, robot, group, base and tip link, chain hash,
    /// parameters, build counts, cell entries, FNV checksum of the entries (little endian).
    pub fn save(&self, path: &Path) -> Result<(), ReachError> {
        let file = path.display().to_string();
        let io = |e: std::io::Error| ReachError::Io {
            file: file.clone(),
            reason: e.to_string(),
        };
        let mut out: Vec<u8> = Vec::with_capacity(self.data.len() + 512);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        for s in [&self.robot, &self.group, &self.base_link, &self.tip_link] {
            out.extend_from_slice(&(s.len() as u32).to_le_bytes());
            out.extend_from_slice(s.as_bytes());
        }
        out.extend_from_slice(&self.hash.to_le_bytes());
        let p = &self.params;
        out.extend_from_slice(&p.resolution.to_le_bytes());
        out.extend_from_slice(&p.rot_bins.to_le_bytes());
        for v in p.min.iter().chain(&p.max) {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&p.samples.to_le_bytes());
        out.extend_from_slice(&p.seed.to_le_bytes());
        for v in [self.stats.samples, self.stats.free, self.stats.outside] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&(self.data.len() as u64).to_le_bytes());
        out.extend_from_slice(&self.data);
        out.extend_from_slice(&fnv(&self.data, FNV_OFFSET).to_le_bytes());
        // Atomically: a reader (or a publisher to a shared cache tier) never sees part of it.
        crate::cache_tier::write_atomic(path, &out).map_err(io)
    }

    /// Reads a grid written by [`ReachabilityGrid::save`] without checking it against a model.
    pub fn load_unchecked(path: &Path) -> Result<ReachabilityGrid, ReachError> {
        let file = path.display().to_string();
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .and_then(|mut f| f.read_to_end(&mut bytes))
            .map_err(|e| ReachError::Io {
                file: file.clone(),
                reason: e.to_string(),
            })?;
        let mut r = Reader {
            b: &bytes,
            at: 0,
            file: &file,
        };
        if r.take(8)? != MAGIC {
            return Err(ReachError::BadMagic { file });
        }
        let version = r.u32()?;
        if version != FORMAT_VERSION {
            return Err(ReachError::Version {
                file,
                found: version,
                expected: FORMAT_VERSION,
            });
        }
        let robot = r.string()?;
        let group = r.string()?;
        let base_link = r.string()?;
        let tip_link = r.string()?;
        let hash = r.u64()?;
        let resolution = r.f64()?;
        let rot_bins = r.u32()?;
        let mut ext = [0.0; 6];
        for v in &mut ext {
            *v = r.f64()?;
        }
        let samples = r.u64()?;
        let seed = r.u64()?;
        let params = GridParams {
            resolution,
            rot_bins,
            min: [ext[0], ext[1], ext[2]],
            max: [ext[3], ext[4], ext[5]],
            samples,
            seed,
        };
        params.validate().map_err(|e| ReachError::Corrupt {
            file: file.clone(),
            reason: e.to_string(),
        })?;
        let stats = BuildStats {
            samples: r.u64()?,
            free: r.u64()?,
            outside: r.u64()?,
            filled: 0,
        };
        let n = r.u64()? as usize;
        if n != params.cells() {
            return Err(ReachError::Corrupt {
                file,
                reason: format!("{n} entries, the parameters give {}", params.cells()),
            });
        }
        let data = r.take(n)?.to_vec();
        let sum = r.u64()?;
        if sum != fnv(&data, FNV_OFFSET) {
            return Err(ReachError::Corrupt {
                file,
                reason: "checksum of the entries does not match".into(),
            });
        }
        let mut g = ReachabilityGrid {
            robot,
            group,
            base_link,
            tip_link,
            hash,
            dims: params.dims(),
            bins: CellBins::new(params.rot_bins, params.resolution),
            params,
            stats,
            max_entry: 0,
            inv_max: 0.0,
            data,
            occupied: Vec::new(),
            positions: Vec::new(),
        };
        g.finish();
        Ok(g)
    }

    /// Reads a grid and checks that it belongs to `robot`'s chain group `group` with unchanged
    /// kinematics; with `expect`, also that it was built with exactly these parameters.
    pub fn load(
        path: &Path,
        robot: &Robot,
        group: &str,
        expect: Option<&GridParams>,
    ) -> Result<ReachabilityGrid, ReachError> {
        let g = ReachabilityGrid::load_unchecked(path)?;
        let file = path.display().to_string();
        g.check(robot, group).map_err(|e| match e {
            ReachError::Mismatch {
                what,
                found,
                expected,
                ..
            } => ReachError::Mismatch {
                file: file.clone(),
                what,
                found,
                expected,
            },
            ReachError::KinematicsChanged {
                chain,
                found,
                expected,
                ..
            } => ReachError::KinematicsChanged {
                file: file.clone(),
                chain,
                found,
                expected,
            },
            e => e,
        })?;
        if let Some(p) = expect {
            let diff = g.params.diff(p);
            if !diff.is_empty() {
                return Err(ReachError::ParamsMismatch { file, diff });
            }
        }
        Ok(g)
    }

    /// Checks that this grid belongs to `robot`'s chain group `group` with unchanged kinematics.
    pub fn check(&self, robot: &Robot, group: &str) -> Result<(), ReachError> {
        let mism = |what: &'static str, found: &str, expected: &str| ReachError::Mismatch {
            file: "(in memory)".into(),
            what,
            found: found.to_string(),
            expected: expected.to_string(),
        };
        if self.robot != robot.name {
            return Err(mism("robot", &self.robot, &robot.name));
        }
        if self.group != group {
            return Err(mism("chain group", &self.group, group));
        }
        let chain = Chain::from_group(robot, group).ok_or_else(|| ReachError::NoChain {
            robot: robot.name.clone(),
            group: group.to_string(),
        })?;
        let h = chain_hash(robot, &chain);
        if h != self.hash {
            return Err(ReachError::KinematicsChanged {
                file: "(in memory)".into(),
                chain: format!("{}→{}", self.base_link, self.tip_link),
                found: self.hash,
                expected: h,
            });
        }
        Ok(())
    }
}

impl ReachabilityMap for ReachabilityGrid {
    #[inline]
    fn probability(&self, pose_in_base: &Pose) -> f64 {
        ReachabilityGrid::probability(self, pose_in_base)
    }

    fn probabilities(&self, frame: &Pose, tcps: &[Pose], out: &mut [f64]) {
        // Positions first: most fall in empty voxels, and only the others need their rotation
        // composed and binned.
        for (t, o) in tcps.iter().zip(out.iter_mut()) {
            let p = frame.transform_point(&t.translation.vector.into()).coords;
            *o = self.entry_parts(&p, || frame.rotation * t.rotation) as f64 * self.inv_max;
        }
    }

    fn voxel_steps(&self) -> [f64; 6] {
        let b = self.params.rot_bins as f64;
        let r = self.params.resolution;
        [r, r, r, 2.0 * PI / b, PI / b, 2.0 * PI / b]
    }
}

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
    file: &'a str,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], ReachError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.b.len());
        match end {
            Some(e) => {
                let s = &self.b[self.at..e];
                self.at = e;
                Ok(s)
            }
            None => Err(ReachError::Corrupt {
                file: self.file.to_string(),
                reason: format!("file ends at byte {} (needed {} more)", self.b.len(), n),
            }),
        }
    }
    fn arr<const N: usize>(&mut self) -> Result<[u8; N], ReachError> {
        let s = self.take(N)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }
    fn u32(&mut self) -> Result<u32, ReachError> {
        Ok(u32::from_le_bytes(self.arr()?))
    }
    fn u64(&mut self) -> Result<u64, ReachError> {
        Ok(u64::from_le_bytes(self.arr()?))
    }
    fn f64(&mut self) -> Result<f64, ReachError> {
        Ok(f64::from_le_bytes(self.arr()?))
    }
    fn string(&mut self) -> Result<String, ReachError> {
        let n = self.u32()? as usize;
        if n > 4096 {
            return Err(ReachError::Corrupt {
                file: self.file.to_string(),
                reason: format!("string of {n} bytes in the header"),
            });
        }
        String::from_utf8(self.take(n)?.to_vec()).map_err(|_| ReachError::Corrupt {
            file: self.file.to_string(),
            reason: "header string is not UTF-8".into(),
        })
    }
}
