//! The certified check of a continuous straight motion ([`FastChecker::segment_certified`]):
//! the coarse pass over equal runs, the midpoints first for short motions, and the halving of
//! runs with a tight end, testing only the pairs tight there (what is proven and under which
//! bound: see the parent module, `sweep.rs`). Split from `sweep.rs` by concept; code moved
//! unchanged.

use super::{lerp, run_param, Inflated, Refine, Sweep};
use crate::collision::fast::{dist2_point_aabb, Certification, FastChecker};

impl FastChecker {
    /// Certified check of the continuous straight motion `a → b` (both ends included) with
    /// every body inflated by at most `max_inflation` metres at the coarse level; see
    /// [`FastChecker::segment_certified`] for what is proven.
    pub(in crate::collision::fast) fn certify_segment(
        &mut self,
        a: &[f64],
        b: &[f64],
        max_inflation: f64,
    ) -> Certification {
        let dof = self.world.dof();
        if a.len() != dof
            || b.len() != dof
            || !a.iter().chain(b).all(|v| v.is_finite())
            || !(max_inflation.is_finite() && max_inflation > 0.0)
            || !self.sweep.bounded
        {
            return Certification::Unproven;
        }
        // The speed bounds count prismatic travel within the limits only.
        let inside = |q: &[f64]| {
            self.sweep.prismatic.iter().all(|&(v, lo, hi)| {
                let x = q[v as usize];
                lo <= x && x <= hi
            })
        };
        if !(inside(a) && inside(b)) {
            return Certification::Unproven;
        }
        if let Some(f) = &self.frozen {
            let same = |q: &[f64]| f.fixed.iter().all(|&(v, x)| q[v].to_bits() == x.to_bits());
            if !(same(a) && same(b)) {
                // The motion moves frozen variables: certify with a checker of the whole world
                // (slow, allocates; planners never do this).
                let mut full = FastChecker::build(&self.world, self.settings, None);
                let r = full.certify_segment(a, b, max_inflation);
                self.checks += full.checks;
                return r;
            }
        }
        let mut s = std::mem::take(&mut self.sweep);
        let mut pool = std::mem::take(&mut s.pool);
        let mut pool_d = std::mem::take(&mut s.pool_d);
        let mut q = std::mem::take(&mut s.q);
        let r = self.certify(
            &mut s,
            (&mut pool, &mut pool_d),
            &mut q,
            a,
            b,
            max_inflation,
        );
        s.pool = pool;
        s.pool_d = pool_d;
        s.q = q;
        self.sweep = s;
        r
    }

    fn certify(
        &mut self,
        s: &mut Sweep,
        (pool, pool_d): (&mut Vec<u32>, &mut Vec<f64>),
        q: &mut [f64],
        a: &[f64],
        b: &[f64],
        max_inflation: f64,
    ) -> Certification {
        let pieces = self.chain_lengths(s, a, b, max_inflation);
        // A long motion (an RRT extension) often ends in collision: its end state alone, with
        // the plain primitives, answers that before the vector bound's pieces and the pairs'
        // inflations are computed. Short ones (a Jacobian step) mostly end free.
        let probed = (s.lmax / (2.0 * max_inflation)).ceil() >= PROBE_END_RUNS;
        if probed && self.find(b).is_some() {
            return Certification::Collides;
        }
        self.vector_lengths(s, q, a, b, pieces);
        let lmax = s.lmax;
        if !lmax.is_finite() {
            return Certification::Unproven;
        }
        // Coarse level: equal runs, each end state checked with the bodies grown for a run.
        let mut runs = ((lmax / (2.0 * max_inflation)).ceil() as usize).clamp(1, CERTIFY_MAX_RUNS);
        let mut h = 1.0 / runs as f64;
        s.set_inflation(h);
        pool.clear();
        pool_d.clear();
        s.state_tight.clear();
        // Short motions (a Jacobian step) mostly end free: the midpoint of each run, checked
        // with the run's inflation, proves the whole run (every state of it lies within half
        // the run's travel of its midpoint) — one state fewer than the run's two ends. Should
        // a midpoint be tight, the runs are halved: the midpoints become run ends of the finer
        // level (free with twice its inflation but for their tight pairs, logged as at any run
        // end), and only the other ends are checked below.
        let mut still_checked = probed;
        let mids = runs <= MIDPOINT_RUNS;
        if mids {
            s.state_tight.resize(2 * runs + 1, (0, 0));
            let mut free = true;
            for k in 0..runs {
                let m = 2 * k + 1;
                lerp(a, b, run_param(m, 2 * runs), q);
                let start = pool.len() as u32;
                match self.check_inflated_logging(s, q, Some(pool), still_checked) {
                    Inflated::Hit => return Certification::Collides,
                    Inflated::Tight => free = false,
                    Inflated::Free => {}
                }
                // Every pair was checked here, with its plain primitives at least.
                still_checked = true;
                self.log_free_inflations(s, &pool[start as usize..], pool_d);
                s.state_tight[m] = (start, pool.len() as u32);
            }
            if free {
                self.certify_finest = self.certify_finest.min(0.5 * h * lmax);
                return Certification::Free;
            }
            runs *= 2;
            h = 1.0 / runs as f64;
            s.set_inflation(h);
        } else {
            s.state_tight.resize(runs + 1, (0, 0));
        }
        if s.order_n != runs {
            crate::collision::motion::bisection_order(runs, &mut s.order);
            s.order_n = runs;
        }
        for idx in 0..=runs {
            let k = if idx < runs { s.order[idx] as usize } else { 0 };
            if mids && k % 2 == 1 {
                continue; // a midpoint, checked above
            }
            if k == runs {
                // The end state itself (the probe above left its frames prepared).
                q.copy_from_slice(b);
            } else {
                lerp(a, b, run_param(k, runs), q);
            }
            let start = pool.len() as u32;
            // A pair whose relative pose the segment keeps is proven by one state: the probe's
            // or the first one here.
            let skip_still = still_checked || idx > 0;
            if self.check_inflated_logging(s, q, Some(pool), skip_still) == Inflated::Hit {
                return Certification::Collides;
            }
            self.log_free_inflations(s, &pool[start as usize..], pool_d);
            s.state_tight[k] = (start, pool.len() as u32);
        }
        s.stack.clear();
        for i in 0..runs {
            let (e0, e1) = (s.state_tight[i], s.state_tight[i + 1]);
            if e0.0 < e0.1 || e1.0 < e1.1 {
                s.stack.push(Refine {
                    t0: run_param(i, runs),
                    t1: run_param(i + 1, runs),
                    e0,
                    e1,
                });
            }
        }
        let mut finest = 0.5 * h * lmax;
        // Refinement, level by level: every run still to prove is halved. Each checked state
        // keeps, per pair tight there, the largest inflation (of a halving sequence) the pair
        // is free with, so a run end is not checked again: a pair is tight at an end at this
        // level when its inflation for a run of this length exceeds what it is free with. The
        // midpoint is checked against the pairs tight at either end (every other pair is proven
        // free along the whole run); a half whose ends leave no pair tight is proven free.
        let mut budget = CERTIFY_MAX_REFINEMENTS;
        while !s.stack.is_empty() {
            let hh = 0.5 * h;
            if budget < s.stack.len() || 0.5 * hh * lmax < CERTIFY_FLOOR {
                return Certification::Unproven;
            }
            budget -= s.stack.len();
            finest = finest.min(0.5 * hh * lmax);
            s.next.clear();
            for ri in 0..s.stack.len() {
                let r = s.stack[ri];
                // The pairs tight at either end for a run of length h.
                s.focus.clear();
                for e in [r.e0, r.e1] {
                    for k in e.0 as usize..e.1 as usize {
                        let pi = pool[k];
                        if s.inflation(pi as usize, h) > pool_d[k] {
                            s.focus.push(pi);
                        }
                    }
                }
                s.focus.sort_unstable();
                s.focus.dedup();
                let tm = 0.5 * (r.t0 + r.t1);
                let start = pool.len() as u32;
                if self.check_focused(s, q, a, b, tm, hh, &s.focus, pool, pool_d) == Inflated::Hit {
                    return Certification::Collides;
                }
                let em = (start, pool.len() as u32);
                let tight_at = |e: (u32, u32)| {
                    (e.0 as usize..e.1 as usize)
                        .any(|k| s.inflation(pool[k] as usize, hh) > pool_d[k])
                };
                let (t0, tmid, t1) = (tight_at(r.e0), tight_at(em), tight_at(r.e1));
                if t0 || tmid {
                    s.next.push(Refine {
                        t0: r.t0,
                        t1: tm,
                        e0: r.e0,
                        e1: em,
                    });
                }
                if tmid || t1 {
                    s.next.push(Refine {
                        t0: tm,
                        t1: r.t1,
                        e0: em,
                        e1: r.e1,
                    });
                }
            }
            std::mem::swap(&mut s.stack, &mut s.next);
            h = hh;
        }
        self.certify_finest = self.certify_finest.min(finest);
        Certification::Free
    }

    /// Per pair of `tight` (logged in the prepared state), the largest inflation of a halving
    /// sequence from the next level's it is free with there, appended to `out`: later levels
    /// read it instead of checking the state again.
    fn log_free_inflations(&mut self, s: &Sweep, tight: &[u32], out: &mut Vec<f64>) {
        for &pi in tight {
            let pi = pi as usize;
            let d = self.free_inflation(s, pi, 0.5 * s.pair_d[pi]);
            out.push(d);
        }
    }

    /// The largest of `d0, d0/2, d0/4, …` (at least [`CERTIFY_FLOOR`]) that pair `pi` is free
    /// with in the prepared state, 0 when none.
    fn free_inflation(&mut self, s: &Sweep, pi: usize, d0: f64) -> f64 {
        let mut d = d0;
        while d >= CERTIFY_FLOOR {
            if !self.pair_hits_by(s, pi, d) {
                return d;
            }
            d *= 0.5;
        }
        0.0
    }

    /// Whether pair `pi` touches in the prepared state with its moving body grown by `d`
    /// (bounding-sphere cull first).
    #[inline]
    fn pair_hits_by(&mut self, s: &Sweep, pi: usize, d: f64) -> bool {
        let p = self.pairs[pi];
        let reach = s.pair_reach0[pi] + d;
        let (x, y) = (p.a as usize, p.b as usize);
        if p.b_static {
            let st = &self.statics[y];
            dist2_point_aabb(&self.body_bc[x], &st.lo, &st.hi) <= reach * reach
                && self.static_prims_hit_by(x, y, d)
        } else {
            (self.body_bc[x] - self.body_bc[y]).norm_squared() <= reach * reach
                && self.moving_prims_hit_by(x, y, d)
        }
    }

    /// The state `a + (b − a)·t` against the pairs `focus` only, every pair's primitives grown
    /// for a run of length `h` (as [`Self::check_inflated`]); the pairs tight there are appended
    /// to `out`, what they are free with ([`Self::free_inflation`]) to `out_d`.
    #[allow(clippy::too_many_arguments)]
    fn check_focused(
        &mut self,
        s: &Sweep,
        q: &mut [f64],
        a: &[f64],
        b: &[f64],
        t: f64,
        h: f64,
        focus: &[u32],
        out: &mut Vec<u32>,
        out_d: &mut Vec<f64>,
    ) -> Inflated {
        if focus.is_empty() {
            return Inflated::Free;
        }
        lerp(a, b, t, q);
        self.checks += 1;
        self.prepare_focused(q, focus);
        let scale = 0.5 * h;
        let mut tight = false;
        for &pi in focus {
            let pi = pi as usize;
            let p = self.pairs[pi];
            let d = scale * s.pair_len[pi];
            let (x, y) = (p.a as usize, p.b as usize);
            if !self.pair_hits_by(s, pi, d) {
                continue;
            }
            let plain = d <= 0.0
                || if p.b_static {
                    self.static_prims_hit(x, y)
                } else {
                    self.moving_prims_hit(x, y)
                };
            if plain {
                return Inflated::Hit;
            }
            tight = true;
            out.push(pi as u32);
            out_d.push(self.free_inflation(s, pi, 0.5 * d));
        }
        if tight {
            Inflated::Tight
        } else {
            Inflated::Free
        }
    }
}

/// Coarse runs (of the static bound) from which a certified check tests the motion's end
/// state alone first ([`FastChecker::certify`]; its frames stay prepared for the coarse check
/// of that state when it is free). Callgrind, `bench planners` (instructions against no probe):
/// from 4 / 8 / 16 / 32 runs, dual-arm IK-RRT with the obstacle (10 runs) −7.7 / −7.7 / −7.8 /
/// −2.8 %, kitchen task and Bimanual (10 runs) −6.6 / −6.6 / −6.6 / −5.8 %, IK-RRT reach with
/// the obstacle (40 runs) +2.9 / +2.7 / +1.9 / +0.3 %; dual-arm J+-RRT (4 runs) −0.8 % at 8 and
/// 16, +8 % probing every motion (its Jacobian steps mostly end free).
const PROBE_END_RUNS: f64 = 16.0;
/// Most coarse runs whose midpoints a certified check tests first ([`FastChecker::certify`]).
/// Callgrind, `bench planners` against ends only (with [`Sweep::run_still`] in both): dual-arm
/// J+-RRT with the obstacle (4 runs) 5 683 → 5 433 M at 1, 5 422 M at 2 (with
/// [`Sweep::any_still`]); Bimanual (10 runs) 1 843.5 → 1 843.6 M at 1 (its drop to 1 835 M at 2
/// is `any_still`'s); dual-arm IK-RRT with the obstacle, IK-RRT reach and the kitchen task
/// within ±0.5 %.
const MIDPOINT_RUNS: usize = 2;
/// Most coarse runs of a certified check (a longer motion is covered by larger inflations).
const CERTIFY_MAX_RUNS: usize = 4096;
/// Most refinement steps (halvings) of one certified check before it gives up (unproven).
const CERTIFY_MAX_REFINEMENTS: usize = 4096;
/// Smallest body inflation (metres) a refinement goes down to before it gives up (unproven):
/// a motion ending or passing closer than about this to a contact is refused (a grasp approach
/// ending 5 µm from the object is still certified, `tests/collision_certified.rs`). Well above
/// the fast model's tolerance (1e-9 m) and the exact checker's: at a 1 nm floor, motions
/// grazing within nanometres were certified that the exact checker's GJK calls touching.
pub(in crate::collision::fast) const CERTIFY_FLOOR: f64 = 1e-6;
