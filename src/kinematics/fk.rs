//! Forward kinematics of every link in one pass over the (topologically ordered) tree.

use nalgebra::{Quaternion, Translation3, UnitQuaternion};

use crate::geometry::Pose;
use crate::model::{JointKind, Robot};

/// Motion of joint `j` at value `v` (in the joint frame).
#[inline]
pub(crate) fn joint_motion(
    kind: JointKind,
    axis: &nalgebra::Unit<nalgebra::Vector3<f64>>,
    v: f64,
) -> Pose {
    match kind {
        JointKind::Revolute | JointKind::Continuous => {
            // (cos v/2, axis · sin v/2) with the fast sin_cos (≤ 2 ulp of libm).
            let (sn, cs) = crate::geometry::sin_cos(0.5 * v);
            Pose::from_parts(
                Translation3::identity(),
                UnitQuaternion::new_unchecked(Quaternion::from_parts(cs, axis.into_inner() * sn)),
            )
        }
        JointKind::Prismatic => Pose::from_parts(
            Translation3::from(axis.into_inner() * v),
            UnitQuaternion::identity(),
        ),
        JointKind::Fixed => Pose::identity(),
    }
}

/// Poses of all links in the frame `base` is given in: `out[l] = base * T_root→l(q)`.
/// `out` must have `robot.links.len()` entries. Allocates nothing.
#[inline]
pub fn forward(robot: &Robot, base: &Pose, q: &[f64], out: &mut [Pose]) {
    debug_assert_eq!(out.len(), robot.links.len());
    debug_assert_eq!(q.len(), robot.dof());
    out[0] = *base;
    for (ji, j) in robot.joints.iter().enumerate() {
        let parent = out[j.parent];
        let local = if j.kind == JointKind::Fixed {
            j.origin
        } else {
            j.origin * joint_motion(j.kind, &j.axis, robot.joint_value(ji, q))
        };
        out[j.child] = parent * local;
    }
}

/// Pose of one link relative to the robot root (walks only the path to it).
pub fn link_pose(robot: &Robot, q: &[f64], link: usize) -> Pose {
    let mut pose = Pose::identity();
    let mut l = link;
    while let Some(ji) = robot.links[l].parent_joint {
        let j = &robot.joints[ji];
        pose = j.origin * joint_motion(j.kind, &j.axis, robot.joint_value(ji, q)) * pose;
        l = j.parent;
    }
    pose
}

/// Reusable FK buffer (one per thread), so hot loops allocate nothing.
#[derive(Debug, Clone)]
pub struct ForwardKinematics {
    pub poses: Vec<Pose>,
}

impl ForwardKinematics {
    pub fn new(robot: &Robot) -> Self {
        ForwardKinematics {
            poses: vec![Pose::identity(); robot.links.len()],
        }
    }

    /// Computes all link poses relative to `base` and returns them.
    pub fn compute(&mut self, robot: &Robot, base: &Pose, q: &[f64]) -> &[Pose] {
        forward(robot, base, q, &mut self.poses);
        &self.poses
    }
}

/// One movable joint of a chain, as [`FkModel::speed_axes`] gives it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeedAxis {
    /// Unit axis in the frame of the joint's child link.
    pub axis: nalgebra::Vector3<f64>,
    /// The joint moves by `mul · Δq` of its variable.
    pub mul: f64,
    /// Revolute or continuous (else prismatic).
    pub revolute: bool,
}

/// A rigid frame as rotation matrix + translation: cheaper to compose than quaternions, and the
/// form the collision checker consumes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    pub rot: nalgebra::Matrix3<f64>,
    pub t: nalgebra::Vector3<f64>,
}

impl Frame {
    pub fn identity() -> Frame {
        Frame {
            rot: nalgebra::Matrix3::identity(),
            t: nalgebra::Vector3::zeros(),
        }
    }

    pub fn from_pose(p: &Pose) -> Frame {
        Frame {
            rot: *p.rotation.to_rotation_matrix().matrix(),
            t: p.translation.vector,
        }
    }

    pub fn to_pose(&self) -> Pose {
        Pose::from_parts(
            Translation3::from(self.t),
            UnitQuaternion::from_matrix(&self.rot),
        )
    }

    #[inline]
    pub fn mul(&self, o: &Frame) -> Frame {
        Frame {
            rot: self.rot * o.rot,
            t: self.rot * o.t + self.t,
        }
    }

    #[inline]
    pub fn transform_point(&self, p: &nalgebra::Vector3<f64>) -> nalgebra::Vector3<f64> {
        self.rot * p + self.t
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum AxisKind {
    X,
    Y,
    Z,
    General,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct FkJoint {
    parent: u32,
    child: u32,
    kind: JointKind,
    axis_kind: AxisKind,
    axis: nalgebra::Vector3<f64>,
    origin: Frame,
    origin_rot_identity: bool,
    /// Variable index and (multiplier, offset) for mimic joints (1, 0 otherwise).
    var: u32,
    mul: f64,
    off: f64,
}

/// Forward kinematics precompiled for one robot: joints with principal axes rotate with six
/// multiplications, fixed joints with identity rotation only translate. Allocation-free.
///
/// The *reduced* model ([`FkModel::reduced`]) folds every fixed joint into the next movable
/// one: it computes only the frames of links that sit right after a movable joint (and the
/// root); every other link is rigidly attached to one of those ([`FkModel::mount`]).
#[derive(Debug, Clone)]
pub struct FkModel {
    joints: Vec<FkJoint>,
    /// Per joint (as `joints`): the variables its child's frame depends on, its own and its
    /// ancestors', as a bit set ([`FkModel::update`]); their union in `deps_all`. Empty when a
    /// variable index is 64 or more (`update` then computes every frame).
    deps: Vec<u64>,
    deps_all: u64,
    /// The variables of the movable joints (`deps_all` as a list), and those of the movable
    /// joints without a movable ancestor: when all of these move, every frame does.
    vars: Vec<u32>,
    root_vars: Vec<u32>,
    links: usize,
    /// Per link: the computed link it is rigidly attached to, and its offset from it.
    rep: Vec<u32>,
    offset: Vec<Option<Frame>>,
    /// Per link: the index in `joints` of the (first) joint whose child it is, `u32::MAX` for
    /// none; walks towards the root take O(1) per step (a chain of hundreds of links would
    /// otherwise cost O(links²) per walk).
    parent_of: Vec<u32>,
}

impl FkModel {
    /// The joint whose child is computed link `k`.
    #[inline]
    fn parent_joint(&self, k: u32) -> Option<&FkJoint> {
        self.parent_of
            .get(k as usize)
            .and_then(|&j| self.joints.get(j as usize))
    }

    pub fn new(robot: &Robot) -> FkModel {
        let joints = robot
            .joints
            .iter()
            .enumerate()
            .map(|(ji, j)| {
                let a = j.axis.into_inner();
                let axis_kind = if (a - nalgebra::Vector3::x()).norm() < 1e-15 {
                    AxisKind::X
                } else if (a - nalgebra::Vector3::y()).norm() < 1e-15 {
                    AxisKind::Y
                } else if (a - nalgebra::Vector3::z()).norm() < 1e-15 {
                    AxisKind::Z
                } else {
                    AxisKind::General
                };
                let (var, mul, off) = match (j.var, j.mimic) {
                    (Some(v), _) => (v as u32, 1.0, 0.0),
                    (None, Some(m)) => (m.var as u32, m.multiplier, m.offset),
                    _ => (u32::MAX, 0.0, 0.0),
                };
                let _ = ji;
                let origin = Frame::from_pose(&j.origin);
                FkJoint {
                    parent: j.parent as u32,
                    child: j.child as u32,
                    kind: if var == u32::MAX {
                        JointKind::Fixed
                    } else {
                        j.kind
                    },
                    axis_kind,
                    axis: a,
                    origin,
                    origin_rot_identity: (origin.rot - nalgebra::Matrix3::identity()).abs().max()
                        < 1e-15,
                    var,
                    mul,
                    off,
                }
            })
            .collect();
        let n = robot.links.len();
        FkModel {
            joints,
            deps: Vec::new(),
            deps_all: 0,
            vars: Vec::new(),
            root_vars: Vec::new(),
            links: n,
            rep: (0..n as u32).collect(),
            offset: vec![None; n],
            parent_of: Vec::new(),
        }
        .with_deps()
    }

    /// Fills [`FkModel::deps`] (joints come parents first).
    fn with_deps(mut self) -> FkModel {
        self.parent_of = vec![u32::MAX; self.links];
        for (i, j) in self.joints.iter().enumerate() {
            if let Some(p) = self.parent_of.get_mut(j.child as usize) {
                if *p == u32::MAX {
                    *p = i as u32;
                }
            }
        }
        self.deps.clear();
        self.deps_all = 0;
        if self
            .joints
            .iter()
            .any(|j| j.kind != JointKind::Fixed && j.var >= 64)
        {
            return self;
        }
        let mut link = vec![0u64; self.links];
        for j in &self.joints {
            let own = if j.kind == JointKind::Fixed {
                0
            } else {
                1u64 << j.var
            };
            let up = link[j.parent as usize];
            if up == 0 && own != 0 && self.root_vars.iter().all(|&v| v != j.var) {
                self.root_vars.push(j.var);
            }
            let d = up | own;
            link[j.child as usize] = d;
            self.deps.push(d);
            self.deps_all |= d;
        }
        self.vars = (0..64u32)
            .filter(|v| self.deps_all & (1 << v) != 0)
            .collect();
        self
    }

    /// The reduced model: only links after movable joints are computed.
    pub fn reduced(robot: &Robot) -> FkModel {
        FkModel::reduced_with(robot, None)
    }

    /// The reduced model for motions of the variables `active` only (`active[v]` for each
    /// robot variable): every joint driven by another variable is frozen at its value in `q`
    /// (a robot configuration) and folded in like a fixed joint. Links that no active variable
    /// moves are then mounted on the root ([`FkModel::mount`] gives link 0); the frames of
    /// this model equal those of [`FkModel::new`] for every configuration that agrees with `q`
    /// outside `active`.
    pub fn frozen(robot: &Robot, active: &[bool], q: &[f64]) -> FkModel {
        FkModel::reduced_with(robot, Some((active, q)))
    }

    fn reduced_with(robot: &Robot, freeze: Option<(&[bool], &[f64])>) -> FkModel {
        let full = FkModel::new(robot);
        let n = robot.links.len();
        let mut rep: Vec<u32> = (0..n as u32).collect();
        let mut offset: Vec<Option<Frame>> = vec![None; n];
        let mut joints = Vec::new();
        for j in &full.joints {
            let mut j = *j;
            if let Some((active, q)) = freeze {
                let v = j.var as usize;
                if j.kind != JointKind::Fixed && !active.get(v).copied().unwrap_or(false) {
                    // origin · motion(q[v]): the child frame under an identity parent.
                    j.origin = j.apply(&Frame::identity(), q);
                    j.kind = JointKind::Fixed;
                }
            }
            let j = &j;
            let (p, c) = (j.parent as usize, j.child as usize);
            let (prep, poff) = (rep[p], offset[p]);
            let origin = match &poff {
                Some(o) => o.mul(&j.origin),
                None => j.origin,
            };
            if j.kind == JointKind::Fixed {
                rep[c] = prep;
                offset[c] = Some(origin);
            } else {
                let mut fj = *j;
                fj.parent = prep;
                fj.origin = origin;
                fj.origin_rot_identity =
                    (origin.rot - nalgebra::Matrix3::identity()).abs().max() < 1e-15;
                joints.push(fj);
            }
        }
        FkModel {
            joints,
            deps: Vec::new(),
            deps_all: 0,
            vars: Vec::new(),
            root_vars: Vec::new(),
            links: n,
            rep,
            offset,
            parent_of: Vec::new(),
        }
        .with_deps()
    }

    /// The computed link that `link` is rigidly attached to and its offset from it (`None` when
    /// the link itself is computed).
    pub fn mount(&self, link: usize) -> (usize, Option<Frame>) {
        (self.rep[link] as usize, self.offset[link])
    }

    /// The computed links from `link`'s computed link up to the root, in order.
    pub fn ancestors(&self, link: usize) -> Vec<usize> {
        let mut out = vec![self.rep[link] as usize];
        let mut k = self.rep[link];
        while let Some(j) = self.parent_joint(k) {
            k = j.parent;
            out.push(k as usize);
        }
        out
    }

    /// A ball, in the frame of the computed link `ancestor`, that holds the sphere (`centre` in
    /// the frame of computed link `link`, `radius`) in every configuration within the joint
    /// limits: the sphere itself when `link` is `ancestor`; otherwise a ball about the origin of
    /// the first joint below `ancestor` (fixed in its frame) that covers the offsets and
    /// prismatic travel of the joints in between. `None` when `ancestor` is not an ancestor of
    /// `link` or a prismatic joint on the way has unbounded travel.
    pub fn reach_ball(
        &self,
        robot: &Robot,
        link: usize,
        centre: &nalgebra::Vector3<f64>,
        radius: f64,
        ancestor: usize,
    ) -> Option<(nalgebra::Vector3<f64>, f64)> {
        let mut k = self.rep[link];
        if k as usize == ancestor {
            return Some((*centre, radius));
        }
        let mut d = centre.norm() + radius;
        while let Some(j) = self.parent_joint(k) {
            let travel = match j.kind {
                JointKind::Prismatic => {
                    let lim = robot.var_limits(j.var as usize);
                    if !lim.bounded {
                        return None;
                    }
                    (j.mul * lim.lower + j.off)
                        .abs()
                        .max((j.mul * lim.upper + j.off).abs())
                }
                _ => 0.0,
            };
            if j.parent as usize == ancestor {
                let r = d + travel;
                return r.is_finite().then_some((j.origin.t, r));
            }
            d += j.origin.t.norm() + travel;
            k = j.parent;
        }
        None
    }

    /// Speed bounds of a ball (`centre` in the frame of computed link `link`, `radius`) for
    /// straight motions in joint space: one `(variable, w)` per movable joint from `link` up to
    /// the root, in that order, such that no point of the ball moves faster than `w` metres per
    /// unit of the variable through that joint. A revolute joint turns its child frame about an
    /// axis through that frame's origin, so a point moves at `|multiplier|` times its distance
    /// from that axis line: `w = |multiplier| · ρ` with `ρ` a bound of the ball's distance from
    /// the axis over every configuration of the joints below. For the first joint the ball is
    /// fixed in the child frame and `ρ` is exact (the centre's distance from the axis plus the
    /// radius); further up the ball lies within `D` of the lower joint's origin `t` (`D` its
    /// farthest distance from the lower frame's origin, growing by each joint's offset and
    /// prismatic travel on the way up), so `ρ ≤ dist(t, axis) + D`, and `ρ ≤ D + |t|` (the
    /// ball's farthest distance from this frame's origin) always. A prismatic joint gives
    /// `|multiplier|`. Summed over the joints, `Σ |Δq_v| · w` bounds how far any point of the
    /// ball travels along the segment (Schwarzer, Saha & Latombe, IEEE T-RO 2005, distance
    /// bounds of a link point along a joint-space segment). `None` when a prismatic joint on
    /// the way has unbounded travel.
    pub fn speed_bounds(
        &self,
        robot: &Robot,
        link: usize,
        centre: &nalgebra::Vector3<f64>,
        radius: f64,
    ) -> Option<Vec<(usize, f64)>> {
        let mut out = Vec::new();
        let mut k = self.rep[link];
        // The ball lies within `d` of the current frame's origin; its points are within
        // `base` of `at` (a point fixed in the current frame).
        let mut d = centre.norm() + radius;
        let (mut at, mut base) = (*centre, radius);
        while let Some(j) = self.parent_joint(k) {
            let (w, travel) = match j.kind {
                JointKind::Prismatic => {
                    let lim = robot.var_limits(j.var as usize);
                    if !lim.bounded {
                        return None;
                    }
                    let t = (j.mul * lim.lower + j.off)
                        .abs()
                        .max((j.mul * lim.upper + j.off).abs());
                    (j.mul.abs(), t)
                }
                JointKind::Fixed => (0.0, 0.0),
                JointKind::Revolute | JointKind::Continuous => {
                    let rho = (crate::geometry::distance_from_axis(&at, &j.axis) + base).min(d);
                    (j.mul.abs() * rho, 0.0)
                }
            };
            if j.kind != JointKind::Fixed {
                out.push((j.var as usize, w));
            }
            // In the parent frame: this joint's origin is fixed, the ball within `d + travel`
            // of it (the child frame's origin slides by at most `travel`).
            at = j.origin.t;
            base = d + travel;
            d += j.origin.t.norm() + travel;
            k = j.parent;
        }
        out.iter().all(|(_, w)| w.is_finite()).then_some(out)
    }

    /// The movable joints from `link` up to the root, in the order of [`Self::speed_bounds`]:
    /// per joint its unit axis in its child link's frame (a revolute
    /// joint turns about the axis line through the frame's origin; a prismatic one slides
    /// along it), its multiplier (signed: the joint moves by `multiplier · Δq` of its
    /// variable) and whether it is revolute (or continuous). `None` for a degenerate zero axis.
    pub fn speed_axes(&self, link: usize) -> Vec<Option<SpeedAxis>> {
        let mut out = Vec::new();
        let mut k = self.rep[link];
        while let Some(j) = self.parent_joint(k) {
            if j.kind != JointKind::Fixed {
                out.push(j.speed_axis());
            }
            k = j.parent;
        }
        out
    }

    /// Every movable joint in the order [`Self::compute`] visits them (parents first): its
    /// parent and child (computed) links, its variable and its axis ([`Self::speed_axes`]).
    pub fn movable_joints(&self) -> Vec<(usize, usize, usize, Option<SpeedAxis>)> {
        self.joints
            .iter()
            .filter(|j| j.kind != JointKind::Fixed)
            .map(|j| {
                (
                    j.parent as usize,
                    j.child as usize,
                    j.var as usize,
                    j.speed_axis(),
                )
            })
            .collect()
    }

    /// Number of links (length of the output slice).
    pub fn links(&self) -> usize {
        self.links
    }

    /// Frames of all links: `out[l] = base · T_root→l(q)`.
    #[inline]
    pub fn compute(&self, base: &Frame, q: &[f64], out: &mut [Frame]) {
        out[0] = *base;
        let mut t = Trig::new();
        for chunk in self.joints.chunks(TRIG_BATCH) {
            t.set(chunk, q);
            for (k, j) in chunk.iter().enumerate() {
                out[j.child as usize] = j.apply_sc(&out[j.parent as usize], q, t.s[k], t.c[k]);
            }
        }
    }

    /// [`Self::compute`] when `out` already holds the frames of the configuration `last` (same
    /// `base`): only the frames that depend on a variable whose value differs from `last` (bit
    /// for bit) are computed again (all of them when every movable joint without a movable
    /// ancestor moves); then `last` takes `q`'s values of the variables the frames depend on
    /// (the others are never read). Each frame comes from the same
    /// inputs by the same operations as in `compute`, so the frames are bit for bit the same.
    /// A planner that moves one arm of a two-armed robot recomputes that arm only.
    #[inline]
    pub fn update(&self, base: &Frame, q: &[f64], last: &mut [f64], out: &mut [Frame]) {
        let same = |v: u32| q[v as usize].to_bits() == last[v as usize].to_bits();
        if self.deps.len() != self.joints.len()
            || q.len() != last.len()
            || self.root_vars.iter().all(|&v| !same(v))
        {
            // Every frame moves (or the model has no dependency sets): all of them.
            self.compute(base, q, out);
        } else {
            let mut moved = 0u64;
            for &v in &self.vars {
                moved |= u64::from(!same(v)) << v;
            }
            if moved != 0 {
                out[0] = *base;
                let mut t = Trig::new();
                for (chunk, deps) in self
                    .joints
                    .chunks(TRIG_BATCH)
                    .zip(self.deps.chunks(TRIG_BATCH))
                {
                    // The moved joints' angles first, their sines and cosines in one batch.
                    let mut n = 0;
                    for (j, &d) in chunk.iter().zip(deps) {
                        if d & moved != 0 {
                            t.x[n] = j.angle(q);
                            n += 1;
                        }
                    }
                    t.eval(n);
                    let mut k = 0;
                    for (j, &d) in chunk.iter().zip(deps) {
                        if d & moved != 0 {
                            out[j.child as usize] =
                                j.apply_sc(&out[j.parent as usize], q, t.s[k], t.c[k]);
                            k += 1;
                        }
                    }
                }
            }
        }
        if q.len() == last.len() {
            for &v in &self.vars {
                last[v as usize] = q[v as usize];
            }
        }
    }
}

/// Joints per batch of [`Trig`]: the angles of a chunk of joints are known before its frames
/// are composed (they depend on `q` only), so their sines and cosines are evaluated together
/// ([`crate::geometry::sin_cos_lanes`], bit for bit the scalar values).
const TRIG_BATCH: usize = 16;

/// Angles of up to [`TRIG_BATCH`] joints and their sines and cosines (on the stack).
struct Trig {
    x: [f64; TRIG_BATCH],
    s: [f64; TRIG_BATCH],
    c: [f64; TRIG_BATCH],
}

impl Trig {
    #[inline(always)]
    fn new() -> Trig {
        Trig {
            x: [0.0; TRIG_BATCH],
            s: [0.0; TRIG_BATCH],
            c: [0.0; TRIG_BATCH],
        }
    }

    /// Takes the angles of `joints` (at most [`TRIG_BATCH`]) at `q`, with their sines and
    /// cosines. One `Trig` serves every chunk of a pass (created, zeroed, once per pass; lanes
    /// past the chunk's joints keep an earlier chunk's angles, whose results are never read).
    #[inline(always)]
    fn set(&mut self, joints: &[FkJoint], q: &[f64]) {
        for (x, j) in self.x.iter_mut().zip(joints) {
            *x = j.angle(q);
        }
        self.eval(joints.len());
    }

    /// Sines and cosines of the first `n` angles.
    #[inline(always)]
    fn eval(&mut self, n: usize) {
        crate::geometry::sin_cos_lanes(&self.x, &mut self.s, &mut self.c, n);
    }
}

impl FkJoint {
    /// This movable joint as [`FkModel::speed_axes`] gives it (`None` for a zero axis).
    fn speed_axis(&self) -> Option<SpeedAxis> {
        let n = self.axis.norm();
        (n > 0.0).then(|| SpeedAxis {
            axis: self.axis / n,
            mul: self.mul,
            revolute: self.kind != JointKind::Prismatic,
        })
    }

    /// The angle of a revolute joint at `q` (0 for other kinds, whose variable may not exist).
    #[inline(always)]
    fn angle(&self, q: &[f64]) -> f64 {
        match self.kind {
            JointKind::Revolute | JointKind::Continuous => {
                self.mul * q[self.var as usize] + self.off
            }
            _ => 0.0,
        }
    }

    /// Frame of the child link given the parent's frame `p`.
    #[inline(always)]
    fn apply(&self, p: &Frame, q: &[f64]) -> Frame {
        let (s, c) = crate::geometry::sin_cos(self.angle(q));
        self.apply_sc(p, q, s, c)
    }

    /// [`Self::apply`] given `(s, c) = sin_cos(self.angle(q))` (ignored unless revolute).
    #[inline(always)]
    fn apply_sc(&self, p: &Frame, q: &[f64], s: f64, c: f64) -> Frame {
        let (r0, t) = self.joint_frame(p);
        self.move_by(r0, t, q, s, c)
    }

    /// The joint's frame before its motion (the parent's frame `p` times the origin): rotation
    /// and translation.
    #[inline(always)]
    fn joint_frame(&self, p: &Frame) -> (nalgebra::Matrix3<f64>, nalgebra::Vector3<f64>) {
        let j = self;
        let t = p.rot * j.origin.t + p.t;
        let r0 = if j.origin_rot_identity {
            p.rot
        } else {
            p.rot * j.origin.rot
        };
        (r0, t)
    }

    /// The child's frame from the joint frame `(r0, t)` ([`Self::joint_frame`]) and the
    /// joint's motion at `q` (`(s, c)` its angle's sine and cosine when revolute).
    #[inline(always)]
    fn move_by(
        &self,
        r0: nalgebra::Matrix3<f64>,
        mut t: nalgebra::Vector3<f64>,
        q: &[f64],
        s: f64,
        c: f64,
    ) -> Frame {
        let j = self;
        let rot = match j.kind {
            JointKind::Fixed => r0,
            JointKind::Prismatic => {
                let v = j.mul * q[j.var as usize] + j.off;
                t += r0 * (j.axis * v);
                r0
            }
            JointKind::Revolute | JointKind::Continuous => {
                let v = j.mul * q[j.var as usize] + j.off;
                rotate_about_axis(&r0, j.axis_kind, &j.axis, v, s, c)
            }
        };
        Frame { rot, t }
    }
}

/// The pose of one link alone, relative to the robot root: the movable joints on its path with
/// the fixed ones folded in (as in [`FkModel::reduced`]), composed as matrices. Same result as
/// [`link_pose`] to rounding, for hot loops that need one frame per sample (an arm's base under
/// sampled hip joints, 000 §II-D). Allocation-free.
#[derive(Debug, Clone)]
pub struct FkPath {
    /// Root to the link's computed ancestor, in order.
    joints: Vec<FkJoint>,
    /// Offset of the link from that ancestor.
    tail: Option<Frame>,
}

impl FkPath {
    pub fn new(robot: &Robot, link: usize) -> FkPath {
        let model = FkModel::reduced(robot);
        let (mut at, tail) = model.mount(link);
        let mut joints = Vec::new();
        while let Some(j) = model.joints.iter().find(|j| j.child as usize == at) {
            joints.push(*j);
            at = j.parent as usize;
        }
        joints.reverse();
        FkPath { joints, tail }
    }

    /// Frame of the link: `T_root→link(q)`.
    #[inline]
    pub fn frame(&self, q: &[f64]) -> Frame {
        let mut f = Frame::identity();
        let mut t = Trig::new();
        for chunk in self.joints.chunks(TRIG_BATCH) {
            t.set(chunk, q);
            for (k, j) in chunk.iter().enumerate() {
                f = j.apply_sc(&f, q, t.s[k], t.c[k]);
            }
        }
        match &self.tail {
            Some(o) => f.mul(o),
            None => f,
        }
    }

    /// The variable each joint of the path moves, in order (with its multiplier: a mimic
    /// joint moves its master's variable).
    pub fn joint_vars(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.joints.iter().map(|j| (j.var as usize, j.mul))
    }

    /// The `cols` of [`Self::jacobian_into`] for a Jacobian whose columns are the robot
    /// variables `vars` (a chain's [`crate::kinematics::Chain::vars`]): per joint of the path,
    /// the position of its variable in `vars`, `usize::MAX` when absent.
    pub fn jacobian_columns(&self, vars: &[usize]) -> Vec<usize> {
        self.joint_vars()
            .map(|(v, _)| vars.iter().position(|&c| c == v).unwrap_or(usize::MAX))
            .collect()
    }

    /// The geometric Jacobian of the link (rows: linear then angular velocity, in the root
    /// frame) into `jac`, as [`crate::kinematics::Chain::jacobian_into`] computes it for the
    /// chain from the root to this link, in one pass of the frames [`Self::frame`] composes:
    /// `cols[k]` is the column of the path's joint k ([`Self::joint_vars`]; `usize::MAX` for
    /// none), whose axis `z` in the root frame adds `(z × (tip − p), z)` (revolute; `z`
    /// times the mimic multiplier) or `(z, 0)` (prismatic) at the joint's origin `p`. Returns
    /// the link's frame. Same values as the chain's Jacobian to rounding (matrices instead of
    /// quaternions, a few ulp), for the J+ steps of 000 Alg. 2.
    pub fn jacobian_into(
        &self,
        q: &[f64],
        cols: &[usize],
        jac: &mut nalgebra::Matrix6xX<f64>,
    ) -> Frame {
        jac.fill(0.0);
        let mut f = Frame::identity();
        let mut k0 = 0;
        let mut t = Trig::new();
        for chunk in self.joints.chunks(TRIG_BATCH) {
            t.set(chunk, q);
            for (k, j) in chunk.iter().enumerate() {
                let (r0, p) = j.joint_frame(&f);
                if let Some(&col) = cols.get(k0 + k).filter(|&&c| c < jac.ncols()) {
                    let z = r0 * (j.axis * j.mul);
                    let revolute = j.kind != JointKind::Prismatic;
                    let lin = if revolute { -z.cross(&p) } else { z };
                    let mut column = jac.column_mut(col);
                    for r in 0..3 {
                        column[r] += lin[r];
                        if revolute {
                            column[r + 3] += z[r];
                        }
                    }
                }
                f = j.move_by(r0, p, q, t.s[k], t.c[k]);
            }
            k0 += chunk.len();
        }
        let f = match &self.tail {
            Some(o) => f.mul(o),
            None => f,
        };
        for mut column in jac.column_iter_mut() {
            let w = nalgebra::Vector3::new(column[3], column[4], column[5]);
            let t = w.cross(&f.t);
            for r in 0..3 {
                column[r] += t[r];
            }
        }
        f
    }

    /// Pose of the link: `T_root→link(q)`.
    #[inline]
    pub fn pose(&self, q: &[f64]) -> Pose {
        path_pose(&self.frame(q))
    }

    /// This path together with the link of `prefix`, when `prefix`'s joints are the first
    /// joints of this path (same robot model; `None` otherwise): [`FkPathPair::poses`] gives
    /// both links' poses in one pass.
    pub fn with_prefix(&self, prefix: &FkPath) -> Option<FkPathPair> {
        self.joints.starts_with(&prefix.joints).then(|| FkPathPair {
            path: self.clone(),
            shared: prefix.joints.len(),
            prefix_tail: prefix.tail,
        })
    }
}

/// An [`FkPath`] and a second link on it ([`FkPath::with_prefix`]): an arm's tip and the other
/// arm's base under the same sampled hip (000 §III), their shared joints composed once.
#[derive(Debug, Clone)]
pub struct FkPathPair {
    path: FkPath,
    /// Joints of `path` that lead to the second link's computed ancestor.
    shared: usize,
    /// Offset of the second link from that ancestor.
    prefix_tail: Option<Frame>,
}

impl FkPathPair {
    /// `(path.pose(q), prefix.pose(q))` of the two paths [`FkPath::with_prefix`] was given, bit
    /// for bit: the same products in the same order (the batched sines and cosines equal the
    /// scalar ones), the shared joints composed once.
    #[inline]
    pub fn poses(&self, q: &[f64]) -> (Pose, Pose) {
        let joints = &self.path.joints;
        let mut f = Frame::identity();
        let mut at_prefix = f;
        let mut k0 = 0;
        let mut t = Trig::new();
        for chunk in joints.chunks(TRIG_BATCH) {
            t.set(chunk, q);
            for (k, j) in chunk.iter().enumerate() {
                if k0 + k == self.shared {
                    at_prefix = f;
                }
                f = j.apply_sc(&f, q, t.s[k], t.c[k]);
            }
            k0 += chunk.len();
        }
        if self.shared == joints.len() {
            at_prefix = f;
        }
        let tip = match &self.path.tail {
            Some(o) => f.mul(o),
            None => f,
        };
        let base = match &self.prefix_tail {
            Some(o) => at_prefix.mul(o),
            None => at_prefix,
        };
        (path_pose(&tip), path_pose(&base))
    }
}

/// The pose of a frame [`FkPath`] composed (its rotation taken as orthonormal as it is).
#[inline]
fn path_pose(f: &Frame) -> Pose {
    Pose::from_parts(
        Translation3::from(f.t),
        UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(f.rot)),
    )
}

/// `r · R_axis(v)` given `(s, c) = sin_cos(v)`: for a principal axis only two columns change.
#[inline(always)]
fn rotate_about_axis(
    r: &nalgebra::Matrix3<f64>,
    kind: AxisKind,
    axis: &nalgebra::Vector3<f64>,
    v: f64,
    s: f64,
    c: f64,
) -> nalgebra::Matrix3<f64> {
    let (x, y, z) = (r.column(0), r.column(1), r.column(2));
    match kind {
        AxisKind::Z => {
            nalgebra::Matrix3::from_columns(&[x * c + y * s, y * c - x * s, z.into_owned()])
        }
        AxisKind::Y => {
            nalgebra::Matrix3::from_columns(&[x * c - z * s, y.into_owned(), x * s + z * c])
        }
        AxisKind::X => {
            nalgebra::Matrix3::from_columns(&[x.into_owned(), y * c + z * s, z * c - y * s])
        }
        AxisKind::General => {
            r * nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_unchecked(*axis), v)
                .matrix()
        }
    }
}
