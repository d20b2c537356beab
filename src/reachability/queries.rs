//! Ready-made IK queries on scene objects: the scene's grasp set of an end effector, the grasped
//! object attached to the hand for collision checking, the randomized single-arm IK (000 §II-D)
//! and the dual-arm IK (000 §III) wired to fast collision checkers and reachability grids.

use std::sync::Arc;

use nalgebra::Vector3;
use rand::Rng;
use thiserror::Error;

use super::grid::ReachabilityGrid;
use super::validity::{hand_links, GraspCheckers, ObjectPlacement};
use crate::collision::CollisionWorld;
use crate::geometry::Pose;
use crate::kinematics::dual_arm::{DualArmIk, DualArmQuery, DualArmSolution};
use crate::kinematics::randomized::{
    ArmChain, GraspQuery, IkSolution, RandomizedIk, RandomizedIkError, RandomizedIkSettings,
    ReachabilityMap,
};
use crate::kinematics::Chain;
use crate::model::{Robot, Scene};

/// Why a query cannot be set up.
#[derive(Debug, Error)]
pub enum QueryError {
    #[error("scene '{scene}' has no robot '{robot}'")]
    NoRobot { scene: String, robot: String },
    #[error("scene '{scene}' has no object '{object}'")]
    NoObject { scene: String, object: String },
    #[error("robot '{robot}' has no end effector at link '{link}' (tip of chain '{group}')")]
    NoEndEffector {
        robot: String,
        group: String,
        link: String,
    },
    #[error("object '{object}' has no grasps for end effector '{end_effector}'")]
    NoGrasps {
        object: String,
        end_effector: String,
    },
    #[error("reachability grid of {grid_base}→{grid_tip} does not fit the arm {arm_base}→{arm_tip} of chain '{group}'")]
    GridMismatch {
        group: String,
        grid_base: String,
        grid_tip: String,
        arm_base: String,
        arm_tip: String,
    },
    #[error(transparent)]
    Ik(#[from] RandomizedIkError),
}

/// The grasps of one end effector on one object.
#[derive(Debug, Clone)]
pub struct GraspSet {
    pub object: String,
    pub end_effector: String,
    /// Index of each grasp in the object's grasp list.
    pub indices: Vec<usize>,
    /// Names of the grasps.
    pub names: Vec<String>,
    /// TCP poses in the object frame.
    pub tcps: Vec<Pose>,
    /// Translation of each grasp's pre-grasp TCP pose in its TCP frame (the scene's
    /// `pregrasp_offset`): where the hand approaches the grasp from.
    pub pregrasp_offsets: Vec<Vector3<f64>>,
}

/// The grasps of `object` for end effector `end_effector`.
pub fn grasp_set(scene: &Scene, object: &str, end_effector: &str) -> Result<GraspSet, QueryError> {
    let o = scene.object(object).ok_or_else(|| QueryError::NoObject {
        scene: scene.name.clone(),
        object: object.to_string(),
    })?;
    let mut gs = GraspSet {
        object: object.to_string(),
        end_effector: end_effector.to_string(),
        indices: Vec::new(),
        names: Vec::new(),
        tcps: Vec::new(),
        pregrasp_offsets: Vec::new(),
    };
    for (i, g) in o.grasps.iter().enumerate() {
        if g.end_effector == end_effector {
            gs.indices.push(i);
            gs.names.push(g.name.clone());
            gs.tcps.push(g.tcp);
            gs.pregrasp_offsets.push(g.pregrasp_offset);
        }
    }
    if gs.tcps.is_empty() {
        return Err(QueryError::NoGrasps {
            object: object.to_string(),
            end_effector: end_effector.to_string(),
        });
    }
    Ok(gs)
}

/// The end effector whose parent link is `link`.
pub fn end_effector_at(robot: &Robot, link: usize, group: &str) -> Result<String, QueryError> {
    robot
        .end_effectors
        .iter()
        .find(|e| e.parent_link == link)
        .map(|e| e.name.clone())
        .ok_or_else(|| QueryError::NoEndEffector {
            robot: robot.name.clone(),
            group: group.to_string(),
            link: robot.links[link].name.clone(),
        })
}

fn check_grid(
    robot: &Robot,
    ik_group: &str,
    arm_base: usize,
    tip: usize,
    g: &ReachabilityGrid,
) -> Result<(), QueryError> {
    if g.robot() != robot.name
        || g.base_link() != robot.links[arm_base].name
        || g.tip_link() != robot.links[tip].name
    {
        return Err(QueryError::GridMismatch {
            group: ik_group.to_string(),
            grid_base: g.base_link().to_string(),
            grid_tip: g.tip_link().to_string(),
            arm_base: robot.links[arm_base].name.clone(),
            arm_tip: robot.links[tip].name.clone(),
        });
    }
    Ok(())
}

/// The SRDF chain group running exactly from an arm's base to its tip: the chain of that arm's
/// reachability grid (e.g. `right_arm` for ARMAR's `torso_right_arm`). `None` when the robot
/// defines no such group.
pub fn arm_grid_group(robot: &Robot, arm: &ArmChain) -> Option<String> {
    robot
        .groups
        .iter()
        .find(|g| {
            Chain::from_group(robot, &g.name)
                .is_some_and(|c| c.base_link == arm.arm_base && c.tip_link == arm.chain.tip_link)
        })
        .map(|g| g.name.clone())
}

/// A single-arm grasp problem: robot of a scene, chain, object and its grasp set, with one fast
/// checker per grasp (object attached to the hand).
#[derive(Debug, Clone)]
pub struct SingleArmProblem {
    pub ik: RandomizedIk,
    pub grasps: GraspSet,
    pub checkers: GraspCheckers,
    /// World pose of the robot's root.
    pub robot_base: Pose,
    /// The robot's configuration outside the chain.
    pub start: Vec<f64>,
    /// The object's pose in the scene.
    pub object_pose: Pose,
    grid: Option<Arc<ReachabilityGrid>>,
}

impl SingleArmProblem {
    /// Sets up chain group `group` of the scene's robot `robot` (instance name) for grasping
    /// `object` with the end effector at the chain's tip.
    pub fn new(
        scene: &Scene,
        robot: &str,
        group: &str,
        object: &str,
    ) -> Result<SingleArmProblem, QueryError> {
        let ri = scene
            .robots
            .iter()
            .position(|r| r.name == robot)
            .ok_or_else(|| QueryError::NoRobot {
                scene: scene.name.clone(),
                robot: robot.to_string(),
            })?;
        let placement = &scene.robots[ri];
        let ik = RandomizedIk::new(placement.robot.clone(), group)?;
        let model = &placement.robot;
        let tip = ik.split().chain.tip_link;
        let ee = end_effector_at(model, tip, group)?;
        let grasps = grasp_set(scene, object, &ee)?;
        let world = CollisionWorld::from_scene(scene);
        let touch = hand_links(model, &ee).unwrap_or_else(|| vec![tip]);
        let wq = CollisionWorld::start_config(scene);
        let checkers = GraspCheckers::new(&world, ri, object, tip, &touch, &grasps.tcps, &wq)
            .ok_or_else(|| QueryError::NoObject {
                scene: scene.name.clone(),
                object: object.to_string(),
            })?;
        let object_pose = scene
            .object(object)
            .map(|o| o.body.pose)
            .unwrap_or_else(Pose::identity);
        Ok(SingleArmProblem {
            ik,
            grasps,
            checkers,
            robot_base: placement.base_pose,
            start: placement.start_config(),
            object_pose,
            grid: None,
        })
    }

    /// Uses a reachability grid of the arm chain (refused if it is of another chain).
    pub fn set_grid(&mut self, grid: Option<Arc<ReachabilityGrid>>) -> Result<(), QueryError> {
        if let Some(g) = &grid {
            let s = self.ik.split();
            check_grid(self.ik.robot(), &s.group, s.arm_base, s.chain.tip_link, g)?;
        }
        self.grid = grid;
        Ok(())
    }

    pub fn grid(&self) -> Option<&Arc<ReachabilityGrid>> {
        self.grid.as_ref()
    }

    /// Randomized IK (000 §II-D) for the object at `object_pose`; the answer's `grasp` indexes
    /// [`SingleArmProblem::grasps`].
    pub fn solve<R: Rng + ?Sized>(
        &mut self,
        object_pose: &Pose,
        use_grid: bool,
        settings: &RandomizedIkSettings,
        rng: &mut R,
    ) -> Result<IkSolution, RandomizedIkError> {
        let query = GraspQuery {
            robot_base: self.robot_base,
            object_pose: *object_pose,
            grasps: &self.grasps.tcps,
            start: &self.start,
        };
        let reach: Option<&dyn ReachabilityMap> = if use_grid {
            self.grid.as_deref().map(|g| g as &dyn ReachabilityMap)
        } else {
            None
        };
        let checkers = &mut self.checkers;
        self.ik
            .solve(&query, reach, settings, rng, |g, q| checkers.is_free(g, q))
    }
}

/// A dual-arm problem on a scene object: left and right grasp sets, the object attached to the
/// left hand (both hands may touch it), placement checks of the free object.
#[derive(Debug, Clone)]
pub struct DualArmProblem {
    pub ik: DualArmIk,
    pub left_grasps: GraspSet,
    pub right_grasps: GraspSet,
    /// One checker per left grasp: the object attached to the left TCP.
    pub checkers: GraspCheckers,
    pub placement: ObjectPlacement,
    pub robot_base: Pose,
    pub start: Vec<f64>,
    grids: Option<(Arc<ReachabilityGrid>, Arc<ReachabilityGrid>)>,
}

impl DualArmProblem {
    /// Sets up chain groups `left_group` / `right_group` of robot instance `robot` with `object`.
    pub fn new(
        scene: &Scene,
        robot: &str,
        left_group: &str,
        right_group: &str,
        object: &str,
    ) -> Result<DualArmProblem, QueryError> {
        let ri = scene
            .robots
            .iter()
            .position(|r| r.name == robot)
            .ok_or_else(|| QueryError::NoRobot {
                scene: scene.name.clone(),
                robot: robot.to_string(),
            })?;
        let placement = &scene.robots[ri];
        let model = &placement.robot;
        let ik = DualArmIk::new(model.clone(), left_group, right_group)?;
        let (lt, rt) = (ik.left().chain.tip_link, ik.right().chain.tip_link);
        let lee = end_effector_at(model, lt, left_group)?;
        let ree = end_effector_at(model, rt, right_group)?;
        let left_grasps = grasp_set(scene, object, &lee)?;
        let right_grasps = grasp_set(scene, object, &ree)?;
        let world = CollisionWorld::from_scene(scene);
        let mut touch = hand_links(model, &lee).unwrap_or_else(|| vec![lt]);
        touch.extend(hand_links(model, &ree).unwrap_or_else(|| vec![rt]));
        let wq = CollisionWorld::start_config(scene);
        let no_obj = || QueryError::NoObject {
            scene: scene.name.clone(),
            object: object.to_string(),
        };
        let checkers = GraspCheckers::new(&world, ri, object, lt, &touch, &left_grasps.tcps, &wq)
            .ok_or_else(no_obj)?;
        let placement_check = ObjectPlacement::new(&world, object).ok_or_else(no_obj)?;
        Ok(DualArmProblem {
            ik,
            left_grasps,
            right_grasps,
            checkers,
            placement: placement_check,
            robot_base: placement.base_pose,
            start: placement.start_config(),
            grids: None,
        })
    }

    /// Uses reachability grids of the left and right arm chains.
    pub fn set_grids(
        &mut self,
        grids: Option<(Arc<ReachabilityGrid>, Arc<ReachabilityGrid>)>,
    ) -> Result<(), QueryError> {
        if let Some((l, r)) = &grids {
            let (la, ra) = (self.ik.left(), self.ik.right());
            let model = self.model();
            check_grid(&model, &la.group, la.arm_base, la.chain.tip_link, l)?;
            check_grid(&model, &ra.group, ra.arm_base, ra.chain.tip_link, r)?;
        }
        self.grids = grids;
        Ok(())
    }

    fn model(&self) -> Arc<Robot> {
        self.ik.robot().clone()
    }

    /// World pose of the left TCP's object for a solution: `left_tcp · grasp⁻¹`.
    pub fn object_pose_of(&self, sol: &DualArmSolution) -> Pose {
        sol.object_pose
    }

    /// Dual-arm IK. `held`: variant (b) with the object already in the left hand by that left
    /// grasp; `None`: variant (a), flexible grasp selection. `region`: box (world) for the
    /// object position.
    pub fn solve<R: Rng + ?Sized>(
        &mut self,
        region: ([f64; 3], [f64; 3]),
        held: Option<usize>,
        use_grids: bool,
        settings: &RandomizedIkSettings,
        rng: &mut R,
    ) -> Result<DualArmSolution, RandomizedIkError> {
        let query = DualArmQuery {
            robot_base: self.robot_base,
            region,
            left_grasps: &self.left_grasps.tcps,
            right_grasps: &self.right_grasps.tcps,
            start: &self.start,
        };
        let reach: Option<(&dyn ReachabilityMap, &dyn ReachabilityMap)> =
            match (&self.grids, use_grids) {
                (Some((l, r)), true) => {
                    Some((&**l as &dyn ReachabilityMap, &**r as &dyn ReachabilityMap))
                }
                _ => None,
            };
        let checkers = &mut self.checkers;
        let placement = &mut self.placement;
        let valid = |gl: usize, _gr: usize, q: &[f64]| checkers.is_free(gl, q);
        match held {
            Some(h) => self.ik.solve_held(
                &query,
                h,
                reach,
                settings,
                rng,
                |p| placement.is_free(p),
                valid,
            ),
            None => self.ik.solve(
                &query,
                reach,
                settings,
                rng,
                |p| placement.is_free(p),
                valid,
            ),
        }
    }
}
