//! The 8-lane tests of [`super::SphereChecker::body_env_avx`] and [`super::SphereChecker::pair_spheres_avx`] in
//! AVX2 + FMA intrinsics; each mirrors the generic function of the same name (`obs_mask`,
//! `near_mask`, `point_near_mask`, `lin4`).

use super::{Lane, Obs};
use std::arch::x86_64::*;

type V = __m256;

/// An obstacle with its parameters already broadcast to 8 lanes, so the tests of [`obs`] read
/// them as vector operands (no broadcast per test). Built once per checker; stored inline in
/// one array read by the hot loop (a box in another allocation would cost an indirection per
/// test), so the variants' sizes differ on purpose.
#[derive(Debug, Clone, Copy)]
#[allow(clippy::large_enum_variant)]
pub(super) enum ObsWide {
    Sphere {
        c: [Lane; 3],
        r: f32,
    },
    Box {
        c: [Lane; 3],
        rt: [[Lane; 3]; 3],
        half: [Lane; 3],
    },
    Cylinder {
        c: [Lane; 3],
        axis: [Lane; 3],
        r: Lane,
        h: Lane,
    },
    Capsule {
        c: [Lane; 3],
        axis: [Lane; 3],
        r: f32,
        h: Lane,
        neg_h: Lane,
    },
}

impl ObsWide {
    pub(super) fn of(o: &Obs) -> ObsWide {
        let w = |v: f32| [v; 8];
        let w3 = |v: &[f32; 3]| [w(v[0]), w(v[1]), w(v[2])];
        match o {
            Obs::Sphere { c, r } => ObsWide::Sphere { c: w3(c), r: *r },
            Obs::Box { c, rt, half } => ObsWide::Box {
                c: w3(c),
                rt: [w3(&rt[0]), w3(&rt[1]), w3(&rt[2])],
                half: w3(half),
            },
            Obs::Cylinder { c, axis, r, h } => ObsWide::Cylinder {
                c: w3(c),
                axis: w3(axis),
                r: w(*r),
                h: w(*h),
            },
            Obs::Capsule { c, axis, r, h } => ObsWide::Capsule {
                c: w3(c),
                axis: w3(axis),
                r: *r,
                h: w(*h),
                neg_h: w(-h),
            },
        }
    }
}

#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn load3(w: &[Lane; 3]) -> [V; 3] {
    // SAFETY: each lane array holds 8 f32 (unaligned loads).
    unsafe {
        [
            _mm256_loadu_ps(w[0].as_ptr()),
            _mm256_loadu_ps(w[1].as_ptr()),
            _mm256_loadu_ps(w[2].as_ptr()),
        ]
    }
}

#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn store3(w: &mut [Lane; 3], v: [V; 3]) {
    // SAFETY: each lane array holds 8 f32 (unaligned stores).
    unsafe {
        _mm256_storeu_ps(w[0].as_mut_ptr(), v[0]);
        _mm256_storeu_ps(w[1].as_mut_ptr(), v[1]);
        _mm256_storeu_ps(w[2].as_mut_ptr(), v[2]);
    }
}

#[inline]
#[target_feature(enable = "avx2,fma")]
fn load(l: &Lane) -> V {
    // SAFETY: 8 f32.
    unsafe { _mm256_loadu_ps(l.as_ptr()) }
}

/// World position of the point `p` of frame `f`, all lanes.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn place(f: &[Lane; 12], p: &[f32; 3]) -> [V; 3] {
    let (x, y, z) = (
        _mm256_set1_ps(p[0]),
        _mm256_set1_ps(p[1]),
        _mm256_set1_ps(p[2]),
    );
    let row = |r: usize| {
        _mm256_fmadd_ps(
            load(&f[6 + r]),
            z,
            _mm256_fmadd_ps(
                load(&f[3 + r]),
                y,
                _mm256_fmadd_ps(load(&f[r]), x, load(&f[9 + r])),
            ),
        )
    };
    [row(0), row(1), row(2)]
}

/// Lanes whose `d` is ≤ 0 (NaN: not set).
#[inline]
#[target_feature(enable = "avx2,fma")]
fn le_zero(d: V) -> u32 {
    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(d, _mm256_setzero_ps())) as u32
}

/// |d|² − r² per lane.
#[inline]
#[target_feature(enable = "avx2,fma")]
fn dist2_minus(dx: V, dy: V, dz: V, r2: f32) -> V {
    _mm256_fmadd_ps(
        dz,
        dz,
        _mm256_fmadd_ps(dy, dy, _mm256_fmsub_ps(dx, dx, _mm256_set1_ps(r2))),
    )
}

/// Lanes whose two points are at most `r` apart.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn near(a: [V; 3], b: [V; 3], r: f32) -> u32 {
    let d = dist2_minus(
        _mm256_sub_ps(a[0], b[0]),
        _mm256_sub_ps(a[1], b[1]),
        _mm256_sub_ps(a[2], b[2]),
        r * r,
    );
    le_zero(d)
}

/// Lanes whose point is at most `r` from the fixed point `p` (first three values).
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn point_near(a: [V; 3], p: &[f32; 4], r: f32) -> u32 {
    let d = dist2_minus(
        _mm256_sub_ps(a[0], _mm256_set1_ps(p[0])),
        _mm256_sub_ps(a[1], _mm256_set1_ps(p[1])),
        _mm256_sub_ps(a[2], _mm256_set1_ps(p[2])),
        r * r,
    );
    le_zero(d)
}

/// Lanes whose sphere (centre `p`, radius `r`) touches the obstacle (parameters pre-broadcast,
/// [`ObsWide`]; the operations of the generic `obs_mask`, fused).
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn obs(o: &ObsWide, p: [V; 3], r: f32) -> u32 {
    // The same operations as with a per-lane radius (`(r + ro)²`, `r²` per lane equal the
    // scalar ones), so the same masks.
    obs_r(o, p, _mm256_set1_ps(r))
}

/// Lanes whose sphere (centre `p`, radius `r` per lane) touches the obstacle ([`obs`] with one
/// radius; the chord certificate's balls, see `chord.rs`).
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn obs_r(o: &ObsWide, p: [V; 3], r: V) -> u32 {
    let zero = _mm256_setzero_ps();
    let abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff));
    let rel = |c: &[Lane; 3]| {
        [
            _mm256_sub_ps(p[0], load(&c[0])),
            _mm256_sub_ps(p[1], load(&c[1])),
            _mm256_sub_ps(p[2], load(&c[2])),
        ]
    };
    let dot = |a: &[Lane; 3], d: &[V; 3]| {
        _mm256_fmadd_ps(
            load(&a[2]),
            d[2],
            _mm256_fmadd_ps(load(&a[1]), d[1], _mm256_mul_ps(load(&a[0]), d[0])),
        )
    };
    let sq3 = |d: &[V; 3], rr: V| {
        _mm256_fmadd_ps(
            d[2],
            d[2],
            _mm256_fmadd_ps(
                d[1],
                d[1],
                _mm256_fmsub_ps(d[0], d[0], _mm256_mul_ps(rr, rr)),
            ),
        )
    };
    let d = match o {
        ObsWide::Sphere { c, r: ro } => sq3(&rel(c), _mm256_add_ps(r, _mm256_set1_ps(*ro))),
        ObsWide::Box { c, rt, half } => {
            let d = rel(c);
            let mut acc = _mm256_sub_ps(zero, _mm256_mul_ps(r, r));
            for k in 0..3 {
                let q = _mm256_and_ps(dot(&rt[k], &d), abs_mask);
                let e = _mm256_max_ps(_mm256_sub_ps(q, load(&half[k])), zero);
                acc = _mm256_fmadd_ps(e, e, acc);
            }
            acc
        }
        ObsWide::Cylinder { c, axis, r: rc, h } => {
            let d = rel(c);
            let pz = dot(axis, &d);
            let all = dist2_minus(d[0], d[1], d[2], 0.0);
            let rad2 = _mm256_max_ps(_mm256_fnmadd_ps(pz, pz, all), zero);
            let dr = _mm256_max_ps(_mm256_sub_ps(_mm256_sqrt_ps(rad2), load(rc)), zero);
            let ez = _mm256_max_ps(_mm256_sub_ps(_mm256_and_ps(pz, abs_mask), load(h)), zero);
            _mm256_fmadd_ps(dr, dr, _mm256_fmsub_ps(ez, ez, _mm256_mul_ps(r, r)))
        }
        ObsWide::Capsule {
            c,
            axis,
            r: rc,
            h,
            neg_h,
        } => {
            let d = rel(c);
            let pz = dot(axis, &d);
            let t = _mm256_min_ps(_mm256_max_ps(pz, load(neg_h)), load(h));
            let e = [
                _mm256_fnmadd_ps(t, load(&axis[0]), d[0]),
                _mm256_fnmadd_ps(t, load(&axis[1]), d[1]),
                _mm256_fnmadd_ps(t, load(&axis[2]), d[2]),
            ];
            sq3(&e, _mm256_add_ps(r, _mm256_set1_ps(*rc)))
        }
    };
    le_zero(d)
}

/// Chord midpoints and half lengths of 8 lanes of points: `((p + p⁺) / 2, |p⁺ − p| / 2)`, `p⁺`
/// the next lane's point (the last lane's own).
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn chords(p: [V; 3]) -> ([V; 3], V) {
    let idx = _mm256_setr_epi32(1, 2, 3, 4, 5, 6, 7, 7);
    let half = _mm256_set1_ps(0.5);
    let n = [
        _mm256_permutevar8x32_ps(p[0], idx),
        _mm256_permutevar8x32_ps(p[1], idx),
        _mm256_permutevar8x32_ps(p[2], idx),
    ];
    let mid = [
        _mm256_mul_ps(_mm256_add_ps(p[0], n[0]), half),
        _mm256_mul_ps(_mm256_add_ps(p[1], n[1]), half),
        _mm256_mul_ps(_mm256_add_ps(p[2], n[2]), half),
    ];
    let d = [
        _mm256_sub_ps(n[0], p[0]),
        _mm256_sub_ps(n[1], p[1]),
        _mm256_sub_ps(n[2], p[2]),
    ];
    let len = _mm256_sqrt_ps(dist2_minus(d[0], d[1], d[2], 0.0));
    (mid, _mm256_mul_ps(len, half))
}

/// Lanes whose point `a` lies within `r` (per lane) of point `b`.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn within(a: [V; 3], b: [V; 3], r: V) -> u32 {
    let d = [
        _mm256_sub_ps(a[0], b[0]),
        _mm256_sub_ps(a[1], b[1]),
        _mm256_sub_ps(a[2], b[2]),
    ];
    let rr = _mm256_mul_ps(r, r);
    le_zero(_mm256_sub_ps(dist2_minus(d[0], d[1], d[2], 0.0), rr))
}

/// Lanes whose point lies within `r` (per lane) of the origin.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn within_origin(a: [V; 3], r: V) -> u32 {
    le_zero(_mm256_sub_ps(
        dist2_minus(a[0], a[1], a[2], 0.0),
        _mm256_mul_ps(r, r),
    ))
}

/// Lanes `l` whose chord from `d` (lane `l`) to `d⁺` (lane `l + 1`) comes within `r` of the
/// origin: the segment's point nearest the origin, `d + s e` with `e = d⁺ − d` and
/// `s = clamp(−d·e / e·e, 0, 1)` (0 for a chord of length 0), tested against `r`.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn chord_within_origin(d: [V; 3], r: f32) -> u32 {
    let idx = _mm256_setr_epi32(1, 2, 3, 4, 5, 6, 7, 7);
    let e = [
        _mm256_sub_ps(_mm256_permutevar8x32_ps(d[0], idx), d[0]),
        _mm256_sub_ps(_mm256_permutevar8x32_ps(d[1], idx), d[1]),
        _mm256_sub_ps(_mm256_permutevar8x32_ps(d[2], idx), d[2]),
    ];
    let ee = _mm256_fmadd_ps(
        e[2],
        e[2],
        _mm256_fmadd_ps(e[1], e[1], _mm256_mul_ps(e[0], e[0])),
    );
    let de = _mm256_fmadd_ps(
        d[2],
        e[2],
        _mm256_fmadd_ps(d[1], e[1], _mm256_mul_ps(d[0], e[0])),
    );
    // −d·e / e·e, NaN for 0 / 0: `max` returns its second operand (0) then.
    let x = _mm256_div_ps(_mm256_sub_ps(_mm256_setzero_ps(), de), ee);
    let s = _mm256_min_ps(_mm256_max_ps(x, _mm256_setzero_ps()), _mm256_set1_ps(1.0));
    let c = [
        _mm256_fmadd_ps(s, e[0], d[0]),
        _mm256_fmadd_ps(s, e[1], d[1]),
        _mm256_fmadd_ps(s, e[2], d[2]),
    ];
    le_zero(dist2_minus(c[0], c[1], c[2], r * r))
}

/// `a − b` per lane.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn sub3(a: [V; 3], b: [V; 3]) -> [V; 3] {
    [
        _mm256_sub_ps(a[0], b[0]),
        _mm256_sub_ps(a[1], b[1]),
        _mm256_sub_ps(a[2], b[2]),
    ]
}

/// `v + s` per lane.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn add_s(v: V, s: f32) -> V {
    _mm256_add_ps(v, _mm256_set1_ps(s))
}

/// The broadcast point `p`.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn splat3(p: [f32; 3]) -> [V; 3] {
    [
        _mm256_set1_ps(p[0]),
        _mm256_set1_ps(p[1]),
        _mm256_set1_ps(p[2]),
    ]
}

/// One lane array as a register.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn load1(l: &Lane) -> V {
    load(l)
}

/// A register into one lane array.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn store1(l: &mut Lane, v: V) {
    // SAFETY: 8 f32.
    unsafe { _mm256_storeu_ps(l.as_mut_ptr(), v) }
}
