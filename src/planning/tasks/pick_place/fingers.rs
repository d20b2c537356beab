//! Closing and opening a hand on the object, certified against the object's true geometry
//! (paper 003 §IV-A gives the grasp — palm pose, finger values, contacts — but not how a hand
//! comes to it; 003 §V-B plans the arms only).
//!
//! **What is guaranteed.** While a hand closes on the object (grasp) or opens from it
//! (release), the palm stays still relative to the object and only the hand's variables move.
//! Along the whole continuous motion every link of the hand is free of the object — the true
//! mesh, its inside included ([`GraspObject::distance`]) — except the grasp's *contact links*
//! (the fingertips the grasp list placed on the surface), and a contact link may touch the
//! object only while its *contact point* (the point of the link at the grasp's contact) lies
//! within the list's contact tolerance ([`crate::grasp::GraspListParams::contact_tolerance`],
//! 1 mm by default) of that contact. The rest of the world (scene, the robot itself, the other
//! hand) is proven by [`crate::collision::FastChecker::motion_certified`] as for every other
//! motion.
//!
//! **How a hand closes** ([`closing_motions`]): from the grasp, each contact finger's contact
//! point *retreats* along the contact's outward normal by ¼, ½, 1, 2 and 3 fingertip radii
//! ([`approach`]: Newton steps of the point on the finger's three IK variables), as far as each
//! step is certified; a *pre-shape* that clears the object opens the fingers from a retreat
//! configuration ([`super::hands::finger_preshape`], finger by finger or all together). The
//! closing motion is pre-shape → retreat configurations → grasp, straight joint-space segments;
//! opening is the same path reversed. Moving the contact point itself along the normal keeps
//! the fingertip's first touch at its contact (a fingertip frame sent along the normal turns the
//! link, and its pad then meets the surface early, up to a millimetre off). A grasp none of
//! whose candidate motions is certified is refused (the task tries its other grasps and double
//! grasps).
//!
//! **The certificate** ([`FingerCertificate::certify`]): for a straight motion `a → b` of the
//! hand variables, no point of link `l` moves farther than `L_l = Σ_v |b_v − a_v| · w_lv`
//! ([`crate::kinematics::FkModel::speed_bounds`]; Schwarzer, Saha & Latombe 2005). A run
//! `[t0, t1]` is free when `d(t0) + d(t1) > L_l · (t1 − t0)`, `d` the exact distance from the
//! object; for a contact link a run is also accepted when its contact point stays within the
//! tolerance of the contact, bounded by `(e(t0) + e(t1) + L_c · (t1 − t0)) / 2` with `e(t)` the
//! point's distance from the contact and `L_c` the point's own travel bound. Runs neither proves
//! are halved; a state where a link touches outside that allowance is a collision; a run shorter
//! than 1e-9 m of travel, or more than [`MAX_EVALUATIONS`] evaluations, is unproven (refused).

use nalgebra::{Matrix3, Point3, Vector3};

use super::hands::{finger_preshape, fingers_of, with_fingers};
use super::ArmHand;
use crate::geometry::Pose;
use crate::grasp::{GraspList, GraspObject, SingleGrasp};
use crate::kinematics::FkModel;

/// A hand motion as hand-variable values, pre-shape first, grasp last.
pub type FingerPath = Vec<Vec<f64>>;

/// The grasps of a list a hand can close on ([`super::hands::closable`]): the list of them,
/// their indices in the full list and each one's candidate closing motions.
pub type Closable = (GraspList, Vec<usize>, Vec<Vec<FingerPath>>);

/// Most distance evaluations of one certified finger motion.
pub const MAX_EVALUATIONS: usize = 20_000;

/// Shortest travel (m) of a run the certificate still halves.
const MIN_RUN_TRAVEL: f64 = 1e-9;

/// How a certified motion check ended.
#[derive(Debug, Clone, PartialEq)]
pub enum FingerVerdict {
    /// Proven: free, contact links touching only within the tolerance of their grasp pose.
    Certified,
    /// A link touches the object outside the allowance at motion parameter `t`.
    Collides { link: String, t: f64 },
    /// Neither proven nor refuted within the bounds (module docs).
    Unproven { link: String },
    /// Not a finger motion: a variable outside the hand moves, or the values do not fit.
    NotFingers,
}

/// One hand link as the certificate sees it.
#[derive(Debug, Clone)]
struct LinkModel {
    link: usize,
    /// `(variable, w)`: speed bounds of the link's ball (module docs).
    speed: Vec<(usize, f64)>,
    /// A contact link: its contact point (link frame), that point's place at the grasp (object
    /// frame) and its speed bounds.
    contact: Option<ContactModel>,
}

#[derive(Debug, Clone)]
struct ContactModel {
    local: Point3<f64>,
    at_grasp: Point3<f64>,
    speed: Vec<(usize, f64)>,
}

/// The certificate of the finger motions of one hand on one grasp (module docs).
#[derive(Debug, Clone)]
pub struct FingerCertificate<'a> {
    ah: &'a ArmHand,
    object: &'a GraspObject,
    /// Palm pose in the object frame.
    palm: Pose,
    tol: f64,
    links: Vec<LinkModel>,
}

impl<'a> FingerCertificate<'a> {
    /// The certificate for `ah` holding `object` by `grasp` (palm pose and contacts), contact
    /// tolerance `tol`; `q_grasp` is any robot configuration with the hand at the grasp's
    /// finger values.
    pub fn new(
        ah: &'a ArmHand,
        object: &'a GraspObject,
        grasp: &SingleGrasp,
        q_grasp: &[f64],
        tol: f64,
    ) -> FingerCertificate<'a> {
        let h = &ah.hand;
        let robot = &h.robot;
        let fk = FkModel::new(robot);
        let palm = grasp.palm_pose();
        let mut links = Vec::new();
        for f in &h.fingers {
            for &l in &f.links {
                let geoms = &robot.links[l].collision;
                if geoms.is_empty() {
                    continue;
                }
                let (rep, off) = fk.mount(l);
                let speed = link_speed(&fk, robot, l, &h.vars);
                let contact = grasp
                    .contacts
                    .iter()
                    .find(|c| {
                        h.fingers
                            .iter()
                            .any(|f| f.group == c.finger && f.contact_link == l)
                    })
                    .map(|c| {
                        let at_grasp = Point3::from(Vector3::from(c.point));
                        let pose = palm * h.link_in_palm(l, q_grasp);
                        let local = pose.inverse() * at_grasp;
                        let in_rep = off.map_or(local.coords, |o| o.transform_point(&local.coords));
                        let speed =
                            fk.speed_bounds(robot, rep, &in_rep, 0.0)
                                .unwrap_or_else(|| {
                                    h.vars.iter().map(|&v| (v, f64::INFINITY)).collect()
                                });
                        ContactModel {
                            local,
                            at_grasp,
                            speed,
                        }
                    });
                links.push(LinkModel {
                    link: l,
                    speed,
                    contact,
                });
            }
        }
        FingerCertificate {
            ah,
            object,
            palm,
            tol,
            links,
        }
    }

    /// Exact distance of link `lm` at configuration `q` from the object, and (contact links)
    /// the bound of its points' distance from their grasp positions.
    fn eval(&self, lm: &LinkModel, q: &[f64]) -> (f64, f64) {
        let h = &self.ah.hand;
        let pose = self.palm * h.link_in_palm(lm.link, q);
        let d = h.shapes.get(&lm.link).map_or(f64::INFINITY, |shapes| {
            shapes
                .iter()
                .map(|(s, local)| self.object.distance(s, &(pose * local)))
                .fold(f64::INFINITY, f64::min)
        });
        let e = lm
            .contact
            .as_ref()
            .map_or(f64::INFINITY, |c| (pose * c.local - c.at_grasp).norm());
        (d, e)
    }

    /// Proves the straight motion `a → b` of the hand (module docs).
    pub fn certify(&self, a: &[f64], b: &[f64]) -> FingerVerdict {
        let vars = &self.ah.hand.vars;
        if a.len() != b.len()
            || a.iter().chain(b).any(|x| !x.is_finite())
            || (0..a.len()).any(|i| a[i] != b[i] && !vars.contains(&i))
        {
            return FingerVerdict::NotFingers;
        }
        let at = |t: f64| -> Vec<f64> { a.iter().zip(b).map(|(x, y)| x + t * (y - x)).collect() };
        let name = |lm: &LinkModel| self.ah.hand.robot.links[lm.link].name.clone();
        let mut evals = 0usize;
        for lm in &self.links {
            let travel: f64 = lm.speed.iter().map(|&(v, w)| (b[v] - a[v]).abs() * w).sum();
            let contact_travel: f64 = lm.contact.as_ref().map_or(f64::INFINITY, |c| {
                c.speed.iter().map(|&(v, w)| (b[v] - a[v]).abs() * w).sum()
            });
            let allowed = |(d, e): (f64, f64)| d > 0.0 || e <= self.tol;
            let e0 = self.eval(lm, a);
            let e1 = self.eval(lm, b);
            evals += 2;
            for (t, e) in [(0.0, e0), (1.0, e1)] {
                if !allowed(e) {
                    return FingerVerdict::Collides { link: name(lm), t };
                }
            }
            if travel == 0.0 {
                continue;
            }
            if !travel.is_finite() {
                return FingerVerdict::Unproven { link: name(lm) };
            }
            let mut stack = vec![(0.0f64, 1.0f64, e0, e1)];
            while let Some((t0, t1, (d0, c0), (d1, c1))) = stack.pop() {
                let run = travel * (t1 - t0);
                if d0 + d1 > run || (c0 + c1 + contact_travel * (t1 - t0)) / 2.0 <= self.tol {
                    continue;
                }
                if run < MIN_RUN_TRAVEL || evals >= MAX_EVALUATIONS {
                    return FingerVerdict::Unproven { link: name(lm) };
                }
                let tm = (t0 + t1) / 2.0;
                let em = self.eval(lm, &at(tm));
                evals += 1;
                if !allowed(em) {
                    return FingerVerdict::Collides {
                        link: name(lm),
                        t: tm,
                    };
                }
                stack.push((tm, t1, em, (d1, c1)));
                stack.push((t0, tm, (d0, c0), em));
            }
        }
        FingerVerdict::Certified
    }

    /// The smallest exact distance of the hand's finger links from the object at `q`.
    pub fn clearance(&self, q: &[f64]) -> f64 {
        self.links
            .iter()
            .map(|lm| self.eval(lm, q).0)
            .fold(f64::INFINITY, f64::min)
    }

    /// True when every straight segment of `path` is certified.
    pub fn path_certified(&self, path: &[Vec<f64>]) -> bool {
        path.windows(2)
            .all(|w| self.certify(&w[0], &w[1]) == FingerVerdict::Certified)
    }
}

/// Speed bounds `(variable, w)` of the ball around link `l`'s collision geometry
/// ([`FkModel::speed_bounds`]); a link whose speed cannot be bounded gets an infinite bound on
/// each of `vars` (never proven).
pub(super) fn link_speed(
    fk: &FkModel,
    robot: &crate::model::Robot,
    l: usize,
    vars: &[usize],
) -> Vec<(usize, f64)> {
    let (rep, off) = fk.mount(l);
    let balls: Vec<(Vector3<f64>, f64)> = robot.links[l]
        .collision
        .iter()
        .map(|g| (g.origin.translation.vector, g.shape.bounding_radius()))
        .collect();
    let n = balls.len().max(1) as f64;
    let centre = balls.iter().fold(Vector3::zeros(), |s, (c, _)| s + c) / n;
    let radius = balls
        .iter()
        .map(|(c, r)| (c - centre).norm() + r)
        .fold(0.0, f64::max);
    let in_rep = off.map_or(centre, |o| o.transform_point(&centre));
    fk.speed_bounds(robot, rep, &in_rep, radius)
        .unwrap_or_else(|| vars.iter().map(|&v| (v, f64::INFINITY)).collect())
}

/// Back-off distances of the retreat from the contacts, as multiples of the finger's tip
/// radius, nearest first.
const RETREAT_TIPS: [f64; 5] = [0.25, 0.5, 1.0, 2.0, 3.0];

/// The configuration of grasp state `q` with each contact finger's contact point (the point
/// of its contact link at the grasp's contact) backed off from the contact along the outward
/// normal by `k` tip radii (module docs): Newton steps on the finger's three IK variables
/// (the point's 3 × 3 Jacobian by central differences), from `from`, within the joint limits.
/// Moving the contact point itself along the normal (not the fingertip frame) keeps the
/// fingertip's first touch on the way in at its contact. `None` when some finger's point stays
/// farther than a third of the back-off from its target.
pub fn approach(
    ah: &ArmHand,
    grasp: &SingleGrasp,
    q: &[f64],
    from: &[f64],
    k: f64,
) -> Option<Vec<f64>> {
    let h = &ah.hand;
    let palm_inv = grasp.palm_pose().inverse();
    let mut out = from.to_vec();
    for c in &grasp.contacts {
        let f = h.fingers.iter().find(|f| f.group == c.finger)?;
        // The contact point in the contact link's frame and its target, palm frame.
        let at = palm_inv * Point3::from(Vector3::from(c.point));
        let local = h.link_in_palm(f.contact_link, q).inverse() * at;
        let n_out = palm_inv.rotation * -Vector3::from(c.normal);
        let back = k * f.tip_radius;
        let target = at + n_out * back;
        let point = |x: &[f64]| h.link_in_palm(f.contact_link, x) * local;
        let mut err = f64::INFINITY;
        for _ in 0..8 {
            let r = target - point(&out);
            err = r.norm();
            if err < 1e-6 {
                break;
            }
            let mut jac = Matrix3::zeros();
            for (col, &v) in f.ik_vars.iter().enumerate() {
                let step = 1e-6;
                let mut qp = out.clone();
                let mut qm = out.clone();
                qp[v] += step;
                qm[v] -= step;
                jac.set_column(col, &((point(&qp) - point(&qm)) / (2.0 * step)));
            }
            let dq = jac.svd(true, true).solve(&r, 1e-9).ok()?;
            for (col, &v) in f.ik_vars.iter().enumerate() {
                let l = h.robot.var_limits(v);
                let x = out[v] + dq[col];
                out[v] = if l.bounded {
                    x.clamp(l.lower, l.upper)
                } else {
                    x
                };
            }
        }
        err = err.min((target - point(&out)).norm());
        if err.is_nan() || err >= back / 3.0 {
            return None;
        }
    }
    Some(out)
}

/// Candidate closing motions of `ah` onto `grasp` (module docs), each certified against the
/// object alone ([`FingerCertificate`]): hand-variable values from a pre-shape through the
/// retreat configurations ([`RETREAT_TIPS`], each certified to the next) to the grasp, best
/// first (the farthest retreat first), at most `max` of them. `rest` supplies the other
/// variables (the certificate depends on the hand's variables only); `fractions` are the
/// pre-shape fractions; `free` says whether a robot configuration (a pre-shape) is free of
/// the robot itself (fingers against each other and the palm).
#[allow(clippy::too_many_arguments)]
pub fn closing_motions(
    ah: &ArmHand,
    object: &GraspObject,
    grasp: &SingleGrasp,
    rest: &[f64],
    tol: f64,
    fractions: &[f64],
    max: usize,
    free: &mut dyn FnMut(&[f64]) -> bool,
) -> Vec<Vec<Vec<f64>>> {
    let q = with_fingers(ah, rest, &grasp.config);
    let cert = FingerCertificate::new(ah, object, grasp, &q, tol);
    let palm = grasp.palm_pose();
    // The retreat: grasp, then ever farther from the contacts while each step is certified.
    let mut retreat = vec![q.clone()];
    for &k in &RETREAT_TIPS {
        let prev = retreat.last().cloned().unwrap_or_else(|| q.clone());
        match approach(ah, grasp, &q, &prev, k) {
            Some(a) if cert.certify(&a, &prev) == FingerVerdict::Certified => retreat.push(a),
            _ => break,
        }
    }
    // Pre-shapes opened from every retreat configuration (finger by finger, towards the joint
    // limits or the stretched values, or all fingers together), free of the robot itself and
    // of the object; each may join any retreat configuration, the farthest first.
    let open = fingers_of(ah, rest);
    let mut pres: Vec<Vec<f64>> = Vec::new();
    for qa in retreat.iter().rev() {
        let closed = fingers_of(ah, qa);
        let uniform = fractions.iter().map(|&s| {
            let f: Vec<f64> = closed
                .iter()
                .zip(&open)
                .map(|(c, o)| c + s * (o - c))
                .collect();
            with_fingers(ah, qa, &f)
        });
        for p in [true, false]
            .into_iter()
            .filter_map(|ext| finger_preshape(ah, object, &palm, qa, fractions, ext))
            .chain(uniform)
        {
            if !pres.contains(&p) && free(&p) {
                pres.push(p);
            }
        }
    }
    let mut out: Vec<(f64, Vec<Vec<f64>>)> = Vec::new();
    'levels: for j in (0..retreat.len()).rev() {
        for p in &pres {
            if out.len() >= max {
                break 'levels;
            }
            if cert.certify(p, &retreat[j]) != FingerVerdict::Certified {
                continue;
            }
            let mut path = vec![fingers_of(ah, p)];
            path.extend(retreat[..=j].iter().rev().map(|r| fingers_of(ah, r)));
            path.dedup();
            if !out.iter().any(|(_, o)| o == &path) {
                out.push((cert.clearance(p), path));
            }
        }
    }
    // The pre-shape farthest from the object first: the arm's query ends there, and the
    // planners' conservative model of the object needs room to prove it free.
    out.sort_by(|a, b| b.0.total_cmp(&a.0));
    out.into_iter().map(|(_, p)| p).collect()
}
