//! The origin's depth in a 6-D hull without building the whole hull: an expanding-polytope
//! search (the EPA of GJK-based penetration depth, van den Bergen 2001; in grasp analysis the
//! iterative "grow the polytope toward the nearest facet" scheme of Zheng & Qian's ray-shooting
//! ε, 2005) on the quickhull machinery of [`super`].
//!
//! The Ferrari–Canny ε only depends on the facets nearest to the origin, so the hull is grown
//! only there. Start from quickhull's initial simplex of the *joggled* points (the same
//! deterministic joggle as [`super::ConvexHull`]'s first attempt, so the same points); keep
//! every facet in a min-heap by offset (its signed distance from the origin); repeatedly pop the
//! nearest facet F and scan the points not yet added for the farthest one above F:
//!
//! - if there is one (above by more than the hull's τ), it becomes an apex and the hull of the
//!   points added so far, S, is expanded exactly as in quickhull's step 4 (visible set, horizon,
//!   new facets, ridge links);
//! - if there is none, F supports all the points, so F is a facet of the hull of *all* points.
//!
//! **Why the first such facet is the nearest one.** When the popped F has offset o > 0, every
//! facet of hull(S) has offset ≥ o, so the origin is inside hull(S) at depth o; since
//! hull(S) ⊆ hull(all), the depth in the whole hull is ≥ o, and F is a facet of the whole hull at
//! distance o: the depth is o. From then on the origin is inside hull(S), each expansion only
//! grows hull(S), so new facets have offsets ≥ the popped one and the facets of the whole hull
//! come off the heap in increasing offset. That is exactly the order in which
//! [`super::ConvexHull::support_depth`] visits its candidates, so the same candidates (facets
//! within twice the polish slack of the nearest) are polished the same way against the unjoggled
//! points ([`super::polished_support`]) with the same stopping rule, and the depth is the one the
//! full hull gives (to round-off: a facet's vertices may come in another order).
//!
//! Where the argument does not apply, the answer is [`NearestDepth::Undecided`] and the caller
//! builds the full hull: the nearest true facet within the polish slack of the origin (the
//! origin on or near the boundary, where the full hull's verdict depends on its polish), a
//! numerical failure (the full hull would retry with a larger joggle), more than `max_facets`
//! facets, or a grown hull that fails the local convexity check. When the nearest true facet has
//! the origin clearly outside — the support value h(n) = max_i n · p_i of the *unjoggled*
//! points for its normal n below −slack, a separating direction — the origin is outside the
//! hull ([`NearestDepth::Outside`]).
//!
//! Cost: O(N) per popped facet (the scan) plus quickhull's cost for the facets of hull(S). The
//! pops are few (on the 20-contact sets below a median 31 pops and 20 apexes, so |S| ≈ 27), so
//! the cost is building hull(S): about 1700 facets created (800 alive at the end) per set. Per
//! created facet the plane comes from its parents' pencil ([`super`]'s module docs), the ridges
//! are paired in a stamped open-addressing table, and the builder's memory is reused between
//! calls on a thread (`Work`), which cut the instructions per 20-contact set from 6.0 M to
//! 2.4 M (callgrind on 100 kitchen_two sets; 8 contacts 8.4 M → 3.3 M). On the kitchen_two
//! table grasps with 8 cone edges (`manyhands bench multi-robot --only score`, one core of
//! the loaded 2-core machine, alternated with the previous binary): 20 contacts (160
//! wrenches) grow a median 735 facets in about a third of the previous 1.2–1.8 ms (figures in
//! the commit that brought this), where the full hull has 14 400 facets; the collector's
//! 8-contact combinations grow 1155 facets against 4800. [`depth_exceeds`] stops far earlier
//! (a median 40–60 µs there).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use super::{dot, joggle, polished_support, support, Builder, Fail, HullError, HullOptions};
use super::{Point6, DIM, NONE};

/// What [`nearest_facet_depth`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NearestDepth {
    /// The origin is inside at this (polished) depth, the value
    /// [`super::ConvexHull::support_depth`] gives; `facets` of the grown hull.
    Inside { depth: f64, facets: usize },
    /// The origin is outside the hull (by more than the polish slack).
    Outside { facets: usize },
    /// Only with a bound ([`depth_exceeds`]): the depth exceeds the bound; `lower` is the
    /// proven lower bound (the grown hull's depth less the largest joggle displacement).
    Above { lower: f64, facets: usize },
    /// Not decided here (module docs): build the full hull.
    Undecided,
}

/// A heap entry: a facet and its offset when it was pushed, smallest offset first.
#[derive(Clone, Copy, PartialEq)]
struct Entry {
    off: f64,
    id: u32,
    birth: u32,
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, o: &Self) -> Ordering {
        // Reversed: BinaryHeap is a max-heap.
        o.off
            .total_cmp(&self.off)
            .then_with(|| o.id.cmp(&self.id))
            .then_with(|| o.birth.cmp(&self.birth))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

/// The depth of the origin in the convex hull of `points` (module docs), growing the hull only
/// toward the origin. Errors as [`super::ConvexHull::new`] for non-finite input, too few
/// distinct points and flat input; everything else it cannot decide is
/// [`NearestDepth::Undecided`].
pub fn nearest_facet_depth(
    points: &[Point6],
    max_facets: usize,
) -> Result<NearestDepth, HullError> {
    search(points, max_facets, None)
}

/// Whether the origin's depth in the hull of `points` provably exceeds `bound` (≥ 0), decided
/// early: as soon as every facet of the grown hull is farther than the polish slack and than
/// `bound + √6 δ` from the origin (δ the joggle per coordinate, so √6 δ bounds how far a joggled
/// point moved), the true depth — and the polished depth of the full hull, which is never below
/// it — exceeds `bound`: [`NearestDepth::Above`]. Otherwise the search runs on and answers as
/// [`nearest_facet_depth`] (whose depth may still exceed `bound`).
pub fn depth_exceeds(
    points: &[Point6],
    max_facets: usize,
    bound: f64,
) -> Result<NearestDepth, HullError> {
    search(points, max_facets, Some(bound))
}

/// The search's reusable state: the builder's facet slots, ridge table and the heap keep their
/// memory from one call to the next on a thread (the collector scores thousands of
/// combinations; growing these from empty each time cost about a tenth of a search).
#[derive(Default)]
struct Work {
    b: Builder,
    heap: BinaryHeap<Entry>,
}

/// Kept between calls only up to this many facet slots (about 10 MB), so one huge input does
/// not pin its memory to the thread.
const KEEP_FACETS: usize = 1 << 16;

thread_local! {
    static WORK: std::cell::RefCell<Work> = std::cell::RefCell::new(Work::default());
}

fn search(
    points: &[Point6],
    max_facets: usize,
    accept: Option<f64>,
) -> Result<NearestDepth, HullError> {
    WORK.with(|cell| match cell.try_borrow_mut() {
        Ok(mut w) => {
            let r = search_in(points, max_facets, accept, &mut w);
            if w.b.facets.capacity() > KEEP_FACETS {
                *w = Work::default();
            }
            r
        }
        Err(_) => search_in(points, max_facets, accept, &mut Work::default()),
    })
}

fn search_in(
    points: &[Point6],
    max_facets: usize,
    accept: Option<f64>,
    w: &mut Work,
) -> Result<NearestDepth, HullError> {
    let (scale, keep) = super::prepare(points)?;
    // The first attempt of ConvexHull::with_options: the same joggled points.
    let delta = HullOptions::default().joggle.max(1e-14) * scale;
    let pts: Vec<Point6> = keep
        .iter()
        .map(|&i| joggle(&points[i as usize], delta, 0))
        .collect();
    let Work { b, heap } = w;
    let interior = match b.init(&pts, scale, delta) {
        Ok(i) => i,
        Err(Fail::Hard(e)) => return Err(e),
        Err(Fail::Numeric) => return Ok(NearestDepth::Undecided),
    };
    let tau = 1e-10 * scale;
    let slack = 1e-4 * scale + 100.0 * delta;
    let simplex = b.simplex;
    let mut rest: Vec<u32> = (0..pts.len() as u32)
        .filter(|i| !simplex.contains(i))
        .collect();
    heap.clear();
    heap.extend((0..=DIM as u32).map(|id| Entry {
        off: b.facets[id as usize].off,
        id,
        birth: b.facets[id as usize].birth,
    }));
    let mut nearest: Option<f64> = None;
    let mut best = f64::INFINITY;
    let mut round = 0u32;
    while let Some(e) = heap.pop() {
        let f = &b.facets[e.id as usize];
        if !f.alive || f.birth != e.birth {
            continue;
        }
        // Every facet of hull(S) is at least this far: the origin is inside at that depth.
        if let Some(bound) = accept {
            let lower = f.off - 6f64.sqrt() * delta - 1e-12 * scale;
            if nearest.is_none() && f.off > slack && lower > bound {
                return Ok(NearestDepth::Above {
                    lower,
                    facets: b.live,
                });
            }
        }
        // The farthest point above F among those not added yet.
        let (mut apex, mut far) = (NONE, tau);
        for (k, &i) in rest.iter().enumerate() {
            let d = dot(&f.normal, &pts[i as usize]) - f.off;
            if d > far {
                (apex, far) = (k as u32, d);
            }
        }
        if apex != NONE {
            round += 1;
            let a = rest.swap_remove(apex as usize);
            if b.expand(&pts, a, e.id, round, &interior, scale).is_err() {
                return Ok(NearestDepth::Undecided);
            }
            for vi in 0..b.visible.len() {
                let v = b.visible[vi];
                b.kill(v);
            }
            for &nf in &b.new_ids {
                let g = &b.facets[nf as usize];
                heap.push(Entry {
                    off: g.off,
                    id: nf,
                    birth: g.birth,
                });
            }
            if b.live > max_facets {
                return Ok(NearestDepth::Undecided);
            }
            continue;
        }
        // F is a facet of the hull of all points, the nearest not yet examined.
        let vertices = f.v.map(|k| keep[k as usize]);
        let first = *nearest.get_or_insert(f.off);
        if first <= slack {
            // The origin outside, on or near the boundary.
            // h(n) < 0 for the unjoggled points: a separating direction, a certificate.
            let outside = f.off < -slack && support(points, &f.normal) < -slack;
            if outside && b.check_convex(&pts, delta).is_ok() {
                return Ok(NearestDepth::Outside { facets: b.live });
            }
            return Ok(NearestDepth::Undecided);
        }
        if f.off > first + 2.0 * slack || f.off - slack > best {
            break;
        }
        best = best.min(polished_support(points, &vertices, &f.normal, scale));
    }
    if !best.is_finite() || b.check_convex(&pts, delta).is_err() {
        return Ok(NearestDepth::Undecided);
    }
    Ok(NearestDepth::Inside {
        depth: best,
        facets: b.live,
    })
}
