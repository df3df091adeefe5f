//! Range checks of a pick experiment, each error naming the field and the rule.

use anyhow::{bail, Result};

use super::PickExperiment;
use crate::scenario::recording::CAMERA_MAX_TILT_DEG;

impl PickExperiment {
    fn validate_faults(&self) -> Result<()> {
        let f = &self.faults;
        let time = |field: &str, t: f64| check(field, t, t >= 0.0, ">= 0");
        if let Some(bump) = f.camera_bump {
            time("faults.camera_bump.at_s", bump.at_s)?;
            check(
                "faults.camera_bump.rotation_deg",
                bump.rotation_deg,
                bump.rotation_deg.abs() <= 30.0,
                "within +-30",
            )?;
            check(
                "faults.camera_bump.shift_m",
                bump.shift_m,
                bump.shift_m.abs() <= 0.5,
                "within +-0.5",
            )?;
        }
        for (name, window) in [
            ("vision_outage", f.vision_outage),
            ("control_stall", f.control_stall),
        ] {
            if let Some(w) = window {
                time(&format!("faults.{name}.at_s"), w.at_s)?;
                check(
                    &format!("faults.{name}.duration_s"),
                    w.duration_s,
                    w.duration_s > 0.0,
                    "> 0",
                )?;
            }
        }
        if let Some(missed) = f.missed_counts {
            time("faults.missed_counts.at_s", missed.at_s)?;
        }
        if let Some(change) = f.conveyor_change {
            time("faults.conveyor_change.at_s", change.at_s)?;
            check(
                "faults.conveyor_change.speed_rad_s",
                change.speed_rad_s,
                change.speed_rad_s.abs() <= 5.0,
                "within +-5",
            )?;
            check(
                "faults.conveyor_change.acceleration_rad_s2",
                change.acceleration_rad_s2,
                change.acceleration_rad_s2 > 0.0,
                "> 0",
            )?;
            if self.conveyor.stop.is_some() {
                bail!("faults.conveyor_change needs an experiment without conveyor.stop");
            }
        }
        Ok(())
    }
}

/// `value` must satisfy `ok`; the error names the field and the rule.
fn check(field: &str, value: f64, ok: bool, rule: &str) -> Result<()> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        bail!("{field} = {value} is out of range: it must be {rule}")
    }
}

fn probability(field: &str, p: f64) -> Result<()> {
    check(field, p, (0.0..1.0).contains(&p), "in [0, 1)")
}

impl PickExperiment {
    /// Range checks, each naming its field.
    pub fn validate(&self) -> Result<()> {
        if self.name.trim().is_empty() {
            bail!("name must not be empty");
        }
        self.image.validate()?;
        check(
            "time_limit_s",
            self.time_limit_s,
            self.time_limit_s > 0.0,
            "> 0",
        )?;

        check(
            "disc_height_tolerance_m",
            self.disc_height_tolerance_m,
            (0.0..=0.05).contains(&self.disc_height_tolerance_m),
            "in [0, 0.05]",
        )?;
        if !self.drop_off_base_m.iter().all(|x| x.is_finite()) {
            bail!(
                "drop_off_base_m = {:?} must be finite",
                self.drop_off_base_m
            );
        }

        let l = &self.cell;
        for (field, [low, high], min, max) in [
            ("cell.disc_distance_m", l.disc_distance_m, 0.65, 1.2),
            (
                "cell.disc_below_shoulder_m",
                l.disc_below_shoulder_m,
                0.0,
                0.67,
            ),
            ("cell.disc_azimuth_deg", l.disc_azimuth_deg, -180.0, 180.0),
        ] {
            if !(low.is_finite() && high.is_finite() && min <= low && low <= high && high <= max) {
                bail!("{field} = [{low}, {high}] must be an ordered range within [{min}, {max}]");
            }
        }

        let c = &self.conveyor;
        check("conveyor.speed_rad_s", c.speed_rad_s, true, "finite")?;
        check(
            "conveyor.ripple_fraction",
            c.ripple_fraction,
            (0.0..1.0).contains(&c.ripple_fraction),
            "in [0, 1)",
        )?;
        check(
            "conveyor.ripple_hz",
            c.ripple_hz,
            c.ripple_hz >= 0.0,
            ">= 0",
        )?;
        if c.counts_per_rev == 0 {
            bail!("conveyor.counts_per_rev = 0 is out of range: it must be > 0");
        }
        if !matches!(c.counter_bits, 16 | 32) {
            bail!(
                "conveyor.counter_bits = {} is out of range: it must be 16 or 32",
                c.counter_bits
            );
        }
        if let Some(stop) = c.stop {
            check(
                "conveyor.stop.after_s",
                stop.after_s,
                stop.after_s >= 0.0,
                ">= 0",
            )?;
            check(
                "conveyor.stop.deceleration_rad_s2",
                stop.deceleration_rad_s2,
                stop.deceleration_rad_s2 > 0.0,
                "> 0",
            )?;
        }

        self.validate_faults()?;

        let cam = &self.camera;
        if cam.frame_period_ms == 0 {
            bail!("camera.frame_period_ms = 0 is out of range: it must be > 0");
        }
        check(
            "camera.pixel_sigma_px",
            cam.pixel_sigma_px,
            cam.pixel_sigma_px >= 0.0,
            ">= 0",
        )?;
        probability("camera.dropout_probability", cam.dropout_probability)?;
        probability("camera.outlier_probability", cam.outlier_probability)?;
        check(
            "camera.latency_ms",
            cam.latency_ms,
            cam.latency_ms >= 0.0,
            ">= 0",
        )?;
        check(
            "camera.latency_jitter_ms",
            cam.latency_jitter_ms,
            cam.latency_jitter_ms >= 0.0 && cam.latency_jitter_ms <= cam.latency_ms,
            "in [0, latency_ms]",
        )?;
        let [low, high] = cam.tilt_deg;
        let max = CAMERA_MAX_TILT_DEG;
        if !(low.is_finite() && high.is_finite() && 0.0 <= low && low <= high && high <= max) {
            bail!("camera.tilt_deg = [{low}, {high}] is out of range: it must be low <= high within [0, {max}]");
        }

        let part = &self.part;
        if !(2..=8).contains(&part.feature_count) {
            bail!(
                "part.feature_count = {} is out of range: it must be 2 to 8",
                part.feature_count
            );
        }
        check(
            "part.height_m",
            part.height_m,
            (0.0..=0.3).contains(&part.height_m),
            "in [0, 0.3]",
        )?;
        check("part.mass_kg", part.mass_kg, part.mass_kg >= 0.0, ">= 0")?;

        let r = &self.robot;
        check(
            "robot.link_mass_error",
            r.link_mass_error,
            (0.0..1.0).contains(&r.link_mass_error),
            "in [0, 1)",
        )?;
        check(
            "robot.payload_kg",
            r.payload_kg,
            r.payload_kg >= 0.0,
            ">= 0",
        )?;
        check(
            "robot.joint_counts_per_motor_rev",
            r.joint_counts_per_motor_rev,
            r.joint_counts_per_motor_rev > 0.0,
            "> 0",
        )?;
        check(
            "robot.control_rate_hz",
            r.control_rate_hz,
            r.control_rate_hz > 0.0,
            "> 0",
        )?;
        r.drive.validate()?;
        if r.plant_substeps == 0 {
            bail!("robot.plant_substeps = 0 is out of range: it must be >= 1");
        }

        let g = &self.gripper;
        check(
            "gripper.horizontal_m",
            g.horizontal_m,
            g.horizontal_m > 0.0,
            "> 0",
        )?;
        check(
            "gripper.vertical_m",
            g.vertical_m,
            g.vertical_m > 0.0,
            "> 0",
        )?;
        check(
            "gripper.yaw_deg",
            g.yaw_deg,
            g.yaw_deg > 0.0 && g.yaw_deg <= 90.0,
            "in (0, 90]",
        )?;
        check(
            "gripper.relative_speed_m_s",
            g.relative_speed_m_s,
            g.relative_speed_m_s > 0.0,
            "> 0",
        )?;
        Ok(())
    }
}
