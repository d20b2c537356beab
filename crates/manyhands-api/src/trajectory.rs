//! Timed trajectories: the `trajectory` of every plan answer (`GET /v1/plans/{id}`, CLI
//! `--json`) and `POST /v1/trajectories`, in the shape of ROS's `trajectory_msgs/JointTrajectory`.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

/// A joint trajectory sampled on a fixed period, like ROS's `trajectory_msgs/JointTrajectory`
/// (time-optimal along the planned polyline within the joints' velocity and acceleration
/// limits; it stops at every corner of the polyline, see the server's documentation).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct JointTrajectory {
    /// The joints of `positions`, … (a plan's `variables` / `joints`, in that order).
    pub joint_names: Vec<String>,
    /// States every `sample_period` seconds from 0, and the last one at `duration`.
    pub points: Vec<TrajectoryPoint>,
    /// Seconds between two points: as requested, or coarser in a plan answer whose sampling
    /// would exceed 100000 points or 500000 values (points × joints).
    pub sample_period: f64,
    /// Seconds from the first point to the last.
    pub duration: f64,
    /// The path's waypoints with the time each is reached.
    pub waypoints: Vec<TimedWaypoint>,
    /// Grasps and releases with their time.
    #[serde(default)]
    pub events: Vec<TrajectoryEvent>,
}

/// One sampled state (`trajectory_msgs/JointTrajectoryPoint`; times in seconds).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct TrajectoryPoint {
    pub positions: Vec<f64>,
    pub velocities: Vec<f64>,
    pub accelerations: Vec<f64>,
    pub time_from_start: f64,
}

/// A waypoint of the path and the time it is reached.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct TimedWaypoint {
    pub positions: Vec<f64>,
    pub time_from_start: f64,
}

/// A grasp or release at a time of the trajectory.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct TrajectoryEvent {
    /// `grasp` or `release`.
    pub kind: String,
    pub time_from_start: f64,
    /// Index of the waypoint where it happens (the plan's `waypoints`), when there is one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub waypoint: Option<usize>,
    /// Robot instance of the scene.
    pub robot: String,
    /// End effector (SRDF) name.
    pub end_effector: String,
    pub object: String,
    /// Grasp name (scene grasp set), or the place pose label of a final release.
    pub grasp: String,
}

/// `POST /v1/trajectories`: time a given path of one robot (synchronous).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct TrajectoryRequest {
    /// Robot model name (`GET /v1/robots`).
    pub robot: String,
    /// Joints of the waypoints' values, as `joint` or `robot/joint`.
    #[serde(default)]
    pub joint_names: Option<Vec<String>>,
    /// Or a group whose joints (in the robot's variable order) the values are; without either,
    /// all of the robot's variables in model order.
    #[serde(default)]
    pub group: Option<String>,
    /// Waypoints (1..=10000), each one value per joint.
    #[cfg_attr(feature = "openapi", schema(min_items = 1, max_items = 10000))]
    pub waypoints: Vec<Vec<f64>>,
    /// Velocity limits by joint name, overriding the robot's (rad/s or m/s, > 0).
    #[serde(default)]
    pub max_velocity: Option<HashMap<String, f64>>,
    /// Acceleration limits by joint name, overriding the robot's (rad/s² or m/s², > 0).
    #[serde(default)]
    pub max_acceleration: Option<HashMap<String, f64>>,
    /// Factor (0.001..=1) on every velocity limit (default 1), as MoveIt's.
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub velocity_scaling: Option<f64>,
    /// Factor (0.001..=1) on every acceleration limit (default 1), as MoveIt's.
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub acceleration_scaling: Option<f64>,
    /// Seconds between points (0.001..=10, default 0.01; at most 100000 points and 500000
    /// values, points × joints).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 10.0))]
    pub sample_period: Option<f64>,
}
