//! The exchange position of the object (paper 003 §V-C, Fig. 6) and the exchange poses sampled
//! around it.
//!
//! **Grid.** 003 minimises the wrist motions "on a 3D grid": the grid here spans the space both
//! hands can reach in front of the torso at the rest configuration q_r^i. Each arm's reach is a
//! ball about its shoulder centre of radius [`super::ArmHand::tcp_reach`] (arm length plus the
//! fixed wrist–TCP offset); the grid is the bounding box of the two balls' intersection, `cells`
//! nodes per axis, and a node is a candidate when it lies in both balls and in front of the
//! torso: on the side of the plane through the two shoulders (and the vertical) where the
//! object's initial and final positions lie on average. Nothing is keyed to a robot: shoulders,
//! reach and "front" come from the arms' kinematics and the problem.
//!
//! **Collision-free node.** A node is free when the ball of the object's radius about it (the
//! object in *any* orientation, 003's "predetermined orientations" all at once) touches neither
//! a fixed obstacle nor a robot link that the arms do not move (torso, head, pedestal) at the
//! rest configuration, tested with parry on the exact shapes.
//!
//! **Cost (Fig. 6).** The sum of the wrist travels that depend on the exchange point e: the
//! object's (pick wrist) from its initial position to e and the place wrist's from e to the
//! final position, plus the free arms' travels — the place wrist from its rest position to e
//! before the exchange and the pick wrist from e back to its rest position after it:
//! `|c_i − e| + |e − c_f| + |w_place^i − e| + |e − w_pick^i|` (c: the object's centre at q_o^i,
//! q_o^f; w^i: wrist centres at q_r^i). The first two alone are minimal anywhere on the segment
//! c_i–c_f; the rest terms pull the exchange towards the torso, which is what 003 Fig. 7 shows
//! ("the computed exchange configuration brings the object near the robot torso"). The exchange
//! position is the free node of least cost (ties: lowest node index).
//!
//! **Poses.** "The orientation is determined by the selected double grasp directions and the
//! object position wrt. the robot torso": for a double grasp, the rotation R that best maps
//! each grasp's approach direction (palm → finger workspace centre, object frame) onto the
//! direction from its arm's shoulder to e (two-vector Kabsch); then, "the object configuration
//! is sampled following a Gaussian distribution centered on the theoretical best q_o^e":
//! pose 0 is (R, e) itself, the others add a seeded Gaussian position offset (σ = half a grid
//! cell unless set) and a Gaussian rotation vector (σ = `rotation_sigma`).

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use parry3d_f64::query;
use parry3d_f64::shape::{Ball, SharedShape};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{PickPlaceError, PickPlaceProblem};
use crate::collision::{parry_shape, to_parry};
use crate::geometry::{Geometry, Pose};
use crate::grasp::SingleGrasp;
use crate::kinematics::forward;

/// Settings of the exchange grid and of the exchange poses.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ExchangeParams {
    /// Grid nodes per axis (2..=64).
    pub cells: usize,
    /// σ of the Gaussian position offset in m (`None`: half a grid cell).
    pub position_sigma: Option<f64>,
    /// σ of the Gaussian rotation vector in rad.
    pub rotation_sigma: f64,
}

impl Default for ExchangeParams {
    /// 16 nodes per axis, σ = half a cell, 0.15 rad.
    fn default() -> Self {
        ExchangeParams {
            cells: 16,
            position_sigma: None,
            rotation_sigma: 0.15,
        }
    }
}

impl ExchangeParams {
    pub fn validate(&self) -> Result<(), PickPlaceError> {
        let bad = |f: &str, r: String| {
            Err(PickPlaceError::Invalid {
                field: f.into(),
                reason: r,
            })
        };
        if !(2..=64).contains(&self.cells) {
            return bad("cells", format!("must be in 2..=64, got {}", self.cells));
        }
        if let Some(s) = self.position_sigma {
            if !(s.is_finite() && s >= 0.0) {
                return bad("position_sigma", format!("must be finite and ≥ 0, got {s}"));
            }
        }
        if !(self.rotation_sigma.is_finite() && self.rotation_sigma >= 0.0) {
            return bad(
                "rotation_sigma",
                format!("must be finite and ≥ 0, got {}", self.rotation_sigma),
            );
        }
        Ok(())
    }
}

/// One candidate node of the grid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GridNode {
    /// Grid coordinates and world position.
    pub index: [usize; 3],
    pub position: [f64; 3],
    /// The Fig. 6 cost (module docs).
    pub cost: f64,
    /// The object's ball about the node is free (module docs).
    pub free: bool,
}

/// The exchange grid: its candidate nodes (in both reach balls and in front) and the best one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExchangeGrid {
    /// Lower corner of the grid box, node spacing per axis, nodes per axis.
    pub origin: [f64; 3],
    pub spacing: [f64; 3],
    pub cells: usize,
    /// Candidate nodes, in grid order (x fastest).
    pub nodes: Vec<GridNode>,
    /// Index into `nodes` of the exchange position.
    pub best: usize,
    /// The unit "front" direction (module docs) and the shoulders' centres at q_r^i.
    pub front: [f64; 3],
    pub pick_shoulder: [f64; 3],
    pub place_shoulder: [f64; 3],
}

impl ExchangeGrid {
    /// The exchange position e (world).
    pub fn position(&self) -> Vector3<f64> {
        Vector3::from(self.nodes[self.best].position)
    }
}

/// The Fig. 6 cost of exchange point `e` (module docs).
pub fn exchange_cost(p: &PickPlaceProblem, e: &Vector3<f64>) -> f64 {
    let ci = p.centre_at(&p.initial);
    let cf = p.centre_at(&p.final_pose);
    let wp = p.pick.wrist(&p.robot, &p.base, &p.rest);
    let wl = p.place.wrist(&p.robot, &p.base, &p.rest);
    (ci - e).norm() + (e - cf).norm() + (wl - e).norm() + (e - wp).norm()
}

/// Shapes the exchange ball must not touch: the obstacles and the links no arm moves, at q_r^i.
fn fixed_shapes(p: &PickPlaceProblem) -> Vec<(SharedShape, Pose, f64)> {
    let mut out = Vec::new();
    let mut add = |g: &Geometry, at: &Pose| {
        let (s, local) = parry_shape(g);
        // A ball about the shape's origin holding it: the local bounding sphere's radius plus
        // the distance of its centre from the origin.
        let bs = s.compute_local_bounding_sphere();
        let r = bs.radius() + bs.center().length() + 1e-9;
        out.push((s, at * local, r));
    };
    for b in &p.obstacles {
        for g in &b.shapes {
            add(g, &b.pose);
        }
    }
    let r = &p.robot;
    let mut poses = vec![Pose::identity(); r.links.len()];
    forward(r, &p.base, &p.rest, &mut poses);
    let arm_joints: Vec<usize> = p
        .pick
        .arm
        .chain()
        .joints
        .iter()
        .chain(p.place.arm.chain().joints.iter())
        .copied()
        .collect();
    for (l, link) in r.links.iter().enumerate() {
        // Moved by an arm when an arm joint lies on its path to the root.
        let mut moved = false;
        let mut k = l;
        while let Some(j) = r.links[k].parent_joint {
            if arm_joints.contains(&j) {
                moved = true;
                break;
            }
            k = r.joints[j].parent;
        }
        if !moved {
            for g in &link.collision {
                add(g, &poses[l]);
            }
        }
    }
    out
}

fn ball_free(ball: &Ball, at: &Vector3<f64>, shapes: &[(SharedShape, Pose, f64)]) -> bool {
    let bp = Pose::from_parts(
        nalgebra::Translation3::from(*at),
        UnitQuaternion::identity(),
    );
    shapes.iter().all(|(s, pose, r)| {
        if (pose.translation.vector - at).norm() > r + ball.radius + 1e-9 {
            return true;
        }
        !query::intersection_test(&to_parry(&bp), ball, &to_parry(pose), s.as_ref())
            .map(|r| r.intersecting)
            .unwrap_or(true)
    })
}

/// The exchange grid and position of `p` (module docs). Errors when no node lies in both reach
/// balls in front of the torso, or none of them is free.
pub fn exchange_grid(
    p: &PickPlaceProblem,
    params: &ExchangeParams,
) -> Result<ExchangeGrid, PickPlaceError> {
    params.validate()?;
    let (r, b, q) = (&p.robot, &p.base, &p.rest);
    let sp = p.pick.shoulder(r, b, q);
    let sl = p.place.shoulder(r, b, q);
    let (rp, rl) = (p.pick.tcp_reach(), p.place.tcp_reach());
    // Front: horizontal-ish normal of the plane through the shoulders and the vertical, on the
    // objects' side.
    let across = sl - sp;
    let up = Vector3::z();
    let mut front = across.cross(&up);
    if front.norm() < 1e-9 {
        return Err(PickPlaceError::NoExchange(
            "the shoulders are vertically aligned: no front direction".into(),
        ));
    }
    front.normalize_mut();
    let mid = 0.5 * (sp + sl);
    let objects = 0.5 * (p.centre_at(&p.initial) + p.centre_at(&p.final_pose));
    if front.dot(&(objects - mid)) < 0.0 {
        front = -front;
    }
    let lo = (sp.add_scalar(-rp)).sup(&sl.add_scalar(-rl));
    let hi = (sp.add_scalar(rp)).inf(&sl.add_scalar(rl));
    if (0..3).any(|i| hi[i] <= lo[i]) {
        return Err(PickPlaceError::NoExchange(
            "the two arms' reach balls do not intersect".into(),
        ));
    }
    let n = params.cells;
    let spacing = (hi - lo) / (n - 1) as f64;
    let fixed = fixed_shapes(p);
    let ball = Ball::new(p.object_radius);
    let mut nodes = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let e = lo + Vector3::new(i as f64, j as f64, k as f64).component_mul(&spacing);
                if (e - sp).norm() > rp || (e - sl).norm() > rl || front.dot(&(e - mid)) <= 0.0 {
                    continue;
                }
                nodes.push(GridNode {
                    index: [i, j, k],
                    position: e.into(),
                    cost: exchange_cost(p, &e),
                    free: ball_free(&ball, &e, &fixed),
                });
            }
        }
    }
    if nodes.is_empty() {
        return Err(PickPlaceError::NoExchange(
            "no grid node within both arms' reach in front of the torso".into(),
        ));
    }
    let best = nodes
        .iter()
        .enumerate()
        .filter(|(_, n)| n.free)
        .min_by(|a, b| a.1.cost.total_cmp(&b.1.cost).then(a.0.cmp(&b.0)))
        .map(|(i, _)| i)
        .ok_or_else(|| {
            PickPlaceError::NoExchange(format!(
                "none of the {} grid nodes in reach leaves room for the object (radius {:.3} m)",
                nodes.len(),
                p.object_radius
            ))
        })?;
    Ok(ExchangeGrid {
        origin: lo.into(),
        spacing: spacing.into(),
        cells: n,
        nodes,
        best,
        front: front.into(),
        pick_shoulder: sp.into(),
        place_shoulder: sl.into(),
    })
}

/// A grasp's approach direction in the object frame: palm origin → the hand's finger workspace
/// centre (the same direction as [`crate::grasp::double_grasp::approach_score`]).
fn approach(hand: &crate::grasp::Hand, g: &SingleGrasp) -> Vector3<f64> {
    let palm = g.palm_pose();
    let c = hand.workspace_centre(&hand.base_config());
    palm.rotation * c
}

/// The rotation R minimising Σ |R aᵢ − dᵢ|² (Kabsch, proper rotation).
fn kabsch(pairs: &[(Vector3<f64>, Vector3<f64>)]) -> UnitQuaternion<f64> {
    let mut h = Matrix3::zeros();
    for (a, d) in pairs {
        if let (Some(a), Some(d)) = (a.try_normalize(1e-12), d.try_normalize(1e-12)) {
            h += d * a.transpose();
        }
    }
    let svd = h.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return UnitQuaternion::identity();
    };
    let d = (u * v_t).determinant().signum();
    let m =
        u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, if d == 0.0 { 1.0 } else { d })) * v_t;
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
}

/// Standard normal draw (Box–Muller).
pub(crate) fn gaussian<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    let u1: f64 = rng.random::<f64>().max(f64::MIN_POSITIVE);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// `count` exchange object poses for the double grasp (`pick`, `place`) around the grid's
/// exchange position (module docs): pose 0 is the mean, seeded by `seed`.
pub fn exchange_poses(
    p: &PickPlaceProblem,
    grid: &ExchangeGrid,
    pick: &SingleGrasp,
    place: &SingleGrasp,
    params: &ExchangeParams,
    count: usize,
    seed: u64,
) -> Vec<Pose> {
    let e = grid.position();
    let sp = Vector3::from(grid.pick_shoulder);
    let sl = Vector3::from(grid.place_shoulder);
    let rot = kabsch(&[
        (approach(&p.pick.hand, pick), e - sp),
        (approach(&p.place.hand, place), e - sl),
    ]);
    let sigma_p = params
        .position_sigma
        .unwrap_or_else(|| 0.5 * grid.spacing.iter().copied().fold(f64::INFINITY, f64::min));
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count)
        .map(|k| {
            let (dp, dr) = if k == 0 {
                (Vector3::zeros(), Vector3::zeros())
            } else {
                let mut g = || gaussian(&mut rng);
                let dp = Vector3::new(g(), g(), g()) * sigma_p;
                let dr = Vector3::new(g(), g(), g()) * params.rotation_sigma;
                (dp, dr)
            };
            let r = UnitQuaternion::from_scaled_axis(dr) * rot;
            // The object's centre goes to e + dp.
            let t = e + dp - r * p.object_centre;
            Pose::from_parts(nalgebra::Translation3::from(t), r)
        })
        .collect()
}
