//! Planner settings derived from the robot instead of its name: how far a joint-space step
//! moves the robot's collision geometry in the workspace.
//!
//! Along a straight joint-space motion Δq a point of link k moves at most
//! `Σ_v |Δq_v| · w_kv`, where `w_kv` bounds its distance to the axis of every joint driven by
//! variable v ([`crate::kinematics::FkModel::speed_bounds`]: the link lengths and prismatic
//! travel from the link up to that joint — the bound the certified motion checks use too).
//! With the *lever arm* `L_v = max_k w_kv` of each variable (the farthest any point it moves
//! can be from its axis) and Cauchy–Schwarz, a step of weighted length
//! `‖Δq‖ = sqrt(Σ_v c_v Δq_v²)` (the space's weights c_v) moves every point by at most
//! `Σ_v |Δq_v| L_v ≤ ‖Δq‖ · S`, `S = sqrt(Σ_v L_v² / c_v)`: the *motion scale* (metres per unit
//! of joint-space distance). `Σ_v |Δq_v| L_v` also bounds the sum of the motions of a robot's
//! independent chains (both arms of a bimanual robot), so S counts every joint of the space:
//! a 14-joint two-arm space has about √2 times the scale of one of its arms.
//!
//! A step of `D / S` moves the geometry by at most D; with D proportional to the robot's
//! reach (the largest lever arm) the range is the same for a robot scaled in size, and shrinks
//! as `1/√n` with the number n of joints of full reach. [`MotionScale`] computes L, the reach
//! and S; the planners' defaults built from them are in the README ("Settings derived from the
//! robot").

use crate::collision::CollisionWorld;
use crate::kinematics::FkModel;
use crate::planning::JointSpace;

/// How far the robots' collision geometry can move per unit of joint-space distance of a
/// space (see the module documentation).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MotionScale {
    /// Per dimension of the space: the lever arm `L_v` — the largest distance of any point of
    /// the collision geometry the variable moves from that variable's joint axis (metres; for
    /// a prismatic joint, metres per metre: its multiplier), an upper bound over the limits.
    pub lever: Vec<f64>,
    /// The largest lever arm (the robot's reach about its most loaded joint), metres.
    pub reach: f64,
    /// `S = sqrt(Σ_v L_v² / c_v)`, metres per unit of joint-space distance.
    pub scale: f64,
}

impl MotionScale {
    /// The motion scale of `space` in `world`. `None` when no link with collision geometry
    /// moves with the space's variables, or when a prismatic joint on the way has unbounded
    /// travel.
    pub fn of(world: &CollisionWorld, space: &JointSpace) -> Option<MotionScale> {
        let mut lever_world = vec![0.0f64; world.dof()];
        for p in &world.robots {
            let robot = &p.robot;
            let fk = FkModel::reduced(robot);
            for (li, link) in robot.links.iter().enumerate() {
                if link.collision.is_empty() {
                    continue;
                }
                let (mount, off) = fk.mount(li);
                // Bounding ball of the link's geometry in its mount's frame: the shapes'
                // bounding spheres about their mean centre.
                let centres: Vec<_> = link
                    .collision
                    .iter()
                    .map(|g| {
                        let c = g.origin.translation.vector;
                        (
                            off.map_or(c, |o| o.transform_point(&c)),
                            g.shape.bounding_radius(),
                        )
                    })
                    .collect();
                let n = centres.len() as f64;
                let mid = centres
                    .iter()
                    .fold(nalgebra::Vector3::zeros(), |s, (c, _)| s + c)
                    / n;
                let radius = centres
                    .iter()
                    .map(|(c, r)| (c - mid).norm() + r)
                    .fold(0.0, f64::max);
                for (v, w) in fk.speed_bounds(robot, mount, &mid, radius)? {
                    let l = &mut lever_world[p.offset + v];
                    *l = l.max(w);
                }
            }
        }
        let lever: Vec<f64> = space.vars().iter().map(|&v| lever_world[v]).collect();
        let scale = lever
            .iter()
            .zip(space.weights())
            .map(|(l, c)| l * l / c)
            .sum::<f64>()
            .sqrt();
        let reach = lever.iter().copied().fold(0.0, f64::max);
        (scale > 0.0 && scale.is_finite()).then_some(MotionScale {
            lever,
            reach,
            scale,
        })
    }

    /// The joint-space distance whose straight motion moves the geometry by at most
    /// `workspace_step` metres in total (summed over the joints' contributions).
    pub fn range_for(&self, workspace_step: f64) -> f64 {
        workspace_step / self.scale
    }
}

/// How far one EXTEND step may move the robot's collision geometry, metres (the bound
/// `‖Δq‖ · S` of the module documentation, summed over the joints): the default range is
/// `WORKSPACE_STEP / S`. A workspace distance, the same for every robot; chosen on the
/// MotionBenchMaker Panda sets, where it gives VAMP's own range (1.0 rad); on the Baxter sets
/// (both arms, 14 joints) it gives 0.58 against VAMP's 0.5.
pub const WORKSPACE_STEP: f64 = 2.0;

/// Dynamic-domain radius per unit of the space's maximum extent (OMPL's `getMaximumExtent`,
/// the diagonal of the joint-limit box; OMPL's default range is 0.2 of it): the default radius
/// is `DOMAIN_PER_EXTENT · max_extent`. 0.3 gives the Panda VAMP's radius 4 (extent 13.4 rad)
/// and Baxter's both-arm space 5.3 (extent 17.6 rad; measured on 300 of its problems: a
/// ninth of the iterations of radius 4, and a smaller median time).
pub const DOMAIN_PER_EXTENT: f64 = 0.3;

/// The RRT-Connect settings derived from the robot and the space (see the module
/// documentation): `range = WORKSPACE_STEP / S`, dynamic-domain radius
/// `DOMAIN_PER_EXTENT · max_extent` (never below the range).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DerivedSettings {
    pub motion: MotionScale,
    pub range: f64,
    pub dynamic_domain: f64,
}

impl DerivedSettings {
    /// `None` as [`MotionScale::of`].
    pub fn of(world: &CollisionWorld, space: &JointSpace) -> Option<DerivedSettings> {
        let motion = MotionScale::of(world, space)?;
        let range = motion.range_for(WORKSPACE_STEP);
        Some(DerivedSettings {
            motion,
            range,
            dynamic_domain: (DOMAIN_PER_EXTENT * space.max_extent()).max(range),
        })
    }
}
