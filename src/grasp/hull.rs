//! A 6-D convex hull (quickhull / beneath-beyond with simplicial facets) for grasp wrench spaces.
//!
//! No hull crate fits (the `qhull` crate needs libclang at build time, a system package this
//! machine does not have; chull panics above 3-D, quickhull and parry's hull are 3-D only), so
//! this is an own implementation of Barber, Dobkin & Huhdanpaa's quickhull (1996) in fixed
//! dimension [`DIM`] = 6:
//!
//! 1. **Joggle** (as qhull's `QJ`): every input point is moved by a deterministic pseudo-random
//!    offset of at most `joggle × scale` per coordinate (`scale` = largest absolute coordinate,
//!    `joggle` = [`HullOptions::joggle`], 1e-6 by default). Exact duplicates are dropped first
//!    (the first occurrence is kept). The offset is a hash of the point's own coordinates and the
//!    attempt number (not of its index), so permuting the input gives bit-identical joggled
//!    points. After joggling, the input is in general position with probability 1, so every
//!    facet is a simplex and no facet merging is needed. The joggle must be well above
//!    √(machine ε): the cone wrenches of one contact are exactly co-flat, and joggled facets
//!    holding several of them are slivers as thin as the joggle whose normals carry round-off /
//!    joggle errors (with 1e-10 the hull came out visibly non-convex).
//! 2. **Initial simplex**: 7 points chosen greedily for volume (the first the one with the
//!    smallest x₀, each next one the farthest from the affine span of those chosen); if any next
//!    point is within `20 × joggle` of that span, the points are flat ([`HullError::Flat`], not
//!    retried). The interior point is the simplex centroid.
//! 3. **Outside sets**: each point is assigned to one facet it lies above (distance > τ,
//!    τ = 1e-10 × scale, above the sliver round-off); points above no facet are inside for good.
//! 4. **Expansion**: for a facet with a non-empty outside set, its farthest point p is the apex;
//!    the visible facets are found by a breadth-first walk over facet adjacency; each horizon ridge
//!    (a visible facet's side whose neighbour is not visible) and p form a new facet, linked to the
//!    non-visible neighbour across the ridge and to each other through their ridges that hold p:
//!    a small open-addressing table keyed by the ridge's other 4 vertex ids (sorted), stamped
//!    per expansion so it is never cleared. The orphaned outside points are
//!    reassigned to the new facets. Each point is an apex at most once, so the loop ends after at
//!    most N rounds.
//! 5. **Checks**: unpaired or over-paired ridges, a degenerate new facet (hyperplane not
//!    determined), an interior point not strictly inside, and finally local convexity (the
//!    opposite vertex of every neighbour lies below the facet, within the joggle) — a closed,
//!    locally convex simplicial surface around an interior point is convex. Any of these
//!    failures restarts with a 10× larger joggle (by default 1e-6, 1e-5, 1e-4 relative: three
//!    attempts); after that [`HullError::Degenerate`]. More than [`HullOptions::max_facets`]
//!    live facets is [`HullError::TooManyFacets`] at once. Nothing panics and nothing loops
//!    unboundedly.
//! 6. **Polish** ([`ConvexHull::support_depth`]): the joggle shifts facet planes by about the
//!    joggle; the depth of the origin is recomputed from the unjoggled points (support values of
//!    the facet normals and of the planes through the facets' unjoggled vertices), which is exact
//!    to round-off for well-conditioned faces and never below the true depth when the origin is
//!    inside.
//!
//! 7. **Only the nearest facets** (submodule `nearest`, [`nearest_facet_depth`],
//!    [`depth_exceeds`]): the same joggled points and steps 2 and 4, but only the facet nearest
//!    to the origin is ever expanded (an expanding-polytope search), which gives the polished
//!    depth of step 6 from a fraction of the facets, or proves a lower bound early.
//!
//! Hyperplanes: the normal of 6 points is the null vector of the 5×6 matrix of differences
//! `v_k − v_0`, computed by modified Gram–Schmidt with re-orthogonalisation (each difference
//! orthonormalised twice against the previous ones), then the unit coordinate axis with the largest
//! residual is projected onto the orthogonal complement. The normal is oriented away from the
//! interior point; the offset is the mean of `n · v_k`. A new facet of step 4 gets its plane
//! cheaper, from the pencil of its two parents' planes (the visible facet and its non-visible
//! neighbour both contain the horizon ridge): ψ = −φ_g(p) φ_f + φ_f(p) φ_g vanishes on the ridge
//! and at the apex p (about 60 flops where Gram–Schmidt costs about 500; it was 46 % of the
//! nearest-facet search). The pencil plane is kept only when it passes within 1e-14 × scale of
//! all 6 of its (joggled) vertices and has the interior strictly inside — an a-posteriori check,
//! so no error is inherited from the parents — and is recomputed by Gram–Schmidt otherwise
//! (nearly parallel parents, where the pencil cancels: 5 of 243 000 new facets on 100
//! 8-contact kitchen_two wrench sets, none of 171 000 on 100 20-contact ones).
//!
//! Cost: O(N log N)-ish expected for points in general position plus O(F) per round for the
//! visible set, where F (the number of facets) can grow like O(N^3) in 6-D in the worst case;
//! [`HullOptions::max_facets`] bounds memory (reused buffers, one `Vec` per facet for its outside
//! set; the peak was about 230 bytes per facet: 140 MB RSS for 6.1e5 facets). Measured in release
//! mode on the 2-core development machine (8 cone edges, point contacts): 3 contacts ≈ 640
//! facets in 1.5 ms, 4 contacts ≈ 1300 facets in 3.6 ms, 10 random contacts ≈ 5800 facets in
//! about 40 ms, 20 about 14 000 facets in 0.1 s, 64 about 60 000 facets in 0.55 s; with 32 cone
//! edges 64 contacts give 6.1e5 facets in 9 s. Those figures predate the pencil planes and the
//! stamped ridge table, which made the 20-contact hull about 2.7× faster (`manyhands bench
//! multi-robot --only score`, one core, alternated in one loaded sitting: median 38.6 ms
//! against 105 ms).

mod nearest;

pub use nearest::{depth_exceeds, nearest_facet_depth, NearestDepth};

use std::collections::HashSet;

/// The dimension of wrench space.
pub const DIM: usize = 6;

/// A point of R^6 (a wrench `[force; λ · torque]`).
pub type Point6 = [f64; DIM];

const NONE: u32 = u32::MAX;

/// A hull facet: a 6-vertex simplex on the hyperplane `normal · x = offset`; `normal` is a unit
/// vector pointing out of the hull, so `offset` is the signed distance of the origin from the
/// facet plane, positive when the origin is on the inner side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Facet {
    /// Indices into the input points.
    pub vertices: [u32; DIM],
    pub normal: Point6,
    pub offset: f64,
}

/// Why a hull could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HullError {
    #[error("{0} distinct points cannot span a 6-D hull (at least 7 are needed)")]
    TooFewPoints(usize),
    #[error("point {index} has a non-finite coordinate")]
    NonFinite { index: usize },
    #[error("the points lie in an affine subspace of fewer than 6 dimensions")]
    Flat,
    #[error("the hull has more than {limit} facets")]
    TooManyFacets { limit: usize },
    #[error("numerically inconsistent hull even after {attempts} joggles")]
    Degenerate { attempts: u32 },
}

/// Knobs of [`ConvexHull::with_options`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HullOptions {
    /// Stop with [`HullError::TooManyFacets`] beyond this many live facets.
    pub max_facets: usize,
    /// First joggle, relative to the largest absolute coordinate. Retries multiply it by 10, at
    /// most twice. It must be well above √(machine ε) ≈ 1.5e-8: the wrenches of one contact are
    /// exactly co-flat (a 2-flat), so joggled facets with several of them are slivers as thin as
    /// the joggle, whose normals carry round-off / joggle errors.
    pub joggle: f64,
}

impl Default for HullOptions {
    fn default() -> Self {
        HullOptions {
            max_facets: 1_000_000,
            joggle: 1e-6,
        }
    }
}

/// The convex hull of a set of points of R^6.
#[derive(Debug, Clone)]
pub struct ConvexHull {
    facets: Vec<Facet>,
    points: Vec<Point6>,
    scale: f64,
    joggle: f64,
}

/// The points' checks shared by the full hull and the nearest-facet search: every coordinate
/// finite, the largest absolute coordinate (the scale of tolerances), and the indices kept after
/// dropping exact duplicates (each kept index is the first occurrence, so indices stay stable);
/// more than `DIM` of them, or there is no full-dimensional hull.
pub(crate) fn prepare(points: &[Point6]) -> Result<(f64, Vec<u32>), HullError> {
    if let Some(index) = points.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        return Err(HullError::NonFinite { index });
    }
    let scale = points
        .iter()
        .flat_map(|p| p.iter())
        .fold(0.0f64, |m, c| m.max(c.abs()));
    let mut seen = HashSet::with_capacity(points.len());
    let keep: Vec<u32> = (0..points.len() as u32)
        .filter(|&i| seen.insert(points[i as usize].map(f64::to_bits)))
        .collect();
    if keep.len() <= DIM {
        return Err(HullError::TooFewPoints(keep.len()));
    }
    Ok((scale, keep))
}

impl ConvexHull {
    /// The hull with [`HullOptions::default`].
    pub fn new(points: &[Point6]) -> Result<ConvexHull, HullError> {
        ConvexHull::with_options(points, &HullOptions::default())
    }

    pub fn with_options(points: &[Point6], opts: &HullOptions) -> Result<ConvexHull, HullError> {
        let (scale, keep) = prepare(points)?;
        let mut rel = opts.joggle.max(1e-14);
        let mut b = Builder::default();
        const ATTEMPTS: u32 = 3;
        for attempt in 0..ATTEMPTS {
            let delta = rel * scale;
            let jogged: Vec<Point6> = keep
                .iter()
                .map(|&i| joggle(&points[i as usize], delta, attempt))
                .collect();
            match b.build(&jogged, scale, delta, opts.max_facets) {
                Ok(()) => {
                    let facets = b
                        .facets
                        .iter()
                        .filter(|f| f.alive)
                        .map(|f| Facet {
                            vertices: f.v.map(|k| keep[k as usize]),
                            normal: f.normal,
                            offset: f.off,
                        })
                        .collect();
                    let mut pts = points.to_vec();
                    for (k, &i) in keep.iter().enumerate() {
                        pts[i as usize] = jogged[k];
                    }
                    return Ok(ConvexHull {
                        facets,
                        points: pts,
                        scale,
                        joggle: delta,
                    });
                }
                Err(Fail::Numeric) => rel *= 10.0,
                Err(Fail::Hard(e)) => return Err(e),
            }
        }
        Err(HullError::Degenerate { attempts: ATTEMPTS })
    }

    /// The facets (simplices; a flat face of a degenerate input comes out triangulated).
    pub fn facets(&self) -> &[Facet] {
        &self.facets
    }

    /// The points the hull was built from, after joggling (duplicates unchanged).
    pub fn joggled_points(&self) -> &[Point6] {
        &self.points
    }

    /// Largest absolute input coordinate.
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// The absolute joggle used (largest coordinate offset).
    pub fn joggle(&self) -> f64 {
        self.joggle
    }

    /// Signed distance from the origin to the hull boundary: min over facets of `offset`;
    /// positive iff the origin is strictly inside. This is the depth of the joggled hull, as
    /// computed (sliver facets may carry normal errors near 1e-6 relative); see
    /// [`ConvexHull::support_depth`] for the polished value.
    pub fn origin_depth(&self) -> f64 {
        self.facets
            .iter()
            .map(|f| f.offset)
            .fold(f64::INFINITY, f64::min)
    }

    /// The origin depth polished against `points` (the unjoggled input the hull was built from).
    ///
    /// Candidates are the facets whose offset is within 2 × slack of the smallest (slack =
    /// 1e-4 × scale + 100 × joggle), taken in increasing offset until one exceeds the best value
    /// found so far by more than the slack. For each candidate two unit normals are tried: the facet's own (from joggled points) and the
    /// hyperplane through its 6 vertices taken *unjoggled* (when they are well conditioned: each
    /// Gram–Schmidt residual ≥ 1e-6 × scale). For a normal n the support value
    /// h(n) = max_i n · p_i is the offset of a supporting hyperplane of the input, so it never
    /// underestimates the true depth (= min over unit n of h(n) when the origin is inside). The
    /// unjoggled vertices of a joggled facet lie on one true face, so a well-conditioned simplex
    /// of the nearest face gives the exact face plane and the result equals the true depth to
    /// round-off, independent of the joggle (permuting or extending the input changes it only
    /// by round-off). Without such a simplex the error is of the order of the joggle (upper
    /// bound). Cost: O(F) plus O(N) per candidate facet.
    pub fn support_depth(&self, points: &[Point6]) -> f64 {
        let min_off = self.origin_depth();
        if !min_off.is_finite() || points.len() != self.points.len() {
            return min_off;
        }
        let slack = 1e-4 * self.scale + 100.0 * self.joggle;
        let mut cand: Vec<(f64, usize)> = self
            .facets
            .iter()
            .enumerate()
            .filter(|(_, f)| f.offset <= min_off + 2.0 * slack)
            .map(|(i, f)| (f.offset, i))
            .collect();
        cand.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut best = f64::INFINITY;
        for (off, i) in cand {
            if off - slack > best {
                break;
            }
            let f = &self.facets[i];
            best = best.min(polished_support(points, &f.vertices, &f.normal, self.scale));
        }
        best
    }
}

/// The support value h(n) = max_i n · p_i of `points`.
fn support(points: &[Point6], n: &Point6) -> f64 {
    points
        .iter()
        .map(|p| dot(n, p))
        .fold(f64::NEG_INFINITY, f64::max)
}

/// One candidate facet of [`ConvexHull::support_depth`]: the smaller support value of `points`
/// (unjoggled) over the facet's own unit normal and the normal of the hyperplane through its
/// vertices taken unjoggled, when they are well conditioned (each Gram–Schmidt residual ≥
/// 1e-6 × `scale`), oriented like `normal`.
fn polished_support(points: &[Point6], vertices: &[u32; DIM], normal: &Point6, scale: f64) -> f64 {
    let well = 1e-6 * scale;
    let mut best = support(points, normal);
    let o = points[vertices[0] as usize];
    let mut q = [[0.0; DIM]; DIM];
    let conditioned = (1..DIM).all(|k| {
        let d = sub(&points[vertices[k] as usize], &o);
        orthonormalise(&mut q, k - 1, d) >= well
    });
    if conditioned {
        if let Some((mut n, _)) = complement(points, vertices, &mut q) {
            if dot(&n, normal) < 0.0 {
                n = n.map(|x| -x);
            }
            best = best.min(support(points, &n));
        }
    }
    best
}

enum Fail {
    Numeric,
    Hard(HullError),
}

#[derive(Debug, Clone, Default)]
struct F {
    v: [u32; DIM],
    n: [u32; DIM],
    /// The neighbour `n[k]`'s vertex opposite the shared ridge (for the convexity check).
    o: [u32; DIM],
    normal: Point6,
    off: f64,
    outside: Vec<u32>,
    alive: bool,
    /// Round in which the facet was found visible / examined.
    vis: u32,
    seen: u32,
    /// Allocation stamp (slots are reused): tells a stale heap entry of [`nearest`] apart.
    birth: u32,
}

/// The working state, reused across joggle attempts.
#[derive(Default)]
struct Builder {
    facets: Vec<F>,
    free: Vec<u32>,
    live: usize,
    visible: Vec<u32>,
    new_ids: Vec<u32>,
    pending: Vec<u32>,
    ridges: RidgeTable,
    orphans: Vec<u32>,
    /// The initial simplex's vertices.
    simplex: [u32; DIM + 1],
    /// Facets allocated so far (the next [`F::birth`]).
    births: u32,
}

/// Largest residual (relative to the scale) of a new facet's pencil plane at its 6 vertices
/// ([`Builder::through_ridge`]) before it is recomputed by Gram–Schmidt.
const PENCIL_RESIDUAL: f64 = 1e-14;

/// Pairs the ridges through the apex of one expansion's new facets (each such ridge is shared
/// by exactly two new facets): open addressing keyed by the ridge's 4 other vertex ids
/// (sorted), slots stamped with the expansion so nothing is cleared between expansions. The
/// pairing does not depend on the hash, so the hull does not either.
#[derive(Default)]
struct RidgeTable {
    slots: Vec<RidgeSlot>,
    stamp: u32,
    /// Ridges inserted and not yet paired in this expansion.
    open: usize,
}

#[derive(Clone, Copy, Default)]
struct RidgeSlot {
    key: [u32; DIM - 2],
    facet: u32,
    slot: u8,
    paired: bool,
    stamp: u32,
}

impl RidgeTable {
    /// Starts an expansion with at most `ridges` insertions.
    fn begin(&mut self, ridges: usize) {
        let cap = (2 * ridges).next_power_of_two().max(16);
        if self.slots.len() < cap {
            self.slots = vec![RidgeSlot::default(); cap];
            self.stamp = 0;
        }
        if self.stamp == u32::MAX {
            self.slots.iter_mut().for_each(|s| s.stamp = 0);
            self.stamp = 0;
        }
        self.stamp += 1;
        self.open = 0;
    }

    /// Inserts the ridge `key` of (`facet`, `slot`), or pairs it with the one inserted before:
    /// `Ok(Some(that facet, its slot))`; a third occurrence is an error.
    fn pair(&mut self, key: [u32; DIM - 2], facet: u32, slot: u8) -> Result<Option<(u32, u8)>, ()> {
        let mask = self.slots.len() - 1;
        let h = (u64::from(key[0]) | u64::from(key[1]) << 32).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (u64::from(key[2]) | u64::from(key[3]) << 32).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        let mut i = (h >> 32) as usize & mask;
        loop {
            let s = &mut self.slots[i];
            if s.stamp != self.stamp {
                *s = RidgeSlot {
                    key,
                    facet,
                    slot,
                    paired: false,
                    stamp: self.stamp,
                };
                self.open += 1;
                return Ok(None);
            }
            if s.key == key {
                if s.paired {
                    return Err(());
                }
                s.paired = true;
                self.open -= 1;
                return Ok(Some((s.facet, s.slot)));
            }
            i = (i + 1) & mask;
        }
    }
}

/// Sorts 5 (id, slot) pairs by id (a sorting network).
fn sort5(k: &mut [(u32, u8); DIM - 1]) {
    for (a, b) in [
        (0, 1),
        (3, 4),
        (2, 4),
        (2, 3),
        (0, 3),
        (0, 2),
        (1, 4),
        (1, 3),
        (1, 2),
    ] {
        if k[a].0 > k[b].0 {
            k.swap(a, b);
        }
    }
}

fn dot(a: &Point6, b: &Point6) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn sub(a: &Point6, b: &Point6) -> Point6 {
    std::array::from_fn(|i| a[i] - b[i])
}

fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The point moved by a pseudo-random offset in [-delta, delta]^6 seeded by its own bits.
fn joggle(p: &Point6, delta: f64, attempt: u32) -> Point6 {
    let mut s = 0x5EED_0000_0000_0000u64 ^ u64::from(attempt);
    for c in p {
        s ^= c.to_bits();
        splitmix(&mut s);
    }
    std::array::from_fn(|i| {
        let u = (splitmix(&mut s) >> 11) as f64 / (1u64 << 53) as f64; // [0, 1)
        p[i] + delta * (2.0 * u - 1.0)
    })
}

/// Orthonormalises `d` against `q[..k]` (twice, modified Gram–Schmidt); returns the residual norm.
fn orthonormalise(q: &mut [Point6], k: usize, mut d: Point6) -> f64 {
    for _ in 0..2 {
        for qj in &q[..k] {
            let c = dot(&d, qj);
            for i in 0..DIM {
                d[i] -= c * qj[i];
            }
        }
    }
    let n = dot(&d, &d).sqrt();
    if n > 0.0 {
        q[k] = d.map(|x| x / n);
    }
    n
}

/// Unit normal and offset of the hyperplane through 6 points, or None when they do not
/// determine one (some difference vector within `tiny` of the span of the previous ones).
fn hyperplane(pts: &[Point6], v: &[u32; DIM], tiny: f64) -> Option<(Point6, f64)> {
    let o = pts[v[0] as usize];
    let mut q = [[0.0; DIM]; DIM];
    for k in 1..DIM {
        let d = sub(&pts[v[k] as usize], &o);
        if orthonormalise(&mut q, k - 1, d) <= tiny {
            return None;
        }
    }
    complement(pts, v, &mut q)
}

/// The unit normal orthogonal to `q[..5]` (orthonormal) and the mean offset of the points `v`.
fn complement(pts: &[Point6], v: &[u32; DIM], q: &mut [Point6; DIM]) -> Option<(Point6, f64)> {
    // The axis least represented in span(q) gives the best-conditioned complement.
    let mut best = (0usize, -1.0f64);
    for a in 0..DIM {
        let r = 1.0 - q[..DIM - 1].iter().map(|qj| qj[a] * qj[a]).sum::<f64>();
        if r > best.1 {
            best = (a, r);
        }
    }
    let mut e = [0.0; DIM];
    e[best.0] = 1.0;
    if orthonormalise(q, DIM - 1, e) <= 1e-8 {
        return None;
    }
    let n = q[DIM - 1];
    let off = v.iter().map(|&i| dot(&n, &pts[i as usize])).sum::<f64>() / DIM as f64;
    Some((n, off))
}

impl Builder {
    fn alloc(&mut self, v: [u32; DIM], normal: Point6, off: f64) -> u32 {
        self.live += 1;
        self.births = self.births.wrapping_add(1);
        match self.free.pop() {
            Some(i) => {
                // In place: the slot keeps its outside set's allocation (cleared by kill).
                let slot = &mut self.facets[i as usize];
                slot.birth = self.births;
                slot.v = v;
                slot.n = [NONE; DIM];
                slot.o = [NONE; DIM];
                slot.normal = normal;
                slot.off = off;
                slot.alive = true;
                slot.vis = 0;
                slot.seen = 0;
                i
            }
            None => {
                self.facets.push(F {
                    birth: self.births,
                    v,
                    n: [NONE; DIM],
                    o: [NONE; DIM],
                    normal,
                    off,
                    outside: Vec::new(),
                    alive: true,
                    vis: 0,
                    seen: 0,
                });
                (self.facets.len() - 1) as u32
            }
        }
    }

    fn kill(&mut self, i: u32) {
        let f = &mut self.facets[i as usize];
        f.alive = false;
        f.outside.clear();
        self.live -= 1;
        self.free.push(i);
    }

    fn dist(&self, f: u32, p: &Point6) -> f64 {
        let f = &self.facets[f as usize];
        dot(&f.normal, p) - f.off
    }

    /// A plane through `v`, oriented away from `interior`.
    fn oriented(
        pts: &[Point6],
        v: &[u32; DIM],
        interior: &Point6,
        tiny: f64,
        tau: f64,
    ) -> Result<(Point6, f64), Fail> {
        let (mut n, mut off) = hyperplane(pts, v, tiny).ok_or(Fail::Numeric)?;
        let d = dot(&n, interior) - off;
        if d.abs() <= tau {
            return Err(Fail::Numeric);
        }
        if d > 0.0 {
            n = n.map(|x| -x);
            off = -off;
        }
        Ok((n, off))
    }

    fn build(
        &mut self,
        pts: &[Point6],
        scale: f64,
        delta: f64,
        max_facets: usize,
    ) -> Result<(), Fail> {
        let tau = 1e-10 * scale;
        let interior = self.init(pts, scale, delta)?;
        let n = pts.len();
        let simplex = self.simplex;
        for i in 0..n as u32 {
            if simplex.contains(&i) {
                continue;
            }
            let p = &pts[i as usize];
            if let Some(f) = (0..=DIM as u32).find(|&f| self.dist(f, p) > tau) {
                self.facets[f as usize].outside.push(i);
            }
        }
        self.pending.extend(0..=DIM as u32);

        let mut round = 0u32;
        while let Some(f0) = self.pending.pop() {
            let f0u = f0 as usize;
            if !self.facets[f0u].alive || self.facets[f0u].outside.is_empty() {
                continue;
            }
            round += 1;
            // The apex: the farthest outside point.
            let (apex, _) = self.facets[f0u]
                .outside
                .iter()
                .fold((NONE, f64::MIN), |b, &i| {
                    let d = self.dist(f0, &pts[i as usize]);
                    if d > b.1 {
                        (i, d)
                    } else {
                        b
                    }
                });
            self.expand(pts, apex, f0, round, &interior, scale)?;
            // Orphaned outside points go to the new facets (or are inside now).
            self.orphans.clear();
            for vi in 0..self.visible.len() {
                let f = self.visible[vi] as usize;
                self.orphans.extend_from_slice(&self.facets[f].outside);
            }
            for oi in 0..self.orphans.len() {
                let i = self.orphans[oi];
                if i == apex {
                    continue;
                }
                let q = &pts[i as usize];
                let hit = self
                    .new_ids
                    .iter()
                    .copied()
                    .find(|&nf| self.dist(nf, q) > tau);
                if let Some(nf) = hit {
                    self.facets[nf as usize].outside.push(i);
                }
            }
            for vi in 0..self.visible.len() {
                let f = self.visible[vi];
                self.kill(f);
            }
            for ni in 0..self.new_ids.len() {
                let nf = self.new_ids[ni];
                if !self.facets[nf as usize].outside.is_empty() {
                    self.pending.push(nf);
                }
            }
            if self.live > max_facets {
                return Err(Fail::Hard(HullError::TooManyFacets { limit: max_facets }));
            }
        }
        self.check_convex(pts, delta)
    }

    /// Step 2 of the module docs: clears the state and builds the initial simplex's 7 facets
    /// (ids 0..=6, facet k opposite simplex vertex k); returns the interior point.
    fn init(&mut self, pts: &[Point6], scale: f64, delta: f64) -> Result<Point6, Fail> {
        self.facets.clear();
        self.free.clear();
        self.live = 0;
        self.pending.clear();
        let tau = 1e-10 * scale;
        let tiny = 1e-13 * scale;
        let n = pts.len();

        // Initial simplex: greedy volume.
        let mut simplex = [0u32; DIM + 1];
        let i0 = (0..n)
            .min_by(|&a, &b| pts[a][0].total_cmp(&pts[b][0]))
            .unwrap_or(0);
        simplex[0] = i0 as u32;
        let mut q = [[0.0; DIM]; DIM];
        for k in 0..DIM {
            let mut best = (0usize, -1.0f64);
            for (i, p) in pts.iter().enumerate() {
                let mut d = sub(p, &pts[i0]);
                for qj in &q[..k] {
                    let c = dot(&d, qj);
                    for t in 0..DIM {
                        d[t] -= c * qj[t];
                    }
                }
                let r = dot(&d, &d);
                if r > best.1 {
                    best = (i, r);
                }
            }
            let d = sub(&pts[best.0], &pts[i0]);
            let r = orthonormalise(&mut q, k, d);
            if r <= 20.0 * delta {
                return Err(Fail::Hard(HullError::Flat));
            }
            simplex[k + 1] = best.0 as u32;
        }
        let mut interior = [0.0; DIM];
        for &i in &simplex {
            for t in 0..DIM {
                interior[t] += pts[i as usize][t] / (DIM + 1) as f64;
            }
        }
        for k in 0..=DIM {
            let mut v = [0u32; DIM];
            let mut nb = [0u32; DIM];
            let others = simplex.iter().enumerate().filter(|&(j, _)| j != k);
            for (s, (j, &vj)) in others.enumerate() {
                v[s] = vj;
                nb[s] = j as u32; // the ridge opposite vertex j is shared with facet j
            }
            let (normal, off) = Self::oriented(pts, &v, &interior, tiny, tau)?;
            let id = self.alloc(v, normal, off);
            debug_assert_eq!(id as usize, k);
            self.facets[id as usize].n = nb;
            // Facet j (without vertex j) has simplex vertex k off the shared ridge.
            self.facets[id as usize].o = [simplex[k]; DIM];
        }
        self.simplex = simplex;
        Ok(interior)
    }

    /// Step 4 of the module docs for apex `apex` above facet `f0`: finds the visible facets
    /// (into `self.visible`, marked with `round`, not yet killed) by a breadth-first walk from
    /// `f0`, builds a new facet on each horizon ridge (into `self.new_ids`) and links the new
    /// facets to their non-visible neighbours and to each other.
    fn expand(
        &mut self,
        pts: &[Point6],
        apex: u32,
        f0: u32,
        round: u32,
        interior: &Point6,
        scale: f64,
    ) -> Result<(), Fail> {
        let tau = 1e-10 * scale;
        let f0u = f0 as usize;
        let p = &pts[apex as usize];
        // Visible facets: breadth-first over adjacency from f0.
        self.visible.clear();
        self.visible.push(f0);
        self.facets[f0u].vis = round;
        self.facets[f0u].seen = round;
        let mut head = 0;
        while head < self.visible.len() {
            let f = self.visible[head];
            head += 1;
            for k in 0..DIM {
                let g = self.facets[f as usize].n[k];
                if g == NONE {
                    return Err(Fail::Numeric);
                }
                let gu = g as usize;
                if self.facets[gu].seen == round {
                    continue;
                }
                self.facets[gu].seen = round;
                if self.dist(g, p) > tau {
                    self.facets[gu].vis = round;
                    self.visible.push(g);
                }
            }
        }
        // Horizon → new facets.
        self.new_ids.clear();
        for vi in 0..self.visible.len() {
            let f = self.visible[vi];
            for k in 0..DIM {
                let g = self.facets[f as usize].n[k];
                if self.facets[g as usize].vis == round {
                    continue;
                }
                let mut v = self.facets[f as usize].v;
                v[k] = apex;
                let (normal, off) = self.through_ridge(pts, f, k, &v, interior, scale)?;
                let nf = self.alloc(v, normal, off);
                let Some(j) = self.facets[g as usize].n.iter().position(|&x| x == f) else {
                    return Err(Fail::Numeric);
                };
                let gf = &mut self.facets[g as usize];
                gf.n[j] = nf;
                gf.o[j] = apex;
                let gv = gf.v[j];
                let nfu = &mut self.facets[nf as usize];
                nfu.n[k] = g;
                nfu.o[k] = gv;
                self.new_ids.push(nf);
            }
        }
        // The new facets' ridges through the apex, paired by their other 4 vertices.
        self.ridges.begin(self.new_ids.len() * (DIM - 1));
        for ni in 0..self.new_ids.len() {
            let nf = self.new_ids[ni];
            let v = self.facets[nf as usize].v;
            // The 5 other vertices with their slots, sorted by id: the ridge opposite slot
            // w[r].1 is the apex and w without w[r], still sorted.
            let mut w = [(0u32, 0u8); DIM - 1];
            let mut s = 0;
            for (j, &x) in v.iter().enumerate() {
                if x != apex && s < DIM - 1 {
                    w[s] = (x, j as u8);
                    s += 1;
                }
            }
            sort5(&mut w);
            let keys = [
                [w[1].0, w[2].0, w[3].0, w[4].0],
                [w[0].0, w[2].0, w[3].0, w[4].0],
                [w[0].0, w[1].0, w[3].0, w[4].0],
                [w[0].0, w[1].0, w[2].0, w[4].0],
                [w[0].0, w[1].0, w[2].0, w[3].0],
            ];
            for (r, &key) in keys.iter().enumerate() {
                let i = w[r].1;
                match self.ridges.pair(key, nf, i) {
                    Ok(None) => {}
                    Ok(Some((of, oi))) => {
                        if self.facets[of as usize].n[oi as usize] != NONE
                            || self.facets[nf as usize].n[i as usize] != NONE
                        {
                            return Err(Fail::Numeric);
                        }
                        self.facets[nf as usize].n[i as usize] = of;
                        self.facets[nf as usize].o[i as usize] =
                            self.facets[of as usize].v[oi as usize];
                        self.facets[of as usize].n[oi as usize] = nf;
                        self.facets[of as usize].o[oi as usize] = v[i as usize];
                    }
                    Err(()) => return Err(Fail::Numeric),
                }
            }
        }
        if self.ridges.open != 0 {
            return Err(Fail::Numeric);
        }
        Ok(())
    }

    /// The plane of the new facet `v` (the visible facet `f` with its vertex `k` replaced by
    /// the apex p = `v[k]`) on the horizon ridge between `f` and its non-visible neighbour
    /// g = `f.n[k]`. Both planes contain the ridge, so the pencil ψ = b φ_f + a φ_g
    /// (φ(x) = n · x − offset) does too, and a = φ_f(p), b = −φ_g(p) make it vanish at p:
    /// about 60 flops where the Gram–Schmidt of [`hyperplane`] costs about 500. a > 0 and
    /// b ≥ 0 (p above f, not above g), so the normal points out. It is kept only when it
    /// passes within [`PENCIL_RESIDUAL`] × scale of all 6 (joggled) vertices — an
    /// a-posteriori check, so no error is inherited from the parents beyond that — and has the
    /// interior strictly inside; otherwise (nearly parallel parents, where the pencil cancels)
    /// the plane is recomputed by [`Builder::oriented`].
    fn through_ridge(
        &self,
        pts: &[Point6],
        f: u32,
        k: usize,
        v: &[u32; DIM],
        interior: &Point6,
        scale: f64,
    ) -> Result<(Point6, f64), Fail> {
        let tau = 1e-10 * scale;
        let tiny = 1e-13 * scale;
        let ff = &self.facets[f as usize];
        let gg = &self.facets[ff.n[k] as usize];
        let p = &pts[v[k] as usize];
        let a = dot(&ff.normal, p) - ff.off; // φ_f(p) > 0
        let b = gg.off - dot(&gg.normal, p); // −φ_g(p) ≥ 0
        let mut n: Point6 = std::array::from_fn(|i| b * ff.normal[i] + a * gg.normal[i]);
        let len = dot(&n, &n).sqrt();
        if len > 0.0 && len.is_finite() {
            n = n.map(|x| x / len);
            let d: [f64; DIM] = std::array::from_fn(|k| dot(&n, &pts[v[k] as usize]));
            let off = d.iter().sum::<f64>() / DIM as f64;
            let res = d.iter().fold(0.0f64, |m, x| m.max((x - off).abs()));
            if res <= PENCIL_RESIDUAL * scale && dot(&n, interior) - off < -tau {
                return Ok((n, off));
            }
        }
        Self::oriented(pts, v, interior, tiny, tau)
    }

    /// Step 5's local convexity: every live facet's neighbours are live and their opposite
    /// vertex lies below the facet, up to `tol` (the joggle: sliver normals err by about
    /// round-off / joggle ≈ 1e-10 relative; a wrong visibility decision gives errors far larger
    /// than the joggle).
    fn check_convex(&self, pts: &[Point6], tol: f64) -> Result<(), Fail> {
        for f in 0..self.facets.len() {
            if !self.facets[f].alive {
                continue;
            }
            for k in 0..DIM {
                let g = self.facets[f].n[k];
                if g == NONE || !self.facets[g as usize].alive {
                    return Err(Fail::Numeric);
                }
                let opp = self.facets[f].o[k];
                if opp == NONE {
                    return Err(Fail::Numeric);
                }
                if self.dist(f as u32, &pts[opp as usize]) > tol {
                    return Err(Fail::Numeric);
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cross_polytope_has_64_facets_at_distance_one_over_sqrt6() {
        let mut pts = Vec::new();
        for a in 0..DIM {
            for s in [-1.0, 1.0] {
                let mut p = [0.0; DIM];
                p[a] = s;
                pts.push(p);
            }
        }
        let h = ConvexHull::new(&pts).expect("hull");
        assert_eq!(h.facets().len(), 64);
        let exact = 1.0 / 6f64.sqrt();
        // Polished: exact to round-off; as built: within the joggle bound (a joggled point moves
        // by at most √6 × joggle, local convexity admits one more joggle).
        let polished = h.support_depth(&pts);
        assert!((polished - exact).abs() < 1e-12, "{polished}");
        let bound = (6f64.sqrt() + 1.0) * h.joggle();
        assert!(
            (h.origin_depth() - exact).abs() <= bound,
            "{}",
            h.origin_depth()
        );
    }

    #[test]
    fn hypercube_is_degenerate_but_fine() {
        let pts: Vec<Point6> = (0..64u32)
            .map(|b| std::array::from_fn(|i| if b >> i & 1 == 1 { 1.0 } else { -1.0 }))
            .collect();
        let h = ConvexHull::new(&pts).expect("hull");
        let polished = h.support_depth(&pts);
        assert!((polished - 1.0).abs() < 1e-12, "{polished}");
        let bound = (6f64.sqrt() + 1.0) * h.joggle();
        assert!(
            (h.origin_depth() - 1.0).abs() <= bound,
            "{}",
            h.origin_depth()
        );
    }

    #[test]
    fn flat_and_tiny_inputs() {
        let pts: Vec<Point6> = (0..20)
            .map(|i| {
                [
                    i as f64,
                    (i * i) as f64 * 0.1,
                    1.0,
                    0.0,
                    (i % 3) as f64,
                    2.0,
                ]
            })
            .collect();
        assert_eq!(ConvexHull::new(&pts).unwrap_err(), HullError::Flat);
        assert!(matches!(
            ConvexHull::new(&pts[..5]).unwrap_err(),
            HullError::TooFewPoints(5)
        ));
        let mut bad = pts.clone();
        bad[3][2] = f64::NAN;
        assert_eq!(
            ConvexHull::new(&bad).unwrap_err(),
            HullError::NonFinite { index: 3 }
        );
    }
}
