//! `manyhands plan exchange`: the exchange position and the grasp, exchange and place
//! configurations of paper 003 §V-C ([`manyhands::planning::tasks::pick_place`]) for a scene's object
//! and its goal pose; `manyhands bench exchange`: the time of that configuration phase.

use std::sync::Arc;
use std::time::Instant;

use anyhow::{anyhow, Result};
use clap::Args;
use serde_json::json;

use manyhands::grasp::list::workspace_params;
use manyhands::grasp::{GraspList, GraspListCache, GraspListParams, GraspObject};
use manyhands::planning::tasks::pick_place::{
    exchange_grid, key_configurations, ConfigParams, ExchangeGrid, KeyConfigurations,
    PickPlaceProblem,
};

use super::commands::Ctx;

/// A two-hand pick-and-place problem of a scene (`plan exchange`, `plan pick-place` and their
/// benchmarks).
#[derive(Args, Debug, Clone)]
pub struct TaskArgs {
    #[arg(long, default_value = "pick_place")]
    pub scene: String,
    /// Robot instance of the scene.
    #[arg(long, default_value = "justin")]
    pub robot: String,
    /// The object (its `goal` is the final pose).
    #[arg(long, default_value = "statuette")]
    pub object: String,
    /// Hand group that picks the object at its initial pose (its arm: the SRDF end effector's
    /// parent group).
    #[arg(long, default_value = "right_hand")]
    pub pick_hand: String,
    /// Hand group that places it at its goal pose.
    #[arg(long, default_value = "left_hand")]
    pub place_hand: String,
}

impl TaskArgs {
    /// The problem (003 §V-C) with the grasp lists' default workspace; errors name the flag.
    pub fn problem(&self, ctx: &Ctx) -> Result<PickPlaceProblem> {
        let scene = ctx.scene(&self.scene)?;
        PickPlaceProblem::from_scene(
            &scene,
            &self.robot,
            &self.object,
            &self.pick_hand,
            &self.place_hand,
            &workspace_params(&GraspListParams::default()),
        )
        .map_err(|e| anyhow!("{e} (flag --{})", e.field().replace('_', "-")))
    }
}

/// The problem and the search bounds.
#[derive(Args, Debug, Clone)]
pub struct ExchangeArgs {
    #[command(flatten)]
    pub task: TaskArgs,
    /// Seed of the torso and exchange-pose samples.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Torso samples per grasp.
    #[arg(long)]
    pub torso_samples: Option<usize>,
    /// Exchange poses per double grasp.
    #[arg(long)]
    pub exchange_samples: Option<usize>,
    /// Most double grasps tried.
    #[arg(long)]
    pub max_double_grasps: Option<usize>,
    /// Grid nodes per axis of the exchange grid.
    #[arg(long)]
    pub cells: Option<usize>,
    /// Folder of cached grasp lists (built with default parameters when missing).
    #[arg(long, default_value = "data/grasps")]
    pub cache: std::path::PathBuf,
}

impl ExchangeArgs {
    fn params(&self) -> Result<ConfigParams> {
        let mut p = ConfigParams {
            seed: self.seed,
            ..ConfigParams::default()
        };
        if let Some(v) = self.torso_samples {
            p.torso_samples = v;
        }
        if let Some(v) = self.exchange_samples {
            p.exchange_samples = v;
        }
        if let Some(v) = self.max_double_grasps {
            p.max_double_grasps = v;
        }
        if let Some(v) = self.cells {
            p.exchange.cells = v;
        }
        p.validate()
            .map_err(|e| anyhow!("{e} (flag --{})", e.field().replace('_', "-")))?;
        Ok(p)
    }
}

/// Everything the configuration phase needs, prepared offline (problem, grasp lists).
struct Setup {
    problem: PickPlaceProblem,
    pick_list: Arc<GraspList>,
    place_list: Arc<GraspList>,
}

fn setup(ctx: &Ctx, a: &ExchangeArgs) -> Result<Setup> {
    let lp = GraspListParams::default();
    let problem = a.task.problem(ctx)?;
    let object = GraspObject::new(&problem.object_name, problem.object.clone())
        .map_err(|e| anyhow!("{e} (flag --object)"))?;
    let cache = GraspListCache::new(Some(a.cache.clone()));
    let list = |hand| {
        cache
            .get_or_build(hand, &object, &lp, &|_, _| {}, &|| false)
            .map(|(l, _)| l)
            .map_err(|e| anyhow!("{e}"))
    };
    let pick_list = list(&problem.pick.hand)?;
    let place_list = list(&problem.place.hand)?;
    Ok(Setup {
        problem,
        pick_list,
        place_list,
    })
}

/// The online part: exchange grid, single and double grasp configurations.
fn configure(s: &Setup, params: &ConfigParams) -> Result<(ExchangeGrid, KeyConfigurations)> {
    let p = &s.problem;
    let grid = exchange_grid(p, &params.exchange).map_err(|e| anyhow!("{e}"))?;
    let keys = key_configurations(p, &s.pick_list, &s.place_list, &grid, params)
        .map_err(|e| anyhow!("{e}"))?;
    Ok((grid, keys))
}

/// `manyhands plan exchange`.
pub fn plan(ctx: &Ctx, a: &ExchangeArgs) -> Result<()> {
    let params = a.params()?;
    let s = setup(ctx, a)?;
    let t0 = Instant::now();
    let (grid, keys) = configure(&s, &params)?;
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    let p = &s.problem;
    let names = |q: &[f64]| -> serde_json::Map<String, serde_json::Value> {
        q.iter()
            .enumerate()
            .map(|(v, x)| (p.robot.var_name(v).to_string(), json!(x)))
            .collect()
    };
    let e = grid.position();
    let v = json!({
        "scene": a.task.scene, "object": p.object_name, "seed": a.seed,
        "pick_hand": p.pick.hand.group, "place_hand": p.place.hand.group,
        "grasp_lists": {"pick": s.pick_list.grasps.len(), "place": s.place_list.grasps.len()},
        "exchange": {"position": grid.nodes[grid.best].position, "cost": grid.nodes[grid.best].cost,
            "nodes": grid.nodes.len(), "free": grid.nodes.iter().filter(|n| n.free).count(),
            "pose": keys.exchange_pose},
        "double": keys.double,
        "grasp": {"grasp": keys.grasp.grasp, "score": keys.grasp.score, "q": names(&keys.grasp.q)},
        "exchange_config": names(&keys.exchange),
        "place": {"grasp": keys.place.grasp, "score": keys.place.score, "q": names(&keys.place.q)},
        "complete": keys.complete, "stats": keys.stats, "ms": ms,
    });
    ctx.print(&v, || {
        let st = &keys.stats;
        let torso = |q: &[f64]| {
            p.torso
                .iter()
                .map(|&v| format!("{}={:.3}", p.robot.var_name(v), q[v]))
                .collect::<Vec<_>>()
                .join(" ")
        };
        format!(
            "{} in {}: grasp lists {} ({}) / {} ({}); single-grasp configurations {} / {}, {} double grasps among them\n\
             exchange position ({:.3}, {:.3}, {:.3}) m, cost {:.3} m ({} grid nodes in reach, {} free)\n\
             double grasp pick #{} place #{}: score {:.3} (quality {:.3}, configuration {:.3}); {} complete\n\
             grasp    q_r^g: {}  score {:.3}\n\
             exchange q_r^e: {}\n\
             place    q_r^p: {}  score {:.3}\n\
             {} double grasps tried, {} IK calls, {} IK solutions, {} exact collision checks, {} exchange poses; {:.1} ms",
            p.object_name, a.task.scene, s.pick_list.grasps.len(), p.pick.hand.group,
            s.place_list.grasps.len(), p.place.hand.group,
            keys.stats.single_pick, keys.stats.single_place, keys.stats.double_grasps,
            e.x, e.y, e.z, grid.nodes[grid.best].cost, grid.nodes.len(),
            grid.nodes.iter().filter(|n| n.free).count(),
            keys.double.pick, keys.double.place, keys.double.score, keys.double.quality,
            keys.double.configuration, keys.complete,
            torso(&keys.grasp.q), keys.grasp.score, torso(&keys.exchange), torso(&keys.place.q),
            keys.place.score,
            st.double_grasps_tried, st.ik_calls, st.ik_solutions, st.collision_checks, st.exchange_poses, ms
        )
    });
    Ok(())
}

/// `manyhands bench exchange` arguments.
#[derive(Args, Debug)]
pub struct ExchangeBenchArgs {
    #[command(flatten)]
    pub problem: ExchangeArgs,
    /// Seeded runs (seeds seed..seed+runs).
    #[arg(long, default_value_t = 20)]
    pub runs: u64,
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => f64::NAN,
        _ if n % 2 == 1 => v[n / 2],
        _ => (v[n / 2 - 1] + v[n / 2]) / 2.0,
    }
}

/// `manyhands bench exchange`: the configuration phase (exchange grid; single-grasp
/// configurations, double grasps among them, exchange configurations) timed over seeded runs; the grasp lists (offline) are
/// loaded or built once before.
pub fn bench(ctx: &Ctx, a: &ExchangeBenchArgs) -> Result<()> {
    let s = setup(ctx, &a.problem)?;
    let mut total = Vec::new();
    let mut grid_ms = Vec::new();
    let mut configs_ms = Vec::new();
    let mut solved = 0;
    let mut checks = Vec::new();
    for run in 0..a.runs.max(1) {
        let mut params = a.problem.params()?;
        params.seed = a.problem.seed + run;
        let p = &s.problem;
        let t0 = Instant::now();
        let grid = exchange_grid(p, &params.exchange);
        let t1 = Instant::now();
        let res =
            grid.and_then(|g| key_configurations(p, &s.pick_list, &s.place_list, &g, &params));
        let t2 = Instant::now();
        if let Ok(k) = &res {
            solved += 1;
            checks.push(k.stats.collision_checks as f64);
        }
        grid_ms.push((t1 - t0).as_secs_f64() * 1e3);
        configs_ms.push((t2 - t1).as_secs_f64() * 1e3);
        total.push((t2 - t0).as_secs_f64() * 1e3);
    }
    let runs = total.len();
    let (md, mc, mt) = (
        median(&mut grid_ms),
        median(&mut configs_ms),
        median(&mut total),
    );
    let mchecks = median(&mut checks);
    let v = json!({"scene": a.problem.task.scene, "runs": runs, "solved": solved,
        "median_ms": {"exchange_grid": md, "configurations": mc, "total": mt},
        "median_collision_checks": mchecks, "target_ms": 50.0, "paper_s": 6.8});
    ctx.print(&v, || {
        format!(
            "configuration phase (003 §IV-B + §V-C), {} × {} in {}, median over {runs} seeded runs ({solved}/{runs} solved):\n\
             \x20 exchange grid                       {md:>9.2} ms\n\
             \x20 single + double grasp configs      {mc:>9.2} ms   ({mchecks:.0} exact collision checks)\n\
             \x20 total                               {mt:>9.2} ms   target ≤ 50 ms [paper: 4.2 s + 2.6 s]",
            a.problem.task.robot, a.problem.task.object, a.problem.task.scene
        )
    });
    Ok(())
}
