//! The synchronous queries: FK, IK and collision checks (`/v1/fk`, `/v1/ik`, `/v1/check`).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// `joint name → value` (radians or metres), applied on top of a base configuration.
pub type ConfigMap = BTreeMap<String, f64>;

/// A pose: `position` [x, y, z] in metres and either `rpy` [roll, pitch, yaw] (URDF fixed axes)
/// or `quat_xyzw`. Missing parts are identity.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct PoseBody {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(min_items = 3, max_items = 3))]
    pub position: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(min_items = 3, max_items = 3))]
    pub rpy: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(min_items = 4, max_items = 4))]
    pub quat_xyzw: Option<[f64; 4]>,
}

/// A pose in every form: position, roll-pitch-yaw and quaternion.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct PoseOut {
    #[cfg_attr(feature = "openapi", schema(min_items = 3, max_items = 3))]
    pub position: [f64; 3],
    #[cfg_attr(feature = "openapi", schema(min_items = 3, max_items = 3))]
    pub rpy: [f64; 3],
    #[cfg_attr(feature = "openapi", schema(min_items = 4, max_items = 4))]
    pub quat_xyzw: [f64; 4],
}

/// `POST /v1/fk`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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

#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct LinkPose {
    pub link: String,
    pub pose: PoseOut,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct FkResponse {
    pub robot: String,
    /// Joint names of `config`.
    pub joints: Vec<String>,
    pub config: Vec<f64>,
    pub links: Vec<LinkPose>,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum IkFrame {
    /// The robot's root link.
    #[default]
    Root,
    /// The base link of the group's chain.
    Base,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum IkOrder {
    /// Nearest to the seed configuration first.
    #[default]
    Seed,
    Random,
}

/// `POST /v1/ik`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 3600))]
    pub psi_steps: Option<u32>,
    #[serde(default)]
    pub order: IkOrder,
    /// At most this many solutions are returned (1..=10000, default 16).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 10000))]
    pub max_solutions: Option<u32>,
    /// Seed of the random generator (numeric restarts, random order).
    #[serde(default)]
    pub seed: Option<u64>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct CheckRequest {
    pub scene: String,
    /// Robots not listed stay at their start configuration.
    #[serde(default)]
    pub robots: Vec<SceneRobotConfig>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct CheckFast {
    pub collision: bool,
    #[cfg_attr(feature = "openapi", schema(min_items = 2, max_items = 2))]
    pub pair: Option<[String; 2]>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct CheckResponse {
    pub scene: String,
    /// Exact (parry) answer.
    pub collision: bool,
    /// The first colliding pair (`robot/link`, `obstacle:name`, `object:name`).
    #[cfg_attr(feature = "openapi", schema(min_items = 2, max_items = 2))]
    pub pair: Option<[String; 2]>,
    /// The conservative fast checker's answer (may report contact where the exact one does not).
    pub fast_checker: CheckFast,
}
