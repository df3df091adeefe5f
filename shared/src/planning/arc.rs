//! Rest-to-rest moves round the robot's base axis, in cylindrical coordinates.
//!
//! The pick's long moves (sweeping the marks past the camera, carrying the part
//! to the drop-off, returning) can cross to the other side of the robot. A
//! straight line would then pass close to the base axis, where the PUMA's
//! shoulder is singular; an arc `(r(t), phi(t), z(t))` keeps the radius bounded
//! away from it. The four coordinates (with the gripper's yaw, pointing down)
//! move together along one time scaling (`scaling`): a quintic, or for a long
//! move blends and a cruise at the top speed; smooth to the acceleration
//! either way, as Eq 23's feed-forward needs.

use nalgebra::{convert, RealField, Vector3, Vector4};

use super::path::TaskPath;
use super::scaling::TimeScaling;
use super::{PlanError, TaskState};

/// A point in cylindrical coordinates about the base Z axis, with the gripper's yaw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcPoint<T> {
    /// Distance from the base Z axis, m.
    pub radius_m: T,
    /// Angle about the base Z axis from +X, rad (not wrapped: a move goes from one
    /// value to the other the way the numbers say).
    pub azimuth_rad: T,
    /// Height, m.
    pub z_m: T,
    /// The gripper's yaw, rad.
    pub yaw_rad: T,
}

impl<T: RealField + Copy> ArcPoint<T> {
    /// The point above `position` (azimuth in (-pi, pi]).
    pub fn from_position(position: &Vector3<T>, yaw_rad: T) -> Self {
        Self {
            radius_m: position.x.hypot(position.y),
            azimuth_rad: position.y.atan2(position.x),
            z_m: position.z,
            yaw_rad,
        }
    }

    fn as_vector(&self) -> Vector4<T> {
        Vector4::new(self.radius_m, self.azimuth_rad, self.z_m, self.yaw_rad)
    }
}

/// Speed limits that set an arc's duration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcLimits<T> {
    /// Largest speed along the arc, m/s.
    pub max_speed_m_s: T,
    /// Largest acceleration, m/s^2.
    pub max_acceleration_m_s2: T,
    /// Largest yaw rate, rad/s.
    pub max_yaw_rate_rad_s: T,
    /// Shortest duration, s.
    pub min_duration_s: T,
}

impl<T: RealField + Copy> Default for ArcLimits<T> {
    fn default() -> Self {
        Self {
            max_speed_m_s: convert(0.5),
            max_acceleration_m_s2: convert(1.5),
            max_yaw_rate_rad_s: convert(1.2),
            min_duration_s: convert(0.5),
        }
    }
}

/// A rest-to-rest arc between two [`ArcPoint`]s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcMove<T: RealField + Copy> {
    /// `[r, phi, z, yaw]` at the start.
    start: Vector4<T>,
    /// `[r, phi, z, yaw]` from the start to the end.
    delta: Vector4<T>,
    /// How far along `delta` the move is, against time.
    scaling: TimeScaling<T>,
}

impl<T: RealField + Copy> ArcMove<T> {
    /// The shortest arc from `start` to `end` within `limits`. The radius must
    /// stay positive (the arc never crosses the base axis).
    pub fn new(
        start: &ArcPoint<T>,
        end: &ArcPoint<T>,
        limits: &ArcLimits<T>,
    ) -> Result<Self, PlanError> {
        let (a, b) = (start.as_vector(), end.as_vector());
        if !(a.iter().chain(b.iter()).all(|x| x.is_finite())) {
            return Err(PlanError::NonFinite {
                what: "arc end point",
            });
        }
        if start.radius_m <= T::zero() || end.radius_m <= T::zero() {
            return Err(PlanError::InvalidLimits {
                what: "an arc's radius must be positive",
            });
        }
        let ok = |x: T| x.is_finite() && x > T::zero();
        let limits_ok = ok(limits.max_speed_m_s)
            && ok(limits.max_acceleration_m_s2)
            && ok(limits.max_yaw_rate_rad_s)
            && limits.min_duration_s.is_finite()
            && limits.min_duration_s >= T::zero();
        if !limits_ok {
            return Err(PlanError::InvalidLimits {
                what: "arc speed, acceleration and yaw-rate limits must be finite and positive",
            });
        }
        let delta = b - a;
        let radius = start.radius_m.max(end.radius_m);
        // The largest distance any coordinate travels, in metres (arc length for phi).
        let linear = delta
            .x
            .abs()
            .max((delta.y * radius).abs())
            .max(delta.z.abs());
        // The limits as rates of progress along the move (a null distance
        // leaves its limit unbounded but finite).
        let tiny: T = convert(1e-9);
        let max_rate = (limits.max_speed_m_s / linear.max(tiny))
            .min(limits.max_yaw_rate_rad_s / delta.w.abs().max(tiny));
        let max_acceleration = limits.max_acceleration_m_s2 / linear.max(tiny);
        Ok(Self {
            start: a,
            delta,
            scaling: TimeScaling::shortest(max_rate, max_acceleration, limits.min_duration_s),
        })
    }
}

impl<T: RealField + Copy> TaskPath<T> for ArcMove<T> {
    fn duration(&self) -> T {
        self.scaling.duration()
    }

    /// Chain rule of `p = (r cos phi, r sin phi, z)`: the velocity has a radial
    /// and a tangential part, the acceleration adds the centripetal `-r phi'^2`
    /// and the Coriolis `2 r' phi'` terms.
    fn sample(&self, t: T) -> TaskState<T> {
        let progress = self.scaling.at(t);
        let p = self.start + self.delta * progress.s;
        let v = self.delta * progress.rate;
        let a = self.delta * progress.acceleration;
        let (r, phi, z, yaw) = (p.x, p.y, p.z, p.w);
        let (rd, phid, zd, yawd) = (v.x, v.y, v.z, v.w);
        let (rdd, phidd, zdd, yawdd) = (a.x, a.y, a.z, a.w);
        // Sampled every control period: the control loop's sine and cosine.
        let (s, c) = crate::control::trig::sin_cos(phi);
        let radial = Vector3::new(c, s, T::zero());
        let tangential = Vector3::new(-s, c, T::zero());
        let two: T = convert(2.0);
        TaskState {
            position: radial * r + Vector3::new(T::zero(), T::zero(), z),
            velocity: radial * rd
                + tangential * (r * phid)
                + Vector3::new(T::zero(), T::zero(), zd),
            acceleration: radial * (rdd - r * phid * phid)
                + tangential * (r * phidd + two * rd * phid)
                + Vector3::new(T::zero(), T::zero(), zdd),
            yaw,
            yaw_rate: yawd,
            yaw_acceleration: yawdd,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(r: f64, phi: f64, z: f64, yaw: f64) -> ArcPoint<f64> {
        ArcPoint {
            radius_m: r,
            azimuth_rad: phi,
            z_m: z,
            yaw_rad: yaw,
        }
    }

    #[test]
    fn velocity_and_acceleration_are_the_derivatives_of_position() {
        let arc = ArcMove::new(
            &point(0.6, -2.5, 0.7, 0.0),
            &point(0.7, 2.0, 0.4, 1.0),
            &ArcLimits::default(),
        )
        .unwrap();
        let h = 1e-5;
        let d = arc.duration();
        for k in 1..10 {
            let t = d * f64::from(k) / 10.0;
            let s = arc.sample(t);
            let (m, p) = (arc.sample(t - h), arc.sample(t + h));
            assert!((s.velocity - (p.position - m.position) / (2.0 * h)).norm() < 1e-6);
            assert!((s.acceleration - (p.velocity - m.velocity) / (2.0 * h)).norm() < 1e-5);
            assert!(((p.yaw - m.yaw) / (2.0 * h) - s.yaw_rate).abs() < 1e-6);
        }
    }

    #[test]
    fn keeps_its_radius_and_limits_and_rests_at_both_ends() {
        let limits = ArcLimits::default();
        let arc = ArcMove::new(
            &point(0.65, -2.6, 0.7, 0.0),
            &point(0.65, 2.6, 0.7, 0.0),
            &limits,
        )
        .unwrap();
        let d = arc.duration();
        for k in 0..=200 {
            let s = arc.sample(d * f64::from(k) / 200.0);
            assert!((s.position.xy().norm() - 0.65).abs() < 1e-12, "radius held");
            assert!(s.velocity.norm() <= limits.max_speed_m_s * 1.001);
            assert!(
                s.acceleration.norm() <= limits.max_acceleration_m_s2 * 1.6,
                "centripetal included"
            );
        }
        assert!(arc.sample(0.0).velocity.norm() < 1e-12);
        assert!(arc.sample(d).velocity.norm() < 1e-12);
        let end = arc.sample(d).position;
        assert!((end - Vector3::new(0.65 * 2.6f64.cos(), 0.65 * 2.6f64.sin(), 0.7)).norm() < 1e-12);
    }

    #[test]
    fn refuses_the_base_axis_and_bad_numbers() {
        let limits = ArcLimits::default();
        assert!(ArcMove::new(
            &point(0.0, 0.0, 0.5, 0.0),
            &point(0.5, 1.0, 0.5, 0.0),
            &limits
        )
        .is_err());
        assert!(ArcMove::new(
            &point(0.5, f64::NAN, 0.5, 0.0),
            &point(0.5, 1.0, 0.5, 0.0),
            &limits
        )
        .is_err());
        let bad = ArcLimits {
            max_speed_m_s: 0.0,
            ..limits
        };
        assert!(
            ArcMove::new(&point(0.5, 0.0, 0.5, 0.0), &point(0.5, 1.0, 0.5, 0.0), &bad).is_err()
        );
    }
}
