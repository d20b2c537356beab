//! The hand's approach: the arm brings the pre-shaped hand the last centimetres to its grasp
//! along the hand's approach axis, certified against the object's true geometry (003 §V-B
//! plans the arms between key configurations and leaves how a hand comes to its grasp open).
//!
//! A grasp configuration puts the pre-shaped hand within millimetres of the object
//! ([`super::fingers`]). The roadmap's straight certified motions and the RRT repair prove
//! motions with the planners' conservative model of the object ([`crate::collision::FastChecker`],
//! whose cover of a mesh may protrude beyond it by centimetres), so a query that ends there
//! must creep out of that gap in tiny proven steps. Here the query ends instead at the
//! *approach configuration*: the same hand pre-shape with the palm backed off along an approach
//! direction ([`approach_configuration`]), and one straight joint-space motion brings it in:
//!
//! - against the object the motion is proven by [`ApproachCertificate`], on the object's true
//!   geometry ([`GraspObject::distance`]): no link of the hand touches it anywhere along the
//!   continuous motion (no contact allowance at all);
//! - against everything else (scene, the robot itself, the other hand) by
//!   [`crate::collision::FastChecker::motion_certified`] in the query's world with only the
//!   hand–object pairs left out, as for every other motion.
//!
//! **The certificate** is the finger certificate's ([`super::fingers::FingerCertificate`]) for
//! any robot motion: a hand link's points travel at most `L_l = Σ_v |b_v − a_v| · w_lv` along
//! the segment ([`crate::kinematics::FkModel::speed_bounds`] of the link's bounding ball over
//! every joint from the robot's root; Schwarzer, Saha & Latombe 2005), and a run `[t0, t1]` is
//! free when `d(t0) + d(t1) > L_l · (t1 − t0)`, `d` the exact distance from the object; runs
//! not proven are halved, within [`super::fingers::MAX_EVALUATIONS`] evaluations.

use nalgebra::{Translation3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::fingers::{link_speed, FingerCertificate, FingerVerdict, MAX_EVALUATIONS};
use super::{ArmHand, PickPlaceProblem};
use crate::geometry::Pose;
use crate::grasp::GraspObject;
use crate::kinematics::{link_pose, FkModel, SolutionOrder};

/// Shortest travel (m) of a run the certificate still halves.
const MIN_RUN_TRAVEL: f64 = 1e-9;

/// Back-off distances of the approach configuration (m), farthest first: the query's end then
/// lies beyond the conservative object model's protrusion (module docs).
pub const APPROACH_DISTANCES: [f64; 4] = [0.08, 0.06, 0.04, 0.025];

/// Largest change (rad) of an arm joint between the approach and the grasp configuration: the
/// same IK branch, a short motion.
const MAX_JOINT_CHANGE: f64 = 0.6;

/// Swivel angles the S-R-S IK enumerates for an approach configuration.
const PSI_STEPS: usize = 36;

/// The certificate of a hand's straight robot motions against an object that does not move
/// relative to the robot's root during them (module docs).
#[derive(Debug, Clone)]
pub struct ApproachCertificate<'a> {
    ah: &'a ArmHand,
    object: &'a GraspObject,
    /// Root frame → object frame.
    root_to_object: Pose,
    /// `(link, speed bounds)` of each hand link with geometry.
    links: Vec<(usize, Vec<(usize, f64)>)>,
}

impl<'a> ApproachCertificate<'a> {
    /// The certificate of `ah`'s hand links against `object` at `object_in_root` (the object's
    /// frame in the robot's root frame).
    pub fn new(
        ah: &'a ArmHand,
        object: &'a GraspObject,
        object_in_root: &Pose,
    ) -> ApproachCertificate<'a> {
        let robot = &ah.hand.robot;
        let fk = FkModel::new(robot);
        let mut links = Vec::new();
        for &l in &ah.links {
            let geoms = &robot.links[l].collision;
            if geoms.is_empty() || !ah.hand.shapes.contains_key(&l) {
                continue;
            }
            let all: Vec<usize> = (0..robot.dof()).collect();
            links.push((l, link_speed(&fk, robot, l, &all)));
        }
        ApproachCertificate {
            ah,
            object,
            root_to_object: object_in_root.inverse(),
            links,
        }
    }

    /// Exact distance of hand link `l` at robot configuration `q` from the object.
    fn distance(&self, l: usize, q: &[f64]) -> f64 {
        let h = &self.ah.hand;
        let pose = self.root_to_object * link_pose(&h.robot, q, l);
        h.shapes.get(&l).map_or(f64::INFINITY, |shapes| {
            shapes
                .iter()
                .map(|(s, local)| self.object.distance(s, &(pose * local)))
                .fold(f64::INFINITY, f64::min)
        })
    }

    /// The smallest exact distance of the hand's links from the object at `q`.
    pub fn clearance(&self, q: &[f64]) -> f64 {
        self.links
            .iter()
            .map(|(l, _)| self.distance(*l, q))
            .fold(f64::INFINITY, f64::min)
    }

    /// Proves the straight robot motion `a → b` free of the object for every hand link
    /// (module docs).
    pub fn certify(&self, a: &[f64], b: &[f64]) -> FingerVerdict {
        let dof = self.ah.hand.robot.dof();
        if a.len() != dof || b.len() != dof || a.iter().chain(b).any(|x| !x.is_finite()) {
            return FingerVerdict::NotFingers;
        }
        let at = |t: f64| -> Vec<f64> { a.iter().zip(b).map(|(x, y)| x + t * (y - x)).collect() };
        let name = |l: usize| self.ah.hand.robot.links[l].name.clone();
        let mut evals = 0usize;
        for (l, speed) in &self.links {
            let l = *l;
            let travel: f64 = speed.iter().map(|&(v, w)| (b[v] - a[v]).abs() * w).sum();
            let (d0, d1) = (self.distance(l, a), self.distance(l, b));
            evals += 2;
            for (t, d) in [(0.0, d0), (1.0, d1)] {
                if d <= 0.0 {
                    return FingerVerdict::Collides { link: name(l), t };
                }
            }
            if travel == 0.0 {
                continue;
            }
            if !travel.is_finite() {
                return FingerVerdict::Unproven { link: name(l) };
            }
            let mut stack = vec![(0.0f64, 1.0f64, d0, d1)];
            while let Some((t0, t1, d0, d1)) = stack.pop() {
                let run = travel * (t1 - t0);
                if d0 + d1 > run {
                    continue;
                }
                if run < MIN_RUN_TRAVEL || evals >= MAX_EVALUATIONS {
                    return FingerVerdict::Unproven { link: name(l) };
                }
                let tm = (t0 + t1) / 2.0;
                let dm = self.distance(l, &at(tm));
                evals += 1;
                if dm <= 0.0 {
                    return FingerVerdict::Collides {
                        link: name(l),
                        t: tm,
                    };
                }
                stack.push((tm, t1, dm, d1));
                stack.push((t0, tm, d0, dm));
            }
        }
        FingerVerdict::Certified
    }
}

/// The object certificate of a phase that moves a hand near the object it does not hold, or
/// on the object it grasps.
#[derive(Debug, Clone)]
pub enum ObjectCertificate<'a> {
    /// Closing or opening the hand ([`super::fingers`]).
    Fingers(FingerCertificate<'a>),
    /// The arm's approach or departure (module docs).
    Approach(ApproachCertificate<'a>),
}

impl ObjectCertificate<'_> {
    pub fn certify(&self, a: &[f64], b: &[f64]) -> FingerVerdict {
        match self {
            ObjectCertificate::Fingers(c) => c.certify(a, b),
            ObjectCertificate::Approach(c) => c.certify(a, b),
        }
    }
}

/// Directions (root frame, unit) in which `ah`'s palm backs off from the object at `q`
/// (`object_centre` in the root frame), best first: out of the hand's opening (from the centre of the fingers' workspaces back through the
/// palm, 003 §IV-A-1's grasp-frame centre), away from the object's centre, and straight up.
pub fn approach_directions(
    p: &PickPlaceProblem,
    ah: &ArmHand,
    q: &[f64],
    object_centre: &Vector3<f64>,
) -> Vec<Vector3<f64>> {
    let palm = link_pose(&p.robot, q, ah.hand.palm);
    let opening = palm.rotation * ah.hand.workspace_centre(q);
    let away = palm.translation.vector - object_centre;
    let up = p.base.rotation.inverse() * Vector3::z();
    let mut out: Vec<Vector3<f64>> = Vec::new();
    for d in [-opening, away, up] {
        if let Some(u) = d.try_normalize(1e-9) {
            if out.iter().all(|o| o.dot(&u) < 0.999) {
                out.push(u);
            }
        }
    }
    out
}

/// The configuration of `q` with `ah`'s palm moved `distance` along `dir` (root frame), the
/// rest of the robot still: the S-R-S IK's solution nearest to `q`'s arm, when every arm joint
/// moves less than [`MAX_JOINT_CHANGE`] and stays within its limits.
pub fn approach_configuration(
    p: &PickPlaceProblem,
    ah: &ArmHand,
    q: &[f64],
    dir: &Vector3<f64>,
    distance: f64,
) -> Option<Vec<f64>> {
    let palm = link_pose(&p.robot, q, ah.hand.palm);
    let moved = Translation3::from(dir * distance) * palm;
    let tcp_root = moved * ah.tip_in_palm;
    let tcp_world = p.base * tcp_root;
    let target = ah.base_pose(&p.robot, &p.base, q).inverse() * tcp_world;
    let now = ah.arm.from_config(q);
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let sols = ah
        .arm
        .solve_enumerate(&target, PSI_STEPS, SolutionOrder::NearestTo(now), &mut rng);
    let sol = sols.first()?;
    if sol
        .iter()
        .zip(&now)
        .any(|(a, b)| (a - b).abs() > MAX_JOINT_CHANGE)
    {
        return None;
    }
    let mut out = q.to_vec();
    ah.arm.to_config(sol, &mut out);
    super::within_limits(p, &out).then_some(out)
}
