//! IK-RRT (Vahrenkamp et al. 2009 = paper 000, §IV-C, Algorithm 3): a bi-directional RRT whose
//! goal tree is fed while planning by an IK solver for a *set* of grasps, so no goal
//! configuration is fixed in advance and the planner stays probabilistically complete.
//!
//! The same loop serves every member of the family; only the [`GoalSampler`] differs:
//! single-arm IK-RRT (randomized 10-DoF IK, 000 §II-D), dual-arm IK-RRT for re-grasping and
//! hand-off (000 §V-B, object held by one hand), Bimanual IK-RRT (paper 002 = Vahrenkamp et al.
//! 2010, Alg. 2, goals from IkDualArm with base placement).
//!
//! Per iteration: while no goal exists, or with probability `p_ik`, one goal-sampler query is
//! made; a valid answer becomes a new root of the goal tree and the start tree then tries to
//! CONNECT to it directly (an addition to Alg. 3 that solves open scenes in one step; the
//! general case is unchanged). Otherwise one RRT-Connect iteration runs between the two trees
//! (EXTEND one toward a uniform sample, CONNECT the other to the new state; the roles swap every
//! iteration), which is Alg. 3's "RRT1.Connect(q_r) & RRT2.Connect(q_r)" in Kuffner and LaValle's
//! formulation. The result names the goal label (grasp) reached.

use std::time::Instant;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use std::sync::Arc;

use crate::collision::{CollisionWorld, FastChecker};
use crate::kinematics::randomized::RandomizedIkSettings;
use crate::planning::base::validity::{space_checker, SegmentChecker, SpaceValidator};
use crate::planning::planners::rrt_connect::{
    connect, extend, finish, join_trees, stopped, Extend,
};
use crate::planning::problems::grasping::{ArmGoals, HandOffGoals, HandOffProblem, ReachProblem};
use crate::planning::{
    GoalSampler, JointSpace, PlanError, PlanResult, PlanStats, RrtConnectSettings, Termination,
    Tree, NO_PARENT,
};
use crate::reachability::ReachabilityGrid;

/// Settings of [`IkRrt`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct IkRrtSettings {
    /// Probability of a goal-sampler query per iteration once a goal exists (000 Alg. 3 p_IK).
    pub p_ik: f64,
    /// Goal-tree roots kept at most; further IK solutions are not added (bounds memory).
    pub max_goals: usize,
    /// EXTEND range, motion resolution, shortcutting and re-validation (as RRT-Connect).
    pub rrt: RrtConnectSettings,
}

impl IkRrtSettings {
    /// Checks `p_ik` (in (0, 1]), `max_goals` (> 0) and the RRT settings that do not depend
    /// on the space ([`RrtConnectSettings::validate`]), so that a caller can refuse bad
    /// settings before any work (the planner checks them again when built).
    pub fn validate(&self) -> Result<(), PlanError> {
        if !(self.p_ik.is_finite() && self.p_ik > 0.0 && self.p_ik <= 1.0) {
            return Err(PlanError::InvalidInput(format!(
                "p_ik must be in (0, 1], got {}",
                self.p_ik
            )));
        }
        if self.max_goals == 0 {
            return Err(PlanError::InvalidInput("max_goals must be > 0".into()));
        }
        self.rrt.validate()
    }
}

impl Default for IkRrtSettings {
    fn default() -> Self {
        IkRrtSettings {
            p_ik: 0.1,
            max_goals: 256,
            rrt: RrtConnectSettings::default(),
        }
    }
}

/// The IK-RRT planner over a [`JointSpace`] (see the module documentation).
pub struct IkRrt<C: SegmentChecker = FastChecker> {
    validator: SpaceValidator<C>,
    settings: IkRrtSettings,
    range: f64,
    trees: [Tree; 2],
    /// (goal-tree root index, label) of every goal added.
    roots: Vec<(u32, usize)>,
    q_rand: Vec<f64>,
    q_new: Vec<f64>,
    q_target: Vec<f64>,
    idx: Vec<u32>,
}

impl IkRrt<FastChecker> {
    pub fn new(
        space: JointSpace,
        world: &CollisionWorld,
        settings: IkRrtSettings,
    ) -> Result<Self, PlanError> {
        let checker = space_checker(world, &space);
        IkRrt::with_checker(space, world, checker, settings)
    }
}

impl<C: SegmentChecker> IkRrt<C> {
    pub fn with_checker(
        space: JointSpace,
        world: &CollisionWorld,
        checker: C,
        settings: IkRrtSettings,
    ) -> Result<Self, PlanError> {
        settings.validate()?;
        let range = settings.rrt.checked_range(&space)?;
        let dim = space.dim();
        let weights = space.weights().to_vec();
        let (a, l) = (
            settings.rrt.angular_resolution,
            settings.rrt.linear_resolution,
        );
        Ok(IkRrt {
            validator: SpaceValidator::new(space, world, checker, a, l),
            settings,
            range,
            trees: [Tree::new(&weights), Tree::new(&weights)],
            roots: Vec::new(),
            q_rand: vec![0.0; dim],
            q_new: vec![0.0; dim],
            q_target: vec![0.0; dim],
            idx: Vec::new(),
        })
    }

    pub fn space(&self) -> &JointSpace {
        self.validator.space()
    }

    pub fn settings(&self) -> &IkRrtSettings {
        &self.settings
    }

    pub fn validator(&mut self) -> &mut SpaceValidator<C> {
        &mut self.validator
    }

    /// Plans from `start` to any goal `goals` produces; `goal_index` of the result is the label
    /// of the goal reached. All randomness (the sampler's included) comes from `seed`.
    pub fn plan(
        &mut self,
        start: &[f64],
        goals: &mut dyn GoalSampler,
        term: &mut Termination,
        seed: u64,
    ) -> Result<PlanResult, PlanError> {
        let t0 = Instant::now();
        self.validator.reset_certify_stats();
        let counters = (t0, self.validator.checks(), self.validator.segments());
        let ik0 = goals.ik_calls();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut stats = PlanStats::default();
        // A start value at most `Limits::TOLERANCE` outside the bounds is clamped into them,
        // as RRT-Connect does (the returned path starts at the clamped start).
        let start = self.validator.space().snap_to_bounds(start).into_owned();
        let start = start.as_slice();
        if let Some(why) = self.validator.invalidity(start) {
            return Err(PlanError::InvalidStart { reason: why });
        }
        let range = self.range;
        let p_ik = self.settings.p_ik;
        let max_goals = self.settings.max_goals;
        let IkRrt {
            validator,
            trees,
            roots,
            q_rand,
            q_new,
            q_target,
            idx,
            settings,
            ..
        } = self;
        let [ts, tg] = trees;
        ts.clear();
        tg.clear();
        roots.clear();
        ts.add(start, NO_PARENT);

        let mut found: Option<(u32, u32)> = None;
        let mut start_side = true;
        while found.is_none() {
            // An iteration may sample IK goals and certify motions, so the clock is read every
            // iteration (tens of ns against µs): the time limit holds within one iteration.
            if term.should_stop() || term.should_stop_now() {
                stats.start_tree_size = ts.len();
                stats.goal_tree_size = tg.len();
                stats.ik_calls = goals.ik_calls() - ik0;
                return Err(stopped(validator, stats, counters, term));
            }
            stats.iterations += 1;
            if roots.is_empty() || (roots.len() < max_goals && rng.random::<f64>() < p_ik) {
                stats.ik_queries += 1;
                let t_ik = Instant::now();
                let answer = goals.sample_goal(&mut rng, q_target);
                stats.ik_time += t_ik.elapsed();
                let Some(label) = answer else {
                    continue;
                };
                // The sampler checks its answers in its own world; the planner's validator has the
                // last word so that the path's end state is checked exactly as its segments are.
                if !validator.is_state_valid(q_target) {
                    continue;
                }
                stats.ik_solutions += 1;
                let g = tg.add(q_target, NO_PARENT);
                roots.push((g, label));
                if let Some(s) = connect(ts, validator, range, q_target, q_new) {
                    found = Some((s, g));
                }
                continue;
            }
            validator.space().sample_uniform(&mut rng, q_rand);
            let (ta, tb) = if start_side {
                (&mut *ts, &mut *tg)
            } else {
                (&mut *tg, &mut *ts)
            };
            if let Extend::Advanced(i) | Extend::Reached(i) =
                extend(ta, validator, range, q_rand, q_new)
            {
                q_target.copy_from_slice(ta.state(i));
                if let Some(j) = connect(tb, validator, range, q_target, q_new) {
                    found = Some(if start_side { (i, j) } else { (j, i) });
                }
            }
            start_side = !start_side;
        }
        let Some((s, g)) = found else {
            return Err(PlanError::InvalidInput(
                "internal: search ended without a solution".into(),
            ));
        };
        let path = join_trees(ts, s, tg, g, idx);
        let root = tg.root_of(g);
        let label = roots
            .iter()
            .find(|(r, _)| *r == root)
            .map(|&(_, l)| l)
            .unwrap_or_default();
        stats.start_tree_size = ts.len();
        stats.goal_tree_size = tg.len();
        stats.ik_calls = goals.ik_calls() - ik0;
        let (path, stats) = finish(
            validator,
            path,
            &settings.rrt,
            stats,
            counters,
            &mut rng,
            term,
        )?;
        Ok(PlanResult {
            path,
            goal_index: label,
            stats,
        })
    }
}

/// IK-RRT over `space` of `world` and the goal sampler `goals` makes from a clone of its
/// collision model (building the model is most of a query's setup).
fn ik_rrt_sharing_checker<G>(
    world: &CollisionWorld,
    space: &JointSpace,
    planner: IkRrtSettings,
    goals: impl FnOnce(FastChecker) -> G,
) -> Result<(IkRrt, G), PlanError> {
    let checker = space_checker(world, space);
    let g = goals(checker.clone());
    Ok((
        IkRrt::with_checker(space.clone(), world, checker, planner)?,
        g,
    ))
}

impl ReachProblem {
    /// The IK-RRT planner of this problem and its goal sampler, sharing one collision model:
    /// built once and cloned (building it is most of a query's setup).
    pub fn ik_rrt(
        &self,
        grid: Option<Arc<ReachabilityGrid>>,
        planner: IkRrtSettings,
        ik: RandomizedIkSettings,
    ) -> Result<(IkRrt, ArmGoals), PlanError> {
        ik_rrt_sharing_checker(&self.world, &self.space, planner, |c| {
            self.goals_with(grid, ik, c)
        })
    }
}

impl HandOffProblem {
    /// The IK-RRT planner of this problem and its goal sampler, sharing one collision model:
    /// built once and cloned (building it is most of a query's setup).
    pub fn ik_rrt(
        &self,
        grid: Option<Arc<ReachabilityGrid>>,
        planner: IkRrtSettings,
        ik: RandomizedIkSettings,
    ) -> Result<(IkRrt, HandOffGoals), PlanError> {
        ik_rrt_sharing_checker(&self.world, &self.space, planner, |c| {
            self.goals_with(grid, ik, c)
        })
    }
}
