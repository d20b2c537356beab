//! Robots and scenes (`/v1/robots`, `/v1/scenes`) and the health answer (`/healthz`, `/readyz`).

use serde::{Deserialize, Serialize};

/// Where a model came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// Loaded at start from the robots/scenes folders; read-only.
    Builtin,
    /// Uploaded with PUT and persisted under the data directory.
    Uploaded,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct RobotSummary {
    pub name: String,
    pub dof: usize,
    pub source: Source,
    pub groups: Vec<String>,
    pub end_effectors: Vec<String>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct JointInfo {
    pub name: String,
    /// `revolute`, `continuous` or `prismatic`.
    #[serde(rename = "type")]
    pub kind: String,
    pub lower: f64,
    pub upper: f64,
    pub velocity: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct GroupInfo {
    pub name: String,
    pub joints: Vec<String>,
    /// `[base_link, tip_link]` for chain groups.
    #[cfg_attr(feature = "openapi", schema(min_items = 2, max_items = 2))]
    pub chain: Option<[String; 2]>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct EndEffectorInfo {
    pub name: String,
    pub parent_link: String,
    pub group: String,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct RobotUpload {
    /// URDF text. Mesh files must be relative paths inside the data directory.
    pub urdf: String,
    /// SRDF text (groups, end effectors, disabled pairs, group states).
    #[serde(default)]
    pub srdf: Option<String>,
    /// Velocity and acceleration limits in MoveIt's `joint_limits.yaml` format (YAML text:
    /// `joint_limits: NAME: {has_velocity_limits, max_velocity, has_acceleration_limits,
    /// max_acceleration}`), used to time the robot's plans.
    #[serde(default)]
    pub joint_limits: Option<String>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct SceneRobotInfo {
    pub name: String,
    pub model: String,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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

/// `GET /healthz`, `GET /readyz`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
