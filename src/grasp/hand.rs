//! A multi-finger hand as the grasp planner of paper 003 §IV-A sees it, derived from the robot's
//! URDF and SRDF: the hand group (its joints), its fingers (the SRDF chain groups whose joints all
//! belong to the hand, from a common palm link to a fingertip), the three IK joints of each
//! finger, the collision shapes of every hand link and each finger's workspace spheres
//! ([`super::finger_workspace`], 003 Alg. 1).
//!
//! A finger is a chain of ≥ 3 variables; its **last three** are the finger's IK joints (003: four
//! 3-DoF fingers). Variables before them (a movable thumb base) are *base joints*, set per grasp to
//! one of `base_steps` values spread over their limits. The fingers are ordered with the one of
//! most variables first (the thumb with its movable base: "we start from the thumb as no stable
//! grasp can be obtained without it"), ties in SRDF order, unless the caller names the order
//! (fingers it does not name follow in the default order).
//! The fingertip is the chain's tip frame; its radius is half the smallest cross-section of the
//! last link with collision geometry (the contact link).

use std::collections::HashMap;
use std::sync::Arc;

use nalgebra::Vector3;
use parry3d_f64::shape::SharedShape;

use super::finger_workspace::{approximate_workspace, workspace_grids, WorkspaceSphere};
use crate::collision::parry_shape;
use crate::geometry::{Pose, Shape};
use crate::kinematics::{Chain, NumericIk};
use crate::model::Robot;

/// Why a hand cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HandError {
    #[error("hand: robot '{robot}' has no group '{group}'")]
    NoGroup { robot: String, group: String },
    #[error("hand: group '{group}' has {found} finger(s) (SRDF chain groups of ≥ 3 joints all in the hand); a precision grasp needs ≥ 3")]
    NoFingers { group: String, found: usize },
    #[error("hand: the fingers of '{group}' start at different links ({a}, {b})")]
    TwoPalms { group: String, a: String, b: String },
    #[error("fingers: '{0}' is not a finger of the hand")]
    UnknownFinger(String),
}

impl HandError {
    pub fn field(&self) -> &'static str {
        match self {
            HandError::UnknownFinger(_) => "fingers",
            _ => "hand",
        }
    }
}

/// How the fingers' workspaces are approximated (003 Alg. 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorkspaceParams {
    /// Grid values per joint (W and E grids).
    pub steps: usize,
    /// Most spheres per finger (k_max).
    pub max_spheres: usize,
    /// Smallest sphere radius (r_min, m); `None`: half the finger's tip radius.
    pub min_radius: Option<f64>,
}

/// One finger (module docs).
#[derive(Debug, Clone)]
pub struct Finger {
    /// Its SRDF group.
    pub group: String,
    pub tip_link: usize,
    /// Robot variables before the IK joints (a thumb base), in chain order.
    pub base_vars: Vec<usize>,
    /// The three IK variables, in chain order.
    pub ik_vars: Vec<usize>,
    /// The link the IK joints hang from (its frame holds the workspace spheres).
    pub ik_base: usize,
    /// Position-only numeric IK of `ik_base → tip`.
    pub ik: NumericIk,
    /// The chain `ik_base → tip` (its Jacobian gives the force ellipsoid).
    pub ik_chain: Chain,
    /// Links of the finger with collision geometry, base to tip.
    pub links: Vec<usize>,
    /// Those of `links` moved only by the base variables.
    pub base_links: Vec<usize>,
    /// The last link with geometry: the one that touches the object.
    pub contact_link: usize,
    /// Fingertip radius (m).
    pub tip_radius: f64,
    /// The stretched configuration (each IK variable nearest 0 within its limits).
    pub rest: [f64; 3],
    /// Mid-range configuration (the other rest candidate, and the IK seed).
    pub mid: [f64; 3],
    /// Workspace spheres in the `ik_base` frame, biggest first.
    pub workspace: Vec<WorkspaceSphere>,
}

/// A hand (module docs).
#[derive(Debug, Clone)]
pub struct Hand {
    pub robot: Arc<Robot>,
    pub group: String,
    /// The common base link of the fingers (the hand frame of a grasp).
    pub palm: usize,
    /// Hand links with geometry moved by no finger variable (the palm).
    pub palm_links: Vec<usize>,
    /// Thumb first (module docs).
    pub fingers: Vec<Finger>,
    /// The hand group's variables.
    pub vars: Vec<usize>,
    /// Collision shapes of each hand link (link frame).
    pub shapes: HashMap<usize, Vec<(SharedShape, Pose)>>,
    /// Palm → link chains of the hand's links with geometry and of the IK bases.
    chains: HashMap<usize, Chain>,
}

fn tip_radius(shape: &Shape) -> f64 {
    match shape {
        Shape::Box { half_extents: h } => h.min(),
        Shape::Cylinder { radius, .. } | Shape::Capsule { radius, .. } => *radius,
        Shape::Sphere { radius } => *radius,
        Shape::Mesh(m) => {
            let (lo, hi) = m.aabb();
            ((hi - lo) / 2.0).min()
        }
    }
}

impl Hand {
    /// The hand of `robot`'s group `group`; `order` names the fingers' order (first = the
    /// thumb), `None` for the default (module docs).
    pub fn new(
        robot: Arc<Robot>,
        group: &str,
        order: Option<&[String]>,
        ws: &WorkspaceParams,
    ) -> Result<Hand, HandError> {
        let g = robot.group(group).ok_or_else(|| HandError::NoGroup {
            robot: robot.name.clone(),
            group: group.to_string(),
        })?;
        let vars = g.vars.clone();
        let mut found: Vec<(String, Chain)> = Vec::new();
        for fg in &robot.groups {
            let Some((b, t)) = fg.chain else { continue };
            let Some(chain) = Chain::new(&robot, b, t) else {
                continue;
            };
            if fg.name != group
                && chain.vars.len() >= 3
                && chain.vars.len() < vars.len()
                && chain.vars.iter().all(|v| vars.contains(v))
            {
                found.push((fg.name.clone(), chain));
            }
        }
        if found.len() < 3 {
            return Err(HandError::NoFingers {
                group: group.to_string(),
                found: found.len(),
            });
        }
        let palm = found[0].1.base_link;
        if let Some((_, c)) = found.iter().find(|(_, c)| c.base_link != palm) {
            return Err(HandError::TwoPalms {
                group: group.to_string(),
                a: robot.links[palm].name.clone(),
                b: robot.links[c.base_link].name.clone(),
            });
        }
        match order {
            Some(names) => {
                let mut ordered = Vec::new();
                for n in names {
                    let i = found
                        .iter()
                        .position(|(g, _)| g == n)
                        .ok_or_else(|| HandError::UnknownFinger(n.clone()))?;
                    ordered.push(found.remove(i));
                }
                // Fingers not named follow, most joints first.
                found.sort_by_key(|(_, c)| std::cmp::Reverse(c.vars.len()));
                ordered.append(&mut found);
                found = ordered;
            }
            None => found.sort_by_key(|(_, c)| std::cmp::Reverse(c.vars.len())),
        }
        let mut chains = HashMap::new();
        let mut shapes = HashMap::new();
        let add_link = |l: usize, chains: &mut HashMap<usize, Chain>| {
            if let Some(c) = Chain::new(&robot, palm, l) {
                chains.insert(l, c);
            }
        };
        let mut fingers = Vec::new();
        let mut finger_links = Vec::new();
        for (name, chain) in found {
            let n = chain.vars.len();
            let ik_vars = chain.vars[n - 3..].to_vec();
            let base_vars = chain.vars[..n - 3].to_vec();
            let first_ik_joint = chain
                .joints
                .iter()
                .copied()
                .find(|&j| robot.joints[j].var == Some(ik_vars[0]))
                .unwrap_or(chain.joints[0]);
            let ik_base = robot.joints[first_ik_joint].parent;
            let ik_chain = Chain::new(&robot, ik_base, chain.tip_link).unwrap_or(chain.clone());
            let mut ik = NumericIk::new(&robot, &ik_chain);
            ik.settings.position_only = true;
            ik.settings.tolerance = 1e-5;
            ik.settings.max_iterations = 40;
            ik.settings.max_restarts = 1;
            let path = robot
                .link_path(palm, chain.tip_link)
                .unwrap_or_else(|| vec![palm, chain.tip_link]);
            let ik_base_pos = path.iter().position(|&l| l == ik_base).unwrap_or(0);
            let mut links = Vec::new();
            let mut base_links = Vec::new();
            for (i, &l) in path.iter().enumerate().skip(1) {
                if !robot.links[l].collision.is_empty() {
                    links.push(l);
                    if i <= ik_base_pos {
                        base_links.push(l);
                    }
                }
            }
            let contact_link = *links.last().unwrap_or(&chain.tip_link);
            let radius = robot.links[contact_link]
                .collision
                .iter()
                .map(|g| tip_radius(&g.shape))
                .fold(f64::INFINITY, f64::min);
            let tip_r = if radius.is_finite() { radius } else { 0.005 };
            let lim = |v: usize| {
                let l = robot.var_limits(v);
                (l.lower, l.upper)
            };
            let limits = [lim(ik_vars[0]), lim(ik_vars[1]), lim(ik_vars[2])];
            let rest = limits.map(|(lo, hi)| 0.0f64.clamp(lo, hi));
            let mid = limits.map(|(lo, hi)| (lo + hi) / 2.0);
            let mut tip = |q: &[f64; 3]| ik.fk(q).translation.vector;
            let (w, e) = workspace_grids(&mut tip, &limits, ws.steps);
            let workspace =
                approximate_workspace(&w, &e, ws.max_spheres, ws.min_radius.unwrap_or(tip_r / 2.0));
            for &l in &links {
                add_link(l, &mut chains);
                finger_links.push(l);
            }
            add_link(ik_base, &mut chains);
            fingers.push(Finger {
                group: name,
                tip_link: chain.tip_link,
                base_vars,
                ik_vars,
                ik_base,
                ik,
                ik_chain,
                links,
                base_links,
                contact_link,
                tip_radius: tip_r,
                rest,
                mid,
                workspace,
            });
        }
        let mut palm_links = Vec::new();
        for &l in &g.links {
            if !robot.links[l].collision.is_empty() && !finger_links.contains(&l) {
                palm_links.push(l);
            }
        }
        if !robot.links[palm].collision.is_empty() && !palm_links.contains(&palm) {
            palm_links.insert(0, palm);
        }
        for &l in palm_links.iter().chain(finger_links.iter()) {
            add_link(l, &mut chains);
            let s: Vec<(SharedShape, Pose)> =
                robot.links[l].collision.iter().map(parry_shape).collect();
            shapes.insert(l, s);
        }
        Ok(Hand {
            robot,
            group: group.to_string(),
            palm,
            palm_links,
            fingers,
            vars,
            shapes,
            chains,
        })
    }

    /// Pose of `link` in the palm frame at robot configuration `q`.
    pub fn link_in_palm(&self, link: usize, q: &[f64]) -> Pose {
        if link == self.palm {
            return Pose::identity();
        }
        match self.chains.get(&link) {
            Some(c) => c.tip_pose(&self.robot, q),
            None => Pose::identity(),
        }
    }

    /// The centre of the fingers' workspaces in the palm frame (003 §IV-A-1: the grasp frame
    /// "centered on the intersection of the finger workspaces"): the mean of each finger's
    /// biggest sphere centre, base joints at mid-range.
    pub fn workspace_centre(&self, q: &[f64]) -> Vector3<f64> {
        let mut acc = Vector3::zeros();
        let mut n = 0.0;
        for f in &self.fingers {
            if let Some(s) = f.workspace.first() {
                acc += self.link_in_palm(f.ik_base, q) * nalgebra::Point3::from(s.centre).coords;
                n += 1.0;
            }
        }
        if n > 0.0 {
            acc / n
        } else {
            Vector3::zeros()
        }
    }

    /// A robot configuration with the hand's base joints at mid-range, each finger stretched,
    /// every other variable 0 clamped into its limits.
    pub fn base_config(&self) -> Vec<f64> {
        let mut q = self.robot.zero_config();
        for f in &self.fingers {
            for &v in &f.base_vars {
                let l = self.robot.var_limits(v);
                q[v] = (l.lower + l.upper) / 2.0;
            }
            for k in 0..3 {
                q[f.ik_vars[k]] = f.rest[k];
            }
        }
        q
    }
}

/// A workspace sphere placed by `pose`.
pub fn transform_sphere(pose: &Pose, s: &WorkspaceSphere) -> WorkspaceSphere {
    WorkspaceSphere {
        centre: (pose * nalgebra::Point3::from(s.centre)).coords,
        radius: s.radius,
    }
}
