//! The conveyor's mean speed over the last seconds, from its encoder alone.
//!
//! Why: the intercept predicts the part seconds ahead with Eq 1 at constant
//! speed. A drive's speed ripple (10 % at 0.3 Hz on a 1 rad/s disc) makes the
//! instantaneous speed a poor predictor over that horizon: its error grows
//! with the horizon (0.17 rad after 1.5 s in a measured run), while the mean
//! speed's stays within the ripple's own excursion (about 0.1 rad there).
//! The window holds a fixed number of samples, spaced evenly in time.

use heapless::Deque;

/// Samples kept: with [`SAMPLE_SPACING_US`] a window of 10 s, three periods
/// of a 0.3 Hz ripple.
pub const MEAN_SPEED_SAMPLES: usize = 41;
/// Time between samples, microseconds.
pub const SAMPLE_SPACING_US: u64 = 250_000;

/// The conveyor's encoder sampled every [`SAMPLE_SPACING_US`] over the last
/// `(MEAN_SPEED_SAMPLES - 1) * SAMPLE_SPACING_US`.
#[derive(Debug, Clone)]
pub struct ConveyorMeanSpeed {
    /// `(time_us, unwrapped counts)`, oldest first.
    samples: Deque<(u64, i64), MEAN_SPEED_SAMPLES>,
    rad_per_count: f32,
}

impl ConveyorMeanSpeed {
    /// An empty window for an encoder of `rad_per_count`.
    pub fn new(rad_per_count: f32) -> Self {
        Self {
            samples: Deque::new(),
            rad_per_count,
        }
    }

    /// Forgets every sample (the conveyor's counts started over).
    pub fn restart(&mut self) {
        self.samples.clear();
    }

    /// Offers the unwrapped `counts` read at `time_us`; kept when a spacing
    /// has passed since the newest sample. A time that goes backwards starts
    /// the window over.
    pub fn push(&mut self, time_us: u64, counts: i64) {
        match self.samples.back() {
            Some(&(newest_us, _)) if time_us < newest_us => self.restart(),
            Some(&(newest_us, _)) if time_us - newest_us < SAMPLE_SPACING_US => return,
            _ => {}
        }
        if self.samples.is_full() {
            let _ = self.samples.pop_front();
        }
        let _ = self.samples.push_back((time_us, counts));
    }

    /// The mean speed over the whole window, rad/s; `None` until the window
    /// is full.
    pub fn mean_rad_s(&self) -> Option<f32> {
        if !self.samples.is_full() {
            return None;
        }
        let (&(t0, c0), &(t1, c1)) = (self.samples.front()?, self.samples.back()?);
        let span_s = (t1.checked_sub(t0)? as f64) * 1e-6;
        if span_s <= 0.0 {
            return None;
        }
        let turned_rad = c1.wrapping_sub(c0) as f64 * f64::from(self.rad_per_count);
        Some((turned_rad / span_s) as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mean_of_a_rippled_speed_is_its_mean_not_its_present_value() {
        let counts_per_rad = 4096.0 / core::f64::consts::TAU;
        let mut mean = ConveyorMeanSpeed::new((1.0 / counts_per_rad) as f32);
        // 1 rad/s with 10 % ripple at 0.3 Hz, read at 1 kHz for 20 s.
        let w = core::f64::consts::TAU * 0.3;
        let theta = |t: f64| t + 0.1 / w * (1.0 - (w * t).cos());
        for k in 0..20_000u64 {
            let t = k as f64 * 1e-3;
            if k < 9_000 {
                assert_eq!(mean.mean_rad_s(), None, "before the window is full");
            }
            mean.push(k * 1_000, (theta(t) * counts_per_rad).floor() as i64);
        }
        let speed = mean.mean_rad_s().unwrap_or(f32::NAN);
        // The present speed is 1 + 0.1 sin(w 20) = 1.095; the mean is 1 within
        // the ripple's excursion over the 10 s window (2 * 0.053 / 10).
        assert!((speed - 1.0).abs() < 0.011, "{speed}");
    }

    #[test]
    fn time_going_backwards_starts_the_window_over() {
        let mut mean = ConveyorMeanSpeed::new(1e-3);
        for k in 0..100u64 {
            mean.push(k * SAMPLE_SPACING_US, (k * 250) as i64);
        }
        assert!(mean.mean_rad_s().is_some_and(|w| (w - 1.0).abs() < 1e-4));
        mean.push(1_000, 0);
        assert_eq!(mean.mean_rad_s(), None);
    }
}
