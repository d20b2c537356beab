//! The sphere-model checker: for worlds whose robot links are made of spheres (as the
//! spherized URDFs of MotionBenchMaker), in the style of VAMP (Thomason, Kingston & Kavraki,
//! "Motions in Microseconds via Vectorized Sampling-Based Planning", ICRA 2024).
//!
//! - float32 structure of arrays; every quantity is a *lane array* holding up to
//!   [`LANES`] different configurations, so one call checks 8 states of a segment at once
//!   (generic loops over the lanes, the reference; when the CPU has AVX2 + FMA, detected at
//!   run time, the kinematics use fused multiply-adds and the body–obstacle and self-pair tests
//!   run as explicit intrinsics in `avx8`);
//! - forward kinematics fused with checking: the reduced kinematic tree (fixed joints folded
//!   into the next movable one) is walked in tree order and each link is tested against the
//!   obstacles as soon as its frame is known, so a colliding configuration usually stops after
//!   a few links;
//! - per link a bounding sphere guards its fine spheres; per link the obstacles it can never
//!   reach (kinematic reach from the root) are dropped at construction;
//! - obstacles: spheres, oriented boxes, exact cylinders and capsules, each with a closed-form
//!   sphere test; meshes become the oriented box around their vertices (a superset);
//! - no allocation per check;
//! - certified motion checks ([`SphereChecker::segment_certified`]): a whole straight segment
//!   is proven collision-free as a continuous motion. By default from the chord certificate
//!   (`chord.rs`): the computed positions at the checked states and a bound on each point's
//!   acceleration along the joint-space line, so that between two states a sphere stays in a
//!   ball about its chord's midpoint; otherwise (a switch for tests) from bounds on how fast each
//!   link's and each self-collision pair's spheres can move (Schwarzer, Saha & Latombe's
//!   swept-distance argument, "Adaptive dynamic collision checking for single and multiple
//!   articulated robots", IEEE T-RO 2005, here with inflated spheres instead of distances).
//!
//! Conservative against [`super::ExactChecker`]: every robot sphere is inflated by
//! [`SphereChecker::ROUNDING_MARGIN`] (plus the requested padding), above the f32 rounding of
//! the kinematics, so a configuration the exact f64 geometry finds in collision is never reported
//! free. Worlds with other robot geometry or attached objects are not handled:
//! [`SphereChecker::new`] returns `None`, and [`AutoChecker`] falls back to the
//! [`FastChecker`].

// Lane code indexes several arrays with one lane/row index; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use nalgebra::Vector3;

use super::world::{BodyId, CollisionWorld};
use super::{CollisionChecker, Contact, FastChecker, FastModelSettings};
use crate::geometry::Shape;

/// Configurations checked together by [`SphereChecker::segment_free`].
pub const LANES: usize = 8;
type Lane = [f32; LANES];

/// A link's spheres.
#[derive(Debug, Clone)]
struct Body {
    id: BodyId,
    node: u32,
    /// Bounding sphere in the node frame.
    bc: [f32; 3],
    br: f32,
    spheres: (u32, u32),
    /// Range into `body_obstacles`.
    obstacles: (u32, u32),
}

#[derive(Debug, Clone, Copy)]
enum Obs {
    Sphere {
        c: [f32; 3],
        r: f32,
    },
    /// `rt` = rows of the rotation (columns of its transpose): local = Rᵀ (x − c).
    Box {
        c: [f32; 3],
        rt: [[f32; 3]; 3],
        half: [f32; 3],
    },
    Cylinder {
        c: [f32; 3],
        axis: [f32; 3],
        r: f32,
        h: f32,
    },
    Capsule {
        c: [f32; 3],
        axis: [f32; 3],
        r: f32,
        h: f32,
    },
}

/// What collided: a body and an obstacle (and the body's sphere that hit it) or another body.
#[derive(Debug, Clone, Copy)]
enum Hit {
    Obstacle(u32, u32, u32),
    SelfPair(u32, u32),
}

/// The sphere-model checker. See the module documentation.
#[derive(Debug, Clone)]
pub struct SphereChecker {
    world: CollisionWorld,
    steps: Vec<Step>,
    bodies: Vec<Body>,
    /// Fine spheres in their node frame (x, y, z, r).
    spheres: Vec<[f32; 4]>,
    obstacles: Vec<Obs>,
    /// The obstacles pre-broadcast for the AVX2 tests (same order).
    #[cfg(target_arch = "x86_64")]
    obstacles_wide: Vec<avx8::ObsWide>,
    /// Static body index of each obstacle.
    obstacle_static: Vec<u32>,
    body_obstacles: Vec<u32>,
    /// Bounding sphere of each entry of `body_obstacles` (centre, radius with a rounding
    /// allowance; stored alongside, read in the same loop).
    body_obstacle_sphere: Vec<[f32; 4]>,
    self_pairs: Vec<(u32, u32)>,
    /// Per self pair: 0, or, at the first pair of a group, the end of the group (exclusive).
    /// The pairs of a node pair with at least [`Self::NODE_CULL_MIN_PAIRS`] pairs are placed
    /// together as one group, skipped when the nodes' bounding spheres are apart.
    pair_group_end: Vec<u32>,
    /// The node-level cull of pair groups is on (off only to compare against in tests).
    node_cull: bool,
    /// Per node: bounding sphere of its bodies' bounding spheres in the node frame (centre,
    /// radius with a rounding allowance).
    node_sphere: Vec<[f32; 4]>,
    // Per-call lane buffers.
    qv: Vec<Lane>,
    frames: Vec<[Lane; 12]>,
    bcw: Vec<[Lane; 3]>,
    sw: Vec<[Lane; 3]>,
    /// Chord certificate: per sphere, its chords' midpoints and half lengths in this call
    /// (placed with `sw`).
    swm: Vec<[Lane; 3]>,
    swh: Vec<Lane>,
    sw_epoch: Vec<u32>,
    /// Per body: the call (`epoch`) its spheres' chords were computed in.
    chord_epoch: Vec<u32>,
    /// Per node: its bounding sphere's centre in this call (valid when `ncw_epoch` is
    /// `epoch`) and the largest inflation of its bodies.
    ncw: Vec<[Lane; 3]>,
    ncw_epoch: Vec<u32>,
    ninfl: Vec<f32>,
    epoch: u32,
    checks: u64,
    avx2: bool,
    inflate: f64,
    // Certified motion checks (see [`SphereChecker::segment_certified`]).
    /// The chains' speed bounds summed per variable, variable-major (`dof × bodies`): a
    /// body's displacement bound over a segment is `Σ_v |Δq_v| · var_w[v · stride + body]`,
    /// one vectorised pass over the bodies per variable (`stride`: the bodies rounded up to a
    /// multiple of 4, the padding 0).
    var_w: Vec<f64>,
    /// Per self pair (`pair-major`, `dof` each): the speed bounds of both bodies' chain
    /// entries below the pair's common ancestor, per variable (joints above it move both
    /// rigidly and do not count).
    pair_w: Vec<f64>,
    /// Per self pair: its displacement bound over the current segment (valid when
    /// `pair_len_epoch` is `seg_epoch`; computed only for pairs that reach the sphere tests).
    pair_len: Vec<f64>,
    pair_len_epoch: Vec<u32>,
    /// Counts certified segments (the epoch of `pair_len`).
    seg_epoch: u32,
    /// Every prismatic joint has bounded travel, so the speed bounds are finite.
    certifiable: bool,
    /// Per body: displacement bound of its spheres over the segment being certified (padded
    /// with zeros to the stride of `var_w`).
    seg_len: Vec<f64>,
    /// Per body: extra radius of its spheres in the current check (0 outside certification).
    infl: Vec<f32>,
    /// Half the sub-interval length of the current check (0 outside certification): a self
    /// pair's spheres must keep `pair_scale · (cum[pa] + cum[pb])` apart (see
    /// [`SphereChecker::pair_inflation`]).
    pair_scale: f64,
    /// Per world variable: |b − a| of the segment being certified.
    seg_dq: Vec<f64>,
    /// The body that last hit an obstacle in an 8-lane check (`u32::MAX`: none yet). The next
    /// 8-lane check tests it first: motions that collide mostly collide with the same link
    /// (Panda's forearm in 69 % of MotionBenchMaker hits), and a check that hits early skips
    /// the other bodies. Verdicts do not depend on the order.
    hot_body: u32,
    /// The body that was hot before `hot_body` (`u32::MAX`: none): an 8-lane check tests it
    /// second, with the kinematics up to its node, when the hot body finds no collision; a hit
    /// there swaps the two. Measured (callgrind, search only, `--no-simplify`): Baxter's two
    /// arms alternate as the colliding one, and 10 problems per set went 1 948 → 1 803 M
    /// instructions (−7.4 %); 15 Panda problems per set 233.5 → 232.0 M (−0.6 %). Verdicts do
    /// not depend on the order.
    warm_body: u32,
    /// The hot body goes first (off only to compare against in tests).
    hot_first: bool,
    /// The (sphere, obstacle) of the hot body's last hit in an 8-lane check (`u32::MAX`:
    /// none). Before the hot body's full test, that one sphere is placed and tested against
    /// that one obstacle with its plain radius, the test the full one would make. Measured
    /// (callgrind, 15 Panda cage problems): 84 % of the 8-lane checks that collide hit the hot
    /// body, and the probe alone decides 27 % of those (4 575 of 16 637). A probe only ever
    /// finds a collision the full test finds too, so verdicts do not change.
    hot_pair: (u32, u32),
    /// The bodies (obstacle tests) and self pairs (`SELF_PAIR | index`) with tight lanes in
    /// the last check, each once, with those lanes.
    tight_log: Vec<(u32, u32)>,
    /// Per tight state of a certification's first pass: (state, body or self pair).
    tight_states: Vec<(usize, u32)>,
    /// Sub-intervals to refine: (t0, t1, depth, range of `focus_pool`, or `NO_FOCUS`).
    refine: Vec<(f64, f64, u32, u32, u32)>,
    /// The first pass's sub-intervals with a tight end (ascending), before pairing.
    refine_needed: Vec<usize>,
    /// The bodies and self pairs each refinement tests (see [`Self::certify`]).
    focus_pool: Vec<u32>,
    /// Refinements test only what was tight at their ends (off only to compare in tests).
    focus: bool,
    /// Scratch of [`Self::pair_spheres_avx`]: the second body's spheres that can touch the
    /// first body at all (see there).
    pair_keep: Vec<u32>,
    /// Counts of the certified checks (see [`SphereChecker::certify_counts`]).
    certify_counts: certified::CertifyCounts,
    /// Benchmark-only: certified checks run without inflation (see
    /// [`SphereChecker::set_uncertified_for_benchmark`]).
    uncertified: bool,
    /// Certified checks use the chord certificate (see `chord.rs`; off only to compare the
    /// linear one in tests and benchmarks).
    chord: bool,
    /// The static terms of the acceleration bound, per node and per body (see
    /// [`chord::accel_statics`]).
    acc_static_body: Vec<(f64, f64)>,
    /// Per node over the current segment: `[W, C, E, G, P, β]` of
    /// [`SphereChecker::segment_accelerations`].
    acc_node: Vec<[f64; 6]>,
    /// Per body: its acceleration bound over the segment being certified (chord certificate;
    /// valid where `acc_epoch` is `acc_seg`).
    seg_acc: Vec<f64>,
    acc_epoch: Vec<u32>,
    /// Counts chord-certified segments.
    acc_seg: u32,
    /// The non-root nodes of the acceleration recursion, compact, parents first.
    acc_steps: Vec<chord::AccStep>,
    /// The nodes (with the largest `d` of their bodies) whose bounds give the call count
    /// ([`chord::acc_amax_nodes`]).
    acc_amax: Vec<(u32, f64)>,
    /// `h² / 8` of the current chord call, and the count of such calls (the epoch of the
    /// allowances in `infl` and `node_dl`).
    chord_k: f64,
    dl_call: u32,
    dl_epoch: Vec<u32>,
    node_dl_epoch: Vec<u32>,
    node_acc_epoch: Vec<u32>,
    /// Per node: its first body and the distance of its bounding sphere's centre from that
    /// body's (`u32::MAX`: no body).
    node_anchor: Vec<(u32, f64)>,
    /// Per node: the acceleration bound of its bounding sphere's centre, and its allowance.
    node_acc: Vec<f64>,
    node_dl: Vec<f32>,
}

/// Marks a self pair's index among the bodies' indices in `tight_log` and `focus_pool`.
const SELF_PAIR: u32 = 1 << 31;
/// A refinement that tests everything.
const NO_FOCUS: u32 = u32::MAX;

#[inline(always)]
fn f3(v: &Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

impl SphereChecker {
    /// Inflation of every robot sphere covering the f32 rounding of kinematics and tests, metres.
    /// Sphere centres lie within ~1.5 m of the robot base and go through at most a few dozen f32
    /// transform steps (relative error ~6e-8 each), the sin/cos kernels err by ≤ 5e-7 times
    /// lever arms ≤ 1.5 m, and joint values are rounded to f32 (≤ 2.4e-7 rad): together well
    /// under 1e-5 m; at exact contact boundaries the observed error stays below 1e-6 m (the
    /// boundary tests in `tests/collision_spheres.rs` pass with a 1e-6 margin and fail with
    /// none). It is small enough that MotionBenchMaker goals lying 0.05 mm from an obstacle
    /// stay free.
    pub const ROUNDING_MARGIN: f64 = 2.5e-5;

    /// Pairs of one node pair from which the node-level cull is tried first. Measured
    /// (callgrind, segment checks): Baxter's grippers (9 bodies on one node each) give groups
    /// of 9–81 pairs, mostly apart, and gain; Panda's hand group of 4 pairs is usually near
    /// its neighbours, and testing it first cost 2.5 %.
    const NODE_CULL_MIN_PAIRS: u32 = 5;

    /// Turns the hot-body-first order of 8-lane checks on or off (on by default). It never
    /// changes a verdict, only the work; tests compare both.
    #[doc(hidden)]
    pub fn set_hot_first(&mut self, on: bool) {
        self.hot_first = on;
        self.hot_body = u32::MAX;
        self.warm_body = u32::MAX;
        self.hot_pair = (u32::MAX, u32::MAX);
    }

    /// Turns focused refinement of certified checks on or off (on by default): with it, a
    /// refinement tests only the bodies and self pairs tight at its ends. It may certify a
    /// segment that the unfocused check gives up on (deeper refinement of pairs already
    /// certified free), never one with a collision; tests compare both.
    #[doc(hidden)]
    pub fn set_focus(&mut self, on: bool) {
        self.focus = on;
    }

    /// Turns the node-level cull of self-pair groups on or off (on by default). It never
    /// changes a result, only the work; tests compare both.
    #[doc(hidden)]
    pub fn set_node_cull(&mut self, on: bool) {
        self.node_cull = on;
    }

    /// The world this checker was built for.
    pub fn world(&self) -> &CollisionWorld {
        &self.world
    }

    /// (bodies, robot spheres, obstacles, body–obstacle tests kept after reach culling,
    /// self-collision body pairs) — the model's size.
    pub fn model_size(&self) -> (usize, usize, usize, usize, usize) {
        (
            self.bodies.len(),
            self.spheres.len(),
            self.obstacles.len(),
            self.body_obstacles.len(),
            self.self_pairs.len(),
        )
    }

    /// Number of robot spheres.
    pub fn sphere_count(&self) -> usize {
        self.spheres.len()
    }

    /// Largest distance by which this model may report a collision that the exact geometry
    /// does not have: twice (padding + rounding margin), for robot–robot pairs; with a mesh
    /// obstacle its cover's protrusion (infinite for a mesh that is not a solid).
    pub fn max_overapproximation(&self) -> f64 {
        // A mesh obstacle is its cover: a solid's boxes protrude at most a cell diagonal, the box
        // around another mesh's vertices is unbounded against the exact checker's hull.
        let mesh = self
            .world
            .statics
            .iter()
            .flat_map(|s| s.shapes.iter())
            .filter_map(|g| match &g.shape {
                Shape::Mesh(m) => Some(m.cover_protrusion()),
                _ => None,
            })
            .fold(0.0, f64::max);
        // Both spheres of a self-collision pair are inflated.
        (2.0 * self.inflate + 1e-6).max(mesh + self.inflate + 1e-6)
    }

    /// True when every state `a + (b − a)·k/n`, k = 1..=n, is free ("raked": the first call
    /// checks 8 states spread over the whole segment, each further call the next 8 between them).
    pub fn segment_free(&mut self, a: &[f64], b: &[f64], n: usize) -> bool {
        let n = n.max(1);
        let batches = n.div_ceil(LANES);
        let inv = 1.0 / n as f64;
        for j in 0..batches {
            let mut used = 0u64;
            for l in 0..LANES {
                let k = n as isize - j as isize - (l * batches) as isize;
                if k >= 1 {
                    used += 1;
                }
                let k = if k >= 1 { k as usize } else { n };
                let t = k as f64 * inv;
                for (i, v) in self.qv.iter_mut().enumerate() {
                    v[l] = (a[i] + (b[i] - a[i]) * t) as f32;
                }
            }
            self.checks += used;
            if self.collides8() {
                return false;
            }
        }
        true
    }

    /// Checks `qs.len()` ≤ [`LANES`] configurations at once: true when any collides.
    pub fn any_collides(&mut self, qs: &[&[f64]]) -> bool {
        assert!(!qs.is_empty() && qs.len() <= LANES);
        for l in 0..LANES {
            let q = qs[l.min(qs.len() - 1)];
            for (i, v) in self.qv.iter_mut().enumerate() {
                v[l] = q[i] as f32;
            }
        }
        self.checks += qs.len() as u64;
        self.collides8()
    }

    /// [`Self::collides8`] testing only the bodies and self pairs `focus_pool[fs..fe]`.
    fn collides8_focus(&mut self, fs: usize, fe: usize) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU supports AVX2 and FMA (checked at construction).
            return unsafe { self.run8_focus_avx2(fs, fe) }.is_some();
        }
        self.run_focus::<LANES, false>(fs, fe).is_some()
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn run8_focus_avx2(&mut self, fs: usize, fe: usize) -> Option<Hit> {
        self.run_focus::<LANES, true>(fs, fe)
    }

    fn collides8(&mut self) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU supports AVX2 and FMA (checked at construction).
            return unsafe { self.run8_avx2() }.is_some();
        }
        self.run::<LANES, false>().is_some()
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn run8_avx2(&mut self) -> Option<Hit> {
        self.run::<LANES, true>()
    }

    /// One state: with AVX2, in all 8 lanes of the vector path (measured, callgrind, UR5-like
    /// box and table sets: the scalar one-lane path cost 8 300 instructions per state, more
    /// than an 8-lane call); otherwise in lane 0 of the generic path.
    fn single(&mut self, q: &[f64]) -> Option<Hit> {
        self.checks += 1;
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            for (v, &x) in self.qv.iter_mut().zip(q) {
                *v = [x as f32; LANES];
            }
            // SAFETY: the CPU supports AVX2 and FMA (checked at construction).
            return unsafe { self.run8_avx2() };
        }
        for (v, &x) in self.qv.iter_mut().zip(q) {
            v[0] = x as f32;
        }
        self.run::<1, false>()
    }

    /// The fixed-body tests of a call fused with the kinematics (each node's frame computed
    /// when first needed): the hot body (`u32::MAX`: none) with its probe, then the one that
    /// collided before it (warm), then every other body in kinematic order, each with `env`;
    /// `Some` at the first collision, the hot and warm bodies following the hits (8-lane calls
    /// only). Shared by the plain checks ([`Self::run`]) and the chord certificate's
    /// (`chord.rs`), which differ in `env` alone. `stepped`: the frames of the first
    /// `stepped` steps are already computed for the loaded lanes (0: none); on return, those
    /// computed now too. Without `REST`, only the hot and warm bodies are tested (the chord
    /// certificate's start, [`Self::hot_start`]).
    #[inline(always)]
    fn bodies_hot_first<const N: usize, const AVX: bool, const REST: bool>(
        &mut self,
        hot: u32,
        stepped: &mut usize,
        env: fn(&mut Self, usize) -> Option<Hit>,
    ) -> Option<Hit> {
        if hot != u32::MAX {
            let node = self.bodies[hot as usize].node as usize;
            for si in *stepped..=node {
                self.step::<N, AVX>(si);
            }
            *stepped = (*stepped).max(node + 1);
            if self.hot_pair.0 != u32::MAX && self.hot_probe::<N, AVX>(hot as usize) {
                return Some(Hit::Obstacle(hot, self.hot_pair.1, self.hot_pair.0));
            }
            if let Some(h) = env(self, hot as usize) {
                if let Hit::Obstacle(_, o, s) = h {
                    self.hot_pair = (s, o);
                }
                return Some(h);
            }
        }
        let warm = if hot != u32::MAX && self.warm_body != hot {
            self.warm_body
        } else {
            u32::MAX
        };
        if warm != u32::MAX {
            let node = self.bodies[warm as usize].node as usize;
            for si in *stepped..=node {
                self.step::<N, AVX>(si);
            }
            *stepped = (*stepped).max(node + 1);
            if let Some(h) = env(self, warm as usize) {
                if let Hit::Obstacle(_, o, s) = h {
                    self.warm_body = hot;
                    self.hot_body = warm;
                    self.hot_pair = (s, o);
                }
                return Some(h);
            }
        }
        if !REST {
            return None;
        }
        for si in 0..self.steps.len() {
            if si >= *stepped {
                self.step::<N, AVX>(si);
            }
            let (b0, b1) = self.steps[si].bodies;
            for b in b0..b1 {
                if b == hot || b == warm {
                    continue;
                }
                if let Some(h) = env(self, b as usize) {
                    if let (true, Hit::Obstacle(_, o, s)) = (N == LANES, h) {
                        self.warm_body = self.hot_body;
                        self.hot_body = b;
                        self.hot_pair = (s, o);
                    }
                    return Some(h);
                }
            }
        }
        None
    }

    /// Fused FK and checking of the first `N` lanes of `qv`.
    #[inline(always)]
    fn run<const N: usize, const AVX: bool>(&mut self) -> Option<Hit> {
        self.new_call();
        // The hot body first (8-lane checks only), with the kinematics up to its node.
        let hot = if N == LANES && self.hot_first {
            self.hot_body
        } else {
            u32::MAX
        };
        if let Some(h) = self.bodies_hot_first::<N, AVX, true>(hot, &mut 0, Self::env_of::<N, AVX>)
        {
            return Some(h);
        }
        let mut pi = 0;
        while pi < self.self_pairs.len() {
            let (a, b) = self.self_pairs[pi];
            let end = self.pair_group_end[pi] as usize;
            if end != 0 && self.node_cull {
                let (na, nb) = (self.bodies[a as usize].node, self.bodies[b as usize].node);
                if !self.nodes_near::<N, AVX>(na as usize, nb as usize) {
                    pi = end;
                    continue;
                }
            }
            if self.pair_of::<N, AVX>(pi, a as usize, b as usize) {
                return Some(Hit::SelfPair(a, b));
            }
            pi += 1;
        }
        None
    }

    /// Clears the per-call state: the tight log and the epoch of placed spheres.
    #[inline(always)]
    fn new_call(&mut self) {
        self.tight_log.clear();
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.sw_epoch.iter_mut().for_each(|e| *e = 0);
            self.chord_epoch.iter_mut().for_each(|e| *e = 0);
            self.ncw_epoch.iter_mut().for_each(|e| *e = 0);
            self.epoch = 1;
        }
    }

    /// [`Self::run`] restricted to the bodies (against their obstacles) and self pairs
    /// `focus_pool[fs..fe]`, with the kinematics up to the deepest node among them.
    #[inline(always)]
    fn run_focus<const N: usize, const AVX: bool>(&mut self, fs: usize, fe: usize) -> Option<Hit> {
        self.new_call();
        for si in 0..self.focus_steps(fs, fe) {
            self.step::<N, AVX>(si);
        }
        for k in fs..fe {
            let id = self.focus_pool[k];
            if id & SELF_PAIR == 0 {
                if let Some(h) = self.env_of::<N, AVX>(id as usize) {
                    return Some(h);
                }
                continue;
            }
            let pi = (id & !SELF_PAIR) as usize;
            let (a, b) = self.self_pairs[pi];
            for x in [a, b] {
                let body = &self.bodies[x as usize];
                let c = Self::place::<N, AVX>(&self.frames[body.node as usize], &body.bc);
                for r in 0..3 {
                    self.bcw[x as usize][r][..N].copy_from_slice(&c[r]);
                }
            }
            if self.pair_of::<N, AVX>(pi, a as usize, b as usize) {
                return Some(Hit::SelfPair(a, b));
            }
        }
        None
    }

    /// The number of kinematic steps that the bodies and self pairs `focus_pool[fs..fe]` need:
    /// up to the deepest node among them.
    #[inline(always)]
    fn focus_steps(&self, fs: usize, fe: usize) -> usize {
        let mut last = 0;
        for &id in &self.focus_pool[fs..fe] {
            let (a, b) = if id & SELF_PAIR != 0 {
                self.self_pairs[(id & !SELF_PAIR) as usize]
            } else {
                (id, id)
            };
            last = last
                .max(self.bodies[a as usize].node as usize)
                .max(self.bodies[b as usize].node as usize);
        }
        (last + 1).min(self.steps.len())
    }

    /// Whether the hot pair's sphere (of body `b`, its node's frame computed) touches the hot
    /// pair's obstacle in any lane with its plain radius (see [`Self::hot_pair`]).
    #[inline(always)]
    fn hot_probe<const N: usize, const AVX: bool>(&self, b: usize) -> bool {
        let (si, oi) = (self.hot_pair.0 as usize, self.hot_pair.1 as usize);
        let f = &self.frames[self.bodies[b].node as usize];
        let sp = self.spheres[si];
        #[cfg(target_arch = "x86_64")]
        if AVX && N == LANES {
            // SAFETY: as in `env_of`.
            return unsafe { self.hot_probe_avx(f, &sp, oi) };
        }
        let p = Self::place::<N, AVX>(f, &[sp[0], sp[1], sp[2]]);
        obs_mask::<N>(&self.obstacles[oi], &p[0], &p[1], &p[2], sp[3]) != 0
    }

    /// [`Self::hot_probe`] in AVX2 + FMA registers.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn hot_probe_avx(&self, f: &[Lane; 12], sp: &[f32; 4], oi: usize) -> bool {
        let p = avx8::place(f, &[sp[0], sp[1], sp[2]]);
        avx8::obs(&self.obstacles_wide[oi], p, sp[3]) != 0
    }

    /// Self pair `pi` (bodies `a`, `b`, their centres placed).
    #[inline(always)]
    fn pair_of<const N: usize, const AVX: bool>(&mut self, pi: usize, a: usize, b: usize) -> bool {
        #[cfg(target_arch = "x86_64")]
        if AVX && N == LANES {
            // SAFETY: as in `env_of`. The bounding-sphere test inline, the spheres' tests in
            // a call only for the pairs that pass it (13 % on Panda cage).
            return unsafe { self.pair_near_avx(a, b) && self.pair_spheres_avx(pi, a, b) };
        }
        self.pair_hits::<N>(pi, a, b)
    }

    /// Body `b` against the obstacles (its node's frame computed).
    #[inline(always)]
    fn env_of<const N: usize, const AVX: bool>(&mut self, b: usize) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        if AVX && N == LANES {
            // SAFETY: `AVX` is true only inside `run8_avx2` (AVX2 + FMA checked at
            // construction), and the lanes are all LANES wide.
            return unsafe { self.body_env_avx(b) };
        }
        self.body_env::<N>(b)
    }

    /// Whether any lane's bounding spheres of nodes `na` and `nb` (each around all bodies of
    /// the node, grown by the largest inflation among them) touch; when none does, no pair of
    /// their bodies can ([`Self::pair_hits`] tests within those spheres).
    #[inline(always)]
    fn nodes_near<const N: usize, const AVX: bool>(&mut self, na: usize, nb: usize) -> bool {
        for n in [na, nb] {
            if self.ncw_epoch[n] != self.epoch {
                self.ncw_epoch[n] = self.epoch;
                let s = self.node_sphere[n];
                let w = Self::place::<N, AVX>(&self.frames[n], &[s[0], s[1], s[2]]);
                for r in 0..3 {
                    self.ncw[n][r][..N].copy_from_slice(&w[r]);
                }
                let (b0, b1) = self.steps[n].bodies;
                self.ninfl[n] = self.infl[b0 as usize..b1 as usize]
                    .iter()
                    .fold(0.0f32, |m, &x| m.max(x));
            }
        }
        let r =
            self.node_sphere[na][3] + self.node_sphere[nb][3] + (self.ninfl[na] + self.ninfl[nb]);
        near_mask::<N>(&self.ncw[na], &self.ncw[nb], r) != 0
    }

    /// The body's spheres against its obstacles. With an inflation, a lane whose inflated
    /// spheres touch but whose plain spheres do not is logged in `tight_log`; a plain touch is a hit.
    #[inline(always)]
    fn body_env<const N: usize>(&mut self, b: usize) -> Option<Hit> {
        let body = &self.bodies[b];
        let c = Self::place::<N, false>(&self.frames[body.node as usize], &body.bc);
        for r in 0..3 {
            self.bcw[b][r][..N].copy_from_slice(&c[r]);
        }
        let infl = self.infl[b];
        let br = body.br + infl;
        let (o0, o1) = body.obstacles;
        let mut spheres_ready = false;
        let mut tb = 0u32;
        for k in o0 as usize..o1 as usize {
            let oi = self.body_obstacles[k] as usize;
            // Obstacles whose bounding sphere no lane's bounding sphere touches are skipped.
            let ob = self.body_obstacle_sphere[k];
            if point_near_mask::<N>(&c, [ob[0], ob[1], ob[2]], br + ob[3]) == 0 {
                continue;
            }
            let o = self.obstacles[oi];
            if obs_mask::<N>(&o, &c[0], &c[1], &c[2], br) == 0 {
                continue;
            }
            if !spheres_ready {
                self.ensure_spheres::<N, false>(b);
                spheres_ready = true;
            }
            let body = &self.bodies[b];
            for si in body.spheres.0 as usize..body.spheres.1 as usize {
                let w = &self.sw[si];
                let mut x = [0.0f32; N];
                let mut y = [0.0f32; N];
                let mut z = [0.0f32; N];
                x.copy_from_slice(&w[0][..N]);
                y.copy_from_slice(&w[1][..N]);
                z.copy_from_slice(&w[2][..N]);
                let r = self.spheres[si][3];
                let m = obs_mask::<N>(&o, &x, &y, &z, r + infl);
                if m != 0 {
                    if infl == 0.0 || obs_mask::<N>(&o, &x, &y, &z, r) != 0 {
                        return Some(Hit::Obstacle(b as u32, oi as u32, si as u32));
                    }
                    tb |= m;
                }
            }
        }
        if tb != 0 {
            self.tight_log.push((b as u32, tb));
        }
        None
    }

    #[inline(always)]
    fn pair_hits<const N: usize>(&mut self, pi: usize, a: usize, b: usize) -> bool {
        let rr = self.bodies[a].br + self.bodies[b].br + (self.infl[a] + self.infl[b]);
        if near_mask::<N>(&self.bcw[a], &self.bcw[b], rr) == 0 {
            return false;
        }
        let ex = self.pair_inflation(pi);
        self.ensure_spheres::<N, false>(a);
        self.ensure_spheres::<N, false>(b);
        let (sa, sb) = (self.bodies[a].spheres, self.bodies[b].spheres);
        let (bb, rb) = (&self.bcw[b], self.bodies[b].br);
        let mut tp = 0u32;
        for i in sa.0 as usize..sa.1 as usize {
            let (wi, ri) = (&self.sw[i], self.spheres[i][3]);
            // The sphere against b's bounding sphere first.
            if near_mask::<N>(wi, bb, ri + rb + ex) == 0 {
                continue;
            }
            for j in sb.0 as usize..sb.1 as usize {
                let rij = ri + self.spheres[j][3];
                let m = near_mask::<N>(wi, &self.sw[j], rij + ex);
                if m != 0 {
                    if ex == 0.0 || near_mask::<N>(wi, &self.sw[j], rij) != 0 {
                        return true;
                    }
                    tp |= m;
                }
            }
        }
        if tp != 0 {
            self.tight_log.push((SELF_PAIR | pi as u32, tp));
        }
        false
    }

    /// [`Self::body_env`] for 8 lanes in AVX2 + FMA registers: the same tests in the same
    /// order (the generic version is the reference; results differ only by FMA rounding, far
    /// below [`Self::ROUNDING_MARGIN`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn body_env_avx(&mut self, b: usize) -> Option<Hit> {
        use avx8::*;
        let SphereChecker {
            bodies,
            frames,
            bcw,
            infl,
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
        let infl = infl[b];
        let br = body.br + infl;
        let (o0, o1) = (body.obstacles.0 as usize, body.obstacles.1 as usize);
        let (s0, s1) = (body.spheres.0 as usize, body.spheres.1 as usize);
        let mut placed = sw_epoch[b] == *epoch;
        let mut tb = 0u32;
        for (&oi, ob) in body_obstacles[o0..o1]
            .iter()
            .zip(&body_obstacle_sphere[o0..o1])
        {
            // Obstacles whose bounding sphere no lane's bounding sphere touches are skipped.
            if point_near(c, ob, br + ob[3]) == 0 {
                continue;
            }
            let o = &obstacles_wide[oi as usize];
            if obs(o, c, br) == 0 {
                continue;
            }
            if !placed {
                placed = true;
                sw_epoch[b] = *epoch;
                for (sp, w) in spheres[s0..s1].iter().zip(&mut sw[s0..s1]) {
                    store3(w, place(f, &[sp[0], sp[1], sp[2]]));
                }
            }
            for (si, (sp, w)) in spheres[s0..s1].iter().zip(&sw[s0..s1]).enumerate() {
                let p = load3(w);
                let m = obs(o, p, sp[3] + infl);
                if m != 0 {
                    if infl == 0.0 || obs(o, p, sp[3]) != 0 {
                        return Some(Hit::Obstacle(b as u32, oi, (s0 + si) as u32));
                    }
                    tb |= m;
                }
            }
        }
        if tb != 0 {
            tight_log.push((b as u32, tb));
        }
        None
    }

    /// The first test of [`Self::pair_hits`] in AVX2 + FMA registers: whether the bodies'
    /// bounding spheres (grown by their inflations) touch in any lane.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn pair_near_avx(&self, a: usize, b: usize) -> bool {
        let (ca, cb) = (avx8::load3(&self.bcw[a]), avx8::load3(&self.bcw[b]));
        let r = self.bodies[a].br + self.bodies[b].br + (self.infl[a] + self.infl[b]);
        avx8::near(ca, cb, r) != 0
    }

    /// [`Self::pair_hits`] after its first test ([`Self::pair_near_avx`]) for 8 lanes in
    /// AVX2 + FMA registers (see [`Self::body_env_avx`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn pair_spheres_avx(&mut self, pi: usize, a: usize, b: usize) -> bool {
        use avx8::*;
        let ca = load3(&self.bcw[a]);
        let cb = load3(&self.bcw[b]);
        let ex = self.pair_inflation(pi);
        self.ensure_spheres::<LANES, true>(a);
        self.ensure_spheres::<LANES, true>(b);
        let (ba, bb) = (&self.bodies[a], &self.bodies[b]);
        let (sa0, sa1) = (ba.spheres.0 as usize, ba.spheres.1 as usize);
        let (sb0, sb1) = (bb.spheres.0 as usize, bb.spheres.1 as usize);
        let (ra, rb) = (ba.br, bb.br);
        // b's spheres that touch a's bounding sphere (grown by the pair's inflation): only
        // they can touch one of a's spheres, which lie inside it (|c_j − c_a| ≤ |c_j − c_i| +
        // |c_i − c_a| ≤ r_i + r_j + ex + r_a − r_i). The cull of a's spheres against b's
        // bounding sphere below, from the other side, so that for pairs of bodies of many
        // spheres (hands, held rods, links of other arms) most sphere pairs go untested; the
        // same sphere pairs are tested in the same order otherwise, so verdicts and tight
        // lanes are those of `pair_hits`. Measured (callgrind, `bench collision --multi-arm
        // --samples 2000`): this function 1 205 → 1 000 M instructions, the 8-lane checks
        // 3 993 → 3 790 M (−5 %). Not in the generic `pair_hits`, whose single-state use
        // (one lane) got 1 % slower with it.
        let mut keep = std::mem::take(&mut self.pair_keep);
        keep.clear();
        for (j, (sj, wj)) in self.spheres[sb0..sb1]
            .iter()
            .zip(&self.sw[sb0..sb1])
            .enumerate()
        {
            if near(load3(wj), ca, sj[3] + ra + ex) != 0 {
                keep.push((sb0 + j) as u32);
            }
        }
        let mut tp = 0u32;
        let mut hit = false;
        'outer: for (si, wi) in self.spheres[sa0..sa1].iter().zip(&self.sw[sa0..sa1]) {
            if keep.is_empty() {
                break;
            }
            let (pi_, ri) = (load3(wi), si[3]);
            // The sphere against b's bounding sphere first.
            if near(pi_, cb, ri + rb + ex) == 0 {
                continue;
            }
            for &j in &keep {
                let j = j as usize;
                let pj = load3(&self.sw[j]);
                let rij = ri + self.spheres[j][3];
                let m = near(pi_, pj, rij + ex);
                if m != 0 {
                    if ex == 0.0 || near(pi_, pj, rij) != 0 {
                        hit = true;
                        break 'outer;
                    }
                    tp |= m;
                }
            }
        }
        self.pair_keep = keep;
        if hit {
            return true;
        }
        if tp != 0 {
            self.tight_log.push((SELF_PAIR | pi as u32, tp));
        }
        false
    }

    fn contact(&self, h: Hit) -> Contact {
        let (a, b) = match h {
            Hit::Obstacle(b, o, _) => (
                self.bodies[b as usize].id,
                BodyId::Static(self.obstacle_static[o as usize] as usize),
            ),
            Hit::SelfPair(a, b) => (self.bodies[a as usize].id, self.bodies[b as usize].id),
        };
        Contact {
            a: self.world.body_name(a),
            b: self.world.body_name(b),
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx8;
mod lanes;
use lanes::*;

impl CollisionChecker for SphereChecker {
    fn is_free(&mut self, q: &[f64]) -> bool {
        self.single(q).is_none()
    }

    fn first_contact(&mut self, q: &[f64]) -> Option<Contact> {
        let h = self.single(q)?;
        Some(self.contact(h))
    }

    fn checks(&self) -> u64 {
        self.checks
    }
}

/// The [`SphereChecker`] when the world's robots are made of spheres, else the [`FastChecker`].
#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)]
pub enum AutoChecker {
    Spheres(SphereChecker),
    Fast(FastChecker),
}

impl AutoChecker {
    /// `padding` (metres) is added to every robot primitive in either model.
    pub fn new(world: &CollisionWorld, padding: f64) -> AutoChecker {
        match SphereChecker::new(world, padding) {
            Some(s) => AutoChecker::Spheres(s),
            None => AutoChecker::Fast(FastChecker::with_settings(
                world,
                FastModelSettings { padding },
            )),
        }
    }

    /// "spheres" or "fast".
    pub fn kind(&self) -> &'static str {
        match self {
            AutoChecker::Spheres(_) => "spheres",
            AutoChecker::Fast(_) => "fast",
        }
    }

    /// Checks the states `a + (b − a)·k/n`, k = 1..=n: 8-lane raked batches with the sphere
    /// model, [`FastChecker::segment_free`] with the fast one (`None`: check them one by one).
    pub fn segment_free(&mut self, a: &[f64], b: &[f64], n: usize) -> Option<bool> {
        match self {
            AutoChecker::Spheres(s) => Some(s.segment_free(a, b, n)),
            AutoChecker::Fast(f) => f.segment_free(a, b, n),
        }
    }
}

impl CollisionChecker for AutoChecker {
    fn is_free(&mut self, q: &[f64]) -> bool {
        match self {
            AutoChecker::Spheres(s) => s.is_free(q),
            AutoChecker::Fast(f) => f.is_free(q),
        }
    }

    fn first_contact(&mut self, q: &[f64]) -> Option<Contact> {
        match self {
            AutoChecker::Spheres(s) => s.first_contact(q),
            AutoChecker::Fast(f) => f.first_contact(q),
        }
    }

    fn checks(&self) -> u64 {
        match self {
            AutoChecker::Spheres(s) => s.checks(),
            AutoChecker::Fast(f) => f.checks(),
        }
    }
}

mod certified;
mod chord;
pub use certified::{CertifyCounts, SegmentScreen};
mod kinematics;
use kinematics::{origin_terms, Axis, OriginRot, Step, StepKind};
mod model;

#[cfg(test)]
mod tests;
