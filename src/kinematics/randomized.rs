//! Randomized whole-body IK for a chain "free joints + 7-DoF S-R-S arm" (paper 000 = Vahrenkamp
//! et al. 2009, §II-A and §II-D: the 10-DoF hip + arm IK of ARMAR-III), optionally sped up by a
//! reachability space (§II-B), and the gradient ascent in reachability space (§II-C).
//!
//! Each *try* samples the free joints (e.g. the three hip joints) uniformly within their limits,
//! transforms every grasp target (object pose · grasp TCP) into the frame of the arm base, and —
//! with a reachability map — calls the analytic arm IK ([`SrsArm::solve`], random swivel angle ψ)
//! only for the grasps whose voxel entry lies above a threshold, best first; without a map, for all
//! grasps in random order. Every arm solution is handed to a validity callback (self- and
//! environment collision). The search stops after a number of tries with
//! [`RandomizedIkError::NoSolution`].
//!
//! To stay probabilistically complete (000 §II-C, last paragraph) the reachability filter is
//! applied only with probability [`RandomizedIkSettings::reach_probability`]; in the other tries
//! one random grasp goes to the analytic IK unfiltered.
//!
//! This module knows nothing of collision checking or of the reachability grid's storage: both come
//! in through the [`ReachabilityMap`] trait and a validity closure (`reachability` supplies them).

use std::f64::consts::PI;
use std::sync::Arc;

use rand::Rng;
use thiserror::Error;

use super::chain::Chain;
use super::fk::FkPath;
use super::srs::{SrsArm, SrsError};
use crate::geometry::Pose;
use crate::model::Robot;

/// A reachability space: the probability that an IK query for a TCP pose (given in the frame of
/// the arm chain's base) succeeds (000 §II-B).
pub trait ReachabilityMap: Send + Sync {
    /// Probability in [0, 1] for a TCP pose in the chain-base frame (0 outside the map).
    fn probability(&self, pose_in_base: &Pose) -> f64;
    /// The probability of `frame · t` for every TCP pose `t` of `tcps`, into `out` (same
    /// length). Implementations may batch: the grid finds every cell first and then reads them,
    /// so the (cache-missing) memory loads overlap.
    fn probabilities(&self, frame: &Pose, tcps: &[Pose], out: &mut [f64]) {
        for (o, t) in out.iter_mut().zip(tcps) {
            *o = self.probability(&(frame * t));
        }
    }
    /// Extent of one voxel in (x, y, z, roll, pitch, yaw): m and rad.
    fn voxel_steps(&self) -> [f64; 6];
}

/// Counters of one query.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct IkCounters {
    /// Samples of the free parameters.
    pub tries: u64,
    /// Reachability lookups.
    pub reach_lookups: u64,
    /// Analytic arm-IK queries: one per (try, grasp) handed to the arm solver, which enumerates
    /// up to [`RandomizedIkSettings::psi_samples`] swivel angles (as the ARMAR-III solver of 000
    /// §II-A "computes all possible elbow positions").
    pub ik_calls: u64,
    /// Single-ψ solves ([`SrsArm::solve`]) made by those queries.
    pub psi_solves: u64,
    /// Arm solutions returned by those calls.
    pub ik_solutions: u64,
    /// Configurations handed to the validity (collision) check, object-pose checks included.
    pub collision_checks: u64,
    /// Moves of the gradient ascent in reachability space (000 §II-C).
    pub gradient_steps: u64,
    /// Tries whose sampled base pose was rejected before any arm was solved (IkDualArm's
    /// base test, [`crate::reachability::inverse::ik_dual_arm_filtered`]).
    pub rejected_bases: u64,
}

impl IkCounters {
    /// Adds another query's counters.
    pub fn add(&mut self, o: &IkCounters) {
        self.tries += o.tries;
        self.reach_lookups += o.reach_lookups;
        self.ik_calls += o.ik_calls;
        self.psi_solves += o.psi_solves;
        self.ik_solutions += o.ik_solutions;
        self.collision_checks += o.collision_checks;
        self.gradient_steps += o.gradient_steps;
        self.rejected_bases += o.rejected_bases;
    }
}

/// Why a randomized IK query failed or could not start.
#[derive(Debug, Clone, Error)]
pub enum RandomizedIkError {
    #[error("no solution after {tries} tries ({} analytic IK calls, {} collision checks)", counters.ik_calls, counters.collision_checks)]
    NoSolution { tries: u64, counters: IkCounters },
    #[error("robot '{robot}' has no chain group '{group}'")]
    NoChain { robot: String, group: String },
    #[error("chain '{group}' has {found} movable joints; a randomized IK chain needs the 7 arm joints last and may have free joints before them")]
    ShortChain { group: String, found: usize },
    #[error("the last 7 joints of chain '{group}': {source}")]
    NotSrs {
        group: String,
        #[source]
        source: Box<SrsError>,
    },
    #[error("the query has no grasps")]
    NoGrasps,
    #[error("start configuration has {found} values, the robot has {expected} variables")]
    BadStart { found: usize, expected: usize },
    #[error("non-finite object pose or grasp")]
    BadTarget,
    #[error("chains '{a}' and '{b}' do not share their free joints: {reason}")]
    Incompatible {
        a: String,
        b: String,
        reason: String,
    },
}

/// Parameters of the randomized search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RandomizedIkSettings {
    /// Samples of the free parameters before giving up.
    pub max_tries: u64,
    /// The analytic IK is called for a grasp only if its reachability entry is above this.
    pub threshold: f64,
    /// Probability that a try uses the reachability filter (< 1 keeps the solver probabilistically
    /// complete, 000 §II-C); ignored without a map.
    pub reach_probability: f64,
    /// Swivel angles ψ enumerated per arm-IK query (evenly spaced from a random offset; the query
    /// stops at the first ψ with solutions).
    pub psi_samples: u32,
    /// Probability of a gradient ascent on a free object pose (dual-arm IK, 000 §II-C).
    pub gradient_probability: f64,
    /// Largest number of voxel moves of one ascent.
    pub gradient_max_steps: u32,
}

impl Default for RandomizedIkSettings {
    fn default() -> Self {
        RandomizedIkSettings {
            max_tries: 20_000,
            threshold: 0.0,
            reach_probability: 0.98,
            psi_samples: 8,
            gradient_probability: 0.5,
            gradient_max_steps: 20,
        }
    }
}

/// A grasp query: reach one of `grasps` on an object at `object_pose`.
#[derive(Debug, Clone, Copy)]
pub struct GraspQuery<'a> {
    /// World pose of the robot's root link.
    pub robot_base: Pose,
    /// World pose of the object.
    pub object_pose: Pose,
    /// TCP poses in the object frame (a grasp set).
    pub grasps: &'a [Pose],
    /// Full robot configuration giving every joint outside the chain.
    pub start: &'a [f64],
}

/// A configuration reaching one grasp.
#[derive(Debug, Clone, PartialEq)]
pub struct IkSolution {
    /// Full robot configuration.
    pub config: Vec<f64>,
    /// Index into the query's grasps.
    pub grasp: usize,
    pub counters: IkCounters,
}

/// The split of a chain into free joints and a final S-R-S arm.
#[derive(Debug, Clone)]
pub struct ArmChain {
    pub group: String,
    pub chain: Chain,
    pub arm: SrsArm,
    /// The link the arm chain starts at (frame of its reachability map).
    pub arm_base: usize,
    /// Variables of the chain before the arm (sampled).
    pub free_vars: Vec<usize>,
    /// FK of `arm_base` alone (it moves with the free joints).
    pub base_path: FkPath,
}

impl ArmChain {
    /// Splits SRDF chain group `group` (e.g. `torso_right_arm`: hip 3 + arm 7).
    pub fn new(robot: &Robot, group: &str) -> Result<ArmChain, RandomizedIkError> {
        let chain = Chain::from_group(robot, group).ok_or_else(|| RandomizedIkError::NoChain {
            robot: robot.name.clone(),
            group: group.to_string(),
        })?;
        let movable: Vec<usize> = chain
            .joints
            .iter()
            .copied()
            .filter(|&j| robot.joints[j].is_movable())
            .collect();
        if movable.len() < 7 {
            return Err(RandomizedIkError::ShortChain {
                group: group.to_string(),
                found: movable.len(),
            });
        }
        let first_arm = movable[movable.len() - 7];
        let arm_base = robot.joints[first_arm].parent;
        let arm_chain = Chain::new(robot, arm_base, chain.tip_link).ok_or_else(|| {
            RandomizedIkError::NoChain {
                robot: robot.name.clone(),
                group: group.to_string(),
            }
        })?;
        let arm = SrsArm::new(robot, &arm_chain).map_err(|source| RandomizedIkError::NotSrs {
            group: group.to_string(),
            source: Box::new(source),
        })?;
        let free_vars = chain
            .vars
            .iter()
            .copied()
            .filter(|v| !arm.vars().contains(v))
            .collect();
        Ok(ArmChain {
            group: group.to_string(),
            chain,
            arm,
            arm_base,
            free_vars,
            base_path: FkPath::new(robot, arm_base),
        })
    }
}

/// The swivel-angle sweep both arm-IK queries share: the analytic arm IK for `target` (arm-base
/// frame) at up to `psi_samples` angles ψ evenly spaced from a random offset; every ψ with
/// solutions hands them to `on`, and the sweep stops when `on` returns true (the result).
#[inline]
fn psi_sweep<R: Rng + ?Sized>(
    arm: &SrsArm,
    target: &Pose,
    psi_samples: u32,
    sols: &mut [[f64; 7]; 8],
    counters: &mut IkCounters,
    rng: &mut R,
    mut on: impl FnMut(&[[f64; 7]], &mut IkCounters, &mut R) -> bool,
) -> bool {
    let k = psi_samples.max(1);
    let psi0 = rng.random_range(-PI..PI);
    counters.ik_calls += 1;
    let target = arm.prepare(target);
    for i in 0..k {
        let mut psi = psi0 + 2.0 * PI * i as f64 / k as f64;
        if psi >= PI {
            psi -= 2.0 * PI;
        }
        counters.psi_solves += 1;
        let n = arm.solve_prepared(&target, psi, sols);
        if n == 0 {
            continue;
        }
        counters.ik_solutions += n as u64;
        if on(&sols[..n], counters, rng) {
            return true;
        }
    }
    false
}

/// The analytic arm IK for `target` (arm-base frame) at up to `psi_samples` swivel angles evenly
/// spaced from a random offset: the solutions (into `sols`) of the first ψ that has any; 0 when
/// none has.
#[inline]
pub(crate) fn solve_psi<R: Rng + ?Sized>(
    arm: &SrsArm,
    target: &Pose,
    psi_samples: u32,
    sols: &mut [[f64; 7]; 8],
    counters: &mut IkCounters,
    rng: &mut R,
) -> usize {
    let mut found = 0;
    psi_sweep(arm, target, psi_samples, sols, counters, rng, |s, _, _| {
        found = s.len();
        true
    });
    found
}

/// One analytic arm-IK query: solves the arm for `target` (arm-base frame) at `psi_samples` swivel
/// angles evenly spaced from a random offset and hands each solution of every ψ that has any
/// (random order within a ψ) to `valid`, up to the first accepted one; true when one was
/// accepted (left in `q`).
#[inline]
pub(crate) fn try_arm<R: Rng + ?Sized>(
    arm: &SrsArm,
    target: &Pose,
    psi_samples: u32,
    q: &mut [f64],
    counters: &mut IkCounters,
    rng: &mut R,
    mut valid: impl FnMut(&[f64]) -> bool,
) -> bool {
    let mut sols = [[0.0; 7]; 8];
    psi_sweep(
        arm,
        target,
        psi_samples,
        &mut sols,
        counters,
        rng,
        |s, counters, rng| {
            let n = s.len();
            let off = rng.random_range(0..n);
            (0..n).any(|k| {
                arm.to_config(&s[(off + k) % n], q);
                counters.collision_checks += 1;
                valid(q)
            })
        },
    )
}

/// Randomized IK of one "free joints + S-R-S arm" chain (000 §II-A, §II-D).
#[derive(Debug, Clone)]
pub struct RandomizedIk {
    robot: Arc<Robot>,
    split: ArmChain,
}

impl RandomizedIk {
    /// The solver for SRDF chain group `group` (e.g. `torso_right_arm`).
    pub fn new(robot: Arc<Robot>, group: &str) -> Result<RandomizedIk, RandomizedIkError> {
        let split = ArmChain::new(&robot, group)?;
        Ok(RandomizedIk { robot, split })
    }

    /// The solver for an already split chain of `robot`.
    pub fn from_chain(robot: Arc<Robot>, split: ArmChain) -> RandomizedIk {
        RandomizedIk { robot, split }
    }

    pub fn robot(&self) -> &Arc<Robot> {
        &self.robot
    }

    /// The chain split (free variables, arm, arm base link).
    pub fn split(&self) -> &ArmChain {
        &self.split
    }

    /// World pose of the arm base for a configuration.
    #[inline]
    pub fn arm_base_pose(&self, robot_base: &Pose, q: &[f64]) -> Pose {
        robot_base * self.split.base_path.pose(q)
    }

    /// Searches a configuration that brings the TCP to one of the query's grasps and passes
    /// `valid(grasp, config)`. With `reach`, the analytic IK is called only for grasps whose
    /// voxel entry (target in the arm-base frame) is above `settings.threshold` (000 §II-B).
    pub fn solve<R: Rng + ?Sized>(
        &self,
        query: &GraspQuery<'_>,
        reach: Option<&dyn ReachabilityMap>,
        settings: &RandomizedIkSettings,
        rng: &mut R,
        mut valid: impl FnMut(usize, &[f64]) -> bool,
    ) -> Result<IkSolution, RandomizedIkError> {
        let robot = &*self.robot;
        if query.start.len() != robot.dof() {
            return Err(RandomizedIkError::BadStart {
                found: query.start.len(),
                expected: robot.dof(),
            });
        }
        if query.grasps.is_empty() {
            return Err(RandomizedIkError::NoGrasps);
        }
        let finite = |p: &Pose| {
            p.translation.vector.iter().all(|v| v.is_finite())
                && p.rotation.coords.iter().all(|v| v.is_finite())
        };
        if !finite(&query.robot_base)
            || !finite(&query.object_pose)
            || !query.grasps.iter().all(finite)
        {
            return Err(RandomizedIkError::BadTarget);
        }
        let targets: Vec<Pose> = query.grasps.iter().map(|g| query.object_pose * g).collect();
        let mut q = query.start.to_vec();
        let mut counters = IkCounters::default();
        let mut cand: Vec<(f64, usize)> = Vec::with_capacity(targets.len());
        let mut probs = vec![0.0; targets.len()];
        let arm = &self.split.arm;
        for _ in 0..settings.max_tries {
            counters.tries += 1;
            robot.sample_vars(&self.split.free_vars, &mut q, rng);
            let inv = self.arm_base_pose(&query.robot_base, &q).inverse();
            cand.clear();
            match reach {
                Some(map) if rng.random::<f64>() < settings.reach_probability => {
                    counters.reach_lookups += targets.len() as u64;
                    map.probabilities(&inv, &targets, &mut probs);
                    for (g, &p) in probs.iter().enumerate() {
                        if p > settings.threshold {
                            cand.push((p, g));
                        }
                    }
                    cand.sort_by(|a, b| b.0.total_cmp(&a.0));
                }
                Some(_) => cand.push((0.0, rng.random_range(0..targets.len()))),
                None => {
                    cand.extend((0..targets.len()).map(|g| (0.0, g)));
                    for i in (1..cand.len()).rev() {
                        cand.swap(i, rng.random_range(0..=i));
                    }
                }
            }
            for &(_, g) in &cand {
                let t = inv * targets[g];
                if try_arm(
                    arm,
                    &t,
                    settings.psi_samples,
                    &mut q,
                    &mut counters,
                    rng,
                    |q| valid(g, q),
                ) {
                    return Ok(IkSolution {
                        config: q,
                        grasp: g,
                        counters,
                    });
                }
            }
        }
        Err(RandomizedIkError::NoSolution {
            tries: counters.tries,
            counters,
        })
    }
}

/// Pose from position and URDF roll-pitch-yaw.
#[inline]
fn pose_from6(v: &[f64; 6]) -> Pose {
    Pose::from_parts(
        nalgebra::Translation3::new(v[0], v[1], v[2]),
        crate::geometry::quat_from_rpy([v[3], v[4], v[5]]),
    )
}

/// Gradient ascent in reachability space (000 §II-C): from `start`, repeatedly look at the 12
/// neighbouring voxels (± one voxel extent `steps[k]` in x, y, z, roll, pitch, yaw of the pose)
/// and move to the best one whose `score` is higher and that `free` accepts, until no neighbour is
/// better (a local maximum of the discretized distribution) or `max_steps` moves were made.
/// Returns the final pose, its score and the number of moves.
///
/// `score(pose, floor)` is asked only whether a pose beats `floor` (the current score; −∞ for the
/// start): a score that cannot exceed `floor` may be cut short and returned as any value
/// ≤ `floor`, since such a neighbour is never taken. Scores above `floor` must be exact.
pub fn gradient_ascent(
    start: &Pose,
    steps: &[f64; 6],
    max_steps: u32,
    mut score: impl FnMut(&Pose, f64) -> f64,
    mut free: impl FnMut(&Pose) -> bool,
) -> (Pose, f64, u32) {
    let t = start.translation.vector;
    let (r, p, y) = start.rotation.euler_angles();
    let mut cur = [t.x, t.y, t.z, r, p, y];
    let mut pose = *start;
    let mut best = score(start, f64::NEG_INFINITY);
    let mut moves = 0;
    while moves < max_steps {
        let mut nb: [(f64, [f64; 6]); 12] = [(f64::NEG_INFINITY, [0.0; 6]); 12];
        for k in 0..6 {
            for (s, sign) in [(0, 1.0), (1, -1.0)] {
                let mut v = cur;
                v[k] += sign * steps[k];
                nb[2 * k + s] = (score(&pose_from6(&v), best), v);
            }
        }
        nb.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut moved = false;
        for (sc, v) in nb {
            if sc <= best {
                break;
            }
            let cand = pose_from6(&v);
            if free(&cand) {
                cur = v;
                pose = cand;
                best = sc;
                moves += 1;
                moved = true;
                break;
            }
        }
        if !moved {
            break;
        }
    }
    (pose, best, moves)
}
