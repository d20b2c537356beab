//! The hands of the pick-and-place task (paper 003 §V-B; 003 does not say how a hand comes to
//! its grasp): a hand's finger values in a world configuration, the finger-wise pre-shape of a
//! grasp, and the grasps of a list a hand can close on with a certified motion.

use super::ArmHand;
use crate::geometry::Pose;
use crate::grasp::{GraspList, GraspObject};

/// The values of `ah`'s hand variables in world configuration `q`.
pub(super) fn fingers_of(ah: &ArmHand, q: &[f64]) -> Vec<f64> {
    ah.hand.vars.iter().map(|&v| q[v]).collect()
}

/// `q` with `ah`'s hand variables set to `values`.
pub(super) fn with_fingers(ah: &ArmHand, q: &[f64], values: &[f64]) -> Vec<f64> {
    let mut q = q.to_vec();
    for (&v, &x) in ah.hand.vars.iter().zip(values) {
        q[v] = x;
    }
    q
}

/// The finger-wise pre-shape of a grasp (module docs): `q` with each finger of `ah`'s hand
/// opened from its values in `q` by the first of `fractions` at which that finger's links are
/// free of `object`, the palm at `palm` in the object frame. Opened towards the finger's
/// stretched values ([`crate::grasp::Finger::rest`]), or with `extended` towards the joint
/// limits beyond them (each IK variable to the limit on the side of its stretched value from
/// mid-range; one whose stretched value is mid-range, a spread, to that value): the most
/// clearance on the palm side, what the fast checker's conservative model of the object needs.
/// `None` when some finger has no such fraction: the grasp wraps the object so that the hand
/// cannot come to it open (a finger hooked around a leg).
pub fn finger_preshape(
    ah: &ArmHand,
    object: &GraspObject,
    palm: &Pose,
    q: &[f64],
    fractions: &[f64],
    extended: bool,
) -> Option<Vec<f64>> {
    let h = &ah.hand;
    let mut out = q.to_vec();
    for f in &h.fingers {
        let target: Vec<f64> = (0..f.ik_vars.len().min(3))
            .map(|k| {
                let (v, r, m) = (f.ik_vars[k], f.rest[k], f.mid[k]);
                let l = h.robot.var_limits(v);
                match (extended, (r - m).abs() > 1e-9) {
                    (true, true) if r < m => l.lower,
                    (true, true) => l.upper,
                    (_, _) => r,
                }
            })
            .collect();
        let opened = fractions.iter().find_map(|&s| {
            let mut qq = out.clone();
            for (&v, &r) in f.ik_vars.iter().zip(&target) {
                // Clamped: `q + 1 · (limit − q)` may round past the limit.
                let l = h.robot.var_limits(v);
                let x = q[v] + s * (r - q[v]);
                qq[v] = if l.bounded {
                    x.clamp(l.lower, l.upper)
                } else {
                    x
                };
            }
            let hit = f.links.iter().any(|&l| {
                let lp = palm * h.link_in_palm(l, &qq);
                h.shapes.get(&l).is_some_and(|shapes| {
                    shapes
                        .iter()
                        .any(|(sh, local)| object.hits(sh, &(lp * local), f64::INFINITY))
                })
            });
            (!hit).then_some(qq)
        })?;
        out = opened;
    }
    Some(out)
}

/// The grasps of `list` the hand can close on with a certified motion
/// ([`super::fingers::closing_motions`], at most `max` candidates each): a copy of the list with
/// only those, their indices in `list` and their candidate motions (hand-variable values).
pub(super) fn closable(
    ah: &ArmHand,
    object: &GraspObject,
    list: &GraspList,
    rest: &[f64],
    fractions: &[f64],
    max: usize,
) -> super::fingers::Closable {
    use crate::collision::{CollisionChecker, CollisionWorld, ExactChecker};
    use rayon::prelude::*;
    let tol = list.params.contact_tolerance;
    // The robot alone: a pre-shape must not turn the fingers into each other or the palm.
    let alone = CollisionWorld::single(ah.hand.robot.clone(), Pose::identity());
    let motions: Vec<Vec<Vec<Vec<f64>>>> = list
        .grasps
        .par_iter()
        .map_init(
            || ExactChecker::new(&alone),
            |x, g| {
                let mut free = |q: &[f64]| x.is_free(q);
                super::fingers::closing_motions(ah, object, g, rest, tol, fractions, max, &mut free)
            },
        )
        .collect();
    let idx: Vec<usize> = (0..list.grasps.len())
        .filter(|&i| !motions[i].is_empty())
        .collect();
    let mut out = list.clone();
    out.grasps = idx.iter().map(|&i| list.grasps[i].clone()).collect();
    let motions = idx.iter().map(|&i| motions[i].clone()).collect();
    (out, idx, motions)
}
