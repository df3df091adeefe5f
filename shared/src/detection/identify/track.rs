//! A track: one blob followed over frames while the disc turns, with a fit of
//! its path against the encoder angle.
//!
//! A point fixed on the turning disc (or on the part standing on it) moves on
//! a circle about the disc's axis; through a camera whose depth varies little
//! over that circle its image is `x(theta) = c + a cos(theta) + b sin(theta)`
//! (`c`: the image of the circle's centre on the axis; `a`, `b`: the image of
//! the disc's X and Y directions scaled by the radius). The fit keeps the
//! 3 x 3 normal equations of that linear model with a forgetting factor, so
//! perspective (the model is exact only for an affine camera) is absorbed by
//! fitting the recent arc; a point that is not on the disc (the arm's marks)
//! leaves a large residual, and one at rest (the disc centre, a fixed glint)
//! fits with `a = b = 0`.

use nalgebra::{Matrix3, Vector3};

use crate::observation::PixelPoint;

/// Weight of an observation one frame older than the newest: in the fit
/// that predicts (a short recent arc, where the affine model holds well),
/// and in the fit that measures the path's centre and size (most of a turn).
pub const RECENT_FORGETTING: f64 = 0.85;
/// See [`RECENT_FORGETTING`].
pub const WHOLE_FORGETTING: f64 = 0.98;

/// The running fit of `x(theta) = c + a cos + b sin` for both image axes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcFit {
    normal: Matrix3<f64>,
    rhs_u: Vector3<f64>,
    rhs_v: Vector3<f64>,
    /// Weighted sum of squared coordinates (for the residual).
    sum_sq: f64,
    /// Weighted count.
    weight: f64,
    /// Smallest and largest angle seen (the arc the fit spans), rad.
    theta_min: f64,
    theta_max: f64,
    forgetting: f64,
}

/// What a fit says about a track.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcModel {
    /// Image of the circle's centre, px.
    pub centre_px: [f64; 2],
    /// Image of the disc's X and Y directions times the radius, px.
    pub a_px: [f64; 2],
    /// Image of the disc's Y direction times the radius, px.
    pub b_px: [f64; 2],
    /// RMS residual of the recent observations, px.
    pub rms_px: f64,
}

impl ArcModel {
    /// The predicted pinhole pixel at `theta`.
    pub fn at(&self, theta: f64) -> PixelPoint {
        let (s, c) = libm::sincos(theta);
        [
            self.centre_px[0] + self.a_px[0] * c + self.b_px[0] * s,
            self.centre_px[1] + self.a_px[1] * c + self.b_px[1] * s,
        ]
    }

    /// The path's radius in the image, px (RMS of its two half-axes).
    pub fn radius_px(&self) -> f64 {
        libm::sqrt(
            (self.a_px[0] * self.a_px[0]
                + self.a_px[1] * self.a_px[1]
                + self.b_px[0] * self.b_px[0]
                + self.b_px[1] * self.b_px[1])
                / 2.0,
        )
    }
}

impl ArcFit {
    /// An empty fit whose observations weigh `forgetting` times less a frame.
    pub fn new(forgetting: f64) -> Self {
        Self {
            forgetting,
            normal: Matrix3::zeros(),
            rhs_u: Vector3::zeros(),
            rhs_v: Vector3::zeros(),
            sum_sq: 0.0,
            weight: 0.0,
            theta_min: f64::INFINITY,
            theta_max: f64::NEG_INFINITY,
        }
    }

    /// Adds an observation at `theta`, older ones weighing less.
    pub fn add(&mut self, theta: f64, p: PixelPoint) {
        let (s, c) = libm::sincos(theta);
        let phi = Vector3::new(1.0, c, s);
        self.normal = self.normal * self.forgetting + phi * phi.transpose();
        self.rhs_u = self.rhs_u * self.forgetting + phi * p[0];
        self.rhs_v = self.rhs_v * self.forgetting + phi * p[1];
        self.sum_sq = self.sum_sq * self.forgetting + p[0] * p[0] + p[1] * p[1];
        self.weight = self.weight * self.forgetting + 1.0;
        self.theta_min = self.theta_min.min(theta);
        self.theta_max = self.theta_max.max(theta);
    }

    /// The arc spanned, rad.
    pub fn arc_rad(&self) -> f64 {
        (self.theta_max - self.theta_min).max(0.0)
    }

    /// The model, once the arc is long enough for the three terms to part
    /// (`None` before, or when the normal equations are singular).
    pub fn model(&self, min_arc_rad: f64) -> Option<ArcModel> {
        if self.arc_rad() < min_arc_rad || self.weight < 3.0 {
            return None;
        }
        let inverse = self.normal.try_inverse()?;
        let cu = inverse * self.rhs_u;
        let cv = inverse * self.rhs_v;
        // Residual sum of squares: y'y - c' N c for each axis.
        let rss = self.sum_sq - cu.dot(&(self.normal * cu)) - cv.dot(&(self.normal * cv));
        let rms_px = libm::sqrt(rss.max(0.0) / self.weight);
        let model = ArcModel {
            centre_px: [cu.x, cv.x],
            a_px: [cu.y, cv.y],
            b_px: [cu.z, cv.z],
            rms_px,
        };
        let finite = [cu, cv].iter().all(|c| c.iter().all(|x| x.is_finite()));
        (finite && rms_px.is_finite()).then_some(model)
    }
}

/// A blob followed over frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Track {
    /// The observation before `previous` (angle, pinhole pixel).
    pub earlier: Option<(f64, PixelPoint)>,
    /// The observation before the newest.
    pub previous: Option<(f64, PixelPoint)>,
    /// The newest observation.
    pub latest: (f64, PixelPoint),
    /// Observations taken.
    pub hits: u32,
    /// Frames since the last observation.
    pub misses: u32,
    /// Sum of the blobs' areas, px (for the mark's size).
    pub area_sum: f64,
    /// Sum of the blobs' fluxes (area times mean contrast, grey px): the
    /// light a mark sends, proportional to its true area however blurred.
    pub flux_sum: f64,
    /// The newest blob's flux: a mark's light changes little from one frame
    /// to the next, however much it changes across the image.
    pub latest_flux: f64,
    /// The path's fit over the recent arc (prediction, consistency).
    pub fit: ArcFit,
    /// The path's fit over most of a turn (its centre and size).
    pub whole: ArcFit,
}

impl Track {
    /// A track started by one observation.
    pub fn start(theta: f64, p: PixelPoint, area_px: f64, flux: f64) -> Self {
        let mut fit = ArcFit::new(RECENT_FORGETTING);
        fit.add(theta, p);
        let mut whole = ArcFit::new(WHOLE_FORGETTING);
        whole.add(theta, p);
        Self {
            earlier: None,
            previous: None,
            latest: (theta, p),
            hits: 1,
            misses: 0,
            area_sum: area_px,
            flux_sum: flux,
            latest_flux: flux,
            fit,
            whole,
        }
    }

    /// Takes the next observation.
    pub fn update(&mut self, theta: f64, p: PixelPoint, area_px: f64, flux: f64) {
        self.flux_sum += flux;
        self.latest_flux = flux;
        self.earlier = self.previous;
        self.previous = Some(self.latest);
        self.latest = (theta, p);
        self.hits = self.hits.saturating_add(1);
        self.misses = 0;
        self.area_sum += area_px;
        self.fit.add(theta, p);
        self.whole.add(theta, p);
    }

    /// Mean blob flux, grey px.
    pub fn mean_flux(&self) -> f64 {
        self.flux_sum / f64::from(self.hits.max(1))
    }

    /// Mean blob area, px.
    pub fn mean_area_px(&self) -> f64 {
        self.area_sum / f64::from(self.hits.max(1))
    }

    /// Where the track's blob should be at `theta`. From its fit when that
    /// explains the recent path within `max_rms_px`. A point far from the
    /// disc's axis under a tilted camera is not on an affine path (its depth
    /// changes round the circle: the image moves unevenly with the angle),
    /// and its fit misses by a pixel or more: then by the parabola through
    /// its last three observations in the angle, as long as `theta` lies
    /// within their span past the newest (a short step, where the path's
    /// curvature is all that matters). Else from the fit when it explains
    /// the path within `max_rms_px` plus 1.5 % of its radius, else by moving
    /// it linearly with the angle from its last two observations (at rest
    /// when the angle has not changed).
    pub fn predict(&self, theta: f64, min_arc_rad: f64, max_rms_px: f64) -> PixelPoint {
        let model = self.fit.model(min_arc_rad);
        if let Some(model) = model.filter(|m| m.rms_px <= max_rms_px) {
            return model.at(theta);
        }
        if let Some(p) = self.parabola(theta) {
            return p;
        }
        if let Some(model) = model {
            if model.rms_px <= max_rms_px + 0.015 * model.radius_px() {
                return model.at(theta);
            }
        }
        let (theta1, p1) = self.latest;
        match self.previous {
            Some((theta0, p0)) if (theta1 - theta0).abs() > 1e-6 => {
                let k = (theta - theta1) / (theta1 - theta0);
                [p1[0] + (p1[0] - p0[0]) * k, p1[1] + (p1[1] - p0[1]) * k]
            }
            _ => p1,
        }
    }

    /// The Lagrange parabola through the last three observations at
    /// `theta`, when their angles are distinct and `theta` lies no further
    /// past the newest than they span.
    fn parabola(&self, theta: f64) -> Option<PixelPoint> {
        let (t0, p0) = self.earlier?;
        let (t1, p1) = self.previous?;
        let (t2, p2) = self.latest;
        let span = (t2 - t0).abs();
        let distinct = (t1 - t0).abs() > 1e-6 && (t2 - t1).abs() > 1e-6 && span > 1e-6;
        if !distinct || (theta - t2).abs() > span {
            return None;
        }
        let w0 = (theta - t1) * (theta - t2) / ((t0 - t1) * (t0 - t2));
        let w1 = (theta - t0) * (theta - t2) / ((t1 - t0) * (t1 - t2));
        let w2 = (theta - t0) * (theta - t1) / ((t2 - t0) * (t2 - t1));
        let p = [
            w0 * p0[0] + w1 * p1[0] + w2 * p2[0],
            w0 * p0[1] + w1 * p1[1] + w2 * p2[1],
        ];
        p.iter().all(|x| x.is_finite()).then_some(p)
    }
}
