//! The sampling generator of the tree planners' inner loops: xoshiro256++ (Blackman & Vigna,
//! "Scrambled linear pseudorandom number generators", ACM TOMS 2021). A few adds, shifts and
//! rotates per 64-bit draw — RRT-Connect draws one per joint every iteration, and on
//! MotionBenchMaker's Baxter problems most of ~10⁵ iterations end after sampling and one
//! nearest-neighbour query, where ChaCha8 took a tenth of the time. Not for cryptography.
//! Seeded from a `u64` through SplitMix64 (the authors' recommendation), so equal seeds give
//! equal streams on every platform.

use rand::{RngCore, SeedableRng};

/// Independent xoshiro256++ generators stepped together (one AVX2 vector of 64-bit lanes).
const LANES: usize = 4;

/// xoshiro256++ (see the module documentation), [`LANES`] independent generators stepped
/// together so that one vector step yields [`LANES`] draws. The stream is lane 0's first
/// output, lane 1's first, …, lane 3's first, lane 0's second, and so on, however it is
/// consumed (`next_u64` or [`PlannerRng::fill_unit`]).
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

/// Fills `out` (a multiple of [`LANES`] long) with one vector step per [`LANES`] values.
#[inline(always)]
fn fill_blocks(s: &mut [[u64; LANES]; 4], out: &mut [f64]) {
    for chunk in out.chunks_exact_mut(LANES) {
        let v = step(s);
        for (o, &x) in chunk.iter_mut().zip(&v) {
            *o = unit(x);
        }
    }
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
    unsafe fn unit(x: __m256i) -> __m256d {
        let m = _mm256_or_si256(
            _mm256_srli_epi64::<12>(x),
            _mm256_set1_epi64x(0x3FF0_0000_0000_0000),
        );
        _mm256_sub_pd(_mm256_castsi256_pd(m), _mm256_set1_pd(1.0))
    }

    /// [`super::PlannerRng::fill_unit`] after the buffered values: whole vectors into `out`,
    /// then one more step into `buf` for the tail (`buf[..tail]` written to `out`'s end).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn fill_rest(
        s: &mut [[u64; LANES]; 4],
        buf: &mut [u64; LANES],
        out: &mut [f64],
    ) -> usize {
        let mut v = load(s);
        let mut chunks = out.chunks_exact_mut(LANES);
        for chunk in &mut chunks {
            _mm256_storeu_pd(chunk.as_mut_ptr(), unit(step(&mut v)));
        }
        let tail = chunks.into_remainder();
        let used = if tail.is_empty() {
            LANES
        } else {
            let x = step(&mut v);
            _mm256_storeu_si256(buf.as_mut_ptr().cast(), x);
            for (o, &b) in tail.iter_mut().zip(buf.iter()) {
                *o = super::unit(b);
            }
            tail.len()
        };
        store(&v, s);
        used
    }

    #[inline(always)]
    unsafe fn store(v: &[__m256i; 4], s: &mut [[u64; LANES]; 4]) {
        for k in 0..4 {
            _mm256_storeu_si256(s[k].as_mut_ptr().cast(), v[k]);
        }
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
    /// Fills `out` with uniform values in [0, 1) (52 random bits each), consuming one draw of
    /// the stream per value.
    #[inline]
    pub fn fill_unit(&mut self, out: &mut [f64]) {
        let mut rest = out;
        // Values still buffered from the last step come first.
        while self.pos < LANES {
            let Some((first, tail)) = rest.split_first_mut() else {
                return;
            };
            *first = unit(self.buf[self.pos]);
            self.pos += 1;
            rest = tail;
        }
        if rest.is_empty() {
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the CPU has AVX2 (checked at seeding).
            self.pos = unsafe { avx2::fill_rest(&mut self.s, &mut self.buf, rest) };
            return;
        }
        let whole = rest.len() - rest.len() % LANES;
        let (blocks, tail) = rest.split_at_mut(whole);
        fill_blocks(&mut self.s, blocks);
        for o in tail {
            *o = unit(self.next_u64());
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

    /// `fill_unit` consumes the same stream as `next_u64`, whatever the buffer position and
    /// length, and every value is in [0, 1).
    #[test]
    fn fill_unit_follows_the_stream() {
        for skip in 0..5 {
            for len in [0usize, 1, 3, 4, 7, 14, 33] {
                let mut a = PlannerRng::seed_from_u64(11);
                let mut b = PlannerRng::seed_from_u64(11);
                for _ in 0..skip {
                    a.next_u64();
                    b.next_u64();
                }
                let mut got = vec![0.0; len];
                a.fill_unit(&mut got);
                let want: Vec<f64> = (0..len).map(|_| unit(b.next_u64())).collect();
                assert_eq!(got, want, "skip {skip}, len {len}");
                assert!(got.iter().all(|v| (0.0..1.0).contains(v)));
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
