//! Randomized dual-arm IK (paper 000 = Vahrenkamp et al. 2009, §III).
//!
//! (a) *Flexible grasp selection* (§III-A/B, 23-D: 6-D object pose + 3 hip + 2 × 7 arm joints):
//! each try samples an object pose (position uniform in a box, orientation uniform) and the free
//! (hip) joints; with reachability maps the arm IKs are called only if at least one left and one
//! right grasp are above the threshold (§III-B), best first. With some probability a gradient
//! ascent in reachability space (§II-C) first moves the object pose toward higher
//! min(best left, best right) entries while the object stays collision-free.
//!
//! (b) *Object already grasped with the left hand* (17-D: hip + both arms): the object is
//! rigidly attached to the left TCP by the held grasp, so it moves with the hand; the solver is
//! (a) restricted to that single left grasp ([`DualArmIk::solve_held`]), which is why it needs
//! more tries than (a) (000 Table 2).
//!
//! Collision checking comes in through closures (this module knows nothing of collision).

use std::sync::Arc;

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use rand::Rng;

use super::randomized::{
    gradient_ascent, try_arm, ArmChain, IkCounters, RandomizedIkError, RandomizedIkSettings,
    ReachabilityMap,
};
use crate::geometry::Pose;
use crate::model::Robot;

/// A dual-arm query with a free object pose.
#[derive(Debug, Clone, Copy)]
pub struct DualArmQuery<'a> {
    /// World pose of the robot's root link.
    pub robot_base: Pose,
    /// Box (world frame) the object position is sampled in: lower and upper corner.
    pub region: ([f64; 3], [f64; 3]),
    /// Left-hand TCP poses in the object frame.
    pub left_grasps: &'a [Pose],
    /// Right-hand TCP poses in the object frame.
    pub right_grasps: &'a [Pose],
    /// Full robot configuration giving every joint outside the chains.
    pub start: &'a [f64],
}

/// A dual-arm answer.
#[derive(Debug, Clone, PartialEq)]
pub struct DualArmSolution {
    pub config: Vec<f64>,
    /// World pose of the object.
    pub object_pose: Pose,
    /// Index into the query's left grasps.
    pub left_grasp: usize,
    /// Index into the query's right grasps.
    pub right_grasp: usize,
    pub counters: IkCounters,
}

/// Randomized dual-arm IK for two "free joints + S-R-S arm" chains sharing their free joints
/// (`torso_left_arm` and `torso_right_arm` of armar: hip + left arm + right arm).
#[derive(Debug, Clone)]
pub struct DualArmIk {
    robot: Arc<Robot>,
    left: ArmChain,
    right: ArmChain,
    free_vars: Vec<usize>,
}

/// Orientation drawn uniformly from SO(3) (Shoemake).
pub fn random_rotation<R: Rng + ?Sized>(rng: &mut R) -> UnitQuaternion<f64> {
    let (u1, u2, u3): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
    let tau = std::f64::consts::TAU;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    let (s2, c2) = crate::geometry::sin_cos(tau * u2);
    let (s3, c3) = crate::geometry::sin_cos(tau * u3);
    UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(b * c3, a * s2, a * c2, b * s3))
}

impl DualArmIk {
    /// The solver for two chain groups (e.g. `torso_left_arm`, `torso_right_arm`).
    pub fn new(
        robot: Arc<Robot>,
        left_group: &str,
        right_group: &str,
    ) -> Result<DualArmIk, RandomizedIkError> {
        let left = ArmChain::new(&robot, left_group)?;
        let right = ArmChain::new(&robot, right_group)?;
        if left.arm.vars().iter().any(|v| right.arm.vars().contains(v)) {
            return Err(RandomizedIkError::Incompatible {
                a: left_group.into(),
                b: right_group.into(),
                reason: "the two arms share joints".into(),
            });
        }
        let mut free_vars = left.free_vars.clone();
        for v in &right.free_vars {
            if !free_vars.contains(v) {
                free_vars.push(*v);
            }
        }
        Ok(DualArmIk {
            robot,
            left,
            right,
            free_vars,
        })
    }

    pub fn robot(&self) -> &Arc<Robot> {
        &self.robot
    }
    pub fn left(&self) -> &ArmChain {
        &self.left
    }
    pub fn right(&self) -> &ArmChain {
        &self.right
    }
    /// The shared free variables (sampled).
    pub fn free_vars(&self) -> &[usize] {
        &self.free_vars
    }

    /// The inverses of the left and right arm-base world poses for configuration `q`, the
    /// robot's root at `robot_base`: what maps world TCP targets into each arm's frame. Both
    /// arms usually hang off the same link (ARMAR's torso): one FK walk then.
    pub fn base_inverses(&self, robot_base: &Pose, q: &[f64]) -> (Pose, Pose) {
        let linv = (robot_base * self.left.base_path.pose(q)).inverse();
        let rinv = if self.right.arm_base == self.left.arm_base {
            linv
        } else {
            (robot_base * self.right.base_path.pose(q)).inverse()
        };
        (linv, rinv)
    }

    /// Variant (a), object pose free (000 §III). `object_free(pose)` says whether the object may
    /// be at a pose (environment collision); `valid(left, right, q)` checks a full configuration
    /// with the object held (self- and environment collision).
    #[allow(clippy::too_many_arguments)]
    pub fn solve<R: Rng + ?Sized>(
        &self,
        query: &DualArmQuery<'_>,
        reach: Option<(&dyn ReachabilityMap, &dyn ReachabilityMap)>,
        settings: &RandomizedIkSettings,
        rng: &mut R,
        mut object_free: impl FnMut(&Pose) -> bool,
        mut valid: impl FnMut(usize, usize, &[f64]) -> bool,
    ) -> Result<DualArmSolution, RandomizedIkError> {
        let robot = &*self.robot;
        if query.start.len() != robot.dof() {
            return Err(RandomizedIkError::BadStart {
                found: query.start.len(),
                expected: robot.dof(),
            });
        }
        if query.left_grasps.is_empty() || query.right_grasps.is_empty() {
            return Err(RandomizedIkError::NoGrasps);
        }
        let (lo, hi) = query.region;
        if !(0..3).all(|k| lo[k].is_finite() && hi[k].is_finite() && lo[k] <= hi[k]) {
            return Err(RandomizedIkError::BadTarget);
        }
        let mut q = query.start.to_vec();
        let mut c = IkCounters::default();
        let mut lc: Vec<(f64, usize)> = Vec::new();
        let mut rc: Vec<(f64, usize)> = Vec::new();
        let (nl, nr) = (query.left_grasps.len(), query.right_grasps.len());
        let (mut pl, mut pr) = (vec![0.0; nl], vec![0.0; nr]);
        for _ in 0..settings.max_tries {
            c.tries += 1;
            robot.sample_vars(&self.free_vars, &mut q, rng);
            let pos = Vector3::from_fn(|k, _| {
                if hi[k] > lo[k] {
                    rng.random_range(lo[k]..=hi[k])
                } else {
                    lo[k]
                }
            });
            let mut obj = Pose::from_parts(Translation3::from(pos), random_rotation(rng));
            let (linv, rinv) = self.base_inverses(&query.robot_base, &q);
            lc.clear();
            rc.clear();
            let filtered = match reach {
                Some((ml, mr)) if rng.random::<f64>() < settings.reach_probability => {
                    // min(best left, best right); when the left hand alone cannot beat
                    // `floor` (see `gradient_ascent`), the right hand need not look.
                    let mut best = |obj: &Pose, floor: f64, c: &mut IkCounters| -> f64 {
                        ml.probabilities(&(linv * obj), query.left_grasps, &mut pl);
                        c.reach_lookups += nl as u64;
                        let bl = pl.iter().copied().fold(0.0, f64::max);
                        if bl <= 0.0 || bl <= floor {
                            return bl; // min(bl, anything ≥ 0) ≤ bl
                        }
                        mr.probabilities(&(rinv * obj), query.right_grasps, &mut pr);
                        c.reach_lookups += nr as u64;
                        let br = pr.iter().copied().fold(0.0, f64::max);
                        bl.min(br)
                    };
                    let s = best(&obj, f64::NEG_INFINITY, &mut c);
                    if s <= settings.threshold {
                        continue;
                    }
                    if rng.random::<f64>() < settings.gradient_probability {
                        let steps = ml.voxel_steps();
                        let mut look = IkCounters::default();
                        let mut checks = 0;
                        let (p, _, moves) = gradient_ascent(
                            &obj,
                            &steps,
                            settings.gradient_max_steps,
                            |o, floor| best(o, floor, &mut look),
                            |o| {
                                checks += 1;
                                object_free(o)
                            },
                        );
                        c.reach_lookups += look.reach_lookups;
                        c.collision_checks += checks;
                        c.gradient_steps += moves as u64;
                        obj = p;
                    }
                    ml.probabilities(&(linv * obj), query.left_grasps, &mut pl);
                    mr.probabilities(&(rinv * obj), query.right_grasps, &mut pr);
                    lc.extend(
                        pl.iter()
                            .enumerate()
                            .filter(|(_, &p)| p > settings.threshold)
                            .map(|(g, &p)| (p, g)),
                    );
                    rc.extend(
                        pr.iter()
                            .enumerate()
                            .filter(|(_, &p)| p > settings.threshold)
                            .map(|(g, &p)| (p, g)),
                    );
                    c.reach_lookups += (nl + nr) as u64;
                    lc.sort_by(|a, b| b.0.total_cmp(&a.0));
                    rc.sort_by(|a, b| b.0.total_cmp(&a.0));
                    true
                }
                _ => false,
            };
            if !filtered {
                lc.push((0.0, rng.random_range(0..nl)));
                rc.push((0.0, rng.random_range(0..nr)));
            }
            if lc.is_empty() || rc.is_empty() {
                continue;
            }
            c.collision_checks += 1;
            if !object_free(&obj) {
                continue;
            }
            // Left arm first (any solution), then the right arm against it.
            for &(_, gl) in &lc {
                let tl = linv * obj * query.left_grasps[gl];
                let mut found = None;
                let ok = try_arm(
                    &self.left.arm,
                    &tl,
                    settings.psi_samples,
                    &mut q,
                    &mut c,
                    rng,
                    |_| true,
                );
                // `try_arm` counted the accepted left solution as a check; it is not one.
                if !ok {
                    continue;
                }
                c.collision_checks -= 1;
                for &(_, gr) in &rc {
                    let tr = rinv * obj * query.right_grasps[gr];
                    if try_arm(
                        &self.right.arm,
                        &tr,
                        settings.psi_samples,
                        &mut q,
                        &mut c,
                        rng,
                        |q| valid(gl, gr, q),
                    ) {
                        found = Some(gr);
                        break;
                    }
                }
                if let Some(gr) = found {
                    return Ok(DualArmSolution {
                        config: q,
                        object_pose: obj,
                        left_grasp: gl,
                        right_grasp: gr,
                        counters: c,
                    });
                }
            }
        }
        Err(RandomizedIkError::NoSolution {
            tries: c.tries,
            counters: c,
        })
    }

    /// Variant (b), object already grasped with the left hand by `held` (index into
    /// `query.left_grasps`): hip + both arms (17-D), the object moving with the left hand.
    #[allow(clippy::too_many_arguments)]
    pub fn solve_held<R: Rng + ?Sized>(
        &self,
        query: &DualArmQuery<'_>,
        held: usize,
        reach: Option<(&dyn ReachabilityMap, &dyn ReachabilityMap)>,
        settings: &RandomizedIkSettings,
        rng: &mut R,
        object_free: impl FnMut(&Pose) -> bool,
        mut valid: impl FnMut(usize, usize, &[f64]) -> bool,
    ) -> Result<DualArmSolution, RandomizedIkError> {
        let one = query
            .left_grasps
            .get(held..held + 1)
            .ok_or(RandomizedIkError::NoGrasps)?;
        let q1 = DualArmQuery {
            left_grasps: one,
            ..*query
        };
        let mut s = self.solve(&q1, reach, settings, rng, object_free, |_, gr, q| {
            valid(held, gr, q)
        })?;
        s.left_grasp = held;
        Ok(s)
    }
}
