//! Multi-Robot-RRT (paper 002 = Vahrenkamp et al. 2010, §IV-B/C, Alg. 3): n mobile two-armed
//! robots grasp one object together.
//!
//! One Bimanual IK-RRT worker per robot ([`crate::planning::planners::bimanual_ik_rrt`], 002 Alg. 2) plans in the
//! static environment — the other robots are ignored, as in the paper — and keeps producing
//! solution trajectories until it is stopped: each solution is a new Bimanual IK-RRT search with
//! the worker's next seed (the maps and grasp sets are built once per worker); a solution whose
//! grasp pair and final configuration repeat an earlier one of the same worker is dropped, so
//! every stored solution is distinct. (The paper does not say whether a sub-planner keeps its
//! trees between solutions; a fresh search per solution keeps each one a plain Alg. 2 run.)
//!
//! A **collector** (the calling thread) receives every new solution over a channel and evaluates
//! only the combinations it enables — the new s_k with every stored solution of each other robot,
//! each combination once — cheapest test first (Alg. 3 lines 7–10):
//! 1. the final configurations of all robots do not collide with each other;
//! 2. the **grasp score** — the Ferrari–Canny ε of the L1 wrench space of all contacts of all
//!    hands ([`crate::grasp`], centre of mass and λ = 1 / radius of the object, 002 §IV-B) —
//!    exceeds s_min. Decided without the whole wrench hull: first a proof that ε > s_min
//!    ([`crate::grasp::score_exceeds_nearest`]: the hull grown toward the origin until all its
//!    facets are farther than s_min plus the joggle bound), and the exact ε, where it is
//!    reported (a rejection's score, the accepted combination), from the nearest facets alone
//!    ([`crate::grasp::quality_of_wrenches_nearest`], the full hull's value and verdict, falling
//!    back to the full hull where it cannot decide); `tests/grasp_nearest.rs` compares both
//!    with the full hull;
//! 3. the **deadlock check** (002 eq. 2): for every robot k, its start and its goal configuration
//!    collide with no configuration on any other robot's trajectory, checked as continuous motion
//!    ([`crate::collision::FastChecker::motion_certified`] on the robots alone, links and what
//!    they hold). Then sequential execution is always possible.
//!
//! Tests 1 and 3 are pairwise, so their verdicts are cached per pair of solutions (the
//! collector is in the submodule `collector`). On the first
//! combination that passes, every worker is stopped and the trajectories are scheduled for
//! simultaneous execution by [`crate::planning::planners::phase_space`] (002 §V). The time limit and the stop flag
//! reach every worker through its [`Termination`] (one atomic load per iteration) and the
//! collector through a 1 ms receive timeout, so all stop within a few milliseconds.
//!
//! **Threads.** Parallel mode (the default): one OS thread per worker inside a
//! `std::thread::scope` (a rayon scope would starve workers when there are more robots than
//! pool threads, since workers only end when stopped) and the collector on the calling thread;
//! results depend on timing. Deterministic mode: the workers are stepped round-robin on the
//! calling thread, one solution per step with per-worker seeded streams, and the collector
//! evaluates after each step, so request + seed → the same plan.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::sync::Arc;
use std::time::{Duration, Instant};

use nalgebra::Vector3;

mod collector;

use collector::Collector;

use crate::collision::CollisionWorld;
use crate::grasp::{grasp_contacts, grasp_quality, object_centre, object_radius, Contact};
use crate::grasp::{
    primitive_wrenches_into, quality_of_wrenches_nearest, GraspQuality, Point6, WrenchSpaceSettings,
};
use crate::kinematics::randomized::RandomizedIkSettings;
use crate::model::Scene;
use crate::planning::planners::bimanual_ik_rrt::{BimanualProblem, BimanualSettings};
use crate::planning::planners::phase_space::{
    PhaseSpace, PhaseSpaceSettings, RobotTrajectory, Schedule,
};
use crate::planning::{IkRrtSettings, PlanError, PlanStats, StopReason, Termination};
use crate::reachability::{GridCache, GridRecipe, ReachabilityGrid};

/// Settings of Multi-Robot-RRT.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiRobotSettings {
    /// Minimum grasp score s_min (Alg. 3 line 10): a combination passes when ε > s_min.
    pub s_min: f64,
    /// Wrench space of the score (μ, cone edges; λ `None` = 1 / the object's radius).
    pub wrench: WrenchSpaceSettings,
    /// The workers' Bimanual IK-RRT (p_IK 0.03 in 002 §VI).
    pub planner: IkRrtSettings,
    pub ik: RandomizedIkSettings,
    pub maps: BimanualSettings,
    /// Most solutions a worker stores (it stops producing after that).
    pub max_solutions: usize,
    /// Round-robin on one thread, reproducible (module documentation).
    pub deterministic: bool,
    pub phase: PhaseSpaceSettings,
}

impl Default for MultiRobotSettings {
    fn default() -> Self {
        MultiRobotSettings {
            s_min: 0.0,
            wrench: WrenchSpaceSettings::default(),
            planner: crate::planning::planners::bimanual_ik_rrt::paper_settings(),
            ik: RandomizedIkSettings::default(),
            maps: BimanualSettings::default(),
            max_solutions: 32,
            deterministic: false,
            phase: PhaseSpaceSettings::default(),
        }
    }
}

/// Most robots of one Multi-Robot-RRT problem.
pub const MAX_ROBOTS: usize = 8;

/// One robot of a Multi-Robot-RRT problem: its worker's Bimanual IK-RRT problem.
pub struct MultiRobotMember {
    /// Index of the robot in the problem's world.
    pub robot: usize,
    pub name: String,
    pub problem: BimanualProblem,
    /// Contacts (object frame) of each left and right grasp.
    left_contacts: Vec<Vec<Contact>>,
    right_contacts: Vec<Vec<Contact>>,
}

/// n robots of a scene grasping one object together.
pub struct MultiRobotProblem {
    /// The scene's world (all robots, the object resting).
    pub world: CollisionWorld,
    pub world_q: Vec<f64>,
    pub object: String,
    pub members: Vec<MultiRobotMember>,
    /// Object centre of mass and radius (object frame), for the score.
    centre: Vector3<f64>,
    radius: f64,
    /// Time spent on the inverse maps of all robots.
    pub map_time: Duration,
}

/// The robots of a [`MultiRobotProblem`]: instance name, left and right chain groups (from the
/// platform), and their reachability grids.
pub struct MemberSpec<'a> {
    pub robot: &'a str,
    pub left: &'a str,
    pub right: &'a str,
    pub grids: (&'a ReachabilityGrid, &'a ReachabilityGrid),
}

impl MultiRobotProblem {
    /// The problem of `members` grasping `object` of `scene`, every robot from its scene start.
    pub fn new(
        scene: &Scene,
        members: &[MemberSpec<'_>],
        object: &str,
        maps: BimanualSettings,
    ) -> Result<MultiRobotProblem, PlanError> {
        if members.is_empty() || members.len() > MAX_ROBOTS {
            return Err(PlanError::InvalidInput(format!(
                "robots: 1 to {MAX_ROBOTS} robots, got {}",
                members.len()
            )));
        }
        let world = CollisionWorld::from_scene(scene);
        let world_q = CollisionWorld::start_config(scene);
        let obj = scene.object(object).ok_or_else(|| {
            PlanError::InvalidInput(format!("object: the scene has no object '{object}'"))
        })?;
        let (centre, _) = object_centre(&obj.body.shapes);
        let radius = object_radius(&obj.body.shapes, &centre);
        let t0 = Instant::now();
        let mut out: Vec<MultiRobotMember> = Vec::with_capacity(members.len());
        for (k, m) in members.iter().enumerate() {
            let r = world
                .robots
                .iter()
                .position(|p| p.name == m.robot)
                .ok_or_else(|| {
                    PlanError::InvalidInput(format!(
                        "robots[{k}].name: the scene has no robot '{}'",
                        m.robot
                    ))
                })?;
            if out.iter().any(|o| o.robot == r) {
                return Err(PlanError::InvalidInput(format!(
                    "robots[{k}].name: robot '{}' given twice",
                    m.robot
                )));
            }
            let sub = world
                .subset(&[r])
                .ok_or_else(|| PlanError::InvalidInput(format!("robots[{k}]: robot index {r}")))?;
            let sub_q = world.subset_config(&[r], &world_q);
            let problem = BimanualProblem::new(
                scene,
                &sub,
                &sub_q,
                m.robot,
                (m.left, m.right),
                object,
                m.grids,
                maps,
            )
            .map_err(|e| match e {
                PlanError::InvalidInput(s) => PlanError::InvalidInput(format!("robots[{k}]: {s}")),
                e => PlanError::InPhase {
                    phase: format!("robot '{}'", m.robot),
                    error: Box::new(e),
                },
            })?;
            let contacts = |names: &[String]| -> Vec<Vec<Contact>> {
                names
                    .iter()
                    .map(|n| {
                        obj.grasps
                            .iter()
                            .find(|g| &g.name == n)
                            .map(grasp_contacts)
                            .unwrap_or_default()
                    })
                    .collect()
            };
            out.push(MultiRobotMember {
                robot: r,
                name: m.robot.to_string(),
                left_contacts: contacts(&problem.left_names),
                right_contacts: contacts(&problem.right_names),
                problem,
            });
        }
        Ok(MultiRobotProblem {
            world,
            world_q,
            object: object.to_string(),
            members: out,
            centre,
            radius,
            map_time: t0.elapsed(),
        })
    }

    /// [`MultiRobotProblem::new`] with every robot's (left, right) platform-frame grids taken
    /// from `cache` (built on first use with `recipe`).
    #[allow(clippy::too_many_arguments)]
    pub fn with_grids(
        scene: &Scene,
        names: &[String],
        left: &str,
        right: &str,
        object: &str,
        cache: &GridCache,
        recipe: GridRecipe,
        maps: BimanualSettings,
    ) -> Result<MultiRobotProblem, PlanError> {
        let mut grids: Vec<(Arc<ReachabilityGrid>, Arc<ReachabilityGrid>)> = Vec::new();
        for (k, n) in names.iter().enumerate() {
            let model = scene
                .robot(n)
                .ok_or_else(|| {
                    PlanError::InvalidInput(format!("robots[{k}]: the scene has no robot '{n}'"))
                })?
                .robot
                .clone();
            let grid = |g: &str| {
                cache
                    .get(&model, g, recipe)
                    .map_err(|e| PlanError::InvalidInput(format!("robots[{k}]: {e}")))
            };
            grids.push((grid(left)?, grid(right)?));
        }
        let specs: Vec<MemberSpec<'_>> = names
            .iter()
            .zip(&grids)
            .map(|(n, (gl, gr))| MemberSpec {
                robot: n,
                left,
                right,
                grids: (gl, gr),
            })
            .collect();
        MultiRobotProblem::new(scene, &specs, object, maps)
    }

    /// The contacts of a combination and the score settings with λ filled in.
    fn score_input(
        &self,
        grasps: &[(usize, usize)],
        wrench: &WrenchSpaceSettings,
    ) -> (Vec<Contact>, WrenchSpaceSettings) {
        let mut contacts = Vec::new();
        for (m, &(l, r)) in self.members.iter().zip(grasps) {
            contacts.extend_from_slice(&m.left_contacts[l]);
            contacts.extend_from_slice(&m.right_contacts[r]);
        }
        let settings = WrenchSpaceSettings {
            lambda: wrench
                .lambda
                .or_else(|| (self.radius > 0.0).then(|| 1.0 / self.radius)),
            ..*wrench
        };
        (contacts, settings)
    }

    /// The grasp score of a combination: ε of all contacts of all hands (002 §IV-B), with
    /// `wrench.cone_edges` edges per friction cone.
    pub fn score(
        &self,
        grasps: &[(usize, usize)],
        wrench: &WrenchSpaceSettings,
    ) -> Result<GraspQuality, PlanError> {
        let (contacts, settings) = self.score_input(grasps, wrench);
        grasp_quality(&contacts, &self.centre, &settings)
            .map_err(|e| PlanError::InvalidInput(format!("grasp score: {e}")))
    }

    /// The scheduler's input for some solutions: each one's robot and path, with the robot's
    /// acceleration limits (its joint-limits file or the default,
    /// [`crate::Robot::acceleration_limit`]), so that the schedule starts and ends at rest and
    /// its trajectories respect both limits.
    pub fn trajectories(&self, solutions: &[Solution]) -> Vec<RobotTrajectory> {
        solutions
            .iter()
            .map(|s| {
                let robot = self.members[s.member].robot;
                let model = &self.world.robots[robot].robot;
                RobotTrajectory {
                    robot,
                    waypoints: s.path.clone(),
                    accelerations: Some(
                        (0..model.dof())
                            .map(|v| model.acceleration_limit(v))
                            .collect(),
                    ),
                }
            })
            .collect()
    }

    /// The primitive wrenches of all contacts of a combination (002 §IV-B) and λ.
    pub fn combination_wrenches(
        &self,
        grasps: &[(usize, usize)],
        wrench: &WrenchSpaceSettings,
    ) -> Result<(Vec<Point6>, f64), PlanError> {
        let (contacts, settings) = self.score_input(grasps, wrench);
        let mut all = Vec::new();
        let lambda = primitive_wrenches_into(&contacts, &self.centre, &settings, &mut all)
            .map_err(|e| PlanError::InvalidInput(format!("grasp score: {e}")))?;
        Ok((all, lambda))
    }

    /// Whether the score of a combination exceeds `s_min`, and the score: the exact ε of
    /// [`MultiRobotProblem::score`] (the same verdict and value to round-off), computed by
    /// [`quality_of_wrenches_nearest`], which grows the wrench hull only toward the origin
    /// (`crate::grasp::hull` module `nearest`) instead of building all of it. Returns (pass,
    /// quality, cone edges used = `wrench.cone_edges`).
    pub fn score_exceeds(
        &self,
        grasps: &[(usize, usize)],
        wrench: &WrenchSpaceSettings,
        s_min: f64,
    ) -> Result<(bool, GraspQuality, usize), PlanError> {
        let (all, lambda) = self.combination_wrenches(grasps, wrench)?;
        let q = quality_of_wrenches_nearest(&all, lambda)
            .map_err(|e| PlanError::InvalidInput(format!("grasp score: {e}")))?;
        Ok((q.force_closure && q.epsilon > s_min, q, wrench.cone_edges))
    }
}

/// A solution trajectory of one worker.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// Index of the member (worker).
    pub member: usize,
    /// The robot's configurations (all its variables), start to goal.
    pub path: Vec<Vec<f64>>,
    /// Left and right grasp indices.
    pub grasps: (usize, usize),
    pub stats: PlanStats,
}

/// Why a combination was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Rejection {
    /// The final configurations of two robots collide.
    Collision,
    /// The grasp score is not above s_min.
    Score,
    /// 002 eq. 2 fails.
    Deadlock,
}

/// Per-worker statistics (002 Tables I and II, per sub-planner).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WorkerStats {
    pub name: String,
    /// Bimanual IK-RRT searches started.
    pub searches: u64,
    /// Searches that ended with a solution (distinct or not).
    pub solved: u64,
    /// Distinct solution trajectories delivered.
    pub solutions: u64,
    /// IK results: valid goal configurations added to the goal trees.
    pub ik_results: u64,
    pub collision_checks: u64,
    pub time: Duration,
}

/// Statistics of one Multi-Robot-RRT run (002 Tables I and II).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MultiRobotStats {
    /// Until the accepted combination (workers and collector).
    pub planning_time: Duration,
    /// Phase-space scheduling.
    pub phase_space_time: Duration,
    pub total_time: Duration,
    pub workers: Vec<WorkerStats>,
    /// n-handed grasp configurations (combinations) checked, and rejected by reason.
    pub combinations: u64,
    pub rejected_collision: u64,
    pub rejected_score: u64,
    pub rejected_deadlock: u64,
    /// Collector collision checks (final poses and deadlock, certified segments count one each).
    pub collector_checks: u64,
    /// Scoring: combinations scored, total time, and how many of them needed the exact ε
    /// (a rejection's reported score, the accepted combination) beyond the cheap proof.
    pub scores: u64,
    pub score_time: Duration,
    pub exact_scores: u64,
    pub best_score: f64,
}

impl MultiRobotStats {
    /// Sum of IK results over workers.
    pub fn ik_results(&self) -> u64 {
        self.workers.iter().map(|w| w.ik_results).sum()
    }
    /// Sum of solution trajectories over workers.
    pub fn solutions(&self) -> u64 {
        self.workers.iter().map(|w| w.solutions).sum()
    }
    /// Collision checks of workers and collector.
    pub fn collision_checks(&self) -> u64 {
        self.workers.iter().map(|w| w.collision_checks).sum::<u64>() + self.collector_checks
    }
}

/// What the collector reports while it runs.
#[derive(Debug, Clone, PartialEq)]
pub enum MultiRobotEvent<'a> {
    /// A worker delivered a new solution.
    Solution { robot: &'a str, count: u64 },
    /// A combination was checked.
    Combination {
        checked: u64,
        rejected: Option<Rejection>,
        score: Option<f64>,
        best: f64,
    },
    /// A combination passed; scheduling starts.
    Scheduling,
}

/// The accepted combination, its schedule and the statistics.
#[derive(Debug, Clone)]
pub struct MultiRobotPlan {
    /// Per member: its solution.
    pub solutions: Vec<Solution>,
    /// The score that passed: the exact ε at `score_edges` cone edges, which are the requested
    /// ones ([`MultiRobotProblem::score_exceeds`]; the result JSON keeps `cone_edges` and
    /// `lower_bound: false` for clients of the earlier cone-subset levels).
    pub score: GraspQuality,
    pub score_edges: usize,
    /// The cone edges the request asked for.
    pub requested_edges: usize,
    pub schedule: Schedule,
    pub stats: MultiRobotStats,
}

/// One worker's source of solutions: successive Bimanual IK-RRT searches with seeds
/// `seed_of(seed, member, attempt)`, repeats dropped.
struct Worker<'p> {
    member: usize,
    p: &'p MultiRobotMember,
    seed: u64,
    attempt: u64,
    delivered: Vec<((usize, usize), Vec<f64>)>,
    stats: WorkerStats,
    /// An error no further search can change (the start invalid, bad input): ends the run.
    fatal: Option<PlanError>,
}

/// A seed per (run seed, member, attempt): SplitMix64 of the three.
fn seed_of(seed: u64, member: usize, attempt: u64) -> u64 {
    let mut z = seed
        ^ (member as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ attempt.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl<'p> Worker<'p> {
    /// Runs searches until one gives a new distinct solution, or the termination ends; `None`
    /// when stopped.
    fn next(&mut self, s: &MultiRobotSettings, term: &mut Termination) -> Option<Solution> {
        loop {
            if term.should_stop_now() {
                return None;
            }
            let seed = seed_of(self.seed, self.member, self.attempt);
            self.attempt += 1;
            self.stats.searches += 1;
            let t = Instant::now();
            let r = self.p.problem.plan(s.planner, s.ik, term, seed);
            self.stats.time += t.elapsed();
            match r {
                Ok(r) => {
                    self.stats.solved += 1;
                    self.stats.ik_results += r.stats.ik_solutions;
                    self.stats.collision_checks += r.stats.collision_checks;
                    let grasps = self.p.problem.decode(r.goal_index);
                    let path = self.p.problem.space.path_to_world(&r.path);
                    let goal = path.last().cloned().unwrap_or_default();
                    let repeat = self.delivered.iter().any(|(g, q)| {
                        *g == grasps && q.iter().zip(&goal).all(|(a, b)| (a - b).abs() < 1e-3)
                    });
                    if repeat {
                        continue;
                    }
                    self.delivered.push((grasps, goal));
                    self.stats.solutions += 1;
                    return Some(Solution {
                        member: self.member,
                        path,
                        grasps,
                        stats: r.stats,
                    });
                }
                Err(e) => {
                    if let Some(st) = e.stats() {
                        self.stats.ik_results += st.ik_solutions;
                        self.stats.collision_checks += st.collision_checks;
                    }
                    match e {
                        PlanError::Timeout { .. } | PlanError::Stopped { .. } => return None,
                        PlanError::InvalidStart { .. } | PlanError::InvalidInput(_) => {
                            self.fatal = Some(e);
                            return None;
                        }
                        // A search that ended otherwise (no goal found this time): try again.
                        _ => continue,
                    }
                }
            }
        }
    }
}

/// Runs Multi-Robot-RRT (002 Alg. 3) and schedules the accepted trajectories (002 §V).
pub fn multi_robot_rrt(
    p: &MultiRobotProblem,
    settings: &MultiRobotSettings,
    term: &mut Termination,
    seed: u64,
    progress: &mut dyn FnMut(MultiRobotEvent<'_>),
) -> Result<MultiRobotPlan, PlanError> {
    let t0 = Instant::now();
    if !(settings.s_min.is_finite() && settings.s_min >= 0.0) {
        return Err(PlanError::InvalidInput(
            "s_min: must be finite and ≥ 0".into(),
        ));
    }
    if settings.max_solutions == 0 {
        return Err(PlanError::InvalidInput("max_solutions: must be ≥ 1".into()));
    }
    settings
        .wrench
        .validate()
        .map_err(|e| PlanError::InvalidInput(e.to_string()))?;
    let mut collector = Collector::new(p, settings);
    let mut workers: Vec<Worker<'_>> = p
        .members
        .iter()
        .enumerate()
        .map(|(k, m)| Worker {
            member: k,
            p: m,
            seed,
            attempt: 0,
            delivered: Vec::new(),
            stats: WorkerStats {
                name: m.name.clone(),
                ..WorkerStats::default()
            },
            fatal: None,
        })
        .collect();
    let found = if settings.deterministic {
        deterministic(&mut collector, &mut workers, settings, term, progress)
    } else {
        parallel(&mut collector, &mut workers, settings, term, progress)
    };
    let mut stats = std::mem::take(&mut collector.stats);
    for (s, w) in stats.workers.iter_mut().zip(&workers) {
        *s = w.stats.clone();
    }
    stats.planning_time = t0.elapsed();
    if let Some(w) = workers.iter_mut().find(|w| w.fatal.is_some()) {
        if let Some(e) = w.fatal.take() {
            return Err(PlanError::InPhase {
                phase: format!("robot '{}'", w.stats.name),
                error: Box::new(e),
            });
        }
    }
    let Some((idx, score)) = found else {
        let ps = PlanStats {
            time: t0.elapsed(),
            collision_checks: stats.collision_checks(),
            ik_solutions: stats.ik_results(),
            ..PlanStats::default()
        };
        let reason = term.reason().unwrap_or(StopReason::IterationLimit);
        return Err(match reason {
            StopReason::IterationLimit => PlanError::InvalidGoal {
                count: stats.combinations as usize,
                reason: format!(
                    "every worker stored {} solutions and no combination passed ({} by collision, {} by score, {} by deadlock)",
                    settings.max_solutions,
                    stats.rejected_collision,
                    stats.rejected_score,
                    stats.rejected_deadlock
                ),
            },
            r => PlanError::stopped(r, ps),
        });
    };
    progress(MultiRobotEvent::Scheduling);
    let solutions: Vec<Solution> = idx
        .iter()
        .enumerate()
        .map(|(k, &i)| collector.solutions[k][i].clone())
        .collect();
    let t1 = Instant::now();
    let trajectories = p.trajectories(&solutions);
    let mut ps = PhaseSpace::new(&p.world, &p.world_q, &trajectories)?;
    let schedule = ps
        .plan(&settings.phase, term, seed)
        .map_err(|e| e.in_phase("phase space"))?;
    stats.phase_space_time = t1.elapsed();
    stats.total_time = t0.elapsed();
    Ok(MultiRobotPlan {
        solutions,
        score,
        score_edges: collector.score_edges,
        requested_edges: settings.wrench.cone_edges,
        schedule,
        stats,
    })
}

fn deterministic(
    c: &mut Collector<'_>,
    workers: &mut [Worker<'_>],
    s: &MultiRobotSettings,
    term: &mut Termination,
    progress: &mut dyn FnMut(MultiRobotEvent<'_>),
) -> Option<(Vec<usize>, GraspQuality)> {
    loop {
        let mut any = false;
        for w in workers.iter_mut() {
            if w.stats.solutions as usize >= s.max_solutions {
                continue;
            }
            any = true;
            let sol = w.next(s, term)?;
            if let Some(r) = c.add(sol, progress) {
                return Some(r);
            }
        }
        if !any {
            return None;
        }
    }
}

fn parallel(
    c: &mut Collector<'_>,
    workers: &mut [Worker<'_>],
    s: &MultiRobotSettings,
    term: &mut Termination,
    progress: &mut dyn FnMut(MultiRobotEvent<'_>),
) -> Option<(Vec<usize>, GraspQuality)> {
    let stop = Arc::new(AtomicBool::new(false));
    let (tx, rx) = mpsc::channel::<Solution>();
    let limit = term.remaining();
    std::thread::scope(|scope| {
        for w in workers.iter_mut() {
            let tx = tx.clone();
            let stop = stop.clone();
            scope.spawn(move || {
                let mut t = Termination::new().with_stop_flag(stop.clone());
                if let Some(l) = limit {
                    t = t.with_time_limit(l);
                }
                while (w.stats.solutions as usize) < s.max_solutions {
                    match w.next(s, &mut t) {
                        Some(sol) => {
                            if tx.send(sol).is_err() {
                                break;
                            }
                        }
                        None => break,
                    }
                }
                if w.fatal.is_some() {
                    // No combination can pass without this robot: stop the others too.
                    stop.store(true, Ordering::Relaxed);
                }
            });
        }
        drop(tx);
        let mut result = None;
        loop {
            if term.should_stop_now() || stop.load(Ordering::Relaxed) {
                break;
            }
            match rx.recv_timeout(Duration::from_millis(1)) {
                Ok(sol) => {
                    if let Some(r) = c.add(sol, progress) {
                        result = Some(r);
                        break;
                    }
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
        }
        stop.store(true, Ordering::Relaxed);
        result
    })
}

mod json;

#[cfg(test)]
mod tests;
