//! Planning jobs (`/v1/plans`): the request of every job kind and the job as answered.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::error::ErrorDetail;
use crate::queries::ConfigMap;

/// One robot of a joint-space planning problem.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct JointSpacePlan {
    pub scene: String,
    #[cfg_attr(feature = "openapi", schema(min_items = 1))]
    pub robots: Vec<PlanRobot>,
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
    /// Factor (0.001..=1) on the joints' velocity limits for the `trajectory` (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub velocity_scaling: Option<f64>,
    /// Factor (0.001..=1) on the joints' acceleration limits for the `trajectory` (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub acceleration_scaling: Option<f64>,
    /// Shortcut the path (default true).
    #[serde(default)]
    pub simplify: Option<bool>,
    /// EXTEND step (joint-space distance; default 0.2 × the space's extent).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0))]
    pub range: Option<f64>,
    /// Dynamic-domain sampling radius (joint-space distance, Yershova et al. 2005; VAMP uses
    /// 4). Default: off.
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0))]
    pub dynamic_domain: Option<f64>,
    /// Grow the smaller tree each iteration instead of alternating (default false).
    #[serde(default)]
    pub balance: Option<bool>,
    /// Certified motion checks for robots made of spheres: every segment is proven free as a
    /// continuous motion, spheres inflated by at most this many metres per checked state
    /// (0 < certify ≤ 0.5). Other robots keep checking states at the resolution. Default: off.
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0, maximum = 0.5))]
    pub certify: Option<f64>,
    /// Sample source: `uniform` (draws from the seeded generator, the default) or `halton`
    /// (the Halton sequence in bases 3, 5, 7, … from its first point, the same for every seed:
    /// VAMP's default; the seed still drives the shortcutting).
    #[serde(default)]
    pub sampler: Option<SamplerName>,
}

/// The sample source of RRT-Connect (`JointSpacePlan::sampler`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum SamplerName {
    Uniform,
    Halton,
}

/// `kind: collision_sweep` — uniform random configurations of a scene's robots checked for
/// collision: free-space fraction and the most frequent colliding pairs.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct CollisionSweep {
    pub scene: String,
    /// Robot instances whose joints are sampled (default: all robots of the scene).
    #[serde(default)]
    pub robots: Option<Vec<String>>,
    /// Number of samples (1..=1e9).
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 1000000000))]
    pub samples: u64,
    #[serde(default)]
    pub seed: Option<u64>,
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
}

/// `kind: grasp_list` — the single-grasp list of a multi-finger hand and an object (paper 003
/// §IV-A): grasp frames on a grid of positions in the object's box × an SO(3) grid, contacts
/// found finger by finger (thumb first) with each finger's workspace spheres and IK, force
/// closure (ε > 0) and a weighted quality. Built once and kept under the data folder (a list of
/// another hand, object or parameters is never reused); the result names the list's `id`
/// (`GET /v1/grasp-lists/{id}`) and its best grasps. Give `mesh`, or `scene` with `object`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct GraspListPlan {
    /// Robot model (e.g. `justin`).
    pub robot: String,
    /// The hand's SRDF group (e.g. `left_hand`); its fingers are the chain groups within it.
    pub hand: String,
    /// A mesh of the built-in scenes' `meshes/` folder by file stem (e.g. `statuette`).
    #[serde(default)]
    pub mesh: Option<String>,
    /// A scene whose `object` is grasped (its mesh shapes).
    #[serde(default)]
    pub scene: Option<String>,
    #[serde(default)]
    pub object: Option<String>,
    /// The list's parameters (unset fields keep their defaults).
    #[serde(default)]
    pub params: Option<GraspListParamsBody>,
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
}

/// Parameters of a single-grasp list; each unset field keeps its default.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct GraspListParamsBody {
    /// Grasp positions in the object's box, about (default 125); positions × orientations
    /// (72 · 8^`orientation_level`) at most 2097152 frames: 1..=29127 at level 0, 3640 at
    /// level 1, 455 at 2, 56 at 3, 7 at 4.
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1))]
    pub positions: Option<usize>,
    /// SO(3) grid level, 72 · 8^level orientations (0..=4, default 0).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0, maximum = 4))]
    pub orientation_level: Option<u32>,
    /// Spacing of the surface samples in m (default: the smallest fingertip radius).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.0001, maximum = 0.1))]
    pub surface_spacing: Option<f64>,
    /// Grid values per finger joint for the workspace spheres (3..=40, default 12).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 3, maximum = 40))]
    pub workspace_steps: Option<usize>,
    /// Most workspace spheres per finger (1..=64, default 16).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 64))]
    pub max_spheres: Option<usize>,
    /// Smallest workspace sphere radius in m (default: half the fingertip radius).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.0001, maximum = 0.1))]
    pub min_sphere_radius: Option<f64>,
    /// Surface points tried per workspace sphere (1..=64, default 4).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 64))]
    pub candidates_per_sphere: Option<usize>,
    /// Values tried for a thumb's base joints (1..=16, default 3).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 16))]
    pub base_steps: Option<usize>,
    /// Thumb contacts tried per grasp frame, each a closure of the other fingers, until one is
    /// force closure (1..=64, default 2).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 64))]
    pub thumb_contacts: Option<usize>,
    /// Near-duplicate distance in m: grasps with the same contact fingers whose palm origins and
    /// contact points all lie closer than this keep only the best (0..=0.1, default: the width
    /// of the narrowest fingertip).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.0, maximum = 0.1))]
    pub min_separation: Option<f64>,
    /// Depth in m a fingertip may enter the object at its contact (0..=0.01, default 0.001).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.0, maximum = 0.01))]
    pub contact_tolerance: Option<f64>,
    /// Friction coefficient of the force-closure test (default 0.5).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0))]
    pub mu: Option<f64>,
    /// Friction-cone edges (3..=32, default 8).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 3, maximum = 32))]
    pub cone_edges: Option<usize>,
    /// Weights of the force-closure, centroid, force-ellipsoid and curvature scores (default
    /// 1, 1, 1, 6 as paper 003).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(min_items = 4, max_items = 4))]
    pub weights: Option<[f64; 4]>,
    /// Most grasps kept (1..=100000, default 2000).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 100000))]
    pub max_grasps: Option<usize>,
    /// Seed of the surface sampling and the finger IK restarts (default 1).
    #[serde(default)]
    pub seed: Option<u64>,
    /// Finger groups in search order, thumb first (default: most joints first).
    #[serde(default)]
    pub fingers: Option<Vec<String>>,
}

/// `kind: reach` — grasp an object of the scene with one hand (IK-RRT, 000 Alg. 3, or J+-RRT,
/// Alg. 1–2). IK-RRT's randomized IK is filtered by the arm's reachability grid (000 §II-D),
/// built on first use and cached under the data folder.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
    /// Factor (0.001..=1) on the joints' velocity limits for the `trajectory` (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub velocity_scaling: Option<f64>,
    /// Factor (0.001..=1) on the joints' acceleration limits for the `trajectory` (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub acceleration_scaling: Option<f64>,
    /// Probability of an IK query per iteration (000 Alg. 3 / 002 Alg. 2); default 0.1, bimanual
    /// 0.03 (002 §VI).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0, maximum = 1.0))]
    pub p_ik: Option<f64>,
    /// Randomized-IK tries per goal query (1..=100000, default 50).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 100000))]
    pub ik_tries: Option<u64>,
    /// Prune (shortcut) the paths (default true).
    #[serde(default)]
    pub simplify: Option<bool>,
}

/// Grasp planner of a `reach` or `regrasp` job (paper 000).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum GraspPlannerName {
    /// IK-RRT (Alg. 3) / dual-arm IK-RRT (§V-B).
    #[default]
    IkRrt,
    /// J+-RRT (Alg. 1–2) / dual-arm J+-RRT (Alg. 4–5), approaching each grasp through its
    /// pre-grasp pose (the grasp's `pregrasp_offset`); `p_ik` and `ik_tries` do not apply.
    JPlusRrt,
}

/// A hand: robot instance and chain group.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct HandRef {
    pub robot: String,
    pub group: String,
}

/// `kind: regrasp` — dual-arm re-grasping (000 §V) or a hand-off between two robots
/// (000 §VI-D): the object goes from the giver's hand to the receiver's (grasped first when it
/// rests on something). Dual-arm IK-RRT filters its IK by the receiver arm's reachability grid
/// (000 §III-B), built on first use and cached under the data folder.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
    /// Factor (0.001..=1) on the joints' velocity limits for the `trajectory` (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub velocity_scaling: Option<f64>,
    /// Factor (0.001..=1) on the joints' acceleration limits for the `trajectory` (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub acceleration_scaling: Option<f64>,
    /// Probability of an IK query per iteration (000 Alg. 3 / 002 Alg. 2); default 0.1, bimanual
    /// 0.03 (002 §VI).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0, maximum = 1.0))]
    pub p_ik: Option<f64>,
    /// Randomized-IK tries per goal query (1..=100000, default 50).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 100000))]
    pub ik_tries: Option<u64>,
    /// Prune (shortcut) the paths (default true).
    #[serde(default)]
    pub simplify: Option<bool>,
}

/// `kind: kitchen_task` — paper 000's kitchen experiment (§VI-C) on a kitchen-like scene:
/// `armar` grasps the wok with the right hand, re-grasps it to the left, moves the right arm
/// away and places the wok on a shelf of the cabinet. The IK is filtered by both arms'
/// reachability grids, built on first use and cached under the data folder.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct KitchenTaskPlan {
    pub scene: String,
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
    /// Factor (0.001..=1) on the joints' velocity limits for the `trajectory` (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub velocity_scaling: Option<f64>,
    /// Factor (0.001..=1) on the joints' acceleration limits for the `trajectory` (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub acceleration_scaling: Option<f64>,
    /// Probability of an IK query per iteration (000 Alg. 3 / 002 Alg. 2); default 0.1, bimanual
    /// 0.03 (002 §VI).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0, maximum = 1.0))]
    pub p_ik: Option<f64>,
    /// Randomized-IK tries per goal query (1..=100000, default 50).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 100000))]
    pub ik_tries: Option<u64>,
    /// Prune (shortcut) the paths (default true).
    #[serde(default)]
    pub simplify: Option<bool>,
}

/// `kind: bimanual` — Bimanual IK-RRT (002 Alg. 2): platform + hip + both arms to a two-hand
/// grasp of an object, goals from IkDualArm with base placement. The platform-frame
/// reachability grids are built on first use and cached under the data folder.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
    /// Factor (0.001..=1) on the joints' velocity limits for the `trajectory` (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub velocity_scaling: Option<f64>,
    /// Factor (0.001..=1) on the joints' acceleration limits for the `trajectory` (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub acceleration_scaling: Option<f64>,
    /// Probability of an IK query per iteration (000 Alg. 3 / 002 Alg. 2); default 0.1, bimanual
    /// 0.03 (002 §VI).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0, maximum = 1.0))]
    pub p_ik: Option<f64>,
    /// Randomized-IK tries per goal query (1..=100000, default 50).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 100000))]
    pub ik_tries: Option<u64>,
    /// Prune (shortcut) the paths (default true).
    #[serde(default)]
    pub simplify: Option<bool>,
}

/// `kind: multi_robot` — Multi-Robot-RRT (002 Alg. 3): one Bimanual IK-RRT worker per robot,
/// a collector scoring the wrench space of all hands' contacts (ε > `s_min`) and rejecting
/// deadlocks (002 eq. 2), then phase-space scheduling (002 §V) so that all robots move at the
/// same time. The answer holds every robot's trajectory, the schedule on one clock, the phase
/// path and the statistics of 002 Tables I–II.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct MultiRobotRequest {
    pub scene: String,
    /// Robot instances of the scene (default: all of them).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(min_items = 1, max_items = 8))]
    pub robots: Option<Vec<String>>,
    /// Left and right chain groups from the platform (default `torso_left_arm`,
    /// `torso_right_arm`).
    #[serde(default)]
    pub left: Option<String>,
    #[serde(default)]
    pub right: Option<String>,
    pub object: String,
    /// Minimum grasp score s_min: ε of the L1 wrench space of all contacts must exceed it
    /// (default 0: any force-closure combination).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.0))]
    pub s_min: Option<f64>,
    /// Friction coefficient μ of the score (default 0.5).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0))]
    pub mu: Option<f64>,
    /// Friction cone edges of the score (3..=32, default 8).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 3, maximum = 32))]
    pub cone_edges: Option<usize>,
    /// Torque scale λ of the score (default 1 / the object's radius).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0))]
    pub lambda: Option<f64>,
    /// Probability of an IK query per worker iteration (default 0.03, 002 §VI).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0, maximum = 1.0))]
    pub p_ik: Option<f64>,
    /// Randomized-IK tries per goal query (1..=100000, default 50).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 100000))]
    pub ik_tries: Option<u64>,
    /// Prune (shortcut) the workers' paths (default true).
    #[serde(default)]
    pub simplify: Option<bool>,
    /// Most solution trajectories per worker (1..=256, default 32).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 256))]
    pub max_solutions: Option<usize>,
    /// Workers stepped round-robin on one thread, so request + seed give the same plan
    /// (default false: one thread per worker).
    #[serde(default)]
    pub deterministic: Option<bool>,
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
    /// Seconds between the points of every robot's `trajectories` entry (0.001..=10, default
    /// 0.01); when given, the schedule is also sampled (`schedule.samples`).
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

/// One robot's trajectory for `kind: schedule`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct ScheduleTrajectory {
    /// Robot instance of the scene.
    pub robot: String,
    /// The variables the waypoints give, as `joint` or `robot/joint` (a `joint_space` answer's
    /// `joints`); the others keep the robot's scene start values. Default: all of the robot's
    /// variables in model order.
    #[serde(default)]
    pub joints: Option<Vec<String>>,
    /// Waypoints (at least one), each with one value per joint of `joints`.
    #[cfg_attr(feature = "openapi", schema(min_items = 1, max_items = 10000))]
    pub path: Vec<Vec<f64>>,
    /// Acceleration limits by joint name (rad/s² or m/s²); joints not named use
    /// `max_acceleration`, else the robot's (its `joint_limits.yaml`, default 1).
    #[serde(default)]
    pub accelerations: Option<HashMap<String, f64>>,
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0))]
    pub max_acceleration: Option<f64>,
}

/// `kind: schedule` — phase-space scheduling (002 §V, Alg. 4) of given joint trajectories, one
/// per robot of a scene, for simultaneous execution: a monotone phase path from all-start to
/// all-goal whose every segment is proven collision-free between the robots, timed on one
/// clock within the joints' velocity (and given acceleration) limits. Each trajectory must be
/// free in the scene on its own (refused with 422 naming the robot and waypoint otherwise).
/// When no schedule exists or none is found (the trajectories' final configurations collide
/// with each other, or no phase path was found and one robot after the other collides) the job
/// fails with error code `no_schedule`, message "no collision-free schedule: …" and the reason.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct ScheduleRequest {
    pub scene: String,
    pub trajectories: Vec<ScheduleTrajectory>,
    /// ε_extend of Alg. 4 in phase units (0.001..=1, default 0.1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub extend: Option<f64>,
    /// Fall back to one robot after the other when the search fails (default true).
    #[serde(default)]
    pub sequential_fallback: Option<bool>,
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
    /// Seconds between the points of every robot's `trajectories` entry (0.001..=10, default
    /// 0.01); when given, the schedule is also sampled (`schedule.samples`).
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

/// `kind: pick_place` — the two-hand pick-and-place task of paper 003 (Fig. 2, §V-B): the
/// object of `scene` is picked at its pose by `pick_hand`, handed over to `place_hand` at an
/// exchange pose near the torso and put down at its goal pose (`objects[].goal`). Offline data
/// (both hands' grasp lists, the super graph of torso + arms) come from the data folder and are
/// built there on first use; online: the key configurations (single and double grasps,
/// exchange), the four queries (grasp, carry, place, rest) in the super graph with lazy
/// revalidation against the object, and one certified plan with grasp and release events. SSE
/// `progress` names the phase (`grasp_lists`, `roadmap`, `exchange`, `double_grasps`,
/// `query_grasp`, `query_carry`, `query_place`, `query_rest`, `certification`).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct PickPlaceTaskPlan {
    pub scene: String,
    /// Robot instance of the scene.
    pub robot: String,
    /// The free object moved (it needs a `goal` pose in the scene).
    pub object: String,
    /// Hand group (SRDF) that picks the object up; its arm is the end effector's parent group.
    pub pick_hand: String,
    /// Hand group that places it (another arm on the same torso).
    pub place_hand: String,
    /// `roadmap` (default, 003 §V-B) or `rrt_connect` (plain single-query planner).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(pattern = "^(roadmap|rrt_connect)$"))]
    pub planner: Option<String>,
    /// Key-configuration searches (each a new seed) tried at most (1..=100, default 4).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 100))]
    pub attempts: Option<usize>,
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
    /// Factor (0.001..=1) on the joints' velocity limits for the `trajectory` (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub velocity_scaling: Option<f64>,
    /// Factor (0.001..=1) on the joints' acceleration limits for the `trajectory` (default 1).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.001, maximum = 1.0))]
    pub acceleration_scaling: Option<f64>,
}

/// `POST /v1/plans`: a problem, selected by `kind`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum PlanRequest {
    JointSpace(JointSpacePlan),
    CollisionSweep(CollisionSweep),
    Reach(ReachPlan),
    Regrasp(RegraspPlan),
    KitchenTask(KitchenTaskPlan),
    Bimanual(BimanualPlan),
    MultiRobot(MultiRobotRequest),
    Schedule(ScheduleRequest),
    GraspList(GraspListPlan),
    PickPlace(PickPlaceTaskPlan),
    MultiArm(crate::multi_arm::MultiArmRequest),
}

impl PlanRequest {
    /// Every `kind` tag, in the order of the variants.
    pub const KINDS: [&'static str; 11] = [
        "joint_space",
        "collision_sweep",
        "reach",
        "regrasp",
        "kitchen_task",
        "bimanual",
        "multi_robot",
        "schedule",
        "grasp_list",
        "pick_place",
        "multi_arm",
    ];

    /// The request's queue settings: `priority` and `max_attempts` (unset ones `None`).
    pub fn queue_settings(&self) -> (Option<i32>, Option<u32>) {
        match self {
            PlanRequest::JointSpace(r) => (r.priority, r.max_attempts),
            PlanRequest::CollisionSweep(r) => (r.priority, r.max_attempts),
            PlanRequest::Reach(r) => (r.priority, r.max_attempts),
            PlanRequest::Regrasp(r) => (r.priority, r.max_attempts),
            PlanRequest::KitchenTask(r) => (r.priority, r.max_attempts),
            PlanRequest::Bimanual(r) => (r.priority, r.max_attempts),
            PlanRequest::MultiRobot(r) => (r.priority, r.max_attempts),
            PlanRequest::Schedule(r) => (r.priority, r.max_attempts),
            PlanRequest::GraspList(r) => (r.priority, r.max_attempts),
            PlanRequest::PickPlace(r) => (r.priority, r.max_attempts),
            PlanRequest::MultiArm(r) => (r.priority, r.max_attempts),
        }
    }

    /// The `kind` tag of this request.
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
            PlanRequest::GraspList(_) => "grasp_list",
            PlanRequest::PickPlace(_) => "pick_place",
            PlanRequest::MultiArm(_) => "multi_arm",
        }
    }
}

/// Life cycle of a job.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
    /// Every state, in life-cycle order.
    pub const ALL: [JobState; 6] = [
        JobState::Queued,
        JobState::Running,
        JobState::Succeeded,
        JobState::Failed,
        JobState::Cancelled,
        JobState::Interrupted,
    ];

    /// Succeeded, failed, cancelled or interrupted: the state will not change any more.
    pub fn is_final(self) -> bool {
        !matches!(self, JobState::Queued | JobState::Running)
    }

    /// The state as serialised (`queued`, `running`, …).
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
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
    #[cfg_attr(feature = "openapi", schema(value_type = Object))]
    pub request: Value,
    /// Latest progress (kind-specific counters: iterations, tree sizes, samples, …).
    #[cfg_attr(feature = "openapi", schema(value_type = Option<Object>))]
    pub progress: Option<Value>,
    /// Result of a succeeded job (kind-specific; `joint_space`: `joints`, `path`, `stats`,
    /// `trajectory`, a `JointTrajectory`; `multi_robot` and `schedule`: `trajectories` by robot).
    #[cfg_attr(feature = "openapi", schema(value_type = Option<Object>))]
    pub result: Option<Value>,
    /// Why a failed job failed: `code` is `invalid_input`, `invalid_start`, `invalid_goal`
    /// (no valid goal configuration), `no_schedule` (fixed trajectories that cannot be
    /// coordinated), `timeout`, `iteration_limit`, `cancelled`, `interrupted`, `path_invalid`
    /// or another kind-specific code, with a message saying why.
    pub error: Option<ErrorDetail>,
    /// What the server changed in the request, e.g. a `time_limit` capped to its maximum.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// Attempts started so far (a job whose replica died is run again while attempts remain).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attempt: Option<u32>,
    /// Attempts the request allows (`max_attempts`, default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_attempts: Option<u32>,
    /// Queue priority (higher first; default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub priority: Option<i32>,
    /// The replica that runs (or ran) the job's current attempt.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub replica: Option<String>,
}

/// `GET /v1/plans`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct JobList {
    /// Newest first.
    pub jobs: Vec<JobSummary>,
    /// Pass as `cursor` for the next page; absent on the last page.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub next_cursor: Option<String>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct JobSummary {
    pub id: String,
    pub kind: String,
    pub state: JobState,
    pub created_ms: u64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn kinds_names_and_tags_agree() {
        let bodies = [
            json!({"kind": "joint_space", "scene": "s", "robots": []}),
            json!({"kind": "collision_sweep", "scene": "s", "samples": 1}),
            json!({"kind": "reach", "scene": "s", "robot": "r", "group": "g", "object": "o"}),
            json!({"kind": "regrasp", "scene": "s", "giver": {"robot": "a", "group": "g"},
                "receiver": {"robot": "b", "group": "g"}, "object": "o"}),
            json!({"kind": "kitchen_task", "scene": "s"}),
            json!({"kind": "bimanual", "scene": "s", "robot": "r", "object": "o"}),
            json!({"kind": "multi_robot", "scene": "s", "object": "o"}),
            json!({"kind": "schedule", "scene": "s", "trajectories": []}),
            json!({"kind": "grasp_list", "robot": "r", "hand": "h", "mesh": "m"}),
            json!({"kind": "pick_place", "scene": "s", "robot": "r", "object": "o",
                "pick_hand": "a", "place_hand": "b"}),
            json!({"kind": "multi_arm", "scene": "s",
                "robots": [{"name": "r", "group": "g", "goal": {"j": 0.0}}]}),
        ];
        assert_eq!(bodies.len(), PlanRequest::KINDS.len());
        for (body, kind) in bodies.iter().zip(PlanRequest::KINDS) {
            let r: PlanRequest = serde_json::from_value(body.clone()).expect(kind);
            assert_eq!(r.kind(), kind);
            let back = serde_json::to_value(&r).expect("serialise");
            assert_eq!(back["kind"], json!(kind));
        }
        let unknown = json!({"kind": "reach", "scene": "s", "robot": "r", "group": "g",
            "object": "o", "colour": "red"});
        assert!(serde_json::from_value::<PlanRequest>(unknown).is_err());
        for s in JobState::ALL {
            assert_eq!(serde_json::to_value(s).expect("state"), json!(s.name()));
            assert_eq!(
                s.is_final(),
                !matches!(s, JobState::Queued | JobState::Running)
            );
        }
    }
}
