//! The sampling generator of the tree planners' inner loops: xoshiro256++ (Blackman & Vigna,
//! "Scrambled linear pseudorandom number generators", ACM TOMS 2021), four independent
//! generators stepped together in one AVX2 vector (scalar code off AVX2, same stream). A few
//! adds, shifts and rotates per step of four 64-bit draws — RRT-Connect draws one per joint
//! every iteration, and on MotionBenchMaker's Baxter problems most of ~10⁵ iterations end
//! right after sampling, so [`PlannerRng::fill_uniform`] turns draws into samples within the
//! bounds a vector at a time (two 32-bit values per draw), and
//! [`PlannerRng::fill_uniform_until_inside`] draws and rejects the samples a dynamic domain
//! skips in one loop in registers, most of them by an f32 pretest (`DomainPretest`). Not
//! for cryptography. Seeded from a `u64` through SplitMix64 (the authors' recommendation), so
//! equal seeds give equal streams on every platform.

use rand::{RngCore, SeedableRng};

use crate::planning::DomainBall;

/// Independent xoshiro256++ generators stepped together (one AVX2 vector of 64-bit lanes).
const LANES: usize = 4;

/// xoshiro256++ (see the module documentation), [`LANES`] independent generators stepped
/// together so that one vector step yields [`LANES`] draws. `next_u64` returns lane 0's first
/// output, lane 1's first, …, lane 3's first, lane 0's second, and so on;
/// [`PlannerRng::fill_uniform`] consumes whole steps from a fresh one (draws still buffered
/// are dropped).
#[derive(Debug, Clone)]
pub struct PlannerRng {
    /// `s[k][lane]`: word `k` of each lane's state.
    s: [[u64; LANES]; 4],
    /// The last vector step's outputs; `buf[pos..]` not yet consumed.
    buf: [u64; LANES],
    pos: usize,
    /// The CPU has AVX2 (the vector step uses it).
    avx2: bool,
}

fn splitmix64(x: &mut u64) -> u64 {
    *x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *x;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// One xoshiro256++ step of every lane; returns their outputs.
#[inline(always)]
fn step(s: &mut [[u64; LANES]; 4]) -> [u64; LANES] {
    let mut out = [0u64; LANES];
    for l in 0..LANES {
        out[l] = s[0][l]
            .wrapping_add(s[3][l])
            .rotate_left(23)
            .wrapping_add(s[0][l]);
        let t = s[1][l] << 17;
        s[2][l] ^= s[0][l];
        s[3][l] ^= s[1][l];
        s[1][l] ^= s[2][l];
        s[0][l] ^= s[3][l];
        s[2][l] ^= t;
        s[3][l] = s[3][l].rotate_left(45);
    }
    out
}

/// A draw as a uniform f64 in [0, 1): its top 52 bits as the mantissa of a number in [1, 2),
/// minus 1 (exact, no integer-to-float conversion, which AVX2 lacks for 64-bit lanes).
#[cfg(test)]
#[inline(always)]
fn unit(v: u64) -> f64 {
    f64::from_bits((v >> 12) | ONE_BITS) - 1.0
}

/// The bits of 1.0.
const ONE_BITS: u64 = 0x3FF0_0000_0000_0000;

/// Half a draw as a uniform f64 in [0, 1) with 32 random bits: `h`·2⁻³², built as the
/// mantissa of a number in [1, 2) minus 1 (exact), as the vector path does.
#[inline(always)]
fn unit32(h: u32) -> f64 {
    f64::from_bits((u64::from(h) << 20) | ONE_BITS) - 1.0
}

/// Values per vector step in [`PlannerRng::fill_uniform`]: two 32-bit halves of each lane.
const VALUES_PER_STEP: usize = 2 * LANES;

/// The uniform value in [0, 1) that [`PlannerRng::fill_uniform`] makes of value `j` (below
/// [`VALUES_PER_STEP`]) of a step's outputs `x`: the low halves of the lanes, then the high
/// halves.
#[inline(always)]
fn step_value(x: &[u64; LANES], j: usize) -> f64 {
    let w = x[j % LANES];
    unit32(if j < LANES {
        w as u32
    } else {
        (w >> 32) as u32
    })
}

/// `lo + (hi − lo)·u` for `u` a uniform value in [0, 1) (the arithmetic of every path).
#[inline(always)]
fn scale(lo: f64, hi: f64, u: f64) -> f64 {
    lo + (hi - lo) * u
}

/// Steps per draw the f32 pretest handles (so dimensions up to 32).
const PRETEST_STEPS: usize = 4;

/// f32 values in the lane order of a vector step seen as 8 lanes of 32 bits, a vector per
/// step.
#[derive(Debug, Clone, Copy)]
#[repr(align(32))]
struct StepLanes([[f32; 8]; PRETEST_STEPS]);

/// The f32 pretest of [`PlannerRng::fill_uniform_until_inside`] for one tree: the space's
/// bounds and the tree's state 0 and weights in f32, placed in the 32-bit lane order of the
/// vector step (lane 2m of a step holds value m's low half, lane 2m + 1 value m + 4's high
/// half; see [`step_value`]), and a bound of the f32 distance's error. A draw whose f32
/// distance exceeds the ball's exclusion threshold by more than that bound is skipped without
/// its f64 sample; all others go through the exact test, so the verdicts are the exact test's.
/// Built once per tree root, and only valid with that tree's balls (its state 0 and weights;
/// checked in debug builds): with another tree's ball it would skip the wrong draws. Up to 32
/// dimensions of modest magnitude (|values| ≤ 10⁴).
#[derive(Debug, Clone)]
pub(crate) struct DomainPretest {
    steps: usize,
    lo: StepLanes,
    span: StepLanes,
    center: StepLanes,
    weights: StepLanes,
    /// Bound of |f32 distance − exact distance| (absolute part).
    margin: f64,
    /// The f64 center and weights it was built for.
    center64: [f64; PRETEST_STEPS * VALUES_PER_STEP],
    weights64: [f64; PRETEST_STEPS * VALUES_PER_STEP],
    n: usize,
}

impl DomainPretest {
    /// The pretest for samples in [`lo`, `hi`) against balls around `center` in the metric of
    /// `weights`; `None` off AVX2 + FMA, beyond 32 dimensions, or for values outside ±10⁴ (or
    /// weights outside (0, 10⁴]), where the f32 bound would not hold.
    pub(crate) fn new(
        lo: &[f64],
        hi: &[f64],
        center: &[f64],
        weights: &[f64],
    ) -> Option<DomainPretest> {
        let n = center.len();
        #[cfg(target_arch = "x86_64")]
        let simd = is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma");
        #[cfg(not(target_arch = "x86_64"))]
        let simd = false;
        const BIG: f64 = 1e4;
        let modest = |v: f64| v.is_finite() && v.abs() <= BIG;
        if !simd
            || n == 0
            || n > PRETEST_STEPS * VALUES_PER_STEP
            || lo.len() != n
            || hi.len() != n
            || weights.len() != n
            || !lo.iter().chain(hi).chain(center).all(|&v| modest(v))
            || !weights.iter().all(|&w| w > 0.0 && w <= BIG)
            || lo.iter().zip(hi).any(|(l, h)| l > h)
        {
            return None;
        }
        let zero = StepLanes([[0.0; 8]; PRETEST_STEPS]);
        let mut p = DomainPretest {
            steps: n.div_ceil(VALUES_PER_STEP),
            lo: zero,
            span: zero,
            center: zero,
            weights: zero,
            margin: 0.0,
            center64: [0.0; PRETEST_STEPS * VALUES_PER_STEP],
            weights64: [0.0; PRETEST_STEPS * VALUES_PER_STEP],
            n,
        };
        p.center64[..n].copy_from_slice(center);
        p.weights64[..n].copy_from_slice(weights);
        let eps32 = 2f64.powi(-24);
        let mut margin = 0.0;
        for i in 0..n {
            let (step, j) = (i / VALUES_PER_STEP, i % VALUES_PER_STEP);
            let lane = if j < LANES {
                2 * j
            } else {
                2 * (j - LANES) + 1
            };
            let span = hi[i] - lo[i];
            p.lo.0[step][lane] = lo[i] as f32;
            p.span.0[step][lane] = span as f32;
            p.center.0[step][lane] = center[i] as f32;
            p.weights.0[step][lane] = weights[i] as f32;
            // The f32 value differs from the f64 one by at most (|lo| + span)·5·2⁻²⁴ (the
            // 23-bit fraction, the roundings of lo, span and the fused multiply-add), the
            // f32 difference to the center by ε below; e is at most E in magnitude.
            let eps = (center[i].abs() + lo[i].abs() + span) * 8.0 * eps32;
            let e_max = (center[i] - lo[i]).abs().max((hi[i] - center[i]).abs());
            let w = weights[i];
            margin += w * (2.0 * e_max * eps + eps * eps + 4.0 * eps32 * (e_max + eps).powi(2));
        }
        // Twice the bound, for the roundings it does not itemise.
        p.margin = 2.0 * margin;
        Some(p)
    }

    /// Built for this ball's center and weights (checked in debug builds; the dimension
    /// always).
    #[inline]
    fn matches(&self, ball: &DomainBall<'_>) -> bool {
        debug_assert!(
            ball.center().len() != self.n
                || (ball.center() == &self.center64[..self.n]
                    && ball.weights() == &self.weights64[..self.n]),
            "a DomainPretest used with a ball of another tree"
        );
        ball.center().len() == self.n
    }

    /// The f32 distance above which a draw is certainly excluded by `ball`: the exact test's
    /// boundary (with room for its f64 rounding) plus the error bound, with room for the f32
    /// summation's relative error (≤ 16·2⁻²⁴ for at most 4 steps of 8 lanes): a factor
    /// `1 + 2⁻¹⁷ ≥ 1 / (1 − 2⁻¹⁸)`, a product where a division's latency stood out.
    #[inline]
    fn threshold(&self, ball: &DomainBall<'_>) -> f64 {
        (ball.exclusion_boundary() * (1.0 + 2f64.powi(-40)) + self.margin) * (1.0 + 2f64.powi(-17))
    }
}

/// The vector step with AVX2 intrinsics (the compiler does not vectorise [`step`] by itself):
/// the same arithmetic as [`step`], all lanes at once.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{DomainBall, LANES};
    use std::arch::x86_64::*;

    #[inline(always)]
    unsafe fn rotl<const L: i32, const R: i32>(x: __m256i) -> __m256i {
        _mm256_or_si256(_mm256_slli_epi64::<L>(x), _mm256_srli_epi64::<R>(x))
    }

    /// One step of every lane from the state in registers; returns the outputs.
    #[inline(always)]
    unsafe fn step(s: &mut [__m256i; 4]) -> __m256i {
        let out = _mm256_add_epi64(rotl::<23, 41>(_mm256_add_epi64(s[0], s[3])), s[0]);
        let t = _mm256_slli_epi64::<17>(s[1]);
        s[2] = _mm256_xor_si256(s[2], s[0]);
        s[3] = _mm256_xor_si256(s[3], s[1]);
        s[1] = _mm256_xor_si256(s[1], s[2]);
        s[0] = _mm256_xor_si256(s[0], s[3]);
        s[2] = _mm256_xor_si256(s[2], t);
        s[3] = rotl::<45, 19>(s[3]);
        out
    }

    #[inline(always)]
    unsafe fn load(s: &[[u64; LANES]; 4]) -> [__m256i; 4] {
        [
            _mm256_loadu_si256(s[0].as_ptr().cast()),
            _mm256_loadu_si256(s[1].as_ptr().cast()),
            _mm256_loadu_si256(s[2].as_ptr().cast()),
            _mm256_loadu_si256(s[3].as_ptr().cast()),
        ]
    }

    #[inline(always)]
    unsafe fn store(v: &[__m256i; 4], s: &mut [[u64; LANES]; 4]) {
        for k in 0..4 {
            _mm256_storeu_si256(s[k].as_mut_ptr().cast(), v[k]);
        }
    }

    /// The two vectors of uniform values in [0, 1) a step's outputs make (see
    /// [`super::step_value`]): 32-bit halves placed in the mantissa of a number in [1, 2),
    /// minus 1.
    #[inline(always)]
    unsafe fn units(x: __m256i) -> (__m256d, __m256d) {
        let one = _mm256_set1_epi64x(super::ONE_BITS as i64);
        let low = _mm256_srli_epi64::<12>(_mm256_slli_epi64::<32>(x));
        let high = _mm256_slli_epi64::<20>(_mm256_srli_epi64::<32>(x));
        let one_pd = _mm256_set1_pd(1.0);
        (
            _mm256_sub_pd(_mm256_castsi256_pd(_mm256_or_si256(low, one)), one_pd),
            _mm256_sub_pd(_mm256_castsi256_pd(_mm256_or_si256(high, one)), one_pd),
        )
    }

    /// Lanes below `r` set (for the last, partial vector of a slice).
    #[inline(always)]
    unsafe fn lanes_below(r: usize) -> __m256i {
        _mm256_cmpgt_epi64(_mm256_set1_epi64x(r as i64), _mm256_set_epi64x(3, 2, 1, 0))
    }

    /// Loads `LANES` values of `p` from `k`, only the lanes of `mask` when `partial` (the
    /// others read as 0).
    ///
    /// # Safety
    /// `p[k..k + LANES]`, or its lanes in `mask` when `partial`, are in bounds.
    #[inline(always)]
    unsafe fn load_at(p: &[f64], k: usize, partial: bool, mask: __m256i) -> __m256d {
        if partial {
            _mm256_maskload_pd(p.as_ptr().add(k), mask)
        } else {
            _mm256_loadu_pd(p.as_ptr().add(k))
        }
    }

    /// One sample into `out` from the step outputs `next` yields (`lo + (hi − lo)·u` per value, whole steps of
    /// [`super::VALUES_PER_STEP`] values) and, when `DIST`, the 4-lane accumulator of
    /// `w·(c − x)·(c − x)` (as `tree::plain_dist_sq_avx` sums it). All five slices have length
    /// `n`; `mask` is [`lanes_below`]`(n % LANES)`.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    unsafe fn draw<const DIST: bool>(
        next: &mut impl FnMut() -> __m256i,
        lo: &[f64],
        hi: &[f64],
        center: &[f64],
        w: &[f64],
        out: &mut [f64],
        n: usize,
        mask: __m256i,
    ) -> __m256d {
        let mut acc = _mm256_setzero_pd();
        let mut k = 0;
        while k < n {
            let (a, b) = units(next());
            for u in [a, b] {
                if k >= n {
                    break;
                }
                let partial = k + LANES > n;
                // SAFETY: lanes k.. below n are in bounds of all five slices; the mask keeps
                // the partial vector's loads and store within them.
                let l = load_at(lo, k, partial, mask);
                let h = load_at(hi, k, partial, mask);
                let x = _mm256_add_pd(l, _mm256_mul_pd(_mm256_sub_pd(h, l), u));
                if partial {
                    _mm256_maskstore_pd(out.as_mut_ptr().add(k), mask, x);
                } else {
                    _mm256_storeu_pd(out.as_mut_ptr().add(k), x);
                }
                if DIST {
                    let e = _mm256_sub_pd(load_at(center, k, partial, mask), x);
                    let we = _mm256_mul_pd(load_at(w, k, partial, mask), e);
                    acc = _mm256_add_pd(acc, _mm256_mul_pd(we, e));
                }
                k += LANES;
            }
        }
        acc
    }

    /// [`super::PlannerRng::fill_uniform`]. The three slices have equal lengths.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn fill_uniform(
        s: &mut [[u64; LANES]; 4],
        lo: &[f64],
        hi: &[f64],
        out: &mut [f64],
    ) {
        let n = out.len().min(lo.len()).min(hi.len());
        let mut v = load(s);
        draw::<false>(
            &mut || step(&mut v),
            lo,
            hi,
            &[],
            &[],
            out,
            n,
            lanes_below(n % LANES),
        );
        store(&v, s);
    }

    /// The f64 test of one draw from the step outputs `next` yields: the sample into `out`, the
    /// distance with the arithmetic of `tree::plain_dist_sq_avx`; true when inside.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    unsafe fn exact_inside(
        next: &mut impl FnMut() -> __m256i,
        lo: &[f64],
        hi: &[f64],
        ball: &DomainBall<'_>,
        out: &mut [f64],
        n: usize,
        mask: __m256i,
    ) -> bool {
        let acc = draw::<true>(next, lo, hi, ball.center(), ball.weights(), out, n, mask);
        let half = _mm_add_pd(_mm256_castpd256_pd128(acc), _mm256_extractf128_pd::<1>(acc));
        let d2 = _mm_cvtsd_f64(_mm_add_sd(half, _mm_unpackhi_pd(half, half)));
        !ball.excludes_dist_sq(d2)
    }

    /// [`super::PlannerRng::fill_uniform_until_inside`] without a pretest: every draw through
    /// [`exact_inside`], all in registers. Returns (draws, inside). `out`, `lo`, `hi` and the
    /// ball have `n` values; `max_draws` ≥ 1.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn fill_uniform_until_inside(
        s: &mut [[u64; LANES]; 4],
        lo: &[f64],
        hi: &[f64],
        ball: &DomainBall<'_>,
        max_draws: u64,
        out: &mut [f64],
    ) -> (u64, bool) {
        let n = out.len();
        let mask = lanes_below(n % LANES);
        let mut v = load(s);
        let mut draws = 0;
        let mut inside = false;
        while draws < max_draws {
            draws += 1;
            if exact_inside(&mut || step(&mut v), lo, hi, ball, out, n, mask) {
                inside = true;
                break;
            }
        }
        store(&v, s);
        (draws, inside)
    }

    /// The saved step outputs of a draw, in order, as [`draw`] takes them (it takes exactly
    /// `C`: the pretest's steps per draw).
    #[inline(always)]
    fn replay<const C: usize>(xs: &[__m256i; C]) -> impl FnMut() -> __m256i + '_ {
        let mut i = 0;
        move || {
            let x = xs[i.min(C - 1)];
            i += 1;
            x
        }
    }

    /// [`fill_uniform_until_inside`] with the f32 pretest of `pre` (`C` = its steps per
    /// draw): each draw's steps are made once; their distance in f32 (8 lanes, 23 bits of each
    /// value, the constants in the steps' lane order) skips the draw when it exceeds
    /// `threshold`, which the f32 error bound puts past the exact test's boundary; any other
    /// draw goes through the exact f64 test from the same step outputs.
    #[target_feature(enable = "avx2,fma")]
    #[allow(clippy::too_many_arguments)]
    pub(super) unsafe fn fill_uniform_until_inside_pretest<const C: usize>(
        s: &mut [[u64; LANES]; 4],
        lo: &[f64],
        hi: &[f64],
        ball: &DomainBall<'_>,
        pre: &super::DomainPretest,
        threshold: f64,
        max_draws: u64,
        out: &mut [f64],
    ) -> (u64, bool) {
        let n = out.len();
        let mask = lanes_below(n % LANES);
        let mut v = load(s);
        let ld = |a: &[[f32; 8]; super::PRETEST_STEPS], k: usize| _mm256_loadu_ps(a[k].as_ptr());
        let mut plo = [_mm256_setzero_ps(); C];
        let mut pspan = [_mm256_setzero_ps(); C];
        let mut pc = [_mm256_setzero_ps(); C];
        let mut pw = [_mm256_setzero_ps(); C];
        for k in 0..C {
            plo[k] = ld(&pre.lo.0, k);
            pspan[k] = ld(&pre.span.0, k);
            pc[k] = ld(&pre.center.0, k);
            pw[k] = ld(&pre.weights.0, k);
        }
        let one_bits = _mm256_set1_epi32(0x3F80_0000);
        let one = _mm256_set1_ps(1.0);
        let mut draws = 0;
        let mut inside = false;
        let mut xs = [_mm256_setzero_si256(); C];
        let mut tested_exactly = false;
        while draws < max_draws {
            draws += 1;
            tested_exactly = false;
            let mut acc = _mm256_setzero_ps();
            for k in 0..C {
                let x = step(&mut v);
                xs[k] = x;
                let u = _mm256_sub_ps(
                    _mm256_castsi256_ps(_mm256_or_si256(_mm256_srli_epi32::<9>(x), one_bits)),
                    one,
                );
                let e = _mm256_sub_ps(pc[k], _mm256_fmadd_ps(pspan[k], u, plo[k]));
                acc = _mm256_fmadd_ps(_mm256_mul_ps(pw[k], e), e, acc);
            }
            let h = _mm_add_ps(_mm256_castps256_ps128(acc), _mm256_extractf128_ps::<1>(acc));
            let h = _mm_add_ps(h, _mm_movehl_ps(h, h));
            let d32 = _mm_cvtss_f32(_mm_add_ss(h, _mm_movehdup_ps(h)));
            if f64::from(d32) > threshold {
                continue;
            }
            tested_exactly = true;
            if exact_inside(&mut replay(&xs), lo, hi, ball, out, n, mask) {
                inside = true;
                break;
            }
        }
        if !tested_exactly {
            // The last draw was skipped by the pretest: its sample still goes to `out`.
            draw::<false>(&mut replay(&xs), lo, hi, &[], &[], out, n, mask);
        }
        store(&v, s);
        (draws, inside)
    }

    /// [`super::step`] with AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn step_once(s: &mut [[u64; LANES]; 4]) -> [u64; LANES] {
        let mut v = load(s);
        let x = step(&mut v);
        store(&v, s);
        let mut out = [0u64; LANES];
        _mm256_storeu_si256(out.as_mut_ptr().cast(), x);
        out
    }
}

impl PlannerRng {
    /// Fills `out[i]` with a uniform value in [`lo[i]`, `hi[i]`) (32 random bits each; the
    /// three slices have equal lengths). Consumes whole vector steps from a fresh one (draws
    /// still buffered are dropped): each step's [`LANES`] outputs make [`VALUES_PER_STEP`]
    /// values, the low halves then the high halves (see [`step_value`]), and what a last step
    /// leaves over is dropped too.
    #[inline]
    pub fn fill_uniform(&mut self, lo: &[f64], hi: &[f64], out: &mut [f64]) {
        debug_assert!(lo.len() == out.len() && hi.len() == out.len());
        self.pos = LANES;
        if out.is_empty() {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the CPU has AVX2 (checked at seeding).
            unsafe { avx2::fill_uniform(&mut self.s, lo, hi, out) };
            return;
        }
        for (c, chunk) in out.chunks_mut(VALUES_PER_STEP).enumerate() {
            let x = step(&mut self.s);
            let k = c * VALUES_PER_STEP;
            for (j, o) in chunk.iter_mut().enumerate() {
                *o = scale(lo[k + j], hi[k + j], step_value(&x, j));
            }
        }
    }

    /// Draws samples as [`PlannerRng::fill_uniform`] does, one after another into `out`, until
    /// one is not certainly outside `ball` ([`DomainBall::excludes`]) or `max_draws` (at least
    /// one) were made; returns the number of draws and whether the last is inside. The same
    /// draws, samples and verdicts as calling `fill_uniform` and `excludes` in turn (tested),
    /// but on AVX2 CPUs one fused loop in registers, and with a `pretest` built for the ball's
    /// tree ([`DomainPretest`]) most draws are rejected in f32 without their f64 sample:
    /// dynamic-domain RRT-Connect skips most of its samples this way (Yershova et al., ICRA
    /// 2005), and there the separate calls cost more than the test itself.
    #[inline]
    pub(crate) fn fill_uniform_until_inside(
        &mut self,
        lo: &[f64],
        hi: &[f64],
        ball: &DomainBall<'_>,
        pretest: Option<&DomainPretest>,
        max_draws: u64,
        out: &mut [f64],
    ) -> (u64, bool) {
        let max_draws = max_draws.max(1);
        let n = out.len();
        #[cfg(target_arch = "x86_64")]
        if self.avx2
            && ball.uses_avx()
            && n > 0
            && lo.len() == n
            && hi.len() == n
            && ball.center().len() == n
            && ball.weights().len() == n
        {
            self.pos = LANES;
            if let Some(p) = pretest.filter(|p| p.matches(ball)) {
                let t = p.threshold(ball);
                let (s, pre) = (&mut self.s, p);
                // SAFETY: a pretest exists only on CPUs with AVX2 and FMA (checked in
                // `DomainPretest::new`); its constants cover the n ≤ 8·steps values.
                return unsafe {
                    match p.steps {
                        1 => avx2::fill_uniform_until_inside_pretest::<1>(
                            s, lo, hi, ball, pre, t, max_draws, out,
                        ),
                        2 => avx2::fill_uniform_until_inside_pretest::<2>(
                            s, lo, hi, ball, pre, t, max_draws, out,
                        ),
                        3 => avx2::fill_uniform_until_inside_pretest::<3>(
                            s, lo, hi, ball, pre, t, max_draws, out,
                        ),
                        _ => avx2::fill_uniform_until_inside_pretest::<4>(
                            s, lo, hi, ball, pre, t, max_draws, out,
                        ),
                    }
                };
            }
            // SAFETY: `avx2` is set only when the CPU has AVX2 (checked at seeding); the
            // ball's distance uses the same AVX arithmetic.
            return unsafe {
                avx2::fill_uniform_until_inside(&mut self.s, lo, hi, ball, max_draws, out)
            };
        }
        let _ = pretest;
        let mut draws = 0;
        while draws < max_draws {
            draws += 1;
            self.fill_uniform(lo, hi, out);
            if !ball.excludes(out) {
                return (draws, true);
            }
        }
        (draws, false)
    }

    /// Steps every lane once into the buffer.
    #[inline]
    fn refill(&mut self) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the CPU has AVX2 (checked at seeding).
            self.buf = unsafe { avx2::step_once(&mut self.s) };
            self.pos = 0;
            return;
        }
        self.buf = step(&mut self.s);
        self.pos = 0;
    }

    fn from_words(words: [u64; 4 * LANES]) -> PlannerRng {
        let mut s = [[0u64; LANES]; 4];
        for (l, w) in words.chunks_exact(4).enumerate() {
            for k in 0..4 {
                s[k][l] = w[k];
            }
        }
        PlannerRng {
            s,
            buf: [0; LANES],
            pos: LANES,
            #[cfg(target_arch = "x86_64")]
            avx2: std::is_x86_feature_detected!("avx2"),
            #[cfg(not(target_arch = "x86_64"))]
            avx2: false,
        }
    }
}

impl RngCore for PlannerRng {
    #[inline]
    fn next_u64(&mut self) -> u64 {
        if self.pos == LANES {
            self.refill();
        }
        let v = self.buf[self.pos];
        self.pos += 1;
        v
    }

    #[inline]
    fn next_u32(&mut self) -> u32 {
        (self.next_u64() >> 32) as u32
    }

    fn fill_bytes(&mut self, dst: &mut [u8]) {
        for chunk in dst.chunks_mut(8) {
            let v = self.next_u64().to_le_bytes();
            chunk.copy_from_slice(&v[..chunk.len()]);
        }
    }
}

impl SeedableRng for PlannerRng {
    type Seed = [u8; 32];

    /// The state of every lane from SplitMix64 of the `seed` read as four little-endian words
    /// (each word seeds its own SplitMix64 sequence), so no lane starts at the all-zero state
    /// and equal seeds give equal streams on every platform.
    fn from_seed(seed: [u8; 32]) -> PlannerRng {
        let mut words = [0u64; 4 * LANES];
        for (k, c) in seed.chunks_exact(8).enumerate() {
            let mut b = [0u8; 8];
            b.copy_from_slice(c);
            let mut x = u64::from_le_bytes(b);
            for l in 0..LANES {
                words[4 * l + k] = splitmix64(&mut x);
            }
        }
        PlannerRng::from_words(words)
    }

    /// Every lane's state from one SplitMix64 sequence started at `seed` (the authors'
    /// recommended seeding).
    fn seed_from_u64(seed: u64) -> PlannerRng {
        let mut x = seed;
        let mut words = [0u64; 4 * LANES];
        for w in words.iter_mut() {
            *w = splitmix64(&mut x);
        }
        PlannerRng::from_words(words)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reference implementation's output (xoshiro256plusplus.c) for the state
    /// s = [1, 2, 3, 4], in every lane: each lane is that generator, and the stream
    /// interleaves the lanes.
    #[test]
    fn matches_the_reference_stream() {
        let mut words = [0u64; 4 * LANES];
        for l in 0..LANES {
            words[4 * l..4 * l + 4].copy_from_slice(&[1, 2, 3, 4]);
        }
        words[4] = 5; // lane 1 differs, so the interleaving order is visible
        let mut r = PlannerRng::from_words(words);
        let got: Vec<u64> = (0..4 * LANES).map(|_| r.next_u64()).collect();
        let reference = [41943041u64, 58720359, 3588806011781223, 3591011842654386];
        for (n, &want) in reference.iter().enumerate() {
            for l in [0, 2, 3] {
                assert_eq!(got[n * LANES + l], want, "draw {n} of lane {l}");
            }
        }
        assert_ne!(got[1], got[0]);
    }

    /// `fill_uniform` consumes whole steps from a fresh one whatever the buffer position,
    /// [`VALUES_PER_STEP`] values per step in [`step_value`] order (the scalar reference),
    /// drops what is left, and values stay in [lo, hi).
    #[test]
    fn fill_uniform_follows_the_stream() {
        for skip in 0..5 {
            for len in [0usize, 1, 3, 4, 7, 8, 9, 14, 33] {
                let mut a = PlannerRng::seed_from_u64(11);
                let mut b = PlannerRng::seed_from_u64(11);
                for _ in 0..skip {
                    a.next_u64();
                    b.next_u64();
                }
                let lo: Vec<f64> = (0..len).map(|i| -1.0 - i as f64).collect();
                let hi: Vec<f64> = (0..len).map(|i| 0.5 * i as f64).collect();
                let mut got = vec![0.0; len];
                a.fill_uniform(&lo, &hi, &mut got);
                let mut want = vec![0.0; len];
                for (i, w) in want.iter_mut().enumerate() {
                    if i % VALUES_PER_STEP == 0 {
                        b.pos = LANES;
                        b.refill();
                    }
                    *w = scale(lo[i], hi[i], step_value(&b.buf, i % VALUES_PER_STEP));
                }
                assert_eq!(got, want, "skip {skip}, len {len}");
                assert!(got
                    .iter()
                    .zip(&lo)
                    .zip(&hi)
                    .all(|((v, l), h)| l <= v && v < h));
                b.pos = LANES;
                assert_eq!(a.next_u64(), b.next_u64(), "skip {skip}, len {len}");
            }
        }
        assert_eq!(unit(0), 0.0);
        assert_eq!(unit(u64::MAX), 1.0 - f64::EPSILON);
        assert_eq!(unit32(0), 0.0);
        assert_eq!(unit32(u32::MAX), 1.0 - 2f64.powi(-32));
        let x = [0x0000_0002_0000_0001u64, 0, 0, 0];
        assert_eq!(step_value(&x, 0), 2f64.powi(-32));
        assert_eq!(step_value(&x, LANES), 2.0 * 2f64.powi(-32));
    }

    /// `fill_uniform_until_inside` makes the same draws, samples and verdicts as
    /// `fill_uniform` and `DomainBall::excludes` in turn, for balls that exclude from none to
    /// all of the samples (so verdicts near the boundary are exercised too), for dimensions
    /// with and without a partial last vector.
    #[test]
    fn fused_sampling_equals_sample_then_test() {
        use crate::planning::{Tree, NO_PARENT};
        let mut total = [0u64; 2];
        for dim in [1usize, 3, 4, 7, 8, 14, 20] {
            let lo: Vec<f64> = (0..dim).map(|i| -1.0 - 0.3 * i as f64).collect();
            let hi: Vec<f64> = (0..dim).map(|i| 1.5 + 0.1 * i as f64).collect();
            let w: Vec<f64> = (0..dim).map(|i| 0.5 + 0.25 * (i % 3) as f64).collect();
            let mut tree = Tree::new(&w);
            let root: Vec<f64> = (0..dim).map(|i| 0.1 * i as f64 - 0.2).collect();
            tree.add(&root, NO_PARENT);
            for (case, r) in [0.05, 0.5, 1.0, 1.5, 2.0, 3.0, 6.0].iter().enumerate() {
                tree.set_radius(0, r * (dim as f64).sqrt());
                let Some(ball) = tree.domain_ball() else {
                    panic!("a finite radius gives a ball");
                };
                let pretest = DomainPretest::new(&lo, &hi, &root, &w);
                assert!(pretest.is_some() || !is_x86_feature_detected!("fma"));
                for (max, pre) in [(1u64, None), (5, None), (65, None), (1, pretest.as_ref())]
                    .into_iter()
                    .chain([5, 65, 1000].map(|m| (m, pretest.as_ref())))
                {
                    let seed = (dim * 100 + case * 10) as u64 + max;
                    let mut a = PlannerRng::seed_from_u64(seed);
                    let mut b = PlannerRng::seed_from_u64(seed);
                    let (mut qa, mut qb) = (vec![0.0; dim], vec![0.0; dim]);
                    for _ in 0..20 {
                        let (draws, inside) =
                            a.fill_uniform_until_inside(&lo, &hi, &ball, pre, max, &mut qa);
                        let mut want = (0, false);
                        while want.0 < max {
                            want.0 += 1;
                            b.fill_uniform(&lo, &hi, &mut qb);
                            if !ball.excludes(&qb) {
                                want.1 = true;
                                break;
                            }
                        }
                        let at = format!("dim {dim}, radius {r}, max {max}, {}", pre.is_some());
                        assert_eq!((draws, inside), want, "{at}");
                        assert_eq!(qa, qb, "{at}");
                        total[usize::from(inside)] += 1;
                    }
                    assert_eq!(a.next_u64(), b.next_u64());
                }
            }
        }
        // Both outcomes occur.
        assert!(total[0] > 100 && total[1] > 100, "{total:?}");
    }

    /// Near the boundary: a 14-D ball that excludes about half of the samples, so many
    /// draws lie close to it; the pretest's verdicts still equal the exact test's, and its
    /// threshold sits within 0.1 % of the exact boundary (it does skip draws there).
    #[test]
    fn pretest_verdicts_near_the_boundary() {
        use crate::planning::{Tree, NO_PARENT};
        let lo = [
            -1.7, -2.147, -3.05, -0.05, -3.059, -1.57, -3.059, -1.7, -2.147, -3.05, -0.05, -3.059,
            -1.57, -3.059,
        ];
        let hi = [
            1.7, 1.047, 3.05, 2.618, 3.059, 2.094, 3.059, 1.7, 1.047, 3.05, 2.618, 3.059, 2.094,
            3.059,
        ];
        let w = [1.0; 14];
        let root = [
            0.3, -0.5, 0.1, 1.2, -0.4, 0.6, 0.0, -0.3, 0.2, 1.0, 0.5, 0.0, -0.6, 2.0,
        ];
        let mut tree = Tree::new(&w);
        tree.add(&root, NO_PARENT);
        tree.set_radius(0, 5.1);
        let Some(ball) = tree.domain_ball() else {
            panic!("a finite radius gives a ball");
        };
        let Some(pre) = DomainPretest::new(&lo, &hi, &root, &w) else {
            assert!(!is_x86_feature_detected!("fma"));
            return;
        };
        let boundary = ball.exclusion_boundary();
        assert!(pre.threshold(&ball) < boundary * 1.001);
        assert!(pre.threshold(&ball) > boundary);
        let mut a = PlannerRng::seed_from_u64(5);
        let mut b = PlannerRng::seed_from_u64(5);
        let (mut qa, mut qb) = ([0.0; 14], [0.0; 14]);
        let (mut inside, mut near) = (0, 0);
        for _ in 0..20_000 {
            let got = a.fill_uniform_until_inside(&lo, &hi, &ball, Some(&pre), 1, &mut qa);
            b.fill_uniform(&lo, &hi, &mut qb);
            let d2 = ball.dist_sq(&qb);
            assert_eq!(
                got,
                (1, !ball.excludes(&qb)),
                "d² {d2}, boundary {boundary}"
            );
            assert_eq!(qa, qb);
            inside += usize::from(got.1);
            near += usize::from((d2 / boundary - 1.0).abs() < 0.01);
        }
        assert!((5_000..15_000).contains(&inside), "{inside} inside");
        assert!(near > 200, "{near} near the boundary");
    }

    /// The scalar paths (CPUs without AVX2) make the same samples and verdicts as the vector
    /// paths: the same stream on every x86-64 CPU.
    #[test]
    fn scalar_paths_equal_vector_paths() {
        use crate::planning::{Tree, NO_PARENT};
        let dim = 14;
        let lo: Vec<f64> = (0..dim).map(|i| -1.5 - 0.2 * i as f64).collect();
        let hi: Vec<f64> = (0..dim).map(|i| 1.0 + 0.3 * i as f64).collect();
        let w: Vec<f64> = (0..dim).map(|i| 1.0 + 0.5 * (i % 2) as f64).collect();
        let mut tree = Tree::new(&w);
        tree.add(&vec![0.1; dim], NO_PARENT);
        tree.set_radius(0, 5.5);
        let Some(ball) = tree.domain_ball() else {
            panic!("a finite radius gives a ball");
        };
        let pre = DomainPretest::new(&lo, &hi, ball.center(), &w);
        let mut a = PlannerRng::seed_from_u64(21);
        let mut b = PlannerRng::seed_from_u64(21);
        b.avx2 = false;
        let (mut qa, mut qb) = (vec![0.0; dim], vec![0.0; dim]);
        let mut inside = 0;
        for k in 0..300 {
            a.fill_uniform(&lo, &hi, &mut qa);
            b.fill_uniform(&lo, &hi, &mut qb);
            assert_eq!(qa, qb);
            let max = 1 + k % 20;
            let ra = a.fill_uniform_until_inside(&lo, &hi, &ball, pre.as_ref(), max, &mut qa);
            let rb = b.fill_uniform_until_inside(&lo, &hi, &ball, pre.as_ref(), max, &mut qb);
            assert_eq!(ra, rb);
            assert_eq!(qa, qb);
            inside += usize::from(ra.1);
            assert_eq!(a.next_u64(), b.next_u64());
        }
        assert!((10..290).contains(&inside), "{inside}");
    }

    #[test]
    fn equal_seeds_equal_streams() {
        let mut a = PlannerRng::seed_from_u64(7);
        let mut b = PlannerRng::seed_from_u64(7);
        let mut c = PlannerRng::seed_from_u64(8);
        let (x, y, z) = (a.next_u64(), b.next_u64(), c.next_u64());
        assert_eq!(x, y);
        assert_ne!(x, z);
    }
}
