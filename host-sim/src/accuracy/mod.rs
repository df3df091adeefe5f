//! Seeded Monte-Carlo accuracy runs of the self-calibration over random
//! workcells, with the paper's two-frame method beside the refined estimate.

pub mod harness;
pub mod metrics;
pub mod report;
pub mod stats;
pub mod summary;
