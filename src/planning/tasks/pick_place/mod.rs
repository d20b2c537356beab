//! Pick-and-place with a two-hand exchange (paper 003, Saut et al. 2010): the problem and its
//! key configurations.
//!
//! The robot grasps the object at its initial pose q_o^i with one hand (the *pick* hand, 003's
//! Arm_1), hands it over to the other (the *place* hand, Arm_2) at an exchange pose q_o^e and
//! puts it down at its final pose q_o^f (003 §III). This module owns:
//!
//! - [`PickPlaceProblem`]: robot, fixed obstacles, object, its two poses, the rest
//!   configuration q_r^i and the two arm–hand pairs, built from a scene
//!   ([`PickPlaceProblem::from_scene`]); the arm of each hand is the SRDF end effector's parent
//!   group, the torso the variables between the robot root and the arms' common base link;
//! - [`exchange`]: the exchange position (003 §V-C, Fig. 6) on a 3-D grid derived from the two
//!   arms' reach, and the object poses sampled around it;
//! - [`configurations`]: the grasp, exchange and place configurations q_r^g, q_r^e, q_r^p (003
//!   §V-C) by sampling the torso and solving the arms' analytic S-R-S IK, every one
//!   collision-free under the exact checker with the object attached to the holding hand;
//! - [`task`]: the whole task (003 Fig. 2, §V-B): offline grasp lists and super graph, the key
//!   configurations, the four roadmap queries and one certified plan with its grasp and
//!   release events.
//!
//! Planning core: no server, no tokio.

pub mod approach;
pub mod configurations;
pub mod exchange;
pub mod fingers;
mod hands;
mod room;
pub mod task;

use std::sync::Arc;

use nalgebra::Vector3;
use thiserror::Error;

use crate::collision::{CollisionWorld, StaticBody, StaticKind};
use crate::geometry::{Geometry, Pose};
use crate::grasp::{object_centre, Hand, HandError, WorkspaceParams};
use crate::kinematics::{link_pose, SrsArm};
use crate::model::{Robot, Scene};

pub use configurations::{
    exchange_configuration, exchange_configuration_with, key_configurations,
    key_configurations_with, single_configuration, single_configuration_with, within_limits,
    AnyHand, ConfigParams, ConfigStats, HandRoom, Holder, KeyConfigurations, SingleConfiguration,
};
pub use exchange::{exchange_grid, exchange_poses, ExchangeGrid, ExchangeParams};
pub use task::{
    plan_pick_place, prepare_pick_place, task_world, ClosingCache, MotionPlanner, PickPlaceOffline,
    PickPlacePlan, PickPlaceSettings, PickPlaceTaskError, QueryRecord, RoadmapLearning,
    TaskProgress,
};

/// Why a pick-and-place problem cannot be set up or its configurations not be found.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PickPlaceError {
    #[error("scene has no robot '{0}'")]
    NoRobot(String),
    #[error("scene has no object '{0}'")]
    NoObject(String),
    #[error("object '{0}' has no goal pose (the scene's objects[].goal)")]
    NoGoal(String),
    #[error("robot '{robot}' has no end effector for hand group '{hand}' with a parent arm group")]
    NoArm { robot: String, hand: String },
    #[error("arm '{arm}': {reason}")]
    Arm { arm: String, reason: String },
    #[error("hand '{hand}': {reason}")]
    Hand { hand: String, reason: String },
    #[error("the arms '{0}' and '{1}' do not share their base link")]
    ArmBases(String, String),
    #[error("invalid {field}: {reason}")]
    Invalid { field: String, reason: String },
    #[error(
        "the object's {pose} pose is out of reach of the {hand}: {reason} \
         ({grasps} grasps tried, {torso} torso samples each, {ik} IK solutions, {checks} collision checks)"
    )]
    Unreachable {
        pose: String,
        hand: String,
        reason: String,
        grasps: usize,
        torso: usize,
        ik: usize,
        checks: usize,
    },
    #[error("no exchange configuration found: {0}")]
    NoExchange(String),
}

impl PickPlaceError {
    /// The request field an error is about (for 4xx answers).
    pub fn field(&self) -> &str {
        match self {
            PickPlaceError::NoRobot(_) => "robot",
            PickPlaceError::NoObject(_) | PickPlaceError::NoGoal(_) => "object",
            PickPlaceError::NoArm { .. } | PickPlaceError::Hand { .. } => "hand",
            PickPlaceError::Arm { .. } | PickPlaceError::ArmBases(..) => "hand",
            PickPlaceError::Invalid { field, .. } => field,
            PickPlaceError::Unreachable { pose, .. } => pose,
            PickPlaceError::NoExchange(_) => "object",
        }
    }
}

/// One arm with its hand: the S-R-S IK of the arm chain (base → TCP) and the hand model.
#[derive(Debug, Clone)]
pub struct ArmHand {
    pub arm_group: String,
    pub arm: SrsArm,
    pub hand: Hand,
    /// The arm chain's tip (the TCP) in the hand's palm frame (fixed joints only).
    pub tip_in_palm: Pose,
    /// Links of the hand (palm and fingers): they may touch the object they grasp.
    pub links: Vec<usize>,
}

impl ArmHand {
    fn new(
        robot: &Arc<Robot>,
        hand_group: &str,
        ws: &WorkspaceParams,
    ) -> Result<ArmHand, PickPlaceError> {
        let arm_group = robot
            .end_effectors
            .iter()
            .find(|e| e.group == hand_group)
            .and_then(|e| e.parent_group.clone())
            .ok_or_else(|| PickPlaceError::NoArm {
                robot: robot.name.clone(),
                hand: hand_group.to_string(),
            })?;
        let arm = SrsArm::from_group(robot, &arm_group).map_err(|e| PickPlaceError::Arm {
            arm: arm_group.clone(),
            reason: e.to_string(),
        })?;
        let hand = Hand::new(robot.clone(), hand_group, None, ws).map_err(|e: HandError| {
            PickPlaceError::Hand {
                hand: hand_group.to_string(),
                reason: e.to_string(),
            }
        })?;
        let q = robot.zero_config();
        let tip_in_palm =
            link_pose(robot, &q, hand.palm).inverse() * link_pose(robot, &q, arm.chain().tip_link);
        let mut links = hand.palm_links.clone();
        links.extend(hand.fingers.iter().flat_map(|f| f.links.iter().copied()));
        if let Some(g) = robot.group(hand_group) {
            links.extend(g.links.iter().copied());
        }
        links.sort_unstable();
        links.dedup();
        Ok(ArmHand {
            arm_group,
            arm,
            hand,
            tip_in_palm,
            links,
        })
    }

    /// The arm's base link (e.g. the chest).
    pub fn base_link(&self) -> usize {
        self.arm.chain().base_link
    }

    /// World pose of the arm's base link at robot configuration `q`, robot at `base`.
    pub fn base_pose(&self, robot: &Robot, base: &Pose, q: &[f64]) -> Pose {
        base * link_pose(robot, q, self.base_link())
    }

    /// World shoulder centre at `q`.
    pub fn shoulder(&self, robot: &Robot, base: &Pose, q: &[f64]) -> Vector3<f64> {
        (self.base_pose(robot, base, q) * nalgebra::Point3::from(self.arm.shoulder_centre())).coords
    }

    /// World wrist centre at `q` (the arm's joint-7 frame origin).
    pub fn wrist(&self, robot: &Robot, base: &Pose, q: &[f64]) -> Vector3<f64> {
        let q7 = self.arm.from_config(q);
        let tip = self.arm.fk(&q7);
        // The wrist centre is fixed in the tip frame: w_tip = T_tip(0)⁻¹ · w.
        let tip0 = self.arm.fk(&[0.0; 7]);
        let w_in_tip = tip0.inverse() * nalgebra::Point3::from(self.arm.wrist_centre());
        (self.base_pose(robot, base, q) * (tip * w_in_tip)).coords
    }

    /// Largest distance from the shoulder centre to the TCP: the arm's reach plus the fixed
    /// wrist–TCP offset (joint limits ignored).
    pub fn tcp_reach(&self) -> f64 {
        let tip0 = self.arm.fk(&[0.0; 7]);
        self.arm.reach() + (tip0.translation.vector - self.arm.wrist_centre()).norm()
    }
}

/// A pick-and-place problem (003 §III): see the module docs.
#[derive(Debug, Clone)]
pub struct PickPlaceProblem {
    pub robot: Arc<Robot>,
    /// World pose of the robot's root.
    pub base: Pose,
    /// The fixed obstacles (the object excluded).
    pub obstacles: Vec<StaticBody>,
    pub object_name: String,
    /// The object's shapes (object frame).
    pub object: Vec<Geometry>,
    /// Centre of mass (object frame) and the radius of a ball about it holding the object.
    pub object_centre: Vector3<f64>,
    pub object_radius: f64,
    /// q_o^i and q_o^f.
    pub initial: Pose,
    pub final_pose: Pose,
    /// q_r^i = q_r^f: the rest configuration the task starts and ends in.
    pub rest: Vec<f64>,
    /// Arm_1 (grasps at q_o^i) and Arm_2 (places at q_o^f).
    pub pick: ArmHand,
    pub place: ArmHand,
    /// The variables between the robot root and the arms' base link (the torso), sampled by
    /// the configuration generator.
    pub torso: Vec<usize>,
}

impl PickPlaceProblem {
    /// The problem of moving `object` of `scene` from its pose to its goal pose with robot
    /// `robot` (its start configuration is the rest configuration), picking with hand group
    /// `pick_hand` and placing with `place_hand`.
    pub fn from_scene(
        scene: &Scene,
        robot: &str,
        object: &str,
        pick_hand: &str,
        place_hand: &str,
        ws: &WorkspaceParams,
    ) -> Result<PickPlaceProblem, PickPlaceError> {
        let placement = scene
            .robot(robot)
            .ok_or_else(|| PickPlaceError::NoRobot(robot.to_string()))?;
        let obj = scene
            .object(object)
            .ok_or_else(|| PickPlaceError::NoObject(object.to_string()))?;
        let goal = obj
            .goal
            .ok_or_else(|| PickPlaceError::NoGoal(object.to_string()))?;
        if pick_hand == place_hand {
            return Err(PickPlaceError::Invalid {
                field: "place_hand".into(),
                reason: format!("the placing hand must differ from the picking hand '{pick_hand}'"),
            });
        }
        let r = placement.robot.clone();
        let pick = ArmHand::new(&r, pick_hand, ws)?;
        let place = ArmHand::new(&r, place_hand, ws)?;
        if pick.base_link() != place.base_link() {
            return Err(PickPlaceError::ArmBases(
                pick.arm_group.clone(),
                place.arm_group.clone(),
            ));
        }
        // Torso: the movable joints on the path from the root to the arms' base link.
        let mut torso = Vec::new();
        let mut l = pick.base_link();
        while let Some(ji) = r.links[l].parent_joint {
            let j = &r.joints[ji];
            if let (Some(v), None) = (j.var, &j.mimic) {
                torso.push(v);
            }
            l = j.parent;
        }
        torso.reverse();
        // The scene's fixed bodies as the collision world builds them, less the object moved.
        let obstacles: Vec<StaticBody> = CollisionWorld::from_scene(scene)
            .statics
            .into_iter()
            .filter(|b| !(b.kind == StaticKind::Object && b.name == object))
            .collect();
        let (centre, _) = object_centre(&obj.body.shapes);
        // The exchange grid's clearance ball keeps the shapes' bounding radius.
        let radius = crate::grasp::mass::bounding_radius(&obj.body.shapes, &centre);
        Ok(PickPlaceProblem {
            robot: r,
            base: placement.base_pose,
            obstacles,
            object_name: object.to_string(),
            object: obj.body.shapes.clone(),
            object_centre: centre,
            object_radius: radius,
            initial: obj.body.pose,
            final_pose: goal,
            rest: placement.start_config(),
            pick,
            place,
            torso,
        })
    }

    /// The same problem with the object's poses replaced (e.g. to test an unreachable pose).
    pub fn with_poses(&self, initial: Pose, final_pose: Pose) -> PickPlaceProblem {
        PickPlaceProblem {
            initial,
            final_pose,
            ..self.clone()
        }
    }

    /// World position of the object's centre at object pose `pose`.
    pub fn centre_at(&self, pose: &Pose) -> Vector3<f64> {
        (pose * nalgebra::Point3::from(self.object_centre)).coords
    }
}
