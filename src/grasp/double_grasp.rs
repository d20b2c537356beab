//! Double grasps: paper 003 (Saut et al. 2010) §IV-B.
//!
//! A double grasp pairs a grasp of the picking hand's list (it takes the object at its initial
//! pose) with one of the placing hand's list (it puts the object down at its final pose). As in
//! 003, the lists are first filtered by the environment: a picking grasp is kept when its hand
//! (palm and fingers at the grasp's configuration) is free of every fixed body with the object at
//! the initial pose, a placing grasp likewise at the final pose ("all the grasps that take the
//! object from below … lead to a collision between the object support and the hand"). Each
//! remaining pair is then tested for hand–hand collision (both hands on the object, object
//! frame; exact parry shapes). The score of a pair is the sum of two scores, each normalised
//! (min–max) over all collision-free pairs:
//!
//! - the minimum of the two single-grasp qualities ([`super::SingleGrasp::quality`]);
//! - the minimum of the two robot-configuration scores (003 §V-C): here the grasping-arm term,
//!   the cosine of the angle between the grasp's approach direction (palm origin → the hand's
//!   workspace centre, world frame) and the direction from the robot base to the object's
//!   centre of mass (the list's centre: the union of the object's parts, [`super::mass`]), at
//!   the pose where that hand grasps. 003's free-arm terms (joint distance and height difference
//!   to a rest configuration, wrist distance to the torso plane) need the arm configurations of
//!   the exchange (003 §V-C, grasp configurations), which this module does not compute.
//!
//! Bounded: at most `max_pairs` pairs are tested (best single qualities first), the best
//! `max_results` double grasps are returned.

use nalgebra::{Point3, Vector3};
use parry3d_f64::query;
use parry3d_f64::shape::SharedShape;
use serde::{Deserialize, Serialize};

use super::hand::Hand;
use super::list::{GraspList, SingleGrasp};
use crate::collision::{is_solid_mesh, parry_shape, to_parry, StaticBody};
use crate::geometry::{Geometry, Pose};

/// Bounds of a double-grasp search.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DoubleGraspParams {
    /// Most pairs tested for hand–hand collision.
    pub max_pairs: usize,
    /// Most double grasps returned (best first).
    pub max_results: usize,
}

impl Default for DoubleGraspParams {
    fn default() -> Self {
        DoubleGraspParams {
            max_pairs: 250_000,
            max_results: 1000,
        }
    }
}

/// One double grasp: indices into the picking and placing lists, and its scores.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DoubleGrasp {
    pub pick: usize,
    pub place: usize,
    /// min of the two single qualities, and its normalised value.
    pub quality: f64,
    /// min of the two configuration scores (cosines), and its normalised value.
    pub configuration: f64,
    /// Normalised quality + normalised configuration score (0..=2).
    pub score: f64,
}

/// The outcome of [`double_grasps`].
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DoubleGraspResult {
    /// Picking grasps free of the environment at the initial pose (indices into its list).
    pub pick_free: Vec<usize>,
    /// Placing grasps free of the environment at the final pose.
    pub place_free: Vec<usize>,
    /// Pairs tested and pairs whose hands collide.
    pub pairs_tested: usize,
    pub hand_collisions: usize,
    /// Best first.
    pub grasps: Vec<DoubleGrasp>,
}

/// A hand's links placed for one grasp: (link, shape, world pose, bounding radius).
type Placed = Vec<(usize, SharedShape, Pose, f64)>;

fn placed_hand(hand: &Hand, g: &SingleGrasp, object_pose: &Pose) -> Placed {
    placed_hand_at(hand, &g.config, &(object_pose * g.palm_pose()), |_| true)
}

/// `hand`'s links with its variables at `values` (the hand group's variables in order) and its
/// palm at `palm`, each of their collision shapes that `keep` admits.
fn placed_hand_at(
    hand: &Hand,
    values: &[f64],
    palm: &Pose,
    keep: impl Fn(&Geometry) -> bool,
) -> Placed {
    let mut q = hand.base_config();
    for (i, &v) in hand.vars.iter().enumerate() {
        if let Some(x) = values.get(i) {
            q[v] = *x;
        }
    }
    let mut out = Vec::new();
    let links = hand
        .palm_links
        .iter()
        .chain(hand.fingers.iter().flat_map(|f| f.links.iter()));
    for &l in links {
        let lp = palm * hand.link_in_palm(l, &q);
        // `Hand::shapes` holds one parry shape per collision geometry, in the link's order.
        let geoms = &hand.robot.links[l].collision;
        for ((s, local), g) in hand.shapes.get(&l).into_iter().flatten().zip(geoms) {
            if keep(g) {
                let r = s.compute_local_bounding_sphere().radius() + 1e-9;
                out.push((l, s.clone(), lp * local, r));
            }
        }
    }
    out
}

/// Fixed bodies as placed parry shapes with their bounding radii, built once for
/// [`hand_free_of`]: the shapes the exact checker tests alone; a mesh it models as a non-convex
/// solid is left out.
pub struct Environment(Vec<(SharedShape, Pose, f64)>);

impl Environment {
    pub fn new(env: &[StaticBody]) -> Environment {
        let solid_free: Vec<StaticBody> = env
            .iter()
            .map(|b| StaticBody {
                shapes: b
                    .shapes
                    .iter()
                    .filter(|g| !is_solid_mesh(g))
                    .cloned()
                    .collect(),
                ..b.clone()
            })
            .collect();
        Environment(world_shapes(&solid_free))
    }
}

/// Is `hand` alone, its variables at `values` (the hand group's variables in order) and its
/// palm at `palm` (world frame), free of every body of `env`? The shapes the exact checker
/// tests (a link mesh it models as a non-convex solid is left out), so a hand that collides
/// here collides in every robot configuration that puts it there, by the exact checker: 003
/// §IV-B's environment filter as a necessary condition the configuration search (003 §V-C)
/// tests once per grasp instead of once per IK solution.
pub fn hand_free_of(hand: &Hand, values: &[f64], palm: &Pose, env: &Environment) -> bool {
    free_of(
        &placed_hand_at(hand, values, palm, |g| !is_solid_mesh(g)),
        &env.0,
    )
}

fn world_shapes(env: &[StaticBody]) -> Vec<(SharedShape, Pose, f64)> {
    env.iter()
        .flat_map(|b| {
            b.shapes.iter().map(move |g| {
                let (s, p) = parry_shape(g);
                let r = s.compute_local_bounding_sphere().radius() + 1e-9;
                (s, b.pose * p, r)
            })
        })
        .collect()
}

fn intersect(a: &SharedShape, pa: &Pose, ra: f64, b: &SharedShape, pb: &Pose, rb: f64) -> bool {
    if (pa.translation.vector - pb.translation.vector).norm() > ra + rb {
        return false;
    }
    query::intersection_test(&to_parry(pa), a.as_ref(), &to_parry(pb), b.as_ref())
        .map(|r| r.intersecting)
        .unwrap_or(true)
}

fn free_of(placed: &Placed, env: &[(SharedShape, Pose, f64)]) -> bool {
    placed.iter().all(|(_, s, p, r)| {
        env.iter()
            .all(|(es, ep, er)| !intersect(s, p, *r, es, ep, *er))
    })
}

/// The grasping-arm configuration score (module docs) of grasp `g` with the object at `pose`,
/// its centre of mass at `com` (object frame), and the robot base at `base` (world frame).
pub fn approach_score(
    hand: &Hand,
    g: &SingleGrasp,
    pose: &Pose,
    com: &Vector3<f64>,
    base: &Vector3<f64>,
) -> f64 {
    let palm = pose * g.palm_pose();
    let centre = palm * Point3::from(hand.workspace_centre(&hand.base_config()));
    let approach = centre.coords - palm.translation.vector;
    let to_object = (pose * Point3::from(*com)).coords - base;
    if approach.norm() == 0.0 || to_object.norm() == 0.0 {
        return 0.0;
    }
    approach.normalize().dot(&to_object.normalize())
}

/// Double grasps of `pick` (its hand and list; grasps the object at `initial`) and `place`
/// (at `final_pose`), among the fixed bodies `env`, for a robot whose base is at `base`
/// (module docs).
pub fn double_grasps(
    pick: (&Hand, &GraspList),
    place: (&Hand, &GraspList),
    env: &[StaticBody],
    initial: &Pose,
    final_pose: &Pose,
    base: &Vector3<f64>,
    params: &DoubleGraspParams,
) -> DoubleGraspResult {
    let envs = world_shapes(env);
    let mut out = DoubleGraspResult::default();
    // Environment filter (each list at its own pose), then the placed hands in the object frame.
    let mut picks = Vec::new();
    for (i, g) in pick.1.grasps.iter().enumerate() {
        if free_of(&placed_hand(pick.0, g, initial), &envs) {
            out.pick_free.push(i);
            picks.push((
                i,
                placed_hand(pick.0, g, &Pose::identity()),
                approach_score(pick.0, g, initial, &Vector3::from(pick.1.centre), base),
            ));
        }
    }
    let mut places = Vec::new();
    for (i, g) in place.1.grasps.iter().enumerate() {
        if free_of(&placed_hand(place.0, g, final_pose), &envs) {
            out.place_free.push(i);
            places.push((
                i,
                placed_hand(place.0, g, &Pose::identity()),
                approach_score(place.0, g, final_pose, &Vector3::from(place.1.centre), base),
            ));
        }
    }
    // Lists are sorted best first, so pairs in this order try the best qualities first.
    let mut raw = Vec::new();
    'outer: for (a, ha, ca) in &picks {
        for (b, hb, cb) in &places {
            if out.pairs_tested >= params.max_pairs {
                break 'outer;
            }
            out.pairs_tested += 1;
            let clash = ha.iter().any(|(_, s, p, r)| {
                hb.iter()
                    .any(|(_, s2, p2, r2)| intersect(s, p, *r, s2, p2, *r2))
            });
            if clash {
                out.hand_collisions += 1;
                continue;
            }
            let q = pick.1.grasps[*a].quality.min(place.1.grasps[*b].quality);
            raw.push((*a, *b, q, ca.min(*cb)));
        }
    }
    let norm = |v: &[f64]| {
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        move |x: f64| if hi > lo { (x - lo) / (hi - lo) } else { 1.0 }
    };
    let qs: Vec<f64> = raw.iter().map(|r| r.2).collect();
    let cs: Vec<f64> = raw.iter().map(|r| r.3).collect();
    let (nq, nc) = (norm(&qs), norm(&cs));
    out.grasps = raw
        .into_iter()
        .map(|(pick, place, q, c)| DoubleGrasp {
            pick,
            place,
            quality: q,
            configuration: c,
            score: nq(q) + nc(c),
        })
        .collect();
    out.grasps.sort_by(|x, y| {
        y.score
            .total_cmp(&x.score)
            .then(x.pick.cmp(&y.pick))
            .then(x.place.cmp(&y.place))
    });
    out.grasps.truncate(params.max_results);
    out
}
