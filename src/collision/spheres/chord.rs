//! The chord certificate of the sphere checker's certified motion checks
//! ([`SphereChecker::segment_certified`]): a straight joint-space segment proven collision-free
//! from the robot's *computed* positions at a few states and a bound on how far each point can
//! stray from the straight line between two of them.
//!
//! Along `q(t) = a + t (b − a)`, a point `p` riding on a body has bounded *acceleration*
//! `|p''(t)| ≤ A` (below). The error of linear interpolation of a C² curve is at most
//! `A (t − t₀)(t₁ − t) / 2 ≤ A h² / 8` on a sub-interval of length `h`, so on `[t₀, t₁]` the
//! point stays within `δ = A h² / 8` of the chord `[p(t₀), p(t₁)]`, and a sphere of radius `r`
//! about it stays inside the ball about the chord's midpoint of radius
//! `r + δ + |p(t₁) − p(t₀)| / 2`. That ball free of an obstacle certifies the sphere free of it
//! over the whole sub-interval (and, as it contains both end spheres, both end states). For a
//! self pair the difference of the two points has acceleration at most `A_a + A_b`, and the same
//! argument applies to it: the pair is apart over the sub-interval when the ball about the
//! difference's chord midpoint, of radius `r_i + r_j + δ_a + δ_b + |Δd| / 2`, excludes the
//! origin — or, where that ball is loose, when the chord itself keeps `r_i + r_j + δ_a + δ_b`
//! from the origin ([`SphereChecker::CHORD_SEGMENT_MARGIN`]).
//!
//! The linear certificate ([`SphereChecker::segment_certified`]'s other form) inflates each state
//! by a bound on the *speed*, `Σ_v |Δq_v| w_v`, a sum of worst-case lever arms; the chord's half
//! length is the motion the arm actually makes, and the acceleration term shrinks with the square
//! of the sub-interval. Measured on a UR5-like arm's range-length segments: worst sphere's half
//! chord 0.023 m (median) over seventh-segments and δ 0.006 m, where the speed bound needs 16
//! states for 0.04 m; so one 8-state call usually certifies what took two or three.
//!
//! **The acceleration bound.** Joints `v` of the body's chain from the root, joint speeds
//! `s_v = |mul_v · Δq_v|`, revolute axes `ω_v` through a point `o_v` fixed in the parent link.
//! `p' = Σ_v q̇_v ω_v × (p − o_v)` (revolute) `+ Σ_v q̇_v ω_v` (prismatic), and differentiating
//! (`ω_v' = Σ_{u<v} q̇_u ω_u × ω_v`, `o_v'` the velocity of a point of the parent link):
//! `|p''| ≤ Σ_{v rev} s_v (2 W_{<v} D_v + Σ_{u≥v} s_u c_u) + Σ_{v pris} s_v W_{<v}`, where
//! `W_{<v}` sums the revolute speeds above `v`, `D_v ≥ |p − o_v|`, and `c_u` is `ρ_u ≥` the
//! distance of `p` from axis `u` (revolute) or 1 (prismatic). Summed in one pass from the root:
//! `A = Σ_{v rev} (2 s_v D_v W_{<v} + s_v ρ_v W_{≤v}) + Σ_{v pris} 2 s_v W_{<v}`. `D_v` and `ρ_v`
//! are the kinematic-chain bounds of the linear certificate (`model.rs`), taken over the body's
//! sphere centres and its bounding sphere's centre.
//!
//! Rounding: the positions are the f32 kinematics', within the rounding allowance already in
//! every radius ([`SphereChecker::ROUNDING_MARGIN`]); the midpoint and half chord computed from
//! them may each be off by that much again, so δ carries one more allowance.

// Lane code indexes several arrays with one lane/row index; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use nalgebra::Vector3;

use super::kinematics::{Step, StepKind};
use super::lanes::{le_zero_mask, obs_lanes_mask};
use super::{Body, Hit, Lane, SphereChecker, LANES, NO_FOCUS, SELF_PAIR};

/// The sub-intervals of one 8-lane call (lane `l` to lane `l + 1`).
const SUB: u32 = (1 << (LANES - 1)) - 1;

/// Two static terms of the acceleration bound (see [`accel_statics`]).
pub(super) type Pair = (f64, f64);

/// The static terms of the acceleration bound (see
/// [`SphereChecker::segment_accelerations`]): per node `(L, g)` with `L = |t| + travel` (its
/// joint origin's offset in the parent, plus a prismatic joint's travel: what the distance of a
/// point below it from the parent's origin may exceed its distance from its own) and
/// `g = |t| − dist(t, parent's axis)` (what the distance from a point of the parent's axis
/// exceeds that from the axis itself); per body `(d, λ)`, the largest distance of its points
/// (sphere centres and its bounding sphere's centre) from its node's origin and from its node's
/// axis.
pub(super) fn accel_statics(
    steps: &[Step],
    bodies: &[Body],
    spheres: &[[f32; 4]],
) -> (Vec<Pair>, Vec<Pair>) {
    let v3 = |a: &[f32; 3]| Vector3::new(f64::from(a[0]), f64::from(a[1]), f64::from(a[2]));
    let across =
        |p: &Vector3<f64>, axis: &[f32; 3]| crate::geometry::distance_from_axis(p, &v3(axis));
    let nodes = steps
        .iter()
        .map(|st| {
            let t = v3(&st.t);
            let g = if st.kind == StepKind::Root {
                0.0
            } else {
                (t.norm() - across(&t, &steps[st.parent as usize].axis)).max(0.0)
            };
            (t.norm() + st.travel, g)
        })
        .collect();
    let bodies = bodies
        .iter()
        .map(|body| {
            let mut pts: Vec<Vector3<f64>> = spheres
                [body.spheres.0 as usize..body.spheres.1 as usize]
                .iter()
                .map(|s| v3(&[s[0], s[1], s[2]]))
                .collect();
            pts.push(v3(&body.bc));
            let axis = &steps[body.node as usize].axis;
            (
                pts.iter().map(|c| c.norm()).fold(0.0, f64::max),
                pts.iter().map(|c| across(c, axis)).fold(0.0, f64::max),
            )
        })
        .collect();
    (nodes, bodies)
}

/// One non-root node of the acceleration recursion of
/// [`SphereChecker::segment_accelerations`], compact (its `Step`'s fields it needs, with the
/// static terms of [`accel_statics`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct AccStep {
    pub(super) node: u32,
    pub(super) parent: u32,
    pub(super) var: u32,
    /// |mimic multiplier|.
    pub(super) mul: f64,
    pub(super) l: f64,
    pub(super) g: f64,
    pub(super) prismatic: bool,
}

/// The non-root nodes as [`AccStep`]s, in tree order (parents first, as `steps`).
pub(super) fn acc_steps(steps: &[Step], statics: &[Pair]) -> Vec<AccStep> {
    steps
        .iter()
        .enumerate()
        .filter(|(_, st)| st.kind != StepKind::Root)
        .map(|(si, st)| AccStep {
            node: si as u32,
            parent: st.parent,
            var: st.var,
            mul: f64::from(st.mul).abs(),
            l: statics[si].0,
            g: statics[si].1,
            prismatic: st.kind == StepKind::Prismatic,
        })
        .collect()
}

/// The nodes whose bound `dmax C + E + P` can be the largest (`dmax`: the largest `d` of the
/// node's bodies, `-1` where it has none), with their `dmax`. Along a chain `C`, `E` and `P`
/// never decrease and `E` grows by at least `L_k C_n` per node `k` passed below `n`, so a node
/// `n` with a descendant `m` such that `dmax_m + Σ L ≥ dmax_n` (the sum over the nodes from
/// below `n` down to `m`) never has the larger bound and is left out. The bound only sets the
/// first pass's number of calls; every allowance is each body's own.
pub(super) fn acc_amax_nodes(steps: &[Step], statics: &[Pair], dmax: &[f64]) -> Vec<(u32, f64)> {
    let mut dominated = vec![false; steps.len()];
    for (m, &dm) in dmax.iter().enumerate() {
        if dm < 0.0 {
            continue;
        }
        let (mut k, mut reach) = (m, dm);
        while steps[k].kind != StepKind::Root {
            reach += statics[k].0;
            k = steps[k].parent as usize;
            if dmax[k] >= 0.0 && reach >= dmax[k] {
                dominated[k] = true;
            }
        }
    }
    dmax.iter()
        .enumerate()
        .filter(|&(n, &d)| d >= 0.0 && !dominated[n])
        .map(|(n, &d)| (n as u32, d))
        .collect()
}

/// Lane `l` ← lane `l + 1` (the last lane keeps its value).
#[inline(always)]
fn next(v: &Lane) -> Lane {
    let mut o = *v;
    o[..LANES - 1].copy_from_slice(&v[1..]);
    o
}

/// Chord midpoints and half lengths of a lane triple: `((p + p⁺) / 2, |p⁺ − p| / 2)` with
/// `p⁺` the next lane's point.
#[inline(always)]
fn chords(p: &[Lane; 3]) -> ([Lane; 3], Lane) {
    let mut mid = [[0.0f32; LANES]; 3];
    let mut h2 = [0.0f32; LANES];
    for r in 0..3 {
        let n = next(&p[r]);
        for l in 0..LANES {
            mid[r][l] = 0.5 * (p[r][l] + n[l]);
            let d = n[l] - p[r][l];
            h2[l] += d * d;
        }
    }
    let mut half = [0.0f32; LANES];
    for l in 0..LANES {
        half[l] = 0.5 * h2[l].sqrt();
    }
    (mid, half)
}

/// Lanes `l` whose chord from `d` (lane `l`) to `d⁺` (lane `l + 1`) comes within `r` of the
/// origin (the AVX path's [`super::avx8::chord_within_origin`], operation for operation).
#[inline(always)]
pub(super) fn chord_within_origin(d: &[Lane; 3], r: f32) -> u32 {
    let n = [next(&d[0]), next(&d[1]), next(&d[2])];
    let mut m = 0u32;
    for l in 0..LANES {
        let e = [n[0][l] - d[0][l], n[1][l] - d[1][l], n[2][l] - d[2][l]];
        let ee = e[2].mul_add(e[2], e[1].mul_add(e[1], e[0] * e[0]));
        let de = d[2][l].mul_add(e[2], d[1][l].mul_add(e[1], d[0][l] * e[0]));
        let x = (0.0 - de) / ee;
        // As `_mm256_max_ps(x, 0)`: 0 when x is NaN.
        let s = (if x > 0.0 { x } else { 0.0 }).min(1.0);
        let c = [
            s.mul_add(e[0], d[0][l]),
            s.mul_add(e[1], d[1][l]),
            s.mul_add(e[2], d[2][l]),
        ];
        let d2 = c[2].mul_add(c[2], c[1].mul_add(c[1], c[0].mul_add(c[0], -(r * r))));
        m |= u32::from(d2 <= 0.0) << l;
    }
    m
}

/// Lanes whose point lies within `r[l]` of `c`.
#[inline(always)]
fn within(p: &[Lane; 3], c: [f32; 3], r: &Lane) -> u32 {
    let mut d = [0.0f32; LANES];
    for l in 0..LANES {
        let dx = p[0][l] - c[0];
        let dy = p[1][l] - c[1];
        let dz = p[2][l] - c[2];
        d[l] = dx * dx + dy * dy + dz * dz - r[l] * r[l];
    }
    le_zero_mask::<LANES>(&d)
}

/// Lanes whose two points lie within `r[l]` of each other.
#[inline(always)]
fn within_lanes(a: &[Lane; 3], b: &[Lane; 3], r: &Lane) -> u32 {
    let mut d = [0.0f32; LANES];
    for l in 0..LANES {
        let dx = a[0][l] - b[0][l];
        let dy = a[1][l] - b[1][l];
        let dz = a[2][l] - b[2][l];
        d[l] = dx * dx + dy * dy + dz * dz - r[l] * r[l];
    }
    le_zero_mask::<LANES>(&d)
}

#[inline(always)]
fn sub3(a: &[Lane; 3], b: &[Lane; 3]) -> [Lane; 3] {
    let mut o = [[0.0f32; LANES]; 3];
    for r in 0..3 {
        for l in 0..LANES {
            o[r][l] = a[r][l] - b[r][l];
        }
    }
    o
}

#[inline(always)]
fn plus(half: &Lane, r: f32) -> Lane {
    let mut o = [0.0f32; LANES];
    for l in 0..LANES {
        o[l] = half[l] + r;
    }
    o
}

const ORIGIN: [f32; 3] = [0.0; 3];

/// What [`SphereChecker::hot_start`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum HotStart {
    /// Not run.
    Skipped,
    /// A state collides: the segment is not free.
    Collides,
    /// The hot and warm bodies are free at the one-call first pass's states, which are
    /// loaded, with the frames of the first this many steps computed.
    Free(usize),
}

impl SphereChecker {
    /// Turns the chord certificate of certified checks on or off (on by default; off: the
    /// linear certificate from speed bounds alone). Both are sound; tests compare them.
    #[doc(hidden)]
    pub fn set_chord(&mut self, on: bool) {
        self.chord = on;
    }

    /// Per body its acceleration bound `A` over the segment (`seg_acc`, from `seg_dq`; see the
    /// module documentation) and per node that of its bounding sphere's centre (`node_acc`);
    /// returns the largest of the bodies'.
    ///
    /// The bound `Σ_{k rev} (α_k D_k + β_k ρ_k) + Σ_{k pris} α_k` over the body's chain, with
    /// `α_k = 2 s_k W_{<k}` and `β_k = s_k W_{≤k}`, in O(1) per node and per body: going up from
    /// a body on node `n`, `D_k = d + R(n → k)` with `R` the sum of the offsets `L` of the nodes
    /// passed (`model.rs`'s speed bounds grow `D` so), and `D_k − ρ_k = g_c` of the child `c` on
    /// the way (`ρ_k = dist(t_c, axis_k) + D_c + travel_c`). So with per-node sums
    /// `C_n = C_p + (α_n + β_n)`, `E_n = E_p + L_n C_p`, `G_n = G_p + β_p g_n` and
    /// `P_n = P_p + α_n` (prismatic), over revolute nodes where not said:
    /// `A_b = d_b C_n + E_n − G_n − β_n (d_b − λ_b) + P_n` ([`accel_statics`]).
    pub(super) fn segment_accelerations(&mut self) -> f64 {
        // Root nodes keep `[0; 6]` (set at construction); `acc_steps` holds the others in
        // tree order, parents first.
        let (acc, dq) = (&mut self.acc_node, &self.seg_dq);
        for st in &self.acc_steps {
            let [wp, cp, ep, gp, pp, bp] = acc[st.parent as usize];
            let s = st.mul * dq[st.var as usize];
            let alpha = 2.0 * s * wp;
            let (e, g) = (ep + st.l * cp, gp + bp * st.g);
            acc[st.node as usize] = if st.prismatic {
                [wp, cp, e, g, pp + alpha, 0.0]
            } else {
                let w = wp + s;
                let beta = s * w;
                [w, cp + alpha + beta, e, g, pp, beta]
            };
        }
        // New segment: every body's and node's bound is computed on first use.
        self.acc_seg = self.acc_seg.wrapping_add(1);
        if self.acc_seg == 0 {
            self.acc_epoch.fill(0);
            self.node_acc_epoch.fill(0);
            self.acc_seg = 1;
        }
        // For the number of calls, a bound of every body's: `A_b ≤ d_b C_n + E_n + P_n` (the
        // subtracted terms are ≥ 0) ≤ the same with the node's largest `d`, over the nodes
        // no descendant dominates ([`acc_amax_nodes`]).
        let mut amax = 0.0f64;
        for &(n, dmax) in &self.acc_amax {
            let [_, c, e, _, p, _] = acc[n as usize];
            let a = dmax * c + e + p;
            if a > amax {
                amax = a;
            }
        }
        amax * (1.0 + 1e-5)
    }

    /// A self pair's sub-interval whose ball (about the difference's chord midpoint) touches
    /// the origin is tight only if the chord itself comes within `r_i + r_j + δ_a + δ_b` of
    /// it: the difference stays within `δ_a + δ_b` of its chord (module documentation), so the
    /// chord's distance from the origin bounds it from below over the whole sub-interval. The
    /// ball is the cheap first test; the chord's distance is exact where the ball is loose
    /// (two spheres at a constant distance turning about a common axis: a UR5's base and
    /// shoulder-end upper-arm spheres, 2.4 mm apart at every configuration, made every check
    /// that turns the shoulder tight). The nearest point is computed in f32 from the computed
    /// positions: one more rounding allowance.
    const CHORD_SEGMENT_MARGIN: f32 = Self::ROUNDING_MARGIN as f32;

    /// Body `b`'s acceleration bound over the current segment (computed once per segment).
    #[inline(always)]
    fn body_acc(&mut self, b: usize) -> f64 {
        if self.acc_epoch[b] != self.acc_seg {
            self.acc_epoch[b] = self.acc_seg;
            let [_, c, e, g, p, beta] = self.acc_node[self.bodies[b].node as usize];
            let (d, lever) = self.acc_static_body[b];
            // The relative allowance covers the rounding of these f64 sums.
            self.seg_acc[b] = ((d * c + e - g - beta * (d - lever)).max(0.0) + p) * (1.0 + 1e-5);
        }
        self.seg_acc[b]
    }

    /// Node `n`'s bounding-sphere centre's acceleration bound over the current segment: it
    /// rides with its first body's centre at a fixed offset `o`, so every `D` and `ρ` of it is
    /// within `o` of that centre's, and its bound is the body's plus `o · C`.
    #[inline(always)]
    fn node_acc_of(&mut self, n: usize) -> f64 {
        if self.node_acc_epoch[n] != self.acc_seg {
            self.node_acc_epoch[n] = self.acc_seg;
            let (b0, off) = self.node_anchor[n];
            self.node_acc[n] = if b0 == u32::MAX {
                0.0
            } else {
                self.body_acc(b0 as usize) + off * self.acc_node[n][1] * (1.0 + 1e-5)
            };
        }
        self.node_acc[n]
    }

    /// Every body's and node's bound of the current segment into `seg_acc` and `node_acc`
    /// (tests).
    #[cfg(test)]
    pub(super) fn all_accelerations(&mut self) {
        for b in 0..self.bodies.len() {
            self.body_acc(b);
        }
        for n in 0..self.steps.len() {
            self.node_acc_of(n);
        }
    }

    /// The allowance `δ = A h² / 8` of a point whose acceleration bound is `a`, in the current
    /// call, plus one rounding allowance (see the module documentation).
    #[inline(always)]
    fn allowance(&self, a: f64) -> f32 {
        (a * self.chord_k + Self::ROUNDING_MARGIN) as f32
    }

    /// Body `b`'s allowance `δ = A h² / 8` (plus one rounding allowance, see the module
    /// documentation) in the current call (computed once per call, in `infl`).
    #[inline(always)]
    fn dl(&mut self, b: usize) -> f32 {
        if self.dl_epoch[b] != self.dl_call {
            self.dl_epoch[b] = self.dl_call;
            let a = self.body_acc(b);
            self.infl[b] = self.allowance(a);
        }
        self.infl[b]
    }

    /// Node `n`'s allowance in the current call (see [`Self::dl`]).
    #[inline(always)]
    fn node_dl_of(&mut self, n: usize) -> f32 {
        if self.node_dl_epoch[n] != self.dl_call {
            self.node_dl_epoch[n] = self.dl_call;
            let a = self.node_acc_of(n);
            self.node_dl[n] = self.allowance(a);
        }
        self.node_dl[n]
    }

    /// Sets the allowances `δ = A h² / 8` for sub-intervals of length `h`: each body's and
    /// node's is computed when first needed ([`Self::dl`]).
    #[inline]
    pub(super) fn set_chord_allowance(&mut self, h: f64) {
        self.chord_k = h * h / 8.0;
        self.dl_call = self.dl_call.wrapping_add(1);
        if self.dl_call == 0 {
            self.dl_epoch.fill(0);
            self.node_dl_epoch.fill(0);
            self.dl_call = 1;
        }
    }

    /// One 8-lane call of the chord certificate over the states in `qv` (lane `l` and `l + 1`
    /// the ends of sub-interval `l`, allowances in `infl`): `Some` when a state collides with
    /// the plain spheres; otherwise the sub-intervals some ball touches are logged per body and
    /// self pair in `tight_log` (bit `l`). `focus`: only the bodies and pairs
    /// `focus_pool[fs..fe]` (`NO_FOCUS`: all). `stepped`: the frames of the first `stepped`
    /// steps are already computed for these lanes (by [`Self::hot_start`]; 0: none).
    pub(super) fn chord8(&mut self, fs: u32, fe: u32, stepped: usize) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU supports AVX2 and FMA (checked at construction).
            return unsafe { self.chord8_avx2(fs, fe, stepped) };
        }
        self.chord_run::<false>(fs, fe, stepped)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn chord8_avx2(&mut self, fs: u32, fe: u32, stepped: usize) -> Option<Hit> {
        self.chord_run::<true>(fs, fe, stepped)
    }

    /// The start of a chord-certified check of segment `a → b`, before its bounds: the states
    /// of the first pass's first call when it makes one call (`t = k/7`), loaded, and the hot
    /// and warm bodies tested there with their plain spheres ([`Self::bodies_hot_first`] with
    /// the plain body test), as the plain checks test them. Most checks make one call (on the
    /// UR5-like arm at least 99.8 % of its cage set's, 98.9 % of shelf's, 86 % of box's and
    /// table's: bounds from the calls summed over the checks). Motions that collide mostly
    /// collide with the hot body (UR5-like cage, 10 problems, counted: 97 % of the checks
    /// collide, 87 % of them at the hot body — a quarter of those at its last hit's sphere and
    /// obstacle, the probe — and 8 % at the warm one), and a state colliding there decides the
    /// segment: no certificate could prove it free, and its acceleration bounds
    /// ([`Self::begin_segment`], 390 instructions on the UR5-like arm) and the chords of the
    /// hot body's spheres are not computed. When they are free, the first call reuses the
    /// lanes and the frames computed here. Not with the linear certificate, without a hot
    /// body, or in the benchmark's uncertified mode.
    pub(super) fn hot_start(&mut self, a: &[f64], b: &[f64]) -> HotStart {
        if !self.chord || self.uncertified || !self.hot_first || self.hot_body == u32::MAX {
            return HotStart::Skipped;
        }
        self.load_lanes(a, b, &Self::chord_states(0, 1));
        let mut stepped = 0;
        #[cfg(target_arch = "x86_64")]
        let hit = if self.avx2 {
            // SAFETY: the CPU supports AVX2 and FMA (checked at construction).
            unsafe { self.hot_start_avx2(&mut stepped) }
        } else {
            self.hot_start_run::<false>(&mut stepped)
        };
        #[cfg(not(target_arch = "x86_64"))]
        let hit = self.hot_start_run::<false>(&mut stepped);
        if hit.is_some() {
            self.certify_counts.segments += 1;
            self.checks += LANES as u64;
            return HotStart::Collides;
        }
        HotStart::Free(stepped)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn hot_start_avx2(&mut self, stepped: &mut usize) -> Option<Hit> {
        self.hot_start_run::<true>(stepped)
    }

    #[inline(always)]
    fn hot_start_run<const AVX: bool>(&mut self, stepped: &mut usize) -> Option<Hit> {
        self.new_call();
        let hot = self.hot_body;
        self.bodies_hot_first::<LANES, AVX, false>(hot, stepped, Self::env_of::<LANES, AVX>)
    }

    /// The states of call `c` of a first pass of `calls` calls: `k / (7 calls)` for
    /// `k = 7c … 7c + 7`, the last state of the segment exactly 1.
    #[inline]
    pub(super) fn chord_states(c: usize, calls: usize) -> [f64; LANES] {
        let n = calls * (LANES - 1);
        let h = 1.0 / n as f64;
        let first = c * (LANES - 1);
        std::array::from_fn(|l| {
            if first + l == n {
                1.0
            } else {
                (first + l) as f64 * h
            }
        })
    }

    #[inline(always)]
    fn chord_run<const AVX: bool>(&mut self, fs: u32, fe: u32, stepped: usize) -> Option<Hit> {
        self.new_call();
        if fs == NO_FOCUS {
            // Kinematics fused with the tests, the hot body first, then the warm one (as the
            // plain checks do: `SphereChecker::run`): a state colliding stops the call early.
            // Measured (callgrind, Baxter's hard bookshelf set, planning) when the warm body
            // joined: body tests per colliding call 6.4 → 2.7, planning instructions −13 %.
            let hot = if self.hot_first {
                self.hot_body
            } else {
                u32::MAX
            };
            let mut stepped = stepped;
            if let Some(h) = self.bodies_hot_first::<LANES, AVX, true>(
                hot,
                &mut stepped,
                Self::chord_env_of::<AVX>,
            ) {
                return Some(h);
            }
            let mut pi = 0;
            while pi < self.self_pairs.len() {
                let end = self.pair_group_end[pi] as usize;
                if end != 0 && self.node_cull {
                    let (a, b) = self.self_pairs[pi];
                    let (na, nb) = (self.bodies[a as usize].node, self.bodies[b as usize].node);
                    if !self.chord_nodes_near::<AVX>(na as usize, nb as usize) {
                        pi = end;
                        continue;
                    }
                }
                if let Some(h) = self.chord_pair_of::<AVX>(pi) {
                    return Some(h);
                }
                pi += 1;
            }
            return None;
        }
        let (fs, fe) = (fs as usize, fe as usize);
        for si in 0..self.focus_steps(fs, fe) {
            self.step::<LANES, AVX>(si);
        }
        for k in fs..fe {
            let id = self.focus_pool[k];
            if id & SELF_PAIR == 0 {
                if let Some(h) = self.chord_env_of::<AVX>(id as usize) {
                    return Some(h);
                }
                continue;
            }
            let pi = (id & !SELF_PAIR) as usize;
            let (a, b) = self.self_pairs[pi];
            for x in [a, b] {
                self.place_centre::<AVX>(x as usize);
            }
            if let Some(h) = self.chord_pair_of::<AVX>(pi) {
                return Some(h);
            }
        }
        None
    }

    /// [`Self::chord_env`], in AVX2 + FMA registers when `AVX`.
    #[inline(always)]
    fn chord_env_of<const AVX: bool>(&mut self, b: usize) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        if AVX {
            // SAFETY: `AVX` is true only inside `chord8_avx2` (AVX2 + FMA checked at
            // construction).
            return unsafe { self.chord_env_avx(b) };
        }
        self.chord_env::<AVX>(b)
    }

    /// [`Self::chord_pair`], in AVX2 + FMA registers when `AVX`.
    #[inline(always)]
    fn chord_pair_of<const AVX: bool>(&mut self, pi: usize) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        if AVX {
            // SAFETY: as in `chord_env_of`.
            return unsafe { self.chord_pair_avx(pi) };
        }
        self.chord_pair::<AVX>(pi)
    }

    /// [`Self::chord_env`] in AVX2 + FMA registers: the same tests in the same order.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn chord_env_avx(&mut self, b: usize) -> Option<Hit> {
        use super::avx8::*;
        use std::arch::x86_64::_mm256_set1_ps;
        let dl = self.dl(b);
        let SphereChecker {
            bodies,
            frames,
            bcw,
            body_obstacles,
            body_obstacle_sphere,
            obstacles_wide,
            sw,
            sw_epoch,
            epoch,
            spheres,
            tight_log,
            ..
        } = self;
        let body = &bodies[b];
        let f = &frames[body.node as usize];
        let c = place(f, &body.bc);
        store3(&mut bcw[b], c);
        let (o0, o1) = (body.obstacles.0 as usize, body.obstacles.1 as usize);
        if o0 == o1 {
            return None;
        }
        let (mid, half) = chords(c);
        let reach = add_s(half, body.br + dl);
        let (s0, s1) = (body.spheres.0 as usize, body.spheres.1 as usize);
        let mut placed = sw_epoch[b] == *epoch;
        let mut tb = 0u32;
        for (&oi, ob) in body_obstacles[o0..o1]
            .iter()
            .zip(&body_obstacle_sphere[o0..o1])
        {
            if within(mid, splat3([ob[0], ob[1], ob[2]]), add_s(reach, ob[3])) & SUB == 0 {
                continue;
            }
            let o = &obstacles_wide[oi as usize];
            if obs_r(o, mid, reach) & SUB == 0 {
                continue;
            }
            if !placed {
                placed = true;
                sw_epoch[b] = *epoch;
                for (k, sp) in spheres[s0..s1].iter().enumerate() {
                    store3(&mut sw[s0 + k], place(f, &[sp[0], sp[1], sp[2]]));
                }
            }
            // Chords per sphere here, not with the placement: a colliding call usually stops
            // at a body's first spheres (the self pairs compute all of them, `chord_epoch`).
            for (k, sp) in spheres[s0..s1].iter().enumerate() {
                let p = load3(&sw[s0 + k]);
                let (smid, shalf) = chords(p);
                let m = obs_r(o, smid, add_s(shalf, sp[3] + dl)) & SUB;
                if m == 0 {
                    continue;
                }
                let ends = m | (m << 1);
                if obs_r(o, p, _mm256_set1_ps(sp[3])) & ends != 0 {
                    return Some(Hit::Obstacle(b as u32, oi, (s0 + k) as u32));
                }
                tb |= m;
            }
        }
        if tb != 0 {
            tight_log.push((b as u32, tb));
        }
        None
    }

    /// [`Self::chord_pair`] in AVX2 + FMA registers: the same tests in the same order.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn chord_pair_avx(&mut self, pi: usize) -> Option<Hit> {
        use super::avx8::*;
        use std::arch::x86_64::{_mm256_add_ps, _mm256_set1_ps};
        let (a, b) = self.self_pairs[pi];
        let (a, b) = (a as usize, b as usize);
        let dl = self.dl(a) + self.dl(b);
        let (ra, rb) = (self.bodies[a].br, self.bodies[b].br);
        let ca = load3(&self.bcw[a]);
        let cb = load3(&self.bcw[b]);
        let (mid, half) = chords(sub3(ca, cb));
        if within_origin(mid, add_s(half, ra + rb + dl)) & SUB == 0 {
            return None;
        }
        self.ensure_chords_avx(a);
        self.ensure_chords_avx(b);
        let (sa, sb) = (self.bodies[a].spheres, self.bodies[b].spheres);
        // Each test first with the two points' own chords (the difference's half chord is at
        // most the sum of theirs), then, where that touches, with the difference's chord.
        let (mcb, hcb) = chords(cb);
        let mut tp = 0u32;
        for i in sa.0 as usize..sa.1 as usize {
            let (pi_, ri) = (load3(&self.sw[i]), self.spheres[i][3]);
            let (mi, hi) = (load3(&self.swm[i]), load1(&self.swh[i]));
            // The sphere against b's bounding sphere first.
            if within(mi, mcb, add_s(_mm256_add_ps(hi, hcb), ri + rb + dl)) & SUB == 0 {
                continue;
            }
            for j in sb.0 as usize..sb.1 as usize {
                let rij = ri + self.spheres[j][3];
                let (mj, hj) = (load3(&self.swm[j]), load1(&self.swh[j]));
                if within(mi, mj, add_s(_mm256_add_ps(hi, hj), rij + dl)) & SUB == 0 {
                    continue;
                }
                let pj = load3(&self.sw[j]);
                let d = sub3(pi_, pj);
                let (m1, h1) = chords(d);
                let m = within_origin(m1, add_s(h1, rij + dl)) & SUB;
                if m == 0 {
                    continue;
                }
                let ends = m | (m << 1);
                if within(pi_, pj, _mm256_set1_ps(rij)) & ends != 0 {
                    return Some(Hit::SelfPair(a as u32, b as u32));
                }
                tp |= m & chord_within_origin(d, rij + dl + Self::CHORD_SEGMENT_MARGIN);
            }
        }
        if tp != 0 {
            self.tight_log.push((SELF_PAIR | pi as u32, tp));
        }
        None
    }

    /// Places body `b`'s spheres (once per call) with their chords (`swm`, `swh`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn ensure_chords_avx(&mut self, b: usize) {
        use super::avx8::*;
        if self.chord_epoch[b] == self.epoch {
            return;
        }
        self.chord_epoch[b] = self.epoch;
        let placed = self.sw_epoch[b] == self.epoch;
        self.sw_epoch[b] = self.epoch;
        let body = &self.bodies[b];
        let f = &self.frames[body.node as usize];
        for si in body.spheres.0 as usize..body.spheres.1 as usize {
            let p = if placed {
                load3(&self.sw[si])
            } else {
                let sp = self.spheres[si];
                let p = place(f, &[sp[0], sp[1], sp[2]]);
                store3(&mut self.sw[si], p);
                p
            };
            let (m, h) = chords(p);
            store3(&mut self.swm[si], m);
            store1(&mut self.swh[si], h);
        }
    }

    /// Whether the chord balls of nodes `na` and `nb`'s bounding spheres (around all their
    /// bodies) touch in some sub-interval; when they do not, no pair of their bodies can.
    #[inline(always)]
    fn chord_nodes_near<const AVX: bool>(&mut self, na: usize, nb: usize) -> bool {
        for n in [na, nb] {
            if self.ncw_epoch[n] != self.epoch {
                self.ncw_epoch[n] = self.epoch;
                let s = self.node_sphere[n];
                self.ncw[n] = Self::place::<LANES, AVX>(&self.frames[n], &[s[0], s[1], s[2]]);
            }
        }
        let r = self.node_sphere[na][3]
            + self.node_sphere[nb][3]
            + self.node_dl_of(na)
            + self.node_dl_of(nb);
        let (mid, half) = chords(&sub3(&self.ncw[na], &self.ncw[nb]));
        within(&mid, ORIGIN, &plus(&half, r)) & SUB != 0
    }

    /// Body `b`'s bounding-sphere centre in every lane, into `bcw`.
    #[inline(always)]
    fn place_centre<const AVX: bool>(&mut self, b: usize) {
        let body = &self.bodies[b];
        let c = Self::place::<LANES, AVX>(&self.frames[body.node as usize], &body.bc);
        self.bcw[b] = c;
    }

    /// Body `b` against its obstacles under the chord certificate (its node's frame computed;
    /// its centre placed into `bcw` for the self pairs).
    #[inline(always)]
    fn chord_env<const AVX: bool>(&mut self, b: usize) -> Option<Hit> {
        self.place_centre::<AVX>(b);
        let (o0, o1) = self.bodies[b].obstacles;
        let (o0, o1) = (o0 as usize, o1 as usize);
        if o0 == o1 {
            return None;
        }
        let dl = self.dl(b);
        let body = &self.bodies[b];
        let (mid, half) = chords(&self.bcw[b]);
        let reach = plus(&half, body.br + dl);
        let (s0, s1) = (body.spheres.0 as usize, body.spheres.1 as usize);
        let mut tb = 0u32;
        for k in o0..o1 {
            let ob = self.body_obstacle_sphere[k];
            if within(&mid, [ob[0], ob[1], ob[2]], &plus(&reach, ob[3])) & SUB == 0 {
                continue;
            }
            let oi = self.body_obstacles[k] as usize;
            let o = self.obstacles[oi];
            if obs_lanes_mask(&o, &mid, &reach) & SUB == 0 {
                continue;
            }
            self.ensure_spheres::<LANES, AVX>(b);
            for si in s0..s1 {
                let p = &self.sw[si];
                let r = self.spheres[si][3];
                let (smid, shalf) = chords(p);
                let m = obs_lanes_mask(&o, &smid, &plus(&shalf, r + dl)) & SUB;
                if m == 0 {
                    continue;
                }
                let ends = m | (m << 1);
                if obs_lanes_mask(&o, p, &[r; LANES]) & ends != 0 {
                    return Some(Hit::Obstacle(b as u32, oi as u32, si as u32));
                }
                tb |= m;
            }
        }
        if tb != 0 {
            self.tight_log.push((b as u32, tb));
        }
        None
    }

    /// Self pair `pi` under the chord certificate (both bodies' centres in `bcw`).
    #[inline(always)]
    fn chord_pair<const AVX: bool>(&mut self, pi: usize) -> Option<Hit> {
        let (a, b) = self.self_pairs[pi];
        let (a, b) = (a as usize, b as usize);
        let dl = self.dl(a) + self.dl(b);
        let (ba, bb) = (&self.bodies[a], &self.bodies[b]);
        let (ra, rb) = (ba.br, bb.br);
        let d = sub3(&self.bcw[a], &self.bcw[b]);
        let (mid, half) = chords(&d);
        if within(&mid, ORIGIN, &plus(&half, ra + rb + dl)) & SUB == 0 {
            return None;
        }
        self.ensure_spheres::<LANES, AVX>(a);
        self.ensure_spheres::<LANES, AVX>(b);
        let (ba, bb) = (&self.bodies[a], &self.bodies[b]);
        let (sa, sb) = (ba.spheres, bb.spheres);
        let cb = self.bcw[b];
        let mut tp = 0u32;
        for i in sa.0 as usize..sa.1 as usize {
            let (pi_, ri) = (&self.sw[i], self.spheres[i][3]);
            // The sphere against b's bounding sphere first.
            let (m0, h0) = chords(&sub3(pi_, &cb));
            if within(&m0, ORIGIN, &plus(&h0, ri + rb + dl)) & SUB == 0 {
                continue;
            }
            for j in sb.0 as usize..sb.1 as usize {
                let rij = ri + self.spheres[j][3];
                let dij = sub3(pi_, &self.sw[j]);
                let (m1, h1) = chords(&dij);
                let m = within(&m1, ORIGIN, &plus(&h1, rij + dl)) & SUB;
                if m == 0 {
                    continue;
                }
                let ends = m | (m << 1);
                if within_lanes(pi_, &self.sw[j], &[rij; LANES]) & ends != 0 {
                    return Some(Hit::SelfPair(a as u32, b as u32));
                }
                tp |= m & chord_within_origin(&dij, rij + dl + Self::CHORD_SEGMENT_MARGIN);
            }
        }
        if tp != 0 {
            self.tight_log.push((SELF_PAIR | pi as u32, tp));
        }
        None
    }

    /// Number of 8-lane calls of the chord certificate's first pass: the fewest whose
    /// sub-intervals (7 per call) keep every body's allowance `δ` within half of
    /// `max_inflation` (the chords' half lengths take the rest, or refinement does).
    pub(super) fn chord_calls(amax: f64, max_inflation: f64) -> usize {
        // A h² / 8 ≤ max_inflation / 2  ⇔  1 / h ≥ sqrt(A / (4 max_infl)); the rounding up
        // without `ceil` (a library call on the baseline target).
        let per = (amax / (4.0 * max_inflation)).sqrt() / (LANES - 1) as f64;
        let most = Self::CERTIFY_MAX_STATES / LANES;
        // (NaN, from an infinite bound, takes the largest count too.)
        if per.is_nan() || per >= most as f64 {
            return most;
        }
        let calls = per as usize;
        (calls + usize::from((calls as f64) < per)).max(1)
    }

    /// The chord certificate's first pass: `calls` 8-lane calls over `7 · calls` equal
    /// sub-intervals, states `k / (7 calls)`, consecutive calls sharing their end state. False
    /// when a state collides; the tight (sub-interval, body or self pair) entries in
    /// `tight_states`. `start`: what [`Self::hot_start`] found (with one call, its lanes and
    /// frames are the first call's).
    pub(super) fn chord_first_pass(
        &mut self,
        a: &[f64],
        b: &[f64],
        calls: usize,
        start: HotStart,
    ) -> bool {
        let n = calls * (LANES - 1);
        let h = 1.0 / n as f64;
        self.tight_states.clear();
        if self.uncertified {
            // Benchmark only: the same states with plain spheres.
            for c in 0..calls {
                self.load_lanes(a, b, &Self::chord_states(c, calls));
                self.checks += LANES as u64;
                if self.collides8() {
                    return false;
                }
            }
            return true;
        }
        self.set_chord_allowance(h);
        for c in 0..calls {
            let first = c * (LANES - 1);
            let stepped = match start {
                HotStart::Free(stepped) if calls == 1 => stepped,
                _ => {
                    self.load_lanes(a, b, &Self::chord_states(c, calls));
                    0
                }
            };
            self.checks += LANES as u64;
            if self.chord8(NO_FOCUS, NO_FOCUS, stepped).is_some() {
                return false;
            }
            for e in 0..self.tight_log.len() {
                let (id, mut m) = self.tight_log[e];
                while m != 0 {
                    let l = m.trailing_zeros() as usize;
                    m &= m - 1;
                    self.tight_states.push((first + l, id));
                }
            }
        }
        true
    }

    /// The chord certificate's refinement of the first pass's tight sub-intervals (each split
    /// in 7 by one 8-lane call testing only what was tight in it, recursively).
    pub(super) fn chord_refine(&mut self, a: &[f64], b: &[f64], calls: usize) -> bool {
        let n = calls * (LANES - 1);
        let h = 1.0 / n as f64;
        self.refine.clear();
        self.focus_pool.clear();
        self.tight_states.sort_unstable();
        self.tight_states.dedup();
        let mut i = 0;
        while i < self.tight_states.len() {
            let k = self.tight_states[i].0;
            let start = self.focus_pool.len();
            while i < self.tight_states.len() && self.tight_states[i].0 == k {
                if self.focus {
                    self.focus_pool.push(self.tight_states[i].1);
                }
                i += 1;
            }
            let (fs, fe) = if self.focus {
                (start as u32, self.focus_pool.len() as u32)
            } else {
                (NO_FOCUS, NO_FOCUS)
            };
            let t1 = if k + 1 == n { 1.0 } else { (k + 1) as f64 * h };
            self.refine.push((k as f64 * h, t1, 0, fs, fe));
        }
        let mut budget = Self::CERTIFY_MAX_REFINEMENTS;
        while let Some((t0, t1, depth, fs, fe)) = self.refine.pop() {
            if depth >= Self::CERTIFY_MAX_DEPTH || budget == 0 {
                return false;
            }
            budget -= 1;
            self.certify_counts.refinements += 1;
            let parts = (LANES - 1) as f64;
            let hs = (t1 - t0) / parts;
            self.set_chord_allowance(hs);
            let ts: [f64; LANES] = std::array::from_fn(|l| {
                if l == LANES - 1 {
                    t1
                } else {
                    t0 + hs * l as f64
                }
            });
            self.load_lanes(a, b, &ts);
            self.checks += LANES as u64;
            if self.chord8(fs, fe, 0).is_some() {
                return false;
            }
            let m = self.tight_log.iter().fold(0, |m, e| m | e.1);
            let mut bits = m;
            while bits != 0 {
                let l = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let (nfs, nfe) = if fs == NO_FOCUS {
                    (NO_FOCUS, NO_FOCUS)
                } else {
                    let start = self.focus_pool.len();
                    for e in 0..self.tight_log.len() {
                        let (id, em) = self.tight_log[e];
                        if em & (1 << l) != 0 {
                            self.focus_pool.push(id);
                        }
                    }
                    (start as u32, self.focus_pool.len() as u32)
                };
                self.refine.push((ts[l], ts[l + 1], depth + 1, nfs, nfe));
            }
        }
        true
    }
}
