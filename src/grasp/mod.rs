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
//! centre and λ); paper 003 §IV-A's single-grasp lists: [`list`] (the generator), [`hand`] (a
//! multi-finger hand from URDF + SRDF), [`finger_workspace`] (Alg. 1), [`so3_grid`] (the
//! HEALPix × S¹ orientation grid), [`surface`] (surface samples in a kd-tree) and
//! [`list_cache`] (list files keyed by hand, object and parameters). [`object_centre`] gives the centre and radius of a scene object from its
//! shapes.
//!
//! Reference values (unit cube at the origin, inward normals, μ = 0.5, m = 8, λ = 1, point
//! contacts): four side-face centres → ε = 0.169650; μ = 1 → 0.339299; m = 4 → 0.144338; two
//! opposite face centres → rank 5, not force closure (`tests/grasp_quality.rs`).

pub mod double_grasp;
pub mod finger_workspace;
pub mod hand;
pub mod hull;
pub mod list;
pub mod list_cache;
pub mod object;
pub mod so3_grid;
pub mod surface;
pub mod wrench_space;

use nalgebra::{Point3, Vector3};

use crate::geometry::{Geometry, Shape};

pub use hand::{Finger, Hand, HandError, WorkspaceParams};
pub use hull::{
    depth_exceeds, nearest_facet_depth, ConvexHull, Facet, HullError, HullOptions, NearestDepth,
    Point6,
};
pub use list::{
    build_grasp_list, GraspList, GraspListError, GraspListParams, GraspListStats, GraspObject,
    GraspScores, ListContact, SingleGrasp,
};
pub use list_cache::{
    load_grasp_list, read_grasp_list, save_grasp_list, GraspListCache, ListFileError,
};
pub use object::{grasp_contacts, score_object_grasps, ObjectGraspScores};
pub use wrench_space::{
    grasp_quality, primitive_wrenches, primitive_wrenches_into, quality_of_wrenches,
    quality_of_wrenches_nearest, score_exceeds_nearest, tangents, wrench_rank, Contact, GraspError,
    GraspQuality, WrenchSpaceSettings, MAX_CONE_EDGES, MAX_CONTACTS, MAX_FACETS, MIN_CONE_EDGES,
    RANK_RTOL,
};

/// Centre of mass and radius of a body made of `shapes` (poses in the body frame), assuming
/// uniform density.
///
/// The centre is the volume-weighted mean of the shapes' centroids (primitives: their origin;
/// meshes: the divergence-theorem centroid of the closed surface, else the bounding-box centre
/// weighted by the box volume). Overlapping shapes count twice — an approximation that is exact
/// for disjoint shapes and good for the scene objects (a wok is a cylinder plus two thin handles).
/// The radius is an upper bound of the largest distance of the body from that centre (shape
/// offset + bounding radius), so `1 / radius` is GraspIt!'s torque scale λ = 1 / max radius and all
/// grasps of one object share it. No shapes (or zero volume) → the body origin and radius 0.
pub fn object_centre(shapes: &[Geometry]) -> (Vector3<f64>, f64) {
    let mut vol = 0.0;
    let mut acc = Vector3::zeros();
    for g in shapes {
        let (v, local) = volume_centroid(&g.shape);
        if v > 0.0 && v.is_finite() {
            vol += v;
            acc += (g.origin * Point3::from(local)).coords * v;
        }
    }
    let c = if vol > 0.0 {
        acc / vol
    } else {
        Vector3::zeros()
    };
    (c, object_radius(shapes, &c))
}

/// Upper bound of the largest distance of a body made of `shapes` from `centre` (shape offset
/// + bounding radius, maximised over the shapes; 0 without shapes).
pub fn object_radius(shapes: &[Geometry], centre: &Vector3<f64>) -> f64 {
    shapes
        .iter()
        .map(|g| (g.origin.translation.vector - centre).norm() + g.shape.bounding_radius())
        .fold(0.0f64, f64::max)
}

/// Volume and centroid (in the shape frame) of one shape.
fn volume_centroid(s: &Shape) -> (f64, Vector3<f64>) {
    use std::f64::consts::PI;
    match s {
        Shape::Box { half_extents: h } => (8.0 * h.x * h.y * h.z, Vector3::zeros()),
        Shape::Cylinder {
            radius,
            half_length,
        } => (PI * radius * radius * 2.0 * half_length, Vector3::zeros()),
        Shape::Sphere { radius } => (4.0 / 3.0 * PI * radius.powi(3), Vector3::zeros()),
        Shape::Capsule {
            radius,
            half_length,
        } => (
            PI * radius * radius * (2.0 * half_length + 4.0 / 3.0 * radius),
            Vector3::zeros(),
        ),
        Shape::Mesh(m) => {
            let mut vol = 0.0;
            let mut acc = Vector3::zeros();
            for t in &m.triangles {
                let [a, b, c] = t.map(|i| {
                    m.vertices
                        .get(i as usize)
                        .map(|p| p.coords)
                        .unwrap_or_else(Vector3::zeros)
                });
                let v = a.dot(&b.cross(&c)) / 6.0;
                vol += v;
                acc += (a + b + c) * (v / 4.0);
            }
            if vol.abs() > 1e-12 {
                (vol.abs(), acc / vol)
            } else {
                let (lo, hi) = m.aabb();
                let d = hi - lo;
                (d.x * d.y * d.z, (lo + hi) / 2.0)
            }
        }
    }
}
