use core::fmt;

/// Why a fusion step refused its input. The estimator's state is unchanged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FusionError {
    /// A counter reading does not fit the configured counter width.
    CounterOutOfRange {
        /// The reading.
        raw: u32,
        /// The counter's width in bits.
        bits: u8,
    },
    /// Counts per revolution must be positive.
    ZeroCountsPerRevolution,
    /// A sample's time did not advance (`dt_s` is the step it implied).
    TimeNotIncreasing {
        /// The time step the sample implied, s.
        dt_s: f64,
    },
    /// A non-finite number in the named input.
    NonFinite {
        /// The input holding it.
        what: &'static str,
    },
    /// A filter parameter is out of its valid range.
    InvalidParameter {
        /// The parameter.
        what: &'static str,
    },
    /// A reading jumped further from the prediction than the disc can move
    /// (`innovation_rad` from it, beyond `gate_rad`): a counter glitch.
    Implausible {
        /// How far the reading is from the prediction, rad.
        innovation_rad: f64,
        /// The gate, rad.
        gate_rad: f64,
    },
}

impl fmt::Display for FusionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::CounterOutOfRange { raw, bits } => {
                write!(f, "encoder reading {raw} does not fit a {bits}-bit counter")
            }
            Self::ZeroCountsPerRevolution => {
                write!(f, "encoder counts per revolution must be positive")
            }
            Self::TimeNotIncreasing { dt_s } => {
                write!(f, "encoder sample time did not increase (step {dt_s} s)")
            }
            Self::NonFinite { what } => write!(f, "non-finite value in {what}"),
            Self::InvalidParameter { what } => write!(f, "invalid parameter: {what}"),
            Self::Implausible {
                innovation_rad,
                gate_rad,
            } => write!(
                f,
                "encoder reading {innovation_rad} rad from its prediction, beyond the {gate_rad} rad gate"
            ),
        }
    }
}

impl core::error::Error for FusionError {}
