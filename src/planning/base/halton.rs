//! The Halton sequence (J. H. Halton, "On the efficiency of certain quasi-random sequences of
//! points in evaluating multi-dimensional integrals", Numer. Math. 1960): point k has, in
//! dimension d, the radical inverse of k in the d-th base — k's base-b digits mirrored behind
//! the point. A deterministic low-discrepancy sampler for the tree planners (Branicky, LaValle,
//! Olson & Yang, "Quasi-randomized path planning", ICRA 2001; VAMP's default sampler).
//!
//! The bases are the primes from 3 on, as VAMP's: with base 2 the first variable would
//! alternate between the halves of its range sample after sample. The first point is k = 1
//! (every value 1/b); [`Halton::skip`] starts later, as VAMP's `skip`.

use crate::planning::PlanError;

/// Most dimensions (one prime base each).
pub const MAX_DIMS: usize = 64;

/// Digits kept per dimension: enough for 2^64 points in base 3.
const DIGITS: usize = 41;

/// The first [`MAX_DIMS`] primes from 3 on.
fn bases(n: usize) -> Vec<u64> {
    let mut out = Vec::with_capacity(n);
    let mut p = 3u64;
    while out.len() < n {
        if (3..p)
            .step_by(2)
            .take_while(|d| d * d <= p)
            .all(|d| p % d != 0)
        {
            out.push(p);
        }
        p += 2;
    }
    out
}

/// One dimension: the base-b digits of the index (least significant first) and their
/// radical inverse.
#[derive(Debug, Clone)]
struct Digits {
    base: u64,
    /// `inv[j]` = b^−(j+1).
    inv: [f64; DIGITS],
    digits: [u8; DIGITS],
    /// `partial[j]` = the radical inverse of the digits from `j` up alone, summed from the most
    /// significant one (zero digits add exactly 0); the value is `partial[0]`. A carry
    /// through `c` digits recomputes `partial[..=c]` only.
    partial: [f64; DIGITS + 1],
}

impl Digits {
    fn new(base: u64) -> Digits {
        let mut inv = [0.0; DIGITS];
        let mut p = 1.0;
        for v in inv.iter_mut() {
            p /= base as f64;
            *v = p;
        }
        Digits {
            base,
            inv,
            digits: [0; DIGITS],
            partial: [0.0; DIGITS + 1],
        }
    }

    /// Sets the index to `k`.
    fn set(&mut self, mut k: u64) {
        self.digits = [0; DIGITS];
        self.partial = [0.0; DIGITS + 1];
        for d in self.digits.iter_mut() {
            *d = (k % self.base) as u8;
            k /= self.base;
        }
        self.recompute(DIGITS - 1);
    }

    /// Recomputes `partial[..=c]` from `partial[c + 1]` (the same sums, in the same order, as a
    /// fold over all digits from the most significant one).
    fn recompute(&mut self, c: usize) {
        for j in (0..=c.min(DIGITS - 1)).rev() {
            self.partial[j] = self.partial[j + 1] + self.digits[j] as f64 * self.inv[j];
        }
    }

    /// The radical inverse of the index.
    #[inline]
    fn value(&self) -> f64 {
        self.partial[0]
    }

    /// Adds 1 to the index.
    #[inline]
    fn increment(&mut self) {
        let top = (self.base - 1) as u8;
        let mut c = DIGITS - 1;
        for (j, d) in self.digits.iter_mut().enumerate() {
            if *d < top {
                *d += 1;
                c = j;
                break;
            }
            *d = 0;
        }
        self.recompute(c);
    }
}

/// The Halton sequence in `n` dimensions (see the module documentation).
#[derive(Debug, Clone)]
pub struct Halton {
    dims: Vec<Digits>,
}

impl Halton {
    /// The sequence in `n` dimensions (1 ≤ n ≤ [`MAX_DIMS`]), positioned before its first
    /// point (k = 1).
    pub fn new(n: usize) -> Result<Halton, PlanError> {
        if !(1..=MAX_DIMS).contains(&n) {
            return Err(PlanError::InvalidInput(format!(
                "sampler: the Halton sequence has 1 to {MAX_DIMS} dimensions, not {n}"
            )));
        }
        Ok(Halton {
            dims: bases(n).into_iter().map(Digits::new).collect(),
        })
    }

    /// Positions the sequence so that the next point is point `k + 1` (`skip(0)`: the first).
    pub fn skip(&mut self, k: u64) {
        for d in &mut self.dims {
            d.set(k);
        }
    }

    /// The bases, one per dimension.
    pub fn bases(&self) -> Vec<u64> {
        self.dims.iter().map(|d| d.base).collect()
    }

    /// The next point in [0, 1)^n.
    #[inline]
    pub fn next_unit(&mut self, out: &mut [f64]) {
        for (d, o) in self.dims.iter_mut().zip(out.iter_mut()) {
            d.increment();
            *o = d.value();
        }
    }

    /// The next point scaled into the box [`lo`, `hi`] (`lo + (hi − lo)·u` per dimension).
    #[inline]
    pub fn next_in(&mut self, lo: &[f64], hi: &[f64], out: &mut [f64]) {
        for (((d, o), &l), &h) in self.dims.iter_mut().zip(out.iter_mut()).zip(lo).zip(hi) {
            d.increment();
            *o = l + (h - l) * d.value();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The radical inverse of `k` in base `b`, digit by digit.
    fn radical_inverse(mut k: u64, b: u64) -> f64 {
        let (mut f, mut r) = (1.0, 0.0);
        let mut terms = Vec::new();
        while k > 0 {
            f /= b as f64;
            terms.push((k % b) as f64 * f);
            k /= b;
        }
        for t in terms.into_iter().rev() {
            r += t;
        }
        r
    }

    #[test]
    fn points_are_the_radical_inverses_in_the_odd_prime_bases() {
        let mut h = Halton::new(7).unwrap();
        assert_eq!(h.bases(), vec![3, 5, 7, 11, 13, 17, 19]);
        let mut p = [0.0; 7];
        h.next_unit(&mut p);
        let first: Vec<f64> = [3.0, 5.0, 7.0, 11.0, 13.0, 17.0, 19.0]
            .iter()
            .map(|b| 1.0 / b)
            .collect();
        assert_eq!(p.to_vec(), first);
        for k in 2..5000u64 {
            h.next_unit(&mut p);
            for (d, &b) in [3u64, 5, 7, 11, 13, 17, 19].iter().enumerate() {
                assert_eq!(p[d], radical_inverse(k, b), "point {k}, base {b}");
                assert!((0.0..1.0).contains(&p[d]));
            }
        }
    }

    #[test]
    fn skip_starts_later_and_agrees_with_stepping() {
        let mut a = Halton::new(14).unwrap();
        let mut b = Halton::new(14).unwrap();
        let (mut pa, mut pb) = ([0.0; 14], [0.0; 14]);
        for _ in 0..1234 {
            a.next_unit(&mut pa);
        }
        b.skip(1233);
        b.next_unit(&mut pb);
        assert_eq!(pa, pb);
        b.skip(0);
        b.next_unit(&mut pb);
        assert_eq!(pb[0], 1.0 / 3.0);
        assert_eq!(bases(16)[15], 59);
    }

    #[test]
    fn scaled_points_stay_in_the_box_and_dimensions_are_bounded() {
        let mut h = Halton::new(3).unwrap();
        let (lo, hi) = ([-1.0, 0.0, 2.0], [1.0, 0.5, 2.0]);
        let mut p = [0.0; 3];
        for _ in 0..10_000 {
            h.next_in(&lo, &hi, &mut p);
            for d in 0..3 {
                assert!(p[d] >= lo[d] && p[d] <= hi[d]);
            }
        }
        assert!(Halton::new(0).is_err());
        assert!(Halton::new(MAX_DIMS + 1).is_err());
        assert!(Halton::new(MAX_DIMS).is_ok());
    }
}
