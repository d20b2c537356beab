//! [`DualArmJPlusRrt`] (000 §V-A, Alg. 4–5): the hand-off planner over the shared J+ machinery
//! of [`super`].

use super::*;

/// Dual-arm J+-RRT (000 §V-A, Alg. 4–5): re-grasping an object held by the giver hand with the
/// receiver hand (see the module documentation). Reusable.
pub struct DualArmJPlusRrt<C: SegmentChecker = FastChecker> {
    core: Core<C>,
    giver: HandKin,
    receiver: HandKin,
    /// The giver's grasp (giver TCP in the object frame) and its inverse.
    held: Pose,
    held_inv: Pose,
    /// The receiver's grasps (receiver TCP in the object frame); `goal_index` indexes them.
    grasps: Vec<Pose>,
    /// The pre-grasp pose of each receiver grasp (object frame; the grasp itself when it has
    /// no pre-grasp offset).
    pregrasps: Vec<Pose>,
}

impl DualArmJPlusRrt<FastChecker> {
    /// A planner for `space` of `world` (the object attached to the giver), validating with a
    /// [`FastChecker`]. `held` is the giver's grasp, `grasps` the receiver's (object frame).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        space: JointSpace,
        world: &CollisionWorld,
        giver: &Hand,
        receiver: &Hand,
        held: Pose,
        grasps: Vec<Pose>,
        settings: JPlusRrtSettings,
    ) -> Result<Self, PlanError> {
        let checker = space_checker(world, &space);
        DualArmJPlusRrt::with_checker(
            space, world, checker, giver, receiver, held, grasps, settings,
        )
    }

    /// The planner of a [`HandOffProblem`] (`goal_index` is the receiver's grasp index).
    pub fn for_problem(h: &HandOffProblem, settings: JPlusRrtSettings) -> Result<Self, PlanError> {
        DualArmJPlusRrt::new(
            h.space.clone(),
            &h.world,
            &h.giver,
            &h.receiver,
            h.held,
            h.grasps.clone(),
            settings,
        )?
        .with_pregrasp_offsets(&h.pregrasp_offsets)
    }
}

impl<C: SegmentChecker> DualArmJPlusRrt<C> {
    /// A planner validating with `checker` (built for `world`).
    #[allow(clippy::too_many_arguments)]
    pub fn with_checker(
        space: JointSpace,
        world: &CollisionWorld,
        checker: C,
        giver: &Hand,
        receiver: &Hand,
        held: Pose,
        grasps: Vec<Pose>,
        settings: JPlusRrtSettings,
    ) -> Result<Self, PlanError> {
        let finite = |p: &Pose| {
            p.translation.vector.iter().all(|v| v.is_finite())
                && p.rotation.coords.iter().all(|v| v.is_finite())
        };
        if !finite(&held) || !grasps.iter().all(finite) {
            return Err(PlanError::InvalidInput(
                "held grasp and grasps must be finite".into(),
            ));
        }
        // Each arm's step moves only the variables that do not move the other hand.
        let root_vars = |h: &Hand| -> Result<Vec<usize>, PlanError> {
            let k = HandKin::new(world, h, &space, &[])?;
            Ok(k.chain.vars.iter().map(|v| v + k.offset).collect())
        };
        let (gv, rv) = (root_vars(giver)?, root_vars(receiver)?);
        let g = HandKin::new(world, giver, &space, &rv)?;
        let r = HandKin::new(world, receiver, &space, &gv)?;
        Ok(DualArmJPlusRrt {
            core: Core::new(space, world, checker, settings)?,
            giver: g,
            receiver: r,
            held,
            held_inv: held.inverse(),
            pregrasps: grasps.clone(),
            grasps,
        })
    }

    /// Sets the pre-grasp pose of each receiver grasp: `grasp · Translation(offset)`, `offset`
    /// in the receiver's TCP frame (a scene grasp's `pregrasp_offset`). Goal extensions then
    /// bring the hands to the pre-grasp relation first (module docs); a zero offset approaches
    /// the grasp straight.
    pub fn with_pregrasp_offsets(mut self, offsets: &[Vector3<f64>]) -> Result<Self, PlanError> {
        self.pregrasps = pregrasp_poses(&self.grasps, offsets)?;
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

    /// Plans from `start` until the receiver reaches one of its grasps on the held object (000
    /// Alg. 1 with Alg. 4 as the goal extension). The last state of the path puts the receiver's
    /// TCP exactly at `grasps[goal_index]` on the object. Randomness from `seed`; ends cleanly
    /// when `term` fires.
    pub fn plan(
        &mut self,
        start: &[f64],
        term: &mut Termination,
        seed: u64,
    ) -> Result<PlanResult, PlanError> {
        let counters = self.core.counters();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut stats = PlanStats::default();
        let (gk, rk, held) = (&self.giver, &self.receiver, self.held);
        self.core.start(start, self.grasps.len(), |wq| {
            held * gk.tcp(wq).inverse() * rk.tcp(wq)
        })?;
        let p = self.core.settings.p_extend_to_goal;
        loop {
            // An iteration costs Jacobian steps and certified motion checks (tens of µs and
            // more), so the clock is read every iteration: the time limit holds within one.
            if term.should_stop() || term.should_stop_now() {
                return Err(self.core.stopped(stats, counters, term));
            }
            stats.iterations += 1;
            let (gk, rk) = (&self.giver, &self.receiver);
            let pose = |wq: &[f64]| held * gk.tcp(wq).inverse() * rk.tcp(wq);
            self.core.restart_if_grown(start, pose, &mut stats);
            self.core.extend_randomly(&mut rng, pose);
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

    /// `DualArmExtendToGoal` (000 Alg. 4), through the grasp's pre-grasp relation (module
    /// docs); returns the outcome and the grasp drawn.
    fn extend_to_goal(
        &mut self,
        rng: &mut ChaCha8Rng,
        term: &mut Termination,
        stats: &mut PlanStats,
    ) -> (GoalExt, usize) {
        let DualArmJPlusRrt {
            core,
            giver,
            receiver,
            held,
            held_inv,
            grasps,
            pregrasps,
        } = self;
        let (held, held_inv) = (*held, *held_inv);
        let s = core.settings;
        let w = s.angle_weight;
        let g = rng.random_range(0..grasps.len());
        let Some(near) = core.goal_start(rng, &grasps[g], g) else {
            return (GoalExt::Failed, g);
        };
        let first_new = core.nodes.len();
        let mut cur = near;
        core.q_cur.copy_from_slice(core.nodes.tree.state(near));
        core.load_cur();
        let (mut gt, mut rt) = (giver.tcp(&core.wq), receiver.tcp(&core.wq));
        let mut steps = 0;
        // The receiver's TCP in the object frame to reach: the pre-grasp first, unless it is
        // the grasp itself.
        let mut grasp = pregrasps[g];
        let mut grasp_inv = grasp.inverse();
        'ext: loop {
            if term.should_stop_now() {
                return (GoalExt::Stopped, g);
            }
            // The receiver's target: its (pre-)grasp on the object where the giver holds it.
            let target = gt * held_inv * grasp;
            let (ep, ea) = pose_error(&rt, &target);
            if ep <= s.goal_position && ea <= s.goal_angle {
                if grasp != grasps[g] {
                    // Pre-grasp relation reached: now the grasp.
                    grasp = grasps[g];
                    grasp_inv = grasp.inverse();
                    continue;
                }
                // HandOffPoseReached (Alg. 4 line 10).
                if core.converge(receiver, &target, stats) {
                    core.load_new();
                    let p = held * giver.tcp(&core.wq).inverse() * receiver.tcp(&core.wq);
                    let i = core.nodes.add(&core.q_new, cur, p);
                    return (GoalExt::Reached(i), g);
                }
                break 'ext;
            }
            if steps >= s.max_goal_steps {
                break 'ext;
            }
            steps += 1;
            // Alg. 4 lines 4 and 7: one limited J+ step of each arm toward the other (Alg. 5).
            for receiver_moves in [true, false] {
                let (kin, from, to) = if receiver_moves {
                    (&mut *receiver, rt, gt * held_inv * grasp)
                } else {
                    (&mut *giver, gt, rt * grasp_inv * held)
                };
                let (lin, ang) = limited_twist(&from, &to, s.max_step_position, s.max_step_angle);
                if lin.norm() < 1e-12 && ang.norm() < 1e-12 {
                    continue;
                }
                core.load_cur();
                stats.jacobian_steps += 1;
                if !core.j_plus_step(kin, &lin, &ang) {
                    break 'ext;
                }
                core.load_new();
                if receiver_moves {
                    rt = receiver.tcp(&core.wq);
                } else {
                    gt = giver.tcp(&core.wq);
                }
                let p = held * gt.inverse() * rt;
                cur = core.nodes.add(&core.q_new, cur, p);
                std::mem::swap(&mut core.q_cur, &mut core.q_new);
            }
            let (np, na) = pose_error(&rt, &(gt * held_inv * grasp));
            if np.hypot(w * na) >= ep.hypot(w * ea) {
                break 'ext; // no progress
            }
        }
        core.exclude_failed(near, first_new, g);
        (GoalExt::Failed, g)
    }
}
