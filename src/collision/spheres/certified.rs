//! Certified motion checks of the sphere checker ([`SphereChecker::segment_certified`]): a
//! whole straight segment proven collision-free as a continuous motion, by default by the chord
//! certificate (`chord.rs`), or (a switch for tests) from bounds on how fast each link's and
//! each self pair's spheres move (Schwarzer, Saha & Latombe, "Adaptive dynamic collision
//! checking for single and multiple articulated robots", IEEE T-RO 2005, with inflated spheres
//! instead of distances), refined where the first pass is tight.

use super::chord::HotStart;
use super::{SphereChecker, LANES, NO_FOCUS};

/// The verdict of the first pass of a certified motion check
/// ([`SphereChecker::segment_screened`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SegmentScreen {
    /// A checked state collides: the segment is not free.
    Collides,
    /// The whole continuous segment is proven free.
    Certified,
    /// The checked states are free; the certificate needs refinement (undecided).
    Tight,
}

/// The certificate of one segment (see [`SphereChecker::begin_segment`]).
#[derive(Debug, Clone, Copy)]
enum Certificate {
    /// Speed bounds over this many equal sub-intervals.
    Linear(usize),
    /// The chord certificate with this many 8-lane calls in its first pass.
    Chord(usize),
}

/// Work counts of a sphere checker's certified motion checks since its last
/// [`SphereChecker::reset_certify_counts`]: what a benchmark reports per search.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct CertifyCounts {
    /// Certified motion checks begun (first passes, and refinements of screened segments).
    pub segments: u64,
    /// 8-lane refinement calls (each splits a tight sub-interval in 7).
    pub refinements: u64,
}

/// [`SphereChecker::load_lanes`] with AVX: per variable, the 8 states as two 4-lane f64
/// products and sums (the same IEEE operations as the scalar code, no fused multiply-add, so
/// the same values), rounded to f32 together.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn load_lanes_avx(qv: &mut [super::Lane], a: &[f64], b: &[f64], ts: &[f64; LANES]) {
    use std::arch::x86_64::*;
    let t0 = _mm256_loadu_pd(ts.as_ptr());
    let t1 = _mm256_loadu_pd(ts.as_ptr().add(4));
    for ((v, &ai), &bi) in qv.iter_mut().zip(a).zip(b) {
        let (x, d) = (_mm256_set1_pd(ai), _mm256_set1_pd(bi - ai));
        let lo = _mm256_cvtpd_ps(_mm256_add_pd(x, _mm256_mul_pd(d, t0)));
        let hi = _mm256_cvtpd_ps(_mm256_add_pd(x, _mm256_mul_pd(d, t1)));
        _mm256_storeu_ps(v.as_mut_ptr(), _mm256_set_m128(hi, lo));
    }
}

/// [`SphereChecker::segment_lengths`] with AVX: `len[b] = Σ_v dq[v]·w[v·stride + b]` over the
/// variables with `dq[v] ≠ 0`, in ascending `v`, from 0 (the scalar loop's operations), four
/// bodies per register (`stride = len.len()`, a multiple of 4); the largest is returned. Up
/// to 16 bodies (the Panda has 11) the sums stay in registers.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn segment_lengths_avx(len: &mut [f64], dq: &[f64], w: &[f64]) -> f64 {
    let stride = len.len();
    debug_assert!(stride % 4 == 0 && w.len() >= dq.len() * stride);
    match stride / 4 {
        0 => 0.0,
        1 => lengths_in_registers::<1>(len, dq, w),
        2 => lengths_in_registers::<2>(len, dq, w),
        3 => lengths_in_registers::<3>(len, dq, w),
        4 => lengths_in_registers::<4>(len, dq, w),
        _ => lengths_in_memory(len, dq, w),
    }
}

/// [`segment_lengths_avx`] for `C` registers of 4 bodies.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline]
unsafe fn lengths_in_registers<const C: usize>(len: &mut [f64], dq: &[f64], w: &[f64]) -> f64 {
    use std::arch::x86_64::*;
    let mut acc = [_mm256_setzero_pd(); C];
    for (&d, row) in dq.iter().zip(w.chunks_exact(4 * C)) {
        if d != 0.0 {
            let dv = _mm256_set1_pd(d);
            for (c, a) in acc.iter_mut().enumerate() {
                let x = _mm256_loadu_pd(row.as_ptr().add(4 * c));
                *a = _mm256_add_pd(*a, _mm256_mul_pd(dv, x));
            }
        }
    }
    let mut mx = _mm256_setzero_pd();
    for (c, a) in acc.iter().enumerate() {
        _mm256_storeu_pd(len.as_mut_ptr().add(4 * c), *a);
        mx = _mm256_max_pd(mx, *a);
    }
    let hi = _mm256_extractf128_pd::<1>(mx);
    let m2 = _mm_max_pd(_mm256_castpd256_pd128(mx), hi);
    _mm_cvtsd_f64(_mm_max_sd(m2, _mm_unpackhi_pd(m2, m2)))
}

/// [`segment_lengths_avx`] for more than 16 bodies, the sums in `len`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn lengths_in_memory(len: &mut [f64], dq: &[f64], w: &[f64]) -> f64 {
    use std::arch::x86_64::*;
    let stride = len.len();
    len.fill(0.0);
    for (&d, row) in dq.iter().zip(w.chunks_exact(stride)) {
        if d != 0.0 {
            let dv = _mm256_set1_pd(d);
            for c in (0..stride).step_by(4) {
                let x = _mm256_loadu_pd(row.as_ptr().add(c));
                let a = _mm256_loadu_pd(len.as_ptr().add(c));
                _mm256_storeu_pd(
                    len.as_mut_ptr().add(c),
                    _mm256_add_pd(a, _mm256_mul_pd(dv, x)),
                );
            }
        }
    }
    len.iter().fold(0.0f64, |m, &l| m.max(l))
}

/// Appends to `out` the ids (bodies, self pairs) tight at any state `i..=j`, each once;
/// `tight` holds (state, id) sorted and without repeats.
pub(super) fn focus_of_states(tight: &[(usize, u32)], i: usize, j: usize, out: &mut Vec<u32>) {
    let start = out.len();
    let lo = tight.partition_point(|e| e.0 < i);
    let hi = tight.partition_point(|e| e.0 <= j);
    for &(_, id) in &tight[lo..hi] {
        if !out[start..].contains(&id) {
            out.push(id);
        }
    }
}

/// Appends to `out` the ids of a check's tight log (each id once there) tight in any lane
/// `l..=l + span`: the ends of the `span` sub-intervals between them.
pub(super) fn focus_of_lanes(log: &[(u32, u32)], l: usize, span: usize, out: &mut Vec<u32>) {
    let ends = ((1u32 << (span + 1)) - 1) << l;
    out.extend(log.iter().filter(|e| e.1 & ends != 0).map(|e| e.0));
}

/// Sub-intervals refined together: a run of consecutive sub-intervals that need refining is
/// taken two at a time (one 8-lane call splits both into 7 parts of 2/7 of one, instead of
/// two calls of 1/7 each; the middle state is checked once, not twice), a lone one alone.
/// `needed(i)` says whether sub-interval `i < n` needs refining; `emit(i, span)` receives
/// each group (first sub-interval, 1 or 2 of them) in ascending order.
#[inline]
pub(super) fn pair_runs(
    n: usize,
    needed: impl Fn(usize) -> bool,
    mut emit: impl FnMut(usize, usize),
) {
    let mut i = 0;
    while i < n {
        if !needed(i) {
            i += 1;
            continue;
        }
        let span = if i + 1 < n && needed(i + 1) { 2 } else { 1 };
        emit(i, span);
        i += span;
    }
}

impl SphereChecker {
    /// Largest number of states of the first, uniform pass of [`Self::segment_certified`] (a
    /// longer segment is checked with larger inflations, which stays sound).
    pub const CERTIFY_MAX_STATES: usize = 1 << 16;
    /// Most bisection levels below the uniform pass before a segment is declared uncertifiable.
    pub const CERTIFY_MAX_DEPTH: u32 = 10;
    /// Most refinement checks per segment before it is declared uncertifiable.
    pub const CERTIFY_MAX_REFINEMENTS: usize = 4096;

    /// The work counts of the certified checks since the last [`Self::reset_certify_counts`].
    pub fn certify_counts(&self) -> CertifyCounts {
        self.certify_counts
    }

    /// Starts [`Self::certify_counts`] again.
    pub fn reset_certify_counts(&mut self) {
        self.certify_counts = CertifyCounts::default();
    }

    /// **Benchmark only, unsound when on.** The certified checks run their first pass over the
    /// same states without inflating any sphere, so nothing is tight and nothing is refined:
    /// the same search at the cost of a plain resolution check of those states, which may pass
    /// through a collision between them. `manyhands bench mbm --uncertified` uses it to
    /// measure what the certificate costs and what it buys (the exact re-check's invalid
    /// count); no planner setting and no request reaches it.
    #[doc(hidden)]
    pub fn set_uncertified_for_benchmark(&mut self, on: bool) {
        self.uncertified = on;
    }

    /// Whether [`Self::segment_certified`] applies (every prismatic joint's travel is bounded).
    pub fn certifiable(&self) -> bool {
        self.certifiable
    }

    /// Writes the states `a + (b − a)·t` of the lanes' parameters into the lane buffer.
    #[inline]
    pub(super) fn load_lanes(&mut self, a: &[f64], b: &[f64], ts: &[f64; LANES]) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU supports AVX2 and FMA (checked at construction).
            unsafe { load_lanes_avx(&mut self.qv, a, b, ts) };
            return;
        }
        for (i, v) in self.qv.iter_mut().enumerate() {
            let (ai, di) = (a[i], b[i] - a[i]);
            for l in 0..LANES {
                v[l] = (ai + di * ts[l]) as f32;
            }
        }
    }

    /// Inflation of every body for sub-intervals of length `h` (segment parameter): half the
    /// distance its spheres can travel along such a sub-interval.
    #[inline]
    pub(super) fn set_inflation(&mut self, h: f64) {
        let h = if self.uncertified { 0.0 } else { h };
        for (i, l) in self.infl.iter_mut().zip(&self.seg_len) {
            *i = (0.5 * l * h) as f32;
        }
        self.pair_scale = 0.5 * h;
    }

    /// Extra distance self pair `pi`'s spheres must keep in the current check: half what
    /// both bodies can travel along a sub-interval, counting only the joints below their common
    /// ancestor (those above move both rigidly). At most `infl[a] + infl[b]`, which the
    /// body-level test uses instead, so this is computed only for pairs that pass it (once per
    /// segment).
    #[inline(always)]
    pub(super) fn pair_inflation(&mut self, pi: usize) -> f32 {
        if self.pair_scale == 0.0 {
            return 0.0;
        }
        if self.pair_len_epoch[pi] != self.seg_epoch {
            self.pair_len_epoch[pi] = self.seg_epoch;
            let dof = self.seg_dq.len();
            let w = &self.pair_w[pi * dof..(pi + 1) * dof];
            self.pair_len[pi] = self.seg_dq.iter().zip(w).map(|(d, w)| d * w).sum();
        }
        (self.pair_scale * self.pair_len[pi]) as f32
    }

    /// Certified motion check: true only when the whole continuous straight segment `a → b`
    /// (world configurations, `a` included) is collision-free — not just states sampled on it.
    ///
    /// By default the chord certificate proves it (`chord.rs`: each sphere, between two checked
    /// states, inside the ball about its chord's midpoint grown by half the chord and an
    /// acceleration allowance; sub-intervals split in 7 where a ball touches). With
    /// `set_chord(false)`, the linear certificate described here:
    ///
    /// Along the segment a sphere centre moves at most `L = Σ_v |b_v − a_v|·w_v` (w_v bounds its
    /// distance to the axis of every joint driven by variable v), uniformly in the segment
    /// parameter. A sub-interval of length h is therefore free when both its end states are
    /// free with every sphere inflated by `L·h/2` (each point of the sub-interval lies within
    /// that distance of one end). The segment is split into the fewest equal sub-intervals whose
    /// inflation stays at most `max_inflation` metres, their end states are checked 8 per call
    /// in raked order, and sub-intervals next to a state that is free only with plain spheres
    /// are split in 7 (one 8-lane call, a 7× smaller inflation; two adjacent ones together,
    /// 7 parts of 2/7 of one, see [`pair_runs`]) until certified. A refinement tests only the
    /// bodies (against their obstacles) and self pairs tight at its ends and the states between:
    /// the coarser check certified every other one free over the whole sub-interval. A state
    /// colliding with plain spheres, or more than [`Self::CERTIFY_MAX_DEPTH`] levels or
    /// [`Self::CERTIFY_MAX_REFINEMENTS`] checks of refinement, gives false.
    pub fn segment_certified(&mut self, a: &[f64], b: &[f64], max_inflation: f64) -> bool {
        let start = self.hot_start(a, b);
        if start == HotStart::Collides {
            return false;
        }
        let ok = match self.begin_segment(a, b, max_inflation) {
            Certificate::Linear(n) => self.certify(a, b, n),
            Certificate::Chord(calls) => {
                self.chord_first_pass(a, b, calls, start)
                    && (self.tight_states.is_empty() || self.chord_refine(a, b, calls))
            }
        };
        self.end_segment();
        ok
    }

    /// The first, uniform pass of [`Self::segment_certified`] alone (no refinement):
    /// [`SegmentScreen::Collides`] when a checked state collides with the plain spheres (the
    /// segment is certainly not free), [`SegmentScreen::Certified`] when every state is free
    /// with the inflated spheres (the whole segment is proven free, exactly as
    /// `segment_certified` would prove it), [`SegmentScreen::Tight`] otherwise: the checked
    /// states are free but the certificate needs refinement, which
    /// [`Self::segment_certified`] does. Lazy planners (see
    /// `planning::RrtConnectSettings::lazy`) accept tight segments provisionally and certify
    /// them only when they lie on a solution.
    pub fn segment_screened(&mut self, a: &[f64], b: &[f64], max_inflation: f64) -> SegmentScreen {
        let start = self.hot_start(a, b);
        if start == HotStart::Collides {
            self.tight_states.clear();
            return SegmentScreen::Collides;
        }
        let free = match self.begin_segment(a, b, max_inflation) {
            Certificate::Linear(n) => self.first_pass(a, b, n),
            Certificate::Chord(calls) => self.chord_first_pass(a, b, calls, start),
        };
        let r = if !free {
            SegmentScreen::Collides
        } else if self.tight_states.is_empty() {
            SegmentScreen::Certified
        } else {
            SegmentScreen::Tight
        };
        self.end_segment();
        r
    }

    /// What [`Self::segment_certified_screened`] needs of the last [`Self::segment_screened`]
    /// that answered [`SegmentScreen::Tight`]: its tight (state, body or self pair) entries
    /// (opaque to callers; empty after any other answer).
    pub fn screened_tight(&self) -> &[(usize, u32)] {
        &self.tight_states
    }

    /// [`Self::segment_certified`] of a segment whose [`Self::segment_screened`] answered
    /// [`SegmentScreen::Tight`], given what [`Self::screened_tight`] returned then: the first
    /// pass is not run again (it would find the same states free and the same entries
    /// tight), only the refinement, so the verdict is exactly that of
    /// [`Self::segment_certified`]. Lazy planners certify path edges this way: rerunning the
    /// first pass of every tight edge on a found path made lazy certification slower than
    /// eager certification on the easy MotionBenchMaker sets.
    pub fn segment_certified_screened(
        &mut self,
        a: &[f64],
        b: &[f64],
        max_inflation: f64,
        tight: &[(usize, u32)],
    ) -> bool {
        let plan = self.begin_segment(a, b, max_inflation);
        self.tight_states.clear();
        self.tight_states.extend_from_slice(tight);
        let ok = self.tight_states.is_empty()
            || match plan {
                Certificate::Linear(n) => self.refine_tight(a, b, n),
                Certificate::Chord(calls) => self.chord_refine(a, b, calls),
            };
        self.end_segment();
        ok
    }

    /// Ends a certified check: no inflation outside it.
    pub(super) fn end_segment(&mut self) {
        self.infl.iter_mut().for_each(|i| *i = 0.0);
        self.pair_scale = 0.0;
    }

    /// Sets up the bounds of segment `a → b` and chooses its certificate: the chord certificate
    /// (`chord.rs`) with the fewest 8-lane calls whose allowances stay within half of
    /// `max_inflation`, or, with it off, the linear one over `n` sub-intervals (`n + 1` states
    /// filling whole 8-lane calls). Measured (callgrind, planning only, `bench mbm
    /// --no-simplify`, 8–10 problems per set) against the linear certificate: Panda −18 %,
    /// UR5-like −11 % (box, table, shelf), xArm7-like −9 %, Fetch-like −24 %.
    fn begin_segment(&mut self, a: &[f64], b: &[f64], max_inflation: f64) -> Certificate {
        debug_assert!(self.certifiable && max_inflation > 0.0);
        self.certify_counts.segments += 1;
        for ((d, &x), &y) in self.seg_dq.iter_mut().zip(a).zip(b) {
            *d = (y - x).abs();
        }
        if self.chord {
            let amax = self.segment_accelerations();
            return Certificate::Chord(Self::chord_calls(amax, max_inflation));
        }
        let lmax = self.segment_lengths();
        self.seg_epoch = self.seg_epoch.wrapping_add(1);
        if self.seg_epoch == 0 {
            self.pair_len_epoch.fill(0);
            self.seg_epoch = 1;
        }
        let n = ((lmax / (2.0 * max_inflation)).ceil() as usize).clamp(1, Self::CERTIFY_MAX_STATES);
        // The n + 1 states fill whole 8-lane calls: the spare lanes make sub-intervals shorter
        // (smaller inflations) at no cost.
        Certificate::Linear((n + 1).div_ceil(LANES) * LANES - 1)
    }

    /// Per body its displacement bound `Σ_v |Δq_v|·w_v` over the segment (`seg_len`, from
    /// `seg_dq`); returns the largest. With AVX, four bodies per register, the same products
    /// and sums in the same order (no fused multiply-add), so the same values (measured,
    /// callgrind, Panda cage: 850 instructions per segment in the scalar loop, 8 % of the
    /// search).
    #[inline]
    fn segment_lengths(&mut self) -> f64 {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU supports AVX2 and FMA (checked at construction).
            return unsafe { segment_lengths_avx(&mut self.seg_len, &self.seg_dq, &self.var_w) };
        }
        // Per body Σ_v |Δq_v|·w_v, one pass over the bodies per variable.
        let stride = self.seg_len.len();
        self.seg_len.fill(0.0);
        for (&d, w) in self
            .seg_dq
            .iter()
            .zip(self.var_w.chunks_exact(stride.max(1)))
        {
            if d != 0.0 {
                for (l, &w) in self.seg_len.iter_mut().zip(w) {
                    *l += d * w;
                }
            }
        }
        self.seg_len.iter().fold(0.0f64, |m, &l| m.max(l))
    }

    /// The first pass over the `n + 1` uniform states (inflated for sub-intervals of `1/n`):
    /// false when one collides with the plain spheres; the tight (state, id) entries in
    /// `tight_states` (unsorted).
    fn first_pass(&mut self, a: &[f64], b: &[f64], n: usize) -> bool {
        let h = 1.0 / n as f64;
        self.set_inflation(h);
        // States k = 0..=n, raked: batch j holds k = n − j, n − j − B, … (B batches). The
        // n + 1 states fill whole batches (`begin_segment` rounds n up so), so every lane holds
        // a state. Checked in release builds too: were it broken, the last states would go
        // unchecked and the certificate with them (one comparison per segment).
        let total = n + 1;
        assert!(
            total % LANES == 0,
            "first_pass: {total} states do not fill whole batches of {LANES}"
        );
        let batches = total / LANES;
        self.tight_states.clear();
        for j in 0..batches {
            let top = total - 1 - j;
            let ts: [f64; LANES] = std::array::from_fn(|l| (top - l * batches) as f64 * h);
            self.load_lanes(a, b, &ts);
            self.checks += LANES as u64;
            if self.collides8() {
                return false;
            }
            for e in 0..self.tight_log.len() {
                let (id, mut m) = self.tight_log[e];
                while m != 0 {
                    let l = m.trailing_zeros() as usize;
                    m &= m - 1;
                    self.tight_states.push((top - l * batches, id));
                }
            }
        }
        true
    }

    pub(super) fn certify(&mut self, a: &[f64], b: &[f64], n: usize) -> bool {
        if !self.first_pass(a, b, n) {
            return false;
        }
        if self.tight_states.is_empty() {
            return true;
        }
        self.refine_tight(a, b, n)
    }

    /// The refinement of [`Self::certify`] after a first pass over `n` sub-intervals that
    /// left the tight entries in `tight_states`.
    fn refine_tight(&mut self, a: &[f64], b: &[f64], n: usize) -> bool {
        let h = 1.0 / n as f64;
        // Sub-intervals [i, i+1] with a tight end, each once, in pairs ([`pair_runs`]). A
        // body (against all its obstacles) or self pair free with the inflation at both ends
        // is free over the whole sub-interval (the certificate above, applied to it alone),
        // so the refinement tests only what was tight at its ends and the states between.
        self.refine.clear();
        self.focus_pool.clear();
        self.tight_states.sort_unstable();
        self.tight_states.dedup();
        self.refine_needed.clear();
        {
            let tight = &self.tight_states;
            let needed = &mut self.refine_needed;
            for idx in 0..tight.len() {
                let k = tight[idx].0;
                if idx > 0 && tight[idx - 1].0 == k {
                    continue;
                }
                for i in [k.wrapping_sub(1), k] {
                    if i < n && needed.last().is_none_or(|&l| i > l) {
                        needed.push(i);
                    }
                }
            }
        }
        let needed = std::mem::take(&mut self.refine_needed);
        pair_runs(
            n,
            |i| {
                // `needed` is ascending; `pair_runs` asks in ascending order.
                needed.binary_search(&i).is_ok()
            },
            |i, span| {
                let (fs, fe) = if self.focus {
                    let start = self.focus_pool.len();
                    focus_of_states(&self.tight_states, i, i + span, &mut self.focus_pool);
                    (start as u32, self.focus_pool.len() as u32)
                } else {
                    (NO_FOCUS, NO_FOCUS)
                };
                self.refine
                    .push((i as f64 * h, (i + span) as f64 * h, 0, fs, fe));
            },
        );
        self.refine_needed = needed;
        let mut budget = Self::CERTIFY_MAX_REFINEMENTS;
        while let Some((t0, t1, depth, fs, fe)) = self.refine.pop() {
            if depth >= Self::CERTIFY_MAX_DEPTH || budget == 0 {
                return false;
            }
            budget -= 1;
            self.certify_counts.refinements += 1;
            // One call: the 8 states splitting [t0, t1] into 7 sub-intervals.
            let parts = (LANES - 1) as f64;
            let hs = (t1 - t0) / parts;
            self.set_inflation(hs);
            let mut ts = [0.0; LANES];
            for (l, t) in ts.iter_mut().enumerate() {
                *t = if l == LANES - 1 {
                    t1
                } else {
                    t0 + hs * l as f64
                };
            }
            self.load_lanes(a, b, &ts);
            self.checks += LANES as u64;
            let hit = if fs == NO_FOCUS {
                self.collides8()
            } else {
                self.collides8_focus(fs as usize, fe as usize)
            };
            if hit {
                return false;
            }
            // Lanes free with the plain spheres but not with the inflation; the sub-intervals
            // next to them, in pairs.
            let m = self.tight_log.iter().fold(0, |m, e| m | e.1);
            if m == 0 {
                continue;
            }
            let refine = &mut self.refine;
            let pool = &mut self.focus_pool;
            let log = &self.tight_log;
            pair_runs(
                LANES - 1,
                |l| m & (0b11 << l) != 0,
                |l, span| {
                    let (fs, fe) = if fs == NO_FOCUS {
                        (NO_FOCUS, NO_FOCUS)
                    } else {
                        let start = pool.len();
                        focus_of_lanes(log, l, span, pool);
                        (start as u32, pool.len() as u32)
                    };
                    refine.push((ts[l], ts[l + span], depth + 1, fs, fe));
                },
            );
        }
        true
    }
}
