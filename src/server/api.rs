//! Request and response bodies of the HTTP API (serde + OpenAPI schemas). Request bodies deny
//! unknown fields; configurations are `joint name → value` maps applied on top of a base
//! configuration, so errors can name `robots[1].start.right_elbow`.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use serde_json::Value;
use utoipa::ToSchema;

pub use super::dual_arm_ik::{
    BasePlacementRequest, DualArmIkRequest, RegionJson, TwoHandIkResponse,
};
use super::error::ErrorDetail;
pub use super::grasp_ik::{GraspIkRequest, GraspIkResponse};
pub use super::grasp_quality::{
    GraspContact, GraspQualityRequest, GraspQualityResponse, GraspQualityScore,
};

/// `joint name → value` (radians or metres), applied on top of a base configuration.
pub type ConfigMap = BTreeMap<String, f64>;

/// A pose: `position` [x, y, z] in metres and either `rpy` [roll, pitch, yaw] (URDF fixed axes)
/// or `quat_xyzw`. Missing parts are identity.
#[derive(Debug, Clone, Default, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PoseBody {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rpy: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quat_xyzw: Option<[f64; 4]>,
}

/// A pose in every form: position, roll-pitch-yaw and quaternion.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct PoseOut {
    pub position: [f64; 3],
    pub rpy: [f64; 3],
    pub quat_xyzw: [f64; 4],
}

/// Where a model came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// Loaded at start from the robots/scenes folders; read-only.
    Builtin,
    /// Uploaded with PUT and persisted under the data directory.
    Uploaded,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct RobotSummary {
    pub name: String,
    pub dof: usize,
    pub source: Source,
    pub groups: Vec<String>,
    pub end_effectors: Vec<String>,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct JointInfo {
    pub name: String,
    /// `revolute`, `continuous` or `prismatic`.
    #[serde(rename = "type")]
    pub kind: String,
    pub lower: f64,
    pub upper: f64,
    pub velocity: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct GroupInfo {
    pub name: String,
    pub joints: Vec<String>,
    /// `[base_link, tip_link]` for chain groups.
    pub chain: Option<[String; 2]>,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct EndEffectorInfo {
    pub name: String,
    pub parent_link: String,
    pub group: String,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct RobotDetail {
    pub name: String,
    pub dof: usize,
    pub source: Source,
    /// Movable joints in configuration-variable order.
    pub joints: Vec<JointInfo>,
    pub links: Vec<String>,
    pub groups: Vec<GroupInfo>,
    pub end_effectors: Vec<EndEffectorInfo>,
    pub named_states: Vec<String>,
    pub warnings: Vec<String>,
}

/// Upload of a robot model.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RobotUpload {
    /// URDF text. Mesh files must be relative paths inside the data directory.
    pub urdf: String,
    /// SRDF text (groups, end effectors, disabled pairs, group states).
    #[serde(default)]
    pub srdf: Option<String>,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct SceneRobotInfo {
    pub name: String,
    pub model: String,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct SceneSummary {
    pub name: String,
    pub description: String,
    pub source: Source,
    pub robots: Vec<SceneRobotInfo>,
    pub obstacles: usize,
    pub objects: usize,
    /// Grasps over all objects.
    pub grasps: usize,
}

/// `POST /v1/fk`.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct FkRequest {
    pub robot: String,
    /// Group state the configuration starts from (default `home`, else zero).
    #[serde(default)]
    pub named: Option<String>,
    #[serde(default)]
    pub config: ConfigMap,
    /// Only these links (default: all).
    #[serde(default)]
    pub links: Option<Vec<String>>,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct LinkPose {
    pub link: String,
    pub pose: PoseOut,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct FkResponse {
    pub robot: String,
    /// Joint names of `config`.
    pub joints: Vec<String>,
    pub config: Vec<f64>,
    pub links: Vec<LinkPose>,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum IkFrame {
    /// The robot's root link.
    #[default]
    Root,
    /// The base link of the group's chain.
    Base,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum IkSolver {
    /// Analytic for S-R-S arms, else numeric.
    #[default]
    Auto,
    /// Analytic S-R-S: every solution over the enumerated swivel angles.
    Analytic,
    /// Damped least squares from the seed with random restarts: one solution.
    Numeric,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum IkOrder {
    /// Nearest to the seed configuration first.
    #[default]
    Seed,
    Random,
}

/// `POST /v1/ik`.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct IkRequest {
    pub robot: String,
    /// A chain group of the robot (e.g. `right_arm`).
    pub group: String,
    /// Target pose of the chain's tip link.
    pub pose: PoseBody,
    #[serde(default)]
    pub frame: IkFrame,
    /// Group state of the seed (default `home`, else zero).
    #[serde(default)]
    pub named: Option<String>,
    /// Seed and values of the joints outside the chain.
    #[serde(default)]
    pub config: ConfigMap,
    #[serde(default)]
    pub solver: IkSolver,
    /// Swivel angles enumerated by the analytic solver (1..=3600, default 36).
    #[serde(default)]
    pub psi_steps: Option<u32>,
    #[serde(default)]
    pub order: IkOrder,
    /// At most this many solutions are returned (1..=10000, default 16).
    #[serde(default)]
    pub max_solutions: Option<u32>,
    /// Seed of the random generator (numeric restarts, random order).
    #[serde(default)]
    pub seed: Option<u64>,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct IkResponse {
    pub robot: String,
    pub group: String,
    /// `analytic` or `numeric`.
    pub solver: String,
    pub solutions_found: usize,
    /// Names of the chain joints, the order of each solution's values.
    pub joints: Vec<String>,
    pub solutions: Vec<Vec<f64>>,
    pub time_us: f64,
}

/// Configuration of one robot of a scene.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct SceneRobotConfig {
    /// Robot instance name in the scene.
    pub name: String,
    /// Named configuration of the placement (scene `configs`) or of the model's group states;
    /// default: the scene's start configuration.
    #[serde(default)]
    pub named: Option<String>,
    #[serde(default)]
    pub config: ConfigMap,
}

/// `POST /v1/check`.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CheckRequest {
    pub scene: String,
    /// Robots not listed stay at their start configuration.
    #[serde(default)]
    pub robots: Vec<SceneRobotConfig>,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct CheckFast {
    pub collision: bool,
    pub pair: Option<[String; 2]>,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct CheckResponse {
    pub scene: String,
    /// Exact (parry) answer.
    pub collision: bool,
    /// The first colliding pair (`robot/link`, `obstacle:name`, `object:name`).
    pub pair: Option<[String; 2]>,
    /// The conservative fast checker's answer (may report contact where the exact one does not).
    pub fast_checker: CheckFast,
}

/// One robot of a joint-space planning problem.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PlanRobot {
    /// Robot instance name in the scene.
    pub name: String,
    /// Group whose joints are planned (default: all joints of the robot).
    #[serde(default)]
    pub group: Option<String>,
    /// Start, on top of the scene's start configuration (default: that configuration).
    #[serde(default)]
    pub start: ConfigMap,
    /// Goal, on top of the scene's start configuration.
    pub goal: ConfigMap,
}

/// `kind: joint_space` — RRT-Connect from start to goal configurations of one or more robots
/// of a scene, then shortcutting.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct JointSpacePlan {
    pub scene: String,
    pub robots: Vec<PlanRobot>,
    /// Seconds (default 10; capped by the server's `--max-plan-seconds`).
    #[serde(default)]
    pub time_limit: Option<f64>,
    #[serde(default)]
    pub seed: Option<u64>,
    /// Shortcut the path (default true).
    #[serde(default)]
    pub simplify: Option<bool>,
    /// EXTEND step (joint-space distance; default 0.2 × the space's extent).
    #[serde(default)]
    pub range: Option<f64>,
    /// Dynamic-domain sampling radius (joint-space distance, Yershova et al. 2005; VAMP uses
    /// 4). Default: off.
    #[serde(default)]
    pub dynamic_domain: Option<f64>,
    /// Grow the smaller tree each iteration instead of alternating (default false).
    #[serde(default)]
    pub balance: Option<bool>,
    /// Certified motion checks for robots made of spheres: every segment is proven free as a
    /// continuous motion, spheres inflated by at most this many metres per checked state
    /// (0 < certify ≤ 0.5). Other robots keep checking states at the resolution. Default: off.
    #[serde(default)]
    pub certify: Option<f64>,
}

/// `kind: collision_sweep` — uniform random configurations of a scene's robots checked for
/// collision: free-space fraction and the most frequent colliding pairs.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CollisionSweep {
    pub scene: String,
    /// Robot instances whose joints are sampled (default: all robots of the scene).
    #[serde(default)]
    pub robots: Option<Vec<String>>,
    /// Number of samples (1..=1e9).
    pub samples: u64,
    #[serde(default)]
    pub seed: Option<u64>,
    /// Seconds (default 10; capped by the server's `--max-plan-seconds`).
    #[serde(default)]
    pub time_limit: Option<f64>,
}

/// Settings shared by the grasp planners (IK-RRT family), as given in a request.
#[derive(Debug, Clone, Copy, Default)]
pub struct GraspPlanSettings {
    pub time_limit: Option<f64>,
    pub seed: Option<u64>,
    pub p_ik: Option<f64>,
    pub ik_tries: Option<u64>,
    pub simplify: Option<bool>,
}

macro_rules! grasp_settings {
    ($($t:ty),*) => {$(
        impl $t {
            pub fn settings(&self) -> GraspPlanSettings {
                GraspPlanSettings {
                    time_limit: self.time_limit,
                    seed: self.seed,
                    p_ik: self.p_ik,
                    ik_tries: self.ik_tries,
                    simplify: self.simplify,
                }
            }
        }
    )*};
}
grasp_settings!(ReachPlan, RegraspPlan, KitchenTaskPlan, BimanualPlan);

/// `kind: reach` — grasp an object of the scene with one hand (IK-RRT, 000 Alg. 3, or J+-RRT,
/// Alg. 1–2). IK-RRT's randomized IK is filtered by the arm's reachability grid (000 §II-D),
/// built on first use and cached under the data folder.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ReachPlan {
    pub scene: String,
    /// Robot instance of the scene.
    pub robot: String,
    /// Chain group from the free joints to the hand (e.g. `torso_right_arm`).
    pub group: String,
    pub object: String,
    /// `ik_rrt` (default) or `j_plus_rrt`.
    #[serde(default)]
    pub planner: Option<GraspPlannerName>,
    /// Seconds (default 10; capped by the server's `--max-plan-seconds`).
    #[serde(default)]
    pub time_limit: Option<f64>,
    #[serde(default)]
    pub seed: Option<u64>,
    /// Probability of an IK query per iteration (000 Alg. 3 / 002 Alg. 2); default 0.1, bimanual
    /// 0.03 (002 §VI).
    #[serde(default)]
    pub p_ik: Option<f64>,
    /// Randomized-IK tries per goal query (1..=100000, default 50).
    #[serde(default)]
    pub ik_tries: Option<u64>,
    /// Prune (shortcut) the paths (default true).
    #[serde(default)]
    pub simplify: Option<bool>,
}

/// Grasp planner of a `reach` or `regrasp` job (paper 000).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum GraspPlannerName {
    /// IK-RRT (Alg. 3) / dual-arm IK-RRT (§V-B).
    #[default]
    IkRrt,
    /// J+-RRT (Alg. 1–2) / dual-arm J+-RRT (Alg. 4–5), approaching each grasp through its
    /// pre-grasp pose (the grasp's `pregrasp_offset`); `p_ik` and `ik_tries` do not apply.
    JPlusRrt,
}

impl GraspPlannerName {
    pub fn algorithm(self) -> crate::planning::task::GraspAlgorithm {
        match self {
            GraspPlannerName::IkRrt => crate::planning::task::GraspAlgorithm::IkRrt,
            GraspPlannerName::JPlusRrt => crate::planning::task::GraspAlgorithm::JPlusRrt,
        }
    }
}

/// A hand: robot instance and chain group.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct HandRef {
    pub robot: String,
    pub group: String,
}

/// `kind: regrasp` — dual-arm re-grasping (000 §V) or a hand-off between two robots
/// (000 §VI-D): the object goes from the giver's hand to the receiver's (grasped first when it
/// rests on something). Dual-arm IK-RRT filters its IK by the receiver arm's reachability grid
/// (000 §III-B), built on first use and cached under the data folder.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RegraspPlan {
    pub scene: String,
    pub giver: HandRef,
    pub receiver: HandRef,
    pub object: String,
    /// Giver grasp holding the object at the start (it is put into the hand there).
    #[serde(default)]
    pub held: Option<String>,
    /// `ik_rrt` (default: IK-RRT grasp, dual-arm IK-RRT re-grasp) or `j_plus_rrt` (J+-RRT,
    /// dual-arm J+-RRT).
    #[serde(default)]
    pub planner: Option<GraspPlannerName>,
    /// Seconds (default 10; capped by the server's `--max-plan-seconds`).
    #[serde(default)]
    pub time_limit: Option<f64>,
    #[serde(default)]
    pub seed: Option<u64>,
    /// Probability of an IK query per iteration (000 Alg. 3 / 002 Alg. 2); default 0.1, bimanual
    /// 0.03 (002 §VI).
    #[serde(default)]
    pub p_ik: Option<f64>,
    /// Randomized-IK tries per goal query (1..=100000, default 50).
    #[serde(default)]
    pub ik_tries: Option<u64>,
    /// Prune (shortcut) the paths (default true).
    #[serde(default)]
    pub simplify: Option<bool>,
}

/// `kind: kitchen_task` — paper 000's kitchen experiment (§VI-C) on a kitchen-like scene:
/// `armar` grasps the wok with the right hand, re-grasps it to the left, moves the right arm
/// away and places the wok on a shelf of the cabinet. The IK is filtered by both arms'
/// reachability grids, built on first use and cached under the data folder.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct KitchenTaskPlan {
    pub scene: String,
    /// Seconds (default 10; capped by the server's `--max-plan-seconds`).
    #[serde(default)]
    pub time_limit: Option<f64>,
    #[serde(default)]
    pub seed: Option<u64>,
    /// Probability of an IK query per iteration (000 Alg. 3 / 002 Alg. 2); default 0.1, bimanual
    /// 0.03 (002 §VI).
    #[serde(default)]
    pub p_ik: Option<f64>,
    /// Randomized-IK tries per goal query (1..=100000, default 50).
    #[serde(default)]
    pub ik_tries: Option<u64>,
    /// Prune (shortcut) the paths (default true).
    #[serde(default)]
    pub simplify: Option<bool>,
}

/// `kind: bimanual` — Bimanual IK-RRT (002 Alg. 2): platform + hip + both arms to a two-hand
/// grasp of an object, goals from IkDualArm with base placement. The platform-frame
/// reachability grids are built on first use and cached under the data folder.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct BimanualPlan {
    pub scene: String,
    pub robot: String,
    /// Left and right chain groups from the platform (default `torso_left_arm`,
    /// `torso_right_arm`).
    #[serde(default)]
    pub left: Option<String>,
    #[serde(default)]
    pub right: Option<String>,
    pub object: String,
    /// Seconds (default 10; capped by the server's `--max-plan-seconds`).
    #[serde(default)]
    pub time_limit: Option<f64>,
    #[serde(default)]
    pub seed: Option<u64>,
    /// Probability of an IK query per iteration (000 Alg. 3 / 002 Alg. 2); default 0.1, bimanual
    /// 0.03 (002 §VI).
    #[serde(default)]
    pub p_ik: Option<f64>,
    /// Randomized-IK tries per goal query (1..=100000, default 50).
    #[serde(default)]
    pub ik_tries: Option<u64>,
    /// Prune (shortcut) the paths (default true).
    #[serde(default)]
    pub simplify: Option<bool>,
}

/// `POST /v1/plans`: a problem, selected by `kind`.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum PlanRequest {
    JointSpace(JointSpacePlan),
    CollisionSweep(CollisionSweep),
    Reach(ReachPlan),
    Regrasp(RegraspPlan),
    KitchenTask(KitchenTaskPlan),
    Bimanual(BimanualPlan),
    MultiRobot(super::multi_robot::MultiRobotRequest),
    Schedule(super::multi_robot::ScheduleRequest),
}

impl PlanRequest {
    pub const KINDS: [&'static str; 8] = [
        "joint_space",
        "collision_sweep",
        "reach",
        "regrasp",
        "kitchen_task",
        "bimanual",
        "multi_robot",
        "schedule",
    ];

    pub fn kind(&self) -> &'static str {
        match self {
            PlanRequest::JointSpace(_) => "joint_space",
            PlanRequest::CollisionSweep(_) => "collision_sweep",
            PlanRequest::Reach(_) => "reach",
            PlanRequest::Regrasp(_) => "regrasp",
            PlanRequest::KitchenTask(_) => "kitchen_task",
            PlanRequest::Bimanual(_) => "bimanual",
            PlanRequest::MultiRobot(_) => "multi_robot",
            PlanRequest::Schedule(_) => "schedule",
        }
    }
}

/// Life cycle of a job.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize, ToSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum JobState {
    Queued,
    Running,
    Succeeded,
    Failed,
    Cancelled,
    /// The server stopped (or died) while the job was queued or running.
    Interrupted,
}

impl JobState {
    pub const ALL: [JobState; 6] = [
        JobState::Queued,
        JobState::Running,
        JobState::Succeeded,
        JobState::Failed,
        JobState::Cancelled,
        JobState::Interrupted,
    ];

    pub fn is_final(self) -> bool {
        !matches!(self, JobState::Queued | JobState::Running)
    }

    pub fn name(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Succeeded => "succeeded",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
            JobState::Interrupted => "interrupted",
        }
    }
}

/// A planning job: its request, state, progress and (when final) result or error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Job {
    pub id: String,
    pub kind: String,
    pub state: JobState,
    /// Unix time in milliseconds.
    pub created_ms: u64,
    pub started_ms: Option<u64>,
    pub finished_ms: Option<u64>,
    /// Effective time limit in seconds (after the server's cap).
    pub time_limit: f64,
    /// The request as accepted.
    #[schema(value_type = Object)]
    pub request: Value,
    /// Latest progress (kind-specific counters: iterations, tree sizes, samples, …).
    #[schema(value_type = Option<Object>)]
    pub progress: Option<Value>,
    /// Result of a succeeded job (kind-specific; `joint_space`: `joints`, `path`, `stats`).
    #[schema(value_type = Option<Object>)]
    pub result: Option<Value>,
    pub error: Option<ErrorDetail>,
    /// What the server changed in the request, e.g. a `time_limit` capped to its maximum.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// `GET /v1/plans`.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct JobList {
    pub jobs: Vec<JobSummary>,
}

#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct JobSummary {
    pub id: String,
    pub kind: String,
    pub state: JobState,
    pub created_ms: u64,
}

/// `GET /healthz`, `GET /readyz`.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct Health {
    /// `ok`, or `shutting_down`.
    pub status: String,
    pub version: String,
    pub robots: usize,
    pub scenes: usize,
    pub queue_depth: usize,
    pub queue_capacity: usize,
    pub workers: usize,
}
