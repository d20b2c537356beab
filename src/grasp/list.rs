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
//! 2. **Contacts, finger by finger** (§IV-A-2, [`super::list_search`]): the palm must be free
//!    of the object; then the thumb first, each finger's workspace spheres biggest first
//!    ([`super::finger_workspace`], Alg. 1): the surface points ([`super::surface`], kd-tree)
//!    inside the sphere (at most `candidates_per_sphere` per sphere) are tried with the
//!    finger's position-only numeric IK (the fingertip frame sent to the point); a solution is
//!    a contact when the finger's links are free of the object and of the hand links placed so
//!    far (palm and earlier fingers; pairs the SRDF disables are skipped) and its contact link
//!    touches the object within `contact_tolerance` (gap or depth). A contact link deeper than
//!    that (a flat fingertip on a tilted surface) moves the IK target out along the surface
//!    normal by the excess and tries again (three times at most). The contact is where the
//!    contact link touches: parry's contact point on the object and the inward surface normal
//!    there. The true mesh is used (parry's `TriMesh` and the winding-number inside test of
//!    [`crate::geometry::Solid`]), so a finger may go between the statuette's legs. A thumb
//!    with base joints tries `base_steps` base values (mid-range first).
//!
//!    Which points are tried first decides whether a closure can be stable: the thumb's are
//!    taken nearest the sphere's centre (the part of its workspace farthest from its joint
//!    limits, as 003); every later finger's are ordered by **opposition**, the point whose
//!    inward normal points most against the sum of the inward normals of the contacts made so
//!    far first (a force-closure grasp's forces must push in every direction, so a contact that
//!    pushes along the others' forces never helps). No point is ruled out by the side it faces:
//!    a finger that curls around a leg touches it on the side facing away from the finger's
//!    base, and those contacts are the ones that oppose the thumb; the IK and the depth test
//!    decide whether the fingertip reaches a point from outside.
//!
//!    A finger without contact is left stretched (its rest configuration) or, if that
//!    collides, at mid-range; if both collide the closure gives no grasp. No thumb contact, no
//!    grasp. A frame tries up to `thumb_contacts` thumb contacts in turn (each a full closure
//!    of the other fingers) until one closure is force closure; the first such is the frame's
//!    grasp.
//! 3. **Stability and quality** (§IV-A-3): ≥ 3 contacts → the Ferrari–Canny ε of the point
//!    contacts with friction ([`super::grasp_quality`], centre = the object's centre of mass,
//!    λ = 1 / the largest distance of its surface from that centre, [`super::mass`]); only
//!    force closure with ε > 0 is kept. The quality is the weighted sum
//!    `w₁ ε/ε_max + w₂ (1 − |centroid − com| / radius) + w₃ mean |n·a| + w₄ mean (1 − κ/κ_max)`
//!    of the force-closure score (normalised over the list), the contact centroid's distance
//!    to the centre of mass, the alignment of each inward contact normal with its finger's
//!    force-ellipsoid major axis `a` (the eigenvector of `J Jᵀ` of least eigenvalue, J the
//!    finger's 3×3 position Jacobian; 003 sums the angles, here each term is |cos| so that
//!    higher is better) and the inverse curvature at the contacts (surface variation,
//!    normalised by its maximum over the sampled surface); 003's weights are (1, 1, 1, 6).
//! 4. **Diversity**: two grasps are *near-duplicates* when they touch with the same fingers and
//!    neither the palm origin nor any finger's contact point is `min_separation` or more apart
//!    (default: the width of the hand's narrowest fingertip, twice its radius — two contacts
//!    closer than that share the fingertip's patch). In quality order, a grasp that is a
//!    near-duplicate of one kept is dropped ([`GraspListStats::duplicates`]), so every pair in a
//!    list differs by a finger or by at least `min_separation` at the palm or at a contact
//!    ([`separation`] measures it).
//!
//! Frames are processed in parallel (rayon); each frame's IK restarts draw from its own
//! ChaCha8 generator seeded from `seed` and the frame index, so a list depends only on hand,
//! object and parameters. The grasps are sorted by quality (ties by frame order).

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::hand::{Hand, HandError, WorkspaceParams};
use super::list_search::{Ctx, FrameOutcome, Worker};
use super::so3_grid::{so3_grid, so3_grid_len, MAX_SO3_LEVEL};
use super::wrench_space::WrenchSpaceSettings;
use crate::geometry::Pose;
use crate::model::Robot;

pub use super::grasp_object::GraspObject;

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
    /// Thumb contacts tried per frame, each a closure of the other fingers, until one is force
    /// closure (1..=64).
    pub thumb_contacts: usize,
    /// Near-duplicate distance (m, 0..=0.1): grasps with the same contact fingers whose palm
    /// origins and contact points all lie closer than this keep only the best; default: the
    /// width of the narrowest fingertip (twice its radius).
    pub min_separation: Option<f64>,
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
    /// 125 positions (about: the grid of the object's box) × 72 orientations, 12 grid values
    /// per joint, 16 spheres, 4 candidates per sphere, 3 thumb-base values, 2 thumb contacts per
    /// frame, near-duplicates within a fingertip's width, 1 mm contact tolerance, μ = 0.5, 8
    /// cone edges, weights (1, 1, 1, 6) as 003, 2 000 grasps, seed 1.
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
            thumb_contacts: 2,
            min_separation: None,
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
        if !(1..=64).contains(&self.thumb_contacts) {
            return bad(
                "thumb_contacts",
                format!("must be in 1..=64, got {}", self.thumb_contacts),
            );
        }
        if let Some(d) = self.min_separation {
            if !(d.is_finite() && (0.0..=0.1).contains(&d)) {
                return bad("min_separation", format!("must be in 0..=0.1 m, got {d}"));
            }
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

/// Counts of a list build: where the frames' searches stop (module docs).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GraspListStats {
    pub surface_points: usize,
    pub frames: usize,
    /// Frames whose palm is free of the object.
    pub palm_free: usize,
    /// Frames with a thumb contact.
    pub thumb_contacts: usize,
    /// Frames with a closure of ≥ 3 contacts.
    pub candidates: usize,
    /// Frames with a force-closure grasp (ε > 0).
    pub force_closure: usize,
    /// Hand closures tried (one per thumb contact, at most `thumb_contacts` per frame).
    pub closures: usize,
    /// Closures with ≥ 3 contacts.
    pub closure_candidates: usize,
    /// Closures with ≥ 3 contacts whose forces all push into one half-space (not force
    /// closure, decided without the wrench hull).
    pub one_sided: usize,
    /// Contacts made per finger over all closures (thumb first).
    pub finger_contacts: Vec<usize>,
    /// Force-closure grasps dropped as near-duplicates of a better one.
    pub duplicates: usize,
    /// The near-duplicate distance used (m).
    pub min_separation: f64,
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
    let min_separation = params.min_separation.unwrap_or(2.0 * tip);
    let surface = object.sample_surface(spacing, params.seed)?;
    let frames = grasp_frames(hand, object, params);
    let robot: &Robot = &hand.robot;
    let mut bounds = HashMap::new();
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
        wrench: WrenchSpaceSettings {
            mu: params.mu,
            cone_edges: params.cone_edges,
            lambda: (object.radius > 0.0).then(|| 1.0 / object.radius),
            soft_finger: None,
        },
        base_fracs,
        bounds,
    };
    let done = AtomicUsize::new(0);
    let total = frames.len();
    let stopped = std::sync::atomic::AtomicBool::new(false);
    let results: Vec<FrameOutcome> = frames
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
                    return FrameOutcome::default();
                }
                let mut rng = ChaCha8Rng::seed_from_u64(
                    params.seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
                );
                let out = ctx.frame(palm, w, &mut rng);
                let d = done.fetch_add(1, Ordering::Relaxed) + 1;
                if d % 256 == 0 || d == total {
                    progress(d, total);
                }
                out
            },
        )
        .collect();
    if stopped.load(Ordering::Relaxed) {
        return Err(GraspListError::Stopped);
    }
    let mut stats = GraspListStats {
        surface_points: surface.len(),
        frames: total,
        finger_contacts: vec![0; hand.fingers.len()],
        min_separation,
        spheres: hand.fingers.iter().map(|f| f.workspace.len()).collect(),
        ..Default::default()
    };
    let eps_max = results
        .iter()
        .filter_map(|r| r.candidate.as_ref().map(|c| c.epsilon))
        .fold(0.0f64, f64::max);
    let wts = params.weights;
    let mut grasps = Vec::new();
    for (i, out) in results.into_iter().enumerate() {
        stats.palm_free += out.palm_free as usize;
        stats.thumb_contacts += out.thumb as usize;
        stats.candidates += (out.candidates > 0) as usize;
        stats.closures += out.closures;
        stats.closure_candidates += out.candidates;
        stats.one_sided += out.one_sided;
        for (a, b) in stats.finger_contacts.iter_mut().zip(&out.finger_contacts) {
            *a += b;
        }
        let Some(c) = out.candidate else { continue };
        stats.force_closure += 1;
        let eps = c.epsilon;
        let n = c.contacts.len() as f64;
        let centroid: Vector3<f64> = c.contacts.iter().map(|k| k.point).sum::<Vector3<f64>>() / n;
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
                .map(|fc| fc.axis.normalize().dot(&fc.normal.normalize()).abs())
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
                .map(|fc| ListContact {
                    finger: hand.fingers[fc.finger].group.clone(),
                    point: fc.point.into(),
                    normal: fc.normal.into(),
                })
                .collect(),
            epsilon: eps,
            quality,
            scores,
            frame: i,
        });
    }
    grasps.sort_by(|a, b| b.quality.total_cmp(&a.quality).then(a.frame.cmp(&b.frame)));
    let (grasps, duplicates) = distinct(grasps, min_separation, params.max_grasps);
    stats.duplicates = duplicates;
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

/// The separation of two grasps (module docs, step 4): infinite when they touch with different
/// fingers, else the largest of the distance between their palm origins and the distances
/// between the same finger's contact points (m). Two grasps are near-duplicates when it is
/// below the list's `min_separation`.
pub fn separation(a: &SingleGrasp, b: &SingleGrasp) -> f64 {
    let same = a.contacts.len() == b.contacts.len()
        && a.contacts
            .iter()
            .zip(&b.contacts)
            .all(|(x, y)| x.finger == y.finger);
    if !same {
        return f64::INFINITY;
    }
    let d = |p: &[f64; 3], q: &[f64; 3]| (Vector3::from(*p) - Vector3::from(*q)).norm();
    a.contacts
        .iter()
        .zip(&b.contacts)
        .map(|(x, y)| d(&x.point, &y.point))
        .fold(d(&a.position, &b.position), f64::max)
}

/// The grasps (best first) less every near-duplicate of a better one kept, at most `max` kept,
/// and the number dropped as near-duplicates. Near-duplicates' palm origins lie within
/// `min_separation`, so each grasp is compared only with the kept grasps in the neighbouring
/// cells of a grid of that step.
fn distinct(
    grasps: Vec<SingleGrasp>,
    min_separation: f64,
    max: usize,
) -> (Vec<SingleGrasp>, usize) {
    let mut kept: Vec<SingleGrasp> = Vec::new();
    if min_separation <= 0.0 {
        kept = grasps;
        kept.truncate(max);
        return (kept, 0);
    }
    let mut dropped = 0;
    let cell = |g: &SingleGrasp| g.position.map(|x| (x / min_separation).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for g in grasps {
        if kept.len() >= max {
            break;
        }
        let c = cell(&g);
        let mut dup = false;
        'near: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let k = [c[0] + dx, c[1] + dy, c[2] + dz];
                    if let Some(v) = grid.get(&k) {
                        if v.iter().any(|&i| separation(&kept[i], &g) < min_separation) {
                            dup = true;
                            break 'near;
                        }
                    }
                }
            }
        }
        if dup {
            dropped += 1;
        } else {
            grid.entry(c).or_default().push(kept.len());
            kept.push(g);
        }
    }
    (kept, dropped)
}

/// The workspace parameters of `params` ([`Hand::new`]).
pub fn workspace_params(params: &GraspListParams) -> WorkspaceParams {
    WorkspaceParams {
        steps: params.workspace_steps,
        max_spheres: params.max_spheres,
        min_radius: params.min_sphere_radius,
    }
}
