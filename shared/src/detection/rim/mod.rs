//! The disc's rim: an ellipse measured over every pixel of the rim band,
//! hundreds of edge pixels a frame, where the reference mark gives one point.
//!
//! The paper's virtual rotation (Section 2) reads the camera's tilt and
//! height (`H = f L / l`) from the ellipse one reference point traces over
//! many frames. The rim is a circle of known radius on the same plane, so one
//! frame's image of it carries the same tilt and scale at once. What a
//! vision front end sees of it is a dark band between the disc's surface and
//! the floor, one or two pixels wide; its outer edge is the rim.
//!
//! Two steps, in fixed memory:
//! - [`seed`]: rays cast from the disc centre's image find the band's dip;
//!   a robust conic through the dips starts the fit within a pixel or so;
//! - [`fit`]: every pixel within a few pixels of the band is explained by a
//!   model of the band (the floor, the band, the disc's surface, each level
//!   free in each of [`fit::RIM_SECTORS`] sectors round the rim, meeting at
//!   the outer ellipse and at the image of a concentric circle, each edge a
//!   one-pixel ramp: the area a pixel integrates), and Gauss-Newton moves
//!   the ellipse until the model explains the pixels, with a robust weight
//!   that lets the arm, a glint or a mark the detector missed drop out.
//!   Later frames start from the last frame's fit.
//!
//! Its parts: [`pixels`] (the pixels near the band, found once: the camera
//! does not move), [`model`] (one pixel against the two edges, `f32` with
//! analytic derivatives), [`sums`] (a pass's normal equations, the levels
//! eliminated sector by sector).
//!
//! Working memory: [`RimFinder::WORKING_MEMORY_BYTES`] (the pixels near the
//! band, [`fit::MAX_RIM_PIXELS`] of them at most, 15 B each with their
//! sector, value and zone, and the last fit's levels); a pass's sums (about
//! 5 KiB) live on the stack.

pub mod ellipse;
pub mod fit;
pub mod model;
pub mod pixels;
pub mod seed;
pub mod sums;

use core::fmt;

pub use ellipse::{Ellipse, EllipsePoint};
pub use fit::{RimFinder, RimFit, RimSettings};

/// Why the rim was not measured in a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RimError {
    /// The disc centre's image given as the start does not undistort.
    CentreOffLens,
    /// Too few rays found the band's dip.
    TooFewDips {
        /// Rays whose dip was kept.
        found: usize,
        /// Rays needed.
        needed: usize,
    },
    /// The points do not lie on an ellipse (a hyperbola, a line, a NaN).
    NotAnEllipse,
    /// Too few pixels lie near the band (the rim off the image, or hidden).
    TooFewPixels {
        /// Pixels near the band.
        found: usize,
        /// Pixels needed.
        needed: usize,
    },
    /// Too few sectors round the rim show the band with contrast.
    TooFewSectors {
        /// Sectors that did.
        used: usize,
        /// Sectors needed.
        needed: usize,
    },
    /// The fit's normal equations are singular or its step not finite.
    Degenerate,
    /// The fit moved the ellipse farther than its start allows (a wrong band).
    Diverged,
}

impl fmt::Display for RimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::CentreOffLens => write!(f, "rim: the disc centre's image is off the lens model"),
            Self::TooFewDips { found, needed } => write!(
                f,
                "rim: the band's dip found on {found} rays, {needed} needed"
            ),
            Self::NotAnEllipse => write!(f, "rim: the band's points do not make an ellipse"),
            Self::TooFewPixels { found, needed } => {
                write!(f, "rim: {found} pixels near the band, {needed} needed")
            }
            Self::TooFewSectors { used, needed } => write!(
                f,
                "rim: the band shows in {used} sectors round the rim, {needed} needed"
            ),
            Self::Degenerate => write!(f, "rim: the fit's normal equations are singular"),
            Self::Diverged => write!(f, "rim: the fit left its start (a wrong band?)"),
        }
    }
}

impl core::error::Error for RimError {}

#[cfg(test)]
mod tests;
