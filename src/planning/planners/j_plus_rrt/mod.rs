//! J+-RRT (Vahrenkamp et al. 2009 = paper 000, §IV-B, Algorithms 1–2) and dual-arm J+-RRT (000
//! §V-A, Algorithms 4–5): single-tree RRTs that need no IK solver. The goal is a *set* of TCP
//! poses; the tree is pulled toward them by Jacobian-pseudoinverse steps in task space.
//!
//! **J+-RRT** ([`JPlusRrt`], Alg. 1): one tree rooted at the start. Every iteration makes one
//! ordinary RRT EXTEND toward a uniform sample (Alg. 1 line 3, `ExtendRandomly`) and then, with
//! probability [`JPlusRrtSettings::p_extend_to_goal`], one `ExtendToGoal` (Alg. 2): a random
//! grasp is drawn, the tree node whose stored TCP pose is nearest to that grasp's target pose
//! (workspace metric `sqrt(|Δp|² + (w·Δθ)²)`, `w` = [`JPlusRrtSettings::angle_weight`]; every
//! node's TCP pose is kept in an array parallel to the tree, so this is a linear scan with no FK)
//! is moved toward the target by steps `Δq = J⁺(q) · LimitCartesianStepSize(Δp)`. Each step is
//! rejected — and the extension ends — when it leaves the joint limits or its motion collides
//! (Alg. 2 line 9); valid steps are added to the tree (line 11). When the TCP is within
//! `ThresholdCartesian` ([`JPlusRrtSettings::goal_position`], [`JPlusRrtSettings::goal_angle`])
//! of the target, the solution path root → node is built (line 13), pruned and re-validated by
//! the shared tree-planner finish (000 §IV-B: "standard path pruning techniques \[14\]").
//!
//! **Dual-arm J+-RRT** ([`DualArmJPlusRrt`], Alg. 4–5): the object is held by the giver hand
//! ([`crate::planning::problems::grasping::HandOffProblem`]); the goal is the receiver's TCP at one of its grasps on
//! the moving object. `DualArmExtendToGoal` draws a grasp, takes the node whose receiver TCP is
//! nearest that grasp on the held object (each node stores the receiver TCP in the object frame,
//! so again a linear scan), then alternately moves the receiver's TCP toward the grasp pose on the
//! object (Alg. 5, `MoveLeftArm`) and the giver's TCP toward the pose that brings the object's
//! grasp to the receiver's TCP (`MoveRightArm`), one limited J+ step each, every new
//! configuration checked and added to the tree, until the hand-off pose is reached.
//!
//! **The Jacobian** is the geometric Jacobian of the robot root → TCP chain, restricted to the
//! space's variables that move the TCP (hip joints included); in the dual-arm planner each arm's
//! step uses only the variables that move its TCP and not the other one's (joints the two chains
//! share, e.g. ARMAR's hip, move both hands rigidly and cannot change their relative pose).
//! `J⁺` is computed as damped least squares `Jᵀ (J Jᵀ + λ² I)⁻¹` with a 6 × 6 Cholesky
//! factorisation on the stack ([`JPlusRrtSettings::damping`]); nothing is allocated per step.
//!
//! **Exact convergence** (not in the paper, which stops at `ThresholdCartesian`): a returned path
//! must end *at* a grasp, so once the threshold is met the last state is snapped onto the target
//! by the analytic S-R-S arm IK ([`crate::kinematics::SrsArm::solve`], verified by FK to 1e-9) at
//! the arm's current swivel angle, choosing the solution nearest the current arm configuration
//! and keeping every other variable; should that give no solution (limits), undamped
//! pseudoinverse Newton iterations on the same variables converge to
//! [`JPlusRrtSettings::exact_tolerance`] instead. The snap is checked like any step (bounds and
//! motion validity) and added to the tree.
//!
//! **Where the paper is silent**: p_ExtendToGoal, the step limits, the threshold and the metric
//! weight are settings (defaults below). A goal extension also fails when a step does not reduce
//! the workspace distance (stuck at a singularity or oscillating), or after
//! [`JPlusRrtSettings::max_goal_steps`] steps. The paper excludes the chosen node from further
//! goal extensions after a failure (000 §V-A, last sentence); here the exclusion is per (node,
//! grasp) and also covers the nodes the failed extension added — their extension toward the
//! same grasp is deterministic and would fail the same way — in both planners. Two departures
//! measured on the kitchen wok (30 seeds): a step that would push a variable past its joint
//! limit locks that variable and is recomputed with the others (`Core::j_plus_step`; the
//! paper rejects it, and with rejection the tree stalled for seconds at nodes with a joint at a
//! limit), and translation and rotation of a step are limited separately (`limited_twist`).
//! Defaults p_ExtendToGoal 0.6, 2 cm / 8° per step, 0.3 m/rad: median ~15 ms there, against
//! ~220 ms with 0.1, 2 cm / 3°, 0.1 m/rad and a scaled twist.
//!
//! **Pre-grasp approach** (not in the paper): a grasp with a pre-grasp offset (the scene's
//! `pregrasp_offset`, TCP frame; `with_pregrasp_offsets`, set by `for_problem`) is approached
//! in two legs within one goal extension: the J+ steps first go to the pre-grasp pose (in the
//! dual-arm planner: the receiver's pre-grasp relation to the held object) and, once within
//! `ThresholdCartesian` of it, on to the grasp — the hand closes in along its approach
//! direction instead of sweeping through the object. The nearest node is still chosen by its
//! distance to the grasp. Kitchen wok, `bench planners` (100 runs): J+-RRT median 2.69 → 1.80
//! ms without and 2.44 → 1.88 ms with the obstacle (p95 31 → 16 and 21 → 10 ms).
//!
//! **Dual-arm defaults** ([`JPlusRrtSettings::dual_arm`]): a goal extension in every iteration
//! (p_ExtendToGoal 1), starting with probability 0.5 from the newest node of the tree
//! ([`JPlusRrtSettings::p_extend_from_new`]: the node this iteration's random extension added,
//! or the last node of the previous goal extension) instead of the nearest node. Why: on the
//! kitchen re-grasp the wok starts on the counter, almost every goal extension ends in its first
//! step (the wok tilting into the counter, the receiver's upper arm hitting the torso), and the
//! nearest nodes all sit in that crowded region however many are excluded, so a third of the
//! runs found nothing in 10 s. Starting half the extensions from the newest node spreads them
//! over the tree and lets them continue where the previous one stopped. Measured with `bench
//! planners --only "dual-arm J+" --runs 40 --time-limit 2` (80 runs, failures counted as ∞):
//! p_ExtendToGoal 0.3 alone: median 660 ms, 54 of 80 solved; + pre-grasp approach: 331 ms,
//! 53; + newest node 0.5: 159 ms, 71; + p_ExtendToGoal 1: 50 ms, 79 of 80; + 3 cm steps
//! (`max_step_position`, 2 cm in [`Default`]): 27 ms, 79 (2.5, 4 and 5 cm: 35, 41, 44 ms;
//! seeds 1000–1039: 72 → 53 ms with 3 cm; 12° instead of 8° steps: no change). Newest-node
//! probabilities 0.3 and 0.7 gave 97 and 63 ms; drawing the start among 64 or 256 random nodes,
//! children inheriting their parent's exclusions, letting the other arm go on alone when one
//! is blocked, and retrying a colliding step with the elbow swung (analytic IK at ψ ± 0.2–0.9
//! rad) did not help.
//!
//! **Restarts** ([`JPlusRrtSettings::restart_nodes`], dual-arm default 3 000, single-arm 0 =
//! never): once the tree holds more than that many nodes the search starts over from the start
//! with a new tree, the random stream going on (Luby et al. 1993: restarts cut heavy-tailed run
//! times): a slow run keeps growing its tree in the crowded region, and a fresh tree is a new
//! draw. With the default, 49 / 62 of the 100 bench runs below restart at least once (at most
//! 8 / 11 times), and the tree that finds the solution has a median of 1 188 / 1 716 nodes
//! (temporary per-run log of `start_tree_size` and `restarts`). `bench planners --only "dual-arm J+"`
//! (100 runs, without / with the obstacle): means 68 / 117 → 42 / 58 ms, p95 313 / 341 → 128 /
//! 148 ms, medians 27 / 45 → 26 / 43 ms; seeds 1001–1100: means 84 / 172 → 43 / 69 ms, medians
//! 28 / 56 → 29 / 45 ms. Restarting after 1 500, 2 000 or 5 000 nodes gave means 46 / 61,
//! 35 / 65 and 55 / 69 ms.

use std::time::Instant;

use nalgebra::{Matrix6, Matrix6xX, UnitQuaternion, Vector3, Vector6};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::collision::{CollisionWorld, FastChecker};
use crate::geometry::Pose;
use crate::kinematics::randomized::ArmChain;
use crate::kinematics::{pose_error, Chain, FkPath};
use crate::planning::base::validity::{space_checker, SegmentChecker, SpaceValidator};
use crate::planning::planners::rrt_connect::{extend, finish, stopped};
use crate::planning::problems::grasping::{Hand, HandOffProblem, ReachProblem};
use crate::planning::{
    JointSpace, PlanError, PlanResult, PlanStats, RrtConnectSettings, Termination, Tree, NO_PARENT,
};

mod dual_arm;
mod single;

pub use dual_arm::DualArmJPlusRrt;
pub use single::JPlusRrt;

/// Settings of [`JPlusRrt`] and [`DualArmJPlusRrt`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct JPlusRrtSettings {
    /// Probability of an `ExtendToGoal` after the random extension of an iteration (000 Alg. 1
    /// line 4, p_ExtendToGoal; the paper gives no value).
    pub p_extend_to_goal: f64,
    /// Probability that a goal extension starts from the newest node of the tree (the node this
    /// iteration's random extension added, else the last node of the previous goal extension),
    /// when it is not excluded for the grasp drawn, instead of the node nearest the grasp (000
    /// Alg. 2 line 2, Alg. 4 line 2). 0: always the nearest, as in the paper.
    pub p_extend_from_new: f64,
    /// Restart: once the tree holds more than this many nodes, the search starts over from the
    /// start with a new tree (the random stream goes on, so a seed still gives one answer).
    /// Run times of the dual-arm search are heavy-tailed, and a fresh tree cuts the tail
    /// (module docs). 0: never.
    pub restart_nodes: usize,
    /// Largest TCP translation of one Jacobian step, metres (`LimitCartesianStepSize`).
    pub max_step_position: f64,
    /// Largest TCP rotation of one Jacobian step, radians.
    pub max_step_angle: f64,
    /// `ThresholdCartesian`: a goal extension has reached its grasp once the TCP is this close in
    /// position (m) …
    pub goal_position: f64,
    /// … and in orientation (rad); the last state is then converged exactly (module docs).
    pub goal_angle: f64,
    /// Metres per radian in the workspace metric of the nearest-node search and of the progress
    /// check.
    pub angle_weight: f64,
    /// Damping λ of the least-squares pseudoinverse `Jᵀ (J Jᵀ + λ² I)⁻¹` (0: plain
    /// pseudoinverse, fails at singularities).
    pub damping: f64,
    /// Jacobian steps (dual-arm: step pairs) of one goal extension at most.
    pub max_goal_steps: u32,
    /// Position (m) and orientation (rad) tolerance of the Newton fallback of the exact
    /// convergence.
    pub exact_tolerance: f64,
    /// EXTEND range of the random extension, motion resolution, shortcutting and re-validation
    /// (as RRT-Connect; `direct_connect` is unused).
    pub rrt: RrtConnectSettings,
}

impl Default for JPlusRrtSettings {
    fn default() -> Self {
        JPlusRrtSettings {
            p_extend_to_goal: 0.6,
            p_extend_from_new: 0.0,
            restart_nodes: 0,
            max_step_position: 0.02,
            max_step_angle: 8f64.to_radians(),
            goal_position: 0.01,
            goal_angle: 2f64.to_radians(),
            angle_weight: 0.3,
            damping: 0.01,
            max_goal_steps: 200,
            exact_tolerance: 1e-9,
            rrt: RrtConnectSettings::default(),
        }
    }
}

impl JPlusRrtSettings {
    /// The defaults of the dual-arm planner ([`DualArmJPlusRrt`]): a goal extension in every
    /// iteration (p_ExtendToGoal 1), started from the newest node of the tree with probability
    /// 0.5 (`p_extend_from_new`), 3 cm J+ steps, a restart after 3 000 nodes
    /// (`restart_nodes`), the rest as [`Default`]. See the module docs for the measurements.
    pub fn dual_arm() -> JPlusRrtSettings {
        JPlusRrtSettings {
            p_extend_to_goal: 1.0,
            p_extend_from_new: 0.5,
            restart_nodes: 3000,
            max_step_position: 0.03,
            ..JPlusRrtSettings::default()
        }
    }

    fn check(&self) -> Result<(), PlanError> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        let bad = |what: &str, v: f64| {
            Err(PlanError::InvalidInput(format!(
                "{what} must be finite and > 0, got {v}"
            )))
        };
        let p = self.p_extend_to_goal;
        if !(p.is_finite() && p > 0.0 && p <= 1.0) {
            return Err(PlanError::InvalidInput(format!(
                "p_extend_to_goal must be in (0, 1], got {p}"
            )));
        }
        let p = self.p_extend_from_new;
        if !(0.0..=1.0).contains(&p) {
            return Err(PlanError::InvalidInput(format!(
                "p_extend_from_new must be in [0, 1], got {p}"
            )));
        }
        if (1..10).contains(&self.restart_nodes) {
            return Err(PlanError::InvalidInput(format!(
                "restart_nodes must be 0 (never) or >= 10, got {}",
                self.restart_nodes
            )));
        }
        for (what, v) in [
            ("max_step_position", self.max_step_position),
            ("max_step_angle", self.max_step_angle),
            ("goal_position", self.goal_position),
            ("goal_angle", self.goal_angle),
            ("angle_weight", self.angle_weight),
            ("exact_tolerance", self.exact_tolerance),
        ] {
            if !pos(v) {
                return bad(what, v);
            }
        }
        if !(self.damping.is_finite() && self.damping >= 0.0) {
            return Err(PlanError::InvalidInput(format!(
                "damping must be finite and >= 0, got {}",
                self.damping
            )));
        }
        if self.max_goal_steps == 0 {
            return Err(PlanError::InvalidInput("max_goal_steps must be > 0".into()));
        }
        Ok(())
    }
}

/// Newton iterations of the exact-convergence fallback at most.
const NEWTON_ITERATIONS: u32 = 30;

/// Rotation vector (axis · angle, angle in [0, π]) of a unit quaternion, accurate for tiny angles.
#[inline]
fn rotation_vector(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    let (w, v) = (q.scalar(), q.imag());
    let (w, v) = if w < 0.0 { (-w, -v) } else { (w, v) };
    let n = v.norm();
    if n < 1e-12 {
        v * (2.0 / w)
    } else {
        v * (2.0 * n.atan2(w) / n)
    }
}

/// `acos(x)` for `x` in \[0, 1\] by Abramowitz & Stegun 4.4.46 (`sqrt(1 − x)` times a degree-7
/// polynomial, error ≤ 2·10⁻⁸ rad): the nearest-node scan calls it once per node, and libm's
/// acos was 3–7 % of short and 23 % of long dual-arm J+ runs under perf.
#[inline]
fn acos_unit(x: f64) -> f64 {
    const A: [f64; 8] = [
        1.570_796_305_0,
        -0.214_598_801_6,
        0.088_978_987_4,
        -0.050_174_304_6,
        0.030_891_881_0,
        -0.017_088_125_6,
        0.006_670_090_1,
        -0.001_262_491_1,
    ];
    let p = A.iter().rev().fold(0.0, |acc, &a| acc * x + a);
    (1.0 - x).max(0.0).sqrt() * p
}

/// Workspace distance `sqrt(|Δp|² + (w·Δθ)²)` used to pick the node nearest a goal (the angle
/// from the quaternion dot product: cheap, precise enough to rank).
#[inline]
fn ws_distance_sq(a: &Pose, b: &Pose, w: f64) -> f64 {
    let dp = (a.translation.vector - b.translation.vector).norm_squared();
    let dot = a.rotation.coords.dot(&b.rotation.coords).abs().min(1.0);
    let th = 2.0 * acos_unit(dot);
    dp + w * w * th * th
}

/// The kinematics of one hand as the planners need them: TCP pose, the Jacobian of the space
/// variables that move it, and the analytic arm IK of its S-R-S arm.
struct HandKin {
    /// World pose of the robot's root link.
    base: Pose,
    offset: usize,
    dof: usize,
    /// The TCP link's pose alone.
    tip_path: FkPath,
    /// Robot root → TCP.
    chain: Chain,
    /// (Jacobian column, space dimension) of every variable a step may move.
    cols: Vec<(usize, usize)>,
    /// Per joint of `tip_path`: the Jacobian column of its variable (`usize::MAX`: none).
    tip_cols: Vec<usize>,
    arm: ArmChain,
    /// Space dimension of each of the 7 arm variables (`None`: some arm variable is not free in
    /// the space; the exact convergence then uses Newton iterations only).
    arm_dims: Option<[usize; 7]>,
    jac: Matrix6xX<f64>,
}

impl HandKin {
    /// The hand's kinematics in `space`; world variables in `exclude` are never moved by a step.
    fn new(
        world: &CollisionWorld,
        hand: &Hand,
        space: &JointSpace,
        exclude: &[usize],
    ) -> Result<HandKin, PlanError> {
        let placed = world.robots.get(hand.robot).ok_or_else(|| {
            PlanError::InvalidInput(format!("the world has no robot {}", hand.robot))
        })?;
        let robot = &placed.robot;
        let tip = hand.tcp_link();
        let mut root = tip;
        while let Some(j) = robot.links[root].parent_joint {
            root = robot.joints[j].parent;
        }
        let chain = Chain::new(robot, root, tip).ok_or_else(|| {
            PlanError::InvalidInput("internal: no chain from the robot root to the TCP".into())
        })?;
        let dim_of = |robot_var: usize| {
            let w = robot_var + placed.offset;
            if exclude.contains(&w) {
                None
            } else {
                space.vars().iter().position(|&v| v == w)
            }
        };
        let cols: Vec<(usize, usize)> = chain
            .vars
            .iter()
            .enumerate()
            .filter_map(|(c, &v)| dim_of(v).map(|d| (c, d)))
            .collect();
        if cols.is_empty() {
            return Err(PlanError::InvalidInput(format!(
                "no variable of the space moves the TCP of '{}'",
                hand.end_effector
            )));
        }
        let dims: Vec<usize> = hand
            .arm
            .arm
            .vars()
            .iter()
            .filter_map(|&v| dim_of(v))
            .collect();
        let arm_dims = <[usize; 7]>::try_from(dims.as_slice()).ok();
        let tip_path = FkPath::new(robot, tip);
        let tip_cols = tip_path.jacobian_columns(&chain.vars);
        Ok(HandKin {
            jac: Matrix6xX::zeros(chain.vars.len()),
            tip_cols,
            base: placed.base,
            offset: placed.offset,
            dof: robot.dof(),
            tip_path,
            chain,
            cols,
            arm: hand.arm.clone(),
            arm_dims,
        })
    }

    /// World pose of the TCP for world configuration `wq`.
    #[inline]
    fn tcp(&self, wq: &[f64]) -> Pose {
        self.base * self.tip_path.pose(&wq[self.offset..self.offset + self.dof])
    }

    /// The Jacobian at world configuration `wq` (robot root frame), kept for
    /// [`HandKin::dls_solve`]: the TCP path's frames as matrices with their sines and cosines
    /// batched ([`FkPath::jacobian_into`]; the chain's quaternion pass,
    /// [`crate::kinematics::Chain::jacobian_into`], gives the same to rounding and was 7 % of
    /// the dual-arm J+-RRT row).
    #[inline]
    fn update_jacobian(&mut self, wq: &[f64]) {
        let rq = &wq[self.offset..self.offset + self.dof];
        self.tip_path
            .jacobian_into(rq, &self.tip_cols, &mut self.jac);
    }

    /// [`HandKin::update_jacobian`] then [`HandKin::dls_solve`].
    #[inline]
    fn dls_step(
        &mut self,
        wq: &[f64],
        lin: &Vector3<f64>,
        ang: &Vector3<f64>,
        damping: f64,
        dq: &mut [f64],
    ) -> bool {
        self.update_jacobian(wq);
        self.dls_solve(lin, ang, damping, 0, dq)
    }

    /// One damped-least-squares step (000 Alg. 2 line 7, Alg. 5 line 4) with the Jacobian of
    /// the last [`HandKin::update_jacobian`]: writes into `dq` (space dimensions; zero outside
    /// the hand's columns and for the `locked` dimensions) the joint motion that moves the TCP
    /// by the world-frame twist (`lin`, `ang`) to first order. False when `J Jᵀ + λ² I` is
    /// singular.
    #[inline]
    fn dls_solve(
        &self,
        lin: &Vector3<f64>,
        ang: &Vector3<f64>,
        damping: f64,
        locked: u64,
        dq: &mut [f64],
    ) -> bool {
        // The Jacobian is in the robot root frame.
        let r = self.base.rotation.inverse();
        let (l, a) = (r * lin, r * ang);
        let e = Vector6::new(l.x, l.y, l.z, a.x, a.y, a.z);
        let mut m = Matrix6::<f64>::identity() * (damping * damping);
        let free = |d: usize| d >= 64 || locked & (1 << d) == 0;
        for &(c, d) in &self.cols {
            if free(d) {
                let j = self.jac.fixed_view::<6, 1>(0, c);
                m += j * j.transpose();
            }
        }
        let Some(ch) = m.cholesky() else {
            return false;
        };
        let y = ch.solve(&e);
        dq.fill(0.0);
        for &(c, d) in &self.cols {
            if free(d) {
                dq[d] = self.jac.fixed_view::<6, 1>(0, c).dot(&y);
            }
        }
        dq.iter().all(|v| v.is_finite())
    }
}

/// Twist from `cur` to `target` (world frame) with the translation limited to `max_p` and the
/// rotation to `max_a`, each on its own (`LimitCartesianStepSize`). Limiting them separately
/// (rather than scaling the whole twist) lets the hand finish turning while it is still away from
/// the object: on the kitchen wok it cut the median J+-RRT time from ~70 ms to ~15 ms, because
/// most failed goal extensions were the hand turning into the wok in the last 10 cm.
#[inline]
fn limited_twist(
    cur: &Pose,
    target: &Pose,
    max_p: f64,
    max_a: f64,
) -> (Vector3<f64>, Vector3<f64>) {
    let lin = target.translation.vector - cur.translation.vector;
    let ang = rotation_vector(&(target.rotation * cur.rotation.inverse()));
    let (np, na) = (lin.norm(), ang.norm());
    let sp = if np > max_p { max_p / np } else { 1.0 };
    let sa = if na > max_a { max_a / na } else { 1.0 };
    (lin * sp, ang * sa)
}

/// The tree with the workspace pose of every node and its per-grasp exclusion bits.
struct WsTree {
    tree: Tree,
    poses: Vec<Pose>,
    excluded: Vec<u64>,
    words: usize,
}

impl WsTree {
    fn new(weights: &[f64]) -> WsTree {
        WsTree {
            tree: Tree::new(weights),
            poses: Vec::with_capacity(1024),
            excluded: Vec::new(),
            words: 1,
        }
    }

    fn reset(&mut self, goals: usize) {
        self.clear();
        self.words = goals.div_ceil(64).max(1);
    }

    /// Empty, for as many goals as before.
    fn clear(&mut self) {
        self.tree.clear();
        self.poses.clear();
        self.excluded.clear();
    }

    #[inline]
    fn len(&self) -> usize {
        self.tree.len()
    }

    #[inline]
    fn add(&mut self, q: &[f64], parent: u32, pose: Pose) -> u32 {
        let i = self.tree.add(q, parent);
        self.poses.push(pose);
        self.excluded.extend(std::iter::repeat_n(0, self.words));
        i
    }

    #[inline]
    fn is_excluded(&self, i: usize, g: usize) -> bool {
        self.excluded[i * self.words + g / 64] & (1 << (g % 64)) != 0
    }

    #[inline]
    fn exclude(&mut self, i: usize, g: usize) {
        self.excluded[i * self.words + g / 64] |= 1 << (g % 64);
    }

    /// The node nearest to `goal` (workspace metric) not excluded for grasp `g`.
    #[inline]
    fn nearest(&self, goal: &Pose, g: usize, w: f64) -> Option<u32> {
        let mut best = f64::INFINITY;
        let mut best_i = None;
        for (i, p) in self.poses.iter().enumerate() {
            if self.is_excluded(i, g) {
                continue;
            }
            let d = ws_distance_sq(p, goal, w);
            if d < best {
                best = d;
                best_i = Some(i as u32);
            }
        }
        best_i
    }
}

/// How many times a J+ step is recomputed with the variables it would push past their limits
/// locked ([`Core::j_plus_step`]).
const LIMIT_LOCK_ROUNDS: usize = 3;

/// What both planners share: validator, tree, buffers.
struct Core<C: SegmentChecker> {
    validator: SpaceValidator<C>,
    settings: JPlusRrtSettings,
    range: f64,
    nodes: WsTree,
    q_rand: Vec<f64>,
    q_cur: Vec<f64>,
    q_new: Vec<f64>,
    dq: Vec<f64>,
    /// World configuration buffer (base values outside the space).
    wq: Vec<f64>,
    idx: Vec<u32>,
}

/// Outcome of one goal extension.
enum GoalExt {
    Reached(u32),
    Failed,
    Stopped,
}

impl<C: SegmentChecker> Core<C> {
    /// The search's start time and the validator's check and segment counts now (what
    /// `solution` and `stopped` report against).
    fn counters(&mut self) -> (Instant, u64, u64) {
        self.validator.reset_certify_stats();
        (
            Instant::now(),
            self.validator.checks(),
            self.validator.segments(),
        )
    }

    fn new(
        space: JointSpace,
        world: &CollisionWorld,
        checker: C,
        settings: JPlusRrtSettings,
    ) -> Result<Core<C>, PlanError> {
        settings.check()?;
        let range = settings.rrt.checked_range(&space)?;
        let dim = space.dim();
        let wq = space.base().to_vec();
        let nodes = WsTree::new(space.weights());
        let (a, l) = (
            settings.rrt.angular_resolution,
            settings.rrt.linear_resolution,
        );
        Ok(Core {
            validator: SpaceValidator::new(space, world, checker, a, l),
            settings,
            range,
            nodes,
            q_rand: vec![0.0; dim],
            q_cur: vec![0.0; dim],
            q_new: vec![0.0; dim],
            dq: vec![0.0; dim],
            wq,
            idx: Vec::new(),
        })
    }

    #[inline]
    fn load_cur(&mut self) {
        self.validator
            .space()
            .write_world(&self.q_cur, &mut self.wq);
    }

    #[inline]
    fn load_new(&mut self) {
        self.validator
            .space()
            .write_world(&self.q_new, &mut self.wq);
    }

    /// Checks the start, resets the tree to it; `pose` gives a node's workspace pose.
    fn start(
        &mut self,
        start: &[f64],
        goals: usize,
        pose: impl Fn(&[f64]) -> Pose,
    ) -> Result<(), PlanError> {
        // A start value at most `Limits::TOLERANCE` outside the bounds is clamped into them,
        // as RRT-Connect does (the tree's root, and so the returned path, starts there).
        let start = self.validator.space().snap_to_bounds(start).into_owned();
        let start = start.as_slice();
        if let Some(why) = self.validator.invalidity(start) {
            return Err(PlanError::InvalidStart { reason: why });
        }
        if goals == 0 {
            return Err(PlanError::InvalidGoal {
                count: 0,
                reason: "no grasp given".into(),
            });
        }
        self.nodes.reset(goals);
        self.add_root(start, pose);
        Ok(())
    }

    /// Adds `start` as the root of the (empty) tree, with its workspace pose.
    fn add_root(&mut self, start: &[f64], pose: impl Fn(&[f64]) -> Pose) {
        self.q_cur.copy_from_slice(start);
        self.load_cur();
        let p = pose(&self.wq);
        self.nodes.add(start, NO_PARENT, p);
    }

    /// Restart (see [`JPlusRrtSettings::restart_nodes`]): once the tree holds more than
    /// `restart_nodes` nodes, resets it to `start` (already checked by [`Core::start`]) and
    /// counts the restart in `stats`.
    fn restart_if_grown(
        &mut self,
        start: &[f64],
        pose: impl Fn(&[f64]) -> Pose,
        stats: &mut PlanStats,
    ) {
        let limit = self.settings.restart_nodes;
        if limit == 0 || self.nodes.len() <= limit {
            return;
        }
        stats.restarts += 1;
        self.nodes.clear();
        self.add_root(start, pose);
    }

    /// `ExtendRandomly` (000 Alg. 1 line 3): one RRT EXTEND toward a uniform sample; a new node
    /// gets its workspace pose.
    fn extend_randomly(&mut self, rng: &mut ChaCha8Rng, pose: impl Fn(&[f64]) -> Pose) {
        let Core {
            validator,
            nodes,
            q_rand,
            q_new,
            wq,
            range,
            ..
        } = self;
        validator.space().sample_uniform(rng, q_rand);
        let before = nodes.tree.len();
        extend(&mut nodes.tree, validator, *range, q_rand, q_new);
        for i in before..nodes.tree.len() {
            validator
                .space()
                .write_world(nodes.tree.state(i as u32), wq);
            nodes.poses.push(pose(wq));
            nodes.excluded.extend(std::iter::repeat_n(0, nodes.words));
        }
    }

    /// The node a goal extension toward grasp `g` (workspace pose `goal`) starts from: with
    /// probability `p_extend_from_new` the newest node of the tree (added by this iteration's
    /// random extension or by the last goal extension), if it is not excluded for `g`; else
    /// the nearest node not excluded for `g` (000 Alg. 2 line 2 / Alg. 4 line 2). No random
    /// number is drawn when `p_extend_from_new` is 0.
    fn goal_start(&self, rng: &mut ChaCha8Rng, goal: &Pose, g: usize) -> Option<u32> {
        let p = self.settings.p_extend_from_new;
        if p > 0.0 && rng.random::<f64>() < p {
            let newest = self.nodes.len() - 1;
            if !self.nodes.is_excluded(newest, g) {
                return Some(newest as u32);
            }
        }
        self.nodes.nearest(goal, g, self.settings.angle_weight)
    }

    /// One J+ step of `kin`'s TCP by the twist (`lin`, `ang`) from `q_cur` (000 Alg. 2 lines
    /// 7–9): the damped pseudoinverse step; should it take a variable past its joint limit, that
    /// variable is locked at its current value and the step recomputed with the others (up to
    /// [`LIMIT_LOCK_ROUNDS`] times) — where the paper simply rejects the step, which in practice
    /// stalls every extension whose nearest node has a joint at a limit. True when the result
    /// `q_new` is within the bounds and the motion to it is valid.
    fn j_plus_step(&mut self, kin: &mut HandKin, lin: &Vector3<f64>, ang: &Vector3<f64>) -> bool {
        self.load_cur();
        let damping = self.settings.damping;
        let mut locked = 0u64;
        kin.update_jacobian(&self.wq);
        for _ in 0..=LIMIT_LOCK_ROUNDS {
            if !kin.dls_solve(lin, ang, damping, locked, &mut self.dq) {
                return false;
            }
            let space = self.validator.space();
            let (lo, hi) = (space.lower(), space.upper());
            let mut over = 0u64;
            for (d, (c, dq)) in self.q_cur.iter().zip(&self.dq).enumerate().take(64) {
                let n = c + dq;
                if n < lo[d] || n > hi[d] {
                    over |= 1 << d;
                }
            }
            if over == 0 {
                break;
            }
            locked |= over;
        }
        self.try_step()
    }

    /// `q_new = q_cur + dq`, shortened to the EXTEND range; true when it is within the bounds and
    /// the motion `q_cur → q_new` is valid (000 Alg. 2 line 9).
    #[inline]
    fn try_step(&mut self) -> bool {
        for ((n, c), d) in self.q_new.iter_mut().zip(&self.q_cur).zip(&self.dq) {
            *n = c + d;
        }
        let space = self.validator.space();
        let d = space.distance(&self.q_cur, &self.q_new);
        if d > self.range {
            let s = self.range / d;
            for ((n, c), d) in self.q_new.iter_mut().zip(&self.q_cur).zip(&self.dq) {
                *n = c + s * d;
            }
        }
        self.validator.space().satisfies_bounds(&self.q_new)
            && self.validator.is_motion_valid(&self.q_cur, &self.q_new)
    }

    /// Exact convergence (module docs): from `q_cur` (loaded into `wq`), brings `kin`'s TCP onto
    /// `target` (world) by the analytic arm IK at the current swivel angle, else by Newton
    /// iterations; leaves the result in `q_new` and returns true when it is within the bounds
    /// and the motion to it is valid.
    fn converge(&mut self, kin: &mut HandKin, target: &Pose, stats: &mut PlanStats) -> bool {
        self.load_cur();
        if let Some(dims) = kin.arm_dims {
            let rq = &self.wq[kin.offset..kin.offset + kin.dof];
            let arm = &kin.arm.arm;
            let base = kin.base * kin.arm.base_path.pose(rq);
            let t = base.inverse() * target;
            let q7 = arm.from_config(rq);
            let psi = arm.arm_angle(&q7);
            let mut sols = [[0.0; 7]; 8];
            stats.ik_calls += 1;
            let n = arm.solve(&t, psi, &mut sols);
            let w = self.validator.space().weights();
            let best = sols[..n].iter().min_by(|a, b| {
                let d = |s: &[f64; 7]| -> f64 {
                    (0..7)
                        .map(|j| w[dims[j]] * (s[j] - self.q_cur[dims[j]]).powi(2))
                        .sum()
                };
                d(a).total_cmp(&d(b))
            });
            if let Some(s) = best {
                self.q_new.copy_from_slice(&self.q_cur);
                for j in 0..7 {
                    self.q_new[dims[j]] = s[j];
                }
                if self.validator.space().satisfies_bounds(&self.q_new)
                    && self.validator.is_motion_valid(&self.q_cur, &self.q_new)
                {
                    return true;
                }
            }
        }
        // Newton fallback: undamped (or barely damped) pseudoinverse steps, no step limit.
        self.q_new.copy_from_slice(&self.q_cur);
        let tol = self.settings.exact_tolerance;
        for _ in 0..NEWTON_ITERATIONS {
            self.load_new();
            let tcp = kin.tcp(&self.wq);
            let (ep, ea) = pose_error(&tcp, target);
            if ep <= tol && ea <= tol {
                return self.validator.space().satisfies_bounds(&self.q_new)
                    && self.validator.is_motion_valid(&self.q_cur, &self.q_new);
            }
            let lin = target.translation.vector - tcp.translation.vector;
            let ang = rotation_vector(&(target.rotation * tcp.rotation.inverse()));
            stats.jacobian_steps += 1;
            if !kin.dls_step(&self.wq, &lin, &ang, 0.0, &mut self.dq)
                && !kin.dls_solve(&lin, &ang, 1e-9, 0, &mut self.dq)
            {
                return false;
            }
            for (n, d) in self.q_new.iter_mut().zip(&self.dq) {
                *n += d;
            }
        }
        false
    }

    /// Marks `near` and every node added since `first_new` as excluded for grasp `g`.
    fn exclude_failed(&mut self, near: u32, first_new: usize, g: usize) {
        self.nodes.exclude(near as usize, g);
        for i in first_new..self.nodes.len() {
            self.nodes.exclude(i, g);
        }
    }

    /// The pruned, re-validated path root → `node`.
    fn solution(
        &mut self,
        node: u32,
        goal_index: usize,
        mut stats: PlanStats,
        counters: (Instant, u64, u64),
        rng: &mut ChaCha8Rng,
        term: &mut Termination,
    ) -> Result<PlanResult, PlanError> {
        self.nodes.tree.path_from_root(node, &mut self.idx);
        let path: Vec<Vec<f64>> = self
            .idx
            .iter()
            .map(|&i| self.nodes.tree.state(i).to_vec())
            .collect();
        stats.start_tree_size = self.nodes.len();
        let (path, stats) = finish(
            &mut self.validator,
            path,
            &self.settings.rrt,
            stats,
            counters,
            rng,
            term,
        )?;
        Ok(PlanResult {
            path,
            goal_index,
            stats,
        })
    }

    /// The error of a search ended by `term`.
    fn stopped(
        &self,
        mut stats: PlanStats,
        counters: (Instant, u64, u64),
        term: &Termination,
    ) -> PlanError {
        stats.start_tree_size = self.nodes.len();
        stopped(&self.validator, stats, counters, term)
    }
}

/// `pose · Translation(offset)` for each pose and offset (pre-grasp poses from TCP-frame
/// offsets); an error when the lengths differ or an offset is not finite.
fn pregrasp_poses(poses: &[Pose], offsets: &[Vector3<f64>]) -> Result<Vec<Pose>, PlanError> {
    if offsets.len() != poses.len() {
        return Err(PlanError::InvalidInput(format!(
            "{} pre-grasp offsets for {} grasps",
            offsets.len(),
            poses.len()
        )));
    }
    if !offsets.iter().all(|o| o.iter().all(|v| v.is_finite())) {
        return Err(PlanError::InvalidInput(
            "pre-grasp offsets must be finite".into(),
        ));
    }
    Ok(poses
        .iter()
        .zip(offsets)
        .map(|(p, o)| p * Pose::from_parts((*o).into(), UnitQuaternion::identity()))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The polynomial arc cosine of the nearest-node scan stays within 3·10⁻⁸ rad of libm's
    /// over \[0, 1\], ends included.
    #[test]
    fn acos_unit_matches_libm() {
        let mut worst = 0.0f64;
        for i in 0..=100_000 {
            let x = i as f64 / 100_000.0;
            worst = worst.max((acos_unit(x) - x.acos()).abs());
        }
        for x in [0.0, 1e-12, 0.5, 1.0 - 1e-12, 1.0] {
            worst = worst.max((acos_unit(x) - x.acos()).abs());
        }
        assert!(worst <= 3e-8, "worst error {worst:e}");
    }
}
