//! Request and response bodies of the HTTP API. They are defined in the `manyhands-api` crate,
//! shared with the Rust client (`manyhands-client`) so the two cannot drift, and re-exported
//! here under their old paths; this module adds what only the server needs about them
//! (conversions into planning-core types).
//!
//! Request bodies deny unknown fields; configurations are `joint name → value` maps applied on
//! top of a base configuration, so errors can name `robots[1].start.right_elbow`.

pub use manyhands_api::{
    BasePlacementRequest, BimanualPlan, CheckFast, CheckRequest, CheckResponse, CollisionSweep,
    ConfigMap, DualArmIkRequest, EndEffectorInfo, FkRequest, FkResponse, GraspContact,
    GraspIkRequest, GraspIkResponse, GraspListParamsBody, GraspListPlan, GraspPlannerName,
    GraspQualityRequest, GraspQualityResponse, GraspQualityScore, GroupInfo, HandRef, Health,
    IkFrame, IkOrder, IkRequest, IkResponse, IkSolver, Job, JobList, JobState, JobSummary,
    JointInfo, JointSpacePlan, KitchenTaskPlan, LinkPose, MultiRobotRequest, PickPlaceTaskPlan,
    PlanRequest, PlanRobot, PoseBody, PoseOut, ReachPlan, RegionJson, RegraspPlan, RobotDetail,
    RobotSummary, RobotUpload, SamplerName, SceneRobotConfig, SceneRobotInfo, SceneSummary,
    ScheduleRequest, ScheduleTrajectory, Source, TwoHandIkResponse,
};
pub use manyhands_api::{
    JointTrajectory, TimedWaypoint, TrajectoryEvent, TrajectoryPoint, TrajectoryRequest,
};

use crate::geometry::PoseJson;
use crate::model::GraspType;
use crate::planning::tasks::task::GraspAlgorithm;

/// Settings shared by the grasp planners (IK-RRT family), as given in a request.
#[derive(Debug, Clone, Copy, Default)]
pub struct GraspPlanSettings {
    pub time_limit: Option<f64>,
    pub seed: Option<u64>,
    pub p_ik: Option<f64>,
    pub ik_tries: Option<u64>,
    pub simplify: Option<bool>,
    pub sample_period: Option<f64>,
    pub velocity_scaling: Option<f64>,
    pub acceleration_scaling: Option<f64>,
}

/// The request of a grasp-planner job kind (`reach`, `regrasp`, `kitchen_task`, `bimanual`):
/// its planner settings.
pub trait GraspPlanRequest {
    /// The settings the request gives (unset ones `None`).
    fn settings(&self) -> GraspPlanSettings;
}

macro_rules! grasp_settings {
    ($($t:ty),*) => {$(
        impl GraspPlanRequest for $t {
            fn settings(&self) -> GraspPlanSettings {
                GraspPlanSettings {
                    time_limit: self.time_limit,
                    seed: self.seed,
                    p_ik: self.p_ik,
                    ik_tries: self.ik_tries,
                    simplify: self.simplify,
                    sample_period: self.sample_period,
                    velocity_scaling: self.velocity_scaling,
                    acceleration_scaling: self.acceleration_scaling,
                }
            }
        }
    )*};
}
grasp_settings!(ReachPlan, RegraspPlan, KitchenTaskPlan, BimanualPlan);

impl From<GraspPlannerName> for GraspAlgorithm {
    fn from(name: GraspPlannerName) -> GraspAlgorithm {
        match name {
            GraspPlannerName::IkRrt => GraspAlgorithm::IkRrt,
            GraspPlannerName::JPlusRrt => GraspAlgorithm::JPlusRrt,
        }
    }
}

/// The API form of a scene grasp's kind.
pub fn grasp_type(kind: GraspType) -> manyhands_api::GraspType {
    match kind {
        GraspType::Power => manyhands_api::GraspType::Power,
        GraspType::Precision => manyhands_api::GraspType::Precision,
        GraspType::Pinch => manyhands_api::GraspType::Pinch,
    }
}

/// The API form of a pose (same JSON as the scene files' [`PoseJson`]).
pub fn pose_body(p: PoseJson) -> PoseBody {
    PoseBody {
        position: p.position,
        rpy: p.rpy,
        quat_xyzw: p.quat_xyzw,
    }
}
