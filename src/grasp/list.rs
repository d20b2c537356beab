//! Single-grasp lists: paper 003 (Saut et al. 2010) §IV-A.
//!
//! For one hand ([`Hand`], from the robot's URDF and SRDF) and one object ([`GraspObject`], its
//! mesh geometry), every grasp frame of a grid is tried:
//!
//! 1. **Grasp frames** (§IV-A-1): `positions` points on a regular grid filling the object's
//!    axis-aligned box (cell centres, the step chosen so the count is about `positions`) ×
//!    the orientations of the HEALPix × S¹ grid of level `orientation_level`
//!    ([`super::so3_grid`], 72 · 8^level). The frame is centred on the fingers' workspaces
//!    ([`Hand::workspace_centre`]): the palm pose is `T(p) · R · T(−c)`.
//! 2. **Contacts, finger by finger** (§IV-A-2): the palm must be free of the object; then the
//!    thumb first, each finger's workspace spheres biggest first ([`super::finger_workspace`],
//!    Alg. 1): the surface points ([`super::surface`], kd-tree) inside the sphere, nearest its
//!    centre first, whose outward normal faces the finger's base (at most
//!    `candidates_per_sphere` per sphere), are tried with the finger's position-only numeric
//!    IK (the fingertip frame sent to the point); a solution is a contact when the finger's
//!    links are free of the object and of the hand links placed so far (palm and earlier
//!    fingers; pairs the SRDF disables are skipped) and its contact link touches the object
//!    within `contact_tolerance` (gap or depth). A contact link deeper than that (a flat
//!    fingertip on a tilted surface) moves the IK target out along the surface normal by the
//!    excess and tries again (three times at most). The contact is where the contact link
//!    touches: parry's contact point on the object and the inward surface normal there. The true mesh is used
//!    (parry's `TriMesh` and the winding-number inside test of [`crate::geometry::Solid`]), so a
//!    finger may go between the statuette's legs. A thumb with base joints tries `base_steps`
//!    base values (mid-range first). A finger without contact is left stretched (its rest
//!    configuration) or, if that collides, at mid-range; if both collide the frame gives no
//!    grasp. No thumb contact, no grasp.
//! 3. **Stability and quality** (§IV-A-3): ≥ 3 contacts → the Ferrari–Canny ε of the point
//!    contacts with friction ([`super::grasp_quality`], centre = the object's centre of mass,
//!    λ = 1 / its radius); only force closure with ε > 0 is kept. The quality is the weighted
//!    sum `w₁ ε/ε_max + w₂ (1 − |centroid − com| / radius) + w₃ mean |n·a| + w₄ mean (1 − κ/κ_max)`
//!    of the force-closure score (normalised over the list), the contact centroid's distance
//!    to the centre of mass, the alignment of each inward contact normal with its finger's
//!    force-ellipsoid major axis `a` (the eigenvector of `J Jᵀ` of least eigenvalue, J the
//!    finger's 3×3 position Jacobian; 003 sums the angles, here each term is |cos| so that
//!    higher is better) and the inverse curvature at the contacts (surface variation,
//!    normalised by its maximum over the sampled surface); 003's weights are (1, 1, 1, 6).
//!
//! Frames are processed in parallel (rayon); each frame's IK restarts draw from its own
//! ChaCha8 generator seeded from `seed` and the frame index, so a list depends only on hand,
//! object and parameters. The grasps are sorted by quality (ties by frame order).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Instant;

use nalgebra::{Matrix3, Point3, SymmetricEigen, Translation3, UnitQuaternion, Vector3};
use parry3d_f64::query;
use parry3d_f64::shape::SharedShape;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::hand::{transform_sphere, Hand, HandError, WorkspaceParams};
use super::so3_grid::{so3_grid, so3_grid_len, MAX_SO3_LEVEL};
use super::surface::SurfaceSamples;
use super::wrench_space::{
    forces_one_sided, primitive_wrenches_into, quality_of_wrenches, Contact, WrenchSpaceSettings,
};
use super::{object_centre, object_radius};
use crate::collision::to_parry;
use crate::geometry::{Geometry, Pose, Shape, Solid};
use crate::kinematics::NumericIk;
use crate::model::Robot;

/// Most grasp frames (positions × orientations) of one list.
pub const MAX_FRAMES: usize = 1 << 21;
/// Most grasp positions.
pub const MAX_POSITIONS: usize = 100_000;
/// Most grasps kept in a list.
pub const MAX_GRASPS: usize = 100_000;

/// The parameters of a list (all part of its cache key).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GraspListParams {
    /// Grasp positions in the object's box (about; 1..=100 000).
    pub positions: usize,
    /// Level of the SO(3) grid (0..=4: 72 · 8^level orientations).
    pub orientation_level: u32,
    /// Spacing of the surface points (m); default: the smallest fingertip radius (003: "the
    /// sampling step magnitude is chosen from the fingertip radii").
    pub surface_spacing: Option<f64>,
    /// Grid values per finger joint for the workspace spheres (3..=40).
    pub workspace_steps: usize,
    /// Most workspace spheres per finger (1..=64).
    pub max_spheres: usize,
    /// Smallest workspace sphere radius (m); default: the finger's tip radius / 2.
    pub min_sphere_radius: Option<f64>,
    /// Surface points tried per workspace sphere (1..=64).
    pub candidates_per_sphere: usize,
    /// Values tried for a finger's base joints (a thumb base; 1..=16).
    pub base_steps: usize,
    /// How deep the contact link may enter the object at a contact (m, 0..=0.01).
    pub contact_tolerance: f64,
    /// Coulomb friction coefficient of the force-closure test.
    pub mu: f64,
    /// Friction-cone edges of the force-closure test.
    pub cone_edges: usize,
    /// Weights of the force-closure, centroid, force-ellipsoid and curvature scores.
    pub weights: [f64; 4],
    /// Most grasps kept (the best; 1..=100 000).
    pub max_grasps: usize,
    /// Seed of the surface sampling and the IK restarts.
    pub seed: u64,
    /// Finger groups in search order (first = thumb); default: most joints first.
    pub fingers: Option<Vec<String>>,
}

impl Default for GraspListParams {
    /// 125 positions × 72 orientations (9 000 frames), 12 grid values per joint, 16 spheres,
    /// 4 candidates per sphere, 3 thumb-base values, 1 mm contact tolerance, μ = 0.5, 8 cone
    /// edges, weights (1, 1, 1, 6) as 003, 2 000 grasps, seed 1.
    fn default() -> Self {
        GraspListParams {
            positions: 125,
            orientation_level: 0,
            surface_spacing: None,
            workspace_steps: 12,
            max_spheres: 16,
            min_sphere_radius: None,
            candidates_per_sphere: 4,
            base_steps: 3,
            contact_tolerance: 1e-3,
            mu: 0.5,
            cone_edges: 8,
            weights: [1.0, 1.0, 1.0, 6.0],
            max_grasps: 2000,
            seed: 1,
            fingers: None,
        }
    }
}

/// Why a list cannot be built; [`GraspListError::field`] names the offending field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GraspListError {
    #[error("{field}: {reason}")]
    Invalid { field: String, reason: String },
    #[error(transparent)]
    Hand(#[from] HandError),
    #[error("stopped")]
    Stopped,
}

impl GraspListError {
    pub fn invalid(field: &str, reason: impl Into<String>) -> GraspListError {
        GraspListError::Invalid {
            field: field.to_string(),
            reason: reason.into(),
        }
    }

    pub fn field(&self) -> &str {
        match self {
            GraspListError::Invalid { field, .. } => field,
            GraspListError::Hand(h) => h.field(),
            GraspListError::Stopped => "",
        }
    }

    pub fn reason(&self) -> String {
        match self {
            GraspListError::Invalid { reason, .. } => reason.clone(),
            e => e.to_string(),
        }
    }
}

impl GraspListParams {
    /// Checks every bound; the error names the field.
    pub fn validate(&self) -> Result<(), GraspListError> {
        let bad = |f: &str, r: String| Err(GraspListError::invalid(f, r));
        if !(1..=MAX_POSITIONS).contains(&self.positions) {
            return bad(
                "positions",
                format!("must be in 1..={MAX_POSITIONS}, got {}", self.positions),
            );
        }
        if self.orientation_level > MAX_SO3_LEVEL {
            return bad(
                "orientation_level",
                format!(
                    "must be in 0..={MAX_SO3_LEVEL}, got {}",
                    self.orientation_level
                ),
            );
        }
        let frames = self
            .positions
            .saturating_mul(so3_grid_len(self.orientation_level));
        if frames > MAX_FRAMES {
            return bad(
                "positions",
                format!("positions × orientations = {frames} frames, at most {MAX_FRAMES}"),
            );
        }
        if let Some(s) = self.surface_spacing {
            if !(s.is_finite() && (1e-4..=0.1).contains(&s)) {
                return bad(
                    "surface_spacing",
                    format!("must be in 0.0001..=0.1 m, got {s}"),
                );
            }
        }
        if !(3..=40).contains(&self.workspace_steps) {
            return bad(
                "workspace_steps",
                format!("must be in 3..=40, got {}", self.workspace_steps),
            );
        }
        if !(1..=64).contains(&self.max_spheres) {
            return bad(
                "max_spheres",
                format!("must be in 1..=64, got {}", self.max_spheres),
            );
        }
        if let Some(r) = self.min_sphere_radius {
            if !(r.is_finite() && (1e-4..=0.1).contains(&r)) {
                return bad(
                    "min_sphere_radius",
                    format!("must be in 0.0001..=0.1 m, got {r}"),
                );
            }
        }
        if !(1..=64).contains(&self.candidates_per_sphere) {
            return bad(
                "candidates_per_sphere",
                format!("must be in 1..=64, got {}", self.candidates_per_sphere),
            );
        }
        if !(1..=16).contains(&self.base_steps) {
            return bad(
                "base_steps",
                format!("must be in 1..=16, got {}", self.base_steps),
            );
        }
        if !(self.contact_tolerance.is_finite() && (0.0..=0.01).contains(&self.contact_tolerance)) {
            return bad(
                "contact_tolerance",
                format!("must be in 0..=0.01 m, got {}", self.contact_tolerance),
            );
        }
        let ws = WrenchSpaceSettings {
            mu: self.mu,
            cone_edges: self.cone_edges,
            lambda: None,
            soft_finger: None,
        };
        ws.validate()
            .map_err(|e| GraspListError::invalid(e.field(), e.reason()))?;
        for (i, w) in self.weights.iter().enumerate() {
            if !(w.is_finite() && *w >= 0.0 && *w <= 1e6) {
                return bad(
                    &format!("weights[{i}]"),
                    format!("must be in 0..=1e6, got {w}"),
                );
            }
        }
        if !(1..=MAX_GRASPS).contains(&self.max_grasps) {
            return bad(
                "max_grasps",
                format!("must be in 1..={MAX_GRASPS}, got {}", self.max_grasps),
            );
        }
        Ok(())
    }
}

/// One shape of the object: parry shape, pose in the object frame, the solid of a closed mesh,
/// bounding radius about its origin.
#[derive(Clone)]
struct ObjectShape {
    shape: SharedShape,
    pose: Pose,
    parry_pose: parry3d_f64::math::Pose,
    solid: Option<Arc<Solid>>,
    radius: f64,
}

/// The object to grasp: its mesh geometry (object frame), centre of mass and radius.
#[derive(Clone)]
pub struct GraspObject {
    pub name: String,
    pub geometry: Vec<Geometry>,
    /// Centre of mass (uniform density) and the largest distance of the object from it.
    pub centre: Vector3<f64>,
    pub radius: f64,
    shapes: Vec<ObjectShape>,
}

impl std::fmt::Debug for GraspObject {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GraspObject")
            .field("name", &self.name)
            .field("shapes", &self.geometry.len())
            .finish()
    }
}

impl GraspObject {
    /// An object made of `geometry` (poses in the object frame). Every shape must be a mesh
    /// (the surface is sampled from its triangles); a closed mesh is used as its true solid,
    /// another as its convex hull for collisions.
    pub fn new(name: &str, geometry: Vec<Geometry>) -> Result<GraspObject, GraspListError> {
        if geometry.is_empty() {
            return Err(GraspListError::invalid("object", "has no geometry"));
        }
        let mut shapes = Vec::new();
        for (i, g) in geometry.iter().enumerate() {
            let Shape::Mesh(m) = &g.shape else {
                return Err(GraspListError::invalid(
                    &format!("object.shapes[{i}]"),
                    format!(
                        "a {} (grasp lists sample mesh surfaces only)",
                        g.shape.kind()
                    ),
                ));
            };
            let solid = m.solid.as_ref().ok().cloned();
            let (shape, pose) = match &solid {
                Some(s) => {
                    let pts = s
                        .vertices
                        .iter()
                        .map(|v| parry3d_f64::math::Vector::new(v.x, v.y, v.z))
                        .collect();
                    match SharedShape::trimesh(pts, s.triangles.clone()) {
                        Ok(t) => (t, g.origin),
                        Err(e) => {
                            return Err(GraspListError::invalid(
                                &format!("object.shapes[{i}]"),
                                format!("mesh not usable: {e:?}"),
                            ))
                        }
                    }
                }
                None => crate::collision::parry_shape(g),
            };
            shapes.push(ObjectShape {
                parry_pose: to_parry(&pose),
                shape,
                pose,
                solid,
                radius: m.max_radius(),
            });
        }
        let (centre, _) = object_centre(&geometry);
        let radius = object_radius(&geometry, &centre);
        Ok(GraspObject {
            name: name.to_string(),
            geometry,
            centre,
            radius,
            shapes,
        })
    }

    /// The object of one mesh file (OBJ, STL, DAE; metres), named after the file's stem.
    pub fn from_mesh_file(path: &std::path::Path) -> Result<GraspObject, GraspListError> {
        let mesh = crate::geometry::Mesh::load(path, [1.0; 3])
            .map_err(|e| GraspListError::invalid("mesh", e))?;
        let name = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("mesh")
            .to_string();
        GraspObject::new(
            &name,
            vec![Geometry {
                origin: Pose::identity(),
                shape: Shape::Mesh(Arc::new(mesh)),
            }],
        )
    }

    /// The object's box (object frame).
    pub fn aabb(&self) -> (Vector3<f64>, Vector3<f64>) {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for g in &self.geometry {
            if let Shape::Mesh(m) = &g.shape {
                for v in &m.vertices {
                    let p = (g.origin * v).coords;
                    lo = lo.inf(&p);
                    hi = hi.sup(&p);
                }
            }
        }
        (lo, hi)
    }

    /// The surface points ([`SurfaceSamples`]) of all meshes, spacing `spacing`.
    pub fn sample_surface(
        &self,
        spacing: f64,
        seed: u64,
    ) -> Result<SurfaceSamples, GraspListError> {
        let mut verts = Vec::new();
        let mut tris = Vec::new();
        let mut solid = None;
        for (g, s) in self.geometry.iter().zip(&self.shapes) {
            if let Shape::Mesh(m) = &g.shape {
                let (vs, ts): (&[Point3<f64>], &[[u32; 3]]) = match &s.solid {
                    Some(sol) => (&sol.vertices, &sol.triangles),
                    None => (&m.vertices, &m.triangles),
                };
                let base = verts.len() as u32;
                verts.extend(vs.iter().map(|v| g.origin * v));
                tris.extend(ts.iter().map(|t| t.map(|i| i + base)));
                if self.shapes.len() == 1 && g.origin == Pose::identity() {
                    solid = s.solid.clone();
                }
            }
        }
        SurfaceSamples::new(&verts, &tris, solid.as_deref(), spacing, seed)
            .map_err(|e| GraspListError::invalid("surface_spacing", e))
    }

    /// Whether `shape` at `pose` (object frame) intersects the object (surface or inside).
    pub fn hits(&self, shape: &SharedShape, pose: &Pose, bound: f64) -> bool {
        self.shapes.iter().any(|o| {
            if (pose.translation.vector - o.pose.translation.vector).norm() > bound + o.radius {
                return false;
            }
            let pp = to_parry(pose);
            query::intersection_test(&o.parry_pose, o.shape.as_ref(), &pp, shape.as_ref())
                .map(|r| r.intersecting)
                .unwrap_or(true)
                || self.nested(o, shape, pose)
        })
    }

    /// How deep `shape` at `pose` enters the object (0 when apart; infinite when it lies inside
    /// or the pair cannot be answered).
    pub fn depth(&self, shape: &SharedShape, pose: &Pose, bound: f64) -> f64 {
        let mut worst = 0.0f64;
        for o in &self.shapes {
            if (pose.translation.vector - o.pose.translation.vector).norm() > bound + o.radius {
                continue;
            }
            let pp = to_parry(pose);
            match query::contact(&o.parry_pose, o.shape.as_ref(), &pp, shape.as_ref(), 0.0) {
                Ok(Some(c)) => worst = worst.max(-c.dist),
                Ok(None) => {}
                Err(_) => return f64::INFINITY,
            }
            if self.nested(o, shape, pose) {
                return f64::INFINITY;
            }
        }
        worst
    }

    /// Where `shape` at `pose` touches the object within `tol` (distance or depth): the signed
    /// distance (negative: depth), the contact point on the object and the inward normal there.
    pub fn touch(
        &self,
        shape: &SharedShape,
        pose: &Pose,
        tol: f64,
    ) -> Option<(f64, Vector3<f64>, Vector3<f64>)> {
        let mut best: Option<(f64, Vector3<f64>, Vector3<f64>)> = None;
        let pp = to_parry(pose);
        for o in &self.shapes {
            if let Ok(Some(c)) =
                query::contact(&o.parry_pose, o.shape.as_ref(), &pp, shape.as_ref(), tol)
            {
                if c.dist.abs() <= tol && best.is_none_or(|b| c.dist < b.0) {
                    let p = Vector3::new(c.point1.x, c.point1.y, c.point1.z);
                    let n = -Vector3::new(c.normal1.x, c.normal1.y, c.normal1.z);
                    if n.norm() > 0.0 {
                        best = Some((c.dist, p, n.normalize()));
                    }
                }
            }
        }
        best
    }

    /// The distance between `shape` at `pose` (object frame) and the object's true geometry
    /// (the mesh surface, and its inside for a closed mesh): 0 when they touch, intersect or the
    /// shape lies inside. A pair parry cannot answer counts as touching (0), so the value never
    /// overstates the clearance.
    pub fn distance(&self, shape: &SharedShape, pose: &Pose) -> f64 {
        let pp = to_parry(pose);
        let mut best = f64::INFINITY;
        for o in &self.shapes {
            let d = query::distance(&o.parry_pose, o.shape.as_ref(), &pp, shape.as_ref())
                .map_or(0.0, |r| r.distance);
            if !(d > 0.0) || self.nested(o, shape, pose) {
                return 0.0;
            }
            best = best.min(d);
        }
        best
    }

    fn nested(&self, o: &ObjectShape, shape: &SharedShape, pose: &Pose) -> bool {
        match &o.solid {
            Some(s) => {
                // The shape's origin (primitives are centred on it) inside the solid.
                let l = o.pose.inverse() * Point3::from(pose.translation.vector);
                s.contains(&l.coords)
                    || s.vertices.first().is_some_and(|v| {
                        let w = o.pose * v;
                        let pp = to_parry(pose);
                        shape.contains_point(&pp, parry3d_f64::math::Vector::new(w.x, w.y, w.z))
                    })
            }
            None => false,
        }
    }
}

/// A contact of a grasp (object frame).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ListContact {
    /// The finger's group.
    pub finger: String,
    pub point: [f64; 3],
    /// Inward unit normal (the direction the finger pushes).
    pub normal: [f64; 3],
}

/// The four quality scores of a grasp (each in 0..=1, before weighting).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GraspScores {
    pub force_closure: f64,
    pub centroid: f64,
    pub ellipsoid: f64,
    pub curvature: f64,
}

/// One single grasp (003 §IV-A): grasp frame, contacts, hand configuration, quality.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SingleGrasp {
    /// Pose of the palm link in the object frame: position and quaternion (x, y, z, w).
    pub position: [f64; 3],
    pub quat_xyzw: [f64; 4],
    /// Values of the hand's variables ([`GraspList::joints`] order).
    pub config: Vec<f64>,
    pub contacts: Vec<ListContact>,
    /// Ferrari–Canny ε (> 0: force closure).
    pub epsilon: f64,
    /// Weighted quality (module docs).
    pub quality: f64,
    pub scores: GraspScores,
    /// Index of the grasp frame it came from (position-major).
    pub frame: usize,
}

impl SingleGrasp {
    /// The palm pose in the object frame.
    pub fn palm_pose(&self) -> Pose {
        let [x, y, z, w] = self.quat_xyzw;
        Pose::from_parts(
            Translation3::from(Vector3::from(self.position)),
            UnitQuaternion::new_normalize(nalgebra::Quaternion::new(w, x, y, z)),
        )
    }
}

/// Counts of a list build.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GraspListStats {
    pub surface_points: usize,
    pub frames: usize,
    /// Frames whose palm is free of the object.
    pub palm_free: usize,
    /// Frames with a thumb contact.
    pub thumb_contacts: usize,
    /// Frames with ≥ 3 contacts.
    pub candidates: usize,
    /// Candidates in force closure (ε > 0).
    pub force_closure: usize,
    /// Spheres per finger (thumb first).
    pub spheres: Vec<usize>,
    pub seconds: f64,
}

/// A single-grasp list of one hand and one object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GraspList {
    pub robot: String,
    pub hand: String,
    pub object: String,
    pub palm_link: String,
    /// The hand's joints, the order of [`SingleGrasp::config`].
    pub joints: Vec<String>,
    /// Finger groups in search order.
    pub fingers: Vec<String>,
    pub params: GraspListParams,
    /// SHA-256 (hex) of the hand's kinematics and geometry, the object's geometry and the
    /// parameters ([`super::list_cache`]).
    pub hand_hash: String,
    pub object_hash: String,
    pub params_hash: String,
    pub centre: [f64; 3],
    pub radius: f64,
    pub stats: GraspListStats,
    /// Best first.
    pub grasps: Vec<SingleGrasp>,
}

/// The palm poses of the grasp frames (module docs, step 1), position-major.
pub fn grasp_frames(hand: &Hand, object: &GraspObject, params: &GraspListParams) -> Vec<Pose> {
    let (lo, hi) = object.aabb();
    let ext = hi - lo;
    let vol = ext.x.max(1e-9) * ext.y.max(1e-9) * ext.z.max(1e-9);
    let step = (vol / params.positions as f64).cbrt();
    let n = ext.map(|e| ((e / step).round() as usize).max(1));
    let c = hand.workspace_centre(&hand.base_config());
    let rots = so3_grid(params.orientation_level);
    let mut out = Vec::with_capacity(n.x * n.y * n.z * rots.len());
    for i in 0..n.x {
        for j in 0..n.y {
            for k in 0..n.z {
                let p = lo
                    + Vector3::new(
                        ext.x * (i as f64 + 0.5) / n.x as f64,
                        ext.y * (j as f64 + 0.5) / n.y as f64,
                        ext.z * (k as f64 + 0.5) / n.z as f64,
                    );
                for r in &rots {
                    let t = Pose::from_parts(Translation3::from(p), *r)
                        * Pose::from_parts(Translation3::from(-c), UnitQuaternion::identity());
                    out.push(t);
                }
            }
        }
    }
    out
}

/// One finger's contact: the finger, the nearest surface sample (its curvature), the contact
/// point and inward normal (object frame), the finger's force-ellipsoid major axis.
struct FingerContact {
    finger: usize,
    sample: usize,
    point: Vector3<f64>,
    normal: Vector3<f64>,
    axis: Vector3<f64>,
}

/// What a frame gives before the quality step.
struct Candidate {
    palm: Pose,
    config: Vec<f64>,
    contacts: Vec<FingerContact>,
}

/// Per-thread state.
struct Worker {
    q: Vec<f64>,
    iks: Vec<NumericIk>,
    /// Hand links placed so far: (link, pose in the object frame).
    placed: Vec<(usize, Pose)>,
}

#[derive(Default)]
struct FrameOutcome {
    palm_free: bool,
    thumb: bool,
    candidate: Option<Candidate>,
}

struct Ctx<'a> {
    hand: &'a Hand,
    robot: &'a Robot,
    object: &'a GraspObject,
    surface: &'a SurfaceSamples,
    params: &'a GraspListParams,
    /// Base-joint fractions in search order (mid first).
    base_fracs: Vec<f64>,
    /// Bounding radius of each hand link's shapes (about the shape origin).
    bounds: std::collections::HashMap<usize, Vec<f64>>,
}

impl Ctx<'_> {
    /// Whether `link` at `pose` (object frame) collides with the object or with a placed link
    /// (a contact link is tested by its depth instead, [`Self::link_depth`]).
    fn link_blocked(&self, link: usize, pose: &Pose, placed: &[(usize, Pose)]) -> bool {
        let shapes = &self.hand.shapes[&link];
        let bounds = &self.bounds[&link];
        for ((s, local), b) in shapes.iter().zip(bounds) {
            let w = pose * local;
            if self.object.hits(s, &w, *b) {
                return true;
            }
            for (other, opose) in placed {
                if *other == link || self.robot.is_disabled(link, *other) {
                    continue;
                }
                let os = &self.hand.shapes[other];
                let ob = &self.bounds[other];
                for ((s2, l2), b2) in os.iter().zip(ob) {
                    let w2 = opose * l2;
                    if (w.translation.vector - w2.translation.vector).norm() > b + b2 {
                        continue;
                    }
                    let hit = query::intersection_test(
                        &to_parry(&w),
                        s.as_ref(),
                        &to_parry(&w2),
                        s2.as_ref(),
                    )
                    .map(|r| r.intersecting)
                    .unwrap_or(true);
                    if hit {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// Places a finger's `links` at the current configuration; true when all are free.
    fn place_finger_links(&self, palm: &Pose, w: &mut Worker, links: &[usize]) -> bool {
        for &l in links {
            let pose = palm * self.hand.link_in_palm(l, &w.q);
            if self.link_blocked(l, &pose, &w.placed) {
                return false;
            }
            w.placed.push((l, pose));
        }
        true
    }

    fn frame(&self, palm: &Pose, w: &mut Worker, rng: &mut ChaCha8Rng) -> FrameOutcome {
        let mut out = FrameOutcome::default();
        w.q.copy_from_slice(&self.hand.base_config());
        w.placed.clear();
        for &l in &self.hand.palm_links {
            let pose = palm * self.hand.link_in_palm(l, &w.q);
            if self.link_blocked(l, &pose, &w.placed) {
                return out;
            }
            w.placed.push((l, pose));
        }
        out.palm_free = true;
        let mut contacts = Vec::new();
        for fi in 0..self.hand.fingers.len() {
            let found = self.finger_contact(fi, palm, w, rng);
            match found {
                Some(c) => contacts.push(c),
                None if fi == 0 => return out,
                None => {
                    // Rest (stretched), else mid-range.
                    let f = &self.hand.fingers[fi];
                    let mark = w.placed.len();
                    let mut ok = false;
                    for cfg in [f.rest, f.mid] {
                        for (&v, x) in f.ik_vars.iter().zip(cfg) {
                            w.q[v] = x;
                        }
                        w.placed.truncate(mark);
                        let links = f.links.clone();
                        if self.place_finger_links(palm, w, &links) {
                            ok = true;
                            break;
                        }
                    }
                    if !ok {
                        return out;
                    }
                }
            }
            if fi == 0 {
                out.thumb = true;
            }
        }
        if contacts.len() >= 3 {
            out.candidate = Some(Candidate {
                palm: *palm,
                config: self.hand.vars.iter().map(|&v| w.q[v]).collect(),
                contacts,
            });
        }
        out
    }

    /// Finger `fi` reaching surface point `p` (outward normal `n`): the fingertip is sent to `p`
    /// by IK; the finger's other links must be free of the object and the placed links, its
    /// contact link must touch the object within the tolerance. A contact link deeper than that
    /// (a flat tip on a tilted surface) sends the target back along `n` and tries again (at most
    /// three times). The contact is where the contact link touches the object: parry's contact
    /// point on the object and its inward normal.
    #[allow(clippy::too_many_arguments)]
    fn touch_at(
        &self,
        fi: usize,
        palm: &Pose,
        ib: &Pose,
        p: Vector3<f64>,
        n: Vector3<f64>,
        w: &mut Worker,
        rng: &mut ChaCha8Rng,
        base_mark: usize,
    ) -> Option<FingerContact> {
        let f = &self.hand.fingers[fi];
        let tol = self.params.contact_tolerance;
        let ib_inv = ib.inverse();
        let mut target_p = p;
        for k in 0..3 {
            w.q[f.ik_vars[k]] = f.mid[k];
        }
        for _ in 0..4 {
            w.placed.truncate(base_mark);
            let target = Pose::from_parts(
                Translation3::from((ib_inv * Point3::from(target_p)).coords),
                UnitQuaternion::identity(),
            );
            let sol = w.iks[fi].solve(&target, &w.q, rng).ok()?;
            for k in 0..3 {
                w.q[f.ik_vars[k]] = sol[f.ik_vars[k]];
            }
            for &l in &f.links {
                if f.base_links.contains(&l) || l == f.contact_link {
                    continue;
                }
                let pose = palm * self.hand.link_in_palm(l, &w.q);
                if self.link_blocked(l, &pose, &w.placed) {
                    return None;
                }
                w.placed.push((l, pose));
            }
            let cl = f.contact_link;
            let pose = palm * self.hand.link_in_palm(cl, &w.q);
            // The contact link may enter the object by the tolerance (its depth, computed once,
            // also sets the retry's target).
            let depth = self.link_depth(cl, &pose);
            let hand_free = self.hand_free(cl, &pose, &w.placed);
            if depth > tol || !hand_free {
                // Deeper than the tolerance or hitting the hand: only depth is worth a retry.
                if depth.is_finite() && depth > tol && hand_free {
                    target_p += n * (depth - tol / 2.0);
                    continue;
                }
                return None;
            }
            let (point, normal) = self.link_touch(cl, &pose, tol)?;
            w.placed.push((cl, pose));
            // Force-ellipsoid major axis (object frame).
            let j = f.ik_chain.jacobian(self.robot, &w.q);
            let jp = j.fixed_rows::<3>(0).into_owned();
            let m: Matrix3<f64> = &jp * jp.transpose();
            let e = SymmetricEigen::new(m);
            let imin = e
                .eigenvalues
                .iter()
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(b.1))
                .map_or(0, |x| x.0);
            let axis = ib.rotation * e.eigenvectors.column(imin).into_owned();
            return Some(FingerContact {
                finger: fi,
                sample: self.surface.nearest(&point),
                point,
                normal,
                axis,
            });
        }
        None
    }

    /// Deepest penetration of `link` at `pose` into the object.
    fn link_depth(&self, link: usize, pose: &Pose) -> f64 {
        let shapes = &self.hand.shapes[&link];
        let bounds = &self.bounds[&link];
        shapes
            .iter()
            .zip(bounds)
            .map(|((s, local), b)| self.object.depth(s, &(pose * local), *b))
            .fold(0.0, f64::max)
    }

    /// Whether `link` at `pose` is free of the placed hand links.
    fn hand_free(&self, link: usize, pose: &Pose, placed: &[(usize, Pose)]) -> bool {
        let shapes = &self.hand.shapes[&link];
        let bounds = &self.bounds[&link];
        shapes.iter().zip(bounds).all(|((s, local), b)| {
            let w = pose * local;
            placed.iter().all(|(other, opose)| {
                if *other == link || self.robot.is_disabled(link, *other) {
                    return true;
                }
                self.hand.shapes[other]
                    .iter()
                    .zip(&self.bounds[other])
                    .all(|((s2, l2), b2)| {
                        let w2 = opose * l2;
                        (w.translation.vector - w2.translation.vector).norm() > b + b2
                            || !query::intersection_test(
                                &to_parry(&w),
                                s.as_ref(),
                                &to_parry(&w2),
                                s2.as_ref(),
                            )
                            .map(|r| r.intersecting)
                            .unwrap_or(true)
                    })
            })
        })
    }

    /// Where `link` at `pose` touches the object (within `tol`): the contact point on the object
    /// and the inward normal; `None` when it is farther than `tol`.
    fn link_touch(
        &self,
        link: usize,
        pose: &Pose,
        tol: f64,
    ) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let shapes = &self.hand.shapes[&link];
        let mut best: Option<(f64, Vector3<f64>, Vector3<f64>)> = None;
        for (s, local) in shapes {
            if let Some((d, p, n)) = self.object.touch(s, &(pose * local), tol) {
                if best.is_none_or(|b| d < b.0) {
                    best = Some((d, p, n));
                }
            }
        }
        best.map(|b| (b.1, b.2))
    }

    /// Finger `fi`'s contact (module docs, step 2), its links placed; `None` leaves the
    /// placed links as they were.
    fn finger_contact(
        &self,
        fi: usize,
        palm: &Pose,
        w: &mut Worker,
        rng: &mut ChaCha8Rng,
    ) -> Option<FingerContact> {
        let f = &self.hand.fingers[fi];
        let mark = w.placed.len();
        let fracs: &[f64] = if f.base_vars.is_empty() {
            &[0.5]
        } else {
            &self.base_fracs
        };
        for &t in fracs {
            w.placed.truncate(mark);
            for &v in &f.base_vars {
                let l = self.robot.var_limits(v);
                w.q[v] = l.lower + (l.upper - l.lower) * t;
            }
            if !self.place_finger_links(palm, w, &f.base_links) {
                continue;
            }
            let base_mark = w.placed.len();
            let ib = palm * self.hand.link_in_palm(f.ik_base, &w.q);
            let base_origin = ib.translation.vector;
            for s in &f.workspace {
                let s = transform_sphere(&ib, s);
                let mut tried = 0;
                for idx in self.surface.within(&s.centre, s.radius) {
                    if tried >= self.params.candidates_per_sphere {
                        break;
                    }
                    let p = self.surface.points[idx];
                    let n = self.surface.normals[idx];
                    if n.dot(&(base_origin - p)) <= 0.0 {
                        continue;
                    }
                    tried += 1;
                    if let Some(c) = self.touch_at(fi, palm, &ib, p, n, w, rng, base_mark) {
                        return Some(c);
                    }
                }
            }
        }
        w.placed.truncate(mark);
        None
    }
}

/// Builds the single-grasp list of `hand` for `object` (module docs). `progress(done, total)`
/// is called from worker threads as frames finish; `stop` is polled per frame.
pub fn build_grasp_list(
    hand: &Hand,
    object: &GraspObject,
    params: &GraspListParams,
    progress: &(dyn Fn(usize, usize) + Sync),
    stop: &(dyn Fn() -> bool + Sync),
) -> Result<GraspList, GraspListError> {
    let started = Instant::now();
    params.validate()?;
    let tip = hand
        .fingers
        .iter()
        .map(|f| f.tip_radius)
        .fold(f64::INFINITY, f64::min);
    let spacing = params.surface_spacing.unwrap_or(tip);
    let surface = object.sample_surface(spacing, params.seed)?;
    let frames = grasp_frames(hand, object, params);
    let robot: &Robot = &hand.robot;
    let mut bounds = std::collections::HashMap::new();
    for (l, shapes) in &hand.shapes {
        bounds.insert(
            *l,
            shapes
                .iter()
                .map(|(s, _)| s.compute_local_bounding_sphere().radius() + 1e-9)
                .collect::<Vec<f64>>(),
        );
    }
    let base_fracs: Vec<f64> = {
        let n = params.base_steps;
        let mut v: Vec<f64> = (0..n)
            .map(|i| {
                if n == 1 {
                    0.5
                } else {
                    i as f64 / (n - 1) as f64
                }
            })
            .collect();
        v.sort_by(|a, b| {
            (a - 0.5)
                .abs()
                .total_cmp(&(b - 0.5).abs())
                .then(a.total_cmp(b))
        });
        v
    };
    let ctx = Ctx {
        hand,
        robot,
        object,
        surface: &surface,
        params,
        base_fracs,
        bounds,
    };
    let ws_settings = WrenchSpaceSettings {
        mu: params.mu,
        cone_edges: params.cone_edges,
        lambda: (object.radius > 0.0).then(|| 1.0 / object.radius),
        soft_finger: None,
    };
    let done = AtomicUsize::new(0);
    let total = frames.len();
    let stopped = std::sync::atomic::AtomicBool::new(false);
    type FrameResult = (FrameOutcome, Option<(f64, Vec<Contact>)>);
    let results: Vec<FrameResult> = frames
        .par_iter()
        .enumerate()
        .map_init(
            || Worker {
                q: hand.base_config(),
                iks: hand.fingers.iter().map(|f| f.ik.clone()).collect(),
                placed: Vec::new(),
            },
            |w, (i, palm)| {
                if stopped.load(Ordering::Relaxed) || stop() {
                    stopped.store(true, Ordering::Relaxed);
                    return (FrameOutcome::default(), None);
                }
                let mut rng = ChaCha8Rng::seed_from_u64(
                    params.seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
                );
                let out = ctx.frame(palm, w, &mut rng);
                let q = out.candidate.as_ref().and_then(|c| {
                    let contacts: Vec<Contact> = c
                        .contacts
                        .iter()
                        .map(|k| Contact::new(k.point, k.normal))
                        .collect();
                    // `grasp_quality`, with the hull skipped where the forces alone rule out
                    // force closure.
                    let mut w = Vec::new();
                    let lambda =
                        primitive_wrenches_into(&contacts, &object.centre, &ws_settings, &mut w)
                            .ok()?;
                    if forces_one_sided(&w) {
                        return None;
                    }
                    quality_of_wrenches(&w, lambda)
                        .ok()
                        .filter(|g| g.force_closure && g.epsilon > 0.0)
                        .map(|g| (g.epsilon, contacts))
                });
                let d = done.fetch_add(1, Ordering::Relaxed) + 1;
                if d % 256 == 0 || d == total {
                    progress(d, total);
                }
                (out, q)
            },
        )
        .collect();
    if stopped.load(Ordering::Relaxed) {
        return Err(GraspListError::Stopped);
    }
    let mut stats = GraspListStats {
        surface_points: surface.len(),
        frames: total,
        spheres: hand.fingers.iter().map(|f| f.workspace.len()).collect(),
        ..Default::default()
    };
    let eps_max = results
        .iter()
        .filter_map(|r| r.1.as_ref().map(|q| q.0))
        .fold(0.0f64, f64::max);
    let wts = params.weights;
    let mut grasps = Vec::new();
    for (i, (out, q)) in results.into_iter().enumerate() {
        stats.palm_free += out.palm_free as usize;
        stats.thumb_contacts += out.thumb as usize;
        let Some(c) = out.candidate else { continue };
        stats.candidates += 1;
        let Some((eps, contacts)) = q else { continue };
        stats.force_closure += 1;
        let n = c.contacts.len() as f64;
        let centroid: Vector3<f64> = contacts.iter().map(|k| k.point).sum::<Vector3<f64>>() / n;
        let scores = GraspScores {
            force_closure: if eps_max > 0.0 { eps / eps_max } else { 0.0 },
            centroid: if object.radius > 0.0 {
                (1.0 - (centroid - object.centre).norm() / object.radius).clamp(0.0, 1.0)
            } else {
                1.0
            },
            ellipsoid: c
                .contacts
                .iter()
                .zip(&contacts)
                .map(|(fc, k)| fc.axis.normalize().dot(&k.normal.normalize()).abs())
                .sum::<f64>()
                / n,
            curvature: c
                .contacts
                .iter()
                .map(|fc| 1.0 - surface.curvature[fc.sample] / surface.max_curvature)
                .sum::<f64>()
                / n,
        };
        let quality = wts[0] * scores.force_closure
            + wts[1] * scores.centroid
            + wts[2] * scores.ellipsoid
            + wts[3] * scores.curvature;
        let rq = c.palm.rotation.as_ref().coords;
        grasps.push(SingleGrasp {
            position: c.palm.translation.vector.into(),
            quat_xyzw: [rq[0], rq[1], rq[2], rq[3]],
            config: c.config,
            contacts: c
                .contacts
                .iter()
                .zip(&contacts)
                .map(|(fc, k)| ListContact {
                    finger: hand.fingers[fc.finger].group.clone(),
                    point: k.point.into(),
                    normal: k.normal.into(),
                })
                .collect(),
            epsilon: eps,
            quality,
            scores,
            frame: i,
        });
    }
    grasps.sort_by(|a, b| b.quality.total_cmp(&a.quality).then(a.frame.cmp(&b.frame)));
    grasps.truncate(params.max_grasps);
    stats.seconds = started.elapsed().as_secs_f64();
    Ok(GraspList {
        robot: robot.name.clone(),
        hand: hand.group.clone(),
        object: object.name.clone(),
        palm_link: robot.links[hand.palm].name.clone(),
        joints: hand
            .vars
            .iter()
            .map(|&v| robot.var_name(v).to_string())
            .collect(),
        fingers: hand.fingers.iter().map(|f| f.group.clone()).collect(),
        params: params.clone(),
        hand_hash: super::list_cache::hand_hash(hand),
        object_hash: super::list_cache::object_hash(object),
        params_hash: super::list_cache::params_hash(params),
        centre: object.centre.into(),
        radius: object.radius,
        stats,
        grasps,
    })
}

/// The workspace parameters of `params` ([`Hand::new`]).
pub fn workspace_params(params: &GraspListParams) -> WorkspaceParams {
    WorkspaceParams {
        steps: params.workspace_steps,
        max_spheres: params.max_spheres,
        min_radius: params.min_sphere_radius,
    }
}
