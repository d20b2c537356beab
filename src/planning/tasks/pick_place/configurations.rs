//! The grasp, exchange and place configurations q_r^g, q_r^e, q_r^p (paper 003 §V-C).
//!
//! "All robot joints are sampled except the arm(s) grasping the object (one arm for grasp and
//! place configurations and both for exchange configuration), that are computed using the
//! inverse kinematics characterized by the grasps and the object position. Then, a collision
//! test is performed on the generated configuration." Here:
//!
//! - **Sampled joints**: the torso ([`super::PickPlaceProblem::torso`]), uniformly within a
//!   window of ± `torso_window` × its range about the rest configuration q_r^i, clamped into
//!   the limits; sample 0 is q_r^i's torso itself. The same seeded samples serve every grasp, so
//!   a search is deterministic per seed. The free arm keeps its rest values (the free-arm score
//!   below measures how far the torso moved it); every other variable keeps q_r^i's value.
//! - **Grasping arms**: the TCP target is the object pose × the grasp's palm pose × the fixed
//!   palm → TCP offset, in the arm's base-link frame at the sampled torso; the analytic S-R-S IK
//!   ([`crate::kinematics::SrsArm::solve_enumerate`], `psi_steps` swivel angles) gives the
//!   solutions within the joint limits, nearest to the rest arm configuration first; at most
//!   `solutions_per_sample` of them are checked per torso sample (for the exchange, per arm:
//!   their pairs).
//! - **Fingers**: the grasp's finger joint values from the grasp list (computed there by the
//!   fingers' numeric IK, 003 §IV-A).
//! - **Collision test**: the exact checker ([`crate::collision::ExactChecker`]) on the robot,
//!   the obstacles and the object **attached** to the holding hand's palm (grasp and exchange:
//!   the pick hand; place: the place hand), the grasping hands' links allowed to touch it (their
//!   contact was validated by the grasp list, 003 §IV-A); every other pair is tested, the two
//!   hands against each other included.
//!
//! **Exchange**: object poses from [`super::exchange_poses`] around the exchange position, both
//! arms solved at each torso sample.
//!
//! **Configuration score** (003 §V-C, the robot-configuration term of the double-grasp score):
//! the grasping-arm term, the cosine between the grasp's approach direction and the direction
//! from the robot base to the object ([`crate::grasp::double_grasp::approach_score`]), minus the
//! free-arm terms: the free arm's joint distance to its rest values (rad, Euclidean), the height
//! difference of its wrist to the rest configuration's (m) and its wrist's distance to the torso
//! plane (the vertical plane through the two shoulders, m). [`key_configurations`] ranks the
//! complete double grasps it finds by 003 §IV-B's score with these configuration scores:
//! normalised min quality + normalised min configuration score (grasp and place).
//!
//! **Order** (003 §VI): single-grasp configurations of each hand first (grasps in list order,
//! best quality first, until `single_keep` have one or `max_single` were tried), then the double
//! grasps among those grasps ([`crate::grasp::double_grasp::double_grasps`]: environment at both
//! poses, hand–hand collision, 003 §IV-B score), best first, each tried for an exchange
//! configuration.
//!
//! Bounded: every search is bounded by the sample counts (torso samples, swivel angles,
//! solutions, exchange poses, grasps, double grasps), so a pose out of reach ends in
//! [`PickPlaceError::Unreachable`] naming the pose and the hand, not in a timeout.

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::exchange::{exchange_poses, ExchangeGrid, ExchangeParams};
use super::{ArmHand, PickPlaceError, PickPlaceProblem};
use crate::collision::{AttachedBody, CollisionChecker, CollisionWorld, ExactChecker};
use crate::geometry::Pose;
use crate::grasp::double_grasp::{
    approach_score, double_grasps, hand_free_of, DoubleGrasp, DoubleGraspParams, Environment,
};
use crate::grasp::{GraspList, SingleGrasp};
use crate::kinematics::SolutionOrder;

/// Bounds and seed of the configuration search.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ConfigParams {
    /// Torso samples per grasp (sample 0: the rest torso).
    pub torso_samples: usize,
    /// Half-width of the torso sampling window, as a fraction of each joint's range.
    pub torso_window: f64,
    /// Swivel angles enumerated by the S-R-S IK.
    pub psi_steps: usize,
    /// IK solutions checked per arm and torso sample (nearest to the rest arm first).
    pub solutions_per_sample: usize,
    /// Exchange object poses tried per double grasp and round.
    pub exchange_samples: usize,
    /// Rounds of exchange poses: when no double grasp has an exchange configuration, the
    /// double grasps are tried again with new exchange poses (round 0: the first poses), up to
    /// this many rounds, before the search fails. Only a search that would fail pays for them.
    pub exchange_rounds: usize,
    /// Most grasps of a list searched for a single-grasp configuration (best first).
    pub max_single: usize,
    /// Single-grasp configurations gathered per hand before the double grasps.
    pub single_keep: usize,
    /// Most double grasps tried (best first).
    pub max_double_grasps: usize,
    /// Complete double grasps (grasp, exchange and place configurations found) gathered before
    /// the best one by the 003 §IV-B score is chosen.
    pub accept: usize,
    pub exchange: ExchangeParams,
    pub seed: u64,
}

impl Default for ConfigParams {
    /// 16 torso samples in ± 10 % of each range, 12 swivel angles, 4 solutions, 8 exchange
    /// poses in up to 4 rounds, 6 single-grasp configurations per hand out of at most 200 grasps, 24 double
    /// grasps, 2 accepted, seed 1.
    fn default() -> Self {
        ConfigParams {
            torso_samples: 16,
            torso_window: 0.1,
            psi_steps: 12,
            solutions_per_sample: 4,
            exchange_samples: 8,
            exchange_rounds: 4,
            max_single: 200,
            single_keep: 6,
            max_double_grasps: 24,
            accept: 2,
            exchange: ExchangeParams::default(),
            seed: 1,
        }
    }
}

impl ConfigParams {
    pub fn validate(&self) -> Result<(), PickPlaceError> {
        let bad = |f: &str, r: String| {
            Err(PickPlaceError::Invalid {
                field: f.into(),
                reason: r,
            })
        };
        for (f, v, max) in [
            ("torso_samples", self.torso_samples, 10_000),
            ("psi_steps", self.psi_steps, 3600),
            ("solutions_per_sample", self.solutions_per_sample, 64),
            ("exchange_samples", self.exchange_samples, 10_000),
            ("exchange_rounds", self.exchange_rounds, 100),
            ("max_single", self.max_single, 1_000_000),
            ("single_keep", self.single_keep, 10_000),
            ("max_double_grasps", self.max_double_grasps, 100_000),
            ("accept", self.accept, 10_000),
        ] {
            if !(1..=max).contains(&v) {
                return bad(f, format!("must be in 1..={max}, got {v}"));
            }
        }
        if !(self.torso_window.is_finite() && (0.0..=1.0).contains(&self.torso_window)) {
            return bad(
                "torso_window",
                format!("must be in [0, 1], got {}", self.torso_window),
            );
        }
        self.exchange.validate()
    }
}

/// Counts of a search.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ConfigStats {
    /// Single-grasp configurations found per hand, double grasps among them.
    pub single_pick: usize,
    pub single_place: usize,
    pub double_grasps: usize,
    pub ik_calls: usize,
    pub ik_solutions: usize,
    pub collision_checks: usize,
    pub double_grasps_tried: usize,
    pub exchange_poses: usize,
    /// Grasps left out before their IK: the closed hand collides with the obstacles at the pose
    /// (003 §IV-B's environment filter) or the hand alone has no room there
    /// ([`HandRoom::hand_alone`]).
    #[serde(default)]
    pub hands_filtered: usize,
    /// Time of the single-grasp configurations of both hands (ms; 003 §VI: 4.2 s).
    #[serde(default)]
    pub single_ms: f64,
    /// Time of the double grasps and their exchange configurations (ms; 003 §VI: 2.6 s).
    #[serde(default)]
    pub double_ms: f64,
}

impl ConfigStats {
    /// The counts of two searches added (times: `self`'s).
    fn plus(&self, o: &ConfigStats) -> ConfigStats {
        ConfigStats {
            single_pick: self.single_pick + o.single_pick,
            single_place: self.single_place + o.single_place,
            double_grasps: self.double_grasps + o.double_grasps,
            ik_calls: self.ik_calls + o.ik_calls,
            ik_solutions: self.ik_solutions + o.ik_solutions,
            collision_checks: self.collision_checks + o.collision_checks,
            double_grasps_tried: self.double_grasps_tried + o.double_grasps_tried,
            exchange_poses: self.exchange_poses + o.exchange_poses,
            hands_filtered: self.hands_filtered + o.hands_filtered,
            ..*self
        }
    }
}

/// A grasp or place configuration: the grasp (index into its list), the object pose, the
/// robot configuration and its configuration score (module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SingleConfiguration {
    pub grasp: usize,
    pub object_pose: Pose,
    pub q: Vec<f64>,
    pub score: f64,
}

/// The three key configurations of a double grasp.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KeyConfigurations {
    /// The double grasp (indices into the pick and place lists) with its 003 §IV-B score
    /// recomputed from the configuration scores (module docs).
    pub double: DoubleGrasp,
    /// q_r^g (object at q_o^i, held by the pick hand).
    pub grasp: SingleConfiguration,
    /// q_r^e (object at q_o^e, both hands on it) and q_o^e.
    pub exchange: Vec<f64>,
    pub exchange_pose: Pose,
    /// q_r^p (object at q_o^f, held by the place hand).
    pub place: SingleConfiguration,
    /// Complete double grasps found (the chosen one is the best of them).
    pub complete: usize,
    pub stats: ConfigStats,
}

/// The hand motions on the object a key configuration must leave room for, asked by the search
/// of each configuration it would accept (after its collision test): a grasp whose hand cannot
/// close on the object there (some finger of every pre-shape hits the scene, the other hand or
/// the object) is not a usable key configuration. Grasps are indices into the lists the search
/// was given. The task answers with the very test its motion chain applies
/// ([`super::task`]); [`AnyHand`] admits everything (the configurations of 003 §V-C alone).
pub trait HandRoom {
    /// q_r^g: the pick hand can close on pick grasp `g`, the object resting at q_o^i.
    fn grasp(&mut self, g: usize, q: &[f64]) -> bool;
    /// q_r^e: held by pick grasp `a`, the place hand can close on place grasp `b`, and held by
    /// `b`, the pick hand can open from `a`.
    fn exchange(&mut self, a: usize, b: usize, q: &[f64]) -> bool;
    /// q_r^p: the place hand can open from place grasp `b`, the object resting at q_o^f.
    fn place(&mut self, b: usize, q: &[f64]) -> bool;
    /// Can `holder`'s hand have room on its grasp `g` at all, whatever the arm does: the part
    /// of [`HandRoom::grasp`] (pick) or [`HandRoom::place`] (place) that depends on the hand
    /// alone, its palm at the grasp's pose. A necessary condition of those two, asked once per
    /// grasp before any of its IK solutions; the default admits every grasp.
    fn hand_alone(&mut self, _holder: Holder, _g: usize) -> bool {
        true
    }
}

/// Admits every configuration ([`HandRoom`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct AnyHand;

impl HandRoom for AnyHand {
    fn grasp(&mut self, _: usize, _: &[f64]) -> bool {
        true
    }
    fn exchange(&mut self, _: usize, _: usize, _: &[f64]) -> bool {
        true
    }
    fn place(&mut self, _: usize, _: &[f64]) -> bool {
        true
    }
}

/// Which hand holds the object.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Holder {
    Pick,
    Place,
}

impl PickPlaceProblem {
    fn arm_hand(&self, h: Holder) -> (&ArmHand, &ArmHand) {
        match h {
            Holder::Pick => (&self.pick, &self.place),
            Holder::Place => (&self.place, &self.pick),
        }
    }

    /// The collision world of a key configuration: robot, obstacles, the object attached to
    /// `holder`'s palm by grasp `g`; `holder`'s links (and `also`'s, when both hands are on it)
    /// may touch it.
    pub fn held_world(
        &self,
        holder: &ArmHand,
        g: &SingleGrasp,
        also: Option<&ArmHand>,
    ) -> CollisionWorld {
        let mut w = CollisionWorld::single(self.robot.clone(), self.base);
        w.statics = self.obstacles.clone();
        let mut touch = holder.links.clone();
        if let Some(o) = also {
            touch.extend(o.links.iter().copied());
        }
        w.attached.push(AttachedBody {
            name: self.object_name.clone(),
            robot: 0,
            link: holder.hand.palm,
            rel: g.palm_pose().inverse(),
            shapes: self.object.clone(),
            touch,
        });
        w
    }

    /// The TCP target of grasp `g` with the object at `pose`, in the arm's base-link frame at
    /// robot configuration `q` (its torso).
    pub fn tcp_target(&self, ah: &ArmHand, g: &SingleGrasp, pose: &Pose, q: &[f64]) -> Pose {
        let tcp = pose * g.palm_pose() * ah.tip_in_palm;
        ah.base_pose(&self.robot, &self.base, q).inverse() * tcp
    }

    /// The torso samples of a search (module docs): sample 0 is q_r^i's torso.
    pub fn torso_samples(&self, params: &ConfigParams, seed: u64) -> Vec<Vec<f64>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..params.torso_samples)
            .map(|k| {
                self.torso
                    .iter()
                    .map(|&v| {
                        let rest = self.rest[v];
                        if k == 0 {
                            return rest;
                        }
                        let l = self.robot.var_limits(v);
                        let half = params.torso_window * (l.upper - l.lower) * 0.5;
                        let x = rest + rng.random_range(-1.0..=1.0) * half;
                        x.clamp(l.lower, l.upper)
                    })
                    .collect()
            })
            .collect()
    }

    /// The configuration score of `q` (module docs) for `holder` grasping by `g` at `pose`.
    pub fn configuration_score(
        &self,
        holder: Holder,
        g: &SingleGrasp,
        pose: &Pose,
        q: &[f64],
    ) -> f64 {
        let (ah, free) = self.arm_hand(holder);
        let base = self.base.translation.vector;
        let cos = approach_score(&ah.hand, g, pose, &self.object_centre, &base);
        let fr = free.arm.from_config(q);
        let rest = free.arm.from_config(&self.rest);
        let joint: f64 = fr
            .iter()
            .zip(&rest)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        let w = free.wrist(&self.robot, &self.base, q);
        let w0 = free.wrist(&self.robot, &self.base, &self.rest);
        let height = (w.z - w0.z).abs();
        let sa = ah.shoulder(&self.robot, &self.base, q);
        let sb = free.shoulder(&self.robot, &self.base, q);
        let plane = (sb - sa).cross(&Vector3::z());
        let plane_dist = match plane.try_normalize(1e-12) {
            Some(n) => n.dot(&(w - sa)).abs(),
            None => 0.0,
        };
        cos - joint - height - plane_dist
    }
}

/// Sets the hand's variables of `q` to grasp `g`'s finger values.
fn set_fingers(ah: &ArmHand, g: &SingleGrasp, q: &mut [f64]) {
    for (i, &v) in ah.hand.vars.iter().enumerate() {
        if let Some(x) = g.config.get(i) {
            q[v] = *x;
        }
    }
}

fn set_torso(p: &PickPlaceProblem, t: &[f64], q: &mut [f64]) {
    for (&v, &x) in p.torso.iter().zip(t) {
        q[v] = x;
    }
}

/// IK solutions of `ah` for grasp `g` at `pose` with the torso of `q`, nearest to the rest arm
/// first, at most `params.solutions_per_sample`.
fn arm_solutions(
    p: &PickPlaceProblem,
    ah: &ArmHand,
    g: &SingleGrasp,
    pose: &Pose,
    q: &[f64],
    params: &ConfigParams,
    stats: &mut ConfigStats,
) -> Vec<[f64; 7]> {
    let target = p.tcp_target(ah, g, pose, q);
    stats.ik_calls += 1;
    // The order needs no randomness; the RNG argument is unused for NearestTo.
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let mut sols = ah.arm.solve_enumerate(
        &target,
        params.psi_steps,
        SolutionOrder::NearestTo(ah.arm.from_config(&p.rest)),
        &mut rng,
    );
    stats.ik_solutions += sols.len();
    sols.truncate(params.solutions_per_sample);
    sols
}

/// True when every variable of `q` is within its limits.
pub fn within_limits(p: &PickPlaceProblem, q: &[f64]) -> bool {
    q.len() == p.robot.dof()
        && q.iter()
            .enumerate()
            .all(|(v, &x)| x.is_finite() && p.robot.var_limits(v).contains(x))
}

/// The first collision-free configuration of `holder` grasping by one of `grasps` (indices into
/// `list`, tried in order) with the object at `pose` (module docs), or the reason none exists
/// within the bounds. `pose_name` names the pose in the error ("initial", "final").
#[allow(clippy::too_many_arguments)]
pub fn single_configuration(
    p: &PickPlaceProblem,
    holder: Holder,
    list: &GraspList,
    grasps: &[usize],
    pose: &Pose,
    pose_name: &str,
    params: &ConfigParams,
    stats: &mut ConfigStats,
) -> Result<SingleConfiguration, PickPlaceError> {
    single_configuration_with(
        p,
        holder,
        list,
        grasps,
        pose,
        pose_name,
        params,
        stats,
        &mut AnyHand,
    )
}

/// [`single_configuration`] whose configurations must also leave `room` for the hand's motion
/// on the object ([`HandRoom::grasp`] for the pick hand, [`HandRoom::place`] for the place hand).
#[allow(clippy::too_many_arguments)]
pub fn single_configuration_with(
    p: &PickPlaceProblem,
    holder: Holder,
    list: &GraspList,
    grasps: &[usize],
    pose: &Pose,
    pose_name: &str,
    params: &ConfigParams,
    stats: &mut ConfigStats,
    room: &mut dyn HandRoom,
) -> Result<SingleConfiguration, PickPlaceError> {
    params.validate()?;
    let (ah, _) = p.arm_hand(holder);
    let torsos = p.torso_samples(params, params.seed);
    let before = *stats;
    // How far out of reach the TCP targets are (for the error).
    let mut nearest_gap = f64::INFINITY;
    for &gi in grasps {
        let Some(g) = list.grasps.get(gi) else {
            continue;
        };
        let mut checker: Option<ExactChecker> = None;
        for t in &torsos {
            let mut q = p.rest.clone();
            set_torso(p, t, &mut q);
            set_fingers(ah, g, &mut q);
            let target = p.tcp_target(ah, g, pose, &q);
            let gap =
                (target.translation.vector - ah.arm.shoulder_centre()).norm() - ah.tcp_reach();
            nearest_gap = nearest_gap.min(gap);
            if gap > 0.0 {
                continue;
            }
            for sol in arm_solutions(p, ah, g, pose, &q, params, stats) {
                ah.arm.to_config(&sol, &mut q);
                if !within_limits(p, &q) {
                    continue;
                }
                let c =
                    checker.get_or_insert_with(|| ExactChecker::new(&p.held_world(ah, g, None)));
                stats.collision_checks += 1;
                let roomy = |room: &mut dyn HandRoom, q: &[f64]| match holder {
                    Holder::Pick => room.grasp(gi, q),
                    Holder::Place => room.place(gi, q),
                };
                if c.is_free(&q) && roomy(room, &q) {
                    let score = p.configuration_score(holder, g, pose, &q);
                    return Ok(SingleConfiguration {
                        grasp: gi,
                        object_pose: *pose,
                        q,
                        score,
                    });
                }
            }
        }
    }
    let reason = if grasps.is_empty() {
        "no grasp of the hand's list is free of the environment there".to_string()
    } else if stats.ik_solutions == before.ik_solutions {
        if nearest_gap > 0.0 {
            format!("every TCP target lies beyond the arm's reach (nearest by {nearest_gap:.3} m)")
        } else {
            "no IK solution within the joint limits".to_string()
        }
    } else {
        "every IK solution collides".to_string()
    };
    Err(PickPlaceError::Unreachable {
        pose: pose_name.to_string(),
        hand: ah.hand.group.clone(),
        reason,
        grasps: grasps.len(),
        torso: torsos.len(),
        ik: stats.ik_solutions - before.ik_solutions,
        checks: stats.collision_checks - before.collision_checks,
    })
}

/// An exchange configuration for grasps `a` (pick list) and `b` (place list): the first
/// collision-free one over the exchange poses × torso samples (module docs).
pub fn exchange_configuration(
    p: &PickPlaceProblem,
    grid: &ExchangeGrid,
    a: &SingleGrasp,
    b: &SingleGrasp,
    params: &ConfigParams,
    seed: u64,
    stats: &mut ConfigStats,
) -> Option<(Vec<f64>, Pose)> {
    exchange_configuration_with(
        p,
        grid,
        (a, 0),
        (b, 0),
        params,
        (seed, 0),
        stats,
        &mut AnyHand,
    )
}

/// [`exchange_configuration`] whose configurations must also leave `room` for the hands'
/// motions on the object ([`HandRoom::exchange`]); `a` and `b` with their indices in the lists
/// `room` knows. Round `r` of a seed tries the exchange poses after those of rounds 0..r (one
/// stream of poses per seed, so no pose is tried twice).
#[allow(clippy::too_many_arguments)]
pub fn exchange_configuration_with(
    p: &PickPlaceProblem,
    grid: &ExchangeGrid,
    (a, ia): (&SingleGrasp, usize),
    (b, ib): (&SingleGrasp, usize),
    params: &ConfigParams,
    (seed, round): (u64, usize),
    stats: &mut ConfigStats,
    room: &mut dyn HandRoom,
) -> Option<(Vec<f64>, Pose)> {
    let n = params.exchange_samples;
    let poses =
        exchange_poses(p, grid, a, b, &params.exchange, n * (round + 1), seed).split_off(n * round);
    let torsos = p.torso_samples(params, seed);
    let mut checker: Option<ExactChecker> = None;
    for pose in &poses {
        stats.exchange_poses += 1;
        for t in &torsos {
            let mut q = p.rest.clone();
            set_torso(p, t, &mut q);
            set_fingers(&p.pick, a, &mut q);
            set_fingers(&p.place, b, &mut q);
            let sa = arm_solutions(p, &p.pick, a, pose, &q, params, stats);
            if sa.is_empty() {
                continue;
            }
            let sb = arm_solutions(p, &p.place, b, pose, &q, params, stats);
            for x in &sa {
                for y in &sb {
                    p.pick.arm.to_config(x, &mut q);
                    p.place.arm.to_config(y, &mut q);
                    if !within_limits(p, &q) {
                        continue;
                    }
                    let c = checker.get_or_insert_with(|| {
                        ExactChecker::new(&p.held_world(&p.pick, a, Some(&p.place)))
                    });
                    stats.collision_checks += 1;
                    if c.is_free(&q) && room.exchange(ia, ib, &q) {
                        return Some((q, *pose));
                    }
                }
            }
        }
    }
    None
}

/// Single-grasp configurations of `holder` at `pose` (003 §VI: "the planner generates 4 (right)
/// and 7 (left) collision-free single grasps configurations"): the grasps of `list` in its order
/// (best quality first), each searched by [`single_configuration`], until `single_keep` have one
/// or `max_single` grasps were tried. Errors when none has one.
#[allow(clippy::too_many_arguments)]
pub fn single_configurations(
    p: &PickPlaceProblem,
    holder: Holder,
    list: &GraspList,
    pose: &Pose,
    pose_name: &str,
    params: &ConfigParams,
    stats: &mut ConfigStats,
    room: &mut dyn HandRoom,
) -> Result<Vec<SingleConfiguration>, PickPlaceError> {
    let mut out = Vec::new();
    let mut last = None;
    let tried = list.grasps.len().min(params.max_single);
    let before = *stats;
    let (ah, _) = p.arm_hand(holder);
    let env = Environment::new(&p.obstacles);
    for gi in 0..tried {
        // The hand's own tests first: they hold for every torso sample and IK solution alike.
        let g = &list.grasps[gi];
        if !hand_free_of(&ah.hand, &g.config, &(pose * g.palm_pose()), &env)
            || !room.hand_alone(holder, gi)
        {
            stats.hands_filtered += 1;
            continue;
        }
        match single_configuration_with(
            p,
            holder,
            list,
            &[gi],
            pose,
            pose_name,
            params,
            stats,
            &mut *room,
        ) {
            Ok(c) => {
                out.push(c);
                if out.len() >= params.single_keep {
                    break;
                }
            }
            Err(e) => last = Some(e),
        }
    }
    if out.is_empty() {
        let reason = match last {
            Some(PickPlaceError::Unreachable { reason, .. }) => reason,
            None if tried > 0 => "the hand collides with the obstacles, or has no room to close \
                                  or open, at every grasp of its list"
                .into(),
            _ => "the hand's grasp list is empty".into(),
        };
        return Err(PickPlaceError::Unreachable {
            pose: pose_name.to_string(),
            hand: ah.hand.group.clone(),
            reason,
            grasps: tried,
            torso: params.torso_samples,
            ik: stats.ik_solutions - before.ik_solutions,
            checks: stats.collision_checks - before.collision_checks,
        });
    }
    Ok(out)
}

/// `list` restricted to the grasps of `configs` (in their order).
fn sub_list(list: &GraspList, configs: &[SingleConfiguration]) -> GraspList {
    GraspList {
        grasps: configs
            .iter()
            .map(|c| list.grasps[c.grasp].clone())
            .collect(),
        ..list.clone()
    }
}

/// The grasp, exchange and place configurations of the best double grasp, in 003's order:
/// single-grasp configurations of both hands first ([`single_configurations`]), then the double
/// grasps among those grasps (003 §IV-B, [`double_grasps`]: environment, hand–hand collision,
/// score), tried best first, at most `max_double_grasps`, for an exchange configuration until
/// `accept` are complete; the best of those by the 003 §IV-B score with the configuration
/// scores (module docs) is returned.
pub fn key_configurations(
    p: &PickPlaceProblem,
    pick_list: &GraspList,
    place_list: &GraspList,
    grid: &ExchangeGrid,
    params: &ConfigParams,
) -> Result<KeyConfigurations, PickPlaceError> {
    key_configurations_with(
        p,
        pick_list,
        place_list,
        grid,
        params,
        [&mut AnyHand, &mut AnyHand],
    )
}

/// [`key_configurations`] whose every configuration also leaves room for the hands' motions on
/// the object ([`HandRoom`]): `rooms[0]` answers for the grasp and exchange configurations,
/// `rooms[1]` for the place configurations. The single-grasp configurations of the two hands
/// are searched at once (two independent searches, each deterministic per seed).
pub fn key_configurations_with(
    p: &PickPlaceProblem,
    pick_list: &GraspList,
    place_list: &GraspList,
    grid: &ExchangeGrid,
    params: &ConfigParams,
    rooms: [&mut (dyn HandRoom + Send); 2],
) -> Result<KeyConfigurations, PickPlaceError> {
    params.validate()?;
    let [room, place_room] = rooms;
    let t_single = std::time::Instant::now();
    let (mut pick_stats, mut place_stats) = (ConfigStats::default(), ConfigStats::default());
    let (picks, places) = rayon::join(
        || {
            single_configurations(
                p,
                Holder::Pick,
                pick_list,
                &p.initial,
                "initial",
                params,
                &mut pick_stats,
                &mut *room,
            )
        },
        || {
            single_configurations(
                p,
                Holder::Place,
                place_list,
                &p.final_pose,
                "final",
                params,
                &mut place_stats,
                &mut *place_room,
            )
        },
    );
    let (picks, places) = (picks?, places?);
    let mut stats = pick_stats.plus(&place_stats);
    stats.single_ms = t_single.elapsed().as_secs_f64() * 1e3;
    let t_double = std::time::Instant::now();
    let (pl, ll) = (sub_list(pick_list, &picks), sub_list(place_list, &places));
    let doubles = double_grasps(
        (&p.pick.hand, &pl),
        (&p.place.hand, &ll),
        &p.obstacles,
        &p.initial,
        &p.final_pose,
        &p.base.translation.vector,
        &DoubleGraspParams {
            max_pairs: picks.len() * places.len(),
            max_results: params.max_double_grasps,
        },
    );
    stats.single_pick = picks.len();
    stats.single_place = places.len();
    stats.double_grasps = doubles.grasps.len();
    let mut complete: Vec<(DoubleGrasp, Vec<f64>, Pose)> = Vec::new();
    'rounds: for round in 0..params.exchange_rounds {
        if !complete.is_empty() {
            break;
        }
        for (k, d) in doubles.grasps.iter().enumerate() {
            stats.double_grasps_tried += 1;
            let seed = params.seed ^ 0x9E37_79B9_7F4A_7C15u64.wrapping_mul(k as u64 + 1);
            if let Some((qe, pose)) = exchange_configuration_with(
                p,
                grid,
                (&pl.grasps[d.pick], picks[d.pick].grasp),
                (&ll.grasps[d.place], places[d.place].grasp),
                params,
                (seed, round),
                &mut stats,
                &mut *room,
            ) {
                complete.push((*d, qe, pose));
                if complete.len() >= params.accept {
                    break 'rounds;
                }
            }
        }
    }
    stats.double_ms = t_double.elapsed().as_secs_f64() * 1e3;
    if complete.is_empty() {
        return Err(PickPlaceError::NoExchange(format!(
            "{} and {} single-grasp configurations, {} double grasps among them ({} pairs, {} hand \
             collisions), none with an exchange configuration ({} exchange poses, {} collision checks)",
            picks.len(),
            places.len(),
            doubles.grasps.len(),
            doubles.pairs_tested,
            doubles.hand_collisions,
            stats.exchange_poses,
            stats.collision_checks
        )));
    }
    // 003 §IV-B: normalised min quality + normalised min configuration score.
    let qs: Vec<f64> = complete.iter().map(|c| c.0.quality).collect();
    let cs: Vec<f64> = complete
        .iter()
        .map(|c| picks[c.0.pick].score.min(places[c.0.place].score))
        .collect();
    let norm = |v: &[f64], x: f64| {
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if hi > lo {
            (x - lo) / (hi - lo)
        } else {
            1.0
        }
    };
    let n = complete.len();
    let total = |i: usize| norm(&qs, qs[i]) + norm(&cs, cs[i]);
    let best = (0..n)
        .max_by(|&i, &j| total(i).total_cmp(&total(j)).then(j.cmp(&i)))
        .unwrap_or(0);
    let score = total(best);
    let (mut d, qe, pose) = complete.swap_remove(best);
    let grasp = picks[d.pick].clone();
    let place = places[d.place].clone();
    // Back to indices into the full lists.
    d.pick = grasp.grasp;
    d.place = place.grasp;
    d.configuration = cs[best];
    d.score = score;
    Ok(KeyConfigurations {
        double: d,
        grasp,
        exchange: qe,
        exchange_pose: pose,
        place,
        complete: n,
        stats,
    })
}
