//! `manyhands plan multi-robot`: Multi-Robot-RRT (002 Alg. 3) with phase-space scheduling
//! (002 §V) on a scene; the JSON answer is the HTTP job kind `multi_robot`'s result.

use anyhow::{anyhow, Result};
use clap::Args;

use super::commands::Ctx;
use super::plan::{settings, termination, MultiRobotArgs};
use manyhands::grasp::WrenchSpaceSettings;
use manyhands::model::Scene;
use manyhands::planning::multi_robot_rrt::{
    multi_robot_rrt, MultiRobotEvent, MultiRobotPlan, MultiRobotProblem, MultiRobotSettings,
};
use manyhands::planning::phase_space::{phase_space_svg, PhaseSpace, RobotTrajectory};
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
    let names = robot_names(&scene, &a.robots);
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
    ctx.print(&plan.to_json(&p, a.sample_period), || summary(&p, &plan));
    Ok(())
}

/// The phase space of an accepted plan as SVG (002 Fig. 9).
pub fn svg_of(p: &MultiRobotProblem, plan: &MultiRobotPlan) -> Result<String> {
    let trajectories: Vec<RobotTrajectory> = plan
        .solutions
        .iter()
        .map(|s| RobotTrajectory {
            robot: p.members[s.member].robot,
            waypoints: s.path.clone(),
            accelerations: None,
        })
        .collect();
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
    let req: manyhands::server::multi_robot::ScheduleRequest = super::query::parse(&text)?;
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
