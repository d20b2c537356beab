//! `kind: multi_arm` — N independent arms in one cell planned together.

use serde::{Deserialize, Serialize};

use crate::queries::{ConfigMap, PoseBody};

/// One arm of a `multi_arm` request: a robot instance of the scene, the group it moves and its
/// goal — a configuration (`goal`) or a TCP pose (`goal_pose`, exactly one of the two).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct MultiArmRobot {
    /// Robot instance name in the scene (each robot at most once).
    pub name: String,
    /// Group whose joints move (default: all joints of the robot). A `goal_pose` needs a chain
    /// group: its tip link is the TCP.
    #[serde(default)]
    pub group: Option<String>,
    /// Start, on top of the scene's start configuration (default: that configuration).
    #[serde(default)]
    pub start: ConfigMap,
    /// Goal, on top of the start.
    #[serde(default)]
    pub goal: Option<ConfigMap>,
    /// Goal pose of the group's tip link in the scene frame, solved by IK (free in the scene).
    #[serde(default)]
    pub goal_pose: Option<PoseBody>,
}

/// `kind: multi_arm` — one timed plan on one clock for 1–8 independent arms of a scene, every
/// motion proven collision-free with all arms moving together. The planner chooses its method
/// and says which succeeded: `decoupled` (each arm alone, then the phase-space schedule),
/// `prioritized` (each arm planned in space-time around the earlier ones) or `composite`
/// (RRT-Connect in the joint space of the arms in conflict, or of all arms); the plan is then
/// shortcut for a shorter makespan. The answer holds the method, the schedule, the makespan
/// before and after shortcutting, the trajectory and the statistics.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct MultiArmRequest {
    pub scene: String,
    #[cfg_attr(feature = "openapi", schema(min_items = 1, max_items = 8))]
    pub robots: Vec<MultiArmRobot>,
    /// `auto` (default: decoupled, then prioritized, then composite) or one method alone.
    #[serde(default)]
    #[cfg_attr(
        feature = "openapi",
        schema(pattern = "^(auto|decoupled|prioritized|composite)$")
    )]
    pub method: Option<String>,
    /// Shortcut tries for a shorter makespan (0..=10000, default 200; 0: none).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0, maximum = 10000))]
    pub shortcut_iterations: Option<u64>,
    /// Seconds (default 10; capped by the server's `--max-plan-seconds`).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0))]
    pub time_limit: Option<f64>,
    /// Queue priority: higher runs first, equal priorities oldest first (default 0;
    /// -1000..=1000).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = -1000, maximum = 1000))]
    pub priority: Option<i32>,
    /// Attempts allowed (1..=10, default 1): when the replica running the job dies or
    /// stalls past its lease, the job is run again while attempts remain, else it ends
    /// `interrupted`.
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 10))]
    pub max_attempts: Option<u32>,
    #[serde(default)]
    pub seed: Option<u64>,
    /// Seconds between the points of the answer's `trajectory` (0.001..=10, default 0.01).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 10.0))]
    pub sample_period: Option<f64>,
    /// Factor (0.001..=1) on the joints' velocity limits (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub velocity_scaling: Option<f64>,
    /// Factor (0.001..=1) on the joints' acceleration limits (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub acceleration_scaling: Option<f64>,
}
