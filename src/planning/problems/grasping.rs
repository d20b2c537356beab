//! Grasp-planning problems on a scene (paper 000 §IV–VI): what is checked (the
//! [`CollisionWorld`] with the object resting or held), where the planner searches (the
//! [`JointSpace`] of the moving chains) and which goals count (a grasp set), plus the
//! [`GoalSampler`]s that feed [`crate::planning::IkRrt`] (whose `ik_rrt` constructors for these
//! problems are in [`crate::planning::planners`]):
//!
//! * [`ReachProblem`] + [`ArmGoals`]: one "hip + arm" chain reaches one of an object's grasps
//!   (000 §IV, IK-RRT / J+-RRT), or — with the object in the hand — brings it to a place pose.
//! * [`HandOffProblem`] + [`HandOffGoals`]: the object is held by one hand; the goal is every
//!   configuration where another hand — of the same robot (dual-arm re-grasp, 000 §V) or of a
//!   second robot (hand-off, 000 §VI-D) — reaches one of its grasps on it.
//!
//! Contact conventions: only the hand *holding* an object may touch it (the attached body's touch
//! links). A hand about to grasp is checked against the object like any other link, along the
//! whole path and at the goal: the grasp sets of the shipped scenes are open-hand TCP poses free
//! of the object (tests/grasp_planners.rs checks that every IK answer is), so the approach can
//! never pass through the object.

use std::sync::Arc;

use nalgebra::Vector3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::collision::{CollisionChecker, CollisionWorld, FastChecker};
use crate::geometry::Pose;
use crate::kinematics::randomized::{
    try_arm, ArmChain, GraspQuery, IkCounters, RandomizedIk, RandomizedIkSettings, ReachabilityMap,
};
use crate::kinematics::{FkPath, FkPathPair};
use crate::model::Scene;
use crate::planning::base::validity::space_checker;
use crate::planning::{GoalSampler, JointSpace, PlanError};
use crate::reachability::queries::{end_effector_at, grasp_set, GraspSet};
use crate::reachability::{hand_links, GridCache, ReachabilityGrid};

/// One hand: a "free joints + S-R-S arm" chain of a robot of the world, its end effector and the
/// links that may touch what it grasps.
#[derive(Debug, Clone)]
pub struct Hand {
    /// Index of the robot in the world.
    pub robot: usize,
    pub arm: ArmChain,
    pub end_effector: String,
    /// Links of the end effector (and its parent link).
    pub touch: Vec<usize>,
    /// The TCP link's pose alone (for [`Hand::tcp_pose`] in hot loops).
    tcp_path: FkPath,
}

impl Hand {
    /// The hand at the tip of chain group `group` of world robot `robot` (instance name).
    pub fn new(world: &CollisionWorld, robot: &str, group: &str) -> Result<Hand, PlanError> {
        let ri = world
            .robots
            .iter()
            .position(|p| p.name == robot)
            .ok_or_else(|| PlanError::InvalidInput(format!("the scene has no robot '{robot}'")))?;
        let model = &world.robots[ri].robot;
        let arm =
            ArmChain::new(model, group).map_err(|e| PlanError::InvalidInput(e.to_string()))?;
        let tip = arm.chain.tip_link;
        let end_effector = end_effector_at(model, tip, group)
            .map_err(|e| PlanError::InvalidInput(e.to_string()))?;
        let touch = hand_links(model, &end_effector).unwrap_or_else(|| vec![tip]);
        Ok(Hand {
            robot: ri,
            arm,
            end_effector,
            touch,
            tcp_path: FkPath::new(model, tip),
        })
    }

    pub fn tcp_link(&self) -> usize {
        self.arm.chain.tip_link
    }

    /// World variables of the whole chain (free joints and arm).
    pub fn world_vars(&self, world: &CollisionWorld) -> Vec<usize> {
        let off = world.robots[self.robot].offset;
        self.arm.chain.vars.iter().map(|v| v + off).collect()
    }

    /// World pose of the TCP for world configuration `world_q`.
    pub fn tcp_pose(&self, world: &CollisionWorld, world_q: &[f64]) -> Pose {
        let p = &world.robots[self.robot];
        p.base * self.tcp_path.pose(world.robot_config(self.robot, world_q))
    }
}

impl Hand {
    /// A ball `(world centre, radius)` that holds the TCP in every configuration of the chain
    /// within its joint limits, with the rest of the world at `world_q`: about the origin of the
    /// chain's first joint (fixed while only the chain moves), covering every joint offset and
    /// prismatic travel on the way to the TCP ([`crate::kinematics::FkModel::reach_ball`]).
    /// Collisions and revolute limits are ignored, so a target outside it is certainly out of
    /// reach. `None` when a prismatic joint of the chain has unbounded travel.
    pub fn reach_ball(
        &self,
        world: &CollisionWorld,
        world_q: &[f64],
    ) -> Option<(Vector3<f64>, f64)> {
        let p = &world.robots[self.robot];
        let model = &p.robot;
        let fk = crate::kinematics::FkModel::new(model);
        let (tip, offset) = fk.mount(self.arm.chain.tip_link);
        let (base, _) = fk.mount(self.arm.chain.base_link);
        let centre = offset.map(|f| f.t).unwrap_or_else(Vector3::zeros);
        let (c, r) = fk.reach_ball(model, tip, &centre, 0.0, base)?;
        let q = world.robot_config(self.robot, world_q);
        let base_pose = p.base * crate::kinematics::link_pose(model, q, base);
        Some((base_pose * nalgebra::Point3::from(c), r)).map(|(c, r)| (c.coords, r))
    }

    /// Fails at once with [`PlanError::InvalidGoal`] saying why when every TCP target (world
    /// poses) lies outside [`Hand::reach_ball`]: IK-based goal sampling (000 §II-D) could
    /// never find a goal there, and the search would only run into its time limit.
    /// `what` names the targets in the message (e.g. "every grasp of 'wok'").
    pub fn check_reach(
        &self,
        world: &CollisionWorld,
        world_q: &[f64],
        targets: &[Pose],
        what: &str,
    ) -> Result<(), PlanError> {
        let Some((centre, radius)) = self.reach_ball(world, world_q) else {
            return Ok(());
        };
        let gap = targets
            .iter()
            .map(|t| (t.translation.vector - centre).norm() - radius)
            .fold(f64::INFINITY, f64::min);
        if targets.is_empty() || gap <= 0.0 {
            return Ok(());
        }
        let model = &world.robots[self.robot].robot;
        Err(PlanError::InvalidGoal {
            count: targets.len(),
            reason: format!(
                "{what} is out of reach of the {} ('{}' of {}): every TCP target lies beyond \
                 the chain's reach of {radius:.3} m from '{}' (nearest by {gap:.3} m)",
                self.end_effector,
                self.arm.group,
                world.robots[self.robot].name,
                model.links[self.arm.chain.base_link].name,
            ),
        })
    }
}

fn finite_pose(p: &Pose) -> bool {
    p.translation.vector.iter().all(|v| v.is_finite())
        && p.rotation.coords.iter().all(|v| v.is_finite())
}

fn check_world_config(world: &CollisionWorld, q: &[f64]) -> Result<(), PlanError> {
    if q.len() != world.dof() {
        return Err(PlanError::InvalidInput(format!(
            "world configuration has {} values, the world has {} variables",
            q.len(),
            world.dof()
        )));
    }
    Ok(())
}

/// Moves fixed body `object` of `world` to `pose` and attaches it to the hand's TCP (held by the
/// grasp whose TCP, in the object frame, is `grasp`); the hand may touch it. Returns the attached
/// index.
pub fn attach_by_grasp(
    world: &mut CollisionWorld,
    hand: &Hand,
    object: &str,
    grasp: &Pose,
    world_q: &[f64],
) -> Result<usize, PlanError> {
    let si = world
        .statics
        .iter()
        .position(|s| s.name == object)
        .ok_or_else(|| PlanError::InvalidInput(format!("no free object '{object}'")))?;
    world.statics[si].pose = hand.tcp_pose(world, world_q) * grasp.inverse();
    world
        .attach(
            object,
            hand.robot,
            hand.tcp_link(),
            world_q,
            hand.touch.clone(),
        )
        .ok_or_else(|| PlanError::InvalidInput(format!("cannot attach '{object}'")))
}

/// Reaching with one "hip + arm" chain (000 §IV): to a grasp of a resting object, or — with the
/// object held — to a place pose.
#[derive(Debug, Clone)]
pub struct ReachProblem {
    pub world: CollisionWorld,
    pub space: JointSpace,
    pub hand: Hand,
    pub object: String,
    /// World pose of the object at the goal.
    pub object_pose: Pose,
    /// TCP poses in the object frame that count as goals, with their names.
    pub grasps: Vec<Pose>,
    pub grasp_names: Vec<String>,
    /// Translation of each goal's pre-grasp TCP pose in its TCP frame (the scene's
    /// `pregrasp_offset`; zero for place goals): J+-RRT approaches a grasp through it.
    pub pregrasp_offsets: Vec<Vector3<f64>>,
    /// Start state (space coordinates).
    pub start: Vec<f64>,
}

/// The reachability grid of the arm of `group` ([`GridCache::arm_grid`]) of robot
/// instance `robot` in `world`, from `cache` (built and stored on first use): the filter of the
/// randomized IK that feeds IK-RRT's goal trees (000 §II-D; the dual-arm IK of §III-B). `None`
/// when the robot has no SRDF group for that arm chain (the IK then runs unfiltered).
pub fn arm_grid(
    cache: &GridCache,
    world: &CollisionWorld,
    robot: &str,
    group: &str,
) -> Result<Option<Arc<ReachabilityGrid>>, PlanError> {
    let hand = Hand::new(world, robot, group)?;
    cache
        .arm_grid(&world.robots[hand.robot].robot, &hand.arm)
        .map_err(|e| PlanError::InvalidInput(format!("reachability grid of '{group}': {e}")))
}

impl ReachProblem {
    /// Grasp `object` (a fixed body of `world`, with grasps in `scene`) with the hand at the tip of
    /// `group` of robot `robot`, from world configuration `world_q`.
    pub fn grasp(
        scene: &Scene,
        world: &CollisionWorld,
        world_q: &[f64],
        robot: &str,
        group: &str,
        object: &str,
    ) -> Result<ReachProblem, PlanError> {
        check_world_config(world, world_q)?;
        let hand = Hand::new(world, robot, group)?;
        let set: GraspSet = grasp_set(scene, object, &hand.end_effector)
            .map_err(|e| PlanError::InvalidInput(e.to_string()))?;
        let object_pose = world
            .statics
            .iter()
            .find(|s| s.name == object)
            .map(|s| s.pose)
            .ok_or_else(|| {
                PlanError::InvalidInput(format!("'{object}' is not a free object of the scene"))
            })?;
        let targets: Vec<Pose> = set.tcps.iter().map(|g| object_pose * g).collect();
        hand.check_reach(
            world,
            world_q,
            &targets,
            &format!("every grasp of '{object}'"),
        )?;
        let w = world.clone();
        let space = JointSpace::new(&w, &hand.world_vars(&w), world_q.to_vec())?;
        let start = space.from_world(world_q);
        Ok(ReachProblem {
            world: w,
            space,
            hand,
            object: object.to_string(),
            object_pose,
            grasps: set.tcps,
            grasp_names: set.names,
            pregrasp_offsets: set.pregrasp_offsets,
            start,
        })
    }

    /// Carry `object`, held by the hand with grasp `grasp` (TCP in the object frame) and attached
    /// in `world`, to any of `place_poses` (world poses of the object). The goal labels index
    /// `place_poses`.
    pub fn place(
        world: &CollisionWorld,
        world_q: &[f64],
        hand: Hand,
        object: &str,
        grasp: Pose,
        place_poses: &[Pose],
    ) -> Result<ReachProblem, PlanError> {
        check_world_config(world, world_q)?;
        if place_poses.is_empty() {
            return Err(PlanError::InvalidInput("no place pose given".into()));
        }
        if !place_poses.iter().all(finite_pose) || !finite_pose(&grasp) {
            return Err(PlanError::InvalidInput(
                "place poses and grasp must be finite".into(),
            ));
        }
        if !world.attached.iter().any(|a| a.name == object) {
            return Err(PlanError::InvalidInput(format!(
                "'{object}' is not held by a hand"
            )));
        }
        let targets: Vec<Pose> = place_poses.iter().map(|p| p * grasp).collect();
        hand.check_reach(
            world,
            world_q,
            &targets,
            &format!("every place pose of '{object}'"),
        )?;
        let space = JointSpace::new(world, &hand.world_vars(world), world_q.to_vec())?;
        let start = space.from_world(world_q);
        // Goals as TCP poses in the world: object pose = identity, "grasps" = place · grasp.
        Ok(ReachProblem {
            world: world.clone(),
            space,
            hand,
            object: object.to_string(),
            object_pose: Pose::identity(),
            grasps: place_poses.iter().map(|p| p * grasp).collect(),
            grasp_names: (0..place_poses.len())
                .map(|i| format!("place_{i}"))
                .collect(),
            pregrasp_offsets: vec![Vector3::zeros(); place_poses.len()],
            start,
        })
    }

    /// World TCP targets, one per grasp.
    pub fn targets(&self) -> Vec<Pose> {
        self.grasps.iter().map(|g| self.object_pose * g).collect()
    }

    /// The goal sampler of IK-RRT for this problem: randomized IK (000 §II-D) with at most
    /// `settings.max_tries` tries per query, filtered by `grid` when given.
    pub fn goals(
        &self,
        grid: Option<Arc<ReachabilityGrid>>,
        settings: RandomizedIkSettings,
    ) -> ArmGoals {
        self.goals_with(grid, settings, space_checker(&self.world, &self.space))
    }

    pub(crate) fn goals_with(
        &self,
        grid: Option<Arc<ReachabilityGrid>>,
        settings: RandomizedIkSettings,
        checker: FastChecker,
    ) -> ArmGoals {
        let p = &self.world.robots[self.hand.robot];
        let world_q = self.space.base().to_vec();
        ArmGoals {
            ik: RandomizedIk::from_chain(p.robot.clone(), self.hand.arm.clone()),
            grid,
            settings,
            robot_base: p.base,
            object_pose: self.object_pose,
            grasps: self.grasps.clone(),
            robot_q: world_q[p.offset..p.offset + p.robot.dof()].to_vec(),
            offset: p.offset,
            checker,
            space: self.space.clone(),
            world_q,
            counters: IkCounters::default(),
        }
    }
}

/// IK-RRT goals of a [`ReachProblem`]: randomized IK for the grasp set, each answer checked in
/// the problem's world.
pub struct ArmGoals {
    ik: RandomizedIk,
    grid: Option<Arc<ReachabilityGrid>>,
    settings: RandomizedIkSettings,
    robot_base: Pose,
    object_pose: Pose,
    grasps: Vec<Pose>,
    robot_q: Vec<f64>,
    offset: usize,
    checker: FastChecker,
    space: JointSpace,
    world_q: Vec<f64>,
    counters: IkCounters,
}

impl ArmGoals {
    pub fn counters(&self) -> &IkCounters {
        &self.counters
    }
}

impl GoalSampler for ArmGoals {
    fn sample_goal(&mut self, rng: &mut ChaCha8Rng, out: &mut [f64]) -> Option<usize> {
        let query = GraspQuery {
            robot_base: self.robot_base,
            object_pose: self.object_pose,
            grasps: &self.grasps,
            start: &self.robot_q,
        };
        let reach = self.grid.as_deref().map(|g| g as &dyn ReachabilityMap);
        let (checker, world_q, offset) = (&mut self.checker, &mut self.world_q, self.offset);
        let r = self.ik.solve(&query, reach, &self.settings, rng, |_, q| {
            world_q[offset..offset + q.len()].copy_from_slice(q);
            checker.is_free(world_q)
        });
        match r {
            Ok(sol) => {
                self.counters.add(&sol.counters);
                self.world_q[offset..offset + sol.config.len()].copy_from_slice(&sol.config);
                for (o, &v) in out.iter_mut().zip(self.space.vars()) {
                    *o = self.world_q[v];
                }
                Some(sol.grasp)
            }
            Err(crate::kinematics::randomized::RandomizedIkError::NoSolution {
                counters, ..
            }) => {
                self.counters.add(&counters);
                None
            }
            Err(_) => None,
        }
    }

    fn ik_calls(&self) -> u64 {
        self.counters.ik_calls
    }
}

/// Dual-arm re-grasping (000 §V) and hand-off between two robots (000 §VI-D): the object is held
/// by the `giver` hand; the goal is every configuration where the `receiver` hand reaches one of
/// its grasps on the object. Both chains move (hip + both arms = 17 DoF for one robot, 2 × 10 for
/// two).
#[derive(Debug, Clone)]
pub struct HandOffProblem {
    pub world: CollisionWorld,
    pub space: JointSpace,
    pub giver: Hand,
    pub receiver: Hand,
    pub object: String,
    /// The giver's grasp (TCP in the object frame).
    pub held: Pose,
    /// The receiver's grasps (TCP in the object frame) and their names.
    pub grasps: Vec<Pose>,
    pub grasp_names: Vec<String>,
    /// Translation of each receiver grasp's pre-grasp TCP pose in its TCP frame (the scene's
    /// `pregrasp_offset`): dual-arm J+-RRT approaches a grasp through it.
    pub pregrasp_offsets: Vec<Vector3<f64>>,
    pub start: Vec<f64>,
}

impl HandOffProblem {
    /// `world` has `object` either resting (it is then put into the giver's hand by `held`, at
    /// the pose that grasp implies for `world_q`) or already attached to the giver's hand.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        scene: &Scene,
        world: &CollisionWorld,
        world_q: &[f64],
        giver: (&str, &str),
        receiver: (&str, &str),
        object: &str,
        held: Pose,
    ) -> Result<HandOffProblem, PlanError> {
        check_world_config(world, world_q)?;
        if !finite_pose(&held) {
            return Err(PlanError::InvalidInput("held grasp must be finite".into()));
        }
        let g = Hand::new(world, giver.0, giver.1)?;
        let r = Hand::new(world, receiver.0, receiver.1)?;
        if g.robot == r.robot
            && g.arm
                .arm
                .vars()
                .iter()
                .any(|v| r.arm.arm.vars().contains(v))
        {
            return Err(PlanError::InvalidInput(format!(
                "giver chain '{}' and receiver chain '{}' share arm joints",
                giver.1, receiver.1
            )));
        }
        let set = grasp_set(scene, object, &r.end_effector)
            .map_err(|e| PlanError::InvalidInput(e.to_string()))?;
        // The receiver's TCP is within |held⁻¹ · grasp| of the giver's TCP: the two reach balls
        // must come that close for some grasp.
        if let (Some((cg, rg)), Some((cr, rr))) =
            (g.reach_ball(world, world_q), r.reach_ball(world, world_q))
        {
            let apart = (cg - cr).norm() - rg - rr;
            let gap = set
                .tcps
                .iter()
                .map(|t| apart - (held.inverse() * t).translation.vector.norm())
                .fold(f64::INFINITY, f64::min);
            if !set.tcps.is_empty() && gap > 0.0 {
                return Err(PlanError::InvalidGoal {
                    count: set.tcps.len(),
                    reason: format!(
                        "the {} and the {} cannot meet to pass '{object}': their reaches stay \
                         apart by {gap:.3} m for every grasp",
                        g.end_effector, r.end_effector
                    ),
                });
            }
        }
        let mut w = world.clone();
        if !w.attached.iter().any(|a| a.name == object) {
            attach_by_grasp(&mut w, &g, object, &held, world_q)?;
        }
        let mut vars = g.world_vars(&w);
        for v in r.world_vars(&w) {
            if !vars.contains(&v) {
                vars.push(v);
            }
        }
        let space = JointSpace::new(&w, &vars, world_q.to_vec())?;
        let start = space.from_world(world_q);
        Ok(HandOffProblem {
            world: w,
            space,
            giver: g,
            receiver: r,
            object: object.to_string(),
            held,
            grasps: set.tcps,
            grasp_names: set.names,
            pregrasp_offsets: set.pregrasp_offsets,
            start,
        })
    }

    /// The goal sampler of dual-arm IK-RRT (000 §V-B) for this problem.
    pub fn goals(
        &self,
        grid: Option<Arc<ReachabilityGrid>>,
        settings: RandomizedIkSettings,
    ) -> HandOffGoals {
        self.goals_with(grid, settings, space_checker(&self.world, &self.space))
    }

    pub(crate) fn goals_with(
        &self,
        grid: Option<Arc<ReachabilityGrid>>,
        settings: RandomizedIkSettings,
        checker: FastChecker,
    ) -> HandOffGoals {
        let world_q = self.space.base().to_vec();
        let mut sampled = self.giver.world_vars(&self.world);
        let roff = self.world.robots[self.receiver.robot].offset;
        for v in &self.receiver.arm.free_vars {
            if !sampled.contains(&(v + roff)) {
                sampled.push(v + roff);
            }
        }
        // (world variable, index in the space); a variable outside the space is not sampled.
        let sampled = sampled
            .into_iter()
            .filter_map(|w| {
                self.space
                    .vars()
                    .iter()
                    .position(|&v| v == w)
                    .map(|i| (w, i))
            })
            .collect();
        let rdof = self.world.robots[self.receiver.robot].robot.dof();
        let shared_hip = (self.giver.robot == self.receiver.robot)
            .then(|| {
                self.giver
                    .tcp_path
                    .with_prefix(&self.receiver.arm.base_path)
            })
            .flatten();
        HandOffGoals {
            world: self.world.clone(),
            checker,
            giver: self.giver.clone(),
            receiver: self.receiver.clone(),
            held_inv: self.held.inverse(),
            grasps: self.grasps.clone(),
            grid,
            settings,
            sampled,
            space: self.space.clone(),
            world_q,
            cand: Vec::new(),
            probs: Vec::new(),
            rq: vec![0.0; rdof],
            shared_hip,
            counters: IkCounters::default(),
        }
    }
}

/// Goals of a [`HandOffProblem`]: the 17-D dual-arm IK of 000 §III with the object held (giver's
/// hip and arm sampled, the object pose follows from the giver's TCP, the receiver's arm solved
/// analytically for its grasps, filtered by its reachability grid when given), generalised to a
/// receiver of another robot (its free joints sampled too).
pub struct HandOffGoals {
    world: CollisionWorld,
    checker: FastChecker,
    giver: Hand,
    receiver: Hand,
    held_inv: Pose,
    grasps: Vec<Pose>,
    grid: Option<Arc<ReachabilityGrid>>,
    settings: RandomizedIkSettings,
    /// World variables sampled per try, with their index in the space.
    sampled: Vec<(usize, usize)>,
    space: JointSpace,
    world_q: Vec<f64>,
    cand: Vec<(f64, usize)>,
    probs: Vec<f64>,
    /// The receiver's configuration while its arm is solved (reused per try).
    rq: Vec<f64>,
    /// The giver's TCP path with the receiver's arm base on it, when both hands are on one
    /// robot and the base's joints start the TCP's path (both arms on one sampled hip): the
    /// two poses per try from one pass over the shared joints.
    shared_hip: Option<FkPathPair>,
    counters: IkCounters,
}

impl HandOffGoals {
    pub fn counters(&self) -> &IkCounters {
        &self.counters
    }
}

impl GoalSampler for HandOffGoals {
    fn sample_goal(&mut self, rng: &mut ChaCha8Rng, out: &mut [f64]) -> Option<usize> {
        let rp = &self.world.robots[self.receiver.robot];
        let (roff, rdof) = (rp.offset, rp.robot.dof());
        for _ in 0..self.settings.max_tries {
            self.counters.tries += 1;
            let (lo, hi) = (self.space.lower(), self.space.upper());
            for &(w, i) in &self.sampled {
                self.world_q[w] = lo[i] + (hi[i] - lo[i]) * rng.random::<f64>();
            }
            let rq = &self.world_q[roff..roff + rdof];
            let (tcp, arm_base) = match &self.shared_hip {
                // One robot: the giver's configuration is the receiver's, `rq`.
                Some(pair) => {
                    let (tcp, arm_base) = pair.poses(rq);
                    (rp.base * tcp, arm_base)
                }
                None => (
                    self.giver.tcp_pose(&self.world, &self.world_q),
                    self.receiver.arm.base_path.pose(rq),
                ),
            };
            let object = tcp * self.held_inv;
            let inv = (rp.base * arm_base).inverse();
            self.cand.clear();
            match self.grid.as_deref() {
                Some(map) if rng.random::<f64>() < self.settings.reach_probability => {
                    self.counters.reach_lookups += self.grasps.len() as u64;
                    self.probs.resize(self.grasps.len(), 0.0);
                    map.probabilities(&(inv * object), &self.grasps, &mut self.probs);
                    for (g, &p) in self.probs.iter().enumerate() {
                        if p > self.settings.threshold {
                            self.cand.push((p, g));
                        }
                    }
                    self.cand.sort_by(|a, b| b.0.total_cmp(&a.0));
                }
                _ => self
                    .cand
                    .push((0.0, rng.random_range(0..self.grasps.len()))),
            }
            self.rq.copy_from_slice(&self.world_q[roff..roff + rdof]);
            for k in 0..self.cand.len() {
                let g = self.cand[k].1;
                let target = inv * object * self.grasps[g];
                let (checker, world_q) = (&mut self.checker, &mut self.world_q);
                let ok = try_arm(
                    &self.receiver.arm.arm,
                    &target,
                    self.settings.psi_samples,
                    &mut self.rq,
                    &mut self.counters,
                    rng,
                    |q| {
                        world_q[roff..roff + rdof].copy_from_slice(q);
                        checker.is_free(world_q)
                    },
                );
                if ok {
                    self.world_q[roff..roff + rdof].copy_from_slice(&self.rq);
                    for (o, &v) in out.iter_mut().zip(self.space.vars()) {
                        *o = self.world_q[v];
                    }
                    return Some(g);
                }
            }
        }
        None
    }

    fn ik_calls(&self) -> u64 {
        self.counters.ik_calls
    }
}
