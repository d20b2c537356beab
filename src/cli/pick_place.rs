//! `manyhands plan pick-place`: the whole two-hand pick-and-place task of paper 003 (Fig. 2,
//! §V-B; [`manyhands::planning::tasks::pick_place::task`]) on a scene; `manyhands bench pick-place`:
//! 003 Table I's shape (per query: nodes, planning and validation time) over seeded runs,
//! beside the single-query baseline (plain RRT-Connect on the same four queries with the same
//! certified checks) and the offline costs.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{anyhow, Result};
use clap::Args;
use serde_json::json;

use manyhands::grasp::GraspListCache;
use manyhands::planning::tasks::pick_place::{
    plan_pick_place, prepare_pick_place, MotionPlanner, PickPlaceOffline, PickPlacePlan,
    PickPlaceProblem, PickPlaceSettings, QueryRecord, RoadmapLearning,
};
use manyhands::planning::Termination;
use manyhands::trajectory::timing::TimingOptions;

use super::commands::Ctx;

/// The problem, the offline data folders and the bounds.
#[derive(Args, Debug, Clone)]
pub struct PickPlaceArgs {
    #[command(flatten)]
    pub task: super::exchange::TaskArgs,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// `roadmap` (003 §V-B) or `rrt-connect` (the single-query baseline).
    #[arg(long, default_value = "roadmap")]
    pub planner: String,
    /// Key-configuration searches tried at most.
    #[arg(long, default_value_t = 4)]
    pub attempts: usize,
    /// Seconds for the online task.
    #[arg(long, default_value_t = 10.0)]
    pub time_limit: f64,
    /// Folder of cached grasp lists (built when missing).
    #[arg(long, default_value = "data/grasps")]
    pub cache: PathBuf,
    /// Folder of roadmap files (built when missing).
    #[arg(long, default_value = "data/roadmaps")]
    pub roadmaps: PathBuf,
    /// What the roadmap learns from its RRT repairs: `task` (the task's own later queries;
    /// deterministic per seed) or `shared` (also later tasks of this run).
    #[arg(long, default_value = "task")]
    pub roadmap_learning: String,
}

fn planner(s: &str) -> Result<MotionPlanner> {
    MotionPlanner::from_name(s)
        .ok_or_else(|| anyhow!("--planner: '{s}' is not roadmap or rrt-connect"))
}

struct Setup {
    problem: PickPlaceProblem,
    settings: PickPlaceSettings,
    offline: PickPlaceOffline,
}

fn setup(ctx: &Ctx, a: &PickPlaceArgs) -> Result<Setup> {
    let learning = match a.roadmap_learning.as_str() {
        "task" => RoadmapLearning::Task,
        "shared" => RoadmapLearning::Shared,
        o => return Err(anyhow!("--roadmap-learning: '{o}' is not task or shared")),
    };
    let settings = PickPlaceSettings {
        planner: planner(&a.planner)?,
        attempts: a.attempts,
        learning,
        ..PickPlaceSettings::default()
    };
    let flag = |f: &str| format!("--{}", f.replace('_', "-"));
    settings
        .validate()
        .map_err(|e| anyhow!("{e} (flag {})", flag(e.field())))?;
    let problem = a.task.problem(ctx)?;
    let cache = GraspListCache::new(Some(a.cache.clone()));
    let offline = prepare_pick_place(
        &problem,
        &settings,
        &cache,
        Some(&a.roadmaps),
        None,
        &|| false,
        &mut Termination::new(),
        &mut |_| {},
    )?;
    Ok(Setup {
        problem,
        settings,
        offline,
    })
}

fn run_once(s: &Setup, seed: u64, time_limit: f64) -> Result<PickPlacePlan> {
    let mut term = Termination::new().with_time_limit(Duration::from_secs_f64(time_limit));
    Ok(plan_pick_place(
        &s.problem,
        &s.offline,
        &s.settings,
        seed,
        &mut term,
        &mut |_| {},
    )?)
}

/// `manyhands plan pick-place`.
pub fn plan(ctx: &Ctx, a: &PickPlaceArgs) -> Result<()> {
    if !(a.time_limit.is_finite() && a.time_limit > 0.0) {
        return Err(anyhow!("--time-limit: give a positive number of seconds"));
    }
    let s = setup(ctx, a)?;
    let r = run_once(&s, a.seed, a.time_limit)?;
    let plan = r
        .plan
        .to_json(&s.offline.world, &TimingOptions::default())?;
    let v = json!({
        "scene": a.task.scene, "object": s.problem.object_name, "seed": a.seed,
        "planner": s.settings.planner,
        "plan": plan,
        "queries": r.queries,
        "double_grasp": r.keys.double,
        "attempts": r.attempts,
        "certified_segments": r.certified_segments,
        "timings": r.timings,
        "offline": s.offline.stats,
    });
    ctx.print(&v, || {
        let mut t = format!(
            "{} in {} ({:?}, seed {}): {} waypoints, {} phases, {} events, {} segments re-certified; attempt {}\n",
            s.problem.object_name,
            a.task.scene,
            s.settings.planner,
            a.seed,
            r.plan.waypoints.len(),
            r.plan.phases.len(),
            r.plan.events.len(),
            r.certified_segments,
            r.attempts
        );
        for ph in &r.plan.phases {
            t += &format!(
                "  {:<15} {:<12} waypoints {}..{}\n",
                ph.name, ph.planner, ph.first, ph.last
            );
        }
        for e in &r.plan.events {
            t += &format!(
                "  event {:?} {} {} at waypoint {}\n",
                e.kind, e.end_effector, e.grasp, e.waypoint
            );
        }
        t += &query_table(std::slice::from_ref(&r.queries));
        t += &format!(
            "online {:.1} ms: exchange grid {:.1}, configurations {:.1}, motions {:.1}, certification {:.1}\n",
            r.timings.total_ms,
            r.timings.exchange_grid_ms,
            r.timings.configurations_ms,
            r.timings.motions_ms,
            r.timings.certification_ms
        );
        t += &offline_text(&s.offline);
        t
    });
    Ok(())
}

fn offline_text(o: &PickPlaceOffline) -> String {
    let st = &o.stats;
    format!(
        "offline: grasp lists {} + {} grasps ({:.0} + {:.0} ms, {}), roadmap {} nodes / {} edges ({} in {:.0} ms; its build {:.0} ms)",
        st.pick_grasps,
        st.place_grasps,
        st.pick_list_ms,
        st.place_list_ms,
        if st.pick_list_built || st.place_list_built {
            "built now"
        } else {
            "cached"
        },
        st.roadmap_nodes,
        st.roadmap_edges,
        if st.roadmap_built { "built" } else { "loaded" },
        st.roadmap_ms,
        st.roadmap_build_ms
    )
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => (v[n / 2 - 1] + v[n / 2]) / 2.0,
    }
}

const QUERIES: [&str; 4] = ["grasp", "carry", "place", "rest"];

/// 003 Table I (§VI): per query (grasp, carry, place, rest) n and T of online planning, path
/// validation and their total; `(n, T s)` per cell, rows as [`query_table`].
const PAPER_TABLE_I: [[(f64, f64); 4]; 3] = [
    [(65.0, 2.7), (53.0, 2.6), (32.0, 1.2), (49.0, 1.9)],
    [(3.0, 0.3), (18.0, 1.5), (12.0, 1.1), (3.0, 0.3)],
    [(68.0, 3.0), (71.0, 4.1), (44.0, 2.3), (51.0, 2.1)],
];

/// 003 Table I in full: medians over runs of each query's nodes and times, each row beside the
/// paper's.
fn query_table(runs: &[Vec<QueryRecord>]) -> String {
    let col = |name: &str, f: &dyn Fn(&QueryRecord) -> f64| {
        median(
            runs.iter()
                .filter_map(|r| r.iter().find(|q| q.name == name))
                .map(f)
                .collect(),
        )
    };
    let mut s = format!("{:<24}", "003 Table I");
    for q in QUERIES {
        s += &format!(" {:>7} {:>9}", format!("{q} n"), "T ms");
    }
    s += "\n";
    type F = dyn Fn(&QueryRecord) -> f64;
    let rows: [(&str, &F, &F); 3] = [
        ("online planning", &|q| q.nodes as f64, &|q| q.planning_ms),
        ("path validation", &|q| q.validated as f64, &|q| {
            q.validation_ms
        }),
        ("total", &|q| (q.nodes + q.validated) as f64, &|q| {
            q.total_ms
        }),
    ];
    for (k, (label, n, t)) in rows.into_iter().enumerate() {
        s += &format!("{label:<24}");
        for q in QUERIES {
            s += &format!(" {:>7.0} {:>9.2}", col(q, n), col(q, t));
        }
        s += "\n";
        s += &format!("{:<24}", format!("  003 {label}"));
        for (pn, pt) in PAPER_TABLE_I[k] {
            s += &format!(" {:>7.0} {:>9.0}", pn, pt * 1e3);
        }
        s += "\n";
    }
    s
}

/// 003 §VI's counts beside ours: list sizes, grasps with a certified closing motion,
/// single-grasp and double-grasp configurations and their times, RRT repairs, learnt nodes.
fn section_vi(ok: &[PickPlacePlan], o: &PickPlaceOffline) -> String {
    let tm = |f: &dyn Fn(&PickPlacePlan) -> f64| median(ok.iter().map(f).collect());
    let repairs: usize = ok
        .iter()
        .flat_map(|r| r.queries.iter().map(|q| q.rrt_repairs))
        .sum();
    let learned: usize = ok
        .iter()
        .flat_map(|r| r.queries.iter().map(|q| q.learned_added))
        .sum();
    format!(
        "003 §VI: grasp lists {} (pick) / {} (place) grasps [003: 17 right / 22 left], {:.0} / {:.0} with a certified closing motion (median); \
         single-grasp configurations {:.0} (pick) / {:.0} (place) in {:.1} ms [003: 4 right / 7 left in 4.2 s]; \
         double-grasp configurations {:.0} in {:.1} ms [003: 4 in 2.6 s]; \
         RRT repairs {} over {} runs (learnt nodes {}); \
         closing motions {:.1} ms\n",
        o.stats.pick_grasps,
        o.stats.place_grasps,
        tm(&|r| r.closable[0] as f64),
        tm(&|r| r.closable[1] as f64),
        tm(&|r| r.keys.stats.single_pick as f64),
        tm(&|r| r.keys.stats.single_place as f64),
        tm(&|r| r.keys.stats.single_ms),
        tm(&|r| r.keys.stats.double_grasps as f64),
        tm(&|r| r.keys.stats.double_ms),
        repairs,
        ok.len(),
        learned,
        tm(&|r| r.timings.closing_ms),
    )
}

/// `manyhands bench pick-place` arguments.
#[derive(Args, Debug)]
pub struct PickPlaceBenchArgs {
    #[command(flatten)]
    pub problem: PickPlaceArgs,
    /// Seeded runs (seeds seed..seed+runs) per planner.
    #[arg(long, default_value_t = 20)]
    pub runs: u64,
}

/// `manyhands bench pick-place`.
pub fn bench(ctx: &Ctx, a: &PickPlaceBenchArgs) -> Result<()> {
    let mut s = setup(ctx, &a.problem)?;
    let mut out = Vec::new();
    let mut text = String::new();
    for pl in [MotionPlanner::Roadmap, MotionPlanner::RrtConnect] {
        s.settings.planner = pl;
        let mut ok: Vec<PickPlacePlan> = Vec::new();
        let mut first_error = None;
        for k in 0..a.runs.max(1) {
            match run_once(&s, a.problem.seed + k, a.problem.time_limit) {
                Ok(r) => ok.push(r),
                Err(e) => {
                    first_error.get_or_insert_with(|| format!("seed {}: {e}", a.problem.seed + k));
                }
            }
        }
        let runs: Vec<Vec<QueryRecord>> = ok.iter().map(|r| r.queries.clone()).collect();
        let tm = |f: &dyn Fn(&PickPlacePlan) -> f64| median(ok.iter().map(f).collect());
        let total = tm(&|r| r.timings.total_ms);
        let configs = tm(&|r| r.timings.configurations_ms + r.timings.exchange_grid_ms);
        let motions = tm(&|r| r.timings.motions_ms);
        let cert = tm(&|r| r.timings.certification_ms);
        let queries: f64 = tm(&|r| r.queries.iter().map(|q| q.total_ms).sum());
        let attempts = ok.iter().filter(|r| r.attempts > 1).count();
        out.push(json!({
            "planner": pl, "solved": ok.len(), "runs": a.runs.max(1),
            "median_online_ms": total, "median_configurations_ms": configs,
            "median_motions_ms": motions, "median_queries_ms": queries,
            "median_certification_ms": cert, "runs_with_retries": attempts,
            "median_closable": [tm(&|r| r.closable[0] as f64), tm(&|r| r.closable[1] as f64)],
            "median_single_configurations": [tm(&|r| r.keys.stats.single_pick as f64), tm(&|r| r.keys.stats.single_place as f64)],
            "median_single_ms": tm(&|r| r.keys.stats.single_ms),
            "median_double_configurations": tm(&|r| r.keys.stats.double_grasps as f64),
            "median_double_ms": tm(&|r| r.keys.stats.double_ms),
            "median_closing_ms": tm(&|r| r.timings.closing_ms),
            "queries": QUERIES.iter().map(|q| {
                let col = |f: &dyn Fn(&QueryRecord) -> f64| median(runs.iter()
                    .filter_map(|r| r.iter().find(|x| x.name == *q)).map(f).collect());
                json!({"name": q, "nodes": col(&|x| x.nodes as f64), "planning_ms": col(&|x| x.planning_ms),
                       "validated": col(&|x| x.validated as f64), "validation_ms": col(&|x| x.validation_ms),
                       "total_ms": col(&|x| x.total_ms),
                       "rrt_repairs": runs.iter().filter_map(|r| r.iter().find(|x| x.name == *q)).map(|x| x.rrt_repairs).sum::<usize>(),
                       "learned_added": runs.iter().filter_map(|r| r.iter().find(|x| x.name == *q)).map(|x| x.learned_added).sum::<usize>()})
            }).collect::<Vec<_>>(),
            "first_error": first_error,
        }));
        text += &format!(
            "{:?}: {}/{} solved; median online {:.1} ms (target ≤ 100 ms): configurations {:.1} ms (target ≤ 50 ms), queries + hands {:.1} ms (queries {:.1}), certification {:.1} ms; {} runs needed another attempt\n",
            pl,
            ok.len(),
            a.runs.max(1),
            total,
            configs,
            motions,
            queries,
            cert,
            attempts
        );
        text += &query_table(&runs);
        text += &section_vi(&ok, &s.offline);
        if let Some(e) = &first_error {
            text += &format!("first failure: {e}\n");
        }
    }
    text += &offline_text(&s.offline);
    text += "\nmedians over the solved runs; n = super nodes on the first graph path (RRT: tree nodes) / nodes and edges revalidated with the object [paper 003 Table I: 11.6 s with the roadmap, 35 s single-query]";
    let v = json!({"rows": out, "offline": s.offline.stats});
    ctx.print(&v, || text);
    Ok(())
}
