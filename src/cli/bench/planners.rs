//! `manyhands bench planners`: the shape of paper 000's Tables 3–5 (single-arm, dual-arm
//! re-grasping, kitchen task) and 002's Bimanual IK-RRT on the shipped scenes — N seeded runs per
//! row, without and with the obstacle; median, mean, p95 time, success rate, path length before
//! and after pruning, collision checks; the paper's average beside ours. Times are wall time of
//! the whole query (IK, search, pruning and re-validation); one thread.

use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use clap::Args;
use serde_json::json;

use super::super::commands::Ctx;
use manyhands::collision::CollisionWorld;
use manyhands::geometry::Pose;
use manyhands::kinematics::randomized::RandomizedIkSettings;
use manyhands::model::Scene;
use manyhands::planning::planners::bimanual_ik_rrt::{
    paper_settings, BimanualProblem, BimanualSettings,
};
use manyhands::planning::problems::grasping::{arm_grid, HandOffProblem, ReachProblem};
use manyhands::planning::tasks::task::{kitchen_task, GraspAlgorithm, KitchenTask};
use manyhands::planning::{IkRrtSettings, PlanError, PlanResult, PlanStats, Termination};
use manyhands::reachability::{GridCache, GridRecipe, ReachabilityGrid};

#[derive(Args, Debug)]
pub struct PlannersBenchArgs {
    /// Seeded runs per row.
    #[arg(long, default_value_t = 100)]
    pub runs: u64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Time limit of one run (s); a run that hits it counts as a failure.
    #[arg(long, default_value_t = 10.0)]
    pub time_limit: f64,
    /// Only the rows whose full name contains this (e.g. `IK-RRT reach wok, obstacle`,
    /// `kitchen task`, `Bimanual`); none matching is an error.
    #[arg(long)]
    pub only: Option<String>,
    /// Folder caching the reachability grids: ARMAR's arm grids (the randomized IK's filter,
    /// 000 §II-D / §III-B) and the platform-frame grids of the bimanual row. Loaded, or built
    /// and stored, before anything is timed.
    #[arg(long, default_value = "data/reach")]
    pub grid_dir: std::path::PathBuf,
    /// IK-RRT's goal samplers without the arm grids (the randomized IK unfiltered).
    #[arg(long)]
    pub no_reachability: bool,
}

/// ARMAR's right and left arm grids (none with `--no-reachability`).
type ArmGrids = (Option<Arc<ReachabilityGrid>>, Option<Arc<ReachabilityGrid>>);

fn arm_grids(s: &Scene, a: &PlannersBenchArgs) -> Result<ArmGrids> {
    if a.no_reachability {
        return Ok((None, None));
    }
    let world = CollisionWorld::from_scene(s);
    let cache = GridCache::new(Some(a.grid_dir.clone()));
    Ok((
        arm_grid(&cache, &world, "armar", "torso_right_arm")?,
        arm_grid(&cache, &world, "armar", "torso_left_arm")?,
    ))
}

/// One run's figures.
struct Run {
    ok: bool,
    ms: f64,
    ik_ms: f64,
    len_raw: f64,
    len: f64,
    checks: u64,
}

impl Run {
    fn from(t: Duration, r: Result<&[PlanStats], PlanError>) -> Run {
        let ms = t.as_secs_f64() * 1e3;
        match r {
            Ok(stats) => Run {
                ok: true,
                ms,
                ik_ms: stats.iter().map(|s| s.ik_time.as_secs_f64() * 1e3).sum(),
                len_raw: stats.iter().map(|s| s.length_raw).sum(),
                len: stats.iter().map(|s| s.length_simplified).sum(),
                checks: stats.iter().map(|s| s.collision_checks).sum(),
            },
            Err(_) => Run {
                ok: false,
                ms,
                ik_ms: 0.0,
                len_raw: 0.0,
                len: 0.0,
                checks: 0,
            },
        }
    }
}

struct Row {
    name: String,
    paper: &'static str,
    target: &'static str,
    runs: Vec<Run>,
}

fn pct(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let k = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[k.min(sorted.len() - 1)]
}

impl Row {
    fn summary(&self) -> serde_json::Value {
        let ok: Vec<&Run> = self.runs.iter().filter(|r| r.ok).collect();
        let mut t: Vec<f64> = ok.iter().map(|r| r.ms).collect();
        t.sort_by(f64::total_cmp);
        let mut ik: Vec<f64> = ok.iter().map(|r| r.ik_ms).collect();
        ik.sort_by(f64::total_cmp);
        let mut checks: Vec<f64> = ok.iter().map(|r| r.checks as f64).collect();
        checks.sort_by(f64::total_cmp);
        let n = ok.len().max(1) as f64;
        json!({
            "row": self.name,
            "runs": self.runs.len(),
            "solved": ok.len(),
            "median_ms": pct(&t, 0.5),
            "mean_ms": t.iter().sum::<f64>() / n,
            "p95_ms": pct(&t, 0.95),
            "max_ms": t.last().copied().unwrap_or(f64::NAN),
            "median_ik_ms": pct(&ik, 0.5),
            "mean_length_raw": ok.iter().map(|r| r.len_raw).sum::<f64>() / n,
            "mean_length_pruned": ok.iter().map(|r| r.len).sum::<f64>() / n,
            "median_collision_checks": pct(&checks, 0.5),
            "paper_avg": self.paper,
            "target": self.target,
        })
    }
}

fn ik_settings() -> RandomizedIkSettings {
    RandomizedIkSettings {
        max_tries: 50,
        ..RandomizedIkSettings::default()
    }
}

fn term(limit: f64) -> Termination {
    Termination::new().with_time_limit(Duration::from_secs_f64(limit))
}

/// `a.runs` timed calls of `plan(seed)` with seeds `a.seed`, `a.seed + 1`, …; a plan answers
/// the statistics of its phases.
fn timed_runs(
    a: &PlannersBenchArgs,
    mut plan: impl FnMut(u64) -> Result<Vec<PlanStats>, PlanError>,
) -> Vec<Run> {
    (0..a.runs)
        .map(|i| {
            let t = Instant::now();
            let r = plan(a.seed + i);
            Run::from(t.elapsed(), r.as_deref().map_err(Clone::clone))
        })
        .collect()
}

/// `armar` grasps the wok with the right hand (torso + right arm) from `q0`.
fn grasp_wok(
    s: &Scene,
    world: &CollisionWorld,
    q0: &[f64],
    (algorithm, grid): (GraspAlgorithm, &Option<Arc<ReachabilityGrid>>),
    time_limit: f64,
    seed: u64,
) -> Result<(ReachProblem, PlanResult), PlanError> {
    let p = ReachProblem::grasp(s, world, q0, "armar", "torso_right_arm", "wok")?;
    let r = algorithm.plan_reach(
        &p,
        grid.clone(),
        IkRrtSettings::default(),
        ik_settings(),
        &mut term(time_limit),
        seed,
    )?;
    Ok((p, r))
}

fn reach_row(
    s: &Scene,
    (algorithm, grids): (GraspAlgorithm, &ArmGrids),
    name: &str,
    paper: &'static str,
    target: &'static str,
    a: &PlannersBenchArgs,
) -> Result<Row> {
    let world = CollisionWorld::from_scene(s);
    let q0 = CollisionWorld::start_config(s);
    let runs = timed_runs(a, |seed| {
        let (_, r) = grasp_wok(s, &world, &q0, (algorithm, &grids.0), a.time_limit, seed)?;
        Ok(vec![r.stats])
    });
    Ok(Row {
        name: name.into(),
        paper,
        target,
        runs,
    })
}

/// The wok in the right hand (the grasp IK-RRT finds with seed 0), re-grasped to the left.
fn regrasp_row(
    s: &Scene,
    (algorithm, grids): (GraspAlgorithm, &ArmGrids),
    name: &str,
    paper: &'static str,
    target: &'static str,
    a: &PlannersBenchArgs,
) -> Result<Row> {
    let world = CollisionWorld::from_scene(s);
    let q0 = CollisionWorld::start_config(s);
    let ik = (GraspAlgorithm::IkRrt, &grids.0);
    let (p, r) = grasp_wok(s, &world, &q0, ik, a.time_limit, 0)?;
    let q1 = p
        .space
        .to_world(r.path.last().ok_or_else(|| anyhow!("empty grasp path"))?);
    let held: Pose = p.grasps[r.goal_index];
    let runs = timed_runs(a, |seed| {
        let h = HandOffProblem::new(
            s,
            &world,
            &q1,
            ("armar", "torso_right_arm"),
            ("armar", "torso_left_arm"),
            "wok",
            held,
        )?;
        let r = algorithm.plan_regrasp(
            &h,
            grids.1.clone(),
            IkRrtSettings::default(),
            ik_settings(),
            &mut term(a.time_limit),
            seed,
        )?;
        Ok(vec![r.stats])
    });
    Ok(Row {
        name: name.into(),
        paper,
        target,
        runs,
    })
}

/// Names of the two rows that are not grasp rows (`--only` matches them too).
const KITCHEN_ROW: &str = "kitchen task complete (grasp, regrasp, retreat, place)";
const BIMANUAL_ROW: &str =
    "Bimanual IK-RRT, armar grasps the kitchen table (20 DoF, maps included)";

fn kitchen_row(s: &Scene, grids: &ArmGrids, a: &PlannersBenchArgs) -> Result<Row> {
    let task = KitchenTask {
        grids: grids.clone(),
        ..KitchenTask::armar_wok()
    };
    let runs = timed_runs(a, |seed| {
        let plan = kitchen_task(s, &task, &mut term(a.time_limit), seed)?;
        Ok(plan.phases.into_iter().map(|ph| ph.stats).collect())
    });
    Ok(Row {
        name: KITCHEN_ROW.into(),
        paper: "803 ms IK + 6 310 ms planning",
        target: "≤ 50 ms",
        runs,
    })
}

fn bimanual_row(ctx: &Ctx, a: &PlannersBenchArgs) -> Result<Row> {
    let s = ctx.scene("kitchen")?;
    let model = s
        .robots
        .first()
        .ok_or_else(|| anyhow!("kitchen has no robot"))?
        .robot
        .clone();
    let cache = GridCache::new(Some(a.grid_dir.clone()));
    let gl: Arc<_> = cache.get(&model, "torso_left_arm", GridRecipe::default())?;
    let gr: Arc<_> = cache.get(&model, "torso_right_arm", GridRecipe::default())?;
    let world = CollisionWorld::from_scene(&s);
    let q0 = CollisionWorld::start_config(&s);
    let runs = timed_runs(a, |seed| {
        let p = BimanualProblem::new(
            &s,
            &world,
            &q0,
            "armar",
            ("torso_left_arm", "torso_right_arm"),
            "table",
            (&gl, &gr),
            BimanualSettings::default(),
        )?;
        let r = p.plan(
            paper_settings(),
            ik_settings(),
            &mut term(a.time_limit),
            seed,
        )?;
        Ok(vec![r.stats])
    });
    Ok(Row {
        name: BIMANUAL_ROW.into(),
        paper: "002: no single-robot figure",
        target: "≤ 20 ms",
        runs,
    })
}

pub fn run(ctx: &Ctx, a: &PlannersBenchArgs) -> Result<()> {
    if !(1..=100_000).contains(&a.runs) {
        return Err(anyhow!("runs: {} must be within [1, 100000]", a.runs));
    }
    if !(a.time_limit.is_finite() && a.time_limit > 0.0 && a.time_limit <= 600.0) {
        return Err(anyhow!(
            "time_limit: {} s must be within (0, 600]",
            a.time_limit
        ));
    }
    let want = |n: &str| a.only.as_deref().is_none_or(|o| n.contains(o));
    let kitchen = ctx.scene("kitchen")?;
    let obstacle = ctx.scene("obstacle")?;
    let grids = arm_grids(&kitchen, a)?;
    let mut rows = Vec::new();
    let mut add = |r: Result<Row>| -> Result<()> {
        let r = r?;
        if !ctx.json {
            print_row(&r.summary());
        }
        rows.push(r);
        Ok(())
    };
    if !ctx.json {
        println!(
            "{:<66} {:>7} {:>9} {:>9} {:>9} {:>8} {:>13} {:>8}  paper avg / target",
            "planner (runs)",
            "solved",
            "median",
            "mean",
            "p95",
            "IK med",
            "length→pruned",
            "checks"
        );
    }
    if !ctx.json {
        println!(
            "IK-RRT goals: randomized IK {} (grids loaded before timing)",
            if grids.0.is_some() {
                "filtered by ARMAR's arm reachability grids (000 §II-D, §III-B)"
            } else {
                "unfiltered (--no-reachability)"
            }
        );
    }
    use GraspAlgorithm::{IkRrt as Ik, JPlusRrt as JPlus};
    type RowFn = fn(
        &Scene,
        (GraspAlgorithm, &ArmGrids),
        &str,
        &'static str,
        &'static str,
        &PlannersBenchArgs,
    ) -> Result<Row>;
    /// Row builder, algorithm, label, paper figures and targets (no obstacle, obstacle).
    type GraspRow = (
        RowFn,
        GraspAlgorithm,
        &'static str,
        [&'static str; 2],
        [&'static str; 2],
    );
    let grasp_rows: [GraspRow; 4] = [
        (
            reach_row,
            Ik,
            "IK-RRT reach wok",
            ["140 ms", "480 ms"],
            ["≤ 1 ms", "≤ 5 ms"],
        ),
        (
            reach_row,
            JPlus,
            "J+-RRT reach wok",
            ["2 032 ms", "18 390 ms"],
            ["≤ 20 ms", "≤ 200 ms"],
        ),
        (
            regrasp_row,
            Ik,
            "dual-arm IK-RRT regrasp",
            ["278 ms", "469 ms"],
            ["≤ 5 ms", "≤ 5 ms"],
        ),
        (
            regrasp_row,
            JPlus,
            "dual-arm J+-RRT regrasp",
            ["1 662 ms", "5 192 ms"],
            ["≤ 60 ms", "≤ 60 ms"],
        ),
    ];
    for (row, alg, label, paper, target) in grasp_rows {
        for (k, (scene, what)) in [(&kitchen, "no obstacle"), (&obstacle, "obstacle")]
            .into_iter()
            .enumerate()
        {
            let name = format!("{label}, {what}");
            if want(&name) {
                add(row(scene, (alg, &grids), &name, paper[k], target[k], a))?;
            }
        }
    }
    if want(KITCHEN_ROW) {
        add(kitchen_row(&kitchen, &grids, a))?;
    }
    if want(BIMANUAL_ROW) {
        add(bimanual_row(ctx, a))?;
    }
    if rows.is_empty() {
        return Err(anyhow!(
            "only: no row's name contains {:?} (rows: IK-RRT reach wok, J+-RRT reach wok, \
             dual-arm IK-RRT regrasp, dual-arm J+-RRT regrasp — each ', no obstacle' or \
             ', obstacle' —, {KITCHEN_ROW}, {BIMANUAL_ROW})",
            a.only.as_deref().unwrap_or("")
        ));
    }
    if ctx.json {
        let v: Vec<serde_json::Value> = rows.iter().map(Row::summary).collect();
        println!("{}", serde_json::to_string_pretty(&v)?);
    }
    Ok(())
}

fn print_row(v: &serde_json::Value) {
    let f = |k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    println!(
        "{:<66} {:>3}/{:<3} {:>6.2} ms {:>6.2} ms {:>6.2} ms {:>5.2} ms {:>6.2}→{:<6.2} {:>8.0}  {} / {}",
        format!("{} ({})", v["row"].as_str().unwrap_or(""), v["runs"]),
        v["solved"],
        v["runs"],
        f("median_ms"),
        f("mean_ms"),
        f("p95_ms"),
        f("median_ik_ms"),
        f("mean_length_raw"),
        f("mean_length_pruned"),
        f("median_collision_checks"),
        v["paper_avg"].as_str().unwrap_or(""),
        v["target"].as_str().unwrap_or(""),
    );
}
