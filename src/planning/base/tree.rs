//! RRT search trees (LaValle 1998): states in one flat `Vec<f64>` with parent indices, and an
//! exact nearest-neighbour query in the space's weighted metric: an incremental k-d tree
//! (Bentley 1975; buckets of [`BUCKET`] states split at the median of their widest weighted
//! coordinate) whose leaves also keep their states coordinate-major, so a leaf is scanned with
//! vector arithmetic (AVX when the CPU has it). Small trees (up to `LINEAR_SCAN_MAX` states) are
//! scanned whole from a packed copy in insertion order; larger ones descend with pruning, for
//! trees of 10⁴–10⁵ states (14-DoF bimanual problems). Allocation-free per query;
//! insertion only grows flat arrays. Each state also carries a dynamic-domain radius
//! (Yershova et al., ICRA 2005) for planners that use one.

/// Weighted squared distances from `q` to the first `W` (≤ [`BUCKET`]) states of a
/// coordinate-major leaf block, those slots at once, coordinate by coordinate: the summation
/// order (and rounding) of [`Tree::nearest_linear`], so both give the same distances to the
/// last bit. The other slots are +∞ (a partly filled block needs only its first slots).
#[inline(always)]
fn block_distances<const W: usize>(data: &[f64], weights: &[f64], q: &[f64]) -> [f64; BUCKET] {
    let mut d = [f64::INFINITY; BUCKET];
    d[..W].fill(0.0);
    for ((col, &w), &qk) in data.chunks_exact(BUCKET).zip(weights).zip(q) {
        let col: &[f64; BUCKET] = col.try_into().unwrap_or(&[f64::INFINITY; BUCKET]);
        for s in 0..W {
            let e = col[s] - qk;
            d[s] = (w * e).mul_add(e, d[s]);
        }
    }
    d
}

/// [`block_distances`] compiled for AVX and FMA (4 lanes of f64; the fused multiply-add rounds
/// exactly like `f64::mul_add` in the reference, which off such CPUs is a slower library call).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,fma")]
unsafe fn block_distances_avx<const W: usize>(
    data: &[f64],
    weights: &[f64],
    q: &[f64],
) -> [f64; BUCKET] {
    block_distances::<W>(data, weights, q)
}

/// The linear scan of [`Tree::nearest`] with AVX and FMA: per block the distances of
/// [`block_distances`] (the same operations, so the same values) in four registers, kept
/// against the best so far per lane with blends, so ties still go to the lowest index.
/// Measured: a scalar comparison of all 16 slots was half of each block's cost (callgrind,
/// Panda cage); comparing the block at once and then its slots one by one left a branch per
/// slot that mispredicted (wall clock, UR5-like cage set: without those branches its mean went
/// from 1013 to 918 µs, 4 pairs; these blends and a vector minimum per block holding a closer
/// state measured the same, 6 pairs). `unit`: every weight is 1, so `w·e` is `e` exactly and
/// the product is skipped (the same values; see [`scan_blocks`]; measured, callgrind, 15 Panda
/// cage problems, search only: 17.6 → 15.2 M instructions in the scans).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,fma")]
unsafe fn scan_avx(
    data: &[f64],
    weights: &[f64],
    unit: bool,
    q: &[f64],
    n: usize,
    best: &mut (u32, f64),
) {
    if unit {
        scan_blocks::<true>(data, weights, q, n, best)
    } else {
        scan_blocks::<false>(data, weights, q, n, best)
    }
}

/// [`scan_avx`]'s loop. With `UNIT` (every weight 1) the distance term is `fma(e, e, d)`:
/// `1·e == e` in IEEE arithmetic, so it rounds exactly as the weighted `fma(w·e, e, d)` of
/// [`block_distances`], one product fewer per 4 states and coordinate.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,fma")]
#[inline]
unsafe fn scan_blocks<const UNIT: bool>(
    data: &[f64],
    weights: &[f64],
    q: &[f64],
    n: usize,
    best: &mut (u32, f64),
) {
    use std::arch::x86_64::*;
    const _: () = assert!(BUCKET == 16);
    let dim = weights.len();
    // Per lane `l` the smallest distance so far among slots `l, l + 4, l + 8, …` (in that
    // order, strictly smaller replacing: the first of equal minima) and its index, selected
    // with blends: no branch on the data at all.
    let mut bv = _mm256_set1_pd(best.1);
    let mut bi = _mm256_set1_pd(-1.0);
    let mut idx = _mm256_set_pd(3.0, 2.0, 1.0, 0.0);
    let four = _mm256_set1_pd(4.0);
    for block in data.chunks_exact(dim * BUCKET).take(n.div_ceil(BUCKET)) {
        let mut d = [_mm256_setzero_pd(); 4];
        for ((col, &w), &qk) in block.chunks_exact(BUCKET).zip(weights).zip(q) {
            let (wv, qv) = (_mm256_set1_pd(w), _mm256_set1_pd(qk));
            for (v, dv) in d.iter_mut().enumerate() {
                let e = _mm256_sub_pd(_mm256_loadu_pd(col.as_ptr().add(4 * v)), qv);
                let we = if UNIT { e } else { _mm256_mul_pd(wv, e) };
                *dv = _mm256_fmadd_pd(we, e, *dv);
            }
        }
        for dv in d {
            let lt = _mm256_cmp_pd::<_CMP_LT_OQ>(dv, bv);
            bv = _mm256_blendv_pd(bv, dv, lt);
            bi = _mm256_blendv_pd(bi, idx, lt);
            idx = _mm256_add_pd(idx, four);
        }
    }
    // The smallest of the lanes' minima, and the lowest index among the lanes holding it: the
    // first minimum in index order, as the slot-by-slot scan `x < best` finds it. Unused slots
    // hold +∞ and NaN is never smaller, so neither is ever chosen.
    let lo = _mm256_min_pd(bv, _mm256_permute2f128_pd::<1>(bv, bv));
    let lo = _mm256_min_pd(lo, _mm256_permute_pd::<0b0101>(lo));
    let x = _mm256_cvtsd_f64(lo);
    if x < best.1 {
        let at = _mm256_cmp_pd::<_CMP_EQ_OQ>(bv, lo);
        let i = _mm256_blendv_pd(_mm256_set1_pd(f64::INFINITY), bi, at);
        let i = _mm256_min_pd(i, _mm256_permute2f128_pd::<1>(i, i));
        let i = _mm256_min_pd(i, _mm256_permute_pd::<0b0101>(i));
        *best = (_mm256_cvtsd_f64(i) as u32, x);
    }
}

/// Weighted squared distance with plain products and sums (no fused multiply-add, which off
/// FMA CPUs is a slow library call). Not bit-equal to [`Tree::nearest`]'s distances; for
/// bounds only.
#[inline]
fn plain_dist_sq(a: &[f64], b: &[f64], w: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .zip(w)
        .map(|((x, y), w)| {
            let e = x - y;
            w * e * e
        })
        .sum()
}

/// [`plain_dist_sq`] with AVX intrinsics: one 4-lane accumulator of (w·e)·e, the last partial
/// vector loaded under a mask (its other lanes add 0), then the halves summed. The summation
/// order differs from [`plain_dist_sq`], which bounds allow for; `PlannerRng`'s fused sampler
/// repeats it exactly.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn plain_dist_sq_avx(a: &[f64], b: &[f64], w: &[f64]) -> f64 {
    use std::arch::x86_64::*;
    let n = a.len().min(b.len()).min(w.len());
    let mut acc = _mm256_setzero_pd();
    let mut k = 0;
    while k < n {
        // SAFETY: lanes k.. below n are within all three slices; the mask keeps the loads of a
        // partial last vector within them.
        let (x, y, wk) = if k + 4 <= n {
            (
                _mm256_loadu_pd(a.as_ptr().add(k)),
                _mm256_loadu_pd(b.as_ptr().add(k)),
                _mm256_loadu_pd(w.as_ptr().add(k)),
            )
        } else {
            let r = (n - k) as i64;
            let m = _mm256_set_epi64x(
                -i64::from(r > 3),
                -i64::from(r > 2),
                -i64::from(r > 1),
                -i64::from(r > 0),
            );
            (
                _mm256_maskload_pd(a.as_ptr().add(k), m),
                _mm256_maskload_pd(b.as_ptr().add(k), m),
                _mm256_maskload_pd(w.as_ptr().add(k), m),
            )
        };
        let e = _mm256_sub_pd(x, y);
        let we = _mm256_mul_pd(wk, e);
        acc = _mm256_add_pd(acc, _mm256_mul_pd(we, e));
        k += 4;
    }
    let half = _mm_add_pd(_mm256_castpd256_pd128(acc), _mm256_extractf128_pd::<1>(acc));
    _mm_cvtsd_f64(_mm_add_sd(half, _mm_unpackhi_pd(half, half)))
}

/// Relative slack of [`DomainBall`]'s test, far above the rounding of a few dozen f64
/// operations.
const DOMAIN_SLACK: f64 = 1e-9;

/// A ball around a tree's state 0 that holds every state's dynamic domain
/// ([`Tree::domain_ball`]): radius (largest finite radius + spread) with a relative slack.
#[derive(Debug, Clone, Copy)]
pub struct DomainBall<'a> {
    center: &'a [f64],
    weights: &'a [f64],
    reach_sq: f64,
    avx: bool,
}

impl<'a> DomainBall<'a> {
    /// State 0 of the tree.
    #[inline]
    pub fn center(&self) -> &'a [f64] {
        self.center
    }

    /// The tree's metric weights.
    #[inline]
    pub fn weights(&self) -> &'a [f64] {
        self.weights
    }

    /// True when a point at squared distance `d2` from the center (as [`DomainBall::dist_sq`]
    /// computes it) is certainly outside the ball.
    #[inline]
    pub fn excludes_dist_sq(&self, d2: f64) -> bool {
        d2 * (1.0 - DOMAIN_SLACK) > self.reach_sq
    }

    /// A squared distance beyond which [`DomainBall::excludes_dist_sq`] holds (up to the
    /// rounding of that test's one product): `reach² (1 + 2·slack)`, at least `reach² /
    /// (1 − slack)` (a product: the division's latency stood out in the planner's loop).
    #[inline]
    pub fn exclusion_boundary(&self) -> f64 {
        self.reach_sq * (1.0 + 2.0 * DOMAIN_SLACK)
    }

    /// True when `q` is certainly outside the ball (false for a `q` of the wrong length).
    #[inline]
    pub fn excludes(&self, q: &[f64]) -> bool {
        q.len() == self.center.len() && self.excludes_dist_sq(self.dist_sq(q))
    }

    /// Weighted squared distance from the center to `q` ([`plain_dist_sq`], with AVX when the
    /// CPU has it; `PlannerRng`'s fused sampler repeats the vector arithmetic exactly).
    #[inline]
    pub fn dist_sq(&self, q: &[f64]) -> f64 {
        bound_dist_sq(self.center, q, self.weights, self.avx)
    }

    /// [`DomainBall::dist_sq`] uses the vector arithmetic (AVX).
    #[inline]
    pub(super) fn uses_avx(&self) -> bool {
        self.avx
    }
}

/// [`plain_dist_sq`], with AVX when `avx` (the CPU has AVX; see `Tree::avx`).
#[inline]
fn bound_dist_sq(a: &[f64], b: &[f64], w: &[f64], avx: bool) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if avx {
        // SAFETY: callers pass `avx` true only when the CPU has AVX (checked in `Tree::new`).
        return unsafe { plain_dist_sq_avx(a, b, w) };
    }
    let _ = avx;
    plain_dist_sq(a, b, w)
}

/// Parent index of a root state.
pub const NO_PARENT: u32 = u32::MAX;

/// States per k-d tree leaf before it splits.
pub const BUCKET: usize = 16;
/// Trees up to this size are searched by scanning every leaf (faster than descending).
const LINEAR_SCAN_MAX: usize = 192;

#[derive(Debug, Clone, Copy)]
enum KdNode {
    Leaf {
        len: u8,
        items: [u32; BUCKET],
        /// The leaf's states, coordinate-major (`dim × BUCKET` values from `block · dim · BUCKET`
        /// in `leaf_data`; unused slots hold +∞), so one query scans a leaf with vector loads.
        block: u32,
    },
    Split {
        dim: u32,
        value: f64,
        lo: u32,
        hi: u32,
    },
}

/// A tree (or forest: several roots are allowed) of states of one space.
#[derive(Debug, Clone)]
pub struct Tree {
    dim: usize,
    weights: Vec<f64>,
    states: Vec<f64>,
    parents: Vec<u32>,
    /// Dynamic-domain radius of each state (`f64::INFINITY` until a planner sets one).
    radii: Vec<f64>,
    /// Per state: 0 when the edge from its parent is proven valid, else the tag of
    /// [`Tree::mark_unproven_tagged`] (lazy planners; [`Tree::mark_unproven`] tags
    /// `u32::MAX`).
    unproven: Vec<u32>,
    kd: Vec<KdNode>,
    kd_overflow: Vec<u32>,
    leaf_data: Vec<f64>,
    /// While the tree has at most [`LINEAR_SCAN_MAX`] states: all of them coordinate-major in
    /// insertion order, blocks of [`BUCKET`] (unused slots +∞), so small trees are scanned
    /// without the half-empty slots of split leaves. Not kept beyond that size.
    scan_data: Vec<f64>,
    /// The largest distance of any state from state 0 (the tree's extent around it, for
    /// [`Tree::outside_every_domain`]).
    spread: f64,
    /// Number of states whose dynamic-domain radius is infinite.
    infinite_radii: usize,
    /// An upper bound of every finite dynamic-domain radius (it never decreases).
    finite_radius_bound: f64,
    /// The CPU has AVX and FMA (leaf scans use them).
    avx: bool,
    /// Every weight is exactly 1 (the default metric): the scans skip the products by the
    /// weights, which change nothing then.
    unit: bool,
}

impl Tree {
    /// An empty tree of `weights.len()`-dimensional states measured with these weights.
    pub fn new(weights: &[f64]) -> Tree {
        Tree {
            dim: weights.len(),
            weights: weights.to_vec(),
            states: Vec::with_capacity(weights.len() * 1024),
            parents: Vec::with_capacity(1024),
            radii: Vec::with_capacity(1024),
            unproven: Vec::with_capacity(1024),
            kd: vec![KdNode::Leaf {
                len: 0,
                items: [0; BUCKET],
                block: 0,
            }],
            kd_overflow: Vec::new(),
            leaf_data: vec![f64::INFINITY; weights.len() * BUCKET],
            scan_data: Vec::with_capacity(weights.len() * LINEAR_SCAN_MAX),
            spread: 0.0,
            infinite_radii: 0,
            finite_radius_bound: 0.0,
            #[cfg(target_arch = "x86_64")]
            avx: std::is_x86_feature_detected!("avx") && std::is_x86_feature_detected!("fma"),
            #[cfg(not(target_arch = "x86_64"))]
            avx: false,
            unit: weights.iter().all(|&w| w == 1.0),
        }
    }

    /// Removes every state (keeps the memory).
    pub fn clear(&mut self) {
        self.states.clear();
        self.parents.clear();
        self.radii.clear();
        self.unproven.clear();
        self.kd.clear();
        self.kd_overflow.clear();
        self.kd.push(KdNode::Leaf {
            len: 0,
            items: [0; BUCKET],
            block: 0,
        });
        self.leaf_data.clear();
        self.leaf_data.resize(self.dim * BUCKET, f64::INFINITY);
        self.scan_data.clear();
        self.spread = 0.0;
        self.infinite_radii = 0;
        self.finite_radius_bound = 0.0;
    }

    /// Writes state `i` into slot `slot` of leaf block `block`.
    #[inline]
    fn put_in_block(&mut self, block: u32, slot: usize, i: u32) {
        let b = block as usize * self.dim * BUCKET;
        for k in 0..self.dim {
            self.leaf_data[b + k * BUCKET + slot] = self.states[i as usize * self.dim + k];
        }
    }

    /// Fills leaf block `block` with `items` (the rest +∞).
    fn fill_block(&mut self, block: u32, items: &[u32]) {
        let b = block as usize * self.dim * BUCKET;
        self.leaf_data[b..b + self.dim * BUCKET].fill(f64::INFINITY);
        for (slot, &i) in items.iter().enumerate() {
            self.put_in_block(block, slot, i);
        }
    }

    /// The dynamic-domain radius of state `i`.
    #[inline]
    pub fn radius(&self, i: u32) -> f64 {
        self.radii[i as usize]
    }

    #[inline]
    pub fn set_radius(&mut self, i: u32, r: f64) {
        let old = std::mem::replace(&mut self.radii[i as usize], r);
        self.infinite_radii = self.infinite_radii + usize::from(r == f64::INFINITY)
            - usize::from(old == f64::INFINITY);
        if r.is_finite() {
            self.finite_radius_bound = self.finite_radius_bound.max(r);
        }
    }

    /// Makes every dynamic-domain radius infinite again: a restart of the domains (see
    /// `rrt_connect`'s `DYNAMIC_DOMAIN_STALL`).
    pub fn reset_radii(&mut self) {
        self.radii.fill(f64::INFINITY);
        self.infinite_radii = self.radii.len();
        self.finite_radius_bound = 0.0;
    }

    /// True only when `q` is certainly farther from every state than that state's
    /// dynamic-domain radius, so from its nearest state too: the sample would be skipped
    /// (Yershova et al., ICRA 2005). By the triangle inequality every state is at least
    /// d(q, state 0) − spread from `q`, where spread bounds the states' distances from state 0;
    /// when that exceeds a bound of every radius, no state's domain holds `q`. One distance
    /// instead of a nearest-neighbour query: on MotionBenchMaker's Baxter problems over 99 % of
    /// samples are skipped, ~92 % of them by this test (measured: the trees keep ~5 states on
    /// average, within ~0.7 of their first state). `false` means "not certain" (an infinite
    /// radius, or `q` near the tree), and the caller then asks [`Tree::nearest`].
    #[inline]
    pub fn outside_every_domain(&self, q: &[f64]) -> bool {
        self.domain_ball().is_some_and(|b| b.excludes(q))
    }

    /// The ball around state 0 outside which [`Tree::outside_every_domain`] holds (`None` when
    /// it holds nowhere: an empty tree or an infinite radius), for samplers that test many
    /// samples against it in a row.
    #[inline]
    pub fn domain_ball(&self) -> Option<DomainBall<'_>> {
        if self.is_empty() || self.infinite_radii > 0 {
            return None;
        }
        let reach = (self.finite_radius_bound + self.spread) * (1.0 + DOMAIN_SLACK);
        Some(DomainBall {
            center: &self.states[..self.dim],
            weights: &self.weights,
            reach_sq: reach * reach,
            avx: self.avx,
        })
    }

    /// The metric weights.
    #[inline]
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    #[inline]
    pub fn len(&self) -> usize {
        self.parents.len()
    }

    #[inline]
    pub fn is_empty(&self) -> bool {
        self.parents.is_empty()
    }

    /// Adds a state with `parent` (or [`NO_PARENT`] for a root) and returns its index.
    #[inline]
    pub fn add(&mut self, q: &[f64], parent: u32) -> u32 {
        debug_assert_eq!(q.len(), self.dim);
        debug_assert!(parent == NO_PARENT || (parent as usize) < self.len());
        self.states.extend_from_slice(q);
        self.parents.push(parent);
        self.radii.push(f64::INFINITY);
        self.unproven.push(0);
        self.infinite_radii += 1;
        let i = (self.parents.len() - 1) as u32;
        if (i as usize) < LINEAR_SCAN_MAX {
            let slot = i as usize % BUCKET;
            if slot == 0 {
                self.scan_data
                    .resize(self.scan_data.len() + self.dim * BUCKET, f64::INFINITY);
            }
            let b = (i as usize / BUCKET) * self.dim * BUCKET;
            for (k, &v) in q.iter().enumerate() {
                self.scan_data[b + k * BUCKET + slot] = v;
            }
        }
        let from_first = bound_dist_sq(&self.states[..self.dim], q, &self.weights, self.avx).sqrt();
        self.spread = self.spread.max(from_first);
        self.kd_insert(i);
        i
    }

    fn kd_insert(&mut self, i: u32) {
        let q = i as usize * self.dim;
        let mut n = 0usize;
        loop {
            match &mut self.kd[n] {
                KdNode::Split { dim, value, lo, hi } => {
                    n = if self.states[q + *dim as usize] < *value {
                        *lo as usize
                    } else {
                        *hi as usize
                    };
                }
                KdNode::Leaf { len, items, block } => {
                    if (*len as usize) == BUCKET {
                        // A full leaf that could not split (identical states).
                        self.kd_overflow.push(i);
                        return;
                    }
                    let (slot, block) = (*len as usize, *block);
                    items[slot] = i;
                    *len += 1;
                    let full = (*len as usize) == BUCKET;
                    self.put_in_block(block, slot, i);
                    if full {
                        self.kd_split(n);
                    }
                    return;
                }
            }
        }
    }

    /// Splits a full leaf at the median of its widest (weighted) coordinate.
    fn kd_split(&mut self, n: usize) {
        let KdNode::Leaf { items, block, .. } = self.kd[n] else {
            return;
        };
        let (mut best_dim, mut best_spread) = (0usize, -1.0f64);
        for d in 0..self.dim {
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for &it in &items {
                let v = self.states[it as usize * self.dim + d];
                lo = lo.min(v);
                hi = hi.max(v);
            }
            let spread = (hi - lo) * self.weights[d].sqrt();
            if spread > best_spread {
                best_spread = spread;
                best_dim = d;
            }
        }
        let mut vals = [0.0f64; BUCKET];
        for (v, &it) in vals.iter_mut().zip(&items) {
            *v = self.states[it as usize * self.dim + best_dim];
        }
        vals.sort_by(|a, b| a.total_cmp(b));
        // The median, unless it equals the least value (more than half the states share it):
        // then the next larger value, so that neither side is empty whenever the coordinate
        // varies at all.
        let mut value = vals[BUCKET / 2];
        if value <= vals[0] {
            value = vals.iter().copied().find(|&v| v > vals[0]).unwrap_or(value);
        }
        let mut lo_leaf = ([0u32; BUCKET], 0u8);
        let mut hi_leaf = ([0u32; BUCKET], 0u8);
        for &it in &items {
            let side = if self.states[it as usize * self.dim + best_dim] < value {
                &mut lo_leaf
            } else {
                &mut hi_leaf
            };
            side.0[side.1 as usize] = it;
            side.1 += 1;
        }
        if lo_leaf.1 == 0 || hi_leaf.1 == 0 {
            // Identical states: the leaf stays full; later states reaching it go to the
            // overflow list, which every query scans.
            return;
        }
        let lo = self.kd.len() as u32;
        // The low half reuses the full leaf's block, the high half gets a new one.
        let hi_block = (self.leaf_data.len() / (self.dim * BUCKET)) as u32;
        self.leaf_data
            .resize(self.leaf_data.len() + self.dim * BUCKET, f64::INFINITY);
        self.fill_block(block, &lo_leaf.0[..lo_leaf.1 as usize]);
        self.fill_block(hi_block, &hi_leaf.0[..hi_leaf.1 as usize]);
        self.kd.push(KdNode::Leaf {
            len: lo_leaf.1,
            items: lo_leaf.0,
            block,
        });
        self.kd.push(KdNode::Leaf {
            len: hi_leaf.1,
            items: hi_leaf.0,
            block: hi_block,
        });
        self.kd[n] = KdNode::Split {
            dim: best_dim as u32,
            value,
            lo,
            hi: lo + 1,
        };
    }

    #[inline]
    pub fn state(&self, i: u32) -> &[f64] {
        let s = i as usize * self.dim;
        &self.states[s..s + self.dim]
    }

    #[inline]
    pub fn parent(&self, i: u32) -> Option<u32> {
        let p = self.parents[i as usize];
        (p != NO_PARENT).then_some(p)
    }

    /// The root reached by following parents from `i`.
    pub fn root_of(&self, mut i: u32) -> u32 {
        while let Some(p) = self.parent(i) {
            i = p;
        }
        i
    }

    /// Index and squared weighted distance of the state nearest to `q` (`None` when empty);
    /// ties go to the lowest index in a linear scan, to the first found in the k-d tree.
    #[inline]
    pub fn nearest(&self, q: &[f64]) -> Option<(u32, f64)> {
        let mut best = (u32::MAX, f64::INFINITY);
        if self.len() <= LINEAR_SCAN_MAX {
            // Every state in insertion order, a block at a time: a vectorised linear scan, no
            // descent; ties go to the lowest index, as in `nearest_linear`.
            let n = self.len();
            #[cfg(target_arch = "x86_64")]
            if self.avx {
                // SAFETY: `avx` is set only when the CPU has AVX and FMA (checked in `Tree::new`).
                unsafe { scan_avx(&self.scan_data, &self.weights, self.unit, q, n, &mut best) };
                return (best.0 != u32::MAX).then_some(best);
            }
            for (blk, data) in self.scan_data.chunks_exact(self.dim * BUCKET).enumerate() {
                let first = blk * BUCKET;
                let d = self.block_distances_first(data, q, n - first);
                for (s, &ds) in d.iter().enumerate().take(n - first) {
                    if ds < best.1 {
                        best = ((first + s) as u32, ds);
                    }
                }
            }
            return (best.0 != u32::MAX).then_some(best);
        }
        self.kd_search(0, q, &mut best);
        for &i in &self.kd_overflow {
            let d = self.dist_sq(i, q);
            if d < best.1 {
                best = (i, d);
            }
        }
        (best.0 != u32::MAX).then_some(best)
    }

    /// Weighted squared distance of state `i` from `q`: the same operations in the same order
    /// as the nearest-neighbour scans, so the same value as [`Self::nearest`] gives.
    #[inline(always)]
    pub(crate) fn dist_sq(&self, i: u32, q: &[f64]) -> f64 {
        let s = &self.states[i as usize * self.dim..(i as usize + 1) * self.dim];
        let mut d = 0.0;
        for k in 0..self.dim {
            let e = s[k] - q[k];
            d = (self.weights[k] * e).mul_add(e, d);
        }
        d
    }

    /// [`block_distances`] of the first `used` (rounded up to a multiple of 4) slots of a
    /// block; the others are +∞. The small trees of dynamic-domain searches often fill a
    /// fraction of their one block.
    #[inline]
    fn block_distances_first(&self, data: &[f64], q: &[f64], used: usize) -> [f64; BUCKET] {
        const _: () = assert!(BUCKET == 16);
        #[cfg(target_arch = "x86_64")]
        if self.avx {
            // SAFETY: `avx` is set only when the CPU has AVX and FMA (checked in `Tree::new`).
            return unsafe {
                match used {
                    0..=4 => block_distances_avx::<4>(data, &self.weights, q),
                    5..=8 => block_distances_avx::<8>(data, &self.weights, q),
                    9..=12 => block_distances_avx::<12>(data, &self.weights, q),
                    _ => block_distances_avx::<16>(data, &self.weights, q),
                }
            };
        }
        match used {
            0..=4 => block_distances::<4>(data, &self.weights, q),
            5..=8 => block_distances::<8>(data, &self.weights, q),
            9..=12 => block_distances::<12>(data, &self.weights, q),
            _ => block_distances::<16>(data, &self.weights, q),
        }
    }

    /// Offers the states of a leaf block to `best` (distances from `q`).
    #[inline]
    fn scan_leaf(&self, block: u32, items: &[u32], q: &[f64], best: &mut (u32, f64)) {
        let b = block as usize * self.dim * BUCKET;
        let d =
            self.block_distances_first(&self.leaf_data[b..b + self.dim * BUCKET], q, items.len());
        for (s, &i) in items.iter().enumerate() {
            if d[s] < best.1 {
                *best = (i, d[s]);
            }
        }
    }

    fn kd_search(&self, n: usize, q: &[f64], best: &mut (u32, f64)) {
        match &self.kd[n] {
            KdNode::Leaf { len, items, block } => {
                self.scan_leaf(*block, &items[..*len as usize], q, best);
            }
            KdNode::Split { dim, value, lo, hi } => {
                let diff = q[*dim as usize] - value;
                let (near, far) = if diff < 0.0 { (*lo, *hi) } else { (*hi, *lo) };
                self.kd_search(near as usize, q, best);
                if self.weights[*dim as usize] * diff * diff < best.1 {
                    self.kd_search(far as usize, q, best);
                }
            }
        }
    }

    /// [`Self::nearest`] by linear scan over every state (the reference the leaf scans match);
    /// ties go to the lowest index.
    pub fn nearest_linear(&self, q: &[f64]) -> Option<(u32, f64)> {
        let mut best = (u32::MAX, f64::INFINITY);
        for i in 0..self.len() as u32 {
            let d = self.dist_sq(i, q);
            if d < best.1 {
                best = (i, d);
            }
        }
        (best.0 != u32::MAX).then_some(best)
    }

    /// Marks the edge from state `i`'s parent to `i` as not yet proven valid (lazy collision
    /// checking: it passed a screening check only; see `RrtConnectSettings::lazy`).
    #[inline]
    pub fn mark_unproven(&mut self, i: u32) {
        self.unproven[i as usize] = u32::MAX;
    }

    /// [`Tree::mark_unproven`] with a caller's tag (≥ 1, e.g. where it keeps what finishing the
    /// proof needs), returned by [`Tree::unproven_tag`] and kept by
    /// [`Tree::remove_subtree`].
    #[inline]
    pub fn mark_unproven_tagged(&mut self, i: u32, tag: u32) {
        debug_assert!(tag != 0);
        self.unproven[i as usize] = tag;
    }

    /// Marks the edge into state `i` as proven valid.
    #[inline]
    pub fn mark_proven(&mut self, i: u32) {
        self.unproven[i as usize] = 0;
    }

    /// Whether the edge into state `i` is still unproven ([`Tree::mark_unproven`]).
    #[inline]
    pub fn is_unproven(&self, i: u32) -> bool {
        self.unproven[i as usize] != 0
    }

    /// The tag of an unproven edge into state `i` (`u32::MAX` from [`Tree::mark_unproven`]),
    /// `None` when it is proven.
    #[inline]
    pub fn unproven_tag(&self, i: u32) -> Option<u32> {
        let t = self.unproven[i as usize];
        (t != 0).then_some(t)
    }

    /// Removes state `i` (not a root) and every state below it, keeping the other states in
    /// their order (indices shift down past removed ones; state 0 and the roots keep theirs,
    /// since a state's parent always precedes it) with their parents, radii and proof marks.
    /// The nearest-neighbour structure is rebuilt: lazy planners call this only when an edge
    /// fails its certification, far less often than they add states. Returns how many states
    /// were removed.
    pub fn remove_subtree(&mut self, i: u32) -> usize {
        let n = self.len();
        assert!((i as usize) < n && self.parents[i as usize] != NO_PARENT);
        let mut removed = vec![false; n];
        for k in i as usize..n {
            let p = self.parents[k];
            removed[k] = k == i as usize || (p != NO_PARENT && removed[p as usize]);
        }
        let states = std::mem::take(&mut self.states);
        let parents = std::mem::take(&mut self.parents);
        let radii = std::mem::take(&mut self.radii);
        let unproven = std::mem::take(&mut self.unproven);
        self.clear();
        let mut new_index = vec![NO_PARENT; n];
        for k in 0..n {
            if removed[k] {
                continue;
            }
            let p = parents[k];
            let p = if p == NO_PARENT {
                NO_PARENT
            } else {
                new_index[p as usize]
            };
            let j = self.add(&states[k * self.dim..(k + 1) * self.dim], p);
            new_index[k] = j;
            if radii[k] != f64::INFINITY {
                self.set_radius(j, radii[k]);
            }
            self.unproven[j as usize] = unproven[k];
        }
        n - self.len()
    }

    /// Indices from the root down to `i` (into `out`, cleared first).
    pub fn path_from_root(&self, i: u32, out: &mut Vec<u32>) {
        out.clear();
        let mut k = i;
        out.push(k);
        while let Some(p) = self.parent(k) {
            out.push(p);
            k = p;
        }
        out.reverse();
    }
}

#[cfg(test)]
mod tests;
