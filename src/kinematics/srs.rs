//! Analytic S-R-S IK (being written).
