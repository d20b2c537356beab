//! `manyhands plan multi-robot`: Multi-Robot-RRT (002 Alg. 3) with phase-space scheduling
//! (002 §V) on a scene; the JSON answer is the HTTP job kind `multi_robot`'s result.

use anyhow::{anyhow, Result};
use clap::Args;

use super::commands::Ctx;
use super::plan::{settings, termination, timing, MultiRobotArgs};
use manyhands::grasp::WrenchSpaceSettings;
use manyhands::model::Scene;
use manyhands::planning::planners::multi_robot_rrt::{
    multi_robot_rrt, MultiRobotEvent, MultiRobotPlan, MultiRobotProblem, MultiRobotSettings,
};
use manyhands::planning::planners::phase_space::{phase_space_svg, PhaseSpace, PhaseSpaceSettings};
use manyhands::reachability::{GridCache, GridRecipe};

/// The robot instances of a request: the given names, else every robot of the scene.
pub fn robot_names(scene: &Scene, given: &[String]) -> Vec<String> {
    if given.is_empty() {
        scene.robots.iter().map(|r| r.name.clone()).collect()
    } else {
        given.to_vec()
    }
}

pub fn plan(ctx: &Ctx, a: &MultiRobotArgs) -> Result<()> {
    let scene = ctx.scene(&a.scene)?;
    let names = robot_names(&scene, &a.robot_names);
    let cache = GridCache::new(Some(a.grid_dir.clone()));
    let recipe = GridRecipe {
        samples: a.grid_samples,
        ..GridRecipe::default()
    };
    let p = MultiRobotProblem::with_grids(
        &scene,
        &names,
        &a.left,
        &a.right,
        &a.object,
        &cache,
        recipe,
        Default::default(),
    )?;
    let (planner, ik) = settings(&a.common, 0.03)?;
    let opts = timing(&a.common)?;
    let s = MultiRobotSettings {
        s_min: a.s_min,
        wrench: WrenchSpaceSettings {
            mu: a.mu,
            cone_edges: a.cone_edges,
            lambda: a.lambda,
            soft_finger: None,
        },
        planner,
        ik,
        deterministic: a.deterministic,
        max_solutions: a.max_solutions,
        phase: PhaseSpaceSettings {
            velocity_scaling: opts.velocity_scaling,
            acceleration_scaling: opts.acceleration_scaling,
            ..MultiRobotSettings::default().phase
        },
        ..MultiRobotSettings::default()
    };
    let mut term = termination(&a.common)?;
    let plan = multi_robot_rrt(
        &p,
        &s,
        &mut term,
        a.common.seed,
        &mut |_e: MultiRobotEvent<'_>| {},
    )?;
    if let Some(path) = &a.svg {
        let svg = svg_of(&p, &plan)?;
        std::fs::write(path, svg)?;
    }
    let json = plan.to_json(&p, a.sample_period, opts.sample_period)?;
    ctx.print(&json, || summary(&p, &plan));
    Ok(())
}

/// The phase space of an accepted plan as SVG (002 Fig. 9).
pub fn svg_of(p: &MultiRobotProblem, plan: &MultiRobotPlan) -> Result<String> {
    let trajectories = p.trajectories(&plan.solutions);
    let mut ps = PhaseSpace::new(&p.world, &p.world_q, &trajectories)?;
    let res = if trajectories.len() > 2 { 40 } else { 80 };
    Ok(phase_space_svg(&mut ps, &plan.schedule.phase_path, res))
}

fn summary(p: &MultiRobotProblem, plan: &MultiRobotPlan) -> String {
    let st = &plan.stats;
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    let mut s = format!(
        "Multi-Robot-RRT: {} robots, {:.2} ms in all ({:.2} ms planning, {:.2} ms phase space), score ε {:.4}\n",
        plan.solutions.len(),
        ms(st.total_time),
        ms(st.planning_time),
        ms(st.phase_space_time),
        plan.score.epsilon
    );
    s += &format!(
        "  IK results {}, solution trajectories {}, collision checks {}, combinations {} (rejected: {} collision, {} score, {} deadlock)\n",
        st.ik_results(),
        st.solutions(),
        st.collision_checks(),
        st.combinations,
        st.rejected_collision,
        st.rejected_score,
        st.rejected_deadlock
    );
    for sol in &plan.solutions {
        let m = &p.members[sol.member];
        s += &format!(
            "  {:<10} {} waypoints, grasps {} + {}\n",
            m.name,
            sol.path.len(),
            m.problem.left_names[sol.grasps.0],
            m.problem.right_names[sol.grasps.1]
        );
    }
    s += &format!(
        "  schedule: {:?}, {} knots, {:.2} s (alone: {:?} s)",
        plan.schedule.method,
        plan.schedule.knots.len(),
        plan.schedule.duration,
        plan.schedule
            .robot_durations
            .iter()
            .map(|d| (d * 100.0).round() / 100.0)
            .collect::<Vec<_>>()
    );
    s
}

#[derive(Args, Debug)]
pub struct ScheduleArgs {
    /// The request body of job kind `schedule`: JSON text, `@FILE`, or `-` for standard input.
    pub body: String,
    /// Most seconds the search may take (the server's `--max-plan-seconds`).
    #[arg(long, default_value_t = 60.0)]
    pub max_seconds: f64,
}

pub fn schedule(ctx: &Ctx, a: &ScheduleArgs) -> Result<()> {
    let text = super::query::body_text(&a.body)?;
    let req: manyhands::server::multi_robot::ScheduleRequest =
        super::query::parse(&without_kind(&text, "schedule")?)?;
    let scene = std::sync::Arc::new(ctx.scene(&req.scene)?);
    let v = manyhands::server::multi_robot::schedule_locally(&req, scene, a.max_seconds)
        .map_err(|e| anyhow!("{e}"))?;
    ctx.print(&v, || {
        format!(
            "schedule: {}, {} knots, {:.2} s",
            v["method"].as_str().unwrap_or(""),
            v["points"].as_array().map_or(0, |p| p.len()),
            v["duration"].as_f64().unwrap_or(0.0)
        )
    });
    Ok(())
}

/// The body of `POST /v1/plans` for job kind `kind` as the request of that kind alone: its
/// `"kind"` member, when present, must be `kind` and is dropped (the HTTP body is accepted as
/// is); other text is returned unchanged for the request's own parse to report.
fn without_kind(text: &str, kind: &str) -> Result<String> {
    let Ok(serde_json::Value::Object(mut m)) = serde_json::from_str::<serde_json::Value>(text)
    else {
        return Ok(text.to_string());
    };
    match m.remove("kind") {
        None => Ok(text.to_string()),
        Some(serde_json::Value::String(k)) if k == kind => {
            Ok(serde_json::Value::Object(m).to_string())
        }
        Some(other) => Err(anyhow!(
            "request body, field 'kind': {other} is not \"{kind}\" (this command runs job kind \
             {kind} only)"
        )),
    }
}

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Seeded runs per table.
    #[arg(long, default_value_t = 30)]
    pub runs: u64,
    /// First seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Seconds per run (a run over it counts as a failure).
    #[arg(long, default_value_t = 5.0)]
    pub time_limit: f64,
    /// Only the table whose name contains this (`two`, `three`, `score`, `panda`).
    #[arg(long)]
    pub only: Option<String>,
    #[arg(long, default_value = "data/reach")]
    pub grid_dir: std::path::PathBuf,
}

/// One table of 002 §VI: `runs` seeded runs on `scene` (with `boxes` random boxes per seed),
/// time including the inverse maps; medians, means and p95 of the solved runs.
fn bench_table(
    ctx: &Ctx,
    a: &BenchArgs,
    scene: &str,
    object: &str,
    boxes: usize,
    paper: &str,
) -> Result<()> {
    use manyhands::collision::{random_boxes, RandomBoxes};
    let base = ctx.scene(scene)?;
    let names = robot_names(&base, &[]);
    let cache = GridCache::new(Some(a.grid_dir.clone()));
    let lib = ctx.library()?;
    let mut rows: Vec<[f64; 8]> = Vec::new();
    for run in 0..a.runs {
        let seed = a.seed + run;
        let scene = if boxes > 0 {
            let p = RandomBoxes {
                count: boxes,
                seed,
                lo: [-3.0, -3.0, 0.1],
                hi: [3.0, 3.0, 1.8],
                ..RandomBoxes::default()
            };
            random_boxes(&base, &p, &lib)?
        } else {
            base.clone()
        };
        let p = MultiRobotProblem::with_grids(
            &scene,
            &names,
            "torso_left_arm",
            "torso_right_arm",
            object,
            &cache,
            GridRecipe::default(),
            Default::default(),
        )?;
        let mut term = manyhands::planning::Termination::new()
            .with_time_limit(std::time::Duration::from_secs_f64(a.time_limit));
        let t = std::time::Instant::now();
        let r = multi_robot_rrt(
            &p,
            &MultiRobotSettings::default(),
            &mut term,
            seed,
            &mut |_| {},
        );
        let ms = t.elapsed().as_secs_f64() * 1e3 + p.map_time.as_secs_f64() * 1e3;
        if let Ok(plan) = r {
            let st = &plan.stats;
            rows.push([
                ms,
                st.phase_space_time.as_secs_f64() * 1e3,
                st.ik_results() as f64,
                st.solutions() as f64,
                st.collision_checks() as f64,
                st.combinations as f64,
                if st.scores > 0 {
                    st.score_time.as_secs_f64() * 1e3 / st.scores as f64
                } else {
                    0.0
                },
                plan.schedule.duration,
            ]);
        }
    }
    let n = rows.len();
    let col = |k: usize| -> Vec<f64> {
        let mut v: Vec<f64> = rows.iter().map(|r| r[k]).collect();
        v.sort_by(f64::total_cmp);
        v
    };
    let median = |v: &[f64]| {
        if v.is_empty() {
            f64::NAN
        } else {
            v[v.len() / 2]
        }
    };
    let mean = |v: &[f64]| {
        if v.is_empty() {
            f64::NAN
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    let p95 = |v: &[f64]| {
        if v.is_empty() {
            f64::NAN
        } else {
            v[((v.len() as f64 * 0.95).ceil() as usize).clamp(1, v.len()) - 1]
        }
    };
    let t = col(0);
    println!(
        "{scene} ({} robots{}): solved {n}/{} within {} s",
        names.len(),
        if boxes > 0 {
            format!(", {boxes} random boxes per seed")
        } else {
            String::new()
        },
        a.runs,
        a.time_limit
    );
    println!(
        "  {:<28} {:>10} {:>10} {:>10} {:>8} {:>8} {:>10} {:>8} {:>10} {:>10}",
        "",
        "median ms",
        "mean ms",
        "p95 ms",
        "# IK",
        "# traj",
        "# checks",
        "# combos",
        "phase ms",
        "score ms"
    );
    println!(
        "  {:<28} {:>10.2} {:>10.2} {:>10.2} {:>8.1} {:>8.1} {:>10.0} {:>8.1} {:>10.2} {:>10.3}",
        "manyhands (means but time)",
        median(&t),
        mean(&t),
        p95(&t),
        mean(&col(2)),
        mean(&col(3)),
        mean(&col(4)),
        mean(&col(5)),
        mean(&col(1)),
        mean(&col(6)),
    );
    println!("  {:<28} {paper}", "paper (4 cores, means)");
    println!(
        "  phase space median {:.2} ms; schedule duration median {:.2} s",
        median(&col(1)),
        median(&col(7))
    );
    Ok(())
}

/// The `panda_four` row: four Pandas of the fetched MotionBenchMaker data (an outside robot)
/// around a table with crossing fixed goals; decoupled (each arm alone with RRT-Connect, then
/// the phase-space schedule) against RRT-Connect in the composite 28-D space.
fn bench_panda_four(a: &BenchArgs) -> Result<()> {
    use manyhands::planning::planners::decoupled::{
        composite, decoupled, DecoupledSettings, RobotGoal,
    };
    use manyhands::planning::planners::phase_space::ScheduleMethod;
    let dir = match manyhands::benchmark::mbm_data::locate() {
        Ok(d) => d,
        Err(why) => {
            println!("panda_four: skipped ({why})");
            return Ok(());
        }
    };
    let scene = manyhands::benchmark::mbm_data::panda_four_scene(&dir)?;
    let world = manyhands::collision::CollisionWorld::from_scene(&scene);
    let q0 = manyhands::collision::CollisionWorld::start_config(&scene);
    let goals: Vec<RobotGoal> = scene
        .robots
        .iter()
        .enumerate()
        .map(|(r, p)| {
            p.configs
                .get("goal")
                .map(|g| RobotGoal {
                    robot: r,
                    goal: g.clone(),
                })
                .ok_or_else(|| anyhow!("{}: no `goal` configuration", p.name))
        })
        .collect::<Result<_>>()?;
    let limit = std::time::Duration::from_secs_f64(a.time_limit);
    let (mut dec, mut com) = (Vec::new(), Vec::new());
    let (mut phase_ms, mut makespan, mut seq_span) = (Vec::new(), Vec::new(), Vec::new());
    let mut methods = [0usize; 4];
    let (mut iters, mut nodes, mut segs) = (Vec::new(), Vec::new(), Vec::new());
    for run in 0..a.runs {
        let seed = a.seed + run;
        let mut term = manyhands::planning::Termination::new().with_time_limit(limit);
        let t = std::time::Instant::now();
        if let Ok(p) = decoupled(
            &world,
            &q0,
            &goals,
            &DecoupledSettings::default(),
            &mut term,
            seed,
        ) {
            dec.push(t.elapsed().as_secs_f64() * 1e3);
            phase_ms.push(p.schedule.stats.time.as_secs_f64() * 1e3);
            makespan.push(p.schedule.duration);
            iters.push(p.schedule.stats.iterations as f64);
            nodes.push(p.schedule.stats.tree_nodes as f64);
            segs.push(p.schedule.stats.segments_checked as f64);
            seq_span.push(p.schedule.robot_durations.iter().sum::<f64>());
            methods[match p.schedule.method {
                ScheduleMethod::Simultaneous => 0,
                ScheduleMethod::Prioritized => 1,
                ScheduleMethod::PhaseSpaceRrt => 2,
                ScheduleMethod::Sequential => 3,
            }] += 1;
        }
        let mut term = manyhands::planning::Termination::new().with_time_limit(limit);
        let t = std::time::Instant::now();
        if composite(&world, &q0, &goals, &Default::default(), &mut term, seed).is_ok() {
            com.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    println!(
        "panda_four (4 MotionBenchMaker Pandas, 28 DoF, crossing fixed goals), {} runs, {} s each",
        a.runs, a.time_limit
    );
    println!(
        "  {:<44} {:>8} {:>10} {:>10}",
        "", "solved", "median ms", "phase ms"
    );
    println!(
        "  {:<44} {:>8} {:>10.2} {:>10.2}",
        "decoupled RRT-Connect + phase-space schedule",
        format!("{}/{}", dec.len(), a.runs),
        median(&mut dec),
        median(&mut phase_ms)
    );
    println!(
        "  {:<44} {:>8} {:>10.2}",
        "composite RRT-Connect (28-D)",
        format!("{}/{}", com.len(), a.runs),
        median(&mut com)
    );
    println!(
        "  schedules: {} simultaneous, {} prioritized, {} phase-space RRT, {} sequential; \
         makespan median {:.2} s (one after the other: {:.2} s)",
        methods[0],
        methods[1],
        methods[2],
        methods[3],
        median(&mut makespan),
        median(&mut seq_span)
    );
    println!(
        "  phase space medians: {:.0} iterations, {:.0} tree nodes, {:.0} certified pieces",
        median(&mut iters),
        median(&mut nodes),
        median(&mut segs)
    );
    Ok(())
}

pub fn bench(ctx: &Ctx, a: &BenchArgs) -> Result<()> {
    let want = |s: &str| a.only.as_deref().is_none_or(|o| s.contains(o));
    if want("two") {
        bench_table(
            ctx,
            a,
            "kitchen_two",
            "table",
            0,
            "Table I: 9.5 s, 16.8 IK, 7.8 traj, 7028 checks, 2.8 combos, phase space 1.0 s",
        )?;
    }
    if want("three") {
        bench_table(
            ctx,
            a,
            "boxes_three",
            "large_table",
            30,
            "Table II: 8.9 s, 20.2 IK, 13.0 traj, 19434 checks, 37.1 combos, phase space 7.0 s",
        )?;
    }
    if want("score") {
        bench_score(ctx, a)?;
    }
    if want("panda") {
        bench_panda_four(a)?;
    }
    Ok(())
}

/// The collector's score of one combination (002 §IV-B) on real contact sets of the kitchen_two
/// table grasps (two contacts each): `runs × 10` combinations of the two robots — per robot a
/// random (cell, yaw) of its bimanual map R_bi and a left and a right grasp that cell reaches,
/// i.e. pairs IkDualArm can return (8 contacts) — and as many sets of ten grasps at random
/// (20 contacts, the size of 002 Fig. 7), scored by the collector's proof and nearest-facet ε and
/// by the full wrench hull, alternated per set; medians in µs, and whether they agree.
fn bench_score(ctx: &Ctx, a: &BenchArgs) -> Result<()> {
    use rand::{Rng, SeedableRng};
    let scene = ctx.scene("kitchen_two")?;
    let names = robot_names(&scene, &[]);
    let cache = GridCache::new(Some(a.grid_dir.clone()));
    let p = MultiRobotProblem::with_grids(
        &scene,
        &names,
        "torso_left_arm",
        "torso_right_arm",
        "table",
        &cache,
        GridRecipe::default(),
        Default::default(),
    )?;
    let wrench = MultiRobotSettings::default().wrench;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(a.seed);
    let cells: Vec<Vec<usize>> = p
        .members
        .iter()
        .map(|m| {
            let (bi, rights) = &*m.problem.map;
            (0..bi.value.len())
                .filter(|&k| !bi.grasps[k].is_empty() && !rights[k].is_empty())
                .collect()
        })
        .collect();
    if cells.iter().any(|c| c.is_empty()) {
        return Err(anyhow!("kitchen_two: a robot's bimanual map is empty"));
    }
    let combos = (a.runs * 10).max(1);
    // The collector's combinations: two robots, two hands each.
    let mut pairs = Vec::new();
    for _ in 0..combos {
        let grasps: Vec<(usize, usize)> = p
            .members
            .iter()
            .zip(&cells)
            .map(|(m, cells)| {
                let (bi, rights) = &*m.problem.map;
                let k = cells[rng.random_range(0..cells.len())];
                let l = bi.grasps[k][rng.random_range(0..bi.grasps[k].len())] as usize;
                let r = rights[k][rng.random_range(0..rights[k].len())] as usize;
                (l, r)
            })
            .collect();
        pairs.push(p.combination_wrenches(&grasps, &wrench)?);
    }
    // 20 contacts as in 002 Fig. 7: ten of the table's grasps (two contacts each) at random.
    let table = scene
        .object("table")
        .ok_or_else(|| anyhow!("kitchen_two has no table"))?;
    let (centre, _) = manyhands::grasp::object_centre(&table.body.shapes);
    let radius = manyhands::grasp::object_radius(&table.body.shapes, &centre);
    let ws = WrenchSpaceSettings {
        lambda: Some(1.0 / radius),
        ..wrench
    };
    let mut twenty = Vec::new();
    for _ in 0..combos {
        let mut contacts = Vec::new();
        for _ in 0..10 {
            let g = &table.grasps[rng.random_range(0..table.grasps.len())];
            contacts.extend(manyhands::grasp::grasp_contacts(g));
        }
        let w = manyhands::grasp::primitive_wrenches(&contacts, &centre, &ws)?;
        twenty.push((w, 1.0 / radius));
    }
    for (label, sets) in [
        ("the collector's combinations (2 robots × 2 hands)", pairs),
        (
            "ten table grasps at random (002 Fig. 7's 20 contacts)",
            twenty,
        ),
    ] {
        score_rows(label, &sets, &wrench)?;
    }
    Ok(())
}

/// One block of `bench multi-robot --only score`: the proof, the exact nearest-facet ε and the
/// full hull on `sets`, alternated per set; medians and p95 in µs.
fn score_rows(
    label: &str,
    sets: &[(Vec<manyhands::grasp::Point6>, f64)],
    wrench: &WrenchSpaceSettings,
) -> Result<()> {
    use manyhands::grasp::{
        quality_of_wrenches, quality_of_wrenches_nearest, score_exceeds_nearest,
    };
    let combos = sets.len();
    let (mut fast, mut full) = (Vec::new(), Vec::new());
    let (mut grown, mut whole) = (Vec::new(), Vec::new());
    let (mut agree, mut fc, mut contacts, mut max_rel) = (0u64, 0u64, 0usize, 0.0f64);
    let s_min = MultiRobotSettings::default().s_min;
    let (mut decide, mut proofs, mut wrong, mut fallbacks) = (Vec::new(), 0u64, 0u64, 0u64);
    for (c, (w, lambda)) in sets.iter().enumerate() {
        let lambda = *lambda;
        contacts = contacts.max(w.len() / wrench.cone_edges);
        let time = |f: &dyn Fn() -> Result<manyhands::grasp::GraspQuality, _>| {
            let t = std::time::Instant::now();
            let q = f();
            (t.elapsed().as_secs_f64() * 1e6, q)
        };
        let run_fast = || quality_of_wrenches_nearest(w, lambda);
        let run_full = || quality_of_wrenches(w, lambda);
        let ((tf, qf), (tw, qw)) = if c % 2 == 0 {
            let f = time(&run_fast);
            (f, time(&run_full))
        } else {
            let w = time(&run_full);
            (time(&run_fast), w)
        };
        let (qf, qw) = (qf?, qw?);
        let t = std::time::Instant::now();
        let proven = score_exceeds_nearest(w, s_min);
        decide.push(t.elapsed().as_secs_f64() * 1e6);
        if proven && !(qw.force_closure && qw.epsilon > s_min) {
            wrong += 1;
        }
        proofs += u64::from(proven);
        fallbacks += u64::from(qf.facets == qw.facets);
        fast.push(tf);
        full.push(tw);
        grown.push(qf.facets as f64);
        whole.push(qw.facets as f64);
        let rel = (qf.epsilon - qw.epsilon).abs() / qw.epsilon.abs().max(1e-300);
        if qf.force_closure == qw.force_closure && (qw.epsilon == 0.0 || rel <= 1e-9) {
            agree += 1;
        }
        if qw.epsilon > 0.0 {
            max_rel = max_rel.max(rel);
        }
        fc += u64::from(qw.force_closure);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let p95 = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(((v.len() as f64 * 0.95).ceil() as usize).clamp(1, v.len()) - 1)
            .copied()
            .unwrap_or(f64::NAN)
    };
    println!(
        "kitchen_two grasp score, {label}: {combos} sets of {contacts} contacts (μ {}, {} cone edges), {fc} force closure",
        wrench.mu, wrench.cone_edges
    );
    println!(
        "  {:<36} {:>12} {:>12} {:>14}",
        "", "median µs", "p95 µs", "median facets"
    );
    println!(
        "  {:<36} {:>12.1} {:>12.1} {:>14}",
        format!("proof ε > s_min = {s_min} (collector)"),
        median(&mut decide),
        p95(&mut decide),
        "",
    );
    println!(
        "  {:<36} {:>12.1} {:>12.1} {:>14.0}",
        "exact nearest-facet ε (collector)",
        median(&mut fast),
        p95(&mut fast),
        median(&mut grown)
    );
    println!(
        "  {:<36} {:>12.1} {:>12.1} {:>14.0}",
        "full wrench hull",
        median(&mut full),
        p95(&mut full),
        median(&mut whole)
    );
    println!(
        "  exact: agree with the full hull (verdict, ε within 1e-9 relative) {agree}/{combos}, largest relative ε difference {max_rel:.1e}, {fallbacks} decided by the full hull; proof: {proofs}/{combos} proven, {wrong} wrong"
    );
    Ok(())
}
