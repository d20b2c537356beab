//! Numeric inverse kinematics for any chain: damped least squares (Levenberg–Marquardt style,
//! adaptive damping) on the 6-D pose error, joint limits by clamping each step, random restarts
//! within the limits from a caller-provided (seeded) RNG.
//!
//! The error is `e = [p_t − p, rotvec(R_t Rᵀ)]` in the chain-base frame (so it matches the
//! geometric Jacobian of [`Chain::jacobian`]), weighted per component. Each step solves
//! `Δ = J̃ᵀ (J̃ J̃ᵀ + λ I)⁻¹ ẽ` (6×6 Cholesky, no allocation); a step that lowers the weighted
//! error is accepted and λ shrinks, otherwise λ grows and the step is retried. An attempt ends
//! when the error is within tolerance (success), when λ explodes (local minimum / limit stall),
//! or after `max_iterations` steps; then the solver restarts from a random configuration.

use nalgebra::{Matrix6, Matrix6xX, Unit, Vector3, Vector6};
use rand::Rng;
use thiserror::Error;

use super::chain::Chain;
use super::fk::joint_motion;
use crate::geometry::Pose;
use crate::model::{JointKind, Robot};

/// Settings of one numeric IK call; change `NumericIk::settings` between calls as needed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkSettings {
    /// Convergence tolerance on both the position error (m) and the orientation error (rad).
    pub tolerance: f64,
    /// Maximum number of damped steps (accepted or rejected) per attempt.
    pub max_iterations: usize,
    /// Maximum number of random restarts after the first attempt (from the seed).
    pub max_restarts: usize,
    /// Initial damping λ of each attempt.
    pub damping: f64,
    /// Only the tip position matters (e.g. finger tips); orientation is ignored.
    pub position_only: bool,
    /// Weights of the error components (x, y, z, rx, ry, rz) in the least-squares objective.
    pub weights: [f64; 6],
}

impl Default for IkSettings {
    fn default() -> Self {
        IkSettings {
            tolerance: 1e-10,
            max_iterations: 50,
            max_restarts: 100,
            damping: 1e-2,
            position_only: false,
            weights: [1.0; 6],
        }
    }
}

/// Numeric IK did not converge.
#[derive(Debug, Clone, PartialEq, Error)]
#[error(
    "numeric IK did not converge after {attempts} attempts ({iterations} iterations): best error {best_position_error:.3e} m, {best_orientation_error:.3e} rad"
)]
pub struct IkFailure {
    pub attempts: usize,
    pub iterations: usize,
    pub best_position_error: f64,
    pub best_orientation_error: f64,
    /// Full robot configuration with the best values found.
    pub best: Vec<f64>,
}

/// Statistics of the last call and running totals.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct IkStats {
    /// Iterations of the last call (all attempts).
    pub iterations: usize,
    /// Attempts of the last call (1 = converged from the seed).
    pub attempts: usize,
    pub total_calls: usize,
    pub total_successes: usize,
    pub total_iterations: usize,
}

#[derive(Debug, Clone)]
struct CJoint {
    /// Fixed transform before the joint, relative to the previous movable joint's moving frame.
    pre: Pose,
    axis: Unit<Vector3<f64>>,
    kind: JointKind,
    /// Column (chain variable index) and mimic mapping `value = mul · x[col] + offset`.
    col: usize,
    mul: f64,
    offset: f64,
}

/// Position (m) and orientation (rad) distance between two poses, accurate for tiny errors
/// (unlike `UnitQuaternion::angle`, which loses precision below ~1e-8 rad).
pub fn pose_error(a: &Pose, b: &Pose) -> (f64, f64) {
    super::srs::pose_distance(a, b)
}

fn target_is_finite(p: &Pose) -> bool {
    p.translation.vector.iter().all(|x| x.is_finite())
        && p.rotation.coords.iter().all(|x| x.is_finite())
}

/// Numeric IK of one chain. Owns a compact copy of the chain kinematics and its work buffers.
#[derive(Debug, Clone)]
pub struct NumericIk {
    pub settings: IkSettings,
    pub stats: IkStats,
    joints: Vec<CJoint>,
    tail: Pose,
    vars: Vec<usize>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    bounded: Vec<bool>,
    dof: usize,
    // Buffers.
    x: Vec<f64>,
    x_try: Vec<f64>,
    best_x: Vec<f64>,
    delta: Vec<f64>,
    free: Vec<bool>,
    jac: Matrix6xX<f64>,
    frames: Vec<(Vector3<f64>, Vector3<f64>)>,
}

impl NumericIk {
    pub fn new(robot: &Robot, chain: &Chain) -> NumericIk {
        let mut joints = Vec::new();
        let mut acc = Pose::identity();
        for &j in &chain.joints {
            let jt = &robot.joints[j];
            if jt.kind == JointKind::Fixed {
                acc *= jt.origin;
                continue;
            }
            let (var, mul, offset) = match (jt.var, jt.mimic) {
                (Some(v), _) => (v, 1.0, 0.0),
                (None, Some(m)) => (m.var, m.multiplier, m.offset),
                _ => (usize::MAX, 0.0, 0.0),
            };
            let pre = acc * jt.origin;
            acc = Pose::identity();
            match chain.vars.iter().position(|&v| v == var) {
                Some(col) => joints.push(CJoint {
                    pre,
                    axis: jt.axis,
                    kind: jt.kind,
                    col,
                    mul,
                    offset,
                }),
                // A movable joint without a variable in the chain: treat as fixed at 0.
                None => acc = pre,
            }
        }
        let n = chain.vars.len();
        let lim = |i: usize| robot.var_limits(chain.vars[i]);
        let bounded: Vec<bool> = (0..n).map(|i| lim(i).bounded).collect();
        let lower: Vec<f64> = (0..n)
            .map(|i| {
                if bounded[i] {
                    lim(i).lower
                } else {
                    -std::f64::consts::PI
                }
            })
            .collect();
        let upper: Vec<f64> = (0..n)
            .map(|i| {
                if bounded[i] {
                    lim(i).upper
                } else {
                    std::f64::consts::PI
                }
            })
            .collect();
        NumericIk {
            settings: IkSettings::default(),
            stats: IkStats::default(),
            frames: vec![(Vector3::zeros(), Vector3::zeros()); joints.len()],
            joints,
            tail: acc,
            vars: chain.vars.clone(),
            lower,
            upper,
            bounded,
            dof: robot.dof(),
            x: vec![0.0; n],
            x_try: vec![0.0; n],
            best_x: vec![0.0; n],
            delta: vec![0.0; n],
            free: vec![true; n],
            jac: Matrix6xX::zeros(n),
        }
    }

    /// Robot configuration variables moved by the chain (order of the chain).
    pub fn vars(&self) -> &[usize] {
        &self.vars
    }

    /// Tip pose (chain-base frame) for chain values `x`.
    pub fn fk(&self, x: &[f64]) -> Pose {
        let mut t = Pose::identity();
        for j in &self.joints {
            t = t * j.pre * joint_motion(j.kind, &j.axis, j.mul * x[j.col] + j.offset);
        }
        t * self.tail
    }

    /// Tip pose and the Jacobian (into `self.jac`) for chain values in `self.x`.
    fn fk_jac(&mut self) -> Pose {
        let mut t = Pose::identity();
        for (i, j) in self.joints.iter().enumerate() {
            let f = t * j.pre;
            self.frames[i] = (f.rotation * j.axis.into_inner(), f.translation.vector);
            t = f * joint_motion(j.kind, &j.axis, j.mul * self.x[j.col] + j.offset);
        }
        let tip = t * self.tail;
        let pt = tip.translation.vector;
        self.jac.fill(0.0);
        for (i, j) in self.joints.iter().enumerate() {
            let (z, p) = self.frames[i];
            let (lin, ang) = match j.kind {
                JointKind::Prismatic => (z, Vector3::zeros()),
                _ => (z.cross(&(pt - p)), z),
            };
            for r in 0..3 {
                self.jac[(r, j.col)] += j.mul * lin[r];
                self.jac[(r + 3, j.col)] += j.mul * ang[r];
            }
        }
        tip
    }

    /// Weighted error vector, squared norm and the unweighted (position, orientation) errors.
    fn error(&self, tip: &Pose, target: &Pose) -> (Vector6<f64>, f64, f64, f64) {
        let ep = target.translation.vector - tip.translation.vector;
        let mut e = Vector6::zeros();
        let mut er_norm = 0.0;
        let w = &self.settings.weights;
        for r in 0..3 {
            e[r] = w[r] * ep[r];
        }
        if !self.settings.position_only {
            let mut q = target.rotation * tip.rotation.inverse();
            if q.scalar() < 0.0 {
                q = nalgebra::UnitQuaternion::new_unchecked(-q.into_inner());
            }
            let v = q.imag();
            let sn = v.norm();
            let ang = 2.0 * sn.atan2(q.scalar());
            let rv = if sn > 1e-300 { v * (ang / sn) } else { v * 2.0 };
            for r in 0..3 {
                e[r + 3] = w[r + 3] * rv[r];
            }
            er_norm = ang;
        }
        (e, e.norm_squared(), ep.norm(), er_norm)
    }

    fn clamp_into(&self, x: &mut [f64]) {
        for (i, v) in x.iter_mut().enumerate() {
            if self.bounded[i] {
                *v = v.clamp(self.lower[i], self.upper[i]);
            }
        }
    }

    /// Damped least-squares step `Δ = J̃ᵀ (J̃ J̃ᵀ + λ I)⁻¹ ẽ` into `self.delta`, with an active
    /// set for the joint limits: a joint at a limit whose step would push it outward is frozen
    /// (its column dropped) and the step recomputed, so the other joints keep making progress.
    /// Returns false if the system could not be factorised.
    fn damped_step(&mut self, e: &Vector6<f64>, rows: usize, lambda: f64) -> bool {
        let n = self.vars.len();
        let w = self.settings.weights;
        self.free.iter_mut().for_each(|f| *f = true);
        for _ in 0..=n {
            let mut a = Matrix6::<f64>::zeros();
            for r in 0..rows {
                for c in 0..=r {
                    let mut s = 0.0;
                    for k in 0..n {
                        if self.free[k] {
                            s += self.jac[(r, k)] * self.jac[(c, k)];
                        }
                    }
                    let v = s * w[r] * w[c];
                    a[(r, c)] = v;
                    a[(c, r)] = v;
                }
            }
            for r in 0..6 {
                a[(r, r)] += if r < rows { lambda } else { 1.0 };
            }
            let Some(ch) = a.cholesky() else {
                return false;
            };
            let y = ch.solve(e);
            let mut changed = false;
            for k in 0..n {
                if !self.free[k] {
                    self.delta[k] = 0.0;
                    continue;
                }
                let mut s = 0.0;
                for r in 0..rows {
                    s += self.jac[(r, k)] * w[r] * y[r];
                }
                self.delta[k] = s;
                if self.bounded[k]
                    && ((self.x[k] <= self.lower[k] && s < 0.0)
                        || (self.x[k] >= self.upper[k] && s > 0.0))
                {
                    self.free[k] = false;
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
        true
    }

    /// Solves for a tip pose `target` in the chain-base frame. `seed` is a full robot
    /// configuration (the first attempt starts from it; its non-chain values are kept in the
    /// result). Returns the full configuration with FK error ≤ `settings.tolerance`.
    pub fn solve<R: Rng + ?Sized>(
        &mut self,
        target: &Pose,
        seed: &[f64],
        rng: &mut R,
    ) -> Result<Vec<f64>, IkFailure> {
        if seed.len() != self.dof
            || seed.iter().any(|x| !x.is_finite())
            || !target_is_finite(target)
        {
            // A malformed request: nothing to iterate on.
            return Err(IkFailure {
                attempts: 0,
                iterations: 0,
                best_position_error: f64::INFINITY,
                best_orientation_error: f64::INFINITY,
                best: seed.to_vec(),
            });
        }
        let n = self.vars.len();
        let tol = self.settings.tolerance;
        let rows = if self.settings.position_only { 3 } else { 6 };
        let mut best = (f64::INFINITY, f64::INFINITY, f64::INFINITY); // (cost, ep, er)
        let mut iterations = 0;
        let mut attempts = 0;
        let mut success = false;
        for attempt in 0..=self.settings.max_restarts {
            attempts += 1;
            if attempt == 0 {
                for i in 0..n {
                    self.x[i] = seed[self.vars[i]];
                }
                let mut x = std::mem::take(&mut self.x);
                self.clamp_into(&mut x);
                self.x = x;
            } else {
                for i in 0..n {
                    self.x[i] = rng.random_range(self.lower[i]..=self.upper[i]);
                }
            }
            let mut lambda = self.settings.damping;
            let tip = self.fk_jac();
            let (mut e, mut cost, mut ep, mut er) = self.error(&tip, target);
            let mut it = 0;
            loop {
                if cost < best.0 {
                    best = (cost, ep, er);
                    self.best_x.copy_from_slice(&self.x);
                }
                if ep <= tol && er <= tol {
                    success = true;
                    break;
                }
                if it >= self.settings.max_iterations || lambda > 1e8 {
                    break;
                }
                it += 1;
                if !self.damped_step(&e, rows, lambda) {
                    lambda *= 10.0;
                    continue;
                }
                for k in 0..n {
                    self.x_try[k] = self.x[k] + self.delta[k];
                }
                let mut xt = std::mem::take(&mut self.x_try);
                self.clamp_into(&mut xt);
                let tip_try = self.fk(&xt);
                self.x_try = xt;
                let (e2, cost2, ep2, er2) = self.error(&tip_try, target);
                if cost2 < cost {
                    std::mem::swap(&mut self.x, &mut self.x_try);
                    self.fk_jac();
                    e = e2;
                    cost = cost2;
                    ep = ep2;
                    er = er2;
                    lambda = (lambda * 0.1).max(1e-12);
                } else {
                    lambda *= 10.0;
                }
            }
            iterations += it;
            if success {
                break;
            }
        }
        self.stats.iterations = iterations;
        self.stats.attempts = attempts;
        self.stats.total_calls += 1;
        self.stats.total_iterations += iterations;
        let mut q = seed.to_vec();
        for i in 0..n {
            q[self.vars[i]] = if success { self.x[i] } else { self.best_x[i] };
        }
        if success {
            self.stats.total_successes += 1;
            Ok(q)
        } else {
            Err(IkFailure {
                attempts,
                iterations,
                best_position_error: best.1,
                best_orientation_error: best.2,
                best: q,
            })
        }
    }
}
