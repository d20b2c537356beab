//! The generic lane arithmetic of the sphere checker: fused or plain multiply-adds, the
//! frame products, the masks of the sphere tests and the f32 sine/cosine, written over
//! `[f32; N]` so that the compiler vectorises them (the reference that the AVX2 kernels of
//! `avx8` mirror).

#![allow(clippy::needless_range_loop)]

use super::{Lane, Obs};

/// `a·b + c`: one fused multiply-add when `AVX` (the caller runs compiled with FMA, see
/// [`SphereChecker::run8_avx2`]), else a product and a sum (a software `mul_add` would be slow).
#[inline(always)]
pub(super) fn fmadd<const AVX: bool>(a: f32, b: f32, c: f32) -> f32 {
    if AVX {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// `a·s0 + b·s1 + c·s2` per lane.
#[inline(always)]
pub(super) fn lin3<const N: usize, const AVX: bool>(
    a: &Lane,
    b: &Lane,
    c: &Lane,
    s: [f32; 3],
) -> [f32; N] {
    let mut o = [0.0f32; N];
    for l in 0..N {
        o[l] = fmadd::<AVX>(c[l], s[2], fmadd::<AVX>(b[l], s[1], a[l] * s[0]));
    }
    o
}

/// `a` with its sign bits flipped by `sign` per lane (negated when `sign` is `0x8000_0000`).
/// A bit operation, so the kinematic chain's latency does not grow.
#[inline(always)]
pub(super) fn signed<const N: usize>(a: &Lane, sign: u32) -> [f32; N] {
    let mut o = [0.0f32; N];
    for l in 0..N {
        o[l] = f32::from_bits(a[l].to_bits() ^ sign);
    }
    o
}

/// `a·s0 + b·s1 + c·s2 + d` per lane.
#[inline(always)]
pub(super) fn lin4<const N: usize, const AVX: bool>(
    a: &Lane,
    b: &Lane,
    c: &Lane,
    d: &Lane,
    s: [f32; 3],
) -> [f32; N] {
    let mut o = [0.0f32; N];
    for l in 0..N {
        o[l] = fmadd::<AVX>(
            c[l],
            s[2],
            fmadd::<AVX>(b[l], s[1], fmadd::<AVX>(a[l], s[0], d[l])),
        );
    }
    o
}

/// Lanes (bit l) whose value is ≤ 0 (NaN: not set). The generic (reference) path; the AVX2
/// path tests in `avx8`.
#[inline(always)]
pub(super) fn le_zero_mask<const N: usize>(v: &[f32; N]) -> u32 {
    let mut m = 0u32;
    for l in 0..N {
        m |= u32::from(v[l] <= 0.0) << l;
    }
    m
}

/// Lanes (bit l) whose distance between the two points is at most `r`.
#[inline(always)]
pub(super) fn near_mask<const N: usize>(a: &[Lane; 3], b: &[Lane; 3], r: f32) -> u32 {
    let r2 = r * r;
    let mut d = [0.0f32; N];
    for l in 0..N {
        let dx = a[0][l] - b[0][l];
        let dy = a[1][l] - b[1][l];
        let dz = a[2][l] - b[2][l];
        d[l] = dx * dx + dy * dy + dz * dz - r2;
    }
    le_zero_mask::<N>(&d)
}

/// Lanes (bit l) whose point is at most `r` from the fixed point `p`.
#[inline(always)]
pub(super) fn point_near_mask<const N: usize>(a: &[[f32; N]; 3], p: [f32; 3], r: f32) -> u32 {
    let r2 = r * r;
    let mut d = [0.0f32; N];
    for l in 0..N {
        let dx = a[0][l] - p[0];
        let dy = a[1][l] - p[1];
        let dz = a[2][l] - p[2];
        d[l] = dx * dx + dy * dy + dz * dz - r2;
    }
    le_zero_mask::<N>(&d)
}

/// Lanes (bit l) whose sphere (x, y, z, r) touches the obstacle.
#[inline(always)]
pub(super) fn obs_mask<const N: usize>(
    o: &Obs,
    x: &[f32; N],
    y: &[f32; N],
    z: &[f32; N],
    r: f32,
) -> u32 {
    obs_radii_mask::<N>(o, x, y, z, &[r; N])
}

/// `(sin x, cos x)` of every lane in f32 (Cephes' sinf/cosf kernels after a three-constant
/// reduction by π/2); absolute error ≈ 1e-7 for |x| ≤ 100, branch-free so lanes vectorise.
#[inline(always)]
pub(super) fn sincos_lanes<const N: usize, const AVX: bool>(v: &[f32; N]) -> ([f32; N], [f32; N]) {
    const MAGIC: f32 = 12_582_912.0;
    const DP1: f32 = 1.570_312_5;
    const DP2: f32 = 4.837_513e-4;
    const DP3: f32 = 7.549_79e-8;
    let mut sn = [0.0f32; N];
    let mut cs = [0.0f32; N];
    for l in 0..N {
        // NaN-free and bounded, so the integer conversion below is exact.
        #[allow(clippy::manual_clamp)] // max/min map NaN to a bound; clamp would keep NaN
        let x = v[l].max(-1.0e5).min(1.0e5);
        let k = fmadd::<AVX>(x, std::f32::consts::FRAC_2_PI, MAGIC) - MAGIC;
        let r = fmadd::<AVX>(-k, DP3, fmadd::<AVX>(-k, DP2, fmadd::<AVX>(-k, DP1, x)));
        let z = r * r;
        let ps = fmadd::<AVX>(
            fmadd::<AVX>(z, -1.951_529_6e-4, 8.332_161e-3),
            z,
            -1.666_665_5e-1,
        );
        let s = fmadd::<AVX>(r * z, ps, r);
        let pc = fmadd::<AVX>(
            fmadd::<AVX>(z, 2.443_315_7e-5, -1.388_731_6e-3),
            z,
            4.166_664_6e-2,
        );
        let c = fmadd::<AVX>(z * z, pc, fmadd::<AVX>(-0.5, z, 1.0));
        // SAFETY: |k| ≤ 1e5 · 2/π + 1 fits an i32.
        let q: i32 = unsafe { k.to_int_unchecked() };
        let swap = q & 1 != 0;
        let (s1, c1) = (if swap { c } else { s }, if swap { s } else { c });
        sn[l] = if q & 2 != 0 { -s1 } else { s1 };
        cs[l] = if (q + 1) & 2 != 0 { -c1 } else { c1 };
    }
    (sn, cs)
}

/// [`obs_mask`] for the chord certificate's lane triples with a radius per lane.
#[inline(always)]
pub(super) fn obs_lanes_mask(o: &Obs, p: &[Lane; 3], r: &Lane) -> u32 {
    obs_radii_mask::<{ super::LANES }>(o, &p[0], &p[1], &p[2], r)
}

/// Lanes (bit l) whose sphere (x, y, z, radius `r[l]`) touches the obstacle: closed-form
/// sphere–primitive tests.
#[inline(always)]
fn obs_radii_mask<const N: usize>(
    o: &Obs,
    x: &[f32; N],
    y: &[f32; N],
    z: &[f32; N],
    r: &[f32; N],
) -> u32 {
    let mut d = [0.0f32; N];
    match *o {
        Obs::Sphere { c, r: ro } => {
            for l in 0..N {
                let dx = x[l] - c[0];
                let dy = y[l] - c[1];
                let dz = z[l] - c[2];
                let rr = r[l] + ro;
                d[l] = dx * dx + dy * dy + dz * dz - rr * rr;
            }
        }
        Obs::Box { c, rt, half } => {
            for l in 0..N {
                let dx = x[l] - c[0];
                let dy = y[l] - c[1];
                let dz = z[l] - c[2];
                let mut d2 = 0.0f32;
                for k in 0..3 {
                    let p = rt[k][0] * dx + rt[k][1] * dy + rt[k][2] * dz;
                    let e = (p.abs() - half[k]).max(0.0);
                    d2 += e * e;
                }
                d[l] = d2 - r[l] * r[l];
            }
        }
        Obs::Cylinder { c, axis, r: rc, h } => {
            for l in 0..N {
                let dx = x[l] - c[0];
                let dy = y[l] - c[1];
                let dz = z[l] - c[2];
                let pz = axis[0] * dx + axis[1] * dy + axis[2] * dz;
                let rad2 = (dx * dx + dy * dy + dz * dz - pz * pz).max(0.0);
                let dr = (rad2.sqrt() - rc).max(0.0);
                let ez = (pz.abs() - h).max(0.0);
                d[l] = dr * dr + ez * ez - r[l] * r[l];
            }
        }
        Obs::Capsule { c, axis, r: rc, h } => {
            for l in 0..N {
                let dx = x[l] - c[0];
                let dy = y[l] - c[1];
                let dz = z[l] - c[2];
                let pz = axis[0] * dx + axis[1] * dy + axis[2] * dz;
                let t = pz.clamp(-h, h);
                let ex = dx - t * axis[0];
                let ey = dy - t * axis[1];
                let ez = dz - t * axis[2];
                let rr = r[l] + rc;
                d[l] = ex * ex + ey * ey + ez * ez - rr * rr;
            }
        }
    }
    le_zero_mask::<N>(&d)
}
