//! The object surface as a point set with normals in a kd-tree (paper 003 §IV-A-2, Fig. 2).
//!
//! Points are drawn uniformly over the surface (a triangle with probability proportional to its
//! area, then a uniform point in it), from a seeded ChaCha8 generator. Parts of a mesh that lie
//! inside another part (a statuette joined from overlapping closed parts,
//! [`crate::geometry::Solid`]) are not surface: a point whose outward offset by 0.1 mm is inside
//! the solid (winding number > 1/2) is dropped. Each point carries the outward unit normal of its
//! triangle and a curvature estimate: the surface variation σ = λ₀ / (λ₀ + λ₁ + λ₂) of the
//! covariance of its nearest sample points (Pauly, Gross & Kobbelt 2002; 0 on a plane, 1/3 at
//! most), what 003's curvature score uses. The kd-tree is `kiddo`'s immutable tree.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::geometry::Solid;

/// Most surface points of one object.
pub const MAX_SURFACE_POINTS: usize = 200_000;

/// Neighbours used for the curvature estimate.
pub const CURVATURE_NEIGHBOURS: usize = 12;

/// A uniformly sampled surface (module docs).
#[derive(Debug, Clone)]
pub struct SurfaceSamples {
    pub points: Vec<Vector3<f64>>,
    /// Outward unit normals.
    pub normals: Vec<Vector3<f64>>,
    /// Surface variation at each point (0 flat … 1/3).
    pub curvature: Vec<f64>,
    /// Largest curvature of all points (the normaliser of 003's curvature score; > 0).
    pub max_curvature: f64,
    /// Total surface area of the triangles sampled (m², hidden parts included).
    pub area: f64,
    tree: ImmutableKdTree<f64, 3>,
}

impl SurfaceSamples {
    /// Samples the triangles (`vertices`, `triangles` in the object frame, outward oriented)
    /// with about one point per `spacing²` of area (at most [`MAX_SURFACE_POINTS`]), dropping
    /// points inside `solid` (module docs).
    pub fn new(
        vertices: &[Point3<f64>],
        triangles: &[[u32; 3]],
        solid: Option<&Solid>,
        spacing: f64,
        seed: u64,
    ) -> Result<SurfaceSamples, String> {
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(format!("surface spacing must be > 0, got {spacing}"));
        }
        let tri = |t: &[u32; 3]| -> Option<[Vector3<f64>; 3]> {
            let a = vertices.get(t[0] as usize)?.coords;
            let b = vertices.get(t[1] as usize)?.coords;
            let c = vertices.get(t[2] as usize)?.coords;
            Some([a, b, c])
        };
        let mut cum = Vec::with_capacity(triangles.len());
        let mut area = 0.0;
        for t in triangles {
            let a = tri(t).map_or(0.0, |[a, b, c]| (b - a).cross(&(c - a)).norm() / 2.0);
            area += a;
            cum.push(area);
        }
        if area.is_nan() || area <= 0.0 {
            return Err("the surface has no area".into());
        }
        let wanted = (area / (spacing * spacing)).ceil();
        if wanted > MAX_SURFACE_POINTS as f64 {
            return Err(format!(
                "a spacing of {spacing} m needs {wanted} surface points, at most {MAX_SURFACE_POINTS}"
            ));
        }
        let n = (wanted as usize).max(16);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut raw = Vec::with_capacity(n);
        for _ in 0..n {
            let r = rng.random::<f64>() * area;
            let i = cum.partition_point(|&c| c < r).min(triangles.len() - 1);
            let (u, v): (f64, f64) = (rng.random(), rng.random());
            let Some([a, b, c]) = tri(&triangles[i]) else {
                continue;
            };
            let su = u.sqrt();
            let p = a * (1.0 - su) + b * (su * (1.0 - v)) + c * (su * v);
            let nrm = (b - a).cross(&(c - a));
            if nrm.norm() > 0.0 {
                raw.push((p, nrm.normalize()));
            }
        }
        let kept: Vec<(Vector3<f64>, Vector3<f64>)> = match solid {
            Some(s) => raw
                .into_par_iter()
                .filter(|(p, n)| !s.contains(&(p + n * 1e-4)))
                .collect(),
            None => raw,
        };
        if kept.len() < 4 {
            return Err("fewer than 4 surface points are on the outer surface".into());
        }
        let points: Vec<Vector3<f64>> = kept.iter().map(|k| k.0).collect();
        let normals: Vec<Vector3<f64>> = kept.iter().map(|k| k.1).collect();
        let arr: Vec<[f64; 3]> = points.iter().map(|p| [p.x, p.y, p.z]).collect();
        let tree: ImmutableKdTree<f64, 3> = ImmutableKdTree::new_from_slice(&arr);
        let k = std::num::NonZero::new(CURVATURE_NEIGHBOURS.min(points.len())).unwrap_or(
            std::num::NonZero::<usize>::MIN, // points.len() ≥ 4 here
        );
        let curvature: Vec<f64> = arr
            .par_iter()
            .map(|q| {
                let nb = tree.nearest_n::<SquaredEuclidean>(q, k);
                let m = nb.len() as f64;
                let mean: Vector3<f64> = nb
                    .iter()
                    .map(|n| points[n.item as usize])
                    .sum::<Vector3<f64>>()
                    / m;
                let mut cov = Matrix3::zeros();
                for n in &nb {
                    let d = points[n.item as usize] - mean;
                    cov += d * d.transpose();
                }
                let ev = SymmetricEigen::new(cov).eigenvalues;
                let tr = ev.sum();
                if tr > 0.0 {
                    (ev.min() / tr).max(0.0)
                } else {
                    0.0
                }
            })
            .collect();
        let max_curvature = curvature.iter().copied().fold(0.0f64, f64::max).max(1e-12);
        Ok(SurfaceSamples {
            points,
            normals,
            curvature,
            max_curvature,
            area,
            tree,
        })
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Index of the point nearest `p`.
    pub fn nearest(&self, p: &Vector3<f64>) -> usize {
        self.tree
            .nearest_one::<SquaredEuclidean>(&[p.x, p.y, p.z])
            .item as usize
    }

    /// Indices of the points within `radius` of `centre`, nearest first.
    pub fn within(&self, centre: &Vector3<f64>, radius: f64) -> Vec<usize> {
        self.tree
            .within::<SquaredEuclidean>(&[centre.x, centre.y, centre.z], radius * radius)
            .into_iter()
            .map(|n| n.item as usize)
            .collect()
    }
}
