//! Grasp quality: force closure and the Ferrari–Canny ε of the L1 grasp wrench space.
//!
//! Owns grasp quality; depends on nalgebra, [`crate::geometry`] and the scene data types of
//! [`crate::model`] (to score a scene object's grasp set), never on the server or tokio, so
//! planners, the CLI and the HTTP server share it.
//!
//! Conventions (`../shared/notes/grasp-quality.md`):
//! - contact i: point p_i and **inward** unit normal n_i; Coulomb friction μ, the cone linearised
//!   with m edges f_ij = n_i + μ (cos(2πj/m) t1 + sin(2πj/m) t2) (normal component 1, as in
//!   GraspIt! and Dex-Net);
//! - primitive wrench w_ij = [f_ij ; λ (p_i − c) × f_ij], c the object's centre of mass,
//!   λ = 1 / characteristic length; soft fingers add [0 ; ±λ γ n_i];
//! - the L1 grasp wrench space (Ferrari & Canny 1992, Q1) is the convex hull of the primitive
//!   wrenches in R^6; ε = min over hull facets of the distance from the origin to the facet plane;
//!   the origin outside or on the hull → not force closure, ε = 0;
//! - **rank first**: wrenches spanning fewer than 6 dimensions are never force closure (two point
//!   contacts with friction), whatever an LP feasibility test says.
//! - Not Simox's variant (which measures from the hull's vertex centroid and whose stored cone does
//!   not depend on μ).
//!
//! Uses in the papers: paper 002 (Vahrenkamp et al. 2010, multi-robot grasping) §IV-B — the
//! collector thread scores each multi-robot grasping configuration by the wrench space of all
//! contacts (e.g. 20 contacts of two robots on a table) and stops the planners once a minimum score
//! is reached; paper 001 (Saut et al. 2010, two-hand regrasp) §IV-A — single and double grasps are
//! kept only if force closure (point contacts with friction), then ranked.
//!
//! Modules: [`wrench_space`] (contacts, settings, primitive wrenches, rank, ε), [`hull`] (the
//! own 6-D quickhull with joggle) and [`object`] (a scene object's grasps scored with a shared
//! centre and λ); paper 003 §IV-A's single-grasp lists: [`list`] (the generator; its per-frame finger search in
//! `list_search`), [`grasp_object`] (the object's geometry queries), [`hand`] (a
//! multi-finger hand from URDF + SRDF), [`finger_workspace`] (Alg. 1), [`so3_grid`] (the
//! HEALPix × S¹ orientation grid), [`surface`] (surface samples in a kd-tree) and
//! [`list_cache`] (list files keyed by hand, object and parameters). [`mass`] gives a body's
//! mass properties: volume and centre of mass of the union of its parts and the largest distance
//! of its surface from that centre (the torque scale λ = 1 / that distance);
//! [`object_centre`] and [`object_radius`] are its short forms.
//!
//! Reference values (unit cube at the origin, inward normals, μ = 0.5, m = 8, λ = 1, point
//! contacts): four side-face centres → ε = 0.169650; μ = 1 → 0.339299; m = 4 → 0.144338; two
//! opposite face centres → rank 5, not force closure (`tests/grasp_quality.rs`).

pub mod double_grasp;
pub mod finger_workspace;
pub mod grasp_object;
pub mod hand;
pub mod hull;
pub mod list;
pub mod list_cache;
mod list_search;
pub mod mass;
pub mod object;
pub mod so3_grid;
pub mod surface;
pub mod wrench_space;

use nalgebra::Vector3;

use crate::geometry::Geometry;

pub use hand::{Finger, Hand, HandError, WorkspaceParams};
pub use hull::{
    depth_exceeds, nearest_facet_depth, ConvexHull, Facet, HullError, HullOptions, NearestDepth,
    Point6,
};
pub use list::{
    build_grasp_list, separation, GraspList, GraspListError, GraspListParams, GraspListStats,
    GraspObject, GraspScores, ListContact, SingleGrasp,
};
pub use list_cache::{
    load_grasp_list, read_grasp_list, save_grasp_list, GraspListCache, ListFileError,
};
pub use mass::{mass_properties, MassProperties};
pub use object::{grasp_contacts, score_object_grasps, ObjectGraspScores};
pub use wrench_space::{
    grasp_quality, primitive_wrenches, primitive_wrenches_into, quality_of_wrenches,
    quality_of_wrenches_nearest, score_exceeds_nearest, tangents, wrench_rank, Contact, GraspError,
    GraspQuality, WrenchSpaceSettings, MAX_CONE_EDGES, MAX_CONTACTS, MAX_FACETS, MIN_CONE_EDGES,
    RANK_RTOL,
};

/// Centre of mass and radius of a body made of `shapes` (poses in the body frame), uniform
/// density: the centre of the **union** of the parts (overlaps counted once) and the largest
/// distance of the body's surface from it, so `1 / radius` is GraspIt!'s torque scale
/// λ = 1 / max radius and all grasps of one object share it ([`mass::mass_properties`]: exact
/// for parts that do not overlap, the overlaps integrated by rays; cached per geometry). No
/// shapes (or zero volume) → the body origin and the radius about it.
pub fn object_centre(shapes: &[Geometry]) -> (Vector3<f64>, f64) {
    let m = mass::mass_properties(shapes);
    (m.centre, m.radius)
}

/// The largest distance of the surface of a body made of `shapes` from `centre` (exact: a mesh
/// vertex, a box corner, a sphere's, capsule's or cylinder's farthest point; 0 without shapes).
pub fn object_radius(shapes: &[Geometry], centre: &Vector3<f64>) -> f64 {
    mass::farthest_distance(shapes, centre)
}
