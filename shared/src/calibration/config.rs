//! Tunables of the self-calibration, with defaults for the paper's setting.

/// How the calibration weighs, gates and iterates (serialisable, so that a log's
/// readers can record the configuration an estimate was made with).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CalibrationConfig {
    /// Experiment 2 of the paper: the disc plane's height in the base frame is known.
    /// Then `base_from_disc.translation_m[2]` is this value and Eq 10 is not needed for depth.
    pub disc_height_in_base_m: Option<f64>,
    /// Prior of the pixel noise's standard deviation, px (default 0.5, a
    /// sub-pixel detector's nominal accuracy; nothing the cell states). It
    /// sizes the gates that clean the reference track and the first Huber
    /// loss before any fit exists, and floors the refinement's outlier gate;
    /// the refinement then measures the noise from its residuals
    /// ([`CalibrationQuality::pixel_sigma_px`](crate::observation::CalibrationQuality))
    /// and weighs and gates with that.
    pub pixel_sigma: f64,
    /// Huber threshold of the refinement, in units of the (robustly estimated) pixel sigma:
    /// residuals beyond it count linearly, so a gross outlier cannot dominate (default 3).
    pub huber_k: f64,
    /// Gate of the refinement in units of the pixel sigma: detections whose residual exceeds
    /// it after the first convergence are dropped as gross outliers (default 5).
    pub outlier_gate_sigma: f64,
    /// Levenberg-Marquardt iterations per refinement phase (default 30).
    pub max_iterations: u32,
    /// Smallest conveyor rotation over the observations for heights to be observable
    /// (default 0.3 rad, about 17 degrees).
    pub min_rotation_rad: f64,
}

impl Default for CalibrationConfig {
    fn default() -> Self {
        Self {
            disc_height_in_base_m: None,
            pixel_sigma: 0.5,
            huber_k: 3.0,
            outlier_gate_sigma: 5.0,
            max_iterations: 30,
            min_rotation_rad: 0.3,
        }
    }
}
