//! A deterministic, uniform grid of rotations: the HEALPix × S¹ grid of Yershova, Jain, LaValle
//! and Mitchell, "Generating uniform incremental grids on SO(3) using the Hopf fibration"
//! (IJRR 2010), which paper 003 (Saut et al. 2010) §IV-A-1 cites ([16]) for the grasp frames'
//! orientations.
//!
//! SO(3) is the Hopf bundle of circles S¹ over the sphere S²: a rotation is `(θ, φ)` on S²
//! (HEALPix pixel centres, equal-area cells, ring scheme) and `ψ` on S¹ (equally spaced). At
//! resolution level `l` the sphere has `12 · 4^l` pixels (N_side = 2^l) and the circle
//! `6 · 2^l` points, so the grid has `72 · 8^l` rotations (72, 576, 4 608, 36 864) and each
//! refinement splits every cell into eight. The rotation of `(θ, φ, ψ)` is the unit quaternion
//! `(w, x, y, z) = (cos(θ/2) cos(ψ/2), cos(θ/2) sin(ψ/2), sin(θ/2) cos(φ + ψ/2),
//! sin(θ/2) sin(φ + ψ/2))` (their eq. 4). This is the grid of one level (all its cells), not
//! the paper's incremental ordering across levels: a list is built at one resolution.

use std::f64::consts::PI;

use nalgebra::{Quaternion, UnitQuaternion};

/// Highest resolution level accepted (72 · 8⁴ = 294 912 rotations).
pub const MAX_SO3_LEVEL: u32 = 4;

/// Rotations in the grid of level `level`: `72 · 8^level`.
pub fn so3_grid_len(level: u32) -> usize {
    72usize << (3 * level)
}

/// The centre `(θ, φ)` of HEALPix pixel `ipix` (ring scheme, 0-based) for `nside`.
pub fn healpix_centre(nside: u64, ipix: u64) -> (f64, f64) {
    let ns = nside as f64;
    let npix = 12 * nside * nside;
    let ncap = 2 * nside * (nside - 1);
    let (z, phi) = if ipix < ncap {
        // North polar cap.
        let iring = (1 + isqrt(1 + 2 * ipix)) >> 1;
        let iphi = ipix + 1 - 2 * iring * (iring - 1);
        let r = iring as f64;
        (
            1.0 - r * r / (3.0 * ns * ns),
            (iphi as f64 - 0.5) * PI / (2.0 * r),
        )
    } else if ipix < npix - ncap {
        // Equatorial belt.
        let ip = ipix - ncap;
        let iring = ip / (4 * nside) + nside;
        let iphi = ip % (4 * nside) + 1;
        let fodd = if (iring + nside) & 1 == 1 { 1.0 } else { 0.5 };
        (
            (2.0 * ns - iring as f64) * 2.0 / (3.0 * ns),
            (iphi as f64 - fodd) * PI / (2.0 * ns),
        )
    } else {
        // South polar cap.
        let ip = npix - ipix;
        let iring = (1 + isqrt(2 * ip - 1)) >> 1;
        let iphi = 4 * iring + 1 - (ip - 2 * iring * (iring - 1));
        let r = iring as f64;
        (
            -1.0 + r * r / (3.0 * ns * ns),
            (iphi as f64 - 0.5) * PI / (2.0 * r),
        )
    };
    (z.clamp(-1.0, 1.0).acos(), phi)
}

fn isqrt(n: u64) -> u64 {
    let mut r = (n as f64).sqrt() as u64;
    while r * r > n {
        r -= 1;
    }
    while (r + 1) * (r + 1) <= n {
        r += 1;
    }
    r
}

/// The rotation of Hopf coordinates `(θ, φ, ψ)`.
pub fn hopf_rotation(theta: f64, phi: f64, psi: f64) -> UnitQuaternion<f64> {
    let (c, s) = ((theta / 2.0).cos(), (theta / 2.0).sin());
    UnitQuaternion::new_normalize(Quaternion::new(
        c * (psi / 2.0).cos(),
        c * (psi / 2.0).sin(),
        s * (phi + psi / 2.0).cos(),
        s * (phi + psi / 2.0).sin(),
    ))
}

/// Every rotation of the grid of level `level` (≤ [`MAX_SO3_LEVEL`], clamped), sphere pixel
/// major, circle point minor.
pub fn so3_grid(level: u32) -> Vec<UnitQuaternion<f64>> {
    let level = level.min(MAX_SO3_LEVEL);
    let nside = 1u64 << level;
    let npix = 12 * nside * nside;
    let ncircle = 6u64 << level;
    let mut out = Vec::with_capacity(so3_grid_len(level));
    for ipix in 0..npix {
        let (theta, phi) = healpix_centre(nside, ipix);
        for k in 0..ncircle {
            let psi = (k as f64 + 0.5) * 2.0 * PI / ncircle as f64;
            out.push(hopf_rotation(theta, phi, psi));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn healpix_pixels_cover_the_sphere_evenly() {
        for level in 0..3 {
            let nside = 1u64 << level;
            let n = 12 * nside * nside;
            let pts: Vec<_> = (0..n)
                .map(|i| {
                    let (t, p) = healpix_centre(nside, i);
                    nalgebra::Vector3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
                })
                .collect();
            // Centroid near 0 (symmetric), all distinct.
            let c: nalgebra::Vector3<f64> = pts.iter().sum::<nalgebra::Vector3<f64>>() / n as f64;
            assert!(c.norm() < 1e-9, "level {level}: centroid {c}");
            for i in 0..pts.len() {
                for j in 0..i {
                    assert!((pts[i] - pts[j]).norm() > 1e-6);
                }
            }
        }
    }

    #[test]
    fn the_grid_has_72_8l_distinct_rotations() {
        for level in 0..2 {
            let g = so3_grid(level);
            assert_eq!(g.len(), so3_grid_len(level));
            let mut min = f64::INFINITY;
            for i in 0..g.len() {
                for j in 0..i {
                    min = min.min(g[i].angle_to(&g[j]));
                }
            }
            // Distinct rotations, spread: level 0 cells are about 1 rad across.
            assert!(min > 0.2 / (1 << level) as f64, "level {level}: {min}");
        }
    }
}
