//! Numeric IK (being written).
