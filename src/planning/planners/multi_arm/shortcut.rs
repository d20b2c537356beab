//! Makespan-aware shortcutting of a composite plan (in the manner of mr-shortcut: Huang,
//! Bekris et al., "Benchmarking shortcutting techniques for multi-robot-arm motion planning",
//! 2024): random shortcuts of two kinds, each kept only when its new segments are proven free
//! with all arms moving ([`super::cell`]) and the makespan — the duration of the time-optimal
//! timing of the whole polyline ([`crate::trajectory::timing::time_polyline`]) — does not grow:
//!
//! - **composite**: two points of the polyline joined by one straight composite segment, every
//!   arm moving at once (this merges the waits and the one-after-the-other stretches that
//!   prioritized and decoupled plans contain);
//! - **per arm**: one arm's motion between two instants replaced by a straight line, spread
//!   over the same instants (at each vertex in between, the arm is where the straight line is
//!   at that vertex's time), the other arms' timed motions untouched; kept when the makespan
//!   shrinks, or stays equal while the arm's path gets shorter.
//!
//! Seeded; the numbers before and after go into the statistics.

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::cell::Cell;
use crate::planning::Termination;
use crate::trajectory::timing::{time_polyline, TimingLimits};

/// What the shortcutting did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ShortcutReport {
    pub makespan_before: f64,
    pub makespan_after: f64,
    pub tried: u64,
    pub composite_kept: u64,
    pub per_arm_kept: u64,
}

/// Duration of the time-optimal timing of `path` (infinite when it cannot be timed).
pub(crate) fn makespan(path: &[Vec<f64>], limits: &TimingLimits) -> f64 {
    time_polyline(path, limits, &[]).map_or(f64::INFINITY, |t| t.duration)
}

/// The point at parameter `s` (vertex index + fraction) of `path`.
fn point(path: &[Vec<f64>], s: f64) -> Vec<f64> {
    let i = (s.floor() as usize).min(path.len() - 1);
    if i + 1 >= path.len() {
        return path[i].clone();
    }
    let f = s - i as f64;
    path[i]
        .iter()
        .zip(&path[i + 1])
        .map(|(a, b)| a + (b - a) * f)
        .collect()
}

fn length(path: &[Vec<f64>], range: &std::ops::Range<usize>) -> f64 {
    path.windows(2)
        .map(|w| {
            range
                .clone()
                .map(|j| (w[1][j] - w[0][j]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .sum()
}

/// Shortcuts `path` (`arms`: where each arm's values sit), `iterations` tries at most.
pub(crate) fn shortcut(
    cell: &mut Cell,
    path: Vec<Vec<f64>>,
    arms: &[std::ops::Range<usize>],
    limits: &TimingLimits,
    iterations: u64,
    term: &mut Termination,
    rng: &mut ChaCha8Rng,
) -> (Vec<Vec<f64>>, ShortcutReport) {
    let mut path = path;
    let mut best = makespan(&path, limits);
    let mut rep = ShortcutReport {
        makespan_before: best,
        ..ShortcutReport::default()
    };
    for it in 0..iterations {
        if path.len() < 3 || term.should_stop() {
            break;
        }
        rep.tried += 1;
        let m = (path.len() - 1) as f64;
        let (mut sa, mut sb) = (rng.random::<f64>() * m, rng.random::<f64>() * m);
        if sa > sb {
            std::mem::swap(&mut sa, &mut sb);
        }
        // Snap to vertices half of the time (joining vertices removes corners exactly).
        if rng.random::<bool>() {
            sa = sa.floor();
            sb = sb.ceil();
        }
        let (i, j) = (sa.floor() as usize, sb.ceil() as usize);
        if j <= i + 1 {
            continue;
        }
        let (pa, pb) = (point(&path, sa), point(&path, sb));
        // Even tries: composite; odd tries: one arm.
        let per_arm = it % 2 == 1 && arms.len() > 1;
        let mut mid: Vec<Vec<f64>> = Vec::new();
        let arm = rng.random_range(0..arms.len());
        if per_arm {
            // Instants of the vertices between a and b on the current timing.
            let Ok(timed) = time_polyline(&path, limits, &[]) else {
                break;
            };
            let at = |s: f64| {
                let k = (s.floor() as usize).min(path.len() - 1);
                let t0 = timed.waypoint_times[k];
                let t1 = timed.waypoint_times[(k + 1).min(path.len() - 1)];
                t0 + (t1 - t0) * (s - k as f64)
            };
            let (ta, tb) = (at(sa), at(sb));
            if tb <= ta {
                continue;
            }
            let r = arms[arm].clone();
            for v in path.iter().take(j).skip(i + 1) {
                let k = mid.len() + i + 1;
                let f = ((timed.waypoint_times[k] - ta) / (tb - ta)).clamp(0.0, 1.0);
                let mut c = v.clone();
                for x in r.clone() {
                    c[x] = pa[x] + (pb[x] - pa[x]) * f;
                }
                mid.push(c);
            }
        }
        let mut cand: Vec<Vec<f64>> = path[..=i].to_vec();
        let mut fresh: Vec<Vec<f64>> = Vec::new();
        if pa != path[i] {
            fresh.push(pa.clone());
        }
        fresh.extend(mid);
        if pb != path[j] {
            fresh.push(pb.clone());
        }
        // The new segments: path[i] → fresh… → path[j].
        let mut chain = vec![path[i].clone()];
        chain.extend(fresh.iter().cloned());
        chain.push(path[j].clone());
        cand.extend(fresh);
        cand.extend(path[j..].iter().cloned());
        let new = makespan(&cand, limits);
        let keep = if per_arm {
            let r = &arms[arm];
            new < best - 1e-9 || (new <= best + 1e-12 && length(&cand, r) < length(&path, r) - 1e-9)
        } else {
            new < best - 1e-9
        };
        if !keep {
            continue;
        }
        if chain.windows(2).all(|w| cell.segment_free(&w[0], &w[1])) {
            path = cand;
            best = new;
            if per_arm {
                rep.per_arm_kept += 1;
            } else {
                rep.composite_kept += 1;
            }
        }
    }
    rep.makespan_after = best;
    (path, rep)
}
