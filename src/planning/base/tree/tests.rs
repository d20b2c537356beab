//! Tests of the tree: subtree removal, nearest neighbours, domain balls.

use super::*;

#[test]
fn remove_subtree_keeps_the_rest_and_its_nearest_neighbours() {
    let w = [1.0, 2.0, 0.5];
    let mut t = Tree::new(&w);
    let mut x = 0.377f64;
    let mut next = || {
        x = (x * 3.7 + 0.11).fract();
        x * 4.0 - 2.0
    };
    t.add(&[0.0, 0.0, 0.0], NO_PARENT);
    t.add(&[1.0, 1.0, 1.0], NO_PARENT);
    // Enough states for the k-d tree (beyond the linear scan).
    for k in 2..(LINEAR_SCAN_MAX + 90) as u32 {
        let q = [next(), next(), next()];
        let i = t.add(&q, (k * 7919 + 13) % k);
        if k % 5 == 0 {
            t.mark_unproven(i);
            t.set_radius(i, 0.5 + k as f64 * 1e-3);
        }
    }
    let before = t.clone();
    let cut = 3u32;
    let removed = t.remove_subtree(cut);
    assert!(removed >= 1);
    assert_eq!(t.len() + removed, before.len());
    // The kept states, in order, below the same parents (by state), with their radii and marks.
    let mut gone = vec![false; before.len()];
    let mut kept = Vec::new();
    for k in 0..before.len() {
        let p = before.parents[k];
        gone[k] = k == cut as usize || (p != NO_PARENT && gone[p as usize]);
        if !gone[k] {
            kept.push(k as u32);
        }
    }
    assert_eq!(kept.len(), t.len());
    for (j, &k) in kept.iter().enumerate() {
        let j = j as u32;
        assert_eq!(t.state(j), before.state(k));
        assert_eq!(
            t.parent(j).map(|p| t.state(p).to_vec()),
            before.parent(k).map(|p| before.state(p).to_vec())
        );
        assert_eq!(t.radius(j), before.radius(k));
        assert_eq!(t.is_unproven(j), before.is_unproven(k));
    }
    for _ in 0..200 {
        let q = [next(), next(), next()];
        let (a, da) = t.nearest(&q).expect("not empty");
        let (_, dl) = t.nearest_linear(&q).expect("not empty");
        assert_eq!(da, dl);
        assert!(!gone[kept[a as usize] as usize]);
    }
}

#[test]
fn nearest_and_paths() {
    let mut t = Tree::new(&[1.0, 4.0]);
    assert!(t.nearest(&[0.0, 0.0]).is_none());
    let r = t.add(&[0.0, 0.0], NO_PARENT);
    let a = t.add(&[1.0, 0.0], r);
    let b = t.add(&[0.0, 0.6], a);
    // Weighted: b is 4·0.36 = 1.44 away from the origin, a only 1.
    assert_eq!(t.nearest(&[0.0, 0.55]).map(|x| x.0), Some(b));
    assert_eq!(t.nearest(&[0.6, 0.0]).map(|x| x.0), Some(a));
    let mut p = Vec::new();
    t.path_from_root(b, &mut p);
    assert_eq!(p, vec![r, a, b]);
    assert_eq!(t.root_of(b), r);
    assert_eq!(t.parent(r), None);
}

/// `outside_every_domain` never skips a sample that its nearest state's domain holds (the
/// exact rule), and it does skip samples far from a tree with finite radii.
#[test]
fn outside_every_domain_is_conservative() {
    use rand::{Rng, SeedableRng};
    let w = [
        1.0, 0.5, 2.0, 1.0, 1.0, 0.25, 1.0, 1.0, 1.0, 3.0, 1.0, 1.0, 1.0, 1.0,
    ];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let mut q = [0.0f64; 14];
    let (mut skipped, mut exact_skips) = (0, 0);
    for round in 0..40 {
        let mut t = Tree::new(&w);
        let spread = [0.05, 0.5, 2.0][round % 3];
        let n = 1 + round * 7;
        for _ in 0..n {
            for v in q.iter_mut() {
                *v = rng.random_range(-spread..spread);
            }
            let i = t.add(&q, NO_PARENT);
            assert!(
                !t.outside_every_domain(&q),
                "an infinite radius holds everything"
            );
            t.set_radius(i, rng.random_range(0.1..1.5));
        }
        if round % 5 == 4 {
            // One infinite radius left: nothing may be skipped.
            t.set_radius(0, f64::INFINITY);
        }
        for _ in 0..500 {
            for v in q.iter_mut() {
                *v = rng.random_range(-4.0..4.0);
            }
            let (near, d2) = t.nearest(&q).expect("non-empty");
            let r = t.radius(near);
            let exact_skip = d2 > r * r;
            exact_skips += usize::from(exact_skip);
            if t.outside_every_domain(&q) {
                assert!(exact_skip, "skipped a sample within {r} of state {near}");
                skipped += 1;
            }
        }
    }
    // The bound is useful: most samples the exact rule skips, it skips too.
    assert!(skipped * 2 > exact_skips, "{skipped} of {exact_skips}");
    // Radii change: the bound follows a growth at once and keeps the largest radius seen
    // (conservative after a shrink).
    let mut t = Tree::new(&[1.0, 1.0]);
    let a = t.add(&[0.0, 0.0], NO_PARENT);
    t.set_radius(a, 2.0);
    assert!(!t.outside_every_domain(&[1.5, 0.0]));
    assert!(t.outside_every_domain(&[2.5, 0.0]));
    t.set_radius(a, 1.0);
    assert!(!t.outside_every_domain(&[1.5, 0.0]));
    t.set_radius(a, 3.0);
    assert!(!t.outside_every_domain(&[2.5, 0.0]));
    assert!(t.outside_every_domain(&[3.5, 0.0]));
    // The spread counts: a second state 1 away widens the reach.
    t.add(&[-1.0, 0.0], a);
    t.set_radius(1, 0.5);
    assert!(!t.outside_every_domain(&[3.5, 0.0]));
    assert!(t.outside_every_domain(&[4.5, 0.0]));
    t.clear();
    assert!(!t.outside_every_domain(&[4.5, 0.0]));
}

/// The k-d tree answers exactly what the linear scan answers (distances equal), with
/// weights, duplicated states and clustered states that force deep splits.
#[test]
fn kd_tree_nearest_equals_linear_scan() {
    // Weighted, and unit weights (the scans' product-free path).
    kd_tree_nearest_equals_linear_scan_with(&[1.0, 0.25, 4.0, 1.0, 0.5, 2.0, 1.0]);
    kd_tree_nearest_equals_linear_scan_with(&[1.0; 7]);
    assert!(Tree::new(&[1.0; 7]).unit && !Tree::new(&[1.0, 2.0]).unit);
}

fn kd_tree_nearest_equals_linear_scan_with(w: &[f64]) {
    use rand::{Rng, SeedableRng};
    let mut t = Tree::new(w);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut q = [0.0f64; 7];
    for n in 0..6000u32 {
        for v in q.iter_mut() {
            *v = if n % 3 == 0 {
                rng.random_range(-0.01..0.01)
            } else {
                rng.random_range(-3.0..3.0)
            };
        }
        if n % 500 == 7 {
            // Many identical states.
            for _ in 0..40 {
                t.add(&[0.5; 7], NO_PARENT);
            }
        }
        t.add(&q, NO_PARENT);
        if n % 7 == 0 {
            for v in q.iter_mut() {
                *v = rng.random_range(-3.5..3.5);
            }
            let a = t.nearest(&q).expect("non-empty");
            let b = t.nearest_linear(&q).expect("non-empty");
            assert_eq!(a.1, b.1, "after {n} states");
            if t.len() <= LINEAR_SCAN_MAX {
                // The small-tree scan runs in index order: the same state, ties included.
                assert_eq!(a.0, b.0, "after {n} states");
            }
            if n >= 7 {
                let p = [0.5; 7];
                assert_eq!(t.nearest(&p).map(|x| x.1), Some(0.0));
                if t.len() <= LINEAR_SCAN_MAX {
                    // 40 states at distance 0: the first of them, as the linear scan.
                    assert_eq!(t.nearest(&p), t.nearest_linear(&p), "after {n} states");
                }
            }
        }
    }
    t.clear();
    assert!(t.nearest(&q).is_none());
    // After a clear the small-tree scan starts over.
    for k in 0..40 {
        t.add(&[k as f64 * 0.1; 7], NO_PARENT);
    }
    assert_eq!(t.nearest(&[1.04; 7]), t.nearest_linear(&[1.04; 7]));
    assert_eq!(t.nearest(&[1.04; 7]).map(|x| x.0), Some(10));
}

/// States that share a coordinate value — J+-RRT goal extensions move one arm and leave
/// the other variables exactly as they were — still split: a leaf whose widest coordinate
/// has more than half its values at the minimum splits just above it, so no distinct state
/// lands on the overflow list (which every query scans). With the plain median split, 1 146
/// of these 4 000 states overflowed.
#[test]
fn kd_splits_states_that_share_coordinates() {
    use rand::{Rng, SeedableRng};
    let mut t = Tree::new(&[1.0; 6]);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut q = [0.0f64; 6];
    for _ in 0..4000 {
        // Coordinate 0 is the widest and at 0 in 60 % of the states; the others tell
        // every state apart.
        q[0] = if rng.random::<f64>() < 0.6 {
            0.0
        } else {
            rng.random_range(0.0..1.0)
        };
        for v in q[1..].iter_mut() {
            *v = rng.random_range(-0.001..0.001);
        }
        t.add(&q, NO_PARENT);
    }
    assert!(
        t.kd_overflow.is_empty(),
        "{} distinct states overflowed",
        t.kd_overflow.len()
    );
    for _ in 0..200 {
        for v in q.iter_mut() {
            *v = rng.random_range(-1.2..1.2);
        }
        assert_eq!(
            t.nearest(&q).map(|x| x.1),
            t.nearest_linear(&q).map(|x| x.1)
        );
    }
}
