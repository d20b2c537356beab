//! Analytic inverse kinematics of a 7-DoF S-R-S (spherical shoulder – revolute elbow – spherical
//! wrist) arm, parameterised by the swivel (arm) angle ψ.
//!
//! Reference: paper 000 (Vahrenkamp et al. 2009, "Humanoid motion planning for dual-arm
//! manipulation and re-grasping tasks", §II-A: an IK solver for the 7-DoF arms that is able to
//! enumerate the swivel angles, so an IK-RRT can sample goal configurations), and M. Shimizu,
//! H. Kakuya, W.-K. Yoon, K. Kitagaki, K. Kosuge, "Analytical Inverse Kinematic Computation for
//! 7-DOF Redundant Manipulators With Joint Limits and Its Application to Redundancy Resolution",
//! IEEE T-RO 24(5), 2008 (the arm angle ψ).
//!
//! The solver works in the product-of-exponentials (PoE) form, so it applies to any URDF chain
//! of 7 revolute joints with S-R-S structure, whatever the fixed joint origins and the fixed tip
//! (TCP) offset after joint 7:
//!
//! * joints 1–3 have axes intersecting in the shoulder centre `s`,
//! * joint 4 is the elbow (its rotation changes the shoulder–wrist distance),
//! * joints 5–7 have axes intersecting in the wrist centre `w`,
//! * consecutive axes in each triple are not parallel.
//!
//! With spatial twists ξᵢ taken at the zero configuration in the chain-base frame,
//! `T(θ) = e^{ξ1θ1} ⋯ e^{ξ7θ7} T_tip(0)`. For a target `T` and a swivel angle ψ:
//!
//! 1. wrist-centre target `w_t = T · T_tip(0)⁻¹ · w` (w is fixed in the last link);
//! 2. θ4 from Paden–Kahan subproblem 3, `|e^{ξ4θ4} w − s| = |w_t − s|` (two branches, one when
//!    the arm is stretched);
//! 3. the shoulder rotation `R_sh = e^{[k1]θ1} e^{[k2]θ2} e^{[k3]θ3}` is fixed by ψ: it maps the
//!    arm frame `[â, p, m]` (â = unit(e^{ξ4θ4}w − s), m = unit component of the elbow axis ⟂ â,
//!    p = m × â) onto `[u, d(ψ), u × d(ψ)]` with u = unit(w_t − s),
//!    `d(ψ) = cos ψ · n + sin ψ · (u × n)` and n the unit component of the base −z axis ⟂ u
//!    (+x if u ∥ z);
//! 4. θ1..θ3 from Paden–Kahan subproblem 2 (applied to k3) and subproblem 1 (two branches), the
//!    wrist θ5..θ7 the same way from the rotation part of `(e^{ξ1θ1}⋯e^{ξ4θ4})⁻¹ T T_tip(0)⁻¹`
//!    (two branches). Up to 8 solutions per ψ.
//!
//! ψ is the arm angle of Shimizu et al.: the rotation of the elbow about the shoulder–wrist line,
//! ψ = 0 when the elbow lies in the plane spanned by the s–w line and the base −z direction.
//! Every solution is mapped into the joint limits (±2π) and verified by forward kinematics
//! (error ≤ 1e-9 m / 1e-9 rad); solutions failing either are dropped.
//!
//! Cost: steps 1–2 depend on the target only ([`SrsArm::prepare`]), so a ψ sweep does them once.
//! Each angle of steps 3–4 is carried as (sin, cos), read off the arguments of its `atan2`, so
//! building rotations needs no trigonometry; a cosine test against the middle of each joint's
//! range drops most out-of-limit branches early, and `atan2` runs only for solutions that passed
//! the FK check.

use std::f64::consts::PI;

use nalgebra::{Matrix3, Point3, Unit, Vector3};
use rand::seq::SliceRandom;
use rand::Rng;
use thiserror::Error;

use super::chain::Chain;
use super::fk::joint_motion;
use crate::geometry::{atan2, sin_cos, Pose};
use crate::model::{JointKind, Limits, Robot};

mod solve;

/// Distance (m) within which joint axes must meet in the shoulder / wrist centre.
pub const AXIS_INTERSECTION_TOLERANCE: f64 = 1e-9;
/// Maximum position (m) and orientation (rad) error of a returned solution.
pub const SOLUTION_TOLERANCE: f64 = 1e-9;

/// Why a chain is not an S-R-S arm.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SrsError {
    #[error("group '{0}' is not a chain")]
    NoChain(String),
    #[error(
        "not an S-R-S arm: chain {base}→{tip} has {found} movable joints, an S-R-S arm needs exactly 7 revolute joints"
    )]
    JointCount {
        base: String,
        tip: String,
        found: usize,
    },
    #[error("not an S-R-S arm: joint '{joint}' is {kind}, an S-R-S arm needs 7 revolute joints")]
    NotRevolute { joint: String, kind: &'static str },
    #[error("not an S-R-S arm: joint '{joint}' is a mimic joint")]
    Mimic { joint: String },
    #[error("not an S-R-S arm: axes of consecutive {part} joints '{a}' and '{b}' are parallel")]
    ParallelAxes {
        part: &'static str,
        a: String,
        b: String,
    },
    #[error(
        "not an S-R-S arm: the {part} axes ('{a}', '{b}', '{c}') do not intersect in one point: joint '{worst}' misses their common point by {distance:.3e} m (tolerance 1e-9 m)"
    )]
    NotIntersecting {
        part: &'static str,
        a: String,
        b: String,
        c: String,
        worst: String,
        distance: f64,
    },
    #[error(
        "not an S-R-S arm: elbow joint '{joint}' cannot change the shoulder–wrist distance (its axis passes through the shoulder or wrist centre, or the centres coincide)"
    )]
    DegenerateElbow { joint: String },
}

/// Order of the solutions returned by [`SrsArm::solve_enumerate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SolutionOrder {
    /// In the order found (ψ ascending from −π, then branch).
    AsFound,
    /// Shuffled with the caller's RNG.
    Random,
    /// Ascending Euclidean joint-space distance to a seed (chain variable order).
    NearestTo([f64; 7]),
    /// Ascending weighted distance `Σ wᵢ (qᵢ − seedᵢ)²` to a seed.
    NearestToWeighted { seed: [f64; 7], weights: [f64; 7] },
}

/// Analytic IK of one S-R-S arm chain. Cheap to clone; `solve` allocates nothing.
#[derive(Debug, Clone)]
pub struct SrsArm {
    chain: Chain,
    vars: [usize; 7],
    names: [String; 7],
    limits: [Limits; 7],
    /// Fixed transform before each joint (relative to the previous joint's moving frame).
    pre: [Pose; 7],
    /// Joint axes in their own joint frames.
    local_axis: [Unit<Vector3<f64>>; 7],
    /// Fixed transform from joint 7's moving frame to the tip link.
    tail: Pose,
    /// Spatial axis directions at the zero configuration (chain-base frame).
    k: [Vector3<f64>; 7],
    /// A point on each spatial axis at the zero configuration.
    p: [Vector3<f64>; 7],
    s: Vector3<f64>,
    w: Vector3<f64>,
    /// Wrist centre in the tip frame: `T_tip(0)⁻¹ · w`.
    w_in_tip: Point3<f64>,
    /// Rotation part of `T_tip(0)⁻¹`.
    tip0_rot_inv: Matrix3<f64>,
    reach_min: f64,
    reach_max: f64,
    /// Pre-filters of the joint limits.
    arcs: [ArcTest; 7],
    /// The shoulder (joints 1–3) and wrist (joints 5–7) axis triples.
    shoulder: Triple,
    wrist: Triple,
    /// `pre` and `tail` as rotation matrices and translations (for the FK check of `solve`).
    pre_r: [Matrix3<f64>; 7],
    pre_t: [Vector3<f64>; 7],
    tail_r: Matrix3<f64>,
    tail_t: Vector3<f64>,
}

/// One elbow branch of a prepared target: θ4 and the arm frame `[â, p, m]` (transposed).
#[derive(Debug, Clone, Copy)]
struct Elbow {
    q4: f64,
    a4: Angle,
    r4: Matrix3<f64>,
    frame_t: Matrix3<f64>,
}

/// The part of an IK query that does not depend on the swivel angle ψ: the target, the
/// shoulder–wrist direction with its ψ = 0 frame, and the elbow branches within the limits.
/// Made by [`SrsArm::prepare`], solved at any ψ by [`SrsArm::solve_prepared`]; a ψ sweep
/// prepares once.
#[derive(Debug, Clone)]
pub struct SrsTarget {
    /// Target rotation and translation (chain-base frame).
    rt: Matrix3<f64>,
    tt: Vector3<f64>,
    /// `rt · T_tip(0)⁻¹` (rotation part).
    rt_tip: Matrix3<f64>,
    u: Vector3<f64>,
    nv: Vector3<f64>,
    un: Vector3<f64>,
    elbows: [Elbow; 2],
    n_elbows: usize,
}

/// Rodrigues' rotation about unit `k` by `angle`.
#[inline]
fn rot(k: &Vector3<f64>, angle: f64) -> Matrix3<f64> {
    let (sn, cs) = sin_cos(angle);
    rot_sc(k, sn, cs)
}

/// A joint angle as its sine and cosine (read off the arguments of the `atan2` that would give
/// it, so building its rotation needs no trigonometry); the angle itself is taken (one `atan2`)
/// only for solutions that passed every other test.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Angle {
    s: f64,
    c: f64,
}

impl Angle {
    /// The angle `atan2(y, x)`: `sin = y / h`, `cos = x / h` (h = hypot); 0 when x = y = 0,
    /// NaN when either is NaN.
    #[inline]
    fn of(y: f64, x: f64) -> Angle {
        let h = (x * x + y * y).sqrt();
        if h > 0.0 {
            let inv = 1.0 / h;
            Angle {
                s: y * inv,
                c: x * inv,
            }
        } else if h == 0.0 {
            Angle { s: 0.0, c: 1.0 }
        } else {
            Angle {
                s: f64::NAN,
                c: f64::NAN,
            }
        }
    }

    #[inline]
    fn value(&self) -> f64 {
        atan2(self.s, self.c)
    }
}

/// A necessary condition for [`into_limits`] from an angle's sine and cosine: θ lies within
/// `half` (+ 1e-6 rad slack) of the middle of the range, i.e. `cos(θ − mid) ≥ cos(half)`.
/// A cheap pre-filter; the exact test runs on the solutions that pass.
#[derive(Debug, Clone, Copy)]
struct ArcTest {
    sm: f64,
    cm: f64,
    min_cos: f64,
}

impl ArcTest {
    fn new(lim: &Limits) -> ArcTest {
        let off = ArcTest {
            sm: 0.0,
            cm: 0.0,
            min_cos: -1.0,
        };
        if !lim.bounded {
            return off;
        }
        let mid = 0.5 * (lim.lower + lim.upper);
        let half = 0.5 * (lim.upper - lim.lower) + 1e-6;
        // Where cos is flat (half near 0 or π) rounding could matter: no pre-filter there.
        if !(1e-3..=PI - 1e-3).contains(&half) || !mid.is_finite() {
            return off;
        }
        let (sm, cm) = mid.sin_cos();
        ArcTest {
            sm,
            cm,
            min_cos: half.cos(),
        }
    }

    /// False only when the angle certainly lies outside the limits (also for NaN).
    #[inline]
    fn admits(&self, a: &Angle) -> bool {
        self.sm * a.s + self.cm * a.c >= self.min_cos
    }
}

/// Rodrigues' rotation about unit `k` from the angle's sine and cosine.
#[inline]
fn rot_sc(k: &Vector3<f64>, sn: f64, cs: f64) -> Matrix3<f64> {
    // I + sinθ [k]× + (1 − cosθ) [k]×², written out: c I + (1 − c) k kᵀ + s [k]× (k unit).
    let (x, y, z) = (k.x, k.y, k.z);
    let t = 1.0 - cs;
    let (tx, ty, tz) = (t * x, t * y, t * z);
    let (sx, sy, sz) = (sn * x, sn * y, sn * z);
    Matrix3::new(
        tx * x + cs,
        tx * y - sz,
        tx * z + sy,
        tx * y + sz,
        ty * y + cs,
        ty * z - sx,
        tx * z - sy,
        ty * z + sx,
        tz * z + cs,
    )
}

/// `v` rotated about unit `k` by the angle whose sine and cosine are given.
#[inline]
fn rotate_sc(k: &Vector3<f64>, sn: f64, cs: f64, v: &Vector3<f64>) -> Vector3<f64> {
    v * cs + k.cross(v) * sn + k * (k.dot(v) * (1.0 - cs))
}

/// Paden–Kahan subproblem 1 for directions: the angle about unit `k` that rotates `ap` onto `bp`,
/// both already projected onto the plane ⟂ k.
#[inline]
fn sp1_projected(k: &Vector3<f64>, ap: &Vector3<f64>, bp: &Vector3<f64>) -> Angle {
    Angle::of(k.dot(&ap.cross(bp)), ap.dot(bp))
}

/// A triple of rotation axes (k1 ∦ k2, k2 ∦ k3) and what solving `e^{[k1]a} e^{[k2]b}
/// e^{[k3]c} = r` needs of them alone.
#[derive(Debug, Clone)]
struct Triple {
    k1: Vector3<f64>,
    k2: Vector3<f64>,
    k3: Vector3<f64>,
    k12: f64,
    denom: f64,
    cr: Vector3<f64>,
    cr2: f64,
    /// A unit direction ⟂ k3 to read off the third angle.
    v: Vector3<f64>,
    /// k3 projected onto the plane ⟂ k2 (the fixed side of the subproblem giving b).
    k3_perp2: Vector3<f64>,
}

impl Triple {
    fn new(k1: &Vector3<f64>, k2: &Vector3<f64>, k3: &Vector3<f64>) -> Triple {
        let k12 = k1.dot(k2);
        let cr = k1.cross(k2);
        let t = if k3.x.abs() < 0.6 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        Triple {
            k1: *k1,
            k2: *k2,
            k3: *k3,
            k12,
            denom: k12 * k12 - 1.0,
            cr,
            cr2: cr.norm_squared(),
            v: (t - k3 * k3.dot(&t)).normalize(),
            k3_perp2: k3 - k2 * k2.dot(k3),
        }
    }

    /// Solves `e^{[k1]a} e^{[k2]b} e^{[k3]c} = r`: Paden–Kahan subproblem 2 applied to k3, then
    /// subproblem 1 for the third angle. Up to two solutions; a solution with an angle that
    /// `arcs` rule out is dropped as soon as that angle is known.
    #[inline]
    fn solve(&self, r: &Matrix3<f64>, arcs: &[ArcTest], out: &mut [[Angle; 3]; 2]) -> usize {
        let (k1, k2, k3) = (&self.k1, &self.k2, &self.k3);
        let x = *k3;
        let y = r * k3;
        let k12 = self.k12;
        let alpha = (k12 * k2.dot(&x) - k1.dot(&y)) / self.denom;
        let beta = (k12 * k1.dot(&y) - k2.dot(&x)) / self.denom;
        let g2 = (1.0 - alpha * alpha - beta * beta - 2.0 * alpha * beta * k12) / self.cr2;
        if g2.is_nan() || g2 < -1e-12 {
            return 0; // orientation not reachable by this axis triple (or NaN)
        }
        let g = g2.max(0.0).sqrt();
        let ngam = if g > 0.0 { 2 } else { 1 };
        let rv = r * self.v;
        let y_perp1 = y - k1 * k1.dot(&y);
        let mut n = 0;
        for i in 0..ngam {
            let gamma = if i == 0 { g } else { -g };
            let c = k1 * alpha + k2 * beta + self.cr * gamma;
            let b = sp1_projected(k2, &self.k3_perp2, &(c - k2 * k2.dot(&c)));
            if !arcs[1].admits(&b) {
                continue;
            }
            let a = sp1_projected(k1, &(c - k1 * k1.dot(&c)), &y_perp1);
            if !arcs[0].admits(&a) {
                continue;
            }
            // (e^{[k1]a} e^{[k2]b})ᵀ r v; v is already ⟂ k3.
            let rest = rotate_sc(k2, -b.s, b.c, &rotate_sc(k1, -a.s, a.c, &rv));
            let c3 = sp1_projected(k3, &self.v, &(rest - k3 * k3.dot(&rest)));
            if !arcs[2].admits(&c3) {
                continue;
            }
            out[n] = [a, b, c3];
            n += 1;
        }
        n
    }
}

/// Maps `v` into `lim` by adding multiples of 2π (the representative nearest the middle of the
/// range); `None` if no representative lies within the limits. Unbounded joints: into [−π, π).
#[inline]
fn into_limits(v: f64, lim: &Limits) -> Option<f64> {
    if !v.is_finite() {
        return None;
    }
    if !lim.bounded {
        return Some(v - 2.0 * PI * ((v + PI) / (2.0 * PI)).floor());
    }
    let mid = 0.5 * (lim.lower + lim.upper);
    let t = v + 2.0 * PI * round_fast((mid - v) / (2.0 * PI));
    const EPS: f64 = 1e-10;
    if t >= lim.lower - EPS && t <= lim.upper + EPS {
        Some(t.clamp(lim.lower, lim.upper))
    } else {
        None
    }
}

/// Round to nearest (ties to even) without a libm call (baseline x86-64 has no SSE4.1 round).
#[inline]
fn round_fast(x: f64) -> f64 {
    const MAGIC: f64 = 6_755_399_441_055_744.0; // 1.5 · 2^52
    if x.abs() < 1e15 {
        (x + MAGIC) - MAGIC
    } else {
        x.round()
    }
}

/// A rotation that depends on the swivel angle ψ as `c cos ψ + s sin ψ + o` (every rotation of the
/// solver does: the shoulder rotation and the wrist rotation of a fixed elbow branch).
#[derive(Debug, Clone, Copy)]
struct PsiAffine {
    c: Matrix3<f64>,
    s: Matrix3<f64>,
    o: Matrix3<f64>,
}

impl PsiAffine {
    /// `xᵀ R(ψ) y` as its cos, sin and constant coefficients.
    #[inline]
    fn bilinear(&self, x: &Vector3<f64>, y: &Vector3<f64>) -> [f64; 3] {
        [
            x.dot(&(self.c * y)),
            x.dot(&(self.s * y)),
            x.dot(&(self.o * y)),
        ]
    }
}

/// Pushes the ψ ∈ [−π, π) with `a cos ψ + b sin ψ + c = 0` (none, one or two; none when the
/// left side does not depend on ψ).
fn push_psi_roots(a: f64, b: f64, c: f64, out: &mut Vec<f64>) {
    let r = a.hypot(b);
    if r.is_nan() || r <= 1e-12 {
        return;
    }
    let x = -c / r;
    if !x.is_finite() || x.abs() > 1.0 + 1e-12 {
        return;
    }
    let phi = atan2(b, a);
    let d = x.clamp(-1.0, 1.0).acos();
    for v in [phi + d, phi - d] {
        out.push(v - 2.0 * PI * ((v + PI) / (2.0 * PI)).floor());
    }
}

/// The ψ at which a solution of `e^{[k1]a} e^{[k2]b} e^{[k3]c} = R(ψ)` has a joint on one of its
/// limits, or at which the triple starts or stops having solutions at all (Shimizu et al. 2008,
/// §IV: the joint-limit boundaries in ψ). Each is a root of `α cos ψ + β sin ψ + γ = 0`, because
/// every condition is linear in `R`:
///
/// * `b = L`: `k1ᵀ R k3 = k1ᵀ e^{[k2]L} k3` (`e^{[k1]a}` leaves `k1` and `e^{[k3]c}` leaves `k3`);
/// * `a = L`: `(e^{[k1]L} k2)ᵀ R k3 = k2ᵀ k3` (then some b rotates `k3` onto `e^{−[k1]L} R k3`);
/// * `c = L`: `k1ᵀ R e^{−[k3]L} k2 = k1ᵀ k2`;
/// * solvable at all: `k1ᵀ R k3` within the range of `k1ᵀ e^{[k2]b} k3` over b.
///
/// Between two consecutive roots every branch's angles move continuously without touching a
/// limit, so whether a solution within the limits exists is the same over the whole interval.
fn triple_limit_psi(t: &Triple, lims: &[Limits], r: &PsiAffine, out: &mut Vec<f64>) {
    let (k1, k2, k3) = (&t.k1, &t.k2, &t.k3);
    let limited = |l: &Limits| l.bounded && l.upper - l.lower < 2.0 * PI;
    let f13 = r.bilinear(k1, k3);
    let push =
        |f: [f64; 3], rhs: f64, out: &mut Vec<f64>| push_psi_roots(f[0], f[1], f[2] - rhs, out);
    // Range of k1ᵀ e^{[k2]b} k3 = A cos b + B sin b + C.
    let k23 = k2.dot(k3);
    let (ca, cb, cc) = (k1.dot(k3) - t.k12 * k23, k1.dot(&k2.cross(k3)), t.k12 * k23);
    let amp = ca.hypot(cb);
    push(f13, cc + amp, out);
    push(f13, cc - amp, out);
    for (j, l) in lims.iter().enumerate().take(3) {
        if !limited(l) {
            continue;
        }
        for lim in [l.lower, l.upper] {
            match j {
                0 => push(r.bilinear(&(rot(k1, lim) * k2), k3), k23, out),
                1 => push(f13, k1.dot(&(rot(k2, lim) * k3)), out),
                _ => push(r.bilinear(k1, &(rot(k3, -lim) * k2)), t.k12, out),
            }
        }
    }
}

/// Position (m) and orientation (rad) distance between two poses, accurate for tiny errors.
#[inline]
pub(crate) fn pose_distance(a: &Pose, b: &Pose) -> (f64, f64) {
    let dp = (a.translation.vector - b.translation.vector).norm();
    let q = a.rotation.inverse() * b.rotation;
    let (w, v) = (q.scalar(), q.imag());
    let ang = 2.0 * atan2(v.norm(), w.abs());
    (dp, ang)
}

/// Least-squares intersection point of three lines and the largest distance of a line from it.
fn intersect3(k: &[Vector3<f64>], p: &[Vector3<f64>]) -> (Vector3<f64>, [f64; 3]) {
    let mut a = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for i in 0..3 {
        let m = Matrix3::identity() - k[i] * k[i].transpose();
        a += m;
        b += m * p[i];
    }
    let c = a.try_inverse().map(|ai| ai * b).unwrap_or(p[0]);
    let mut d = [0.0; 3];
    for i in 0..3 {
        let r = c - p[i];
        d[i] = (r - k[i] * k[i].dot(&r)).norm();
    }
    (c, d)
}

impl SrsArm {
    /// Analyses `chain` and precomputes the zero-configuration PoE data in the chain-base frame.
    pub fn new(robot: &Robot, chain: &Chain) -> Result<SrsArm, SrsError> {
        let base = robot.links[chain.base_link].name.clone();
        let tip = robot.links[chain.tip_link].name.clone();
        let movable: Vec<usize> = chain
            .joints
            .iter()
            .copied()
            .filter(|&j| robot.joints[j].kind != JointKind::Fixed)
            .collect();
        if movable.len() != 7 {
            return Err(SrsError::JointCount {
                base,
                tip,
                found: movable.len(),
            });
        }
        for &j in &movable {
            let jt = &robot.joints[j];
            if !matches!(jt.kind, JointKind::Revolute | JointKind::Continuous) {
                return Err(SrsError::NotRevolute {
                    joint: jt.name.clone(),
                    kind: jt.kind.name(),
                });
            }
            if jt.var.is_none() {
                return Err(SrsError::Mimic {
                    joint: jt.name.clone(),
                });
            }
        }
        // Fold fixed joints into per-joint pre-transforms and a tail.
        let mut pre = [Pose::identity(); 7];
        let mut local_axis = [Vector3::z_axis(); 7];
        let mut acc = Pose::identity();
        let mut i = 0;
        for &j in &chain.joints {
            let jt = &robot.joints[j];
            if jt.kind == JointKind::Fixed {
                acc *= jt.origin;
            } else {
                pre[i] = acc * jt.origin;
                local_axis[i] = jt.axis;
                acc = Pose::identity();
                i += 1;
            }
        }
        let tail = acc;
        let vars: [usize; 7] = std::array::from_fn(|i| robot.joints[movable[i]].var.unwrap());
        let names: [String; 7] = std::array::from_fn(|i| robot.joints[movable[i]].name.clone());
        let limits: [Limits; 7] = std::array::from_fn(|i| robot.joints[movable[i]].limits);
        // Zero-configuration spatial axes.
        let mut k = [Vector3::zeros(); 7];
        let mut p = [Vector3::zeros(); 7];
        let mut f = Pose::identity();
        for i in 0..7 {
            f *= pre[i];
            k[i] = (f.rotation * local_axis[i].into_inner()).normalize();
            p[i] = f.translation.vector;
        }
        let tip0 = f * tail;
        for (part, (a, b)) in [
            ("shoulder", (0, 1)),
            ("shoulder", (1, 2)),
            ("wrist", (4, 5)),
            ("wrist", (5, 6)),
        ] {
            if k[a].cross(&k[b]).norm() < 1e-6 {
                return Err(SrsError::ParallelAxes {
                    part,
                    a: names[a].clone(),
                    b: names[b].clone(),
                });
            }
        }
        let centre = |part: &'static str, r: std::ops::Range<usize>| {
            let (c, d) = intersect3(&k[r.clone()], &p[r.clone()]);
            let (wi, wd) = d
                .iter()
                .enumerate()
                .fold((0, 0.0f64), |m, (i, &x)| if x > m.1 { (i, x) } else { m });
            if wd.is_nan() || wd > AXIS_INTERSECTION_TOLERANCE {
                return Err(SrsError::NotIntersecting {
                    part,
                    a: names[r.start].clone(),
                    b: names[r.start + 1].clone(),
                    c: names[r.start + 2].clone(),
                    worst: names[r.start + wi].clone(),
                    distance: wd,
                });
            }
            Ok(c)
        };
        let s = centre("shoulder", 0..3)?;
        let w = centre("wrist", 4..7)?;
        // Elbow: the distance |e^{ξ4θ} w − s| ranges over [|a'| − |b'||, |a'| + |b'|] in the
        // plane ⟂ k4, plus the fixed axial offset.
        let (k4, p4) = (k[3], p[3]);
        let xw = w - p4;
        let xs = s - p4;
        let xwp = xw - k4 * k4.dot(&xw);
        let xsp = xs - k4 * k4.dot(&xs);
        let axial = k4.dot(&(w - s));
        let (rw, rs) = (xwp.norm(), xsp.norm());
        if rw < 1e-9 || rs < 1e-9 {
            return Err(SrsError::DegenerateElbow {
                joint: names[3].clone(),
            });
        }
        let reach_max = (axial * axial + (rw + rs) * (rw + rs)).sqrt();
        let reach_min = (axial * axial + (rw - rs) * (rw - rs)).sqrt();
        let tip0_inv = tip0.inverse();
        let mat = |p: &Pose| p.rotation.to_rotation_matrix().into_inner();
        let shoulder = Triple::new(&k[0], &k[1], &k[2]);
        let wrist = Triple::new(&k[4], &k[5], &k[6]);
        Ok(SrsArm {
            arcs: std::array::from_fn(|i| ArcTest::new(&limits[i])),
            shoulder,
            wrist,
            pre_r: std::array::from_fn(|i| mat(&pre[i])),
            pre_t: std::array::from_fn(|i| pre[i].translation.vector),
            tail_r: mat(&tail),
            tail_t: tail.translation.vector,
            chain: chain.clone(),
            vars,
            names,
            limits,
            pre,
            local_axis,
            tail,
            k,
            p,
            s,
            w,
            w_in_tip: tip0_inv * Point3::from(w),
            tip0_rot_inv: tip0_inv.rotation.to_rotation_matrix().into_inner(),
            reach_min,
            reach_max,
        })
    }

    /// The arm of an SRDF chain group (e.g. `left_arm`).
    pub fn from_group(robot: &Robot, group: &str) -> Result<SrsArm, SrsError> {
        let chain =
            Chain::from_group(robot, group).ok_or_else(|| SrsError::NoChain(group.to_string()))?;
        SrsArm::new(robot, &chain)
    }

    /// The chain this arm was built from.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// Robot configuration variable of each of the 7 arm joints (chain order).
    pub fn vars(&self) -> &[usize; 7] {
        &self.vars
    }

    /// Names of the 7 arm joints.
    pub fn joint_names(&self) -> &[String; 7] {
        &self.names
    }

    /// Limits of the 7 arm joints.
    pub fn limits(&self) -> &[Limits; 7] {
        &self.limits
    }

    /// Shoulder centre (chain-base frame, zero configuration; it never moves).
    pub fn shoulder_centre(&self) -> Vector3<f64> {
        self.s
    }

    /// Wrist centre at the zero configuration (chain-base frame).
    pub fn wrist_centre(&self) -> Vector3<f64> {
        self.w
    }

    /// Elbow axis at the zero configuration: (unit direction, a point on it), chain-base frame.
    pub fn elbow_axis(&self) -> (Vector3<f64>, Vector3<f64>) {
        (self.k[3], self.p[3])
    }

    /// Maximum shoulder–wrist distance (stretched elbow), joint limits ignored.
    pub fn reach(&self) -> f64 {
        self.reach_max
    }

    /// Minimum shoulder–wrist distance (folded elbow), joint limits ignored.
    pub fn min_reach(&self) -> f64 {
        self.reach_min
    }

    /// Writes an arm solution into a full robot configuration.
    pub fn to_config(&self, sol: &[f64; 7], q: &mut [f64]) {
        for (i, &v) in self.vars.iter().enumerate() {
            q[v] = sol[i];
        }
    }

    /// Reads the 7 arm values out of a full robot configuration.
    pub fn from_config(&self, q: &[f64]) -> [f64; 7] {
        std::array::from_fn(|i| q[self.vars[i]])
    }

    /// True when every value is within its joint's limits.
    pub fn within_limits(&self, q7: &[f64; 7]) -> bool {
        q7.iter()
            .zip(&self.limits)
            .all(|(&v, l)| v.is_finite() && l.contains(v))
    }

    /// Tip pose in the chain-base frame (same as `Chain::tip_pose`, without the robot).
    pub fn fk(&self, q7: &[f64; 7]) -> Pose {
        let mut t = Pose::identity();
        for ((pre, axis), &v) in self.pre.iter().zip(&self.local_axis).zip(q7) {
            t = t * pre * joint_motion(JointKind::Revolute, axis, v);
        }
        t * self.tail
    }

    /// Unit target direction u and the ψ = 0 direction n (⟂ u).
    #[inline]
    fn target_frame(u: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        let r = -Vector3::z();
        let mut n = r - u * u.dot(&r);
        if n.norm() < 1e-6 {
            let r = Vector3::x();
            n = r - u * u.dot(&r);
        }
        (n.normalize(), u.cross(&n.normalize()))
    }

    /// Arm frame `[â, p, m]` for elbow angle θ4 (shoulder at zero); `None` if the elbow axis is
    /// parallel to the shoulder–wrist line.
    #[inline]
    fn arm_frame(&self, theta4: f64) -> Option<Matrix3<f64>> {
        let (k4, p4) = (&self.k[3], &self.p[3]);
        let w4 = rot(k4, theta4) * (self.w - p4) + p4;
        let a = (w4 - self.s).try_normalize(1e-12)?;
        let m = (k4 - a * a.dot(k4)).try_normalize(1e-9)?;
        let p = m.cross(&a);
        Some(Matrix3::from_columns(&[a, p, m]))
    }

    /// The arm angle ψ of a configuration (see the module docs): `solve(fk(q), arm_angle(q))`
    /// contains `q`. Returns 0 when ψ is undefined (wrist at the shoulder, elbow axis along
    /// the shoulder–wrist line).
    pub fn arm_angle(&self, q7: &[f64; 7]) -> f64 {
        let Some(f) = self.arm_frame(q7[3]) else {
            return 0.0;
        };
        let rsh = rot(&self.k[0], q7[0]) * rot(&self.k[1], q7[1]) * rot(&self.k[2], q7[2]);
        let u = rsh * f.column(0);
        let d = rsh * f.column(1);
        let (n, un) = Self::target_frame(&u);
        atan2(d.dot(&un), d.dot(&n))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits(lower: f64, upper: f64, bounded: bool) -> Limits {
        Limits {
            lower,
            upper,
            velocity: 1.0,
            effort: 1.0,
            bounded,
        }
    }

    #[test]
    fn euler3_roundtrip() {
        let k1 = Vector3::z();
        let k2 = Vector3::new(0.3, 1.0, 0.1).normalize();
        let k3 = Vector3::new(1.0, -0.2, 0.4).normalize();
        let r = rot(&k1, 0.7) * rot(&k2, -1.1) * rot(&k3, 2.5);
        let mut out = [[Angle::default(); 3]; 2];
        let all = ArcTest::new(&limits(0.0, 0.0, false));
        let n = Triple::new(&k1, &k2, &k3).solve(&r, &[all; 3], &mut out);
        assert!(n >= 1);
        for a in &out[..n] {
            for x in a {
                let v = x.value();
                assert!((x.s - v.sin()).abs() < 1e-12 && (x.c - v.cos()).abs() < 1e-12);
            }
        }
        let out = out.map(|a| a.map(|x| x.value()));
        for s in &out[..n] {
            let r2 = rot(&k1, s[0]) * rot(&k2, s[1]) * rot(&k3, s[2]);
            assert!((r2 - r).norm() < 1e-12);
        }
        assert!(out[..n]
            .iter()
            .any(|s| (s[0] - 0.7).abs() < 1e-9 && (s[1] + 1.1).abs() < 1e-9));
    }

    #[test]
    fn arc_test_never_rejects_an_angle_within_limits() {
        let ranges = [
            (-0.5, 1.0),
            (-2.9, 2.9),
            (0.0, 3.1),
            (-3.1, 3.13),
            (-1e-4, 1e-4),
            (1.0, 1.0 + 2.0 * PI),
            (-6.0, 6.0),
        ];
        for (lower, upper) in ranges {
            let l = limits(lower, upper, true);
            let arc = ArcTest::new(&l);
            let n = 20_000;
            let (mut inside, mut rejected_outside) = (0, 0);
            for i in 0..=n {
                let v = lower - 0.3 + (upper - lower + 0.6) * i as f64 / n as f64;
                for k in [-2.0, 0.0, 1.0] {
                    let a = v + 2.0 * PI * k;
                    let ang = Angle::of(a.sin() * 3.0, a.cos() * 3.0);
                    let admitted = arc.admits(&ang);
                    if into_limits(ang.value(), &l).is_some() {
                        inside += 1;
                        assert!(admitted, "{a} in [{lower}, {upper}] rejected");
                    } else if !admitted {
                        rejected_outside += 1;
                    }
                }
            }
            assert!(inside > 0);
            // Where the filter is active it rejects what lies clearly outside.
            if arc.min_cos > -1.0 {
                assert!(rejected_outside > 0, "[{lower}, {upper}]");
            }
        }
        // Exact boundaries, and NaN.
        let l = limits(-0.5, 1.0, true);
        let arc = ArcTest::new(&l);
        for v in [-0.5f64, 1.0, -0.5 - 5e-11, 1.0 + 5e-11] {
            assert!(arc.admits(&Angle::of(v.sin(), v.cos())));
        }
        assert!(!arc.admits(&Angle::of(f64::NAN, 1.0)));
        assert!(!arc.admits(&Angle::of(1.4f64.sin(), 1.4f64.cos())));
    }

    #[test]
    fn limits_mapping() {
        let l = limits(-0.5, 1.0, true);
        assert_eq!(
            into_limits(0.2 + 2.0 * PI, &l).map(|v| (v - 0.2).abs() < 1e-12),
            Some(true)
        );
        assert_eq!(into_limits(2.0, &l), None);
    }
}
