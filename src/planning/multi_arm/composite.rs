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

/// The composite fallback for the arms in conflict `conflicted` (module documentation): the
/// timed motions (the composite one first) and the arms in the composite search.
#[allow(clippy::too_many_arguments)]
pub(crate) fn composite(
    p: &MultiArmProblem,
    conflicted: &[usize],
    rrt: &RrtConnectSettings,
    st: &SpaceTimeSettings,
    subset_iterations: u64,
    term: &mut Termination,
    rng: &mut ChaCha8Rng,
    seed: u64,
    segments: &mut u64,
) -> Result<(Vec<Timed>, Vec<usize>), PlanError> {
    let n = p.arms.len();
    if !conflicted.is_empty() && conflicted.len() < n {
        // A bounded search over the conflicting arms, so that the complete one keeps its time.
        let mut sub = Termination::new().with_iteration_limit(subset_iterations);
        if let Ok((m, s)) = composite_motion(p, conflicted, rrt, &mut sub, seed) {
            *segments += s;
            let rest: Vec<usize> = (0..n).filter(|k| !conflicted.contains(k)).collect();
            if let Ok(all) = plan_in_order(p, Some(m), &rest, st, term, rng, segments) {
                return Ok((all, conflicted.to_vec()));
            }
        }
        if term.should_stop_now() {
            return Err(PlanError::stopped(
                term.reason()
                    .unwrap_or(crate::planning::StopReason::TimeLimit),
                Default::default(),
            ));
        }
    }
    let all: Vec<usize> = (0..n).collect();
    let (m, s) = composite_motion(p, &all, rrt, term, seed.wrapping_add(1))?;
    *segments += s;
    Ok((vec![m], all))
}
