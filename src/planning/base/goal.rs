//! Goals that are sampled rather than given (OMPL's `GoalSampleableRegion`): a planner asks its
//! goal sampler for goal states while it plans (000 Alg. 3, lines 5–9).

use rand_chacha::ChaCha8Rng;

/// Produces goal states while planning (000 Alg. 3, lines 5–9: "GetRandomGrasp, ComputeIK").
pub trait GoalSampler {
    /// One bounded attempt to find a goal. On success writes the goal state (coordinates of the
    /// planner's space) into `out` and returns its label (e.g. the grasp reached).
    fn sample_goal(&mut self, rng: &mut ChaCha8Rng, out: &mut [f64]) -> Option<usize>;
    /// Analytic IK calls made so far (for statistics).
    fn ik_calls(&self) -> u64 {
        0
    }
}
