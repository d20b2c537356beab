//! The joint space of some world variables (OMPL's `RealVectorStateSpace` with per-dimension
//! weights): bounds from the joint limits, weighted Euclidean distance, straight-line
//! interpolation and uniform sampling. Variables outside the space keep the values of a fixed
//! base world configuration.

use rand::Rng;

use crate::collision::CollisionWorld;
use crate::planning::PlanError;

/// A configuration space made of selected variables of a [`CollisionWorld`] configuration.
///
/// States are `dim()` values in the order of [`JointSpace::vars`]. Continuous (unbounded)
/// joints are treated as the interval [-π, π] without wrap-around, so straight-line
/// interpolation always stays in the bounds.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSpace {
    vars: Vec<usize>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    weights: Vec<f64>,
    names: Vec<String>,
    base: Vec<f64>,
}

impl JointSpace {
    /// The space of the world variables `vars` (indices into a world configuration), the others
    /// held at `base` (a full world configuration). Weights are 1.
    pub fn new(
        world: &CollisionWorld,
        vars: &[usize],
        base: Vec<f64>,
    ) -> Result<JointSpace, PlanError> {
        let dof = world.dof();
        if base.len() != dof {
            return Err(PlanError::InvalidInput(format!(
                "base configuration has {} values, the world has {dof} variables",
                base.len()
            )));
        }
        if let Some(i) = base.iter().position(|v| !v.is_finite()) {
            return Err(PlanError::InvalidInput(format!(
                "base configuration value {i} is not finite"
            )));
        }
        if vars.is_empty() {
            return Err(PlanError::InvalidInput(
                "a joint space needs at least one variable".into(),
            ));
        }
        let mut lower = Vec::with_capacity(vars.len());
        let mut upper = Vec::with_capacity(vars.len());
        let mut names = Vec::with_capacity(vars.len());
        for (k, &w) in vars.iter().enumerate() {
            if vars[..k].contains(&w) {
                return Err(PlanError::InvalidInput(format!(
                    "world variable {w} selected twice"
                )));
            }
            let p = world
                .robots
                .iter()
                .find(|p| w >= p.offset && w < p.offset + p.robot.dof())
                .ok_or_else(|| {
                    PlanError::InvalidInput(format!(
                        "world variable {w} does not exist (world has {dof})"
                    ))
                })?;
            let v = w - p.offset;
            let l = p.robot.var_limits(v);
            if !(l.lower.is_finite() && l.upper.is_finite() && l.lower <= l.upper) {
                return Err(PlanError::InvalidInput(format!(
                    "{}/{}: limits [{}, {}] are not a finite interval",
                    p.name,
                    p.robot.var_name(v),
                    l.lower,
                    l.upper
                )));
            }
            lower.push(l.lower);
            upper.push(l.upper);
            names.push(format!("{}/{}", p.name, p.robot.var_name(v)));
        }
        Ok(JointSpace {
            vars: vars.to_vec(),
            lower,
            upper,
            weights: vec![1.0; vars.len()],
            names,
            base,
        })
    }

    /// The space of every variable of the world.
    pub fn all(world: &CollisionWorld, base: Vec<f64>) -> Result<JointSpace, PlanError> {
        let vars: Vec<usize> = (0..world.dof()).collect();
        JointSpace::new(world, &vars, base)
    }

    /// Sets the per-dimension distance weights (finite, > 0).
    pub fn with_weights(mut self, weights: Vec<f64>) -> Result<JointSpace, PlanError> {
        if weights.len() != self.dim() {
            return Err(PlanError::InvalidInput(format!(
                "{} weights for a {}-dimensional space",
                weights.len(),
                self.dim()
            )));
        }
        if let Some(i) = weights.iter().position(|w| !(w.is_finite() && *w > 0.0)) {
            return Err(PlanError::InvalidInput(format!(
                "weight {i} must be finite and > 0"
            )));
        }
        self.weights = weights;
        Ok(self)
    }

    /// Narrows the bounds of dimension `k` to `[lo, hi]` ∩ its joint limits (e.g. a mobile base's
    /// x, y to the region of a task).
    pub fn with_bounds(mut self, k: usize, lo: f64, hi: f64) -> Result<JointSpace, PlanError> {
        if k >= self.dim() {
            return Err(PlanError::InvalidInput(format!(
                "dimension {k} of a {}-dimensional space",
                self.dim()
            )));
        }
        let (l, u) = (self.lower[k].max(lo), self.upper[k].min(hi));
        if !(l.is_finite() && u.is_finite() && l <= u) {
            return Err(PlanError::InvalidInput(format!(
                "{}: bounds [{lo}, {hi}] do not meet the limits [{}, {}]",
                self.names[k], self.lower[k], self.upper[k]
            )));
        }
        self.lower[k] = l;
        self.upper[k] = u;
        Ok(self)
    }

    /// Number of dimensions.
    #[inline]
    pub fn dim(&self) -> usize {
        self.vars.len()
    }

    /// World-configuration index of every dimension.
    pub fn vars(&self) -> &[usize] {
        &self.vars
    }

    pub fn lower(&self) -> &[f64] {
        &self.lower
    }

    pub fn upper(&self) -> &[f64] {
        &self.upper
    }

    pub fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// `robot/joint` name of every dimension.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The world configuration supplying the variables outside the space.
    pub fn base(&self) -> &[f64] {
        &self.base
    }

    /// Weighted distance of the two bounds' corners (OMPL's `getMaximumExtent`).
    pub fn max_extent(&self) -> f64 {
        self.distance(&self.lower, &self.upper)
    }

    /// Weighted Euclidean distance `sqrt(Σ wᵢ (aᵢ − bᵢ)²)`.
    #[inline]
    pub fn distance(&self, a: &[f64], b: &[f64]) -> f64 {
        self.distance_sq(a, b).sqrt()
    }

    /// Squared weighted distance.
    #[inline]
    pub fn distance_sq(&self, a: &[f64], b: &[f64]) -> f64 {
        let mut s = 0.0;
        for i in 0..self.vars.len() {
            let d = a[i] - b[i];
            s += self.weights[i] * d * d;
        }
        s
    }

    /// `out = a + t (b − a)`.
    #[inline]
    pub fn interpolate(&self, a: &[f64], b: &[f64], t: f64, out: &mut [f64]) {
        for i in 0..self.vars.len() {
            out[i] = a[i] + (b[i] - a[i]) * t;
        }
    }

    /// A state drawn uniformly within the bounds.
    #[inline]
    pub fn sample_uniform<R: Rng + ?Sized>(&self, rng: &mut R, out: &mut [f64]) {
        for ((o, lo), hi) in out.iter_mut().zip(&self.lower).zip(&self.upper) {
            *o = lo + (hi - lo) * rng.random::<f64>();
        }
    }

    /// [`Self::sample_uniform`] with the planners' vectorised generator
    /// ([`PlannerRng::fill_uniform`](crate::planning::PlannerRng::fill_uniform): two vectors of values
    /// per step, 32 random bits each).
    #[inline]
    pub fn sample_uniform_fast(&self, rng: &mut crate::planning::PlannerRng, out: &mut [f64]) {
        rng.fill_uniform(&self.lower, &self.upper, out);
    }

    /// True when `q` has `dim()` finite values within the bounds.
    pub fn satisfies_bounds(&self, q: &[f64]) -> bool {
        q.len() == self.dim()
            && q.iter()
                .enumerate()
                .all(|(i, v)| v.is_finite() && *v >= self.lower[i] && *v <= self.upper[i])
    }

    /// `q` with every value lying at most [`Limits::TOLERANCE`](crate::model::Limits::TOLERANCE)
    /// outside the bounds clamped into them (a start or goal written with fewer digits than the
    /// limits, e.g. π against 3.14159); `q` itself when no value needs it. Values farther out
    /// stay, for [`Self::bounds_violation`] to name.
    pub fn snap_to_bounds<'a>(&self, q: &'a [f64]) -> std::borrow::Cow<'a, [f64]> {
        let tol = crate::model::Limits::TOLERANCE;
        let near = |i: usize, v: f64| {
            (v < self.lower[i] && v >= self.lower[i] - tol)
                || (v > self.upper[i] && v <= self.upper[i] + tol)
        };
        if q.len() != self.dim() || !q.iter().enumerate().any(|(i, &v)| near(i, v)) {
            return std::borrow::Cow::Borrowed(q);
        }
        std::borrow::Cow::Owned(
            q.iter()
                .enumerate()
                .map(|(i, &v)| {
                    if near(i, v) {
                        v.clamp(self.lower[i], self.upper[i])
                    } else {
                        v
                    }
                })
                .collect(),
        )
    }

    /// Why `q` is not a state of the space (`None` when it is).
    pub fn bounds_violation(&self, q: &[f64]) -> Option<String> {
        if q.len() != self.dim() {
            return Some(format!(
                "{} values for a {}-dimensional space",
                q.len(),
                self.dim()
            ));
        }
        q.iter().enumerate().find_map(|(i, v)| {
            (!(v.is_finite() && *v >= self.lower[i] && *v <= self.upper[i])).then(|| {
                format!(
                    "{} = {v} outside [{}, {}]",
                    self.names[i], self.lower[i], self.upper[i]
                )
            })
        })
    }

    /// Writes the state's variables into a world configuration (others untouched).
    #[inline]
    pub fn write_world(&self, q: &[f64], world_q: &mut [f64]) {
        for (i, &w) in self.vars.iter().enumerate() {
            world_q[w] = q[i];
        }
    }

    /// The full world configuration of a state (base values elsewhere).
    pub fn to_world(&self, q: &[f64]) -> Vec<f64> {
        let mut w = self.base.clone();
        self.write_world(q, &mut w);
        w
    }

    /// The world configurations of a path of states.
    pub fn path_to_world(&self, path: &[Vec<f64>]) -> Vec<Vec<f64>> {
        path.iter().map(|q| self.to_world(q)).collect()
    }

    /// The space's variables of a world configuration.
    pub fn from_world(&self, world_q: &[f64]) -> Vec<f64> {
        self.vars.iter().map(|&w| world_q[w]).collect()
    }

    /// Sum of the distances between consecutive states.
    pub fn path_length(&self, path: &[Vec<f64>]) -> f64 {
        path.windows(2).map(|w| self.distance(&w[0], &w[1])).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Pose;
    use std::sync::Arc;

    /// `write_world` puts each variable at its world index, whether the space's variables are
    /// the leading ones of the world or any others; `interpolate` is
    /// `a + (b − a)·t` per variable.
    #[test]
    fn write_world_and_interpolate() {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/robots");
        let robot = Arc::new(
            crate::Robot::from_files(
                &dir.join("twin_arms.urdf"),
                Some(&dir.join("twin_arms.srdf")),
            )
            .expect("tests/robots/twin_arms"),
        );
        let world = CollisionWorld::single(robot.clone(), Pose::identity());
        let dof = world.dof();
        assert!(dof >= 6);
        let base: Vec<f64> = (0..dof).map(|i| 0.01 * i as f64).collect();
        for vars in [vec![0, 1, 2], vec![2, 0, 5], (0..dof).collect::<Vec<_>>()] {
            let space = JointSpace::new(&world, &vars, base.clone()).expect("space");
            let q: Vec<f64> = (0..vars.len()).map(|i| -0.1 * (i + 1) as f64).collect();
            let mut w = base.clone();
            space.write_world(&q, &mut w);
            let mut expect = base.clone();
            for (i, &v) in vars.iter().enumerate() {
                expect[v] = q[i];
            }
            assert_eq!(w, expect, "{vars:?}");
            assert_eq!(space.to_world(&q), expect);
            let b: Vec<f64> = q.iter().map(|x| x + 0.3).collect();
            let mut out = vec![0.0; q.len()];
            space.interpolate(&q, &b, 0.25, &mut out);
            for i in 0..q.len() {
                assert_eq!(out[i], q[i] + (b[i] - q[i]) * 0.25);
            }
        }
    }
}
