//! Task-space computed-torque control of the PUMA 560 (paper Eq 23).
