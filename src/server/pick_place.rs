//! The job kind `pick_place`: the two-hand pick-and-place task of paper 003
//! ([`crate::planning::tasks::pick_place::task`]) over HTTP. A thin adapter: the request is checked
//! against the catalog (422 naming the field), the offline data live under the data folder
//! (`grasps/`, `roadmaps/`), the work and its certification are the planning core's.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use serde_json::{json, Value};

use crate::grasp::list::workspace_params;
use crate::grasp::list_cache::list_file_name;
use crate::grasp::{GraspListCache, GraspListError, GraspListParams, GraspObject};
use crate::planning::planners::roadmap_cache::{load_or_build, RoadmapKey, RoadmapSource};
use crate::planning::tasks::pick_place::task::{decomposition, task_world};
use crate::planning::tasks::pick_place::{
    plan_pick_place, prepare_pick_place as prepare_offline, MotionPlanner, PickPlaceError,
    PickPlaceProblem, PickPlaceSettings, PickPlaceTaskError, TaskProgress,
};
use crate::planning::Termination;
use crate::trajectory::timing::TimingOptions;

use super::api::PickPlaceTaskPlan;
use super::catalog::Catalog;
use super::error::{ApiError, ApiResult};
use super::kinds::{
    time_limit, timing_failure, timing_options, JobContext, JobFailure, JobWork, Prepared,
};

struct PickPlaceWork {
    problem: PickPlaceProblem,
    settings: PickPlaceSettings,
    lists: std::sync::Arc<GraspListCache>,
    roadmap_dir: Option<PathBuf>,
    /// The shared store behind the roadmap cache (several replicas build each roadmap once).
    tier: Option<std::sync::Arc<dyn crate::cache_tier::CacheTier>>,
    seed: u64,
    timing: TimingOptions,
}

/// The request field of a problem error (`hand` → which of the two hands).
fn problem_field(
    e: &PickPlaceError,
    r: &PickPlaceTaskPlan,
    robot: Option<&crate::Robot>,
) -> String {
    let hand_of = |h: &str| {
        if h == r.place_hand {
            "place_hand"
        } else {
            "pick_hand"
        }
    };
    match e {
        PickPlaceError::NoArm { hand, .. } | PickPlaceError::Hand { hand, .. } => {
            hand_of(hand).into()
        }
        PickPlaceError::Arm { arm, .. } => {
            // The hand whose end effector's parent group is that arm.
            let place_arm = robot.and_then(|rb| {
                rb.end_effectors
                    .iter()
                    .find(|ee| ee.group == r.place_hand)
                    .and_then(|ee| ee.parent_group.clone())
            });
            if place_arm.as_deref() == Some(arm.as_str()) {
                "place_hand".into()
            } else {
                "pick_hand".into()
            }
        }
        PickPlaceError::ArmBases(..) => "place_hand".into(),
        e => e.field().to_string(),
    }
}

pub(super) fn prepare_pick_place(
    r: &PickPlaceTaskPlan,
    catalog: &Catalog,
    max: f64,
) -> ApiResult<Prepared> {
    let time_limit = time_limit(r.time_limit, max)?;
    let timing = timing_options(r.sample_period, r.velocity_scaling, r.acceleration_scaling)?;
    let planner = match r.planner.as_deref() {
        None => MotionPlanner::Roadmap,
        Some(s) => MotionPlanner::from_name(s).ok_or_else(|| {
            ApiError::invalid(
                "planner",
                format!("'{s}' is not one of roadmap, rrt_connect"),
            )
        })?,
    };
    let mut settings = PickPlaceSettings {
        planner,
        ..PickPlaceSettings::default()
    };
    if let Some(a) = r.attempts {
        settings.attempts = a;
    }
    settings
        .validate()
        .map_err(|e| ApiError::invalid(e.field(), e.to_string()))?;
    let entry = catalog.scene(&r.scene, "scene")?;
    let problem = PickPlaceProblem::from_scene(
        &entry.scene,
        &r.robot,
        &r.object,
        &r.pick_hand,
        &r.place_hand,
        &workspace_params(&GraspListParams::default()),
    )
    .map_err(|e| {
        let robot = entry.scene.robot(&r.robot).map(|p| &*p.robot);
        ApiError::invalid(problem_field(&e, r, robot), e.to_string())
    })?;
    Ok(Prepared {
        work: Box::new(PickPlaceWork {
            problem,
            settings,
            lists: catalog.grasp_lists(),
            roadmap_dir: catalog.grasp_dir().parent().map(|d| d.join("roadmaps")),
            tier: catalog.cache_tier(),
            seed: r.seed.unwrap_or(1),
            timing,
        }),
        time_limit,
    })
}

/// A task error as the job's answer: `cancelled` on the job's stop flag, `timeout` when its
/// time limit (from the job's start) has been reached, else by the error.
fn failure(e: PickPlaceTaskError, cancelled: bool, past_limit: bool) -> JobFailure {
    let code = match &e {
        _ if cancelled => "cancelled",
        _ if past_limit => "timeout",
        e if e.stopped() || matches!(e, PickPlaceTaskError::Stopped(_)) => "timeout",
        PickPlaceTaskError::Problem(PickPlaceError::Unreachable { .. }) => "unreachable",
        PickPlaceTaskError::Problem(PickPlaceError::NoExchange(_)) => "no_exchange",
        PickPlaceTaskError::Problem(_) => "invalid_input",
        _ => "failed",
    };
    JobFailure {
        stopped: cancelled,
        code,
        message: e.to_string(),
        stats: None,
    }
}

impl PickPlaceWork {
    /// The offline data's first-use builds — both grasp lists, then the super-graph roadmap —
    /// each on a build thread the job waits for within its time limit and stop flag (see
    /// `super::builds`): a build the time limit left goes on and fills the caches (memory, the
    /// data folder, the shared tier) for later jobs. Which of them this job built.
    fn ensure_offline(&self, ctx: &mut JobContext) -> Result<[bool; 3], JobFailure> {
        let builds = ctx.builds.clone();
        let object = GraspObject::new(&self.problem.object_name, self.problem.object.clone())
            .map_err(|e| JobFailure {
                stopped: false,
                code: "invalid_input",
                message: format!("object: {e}"),
                stats: None,
            })?;
        let mut built = [false; 3];
        for (i, ah) in [&self.problem.pick, &self.problem.place]
            .into_iter()
            .enumerate()
        {
            ctx.progress(json!({"phase": "grasp_lists", "hand": ah.hand.group}));
            let key = format!(
                "grasp list {:x} {}",
                Arc::as_ptr(&self.lists) as usize,
                list_file_name(&ah.hand, &object, &self.settings.lists)
            );
            let what = format!(
                "the grasp list of hand '{}' for '{}'",
                ah.hand.group, object.name
            );
            let flag = Arc::new(AtomicBool::new(false));
            let (lists, hand, obj, params, f) = (
                self.lists.clone(),
                ah.hand.clone(),
                object.clone(),
                self.settings.lists.clone(),
                flag.clone(),
            );
            builds.ensure(ctx, key, &what, move |stop| {
                lists
                    .get_or_build(&hand, &obj, &params, &|_, _| {}, &|| stop.stopped())
                    .map(|(_, new)| f.store(new, Ordering::Relaxed))
                    .map_err(|e| match e {
                        GraspListError::Stopped => None,
                        e => Some(e.to_string()),
                    })
            })?;
            built[i] = flag.load(Ordering::Relaxed);
        }
        // The roadmap is kept in the data folder (no folder: the task builds it itself).
        let Some(dir) = self.roadmap_dir.clone() else {
            return Ok(built);
        };
        ctx.progress(json!({"phase": "roadmap"}));
        let world = task_world(&self.problem);
        let dec = decomposition(&self.problem, &world).map_err(|e| failure(e, false, false))?;
        let name = RoadmapKey::of(&world, &dec, &self.problem.rest, &self.settings.roadmap)
            .map_err(|e| JobFailure {
                stopped: false,
                code: "failed",
                message: format!("roadmap: {e}"),
                stats: None,
            })?
            .file_name(&self.problem.robot.name);
        let flag = Arc::new(AtomicBool::new(false));
        let (tier, rest, params, f) = (
            self.tier.clone(),
            self.problem.rest.clone(),
            self.settings.roadmap,
            flag.clone(),
        );
        builds.ensure(
            ctx,
            format!("roadmap {} {name}", dir.display()),
            &format!("the roadmap of '{}'", self.problem.robot.name),
            move |stop| {
                let mut term = Termination::new().with_stop_flag(stop.flag());
                match load_or_build(
                    Some(&dir),
                    tier.as_deref(),
                    &world,
                    &dec,
                    &rest,
                    &params,
                    &mut term,
                ) {
                    Ok((_, _, src)) => {
                        f.store(src == RoadmapSource::Built, Ordering::Relaxed);
                        Ok(())
                    }
                    Err(_) if stop.stopped() => Err(None),
                    Err(e) => Err(Some(e.to_string())),
                }
            },
        )?;
        built[2] = flag.load(Ordering::Relaxed);
        Ok(built)
    }
}

impl JobWork for PickPlaceWork {
    fn run(self: Box<Self>, ctx: &mut JobContext) -> Result<Value, JobFailure> {
        let w = *self;
        let built = w.ensure_offline(ctx)?;
        let mut term = ctx.termination();
        let stop_flag = ctx.stop.clone();
        let (started, limit) = (ctx.started, ctx.time_limit);
        let stop = move || stop_flag.load(Ordering::Relaxed) || started.elapsed() > limit;
        let flag = ctx.stop.clone();
        let cancelled = move || flag.load(Ordering::Relaxed);
        let past = move || started.elapsed() >= limit;
        let mut progress =
            |p: TaskProgress| ctx.progress(serde_json::to_value(&p).unwrap_or(Value::Null));
        let off = prepare_offline(
            &w.problem,
            &w.settings,
            &w.lists,
            w.roadmap_dir.as_deref(),
            w.tier.as_deref(),
            &stop,
            &mut term,
            &mut progress,
        )
        .map_err(|e| failure(e, cancelled(), past()))?;
        let r = plan_pick_place(
            &w.problem,
            &off,
            &w.settings,
            w.seed,
            &mut term,
            &mut progress,
        )
        .map_err(|e| failure(e, cancelled(), past()))?;
        let mut v = r
            .plan
            .to_json(&off.world, &w.timing)
            .map_err(timing_failure)?;
        if let Some(o) = v.as_object_mut() {
            o.insert("queries".into(), json!(r.queries));
            o.insert("double_grasp".into(), json!(r.keys.double));
            o.insert("attempts".into(), json!(r.attempts));
            o.insert("certified_segments".into(), json!(r.certified_segments));
            o.insert("timings".into(), json!(r.timings));
            let mut offline = json!(off.stats);
            // The builds ran before the task (on build threads): say which this job made.
            offline["pick_list_built"] = json!(built[0] || off.stats.pick_list_built);
            offline["place_list_built"] = json!(built[1] || off.stats.place_list_built);
            offline["roadmap_built"] = json!(built[2] || off.stats.roadmap_built);
            o.insert("offline".into(), offline);
        }
        Ok(v)
    }
}
