//! The grasp queries: randomized grasp IK (`/v1/ik/grasp`), the two-handed IK queries
//! (`/v1/ik/dual-arm`, `/v1/ik/base-placement`) and grasp quality (`/v1/grasp-quality`).

use serde::{Deserialize, Serialize};

use crate::queries::PoseBody;

/// `POST /v1/ik/grasp`: a configuration of `robot`'s chain `group` whose hand holds one of
/// `object`'s grasps where the object lies in `scene`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct GraspIkRequest {
    pub scene: String,
    /// Robot instance of the scene.
    pub robot: String,
    /// Chain group "free joints + 7-DoF S-R-S arm" (e.g. `torso_right_arm`, 10 DoF).
    pub group: String,
    /// Object of the scene; its grasp set for the end effector at the chain's tip is used.
    pub object: String,
    /// Samples of the free joints before "no solution" (1..=1000000, default 20000).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 1000000))]
    pub max_tries: Option<u64>,
    /// Swivel angles per arm-IK call (1..=360, default 8).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 360))]
    pub psi_samples: Option<u32>,
    /// Random seed (default 1): same request and seed, same answer.
    #[serde(default)]
    pub seed: Option<u64>,
    /// Call the arm IK only for grasps whose cell of the arm's 6-D reachability grid is
    /// reachable (000 §II-B/§II-D; default true). The grid of the arm chain (an SRDF group from
    /// the arm's base to its tip, e.g. `right_arm`) is built on first use and kept under the
    /// server's data folder; without such a group the query runs unfiltered.
    #[serde(default)]
    pub reachability: Option<bool>,
}

/// The answer: `found` with the configuration and grasp, or not found after `counters.tries`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct GraspIkResponse {
    pub found: bool,
    /// Why nothing was found (`found: false`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Name of the grasp reached.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub grasp: Option<String>,
    /// Names of the chain's joints, the order of `solution`.
    pub joints: Vec<String>,
    /// Values of the chain's joints.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solution: Option<Vec<f64>>,
    /// Every variable of the robot (`joint: value`), the chain's from the solution, the rest
    /// from the scene's start configuration.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub config: Option<serde_json::Map<String, serde_json::Value>>,
    /// Free-joint samples, analytic IK calls, collision checks.
    pub tries: u64,
    pub ik_calls: u64,
    pub collision_checks: u64,
    /// Whether the reachability filter was used.
    pub reachability: bool,
    /// Wall time of the search (µs), without building or loading the grid.
    pub time_us: f64,
}

/// A box of the world frame (metres): `min[i] ≤ max[i]`.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct RegionJson {
    #[cfg_attr(feature = "openapi", schema(min_items = 3, max_items = 3))]
    pub min: [f64; 3],
    #[cfg_attr(feature = "openapi", schema(min_items = 3, max_items = 3))]
    pub max: [f64; 3],
}

/// `POST /v1/ik/dual-arm`: hip and both arms of `robot` holding `object` with two hands.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct DualArmIkRequest {
    pub scene: String,
    /// Robot instance of the scene.
    pub robot: String,
    /// Object of the scene with grasps for both hands.
    pub object: String,
    /// Chain group "free joints + left 7-DoF S-R-S arm" (default `torso_left_arm`).
    #[serde(default)]
    pub left_group: Option<String>,
    /// Chain group "free joints + right arm" (default `torso_right_arm`); the free joints are
    /// shared with the left chain.
    #[serde(default)]
    pub right_group: Option<String>,
    /// Where the object's origin may be (world frame); its orientation is free.
    pub region: RegionJson,
    /// Name of a left grasp the object is already held by (variant (b), 000 §III); absent: both
    /// grasps are chosen (variant (a)).
    #[serde(default)]
    pub held: Option<String>,
    /// Use the arms' reachability grids as a filter (default true).
    #[serde(default)]
    pub reachability: Option<bool>,
    /// Samples of object pose and hip before "no solution" (1..=1000000, default 20000).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 1000000))]
    pub max_tries: Option<u64>,
    /// Swivel angles per arm-IK call (1..=360, default 8).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 360))]
    pub psi_samples: Option<u32>,
    /// Random seed (default 1): same request and seed, same answer.
    #[serde(default)]
    pub seed: Option<u64>,
}

/// `POST /v1/ik/base-placement`: platform, hip and both arms of a mobile `robot` grasping
/// `object` where it lies, the platform placed by IkDualArm (002 Alg. 1).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct BasePlacementRequest {
    pub scene: String,
    /// Robot instance of the scene; its SRDF group `base` holds the platform's x, y, yaw.
    pub robot: String,
    /// Object of the scene with grasps for both hands.
    pub object: String,
    /// Chain group from the platform through the left arm (default `torso_left_arm`).
    #[serde(default)]
    pub left_group: Option<String>,
    /// Chain group from the platform through the right arm (default `torso_right_arm`).
    #[serde(default)]
    pub right_group: Option<String>,
    /// Base positions within this distance of the object (m, (0, 5], default 1.5).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0, maximum = 5.0))]
    pub radius: Option<f64>,
    /// Cell of the base-position grid (m, [0.02, 1], default 0.1). One request evaluates at
    /// most 250000 platform poses, (2⌈radius / cell⌉ + 1)² × yaw_bins, with radius / cell at
    /// most 200 (refused with 422 naming `cell` beyond).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 0.02, maximum = 1.0))]
    pub cell: Option<f64>,
    /// Base yaw bins (1..=360, default 16).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 360))]
    pub yaw_bins: Option<usize>,
    /// Base samples before "no solution" (1..=1000000, default 20000).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 1000000))]
    pub max_tries: Option<u64>,
    /// Swivel angles per arm-IK call (1..=360, default 8).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 1, maximum = 360))]
    pub psi_samples: Option<u32>,
    /// Random seed (default 1): same request and seed, same answer.
    #[serde(default)]
    pub seed: Option<u64>,
}

/// The answer of both two-handed queries: `found` with the configuration and the grasps, or not
/// found after `tries`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct TwoHandIkResponse {
    pub found: bool,
    /// Why nothing was found (`found: false`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub left_grasp: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub right_grasp: Option<String>,
    /// The variables the query chose (hip and both arms; plus the platform for base placement).
    pub joints: Vec<String>,
    /// Their values.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solution: Option<Vec<f64>>,
    /// Every variable of the robot (`joint: value`): the solution's, the rest from the scene's
    /// start configuration.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub config: Option<serde_json::Map<String, serde_json::Value>>,
    /// World pose of the object in the hands (dual-arm; for base placement where it lies).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(value_type = Option<Object>))]
    pub object_pose: Option<PoseBody>,
    /// Samples of the free parameters, analytic arm-IK calls, collision checks.
    pub tries: u64,
    pub ik_calls: u64,
    pub collision_checks: u64,
    /// Whether reachability filtered the arm-IK calls (always, for base placement).
    pub reachability: bool,
    /// Time to build the inverse reachability maps (base placement), µs.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub map_time_us: Option<f64>,
    /// Wall time of the search (µs), without building or loading grids.
    pub time_us: f64,
}

/// A contact of a finger on the object.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct GraspContact {
    /// Contact point [x, y, z] in metres.
    #[cfg_attr(feature = "openapi", schema(min_items = 3, max_items = 3))]
    pub point: [f64; 3],
    /// Inward surface normal (the direction of the finger force); any non-zero length.
    #[cfg_attr(feature = "openapi", schema(min_items = 3, max_items = 3))]
    pub normal: [f64; 3],
}

/// `POST /v1/grasp-quality`: give `contacts` (with `centre`), or `scene` + `object` (its grasps
/// are scored), or both (the contacts are then in the object frame and share the object's centre
/// and λ, so their ε compares with the grasps').
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct GraspQualityRequest {
    /// Contacts to score (at most 64, and at most 1024 primitive wrenches: contacts ×
    /// (cone_edges + 2 with soft fingers)).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(max_items = 64))]
    pub contacts: Vec<GraspContact>,
    /// Centre of mass of the object, same frame as the contacts. Required without `scene` +
    /// `object`; with them the default is the object's centre of mass (uniform density).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(min_items = 3, max_items = 3))]
    pub centre: Option<[f64; 3]>,
    /// Scene of `object`.
    #[serde(default)]
    pub scene: Option<String>,
    /// Object of `scene` whose grasps are scored (their stored contacts).
    #[serde(default)]
    pub object: Option<String>,
    /// Only these grasps of the object, by name (default: all).
    #[serde(default)]
    pub grasps: Option<Vec<String>>,
    /// Coulomb friction coefficient μ > 0 (default 0.5).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0))]
    pub mu: Option<f64>,
    /// Edges of the linearised friction cone, 3..=32 (default 8).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(minimum = 3, maximum = 32))]
    pub cone_edges: Option<u32>,
    /// Torque scale λ in 1/m. Default: 1 / the object's radius about the centre (GraspIt!'s
    /// 1 / max radius) with `scene` + `object`, else 1 / the largest contact distance from
    /// `centre`.
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0))]
    pub lambda: Option<f64>,
    /// Soft-finger torsional friction γ > 0 in metres: adds the wrenches [0; ±λγn] per contact
    /// (default: point contacts with friction).
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(exclusive_minimum = 0.0))]
    pub soft_finger: Option<f64>,
}

/// Kind of a grasp stored in a scene (`power`, `precision`, `pinch`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GraspType {
    /// `power`.
    Power,
    /// `precision`.
    Precision,
    /// `pinch`.
    Pinch,
}

/// The quality of one grasp of the object.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct GraspQualityScore {
    pub name: String,
    pub end_effector: String,
    /// `power`, `precision` or `pinch`.
    #[serde(rename = "type")]
    #[cfg_attr(feature = "openapi", schema(value_type = String))]
    pub kind: GraspType,
    /// Number of stored contacts (a grasp without contacts has rank 0).
    pub contacts: usize,
    /// The `quality` value stored with the grasp in the scene.
    pub scene_quality: f64,
    pub force_closure: bool,
    pub rank: usize,
    pub epsilon: f64,
    pub wrenches: usize,
    pub facets: usize,
}

/// Answer of `POST /v1/grasp-quality`. The top-level quality fields describe the request's
/// `contacts` and are null when it had none.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct GraspQualityResponse {
    /// The origin of wrench space is strictly inside the hull of the primitive wrenches.
    pub force_closure: Option<bool>,
    /// Rank of the 6×N wrench matrix (< 6: never force closure).
    pub rank: Option<usize>,
    /// Ferrari–Canny ε (L1): distance from the origin to the nearest hull facet; 0 when not
    /// force closure.
    pub epsilon: Option<f64>,
    /// Number of primitive wrenches N.
    pub wrenches: Option<usize>,
    /// Facets of the wrench hull (0 when none was built).
    pub facets: Option<usize>,
    /// Torque scale λ used (with `scene` + `object`: the object's, shared by its grasps and the
    /// contacts; null only for an object of radius 0 without contacts).
    pub lambda: Option<f64>,
    /// Centre of mass used.
    #[cfg_attr(feature = "openapi", schema(min_items = 3, max_items = 3))]
    pub centre: [f64; 3],
    /// Upper bound of the object's extent from `centre` (with `scene` + `object`).
    pub radius: Option<f64>,
    pub mu: f64,
    pub cone_edges: u32,
    pub soft_finger: Option<f64>,
    /// One per scored grasp of the object (empty without `scene` + `object`).
    pub grasps: Vec<GraspQualityScore>,
    pub time_us: f64,
}
