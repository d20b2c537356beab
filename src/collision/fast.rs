//! The planners' collision checker: a conservative primitive model, no allocation per check.
//!
//! Every shape becomes one primitive with an exact, closed-form or support-function test:
//! spheres, oriented boxes (separating axes), cylinders and capsules (closed form against
//! spheres, boolean GJK against boxes and each other); a solid mesh becomes its box cover
//! (`src/geometry/solid.rs`; the coarse one on robot links), another mesh the box around its
//! vertices (conservative supersets). A body of many primitives (a fine cover: the statuette of
//! paper 003 resting or held) is tested in two levels, group boxes first (`groups.rs`). Each body
//! (link, attached object, fixed body) has a
//! bounding sphere, fixed bodies a world-aligned box; these are tested first, and the pair list
//! is precomputed from [`CollisionWorld::pairs`], without the pairs that no configuration within
//! the joint limits brings together (reach balls about their first common ancestor, see
//! `pair_can_touch`). Every primitive is inflated by 1e-9 m, so
//! whenever [`super::ExactChecker`] reports a collision this checker does too; the largest
//! over-approximation is reported by [`FastChecker::max_overapproximation`] (≈ 0 without meshes).
//!
//! Its motion check ([`FastChecker::segment_free`], [`FastChecker::motion_certified`],
//! `sweep.rs`) proves the continuous straight motion collision-free, not only its states at a
//! resolution: swept-displacement bounds per body (how far any point of it can move along the
//! motion) against the primitives grown by them, refined where that is tight; motions it cannot
//! prove are refused. What is proven and under which bound: `sweep.rs`. The discrete verdict of
//! the states at the resolution remains as [`FastChecker::segment_free_skipping`] (tests).

use nalgebra::Vector3;

use super::world::{BodyId, CollisionWorld, PlacedRobot};
use super::{CollisionChecker, Contact};
use crate::geometry::Shape;

use crate::kinematics::{FkModel, Frame};

mod build;
mod groups;
mod prim;
mod sweep;

pub(crate) use prim::Prim;
use prim::{aabb, bounding_of, dist2_point_aabb, prim_sets_hit, EPS};

/// Settings of the fast model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FastModelSettings {
    /// Extra padding added to every moving primitive (a safety distance), metres.
    pub padding: f64,
}

impl Default for FastModelSettings {
    fn default() -> Self {
        FastModelSettings { padding: 0.0 }
    }
}

/// `prims_ready` mark of a body whose world primitives never change (a body that no active
/// variable moves, see [`FastChecker::for_active`]).
const PERMANENT: u32 = u32::MAX;

/// Where a moving body hangs: robot link or attached object.
#[derive(Debug, Clone, Copy)]
struct Mount {
    robot: usize,
    link: usize,
}

#[derive(Debug, Clone)]
struct MovingBody {
    id: BodyId,
    mount: Mount,
    /// Primitives in the frame of the mount link.
    local: Vec<Prim>,
    /// Bounding sphere in the frame of the mount link.
    bc: Vector3<f64>,
    br: f64,
    /// Range of this body's primitives in the per-check world buffer.
    start: usize,
    /// Groups of `local` (empty: not grouped; `groups.rs`) and the first of them in the
    /// per-check group buffers.
    groups: Vec<groups::Group>,
    gstart: usize,
}

#[derive(Debug, Clone)]
struct StaticBodyModel {
    id: BodyId,
    /// Primitives in the world with their world-aligned boxes `(prim, lo, hi)`.
    prims: Vec<(Prim, Vector3<f64>, Vector3<f64>)>,
    /// Groups of `prims` (empty: not grouped; `groups.rs`).
    groups: Vec<groups::StaticGroup>,
    lo: Vector3<f64>,
    hi: Vector3<f64>,
}

/// Pair to test: moving body index, and either a static (is_static) or another moving body.
#[derive(Debug, Clone, Copy)]
struct Pair {
    a: u32,
    b: u32,
    b_static: bool,
    /// Squared reach of the body bounding spheres: (r_a + r_b)² against a moving body, r_a²
    /// against a fixed body's box, so the cull touches nothing but the pair and the centres.
    reach2: f64,
}

/// Conservative checker used by planners. See the module documentation.
#[derive(Debug, Clone)]
pub struct FastChecker {
    world: CollisionWorld,
    moving: Vec<MovingBody>,
    statics: Vec<StaticBodyModel>,
    pairs: Vec<Pair>,
    /// `(static body, first pair, end pair)` for the pairs against fixed bodies.
    static_groups: Vec<(u32, u32, u32)>,
    /// Index of the first moving–moving pair.
    self_start: usize,
    /// Box around the bounding spheres of all moving bodies (per check).
    moving_lo: Vector3<f64>,
    moving_hi: Vector3<f64>,
    fk: Vec<FkModel>,
    bases: Vec<Frame>,
    // Per-check buffers.
    link_poses: Vec<Vec<Frame>>,
    /// Per robot: the variables `link_poses` were computed for (empty: not yet;
    /// [`FastChecker::robot_frames`] recomputes what changed).
    fk_last: Vec<Vec<f64>>,
    /// The frames of the sweep's travel-bound pieces (`sweep/travel.rs`), apart from
    /// `link_poses` so that the state checked next keeps its frames, and their variables.
    piece_poses: Vec<Vec<Frame>>,
    piece_last: Vec<Vec<f64>>,
    body_bc: Vec<Vector3<f64>>,
    world_prims: Vec<Prim>,
    /// Bounding-sphere radius of each primitive of `world_prims` (about its centre; constant).
    prim_radius: Vec<f64>,
    prims_ready: Vec<u32>,
    /// Per moving body: the mount frame its world primitives (or group boxes) were last made
    /// with (NaN: never); a body whose frame has not changed keeps them.
    prims_frame: Vec<Frame>,
    /// Grouped bodies (`groups.rs`): the group boxes in the world (made with the body's
    /// primitives' epoch, `prims_ready`), their bounding radii, the epoch of each group's
    /// members in `world_prims`, and a scratch list of unit pairs.
    world_groups: Vec<Prim>,
    group_radius: Vec<f64>,
    group_ready: Vec<u32>,
    unit_pairs: Vec<(u32, u32)>,
    /// World centres of the sweep's mount spheres (per inflated check, `sweep.rs`).
    mount_c: Vec<Vector3<f64>>,
    /// Bodies whose frames each check recomputes (all, except those no active variable moves);
    /// the box around the moving bodies covers these.
    dynamic: Vec<u32>,
    epoch: u32,
    checks: u64,
    overapprox: f64,
    settings: FastModelSettings,
    /// For a checker of active variables ([`FastChecker::for_active`]): the active world
    /// variables, the frozen ones with their values, and the first colliding pair among those
    /// tested once at build time (it collides in every configuration).
    frozen: Option<Frozen>,
    /// Speed bounds of the bodies and buffers of segment checks (`sweep.rs`).
    sweep: sweep::Sweep,
    /// Largest inflation of [`FastChecker::segment_free`] (0: every state is checked).
    skip_inflation: f64,
    /// Coarse inflation of certified segment checks; `None`: [`FastChecker::segment_free`]
    /// gives the discrete verdict instead (tests only).
    certify: Option<f64>,
    /// Counts of certified checks and the smallest inflation a proof needed.
    certify_stats: CertifyStats,
    certify_finest: f64,
    /// The motions most recently proven free ([`Self::certify_motion`]).
    proven: ProvenMotions,
}

/// The last [`PROVEN_SLOTS`] motions a checker proved free, by the exact bits of both ends and
/// of the coarse inflation: the same call again (a planner's final re-validation of the segments
/// it accepted) gets the same answer without repeating the same deterministic computation.
#[derive(Debug, Clone, Default)]
struct ProvenMotions {
    /// Per slot: a hash of the key, the coarse inflation's bits; the ends in `ends`
    /// (`2 · dof` values per slot).
    keys: Vec<(u64, u64)>,
    ends: Vec<f64>,
    next: usize,
}

/// Slots of [`ProvenMotions`].
const PROVEN_SLOTS: usize = 64;

impl ProvenMotions {
    fn hash(a: &[f64], b: &[f64]) -> u64 {
        // FNV-1a over the bits.
        a.iter().chain(b).fold(0xcbf2_9ce4_8422_2325u64, |h, v| {
            (h ^ v.to_bits()).wrapping_mul(0x0000_0100_0000_01b3)
        })
    }

    fn contains(&self, a: &[f64], b: &[f64], inflation: f64) -> bool {
        let n = a.len() + b.len();
        let h = ProvenMotions::hash(a, b);
        self.keys.iter().enumerate().any(|(i, &(kh, ki))| {
            kh == h && ki == inflation.to_bits() && {
                let e = &self.ends[i * n..(i + 1) * n];
                a.iter()
                    .chain(b)
                    .zip(e)
                    .all(|(x, y)| x.to_bits() == y.to_bits())
            }
        })
    }

    fn insert(&mut self, a: &[f64], b: &[f64], inflation: f64) {
        let n = a.len() + b.len();
        let key = (ProvenMotions::hash(a, b), inflation.to_bits());
        let i = if self.keys.len() < PROVEN_SLOTS {
            self.keys.push(key);
            self.ends.resize(self.keys.len() * n, 0.0);
            self.keys.len() - 1
        } else {
            let i = self.next;
            self.next = (self.next + 1) % PROVEN_SLOTS;
            self.keys[i] = key;
            i
        };
        let e = &mut self.ends[i * n..(i + 1) * n];
        for (x, y) in e.iter_mut().zip(a.iter().chain(b)) {
            *x = *y;
        }
    }
}

/// What a certified motion check found ([`FastChecker::certify_motion`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Certification {
    /// The continuous motion is proven collision-free.
    Free,
    /// A state of the motion collides.
    Collides,
    /// Not proven either way within the refinement floor and budget (refused).
    Unproven,
}

/// Counts of a checker's certified motion checks ([`FastChecker::certify_stats`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct CertifyStats {
    /// Motions checked.
    pub motions: u64,
    /// Motions proven collision-free.
    pub proven_free: u64,
    /// Motions with a state in collision.
    pub collides: u64,
    /// Motions refused as not provable (refinement floor or budget reached).
    pub unproven: u64,
    /// Largest body inflation of the coarse level (metres).
    pub max_inflation: f64,
    /// Smallest body inflation (metres) a refinement may reach before it refuses.
    pub floor: f64,
    /// Smallest largest-body inflation (metres) that a proof of a free motion needed (how
    /// close a certified motion came to a contact, roughly; 0 when none was proven).
    pub finest_inflation: f64,
}

#[derive(Debug, Clone)]
struct Frozen {
    active: Vec<usize>,
    fixed: Vec<(usize, f64)>,
    constant_hit: Option<Pair>,
}

impl FastChecker {
    pub fn new(world: &CollisionWorld) -> FastChecker {
        FastChecker::with_settings(world, FastModelSettings::default())
    }

    pub fn with_settings(world: &CollisionWorld, settings: FastModelSettings) -> FastChecker {
        FastChecker::build(world, settings, None)
    }

    /// A checker for configurations that move only the world variables `active` away from
    /// `q0` (a full world configuration), e.g. a planner's joint space: joints of the other
    /// variables are frozen at `q0` in the forward kinematics, and every pair whose relative
    /// pose no active variable changes (two bodies on the same rigid part, or a body that does
    /// not move against a fixed body) is tested once here instead of in every check. A
    /// configuration that differs from `q0` outside `active` is still checked correctly: the
    /// checker first rebuilds itself for it (slow, allocates; planners never do this).
    pub fn for_active(
        world: &CollisionWorld,
        settings: FastModelSettings,
        active: &[usize],
        q0: &[f64],
    ) -> FastChecker {
        let mut c = FastChecker::build(world, settings, Some((active, q0)));
        c.checks = 0;
        c
    }

    /// The bodies of the first colliding pair, if any: [`CollisionChecker::first_contact`]
    /// without building names (allocation-free).
    pub fn first_contact_ids(&mut self, q: &[f64]) -> Option<(BodyId, BodyId)> {
        let p = self.find(q)?;
        let a = self.moving[p.a as usize].id;
        let b = if p.b_static {
            self.statics[p.b as usize].id
        } else {
            self.moving[p.b as usize].id
        };
        Some((a, b))
    }

    /// Whether pair `pi` collides in the prepared configuration.
    fn pair_hits(&mut self, pi: usize) -> bool {
        let p = self.pairs[pi];
        if p.b_static {
            self.static_pair_hits(pi)
        } else {
            self.moving_pair_hits(p)
        }
    }

    /// Largest distance by which the fast model may report a collision that the exact
    /// geometry does not have (0 for worlds of spheres and boxes; two cover cell diagonals with
    /// solid meshes, infinite with other meshes).
    pub fn max_overapproximation(&self) -> f64 {
        self.overapprox
    }

    /// The world this checker was built for.
    pub fn world(&self) -> &CollisionWorld {
        &self.world
    }

    /// Default largest inflation (metres) of [`Self::segment_free`]. On the kitchen planners
    /// (`bench planners`) 0.04–0.08 m were within noise of each other for IK-RRT and 0.06–0.08
    /// best for the dual-arm and mobile ones.
    pub const SKIP_INFLATION: f64 = 0.06;

    /// Sets the largest inflation of [`Self::segment_free`]; 0 makes it check every state.
    pub fn set_skip_inflation(&mut self, metres: f64) {
        self.skip_inflation = if metres.is_finite() && metres > 0.0 {
            metres
        } else {
            0.0
        };
    }

    /// The motion check of planners. With certification on (the default,
    /// [`Self::set_certification`]): `Some(true)` exactly when [`Self::motion_certified`]
    /// proves the continuous motion `a → b` free (`n` is not used). Off (tests of the discrete
    /// check): `Some(true)` exactly when every state `a + (b − a)·k/n`, k = 1..=n, is free,
    /// proving runs of states free together where it can ([`Self::segment_free_skipping`] with
    /// the inflation of [`Self::set_skip_inflation`]), `None` when the states are best checked
    /// one by one.
    pub fn segment_free(&mut self, a: &[f64], b: &[f64], n: usize) -> Option<bool> {
        if let Some(d) = self.certify {
            return Some(self.segment_certified(a, b, d));
        }
        if self.skip_inflation > 0.0 {
            self.segment_free_skipping(a, b, n, self.skip_inflation)
        } else {
            None
        }
    }

    /// Default coarse inflation (metres) of certified motion checks: the skip inflation of the
    /// discrete check, measured best there (`bench planners`, [`Self::SKIP_INFLATION`]).
    pub const CERTIFY_INFLATION: f64 = 0.06;

    /// Smallest body inflation (metres) a certified check refines down to before refusing.
    pub const CERTIFY_FLOOR: f64 = sweep::CERTIFY_FLOOR;

    /// Certified motion checks in [`Self::segment_free`] with a coarse inflation of at most
    /// `max_inflation` metres (`Some`), or the discrete verdict of the states (`None`, or a
    /// non-positive inflation).
    pub fn set_certification(&mut self, max_inflation: Option<f64>) {
        self.certify = max_inflation.filter(|d| d.is_finite() && *d > 0.0);
    }

    /// The coarse inflation of certified checks in [`Self::segment_free`], when on.
    pub fn certification(&self) -> Option<f64> {
        self.certify
    }

    /// True only when the straight motion `a → b` between world configurations (both ends
    /// included; any variables may move) is proven collision-free for every checked pair of the
    /// world — robot links, attached objects and fixed bodies, several robots at once — as a
    /// continuous motion, not only at sampled states. [`Self::segment_certified`] with the
    /// coarse inflation of [`Self::set_certification`] ([`Self::CERTIFY_INFLATION`] when off).
    ///
    /// Bound: along the motion no point of body `i` moves farther than
    /// `L_i = Σ_v |b_v − a_v|·w_iv` ([`crate::kinematics::FkModel::speed_bounds`]), so a run
    /// `[t0, t1]` is free when both its ends are free with every body grown by
    /// `L_i·(t1 − t0)/2` (pairs of moving bodies: the joints below their common ancestor, on
    /// both sides). Proven in this checker's model, which contains the exact geometry (meshes as
    /// the box around their vertices, every primitive grown by 1e-9 m and the padding).
    /// Conservative: motions it cannot prove (closer than [`Self::CERTIFY_FLOOR`] to a contact,
    /// too many refinements, a prismatic variable outside its limits, unbounded speeds,
    /// non-finite values) are answered `false`.
    pub fn motion_certified(&mut self, a: &[f64], b: &[f64]) -> bool {
        let d = self.certify.unwrap_or(FastChecker::CERTIFY_INFLATION);
        self.segment_certified(a, b, d)
    }

    /// [`Self::motion_certified`] with the coarse inflation `max_inflation` (metres): the
    /// motion is cut into equal runs whose bodies grow by at most `max_inflation`; a run whose
    /// ends are free only without the inflation ("tight") is halved, recursively, testing only
    /// the pairs tight at its ends, until every run is proven free (true), a state collides
    /// (false), or the inflation falls below [`Self::CERTIFY_FLOOR`] or more than 4 096 runs
    /// are to be halved (false: not provable).
    pub fn segment_certified(&mut self, a: &[f64], b: &[f64], max_inflation: f64) -> bool {
        self.certify_motion(a, b, max_inflation) == Certification::Free
    }

    /// [`Self::segment_certified`] with the reason of a refusal; counted in
    /// [`Self::certify_stats`]. The last 64 motions proven free are remembered by the exact bits
    /// of `a`, `b` and `max_inflation`: asked again (a planner's final re-validation of the
    /// segments it accepted), the answer is that proof's, without computing it again (the
    /// check is deterministic: the same input gives the same proof).
    pub fn certify_motion(&mut self, a: &[f64], b: &[f64], max_inflation: f64) -> Certification {
        let dof = self.world.dof();
        let keyed = a.len() == dof && b.len() == dof;
        let r = if keyed && self.proven.contains(a, b, max_inflation) {
            Certification::Free
        } else {
            let r = self.certify_segment(a, b, max_inflation);
            if keyed && r == Certification::Free {
                self.proven.insert(a, b, max_inflation);
            }
            r
        };
        let st = &mut self.certify_stats;
        st.motions += 1;
        st.max_inflation = st.max_inflation.max(max_inflation);
        match r {
            Certification::Free => st.proven_free += 1,
            Certification::Collides => st.collides += 1,
            Certification::Unproven => st.unproven += 1,
        }
        r
    }

    /// Forgets the motions proven so far ([`Self::certify_motion`] remembers the last 64): the
    /// next check of any motion proves it again, as a new checker of the same world would.
    pub fn forget_proven(&mut self) {
        self.proven = ProvenMotions::default();
    }

    /// Starts the counts of [`Self::certify_stats`] again.
    pub fn reset_certify_stats(&mut self) {
        self.certify_stats = CertifyStats::default();
        self.certify_finest = f64::INFINITY;
    }

    /// Counts of the certified motion checks since the last [`Self::reset_certify_stats`].
    pub fn certify_stats(&self) -> CertifyStats {
        let mut s = self.certify_stats;
        s.floor = FastChecker::CERTIFY_FLOOR;
        s.finest_inflation = if self.certify_finest.is_finite() {
            self.certify_finest
        } else {
            0.0
        };
        s
    }

    /// Number of body pairs tested per check (before bounding-sphere culling).
    pub fn pair_count(&self) -> usize {
        self.pairs.len()
    }

    #[inline]
    fn prepare(&mut self, q: &[f64]) {
        for r in 0..self.world.robots.len() {
            self.robot_frames(r, q);
        }
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for &i in &self.dynamic {
            let i = i as usize;
            let b = &self.moving[i];
            let f = &self.link_poses[b.mount.robot][b.mount.link];
            let c = f.rot * b.bc + f.t;
            lo = lo.inf(&c.add_scalar(-b.br));
            hi = hi.sup(&c.add_scalar(b.br));
            self.body_bc[i] = c;
        }
        self.moving_lo = lo;
        self.moving_hi = hi;
        self.next_epoch();
    }

    /// Robot `r`'s link frames for the world configuration `q` into `link_poses[r]`: only
    /// what changed since its last call is recomputed ([`FkModel::update`]; the same frames
    /// as computing them all). Everything that writes `link_poses` goes through here.
    #[inline]
    pub(super) fn robot_frames(&mut self, r: usize, q: &[f64]) {
        self.frames_for(r, q, false);
    }

    /// [`Self::robot_frames`] into `piece_poses` (the travel bound's pieces).
    #[inline]
    pub(super) fn piece_frames(&mut self, r: usize, q: &[f64]) {
        self.frames_for(r, q, true);
    }

    /// Robot `r`'s frames for `q` into `piece_poses` (`piece`) or `link_poses`, recomputing
    /// only what changed since that buffer's last configuration (none yet: everything).
    #[inline]
    fn frames_for(&mut self, r: usize, q: &[f64], piece: bool) {
        let p = &self.world.robots[r];
        let q = &q[p.offset..p.offset + p.robot.dof()];
        let (last, out) = if piece {
            (&mut self.piece_last[r], &mut self.piece_poses[r])
        } else {
            (&mut self.fk_last[r], &mut self.link_poses[r])
        };
        if last.len() == q.len() {
            self.fk[r].update(&self.bases[r], q, last, out);
        } else {
            self.fk[r].compute(&self.bases[r], q, out);
            last.clear();
            last.extend_from_slice(q);
        }
    }

    /// [`Self::prepare`] for a test of the pairs `focus` only (indices into the pair list):
    /// the frames of the robots they involve and their bodies' bounding-sphere centres (not the
    /// box around all moving bodies).
    fn prepare_focused(&mut self, q: &[f64], focus: &[u32]) {
        let nr = self.world.robots.len();
        let mut robots = 0u64;
        for &pi in focus {
            let p = self.pairs[pi as usize];
            robots |= 1 << (self.moving[p.a as usize].mount.robot % 64);
            if !p.b_static {
                robots |= 1 << (self.moving[p.b as usize].mount.robot % 64);
            }
        }
        for r in 0..nr {
            if nr > 64 || robots & (1 << r) != 0 {
                self.robot_frames(r, q);
            }
        }
        for &pi in focus {
            let p = self.pairs[pi as usize];
            let b_moving = (!p.b_static).then_some(p.b as usize);
            for i in std::iter::once(p.a as usize).chain(b_moving) {
                if self.prims_ready[i] != PERMANENT {
                    let b = &self.moving[i];
                    let f = &self.link_poses[b.mount.robot][b.mount.link];
                    self.body_bc[i] = f.rot * b.bc + f.t;
                }
            }
        }
        self.next_epoch();
    }

    /// A new epoch of the world primitives (a new prepared configuration).
    #[inline]
    fn next_epoch(&mut self) {
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 || self.epoch == PERMANENT {
            self.prims_ready
                .iter_mut()
                .chain(self.group_ready.iter_mut())
                .filter(|e| **e != PERMANENT)
                .for_each(|e| *e = 0);
            self.epoch = 1;
        }
    }

    /// The world primitives of moving body `i` for the prepared configuration; of a grouped
    /// body its group boxes only (the members on demand, [`Self::ensure_group`]).
    #[inline]
    fn ensure_prims(&mut self, i: usize) {
        if self.prims_ready[i] == self.epoch || self.prims_ready[i] == PERMANENT {
            return;
        }
        self.prims_ready[i] = self.epoch;
        let b = &self.moving[i];
        let f = &self.link_poses[b.mount.robot][b.mount.link];
        let last = &mut self.prims_frame[i];
        let same = |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(a, b)| a.to_bits() == b.to_bits());
        if same(f.rot.as_slice(), last.rot.as_slice()) && same(f.t.as_slice(), last.t.as_slice()) {
            // The frame the body's world primitives were made with (the other arm's links
            // while one arm moves): they stand.
            return;
        }
        *last = *f;
        if b.groups.is_empty() {
            for (k, p) in b.local.iter().enumerate() {
                self.world_prims[b.start + k] = p.transformed(&f.rot, &f.t);
            }
        } else {
            for (k, g) in b.groups.iter().enumerate() {
                self.world_groups[b.gstart + k] = g.bound.transformed(&f.rot, &f.t);
            }
        }
    }

    /// The first colliding pair, if any.
    fn find(&mut self, q: &[f64]) -> Option<Pair> {
        self.checks += 1;
        if let Some(f) = &self.frozen {
            if f.fixed.iter().any(|&(v, x)| q[v].to_bits() != x.to_bits()) {
                // Moved outside the active variables: freeze at this configuration instead.
                let active = f.active.clone();
                let (checks, skip) = (self.checks, self.skip_inflation);
                let (certify, stats, finest) =
                    (self.certify, self.certify_stats, self.certify_finest);
                *self = FastChecker::build(&self.world.clone(), self.settings, Some((&active, q)));
                self.checks = checks;
                self.skip_inflation = skip;
                self.certify = certify;
                self.certify_stats = stats;
                self.certify_finest = finest;
            }
            if let Some(p) = self.frozen.as_ref().and_then(|f| f.constant_hit) {
                return Some(p);
            }
        }
        self.prepare(q);
        for g in 0..self.static_groups.len() {
            let (sb, first, end) = self.static_groups[g];
            let s = &self.statics[sb as usize];
            if (0..3).any(|k| s.lo[k] > self.moving_hi[k] || s.hi[k] < self.moving_lo[k]) {
                continue;
            }
            for pi in first as usize..end as usize {
                if self.static_pair_hits(pi) {
                    return Some(self.pairs[pi]);
                }
            }
        }
        for pi in self.self_start..self.pairs.len() {
            let p = self.pairs[pi];
            if self.moving_pair_hits(p) {
                return Some(p);
            }
        }
        None
    }

    /// Whether the moving bodies of pair `p` collide in the prepared configuration. The
    /// bounding-sphere cull is inlined into the check loop; only pairs that pass call out.
    #[inline(always)]
    fn moving_pair_hits(&mut self, p: Pair) -> bool {
        let (a, b) = (p.a as usize, p.b as usize);
        (self.body_bc[a] - self.body_bc[b]).norm_squared() <= p.reach2
            && self.moving_prims_hit(a, b)
    }

    /// Whether the primitives of moving bodies `a` and `b` collide (bounding spheres overlap).
    fn moving_prims_hit(&mut self, a: usize, b: usize) -> bool {
        self.moving_prims_hit_by(a, b, 0.0)
    }

    /// Whether the primitives of moving bodies `a` and `b` touch with those of `a` grown by
    /// `d` ≥ 0 (the relative motion of the two in a segment check).
    fn moving_prims_hit_by(&mut self, a: usize, b: usize, d: f64) -> bool {
        self.ensure_prims(a);
        self.ensure_prims(b);
        let (ma, mb) = (&self.moving[a], &self.moving[b]);
        if !(ma.groups.is_empty() && mb.groups.is_empty()) {
            return self.grouped_moving_hit_by(a, b, d);
        }
        let (ra, rb) = (
            ma.start..ma.start + ma.local.len(),
            mb.start..mb.start + mb.local.len(),
        );
        let (pa, pb) = (&self.world_prims[ra.clone()], &self.world_prims[rb.clone()]);
        prim_sets_hit(pa, &self.prim_radius[ra], pb, &self.prim_radius[rb], d)
    }

    /// Whether pair `pi` (a moving body against a fixed one) collides; the box cull is
    /// inlined into the check loop.
    #[inline(always)]
    fn static_pair_hits(&mut self, pi: usize) -> bool {
        let p = self.pairs[pi];
        let (a, b) = (p.a as usize, p.b as usize);
        let s = &self.statics[b];
        dist2_point_aabb(&self.body_bc[a], &s.lo, &s.hi) <= p.reach2 && self.static_prims_hit(a, b)
    }

    /// Whether the primitives of moving body `a` and fixed body `b` collide.
    fn static_prims_hit(&mut self, a: usize, b: usize) -> bool {
        self.static_prims_hit_by(a, b, 0.0)
    }

    /// Whether the primitives of moving body `a`, grown by `d` ≥ 0, touch fixed body `b`.
    fn static_prims_hit_by(&mut self, a: usize, b: usize, d: f64) -> bool {
        self.ensure_prims(a);
        let ma = &self.moving[a];
        if !ma.groups.is_empty() {
            return self.grouped_static_hit_by(a, b, d);
        }
        let range = ma.start..ma.start + ma.local.len();
        let (pa, rad) = (&self.world_prims[range.clone()], &self.prim_radius[range]);
        let s = &self.statics[b];
        pa.iter()
            .zip(rad)
            .any(|(x, &xr)| groups::static_body_hits(s, x, xr, d))
    }
}

impl CollisionChecker for FastChecker {
    fn is_free(&mut self, q: &[f64]) -> bool {
        self.find(q).is_none()
    }

    fn first_contact(&mut self, q: &[f64]) -> Option<Contact> {
        let (a, b) = self.first_contact_ids(q)?;
        Some(Contact {
            a: self.world.body_name(a),
            b: self.world.body_name(b),
        })
    }

    fn checks(&self) -> u64 {
        self.checks
    }
}
