//! Method (b), prioritized planning in space-time (Erdmann & Lozano-Pérez 1987): the arms in a
//! priority order, each planned around the timed motions of the arms before it
//! ([`super::space_time`]); the arms after it stand at their start while it plans, so that a
//! later arm can always wait there until its way is clear. When an arm finds no motion, it is
//! moved to the front of the order (to the back when it was first) and the arms are planned
//! again (at most as many orders as arms, no order twice).

use rand_chacha::ChaCha8Rng;

use super::problem::MultiArmProblem;
use super::space_time::{SpaceTime, SpaceTimeSettings};
use super::timed::Timed;
use crate::planning::Termination;
use crate::trajectory::timing::world_limits;

/// The velocity limits of world variables `vars`.
pub(crate) fn velocities(p: &MultiArmProblem, vars: &[usize]) -> Vec<f64> {
    world_limits(&p.world).select(vars).velocity
}

/// Plans the movers (groups of arms) `first` then `rest` (one arm each) in space-time, each
/// around those before it; the timed motions in that order, or the index into `rest` of the
/// arm that failed (`None`: `first` failed, or `term` fired).
pub(crate) fn plan_in_order(
    p: &MultiArmProblem,
    first: Option<Timed>,
    rest: &[usize],
    settings: &SpaceTimeSettings,
    term: &mut Termination,
    rng: &mut ChaCha8Rng,
    segments: &mut u64,
) -> Result<Vec<Timed>, Option<usize>> {
    let mut motions: Vec<Timed> = first.into_iter().collect();
    for (i, &k) in rest.iter().enumerate() {
        let vars = p.arm_world_vars(k);
        let vel = velocities(p, &vars);
        let start: Vec<f64> = vars.iter().map(|&v| p.world_q[v]).collect();
        let mut st = SpaceTime::new(&p.world, &p.world_q, &vars, &vel, &motions);
        let found = st.plan(&start, &p.arms[k].goal, settings, term, rng);
        *segments += st.segments;
        match found {
            Some(m) => motions.push(m),
            None => return Err((!term.should_stop_now()).then_some(i)),
        }
    }
    Ok(motions)
}

/// Prioritized planning from the priority order `order`, re-ordered on failure (module
/// documentation): the timed motions and the order that worked.
pub(crate) fn prioritized(
    p: &MultiArmProblem,
    order: &[usize],
    settings: &SpaceTimeSettings,
    term: &mut Termination,
    rng: &mut ChaCha8Rng,
    segments: &mut u64,
    tried: &mut Vec<Vec<usize>>,
) -> Option<(Vec<usize>, Vec<Timed>)> {
    let mut order = order.to_vec();
    for _ in 0..order.len() {
        if tried.contains(&order) {
            return None;
        }
        tried.push(order.clone());
        match plan_in_order(p, None, &order, settings, term, rng, segments) {
            Ok(m) => return Some((order, m)),
            Err(None) => return None,
            Err(Some(i)) => {
                // The arm that failed goes first; when it was first already, last.
                let k = order.remove(i);
                if i == 0 {
                    order.push(k);
                } else {
                    order.insert(0, k);
                }
            }
        }
    }
    None
}
