//! The travel bound of a certified check's segment ([`FastChecker::segment_lengths`]): how far
//! any point of each moving body can move along a straight joint-space motion, per joint
//! (the static weights of [`Sweep::lengths`]) and, for a body's whole chain, from the forward
//! kinematics along the segment (the vector sums of the joint motions, which cancel where the
//! static weights add up). The certificate of [`super`] grows every body by its bound times
//! the run length, so a tighter bound means fewer coarse states and shallower refinement.

use super::{lerp, FastChecker, Sweep};

impl FastChecker {
    /// [`Sweep::lengths`] with each body's whole-chain travel (what a pair with a fixed body
    /// or another robot's body reads, and `lmax`) bounded from the forward kinematics along
    /// the segment when that is smaller: the points of the body's bounding ball (centre `c`,
    /// radius `r`) move at most `|v_c| + r·|ω|` per unit of the segment parameter, with
    /// `v_c = Σ_k Δθ_k · z_k × (c − o_k)` (prismatic: `Δθ_k · z_k`) and `ω = Σ_k Δθ_k · z_k`
    /// over the joints from the root (the vector sums, where [`Sweep::lengths`] adds
    /// `|Δθ_k| · w_k`: joint motions that cancel, as in a Jacobian step or an elbow folding
    /// while the shoulder turns, no longer add up). These are evaluated at the midpoint of each
    /// of a few equal pieces of the segment and change along a piece by at most `M` per unit,
    /// `M = Σ_k |Δθ_k| · (A_{≥k}·R_k + V_{<k}) + r·Σ_k |Δθ_k|·A_{>k}` (prismatic k:
    /// `|Δθ_k|·A_{>k}` in the first sum) — `A`: the summed `|Δθ|` of the revolute joints at or
    /// above `k`, whose rotation turns `z_k × (c − o_k)`; `R_k`: the static bound of the
    /// ball's distance from axis `k`; `V_{<k}`: the joints below moving `c` — so a piece of
    /// parameter length `f` adds at most `|v_c| + r·|ω| + M·f²/4` (Schwarzer, Saha & Latombe
    /// 2005 bound a link point's travel from the joints' motion; this is its
    /// configuration-dependent form, computed once per piece, not per checked state). Leaves
    /// `link_poses` as they were (the pieces' frames go to `piece_poses`). The certified check
    /// runs its two passes, [`Self::chain_lengths`] and [`Self::vector_lengths`], apart (it
    /// may test the motion's end state between them); this is both, for the tests.
    #[cfg(test)]
    pub(super) fn segment_lengths(
        &mut self,
        s: &mut Sweep,
        q: &mut [f64],
        a: &[f64],
        b: &[f64],
        max_inflation: f64,
    ) {
        let pieces = self.chain_lengths(s, a, b, max_inflation);
        self.vector_lengths(s, q, a, b, pieces);
    }

    /// The first pass of [`Self::segment_lengths`]: the static running sums along every chain
    /// (`cum`, `lmax`: [`Sweep::lengths`]) and the second-order sums; returns the pieces the
    /// vector bound is worth (0: none) and the robots that move.
    pub(super) fn chain_lengths(
        &mut self,
        s: &mut Sweep,
        a: &[f64],
        b: &[f64],
        max_inflation: f64,
    ) -> Pieces {
        let moved = self.moving_robots(a, b);
        let moves = |r: usize| moved & (1 << (r % 64)) != 0;
        // [`Sweep::lengths`] and, in the same pass over each chain (body to root), the
        // second-order sums for the whole segment's |Δθ|, in the incremental form: joint k adds
        // its own term and grows every lower joint's A by |Δθ_k|.
        let mut pieces = 1usize;
        s.lmax = 0.0;
        // The variables that move (bits of those below 64; a body with a variable of 64 or
        // more has every bit in `body_vars` and is never skipped).
        let mut moved_vars = 0u64;
        for v in 0..a.len().min(b.len()).min(64) {
            moved_vars |= u64::from(a[v] != b[v]) << v;
        }
        for (i, &(c0, c1)) in s.range.iter().enumerate() {
            let o = s.cum_off[i] as usize;
            if s.body_vars[i] & moved_vars == 0 {
                // No joint of its chain moves: every running sum is 0 and there is no
                // second-order term (the loop below gives exactly these values).
                s.cum[o..=o + (c1 - c0) as usize].fill(0.0);
                s.body_m[i] = -1.0;
                continue;
            }
            s.cum[o] = 0.0;
            let (mut l, mut a_below, mut v_below, mut m_v, mut m_w) = (0.0, 0.0, 0.0, 0.0, 0.0);
            let mut vector = true;
            for (k, e) in (c0 as usize..c1 as usize).enumerate() {
                let (v, w) = s.chain[e];
                let dq = (b[v as usize] - a[v as usize]).abs();
                l += dq * w;
                s.cum[o + k + 1] = l;
                match s.axes[e] {
                    Some(ax) => {
                        let adth = ax.mul.abs() * dq;
                        if ax.revolute {
                            let rk = s.rs[e];
                            m_v += adth * (2.0 * v_below + adth * rk);
                            m_w += adth * a_below;
                            v_below += adth * rk;
                            a_below += adth;
                        } else {
                            v_below += adth;
                        }
                    }
                    // A degenerate axis: no vector bound unless its variable stays.
                    None => vector &= dq == 0.0,
                }
            }
            s.lmax = s.lmax.max(l);
            s.body_m[i] = -1.0;
            if vector && l > 0.0 && moves(self.moving[i].mount.robot) {
                let m = m_v + self.moving[i].br * m_w;
                s.body_m[i] = m;
                // Pieces enough that the second-order term stays under a share of the static
                // bound (the first-order term is what the vector sums gain on).
                pieces = pieces.max(piece_count(m / (4.0 * l)));
            }
        }
        // A piece costs about half a coarse state (its forward kinematics and the sums): no
        // more pieces than a quarter of the coarse runs the static bound asks for.
        let runs = (s.lmax / (2.0 * max_inflation)).ceil();
        let cap = if runs.is_finite() {
            (runs / RUNS_PER_PIECE).ceil().max(1.0) as usize
        } else {
            1
        };
        let pieces = pieces.min(cap);
        let frac = 1.0 / pieces as f64;
        // Worth the pieces only when some body's second-order term leaves its bound room to
        // shrink to half the static one (long segments of many joints: it does not).
        let room = s.range.iter().enumerate().any(|(i, &(c0, c1))| {
            let l = s.cum[s.cum_off[i] as usize + (c1 - c0) as usize];
            s.body_m[i] >= 0.0 && 0.25 * frac * s.body_m[i] < 0.5 * l
        });
        Pieces {
            count: if room { pieces } else { 0 },
            moved,
        }
    }

    /// The second pass of [`Self::segment_lengths`]: every body's whole-chain bound from the
    /// vector sums at the midpoints of `pieces.count` equal pieces (none: the static bounds
    /// stay), for the robots [`Self::chain_lengths`] found moving.
    pub(super) fn vector_lengths(
        &mut self,
        s: &mut Sweep,
        q: &mut [f64],
        a: &[f64],
        b: &[f64],
        pieces: Pieces,
    ) {
        let Pieces {
            count: pieces,
            moved,
        } = pieces;
        if pieces == 0 {
            return;
        }
        let moves = |r: usize| moved & (1 << (r % 64)) != 0;
        let frac = 1.0 / pieces as f64;
        s.body_vec.fill(0.0);
        for piece in 0..pieces {
            lerp(a, b, (piece as f64 + 0.5) * frac, q);
            for r in 0..self.world.robots.len() {
                if moves(r) {
                    self.piece_frames(r, q);
                }
            }
            for &(r, parent, child, v, ax) in &s.tree {
                let r = r as usize;
                if !moves(r) {
                    continue;
                }
                let sums = &mut s.link_sums[r];
                let mut acc = sums[parent as usize];
                if let Some(ax) = ax {
                    let dth = ax.mul * (b[v as usize] - a[v as usize]) * frac;
                    if dth != 0.0 {
                        let f = &self.piece_poses[r][child as usize];
                        let z = f.rot * ax.axis * dth;
                        if ax.revolute {
                            acc[0] += z;
                            acc[1] += z.cross(&f.t);
                        } else {
                            acc[2] += z;
                        }
                    }
                }
                sums[child as usize] = acc;
            }
            for (i, body) in self.moving.iter().enumerate() {
                let r = body.mount.robot;
                // A body without a second-order term keeps its static bound (below).
                if !moves(r) || s.body_m[i] < 0.0 {
                    continue;
                }
                let f = &self.piece_poses[r][body.mount.link];
                let c = f.rot * body.bc + f.t;
                let [om, gamma, pr] = s.link_sums[r][body.mount.link];
                s.body_vec[i] += (om.cross(&c) - gamma + pr).norm() + body.br * om.norm();
            }
        }
        s.lmax = 0.0;
        for (i, &(c0, c1)) in s.range.iter().enumerate() {
            let o = s.cum_off[i] as usize;
            let n = (c1 - c0) as usize;
            let mut l = s.cum[o + n];
            let m = s.body_m[i];
            if m >= 0.0 {
                // Relative 1e-9 and 1e-12 m: rounding of the frames and of the bound.
                let lv = (s.body_vec[i] + 0.25 * frac * m) * (1.0 + 1e-9) + 1e-12;
                if lv < l {
                    l = lv;
                    s.cum[o + n] = l;
                }
            }
            s.lmax = s.lmax.max(l);
        }
    }
}

/// What [`FastChecker::chain_lengths`] found for [`FastChecker::vector_lengths`]: the pieces
/// of the vector bound (0: none) and the robots that move, bit `r % 64` for robot `r`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Pieces {
    count: usize,
    moved: u64,
}

impl FastChecker {
    /// The robots that move along `a → b`, bit `r % 64` for robot `r` (all bits when there
    /// are more than 64 robots).
    fn moving_robots(&self, a: &[f64], b: &[f64]) -> u64 {
        if self.world.robots.len() > 64 {
            return u64::MAX;
        }
        let mut moved = 0u64;
        for (r, p) in self.world.robots.iter().enumerate() {
            let range = p.offset..p.offset + p.robot.dof();
            if a[range.clone()] != b[range] {
                moved |= 1 << r;
            }
        }
        moved
    }
}

/// Pieces of [`FastChecker::segment_lengths`] for a body whose second-order term over the
/// whole segment is `ratio` times its static bound: the term shrinks with the piece length, so
/// `ratio / PIECE_SHARE` pieces keep it under [`PIECE_SHARE`] of that bound (at most
/// [`MAX_PIECES`]).
fn piece_count(ratio: f64) -> usize {
    if ratio.is_finite() && ratio > 0.0 {
        ((ratio / PIECE_SHARE).ceil() as usize).clamp(1, MAX_PIECES)
    } else {
        1
    }
}

/// Measured on `bench planners` (callgrind, IK-RRT reach 40 runs / dual-arm IK-RRT 10 runs,
/// instructions against the static bound): shares 0.1 / 0.25 / 0.5 with one piece per 4
/// coarse runs gave −29 / −28 / −21 % and +4 / −5 / −4 %; one piece per 2 runs at 0.1:
/// −28 % and +6 %.
const PIECE_SHARE: f64 = 0.25;
const RUNS_PER_PIECE: f64 = 4.0;
const MAX_PIECES: usize = 8;

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use nalgebra::Vector3;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::super::lerp;
    use crate::collision::{CollisionWorld, FastChecker, FastModelSettings};
    use crate::geometry::Pose;
    use crate::model::{load_robot_dir, Robot, Scene};

    /// A 6-joint test robot with what ARMAR and Justin lack: a prismatic joint, a mimic joint
    /// (multiplier −1.5), a continuous joint and a skewed axis.
    fn odd_robot() -> Arc<Robot> {
        let urdf = r#"<robot name="odd">
  <link name="base"><collision><geometry><box size="0.3 0.3 0.1"/></geometry></collision></link>
  <link name="slide"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="a1"><collision><origin xyz="0 0 0.2"/><geometry><cylinder radius="0.04" length="0.4"/></geometry></collision></link>
  <link name="a2"><collision><origin xyz="0.15 0 0"/><geometry><box size="0.3 0.05 0.05"/></geometry></collision></link>
  <link name="a3"><collision><origin xyz="0.1 0.02 0"/><geometry><sphere radius="0.05"/></geometry></collision></link>
  <link name="a4"><collision><origin xyz="0.05 0 0.03"/><geometry><box size="0.1 0.08 0.02"/></geometry></collision></link>
  <link name="a5"><collision><origin xyz="0.04 0 0"/><geometry><sphere radius="0.02"/></geometry></collision></link>
  <joint name="p" type="prismatic"><parent link="base"/><child link="slide"/><origin xyz="0 0 0.1"/><axis xyz="1 0 0"/><limit lower="-0.5" upper="0.5" velocity="1" effort="1"/></joint>
  <joint name="j1" type="revolute"><parent link="slide"/><child link="a1"/><origin xyz="0 0 0.05" rpy="0.1 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1" effort="1"/></joint>
  <joint name="j2" type="revolute"><parent link="a1"/><child link="a2"/><origin xyz="0 0 0.4"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
  <joint name="j3" type="revolute"><parent link="a2"/><child link="a3"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" velocity="1" effort="1"/><mimic joint="j2" multiplier="-1.5" offset="0.2"/></joint>
  <joint name="j4" type="continuous"><parent link="a3"/><child link="a4"/><origin xyz="0.2 0 0" rpy="0 0.3 0"/><axis xyz="0.6 0 0.8"/></joint>
  <joint name="j5" type="revolute"><parent link="a4"/><child link="a5"/><origin xyz="0.1 0 0"/><axis xyz="0 0 1"/><limit lower="-2" upper="2" velocity="1" effort="1"/></joint>
</robot>"#;
        Arc::new(Robot::from_strings(urdf, None, std::path::Path::new(".")).expect("robot"))
    }

    fn kitchen() -> Scene {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let lib = load_robot_dir(&root.join("robots")).expect("robots");
        Scene::from_file(&root.join("scenes/kitchen.json"), &lib).expect("scene")
    }

    /// The bound of every body's travel along a segment ([`FastChecker::segment_lengths`]: the
    /// running sums per joint, and the whole chain's, per joint and as a vector) is never
    /// below the travel of the points of its bounding sphere, measured densely: relative to
    /// the frame above each prefix of its chain, and in the world for the whole chain. On
    /// ARMAR in the kitchen (wok in its right hand), Justin and a robot with prismatic, mimic,
    /// continuous and skewed joints; short segments (a Jacobian step) to segments across the
    /// joint ranges.
    #[test]
    fn segment_travel_bounds_hold_densely() {
        let s = kitchen();
        let mut armar = CollisionWorld::from_scene(&s);
        let q0 = CollisionWorld::start_config(&s);
        let hand = armar.robots[0]
            .robot
            .links
            .iter()
            .position(|l| l.name == "right_hand" || l.name.ends_with("right_hand"))
            .or_else(|| {
                armar.robots[0]
                    .robot
                    .links
                    .iter()
                    .position(|l| l.name.contains("hand"))
            })
            .expect("a hand link");
        armar.attach("wok", 0, hand, &q0, vec![hand]);
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let lib = load_robot_dir(&root.join("robots")).expect("robots");
        let justin =
            CollisionWorld::single(lib.get("justin").expect("justin").clone(), Pose::identity());
        let odd = CollisionWorld::single(odd_robot(), Pose::identity());
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut tight_seen = 0usize;
        for (name, world) in [("armar", armar), ("justin", justin), ("odd", odd)] {
            let mut c = FastChecker::with_settings(&world, FastModelSettings::default());
            let mut sw = std::mem::take(&mut c.sweep);
            let dof = world.dof();
            let (lo, hi): (Vec<f64>, Vec<f64>) = world
                .robots
                .iter()
                .flat_map(|p| {
                    (0..p.robot.dof()).map(move |v| {
                        let l = p.robot.var_limits(v);
                        if l.bounded {
                            (l.lower, l.upper)
                        } else {
                            (-std::f64::consts::PI, std::f64::consts::PI)
                        }
                    })
                })
                .unzip();
            let mut q = vec![0.0; dof];
            for seg in 0..24 {
                let a: Vec<f64> = (0..dof).map(|v| rng.random_range(lo[v]..=hi[v])).collect();
                // Segment lengths from a 0.5° step to the whole range.
                let frac = [0.005, 0.03, 0.2, 1.0][seg % 4];
                let b: Vec<f64> = (0..dof)
                    .map(|v| {
                        let x = rng.random_range(lo[v]..=hi[v]);
                        (a[v] + frac * (x - a[v])).clamp(lo[v], hi[v])
                    })
                    .collect();
                // Dense travel of the ball's centre and its six extreme points.
                let n = 1500;
                let bodies = c.moving.len();
                let mut travel: Vec<Vec<f64>> = (0..bodies)
                    .map(|i| vec![0.0; (sw.range[i].1 - sw.range[i].0) as usize + 1])
                    .collect();
                let mut prev: Vec<Vec<[Vector3<f64>; 7]>> = Vec::new();
                for step in 0..=n {
                    lerp(&a, &b, step as f64 / n as f64, &mut q);
                    for r in 0..world.robots.len() {
                        c.robot_frames(r, &q);
                    }
                    let mut cur = Vec::with_capacity(bodies);
                    for i in 0..bodies {
                        let b = &c.moving[i];
                        let r = b.mount.robot;
                        let up = c.fk[r].ancestors(b.mount.link);
                        let f = c.link_poses[r][b.mount.link];
                        let pts: Vec<Vector3<f64>> = std::iter::once(Vector3::zeros())
                            .chain((0..3).flat_map(|k| {
                                let mut e = Vector3::zeros();
                                e[k] = b.br;
                                [e, -e]
                            }))
                            .map(|e| f.rot * (b.bc + e) + f.t)
                            .collect();
                        let entries = (sw.range[i].1 - sw.range[i].0) as usize;
                        // Prefix k: relative to the frame above joint k (the world for the
                        // whole chain: the robot's root is fixed in it).
                        let mut per_k: Vec<[Vector3<f64>; 7]> = up[..entries]
                            .iter()
                            .map(|&l| {
                                let g = c.link_poses[r][l];
                                std::array::from_fn(|m| g.rot.transpose() * (pts[m] - g.t))
                            })
                            .collect();
                        per_k.push(std::array::from_fn(|m| pts[m]));
                        cur.push(per_k);
                    }
                    if step > 0 {
                        for i in 0..bodies {
                            for (k, t) in travel[i].iter_mut().enumerate() {
                                let d = (0..7)
                                    .map(|m| (cur[i][k][m] - prev[i][k][m]).norm())
                                    .fold(0.0f64, f64::max);
                                *t += d;
                            }
                        }
                    }
                    prev = cur;
                }
                // The coarse inflation sets how many pieces the bound may take (one for a
                // large one, up to eight for a tiny one).
                for inflation in [0.06, 0.001] {
                    c.segment_lengths(&mut sw, &mut q, &a, &b, inflation);
                    for (i, t) in travel.iter().enumerate() {
                        let o = sw.cum_off[i] as usize;
                        for (k, &dist) in t.iter().enumerate() {
                            // The travel of each point is at most its bound; the max over
                            // points of per-step moves can only exceed each point's own sum.
                            let bound = sw.cum[o + k];
                            assert!(
                                dist <= bound * (1.0 + 1e-6) + 1e-9,
                                "{name}, segment {seg}, inflation {inflation}, body {}, \
                                 prefix {k}: travel {dist} > bound {bound}",
                                world.body_name(c.moving[i].id)
                            );
                            if k + 1 == t.len() && dist > 0.5 * bound {
                                tight_seen += 1;
                            }
                        }
                    }
                }
            }
        }
        // Not vacuous: the bound is within 2× of the dense travel for some bodies.
        assert!(tight_seen > 10, "{tight_seen}");
    }
}
