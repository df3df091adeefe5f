//! Joint speeds for the supervisor: encoder readings a few periods apart,
//! differenced. The joint observer's speeds are smoother but lean on the
//! commanded accelerations (Eq 23's qdd), which the arm does not follow while
//! its drives saturate; a speed limit must be checked on what the encoders
//! say, and a 10-period baseline keeps one count of quantisation (0.08 rad/s
//! per period on joint 6) down to 0.008 rad/s.

use crate::robot::JointVector;

/// Readings in the window (the speed spans `WINDOW - 1` periods).
pub const WINDOW: usize = 11;

/// The last `WINDOW` readings and their times.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointSpeedWindow {
    q: [JointVector<f32>; WINDOW],
    time_us: [u64; WINDOW],
    next: usize,
    filled: usize,
}

impl Default for JointSpeedWindow {
    fn default() -> Self {
        Self::new()
    }
}

impl JointSpeedWindow {
    /// An empty window.
    pub fn new() -> Self {
        Self {
            q: [JointVector::zeros(); WINDOW],
            time_us: [0; WINDOW],
            next: 0,
            filled: 0,
        }
    }

    /// Forgets the readings (after a gap: the window must not span it).
    pub fn restart(&mut self) {
        self.filled = 0;
    }

    /// Adds a reading; the speeds over the window once it is full.
    pub fn push(&mut self, q: &JointVector<f32>, time_us: u64) -> Option<JointVector<f32>> {
        let slot = self.next % WINDOW;
        let oldest = (self.next + 1) % WINDOW;
        if let (Some(q_slot), Some(t_slot)) = (self.q.get_mut(slot), self.time_us.get_mut(slot)) {
            *q_slot = *q;
            *t_slot = time_us;
        }
        self.next = oldest;
        self.filled = (self.filled + 1).min(WINDOW);
        if self.filled < WINDOW {
            return None;
        }
        let (q_old, t_old) = (self.q.get(oldest)?, *self.time_us.get(oldest)?);
        let dt_s = crate::kernels::micros_to_seconds(time_us.checked_sub(t_old)?);
        (dt_s > 0.0).then(|| (q - q_old) / dt_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_steady_motion_reads_its_speed_after_the_window_fills() {
        let mut window = JointSpeedWindow::new();
        let speed = JointVector::from_column_slice(&[0.5, -1.0, 2.0, 0.0, 0.1, -0.3]);
        let mut last = None;
        for k in 0..30u64 {
            let t = k as f32 * 1e-3;
            let reading = window.push(&(speed * t), k * 1000);
            if k + 1 < WINDOW as u64 {
                assert_eq!(reading, None, "period {k}");
            }
            last = reading;
        }
        let read = last.unwrap();
        assert!((read - speed).amax() < 1e-3, "{read}");
    }

    #[test]
    fn a_restart_empties_the_window_and_a_stuck_clock_reads_nothing() {
        let mut window = JointSpeedWindow::new();
        for k in 0..20u64 {
            let _ = window.push(&JointVector::zeros(), k * 1000);
        }
        window.restart();
        assert_eq!(window.push(&JointVector::zeros(), 30_000), None);
        let mut stuck = JointSpeedWindow::new();
        let readings: Vec<_> = (0..20)
            .map(|_| stuck.push(&JointVector::zeros(), 5))
            .collect();
        assert!(readings.iter().all(Option::is_none));
    }
}
