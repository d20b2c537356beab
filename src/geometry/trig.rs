//! `sin_cos` and `atan2` for the kinematics hot loop (the analytic S-R-S IK calls them ~100
//! times per swivel angle). `sin_cos`: fdlibm's kernels after a two-constant Cody–Waite
//! reduction by π/2; within 2 ulp of `f64::sin_cos` for |x| ≤ 1e5 (joint angles), the library
//! beyond. About 3× faster than libm's `sincos` here; [`sin_cos_lanes`] evaluates the same
//! operations four angles at a time (AVX2) for forward kinematics. `atan2`: fdlibm's `atan`
//! (four breakpoints, 11-term polynomial, < 1 ulp) with its quadrant logic, inlined; the
//! library for non-finite arguments.

// fdlibm's constants, written with all their digits.
#![allow(clippy::excessive_precision)]
const PIO2_1: f64 = 1.570_796_326_734_125_614_17e+00;
const PIO2_1T: f64 = 6.077_100_506_506_192_249_32e-11;
const INV_PIO2: f64 = std::f64::consts::FRAC_2_PI;

const S1: f64 = -1.666_666_666_666_663_243_48e-01;
const S2: f64 = 8.333_333_333_322_489_461_24e-03;
const S3: f64 = -1.984_126_982_985_794_931_34e-04;
const S4: f64 = 2.755_731_370_707_006_767_89e-06;
const S5: f64 = -2.505_076_025_340_686_341_95e-08;
const S6: f64 = 1.589_690_995_211_550_102_21e-10;

const C1: f64 = 4.166_666_666_666_660_190_37e-02;
const C2: f64 = -1.388_888_888_887_410_957_49e-03;
const C3: f64 = 2.480_158_728_947_672_941_78e-05;
const C4: f64 = -2.755_731_435_139_066_330_35e-07;
const C5: f64 = 2.087_572_321_298_174_827_90e-09;
const C6: f64 = -1.135_964_755_778_819_482_65e-11;

#[inline(always)]
fn kernel(r: f64) -> (f64, f64) {
    let z = r * r;
    let s = r + r * z * (S1 + z * (S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))));
    let hz = 0.5 * z;
    let w = 1.0 - hz;
    let c =
        w + (((1.0 - w) - hz) + z * z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6))))));
    (s, c)
}

/// `(sin x, cos x)`.
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    if x.is_nan() || x.abs() > 1e5 {
        return x.sin_cos();
    }
    // Round to nearest without a libm call (baseline x86-64 has no SSE4.1 round).
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    let k = (x * INV_PIO2 + MAGIC) - MAGIC;
    let r = (x - k * PIO2_1) - k * PIO2_1T;
    let (s, c) = kernel(r);
    // Quadrant select without branches (random angles would mispredict).
    let q = (k as i64 & 3) as usize;
    let t = [s, c, -s, -c];
    (t[q], t[(q + 1) & 3])
}

/// [`sin_cos`] of each of the first `n` of `x` (at most `N`) into `(s[i], c[i])`, bit for bit
/// the values [`sin_cos`] gives: the same operations in the same order, four angles at a time
/// in AVX2 registers where the CPU has them (no fused multiply-adds, so the roundings are the
/// scalar ones). `N` is a multiple of 4 and whole groups of four are evaluated: lanes `n..` up
/// to the next multiple of 4 get the values of whatever angles they hold. For forward
/// kinematics, whose joints' angles are all known before the chain is composed: an arm's
/// seven angles cost two vector evaluations instead of seven scalar ones, and the vector
/// evaluations' latencies overlap (dual-arm IK-RRT rows of `bench planners`: medians −6 %).
#[inline]
pub fn sin_cos_lanes<const N: usize>(x: &[f64; N], s: &mut [f64; N], c: &mut [f64; N], n: usize) {
    const { assert!(N % 4 == 0) };
    let n = n.min(N);
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        let mut i = 0;
        while i < n {
            // SAFETY: AVX2 is present (checked above); i + 4 <= N as N is a multiple of 4.
            unsafe { avx2::sin_cos4(&x[i..i + 4], &mut s[i..i + 4], &mut c[i..i + 4]) };
            i += 4;
        }
        return;
    }
    for k in 0..n {
        (s[k], c[k]) = sin_cos(x[k]);
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;
    use std::arch::x86_64::*;

    /// [`sin_cos`] of `x[0..4]`, lane by lane the scalar function's operations.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn sin_cos4(x: &[f64], s_out: &mut [f64], c_out: &mut [f64]) {
        debug_assert!(x.len() >= 4 && s_out.len() >= 4 && c_out.len() >= 4);
        let set = |v: f64| _mm256_set1_pd(v);
        let (add, sub, mul) = (_mm256_add_pd, _mm256_sub_pd, _mm256_mul_pd);
        let xv = _mm256_loadu_pd(x.as_ptr());
        // Lanes the scalar function hands to the library: NaN or |x| > 1e5.
        let sign = set(-0.0);
        let ok = _mm256_cmp_pd::<_CMP_LE_OQ>(_mm256_andnot_pd(sign, xv), set(1e5));
        const MAGIC: f64 = 6_755_399_441_055_744.0;
        let t = add(mul(xv, set(INV_PIO2)), set(MAGIC));
        let k = sub(t, set(MAGIC));
        let r = sub(sub(xv, mul(k, set(PIO2_1))), mul(k, set(PIO2_1T)));
        // kernel(r)
        let z = mul(r, r);
        let ps = add(set(S5), mul(z, set(S6)));
        let ps = add(set(S4), mul(z, ps));
        let ps = add(set(S3), mul(z, ps));
        let ps = add(set(S2), mul(z, ps));
        let ps = add(set(S1), mul(z, ps));
        let sv = add(r, mul(mul(r, z), ps));
        let hz = mul(set(0.5), z);
        let w = sub(set(1.0), hz);
        let pc = add(set(C5), mul(z, set(C6)));
        let pc = add(set(C4), mul(z, pc));
        let pc = add(set(C3), mul(z, pc));
        let pc = add(set(C2), mul(z, pc));
        let pc = add(set(C1), mul(z, pc));
        let cv = add(w, add(sub(sub(set(1.0), w), hz), mul(mul(z, z), pc)));
        // Quadrant q = k mod 4: t = MAGIC + k exactly, and 2⁵¹ (MAGIC's share of the
        // mantissa) is divisible by 4, so t's low mantissa bits are q in two's complement.
        let ti = _mm256_castpd_si256(t);
        let one = _mm256_set1_epi64x(1);
        let two = _mm256_set1_epi64x(2);
        let odd = _mm256_castsi256_pd(_mm256_cmpeq_epi64(_mm256_and_si256(ti, one), one));
        let neg_s = _mm256_castsi256_pd(_mm256_cmpeq_epi64(_mm256_and_si256(ti, two), two));
        let neg_c = _mm256_castsi256_pd(_mm256_cmpeq_epi64(
            _mm256_and_si256(_mm256_add_epi64(ti, one), two),
            two,
        ));
        // [s, c, -s, -c][q] and [s, c, -s, -c][(q + 1) & 3].
        let sin = _mm256_xor_pd(_mm256_blendv_pd(sv, cv, odd), _mm256_and_pd(neg_s, sign));
        let cos = _mm256_xor_pd(_mm256_blendv_pd(cv, sv, odd), _mm256_and_pd(neg_c, sign));
        _mm256_storeu_pd(s_out.as_mut_ptr(), sin);
        _mm256_storeu_pd(c_out.as_mut_ptr(), cos);
        let m = _mm256_movemask_pd(ok);
        if m != 0b1111 {
            for l in 0..4 {
                if m & (1 << l) == 0 {
                    (s_out[l], c_out[l]) = x[l].sin_cos();
                }
            }
        }
    }
}

const ATAN_HI: [f64; 4] = [
    4.636_476_090_008_060_935_15e-01,
    std::f64::consts::FRAC_PI_4,
    9.827_937_232_473_290_540_82e-01,
    std::f64::consts::FRAC_PI_2,
];
const ATAN_LO: [f64; 4] = [
    2.269_877_745_296_168_709_24e-17,
    3.061_616_997_868_383_017_93e-17,
    1.390_331_103_123_099_845_16e-17,
    6.123_233_995_736_766_035_87e-17,
];
const AT: [f64; 11] = [
    3.333_333_333_333_293_180_27e-01,
    -1.999_999_999_987_648_324_76e-01,
    1.428_571_427_250_346_637_11e-01,
    -1.111_111_040_546_235_578_80e-01,
    9.090_887_133_436_506_561_96e-02,
    -7.691_876_205_044_829_994_95e-02,
    6.661_073_137_387_531_206_69e-02,
    -5.833_570_133_790_573_486_45e-02,
    4.976_877_994_615_932_360_17e-02,
    -3.653_157_274_421_691_552_70e-02,
    1.628_582_011_536_578_236_23e-02,
];
const PI_LO: f64 = 1.224_646_799_147_353_177_2e-16;

/// `atan(t)` for finite `t ≥ 0` (fdlibm `s_atan.c`).
#[inline(always)]
fn atan_pos(t: f64) -> f64 {
    if t >= 7.378_697_629_483_820_6e19 {
        // 2⁶⁶: atan t = π/2 to double precision.
        return ATAN_HI[3] + ATAN_LO[3];
    }
    let (id, x) = if t < 0.4375 {
        if t < 7.450_580_596_923_828e-9 {
            return t; // 2⁻²⁷
        }
        (usize::MAX, t)
    } else if t < 1.1875 {
        if t < 0.6875 {
            (0, (2.0 * t - 1.0) / (2.0 + t))
        } else {
            (1, (t - 1.0) / (t + 1.0))
        }
    } else if t < 2.4375 {
        (2, (t - 1.5) / (1.0 + 1.5 * t))
    } else {
        (3, -1.0 / t)
    };
    let z = x * x;
    let w = z * z;
    let s1 = z * (AT[0] + w * (AT[2] + w * (AT[4] + w * (AT[6] + w * (AT[8] + w * AT[10])))));
    let s2 = w * (AT[1] + w * (AT[3] + w * (AT[5] + w * (AT[7] + w * AT[9]))));
    if id == usize::MAX {
        x - x * (s1 + s2)
    } else {
        ATAN_HI[id] - ((x * (s1 + s2) - ATAN_LO[id]) - x)
    }
}

/// `atan2(y, x)` (fdlibm `e_atan2.c`: quadrants from the signs, `atan |y/x|` in between).
#[inline]
pub fn atan2(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI};
    if !(x.is_finite() && y.is_finite()) {
        return y.atan2(x);
    }
    if y == 0.0 {
        return if x.is_sign_negative() {
            if y.is_sign_negative() {
                -PI
            } else {
                PI
            }
        } else {
            y
        };
    }
    if x == 0.0 {
        return if y < 0.0 { -FRAC_PI_2 } else { FRAC_PI_2 };
    }
    let (ax, ay) = (x.abs(), y.abs());
    let q = ay / ax;
    let z = if q.is_infinite() || q > 1.152_921_504_606_847e18 {
        // |y/x| > 2⁶⁰
        FRAC_PI_2 + 0.5 * PI_LO
    } else if x < 0.0 && q < 8.673_617_379_884_035e-19 {
        // |y/x| < 2⁻⁶⁰ with x < 0: the result is ±π.
        0.0
    } else {
        atan_pos(q)
    };
    match (x < 0.0, y < 0.0) {
        (false, false) => z,
        (false, true) => -z,
        (true, false) => PI - (z - PI_LO),
        (true, true) => (z - PI_LO) - PI,
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn matches_libm_over_joint_ranges() {
        let mut worst: f64 = 0.0;
        let n = 2_000_000;
        for i in 0..=n {
            let x = -20.0 + 40.0 * i as f64 / n as f64;
            let (s, c) = super::sin_cos(x);
            let (s0, c0) = x.sin_cos();
            worst = worst.max((s - s0).abs()).max((c - c0).abs());
        }
        assert!(worst < 5e-16, "worst {worst:e}");
        assert_eq!(super::sin_cos(0.0), (0.0, 1.0));
        let (s, c) = super::sin_cos(1e9);
        assert_eq!((s, c), 1e9f64.sin_cos());
        assert!(super::sin_cos(f64::NAN).0.is_nan());
    }

    #[test]
    fn batch_is_the_scalar_function_bit_for_bit() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut x: Vec<f64> = (0..200_000)
            .map(|i| {
                let m = [0.1, 1.0, 4.0, 40.0, 3e4, 2e5][i % 6];
                rng.random_range(-m..m)
            })
            .collect();
        // Quadrant boundaries, signed zeros, the library's range and non-finite values.
        for k in -8..=8 {
            let b = k as f64 * std::f64::consts::FRAC_PI_2;
            x.extend([b, b.next_up(), b.next_down()]);
        }
        x.extend([
            0.0,
            -0.0,
            1e5,
            -1e5,
            1e5f64.next_up(),
            f64::NAN,
            f64::INFINITY,
        ]);
        x.extend([f64::NEG_INFINITY, 1e300, -7.0]);
        for n in [0, 1, 3, 4, 7, 16] {
            let mut xs = [0.0f64; 16];
            let (mut s, mut c) = ([0.0f64; 16], [0.0f64; 16]);
            for chunk in x.chunks(16) {
                xs[..chunk.len()].copy_from_slice(chunk);
                super::sin_cos_lanes(&xs, &mut s, &mut c, n.min(chunk.len()));
                for i in 0..n.min(chunk.len()) {
                    let (s0, c0) = super::sin_cos(xs[i]);
                    assert_eq!(
                        (s[i].to_bits(), c[i].to_bits()),
                        (s0.to_bits(), c0.to_bits())
                    );
                }
            }
        }
    }

    #[test]
    fn atan2_matches_libm_to_an_ulp() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut worst_ulps = 0u64;
        let ulps = |a: f64, b: f64| (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs();
        for i in 0..2_000_000 {
            // Mixed scales, all four quadrants, and near-axis ratios.
            let e = rng.random_range(-30..30) as f64;
            let y = rng.random_range(-1.0..1.0) * 2f64.powf(e * (i % 3) as f64 / 3.0);
            let x = rng.random_range(-1.0..1.0) * 2f64.powf(-e * (i % 5) as f64 / 5.0);
            let (a, b) = (super::atan2(y, x), y.atan2(x));
            worst_ulps = worst_ulps.max(ulps(a, b));
        }
        assert!(worst_ulps <= 2, "worst {worst_ulps} ulp");
        for (y, x) in [
            (0.0, 1.0),
            (-0.0, 1.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (1.0, 0.0),
            (-1.0, 0.0),
            (1.0, 1.0),
            (1e-300, -1.0),
            (-1e-300, -1.0),
            (1e300, 1e-300),
            (1.0, 1e300),
            (f64::INFINITY, 1.0),
            (1.0, f64::NEG_INFINITY),
        ] {
            let (a, b) = (super::atan2(y, x), y.atan2(x));
            assert!(ulps(a, b) <= 1, "atan2({y}, {x}) = {a} vs {b}");
        }
        assert!(super::atan2(f64::NAN, 1.0).is_nan());
    }
}
