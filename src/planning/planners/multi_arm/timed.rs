//! Timed motions of some arms on one clock, piecewise linear in time (each segment at a
//! constant velocity within the joints' limits, a robot holding its last configuration after
//! its end): what prioritized planning plans against ([`super::space_time`]), and how several
//! of them become one composite polyline.
//!
//! **Why the polyline carries the certificate.** Cut at the union of all knot times, every
//! timed motion is linear in time on each piece, so the composite configuration moves on a
//! straight line of the composite space there. The composite polyline through the cut points
//! is therefore exactly the set of states the timed motions pass through together, and any
//! re-timing that keeps the polyline (the time-optimal one of [`crate::trajectory::timing`])
//! keeps every state it reaches collision-free: the certificate ([`super::cell`]) is a
//! property of the polyline, not of its timing.

/// The motion of some world variables: knot times (non-decreasing, from 0) and the values at
/// each knot.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Timed {
    /// World variable indices.
    pub vars: Vec<usize>,
    pub times: Vec<f64>,
    pub points: Vec<Vec<f64>>,
}

/// The time a straight motion a → b takes at the velocity limits `vel` (the slowest joint's).
pub(crate) fn travel_time(a: &[f64], b: &[f64], vel: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .zip(vel)
        .map(|((x, y), v)| (y - x).abs() / v)
        .fold(0.0, f64::max)
}

impl Timed {
    /// `path` run at the velocity limits from time 0.
    pub fn at_speed(vars: Vec<usize>, path: &[Vec<f64>], vel: &[f64]) -> Timed {
        let mut times = vec![0.0];
        for w in path.windows(2) {
            let t = times[times.len() - 1] + travel_time(&w[0], &w[1], vel);
            times.push(t);
        }
        Timed {
            vars,
            times,
            points: path.to_vec(),
        }
    }

    /// When the motion ends.
    pub fn end(&self) -> f64 {
        self.times.last().copied().unwrap_or(0.0)
    }

    /// The values at time `t` into `out` (the first before 0, the last after the end).
    pub fn at(&self, t: f64, out: &mut [f64]) {
        let n = self.times.len();
        if t <= self.times[0] || n == 1 {
            out.copy_from_slice(&self.points[0]);
            return;
        }
        if t >= self.times[n - 1] {
            out.copy_from_slice(&self.points[n - 1]);
            return;
        }
        let j = self.times.partition_point(|&x| x <= t).clamp(1, n - 1) - 1;
        let (t0, t1) = (self.times[j], self.times[j + 1]);
        let s = if t1 > t0 { (t - t0) / (t1 - t0) } else { 1.0 };
        for ((o, &a), &b) in out.iter_mut().zip(&self.points[j]).zip(&self.points[j + 1]) {
            *o = a + (b - a) * s;
        }
    }

    /// Writes the values at `t` into a world configuration.
    pub fn write_world(&self, t: f64, buf: &mut Vec<f64>, q: &mut [f64]) {
        buf.resize(self.vars.len(), 0.0);
        self.at(t, buf);
        for (&v, &x) in self.vars.iter().zip(buf.iter()) {
            q[v] = x;
        }
    }

    /// Knot times strictly inside (a, b).
    pub fn knots_within(&self, a: f64, b: f64, out: &mut Vec<f64>) {
        out.extend(self.times.iter().copied().filter(|&t| t > a && t < b));
    }
}

/// The composite polyline of timed motions that together cover the composite variables
/// `vars` (each composite variable in exactly one motion), starting from `start`: one vertex
/// at every knot time of any motion (module documentation); repeated vertices dropped.
pub(crate) fn merge(vars: &[usize], start: &[f64], motions: &[Timed]) -> Vec<Vec<f64>> {
    let mut times: Vec<f64> = motions.iter().flat_map(|m| m.times.clone()).collect();
    times.push(0.0);
    times.sort_by(f64::total_cmp);
    times.dedup();
    // Where each motion's variables go in the composite configuration.
    let slots: Vec<Vec<usize>> = motions
        .iter()
        .map(|m| {
            m.vars
                .iter()
                .map(|w| vars.iter().position(|v| v == w).unwrap_or(usize::MAX))
                .collect()
        })
        .collect();
    let mut out: Vec<Vec<f64>> = Vec::with_capacity(times.len());
    let mut buf = Vec::new();
    for &t in &times {
        let mut c = start.to_vec();
        for (m, slot) in motions.iter().zip(&slots) {
            buf.resize(m.vars.len(), 0.0);
            m.at(t, &mut buf);
            for (&s, &x) in slot.iter().zip(&buf) {
                if let Some(c) = c.get_mut(s) {
                    *c = x;
                }
            }
        }
        if out.last() != Some(&c) {
            out.push(c);
        }
    }
    out
}
