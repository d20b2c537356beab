//! Benchmark tooling, apart from the planners: the MotionBenchMaker problem sets ([`mbm`]) and
//! their data ([`mbm_data`]: locating, fetching and reading robots and problems), the problem
//! generator ([`mbm_gen`]) and VAMP-MR's multi-arm cells ([`multi_arm_cells`]). It uses the
//! planning core; nothing in the planning core uses it.

pub mod mbm;
pub mod mbm_data;
pub mod mbm_gen;
pub mod multi_arm_cells;
