//! Method (c), the complete fallback: RRT-Connect (the existing planner,
//! [`crate::planning::RrtConnect`]) in the composite joint space of the arms in conflict only —
//! the pairs whose paths alone have no schedule ([`super::decoupled::conflicts`]) — with the other
//! arms standing at their start; the other arms then plan in space-time around that composite
//! motion ([`super::prioritized::plan_in_order`]). When that does not work, RRT-Connect in the
//! composite space of every arm, which is probabilistically complete (the search VAMP-MR runs
//! for its multi-arm cells).

use rand_chacha::ChaCha8Rng;

use super::prioritized::{plan_in_order, velocities};
use super::problem::MultiArmProblem;
use super::space_time::SpaceTimeSettings;
use super::timed::Timed;
use crate::planning::{JointSpace, PlanError, RrtConnect, RrtConnectSettings, Termination};

/// RRT-Connect in the composite space of `arms` (the others at their start): the timed motion
/// of those arms together, at their velocity limits.
pub(crate) fn composite_motion(
    p: &MultiArmProblem,
    arms: &[usize],
    rrt: &RrtConnectSettings,
    term: &mut Termination,
    seed: u64,
) -> Result<(Timed, u64), PlanError> {
    let vars: Vec<usize> = arms.iter().flat_map(|&k| p.arm_world_vars(k)).collect();
    let start: Vec<f64> = vars.iter().map(|&v| p.world_q[v]).collect();
    let goal: Vec<f64> = arms.iter().flat_map(|&k| p.arms[k].goal.clone()).collect();
    let space = JointSpace::new(&p.world, &vars, p.world_q.clone())?;
    let mut planner = RrtConnect::new(space, &p.world, *rrt)?;
    let r = planner.plan(&start, &[goal], term, seed)?;
    let vel = velocities(p, &vars);
    Ok((
        Timed::at_speed(vars, &r.path, &vel),
        r.stats.segments_checked,
    ))
}

/// The bounded composite search over the arms in conflict `conflicted` (a proper, non-empty
/// subset of the arms), the other arms then planned around its motion in space-time: the timed
/// motions (the composite one first), or `None` when either part fails within its budget.
#[allow(clippy::too_many_arguments)]
pub(crate) fn composite_subset(
    p: &MultiArmProblem,
    conflicted: &[usize],
    rrt: &RrtConnectSettings,
    st: &SpaceTimeSettings,
    subset_iterations: u64,
    term: &mut Termination,
    rng: &mut ChaCha8Rng,
    seed: u64,
    segments: &mut u64,
) -> Option<Vec<Timed>> {
    let n = p.arms.len();
    if conflicted.is_empty() || conflicted.len() >= n {
        return None;
    }
    // Bounded by its own iteration budget, so that the complete search keeps its time.
    let mut sub = Termination::new().with_iteration_limit(subset_iterations);
    let (m, s) = composite_motion(p, conflicted, rrt, &mut sub, seed).ok()?;
    *segments += s;
    let rest: Vec<usize> = (0..n).filter(|k| !conflicted.contains(k)).collect();
    plan_in_order(p, Some(m), &rest, st, term, rng, segments).ok()
}

/// The complete fallback: RRT-Connect in the composite space of every arm (module
/// documentation); the timed motion.
pub(crate) fn composite_all(
    p: &MultiArmProblem,
    rrt: &RrtConnectSettings,
    term: &mut Termination,
    seed: u64,
    segments: &mut u64,
) -> Result<Timed, PlanError> {
    let all: Vec<usize> = (0..p.arms.len()).collect();
    let (m, s) = composite_motion(p, &all, rrt, term, seed.wrapping_add(1))?;
    *segments += s;
    Ok(m)
}
