//! Bimanual IK-RRT (paper 002 = Vahrenkamp et al. 2010, §IV-A, Alg. 2): a bi-directional RRT over
//! the whole body of a mobile two-armed robot — platform (x, y, yaw) + hip + both arms, 20 DoF for
//! ARMAR — whose goal tree is fed by IkDualArm (002 Alg. 1, [`ik_dual_arm`](crate::reachability::inverse::ik_dual_arm)): base poses sampled
//! from the bimanual inverse reachability map R_bi = min(R_left, R_right) of the object's grasps,
//! both arms solved analytically for the grasps the sampled cell lists. With probability p_IK
//! (0.03 in the paper's evaluation, 002 §VI) or while the goal tree is empty an iteration asks
//! IkDualArm for a new goal; otherwise both trees are connected toward a random sample. The
//! search loop is [`IkRrt`] (000 Alg. 3 is the same scheme for one arm); what makes it bimanual
//! is the problem: its space, its goal sampler and the pair of grasps a goal label encodes.
//!
//! The platform's x and y are bounded to the box around the start and the map's reachable cells
//! (plus a margin), so uniform samples stay near the task instead of anywhere in the joint limits
//! (±5 m for ARMAR).

use std::sync::Arc;
use std::time::{Duration, Instant};

use rand_chacha::ChaCha8Rng;

use crate::collision::{CollisionChecker, CollisionWorld, FastChecker};
use crate::geometry::Pose;
use crate::kinematics::dual_arm::DualArmIk;
use crate::kinematics::randomized::{IkCounters, RandomizedIkError, RandomizedIkSettings};
use crate::model::{Robot, Scene};
use crate::planning::base::validity::space_checker;
use crate::planning::problems::grasping::Hand;
use crate::planning::GoalSampler;
use crate::planning::{IkRrt, IkRrtSettings, JointSpace, PlanError, PlanResult, Termination};
use crate::reachability::inverse::{
    bimanual, ik_dual_arm_filtered, inverse_map, placement_cdf, InverseMap,
};
use crate::reachability::queries::grasp_set;
use crate::reachability::ReachabilityGrid;

/// Layout of the inverse reachability maps (002 §III-A) a [`BimanualProblem`] builds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BimanualSettings {
    /// Cell size of the base-position grid (m).
    pub cell: f64,
    /// Base positions within this distance of the object (m).
    pub radius: f64,
    /// Base yaw bins.
    pub yaw_bins: usize,
    /// Reachability entries at or below this do not count.
    pub threshold: f64,
    /// Margin around the start and the reachable cells for the platform's x, y bounds (m).
    pub margin: f64,
}

impl Default for BimanualSettings {
    fn default() -> Self {
        BimanualSettings {
            cell: 0.1,
            radius: 1.5,
            yaw_bins: 16,
            threshold: 0.0,
            margin: 0.5,
        }
    }
}

/// IK-RRT settings of 002's evaluation: p_IK = 0.03.
pub fn paper_settings() -> IkRrtSettings {
    IkRrtSettings {
        p_ik: 0.03,
        ..IkRrtSettings::default()
    }
}

/// Grasping an object with both hands of a mobile robot (002 §IV-A): the space is the base group
/// (x, y, yaw — SRDF group `base`), the hip and both arms.
#[derive(Debug, Clone)]
pub struct BimanualProblem {
    pub world: CollisionWorld,
    pub space: JointSpace,
    pub left: Hand,
    pub right: Hand,
    pub object: String,
    pub object_pose: Pose,
    /// Grasps of each hand (TCP in the object frame) and their names.
    pub left_grasps: Vec<Pose>,
    pub left_names: Vec<String>,
    pub right_grasps: Vec<Pose>,
    pub right_names: Vec<String>,
    /// Start state (space coordinates).
    pub start: Vec<f64>,
    /// R_bi with the left grasps per cell, and the right grasps per cell.
    pub map: Arc<(InverseMap, Vec<Vec<u16>>)>,
    /// Time spent on the inverse maps and R_bi.
    pub map_time: Duration,
    base_vars: [usize; 3],
    ik: Arc<DualArmIk>,
    /// IkDualArm's base test: the bodies the base variables alone place, against the scene
    /// ([`base_checker`]); `None` when the robot holds an object.
    base_checker: Option<FastChecker>,
}

/// A checker of what a sampled base pose alone decides (002 Alg. 1 before the arms are
/// solved): the world with the links of robot `r` that some non-base joint moves stripped of
/// their geometry, so only the platform (every link whose movable ancestor joints are all base
/// joints) is checked against the obstacles, the resting objects and the other robots (at their
/// configuration in `world_q`, as the goal check sees them). The remaining pairs are pairs the
/// full goal check tests with the same fast model, so a base pose it rejects fails every
/// configuration with that base. `None` when an object is attached to the robot (its pose would
/// follow the arms).
pub fn base_checker(
    world: &CollisionWorld,
    world_q: &[f64],
    r: usize,
    base_vars: &[usize; 3],
) -> Option<FastChecker> {
    if world.attached.iter().any(|a| a.robot == r) {
        return None;
    }
    let placed = world.robots.get(r)?;
    let robot = &placed.robot;
    let rigid = |mut l: usize| -> bool {
        while let Some(j) = robot.links[l].parent_joint {
            let joint = &robot.joints[j];
            if joint.is_movable() && !joint.var.is_some_and(|v| base_vars.contains(&v)) {
                return false;
            }
            l = joint.parent;
        }
        true
    };
    let mut stripped = (**robot).clone();
    for l in 0..stripped.links.len() {
        if !rigid(l) {
            stripped.links[l].collision.clear();
        }
    }
    let mut w = world.clone();
    w.robots[r].robot = Arc::new(stripped);
    let active: Vec<usize> = base_vars.iter().map(|v| v + placed.offset).collect();
    Some(FastChecker::for_active(
        &w,
        Default::default(),
        &active,
        world_q,
    ))
}

fn invalid(e: impl std::fmt::Display) -> PlanError {
    PlanError::InvalidInput(e.to_string())
}

/// The base variables (x, y, yaw) of a robot: its SRDF group `base` with three variables.
pub fn base_vars(robot: &Robot) -> Result<[usize; 3], PlanError> {
    let g = robot.group("base").ok_or_else(|| {
        PlanError::InvalidInput(format!(
            "robot '{}' has no SRDF group 'base' (x, y, yaw of the platform)",
            robot.name
        ))
    })?;
    match g.vars[..] {
        [x, y, w] => Ok([x, y, w]),
        _ => Err(PlanError::InvalidInput(format!(
            "robot '{}': group 'base' has {} variables, expected 3 (x, y, yaw)",
            robot.name,
            g.vars.len()
        ))),
    }
}

impl BimanualProblem {
    /// Grasp `object` of `scene` with both hands of robot instance `robot`: `groups` are the
    /// (left, right) chain groups from the platform (e.g. `torso_left_arm`, `torso_right_arm`),
    /// `grids` their platform-frame reachability grids (see `reach build`).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        scene: &Scene,
        world: &CollisionWorld,
        world_q: &[f64],
        robot: &str,
        groups: (&str, &str),
        object: &str,
        grids: (&ReachabilityGrid, &ReachabilityGrid),
        settings: BimanualSettings,
    ) -> Result<BimanualProblem, PlanError> {
        if world_q.len() != world.dof() || world_q.iter().any(|v| !v.is_finite()) {
            return Err(PlanError::InvalidInput(format!(
                "start configuration must be {} finite values",
                world.dof()
            )));
        }
        if !(settings.cell > 0.0
            && settings.radius > 0.0
            && settings.radius / settings.cell <= 200.0
            && (1..=360).contains(&settings.yaw_bins)
            && settings.margin >= 0.0
            && settings.margin.is_finite()
            && (0.0..1.0).contains(&settings.threshold))
        {
            return Err(PlanError::InvalidInput(
                "map settings: cell > 0, radius/cell ≤ 200, 1 ≤ yaw_bins ≤ 360, margin ≥ 0, 0 ≤ threshold < 1".into(),
            ));
        }
        let left = Hand::new(world, robot, groups.0)?;
        let right = Hand::new(world, robot, groups.1)?;
        let placed = &world.robots[left.robot];
        let model = placed.robot.clone();
        grids.0.check(&model, groups.0).map_err(invalid)?;
        grids.1.check(&model, groups.1).map_err(invalid)?;
        let bv = base_vars(&model)?;
        let ik = DualArmIk::new(model.clone(), groups.0, groups.1).map_err(invalid)?;
        let lset = grasp_set(scene, object, &left.end_effector).map_err(invalid)?;
        let rset = grasp_set(scene, object, &right.end_effector).map_err(invalid)?;
        let object_pose = world
            .statics
            .iter()
            .find(|s| s.name == object)
            .map(|s| s.pose)
            .ok_or_else(|| invalid(format!("'{object}' is not a free object of the scene")))?;
        if lset.tcps.len() > u16::MAX as usize || rset.tcps.len() > u16::MAX as usize {
            return Err(invalid("too many grasps"));
        }
        let tl: Vec<Pose> = lset.tcps.iter().map(|g| object_pose * g).collect();
        let tr: Vec<Pose> = rset.tcps.iter().map(|g| object_pose * g).collect();
        let off = placed.offset;
        let robot_q = &world_q[off..off + model.dof()];
        // The maps are laid out in the base variables' (x, y), which are the world's only when
        // the robot is placed at the world origin: the object's position in the placement frame.
        let c = placed
            .base
            .inverse_transform_point(&object_pose.translation.vector.into());
        let centre = [c.x, c.y];
        let t0 = Instant::now();
        let map_of = |grid: &ReachabilityGrid, t: &[Pose]| {
            inverse_map(
                &model,
                &placed.base,
                robot_q,
                &bv,
                grid,
                t,
                centre,
                settings.cell,
                settings.radius,
                settings.yaw_bins,
                settings.threshold,
            )
            .ok_or_else(|| invalid("the grids' base link is not a link of the robot"))
        };
        let ml = map_of(grids.0, &tl)?;
        let mr = map_of(grids.1, &tr)?;
        let (bi, rights) = bimanual(&ml, &mr).ok_or_else(|| invalid("maps differ"))?;
        let map_time = t0.elapsed();

        // Space: base + hip + both arms; x, y bounded to the start and the reachable cells.
        let mut vars: Vec<usize> = bv.iter().map(|v| v + off).collect();
        for v in left
            .world_vars(world)
            .into_iter()
            .chain(right.world_vars(world))
        {
            if !vars.contains(&v) {
                vars.push(v);
            }
        }
        let space = JointSpace::new(world, &vars, world_q.to_vec())?;
        let (mut lo, mut hi) = (
            [robot_q[bv[0]], robot_q[bv[1]]],
            [robot_q[bv[0]], robot_q[bv[1]]],
        );
        let mut any = false;
        for ix in 0..bi.dims[0] {
            for iy in 0..bi.dims[1] {
                let k0 = (ix * bi.dims[1] + iy) * bi.yaw_bins;
                if bi.value[k0..k0 + bi.yaw_bins].iter().any(|&v| v > 0.0) {
                    any = true;
                    let (x, y, _) = bi.cell_pose(ix, iy, 0);
                    lo = [lo[0].min(x), lo[1].min(y)];
                    hi = [hi[0].max(x), hi[1].max(y)];
                }
            }
        }
        if !any {
            return Err(PlanError::InvalidGoal {
                count: tl.len() * tr.len(),
                reason: format!(
                    "no base position within {} m of '{object}' reaches a left and a right grasp (bimanual map empty)",
                    settings.radius
                ),
            });
        }
        let m = settings.margin + settings.cell;
        let space =
            space
                .with_bounds(0, lo[0] - m, hi[0] + m)?
                .with_bounds(1, lo[1] - m, hi[1] + m)?;
        let start = space.from_world(world_q);
        let base_checker = base_checker(world, world_q, left.robot, &bv);
        Ok(BimanualProblem {
            world: world.clone(),
            space,
            left,
            right,
            object: object.to_string(),
            object_pose,
            left_grasps: lset.tcps,
            left_names: lset.names,
            right_grasps: rset.tcps,
            right_names: rset.names,
            start,
            map: Arc::new((bi, rights)),
            map_time,
            base_vars: bv,
            ik: Arc::new(ik),
            base_checker,
        })
    }

    /// The pair (left grasp, right grasp) of a goal label.
    pub fn decode(&self, label: usize) -> (usize, usize) {
        let n = self.right_grasps.len().max(1);
        (label / n, label % n)
    }

    /// World TCP targets of a goal label.
    pub fn targets(&self, label: usize) -> (Pose, Pose) {
        let (l, r) = self.decode(label);
        (
            self.object_pose * self.left_grasps[l],
            self.object_pose * self.right_grasps[r],
        )
    }

    /// The goal sampler: IkDualArm (002 Alg. 1) with at most `settings.max_tries` base samples
    /// per query.
    pub fn goals(&self, settings: RandomizedIkSettings) -> BimanualGoals {
        let p = &self.world.robots[self.left.robot];
        let world_q = self.space.base().to_vec();
        BimanualGoals {
            ik: self.ik.clone(),
            map: self.map.clone(),
            cdf: placement_cdf(&self.map.0),
            robot_base: p.base,
            robot_q: world_q[p.offset..p.offset + p.robot.dof()].to_vec(),
            base_vars: self.base_vars,
            targets_left: self
                .left_grasps
                .iter()
                .map(|g| self.object_pose * g)
                .collect(),
            targets_right: self
                .right_grasps
                .iter()
                .map(|g| self.object_pose * g)
                .collect(),
            n_right: self.right_grasps.len(),
            offset: p.offset,
            settings,
            checker: space_checker(&self.world, &self.space),
            base_checker: self.base_checker.clone(),
            base_bounds: std::array::from_fn(|i| {
                let v = self.base_vars[i] + p.offset;
                self.space
                    .vars()
                    .iter()
                    .position(|&x| x == v)
                    .map(|k| (self.space.lower()[k], self.space.upper()[k]))
                    .unwrap_or((f64::NEG_INFINITY, f64::INFINITY))
            }),
            base_q: world_q.clone(),
            space: self.space.clone(),
            world_q,
            counters: IkCounters::default(),
        }
    }

    /// Runs Bimanual IK-RRT (002 Alg. 2) on this problem; the result's `goal_index` is a label
    /// for [`BimanualProblem::decode`].
    pub fn plan(
        &self,
        planner: IkRrtSettings,
        ik: RandomizedIkSettings,
        term: &mut Termination,
        seed: u64,
    ) -> Result<PlanResult, PlanError> {
        let mut rrt = IkRrt::new(self.space.clone(), &self.world, planner)?;
        let mut goals = self.goals(ik);
        rrt.plan(&self.start, &mut goals, term, seed)
    }
}

/// IK-RRT goals of a [`BimanualProblem`]: IkDualArm answers inside the space's bounds, checked in
/// the problem's world. Labels encode (left, right) as `left · n_right + right`.
pub struct BimanualGoals {
    ik: Arc<DualArmIk>,
    map: Arc<(InverseMap, Vec<Vec<u16>>)>,
    /// [`placement_cdf`] of R_bi, built once per sampler.
    cdf: Vec<f64>,
    robot_base: Pose,
    robot_q: Vec<f64>,
    base_vars: [usize; 3],
    targets_left: Vec<Pose>,
    targets_right: Vec<Pose>,
    n_right: usize,
    offset: usize,
    settings: RandomizedIkSettings,
    checker: FastChecker,
    /// The base test of IkDualArm ([`base_checker`]), the space's bounds of x, y, yaw and a
    /// world configuration for it.
    base_checker: Option<FastChecker>,
    base_bounds: [(f64, f64); 3],
    base_q: Vec<f64>,
    space: JointSpace,
    world_q: Vec<f64>,
    counters: IkCounters,
}

impl BimanualGoals {
    pub fn counters(&self) -> &IkCounters {
        &self.counters
    }
}

impl GoalSampler for BimanualGoals {
    fn sample_goal(&mut self, rng: &mut ChaCha8Rng, out: &mut [f64]) -> Option<usize> {
        let (bi, rights) = &*self.map;
        let (checker, world_q, offset, space) = (
            &mut self.checker,
            &mut self.world_q,
            self.offset,
            &self.space,
        );
        let (base_checker, base_q, base_bounds, base_vars) = (
            &mut self.base_checker,
            &mut self.base_q,
            &self.base_bounds,
            &self.base_vars,
        );
        let r = ik_dual_arm_filtered(
            &self.ik,
            &self.robot_base,
            &self.robot_q,
            &self.base_vars,
            bi,
            &self.cdf,
            rights,
            &self.targets_left,
            &self.targets_right,
            &self.settings,
            rng,
            // A base outside the space's bounds or whose platform collides fails every
            // configuration the goal check below would see with it.
            |q| {
                let inside = base_vars
                    .iter()
                    .zip(base_bounds)
                    .all(|(&v, &(l, u))| q[v] >= l && q[v] <= u);
                inside
                    && base_checker.as_mut().is_none_or(|c| {
                        for &v in base_vars {
                            base_q[offset + v] = q[v];
                        }
                        c.is_free(base_q)
                    })
            },
            |q| {
                world_q[offset..offset + q.len()].copy_from_slice(q);
                space
                    .vars()
                    .iter()
                    .zip(space.lower().iter().zip(space.upper()))
                    .all(|(&v, (&l, &u))| world_q[v] >= l && world_q[v] <= u)
                    && checker.is_free(world_q)
            },
        );
        match r {
            Ok(sol) => {
                self.counters.add(&sol.counters);
                self.world_q[offset..offset + sol.config.len()].copy_from_slice(&sol.config);
                for (o, &v) in out.iter_mut().zip(self.space.vars()) {
                    *o = self.world_q[v];
                }
                Some(sol.left_grasp * self.n_right + sol.right_grasp)
            }
            Err(RandomizedIkError::NoSolution { counters, .. }) => {
                self.counters.add(&counters);
                None
            }
            Err(_) => None,
        }
    }

    fn ik_calls(&self) -> u64 {
        self.counters.ik_calls
    }
}
