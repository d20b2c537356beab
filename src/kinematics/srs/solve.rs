//! The S-R-S solver proper: all solutions at a swivel angle (`solve`, `prepare` +
//! `solve_prepared`), the feasible swivel intervals and their limits (`feasible_psi`,
//! `limit_psi`) and the enumeration over ψ (`solve_enumerate`), over the arm of [`super`].

use super::*;

impl SrsArm {
    /// All solutions for a target tip pose (chain-base frame) at swivel angle ψ, within the joint
    /// limits and verified by FK to 1e-9 m / 1e-9 rad. Writes them to `out` (chain variable
    /// order) and returns their number (0 when out of reach). Allocates nothing.
    /// `prepare` + `solve_prepared`.
    pub fn solve(&self, target: &Pose, psi: f64, out: &mut [[f64; 7]; 8]) -> usize {
        self.solve_prepared(&self.prepare(target), psi, out)
    }

    /// The ψ-independent part of [`SrsArm::solve`] (steps 1–2 of the module docs): the wrist
    /// target, θ4 from Paden–Kahan subproblem 3 and each elbow branch's arm frame.
    pub fn prepare(&self, target: &Pose) -> SrsTarget {
        let rt = target.rotation.to_rotation_matrix().into_inner();
        let mut t = SrsTarget {
            rt,
            tt: target.translation.vector,
            rt_tip: rt * self.tip0_rot_inv,
            u: Vector3::zeros(),
            nv: Vector3::zeros(),
            un: Vector3::zeros(),
            elbows: [Elbow {
                q4: 0.0,
                a4: Angle::default(),
                r4: Matrix3::identity(),
                frame_t: Matrix3::identity(),
            }; 2],
            n_elbows: 0,
        };
        let wt = (target * self.w_in_tip).coords;
        let dv = wt - self.s;
        let dist = dv.norm();
        if !dist.is_finite() || dist < 1e-12 {
            return t;
        }
        let u = dv / dist;
        // θ4: subproblem 3, |e^{ξ4θ4} w − s| = dist.
        let (k4, p4) = (&self.k[3], &self.p[3]);
        let xw = self.w - p4;
        let xs = self.s - p4;
        let xwp = xw - k4 * k4.dot(&xw);
        let xsp = xs - k4 * k4.dot(&xs);
        let axial = k4.dot(&(self.w - self.s));
        let dp2 = dist * dist - axial * axial;
        if dp2 < -1e-12 {
            return t;
        }
        let dp2 = dp2.max(0.0);
        let (rw, rs) = (xwp.norm(), xsp.norm());
        let c = (rw * rw + rs * rs - dp2) / (2.0 * rw * rs);
        if c.is_nan() || c.abs() > 1.0 + 1e-9 {
            return t;
        }
        let c = c.clamp(-1.0, 1.0);
        let th0 = atan2(k4.dot(&xwp.cross(&xsp)), xwp.dot(&xsp));
        // Near the stretched (α = π) and folded (α = 0) elbow, acos amplifies rounding
        // (δc ≈ 1e-16 → δα ≈ 1e-8); snap to a single branch there. The distance error of the
        // snap is ≲ r_w r_s / d · (1e-6)² / 2, far below the 1e-9 verification tolerance.
        let mut al = c.acos();
        let n4 = if al < 1e-6 {
            al = 0.0;
            1
        } else if PI - al < 1e-6 {
            al = PI;
            1
        } else {
            2
        };
        for th4 in [th0 + al, th0 - al].into_iter().take(n4) {
            let Some(q4) = into_limits(th4, &self.limits[3]) else {
                continue;
            };
            let Some(a) = self.arm_frame(th4) else {
                continue;
            };
            let (s4, c4) = sin_cos(q4);
            t.elbows[t.n_elbows] = Elbow {
                q4,
                a4: Angle { s: s4, c: c4 },
                r4: rot_sc(k4, s4, c4),
                frame_t: a.transpose(),
            };
            t.n_elbows += 1;
        }
        let (nv, un) = Self::target_frame(&u);
        (t.u, t.nv, t.un) = (u, nv, un);
        t
    }

    /// [`SrsArm::solve`] of a prepared target at swivel angle ψ (steps 3–4 of the module docs,
    /// then the FK check). Allocates nothing.
    pub fn solve_prepared(&self, t: &SrsTarget, psi: f64, out: &mut [[f64; 7]; 8]) -> usize {
        if t.n_elbows == 0 || !psi.is_finite() {
            return 0;
        }
        let mut n = 0;
        let (sp, cp) = sin_cos(psi);
        let d = t.nv * cp + t.un * sp;
        let b = Matrix3::from_columns(&[t.u, d, t.u.cross(&d)]);
        let mut sh = [[Angle::default(); 3]; 2];
        let mut wr = [[Angle::default(); 3]; 2];
        let arcs = &self.arcs;
        for e in &t.elbows[..t.n_elbows] {
            let rsh = b * e.frame_t;
            let ns = self.shoulder.solve(&rsh, &arcs[..3], &mut sh);
            for s3 in &sh[..ns] {
                let [q1, q2, q3] = *s3;
                let r1234 = rot_sc(&self.k[0], q1.s, q1.c)
                    * rot_sc(&self.k[1], q2.s, q2.c)
                    * rot_sc(&self.k[2], q3.s, q3.c)
                    * e.r4;
                let rw = r1234.transpose() * t.rt_tip;
                let nw = self.wrist.solve(&rw, &arcs[4..], &mut wr);
                for w3 in &wr[..nw] {
                    let [q5, q6, q7] = *w3;
                    if n >= out.len() || !self.fk_matches(&[q1, q2, q3, e.a4, q5, q6, q7], t) {
                        continue;
                    }
                    let mut sol = [0.0; 7];
                    let mut ok = true;
                    for (i, a) in [q1, q2, q3, q5, q6, q7].iter().enumerate() {
                        let j = if i < 3 { i } else { i + 1 };
                        match into_limits(a.value(), &self.limits[j]) {
                            Some(v) => sol[j] = v,
                            None => {
                                ok = false;
                                break;
                            }
                        }
                    }
                    if ok {
                        sol[3] = e.q4;
                        out[n] = sol;
                        n += 1;
                    }
                }
            }
        }
        n
    }

    /// The FK check of a candidate solution: the URDF chain (`pre`, joint rotations, `tail`),
    /// independent of the product-of-exponentials data the solver used, reaches the target
    /// within [`SOLUTION_TOLERANCE`] in position and orientation.
    #[inline]
    fn fk_matches(&self, sol: &[Angle; 7], t: &SrsTarget) -> bool {
        let mut r = Matrix3::identity();
        let mut p = Vector3::zeros();
        for (i, a) in sol.iter().enumerate() {
            p += r * self.pre_t[i];
            r = r * self.pre_r[i] * rot_sc(&self.local_axis[i], a.s, a.c);
        }
        p += r * self.tail_t;
        r *= self.tail_r;
        // ‖R_a − R_b‖_F = 2√2 |sin(θ/2)| for the angle θ between two rotations.
        let rot_tol = 2.0 * std::f64::consts::SQRT_2 * (0.5 * SOLUTION_TOLERANCE).sin();
        (p - t.tt).norm() <= SOLUTION_TOLERANCE && (r - t.rt).norm() <= rot_tol
    }

    /// Convenience wrapper of [`SrsArm::solve`] returning a `Vec`.
    pub fn solve_all(&self, target: &Pose, psi: f64) -> Vec<[f64; 7]> {
        let mut out = [[0.0; 7]; 8];
        let n = self.solve(target, psi, &mut out);
        out[..n].to_vec()
    }

    fn feasible_at(&self, target: &SrsTarget, psi: f64, out: &mut [[f64; 7]; 8]) -> bool {
        self.solve_prepared(target, psi, out) > 0
    }

    /// Intervals `(from, to)` of ψ ∈ [−π, π) for which at least one solution within the limits
    /// exists: ψ is sampled at `samples` points, then each interval end is refined by bisection
    /// to 1e-6 rad. Intervals touching ±π are reported as two intervals (`(-π, a)`, `(b, π)`);
    /// an interval found at a single sample only is reported as a point-sized interval. This is
    /// the swivel-angle enumeration of paper 000 §II-A.
    pub fn feasible_psi(&self, target: &Pose, samples: usize) -> Vec<(f64, f64)> {
        let samples = samples.max(1);
        let target = &self.prepare(target);
        let mut out = [[0.0; 7]; 8];
        let step = 2.0 * PI / samples as f64;
        let psi_at = |i: usize| -PI + step * i as f64;
        let feas: Vec<bool> = (0..samples)
            .map(|i| self.feasible_at(target, psi_at(i), &mut out))
            .collect();
        let mut res = Vec::new();
        // Bisection between a feasible ψ `good` and an infeasible ψ `bad`.
        let mut refine = |mut good: f64, mut bad: f64| -> f64 {
            while (good - bad).abs() > 1e-6 {
                let mid = 0.5 * (good + bad);
                if self.feasible_at(target, mid, &mut out) {
                    good = mid;
                } else {
                    bad = mid;
                }
            }
            good
        };
        let mut i = 0;
        while i < samples {
            if !feas[i] {
                i += 1;
                continue;
            }
            let start = i;
            while i < samples && feas[i] {
                i += 1;
            }
            let end = i - 1; // last feasible sample
            let lo = if start == 0 {
                -PI
            } else {
                refine(psi_at(start), psi_at(start - 1))
            };
            let hi = if end == samples - 1 {
                PI
            } else {
                refine(psi_at(end), psi_at(end + 1))
            };
            res.push((lo, hi));
        }
        res
    }

    /// The swivel angles ψ ∈ [−π, π), sorted, at which a joint of some solution for `target`
    /// reaches one of its limits (or a wrist or shoulder triple starts or stops having solutions):
    /// the boundaries of the feasible ψ intervals of Shimizu et al. (2008), computed in closed form
    /// (see [`triple_limit_psi`]). Whether `target` has a solution within the limits is the same
    /// at every ψ strictly between two consecutive angles (cyclically).
    pub fn limit_psi(&self, target: &SrsTarget) -> Vec<f64> {
        let mut out = Vec::new();
        if target.n_elbows == 0 {
            return out;
        }
        let cols =
            |a: Vector3<f64>, b: Vector3<f64>, c: Vector3<f64>| Matrix3::from_columns(&[a, b, c]);
        let z = Vector3::zeros();
        let (u, n, un) = (target.u, target.nv, target.un);
        for e in &target.elbows[..target.n_elbows] {
            // rsh(ψ) = [u, d(ψ), u × d(ψ)] · frameᵀ, d = n cos ψ + (u × n) sin ψ.
            let sh = PsiAffine {
                c: cols(z, n, un) * e.frame_t,
                s: cols(z, un, -n) * e.frame_t,
                o: cols(u, z, z) * e.frame_t,
            };
            // The wrist rotation (r_sh r4)ᵀ rt_tip of this elbow branch.
            let r4t = e.r4.transpose();
            let wr = PsiAffine {
                c: r4t * sh.c.transpose() * target.rt_tip,
                s: r4t * sh.s.transpose() * target.rt_tip,
                o: r4t * sh.o.transpose() * target.rt_tip,
            };
            triple_limit_psi(&self.shoulder, &self.limits[..3], &sh, &mut out);
            triple_limit_psi(&self.wrist, &self.limits[4..], &wr, &mut out);
        }
        out.sort_by(f64::total_cmp);
        out.dedup();
        out
    }

    /// All solutions for ψ enumerated over [−π, π) in `psi_steps` steps, ordered as asked. Feasible
    /// ψ intervals narrower than a step (between two consecutive [`SrsArm::limit_psi`] angles,
    /// with no step inside) are solved at their middle as well, so a target that has a solution
    /// within the limits never gets none, whatever `psi_steps`.
    pub fn solve_enumerate<R: Rng + ?Sized>(
        &self,
        target: &Pose,
        psi_steps: usize,
        order: SolutionOrder,
        rng: &mut R,
    ) -> Vec<[f64; 7]> {
        let steps = psi_steps.max(1);
        let target = self.prepare(target);
        let mut out = [[0.0; 7]; 8];
        let mut all = Vec::new();
        let step = 2.0 * PI / steps as f64;
        let mut psis: Vec<f64> = (0..steps).map(|i| -PI + step * i as f64).collect();
        let crit = self.limit_psi(&target);
        for (k, &lo) in crit.iter().enumerate() {
            let hi = crit.get(k + 1).copied().unwrap_or(crit[0] + 2.0 * PI);
            // The first step after `lo` (steps repeat every 2π).
            let first = -PI + step * (((lo + PI) / step).floor() + 1.0);
            if first >= hi {
                let mid = 0.5 * (lo + hi);
                psis.push(if mid >= PI { mid - 2.0 * PI } else { mid });
            }
        }
        if psis.len() > steps {
            psis.sort_by(f64::total_cmp);
        }
        for psi in psis {
            let n = self.solve_prepared(&target, psi, &mut out);
            all.extend_from_slice(&out[..n]);
        }
        let sort_by = |all: &mut Vec<[f64; 7]>, seed: &[f64; 7], wts: &[f64; 7]| {
            let dist =
                |q: &[f64; 7]| -> f64 { (0..7).map(|j| wts[j] * (q[j] - seed[j]).powi(2)).sum() };
            // Distances once, then a stable sort by them (ties keep the order found).
            let mut keyed: Vec<(f64, [f64; 7])> = all.iter().map(|q| (dist(q), *q)).collect();
            keyed.sort_by(|a, b| a.0.total_cmp(&b.0));
            all.clear();
            all.extend(keyed.into_iter().map(|(_, q)| q));
        };
        match order {
            SolutionOrder::AsFound => {}
            SolutionOrder::Random => all.shuffle(rng),
            SolutionOrder::NearestTo(seed) => sort_by(&mut all, &seed, &[1.0; 7]),
            SolutionOrder::NearestToWeighted { seed, weights } => {
                sort_by(&mut all, &seed, &weights)
            }
        }
        all
    }
}
