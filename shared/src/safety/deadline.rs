//! A control period that overruns its deadline now and then is counted
//! (`RuntimeReport.deadline_misses`); one that overruns it period after period
//! means the loop cannot keep its rate at all (the cost grew, the clock is
//! wrong, an interrupt storm): its torques are computed for an arm that has
//! moved on. That stops the cell, with its cause
//! ([`super::BoardFault::DeadlineMissed`]).

/// Consecutive overruns that stop the cell: 10 periods (10 ms at 1 kHz) is
/// past any single slow period the pick has (its worst is under half the
/// budget on the emulated board) and well inside the pick's own stall limit
/// (20 ms).
pub const DEADLINE_MISSES_TO_STOP: u16 = 10;

/// Counts overruns in a row.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DeadlineMonitor {
    in_a_row: u16,
}

impl DeadlineMonitor {
    /// No deadline missed yet.
    pub const fn new() -> Self {
        DeadlineMonitor { in_a_row: 0 }
    }

    /// One period ran; `missed` if it overran. True when the cell must stop
    /// (and on every later missed period until one keeps its deadline).
    pub fn period(&mut self, missed: bool) -> bool {
        self.in_a_row = if missed {
            self.in_a_row.saturating_add(1)
        } else {
            0
        };
        self.in_a_row >= DEADLINE_MISSES_TO_STOP
    }

    /// Overruns in a row so far.
    pub fn in_a_row(&self) -> u16 {
        self.in_a_row
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scattered_misses_never_stop_the_cell() {
        let mut monitor = DeadlineMonitor::new();
        for period in 0..100_000u32 {
            // Nine misses in a row, then one period on time, over and over.
            assert!(!monitor.period(period % 10 != 9), "period {period}");
        }
    }

    #[test]
    fn misses_in_a_row_stop_it_at_the_limit() {
        let mut monitor = DeadlineMonitor::new();
        for _ in 1..DEADLINE_MISSES_TO_STOP {
            assert!(!monitor.period(true));
        }
        assert!(monitor.period(true));
        assert!(monitor.period(true));
        assert!(!monitor.period(false));
        assert_eq!(monitor.in_a_row(), 0);
    }
}
