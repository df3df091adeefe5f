//! The camera image the world renders (`[experiment.image]`): lens
//! distortion, exposure, light, surfaces, marks and sensor noise. Only the
//! renderer and `host-sim vision-check` read it; the labelled points the
//! controller receives do not depend on it.

use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};

/// How the world's camera forms its 8-bit grey image.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImageSettings {
    /// Radial distortion of the lens, `r_d = r (1 + k1 r^2 + k2 r^4)` in
    /// normalised coordinates (known, like the other intrinsics).
    pub k1: f64,
    /// Fourth-order radial distortion coefficient.
    pub k2: f64,
    /// Exposure time, ms: what moves blurs over it, centred on the trigger.
    pub exposure_ms: f64,
    /// Grey level of a white (reflectance 1) surface at the image centre under
    /// the mean light.
    pub light_level: f64,
    /// Light change across the image: the level varies linearly by this
    /// fraction from the centre to the edge, along a direction that turns.
    pub light_gradient: f64,
    /// The gradient's direction turns once in this time, s.
    pub light_turn_period_s: f64,
    /// Slow change of the overall level, fraction (sinusoidal).
    pub light_drift: f64,
    /// Period of that change, s.
    pub light_drift_period_s: f64,
    /// Fall-off of the light at the image corners, fraction.
    pub vignetting: f64,
    /// Reflectance of the disc's surface (mean of its texture).
    pub disc_reflectance: f64,
    /// Relative amplitude of the disc texture (rings and sectors).
    pub disc_texture: f64,
    /// Reflectance of the disc's rim band.
    pub rim_reflectance: f64,
    /// Width of the rim band, m.
    pub rim_width_m: f64,
    /// Reflectance of the floor round the disc.
    pub floor_reflectance: f64,
    /// Reflectance of the part's top face (its sides are darker): darker
    /// than the disc, so that its feature marks stand out.
    pub part_reflectance: f64,
    /// Margin of the part's body beyond its feature marks, m.
    pub part_margin_m: f64,
    /// Reflectance of the arm and gripper (shaded as cylinders).
    pub arm_reflectance: f64,
    /// Reflectance of the black bar that carries the gripper's two marks
    /// (a dark backing, as marker plates have).
    pub mark_backing_reflectance: f64,
    /// Reflectance of every mark (white, matte).
    pub mark_reflectance: f64,
    /// Radius of the disc-centre mark, m.
    pub centre_mark_radius_m: f64,
    /// Radius of the reference mark, m.
    pub reference_mark_radius_m: f64,
    /// Radius of each feature mark on the part, m.
    pub feature_mark_radius_m: f64,
    /// Radius of part feature 0's mark, m: larger than the others, so that
    /// the features' order (feature 0, then counter-clockwise seen from
    /// above) follows from the image alone (0: like the others, and the
    /// order is the front end's own).
    pub key_feature_mark_radius_m: f64,
    /// Radii of the gripper's two marks (`EFFECTOR_MARKS_FLANGE_M` order),
    /// m: unlike, so that which is which follows from their sizes (their
    /// images' light differs by the square of the ratio at any height).
    pub effector_mark_radii_m: [f64; 2],
    /// Bright objects on the disc that are no marks, for identification to
    /// refuse (0: none).
    pub distractors: usize,
    /// Their radii, alternately, m: smaller and larger than every mark.
    pub distractor_radii_m: [f64; 2],
    /// Electrons per grey level: shot noise has variance `grey / gain`.
    pub electrons_per_grey: f64,
    /// Read noise, grey levels (standard deviation).
    pub read_noise_grey: f64,
}

impl Default for ImageSettings {
    fn default() -> Self {
        Self {
            k1: -0.06,
            k2: 0.01,
            exposure_ms: 8.0,
            light_level: 200.0,
            light_gradient: 0.2,
            light_turn_period_s: 40.0,
            light_drift: 0.08,
            light_drift_period_s: 11.0,
            vignetting: 0.2,
            disc_reflectance: 0.3,
            disc_texture: 0.12,
            rim_reflectance: 0.12,
            rim_width_m: 0.015,
            floor_reflectance: 0.25,
            part_reflectance: 0.22,
            part_margin_m: 0.02,
            arm_reflectance: 0.3,
            mark_backing_reflectance: 0.05,
            mark_reflectance: 0.95,
            centre_mark_radius_m: 0.012,
            reference_mark_radius_m: 0.012,
            feature_mark_radius_m: 0.008,
            key_feature_mark_radius_m: 0.0095,
            effector_mark_radii_m: [0.016, 0.01],
            distractors: 0,
            distractor_radii_m: [0.005, 0.02],
            electrons_per_grey: 40.0,
            read_noise_grey: 2.0,
        }
    }
}

impl ImageSettings {
    /// The same image without sensor noise.
    pub fn noise_free(&self) -> Self {
        Self {
            electrons_per_grey: f64::INFINITY,
            read_noise_grey: 0.0,
            ..*self
        }
    }

    /// Range checks, each naming its field (`image.` prefixed).
    pub fn validate(&self) -> Result<()> {
        let unit = [
            ("disc_reflectance", self.disc_reflectance),
            ("rim_reflectance", self.rim_reflectance),
            ("floor_reflectance", self.floor_reflectance),
            ("part_reflectance", self.part_reflectance),
            ("arm_reflectance", self.arm_reflectance),
            ("mark_backing_reflectance", self.mark_backing_reflectance),
            ("mark_reflectance", self.mark_reflectance),
            ("disc_texture", self.disc_texture),
            ("light_gradient", self.light_gradient),
            ("light_drift", self.light_drift),
            ("vignetting", self.vignetting),
        ];
        if self.distractors > 32 {
            bail!(
                "image.distractors = {} is out of range: at most 32",
                self.distractors
            );
        }
        for (field, value) in unit {
            if !(value.is_finite() && (0.0..=1.0).contains(&value)) {
                bail!("image.{field} = {value} is out of range: it must be in [0, 1]");
            }
        }
        let positive = [
            ("light_level", self.light_level),
            ("light_turn_period_s", self.light_turn_period_s),
            ("light_drift_period_s", self.light_drift_period_s),
            ("centre_mark_radius_m", self.centre_mark_radius_m),
            ("reference_mark_radius_m", self.reference_mark_radius_m),
            ("feature_mark_radius_m", self.feature_mark_radius_m),
            ("effector_mark_radii_m[0]", self.effector_mark_radii_m[0]),
            ("effector_mark_radii_m[1]", self.effector_mark_radii_m[1]),
            ("distractor_radii_m[0]", self.distractor_radii_m[0]),
            ("distractor_radii_m[1]", self.distractor_radii_m[1]),
            ("electrons_per_grey", self.electrons_per_grey),
        ];
        for (field, value) in positive {
            // The gain may be infinite: no shot noise.
            if value.is_nan()
                || value <= 0.0
                || (value.is_infinite() && field != "electrons_per_grey")
            {
                bail!("image.{field} = {value} is out of range: it must be > 0");
            }
        }
        let non_negative = [
            ("exposure_ms", self.exposure_ms, 100.0),
            ("read_noise_grey", self.read_noise_grey, 50.0),
            ("rim_width_m", self.rim_width_m, 0.1),
            ("part_margin_m", self.part_margin_m, 0.1),
            (
                "key_feature_mark_radius_m",
                self.key_feature_mark_radius_m,
                0.05,
            ),
        ];
        for (field, value, max) in non_negative {
            if !(value.is_finite() && (0.0..=max).contains(&value)) {
                bail!("image.{field} = {value} is out of range: it must be in [0, {max}]");
            }
        }
        for (field, value) in [("k1", self.k1), ("k2", self.k2)] {
            if !(value.is_finite() && value.abs() <= 0.5) {
                bail!("image.{field} = {value} is out of range: it must be within +-0.5");
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_bad_values_are_named() {
        ImageSettings::default().validate().unwrap();
        ImageSettings::default().noise_free().validate().unwrap();
        let bad = ImageSettings {
            mark_reflectance: 1.5,
            ..ImageSettings::default()
        };
        let err = bad.validate().unwrap_err().to_string();
        assert!(err.contains("image.mark_reflectance"), "{err}");
        let bad = ImageSettings {
            k1: f64::NAN,
            ..ImageSettings::default()
        };
        assert!(bad.validate().unwrap_err().to_string().contains("image.k1"));
        // Experiments without the table get the defaults.
        let mut skipping = false;
        let text: String = crate::scenario::pick::DEFAULT_SCENARIO_TOML
            .lines()
            .filter(|line| {
                if line.starts_with("[experiment.image]") {
                    skipping = true;
                } else if line.starts_with('[') {
                    skipping = false;
                }
                !skipping
            })
            .map(|line| format!("{line}\n"))
            .collect();
        assert!(!text.contains("[experiment.image]"));
        let file = crate::scenario::pick::PickScenarioFile::parse(&text).unwrap();
        assert!(file
            .experiment
            .iter()
            .all(|e| e.image == ImageSettings::default()));
    }
}
