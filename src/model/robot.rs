//! `Robot`: links, joints, limits, groups, end effectors, named states and allowed collisions.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use nalgebra::{Unit, Vector3};

use super::joint_limits::VarDynamics;
use super::{srdf, urdf, ModelError};
use crate::geometry::{Geometry, Pose};

/// Kind of a URDF joint. A planar or holonomic base is expressed as two prismatic joints and
/// one revolute joint (see `robots/armar.urdf`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    Revolute,
    Continuous,
    Prismatic,
    Fixed,
}

impl JointKind {
    pub fn name(self) -> &'static str {
        match self {
            JointKind::Revolute => "revolute",
            JointKind::Continuous => "continuous",
            JointKind::Prismatic => "prismatic",
            JointKind::Fixed => "fixed",
        }
    }
}

/// Joint limits. Continuous joints have `lower = -π`, `upper = π` for sampling and
/// `bounded = false` (they may wrap).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    pub lower: f64,
    pub upper: f64,
    pub velocity: f64,
    pub effort: f64,
    pub bounded: bool,
}

impl Limits {
    /// A value drawn uniformly within the limits; unbounded (continuous) joints over [−π, π),
    /// a joint whose limits coincide gets that value.
    pub fn sample<R: rand::Rng + ?Sized>(&self, rng: &mut R) -> f64 {
        if self.bounded && self.upper > self.lower {
            rng.random_range(self.lower..=self.upper)
        } else if self.bounded {
            self.lower
        } else {
            rng.random_range(-std::f64::consts::PI..std::f64::consts::PI)
        }
    }

    /// True when `v` lies within the position limits (always true for unbounded joints).
    pub fn contains(&self, v: f64) -> bool {
        !self.bounded || (v >= self.lower && v <= self.upper)
    }

    /// How far outside its limits a given start or goal value may lie and still be accepted
    /// (then clamped): values written with fewer digits than the limits (a problem's π against
    /// a URDF's 3.14159, 2.65e-6 apart) or rounded by a conversion.
    pub const TOLERANCE: f64 = 1e-5;

    /// `v` clamped into the limits when it lies within them or at most [`Self::TOLERANCE`]
    /// outside (`None` beyond that, or when `v` is not finite). Unbounded joints take any
    /// finite value.
    pub fn clamp_near(&self, v: f64) -> Option<f64> {
        if !v.is_finite() {
            return None;
        }
        if !self.bounded {
            return Some(v);
        }
        (v >= self.lower - Self::TOLERANCE && v <= self.upper + Self::TOLERANCE)
            .then(|| v.clamp(self.lower, self.upper))
    }

    /// True for the limits of a continuous joint written as a revolute one: within
    /// [`Self::TOLERANCE`] of ±π (e.g. ±3.14159), so that values ±π are meant to be valid.
    pub fn is_revolute_pi(&self) -> bool {
        use std::f64::consts::PI;
        self.bounded
            && (self.lower + PI).abs() <= Self::TOLERANCE
            && (self.upper - PI).abs() <= Self::TOLERANCE
    }
}

/// A pair of links that collides in (nearly) every configuration of the collision model and
/// was not disabled by the SRDF (found at load by [`crate::collision::always`], then treated as
/// disabled with reason `Always`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlwaysColliding {
    /// Link indices, `a < b`.
    pub a: usize,
    pub b: usize,
    /// Fraction of the sampled configurations in which the pair collides.
    pub fraction: f64,
}

/// A joint that follows another: `value = multiplier * value(joint) + offset`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mimic {
    /// Index of the configuration variable followed.
    pub var: usize,
    pub multiplier: f64,
    pub offset: f64,
}

/// A URDF joint. Joints are stored so that `joints[l - 1]` is the parent joint of `links[l]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    pub name: String,
    pub kind: JointKind,
    pub parent: usize,
    pub child: usize,
    /// Pose of the joint frame in the parent link frame.
    pub origin: Pose,
    pub axis: Unit<Vector3<f64>>,
    pub limits: Limits,
    /// Index in the configuration vector for independent movable joints.
    pub var: Option<usize>,
    pub mimic: Option<Mimic>,
}

impl Joint {
    /// True for revolute, continuous and prismatic joints (mimic joints included).
    pub fn is_movable(&self) -> bool {
        self.kind != JointKind::Fixed
    }
}

/// A link with its collision geometry and its visual geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    pub name: String,
    /// Index of the joint whose child this link is (`None` for the root).
    pub parent_joint: Option<usize>,
    pub collision: Vec<Geometry>,
    /// The URDF's `<visual>` elements, in file order: what a viewer draws. Never used for
    /// collision checking, and never a reason for the robot not to load.
    pub visual: Vec<Visual>,
}

/// One URDF `<visual>` element of a link (URDF spec: `link/visual`): its pose in the link
/// frame and its geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct Visual {
    /// `<visual name>`, if given.
    pub name: Option<String>,
    /// Pose of the geometry in the link frame (`<origin>`).
    pub origin: Pose,
    pub geometry: VisualGeometry,
}

/// The geometry of a [`Visual`]. Mesh files are not read at load (a viewer fetches them when
/// it draws them), so a missing or unreadable visual mesh never stops a robot from loading.
#[derive(Debug, Clone, PartialEq)]
pub enum VisualGeometry {
    /// Full edge lengths (URDF `size`).
    Box {
        size: [f64; 3],
    },
    /// Along the geometry's z axis, centred.
    Cylinder {
        radius: f64,
        length: f64,
    },
    Capsule {
        radius: f64,
        length: f64,
    },
    Sphere {
        radius: f64,
    },
    Mesh {
        /// The `filename` attribute as written.
        filename: String,
        scale: [f64; 3],
        /// The file it names, resolved against the URDF's folder at load (`None`: no such
        /// file there).
        path: Option<std::path::PathBuf>,
    },
    /// A `<visual>` that could not be read, and why (the robot loads without it).
    Invalid {
        reason: String,
    },
}

/// One element of an SRDF group definition, as written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum GroupMember {
    Joint(String),
    Link(String),
    Chain { base_link: String, tip_link: String },
    Group(String),
}

/// An SRDF planning group: an ordered set of configuration variables.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// The elements the group was defined with (for writing it back).
    pub members: Vec<GroupMember>,
    pub name: String,
    /// Configuration variables of the group, in tree order.
    pub vars: Vec<usize>,
    /// Links of the group.
    pub links: Vec<usize>,
    /// `(base link, tip link)` when the group is (or resolves to) a single chain.
    pub chain: Option<(usize, usize)>,
}

/// An SRDF end effector: a hand attached to `parent_link` (its TCP frame).
#[derive(Debug, Clone, PartialEq)]
pub struct EndEffector {
    pub name: String,
    pub parent_link: usize,
    pub group: String,
    pub parent_group: Option<String>,
}

/// An SRDF named state of a group.
#[derive(Debug, Clone, PartialEq)]
pub struct GroupState {
    pub name: String,
    pub group: String,
    /// `(variable, value)` pairs.
    pub values: Vec<(usize, f64)>,
}

/// A robot: kinematic tree, limits and semantic information from URDF + SRDF.
///
/// Links are in topological order (`links[0]` is the root, parents before children) and
/// `joints[l - 1]` is the parent joint of `links[l]`. A configuration is a `[f64]` of length
/// [`Robot::dof`], one value per independent movable joint (`vars`).
#[derive(Debug, Clone, PartialEq)]
pub struct Robot {
    pub name: String,
    pub links: Vec<Link>,
    pub joints: Vec<Joint>,
    /// Joint index of each configuration variable.
    pub vars: Vec<usize>,
    pub groups: Vec<Group>,
    pub end_effectors: Vec<EndEffector>,
    pub group_states: Vec<GroupState>,
    /// `disabled[a * links.len() + b]`: collisions between links a and b are never checked.
    pub disabled: Vec<bool>,
    /// Reasons given in the SRDF (`Adjacent`, `Never`, …) for disabled pairs, `(a, b, reason)`, a < b.
    pub disabled_reasons: Vec<(usize, usize, String)>,
    /// Things in the files that were tolerated but ignored (e.g. SRDF pairs naming absent links).
    pub warnings: Vec<String>,
    /// Link pairs found colliding in (nearly) every configuration at load and therefore
    /// disabled (also listed in `disabled_reasons` with reason `Always`).
    pub always_colliding: Vec<AlwaysColliding>,
    /// Per configuration variable, the limits of the robot's joint-limits file
    /// (`NAME.joint_limits.yaml`, MoveIt's format; [`super::joint_limits`]), none by default.
    pub dynamics: Vec<VarDynamics>,
    link_index: HashMap<String, usize>,
    joint_index: HashMap<String, usize>,
}

impl Robot {
    /// Loads a robot from a URDF file and, optionally, its SRDF. Link pairs colliding in
    /// (nearly) every configuration that the SRDF does not disable are disabled with a warning
    /// ([`crate::collision::always`]).
    pub fn from_files(urdf_path: &Path, srdf_path: Option<&Path>) -> Result<Robot, ModelError> {
        let urdf_text = read(urdf_path)?;
        let base_dir = urdf_path.parent().unwrap_or(Path::new("."));
        let mut robot = urdf::parse(&urdf_text, &urdf_path.display().to_string(), base_dir)?;
        let srdf_text = match srdf_path {
            Some(sp) => {
                let text = read(sp)?;
                srdf::apply(&mut robot, &text, &sp.display().to_string())?;
                Some(text)
            }
            None => None,
        };
        crate::collision::always::disable_always_colliding(
            &mut robot,
            &urdf_text,
            srdf_text.as_deref(),
        );
        // MoveIt's joint limits next to the URDF: NAME.urdf → NAME.joint_limits.yaml.
        let limits = urdf_path.with_extension("joint_limits.yaml");
        if limits.is_file() {
            let text = read(&limits)?;
            robot.apply_joint_limits(&text, &limits.display().to_string())?;
        }
        Ok(robot)
    }

    /// Parses a robot from URDF and SRDF text. `base_dir` resolves relative mesh paths. As
    /// [`Self::from_files`], always-colliding pairs are disabled with a warning.
    pub fn from_strings(
        urdf_text: &str,
        srdf_text: Option<&str>,
        base_dir: &Path,
    ) -> Result<Robot, ModelError> {
        let mut robot = urdf::parse(urdf_text, "robot.urdf", base_dir)?;
        if let Some(s) = srdf_text {
            srdf::apply(&mut robot, s, "robot.srdf")?;
        }
        crate::collision::always::disable_always_colliding(&mut robot, urdf_text, srdf_text);
        Ok(robot)
    }

    pub(crate) fn new_tree(
        name: String,
        links: Vec<Link>,
        joints: Vec<Joint>,
        vars: Vec<usize>,
    ) -> Robot {
        let n = links.len();
        let link_index = links
            .iter()
            .enumerate()
            .map(|(i, l)| (l.name.clone(), i))
            .collect();
        let joint_index = joints
            .iter()
            .enumerate()
            .map(|(i, j)| (j.name.clone(), i))
            .collect();
        let mut r = Robot {
            name,
            links,
            joints,
            vars,
            groups: Vec::new(),
            end_effectors: Vec::new(),
            group_states: Vec::new(),
            disabled: vec![false; n * n],
            disabled_reasons: Vec::new(),
            warnings: Vec::new(),
            always_colliding: Vec::new(),
            dynamics: Vec::new(),
            link_index,
            joint_index,
        };
        for i in 0..n {
            r.disabled[i * n + i] = true;
        }
        r.dynamics = vec![VarDynamics::default(); r.vars.len()];
        r
    }

    /// Applies a joint-limits file's text (MoveIt's `joint_limits.yaml`; `file` names it in
    /// errors) to the robot: [`Self::velocity_limit`] and [`Self::acceleration_limit`].
    pub fn apply_joint_limits(&mut self, text: &str, file: &str) -> Result<(), ModelError> {
        self.dynamics = super::joint_limits::parse_joint_limits(self, text, file)?;
        Ok(())
    }

    /// Velocity limit of variable `v` (rad/s or m/s): the joint-limits file's `max_velocity`,
    /// else the URDF's `<limit velocity>` when finite and > 0, else
    /// [`super::DEFAULT_VELOCITY`].
    pub fn velocity_limit(&self, v: usize) -> f64 {
        if let Some(x) = self.dynamics.get(v).and_then(|d| d.velocity) {
            return x;
        }
        let x = self.var_limits(v).velocity;
        if x.is_finite() && x > 0.0 {
            x
        } else {
            super::DEFAULT_VELOCITY
        }
    }

    /// Acceleration limit of variable `v` (rad/s² or m/s²): the joint-limits file's
    /// `max_acceleration`, else [`super::DEFAULT_ACCELERATION`] (URDF has
    /// none).
    pub fn acceleration_limit(&self, v: usize) -> f64 {
        self.dynamics
            .get(v)
            .and_then(|d| d.acceleration)
            .unwrap_or(super::DEFAULT_ACCELERATION)
    }

    /// Number of configuration variables.
    pub fn dof(&self) -> usize {
        self.vars.len()
    }

    pub fn link(&self, name: &str) -> Option<usize> {
        self.link_index.get(name).copied()
    }

    pub fn joint(&self, name: &str) -> Option<usize> {
        self.joint_index.get(name).copied()
    }

    /// Configuration variable of a joint name.
    pub fn var(&self, joint_name: &str) -> Option<usize> {
        self.joint(joint_name).and_then(|j| self.joints[j].var)
    }

    /// Name of configuration variable `v`.
    pub fn var_name(&self, v: usize) -> &str {
        &self.joints[self.vars[v]].name
    }

    /// Limits of configuration variable `v`.
    pub fn var_limits(&self, v: usize) -> &Limits {
        &self.joints[self.vars[v]].limits
    }

    pub fn group(&self, name: &str) -> Option<&Group> {
        self.groups.iter().find(|g| g.name == name)
    }

    pub fn end_effector(&self, name: &str) -> Option<&EndEffector> {
        self.end_effectors.iter().find(|e| e.name == name)
    }

    /// True when collisions between links `a` and `b` are not checked (same link, or an SRDF
    /// `disable_collisions` pair).
    pub fn is_disabled(&self, a: usize, b: usize) -> bool {
        self.disabled[a * self.links.len() + b]
    }

    pub(crate) fn disable(&mut self, a: usize, b: usize, reason: &str) {
        let n = self.links.len();
        self.disabled[a * n + b] = true;
        self.disabled[b * n + a] = true;
        self.disabled_reasons
            .push((a.min(b), a.max(b), reason.to_string()));
    }

    /// Configuration of all zeros clamped into the limits.
    pub fn zero_config(&self) -> Vec<f64> {
        (0..self.dof())
            .map(|v| {
                let l = self.var_limits(v);
                0.0f64.clamp(l.lower, l.upper)
            })
            .collect()
    }

    /// A named configuration: an SRDF `group_state` applied to the zero configuration.
    /// When several groups define a state of that name, all are applied.
    pub fn named_config(&self, name: &str) -> Option<Vec<f64>> {
        let mut q = self.zero_config();
        let mut found = false;
        for s in self.group_states.iter().filter(|s| s.name == name) {
            found = true;
            for &(v, x) in &s.values {
                q[v] = x;
            }
        }
        found.then_some(q)
    }

    /// Draws the variables `vars` of the full configuration `q` uniformly within their limits
    /// ([`Limits::sample`]); the other values stay.
    pub fn sample_vars<R: rand::Rng + ?Sized>(&self, vars: &[usize], q: &mut [f64], rng: &mut R) {
        for &v in vars {
            q[v] = self.var_limits(v).sample(rng);
        }
    }

    /// Value of every joint (mimic joints resolved) for configuration `q`; fixed joints get 0.
    #[inline]
    pub fn joint_value(&self, joint: usize, q: &[f64]) -> f64 {
        let j = &self.joints[joint];
        if let Some(v) = j.var {
            q[v]
        } else if let Some(m) = j.mimic {
            m.multiplier * q[m.var] + m.offset
        } else {
            0.0
        }
    }

    /// Clamps into the limits every value of `q` lying at most [`Limits::TOLERANCE`] outside
    /// them (values farther out are left for [`Self::check_config`] to refuse).
    pub fn clamp_config(&self, q: &mut [f64]) {
        for (v, x) in q.iter_mut().enumerate().take(self.dof()) {
            if let Some(c) = self.var_limits(v).clamp_near(*x) {
                *x = c;
            }
        }
    }

    /// A full configuration as a problem or a user writes it: values at most
    /// [`Limits::TOLERANCE`] outside their limits are clamped into them
    /// ([`Self::clamp_config`]), then [`Self::check_config`] (length, finiteness, limits).
    pub fn accept_config(&self, q: &mut [f64]) -> Result<(), String> {
        self.clamp_config(q);
        self.check_config(q)
    }

    /// Checks a configuration: length, finiteness and limits (strictly: see
    /// [`Self::accept_config`] for the tolerance). The error names the joint.
    pub fn check_config(&self, q: &[f64]) -> Result<(), String> {
        if q.len() != self.dof() {
            return Err(format!(
                "expected {} values (robot '{}'), got {}",
                self.dof(),
                self.name,
                q.len()
            ));
        }
        for (v, &x) in q.iter().enumerate() {
            let l = self.var_limits(v);
            if !x.is_finite() {
                return Err(format!("{}: value must be finite", self.var_name(v)));
            }
            if !l.contains(x) {
                return Err(format!(
                    "{}: value {x} outside limit [{}, {}]",
                    self.var_name(v),
                    l.lower,
                    l.upper
                ));
            }
        }
        Ok(())
    }

    /// Builds a configuration from `name → value` pairs on top of `base`. Errors name the joint.
    pub fn config_from_map<'a>(
        &self,
        base: &[f64],
        values: impl IntoIterator<Item = (&'a String, &'a f64)>,
    ) -> Result<Vec<f64>, String> {
        let mut q = base.to_vec();
        for (name, &x) in values {
            let v = self
                .var(name)
                .ok_or_else(|| format!("{name}: no such movable joint in robot '{}'", self.name))?;
            q[v] = x;
        }
        self.clamp_config(&mut q);
        self.check_config(&q)?;
        Ok(q)
    }

    /// Path of links from `base` down to `tip` (both included), or `None` if `tip` is not below
    /// `base`.
    pub fn link_path(&self, base: usize, tip: usize) -> Option<Vec<usize>> {
        let mut path = vec![tip];
        let mut l = tip;
        while l != base {
            let j = self.links[l].parent_joint?;
            l = self.joints[j].parent;
            path.push(l);
        }
        path.reverse();
        Some(path)
    }
}

/// Robots by name, shared read-only.
pub type RobotLibrary = HashMap<String, Arc<Robot>>;

fn read(p: &Path) -> Result<String, ModelError> {
    std::fs::read_to_string(p).map_err(|e| ModelError::Io {
        file: p.display().to_string(),
        reason: e.to_string(),
    })
}
