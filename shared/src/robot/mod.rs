//! PUMA 560 model: kinematics and rigid-body dynamics (paper Eq 16).
