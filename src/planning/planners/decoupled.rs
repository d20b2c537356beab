//! Decoupled multi-robot planning for fixed goals: every robot planned alone with RRT-Connect in
//! the static scene (other robots ignored, as each worker of 002 §IV plans alone), then the
//! paths coordinated by the phase-space scheduler (002 §V, Alg. 4; [`crate::planning::planners::phase_space`]).
//! This is the pipeline of issue 23's `panda_four` cell (over HTTP: one `joint_space` job per
//! robot, then a `schedule` job); [`composite`] is the coupled baseline it is measured against
//! (RRT-Connect in the product space of all robots), both in `manyhands bench multi-robot`.
//!
//! Validity: each path is certified in the static scene by its planner; the schedule is
//! certified between the robots by the phase-space planner (its module documentation gives the
//! bound). Together every robot is free of the scene and of every other robot at every instant
//! of the common clock.

use std::time::{Duration, Instant};

use crate::collision::CollisionWorld;
use crate::planning::planners::phase_space::{
    PhaseSpace, PhaseSpaceSettings, RobotTrajectory, Schedule,
};
use crate::planning::{
    JointSpace, PlanError, PlanResult, RrtConnect, RrtConnectSettings, Termination,
};

/// One robot's query: its index in the world and its goal configuration (all its variables).
#[derive(Debug, Clone, PartialEq)]
pub struct RobotGoal {
    pub robot: usize,
    pub goal: Vec<f64>,
}

/// Settings of [`decoupled`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DecoupledSettings {
    /// RRT-Connect of every single-robot query.
    pub rrt: RrtConnectSettings,
    /// The phase-space scheduler.
    pub phase: PhaseSpaceSettings,
}

/// The answer of [`decoupled`]: every robot's path (in the order of the goals) and the schedule.
#[derive(Debug, Clone)]
pub struct DecoupledPlan {
    pub paths: Vec<PlanResult>,
    /// Time of the single-robot queries together.
    pub planning_time: Duration,
    pub schedule: Schedule,
}

/// Plans every robot of `goals` alone from its configuration in `world_q`, then schedules the
/// paths. Robot `goals[k].robot` uses the seed `seed + k`; `term` bounds everything.
pub fn decoupled(
    world: &CollisionWorld,
    world_q: &[f64],
    goals: &[RobotGoal],
    settings: &DecoupledSettings,
    term: &mut Termination,
    seed: u64,
) -> Result<DecoupledPlan, PlanError> {
    if world_q.len() != world.dof() {
        return Err(PlanError::InvalidInput(format!(
            "world configuration has {} values, the world has {} variables",
            world_q.len(),
            world.dof()
        )));
    }
    let t0 = Instant::now();
    let mut paths = Vec::with_capacity(goals.len());
    for (k, g) in goals.iter().enumerate() {
        let name = world
            .robots
            .get(g.robot)
            .map(|p| p.name.clone())
            .ok_or_else(|| PlanError::InvalidInput(format!("goals[{k}]: no robot {}", g.robot)))?;
        let alone = world
            .subset(&[g.robot])
            .ok_or_else(|| PlanError::InvalidInput(format!("goals[{k}]: robot {name} twice")))?;
        let start = world.robot_config(g.robot, world_q).to_vec();
        let space = JointSpace::all(&alone, start.clone())?;
        let mut rrt = RrtConnect::new(space, &alone, settings.rrt)?;
        let r = rrt
            .plan(
                &start,
                std::slice::from_ref(&g.goal),
                term,
                seed.wrapping_add(k as u64),
            )
            .map_err(|e| e.in_phase(format!("planning {name} alone")))?;
        paths.push(r);
    }
    let planning_time = t0.elapsed();
    let trajectories: Vec<RobotTrajectory> = goals
        .iter()
        .zip(&paths)
        .map(|(g, r)| RobotTrajectory {
            robot: g.robot,
            waypoints: r.path.clone(),
            accelerations: None,
        })
        .collect();
    let mut ps = PhaseSpace::new(world, world_q, &trajectories)?;
    let schedule = ps
        .plan(&settings.phase, term, seed)
        .map_err(|e| e.in_phase("phase-space scheduling"))?;
    Ok(DecoupledPlan {
        paths,
        planning_time,
        schedule,
    })
}

/// The coupled baseline: RRT-Connect in the composite space of every robot of `goals` at once
/// (the others held at `world_q`), in the whole world (scene and robots). The path's states are
/// the goals' robots' variables in order.
pub fn composite(
    world: &CollisionWorld,
    world_q: &[f64],
    goals: &[RobotGoal],
    settings: &RrtConnectSettings,
    term: &mut Termination,
    seed: u64,
) -> Result<PlanResult, PlanError> {
    let mut vars = Vec::new();
    let mut goal_world = world_q.to_vec();
    for (k, g) in goals.iter().enumerate() {
        let p = world
            .robots
            .get(g.robot)
            .ok_or_else(|| PlanError::InvalidInput(format!("goals[{k}]: no robot {}", g.robot)))?;
        if g.goal.len() != p.robot.dof() {
            return Err(PlanError::InvalidInput(format!(
                "goals[{k}] ({}): {} values for {} variables",
                p.name,
                g.goal.len(),
                p.robot.dof()
            )));
        }
        goal_world[p.offset..p.offset + g.goal.len()].copy_from_slice(&g.goal);
        vars.extend(p.offset..p.offset + p.robot.dof());
    }
    let space = JointSpace::new(world, &vars, world_q.to_vec())?;
    let start: Vec<f64> = vars.iter().map(|&v| world_q[v]).collect();
    let goal: Vec<f64> = vars.iter().map(|&v| goal_world[v]).collect();
    let mut rrt = RrtConnect::new(space, world, *settings)?;
    rrt.plan(&start, &[goal], term, seed)
}
