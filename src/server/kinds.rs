//! Job kinds: how a `PlanRequest` becomes work for a planner worker. A kind is a
//! [`JobWork`] implementation plus a `prepare` step that validates the request against the
//! catalog (errors name the field) and resolves everything the worker needs, so the work does
//! not depend on later uploads or deletions. Adding a planner = a `PlanRequest` variant, a
//! `prepare_*` function and a `JobWork` impl.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};

use crate::collision::{AutoChecker, BodyId, CollisionWorld, FastChecker};
use crate::planning::{
    base::halton, JointSpace, PlanError, PlanStats, RrtConnect, RrtConnectSettings, Sampler,
    ShortcutSettings, Termination,
};

use super::api::{
    CollisionSweep, GraspPlanRequest, GraspPlanSettings, JointSpacePlan, PlanRequest, SamplerName,
};
use super::builds::Builds;
use super::catalog::Catalog;
use super::error::{ApiError, ApiResult};
use super::queries::{apply_config, placement_base};
use crate::kinematics::randomized::ArmChain;
use crate::kinematics::randomized::RandomizedIkSettings;
use crate::model::Scene;
use crate::planning::planners::bimanual_ik_rrt::{BimanualProblem, BimanualSettings};
use crate::planning::tasks::task::{
    bimanual_task, kitchen_task, reach_task, regrasp_task, GraspAlgorithm, KitchenTask, RegraspTask,
};
use crate::planning::IkRrtSettings;
use crate::reachability::{GridCache, GridRecipe, ReachError};
use crate::trajectory::timing::{time_polyline, world_limits, TimingError, TimingOptions};

/// Why a job did not succeed.
#[derive(Debug, Clone)]
pub struct JobFailure {
    /// Ended by its stop flag (cancel or shutdown) rather than by a failure.
    pub stopped: bool,
    pub code: &'static str,
    pub message: String,
    /// Statistics gathered before the failure.
    pub stats: Option<Value>,
}

/// What a worker gets besides the work: the stop flag, the time limit (counted from the job's
/// start, first-use builds included: see [`super::builds`]), the builds and a progress sink.
pub struct JobContext {
    pub stop: Arc<AtomicBool>,
    pub time_limit: Duration,
    /// When the job started on its planner thread.
    pub started: Instant,
    /// The first-use builds of this process (grids, grasp lists, roadmaps).
    pub builds: Arc<Builds>,
    progress: Box<dyn FnMut(Value) + Send>,
}

impl JobContext {
    pub fn new(
        stop: Arc<AtomicBool>,
        time_limit: Duration,
        progress: Box<dyn FnMut(Value) + Send>,
    ) -> JobContext {
        JobContext {
            stop,
            time_limit,
            started: Instant::now(),
            builds: Arc::new(Builds::default()),
            progress,
        }
    }

    /// This context sharing the process's `builds` (a later job waits for a build an earlier
    /// one started).
    pub fn with_builds(mut self, builds: Arc<Builds>) -> JobContext {
        self.builds = builds;
        self
    }

    /// Time since the job started.
    pub fn elapsed(&self) -> Duration {
        self.started.elapsed()
    }

    /// Time left before the time limit (zero once it is reached).
    pub fn remaining(&self) -> Duration {
        self.time_limit.saturating_sub(self.started.elapsed())
    }

    /// Has the time limit (counted from the job's start) been reached?
    pub fn past_limit(&self) -> bool {
        self.remaining().is_zero()
    }

    /// The answer of a job whose time limit came while it waited for the first-use build of
    /// `what` (which goes on in the background for later jobs).
    pub fn build_timeout(&self, what: &str) -> JobFailure {
        JobFailure {
            stopped: false,
            code: "timeout",
            message: format!(
                "time limit {} s reached {:.3} s after the job started, while building {what} \
                 (first use: the build goes on in the background and later jobs reuse it)",
                self.time_limit.as_secs_f64(),
                self.elapsed().as_secs_f64()
            ),
            stats: None,
        }
    }

    /// Publishes a progress snapshot (SSE `progress` event, `progress` of the job record).
    pub fn progress(&mut self, v: Value) {
        (self.progress)(v)
    }

    /// The planner termination condition of this job: time limit (from the job's start) and
    /// stop flag.
    pub fn termination(&self) -> Termination {
        Termination::since(self.started)
            .with_time_limit(self.time_limit)
            .with_stop_flag(self.stop.clone())
    }

    pub fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }
}

/// A prepared job, run once on a planner worker thread.
pub trait JobWork: Send + 'static {
    fn run(self: Box<Self>, ctx: &mut JobContext) -> Result<Value, JobFailure>;
}

/// A validated request ready to queue.
pub struct Prepared {
    pub work: Box<dyn JobWork>,
    /// Effective time limit in seconds.
    pub time_limit: f64,
}

/// Default time limit of a job when the request gives none, in seconds.
pub const DEFAULT_TIME_LIMIT: f64 = 10.0;

pub(super) fn time_limit(t: Option<f64>, max: f64) -> ApiResult<f64> {
    match t {
        None => Ok(DEFAULT_TIME_LIMIT.min(max)),
        Some(t) if t.is_finite() && t > 0.0 => Ok(t.min(max)),
        Some(t) => Err(ApiError::invalid(
            "time_limit",
            format!("{t} is not a positive number of seconds"),
        )),
    }
}

/// Validates a request and resolves it into work (CPU: call on the pool).
pub fn prepare(req: &PlanRequest, catalog: &Catalog, max_seconds: f64) -> ApiResult<Prepared> {
    match req {
        PlanRequest::JointSpace(r) => prepare_joint_space(r, catalog, max_seconds),
        PlanRequest::CollisionSweep(r) => prepare_sweep(r, catalog, max_seconds),
        PlanRequest::Reach(_)
        | PlanRequest::Regrasp(_)
        | PlanRequest::KitchenTask(_)
        | PlanRequest::Bimanual(_) => prepare_grasp(req, catalog, max_seconds),
        PlanRequest::MultiRobot(r) => {
            super::multi_robot::prepare_multi_robot(r, catalog, max_seconds)
        }
        PlanRequest::Schedule(r) => super::multi_robot::prepare_schedule(r, catalog, max_seconds),
        PlanRequest::GraspList(r) => {
            super::grasp_lists::prepare_grasp_list(r, catalog, max_seconds)
        }
        PlanRequest::PickPlace(r) => super::pick_place::prepare_pick_place(r, catalog, max_seconds),
        PlanRequest::MultiArm(r) => super::multi_arm::prepare_multi_arm(r, catalog, max_seconds),
    }
}

fn stats_json(s: &PlanStats) -> Value {
    s.to_json()
}

// ---------------------------------------------------------------- joint_space (RRT-Connect)

struct JointSpaceWork {
    world: Arc<CollisionWorld>,
    vars: Vec<usize>,
    base: Vec<f64>,
    start: Vec<f64>,
    goal: Vec<f64>,
    settings: RrtConnectSettings,
    seed: u64,
    timing: TimingOptions,
}

fn prepare_joint_space(r: &JointSpacePlan, catalog: &Catalog, max: f64) -> ApiResult<Prepared> {
    let time_limit = time_limit(r.time_limit, max)?;
    for (field, value) in [("range", r.range), ("dynamic_domain", r.dynamic_domain)] {
        if let Some(x) = value {
            if !(x.is_finite() && x > 0.0) {
                return Err(ApiError::invalid(
                    field,
                    format!("{x} is not a positive number"),
                ));
            }
        }
    }
    if let Some(x) = r.certify {
        if !(x.is_finite() && x > 0.0 && x <= 0.5) {
            return Err(ApiError::invalid(
                "certify",
                format!("{x} is not in (0, 0.5] metres"),
            ));
        }
    }
    if r.robots.is_empty() {
        return Err(ApiError::invalid("robots", "at least one robot is planned"));
    }
    let timing = timing_options(r.sample_period, r.velocity_scaling, r.acceleration_scaling)?;
    let entry = catalog.scene(&r.scene, "scene")?;
    let scene = &entry.scene;
    let world = entry.world();
    let mut base = CollisionWorld::start_config(scene);
    let mut goal_world = base.clone();
    let mut vars = Vec::new();
    let mut seen = Vec::new();
    for (i, pr) in r.robots.iter().enumerate() {
        let field = format!("robots[{i}]");
        let ri = scene
            .robots
            .iter()
            .position(|p| p.name == pr.name)
            .ok_or_else(|| {
                ApiError::invalid(
                    format!("{field}.name"),
                    format!("scene '{}' has no robot '{}'", scene.name, pr.name),
                )
            })?;
        if seen.contains(&ri) {
            return Err(ApiError::invalid(
                format!("{field}.name"),
                format!("robot '{}' listed twice", pr.name),
            ));
        }
        seen.push(ri);
        let p = &scene.robots[ri];
        let robot = &p.robot;
        let group_vars: Vec<usize> = match &pr.group {
            Some(g) => robot
                .group(g)
                .map(|g| g.vars.clone())
                .filter(|v| !v.is_empty())
                .ok_or_else(|| {
                    ApiError::invalid(
                        format!("{field}.group"),
                        format!("robot '{}' has no group '{g}' with joints", pr.name),
                    )
                })?,
            None => (0..robot.dof()).collect(),
        };
        let start_base = placement_base(p, None, &field)?;
        let start = apply_config(robot, &start_base, &pr.start, &format!("{field}.start"))?;
        let goal = apply_config(robot, &start, &pr.goal, &format!("{field}.goal"))?;
        let off = world.robots[ri].offset;
        base[off..off + start.len()].copy_from_slice(&start);
        goal_world[off..off + goal.len()].copy_from_slice(&goal);
        vars.extend(group_vars.iter().map(|v| off + v));
    }
    if r.sampler == Some(SamplerName::Halton) && vars.len() > halton::MAX_DIMS {
        return Err(ApiError::invalid(
            "sampler",
            format!(
                "the Halton sequence has at most {} dimensions; the request plans {} joints",
                halton::MAX_DIMS,
                vars.len()
            ),
        ));
    }
    let start: Vec<f64> = vars.iter().map(|&v| base[v]).collect();
    let goal: Vec<f64> = vars.iter().map(|&v| goal_world[v]).collect();
    let settings = RrtConnectSettings {
        range: r.range,
        shortcut: r.simplify.unwrap_or(true).then(ShortcutSettings::default),
        dynamic_domain: r.dynamic_domain,
        balance: r.balance.unwrap_or(false),
        certify: r.certify,
        sampler: match r.sampler {
            None | Some(SamplerName::Uniform) => Sampler::Uniform,
            Some(SamplerName::Halton) => Sampler::Halton,
        },
        ..RrtConnectSettings::default()
    };
    // The fields were checked one by one above; what the planner would refuse once running is
    // refused here too, at submission.
    settings
        .validate()
        .map_err(|e| ApiError::invalid("range", e.to_string()))?;
    Ok(Prepared {
        work: Box::new(JointSpaceWork {
            world,
            vars,
            base,
            start,
            goal,
            settings,
            seed: r.seed.unwrap_or(1),
            timing,
        }),
        time_limit,
    })
}

pub(super) fn plan_failure(e: PlanError) -> JobFailure {
    let code = match e.root() {
        PlanError::InvalidInput(_) => "invalid_input",
        PlanError::InvalidStart { .. } => "invalid_start",
        PlanError::InvalidGoal { .. } => "invalid_goal",
        PlanError::NoSchedule { .. } => "no_schedule",
        PlanError::Timeout { .. } => "timeout",
        PlanError::IterationLimit { .. } => "iteration_limit",
        PlanError::Stopped { .. } => "cancelled",
        PlanError::PathInvalid { .. } => "path_invalid",
        PlanError::InPhase { .. } => "failed",
    };
    JobFailure {
        stopped: matches!(e.root(), PlanError::Stopped { .. }),
        code,
        message: e.to_string(),
        stats: e.stats().map(stats_json),
    }
}

/// A request's timing fields (`sample_period`, `velocity_scaling`, `acceleration_scaling`),
/// checked (422 naming the field).
pub(super) fn timing_options(
    sample_period: Option<f64>,
    velocity_scaling: Option<f64>,
    acceleration_scaling: Option<f64>,
) -> ApiResult<TimingOptions> {
    TimingOptions::from_request(sample_period, velocity_scaling, acceleration_scaling)
        .map_err(timing_invalid)
}

/// A timing error about the request, as its 422.
pub(super) fn timing_invalid(e: TimingError) -> ApiError {
    ApiError::invalid(e.field, e.reason)
}

/// A timing error after planning (the request's fields were checked before, so not expected).
pub(super) fn timing_failure(e: TimingError) -> JobFailure {
    plan_failure(PlanError::InvalidInput(format!("trajectory: {e}")))
}

impl JobWork for JointSpaceWork {
    fn run(self: Box<Self>, ctx: &mut JobContext) -> Result<Value, JobFailure> {
        let w = *self;
        let space = JointSpace::new(&w.world, &w.vars, w.base).map_err(plan_failure)?;
        let names = space.names().to_vec();
        // The sphere checker for sphere robots (it can certify segments), else the fast one.
        let checker = AutoChecker::new(&w.world, 0.0);
        let checker_kind = checker.kind();
        let certified = w.settings.certify.is_some()
            && matches!(&checker, AutoChecker::Spheres(s) if s.certifiable());
        let mut planner =
            RrtConnect::with_checker(space, &w.world, checker, w.settings).map_err(plan_failure)?;
        ctx.progress(json!({"phase": "planning", "dimensions": names.len()}));
        let mut term = ctx.termination();
        let res = planner
            .plan(&w.start, &[w.goal], &mut term, w.seed)
            .map_err(plan_failure)?;
        // The timed trajectory of the planned variables, within their robots' limits.
        let limits = world_limits(&w.world)
            .select(&w.vars)
            .scaled(w.timing.velocity_scaling, w.timing.acceleration_scaling)
            .map_err(timing_failure)?;
        let trajectory = time_polyline(&res.path, &limits, &[])
            .and_then(|t| t.to_trajectory(&names, w.timing.sample_period, Vec::new()))
            .map_err(timing_failure)?;
        Ok(json!({
            "planner": "rrt_connect",
            "collision_model": checker_kind,
            "certified": certified,
            "joints": names,
            "path": res.path,
            "goal_index": res.goal_index,
            "stats": stats_json(&res.stats),
            "trajectory": trajectory,
        }))
    }
}

// ---------------------------------------------------------------- collision_sweep

struct SweepWork {
    world: Arc<CollisionWorld>,
    base: Vec<f64>,
    vars: Vec<usize>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    samples: u64,
    seed: u64,
}

fn prepare_sweep(r: &CollisionSweep, catalog: &Catalog, max: f64) -> ApiResult<Prepared> {
    let time_limit = time_limit(r.time_limit, max)?;
    if !(1..=1_000_000_000).contains(&r.samples) {
        return Err(ApiError::invalid(
            "samples",
            format!("{} is not in 1..=1000000000", r.samples),
        ));
    }
    let entry = catalog.scene(&r.scene, "scene")?;
    let scene = &entry.scene;
    let world = entry.world();
    let selected: Vec<usize> = match &r.robots {
        Some(names) => names
            .iter()
            .enumerate()
            .map(|(i, n)| {
                scene
                    .robots
                    .iter()
                    .position(|p| &p.name == n)
                    .ok_or_else(|| {
                        ApiError::invalid(
                            format!("robots[{i}]"),
                            format!("scene '{}' has no robot '{n}'", scene.name),
                        )
                    })
            })
            .collect::<ApiResult<_>>()?,
        None => (0..scene.robots.len()).collect(),
    };
    let mut vars = Vec::new();
    let mut lower = Vec::new();
    let mut upper = Vec::new();
    for ri in selected {
        let p = &world.robots[ri];
        for v in 0..p.robot.dof() {
            if vars.contains(&(p.offset + v)) {
                continue;
            }
            let l = p.robot.var_limits(v);
            vars.push(p.offset + v);
            lower.push(if l.lower.is_finite() {
                l.lower
            } else {
                -std::f64::consts::PI
            });
            upper.push(if l.upper.is_finite() {
                l.upper
            } else {
                std::f64::consts::PI
            });
        }
    }
    if vars.is_empty() {
        return Err(ApiError::invalid("robots", "no joints to sample"));
    }
    Ok(Prepared {
        work: Box::new(SweepWork {
            base: CollisionWorld::start_config(scene),
            world,
            vars,
            lower,
            upper,
            samples: r.samples,
            seed: r.seed.unwrap_or(1),
        }),
        time_limit,
    })
}

impl JobWork for SweepWork {
    fn run(self: Box<Self>, ctx: &mut JobContext) -> Result<Value, JobFailure> {
        let mut checker = FastChecker::new(&self.world);
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let mut q = self.base.clone();
        let (mut free, mut colliding) = (0u64, 0u64);
        // Counted by body ids (no allocation per sample), named in the summary.
        let mut pairs: HashMap<(BodyId, BodyId), u64> = HashMap::new();
        let t0 = Instant::now();
        let mut last = t0;
        let mut truncated = false;
        let world = &self.world;
        let summary = |free: u64,
                       colliding: u64,
                       pairs: &HashMap<(BodyId, BodyId), u64>,
                       truncated: bool| {
            let n = free + colliding;
            let mut top: Vec<((String, String), u64)> = pairs
                .iter()
                .map(|(&(a, b), &c)| ((world.body_name(a), world.body_name(b)), c))
                .collect();
            top.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
            json!({
                "samples": n,
                "free": free,
                "colliding": colliding,
                "free_fraction": if n > 0 { free as f64 / n as f64 } else { 0.0 },
                "truncated_by_time_limit": truncated,
                "checker": "fast (conservative)",
                "time_ms": t0.elapsed().as_secs_f64() * 1e3,
                "top_pairs": top.iter().take(10).map(|((a, b), c)| json!({"a": a, "b": b, "count": c})).collect::<Vec<_>>(),
            })
        };
        for i in 0..self.samples {
            if ctx.stopped() {
                return Err(JobFailure {
                    stopped: true,
                    code: "cancelled",
                    message: format!("stopped on request after {i} samples"),
                    stats: Some(summary(free, colliding, &pairs, false)),
                });
            }
            // The clock every 8 samples (a sample of a robot with hundreds of links costs
            // milliseconds); the time limit counts from the job's start (checker build
            // included).
            if i % 8 == 0 && ctx.past_limit() {
                truncated = true;
                break;
            }
            if i % 64 == 0 {
                let now = Instant::now();
                if now - last >= Duration::from_millis(100) {
                    last = now;
                    ctx.progress(json!({"samples_done": i, "samples": self.samples, "free": free, "colliding": colliding}));
                }
            }
            for (k, &v) in self.vars.iter().enumerate() {
                q[v] = self.lower[k] + (self.upper[k] - self.lower[k]) * rng.random::<f64>();
            }
            match checker.first_contact_ids(&q) {
                None => free += 1,
                Some(ids) => {
                    colliding += 1;
                    *pairs.entry(ids).or_insert(0) += 1;
                }
            }
        }
        Ok(summary(free, colliding, &pairs, truncated))
    }
}

// ---------------------------------------------------------------- grasp planners (000, 002)

/// Planner settings of a grasp request, validated.
pub(super) fn grasp_settings(
    s: &GraspPlanSettings,
    default_p_ik: f64,
    max: f64,
) -> ApiResult<(f64, u64, IkRrtSettings, RandomizedIkSettings)> {
    let limit = time_limit(s.time_limit, max)?;
    let p_ik = s.p_ik.unwrap_or(default_p_ik);
    if !(p_ik.is_finite() && p_ik > 0.0 && p_ik <= 1.0) {
        return Err(ApiError::invalid(
            "p_ik",
            format!("{p_ik} is not a probability in (0, 1]"),
        ));
    }
    let tries = s.ik_tries.unwrap_or(50);
    if !(1..=100_000).contains(&tries) {
        return Err(ApiError::invalid(
            "ik_tries",
            format!("{tries} is not within [1, 100000]"),
        ));
    }
    let mut planner = IkRrtSettings {
        p_ik,
        ..IkRrtSettings::default()
    };
    if !s.simplify.unwrap_or(true) {
        planner.rrt.shortcut = None;
    }
    let ik = RandomizedIkSettings {
        max_tries: tries,
        ..RandomizedIkSettings::default()
    };
    // Everything the planner would refuse once running is refused here, at submission.
    planner
        .validate()
        .map_err(|e| ApiError::invalid("p_ik", e.to_string()))?;
    Ok((limit, s.seed.unwrap_or(1), planner, ik))
}

/// Checks that `robot` is an instance of `scene` whose model has chain group `group`.
pub(super) fn check_hand(scene: &Scene, robot: &str, group: &str, field: &str) -> ApiResult<()> {
    let p = scene
        .robots
        .iter()
        .find(|p| p.name == robot)
        .ok_or_else(|| {
            ApiError::invalid(
                format!("{field}robot"),
                format!(
                    "scene '{}' has no robot '{robot}' (its robots: {})",
                    scene.name,
                    names(scene.robots.iter().map(|r| r.name.as_str()))
                ),
            )
        })?;
    if p.robot.group(group).and_then(|g| g.chain).is_none() {
        return Err(ApiError::invalid(
            format!("{field}group"),
            format!(
                "robot model '{}' has no chain group '{group}' (its chain groups: {})",
                p.robot.name,
                names(
                    p.robot
                        .groups
                        .iter()
                        .filter(|g| g.chain.is_some())
                        .map(|g| g.name.as_str())
                )
            ),
        ));
    }
    Ok(())
}

pub(super) fn check_object(scene: &Scene, object: &str) -> ApiResult<()> {
    if scene.object(object).is_none() {
        return Err(ApiError::invalid(
            "object",
            format!(
                "scene '{}' has no object '{object}' (its objects: {})",
                scene.name,
                names(scene.objects.iter().map(|o| o.body.name.as_str()))
            ),
        ));
    }
    Ok(())
}

/// Names for a message: `a, b, c`, or `none`.
pub(super) fn names<'a>(it: impl Iterator<Item = &'a str>) -> String {
    let v: Vec<&str> = it.collect();
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

/// What a grasp job runs: a chained task of the planning library.
enum GraspJob {
    Reach {
        robot: String,
        group: String,
        object: String,
        algorithm: GraspAlgorithm,
    },
    Regrasp(RegraspTask),
    Kitchen(KitchenTask),
    Bimanual {
        robot: String,
        left: String,
        right: String,
        object: String,
        grids: Arc<GridCache>,
    },
}

/// The grid of `model`'s chain group `group` built with `recipe`, from `grids` (memory, the data
/// folder, the shared tier) or built on first use on a build thread the job waits for within
/// its time limit and stop flag ([`super::builds`]); reported as the job's "reachability grids"
/// phase.
pub(super) fn ensure_grid(
    ctx: &mut JobContext,
    grids: &Arc<GridCache>,
    model: &Arc<crate::Robot>,
    group: &str,
    recipe: GridRecipe,
) -> Result<Arc<crate::reachability::ReachabilityGrid>, JobFailure> {
    ctx.progress(json!({"phase": "reachability grids", "robot": model.name, "group": group}));
    let key = format!(
        "grid {:x} {:x} {}/{group} {recipe:?}",
        Arc::as_ptr(grids) as usize,
        Arc::as_ptr(model) as usize,
        model.name
    );
    let what = format!(
        "the reachability grid of robot model '{}' group '{group}'",
        model.name
    );
    let (g, m, grp) = (grids.clone(), model.clone(), group.to_string());
    let builds = ctx.builds.clone();
    builds.ensure(ctx, key, &what, move |stop| {
        g.get_until(&m, &grp, recipe, &|| stop.stopped())
            .map(|_| ())
            .map_err(|e| match e {
                ReachError::Stopped => None,
                e => Some(e.to_string()),
            })
    })?;
    // In memory now: no build.
    grids
        .get_until(model, group, recipe, &|| true)
        .map_err(|e| grid_failure(e, group))
}

/// The arm grid of `robot`'s chain `group` ([`GridRecipe::arm`], the randomized IK's filter,
/// 000 §II-D) through [`ensure_grid`]; `None` when the robot has no SRDF group for that chain.
fn arm_grid_of(
    ctx: &mut JobContext,
    grids: &Arc<GridCache>,
    s: &Scene,
    robot: &str,
    group: &str,
) -> Result<Option<Arc<crate::reachability::ReachabilityGrid>>, JobFailure> {
    let model = scene_model(s, robot)?;
    let arm = ArmChain::new(&model, group)
        .map_err(|e| plan_failure(PlanError::InvalidInput(e.to_string())))?;
    match crate::reachability::queries::arm_grid_group(&model, &arm) {
        Some(g) => ensure_grid(ctx, grids, &model, &g, GridRecipe::arm()).map(Some),
        None => Ok(None),
    }
}

/// The model of robot instance `robot` of scene `s`.
fn scene_model(s: &Scene, robot: &str) -> Result<Arc<crate::Robot>, JobFailure> {
    s.robots
        .iter()
        .find(|p| p.name == robot)
        .map(|p| p.robot.clone())
        .ok_or_else(|| plan_failure(PlanError::InvalidInput(format!("no robot '{robot}'"))))
}

/// A grid build that failed, or that the job's stop flag ended.
pub(super) fn grid_failure(e: ReachError, group: &str) -> JobFailure {
    match e {
        ReachError::Stopped => JobFailure {
            stopped: true,
            code: "cancelled",
            message: format!(
                "stopped on request while building the reachability grid of '{group}'"
            ),
            stats: None,
        },
        e => plan_failure(PlanError::InvalidInput(format!(
            "reachability grid of '{group}': {e}"
        ))),
    }
}

struct GraspWork {
    scene: Arc<Scene>,
    job: GraspJob,
    /// The arm grids filtering IK-RRT's randomized IK (000 §II-D, §III-B).
    grids: Arc<GridCache>,
    planner: IkRrtSettings,
    ik: RandomizedIkSettings,
    seed: u64,
    timing: TimingOptions,
}

fn prepare_grasp(req: &PlanRequest, catalog: &Catalog, max: f64) -> ApiResult<Prepared> {
    let (scene_name, settings, default_p_ik) = match req {
        PlanRequest::Reach(r) => (&r.scene, r.settings(), 0.1),
        PlanRequest::Regrasp(r) => (&r.scene, r.settings(), 0.1),
        PlanRequest::KitchenTask(r) => (&r.scene, r.settings(), 0.1),
        PlanRequest::Bimanual(r) => (&r.scene, r.settings(), 0.03),
        _ => return Err(ApiError::invalid("kind", "not a grasp planner")),
    };
    let (limit, seed, planner, ik) = grasp_settings(&settings, default_p_ik, max)?;
    let timing = timing_options(
        settings.sample_period,
        settings.velocity_scaling,
        settings.acceleration_scaling,
    )?;
    let entry = catalog.scene(scene_name, "scene")?;
    let scene = entry.scene.clone();
    let job = match req {
        PlanRequest::Reach(r) => {
            check_hand(&scene, &r.robot, &r.group, "")?;
            check_object(&scene, &r.object)?;
            GraspJob::Reach {
                robot: r.robot.clone(),
                group: r.group.clone(),
                object: r.object.clone(),
                algorithm: r.planner.unwrap_or_default().into(),
            }
        }
        PlanRequest::Regrasp(r) => {
            check_hand(&scene, &r.giver.robot, &r.giver.group, "giver.")?;
            check_hand(&scene, &r.receiver.robot, &r.receiver.group, "receiver.")?;
            check_object(&scene, &r.object)?;
            GraspJob::Regrasp(RegraspTask {
                giver: (r.giver.robot.clone(), r.giver.group.clone()),
                receiver: (r.receiver.robot.clone(), r.receiver.group.clone()),
                object: r.object.clone(),
                held: r.held.clone(),
                grid: None,
                algorithm: r.planner.unwrap_or_default().into(),
                planner,
                ik,
            })
        }
        PlanRequest::KitchenTask(_) => {
            let t = KitchenTask {
                planner,
                ik,
                ..KitchenTask::armar_wok()
            };
            check_hand(&scene, &t.robot, &t.first, "")?;
            check_hand(&scene, &t.robot, &t.second, "")?;
            check_object(&scene, &t.object)?;
            GraspJob::Kitchen(t)
        }
        PlanRequest::Bimanual(r) => {
            let left = r.left.clone().unwrap_or_else(|| "torso_left_arm".into());
            let right = r.right.clone().unwrap_or_else(|| "torso_right_arm".into());
            check_hand(&scene, &r.robot, &left, "left.")?;
            check_hand(&scene, &r.robot, &right, "right.")?;
            check_object(&scene, &r.object)?;
            GraspJob::Bimanual {
                robot: r.robot.clone(),
                left,
                right,
                object: r.object.clone(),
                grids: catalog.grids(),
            }
        }
        _ => return Err(ApiError::invalid("kind", "not a grasp planner")),
    };
    Ok(Prepared {
        work: Box::new(GraspWork {
            scene,
            job,
            grids: catalog.grids(),
            planner,
            ik,
            seed,
            timing,
        }),
        time_limit: limit,
    })
}

impl JobWork for GraspWork {
    fn run(self: Box<Self>, ctx: &mut JobContext) -> Result<Value, JobFailure> {
        let w = *self;
        let s = &*w.scene;
        let mut term = ctx.termination();
        let plan = match &w.job {
            GraspJob::Reach {
                robot,
                group,
                object,
                algorithm,
            } => {
                // An object out of reach fails here, before a grid is built.
                crate::planning::tasks::task::precheck_reach(s, robot, group, object)
                    .map_err(plan_failure)?;
                let grid = match algorithm {
                    GraspAlgorithm::IkRrt => arm_grid_of(ctx, &w.grids, s, robot, group)?,
                    GraspAlgorithm::JPlusRrt => None,
                };
                ctx.progress(json!({"phase": "planning", "planner": algorithm}));
                reach_task(
                    s, robot, group, object, grid, *algorithm, w.planner, w.ik, &mut term, w.seed,
                )
            }
            GraspJob::Regrasp(t) => {
                let mut t = t.clone();
                if t.algorithm == GraspAlgorithm::IkRrt {
                    let (robot, group) = &t.receiver;
                    t.grid = arm_grid_of(ctx, &w.grids, s, robot, group)?;
                }
                ctx.progress(json!({"phase": "planning", "planner": t.algorithm}));
                regrasp_task(s, &t, &mut term, w.seed)
            }
            GraspJob::Kitchen(t) => {
                let mut t = t.clone();
                crate::planning::tasks::task::precheck_reach(s, &t.robot, &t.first, &t.object)
                    .map_err(plan_failure)?;
                t.grids = (
                    arm_grid_of(ctx, &w.grids, s, &t.robot, &t.first)?,
                    arm_grid_of(ctx, &w.grids, s, &t.robot, &t.second)?,
                );
                ctx.progress(json!({"phase": "planning", "planner": "kitchen_task"}));
                kitchen_task(s, &t, &mut term, w.seed)
            }
            GraspJob::Bimanual {
                robot,
                left,
                right,
                object,
                grids,
            } => {
                let model = scene_model(s, robot)?;
                let gl = ensure_grid(ctx, grids, &model, left, GridRecipe::default())?;
                let gr = ensure_grid(ctx, grids, &model, right, GridRecipe::default())?;
                ctx.progress(json!({"phase": "planning", "planner": "bimanual_ik_rrt"}));
                let world = CollisionWorld::from_scene(s);
                let q0 = CollisionWorld::start_config(s);
                BimanualProblem::new(
                    s,
                    &world,
                    &q0,
                    robot,
                    (left, right),
                    object,
                    (&gl, &gr),
                    BimanualSettings::default(),
                )
                .and_then(|p| bimanual_task(&p, w.planner, w.ik, &mut term, w.seed))
            }
        }
        .map_err(plan_failure)?;
        plan.to_json(&CollisionWorld::from_scene(s), &w.timing)
            .map_err(timing_failure)
    }
}
