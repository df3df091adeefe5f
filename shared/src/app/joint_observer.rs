//! Joint angles and speeds from quantised joint encoders.
//!
//! Eq 23 needs `qd`; differencing counts at 1 kHz gives speed noise of a count
//! per millisecond (about 0.1 rad/s on the PUMA's encoders), which the `Kd` term
//! would turn into torque noise. A second-order observer per joint, driven by the
//! acceleration the controller commanded (`qdd` of Eq 23) and corrected by the
//! encoder, gives a smooth `qd` without the lag of a low-pass filter: its error
//! poles sit at `-bandwidth` (double).

use crate::robot::JointVector;

/// Why a joint reading was refused (the observer's state is unchanged).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointObserverError {
    /// The time step is not positive and finite.
    BadTimeStep,
    /// Joint `joint` (0-based) read `jump_rad` away from its prediction: more than
    /// the arm can move in one period (a missed count burst or a faulty encoder).
    Implausible {
        /// The joint, 0-based.
        joint: usize,
        /// How far from the prediction, rad.
        jump_rad: f32,
    },
    /// A reading or the commanded acceleration was not finite.
    NonFinite,
}

impl core::fmt::Display for JointObserverError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::BadTimeStep => write!(f, "joint observer time step must be positive"),
            Self::Implausible { joint, jump_rad } => write!(
                f,
                "joint {} encoder jumped {jump_rad:.4} rad from its prediction",
                joint + 1
            ),
            Self::NonFinite => write!(f, "non-finite joint reading"),
        }
    }
}

impl core::error::Error for JointObserverError {}

/// Observer state for the six joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointObserver {
    q: JointVector<f32>,
    qd: JointVector<f32>,
    initialised: bool,
    bandwidth_rad_s: f32,
    max_jump_rad: f32,
}

impl JointObserver {
    /// `bandwidth_rad_s` sets how fast estimation errors decay (150 rad/s suits
    /// 1 kHz); a reading further than `max_jump_rad` from the prediction is refused.
    pub fn new(bandwidth_rad_s: f32, max_jump_rad: f32) -> Self {
        Self {
            q: JointVector::zeros(),
            qd: JointVector::zeros(),
            initialised: false,
            bandwidth_rad_s,
            max_jump_rad,
        }
    }

    /// The estimated joint angles, rad.
    pub fn q(&self) -> JointVector<f32> {
        self.q
    }

    /// The estimated joint speeds, rad/s.
    pub fn qd(&self) -> JointVector<f32> {
        self.qd
    }

    /// Forgets the state: the next reading sets it again, at rest. After a
    /// stall the commanded accelerations no longer describe the gap (the
    /// drives' watchdog braked the arm), so predicting across it would only
    /// flag a jump.
    pub fn restart(&mut self) {
        self.initialised = false;
    }

    /// Whether a reading has been absorbed since the last restart.
    pub fn is_initialised(&self) -> bool {
        self.initialised
    }

    /// Absorbs one reading `q_measured` taken `dt_s` after the last, the joints
    /// having been commanded `qdd_commanded` meanwhile. The first reading sets
    /// the state (at rest).
    pub fn update(
        &mut self,
        q_measured: &JointVector<f32>,
        qdd_commanded: &JointVector<f32>,
        dt_s: f32,
    ) -> Result<(), JointObserverError> {
        if !(q_measured.iter().all(|x| x.is_finite())
            && qdd_commanded.iter().all(|x| x.is_finite()))
        {
            return Err(JointObserverError::NonFinite);
        }
        if !self.initialised {
            self.q = *q_measured;
            self.qd = JointVector::zeros();
            self.initialised = true;
            return Ok(());
        }
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(JointObserverError::BadTimeStep);
        }
        let q_predicted = self.q + self.qd * dt_s + qdd_commanded * (0.5 * dt_s * dt_s);
        let qd_predicted = self.qd + qdd_commanded * dt_s;
        let innovation = q_measured - q_predicted;
        if let Some((joint, jump)) = innovation
            .iter()
            .enumerate()
            .find(|(_, e)| e.abs() > self.max_jump_rad)
        {
            return Err(JointObserverError::Implausible {
                joint,
                jump_rad: *jump,
            });
        }
        // Discrete gains placing both error poles at exp(-bandwidth dt).
        let pole = libm::expf(-self.bandwidth_rad_s * dt_s);
        let l_position = 1.0 - pole * pole;
        let l_velocity = (1.0 - pole) * (1.0 - pole) / dt_s;
        self.q = q_predicted + innovation * l_position;
        self.qd = qd_predicted + innovation * l_velocity;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_ramp_speed_from_quantised_angles_without_lag() {
        let counts_per_rad = 10_000.0_f32;
        let quantise = |q: f32| ((q * counts_per_rad).floor() + 0.5) / counts_per_rad;
        let mut observer = JointObserver::new(150.0, 0.05);
        let dt = 1e-3;
        let mut worst_after_settling = 0.0_f32;
        for k in 0..2000 {
            let t = k as f32 * dt;
            // qd = 0.5 t: constant commanded acceleration 0.5 rad/s^2.
            let q = 0.25 * t * t;
            let qdd = JointVector::repeat(0.5);
            observer
                .update(&JointVector::repeat(quantise(q)), &qdd, dt)
                .unwrap();
            if t > 0.2 {
                worst_after_settling = worst_after_settling.max((observer.qd()[0] - 0.5 * t).abs());
            }
        }
        assert!(
            worst_after_settling < 0.02,
            "speed error {worst_after_settling}"
        );
    }

    #[test]
    fn refuses_a_jump_and_keeps_its_state() {
        let mut observer = JointObserver::new(150.0, 0.05);
        observer
            .update(&JointVector::zeros(), &JointVector::zeros(), 1e-3)
            .unwrap();
        let before = observer;
        let mut jumped = JointVector::zeros();
        jumped[3] = 0.2;
        assert!(matches!(
            observer.update(&jumped, &JointVector::zeros(), 1e-3),
            Err(JointObserverError::Implausible { joint: 3, .. })
        ));
        assert_eq!(observer, before);
        assert_eq!(
            observer.update(&JointVector::repeat(f32::NAN), &JointVector::zeros(), 1e-3),
            Err(JointObserverError::NonFinite)
        );
        assert_eq!(observer, before);
    }
}
