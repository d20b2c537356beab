//! The sampling generator of the tree planners' inner loops: xoshiro256++ (Blackman & Vigna,
//! "Scrambled linear pseudorandom number generators", ACM TOMS 2021), four independent
//! generators stepped together in one AVX2 vector (scalar code off AVX2, same stream). A few
//! adds, shifts and rotates per step of four 64-bit draws — RRT-Connect draws one per joint
//! every iteration, and on MotionBenchMaker's Baxter problems most of ~10⁵ iterations end
//! right after sampling, so [`PlannerRng::fill_uniform`] turns draws into samples within the
//! bounds a vector at a time. Not for cryptography. Seeded from a `u64` through SplitMix64
//! (the authors' recommendation), so equal seeds give equal streams on every platform.

use rand::{RngCore, SeedableRng};

/// Independent xoshiro256++ generators stepped together (one AVX2 vector of 64-bit lanes).
const LANES: usize = 4;

/// xoshiro256++ (see the module documentation), [`LANES`] independent generators stepped
/// together so that one vector step yields [`LANES`] draws. `next_u64` returns lane 0's first
/// output, lane 1's first, …, lane 3's first, lane 0's second, and so on;
/// [`PlannerRng::fill_uniform`] starts at a fresh step (draws still buffered are dropped), so
/// its vectors line up with the output slice.
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
#[inline(always)]
fn unit(v: u64) -> f64 {
    f64::from_bits((v >> 12) | 0x3FF0_0000_0000_0000) - 1.0
}

/// `lo + (hi − lo)·u` for `u` a uniform value in [0, 1) (the arithmetic of every path).
#[inline(always)]
fn scale(lo: f64, hi: f64, u: f64) -> f64 {
    lo + (hi - lo) * u
}

/// The vector step with AVX2 intrinsics (the compiler does not vectorise [`step`] by itself):
/// the same arithmetic as [`step`], all lanes at once.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::LANES;
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

    #[inline(always)]
    unsafe fn unit(x: __m256i) -> __m256d {
        let m = _mm256_or_si256(
            _mm256_srli_epi64::<12>(x),
            _mm256_set1_epi64x(0x3FF0_0000_0000_0000),
        );
        _mm256_sub_pd(_mm256_castsi256_pd(m), _mm256_set1_pd(1.0))
    }

    /// [`super::PlannerRng::fill_uniform`]: whole vectors into `out`, then one more step into
    /// `buf` for the tail; returns how many of `buf` were used. The three slices have equal
    /// lengths.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn fill_uniform(
        s: &mut [[u64; LANES]; 4],
        buf: &mut [u64; LANES],
        lo: &[f64],
        hi: &[f64],
        out: &mut [f64],
    ) -> usize {
        let mut v = load(s);
        let n = out.len().min(lo.len()).min(hi.len());
        let mut k = 0;
        while k + LANES <= n {
            // SAFETY: k + LANES <= n, within all three slices. The same arithmetic as
            // `super::scale` (separate multiply and add, no fused rounding).
            let l = _mm256_loadu_pd(lo.as_ptr().add(k));
            let h = _mm256_loadu_pd(hi.as_ptr().add(k));
            let u = unit(step(&mut v));
            let x = _mm256_add_pd(l, _mm256_mul_pd(_mm256_sub_pd(h, l), u));
            _mm256_storeu_pd(out.as_mut_ptr().add(k), x);
            k += LANES;
        }
        let used = if k < n {
            let x = step(&mut v);
            _mm256_storeu_si256(buf.as_mut_ptr().cast(), x);
            for (j, &b) in buf.iter().enumerate().take(n - k) {
                out[k + j] = super::scale(lo[k + j], hi[k + j], super::unit(b));
            }
            n - k
        } else {
            LANES
        };
        store(&v, s);
        used
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
    /// Fills `out[i]` with a uniform value in [`lo[i]`, `hi[i]`) (52 random bits each; the
    /// three slices have equal lengths), a vector of [`LANES`] values per step, starting at a
    /// fresh step (draws still buffered are dropped).
    #[inline]
    pub fn fill_uniform(&mut self, lo: &[f64], hi: &[f64], out: &mut [f64]) {
        debug_assert!(lo.len() == out.len() && hi.len() == out.len());
        if out.is_empty() {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the CPU has AVX2 (checked at seeding).
            self.pos = unsafe { avx2::fill_uniform(&mut self.s, &mut self.buf, lo, hi, out) };
            return;
        }
        self.pos = LANES;
        for ((o, &l), &h) in out.iter_mut().zip(lo).zip(hi) {
            *o = scale(l, h, unit(self.next_u64()));
        }
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

    /// `fill_uniform` draws from a fresh step whatever the buffer position, one draw per value
    /// in stream order, and leaves the rest of its last step to `next_u64`; values stay in
    /// [lo, hi).
    #[test]
    fn fill_uniform_follows_the_stream() {
        for skip in 0..5 {
            for len in [0usize, 1, 3, 4, 7, 14, 33] {
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
                if len > 0 {
                    b.pos = LANES;
                }
                let want: Vec<f64> = (0..len)
                    .map(|i| scale(lo[i], hi[i], unit(b.next_u64())))
                    .collect();
                assert_eq!(got, want, "skip {skip}, len {len}");
                assert!(got
                    .iter()
                    .zip(&lo)
                    .zip(&hi)
                    .all(|((v, l), h)| l <= v && v < h));
                assert_eq!(a.next_u64(), b.next_u64());
            }
        }
        assert_eq!(unit(0), 0.0);
        assert_eq!(unit(u64::MAX), 1.0 - f64::EPSILON);
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
