//! Self-calibration from vision (paper Sections 2 and 3): conic fit of the reference
//! point's image, virtual rotation, part localisation with heights, and the
//! robot-base-to-disc transform.
