//! A finger's workspace approximated by spheres: paper 003 (Saut et al. 2010) §IV-A-2,
//! Algorithm 1.
//!
//! The interior grid W samples the finger's three joints over their ranges, strictly inside the
//! limits (`steps` values per joint, the end values dropped); the envelope grid E blocks one joint
//! at its lower, then upper limit and samples the other two (`steps²` points per face, six
//! faces). Spheres are then placed greedily: each W point's distance to E ∪ S (to a sphere: to
//! its surface) is kept up to date; the farthest point becomes the centre of a sphere of that
//! radius, the W points inside it are removed, until `k_max` spheres or the radius falls below
//! `r_min`. So the spheres come biggest first, deepest inside the workspace (farthest from the
//! joint limits), the order in which 003 tests them.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// One sphere of a finger workspace (in the frame of the finger's first IK joint's parent link).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WorkspaceSphere {
    pub centre: Vector3<f64>,
    pub radius: f64,
}

/// The grids W (interior) and E (envelope) of a 3-joint finger, from its tip position as a
/// function of the three joint values and their limits (module docs). `steps` ≥ 3.
pub fn workspace_grids(
    tip: &mut dyn FnMut(&[f64; 3]) -> Vector3<f64>,
    limits: &[(f64, f64); 3],
    steps: usize,
) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
    let steps = steps.max(3);
    let val = |j: usize, i: usize| {
        let (lo, hi) = limits[j];
        lo + (hi - lo) * i as f64 / (steps - 1) as f64
    };
    let mut interior = Vec::with_capacity((steps - 2).pow(3));
    for a in 1..steps - 1 {
        for b in 1..steps - 1 {
            for c in 1..steps - 1 {
                interior.push(tip(&[val(0, a), val(1, b), val(2, c)]));
            }
        }
    }
    let mut envelope = Vec::with_capacity(6 * steps * steps);
    for blocked in 0..3 {
        for end in [0, steps - 1] {
            for a in 0..steps {
                for b in 0..steps {
                    let mut q = [0.0; 3];
                    let (o1, o2) = ((blocked + 1) % 3, (blocked + 2) % 3);
                    q[blocked] = val(blocked, end);
                    q[o1] = val(o1, a);
                    q[o2] = val(o2, b);
                    envelope.push(tip(&q));
                }
            }
        }
    }
    (interior, envelope)
}

/// Algorithm 1: at most `k_max` spheres of radius ≥ `r_min` inside the workspace given by its
/// interior points `w` and envelope points `e`, biggest first.
pub fn approximate_workspace(
    w: &[Vector3<f64>],
    e: &[Vector3<f64>],
    k_max: usize,
    r_min: f64,
) -> Vec<WorkspaceSphere> {
    let mut d: Vec<f64> = w
        .iter()
        .map(|p| {
            e.iter()
                .map(|q| (p - q).norm_squared())
                .fold(f64::INFINITY, f64::min)
                .sqrt()
        })
        .collect();
    let mut alive = vec![true; w.len()];
    let mut spheres = Vec::new();
    while spheres.len() < k_max {
        let best = (0..w.len())
            .filter(|&i| alive[i])
            .max_by(|&a, &b| d[a].total_cmp(&d[b]).then(b.cmp(&a)));
        let Some(best) = best else { break };
        let r = d[best];
        if r.is_nan() || r < r_min || !r.is_finite() {
            break;
        }
        let s = WorkspaceSphere {
            centre: w[best],
            radius: r,
        };
        spheres.push(s);
        for i in 0..w.len() {
            if !alive[i] {
                continue;
            }
            let to_centre = (w[i] - s.centre).norm();
            if to_centre <= s.radius {
                alive[i] = false;
            } else {
                d[i] = d[i].min(to_centre - s.radius);
            }
        }
    }
    spheres
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spheres_of_a_box_workspace_stay_inside_and_shrink() {
        // A Cartesian "finger": the tip is the joint values themselves, a 0.1 m cube.
        let mut tip = |q: &[f64; 3]| Vector3::new(q[0], q[1], q[2]);
        let lim = [(0.0, 0.1); 3];
        let (w, e) = workspace_grids(&mut tip, &lim, 11);
        assert_eq!(w.len(), 9 * 9 * 9);
        assert_eq!(e.len(), 6 * 121);
        let s = approximate_workspace(&w, &e, 10, 0.005);
        assert!(!s.is_empty());
        // The first sphere is centred and of radius the half side.
        assert!((s[0].centre - Vector3::new(0.05, 0.05, 0.05)).norm() < 1e-9);
        assert!((s[0].radius - 0.05).abs() < 1e-9);
        for p in s.windows(2) {
            assert!(p[0].radius >= p[1].radius);
        }
        for sp in &s {
            for k in 0..3 {
                assert!(sp.centre[k] - sp.radius >= -1e-9);
                assert!(sp.centre[k] + sp.radius <= 0.1 + 1e-9);
            }
        }
    }
}
