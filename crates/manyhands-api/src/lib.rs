//! The request and response bodies of the manyhands HTTP/JSON API, shared by the server (the
//! `manyhands` crate) and the Rust client (`manyhands-client`), so the two cannot drift: the
//! server deserialises requests into these types and serialises its answers from them, and
//! `api/openapi.json` is generated from them (feature `openapi`, which derives
//! `utoipa::ToSchema`; the client does not need it).
//!
//! Plain data only: serde, no planning core. Request bodies deny unknown fields; configurations
//! are `joint name → value` maps ([`ConfigMap`]) applied on top of a base configuration, so
//! errors can name `robots[1].start.right_elbow`. Every 4xx/5xx answer is an [`ErrorBody`].
//!
//! Modules: [`resources`] robots, scenes and health; [`queries`] FK, IK and checks; [`grasp`]
//! the grasp queries; [`plans`] the job kinds ([`multi_arm`] the `multi_arm` kind's request) and jobs; [`trajectory`] timed trajectories;
//! [`error`] the error body. Everything is
//! also re-exported at the crate root.

pub mod error;
pub mod grasp;
pub mod multi_arm;
pub mod plans;
pub mod queries;
pub mod resources;
pub mod trajectory;

pub use error::{ErrorBody, ErrorDetail};
pub use grasp::{
    BasePlacementRequest, DualArmIkRequest, GraspContact, GraspIkRequest, GraspIkResponse,
    GraspQualityRequest, GraspQualityResponse, GraspQualityScore, GraspType, RegionJson,
    TwoHandIkResponse,
};
pub use multi_arm::{MultiArmRequest, MultiArmRobot};
pub use plans::{
    BimanualPlan, CollisionSweep, GraspListParamsBody, GraspListPlan, GraspPlannerName, HandRef,
    Job, JobList, JobState, JobSummary, JointSpacePlan, KitchenTaskPlan, MultiRobotRequest,
    PickPlaceTaskPlan, PlanRequest, PlanRobot, ReachPlan, RegraspPlan, SamplerName,
    ScheduleRequest, ScheduleTrajectory,
};
pub use queries::{
    CheckFast, CheckRequest, CheckResponse, ConfigMap, FkRequest, FkResponse, IkFrame, IkOrder,
    IkRequest, IkResponse, IkSolver, LinkPose, PoseBody, PoseOut, SceneRobotConfig,
};
pub use resources::{
    EndEffectorInfo, GroupInfo, Health, JointInfo, RobotDetail, RobotSummary, RobotUpload,
    SceneRobotInfo, SceneSummary, Source,
};
pub use trajectory::{
    JointTrajectory, TimedWaypoint, TrajectoryEvent, TrajectoryPoint, TrajectoryRequest,
};
