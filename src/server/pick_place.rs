//! The job kind `pick_place`: the two-hand pick-and-place task of paper 003
//! ([`crate::planning::pick_place::task`]) over HTTP. A thin adapter: the request is checked
//! against the catalog (422 naming the field), the offline data live under the data folder
//! (`grasps/`, `roadmaps/`), the work and its certification are the planning core's.

use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::Instant;

use serde_json::{json, Value};

use crate::grasp::list::workspace_params;
use crate::grasp::{GraspListCache, GraspListParams};
use crate::planning::pick_place::{
    plan_pick_place, prepare_pick_place as prepare_offline, MotionPlanner, PickPlaceError,
    PickPlaceProblem, PickPlaceSettings, PickPlaceTaskError, TaskProgress,
};
use crate::planning::timing::TimingOptions;

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

fn failure(e: PickPlaceTaskError, cancelled: bool) -> JobFailure {
    let code = match &e {
        e if e.stopped() || matches!(e, PickPlaceTaskError::Stopped(_)) => {
            if cancelled {
                "cancelled"
            } else {
                "timeout"
            }
        }
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

impl JobWork for PickPlaceWork {
    fn run(self: Box<Self>, ctx: &mut JobContext) -> Result<Value, JobFailure> {
        let w = *self;
        let mut term = ctx.termination();
        let stop_flag = ctx.stop.clone();
        let limit = ctx.time_limit;
        let t0 = Instant::now();
        let stop = move || stop_flag.load(Ordering::Relaxed) || t0.elapsed() > limit;
        let flag = ctx.stop.clone();
        let cancelled = move || flag.load(Ordering::Relaxed);
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
        .map_err(|e| failure(e, cancelled()))?;
        let r = plan_pick_place(
            &w.problem,
            &off,
            &w.settings,
            w.seed,
            &mut term,
            &mut progress,
        )
        .map_err(|e| failure(e, cancelled()))?;
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
            o.insert("offline".into(), json!(off.stats));
        }
        Ok(v)
    }
}
