//! The multi-arm problem: a world (scene, robots, what they hold), every robot's start, and per
//! planned arm its robot, the group variables it moves and its goal — a configuration, or a TCP
//! pose resolved here with the existing numeric IK ([`crate::kinematics::NumericIk`],
//! damped least squares from random restarts) to a configuration that is free in the scene.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::collision::{CollisionChecker, CollisionWorld, FastChecker};
use crate::geometry::Pose;
use crate::kinematics::{link_pose, Chain, NumericIk};
use crate::planning::PlanError;

/// Most arms of one problem.
pub const MAX_ARMS: usize = 8;

/// Most planned variables over all arms.
pub const MAX_VARIABLES: usize = 64;

/// One planned arm: a robot of the world and the variables (robot-local indices, a group's)
/// that move; its other variables stay at their start values.
#[derive(Debug, Clone, PartialEq)]
pub struct Arm {
    /// Index of the robot in the world.
    pub robot: usize,
    /// Robot-local variable indices that move (no repeats).
    pub vars: Vec<usize>,
    /// Goal values of `vars`.
    pub goal: Vec<f64>,
}

/// N independent arms in one cell (module documentation).
#[derive(Debug, Clone)]
pub struct MultiArmProblem {
    /// The whole world: fixed bodies, every robot, attached (held) objects.
    pub world: CollisionWorld,
    /// Every robot's start (world configuration); robots without an arm stay here.
    pub world_q: Vec<f64>,
    pub arms: Vec<Arm>,
}

fn invalid(m: impl Into<String>) -> PlanError {
    PlanError::InvalidInput(m.into())
}

impl MultiArmProblem {
    /// Checks the problem: 1..=[`MAX_ARMS`] arms on distinct robots, valid variables, goals
    /// within the joint limits, at most [`MAX_VARIABLES`] variables. Collisions are checked by
    /// the planner (a colliding start or goal is its clear error).
    pub fn new(
        world: CollisionWorld,
        world_q: Vec<f64>,
        arms: Vec<Arm>,
    ) -> Result<MultiArmProblem, PlanError> {
        if world_q.len() != world.dof() || world_q.iter().any(|x| !x.is_finite()) {
            return Err(invalid(format!(
                "start: {} finite values needed, the world has {} variables",
                world.dof(),
                world.dof()
            )));
        }
        if arms.is_empty() || arms.len() > MAX_ARMS {
            return Err(invalid(format!(
                "arms: 1 to {MAX_ARMS} arms, got {}",
                arms.len()
            )));
        }
        let mut total = 0;
        for (k, a) in arms.iter().enumerate() {
            let p = world
                .robots
                .get(a.robot)
                .ok_or_else(|| invalid(format!("arms[{k}]: no robot {}", a.robot)))?;
            if arms[..k].iter().any(|b| b.robot == a.robot) {
                return Err(invalid(format!(
                    "arms[{k}]: robot '{}' has two arms (one arm per robot)",
                    p.name
                )));
            }
            if a.vars.is_empty() {
                return Err(invalid(format!("arms[{k}] ({}): no variables", p.name)));
            }
            for (i, &v) in a.vars.iter().enumerate() {
                if v >= p.robot.dof() || a.vars[..i].contains(&v) {
                    return Err(invalid(format!(
                        "arms[{k}] ({}): variable {v} unknown or repeated",
                        p.name
                    )));
                }
            }
            if a.goal.len() != a.vars.len() {
                return Err(invalid(format!(
                    "arms[{k}] ({}): goal has {} values for {} variables",
                    p.name,
                    a.goal.len(),
                    a.vars.len()
                )));
            }
            for (&v, &x) in a.vars.iter().zip(&a.goal) {
                let l = p.robot.var_limits(v);
                if !(x.is_finite() && l.lower.is_finite() && l.upper.is_finite())
                    || x < l.lower - 1e-9
                    || x > l.upper + 1e-9
                {
                    return Err(invalid(format!(
                        "arms[{k}] ({}): goal {} = {x} outside [{}, {}]",
                        p.name,
                        p.robot.var_name(v),
                        l.lower,
                        l.upper
                    )));
                }
            }
            total += a.vars.len();
        }
        if total > MAX_VARIABLES {
            return Err(invalid(format!(
                "arms: {total} variables, at most {MAX_VARIABLES}"
            )));
        }
        let mut arms = arms;
        for a in &mut arms {
            let p = &world.robots[a.robot];
            for (&v, x) in a.vars.iter().zip(a.goal.iter_mut()) {
                let l = p.robot.var_limits(v);
                *x = x.clamp(l.lower, l.upper);
            }
        }
        Ok(MultiArmProblem {
            world,
            world_q,
            arms,
        })
    }

    /// World variable indices of arm `k`.
    pub fn arm_world_vars(&self, k: usize) -> Vec<usize> {
        let a = &self.arms[k];
        let off = self.world.robots[a.robot].offset;
        a.vars.iter().map(|v| off + v).collect()
    }

    /// World variables of the composite space: every arm's, arm by arm.
    pub fn vars(&self) -> Vec<usize> {
        (0..self.arms.len())
            .flat_map(|k| self.arm_world_vars(k))
            .collect()
    }

    /// Where arm `k`'s values sit in a composite configuration.
    pub fn arm_range(&self, k: usize) -> std::ops::Range<usize> {
        let s: usize = self.arms[..k].iter().map(|a| a.vars.len()).sum();
        s..s + self.arms[k].vars.len()
    }

    /// The composite start (every arm's start values).
    pub fn start(&self) -> Vec<f64> {
        self.vars().iter().map(|&v| self.world_q[v]).collect()
    }

    /// The composite goal.
    pub fn goal(&self) -> Vec<f64> {
        self.arms.iter().flat_map(|a| a.goal.clone()).collect()
    }

    /// The world configuration with the arms at the composite configuration `c`.
    pub fn world_config(&self, c: &[f64]) -> Vec<f64> {
        let mut q = self.world_q.clone();
        for (&v, &x) in self.vars().iter().zip(c) {
            q[v] = x;
        }
        q
    }

    /// Arm names for reports (`robot`).
    pub fn arm_name(&self, k: usize) -> &str {
        &self.world.robots[self.arms[k].robot].name
    }
}

/// Goal values of the chain group `group` of robot `robot` that put its tip link at `target`
/// (a pose in the world frame), free in the scene with the robot alone (other robots
/// ignored, held objects included): numeric IK from the start configuration, then from random
/// restarts, `tries` solutions at most, seeded. The values are those of the chain's variables,
/// in the group's variable order (`group_vars`).
pub fn pose_goal(
    world: &CollisionWorld,
    world_q: &[f64],
    robot: usize,
    group: &str,
    target: &Pose,
    tries: usize,
    seed: u64,
) -> Result<Vec<f64>, PlanError> {
    let p = world
        .robots
        .get(robot)
        .ok_or_else(|| invalid(format!("no robot {robot}")))?;
    let model = &p.robot;
    let g = model
        .group(group)
        .ok_or_else(|| invalid(format!("robot '{}' has no group '{group}'", p.name)))?;
    let chain = Chain::from_group(model, group).ok_or_else(|| {
        invalid(format!(
            "group '{group}' of robot '{}' is not a chain: a TCP goal needs one",
            p.name
        ))
    })?;
    let start = world.robot_config(robot, world_q).to_vec();
    // Target in the chain's base-link frame: world → robot base → chain base link.
    let in_base = p.base.inverse() * target;
    let local = link_pose(model, &start, chain.base_link).inverse() * in_base;
    let alone = world
        .subset(&[robot])
        .ok_or_else(|| invalid(format!("no robot {robot}")))?;
    let mut checker = FastChecker::new(&alone);
    let mut ik = NumericIk::new(model, &chain);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut last = "no IK solution".to_string();
    for _ in 0..tries.max(1) {
        match ik.solve(&local, &start, &mut rng) {
            Ok(q) => match checker.first_contact(&q) {
                None => return Ok(g.vars.iter().map(|&v| q[v]).collect()),
                Some(c) => last = format!("IK solutions collide ({} with {})", c.a, c.b),
            },
            Err(_) => last = "no IK solution reaches the pose".into(),
        }
    }
    Err(PlanError::InvalidGoal {
        count: 1,
        reason: format!("{} {group}: {last}", p.name),
    })
}
