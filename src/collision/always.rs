//! Link pairs that collide in (nearly) every configuration of a robot's collision model —
//! MoveIt Setup Assistant's "Always" category (`moveit_setup_srdf_plugins`,
//! `compute_default_collisions.cpp`, `computeDefaultCollisions`: a pair in collision in at
//! least `min_collision_fraction` = 95 % of random configurations is disabled with reason
//! `Always`).
//!
//! Real SRDFs often lack such pairs (a sphere model that makes two neighbours overlap
//! everywhere, an SRDF written for another collision model). Left enabled, every configuration
//! is in collision and every query fails at its start state. [`disable_always_colliding`] finds
//! them when a robot is loaded ([`crate::Robot::from_files`], [`crate::Robot::from_strings`]),
//! disables them, and says so (a `tracing` warning and an entry of [`crate::Robot::warnings`]
//! naming the pair and the SRDF line that would disable it).
//!
//! Sampling: [`SAMPLES`] configurations drawn uniformly within the joint limits (continuous
//! joints over [−π, π)) from a fixed seed, so the result depends on the model only. A pair is
//! dropped as soon as it has been free in more than 5 % of [`SAMPLES`] (it can no longer reach
//! 95 %), so a model without such pairs costs a few dozen samples, and the loop ends when no
//! candidate is left. The result is kept per process, keyed by the SHA-256 of the URDF and SRDF
//! text, so each description is sampled once.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use rand::SeedableRng;
use sha2::{Digest, Sha256};

use super::world::{BodyId, CollisionWorld};
use super::{ExactChecker, SphereChecker};
use crate::geometry::Pose;
use crate::model::{AlwaysColliding, Robot};

/// Configurations sampled (MoveIt's setup assistant offers 1 000–100 000, default 10 000; with
/// the early drop a pair that is free in 51 of them is already decided, so 1 000 keeps the
/// fraction's resolution at 0.1 % at a cost of milliseconds).
pub const SAMPLES: usize = 1000;
/// Smallest fraction of the samples a pair must collide in to count as "always" (MoveIt's
/// `min_collision_fraction`).
pub const MIN_FRACTION: f64 = 0.95;
/// Seed of the sampling (a fixed one: same model, same answer).
pub const SEED: u64 = 0x6a09_e667_f3bc_c908;

/// Distance below which two links count as colliding here: both spheres' f32 rounding margin
/// of the planners' sphere model ([`SphereChecker::ROUNDING_MARGIN`]), so a pair that merely
/// touches in every configuration — reported in collision by that model — is found too.
pub fn contact_margin() -> f64 {
    2.0 * SphereChecker::ROUNDING_MARGIN
}

/// The pairs of `robot`'s links that are checked (not SRDF-disabled, not rigidly joined) and
/// collide (exact geometry, within [`contact_margin`]) in at least [`MIN_FRACTION`] of
/// [`SAMPLES`] seeded random configurations, with that fraction; sorted by link indices.
pub fn always_colliding(robot: &Robot) -> Vec<AlwaysColliding> {
    if robot.links.len() < 2 {
        return Vec::new();
    }
    let world = CollisionWorld::single(Arc::new(robot.clone()), Pose::identity());
    let pairs: Vec<(usize, usize)> = world
        .pairs()
        .into_iter()
        .filter_map(|p| match p {
            (BodyId::Link { link: a, .. }, BodyId::Link { link: b, .. }) => {
                Some((a.min(b), a.max(b)))
            }
            _ => None,
        })
        .collect();
    if pairs.is_empty() {
        return Vec::new();
    }
    let mut exact = ExactChecker::new(&world);
    debug_assert_eq!(exact.num_pairs(), pairs.len());
    let max_misses = ((1.0 - MIN_FRACTION) * SAMPLES as f64).floor() as usize;
    let margin = contact_margin();
    // (pair index, hits, misses) of the pairs still able to reach the fraction.
    let mut live: Vec<(usize, usize, usize)> = (0..pairs.len()).map(|p| (p, 0, 0)).collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(SEED);
    let mut q = vec![0.0; robot.dof()];
    let vars: Vec<usize> = (0..robot.dof()).collect();
    for _ in 0..SAMPLES {
        if live.is_empty() {
            break;
        }
        robot.sample_vars(&vars, &mut q, &mut rng);
        exact.set_config(&q);
        live.retain_mut(|(p, hits, misses)| {
            if exact.pair_within(*p, margin) {
                *hits += 1;
            } else {
                *misses += 1;
            }
            *misses <= max_misses
        });
    }
    let mut out: Vec<AlwaysColliding> = live
        .into_iter()
        .map(|(p, hits, _)| AlwaysColliding {
            a: pairs[p].0,
            b: pairs[p].1,
            fraction: hits as f64 / SAMPLES as f64,
        })
        .collect();
    out.sort_by_key(|c| (c.a, c.b));
    out
}

type Cache = Mutex<HashMap<[u8; 32], Vec<AlwaysColliding>>>;

fn cache() -> &'static Cache {
    static CACHE: OnceLock<Cache> = OnceLock::new();
    CACHE.get_or_init(|| Mutex::new(HashMap::new()))
}

/// Cache key: SHA-256 of the sampling's parameters and the URDF and SRDF text.
fn key(urdf: &str, srdf: Option<&str>) -> [u8; 32] {
    let mut h = Sha256::new();
    h.update(format!("always v1 {SAMPLES} {MIN_FRACTION} {SEED}\0").as_bytes());
    h.update(urdf.as_bytes());
    h.update([0u8]);
    if let Some(s) = srdf {
        h.update([1u8]);
        h.update(s.as_bytes());
    }
    h.finalize().into()
}

/// The SRDF line that disables the pair (what a user adds to silence the warning).
pub fn srdf_line(robot: &Robot, c: &AlwaysColliding) -> String {
    format!(
        "<disable_collisions link1=\"{}\" link2=\"{}\" reason=\"Always\"/>",
        robot.links[c.a].name, robot.links[c.b].name
    )
}

/// Finds the always-colliding pairs of `robot` (loaded from `urdf` and `srdf` text; the result
/// is cached per process under their hash), disables them (reason `Always`), records them in
/// [`Robot::always_colliding`] and warns about each, naming the SRDF line that would disable it.
pub fn disable_always_colliding(robot: &mut Robot, urdf: &str, srdf: Option<&str>) {
    let k = key(urdf, srdf);
    let cached = cache()
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .get(&k)
        .cloned();
    let found = match cached {
        Some(v) => v,
        None => {
            let v = always_colliding(robot);
            cache()
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .insert(k, v.clone());
            v
        }
    };
    for c in &found {
        let line = srdf_line(robot, c);
        let (a, b) = (&robot.links[c.a].name, &robot.links[c.b].name);
        tracing::warn!(
            robot = %robot.name,
            link1 = %a,
            link2 = %b,
            fraction = c.fraction,
            srdf = %line,
            "links collide in (nearly) every configuration and the SRDF does not disable them: treated as disabled"
        );
        let msg = format!(
            "links {a} and {b} collide in {:.1} % of {SAMPLES} random configurations and the SRDF does not disable them: treated as disabled (add {line})",
            100.0 * c.fraction
        );
        robot.warnings.push(msg);
        robot.disable(c.a, c.b, "Always");
    }
    robot.always_colliding = found;
}
