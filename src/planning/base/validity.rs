//! State and motion validity in a [`JointSpace`] (OMPL's `StateValidityChecker` and
//! `DiscreteMotionValidator`): bounds plus a [`CollisionChecker`] on the world configuration,
//! segments through the checker's own segment check — for the planners' [`FastChecker`] a
//! certified check of the continuous segment ([`FastChecker::segment_free`]), for the sphere
//! checker its 8-lane check of the states, certified too when asked
//! ([`SegmentChecker::segment_certified`]) — or the collision module's [`MotionValidator`] (fixed
//! resolution, bisection order) for checkers without one (the exact checker).

use crate::collision::{
    AutoChecker, CertifyStats, CollisionChecker, CollisionWorld, Contact, ExactChecker,
    FastChecker, MotionValidator, SegmentScreen, SphereChecker,
};
use crate::planning::JointSpace;

/// A collision checker that may check a whole straight segment itself (e.g. several states per
/// call in SIMD lanes). The default answers `None`: the states are then checked one by one in
/// bisection order by the collision module's [`MotionValidator`].
pub trait SegmentChecker: CollisionChecker {
    /// `Some(true)` when every state `a + (b − a)·k/n`, k = 1..=n, is free (world
    /// configurations); `None` when this checker has no segment check of its own.
    #[inline]
    fn segment_free(&mut self, _a: &[f64], _b: &[f64], _n: usize) -> Option<bool> {
        None
    }

    /// `Some(true)` when the whole continuous segment `a → b` is certified collision-free with
    /// swept-volume bounds (inflations of at most `max_inflation` metres, see
    /// [`SphereChecker::segment_certified`]); `None` when this checker cannot certify.
    #[inline]
    fn segment_certified(&mut self, _a: &[f64], _b: &[f64], _max_inflation: f64) -> Option<bool> {
        None
    }

    /// The first pass of [`Self::segment_certified`] alone (see
    /// [`SphereChecker::segment_screened`]); `None` when this checker has no such pass (lazy
    /// planners then certify every segment at once).
    #[inline]
    fn segment_screened(
        &mut self,
        _a: &[f64],
        _b: &[f64],
        _max_inflation: f64,
    ) -> Option<SegmentScreen> {
        None
    }

    /// Appends to `out` what [`Self::segment_certified_screened`] needs of the last
    /// [`Self::segment_screened`] that answered [`SegmentScreen::Tight`] (opaque entries; see
    /// [`SphereChecker::screened_tight`]). The default appends nothing.
    #[inline]
    fn screen_record(&self, _out: &mut Vec<(usize, u32)>) {}

    /// [`Self::segment_certified`] of a segment screened [`SegmentScreen::Tight`], from its
    /// [`Self::screen_record`] (the same verdict without the first pass again, see
    /// [`SphereChecker::segment_certified_screened`]); `None` when this checker cannot.
    #[inline]
    fn segment_certified_screened(
        &mut self,
        _a: &[f64],
        _b: &[f64],
        _max_inflation: f64,
        _record: &[(usize, u32)],
    ) -> Option<bool> {
        None
    }

    /// Counts of the certified motion checks since the last [`Self::reset_certify_stats`],
    /// when this checker certifies its segment checks.
    fn certify_stats(&self) -> Option<CertifyStats> {
        None
    }

    /// Starts the counts of [`Self::certify_stats`] again.
    fn reset_certify_stats(&mut self) {}
}

impl SegmentChecker for FastChecker {
    /// Certified by default ([`FastChecker::segment_free`]): `Some(true)` only when the
    /// continuous motion is proven free.
    #[inline]
    fn segment_free(&mut self, a: &[f64], b: &[f64], n: usize) -> Option<bool> {
        FastChecker::segment_free(self, a, b, n)
    }

    #[inline]
    fn segment_certified(&mut self, a: &[f64], b: &[f64], max_inflation: f64) -> Option<bool> {
        Some(FastChecker::segment_certified(self, a, b, max_inflation))
    }

    fn certify_stats(&self) -> Option<CertifyStats> {
        self.certification()
            .is_some()
            .then(|| FastChecker::certify_stats(self))
    }

    fn reset_certify_stats(&mut self) {
        FastChecker::reset_certify_stats(self)
    }
}
impl SegmentChecker for ExactChecker {}

impl SegmentChecker for SphereChecker {
    #[inline]
    fn segment_free(&mut self, a: &[f64], b: &[f64], n: usize) -> Option<bool> {
        Some(SphereChecker::segment_free(self, a, b, n))
    }

    #[inline]
    fn segment_certified(&mut self, a: &[f64], b: &[f64], max_inflation: f64) -> Option<bool> {
        self.certifiable()
            .then(|| SphereChecker::segment_certified(self, a, b, max_inflation))
    }

    #[inline]
    fn segment_screened(
        &mut self,
        a: &[f64],
        b: &[f64],
        max_inflation: f64,
    ) -> Option<SegmentScreen> {
        self.certifiable()
            .then(|| SphereChecker::segment_screened(self, a, b, max_inflation))
    }

    #[inline]
    fn screen_record(&self, out: &mut Vec<(usize, u32)>) {
        out.extend_from_slice(self.screened_tight());
    }

    #[inline]
    fn segment_certified_screened(
        &mut self,
        a: &[f64],
        b: &[f64],
        max_inflation: f64,
        record: &[(usize, u32)],
    ) -> Option<bool> {
        self.certifiable()
            .then(|| SphereChecker::segment_certified_screened(self, a, b, max_inflation, record))
    }
}

impl SegmentChecker for AutoChecker {
    #[inline]
    fn segment_free(&mut self, a: &[f64], b: &[f64], n: usize) -> Option<bool> {
        AutoChecker::segment_free(self, a, b, n)
    }

    #[inline]
    fn segment_certified(&mut self, a: &[f64], b: &[f64], max_inflation: f64) -> Option<bool> {
        match self {
            AutoChecker::Spheres(s) => SegmentChecker::segment_certified(s, a, b, max_inflation),
            AutoChecker::Fast(f) => SegmentChecker::segment_certified(f, a, b, max_inflation),
        }
    }

    #[inline]
    fn segment_screened(
        &mut self,
        a: &[f64],
        b: &[f64],
        max_inflation: f64,
    ) -> Option<SegmentScreen> {
        match self {
            AutoChecker::Spheres(s) => SegmentChecker::segment_screened(s, a, b, max_inflation),
            AutoChecker::Fast(f) => SegmentChecker::segment_screened(f, a, b, max_inflation),
        }
    }

    #[inline]
    fn screen_record(&self, out: &mut Vec<(usize, u32)>) {
        match self {
            AutoChecker::Spheres(s) => SegmentChecker::screen_record(s, out),
            AutoChecker::Fast(f) => SegmentChecker::screen_record(f, out),
        }
    }

    #[inline]
    fn segment_certified_screened(
        &mut self,
        a: &[f64],
        b: &[f64],
        max_inflation: f64,
        record: &[(usize, u32)],
    ) -> Option<bool> {
        match self {
            AutoChecker::Spheres(s) => {
                SegmentChecker::segment_certified_screened(s, a, b, max_inflation, record)
            }
            AutoChecker::Fast(f) => {
                SegmentChecker::segment_certified_screened(f, a, b, max_inflation, record)
            }
        }
    }

    fn certify_stats(&self) -> Option<CertifyStats> {
        match self {
            AutoChecker::Spheres(_) => None,
            AutoChecker::Fast(f) => SegmentChecker::certify_stats(f),
        }
    }

    fn reset_certify_stats(&mut self) {
        if let AutoChecker::Fast(f) = self {
            f.reset_certify_stats()
        }
    }
}

/// The fast checker for configurations of `space`: the variables outside it are frozen at
/// the space's base configuration ([`FastChecker::for_active`]).
pub fn space_checker(world: &CollisionWorld, space: &JointSpace) -> FastChecker {
    FastChecker::for_active(world, Default::default(), space.vars(), space.base())
}

/// Checks states, segments and paths of a space with one collision checker. Owns the space and
/// two world-configuration buffers, so no call allocates.
pub struct SpaceValidator<C: SegmentChecker> {
    space: JointSpace,
    motion: MotionValidator<C>,
    wa: Vec<f64>,
    wb: Vec<f64>,
    angular: f64,
    linear: f64,
    /// Segments checked by the checker's own segment check.
    own_segments: u64,
    /// Certify segments continuously (largest inflation, metres) when the checker can.
    certify: Option<f64>,
}

impl<C: SegmentChecker> SpaceValidator<C> {
    /// Segments are checked so that no revolute variable moves more than `angular` radians and no
    /// prismatic one more than `linear` metres between two checked states.
    pub fn new(
        space: JointSpace,
        world: &CollisionWorld,
        checker: C,
        angular: f64,
        linear: f64,
    ) -> Self {
        let wa = space.base().to_vec();
        let wb = wa.clone();
        SpaceValidator {
            motion: MotionValidator::new(world, checker, angular, linear),
            space,
            wa,
            wb,
            angular,
            linear,
            own_segments: 0,
            certify: None,
        }
    }

    /// Segments are certified collision-free as continuous motions (swept-volume bounds with
    /// inflations of at most `max_inflation` metres) when the checker can; other checkers keep
    /// checking states at the resolution. `None` switches back to states at the resolution.
    pub fn with_certification(mut self, max_inflation: Option<f64>) -> Self {
        self.certify = max_inflation.filter(|d| d.is_finite() && *d > 0.0);
        self
    }

    /// The largest inflation of certified segment checks, when they are on.
    pub fn certification(&self) -> Option<f64> {
        self.certify
    }

    pub fn space(&self) -> &JointSpace {
        &self.space
    }

    /// The resolution `(angular rad, linear m)` segments are checked at.
    pub fn resolution(&self) -> (f64, f64) {
        (self.angular, self.linear)
    }

    pub fn checker(&mut self) -> &mut C {
        &mut self.motion.checker
    }

    /// Configuration checks performed so far by the checker.
    pub fn checks(&self) -> u64 {
        self.motion.checker.checks()
    }

    /// Counts of the checker's certified motion checks since the last
    /// [`Self::reset_certify_stats`] (`None`: its segment checks are not certified this way).
    pub fn certify_stats(&self) -> Option<CertifyStats> {
        self.motion.checker.certify_stats()
    }

    /// Starts the counts of [`Self::certify_stats`] again (at the start of a search).
    pub fn reset_certify_stats(&mut self) {
        self.motion.checker.reset_certify_stats()
    }

    /// Segments checked so far.
    pub fn segments(&self) -> u64 {
        self.motion.segments() + self.own_segments
    }

    /// Within bounds and collision-free.
    pub fn is_state_valid(&mut self, q: &[f64]) -> bool {
        if !self.space.satisfies_bounds(q) {
            return false;
        }
        self.space.write_world(q, &mut self.wa);
        self.motion.checker.is_free(&self.wa)
    }

    /// Why `q` is invalid: the bound violated or the colliding pair (`None` when valid).
    pub fn invalidity(&mut self, q: &[f64]) -> Option<String> {
        if let Some(b) = self.space.bounds_violation(q) {
            return Some(b);
        }
        self.space.write_world(q, &mut self.wa);
        self.motion
            .checker
            .first_contact(&self.wa)
            .map(|Contact { a, b }| format!("{a} collides with {b}"))
    }

    /// The segment `a → b` (states of the space, `a` assumed valid): every state at the
    /// resolution, `b` included, is collision-free. Bounds are not checked (a straight segment
    /// between two states in the box stays in it).
    #[inline]
    pub fn is_motion_valid(&mut self, a: &[f64], b: &[f64]) -> bool {
        self.space.write_world(a, &mut self.wa);
        self.space.write_world(b, &mut self.wb);
        if let Some(d) = self.certify {
            if let Some(ok) = self.motion.checker.segment_certified(&self.wa, &self.wb, d) {
                self.own_segments += 1;
                return ok;
            }
        }
        let n = self.motion.steps(&self.wa, &self.wb);
        match self.motion.checker.segment_free(&self.wa, &self.wb, n) {
            Some(ok) => {
                self.own_segments += 1;
                ok
            }
            None => self.motion.is_valid(&self.wa, &self.wb),
        }
    }

    /// The segment `a → b` screened for a lazy planner: with certification on and a checker
    /// that has a screening pass ([`SegmentChecker::segment_screened`]),
    /// [`SegmentScreen::Tight`] marks a segment whose checked states are free but which is not
    /// yet proven free (certify it with [`Self::is_motion_valid`] before returning it);
    /// otherwise the full check of [`Self::is_motion_valid`] as `Certified` or `Collides`.
    #[inline]
    pub fn screen_motion(&mut self, a: &[f64], b: &[f64]) -> SegmentScreen {
        if let Some(d) = self.certify {
            self.space.write_world(a, &mut self.wa);
            self.space.write_world(b, &mut self.wb);
            if let Some(s) = self.motion.checker.segment_screened(&self.wa, &self.wb, d) {
                self.own_segments += 1;
                return s;
            }
        }
        if self.is_motion_valid(a, b) {
            SegmentScreen::Certified
        } else {
            SegmentScreen::Collides
        }
    }

    /// [`Self::screen_motion`] that, on [`SegmentScreen::Tight`], appends the segment's
    /// screening record to `record` (see [`SegmentChecker::screen_record`]) for
    /// [`Self::certify_screened`].
    #[inline]
    pub fn screen_motion_recorded(
        &mut self,
        a: &[f64],
        b: &[f64],
        record: &mut Vec<(usize, u32)>,
    ) -> SegmentScreen {
        let s = self.screen_motion(a, b);
        if s == SegmentScreen::Tight {
            self.motion.checker.screen_record(record);
        }
        s
    }

    /// The full check of [`Self::is_motion_valid`] of a segment screened
    /// [`SegmentScreen::Tight`] by [`Self::screen_motion_recorded`], from its `record` when the
    /// checker can (the same verdict, without the screening pass again).
    #[inline]
    pub fn certify_screened(&mut self, a: &[f64], b: &[f64], record: &[(usize, u32)]) -> bool {
        if let Some(d) = self.certify {
            self.space.write_world(a, &mut self.wa);
            self.space.write_world(b, &mut self.wb);
            if let Some(ok) = self
                .motion
                .checker
                .segment_certified_screened(&self.wa, &self.wb, d, record)
            {
                self.own_segments += 1;
                return ok;
            }
        }
        self.is_motion_valid(a, b)
    }

    /// Checks a whole path: every state within bounds, the first state free and every segment
    /// valid. `Err(k)`: state `k` (or the segment ending at it) is invalid.
    pub fn validate_path(&mut self, path: &[Vec<f64>]) -> Result<(), usize> {
        if let Some(k) = path.iter().position(|q| !self.space.satisfies_bounds(q)) {
            return Err(k);
        }
        let Some(first) = path.first() else {
            return Ok(());
        };
        if !self.is_state_valid(first) {
            return Err(0);
        }
        for k in 1..path.len() {
            if !self.is_motion_valid(&path[k - 1], &path[k]) {
                return Err(k);
            }
        }
        Ok(())
    }
}
