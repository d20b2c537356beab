//! Method (a), decoupled: every arm planned alone in the static scene with the existing
//! single-arm planner (RRT-Connect, the other robots ignored as each worker of paper 002 §IV
//! plans alone), then the paths coordinated by the phase-space scheduler (002 §V, Alg. 4,
//! [`crate::planning::planners::phase_space`]). Fastest when it works; when some pair of paths has no
//! monotone free path in its phase space, no timing of these paths can work and the planner
//! moves on (module documentation of [`super`]). The same pairwise schedules name the arms in
//! conflict for the composite fallback ([`super::composite`]).

use super::problem::MultiArmProblem;
use crate::planning::planners::phase_space::{
    PhaseSpace, PhaseSpaceSettings, RobotTrajectory, Schedule,
};
use crate::planning::{JointSpace, PlanError, RrtConnect, RrtConnectSettings, Termination};

/// Every arm's path alone (values of its variables), in arm order. Arm k uses `seed + k`.
pub(crate) fn plan_alone(
    p: &MultiArmProblem,
    rrt: &RrtConnectSettings,
    term: &mut Termination,
    seed: u64,
) -> Result<Vec<Vec<Vec<f64>>>, PlanError> {
    let mut paths = Vec::with_capacity(p.arms.len());
    for (k, a) in p.arms.iter().enumerate() {
        let name = p.arm_name(k).to_string();
        let alone = p
            .world
            .subset(&[a.robot])
            .ok_or_else(|| PlanError::InvalidInput(format!("arms[{k}]: no robot")))?;
        let base = p.world.robot_config(a.robot, &p.world_q).to_vec();
        let start: Vec<f64> = a.vars.iter().map(|&v| base[v]).collect();
        let space = JointSpace::new(&alone, &a.vars, base)?;
        let mut planner = RrtConnect::new(space, &alone, *rrt)?;
        let r = planner
            .plan(
                &start,
                std::slice::from_ref(&a.goal),
                term,
                seed.wrapping_add(k as u64),
            )
            .map_err(|e| e.in_phase(format!("planning {name} alone")))?;
        paths.push(r.path);
    }
    Ok(paths)
}

/// The phase-space schedule of the arms `which` along their paths alone, the robots without an
/// arm standing at their start and the other arms left out.
pub(crate) fn schedule(
    p: &MultiArmProblem,
    paths: &[Vec<Vec<f64>>],
    which: &[usize],
    settings: &PhaseSpaceSettings,
    term: &mut Termination,
    seed: u64,
) -> Result<Schedule, PlanError> {
    // The world of the arms of `which` (first, in that order) and of the robots without an arm.
    let mut keep: Vec<usize> = which.iter().map(|&k| p.arms[k].robot).collect();
    keep.extend((0..p.world.robots.len()).filter(|r| p.arms.iter().all(|a| a.robot != *r)));
    let world = p
        .world
        .subset(&keep)
        .ok_or_else(|| PlanError::InvalidInput("arms: a robot twice".into()))?;
    let world_q = p.world.subset_config(&keep, &p.world_q);
    let trajectories: Vec<RobotTrajectory> = which
        .iter()
        .enumerate()
        .map(|(i, &k)| {
            let a = &p.arms[k];
            let model = &p.world.robots[a.robot].robot;
            let base = p.world.robot_config(a.robot, &p.world_q);
            RobotTrajectory {
                robot: i,
                waypoints: paths[k]
                    .iter()
                    .map(|q| {
                        let mut c = base.to_vec();
                        for (&v, &x) in a.vars.iter().zip(q) {
                            c[v] = x;
                        }
                        c
                    })
                    .collect(),
                accelerations: Some(
                    (0..model.dof())
                        .map(|v| model.acceleration_limit(v))
                        .collect(),
                ),
            }
        })
        .collect();
    let mut ps = PhaseSpace::new(&world, &world_q, &trajectories)?;
    ps.plan(settings, term, seed)
}

/// The composite polyline of a schedule of all arms (in arm order): its knots, between which
/// every robot moves on a straight line of its joint space.
pub(crate) fn schedule_path(p: &MultiArmProblem, s: &Schedule) -> Vec<Vec<f64>> {
    let mut out: Vec<Vec<f64>> = Vec::with_capacity(s.knots.len());
    for knot in &s.knots {
        let c: Vec<f64> = p
            .arms
            .iter()
            .zip(&knot.configs)
            .flat_map(|(a, q)| a.vars.iter().map(|&v| q[v]).collect::<Vec<_>>())
            .collect();
        if out.last() != Some(&c) {
            out.push(c);
        }
    }
    out
}

/// Pairs of arms whose paths alone have no schedule between the two of them (in conflict).
pub(crate) fn conflicts(
    p: &MultiArmProblem,
    paths: &[Vec<Vec<f64>>],
    settings: &PhaseSpaceSettings,
    term: &mut Termination,
    seed: u64,
) -> Vec<(usize, usize)> {
    let n = p.arms.len();
    let mut out = Vec::new();
    for a in 0..n {
        for b in a + 1..n {
            if term.should_stop() {
                return out;
            }
            if schedule(p, paths, &[a, b], settings, term, seed).is_err() {
                out.push((a, b));
            }
        }
    }
    out
}
