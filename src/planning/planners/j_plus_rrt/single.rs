//! [`JPlusRrt`] (000 §IV-B, Alg. 1–2): the single-hand planner over the shared J+ machinery of
//! [`super`].

use super::*;

/// J+-RRT (000 §IV-B, Alg. 1–2): one hand reaches one of a set of TCP target poses (see the
/// module documentation). Reusable: tree and buffers are kept between queries.
pub struct JPlusRrt<C: SegmentChecker = FastChecker> {
    core: Core<C>,
    hand: HandKin,
    /// World TCP targets; `PlanResult::goal_index` indexes them.
    targets: Vec<Pose>,
    /// The pre-grasp pose of each target (the target itself when it has no pre-grasp offset).
    pregrasps: Vec<Pose>,
}

impl JPlusRrt<FastChecker> {
    /// A planner for `hand` moving in `space` (of `world`) to any of `targets` (world TCP poses),
    /// validating with a [`FastChecker`].
    pub fn new(
        space: JointSpace,
        world: &CollisionWorld,
        hand: &Hand,
        targets: Vec<Pose>,
        settings: JPlusRrtSettings,
    ) -> Result<Self, PlanError> {
        let checker = space_checker(world, &space);
        JPlusRrt::with_checker(space, world, checker, hand, targets, settings)
    }

    /// The planner of a [`ReachProblem`]: its space, world, hand, grasp targets (so
    /// `goal_index` is the grasp index) and their pre-grasp offsets.
    pub fn for_problem(p: &ReachProblem, settings: JPlusRrtSettings) -> Result<Self, PlanError> {
        JPlusRrt::new(p.space.clone(), &p.world, &p.hand, p.targets(), settings)?
            .with_pregrasp_offsets(&p.pregrasp_offsets)
    }
}

impl<C: SegmentChecker> JPlusRrt<C> {
    /// A planner validating with `checker` (built for `world`).
    pub fn with_checker(
        space: JointSpace,
        world: &CollisionWorld,
        checker: C,
        hand: &Hand,
        targets: Vec<Pose>,
        settings: JPlusRrtSettings,
    ) -> Result<Self, PlanError> {
        let finite = |p: &Pose| {
            p.translation.vector.iter().all(|v| v.is_finite())
                && p.rotation.coords.iter().all(|v| v.is_finite())
        };
        if !targets.iter().all(finite) {
            return Err(PlanError::InvalidInput("targets must be finite".into()));
        }
        let hand = HandKin::new(world, hand, &space, &[])?;
        Ok(JPlusRrt {
            core: Core::new(space, world, checker, settings)?,
            hand,
            pregrasps: targets.clone(),
            targets,
        })
    }

    /// Sets the pre-grasp pose of each target: `target · Translation(offset)`, `offset` in the
    /// TCP frame (a scene grasp's `pregrasp_offset`). Goal extensions then approach a target
    /// through its pre-grasp pose (module docs); a zero offset approaches it straight.
    pub fn with_pregrasp_offsets(mut self, offsets: &[Vector3<f64>]) -> Result<Self, PlanError> {
        self.pregrasps = pregrasp_poses(&self.targets, offsets)?;
        Ok(self)
    }

    pub fn space(&self) -> &JointSpace {
        self.core.validator.space()
    }

    pub fn settings(&self) -> &JPlusRrtSettings {
        &self.core.settings
    }

    pub fn validator(&mut self) -> &mut SpaceValidator<C> {
        &mut self.core.validator
    }

    /// Plans from `start` until the TCP reaches one of the targets (000 Alg. 1). The last state
    /// of the path reaches `targets[goal_index]` exactly (module docs). All randomness comes from
    /// `seed`; the search ends with [`PlanError::Timeout`] (or the matching error) when `term`
    /// fires, also in the middle of a goal extension.
    pub fn plan(
        &mut self,
        start: &[f64],
        term: &mut Termination,
        seed: u64,
    ) -> Result<PlanResult, PlanError> {
        let counters = self.core.counters();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut stats = PlanStats::default();
        let hand = &self.hand;
        self.core
            .start(start, self.targets.len(), |wq| hand.tcp(wq))?;
        let p = self.core.settings.p_extend_to_goal;
        loop {
            // An iteration costs Jacobian steps and certified motion checks (tens of µs and
            // more), so the clock is read every iteration: the time limit holds within one.
            if term.should_stop() || term.should_stop_now() {
                return Err(self.core.stopped(stats, counters, term));
            }
            stats.iterations += 1;
            let hand = &self.hand;
            self.core
                .restart_if_grown(start, |wq| hand.tcp(wq), &mut stats);
            self.core.extend_randomly(&mut rng, |wq| hand.tcp(wq));
            if rng.random::<f64>() < p {
                match self.extend_to_goal(&mut rng, term, &mut stats) {
                    (GoalExt::Reached(node), g) => {
                        return self.core.solution(node, g, stats, counters, &mut rng, term)
                    }
                    (GoalExt::Stopped, _) => {
                        return Err(self.core.stopped(stats, counters, term));
                    }
                    (GoalExt::Failed, _) => {}
                }
            }
        }
    }

    /// `ExtendToGoal` (000 Alg. 2), through the grasp's pre-grasp pose (module docs); returns
    /// the outcome and the grasp drawn.
    fn extend_to_goal(
        &mut self,
        rng: &mut ChaCha8Rng,
        term: &mut Termination,
        stats: &mut PlanStats,
    ) -> (GoalExt, usize) {
        let JPlusRrt {
            core,
            hand,
            targets,
            pregrasps,
        } = self;
        let s = core.settings;
        let g = rng.random_range(0..targets.len());
        let grasp = targets[g];
        let Some(near) = core.goal_start(rng, &grasp, g) else {
            return (GoalExt::Failed, g);
        };
        let first_new = core.nodes.len();
        let mut cur = near;
        core.q_cur.copy_from_slice(core.nodes.tree.state(near));
        let mut pose = core.nodes.poses[near as usize];
        let mut steps = 0;
        // The pre-grasp pose first, unless it is the grasp itself.
        let mut target = pregrasps[g];
        loop {
            if term.should_stop_now() {
                return (GoalExt::Stopped, g);
            }
            let (ep, ea) = pose_error(&pose, &target);
            if ep <= s.goal_position && ea <= s.goal_angle {
                if target != grasp {
                    // Pre-grasp pose reached: now the grasp.
                    target = grasp;
                    continue;
                }
                if core.converge(hand, &target, stats) {
                    core.load_new();
                    let p = hand.tcp(&core.wq);
                    let i = core.nodes.add(&core.q_new, cur, p);
                    return (GoalExt::Reached(i), g);
                }
                break;
            }
            if steps >= s.max_goal_steps {
                break;
            }
            steps += 1;
            core.load_cur();
            let (lin, ang) = limited_twist(&pose, &target, s.max_step_position, s.max_step_angle);
            stats.jacobian_steps += 1;
            if !core.j_plus_step(hand, &lin, &ang) {
                break;
            }
            core.load_new();
            let next = hand.tcp(&core.wq);
            let (np, na) = pose_error(&next, &target);
            let w = s.angle_weight;
            if np.hypot(w * na) >= ep.hypot(w * ea) {
                break; // no progress
            }
            cur = core.nodes.add(&core.q_new, cur, next);
            std::mem::swap(&mut core.q_cur, &mut core.q_new);
            pose = next;
        }
        core.exclude_failed(near, first_new, g);
        (GoalExt::Failed, g)
    }
}
