//! Two-level covers: a body of many primitives — a mesh's fine cover of up to
//! [`crate::geometry::solid::MAX_COVER_BOXES`] boxes, the statuette of paper 003 resting on the
//! desk or held in a hand (§V-B: the queries are revalidated with the object resting or
//! attached) — has its primitives in **groups** of nearby ones, each with a box holding them all.
//!
//! A check tests a group's box first and its members only where that box is hit, and moves
//! (transforms into the world) a held body's group boxes per check, a group's members only when
//! its box is hit. A group's box contains every member (their union's box in the members' common
//! frame, grown by [`EPS`]), so whatever a member touches its group's box touches too: the
//! verdict of every test is the one of the members alone, the same as without groups
//! (conservative exactly as the cover is, `src/geometry/solid.rs`). Fixed bodies group their
//! primitives by world-aligned boxes (the union of the members' boxes).
//!
//! Groups: the cover's boxes split at the median of their centres along the longest extent,
//! recursively, until at most about √n boxes are left together (256 boxes: 16 groups of 16).
//! Bodies of at most [`GROUP_MIN`] primitives (robot links, the shipped obstacles) are not
//! grouped and are tested as before.

use std::ops::Range;

use nalgebra::Vector3;

use super::prim::{dist2_point_aabb, prim_sets_hit, prims_hit, Prim, EPS};
use super::{FastChecker, StaticBodyModel, PERMANENT};

/// Bodies with more primitives than this are grouped.
pub(super) const GROUP_MIN: usize = 16;

/// A group of a moving body's primitives: `local[first..end]` (of the body), and a box in the
/// mount link's frame that holds them all (the member itself for a group of one).
#[derive(Debug, Clone, Copy)]
pub(super) struct Group {
    pub bound: Prim,
    pub first: u32,
    pub end: u32,
}

/// A group of a fixed body's primitives: `prims[first..end]` and the world-aligned box around
/// their boxes.
#[derive(Debug, Clone, Copy)]
pub(super) struct StaticGroup {
    pub lo: Vector3<f64>,
    pub hi: Vector3<f64>,
    pub first: u32,
    pub end: u32,
}

/// Members per group for `n` primitives: about √n, at least 4.
fn leaf_size(n: usize) -> usize {
    ((n as f64).sqrt().ceil() as usize).max(4)
}

/// Splits `idx` (indices into `centres`) at the median along the longest extent of their
/// centres, recursively, into runs of at most `leaf`; the runs (ranges of the reordered `idx`,
/// offset by `base`) are appended to `out`. Ties by index: the same input gives the same groups.
fn split(
    centres: &[Vector3<f64>],
    idx: &mut [usize],
    leaf: usize,
    base: usize,
    out: &mut Vec<Range<usize>>,
) {
    if idx.len() <= leaf {
        out.push(base..base + idx.len());
        return;
    }
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for &i in idx.iter() {
        lo = lo.inf(&centres[i]);
        hi = hi.sup(&centres[i]);
    }
    let axis = (hi - lo).imax();
    let mid = idx.len() / 2;
    idx.select_nth_unstable_by(mid, |&a, &b| {
        centres[a][axis]
            .total_cmp(&centres[b][axis])
            .then(a.cmp(&b))
    });
    let (l, r) = idx.split_at_mut(mid);
    split(centres, l, leaf, base, out);
    split(centres, r, leaf, base + mid, out);
}

/// The box holding the boxes `members` that share one rotation (a mesh cover's), grown by
/// [`EPS`]; `None` when some member is not a box of that rotation.
fn bound_of_boxes(members: &[Prim]) -> Option<Prim> {
    let Some(Prim::Obb { rot, .. }) = members.first() else {
        return None;
    };
    let rot = *rot;
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for m in members {
        match m {
            Prim::Obb { c, rot: r, half } if *r == rot => {
                let u = rot.tr_mul(c);
                lo = lo.inf(&(u - half));
                hi = hi.sup(&(u + half));
            }
            _ => return None,
        }
    }
    Some(Prim::Obb {
        c: rot * ((lo + hi) * 0.5),
        rot,
        half: ((hi - lo) * 0.5).add_scalar(EPS),
    })
}

/// Groups a moving body's primitives `local` (reordered so each group's members are
/// contiguous): each mesh cover in `covers` (ranges of `local`) split as the module docs say,
/// every other primitive a group of its own. No groups (empty) for a body of at most
/// [`GROUP_MIN`] primitives.
pub(super) fn group_moving(local: &mut Vec<Prim>, covers: &[Range<usize>]) -> Vec<Group> {
    let n = local.len();
    if n <= GROUP_MIN {
        return Vec::new();
    }
    let mut order: Vec<usize> = Vec::with_capacity(n);
    let mut runs: Vec<Range<usize>> = Vec::new();
    let mut i = 0;
    while i < n {
        match covers.iter().find(|r| r.start == i && r.len() > 1) {
            Some(r) if bound_of_boxes(&local[r.clone()]).is_some() => {
                let centres: Vec<Vector3<f64>> = local.iter().map(|p| *p.centre()).collect();
                let mut idx: Vec<usize> = r.clone().collect();
                let base = order.len();
                split(&centres, &mut idx, leaf_size(r.len()), base, &mut runs);
                order.extend(idx);
                i = r.end;
            }
            _ => {
                runs.push(order.len()..order.len() + 1);
                order.push(i);
                i += 1;
            }
        }
    }
    let reordered: Vec<Prim> = order.iter().map(|&k| local[k]).collect();
    *local = reordered;
    runs.into_iter()
        .map(|r| {
            let members = &local[r.clone()];
            let bound = if members.len() == 1 {
                members[0]
            } else {
                // Every run of a cover holds boxes of its one rotation (checked above).
                bound_of_boxes(members).unwrap_or(members[0])
            };
            Group {
                bound,
                first: r.start as u32,
                end: r.end as u32,
            }
        })
        .collect()
}

/// Groups a fixed body's primitives (with their world-aligned boxes; reordered so each group's
/// members are contiguous) by their boxes' centres; empty for at most [`GROUP_MIN`].
pub(super) fn group_static(
    prims: &mut Vec<(Prim, Vector3<f64>, Vector3<f64>)>,
) -> Vec<StaticGroup> {
    let n = prims.len();
    if n <= GROUP_MIN {
        return Vec::new();
    }
    let centres: Vec<Vector3<f64>> = prims.iter().map(|(_, lo, hi)| (lo + hi) * 0.5).collect();
    let mut idx: Vec<usize> = (0..n).collect();
    let mut runs = Vec::new();
    split(&centres, &mut idx, leaf_size(n), 0, &mut runs);
    let reordered: Vec<_> = idx.iter().map(|&k| prims[k]).collect();
    *prims = reordered;
    runs.into_iter()
        .map(|r| {
            let (lo, hi) = prims[r.clone()].iter().fold(
                (
                    Vector3::repeat(f64::INFINITY),
                    Vector3::repeat(f64::NEG_INFINITY),
                ),
                |(lo, hi), p| (lo.inf(&p.1), hi.sup(&p.2)),
            );
            StaticGroup {
                lo,
                hi,
                first: r.start as u32,
                end: r.end as u32,
            }
        })
        .collect()
}

/// Whether primitive `x` (bounding radius `xr` about its centre), grown by `d` ≥ 0, touches
/// fixed body `s`: its groups' boxes first when it has groups.
#[inline(always)]
pub(super) fn static_body_hits(s: &StaticBodyModel, x: &Prim, xr: f64, d: f64) -> bool {
    let (xc, r) = (x.centre(), xr + d);
    let r2 = r * r;
    let mut grown = None;
    if s.groups.is_empty() {
        for (y, lo, hi) in &s.prims {
            if dist2_point_aabb(xc, lo, hi) <= r2 && prims_hit(x.grown(d, &mut grown), y) {
                return true;
            }
        }
        return false;
    }
    for g in &s.groups {
        if dist2_point_aabb(xc, &g.lo, &g.hi) > r2 {
            continue;
        }
        for (y, lo, hi) in &s.prims[g.first as usize..g.end as usize] {
            if dist2_point_aabb(xc, lo, hi) <= r2 && prims_hit(x.grown(d, &mut grown), y) {
                return true;
            }
        }
    }
    false
}

impl FastChecker {
    /// World members of group `gi` of moving body `i` for the prepared configuration (its box
    /// is, [`FastChecker::ensure_prims`]).
    #[inline]
    pub(super) fn ensure_group(&mut self, i: usize, gi: usize) {
        let b = &self.moving[i];
        let gk = b.gstart + gi;
        let ready = self.group_ready[gk];
        if ready == self.epoch || ready == PERMANENT {
            return;
        }
        self.group_ready[gk] = self.epoch;
        let g = b.groups[gi];
        let f = &self.link_poses[b.mount.robot][b.mount.link];
        for k in g.first as usize..g.end as usize {
            self.world_prims[b.start + k] = b.local[k].transformed(&f.rot, &f.t);
        }
    }

    /// Every group of moving body `i` moved for good (a body that never moves).
    pub(super) fn make_groups_permanent(&mut self, i: usize) {
        for gi in 0..self.moving[i].groups.len() {
            self.ensure_group(i, gi);
            let gk = self.moving[i].gstart + gi;
            self.group_ready[gk] = PERMANENT;
        }
    }

    /// [`FastChecker::static_prims_hit_by`] for a grouped moving body `a`: each group's box
    /// against fixed body `b`, its members where that box is hit.
    pub(super) fn grouped_static_hit_by(&mut self, a: usize, b: usize, d: f64) -> bool {
        for gi in 0..self.moving[a].groups.len() {
            let ma = &self.moving[a];
            let (g, gk) = (ma.groups[gi], ma.gstart + gi);
            let s = &self.statics[b];
            if !static_body_hits(s, &self.world_groups[gk], self.group_radius[gk], d) {
                continue;
            }
            if g.end - g.first == 1 {
                // The group's box is its member.
                return true;
            }
            self.ensure_group(a, gi);
            let start = self.moving[a].start;
            let s = &self.statics[b];
            let members = start + g.first as usize..start + g.end as usize;
            for k in members {
                if static_body_hits(s, &self.world_prims[k], self.prim_radius[k], d) {
                    return true;
                }
            }
        }
        false
    }

    /// The units a moving body is tested by: its groups' boxes when it has groups, else its
    /// primitives; their bounding radii; the groups.
    fn units(&self, i: usize) -> (&[Prim], &[f64], &[Group]) {
        let b = &self.moving[i];
        if b.groups.is_empty() {
            let r = b.start..b.start + b.local.len();
            (&self.world_prims[r.clone()], &self.prim_radius[r], &[])
        } else {
            let r = b.gstart..b.gstart + b.groups.len();
            (
                &self.world_groups[r.clone()],
                &self.group_radius[r],
                &b.groups,
            )
        }
    }

    /// The world members of unit `u` of moving body `i` ([`Self::units`]; a grouped body's
    /// group must be moved, [`Self::ensure_group`]).
    fn unit_members(&self, i: usize, u: usize) -> Range<usize> {
        let b = &self.moving[i];
        match b.groups.get(u) {
            Some(g) => b.start + g.first as usize..b.start + g.end as usize,
            None => b.start + u..b.start + u + 1,
        }
    }

    /// [`FastChecker::moving_prims_hit_by`] when `a` or `b` has groups: unit against unit
    /// (bounding spheres, then the boxes), the members of the unit pairs that touch.
    pub(super) fn grouped_moving_hit_by(&mut self, a: usize, b: usize, d: f64) -> bool {
        let mut queue = std::mem::take(&mut self.unit_pairs);
        queue.clear();
        let mut hit = false;
        {
            let (ua, ra, ga) = self.units(a);
            let (ub, rb, gb) = self.units(b);
            let single = |g: &[Group], k: usize| g.get(k).is_none_or(|g| g.end - g.first == 1);
            'outer: for (i, (x, &xr)) in ua.iter().zip(ra).enumerate() {
                let mut grown = None;
                for (j, (y, &yr)) in ub.iter().zip(rb).enumerate() {
                    let r = xr + yr + d;
                    if (x.centre() - y.centre()).norm_squared() > r * r
                        || !prims_hit(x.grown(d, &mut grown), y)
                    {
                        continue;
                    }
                    if single(ga, i) && single(gb, j) {
                        // Both units are primitives of the bodies.
                        hit = true;
                        break 'outer;
                    }
                    queue.push((i as u32, j as u32));
                }
            }
        }
        if !hit && !queue.is_empty() {
            for &(i, j) in &queue {
                if !self.moving[a].groups.is_empty() {
                    self.ensure_group(a, i as usize);
                }
                if !self.moving[b].groups.is_empty() {
                    self.ensure_group(b, j as usize);
                }
            }
            hit = queue.iter().any(|&(i, j)| {
                let (ka, kb) = (
                    self.unit_members(a, i as usize),
                    self.unit_members(b, j as usize),
                );
                let (pa, pb) = (&self.world_prims[ka.clone()], &self.world_prims[kb.clone()]);
                prim_sets_hit(pa, &self.prim_radius[ka], pb, &self.prim_radius[kb], d)
            });
        }
        self.unit_pairs = queue;
        hit
    }
}
