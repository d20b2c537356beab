//! The sphere checker's kinematics: the reduced kinematic tree (fixed joints folded into the
//! next movable one; joint origins classified so that identity and quarter-turn rotations and
//! zero translation terms cost nothing, as VAMP's generated code compiles them away), one
//! frame per node for all lanes, and the placement of points and of a body's spheres in them.

// Lane code indexes several arrays with one lane/row index; iterators would hide that.
#![allow(clippy::needless_range_loop)]

use nalgebra::{Matrix3, Vector3};

use super::lanes::*;
use super::{f3, Lane, SphereChecker, LANES};

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Axis {
    X,
    Y,
    Z,
    General,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum StepKind {
    /// The root link of a robot: its frame is the fixed `origin` (the robot's base).
    Root,
    Revolute(Axis),
    Prismatic,
}

/// One node of the reduced kinematic tree: the frame after a movable joint (or a root).
#[derive(Debug, Clone)]
pub(super) struct Step {
    pub(super) kind: StepKind,
    pub(super) parent: u32,
    /// Joint origin in the parent node's frame: rotation column-major, then translation.
    pub(super) rot: [f32; 9],
    /// The shape of `rot`, so that its zero terms cost nothing (VAMP compiles them away).
    pub(super) rot_kind: OriginRot,
    pub(super) t: [f32; 3],
    /// Bit k: `t[k]` is not zero (zero terms of the translation are skipped).
    pub(super) t_terms: u8,
    pub(super) axis: [f32; 3],
    pub(super) var: u32,
    pub(super) mul: f32,
    pub(super) off: f32,
    /// Largest |translation| of a prismatic joint over its limits (0 for revolute joints).
    pub(super) travel: f64,
    /// Range of the bodies riding on this node.
    pub(super) bodies: (u32, u32),
}

/// The shape of a joint origin's rotation. URDF origins are mostly identities or quarter turns
/// (`rpy` of ±π/2), whose products with the parent frame need no arithmetic.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum OriginRot {
    Identity,
    /// Column c is `±e_k`: `(k, sign bit)` per column (sign bit 0 for +, `0x8000_0000` for −).
    Permutation([(u8, u32); 3]),
    General,
}

/// Entries within this of 0 or ±1 in a joint origin are taken as exactly 0 or ±1 (the f32
/// model's rounding, [`SphereChecker::ROUNDING_MARGIN`], is orders of magnitude larger).
pub(super) const ORIGIN_SNAP: f64 = 1e-9;

impl OriginRot {
    pub(super) fn classify(m: &Matrix3<f64>) -> OriginRot {
        if (m - Matrix3::identity()).abs().max() < ORIGIN_SNAP {
            return OriginRot::Identity;
        }
        let mut cols = [(0u8, 0u32); 3];
        for (c, col) in cols.iter_mut().enumerate() {
            let Some(k) = (0..3).find(|&k| m[(k, c)].abs() > 0.5) else {
                return OriginRot::General;
            };
            let unit = (m[(k, c)].abs() - 1.0).abs() < ORIGIN_SNAP
                && (0..3).all(|r| r == k || m[(r, c)].abs() < ORIGIN_SNAP);
            if !unit {
                return OriginRot::General;
            }
            *col = (k as u8, if m[(k, c)] < 0.0 { 0x8000_0000 } else { 0 });
        }
        OriginRot::Permutation(cols)
    }
}

/// A joint origin's translation as f32 with its zero terms (within [`ORIGIN_SNAP`]) set to 0
/// and marked absent.
pub(super) fn origin_terms(t: &Vector3<f64>) -> ([f32; 3], u8) {
    let mut v = f3(t);
    let mut mask = 0u8;
    for k in 0..3 {
        if t[k].abs() < ORIGIN_SNAP {
            v[k] = 0.0;
        } else {
            mask |= 1 << k;
        }
    }
    (v, mask)
}

impl SphereChecker {
    #[inline(always)]
    pub(super) fn step<const N: usize, const AVX: bool>(&mut self, si: usize) {
        #[cfg(target_arch = "x86_64")]
        if AVX && N == LANES {
            // SAFETY: `AVX` is true only inside the AVX2 + FMA callers (checked at
            // construction), and the lanes are all LANES wide.
            unsafe { self.step_avx(si) };
            return;
        }
        self.step_lanes::<N, AVX>(si);
    }

    /// [`Self::step`] for 8 lanes in AVX2 + FMA registers, for the revolute joints about a
    /// coordinate axis (every joint of the MotionBenchMaker robots); other steps go to the
    /// generic [`Self::step_lanes`]. The same operations in the same order as the generic code
    /// compiled with FMA, so the same frames bit for bit, but the parent frame is read once
    /// and the child's is written once: the generic version copies its 9 × 8-lane rotation
    /// through the stack for the quarter-turn origins and the runtime axis (measured,
    /// callgrind, Panda cage: about 300 instructions per step, most of them those copies).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    pub(super) fn step_avx(&mut self, si: usize) {
        use std::arch::x86_64::*;
        type V = __m256;
        let s = &self.steps[si];
        let ax = match s.kind {
            StepKind::Revolute(ax) if ax != Axis::General => ax,
            // A root's frame is constant, written at construction (`init_roots`).
            StepKind::Root => return,
            _ => return self.step_lanes::<LANES, true>(si),
        };
        let (pi, ci) = (s.parent as usize, si);
        let (lo, hi) = self.frames.split_at_mut(ci);
        let p = &lo[pi];
        // SAFETY (loads, stores): each lane array holds 8 f32 (unaligned).
        let ld = |k: usize| unsafe { _mm256_loadu_ps(p[k].as_ptr()) };
        // t = P.rot · o.t + P.t without the origin's zero terms, in the order of the generic
        // code; one branch-free body per set of terms.
        #[inline(always)]
        fn moved<const M: u8>(p: &[Lane; 12], t: &[f32; 3]) -> [V; 3] {
            // SAFETY: 8 f32 per lane array; the caller runs with AVX2 + FMA.
            unsafe {
                let ld = |k: usize| _mm256_loadu_ps(p[k].as_ptr());
                std::array::from_fn(|r| {
                    let mut o = ld(9 + r);
                    for k in 0..3 {
                        if M & (1 << k) != 0 {
                            o = _mm256_fmadd_ps(ld(k * 3 + r), _mm256_set1_ps(t[k]), o);
                        }
                    }
                    o
                })
            }
        }
        let t = match s.t_terms & 0b111 {
            0 => moved::<0>(p, &s.t),
            1 => moved::<1>(p, &s.t),
            2 => moved::<2>(p, &s.t),
            3 => moved::<3>(p, &s.t),
            4 => moved::<4>(p, &s.t),
            5 => moved::<5>(p, &s.t),
            6 => moved::<6>(p, &s.t),
            _ => moved::<7>(p, &s.t),
        };
        let mut m: [V; 9] = match s.rot_kind {
            OriginRot::Identity => std::array::from_fn(ld),
            OriginRot::Permutation(cols) => std::array::from_fn(|e| {
                let (c, r) = (e / 3, e % 3);
                let (k, sign) = cols[c];
                let v = ld(usize::from(k).min(2) * 3 + r);
                _mm256_xor_ps(v, _mm256_castsi256_ps(_mm256_set1_epi32(sign as i32)))
            }),
            OriginRot::General => std::array::from_fn(|e| {
                let (c, r) = (e / 3, e % 3);
                let o = [s.rot[c * 3], s.rot[c * 3 + 1], s.rot[c * 3 + 2]];
                _mm256_fmadd_ps(
                    ld(6 + r),
                    _mm256_set1_ps(o[2]),
                    _mm256_fmadd_ps(
                        ld(3 + r),
                        _mm256_set1_ps(o[1]),
                        _mm256_mul_ps(ld(r), _mm256_set1_ps(o[0])),
                    ),
                )
            }),
        };
        // SAFETY: 8 f32.
        let q = unsafe { _mm256_loadu_ps(self.qv[s.var as usize].as_ptr()) };
        let v = _mm256_add_ps(
            _mm256_mul_ps(_mm256_set1_ps(s.mul), q),
            _mm256_set1_ps(s.off),
        );
        let mut va = [0.0f32; LANES];
        // SAFETY: 8 f32.
        unsafe { _mm256_storeu_ps(va.as_mut_ptr(), v) };
        let (sn, cs) = sincos_lanes::<LANES, true>(&va);
        // SAFETY: 8 f32 each.
        let (sn, cs) = unsafe { (_mm256_loadu_ps(sn.as_ptr()), _mm256_loadu_ps(cs.as_ptr())) };
        // Rotation about the third axis of the pair: i' = i c + j s, j' = j c − i s.
        #[inline(always)]
        fn turn<const I: usize, const J: usize>(m: &mut [V; 9], cs: V, sn: V) {
            for r in 0..3 {
                let (a, b) = (m[I + r], m[J + r]);
                // SAFETY: the caller runs with AVX2 + FMA.
                unsafe {
                    m[I + r] = _mm256_fmadd_ps(a, cs, _mm256_mul_ps(b, sn));
                    m[J + r] = _mm256_fmsub_ps(b, cs, _mm256_mul_ps(a, sn));
                }
            }
        }
        match ax {
            Axis::Z => turn::<0, 3>(&mut m, cs, sn),
            Axis::X => turn::<3, 6>(&mut m, cs, sn),
            _ => turn::<6, 0>(&mut m, cs, sn),
        }
        let f = &mut hi[0];
        for (k, v) in m.iter().chain(&t).enumerate() {
            // SAFETY: 8 f32.
            unsafe { _mm256_storeu_ps(f[k].as_mut_ptr(), *v) };
        }
    }

    /// Writes the (constant) frames of the robots' roots in every lane: [`Self::step_avx`]
    /// does not recompute them.
    pub(super) fn init_roots(&mut self) {
        for si in 0..self.steps.len() {
            if self.steps[si].kind == StepKind::Root {
                self.step_lanes::<LANES, false>(si);
            }
        }
    }

    /// [`Self::step`] over `[f32; N]` lanes (the reference; see [`Self::step_avx`]).
    #[inline(always)]
    pub(super) fn step_lanes<const N: usize, const AVX: bool>(&mut self, si: usize) {
        let s = &self.steps[si];
        if s.kind == StepKind::Root {
            let f = &mut self.frames[si];
            for k in 0..9 {
                f[k] = [s.rot[k]; LANES];
            }
            for k in 0..3 {
                f[9 + k] = [s.t[k]; LANES];
            }
            return;
        }
        let (pi, ci) = (s.parent as usize, si);
        let (lo, hi) = self.frames.split_at_mut(ci);
        let p = &lo[pi];
        let f = &mut hi[0];
        // t = P.rot · o.t + P.t ; m = P.rot · o.rot (columns x, y, z at 0, 3, 6).
        let mut m = [[0.0f32; N]; 9];
        let mut t = [[0.0f32; N]; 3];
        for r in 0..3 {
            t[r] = if s.t_terms == 0b111 {
                lin4::<N, AVX>(&p[r], &p[3 + r], &p[6 + r], &p[9 + r], s.t)
            } else {
                // The same sum in the same order without its zero terms.
                let mut o = [0.0f32; N];
                o.copy_from_slice(&p[9 + r][..N]);
                for k in 0..3 {
                    if s.t_terms & (1 << k) != 0 {
                        for l in 0..N {
                            o[l] = fmadd::<AVX>(p[k * 3 + r][l], s.t[k], o[l]);
                        }
                    }
                }
                o
            };
        }
        match s.rot_kind {
            OriginRot::Identity => {
                for k in 0..9 {
                    m[k].copy_from_slice(&p[k][..N]);
                }
            }
            OriginRot::Permutation(cols) => {
                for c in 0..3 {
                    let (k, sign) = cols[c];
                    let k = usize::from(k).min(2); // (no bounds checks below)
                    for r in 0..3 {
                        m[c * 3 + r] = signed::<N>(&p[k * 3 + r], sign);
                    }
                }
            }
            OriginRot::General => {
                for c in 0..3 {
                    let o = [s.rot[c * 3], s.rot[c * 3 + 1], s.rot[c * 3 + 2]];
                    for r in 0..3 {
                        m[c * 3 + r] = lin3::<N, AVX>(&p[r], &p[3 + r], &p[6 + r], o);
                    }
                }
            }
        }
        let q = &self.qv[s.var as usize];
        let mut v = [0.0f32; N];
        for l in 0..N {
            v[l] = s.mul * q[l] + s.off;
        }
        match s.kind {
            StepKind::Root => unreachable!(),
            StepKind::Prismatic => {
                for r in 0..3 {
                    let a = s.axis;
                    for l in 0..N {
                        let d = m[r][l] * a[0] + m[3 + r][l] * a[1] + m[6 + r][l] * a[2];
                        t[r][l] += d * v[l];
                    }
                }
            }
            StepKind::Revolute(ax) => {
                let (sn, cs) = sincos_lanes::<N, AVX>(&v);
                let (i, j) = match ax {
                    Axis::Z => (0, 3),
                    Axis::X => (3, 6),
                    Axis::Y => (6, 0),
                    Axis::General => (usize::MAX, 0),
                };
                if i != usize::MAX {
                    // Rotation about the third axis of the pair: i' = i c + j s, j' = j c − i s.
                    for r in 0..3 {
                        let (a, b) = (m[i + r], m[j + r]);
                        for l in 0..N {
                            m[i + r][l] = fmadd::<AVX>(a[l], cs[l], b[l] * sn[l]);
                            m[j + r][l] = fmadd::<AVX>(b[l], cs[l], -(a[l] * sn[l]));
                        }
                    }
                } else {
                    let (ux, uy, uz) = (s.axis[0], s.axis[1], s.axis[2]);
                    // Rodrigues, column-major, per lane.
                    let mut rm = [[0.0f32; N]; 9];
                    for l in 0..N {
                        let (sv, cv) = (sn[l], cs[l]);
                        let cc = 1.0 - cv;
                        rm[0][l] = cv + ux * ux * cc;
                        rm[1][l] = uy * ux * cc + uz * sv;
                        rm[2][l] = uz * ux * cc - uy * sv;
                        rm[3][l] = ux * uy * cc - uz * sv;
                        rm[4][l] = cv + uy * uy * cc;
                        rm[5][l] = uz * uy * cc + ux * sv;
                        rm[6][l] = ux * uz * cc + uy * sv;
                        rm[7][l] = uy * uz * cc - ux * sv;
                        rm[8][l] = cv + uz * uz * cc;
                    }
                    let mut o = [[0.0f32; N]; 9];
                    for c in 0..3 {
                        for r in 0..3 {
                            for l in 0..N {
                                o[c * 3 + r][l] = m[r][l] * rm[c * 3][l]
                                    + m[3 + r][l] * rm[c * 3 + 1][l]
                                    + m[6 + r][l] * rm[c * 3 + 2][l];
                            }
                        }
                    }
                    m = o;
                }
            }
        }
        for k in 0..9 {
            f[k][..N].copy_from_slice(&m[k]);
        }
        for k in 0..3 {
            f[9 + k][..N].copy_from_slice(&t[k]);
        }
    }

    /// World position of a point of a node frame, all lanes.
    #[inline(always)]
    pub(super) fn place<const N: usize, const AVX: bool>(
        f: &[Lane; 12],
        p: &[f32; 3],
    ) -> [[f32; N]; 3] {
        [
            lin4::<N, AVX>(&f[0], &f[3], &f[6], &f[9], *p),
            lin4::<N, AVX>(&f[1], &f[4], &f[7], &f[10], *p),
            lin4::<N, AVX>(&f[2], &f[5], &f[8], &f[11], *p),
        ]
    }
    #[inline(always)]
    pub(super) fn ensure_spheres<const N: usize, const AVX: bool>(&mut self, b: usize) {
        if self.sw_epoch[b] == self.epoch {
            return;
        }
        self.sw_epoch[b] = self.epoch;
        let body = &self.bodies[b];
        let f = &self.frames[body.node as usize];
        for si in body.spheres.0 as usize..body.spheres.1 as usize {
            let s = self.spheres[si];
            let w = Self::place::<N, AVX>(f, &[s[0], s[1], s[2]]);
            for r in 0..3 {
                self.sw[si][r][..N].copy_from_slice(&w[r]);
            }
        }
    }
}
