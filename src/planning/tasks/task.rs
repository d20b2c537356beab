//! Chained manipulation tasks: several planning queries whose results are joined into one
//! trajectory of world configurations with the grasp and release events marked.
//!
//! [`kitchen_task`] is paper 000's kitchen experiment (§VI-C, Table 5): grasp the wok with one
//! hand (IK-RRT), re-grasp it to the other hand (dual-arm IK-RRT), move the first arm out of the
//! way (RRT-Connect back to its start joint values; the paper does not say what the free arm
//! does), place the wok in the cabinet (IK-RRT with the object held, goals = a set of place
//! poses). Unlike the paper, which fixed one IK
//! solution per step before planning (and so lost probabilistic completeness, as it notes), each
//! step here searches its IK solutions while planning. A re-grasp whose first hand cannot
//! retreat within [`RETREAT_ITERATIONS`] is planned again with another seed (up to
//! [`REGRASP_ATTEMPTS`] attempts, the last with the task's whole remaining time).

use std::sync::Arc;
use std::time::{Duration, Instant};

use serde::Serialize;

use crate::collision::CollisionWorld;
use crate::geometry::{iso_from_rpy, Pose};
use crate::kinematics::randomized::RandomizedIkSettings;
use crate::model::Scene;
use crate::planning::problems::grasping::{attach_by_grasp, Hand, HandOffProblem, ReachProblem};
use crate::planning::{
    DualArmJPlusRrt, IkRrtSettings, JPlusRrt, JPlusRrtSettings, JointSpace, PlanError, PlanResult,
    PlanStats, RrtConnect, RrtConnectSettings, Termination,
};
use crate::reachability::queries::grasp_set;
use crate::reachability::ReachabilityGrid;
use crate::trajectory::timing::{time_polyline, world_limits, TimingError, TimingOptions};

/// Which of paper 000's grasp planners searches a grasp or re-grasp phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GraspAlgorithm {
    /// IK-RRT (000 Alg. 3) / dual-arm IK-RRT (000 §V-B): goal tree fed by randomized IK.
    #[default]
    IkRrt,
    /// J+-RRT (000 Alg. 1–2) / dual-arm J+-RRT (000 Alg. 4–5): no IK, Jacobian steps toward the
    /// grasps, with [`JPlusRrtSettings::default`] and the IK-RRT settings' RRT part.
    JPlusRrt,
}

impl GraspAlgorithm {
    /// Parses `ik-rrt` / `ik_rrt` / `j-plus-rrt` / `j_plus_rrt`.
    pub fn parse(s: &str) -> Option<GraspAlgorithm> {
        match s.replace('-', "_").as_str() {
            "ik_rrt" => Some(GraspAlgorithm::IkRrt),
            "j_plus_rrt" | "jplus_rrt" => Some(GraspAlgorithm::JPlusRrt),
            _ => None,
        }
    }

    /// Phase planner name of a single-hand grasp.
    fn reach_name(self) -> &'static str {
        match self {
            GraspAlgorithm::IkRrt => "ik_rrt",
            GraspAlgorithm::JPlusRrt => "j_plus_rrt",
        }
    }

    /// Phase planner name of a re-grasp.
    fn regrasp_name(self) -> &'static str {
        match self {
            GraspAlgorithm::IkRrt => "dual_arm_ik_rrt",
            GraspAlgorithm::JPlusRrt => "dual_arm_j_plus_rrt",
        }
    }

    fn j_plus(planner: &IkRrtSettings, base: JPlusRrtSettings) -> JPlusRrtSettings {
        JPlusRrtSettings {
            rrt: planner.rrt,
            ..base
        }
    }

    /// Plans a grasp of `p` with this algorithm.
    pub fn plan_reach(
        self,
        p: &ReachProblem,
        grid: Option<Arc<ReachabilityGrid>>,
        planner: IkRrtSettings,
        ik: RandomizedIkSettings,
        term: &mut Termination,
        seed: u64,
    ) -> Result<PlanResult, PlanError> {
        match self {
            GraspAlgorithm::IkRrt => {
                let (mut rrt, mut goals) = p.ik_rrt(grid, planner, ik)?;
                rrt.plan(&p.start, &mut goals, term, seed)
            }
            GraspAlgorithm::JPlusRrt => {
                JPlusRrt::for_problem(p, Self::j_plus(&planner, JPlusRrtSettings::default()))?
                    .plan(&p.start, term, seed)
            }
        }
    }

    /// Plans a re-grasp / hand-off of `h` with this algorithm.
    pub fn plan_regrasp(
        self,
        h: &HandOffProblem,
        grid: Option<Arc<ReachabilityGrid>>,
        planner: IkRrtSettings,
        ik: RandomizedIkSettings,
        term: &mut Termination,
        seed: u64,
    ) -> Result<PlanResult, PlanError> {
        match self {
            GraspAlgorithm::IkRrt => {
                let (mut rrt, mut goals) = h.ik_rrt(grid, planner, ik)?;
                rrt.plan(&h.start, &mut goals, term, seed)
            }
            GraspAlgorithm::JPlusRrt => DualArmJPlusRrt::for_problem(
                h,
                Self::j_plus(&planner, JPlusRrtSettings::dual_arm()),
            )?
            .plan(&h.start, term, seed),
        }
    }
}

/// What happens at a waypoint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// The hand closes on the object (it moves with the hand from here on).
    Grasp,
    /// The hand opens; the object stays where it is (or in the other hand).
    Release,
}

/// A grasp or release at a waypoint of a [`TaskPlan`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TaskEvent {
    /// Index into [`TaskPlan::waypoints`].
    pub waypoint: usize,
    pub kind: EventKind,
    /// Robot instance name.
    pub robot: String,
    /// End effector (SRDF) name.
    pub end_effector: String,
    pub object: String,
    /// Grasp name (scene grasp set), or the place pose label on the final release.
    pub grasp: String,
}

/// One planning query of a task.
#[derive(Debug, Clone, Serialize)]
pub struct TaskPhase {
    pub name: String,
    pub planner: String,
    /// Waypoint range `[first, last]` of the phase.
    pub first: usize,
    pub last: usize,
    pub stats: PlanStats,
    /// What the phase was checked in (the object resting or held), for independent re-checks.
    #[serde(skip)]
    pub world: CollisionWorld,
}

/// A chained task's answer: world configurations (every robot of the scene) and what happens
/// where.
#[derive(Debug, Clone, Serialize)]
pub struct TaskPlan {
    pub waypoints: Vec<Vec<f64>>,
    pub phases: Vec<TaskPhase>,
    pub events: Vec<TaskEvent>,
    /// Wall time of the whole task.
    pub time: Duration,
}

impl TaskPlan {
    fn append(
        &mut self,
        name: &str,
        planner: &str,
        path: Vec<Vec<f64>>,
        stats: PlanStats,
        world: &CollisionWorld,
    ) {
        let first = self.waypoints.len().saturating_sub(1);
        let skip = usize::from(!self.waypoints.is_empty());
        self.waypoints.extend(path.into_iter().skip(skip));
        self.phases.push(TaskPhase {
            name: name.into(),
            planner: planner.into(),
            first,
            last: self.waypoints.len() - 1,
            stats,
            world: world.clone(),
        });
    }

    fn event(&mut self, kind: EventKind, robot: &str, ee: &str, object: &str, grasp: &str) {
        self.events.push(TaskEvent {
            waypoint: self.waypoints.len() - 1,
            kind,
            robot: robot.into(),
            end_effector: ee.into(),
            object: object.into(),
            grasp: grasp.into(),
        });
    }
}

/// Parameters of [`kitchen_task`].
#[derive(Debug, Clone)]
pub struct KitchenTask {
    pub robot: String,
    pub object: String,
    /// Chain of the hand that picks the object up (e.g. `torso_right_arm`).
    pub first: String,
    /// Chain of the hand it is re-grasped to and placed with (e.g. `torso_left_arm`).
    pub second: String,
    /// Candidate place poses of the object (world).
    pub place_poses: Vec<Pose>,
    /// Reachability grids of the first and second arm (optional; see `reach build`).
    pub grids: (Option<Arc<ReachabilityGrid>>, Option<Arc<ReachabilityGrid>>),
    pub planner: IkRrtSettings,
    /// RRT-Connect settings of the retreat of the first arm.
    pub retreat: RrtConnectSettings,
    /// Randomized-IK settings per goal query (`max_tries` bounds one query).
    pub ik: RandomizedIkSettings,
}

/// Place poses on a horizontal surface: a grid of `nx × ny` positions over `centre ± half`
/// (x, y; z fixed) times the yaws `yaws` (radians). The object's z axis stays vertical.
pub fn surface_places(centre: [f64; 3], half: [f64; 2], n: [usize; 2], yaws: &[f64]) -> Vec<Pose> {
    let mut out = Vec::new();
    let step = |k: usize, n: usize, h: f64| {
        if n <= 1 {
            0.0
        } else {
            -h + 2.0 * h * k as f64 / (n - 1) as f64
        }
    };
    for ix in 0..n[0] {
        for iy in 0..n[1] {
            for &yaw in yaws {
                out.push(iso_from_rpy(
                    [
                        centre[0] + step(ix, n[0], half[0]),
                        centre[1] + step(iy, n[1], half[1]),
                        centre[2],
                    ],
                    [0.0, 0.0, yaw],
                ));
            }
        }
    }
    out
}

/// The place poses of the shipped kitchen (`scenes/kitchen.json`): the bottom and middle shelves
/// of `cabinet` (board tops at z = 0.92 m and 1.21 m, inner x 0.60…0.98 m, y 0.27…0.93 m), the
/// wok 1.1 cm above the board, its centre on a 2 × 3 grid (x 0.74…0.80, y 0.45…0.75), every 30°
/// of yaw (which yaws fit depends on the grasp the hand holds; the IK decides): 144 poses.
pub fn kitchen_cabinet_places() -> Vec<Pose> {
    let yaws: Vec<f64> = (0..12).map(|k| (k as f64 * 30.0).to_radians()).collect();
    let mut out = surface_places([0.77, 0.6, 0.931], [0.03, 0.15], [2, 3], &yaws);
    out.extend(surface_places(
        [0.77, 0.6, 1.221],
        [0.03, 0.15],
        [2, 3],
        &yaws,
    ));
    out
}

impl KitchenTask {
    /// The paper's setup on `scene`: robot `armar`, wok picked with the right hand, re-grasped to
    /// the left, the right arm back to its start joint values, the wok placed on a cabinet shelf.
    pub fn armar_wok() -> KitchenTask {
        KitchenTask {
            robot: "armar".into(),
            object: "wok".into(),
            first: "torso_right_arm".into(),
            second: "torso_left_arm".into(),
            place_poses: kitchen_cabinet_places(),
            grids: (None, None),
            planner: IkRrtSettings::default(),
            retreat: RrtConnectSettings::default(),
            ik: RandomizedIkSettings {
                max_tries: 50,
                ..RandomizedIkSettings::default()
            },
        }
    }
}

/// Paper 000's kitchen task (§VI-C) on `scene` from its start configuration: grasp → re-grasp →
/// place, each an IK-RRT query; `term` bounds the whole task. The phases' seeds derive from
/// `seed`.
pub fn kitchen_task(
    scene: &Scene,
    task: &KitchenTask,
    term: &mut Termination,
    seed: u64,
) -> Result<TaskPlan, PlanError> {
    let t0 = Instant::now();
    let world = CollisionWorld::from_scene(scene);
    let q0 = CollisionWorld::start_config(scene);
    let mut plan = TaskPlan {
        waypoints: Vec::new(),
        phases: Vec::new(),
        events: Vec::new(),
        time: Duration::ZERO,
    };
    let tagged = |phase: &str, e: PlanError| PlanError::InPhase {
        phase: phase.into(),
        error: Box::new(e),
    };

    // 1. Grasp with the first hand.
    let p1 = ReachProblem::grasp(scene, &world, &q0, &task.robot, &task.first, &task.object)
        .map_err(|e| tagged("grasp", e))?;
    let (mut planner, mut goals) = p1
        .ik_rrt(task.grids.0.clone(), task.planner, task.ik)
        .map_err(|e| tagged("grasp", e))?;
    let r1 = planner
        .plan(&p1.start, &mut goals, term, seed)
        .map_err(|e| tagged("grasp", e))?;
    let q1 = p1.space.to_world(r1.path.last().map_or(&p1.start, |v| v));
    let held1 = p1.grasps[r1.goal_index];
    let path = p1.space.path_to_world(&r1.path);
    plan.append("grasp", "ik_rrt", path, r1.stats, &p1.world);
    let name1 = &p1.grasp_names[r1.goal_index];
    plan.event(
        EventKind::Grasp,
        &task.robot,
        &p1.hand.end_effector,
        &task.object,
        name1,
    );

    // 2.–3. Re-grasp to the second hand, then the first hand lets go and its arm returns to its
    //    joint values of the start configuration. A re-grasp goal can leave the first hand's
    //    fingers hooked around the handle, so that no retreat exists; the retreat therefore gets
    //    an iteration budget, and when it runs out the re-grasp is planned again (another seed:
    //    another goal). The last attempt has the task's whole remaining time.
    let hand1 = Hand::new(&world, &task.robot, &task.first).map_err(|e| tagged("retreat", e))?;
    let hand2 = Hand::new(&world, &task.robot, &task.second).map_err(|e| tagged("retreat", e))?;
    let mut attempt = 0u64;
    let (q3, held2, w3) = loop {
        let p2 = HandOffProblem::new(
            scene,
            &world,
            &q1,
            (&task.robot, &task.first),
            (&task.robot, &task.second),
            &task.object,
            held1,
        )
        .map_err(|e| tagged("regrasp", e))?;
        let (mut planner, mut goals) = p2
            .ik_rrt(task.grids.1.clone(), task.planner, task.ik)
            .map_err(|e| tagged("regrasp", e))?;
        let seed2 = seed
            .wrapping_add(1)
            .wrapping_add(REGRASP_SEED_STRIDE * attempt);
        let r2 = planner
            .plan(&p2.start, &mut goals, term, seed2)
            .map_err(|e| tagged("regrasp", e))?;
        let q2 = p2.space.to_world(r2.path.last().map_or(&p2.start, |v| v));
        let held2 = p2.grasps[r2.goal_index];

        // 3. The retreat: RRT-Connect over the hip and both arms, the object held by the second
        //    hand, so the object can move out of the opening hand's way.
        let mut w3 = world.clone();
        attach_by_grasp(&mut w3, &hand2, &task.object, &held2, &q2)
            .map_err(|e| tagged("retreat", e))?;
        let off = w3.robots[hand1.robot].offset;
        let mut vars = hand1.world_vars(&w3);
        for v in hand2.world_vars(&w3) {
            if !vars.contains(&v) {
                vars.push(v);
            }
        }
        // Goal candidates (RRT-Connect takes the valid ones as a goal set): the first arm at
        // its start joint values with the hip where it is; the same with the hip back at its
        // start values (when the turned hip puts the returned arm into the counter); and also
        // the second arm back at its start values.
        let arm1: Vec<usize> = hand1.arm.arm.vars().iter().map(|v| v + off).collect();
        let arm2: Vec<usize> = hand2.arm.arm.vars().iter().map(|v| v + off).collect();
        let hip: Vec<usize> = vars
            .iter()
            .copied()
            .filter(|v| !arm1.contains(v) && !arm2.contains(v))
            .collect();
        let space3 = JointSpace::new(&w3, &vars, q2.clone()).map_err(|e| tagged("retreat", e))?;
        let mut goals3: Vec<Vec<f64>> = Vec::new();
        let mut g = q2.clone();
        for reset in [&arm1[..], &hip[..], &arm2[..]] {
            for &v in reset {
                g[v] = q0[v];
            }
            goals3.push(space3.from_world(&g));
        }
        let mut planner =
            RrtConnect::new(space3.clone(), &w3, task.retreat).map_err(|e| tagged("retreat", e))?;
        let last = attempt + 1 >= REGRASP_ATTEMPTS;
        let mut budget = if last {
            term.clone()
        } else {
            term.clone()
                .with_iteration_limit(term.iterations() + RETREAT_ITERATIONS)
        };
        let r3 = match planner.plan(
            &space3.from_world(&q2),
            &goals3,
            &mut budget,
            seed.wrapping_add(2)
                .wrapping_add(REGRASP_SEED_STRIDE * attempt),
        ) {
            Ok(r) => r,
            Err(PlanError::IterationLimit { .. }) if !last => {
                attempt += 1;
                continue;
            }
            Err(e) => return Err(tagged("retreat", e)),
        };
        let path = p2.space.path_to_world(&r2.path);
        plan.append("regrasp", "dual_arm_ik_rrt", path, r2.stats, &p2.world);
        let name2 = &p2.grasp_names[r2.goal_index];
        plan.event(
            EventKind::Grasp,
            &task.robot,
            &p2.receiver.end_effector,
            &task.object,
            name2,
        );
        plan.event(
            EventKind::Release,
            &task.robot,
            &p2.giver.end_effector,
            &task.object,
            name1,
        );
        let q3 = space3.to_world(r3.path.last().map_or(&q2, |v| v));
        let path: Vec<Vec<f64>> = r3.path.iter().map(|q| space3.to_world(q)).collect();
        plan.append("retreat", "rrt_connect", path, r3.stats, &w3);
        break (q3, held2, w3);
    };

    // 4. Place with the second hand.
    let p4 = ReachProblem::place(&w3, &q3, hand2, &task.object, held2, &task.place_poses)
        .map_err(|e| tagged("place", e))?;
    let (mut planner, mut goals) = p4
        .ik_rrt(task.grids.1.clone(), task.planner, task.ik)
        .map_err(|e| tagged("place", e))?;
    let r4 = planner
        .plan(&p4.start, &mut goals, term, seed.wrapping_add(3))
        .map_err(|e| tagged("place", e))?;
    let path = p4.space.path_to_world(&r4.path);
    plan.append("place", "ik_rrt", path, r4.stats, &p4.world);
    let place = p4.grasp_names[r4.goal_index].clone();
    plan.event(
        EventKind::Release,
        &task.robot,
        &p4.hand.end_effector,
        &task.object,
        &place,
    );
    plan.time = t0.elapsed();
    Ok(plan)
}

/// Re-grasp + retreat attempts of [`kitchen_task`] before it gives up.
pub const REGRASP_ATTEMPTS: u64 = 3;
/// RRT-Connect iterations of a retreat before the re-grasp is planned again (all but the last
/// attempt). Running out costs ~0.3 s here (kitchen seed 74: 338 ms in all, one attempt spent).
pub const RETREAT_ITERATIONS: u64 = 5_000;
/// Seed offset between re-grasp attempts.
const REGRASP_SEED_STRIDE: u64 = 1_000;

/// Parameters of [`regrasp_task`]: dual-arm re-grasping (000 §V, one robot's two hands) or a
/// hand-off between two robots (000 §VI-D) — the same query with other chains.
#[derive(Debug, Clone)]
pub struct RegraspTask {
    /// (robot instance, chain group) of the hand holding the object at the end of the grasp.
    pub giver: (String, String),
    /// (robot instance, chain group) of the hand that takes it.
    pub receiver: (String, String),
    pub object: String,
    /// Name of the giver's grasp when the object is to be put into the giver's hand at the start
    /// configuration. `None`: the object is already held when one of the giver's grasps matches
    /// where it lies (within 5 mm / 0.01 rad), otherwise the giver grasps it first (IK-RRT).
    pub held: Option<String>,
    pub grid: Option<Arc<ReachabilityGrid>>,
    /// Grasp and re-grasp planner.
    pub algorithm: GraspAlgorithm,
    /// IK-RRT settings (J+-RRT takes their RRT part).
    pub planner: IkRrtSettings,
    pub ik: RandomizedIkSettings,
}

/// The giver grasp (index into its grasp set) that holds `object` where it lies in `world` at
/// `world_q`, if any (5 mm / 0.01 rad).
pub fn grasp_holding(
    scene: &Scene,
    world: &CollisionWorld,
    world_q: &[f64],
    hand: &Hand,
    object: &str,
) -> Result<Option<usize>, PlanError> {
    let set = grasp_set(scene, object, &hand.end_effector)
        .map_err(|e| PlanError::InvalidInput(e.to_string()))?;
    let pose = world
        .statics
        .iter()
        .find(|s| s.name == object)
        .map(|s| s.pose)
        .ok_or_else(|| {
            PlanError::InvalidInput(format!("'{object}' is not a free object of the scene"))
        })?;
    let tcp = hand.tcp_pose(world, world_q);
    Ok(set.tcps.iter().position(|g| {
        let o = tcp * g.inverse();
        (o.translation.vector - pose.translation.vector).norm() < 0.005
            && o.rotation.angle_to(&pose.rotation) < 0.01
    }))
}

/// Re-grasp (or hand-off) from `scene`'s start configuration, see [`RegraspTask`]: an optional
/// grasp phase (IK-RRT), then the hand-over (dual-arm IK-RRT, 000 §V-B). The plan's events: the
/// giver's grasp (when planned), the receiver's grasp, the giver's release.
pub fn regrasp_task(
    scene: &Scene,
    task: &RegraspTask,
    term: &mut Termination,
    seed: u64,
) -> Result<TaskPlan, PlanError> {
    let t0 = Instant::now();
    let world = CollisionWorld::from_scene(scene);
    let q0 = CollisionWorld::start_config(scene);
    let mut plan = TaskPlan {
        waypoints: vec![q0.clone()],
        phases: Vec::new(),
        events: Vec::new(),
        time: Duration::ZERO,
    };
    let tagged = |phase: &str, e: PlanError| PlanError::InPhase {
        phase: phase.into(),
        error: Box::new(e),
    };
    let giver = Hand::new(&world, &task.giver.0, &task.giver.1)?;
    let set = grasp_set(scene, &task.object, &giver.end_effector)
        .map_err(|e| PlanError::InvalidInput(e.to_string()))?;
    let (q1, held, held_name) = match &task.held {
        Some(name) => {
            let k = set.names.iter().position(|n| n == name).ok_or_else(|| {
                PlanError::InvalidInput(format!(
                    "held: '{name}' is not a grasp of '{}' for {}",
                    task.object, giver.end_effector
                ))
            })?;
            (q0.clone(), set.tcps[k], name.clone())
        }
        None => match grasp_holding(scene, &world, &q0, &giver, &task.object)? {
            Some(k) => (q0.clone(), set.tcps[k], set.names[k].clone()),
            None => {
                let p1 = ReachProblem::grasp(
                    scene,
                    &world,
                    &q0,
                    &task.giver.0,
                    &task.giver.1,
                    &task.object,
                )
                .map_err(|e| tagged("grasp", e))?;
                let r1 = task
                    .algorithm
                    .plan_reach(&p1, task.grid.clone(), task.planner, task.ik, term, seed)
                    .map_err(|e| tagged("grasp", e))?;
                let q1 = p1.space.to_world(r1.path.last().map_or(&p1.start, |v| v));
                let path = p1.space.path_to_world(&r1.path);
                plan.waypoints.clear();
                plan.append(
                    "grasp",
                    task.algorithm.reach_name(),
                    path,
                    r1.stats,
                    &p1.world,
                );
                let name = p1.grasp_names[r1.goal_index].clone();
                plan.event(
                    EventKind::Grasp,
                    &task.giver.0,
                    &giver.end_effector,
                    &task.object,
                    &name,
                );
                (q1, p1.grasps[r1.goal_index], name)
            }
        },
    };
    let p2 = HandOffProblem::new(
        scene,
        &world,
        &q1,
        (&task.giver.0, &task.giver.1),
        (&task.receiver.0, &task.receiver.1),
        &task.object,
        held,
    )
    .map_err(|e| tagged("regrasp", e))?;
    let r2 = task
        .algorithm
        .plan_regrasp(
            &p2,
            task.grid.clone(),
            task.planner,
            task.ik,
            term,
            seed.wrapping_add(1),
        )
        .map_err(|e| tagged("regrasp", e))?;
    let path = p2.space.path_to_world(&r2.path);
    if plan.phases.is_empty() {
        plan.waypoints.clear();
    }
    plan.append(
        "regrasp",
        task.algorithm.regrasp_name(),
        path,
        r2.stats,
        &p2.world,
    );
    plan.event(
        EventKind::Grasp,
        &task.receiver.0,
        &p2.receiver.end_effector,
        &task.object,
        &p2.grasp_names[r2.goal_index],
    );
    plan.event(
        EventKind::Release,
        &task.giver.0,
        &p2.giver.end_effector,
        &task.object,
        &held_name,
    );
    plan.time = t0.elapsed();
    Ok(plan)
}

/// Names of a world's configuration variables (`robot/joint`), in world order.
pub fn world_variables(world: &CollisionWorld) -> Vec<String> {
    world
        .robots
        .iter()
        .flat_map(|p| {
            (0..p.robot.dof()).map(move |v| format!("{}/{}", p.name, p.robot.var_name(v)))
        })
        .collect()
}

impl TaskPlan {
    /// The plan's time-optimal trajectory ([`crate::trajectory::timing`]) in `world` (the plan's world:
    /// every robot of the scene), at rest at every grasp and release.
    pub fn trajectory(
        &self,
        world: &CollisionWorld,
        opts: &TimingOptions,
    ) -> Result<manyhands_api::JointTrajectory, TimingError> {
        let limits =
            world_limits(world).scaled(opts.velocity_scaling, opts.acceleration_scaling)?;
        let rest: Vec<usize> = self.events.iter().map(|e| e.waypoint).collect();
        let timed = time_polyline(&self.waypoints, &limits, &rest)?;
        let events = self
            .events
            .iter()
            .map(|e| manyhands_api::TrajectoryEvent {
                kind: match e.kind {
                    EventKind::Grasp => "grasp".into(),
                    EventKind::Release => "release".into(),
                },
                time_from_start: timed.waypoint_times[e.waypoint],
                waypoint: Some(e.waypoint),
                robot: e.robot.clone(),
                end_effector: e.end_effector.clone(),
                object: e.object.clone(),
                grasp: e.grasp.clone(),
            })
            .collect();
        timed.to_trajectory(&world_variables(world), opts.sample_period, events)
    }

    /// JSON of the plan in `world` (its scene's world): variable names, waypoints (world
    /// configurations), phases with their statistics (ms), events, the total time and the
    /// timed `trajectory` ([`Self::trajectory`]).
    pub fn to_json(
        &self,
        world: &CollisionWorld,
        opts: &TimingOptions,
    ) -> Result<serde_json::Value, TimingError> {
        let variables = world_variables(world);
        let trajectory = self.trajectory(world, opts)?;
        Ok(serde_json::json!({
            "variables": variables,
            "waypoints": self.waypoints,
            "phases": self.phases.iter().map(|p| serde_json::json!({
                "name": p.name,
                "planner": p.planner,
                "first": p.first,
                "last": p.last,
                "stats": p.stats.to_json(),
            })).collect::<Vec<_>>(),
            "events": self.events,
            "time_ms": self.time.as_secs_f64() * 1e3,
            "trajectory": trajectory,
        }))
    }

    /// Sum of the phases' statistics' times (search + simplification), IK time included.
    pub fn planning_time(&self) -> Duration {
        self.phases
            .iter()
            .map(|p| p.stats.time + p.stats.simplify_time)
            .sum()
    }

    /// Sum of the phases' IK times (000 Table 5's "IK solving").
    pub fn ik_time(&self) -> Duration {
        self.phases.iter().map(|p| p.stats.ik_time).sum()
    }
}

/// The checks of [`reach_task`]'s problem without planning: the hand, the object and — before
/// any reachability grid is built — whether any of its grasps is within the arm's reach
/// ([`crate::planning::problems::grasping::Hand::check_reach`]). Cheap (no search).
pub fn precheck_reach(
    scene: &Scene,
    robot: &str,
    group: &str,
    object: &str,
) -> Result<(), PlanError> {
    let world = CollisionWorld::from_scene(scene);
    let q0 = CollisionWorld::start_config(scene);
    ReachProblem::grasp(scene, &world, &q0, robot, group, object).map(|_| ())
}

/// A single grasp (000 §IV: IK-RRT or J+-RRT) from `scene`'s start as a one-phase plan ending
/// in a grasp event.
#[allow(clippy::too_many_arguments)]
pub fn reach_task(
    scene: &Scene,
    robot: &str,
    group: &str,
    object: &str,
    grid: Option<Arc<ReachabilityGrid>>,
    algorithm: GraspAlgorithm,
    planner: IkRrtSettings,
    ik: RandomizedIkSettings,
    term: &mut Termination,
    seed: u64,
) -> Result<TaskPlan, PlanError> {
    let t0 = Instant::now();
    let world = CollisionWorld::from_scene(scene);
    let q0 = CollisionWorld::start_config(scene);
    let p = ReachProblem::grasp(scene, &world, &q0, robot, group, object)?;
    let r = algorithm.plan_reach(&p, grid, planner, ik, term, seed)?;
    let mut plan = TaskPlan {
        waypoints: Vec::new(),
        phases: Vec::new(),
        events: Vec::new(),
        time: Duration::ZERO,
    };
    let path = p.space.path_to_world(&r.path);
    plan.append("grasp", algorithm.reach_name(), path, r.stats, &p.world);
    plan.event(
        EventKind::Grasp,
        robot,
        &p.hand.end_effector,
        object,
        &p.grasp_names[r.goal_index],
    );
    plan.time = t0.elapsed();
    Ok(plan)
}

/// Bimanual IK-RRT (002 Alg. 2) on a prepared problem as a one-phase plan ending in the two
/// grasp events.
pub fn bimanual_task(
    p: &crate::planning::planners::bimanual_ik_rrt::BimanualProblem,
    planner: IkRrtSettings,
    ik: RandomizedIkSettings,
    term: &mut Termination,
    seed: u64,
) -> Result<TaskPlan, PlanError> {
    let t0 = Instant::now();
    let r = p.plan(planner, ik, term, seed)?;
    let mut plan = TaskPlan {
        waypoints: Vec::new(),
        phases: Vec::new(),
        events: Vec::new(),
        time: Duration::ZERO,
    };
    let path = p.space.path_to_world(&r.path);
    plan.append("grasp", "bimanual_ik_rrt", path, r.stats, &p.world);
    let (l, rr) = p.decode(r.goal_index);
    let robot = p.world.robots[p.left.robot].name.clone();
    plan.event(
        EventKind::Grasp,
        &robot,
        &p.left.end_effector,
        &p.object,
        &p.left_names[l],
    );
    plan.event(
        EventKind::Grasp,
        &robot,
        &p.right.end_effector,
        &p.object,
        &p.right_names[rr],
    );
    plan.time = t0.elapsed();
    Ok(plan)
}
