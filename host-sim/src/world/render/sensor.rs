//! From the scene's reflectance to 8-bit grey levels: light that varies
//! across the image (a linear gradient whose direction turns, vignetting)
//! and over time (a slow drift of the level), then the sensor's shot noise
//! (Poisson, as a Gaussian of variance `grey / electrons_per_grey`) and read
//! noise (Gaussian), rounded and clipped to 0..=255.

use rand::{Rng, RngExt};
use rand_distr::StandardNormal;

use super::raster::FrameBuffer;
use crate::scenario::pick::ImageSettings;

/// The light over the image at one instant, grey levels per unit
/// reflectance: `level (1 + g (x cos a + y sin a)) (1 - vignetting (x^2 + y^2) / 2)`
/// in coordinates normalised to the half image, the drift folded into the level.
#[derive(Debug, Clone, Copy)]
pub struct Light {
    level: f64,
    gx: f64,
    gy: f64,
    vignetting: f64,
    cx: f64,
    cy: f64,
    inverse_half: f64,
}

impl Light {
    pub fn new(settings: &ImageSettings, width: usize, height: usize, time_s: f64) -> Self {
        let tau = std::f64::consts::TAU;
        let (cx, cy) = ((width as f64 - 1.0) / 2.0, (height as f64 - 1.0) / 2.0);
        let half = cx.max(cy).max(1.0);
        let direction = tau * time_s / settings.light_turn_period_s;
        let drift =
            1.0 + settings.light_drift * (tau * time_s / settings.light_drift_period_s).sin();
        Self {
            level: settings.light_level * drift,
            gx: settings.light_gradient * direction.cos(),
            gy: settings.light_gradient * direction.sin(),
            vignetting: settings.vignetting,
            cx,
            cy,
            inverse_half: 1.0 / half,
        }
    }

    /// Grey levels per unit reflectance at pixel `(u, v)`.
    #[inline]
    pub fn at(&self, u: f64, v: f64) -> f64 {
        let (x, y) = (
            (u - self.cx) * self.inverse_half,
            (v - self.cy) * self.inverse_half,
        );
        // The corners are at x^2 + y^2 = 2.
        self.level
            * (1.0 + self.gx * x + self.gy * y)
            * (1.0 - self.vignetting * (x * x + y * y) / 2.0)
    }
}

/// The grey image of `buffer` lit at `time_s`, with noise from `rng` (none
/// drawn when the settings have no noise).
pub fn expose(
    buffer: &FrameBuffer,
    settings: &ImageSettings,
    time_s: f64,
    rng: &mut impl Rng,
    out: &mut Vec<u8>,
) {
    out.clear();
    out.reserve(buffer.width * buffer.height);
    let light = Light::new(settings, buffer.width, buffer.height, time_s);
    let noisy = settings.read_noise_grey > 0.0 || settings.electrons_per_grey.is_finite();
    let read2 = settings.read_noise_grey * settings.read_noise_grey;
    let per_grey = 1.0 / settings.electrons_per_grey;
    for (index, albedo) in buffer.albedo.iter().enumerate() {
        let (u, v) = ((index % buffer.width) as f64, (index / buffer.width) as f64);
        let mut grey = f64::from(*albedo) * light.at(u, v);
        if noisy {
            let sigma = (read2 + grey.max(0.0) * per_grey).sqrt();
            let n: f64 = rng.sample(StandardNormal);
            grey += sigma * n;
        }
        out.push(grey.round().clamp(0.0, 255.0) as u8);
    }
}
