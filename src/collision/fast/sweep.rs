//! Swept-volume bounds of the [`FastChecker`]'s motion checks: the certified check of a
//! continuous straight motion ([`FastChecker::segment_certified`], what planners use), and the
//! discrete check that skips states ([`FastChecker::segment_free_skipping`], the verdict of
//! checking every state at the resolution; tests).
//!
//! Every moving body (robot link or attached object) has speed bounds per variable
//! ([`crate::kinematics::FkModel::speed_bounds`] of its bounding sphere): along the segment
//! `a → b` no point of body `i` travels farther than `L_i = Σ_v |b_v − a_v| · w_iv`, uniformly
//! in the segment parameter; a body's whole-chain `L_i` is the smaller of that and its
//! configuration-dependent bound along the segment (`travel.rs`: the joint motions summed as
//! vectors at the midpoints of a few pieces, plus a second-order term for their change, proven
//! against dense forward kinematics in its test). A run of states between parameters `t0` and `t1` is free when both
//! its end states are free with every body's primitives grown by `L_i · (t1 − t0) / 2` (each
//! state of the run lies within that distance of one end, the same certificate as
//! [`crate::collision::SphereChecker::segment_certified`]; Schwarzer, Saha & Latombe, IEEE T-RO
//! 2005, with inflated primitives instead of distances). For a pair of moving bodies only the
//! joints below their first common ancestor count (the ones above move both rigidly), on both
//! sides (the pair's primitives are grown by the sum), or their whole chains' bounds when that
//! sum is smaller (both bodies' travels in the world bound their relative motion too: a point
//! where they meet in a run lies within `L_a·δ` of a point of `a` and `L_b·δ` of a point of
//! `b` at the run's end); for a body against a fixed one all of them; bodies of different
//! robots count their whole chains. Growing a primitive's radii and
//! half extents by a distance contains its Minkowski sum with a ball of that radius, so the
//! test stays conservative.
//!
//! **Certified check — what is proven, under which bound.** The motion is cut into the fewest
//! equal runs whose largest body inflation is at most the coarse inflation (6 cm by default);
//! every run end (both ends of the motion included) is checked with the inflation of a run, each
//! pair free with the plain primitives but not with the grown ones ("tight") logged with the
//! largest inflation of a halving sequence it is free with there. A run with a tight end is
//! halved, level by level: its ends need no new check (a pair is tight there at a level when its
//! inflation for a run of that length exceeds what it is free with — free with the larger
//! inflation is free with the smaller), its midpoint is checked against the pairs tight at
//! either end (every other pair is proven free along the whole run). A motion of at most
//! `certify::MIDPOINT_RUNS` runs checks each run's midpoint first, with the run's inflation (every state
//! of a run lies within half its travel of the midpoint): all free proves the motion with one
//! state fewer per run; otherwise the runs are halved, the midpoints serve as run ends of the
//! finer level with their tight pairs logged, and the remaining ends are checked. A pair whose
//! travel bound along the motion is 0 (its bodies keep their relative pose) collides in every
//! state or in none, and is checked in the first state only. The answer is free only when every run is proven free; a state in
//! collision (plain primitives) answers collision; a run still tight when the largest body
//! inflation would fall below [`CERTIFY_FLOOR`] (1 µm), or more than 4 096 runs to halve,
//! answers "unproven", which planners treat as not free. What is proven: no configuration
//! `a + (b − a)·t`, t ∈ [0, 1], collides in the fast model, which contains the exact geometry
//! (primitives grown by 1e-9 m and the padding; meshes as the box around their vertices), for
//! every pair of the world's pair list (robot links, attached objects, fixed bodies, several
//! robots). The bounds assume prismatic variables within their limits (checked) and finite
//! speeds (a prismatic joint without limits: never certified).
//!
//! Owns the sweep model and its buffers; works on the checker's prepared frames and must not
//! depend on planning.

use super::{dist2_point_aabb, FastChecker};

mod certify;
mod travel;

pub(super) use certify::CERTIFY_FLOOR;

/// What an inflated check of one state found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Inflated {
    /// Free with every body inflated.
    Free,
    /// Free with the plain primitives, not with the inflated ones.
    Tight,
    /// A collision with the plain primitives.
    Hit,
}

/// The speed bounds of the moving bodies and the per-segment buffers.
#[derive(Debug, Clone, Default)]
pub(super) struct Sweep {
    /// False when some body's speed is unbounded (a prismatic joint without limits).
    bounded: bool,
    /// `(world variable, w)` of every body's joints from its mount up to the root;
    /// body `i` owns `chain[range[i].0..range[i].1]`.
    chain: Vec<(u32, f64)>,
    /// Per `chain` entry: its joint's axis, signed multiplier and kind (`None`: a zero axis),
    /// for the second-order sums of [`FastChecker::segment_lengths`].
    axes: Vec<Option<crate::kinematics::SpeedAxis>>,
    /// Per `chain` entry: the static bound of the ball centre's distance from a revolute
    /// joint's axis (`w / |mul|`, with the radius; 0 otherwise), for the second-order term.
    rs: Vec<f64>,
    /// Every robot's movable joints in forward-kinematics order `(robot, parent link, child
    /// link, world variable, axis)`, and per robot and computed link the sums over the joints
    /// from the root to it (for the current bound piece): `Σ Δθ·z` of the revolute ones (the
    /// link's angular velocity `Ω`), `Σ Δθ·z × o` (`Γ`) and `Σ Δθ·z` of the prismatic ones
    /// (`P`); a point `c` of the link moves at `Ω × c − Γ + P`.
    tree: Vec<(u32, u32, u32, u32, Option<crate::kinematics::SpeedAxis>)>,
    link_sums: Vec<Vec<[nalgebra::Vector3<f64>; 3]>>,
    /// Per body: the whole chain's vector bound summed over the pieces so far, and the
    /// second-order sum `M` for the whole segment (negative: no vector bound).
    body_vec: Vec<f64>,
    body_m: Vec<f64>,
    range: Vec<(u32, u32)>,
    /// Per body: the world variables of its chain as a bit set (all bits when one is 64 or
    /// more), so the travel bounds skip the bodies a segment does not move.
    body_vars: Vec<u64>,
    /// Running sums of `|Δq_v| · w` along each body's chain (`chain length + 1` entries
    /// from `cum_off[i]`), for the current segment.
    cum: Vec<f64>,
    cum_off: Vec<u32>,
    /// Per pair of the checker's list: the two entries of `cum` whose sum bounds the relative
    /// motion (a body against a fixed one: its whole chain and its entry 0, which is 0; two
    /// moving bodies: each chain below their first common ancestor).
    pair_cum: Vec<(u32, u32)>,
    /// Per pair: the two entries of `cum` for the bodies' whole chains (a body against a fixed
    /// one: as `pair_cum`). The sum of two bodies' travels in the world bounds their relative
    /// motion too, and a whole chain's bound may be the tighter one: the configuration-dependent
    /// bound of `travel.rs` tightens whole chains only.
    pair_whole: Vec<(u32, u32)>,
    /// Per pair, for the current segment: the smaller of the two sums (`pair_cum`,
    /// `pair_whole`) — how far the pair's bodies move relative to each other.
    pair_len: Vec<f64>,
    /// How many pairs (the first ones) are against fixed bodies.
    static_pairs: usize,
    /// Per pair, for the current inflation: the distance its primitives are grown by and the
    /// squared reach of its bounding-sphere cull.
    pair_d: Vec<f64>,
    pair_reach2: Vec<f64>,
    /// Per pair: the reach of its cull without growth (bounding-sphere radii), contiguous
    /// for `set_inflation` (read from the bodies it measured 5 % slower on IK-RRT).
    pair_reach0: Vec<f64>,
    /// The pairs in runs `(first pair, end pair, body, mount)` of consecutive pairs: a moving
    /// body `a` against moving bodies that ride on one link (a hand's links in a checker that
    /// freezes the fingers), or a fixed body against moving bodies on one link; the spheres
    /// around the bodies of each mount link `(robot, link, centre in the link frame, radius)`;
    /// per run, the reach of its cull without growth (the mount sphere's radius, plus `a`'s
    /// against a moving body) and, for the current inflation, squared with the largest growth
    /// of its pairs. A run whose mount sphere cannot reach `a` (or the fixed body's box) holds
    /// no pair that the pairs' own culls would let through: a body's sphere lies in its mount's.
    static_runs: Vec<Run>,
    runs: Vec<Run>,
    mounts: Vec<MountSphere>,
    /// The mounts of the runs of more than one pair (the others are not culled by run).
    used_mounts: Vec<u32>,
    static_run_reach0: Vec<f64>,
    static_run_reach2: Vec<f64>,
    run_reach0: Vec<f64>,
    run_reach2: Vec<f64>,
    /// Per run, for the current segment: whether every pair of it keeps its relative pose
    /// along the whole segment (travel bound 0): such a pair collides in every state of the
    /// segment or in none, so one check of it proves the segment for it.
    static_run_still: Vec<bool>,
    run_still: Vec<bool>,
    /// Whether any run is still.
    any_still: bool,
    /// The farthest any body travels along the current segment, and half the current run's
    /// share of the segment (a body's inflation is `scale` times its travel).
    lmax: f64,
    scale: f64,
    /// World variables that drive a prismatic joint, with their limits: the speed bounds
    /// count the joint's travel within its limits, so a certified motion must stay inside them.
    prismatic: Vec<(u32, f64, f64)>,
    // Buffers.
    q: Vec<f64>,
    order: Vec<u32>,
    order_n: usize,
    ends: Vec<End>,
    /// Certification: tight pair lists (index ranges into `pool`) of the coarse states, the
    /// pair lists themselves, the refinement stack and a scratch pair list.
    state_tight: Vec<(u32, u32)>,
    pool: Vec<u32>,
    /// Per pool entry: the largest inflation the pair is free with at that state.
    pool_d: Vec<f64>,
    stack: Vec<Refine>,
    next: Vec<Refine>,
    focus: Vec<u32>,
}

/// A run of pairs ([`Sweep::runs`]): first pair, end pair, the body all its pairs share, the
/// mount link (index into [`Sweep::mounts`]) of the other bodies.
type Run = (u32, u32, u32, u32);

/// The sphere around the bodies riding on one link ([`Sweep::mounts`]): robot, link, centre in
/// the link frame, radius.
type MountSphere = (usize, usize, nalgebra::Vector3<f64>, f64);

/// Runs and the reach of each without growth ([`Sweep::run_reach0`]).
type RunsReach = (Vec<Run>, Vec<f64>);

/// A run `[t0, t1]` of a certified check still to prove: the pairs tight at each end with the
/// inflation of a run of its length (ranges into the pool). Every other pair is already proven
/// free along the run.
#[derive(Debug, Clone, Copy)]
struct Refine {
    t0: f64,
    t1: f64,
    e0: (u32, u32),
    e1: (u32, u32),
}

/// A run end in [`FastChecker::segment_free_skipping`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum End {
    Free,
    Tight,
    /// The segment's start state, in collision (not a state the check is about).
    Blocked,
}

impl Sweep {
    /// The sweep model of `c`'s bodies and pairs (after the pair list is final).
    pub(super) fn new(c: &FastChecker) -> Sweep {
        let mut chain = Vec::new();
        let mut axes = Vec::new();
        let mut range = Vec::with_capacity(c.moving.len());
        let mut cum_off = Vec::with_capacity(c.moving.len());
        let mut bounded = true;
        let mut cum_len = 0u32;
        for b in &c.moving {
            let first = chain.len() as u32;
            let r = b.mount.robot;
            let placed = &c.world.robots[r];
            match c.fk[r].speed_bounds(&placed.robot, b.mount.link, &b.bc, b.br) {
                Some(s) => {
                    let ax = c.fk[r].speed_axes(b.mount.link);
                    debug_assert_eq!(ax.len(), s.len());
                    let n = s.len();
                    chain.extend(
                        s.into_iter()
                            // 1e-9 relative: rounding of the bound itself never makes it too small.
                            .map(|(v, w)| ((placed.offset + v) as u32, w * (1.0 + 1e-9))),
                    );
                    axes.extend(ax.into_iter().chain(std::iter::repeat(None)).take(n));
                }
                None => bounded = false,
            }
            range.push((first, chain.len() as u32));
            cum_off.push(cum_len);
            cum_len += chain.len() as u32 - first + 1;
        }
        // Computed links from each body's mount up to the root (chain entry k is the joint
        // whose child is `up[k]`: the checker's models are reduced, every joint in them moves).
        let up: Vec<Vec<usize>> = c
            .moving
            .iter()
            .map(|b| c.fk[b.mount.robot].ancestors(b.mount.link))
            .collect();
        let below_common = |a: usize, b: usize| -> usize {
            let n = (range[a].1 - range[a].0) as usize;
            if c.moving[a].mount.robot != c.moving[b].mount.robot {
                return n;
            }
            up[a]
                .iter()
                .position(|l| up[b].contains(l))
                .unwrap_or(n)
                .min(n)
        };
        let pair_whole = c
            .pairs
            .iter()
            .map(|p| {
                let a = p.a as usize;
                let whole = |i: usize| cum_off[i] + range[i].1 - range[i].0;
                if p.b_static {
                    (whole(a), cum_off[a])
                } else {
                    (whole(a), whole(p.b as usize))
                }
            })
            .collect();
        let pair_cum = c
            .pairs
            .iter()
            .map(|p| {
                let a = p.a as usize;
                if p.b_static {
                    let n = range[a].1 - range[a].0;
                    (cum_off[a] + n, cum_off[a])
                } else {
                    let b = p.b as usize;
                    (
                        cum_off[a] + below_common(a, b) as u32,
                        cum_off[b] + below_common(b, a) as u32,
                    )
                }
            })
            .collect();
        let rs: Vec<f64> = chain
            .iter()
            .zip(&axes)
            .map(|(&(_, w), ax)| match ax {
                Some(ax) if ax.revolute && ax.mul != 0.0 => w / ax.mul.abs(),
                _ => 0.0,
            })
            .collect();
        let mut tree = Vec::new();
        for (r, p) in c.world.robots.iter().enumerate() {
            for (parent, child, v, ax) in c.fk[r].movable_joints() {
                tree.push((
                    r as u32,
                    parent as u32,
                    child as u32,
                    (p.offset + v) as u32,
                    ax,
                ));
            }
        }
        let link_sums = c
            .link_poses
            .iter()
            .map(|l| vec![[nalgebra::Vector3::zeros(); 3]; l.len()])
            .collect();
        let np = c.pairs.len();
        let mut prismatic = Vec::new();
        for p in &c.world.robots {
            for j in &p.robot.joints {
                if j.kind != crate::model::JointKind::Prismatic {
                    continue;
                }
                if let Some(v) = j.var.or(j.mimic.as_ref().map(|m| m.var)) {
                    let lim = p.robot.var_limits(v);
                    if !lim.bounded {
                        continue;
                    }
                    let wv = (p.offset + v) as u32;
                    if !prismatic.iter().any(|&(x, _, _)| x == wv) {
                        prismatic.push((wv, lim.lower, lim.upper));
                    }
                }
            }
        }
        let body_vars = range
            .iter()
            .map(|&(c0, c1)| {
                chain[c0 as usize..c1 as usize]
                    .iter()
                    .fold(0u64, |m, &(v, _)| {
                        m | 1u64.checked_shl(v).unwrap_or(u64::MAX)
                    })
            })
            .collect();
        let (mounts, (static_runs, static_run_reach0), (runs, run_reach0)) = mount_runs(c);
        let mut used_mounts: Vec<u32> = static_runs
            .iter()
            .chain(&runs)
            .filter(|r| r.1 - r.0 > 1)
            .map(|r| r.3)
            .collect();
        used_mounts.sort_unstable();
        used_mounts.dedup();
        Sweep {
            used_mounts,
            static_run_reach2: vec![0.0; static_runs.len()],
            static_run_still: vec![false; static_runs.len()],
            run_still: vec![false; runs.len()],
            any_still: false,
            static_runs,
            static_run_reach0,
            run_reach2: vec![0.0; runs.len()],
            runs,
            mounts,
            run_reach0,
            prismatic,
            state_tight: Vec::new(),
            pool: Vec::new(),
            pool_d: Vec::new(),
            stack: Vec::new(),
            next: Vec::new(),
            focus: Vec::new(),
            pair_reach0: c
                .pairs
                .iter()
                .map(|p| {
                    let rb = if p.b_static {
                        0.0
                    } else {
                        c.moving[p.b as usize].br
                    };
                    c.moving[p.a as usize].br + rb
                })
                .collect(),
            pair_d: vec![0.0; np],
            pair_reach2: vec![0.0; np],
            bounded,
            chain,
            axes,
            rs,
            tree,
            link_sums,
            body_vec: vec![0.0; c.moving.len()],
            body_m: vec![-1.0; c.moving.len()],
            body_vars,
            range,
            cum: vec![0.0; cum_len as usize],
            cum_off,
            pair_cum,
            pair_whole,
            pair_len: vec![0.0; np],
            static_pairs: c.pairs.iter().take_while(|p| p.b_static).count(),
            lmax: 0.0,
            scale: 0.0,
            q: vec![0.0; c.world.dof()],
            order: Vec::new(),
            order_n: 0,
            ends: Vec::new(),
        }
    }

    /// Mount spheres ([`Sweep::runs`]).
    pub(super) fn mount_count(&self) -> usize {
        self.mounts.len()
    }

    /// The distance each body's points travel along `a → b` (the running sums `cum`, the
    /// largest in `lmax`).
    fn lengths(&mut self, a: &[f64], b: &[f64]) {
        self.lmax = 0.0;
        for (i, &(c0, c1)) in self.range.iter().enumerate() {
            let o = self.cum_off[i] as usize;
            let mut l = 0.0;
            self.cum[o] = 0.0;
            for (k, &(v, w)) in self.chain[c0 as usize..c1 as usize].iter().enumerate() {
                let v = v as usize;
                l += (b[v] - a[v]).abs() * w;
                self.cum[o + k + 1] = l;
            }
            self.lmax = self.lmax.max(l);
        }
    }

    /// Inflations for runs of length `h` (segment parameter): every pair's growth and cull
    /// reach.
    fn set_inflation(&mut self, h: f64) {
        self.scale = 0.5 * h;
        let cum = &self.cum;
        // Pairs against fixed bodies come first: their length is the moving body's whole
        // chain (`pair_cum` and `pair_whole` agree, the fixed side's entry is 0).
        let ns = self.static_pairs;
        for (len, &(ca, _)) in self.pair_len[..ns].iter_mut().zip(&self.pair_cum[..ns]) {
            *len = cum[ca as usize];
        }
        for ((len, &(ca, cb)), &(wa, wb)) in self.pair_len[ns..]
            .iter_mut()
            .zip(&self.pair_cum[ns..])
            .zip(&self.pair_whole[ns..])
        {
            *len = (cum[ca as usize] + cum[cb as usize]).min(cum[wa as usize] + cum[wb as usize]);
        }
        let scale = self.scale;
        for (((d, r2), &len), &r0) in self
            .pair_d
            .iter_mut()
            .zip(self.pair_reach2.iter_mut())
            .zip(&self.pair_len)
            .zip(&self.pair_reach0)
        {
            *d = scale * len;
            let reach = r0 + *d;
            *r2 = reach * reach;
        }
        let mut any_still = false;
        for (runs, reach0, reach2, still) in [
            (
                &self.static_runs,
                &self.static_run_reach0,
                &mut self.static_run_reach2,
                &mut self.static_run_still,
            ),
            (
                &self.runs,
                &self.run_reach0,
                &mut self.run_reach2,
                &mut self.run_still,
            ),
        ] {
            for (ri, &(first, end, _, _)) in runs.iter().enumerate() {
                let d = self.pair_d[first as usize..end as usize]
                    .iter()
                    .fold(0.0f64, |m, &d| m.max(d));
                let reach = reach0[ri] + d;
                reach2[ri] = reach * reach;
                still[ri] = d == 0.0;
                any_still |= d == 0.0;
            }
        }
        self.any_still = any_still;
    }

    /// The inflation of pair `pi` for a run of length `h` (segment parameter) of the current
    /// segment.
    #[inline]
    fn inflation(&self, pi: usize, h: f64) -> f64 {
        0.5 * h * self.pair_len[pi]
    }

    /// The state `a + (b − a)·t` into `q`, as the motion validator computes its states
    /// (t = 1 included), bit for bit.
    fn load(&mut self, a: &[f64], b: &[f64], t: f64) {
        for ((q, &x), &y) in self.q.iter_mut().zip(a).zip(b) {
            *q = x + (y - x) * t;
        }
    }
}

impl FastChecker {
    /// Whether [`Self::segment_free_skipping`] may run for `a → b`: speeds bounded, sizes
    /// right, frozen variables unchanged.
    fn can_sweep(&self, a: &[f64], b: &[f64], max_inflation: f64) -> bool {
        let dof = self.world.dof();
        let inflation_ok = max_inflation.is_finite() && max_inflation > 0.0;
        if !(self.sweep.bounded && inflation_ok)
            || a.len() != dof
            || b.len() != dof
            || !a.iter().chain(b).all(|v| v.is_finite())
        {
            return false;
        }
        match &self.frozen {
            Some(f) => {
                let same = |q: &[f64]| f.fixed.iter().all(|&(v, x)| q[v].to_bits() == x.to_bits());
                same(a) && same(b)
            }
            None => true,
        }
    }

    /// Discrete motion check that skips what it can prove: `Some(true)` exactly when every
    /// state `a + (b − a)·k/n`, k = 1..=n, is free — the verdict of checking them one by one
    /// (the same states, computed the same way), so planners behave as with
    /// [`crate::collision::MotionValidator`]. Every `m`-th state is checked first (bisection
    /// order, the end first) with the bodies inflated for `m` steps, `m` the most steps whose
    /// inflation stays at most `max_inflation` metres (module documentation): a state in
    /// collision ends the check; a run of `m` steps between two states free with the inflation
    /// is free as a whole and not checked further; the states inside the other runs are checked
    /// one by one. `None` (check state by state instead) when that cannot save checks (`m` < 3)
    /// or the checker cannot bound the motion: a body with unbounded speed, or `a` or `b` moves
    /// a variable that a checker for active variables froze.
    pub fn segment_free_skipping(
        &mut self,
        a: &[f64],
        b: &[f64],
        n: usize,
        max_inflation: f64,
    ) -> Option<bool> {
        if n < 3 || !self.can_sweep(a, b, max_inflation) {
            return None;
        }
        let mut s = std::mem::take(&mut self.sweep);
        let ok = self.skip(&mut s, a, b, n, max_inflation);
        self.sweep = s;
        ok
    }

    fn skip(
        &mut self,
        s: &mut Sweep,
        a: &[f64],
        b: &[f64],
        n: usize,
        max_inflation: f64,
    ) -> Option<bool> {
        s.lengths(a, b);
        let lmax = s.lmax;
        let m = if lmax > 0.0 {
            (2.0 * max_inflation * n as f64 / lmax).floor()
        } else {
            n as f64
        };
        // (NaN, from an infinite length, also gives up.)
        if m.is_nan() || m < 3.0 {
            return None;
        }
        let m = (m as usize).min(n);
        let runs = n.div_ceil(m);
        // Every run is at most m steps long: the inflation of m steps covers each.
        s.set_inflation(m as f64 / n as f64);
        if s.order_n != runs {
            super::super::motion::bisection_order(runs, &mut s.order);
            s.order_n = runs;
        }
        s.ends.clear();
        s.ends.resize(runs + 1, End::Free);
        for idx in 0..=runs {
            let i = if idx < runs { s.order[idx] as usize } else { 0 };
            let k = (i * m).min(n);
            match self.check_state(s, a, b, k as f64 / n as f64) {
                // State 0 (`a`) is not one of the states asked about: its run is checked
                // state by state instead.
                Inflated::Hit if i == 0 => s.ends[0] = End::Blocked,
                Inflated::Hit => return Some(false),
                Inflated::Tight => s.ends[i] = End::Tight,
                Inflated::Free => {}
            }
        }
        // A run with an end free only without the inflation (or the start in collision):
        // its states one by one. (Measured on the kitchen wok and dropped: halving such runs
        // with the inflation, or checking the free end again with twice the inflation to cover
        // the run from one side, cost more checks than they saved — the hand stays within the
        // inflation of the wok along whole runs.)
        for i in 0..runs {
            if s.ends[i] == End::Free && s.ends[i + 1] == End::Free {
                continue;
            }
            for k in i * m + 1..((i + 1) * m).min(n) {
                if self.plain_state(s, a, b, k as f64 / n as f64) {
                    return Some(false);
                }
            }
        }
        Some(true)
    }

    /// Whether the state `a + (b − a)·t` collides (plain primitives).
    fn plain_state(&mut self, s: &mut Sweep, a: &[f64], b: &[f64], t: f64) -> bool {
        s.load(a, b, t);
        self.find(&s.q).is_some()
    }

    /// Checks the state `a + (b − a)·t` with the current inflations.
    fn check_state(&mut self, s: &mut Sweep, a: &[f64], b: &[f64], t: f64) -> Inflated {
        s.load(a, b, t);
        self.check_inflated(s, &s.q)
    }

    /// One state with every moving body grown by its inflation (pairs of moving bodies by the
    /// part of their motion below their common ancestor). `q` agrees with a frozen checker's
    /// fixed variables (the caller checked).
    fn check_inflated(&mut self, s: &Sweep, q: &[f64]) -> Inflated {
        self.check_inflated_logging(s, q, None, false)
    }

    /// [`Self::check_inflated`]; with `log`, every pair free with the plain primitives but not
    /// with the inflated ones is appended to it (all of them: the check goes on after the
    /// first), for the refinement of a certified check. With `skip_still`, the runs whose
    /// pairs keep their relative pose along the segment ([`Sweep::run_still`]) are not checked:
    /// the caller has checked them free in another state of the segment.
    fn check_inflated_logging(
        &mut self,
        s: &Sweep,
        q: &[f64],
        mut log: Option<&mut Vec<u32>>,
        skip_still: bool,
    ) -> Inflated {
        let logging = log.is_some();
        let skip_still = skip_still && s.any_still;
        self.checks += 1;
        if self.frozen.as_ref().and_then(|f| f.constant_hit).is_some() {
            return Inflated::Hit;
        }
        self.prepare(q);
        let d = s.scale * s.lmax;
        let (lo, hi) = (self.moving_lo.add_scalar(-d), self.moving_hi.add_scalar(d));
        let mut tight = false;
        // Runs of one pair are culled by the pair itself (no mount centre needed).
        for &m in &s.used_mounts {
            let (robot, link, c, _) = s.mounts[m as usize];
            let f = &self.link_poses[robot][link];
            self.mount_c[m as usize] = f.rot * c + f.t;
        }
        for ri in 0..s.static_runs.len() {
            let (first, end, sb, m) = s.static_runs[ri];
            if skip_still && s.static_run_still[ri] {
                continue;
            }
            let st = &self.statics[sb as usize];
            if (0..3).any(|k| st.lo[k] > hi[k] || st.hi[k] < lo[k])
                || (end - first > 1
                    && dist2_point_aabb(&self.mount_c[m as usize], &st.lo, &st.hi)
                        > s.static_run_reach2[ri])
            {
                continue;
            }
            for pi in first as usize..end as usize {
                if tight && !logging {
                    // Tight already: only a collision can change the answer.
                    if self.static_pair_hits(pi) {
                        return Inflated::Hit;
                    }
                    continue;
                }
                let p = self.pairs[pi];
                let (a, sb, d) = (p.a as usize, p.b as usize, s.pair_d[pi]);
                let st = &self.statics[sb];
                if dist2_point_aabb(&self.body_bc[a], &st.lo, &st.hi) > s.pair_reach2[pi]
                    || !self.static_prims_hit_by(a, sb, d)
                {
                    continue;
                }
                if d > 0.0 && !self.static_prims_hit(a, sb) {
                    tight = true;
                    if let Some(l) = log.as_deref_mut() {
                        l.push(pi as u32);
                    }
                } else {
                    return Inflated::Hit;
                }
            }
        }
        for ri in 0..s.runs.len() {
            let (first, end, a, m) = s.runs[ri];
            if skip_still && s.run_still[ri] {
                continue;
            }
            if end - first > 1
                && (self.body_bc[a as usize] - self.mount_c[m as usize]).norm_squared()
                    > s.run_reach2[ri]
            {
                continue;
            }
            for pi in first as usize..end as usize {
                if tight && !logging {
                    if self.moving_pair_hits(self.pairs[pi]) {
                        return Inflated::Hit;
                    }
                    continue;
                }
                let p = self.pairs[pi];
                let (a, b, d) = (p.a as usize, p.b as usize, s.pair_d[pi]);
                if (self.body_bc[a] - self.body_bc[b]).norm_squared() > s.pair_reach2[pi]
                    || !self.moving_prims_hit_by(a, b, d)
                {
                    continue;
                }
                if d > 0.0 && !self.moving_prims_hit(a, b) {
                    tight = true;
                    if let Some(l) = log.as_deref_mut() {
                        l.push(pi as u32);
                    }
                } else {
                    return Inflated::Hit;
                }
            }
        }
        if tight {
            Inflated::Tight
        } else {
            Inflated::Free
        }
    }
}

/// The mount spheres of [`Sweep::runs`], and the runs over `c`'s pairs against fixed bodies
/// and over its moving–moving pairs (its pair list final) with each run's reach without growth.
/// A mount sphere holds every body sphere of its link (grown by a relative 1e-12 and 1e-9 m
/// against round-off).
fn mount_runs(c: &FastChecker) -> (Vec<MountSphere>, RunsReach, RunsReach) {
    use nalgebra::Vector3;
    let mut mounts: Vec<MountSphere> = Vec::new();
    let mut body_mount = Vec::with_capacity(c.moving.len());
    for b in &c.moving {
        let key = (b.mount.robot, b.mount.link);
        let m = match mounts.iter().position(|m| (m.0, m.1) == key) {
            Some(m) => m,
            None => {
                mounts.push((key.0, key.1, Vector3::zeros(), 0.0));
                mounts.len() - 1
            }
        };
        body_mount.push(m);
    }
    for (m, mount) in mounts.iter_mut().enumerate() {
        let bodies = || {
            c.moving
                .iter()
                .zip(&body_mount)
                .filter(move |(_, &bm)| bm == m)
                .map(|(b, _)| b)
        };
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for b in bodies() {
            lo = lo.inf(&b.bc.add_scalar(-b.br));
            hi = hi.sup(&b.bc.add_scalar(b.br));
        }
        let centre = (lo + hi) * 0.5;
        let r = bodies()
            .map(|b| (b.bc - centre).norm() + b.br)
            .fold(0.0f64, f64::max);
        mount.2 = centre;
        mount.3 = r * (1.0 + 1e-12) + 1e-9;
    }
    // Against a fixed body `b`, runs of the moving bodies `a` on one mount; moving pairs `(a,
    // b)`, runs of the bodies `b` on one mount.
    let (mut static_runs, mut runs): (Vec<Run>, Vec<Run>) = (Vec::new(), Vec::new());
    for (pi, p) in c.pairs.iter().enumerate() {
        let (runs, body, m) = if p.b_static {
            (&mut static_runs, p.b, body_mount[p.a as usize] as u32)
        } else {
            (&mut runs, p.a, body_mount[p.b as usize] as u32)
        };
        match runs.last_mut() {
            Some(r) if r.1 as usize == pi && r.2 == body && r.3 == m => r.1 += 1,
            _ => runs.push((pi as u32, pi as u32 + 1, body, m)),
        }
    }
    let static_reach0 = static_runs
        .iter()
        .map(|&(_, _, _, m)| mounts[m as usize].3)
        .collect();
    let reach0 = runs
        .iter()
        .map(|&(_, _, a, m)| c.moving[a as usize].br + mounts[m as usize].3)
        .collect();
    (mounts, (static_runs, static_reach0), (runs, reach0))
}

/// The state `a + (b − a)·t` into `out`.
#[inline]
fn lerp(a: &[f64], b: &[f64], t: f64, out: &mut [f64]) {
    for ((q, &x), &y) in out.iter_mut().zip(a).zip(b) {
        *q = x + (y - x) * t;
    }
}

/// Parameter of state `k` of `runs` equal runs (1 exactly for the last).
#[inline]
fn run_param(k: usize, runs: usize) -> f64 {
    if k >= runs {
        1.0
    } else {
        k as f64 / runs as f64
    }
}
